"""Path order, the public entry: chain pen paths whose ends meet and order them to cut
pen-up travel.

The seed's CAM aligned DXF entities so each started where the last one ended
(reversing where needed); `optimize` does that for every format's pieces of one pen:

1. **pieces** (pieces.py): pen paths and flashes, each drawable backwards with
   the same geometry; what the pen would draw twice (a segment, a dot where the pen
   passes anyway, a flash) is drawn once (repeats.py);
2. **chains** (chains.py): paths whose ends meet within `join_nm` joined into as
   few strokes as the ends allow (Euler trails), a short stretch drawn twice where
   that saves a lift (retrace.py);
3. **order** (here): a shortest open path from the head's position over the chain ends
   (either end first: a chain may be drawn reversed), exact up to EXACT chains, else
   the local search of tour.py (spatial queries in nearby.py). With a goal (where the
   next pen's work is) the path's end is charged its distance from there.

Everything stays in integer nm; travel is compared as Euclidean distances in float
only to choose, never to place.
"""

from __future__ import annotations

import math

from galileo_cnc.plan.order.chains import chain
from galileo_cnc.plan.collector import collector_paused
from galileo_cnc.plan.order.nearby import distances_to
from galileo_cnc.plan.order.pieces import Piece, Point, Row, cut_pieces
from galileo_cnc.plan.order.repeats import drop_repeats
from galileo_cnc.plan.order.tour import PERTURB_MAX, PERTURB_PER_CHAIN, Tour
from galileo_cnc.program.ops import X, Y

__all__ = ["EXACT", "TWO_OPT_MOVES", "Piece", "chain", "cut_pieces", "optimize", "order",
           "travel_nm"]

#: moves tried per group at most (one candidate end examined by the local search or
#: the perturbation is one): a count, not a time, so that planning the same file twice
#: gives the same job (resume replans and continues by command index)
TWO_OPT_MOVES = 2_000_000
#: chains up to which the order is searched exhaustively (the shortest there is)
EXACT = 8


def order(chains: list[Piece], start: Point, moves: int = TWO_OPT_MOVES,
          goal: list[Point] | None = None) -> tuple[list[Piece], Point]:
    """Chains in drawing order from `start` (greedy, then 2-opt, Or-opt and
    perturbation within `moves` moves tried); and where the head ends. With `goal`
    (the points where the work after these chains may start) the order is the
    shortest counting the travel from its end to the nearest goal point: a pen's
    work then ends near the next pen's instead of wherever it was shortest alone."""
    if not chains:
        return [], start
    # node 0 is the start, node 1 the free end (mates); chain c's ends are 2c+2, 2c+3
    xs = [float(start[0]), 0.0]
    ys = [float(start[1]), 0.0]
    for c in chains:
        xs += [float(c.start[0]), float(c.end[0])]
        ys += [float(c.start[1]), float(c.end[1])]
    # each node's distance on to the goal: node 1, the free end, stands for it
    tail = [0.0, 0.0] + distances_to(xs[2:], ys[2:], goal) if goal else None
    if len(chains) <= EXACT:
        entries = _exact(xs, ys, tail)
    else:
        tour = Tour(xs, ys, tail)
        tour.build()
        tour.search(moves, min(PERTURB_MAX, PERTURB_PER_CHAIN * len(chains)))
        entries = tour.walk()
    out = []
    for v in entries:
        c = chains[(v - 2) >> 1]
        out.append(c if v % 2 == 0 else c.reversed())
    return out, (out[-1].end if out else start)


def _exact(xs: list[float], ys: list[float], tail: list[float] | None) -> list[int]:
    """The shortest order for a few chains (dynamic programming over the sets of
    chains drawn and the end left at), `tail[v]` added for ending at node v: the
    chain ends entered, in order."""
    n = (len(xs) - 2) // 2

    def dist(a: int, b: int) -> float:
        dx = xs[a] - xs[b]
        dy = ys[a] - ys[b]
        return math.sqrt(dx * dx + dy * dy)

    best: dict[tuple[int, int], tuple[float, tuple[int, int] | None, int]] = {}
    for c in range(n):
        for entry in (2 * c + 2, 2 * c + 3):
            best[(1 << c, entry ^ 1)] = (dist(0, entry), None, entry)
    for mask in range(1, 1 << n):
        for c in range(n):
            for leave in (2 * c + 2, 2 * c + 3):
                state = best.get((mask, leave))
                if state is None:
                    continue
                for c2 in range(n):
                    if mask >> c2 & 1:
                        continue
                    for entry in (2 * c2 + 2, 2 * c2 + 3):
                        key = (mask | 1 << c2, entry ^ 1)
                        cost = state[0] + dist(leave, entry)
                        if key not in best or cost < best[key][0]:
                            best[key] = (cost, (mask, leave), entry)
    full = (1 << n) - 1
    key: tuple[int, int] | None = min(
        ((full, leave) for c in range(n) for leave in (2 * c + 2, 2 * c + 3)),
        key=lambda k: best[k][0] + (tail[k[1]] if tail else 0.0))
    entries = []
    while key is not None:
        _cost, before, entry = best[key]
        entries.append(entry)
        key = before
    return entries[::-1]


def travel_nm(tour: list[Piece], start: Point) -> float:
    """Pen-up travel of drawing `tour` from `start` (nm)."""
    total, here = 0.0, start
    for c in tour:
        total += math.dist(here, c.start)
        here = c.end
    return total


def optimize(rows: list[tuple[int, Row]], start: Point, join_nm: int,
             moves: int = TWO_OPT_MOVES, goal: list[Point] | None = None,
             whole: frozenset[int] = frozenset()) -> tuple[list[tuple[int, Row]], Point]:
    """Rows of one pen in an order that draws the same ink with less pen-up travel
    (what the pen would draw twice drawn once: repeats.py), ending, with `goal`,
    near where the next pen's work starts (see `order`). A path whose MOVE's op index
    is in `whole` is a stroke already (pieces.WHOLE_PATHS): it is ordered as it is."""
    with collector_paused():
        pieces = cut_pieces(rows, start)
        kept = [p for p in pieces if p.rows[0][0] in whole]
        others = [p for p in pieces if p.rows[0][0] not in whole]
        if kept and others:
            # a whole path that another piece touches (a centre line ending on a
            # pad's walk) is chained with it as any path is: one stroke may draw both
            near = touching(kept, others, join_nm)
            others += [p for p, hit in zip(kept, near) if hit]
            kept = [p for p, hit in zip(kept, near) if not hit]
        chains = chain(drop_repeats(others), join_nm) if others else []
        if kept:      # in the file's order, as chain() leaves its chains
            chains = sorted(kept + chains, key=lambda c: min(i for i, _row in c.rows))
        tour, end = order(chains, start, moves, goal)
        return [entry for c in tour for entry in c.rows], end


def touching(paths: list[Piece], others: list[Piece], join_nm: int) -> list[bool]:
    """For each of `paths`, whether one of its vertices may lie within `join_nm` of a
    vertex of `others` (flashes included): both in one cell of a join_nm grid or in
    neighbouring ones. Never false where chaining or repeats could join them; now
    and then true where they could not (two cells apart diagonally)."""
    cell = max(join_nm, 1)
    near: set[tuple[int, int]] = set()
    for piece in others:
        for _index, row in piece.rows:
            cx, cy = row[X] // cell, row[Y] // cell
            near.update((cx + dx, cy + dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1))
    return [any((row[X] // cell, row[Y] // cell) in near for _index, row in p.rows)
            for p in paths]
