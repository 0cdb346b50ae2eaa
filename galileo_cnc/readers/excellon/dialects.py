"""What each EDA tool writes around the Excellon core: the comments that state the
format, the tool sizes or the plating, the tool that wrote the file, and what it
means when a file states nothing.

Comments read here:
  KiCad    `; DRILL file {KiCad ...}`, `;FORMAT={-:-/ absolute / inch / decimal}`,
           `; #@! TF.FileFunction,Plated,1,2,PTH` (X2 attributes as comments), and in a
           file of both kinds `; #@! TA.AperFunction,NonPlated,NPTH,ComponentDrill`
           before each tool
  Altium, P-CAD, EasyEDA `;FILE_FORMAT=2:4`, `;TYPE=PLATED` / `;TYPE=NON_PLATED`
           before the tools they cover
  Eagle    `;GenerationSoftware,Autodesk,EAGLE,9.5.1*%`
  Mentor   `; Format  : 2.4 / Absolute / Inch / Trailing` (the zeros it suppresses),
           `; Contents: Thru / Drill / Non-Plated`
  Allegro, OrCAD `;T01 Holesize 1. = 8.000000 Tolerance = ... PLATED MILS Quantity = 3`
           (the only tool table an Allegro drill file has; route files have none)
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

from galileo_cnc.readers.excellon.numbers import DEFAULT_DIGITS, MAX_FORMAT_DIGITS

# Digit counts and tool numbers of at most a few digits: longer is no format (and
# int() of thousands of digits is refused by Python itself).
_FILE_FORMAT = re.compile(r";\s*FILE_FORMAT\s*=\s*(\d{1,3})\s*:\s*(\d{1,3})(?!\d)", re.I)
_KICAD_FORMAT = re.compile(r";\s*FORMAT\s*=\s*\{([^}]*)\}", re.I)
_MENTOR_FORMAT = re.compile(r";\s*Format\s*:\s*(\d{1,3})\.(\d{1,3})\s*/\s*(\w+)\s*/\s*(\w+)\s*/\s*(\w+)", re.I)
_TYPE = re.compile(r";\s*TYPE\s*=\s*(NON[_-]?PLATED|PLATED)", re.I)
_FILE_FUNCTION = re.compile(r"TF\.FileFunction\s*,\s*(NonPlated|Plated|MixedPlating)", re.I)
_APER_FUNCTION = re.compile(r";\s*#@!\s*TA\.AperFunction\s*,\s*(NonPlated|Plated)", re.I)
_CONTENTS = re.compile(r";\s*Contents\s*:.*?(Non-?Plated|Plated)", re.I)
_HOLESIZE = re.compile(
    r";\s*T(\d{1,9})\s+Holesize\s+[\d.]+\s*=\s*([\d.]+)\s+Tolerance.*?\b(NON_PLATED|PLATED)?"
    r"\s*\b(MILS|MM|INCH|INCHES)\b", re.I)
_GENERATORS = (
    (re.compile(r"KiCad", re.I), "KiCad"),
    (re.compile(r"EAGLE", re.I), "Eagle"),
    (re.compile(r"EasyEDA", re.I), "EasyEDA"),
    (re.compile(r"Layer_Color=", re.I), "Altium/Protel"),
    (re.compile(r";\s*(LEADER|Holesize|T\d+ Holesize)", re.I), "Allegro/OrCAD"),
    (re.compile(r";\s*(Version\s*:|Job\s*:|PARTNO)", re.I), "Mentor"),
)


@dataclass
class Stated:
    """What the comments said: digits, zeros, decimal form, plating, writer."""

    digits: tuple[int, int] | None = None
    zeros: str | None = None           # "LZ" / "TZ"
    decimal: bool = False
    units: str | None = None
    plated: bool | None = None
    plated_from: str = ""
    generator: str = ""


def read_comment(comment: str, stated: Stated) -> bool | None:
    """Note what a comment line says in `stated`; returns the plating of the tools
    that follow for an Altium-style `;TYPE=` line (None otherwise)."""
    if not stated.generator:
        for pattern, name in _GENERATORS:
            if pattern.search(comment):
                stated.generator = name
                break
    if m := _FILE_FORMAT.match(comment):
        stated.digits = (int(m.group(1)), int(m.group(2)))
    elif m := _KICAD_FORMAT.match(comment):
        _kicad_format(m.group(1), stated)
    elif m := _MENTOR_FORMAT.match(comment):
        stated.digits = (int(m.group(1)), int(m.group(2)))
        unit, zeros = m.group(4).lower(), m.group(5).lower()
        stated.units = {"inch": "in", "mm": "mm", "metric": "mm"}.get(unit, stated.units)
        # Mentor names the zeros it leaves out
        stated.zeros = {"leading": "TZ", "trailing": "LZ"}.get(zeros, stated.zeros)
    elif m := _FILE_FUNCTION.search(comment):
        if m.group(1).lower() != "mixedplating":       # mixed: each tool says (TA below)
            stated.plated = m.group(1).lower() == "plated"
            stated.plated_from = "X2 comment"
    elif m := _CONTENTS.match(comment):
        stated.plated = not m.group(1).lower().startswith("non")
        stated.plated_from = "header comment"
    elif m := _TYPE.match(comment):
        return not m.group(1).upper().startswith("NON")
    elif m := _APER_FUNCTION.match(comment):          # KiCad: the next tool's plating
        return m.group(1).lower() == "plated"
    return None


def _kicad_format(body: str, stated: Stated) -> None:
    parts = [p.strip().lower() for p in body.split("/")]
    if parts and (m := re.match(r"(\d{1,3}):(\d{1,3})(?!\d)", parts[0])):
        stated.digits = (int(m.group(1)), int(m.group(2)))
    for part in parts[1:]:
        if part in ("inch", "metric"):
            stated.units = "in" if part == "inch" else "mm"
        elif part == "decimal":
            stated.decimal = True
        elif "suppress leading" in part:
            stated.zeros = "TZ"
        elif "suppress trailing" in part or "keep zeros" in part:
            stated.zeros = "LZ"


def holesize_comment(comment: str) -> tuple[int, str, str, bool | None] | None:
    """An Allegro `;T01 Holesize` comment: (tool number, size text, unit, plated)."""
    m = _HOLESIZE.match(comment)
    if not m:
        return None
    unit = {"MILS": "mil", "MM": "mm"}.get(m.group(4).upper(), "in")
    plating = m.group(3)
    return int(m.group(1)), m.group(2), unit, None if plating is None else plating.upper() == "PLATED"


_NAME_UNPLATED = re.compile(r"(^|[^a-z])(npth|nplt|non[-_ ]?plated|unplated)([^a-z]|$)", re.I)
_NAME_PLATED = re.compile(r"(^|[^a-z])(pth|plt|plated)([^a-z]|$)", re.I)


def plating_from_name(path: str) -> bool | None:
    """-NPTH, _nplt, NonPlated, unplated: False; -PTH, _plt, plated: True; else None."""
    name = os.path.basename(path)
    if _NAME_UNPLATED.search(name) or re.search(r"NonPlated", name):
        return False
    if _NAME_PLATED.search(name) or re.search(r"(?<![Nn]on)Plated", name):
        return True
    return None


_NUMBER = re.compile(r"[XY][+-]?(\d+)(?![\d.])")
SCAN_LINES = 20_000  # coordinate lines looked at to infer an unstated format


def coordinate_widths(lines: list[str]) -> tuple[int, int, int]:
    """(widest integer coordinate, numbers that show kept leading zeros, numbers that
    show kept trailing zeros), from the first coordinate lines."""
    numbers: list[str] = []
    for line in lines[:SCAN_LINES]:
        if line.startswith(";") or "." in line:
            continue
        numbers.extend(_NUMBER.findall(line))
    numbers = [n for n in numbers if len(n) <= MAX_FORMAT_DIGITS]   # longer: an error later
    if not numbers:
        return 0, 0, 0
    widest = max(len(n) for n in numbers)
    short = [n for n in numbers if 1 < len(n) < widest]
    return (widest, sum(n[0] == "0" for n in short), sum(n[-1] == "0" for n in short))


def infer_format(units: str, zeros: str | None, digits: tuple[int, int] | None,
                 lines: list[str], generator: str) -> tuple[str, tuple[int, int], list[str]]:
    """The zeros and digits to read with, and notes on what was assumed (for metadata).

    Unstated zeros: a short number that starts with 0 shows leading zeros kept (LZ),
    one that ends in 0 trailing zeros kept (TZ); with neither, TZ (Eagle, Protel,
    gEDA). Unstated digits: 2.4 inch or 3.3 mm, the integer part widened to hold the
    widest LZ number (Zuken's 8-digit inch coordinates are 4.4); Allegro writes
    3.5 inch when its numbers have 7 or 8 digits; gEDA PCB before 2007 wrote mils
    (INCH,TZ, tools as T01F00S00C0.020, coordinates with 3 decimals)."""
    notes = []
    widest, lz_evidence, tz_evidence = coordinate_widths(lines)
    if zeros is None:
        zeros = "LZ" if lz_evidence > tz_evidence else "TZ"
        if widest:
            notes.append(f"zeros not stated: {'leading' if zeros == 'LZ' else 'trailing'} "
                         "zeros kept, as the coordinates show")
    if digits is None:
        integer, decimal = DEFAULT_DIGITS[units]
        if generator == "Allegro/OrCAD" and units == "in" and widest >= 7:
            integer, decimal = 3, 5
        elif generator == "gEDA PCB (mils)":
            decimal = 3
        if zeros == "LZ" and widest > integer + decimal:
            integer = widest - decimal
        digits = (integer, decimal)
        if widest:
            notes.append(f"digits not stated: {integer}.{decimal}"
                         + (f" (what {generator} writes)" if generator else ""))
    return zeros, digits, notes
