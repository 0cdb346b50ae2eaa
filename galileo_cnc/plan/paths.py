"""Path order: chain pen paths whose ends meet and order them to cut pen-up travel.

The seed's CAM aligned DXF entities so each started where the last one ended
(reversing where needed); this does that for every format's pieces, then orders
the chains:

1. **Pieces.** A piece is a pen path (a MOVE to its start, then LINE/ARC rows) or a
   flash (a point). Rows that draw nothing are dropped: the planner ignores them.
2. **Reversal** keeps the geometry exactly: the rows are walked backwards, each
   segment ends where it began, and an arc swaps its direction and takes its
   centre relative to its new start (same centre, integer nm).
3. **Chaining.** A path whose start (or end, reversed) lies within `join_nm` (one
   step) of a chain's end continues that chain without a lift; the first row of
   the joined path keeps its own end point, and an arc keeps its centre.
4. **Ordering.** Nearest neighbour from the machine's position over a grid of chain
   ends (either end of a reversible chain), then 2-opt moves (reversing a run of
   chains, each flipped) while they shorten the travel, bounded by a count of moves
   tried (not a time: the same file must plan to the same job for resume).

Everything stays in integer nm; travel is compared as squared or Euclidean
distances in float only to choose, never to place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind

_MOVE, _LINE = int(OpKind.MOVE), int(OpKind.LINE)
_CW, _CCW, _FLASH = int(OpKind.ARC_CW), int(OpKind.ARC_CCW), int(OpKind.FLASH)
_SEGMENTS = (_LINE, _CW, _CCW)
#: 2-opt moves tried per group at most: a count, not a time, so that planning the same
#: file twice gives the same job (resume replans and continues by command index)
TWO_OPT_MOVES = 2_000_000

Row = list[int]
Point = tuple[int, int]


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
        return self.rows[0][1][KIND] == _MOVE

    def reversed(self) -> "Piece":
        """The same path drawn from its end to its start (a flash is its own reverse)."""
        if not self.is_path:
            return self
        points = [(row[X], row[Y]) for _i, row in self.rows]
        out = [_with(self.rows[-1], kind=_MOVE, to=points[-1])]
        for k in range(len(self.rows) - 1, 0, -1):
            index, row = self.rows[k]
            back = list(row)
            back[X], back[Y] = points[k - 1]
            if row[KIND] in (_CW, _CCW):
                centre = (points[k - 1][0] + row[I], points[k - 1][1] + row[J])
                back[KIND] = _CCW if row[KIND] == _CW else _CW
                back[I], back[J] = centre[0] - points[k][0], centre[1] - points[k][1]
            out.append((index, back))
        return Piece(out)


def _with(entry: tuple[int, Row], kind: int, to: Point) -> tuple[int, Row]:
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
        if kind == _MOVE:
            current = Piece([(index, list(row))])
            pieces.append(current)
        elif kind == _FLASH:
            pieces.append(Piece([(index, list(row))]))
            current = None
        elif kind in _SEGMENTS:
            if current is None:
                current = Piece([_with((index, row), _MOVE, point)])
                pieces.append(current)
            current.rows.append((index, list(row)))
        else:
            continue                         # markers and selects draw nothing
        point = (row[X], row[Y])
    return [p for p in pieces if len(p.rows) > 1 or p.rows[0][1][KIND] == _FLASH]


def chain(pieces: list[Piece], join_nm: int) -> list[Piece]:
    """Join paths whose ends meet within `join_nm` into chains (seed: entity alignment)."""
    cell = max(join_nm, 1)
    ends: dict[tuple[int, int], set[int]] = {}      # grid cell -> piece ids (either end)

    def key(p: Point) -> tuple[int, int]:
        return (p[0] // cell, p[1] // cell)

    def add(pid: int) -> None:
        for point in (pieces[pid].start, pieces[pid].end):
            ends.setdefault(key(point), set()).add(pid)

    def remove(pid: int) -> None:
        for point in (pieces[pid].start, pieces[pid].end):
            ends.get(key(point), set()).discard(pid)

    def partner(point: Point) -> tuple[int, bool] | None:
        """A free path with an end within join_nm of `point`: (id, reverse it)."""
        kx, ky = key(point)
        best = None
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for pid in ends.get((kx + dx, ky + dy), ()):
                    for flip, end in ((False, pieces[pid].start), (True, pieces[pid].end)):
                        gap = math.dist(point, end)
                        if gap <= join_nm and (best is None or (gap, pid) < best[0]):
                            best = ((gap, pid), pid, flip)
        return None if best is None else (best[1], best[2])

    for pid, piece in enumerate(pieces):
        if piece.is_path:
            add(pid)
    chains: list[Piece] = []
    for pid, piece in enumerate(pieces):
        if not piece.is_path:
            chains.append(piece)
            continue
        if pid not in ends.get(key(piece.start), ()):
            continue                                   # already in a chain
        remove(pid)
        current = piece
        for _direction in range(2):                    # forward, then from the start
            while (found := partner(current.end)) is not None:
                other, flip = found
                remove(other)
                current = _join(current, pieces[other].reversed() if flip else pieces[other])
            current = current.reversed()
        chains.append(current)
    return chains


def _join(first: Piece, then: Piece) -> Piece:
    """`then` drawn on from `first`'s end without its MOVE; an arc keeps its centre."""
    gap = (then.start[0] - first.end[0], then.start[1] - first.end[1])
    rows = list(then.rows[1:])
    index, row = rows[0]
    if row[KIND] in (_CW, _CCW) and gap != (0, 0):
        row = list(row)
        row[I], row[J] = row[I] + gap[0], row[J] + gap[1]
        rows[0] = (index, row)
    return Piece(first.rows + rows)


