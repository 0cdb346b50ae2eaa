"""Load transforms (%LM, %LR, %LS): how flashed apertures are mirrored, rotated, scaled.

They change the image of each flash, not where it is placed. For an aperture block
(%AB) the image is drawn geometry, so the block's rows are transformed about the
block origin before they are moved to the flash point: first mirroring, then
rotation, then scaling (the order of the Gerber specification; the uniform scale
commutes with the other two anyway). Quarter turns are exact; other angles are
computed in float and rounded to the nanometre.
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

    def transform_rows(self, rows: np.ndarray) -> np.ndarray:
        """A transformed copy of op rows (coordinates and arc centre offsets)."""
        rows = rows.copy()
        if self.is_identity():
            return rows
        x, y, i, j = (rows[:, c].copy() for c in (X, Y, I, J))
        if "X" in self.mirror:
            x, i = -x, -i
        if "Y" in self.mirror:
            y, j = -y, -j
        if self.mirror in ("X", "Y"):  # one mirror turns arcs around
            clockwise = rows[:, KIND] == ARC_CW
            rows[rows[:, KIND] == ARC_CCW, KIND] = ARC_CW
            rows[clockwise, KIND] = ARC_CCW
        x, y = _rotate(x, y, self.rotation_deg)
        i, j = _rotate(i, j, self.rotation_deg)
        if self.scale != 1:
            x, y, i, j = (np.array([round_div(int(v) * self.scale.numerator, self.scale.denominator)
                                    for v in values], dtype=np.int64) for values in (x, y, i, j))
        rows[:, X], rows[:, Y], rows[:, I], rows[:, J] = x, y, i, j
        return rows


def _rotate(x: np.ndarray, y: np.ndarray, degrees: Fraction):
    turns = degrees % 360
    if turns % 90 == 0:
        for _ in range(int(turns // 90)):
            x, y = -y, x
        return x, y
    angle = math.radians(float(turns))
    c, s = math.cos(angle), math.sin(angle)
    return (np.rint(x * c - y * s).astype(np.int64), np.rint(x * s + y * c).astype(np.int64))
