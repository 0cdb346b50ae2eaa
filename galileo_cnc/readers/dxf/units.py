"""Drawing units to nanometres: exact factors and the one rounding of each coordinate.

`$INSUNITS` names the unit of a drawing. Each unit is an exact rational number of
nanometres (the inch is 25.4 mm by definition, the US survey foot 1200/3937 m), and
a DXF coordinate (a binary float) is converted once, as the exact product
`float * factor` rounded half away from zero: no second rounding through a float.
"""

from __future__ import annotations

import math
from fractions import Fraction

# $INSUNITS code -> (short name, nanometres per unit). 0 = unitless (read as mm).
_US_FOOT = Fraction(1_200_000_000_000, 3937)  # the US survey foot: 1200/3937 m
INSUNITS: dict[int, tuple[str, Fraction]] = {
    1: ("in", Fraction(25_400_000)),
    2: ("ft", Fraction(304_800_000)),
    3: ("mi", Fraction(1_609_344_000_000)),
    4: ("mm", Fraction(1_000_000)),
    5: ("cm", Fraction(10_000_000)),
    6: ("m", Fraction(1_000_000_000)),
    7: ("km", Fraction(10**12)),
    8: ("uin", Fraction(127, 5)),  # microinch: 25.4 nm
    9: ("mil", Fraction(25_400)),
    10: ("yd", Fraction(914_400_000)),
    11: ("angstrom", Fraction(1, 10)),
    12: ("nm", Fraction(1)),
    13: ("um", Fraction(1_000)),
    14: ("dm", Fraction(100_000_000)),
    15: ("dam", Fraction(10**10)),
    16: ("hm", Fraction(10**11)),
    17: ("Gm", Fraction(10**18)),
    18: ("au", Fraction(149_597_870_700 * 10**9)),
    21: ("us-ft", _US_FOOT),
    22: ("us-in", _US_FOOT / 12),
    23: ("us-yd", _US_FOOT * 3),
    24: ("us-mi", _US_FOOT * 5280),
}
# 19 light years and 20 parsecs have no exact length in metres and no use on a plotter.

# Names accepted for the `units=` override (the first of each is the canonical one).
UNIT_NAMES: dict[str, int] = {
    "mm": 4, "millimeter": 4, "millimetre": 4,
    "in": 1, "inch": 1, "inches": 1,
    "cm": 5, "m": 6, "um": 13, "µm": 13, "micron": 13,
    "ft": 2, "foot": 2, "feet": 2, "mil": 9, "thou": 9, "yd": 10, "dm": 14,
}


def unit_factor(code: int) -> tuple[str, Fraction] | None:
    """(name, nm per unit) of an $INSUNITS code, None for unitless or unknown codes."""
    return INSUNITS.get(code)


class Scale:
    """Converts drawing-unit floats to integer nanometres: round(v * factor), ties away
    from zero, computed exactly from the float's binary fraction."""

    __slots__ = ("num", "den", "factor")

    def __init__(self, factor: Fraction):
        self.num = factor.numerator
        self.den = factor.denominator
        self.factor = float(factor)

    def nm(self, value: float) -> int:
        """Exactly round(value * factor), halves away from zero; ValueError if not finite."""
        if not math.isfinite(value):
            raise ValueError(f"{value} is not a number")
        a, b = value.as_integer_ratio()  # value = a / b, b a power of two
        n = abs(a) * self.num
        q = b * self.den
        r = (2 * n + q) // (2 * q)
        return -r if a < 0 else r
