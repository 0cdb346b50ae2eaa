"""Write a Program as G-code that reads back to the same ops.

The output is plain GRBL-style G-code: millimetres (G21), absolute (G90), each
coordinate with up to 6 decimals so every nanometre value is exact, one op per
line. `read_gcode(write_gcode(p))` gives p's op table back (line and column
aside) for any program the G-code reader could have produced; docs/gcode.md
lists the few op sequences that need care and how they are written.
"""

from __future__ import annotations

from typing import Iterator

from galileo_cnc.errors import GalileoError, SourcePos
from galileo_cnc.program.describe import describe_op
from galileo_cnc.readers.gcode.lexer import scaled
from galileo_cnc.program.ops import (COL, I, J, KIND, LINE, NM_PER_MM, NO_TOOL, TOOL, VALUE,
                                     X, Y, OpKind, Program)


class GcodeExportError(GalileoError):
    """A Program holds an op that G-code cannot express (flash, region, polarity)."""

    def __init__(self, pos: SourcePos, message: str):
        self.pos = pos
        self.message = message
        super().__init__(f"{pos}: {message}")


def write_gcode(program: Program) -> str:
    """The program as G-code text (newline-terminated lines)."""
    return "".join(line + "\n" for line in gcode_lines(program))


def gcode_lines(program: Program) -> Iterator[str]:
    """The program as G-code, one line at a time (for streaming large plans)."""
    source = " ".join(str(program.source).split())  # no line breaks inside the comment
    yield f"; written by galileo-cnc from {source}"
    yield "G21 G90 G17"
    home_rows = set(program.metadata.get("home_rows", ()))
    pen_wanted = pen_down = False  # mirrors the reader: see reader._resume_pen
    tool = NO_TOOL
    for index, row in enumerate(program.table.tolist()):
        kind = row[KIND]
        if kind == OpKind.MOVE:
            if index in home_rows and row[X] == 0 and row[Y] == 0:
                yield "G28"
                pen_wanted = False  # homing Z lifts the pen for good
            else:
                yield f"G0 X{mm(row[X])} Y{mm(row[Y])}"
            pen_down = False
        elif kind in (OpKind.LINE, OpKind.ARC_CW, OpKind.ARC_CCW):
            if row[TOOL] != tool and row[TOOL] != NO_TOOL:
                tool = row[TOOL]
                yield f"T{tool} M6"
            if pen_wanted and not pen_down:
                # The reader would lower the pen again after a travel; this op
                # is drawn with the pen up, so say that the file wants it up.
                yield "G0 Z1 ; the pen stays up after the travel"
                pen_wanted = False
            if kind == OpKind.LINE:
                yield f"G1 X{mm(row[X])} Y{mm(row[Y])}"
            else:
                code = "G2" if kind == OpKind.ARC_CW else "G3"
                yield f"{code} X{mm(row[X])} Y{mm(row[Y])} I{mm(row[I])} J{mm(row[J])}"
        elif kind == OpKind.PEN_DOWN:
            pen_wanted = pen_down = True
            yield "M3"
        elif kind == OpKind.PEN_UP:
            pen_wanted = pen_down = False
            yield "M5"
        elif kind == OpKind.SELECT:
            if row[TOOL] < 0:
                raise _refuse(program, row, "a pen selection needs a pen number of 0 or more")
            tool = row[TOOL]
            yield f"T{tool} M6"
        elif kind == OpKind.DWELL:
            if row[VALUE] < 0:
                raise _refuse(program, row, "a dwell cannot be negative")
            yield f"G4 P{row[VALUE]}"
        elif kind == OpKind.FEED:
            if row[VALUE] <= 0:
                raise _refuse(program, row, "a feed rate must be positive")
            yield f"F{feed_text(row[VALUE])}"
        else:
            raise _refuse(program, row, f"{describe_op(program, index)}: G-code has no such "
                          "thing")
    yield "M2"


def feed_text(nm_per_s: int) -> str:
    """A feed (nm/s) as the shortest mm/min text this reader reads back to the same
    nm/s: 1666667 nm/s (F100 read) -> '100', not '100.00002'."""
    for decimals in range(7):
        text = f"{nm_per_s * 60 / NM_PER_MM:.{decimals}f}"
        if scaled(text, NM_PER_MM, 60) == nm_per_s:
            return text
    return mm(nm_per_s * 60)            # exact, when no shorter text reads back


def mm(nm: int) -> str:
    """Integer nanometres as exact millimetre text: 1500000 -> '1.5', -1 -> '-0.000001'."""
    whole, fraction = divmod(abs(nm), NM_PER_MM)
    sign = "-" if nm < 0 else ""
    if fraction == 0:
        return f"{sign}{whole}"
    return f"{sign}{whole}.{fraction:06d}".rstrip("0")


def _refuse(program: Program, row: list, message: str) -> GcodeExportError:
    return GcodeExportError(SourcePos(program.source, row[LINE], row[COL]), message)
