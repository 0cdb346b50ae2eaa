"""Pen pieces: what path order moves about, and how a piece is drawn backwards.

A piece is a pen path (a MOVE to its start, then LINE/ARC rows) or a flash (a
point). Rows that draw nothing are dropped: the planner ignores them. Reversal
keeps the geometry exactly: the rows are walked backwards, each segment ends where
it began, and an arc swaps its direction and takes its centre relative to its new
start (same centre, integer nm).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind

MOVE, LINE = int(OpKind.MOVE), int(OpKind.LINE)
CW, CCW, FLASH = int(OpKind.ARC_CW), int(OpKind.ARC_CCW), int(OpKind.FLASH)
SEGMENTS = (LINE, CW, CCW)

Row = list[int]
Point = tuple[int, int]

#: Program metadata key: [first, end) op ranges, each one path that is a whole stroke
#: already (the ink's fill walks): path order moves and reverses it, but does not cut
#: it at repeats or junctions to chain it again (paths.py).
WHOLE_PATHS = "whole_paths"


@dataclass
class Piece:
    """Rows (op index, row) that draw without a lift: [MOVE, segments...] or [FLASH]."""

    rows: list[tuple[int, Row]] = field(default_factory=list)

    @property
    def start(self) -> Point:
        row = self.rows[0][1]
        return (row[X], row[Y])

    @property
    def end(self) -> Point:
        row = self.rows[-1][1]
        return (row[X], row[Y])

    @property
    def is_path(self) -> bool:
        """A pen path (MOVE-led), which can join others; else a flash (a point)."""
        return self.rows[0][1][KIND] == MOVE

    def reversed(self) -> "Piece":
        """The same path drawn from its end to its start (a flash is its own reverse)."""
        if not self.is_path:
            return self
        points = [(row[X], row[Y]) for _i, row in self.rows]
        out = [with_kind(self.rows[-1], kind=MOVE, to=points[-1])]
        for k in range(len(self.rows) - 1, 0, -1):
            index, row = self.rows[k]
            back = list(row)
            back[X], back[Y] = points[k - 1]
            if row[KIND] in (CW, CCW):
                centre = (points[k - 1][0] + row[I], points[k - 1][1] + row[J])
                back[KIND] = CCW if row[KIND] == CW else CW
                back[I], back[J] = centre[0] - points[k][0], centre[1] - points[k][1]
            out.append((index, back))
        return Piece(out)


def with_kind(entry: tuple[int, Row], kind: int, to: Point) -> tuple[int, Row]:
    index, row = entry
    new = list(row)
    new[KIND], new[X], new[Y] = kind, to[0], to[1]
    new[I] = new[J] = 0
    return (index, new)


def cut_pieces(rows: list[tuple[int, Row]], start: Point) -> list[Piece]:
    """Pieces of rows in plotting order; a path that does not begin with a MOVE gets
    one to where the head was, so it draws what it drew in order."""
    pieces: list[Piece] = []
    current: Piece | None = None
    point = start
    for index, row in rows:
        kind = row[KIND]
        if kind == MOVE:
            current = Piece([(index, list(row))])
            pieces.append(current)
        elif kind == FLASH:
            pieces.append(Piece([(index, list(row))]))
            current = None
        elif kind in SEGMENTS:
            if current is None:
                current = Piece([with_kind((index, row), MOVE, point)])
                pieces.append(current)
            current.rows.append((index, list(row)))
        else:
            continue                         # markers and selects draw nothing
        point = (row[X], row[Y])
    return [p for p in pieces if len(p.rows) > 1 or p.rows[0][1][KIND] == FLASH]
