"""Excellon numbers as exact integer nm: the coordinate format and its conversion.

A coordinate is either decimal (`X2.1142`, `X55.`) or an integer with an implied
decimal point (`X026814`). Which digits are the integer part depends on the zeros
the file keeps: LZ keeps the leading zeros (the trailing ones may be left off, so
the number is read from the left), TZ keeps the trailing zeros (the leading ones may
be left off, so the number is read from the right). Everything is integer
arithmetic: millimetres and inches convert exactly, as in the Gerber reader.
"""

from __future__ import annotations

from dataclasses import dataclass

from galileo_cnc.readers.gerber.numbers import NM_PER_UNIT, parse_decimal, round_div, to_nm
from galileo_cnc.readers.limits import MAX_GERBER_COORD_NM, MAX_NUMBER_CHARS

# What each unit's coordinates have when the file does not say: Excellon's 2.4 inch
# (Eagle, Protel, gEDA, DipTrace, PADS) and 3.3 mm (Eagle metric, Mentor, OrCAD).
DEFAULT_DIGITS = {"in": (2, 4), "mm": (3, 3)}

# Digits of a coordinate format (integer and decimal together): 4.4 is the most any
# tool writes; past this a stated format is broken.
MAX_FORMAT_DIGITS = 16

# Coordinates further than this from the origin are a broken file (10 m, as Gerber).
MAX_DRILL_COORD_NM = MAX_GERBER_COORD_NM


@dataclass
class NumberFormat:
    """How the file writes lengths: its unit, the zeros it keeps and its digits."""

    units: str = "in"              # "mm" or "in"
    zeros: str = "TZ"              # "LZ": leading zeros kept; "TZ": trailing zeros kept
    integer_digits: int = 2
    decimal_digits: int = 4
    decimal: bool = False          # KiCad's "decimal" format: X55 is 55 units

    def describe(self) -> str:
        kept = "leading" if self.zeros == "LZ" else "trailing"
        return (f"{'METRIC' if self.units == 'mm' else 'INCH'} "
                f"{self.integer_digits}.{self.decimal_digits}, {kept} zeros kept")


def coordinate_nm(text: str, fmt: NumberFormat) -> int:
    """`text` ('+026814', '-108128', '2.1142', '55.') as nm; ValueError if not a number."""
    if len(text) > MAX_NUMBER_CHARS:
        raise ValueError(f"number of {len(text):,} characters (at most {MAX_NUMBER_CHARS})")
    if "." in text or fmt.decimal:
        nm = to_nm(parse_decimal(text), fmt.units)
    else:
        negative = text.startswith("-")
        digits = text.lstrip("+-")
        if not digits.isdigit() or not digits.isascii() or len(text) - len(digits) > 1:
            raise ValueError(f"not a number: {text!r}")
        width = fmt.integer_digits + fmt.decimal_digits
        if width > MAX_FORMAT_DIGITS:
            raise ValueError(f"the format {fmt.integer_digits}.{fmt.decimal_digits} has more "
                             f"than {MAX_FORMAT_DIGITS} digits")
        if fmt.zeros == "LZ":
            if len(digits) > width:
                raise ValueError(f"{text!r} has {len(digits)} digits, more than the "
                                 f"{fmt.integer_digits}.{fmt.decimal_digits} format holds")
            digits = digits.ljust(width, "0")
        nm = round_div(int(digits) * NM_PER_UNIT[fmt.units], 10 ** fmt.decimal_digits)
        nm = -nm if negative else nm
    if abs(nm) > MAX_DRILL_COORD_NM:
        raise ValueError(f"{text!r} lies {abs(nm) / 1e9:g} m from the origin "
                         f"(at most {MAX_DRILL_COORD_NM // 10**9} m)")
    return nm


def size_nm(text: str, units: str) -> int:
    """A tool size ('0.800', '.864', '1.') in `units` as nm; ValueError if not one."""
    nm = to_nm(parse_decimal(text), units)
    if nm < 0:
        raise ValueError(f"negative size {text!r}")
    return nm
