"""Pick the right reader for a file by its content, not its extension."""

from __future__ import annotations

import os

from galileo_cnc.errors import GalileoError, UnknownFormatError
from galileo_cnc.program.ops import Program
from galileo_cnc.readers.dxf import looks_like_dxf, read_dxf
from galileo_cnc.readers.gcode import looks_like_gcode, read_gcode
from galileo_cnc.readers.gerber import looks_like_gerber, read_gerber


def detect_format(text: str) -> str | None:
    """'gerber', 'gcode', 'dxf' or None for text that is none of them."""
    if looks_like_gerber(text):
        return "gerber"
    if looks_like_dxf(text):
        return "dxf"
    if looks_like_gcode(text):
        return "gcode"
    return None


def read_file(path: str | os.PathLike) -> Program:
    """Read a Gerber, G-code or DXF file into a Program; errors name the file and line."""
    try:
        with open(path, "rb") as handle:
            text = handle.read().decode("utf-8", errors="replace")
    except OSError as problem:
        raise GalileoError(f"{path}: cannot read: {problem.strerror or problem}") from None
    fmt = detect_format(text)
    if fmt == "gerber":
        return read_gerber(path, text)
    if fmt == "gcode":
        return read_gcode(path, text)
    if fmt == "dxf":
        return read_dxf(path)             # reads the bytes itself: binary DXF too
    raise UnknownFormatError(
        f"{path}: neither a Gerber RS-274X, a G-code nor a DXF file "
        "(Gerber starts with %FS/%MO/G04, G-code with G/M/N words, DXF with a 0/SECTION "
        "group)")
