"""Path order for the ink, worked out from the walks' ends while their arcs are fitted.

Path order (plan/order/paths.py) moves and reverses each fill walk whole
(pieces.WHOLE_PATHS): what it decides depends on a walk's two ends, its place in the
rows and, for the last pen, whether a vertex of it lies near a centre line
(paths.touching). It never looks inside a walk that touches nothing. So the order can be
worked out on a *skeleton* of the ink, each such walk two rows (a MOVE to its start, a
LINE to its end), in a forked process while this one fits the walks' arcs (arcs.py: a
second of CPU on the largest layers), and then be spelled out with the walks' real rows.
The answer is the order `optimized_order` gives on the real rows, row for row:

- a walk keeps its rows in the skeleton (arcs fitted first) where any of its polyline
  vertices is near a centre line: its rows' ends are some of those vertices, so a walk
  the skeleton shortens cannot touch one in the real rows either;
- the skeleton's rows come in the real rows' order, so every sort by op index (file
  order among whole paths, chains' first rows) sorts the same;
- a shortened walk comes back forward (its MOVE first) or reversed (its LINE's index
  first, as Piece.reversed leaves it), and is written out as its real rows or their
  reverse (`reversed_table`, the same rows as Piece.reversed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from galileo_cnc.plan.ink.background import Deferred
from galileo_cnc.plan.order.apertures import OrderedRows, drawing_apertures, optimized_order
from galileo_cnc.plan.order.links import LINK_AREAS, linked_moves
from galileo_cnc.plan.order.pieces import WHOLE_PATHS
from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind, Program

_MOVE, _CW, _CCW = int(OpKind.MOVE), int(OpKind.ARC_CW), int(OpKind.ARC_CCW)
_LINE = int(OpKind.LINE)
Row = list[int]


def touching_walks(paths: list[np.ndarray], others: np.ndarray, join_nm: int) -> np.ndarray:
    """For each walk (an (n, 2) polyline), whether a vertex of it lies in a cell of the
    join_nm grid next to (or at) a point of `others` ((m, 2): the centre lines' row
    points): paths.touching's test, on every vertex of the polyline."""
    if not len(paths) or not len(others):
        return np.zeros(len(paths), dtype=bool)
    cell = max(join_nm, 1)
    near_cells = others // cell
    shifts = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)], dtype=np.int64)
    near = _cell_keys((near_cells[:, None, :] + shifts[None, :, :]).reshape(-1, 2))
    vertices = np.concatenate(paths)
    hit = np.isin(_cell_keys(vertices // cell), near)
    owner = np.repeat(np.arange(len(paths)), [len(p) for p in paths])
    touched = np.zeros(len(paths), dtype=bool)
    touched[owner[hit]] = True
    return touched


def _cell_keys(cells: np.ndarray) -> np.ndarray:
    """One int64 per (cx, cy) cell (cells of a board within +-2^31 of the origin)."""
    return (cells[:, 0] << 32) + (cells[:, 1] & 0xFFFFFFFF)


def reversed_table(table: np.ndarray, first: int) -> tuple[np.ndarray, np.ndarray]:
    """Piece.reversed for a path of rows table[0:n] (MOVE, then segments) whose first
    op index is `first`: the same op indices and rows, worked out at once, as arrays."""
    n = len(table)
    head = table[n - 1].copy()
    head[KIND] = _MOVE
    head[I] = head[J] = 0
    back = table[:0:-1].copy()                      # rows n-1 .. 1, each drawn back
    before = table[n - 2::-1][:, [X, Y]]            # to the point of the row before it
    arcs = (back[:, KIND] == _CW) | (back[:, KIND] == _CCW)
    centre_to_end = before + back[:, [I, J]] - back[:, [X, Y]]
    back[:, [X, Y]] = before
    back[arcs, KIND] = np.where(back[arcs, KIND] == _CW, _CCW, _CW)
    back[arcs, I] = centre_to_end[arcs, 0]
    back[arcs, J] = centre_to_end[arcs, 1]
    indices = np.concatenate([[first + n - 1], np.arange(first + n - 1, first, -1)])
    return indices.astype(np.int64), np.concatenate([head[None, :], back])


@dataclass
class Skeleton:
    """The ink's rows with the walks that touch nothing shortened to two rows."""

    program: Program
    short: np.ndarray       # per walk (pieces.WHOLE_PATHS order): shortened here


class WalkOrder:
    """optimized_order on a skeleton, in a forked process when `fork` (background.py);
    `rows(program)` spells it out on the ink's real rows."""

    def __init__(self, skeleton: Skeleton, start: tuple[int, int], join_nm: int,
                 fork: bool):
        self.skeleton = skeleton
        several = len(drawing_apertures(skeleton.program)) > 1
        self._order = Deferred(optimized_order, skeleton.program, start, join_nm, several,
                               fork=fork)

    def cancel(self) -> None:
        self._order.cancel()

    def rows(self, program: Program) -> OrderedRows:
        """The rows, with their op indices, in the order `optimized_order` gives on
        `program`, the ink whose skeleton this is."""
        ordered = self._order.result()
        walks = program.metadata[WHOLE_PATHS]
        skeleton_walks = self.skeleton.program.metadata[WHOLE_PATHS]
        index_map = _index_map(skeleton_walks, walks, len(self.skeleton.program))
        forward, backward = {}, {}
        for (s_first, _s_end), (first, end), short in zip(skeleton_walks, walks,
                                                          self.skeleton.short.tolist()):
            if short:
                forward[s_first] = (first, end)
                backward[s_first + 1] = (first, end)
        table = program.table
        indices: list[np.ndarray] = []      # the parts, in order: op indices and rows
        rows: list[np.ndarray] = []
        single: list[tuple[int, Row]] = []  # rows kept as they are, since the last part

        def flush() -> None:
            if single:
                indices.append(np.array([index for index, _row in single], dtype=np.int64))
                rows.append(np.array([row for _index, row in single], dtype=np.int64))
                single.clear()

        skip = None
        for index, row in ordered:
            if skip is not None:
                if index != skip:
                    raise AssertionError(f"skeleton row {index} where {skip} was expected")
                skip = None
                continue
            if row[KIND] == _MOVE and index in forward:
                first, end = forward[index]
                flush()
                indices.append(np.arange(first, end, dtype=np.int64))
                rows.append(table[first:end])
                skip = index + 1
            elif row[KIND] == _MOVE and index in backward:
                first, end = backward[index]
                flush()
                part_indices, part_rows = reversed_table(table[first:end], first)
                indices.append(part_indices)
                rows.append(part_rows)
                skip = index
            else:
                single.append((int(index_map[index]), row))
        flush()
        if not rows:
            return OrderedRows(np.zeros(0, dtype=np.int64), table[:0])
        out = np.concatenate(rows).astype(np.int64)
        # the skeleton carries no link areas: the real rows are linked as
        # optimized_order links them (plan/order/links.py)
        areas = program.metadata.get(LINK_AREAS)
        if areas:
            out[linked_moves(out, areas), KIND] = _LINE
        return OrderedRows(np.concatenate(indices), out)


def _index_map(skeleton_walks: list, walks: list, size: int) -> np.ndarray:
    """The real row index of every skeleton row: 1:1 between walks, a shortened
    walk's MOVE and LINE to its first and last row."""
    index_map = np.empty(size, dtype=np.int64)
    s_at = at = 0
    for (s_first, s_end), (first, end) in zip(skeleton_walks, walks):
        index_map[s_at:s_first] = np.arange(at, first)
        if s_end - s_first == end - first:
            index_map[s_first:s_end] = np.arange(first, end)
        else:
            index_map[s_first], index_map[s_first + 1] = first, end - 1
        s_at, at = s_end, end
    index_map[s_at:] = np.arange(at, at + size - s_at)
    return index_map
