"""Pick the right reader for a file by its content, not its extension.

Gerber, G-code and DXF make a Program (`read_file`); an Excellon drill or route file
makes a DrillFile (`read_drill`), which holds holes and slots rather than strokes, so
`read_file` names the other entry for it.
"""

from __future__ import annotations

import os

from galileo_cnc.errors import GalileoError, SourcePos
from galileo_cnc.program.drills import DrillFile
from galileo_cnc.program.ops import Program
from galileo_cnc.readers.dxf import looks_like_dxf, read_dxf
from galileo_cnc.readers.dxf.scan import BINARY_SENTINEL
from galileo_cnc.readers.excellon import ExcellonError, looks_like_excellon, read_excellon
from galileo_cnc.readers.gcode import looks_like_gcode, read_gcode
from galileo_cnc.readers.gerber import looks_like_gerber, read_gerber
from galileo_cnc.readers.source import (UnrecognisedFileError, binary_error, decode,
                                        first_binary_byte, read_bytes)


def detect_format(text: str) -> str | None:
    """'gerber', 'gcode', 'dxf', 'excellon' or None for text that is none of them."""
    if looks_like_gerber(text):
        return "gerber"
    if looks_like_dxf(text):
        return "dxf"
    if looks_like_gcode(text):
        return "gcode"
    if looks_like_excellon(text):   # after G-code: its sniffer refuses Excellon lines
        return "excellon"
    return None


def is_drill_file(path: str | os.PathLike) -> bool:
    """True if `path` is a readable text file that holds Excellon (drill or route)."""
    try:
        data = read_bytes(path)
    except GalileoError:
        return False
    if data.startswith(BINARY_SENTINEL) or first_binary_byte(data) is not None:
        return False
    return detect_format(decode(data[:65_536])) == "excellon"


def read_drill(path: str | os.PathLike, *, max_ops: int | None = None) -> DrillFile:
    """Read an Excellon drill or route file into a DrillFile; errors name file:line:col.
    `max_ops` bounds its holes and slots (readers/limits.py, $GALILEO_MAX_OPS)."""
    name = os.fsdecode(path)
    data = read_bytes(name)
    at = first_binary_byte(data)
    if at is not None:
        raise binary_error(name, data, at, ExcellonError)
    text = decode(data)
    del data
    fmt = detect_format(text)
    if fmt not in ("excellon", None):
        raise ExcellonError(SourcePos(name, 1, 1), f"this is a {fmt} file, not an Excellon "
                            "drill file (plot and info read it as it is)")
    return read_excellon(name, text, max_ops=max_ops)


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
    if fmt == "excellon":
        read_excellon(path, text, max_ops=max_ops)   # a malformed one names its line
        raise UnrecognisedFileError(
            SourcePos(os.fsdecode(path), 1, 1),
            "an Excellon drill file holds holes, not drawing: `galileo-cnc info` lists them "
            "and a board (with its copper) plots them as drill marks", text[:80])
    blank = len(text) - len(text.lstrip())
    line = text.count("\n", 0, blank) + 1
    raise UnrecognisedFileError(
        SourcePos(os.fsdecode(path), line, 1),
        ("the file is empty: " if not text.strip() else "")
        + "neither a Gerber RS-274X, a G-code nor a DXF file (Gerber starts with %FS/%MO/G04, "
        "G-code with G/M/N words, DXF with a 0/SECTION group)", text[blank:blank + 80])
