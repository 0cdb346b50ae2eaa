"""Offsets: where the artwork goes on the machine (the seed's minimum-coordinate rule).

The offset is subtracted from every coordinate. The proposal brings the artwork's
lower-left corner to (margin, margin); the user may type their own in mm or keep
the file's coordinates.
"""

from __future__ import annotations

import math

from galileo_cnc.errors import GalileoError
from galileo_cnc.program.extents import extents
from galileo_cnc.program.ops import NM_PER_MM, Program

DEFAULT_MARGIN_NM = 1 * NM_PER_MM
#: 1 km, as the readers' coordinates: far beyond any travel, and well inside int64 in nm
MAX_OFFSET_MM = 1_000_000


class OffsetError(GalileoError):
    """An offset the user gave cannot be read."""


class OffsetRangeError(ValueError):
    """An offset read, but beyond MAX_OFFSET_MM."""


def offset_for_box(box: tuple[int, int, int, int] | None,
                   margin_nm: int = DEFAULT_MARGIN_NM) -> tuple[int, int]:
    """The seed's rule: the box's minimum coordinate minus a margin ((0, 0) for no box).

    Subtracting it from every coordinate puts the box's lower-left corner at
    (margin, margin) from the machine origin.
    """
    if box is None:
        return (0, 0)
    return (box[0] - margin_nm, box[1] - margin_nm)


def proposed_offset(program: Program, margin_nm: int = DEFAULT_MARGIN_NM) -> tuple[int, int]:
    """The offset getg proposes: the seed's rule over everything the machine visits
    (drawn, flashed and travelled to), so a closing `G0 X0 Y0` fits too."""
    return offset_for_box(extents(program, visited=True), margin_nm)


def offset_from_text(text: str) -> tuple[int, int]:
    """An offset the user typed, 'X,Y' or 'X Y' in mm, in nm; ValueError otherwise."""
    parts = text.replace(",", " ").split()
    if len(parts) != 2:
        raise ValueError(f"expected two numbers, X,Y in mm, got {text!r}")
    try:
        x_mm, y_mm = float(parts[0]), float(parts[1])
    except ValueError:
        raise ValueError(f"expected two numbers, X,Y in mm, got {text!r}") from None
    if not (math.isfinite(x_mm) and math.isfinite(y_mm)):
        raise ValueError("the offsets must be finite numbers")
    if max(abs(x_mm), abs(y_mm)) > MAX_OFFSET_MM:
        raise OffsetRangeError(f"the offsets must be within {MAX_OFFSET_MM} mm (1 km)")
    return round(x_mm * NM_PER_MM), round(y_mm * NM_PER_MM)

