"""Exact conversion of Gerber numbers to integer nanometres.

Coordinates are integers with an implied decimal point (%FS); aperture and macro
parameters are decimal strings. Both are converted with integer arithmetic only:
millimetres with up to 6 decimals and inches with up to 5 decimals are exact;
finer inch formats round half away from zero to the nanometre.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from fractions import Fraction

from galileo_cnc.program.ops import NM_PER_INCH, NM_PER_MM
from galileo_cnc.readers.limits import MAX_NUMBER_CHARS

NM_PER_UNIT = {"mm": NM_PER_MM, "in": NM_PER_INCH}
MAX_NM = 10**12  # a kilometre: anything larger is a broken file, and must not overflow int64

_DECIMAL = re.compile(r"\s*([+-]?)(\d*)(?:\.(\d*))?(?:[eE]([+-]?\d+))?\s*$")


def round_div(numerator: int, denominator: int) -> int:
    """numerator / denominator rounded half away from zero (denominator > 0)."""
    if numerator >= 0:
        return (2 * numerator + denominator) // (2 * denominator)
    return -((-2 * numerator + denominator) // (2 * denominator))


def parse_decimal(text: str) -> Fraction:
    """'0.254', '-.5', '1.', '2E-3' as an exact Fraction; ValueError if not a number."""
    if len(text) > MAX_NUMBER_CHARS:
        text = text.strip()
        if len(text) > MAX_NUMBER_CHARS:
            raise ValueError(f"number of {len(text):,} characters (at most {MAX_NUMBER_CHARS}): "
                             f"{text[:20]}...")
    m = _DECIMAL.match(text)
    if not m or not (m.group(2) or m.group(3)):
        raise ValueError(f"not a decimal number: {text!r}")
    sign, whole, frac, exp = m.groups()
    frac = frac or ""
    value = Fraction(int((whole or "0") + frac), 10 ** len(frac))
    if exp:
        if abs(int(exp)) > 30:
            raise ValueError(f"exponent out of range in {text!r}")
        value *= Fraction(10) ** int(exp)
    return -value if sign == "-" else value


def to_nm(value: Fraction, units: str) -> int:
    """A length in `units` as integer nanometres (round half away from zero)."""
    return checked_nm(round_div(value.numerator * NM_PER_UNIT[units], value.denominator))


def checked_nm(nm: int) -> int:
    if abs(nm) > MAX_NM:
        raise ValueError(f"length of {nm / 1e9:g} m is out of range (at most 1 km)")
    return nm


def decimal_to_nm(text: str, units: str) -> int:
    return to_nm(parse_decimal(text), units)


@dataclass(frozen=True, slots=True)
class AxisFormat:
    """How one axis' coordinate digits turn into nm under a %FS and %MO.

    nm = digits * numerator // denominator (rounded), where the digits are first
    padded on the right when trailing zeros are omitted.
    """

    integer_digits: int
    decimal_digits: int
    trailing_zeros_omitted: bool
    numerator: int
    denominator: int
    plain: bool  # nm = int(digits) * numerator exactly: no padding, no rounding

    @classmethod
    def make(cls, integer_digits: int, decimal_digits: int, trailing: bool, units: str):
        scale = Fraction(NM_PER_UNIT[units], 10 ** decimal_digits)
        return cls(integer_digits, decimal_digits, trailing, scale.numerator, scale.denominator,
                   not trailing and scale.denominator == 1)

    def to_nm(self, digits: str) -> int:
        if self.trailing_zeros_omitted:
            negative = digits[0] == "-"
            body = digits.lstrip("+-")
            value = int(body.ljust(self.integer_digits + self.decimal_digits, "0"))
            if negative:
                value = -value
        else:
            value = int(digits)
        if self.denominator == 1:
            return value * self.numerator
        return round_div(value * self.numerator, self.denominator)
