"""Load transforms (%LM, %LR, %LS): how apertures are mirrored, rotated, scaled.

They change the image of each flash, and the aperture of each draw and arc, not
where it is placed: mirroring first, then rotation, then scaling, about the
aperture origin (the order of the Gerber specification; the uniform scale commutes
with the other two anyway). Standard and macro apertures get a transformed copy
(transformed.py); an aperture block (%AB) is drawn geometry, so its rows are
transformed about the block origin before they are moved to the flash point.

Quarter turns are exact and an exact scale rounds once (half away from zero);
other angles are computed in float, rotation and scale together, and rounded to
the nanometre once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind
from galileo_cnc.readers.gerber.numbers import parse_decimal, round_div
from galileo_cnc.readers.limits import MAX_ROTATION_DEGREES, MAX_SCALE

ARC_CW, ARC_CCW = int(OpKind.ARC_CW), int(OpKind.ARC_CCW)
_INT64_SAFE = 2**61  # |value x numerator| below this cannot overflow the rounding below


@dataclass
class LoadTransform:
    mirror: str = "N"  # N, X, Y or XY
    rotation_deg: Fraction = Fraction(0)
    scale: Fraction = Fraction(1)

    def apply_command(self, block: str) -> None:
        """Take one %LM/%LR/%LS block; ValueError if malformed."""
        code, body = block[:2], block[2:]
        if code == "LM":
            if body not in ("N", "X", "Y", "XY"):
                raise ValueError("expected %LMN*, %LMX*, %LMY* or %LMXY*")
            self.mirror = body
        elif code == "LR":
            rotation = parse_decimal(body)
            if abs(rotation) > MAX_ROTATION_DEGREES:
                raise ValueError(f"%LR rotation of {float(rotation):g} degrees (at most "
                                 f"{MAX_ROTATION_DEGREES} either way)")
            self.rotation_deg = rotation
        else:
            scale = parse_decimal(body)
            if scale <= 0:
                raise ValueError("expected a positive %LS scale factor")
            if scale > MAX_SCALE:
                raise ValueError(f"%LS scale factor {float(scale):g} (at most {MAX_SCALE})")
            self.scale = scale

    def is_identity(self) -> bool:
        return self.mirror == "N" and self.rotation_deg % 360 == 0 and self.scale == 1

    def key(self) -> tuple[str, Fraction, Fraction]:
        """What makes two transforms the same (rotations modulo a full turn)."""
        return (self.mirror, self.rotation_deg % 360, self.scale)

    def copy(self) -> "LoadTransform":
        return LoadTransform(self.mirror, self.rotation_deg, self.scale)

    def describe(self) -> str:
        """The commands that are not the identity, e.g. '%LMX %LR30 %LS0.5'."""
        parts = [f"%LM{self.mirror}"] if self.mirror != "N" else []
        if self.rotation_deg % 360:
            parts.append(f"%LR{_decimal(self.rotation_deg % 360)}")
        if self.scale != 1:
            parts.append(f"%LS{_decimal(self.scale)}")
        return " ".join(parts)

    @property
    def mirrors_once(self) -> bool:
        """One axis mirrored: the outline's orientation (and arc direction) reverses."""
        return self.mirror in ("X", "Y")

    def quarter_turns(self) -> int | None:
        """Rotation in quarter turns (0..3), or None for any other angle."""
        turns = self.rotation_deg % 360
        return int(turns // 90) if turns % 90 == 0 else None

    def transform_xy(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Points (or offsets) transformed, int64. Integer input is exact for quarter
        turns (scale rounded once); float input (half-nm corners of standard shapes)
        and other angles round once, after rotation and scaling."""
        x, y = np.asarray(x), np.asarray(y)
        if "X" in self.mirror:
            x = -x
        if "Y" in self.mirror:
            y = -y
        turns = self.quarter_turns()
        exact = turns is not None and x.dtype.kind in "iu" and y.dtype.kind in "iu"
        if exact:
            x, y = x.astype(np.int64), y.astype(np.int64)
            for _ in range(turns):
                x, y = -y, x
            return _scale_exact(x, self.scale), _scale_exact(y, self.scale)
        angle = math.radians(float(self.rotation_deg % 360))
        c, s = math.cos(angle), math.sin(angle)
        if turns is not None:  # float input at a quarter turn: no trigonometry noise
            c, s = ((1, 0), (0, 1), (-1, 0), (0, -1))[turns]
        k = float(self.scale)
        fx, fy = x.astype(np.float64), y.astype(np.float64)
        return (np.rint((fx * c - fy * s) * k).astype(np.int64),
                np.rint((fx * s + fy * c) * k).astype(np.int64))

    def scale_length(self, nm: int) -> int:
        """A size (diameter, side) under the scale: exact, rounded half away from zero."""
        return round_div(nm * self.scale.numerator, self.scale.denominator)

    def transform_rows(self, rows: np.ndarray) -> np.ndarray:
        """A transformed copy of op rows (coordinates and arc centre offsets)."""
        rows = rows.copy()
        if self.is_identity():
            return rows
        if self.mirrors_once:  # one mirror turns arcs around
            clockwise = rows[:, KIND] == ARC_CW
            rows[rows[:, KIND] == ARC_CCW, KIND] = ARC_CW
            rows[clockwise, KIND] = ARC_CCW
        rows[:, X], rows[:, Y] = self.transform_xy(rows[:, X], rows[:, Y])
        rows[:, I], rows[:, J] = self.transform_xy(rows[:, I], rows[:, J])
        return rows


def _scale_exact(values: np.ndarray, scale: Fraction) -> np.ndarray:
    """values x scale, rounded half away from zero (as round_div), int64."""
    if scale == 1 or not len(values):
        return values
    n, d = scale.numerator, scale.denominator
    if int(np.abs(values).max()) * n < _INT64_SAFE:
        product = values * n
        return np.sign(product) * ((2 * np.abs(product) + d) // (2 * d))
    return np.array([round_div(int(v) * n, d) for v in values.tolist()], dtype=np.int64)


def _decimal(value: Fraction) -> str:
    if value.denominator == 1:
        return str(value.numerator)
    text = f"{float(value):.6f}".rstrip("0").rstrip(".")
    return text
