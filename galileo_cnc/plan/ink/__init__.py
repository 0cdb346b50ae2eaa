"""Ink the copper: Gerber objects as exact dark shapes in integer nm (docs/ink.md).

`dark_geometry(program)` is the first step: the copper of a layer as one polygon
set, dark objects united and clear ones subtracted in file order.
"""

from galileo_cnc.plan.ink.geometry import (
    DEFAULT_BACKEND,
    DarkImage,
    InkError,
    dark_geometry,
)
from galileo_cnc.plan.ink.shapes import DEFAULT_TOLERANCE_NM

__all__ = ["DEFAULT_BACKEND", "DEFAULT_TOLERANCE_NM", "DarkImage", "InkError", "dark_geometry"]
