"""The deprecated image parameters that move geometry: AS, MI, SF, OF, IR (and IP).

They are file-wide, so the reader collects the last value of each and applies
one integer affine transform to the whole op table at the end, in the order of
the old RS-274X specification: axis select, mirror, scale, offset, rotation.
A mirror (odd number of them) turns clockwise arcs into counter-clockwise ones.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind
from galileo_cnc.readers.gerber.numbers import parse_decimal, round_div, to_nm
from galileo_cnc.readers.limits import MAX_SCALE

ARC_CW_KIND, ARC_CCW_KIND = int(OpKind.ARC_CW), int(OpKind.ARC_CCW)
_AB = re.compile(r"(?:A([+-]?[\d.]+))?(?:B([+-]?[\d.]+))?$")


@dataclass
class ImageTransform:
    swap_axes: bool = False
    mirror_a: bool = False
    mirror_b: bool = False
    scale_a: Fraction = Fraction(1)
    scale_b: Fraction = Fraction(1)
    offset_a_nm: int = 0
    offset_b_nm: int = 0
    rotation_deg: int = 0
    negative: bool = False

    def apply_command(self, block: str, units: str) -> bool:
        """Take one %AS/%MI/%SF/%OF/%IR/%IP block; True if it changes geometry."""
        code, body = block[:2], block[2:]
        if code == "IP":
            if body not in ("POS", "NEG"):
                raise ValueError("expected %IPPOS* or %IPNEG*")
            self.negative = body == "NEG"
            return False
        if code == "IR":
            if body not in ("0", "90", "180", "270"):
                raise ValueError("expected %IR0*, %IR90*, %IR180* or %IR270*")
            self.rotation_deg = int(body)
            return self.rotation_deg != 0
        if code == "AS":
            if body not in ("AXBY", "AYBX"):
                raise ValueError("expected %ASAXBY* or %ASAYBX*")
            self.swap_axes = body == "AYBX"
            return self.swap_axes
        m = _AB.match(body)
        if not m:
            raise ValueError(f"expected %{code}A<n>B<n>*")
        a, b = m.groups()
        if code == "MI":
            self.mirror_a, self.mirror_b = a not in (None, "0"), b not in (None, "0")
            return self.mirror_a or self.mirror_b
        if code == "SF":
            self.scale_a = parse_decimal(a) if a else Fraction(1)
            self.scale_b = parse_decimal(b) if b else Fraction(1)
            if max(abs(self.scale_a), abs(self.scale_b)) > MAX_SCALE:
                raise ValueError(f"%SF scale factor beyond {MAX_SCALE}")
            return (self.scale_a, self.scale_b) != (1, 1)
        # OF
        self.offset_a_nm = to_nm(parse_decimal(a), units) if a else 0
        self.offset_b_nm = to_nm(parse_decimal(b), units) if b else 0
        return (self.offset_a_nm, self.offset_b_nm) != (0, 0)

    def is_identity(self) -> bool:
        return not (self.swap_axes or self.mirror_a or self.mirror_b or self.rotation_deg
                    or self.offset_a_nm or self.offset_b_nm or (self.scale_a, self.scale_b) != (1, 1))

    def describe(self) -> dict:
        return {"swap_axes": self.swap_axes, "mirror": [self.mirror_a, self.mirror_b],
                "scale": [str(self.scale_a), str(self.scale_b)],
                "offset_nm": [self.offset_a_nm, self.offset_b_nm],
                "rotation_deg": self.rotation_deg, "negative": self.negative}

    def apply(self, table: np.ndarray) -> None:
        """Transform every row of an op table in place."""
        x, y = table[:, X].copy(), table[:, Y].copy()
        i, j = table[:, I].copy(), table[:, J].copy()
        if self.swap_axes:
            x, y, i, j = y, x, j, i
        if self.mirror_a:
            x, i = -x, -i
        if self.mirror_b:
            y, j = -y, -j
        x, i = _scale(x, self.scale_a), _scale(i, self.scale_a)
        y, j = _scale(y, self.scale_b), _scale(j, self.scale_b)
        x = x + self.offset_a_nm
        y = y + self.offset_b_nm
        for _ in range(self.rotation_deg // 90):
            x, y, i, j = -y, x, -j, i
        table[:, X], table[:, Y], table[:, I], table[:, J] = x, y, i, j
        if self.swap_axes ^ self.mirror_a ^ self.mirror_b:
            arcs_cw = table[:, KIND] == ARC_CW_KIND
            arcs_ccw = table[:, KIND] == ARC_CCW_KIND
            table[arcs_cw, KIND] = ARC_CCW_KIND
            table[arcs_ccw, KIND] = ARC_CW_KIND


def _scale(values: np.ndarray, factor: Fraction) -> np.ndarray:
    if factor == 1:
        return values
    return np.array([round_div(int(v) * factor.numerator, factor.denominator) for v in values],
                    dtype=np.int64)
