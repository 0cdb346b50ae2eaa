"""Paths in drawing units -> Program rows in integer nanometres.

A path is drawn as the G-code and Gerber readers draw: a MOVE (pen-up travel) to its
start, PEN_DOWN, then LINE / ARC_CW / ARC_CCW rows with the pen down. A path that
starts where the pen already is (within JOIN_NM) continues the stroke without a
MOVE, and one that ends there is drawn backwards, so chained outlines (a LINE, then
an ARC, ...) are drawn in one stroke. Each coordinate is converted once
(units.Scale.nm); arc centres are given relative to the row's actual start point.
"""

from __future__ import annotations

import math

from galileo_cnc.errors import SourcePos
from galileo_cnc.program.ops import NO_TOOL, OpKind, ProgramBuilder
from galileo_cnc.readers import limits
from galileo_cnc.readers.dxf import geometry as geo
from galileo_cnc.readers.dxf.errors import DxfError
from galileo_cnc.readers.dxf.scan import EntityLines
from galileo_cnc.readers.dxf.units import Scale

# Coordinates beyond this are refused (1000 km): far beyond any plotter, and every
# product the planner forms stays exact.
MAX_COORD_NM = 10**15
# A path whose start (or end) is this close to where the pen is continues the
# stroke: CAD endpoints computed from angles and written with few decimals miss
# each other by nanometres, and a pen lift there is wasted.
JOIN_NM = 1000

_MOVE, _LINE = int(OpKind.MOVE), int(OpKind.LINE)
_CW, _CCW = int(OpKind.ARC_CW), int(OpKind.ARC_CCW)
_PEN_DOWN = int(OpKind.PEN_DOWN)


class Emitter:
    def __init__(self, builder: ProgramBuilder, scale: Scale, source: str):
        self.out = builder
        self.scale = scale
        self.source = source
        self.at: tuple[int, int] | None = None  # where the pen is, nm
        self.pen_down = False
        self.line = 0
        self.vertex_lines: list[int] = []
        self.handle: str | None = None
        self.handles: dict[int, str] = {}  # first row of an entity's geometry -> its handle
        self.widths_noted: int | None = None
        self.paths = 0
        self.joined = 0
        self.max_ops = limits.MAX_OPS

    def entity(self, info: EntityLines | None, handle: str | None) -> None:
        """The entity whose paths follow (for the rows' lines and the handle map)."""
        self.line = info.line if info else 0
        self.vertex_lines = info.vertex_lines if info else []
        self.handle = handle

    def note_widths(self) -> None:
        if self.widths_noted is None:
            self.widths_noted = self.line

    def _nm(self, value: float) -> int:
        try:
            nm = self.scale.nm(value)
        except ValueError:
            raise DxfError(SourcePos(self.source, max(self.line, 1), 1),
                           f"coordinate {value} is not a number") from None
        if not -MAX_COORD_NM <= nm <= MAX_COORD_NM:
            raise DxfError(SourcePos(self.source, max(self.line, 1), 1),
                           f"coordinate {value} is out of range (more than 1000 km from the "
                           "origin)")
        return nm

    def _line_of(self, vertex: int) -> int:
        if 0 <= vertex < len(self.vertex_lines):
            return self.vertex_lines[vertex]
        return self.line

    def path(self, start: geo.Point, segments: list, dot: bool = False,
             start_vertex: int = -1) -> None:
        if not segments:
            return
        nm = self._nm
        sx, sy = nm(start[0]), nm(start[1])
        converted = []
        px, py = start  # the float start of each segment
        qx, qy = sx, sy
        for kind, x, y, cx, cy, vertex in segments:
            ex, ey = nm(x), nm(y)
            if kind == geo.LINE:
                converted.append((kind, ex, ey, 0, 0, vertex))
            else:
                ncx, ncy = nm(cx), nm(cy)
                if kind & geo.FULL:
                    ex, ey = qx, qy
                elif (ex, ey) == (qx, qy) and _sweep(px, py, x, y, cx, cy, kind) > math.pi:
                    kind |= geo.FULL  # a chord below a nanometre on the long way round
                converted.append((kind, ex, ey, ncx, ncy, vertex))
            px, py, qx, qy = x, y, ex, ey
        start_nm = (sx, sy)
        end_nm = (converted[-1][1], converted[-1][2])
        at = self.at
        if at is not None and self.pen_down and not dot:
            if _near(at, start_nm):
                self.joined += 1
            elif _near(at, end_nm):
                start_nm, converted = geo.reverse(start_nm, converted)
                self.joined += 1
            else:
                at = None
        else:
            at = None
        rows = []
        here = start_nm if at is None else at
        for kind, x, y, cx, cy, vertex in converted:
            line = self._line_of(vertex)
            if kind == geo.LINE:
                if (x, y) != here or dot:
                    rows.append((_LINE, x, y, 0, 0, line))
                    here = (x, y)
                continue
            if kind & geo.FULL:
                x, y = here
            elif (x, y) == here:
                continue  # an arc shorter than a nanometre
            i, j = cx - here[0], cy - here[1]
            if i == 0 and j == 0:
                rows.append((_LINE, x, y, 0, 0, line))  # a radius below a nanometre
            else:
                rows.append((_CW if kind & 3 == geo.CW else _CCW, x, y, i, j, line))
            here = (x, y)
        if not rows:
            return  # nothing to draw (a zero-length line)
        first = self.out.count()
        emit = self.out.emit
        if at is None:
            line = self._line_of(start_vertex)
            emit(_MOVE, start_nm[0], start_nm[1], 0, 0, NO_TOOL, 0, line, 1)
            emit(_PEN_DOWN, 0, 0, 0, 0, NO_TOOL, 0, line, 1)
        for kind, x, y, i, j, line in rows:
            emit(kind, x, y, i, j, NO_TOOL, 0, line, 1)
        if self.out.count() > self.max_ops:
            raise DxfError(SourcePos(self.source, max(self.line, 1), 1),
                           limits.ops_message(self.max_ops, "by this entity the drawing makes"))
        self.paths += 1
        if self.handle:
            self.handles.setdefault(first, self.handle)
        self.at = here
        self.pen_down = True


def _near(a: tuple[int, int], b: tuple[int, int]) -> bool:
    return abs(a[0] - b[0]) <= JOIN_NM and abs(a[1] - b[1]) <= JOIN_NM


def _sweep(px: float, py: float, x: float, y: float, cx: float, cy: float, kind: int) -> float:
    """The angle an arc turns from (px, py) to (x, y) about (cx, cy), in [0, 2 pi)."""
    a0 = math.atan2(py - cy, px - cx)
    a1 = math.atan2(y - cy, x - cx)
    turn = (a1 - a0) % math.tau
    return turn if kind & 3 == geo.CCW else (math.tau - turn) % math.tau
