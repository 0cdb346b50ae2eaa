"""Repeated ink: what one pen would draw twice, drawn once.

Files draw some things twice with the same aperture: a KiCad zone outline runs out
to an island and back along the same line, two objects share a track or a pad and
each draws it, a path closes with a zero-length draw onto a corner it has just
drawn. Drawing a segment the pen has already drawn (or a dot where the pen already
passes) puts ink on no new point and costs drawing time; a second flash at a point
costs a lift. So, within one pen's pieces (pieces.py):

- a segment equal to one drawn before (a line between the same two points either
  way; an arc round the same centre between the same points the same way round,
  whichever way it is drawn) is left out, unless that would add a stroke and the
  segment is shorter than LIFT_NM (a lift costs more than drawing it again: see
  `_drop_repeats`);
- a dot (a zero-length line) is left out when the pen draws through that point
  anyway: a segment end of a kept segment, or a dot kept before;
- a flash at the point of a flash kept before is left out.

Exact integer nm only: nothing within a tolerance, so the pen covers exactly the same
points. The first of each (in the pieces' order) is kept; a path is cut where a
repeat is left out (the rest gets a MOVE to where it goes on), and chaining joins
what can be joined again.
"""

from __future__ import annotations

import math

from galileo_cnc.plan.order.pieces import CW, LINE, MOVE, Piece, Point, Row, with_kind
from galileo_cnc.program.ops import I, J, KIND, X, Y

#: a repeat at least this long is left out even where that adds a stroke: on the
#: reference machine a stroke costs a pen lift and lowering (2 x 300 steps at 5 mm/s,
#: 0.75 s) and some travel, about what drawing 5 mm at 5 mm/s takes
LIFT_NM = 5_000_000


def segment_key(start: Point, row: Row) -> tuple | None:
    """What the segment from `start` to `row` draws, the same whichever way it is
    drawn: ("L", a, b) with a <= b, ("A", centre, from, to) counter-clockwise; None
    for a dot."""
    end = (row[X], row[Y])
    if row[KIND] == LINE:
        if end == start:
            return None
        return ("L",) + ((start, end) if start <= end else (end, start))
    centre = (start[0] + row[I], start[1] + row[J])
    return ("A", centre) + ((end, start) if row[KIND] == CW else (start, end))


def drop_repeats(pieces: list[Piece]) -> list[Piece]:
    """The pieces without repeated segments, dots on drawn points and repeated
    flashes (see module doc); the same list when there are none."""
    seen: set[tuple] = set()
    kept: list[list[bool]] = []              # per path piece, per segment row
    repeats: list[tuple[list[bool], int, Point, Point]] = []
    degree: dict[Point, int] = {}
    parent: dict[Point, Point] = {}

    def find(p: Point) -> Point:
        while parent.setdefault(p, p) != p:
            parent[p] = parent[parent[p]]
            p = parent[p]
        return p

    for piece in pieces:
        flags: list[bool] = []
        if piece.is_path:
            here = piece.start
            for _index, row in piece.rows[1:]:
                key = segment_key(here, row)
                end = (row[X], row[Y])
                flags.append(True)               # dots: decided below
                if key is not None:
                    degree[here] = degree.get(here, 0) + 1
                    degree[end] = degree.get(end, 0) + 1
                    parent[find(here)] = find(end)
                    if key in seen:
                        repeats.append((flags, len(flags) - 1, here, end,
                                        segment_length_nm(here, row)))
                    seen.add(key)
                here = end
        kept.append(flags)
    _drop_repeats(repeats, degree, find)
    passed = set()                           # ends of the kept segments
    for piece, flags in zip(pieces, kept):
        if piece.is_path:
            here = piece.start
            for (_index, row), keep in zip(piece.rows[1:], flags):
                end = (row[X], row[Y])
                if keep and end != here or keep and row[KIND] != LINE:
                    passed.update((here, end))
                here = end
    dots: set[Point] = set()
    flashes: set[Point] = set()
    out: list[Piece] = []
    changed = False
    for piece, flags in zip(pieces, kept):
        if not piece.is_path:
            if piece.start in flashes:
                changed = True
            else:
                flashes.add(piece.start)
                out.append(piece)
            continue
        rows = piece.rows
        part: list[tuple[int, Row]] | None = [rows[0]]
        here = piece.start
        for r in range(1, len(rows)):
            row = rows[r][1]
            end = (row[X], row[Y])
            keep = flags[r - 1]
            if keep and end == here and row[KIND] == LINE:      # a dot
                keep = here not in passed and here not in dots
                dots.add(here)
            if keep:
                if part is None:
                    part = [with_kind(rows[r], MOVE, here)]
                part.append(rows[r])
            else:
                changed = True
                if part is not None and len(part) > 1:
                    out.append(Piece(part))
                part = None
            here = end
        if part is not None and len(part) > 1:
            out.append(Piece(part))
    return out if changed else pieces


def segment_length_nm(start: Point, row: Row) -> float:
    """A segment's length (float: only to choose what to leave out)."""
    end = (row[X], row[Y])
    if row[KIND] == LINE:
        return math.dist(start, end)
    radius = math.hypot(row[I], row[J])
    a0 = math.atan2(-row[J], -row[I])
    a1 = math.atan2(end[1] - start[1] - row[J], end[0] - start[0] - row[I])
    sweep = (a0 - a1 if row[KIND] == CW else a1 - a0) % (2 * math.pi)
    return radius * (sweep or 2 * math.pi)


def _drop_repeats(repeats, degree: dict[Point, int], find) -> None:
    """Leave out each repeat (flags[k] = False) unless that adds a stroke and the
    segment is shorter than LIFT_NM: a set of
    connected segments with 2n ends of odd degree is drawn in max(1, n) strokes
    (chains.py), and leaving out one copy of a segment flips the parity of both its
    ends. A zone outline's bridge out to an island and back is left once (its ends
    turn odd, the outline and island are still one stroke). Repeats are taken in
    file order; the points are exact, where chains.py joins within a step, so this
    counts strokes as chaining will, or a few more."""
    odd: dict[Point, int] = {}
    for p, d in degree.items():
        if d % 2:
            root = find(p)
            odd[root] = odd.get(root, 0) + 1
    for flags, k, a, b, length in repeats:
        root = find(a)
        if a == b:                               # a full circle: parity unchanged
            flags[k] = False
            continue
        before = odd.get(root, 0)
        after = before + (-1 if degree[a] % 2 else 1) + (-1 if degree[b] % 2 else 1)
        if max(1, after // 2) <= max(1, before // 2) or length >= LIFT_NM:
            flags[k] = False
            degree[a] -= 1
            degree[b] -= 1
            odd[root] = after