def order(chains: list[Piece], start: Point,
          moves: int = TWO_OPT_MOVES) -> tuple[list[Piece], Point]:
    """Chains in drawing order from `start` (nearest neighbour, then 2-opt); and where
    the head ends."""
    tour = _nearest_neighbour(chains, start)
    tour = _two_opt(tour, start, moves)
    return tour, (tour[-1].end if tour else start)


def _nearest_neighbour(chains: list[Piece], start: Point) -> list[Piece]:
    if not chains:
        return []
    # cells sized to the box of every end and the start, so the ring search from the
    # start reaches the chains in a few rings (a 1 nm cell once spun for minutes)
    xs = [p[0] for c in chains for p in (c.start, c.end)] + [start[0]]
    ys = [p[1] for c in chains for p in (c.start, c.end)] + [start[1]]
    span = max(max(xs) - min(xs), max(ys) - min(ys), 1)
    cell = max(span // max(int(math.sqrt(len(chains))), 1), 1)
    grid: dict[tuple[int, int], set[int]] = {}
    for cid, c in enumerate(chains):
        for point in ((c.start, c.end) if c.is_path else (c.start,)):
            grid.setdefault((point[0] // cell, point[1] // cell), set()).add(cid)
    left, tour, here = set(range(len(chains))), [], start
    while left:
        cid, flip = _closest(grid, chains, here, cell)
        left.discard(cid)
        c = chains[cid]
        for point in (c.start, c.end):
            grid.get((point[0] // cell, point[1] // cell), set()).discard(cid)
        c = c.reversed() if flip else c
        tour.append(c)
        here = c.end
    return tour


def _closest(grid, chains, here: Point, cell: int) -> tuple[int, bool]:
    """Nearest free chain end to `here`: search rings of cells until the best found
    is closer than any unsearched ring can be (the caller has chains left, so the
    rings reach one)."""
    hx, hy = here[0] // cell, here[1] // cell
    best: tuple[float, int, bool] | None = None
    ring = 0
    while True:
        for gx in range(hx - ring, hx + ring + 1):
            for gy in range(hy - ring, hy + ring + 1):
                if max(abs(gx - hx), abs(gy - hy)) != ring:
                    continue
                for cid in grid.get((gx, gy), ()):
                    c = chains[cid]
                    ends = ((c.start, False), (c.end, True)) if c.is_path else ((c.start, False),)
                    for point, flip in ends:
                        d = math.dist(here, point)
                        if best is None or (d, cid) < best[:2]:
                            best = (d, cid, flip)
        if best is not None and best[0] <= ring * cell:
            return best[1], best[2]
        ring += 1


def _two_opt(tour: list[Piece], start: Point, moves: int) -> list[Piece]:
    """Reverse runs of chains (each flipped) while that shortens the travel, trying at
    most `moves` reversals in all (deterministic: the same input, the same order)."""
    n = len(tour)
    if n < 3:
        return tour
    improved = True
    while improved and moves > 0:
        improved = False
        for a in range(n - 1):
            if moves <= 0:
                break
            moves -= n - a - 1
            before = tour[a - 1].end if a else start
            for b in range(a + 1, n):
                after = tour[b + 1].start if b + 1 < n else None
                old = math.dist(before, tour[a].start) + (
                    math.dist(tour[b].end, after) if after else 0.0)
                new = math.dist(before, tour[b].end) + (
                    math.dist(tour[a].start, after) if after else 0.0)
                if new + 1e-6 < old:
                    tour[a:b + 1] = [c.reversed() for c in reversed(tour[a:b + 1])]
                    improved = True
    return tour


def travel_nm(tour: list[Piece], start: Point) -> float:
    """Pen-up travel of drawing `tour` from `start` (nm)."""
    total, here = 0.0, start
    for c in tour:
        total += math.dist(here, c.start)
        here = c.end
    return total


def optimise(rows: list[tuple[int, Row]], start: Point, join_nm: int,
             moves: int = TWO_OPT_MOVES) -> tuple[list[tuple[int, Row]], Point]:
    """Rows of one pen in an order that draws the same with less pen-up travel."""
    chains = chain(cut_pieces(rows, start), join_nm)
    tour, end = order(chains, start, moves)
    return [entry for c in tour for entry in c.rows], end
