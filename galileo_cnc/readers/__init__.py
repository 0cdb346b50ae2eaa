"""Pick the right reader for a file by its content, not its extension."""

from __future__ import annotations

import os

from galileo_cnc.errors import GalileoError, SourcePos
from galileo_cnc.program.ops import Program
from galileo_cnc.readers.dxf import looks_like_dxf, read_dxf
from galileo_cnc.readers.dxf.scan import BINARY_SENTINEL
from galileo_cnc.readers.gcode import looks_like_gcode, read_gcode
from galileo_cnc.readers.gerber import looks_like_gerber, read_gerber
from galileo_cnc.readers.source import (UnrecognisedFileError, binary_error, decode,
                                        first_binary_byte, read_bytes)


def detect_format(text: str) -> str | None:
    """'gerber', 'gcode', 'dxf' or None for text that is none of them."""
    if looks_like_gerber(text):
        return "gerber"
    if looks_like_dxf(text):
        return "dxf"
    if looks_like_gcode(text):
        return "gcode"
    return None


def read_file(path: str | os.PathLike, *, max_ops: int | None = None,
              layers: tuple[str, ...] = (), units: str | None = None) -> Program:
    """Read a Gerber, G-code or DXF file into a Program; errors name the file and line.

    Only regular text files are read (see readers/source.py); `max_ops` overrides the
    op limit (readers/limits.py, $GALILEO_MAX_OPS). `layers` and `units` are a DXF
    drawing's (read_dxf); given for another format they are an error, not ignored.
    """
    data = read_bytes(path)
    dxf_options = {"layers": tuple(layers) or None, "units": units}
    if data.startswith(BINARY_SENTINEL):
        return read_dxf(path, max_ops=max_ops, **dxf_options)  # binary DXF
    at = first_binary_byte(data)
    if at is not None:
        raise binary_error(os.fsdecode(path), data, at)
    text = decode(data)
    del data
    fmt = detect_format(text)
    if fmt in ("gerber", "gcode") and (layers or units):
        raise GalileoError(f"{os.fsdecode(path)}: --layers and --units are for DXF drawings; "
                           f"this is a {'Gerber' if fmt == 'gerber' else 'G-code'} file")
    if fmt == "gerber":
        return read_gerber(path, text, max_ops=max_ops)
    if fmt == "gcode":
        return read_gcode(path, text, max_ops=max_ops)
    if fmt == "dxf":
        del text
        return read_dxf(path, max_ops=max_ops, **dxf_options)  # reads the bytes: binary too
    blank = len(text) - len(text.lstrip())
    line = text.count("\n", 0, blank) + 1
    raise UnrecognisedFileError(
        SourcePos(os.fsdecode(path), line, 1),
        ("the file is empty: " if not text.strip() else "")
        + "neither a Gerber RS-274X, a G-code nor a DXF file (Gerber starts with %FS/%MO/G04, "
        "G-code with G/M/N words, DXF with a 0/SECTION group)", text[blank:blank + 80])
