"""A planned file as pen-plotter G-code: what `galileo-cnc convert` writes.

The seed's CAM program turned drawings into G-code for the plotter; this does the
same for any input, in the order the planner plots it (paths chained and ordered,
one pen at a time, the ink in ink mode) and with the offset applied, so the file
runs as it is on our machine and on a stock GRBL board:

- millimetres, absolute (G21 G90 G17), coordinates exact to the nanometre;
- the pen: M3 down, M5 up (a servo or a solenoid on the spindle output), a flash is
  a dot (M3 then M5 at the point);
- a pen change: pen up, `T<n>` with the pen named in a comment, then M0, which
  pauses GRBL until cycle start (our reader asks for the pen at the T word). Pens
  are numbered 1, 2, ... in the order they are first used (GRBL takes T up to 255;
  Gerber apertures go higher);
- one feed (F, mm/min) for drawing: the profile's.

Reading the output back with our G-code reader and planning it with offset none in
file order gives the same pen-down paths, step for step (tests/cli/test_convert.py).
"""

from __future__ import annotations

from typing import Iterator

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan.order.apertures import DRAWING_KINDS
from galileo_cnc.plan.pipeline import PlannedFile
from galileo_cnc.plan.planner import plotting_order
from galileo_cnc.program.ops import I, J, KIND, NM_PER_MM, NO_TOOL, TOOL, VALUE, X, Y, OpKind
from galileo_cnc.readers.gcode.writer import mm


def converted_gcode(planned: PlannedFile, config: MachineConfig) -> Iterator[str]:
    """The planned file as G-code lines, in plotting order (see the module doc)."""
    program, job = planned.plotted, planned.job
    ox, oy = planned.offset_nm
    rows, _grouped, _ordered = plotting_order(program, config, planned.offset_nm,
                                              group=job.grouped, optimize=job.ordered)
    source = " ".join(str(planned.artwork.program.source).split())
    yield f"; galileo-cnc convert of {source}"
    yield (f"; {planned.mode} mode, offset {mm(ox)}, {mm(oy)} mm subtracted"
           + (f", pens {', '.join(mm(w) for w in job.pens_nm)} mm" if job.pens_nm else ""))
    yield "G21 G90 G17"
    yield "M5"
    yield f"F{mm(round(config.feed_mm_s * 60 * NM_PER_MM))}"
    several_pens = len({row[TOOL] for _i, row in rows
                        if row[KIND] in DRAWING_KINDS and row[TOOL] != NO_TOOL}) > 1
    pen_numbers: dict[int, int] = {}
    aperture = pen = NO_TOOL
    down = False
    at: tuple[int, int] | None = None

    def lift() -> Iterator[str]:
        nonlocal down
        if down:
            yield "M5"
            down = False

    def lower() -> Iterator[str]:
        nonlocal down
        if not down:
            yield "M3"
            down = True

    for _index, row in rows:
        kind = row[KIND]
        if kind == OpKind.SELECT:
            aperture = row[TOOL]
            continue
        if kind in DRAWING_KINDS and row[TOOL] != NO_TOOL:
            aperture = row[TOOL]
        if several_pens and (kind in DRAWING_KINDS or kind == OpKind.PEN_DOWN) \
                and aperture != pen and aperture != NO_TOOL:
            yield from lift()
            number = pen_numbers.setdefault(aperture, len(pen_numbers) + 1)
            label = job.pen_labels.get(aperture, f"pen {number}")
            yield f"T{number} ; insert {label}"
            yield "M0"
            pen = aperture
        point = (row[X] - ox, row[Y] - oy)
        if kind == OpKind.MOVE:
            if point != at:
                yield from lift()
                yield f"G0 X{mm(point[0])} Y{mm(point[1])}"
            at = point
        elif kind == OpKind.LINE:
            yield from lower()
            yield f"G1 X{mm(point[0])} Y{mm(point[1])}"
            at = point
        elif kind in (OpKind.ARC_CW, OpKind.ARC_CCW):
            yield from lower()
            code = "G2" if kind == OpKind.ARC_CW else "G3"
            yield f"{code} X{mm(point[0])} Y{mm(point[1])} I{mm(row[I])} J{mm(row[J])}"
            at = point
        elif kind == OpKind.FLASH:
            yield from lift()
            if point != at:
                yield f"G0 X{mm(point[0])} Y{mm(point[1])}"
            yield "M3"
            yield "M5"
            at = point
        elif kind == OpKind.PEN_DOWN:
            yield from lower()           # as the planner: lowered here, a dot if no draw follows
        elif kind == OpKind.PEN_UP:
            yield from lift()
        elif kind == OpKind.FEED and row[VALUE] > 0:
            yield f"F{mm(row[VALUE] * 60)}"
        elif kind == OpKind.DWELL and row[VALUE] >= 0:
            yield f"G4 P{row[VALUE]}"
        # regions, polarity and markers draw nothing by themselves
    yield from lift()
    yield "M2"
