"""One op of a Program in words and millimetres, for messages a user reads.

A refusal names what the file asked for ("the counter-clockwise arc from X 195 Y 10
to X 195 Y 30 mm (centre X 195 Y 20, file coordinates)"), not the op's internal kind
and index (`ARC_CCW (op 7)`); the message's position names the file line.
"""

from __future__ import annotations

import numpy as np

from galileo_cnc.program.ops import (KIND, NM_PER_MM, POSITIONED_KINDS, TOOL, VALUE, I, J, OpKind,
                                     Program, X, Y)

_WHERE = "file coordinates"


def mm_text(nm: int) -> str:
    """Nanometres as millimetres with at most 4 decimals and no trailing zeros: '12.5'."""
    text = f"{nm / NM_PER_MM:.4f}".rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def _point(x_nm: int, y_nm: int) -> str:
    return f"X {mm_text(x_nm)} Y {mm_text(y_nm)}"


def _start(table: np.ndarray, index: int) -> tuple[int, int] | None:
    """Where the pen is before row `index`: the last positioned row's point, if any."""
    before = np.flatnonzero(np.isin(table[:index, KIND], POSITIONED_KINDS))
    if not len(before):
        return None
    row = table[before[-1]]
    return int(row[X]), int(row[Y])


def _tool(program: Program, tool: int) -> str:
    aperture = program.apertures.get(tool)
    if program.format == "gerber":
        return f"D{tool & 0xFFFFFFFF}" + (f" ({aperture.describe()})" if aperture else "")
    return f"pen {tool}"


def describe_op(program: Program, index: int) -> str:
    """What row `index` of the program does, in words and mm (file coordinates)."""
    row = program.table[index]
    kind = OpKind(int(row[KIND]))
    x, y = int(row[X]), int(row[Y])
    if kind in (OpKind.LINE, OpKind.ARC_CW, OpKind.ARC_CCW):
        start = _start(program.table, index)
        origin = _point(*start) if start is not None else "where the pen was"
        if kind == OpKind.LINE:
            return f"the line from {origin} to {_point(x, y)} mm ({_WHERE})"
        turn = "clockwise" if kind == OpKind.ARC_CW else "counter-clockwise"
        centre = ""
        if start is not None:
            centre = f"centre {_point(start[0] + int(row[I]), start[1] + int(row[J]))}, "
        return f"the {turn} arc from {origin} to {_point(x, y)} mm ({centre}{_WHERE})"
    if kind == OpKind.MOVE:
        return f"the pen-up move to {_point(x, y)} mm ({_WHERE})"
    if kind == OpKind.FLASH:
        return f"the flash of {_tool(program, int(row[TOOL]))} at {_point(x, y)} mm ({_WHERE})"
    if kind == OpKind.PEN_DOWN:
        return f"lowering the pen at {_point(x, y)} mm ({_WHERE})"
    if kind == OpKind.PEN_UP:
        return "lifting the pen"
    if kind == OpKind.SELECT:
        return f"the change to {_tool(program, int(row[TOOL]))}"
    if kind == OpKind.DWELL:
        return f"a pause of {int(row[VALUE])} ms"
    if kind == OpKind.FEED:
        per_s = int(row[VALUE])
        return f"the feed of {mm_text(per_s)} mm/s ({mm_text(per_s * 60)} mm/min)"
    return {OpKind.REGION_BEGIN: "the start of a filled region (G36)",
            OpKind.REGION_END: "the end of a filled region (G37)",
            OpKind.POLARITY: "a polarity change (%LP)"}[kind]
