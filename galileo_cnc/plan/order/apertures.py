"""Ordering Gerber artwork for a pen plotter: all the work of one aperture together.

The seed stopped for a pen change at every aperture switch, and Gerber files
switch often (pads, then tracks, then pads again). Drawing order does not change
what ink ends up on the board, so the work is cut into pieces and the pieces are
stably sorted by the order in which their aperture first appears: one pen change
per aperture, and the file's order within an aperture.

A piece starts at every MOVE (D02), every FLASH (D03), and wherever the aperture
of a draw changes without a move. A piece whose path does not start with a MOVE
(after a flash, or at an aperture change mid-path) gets one to the point where
it starts (a synthetic row carrying the first op's index), so it draws exactly
what it drew in file order. Pieces that draw nothing (a lone MOVE,
markers) are dropped: they would only add travel.

`optimized_order` is path order's entry for a whole Program (the planner's, and the
ink's on its walks' ends): one pen per aperture, each pen's paths chained and ordered
(paths.optimize), each pen's work ending near where the next pen's starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from galileo_cnc.plan.order.links import LINK_AREAS, linked_pairs
from galileo_cnc.plan.order.paths import cut_pieces, optimize
from galileo_cnc.plan.order.pieces import WHOLE_PATHS
from galileo_cnc.program.ops import COLUMNS, KIND, NO_TOOL, TOOL, X, Y, OpKind, Program

DRAWING_KINDS = (int(OpKind.LINE), int(OpKind.ARC_CW), int(OpKind.ARC_CCW), int(OpKind.FLASH))
_POSITIONED = (int(OpKind.MOVE),) + DRAWING_KINDS
PATH_KINDS = (int(OpKind.LINE), int(OpKind.ARC_CW), int(OpKind.ARC_CCW))


@dataclass
class OrderedRows:
    """Rows in the order they are plotted, as arrays: each row's op index (`indices`)
    and the rows themselves (`table`, Program.table's columns). What plan_program also
    takes as a list of (op index, row) pairs, without a list per row (the ink's walks:
    95k rows on hellboard)."""

    indices: np.ndarray
    table: np.ndarray

    def __len__(self) -> int:
        return len(self.indices)


def drawing_apertures(program: Program) -> set[int]:
    """Apertures (pens) that draw or flash something, region outlines included."""
    kinds, tools = program.table[:, KIND], program.table[:, TOOL]
    # the aperture selected at each row: that of the last SELECT up to it
    last = np.where(kinds == OpKind.SELECT, np.arange(len(kinds)), -1)
    np.maximum.accumulate(last, out=last)
    selected = np.where(last >= 0, tools[last], NO_TOOL)
    drawing = np.isin(kinds, DRAWING_KINDS)
    used = np.where(tools[drawing] != NO_TOOL, tools[drawing], selected[drawing])
    return set(np.unique(used).tolist()) - {NO_TOOL}


def group_by_aperture(program: Program) -> list[tuple[int, list[int]]]:
    """(op index, row) pairs in plotting order (see module doc).

    The file's SELECT rows are left out: each piece starts with a SELECT of its
    aperture, and each drawing row carries it in `tool` (region outlines, which
    carry none, get the one selected), so the planner sees the right pen
    whatever order the pieces end up in."""
    pieces: list[tuple[int, list[tuple[int, list[int]]]]] = []   # (aperture, rows)
    current: list[tuple[int, list[int]]] = []
    piece_aperture: int | None = None        # None: the piece has drawn nothing yet
    point = (0, 0)
    selected = NO_TOOL

    def close_piece() -> None:
        nonlocal current, piece_aperture
        if piece_aperture is not None:
            pieces.append((piece_aperture, current))
        current, piece_aperture = [], None

    for index, row in enumerate(program.table.tolist()):
        kind = row[KIND]
        if kind == OpKind.SELECT:
            selected = row[TOOL]
            continue
        if kind in DRAWING_KINDS and row[TOOL] == NO_TOOL:
            row[TOOL] = selected
        if kind == OpKind.MOVE or kind == OpKind.FLASH \
                or kind in DRAWING_KINDS and piece_aperture not in (None, row[TOOL]):
            close_piece()
        if kind in PATH_KINDS and not any(r[KIND] == OpKind.MOVE for _i, r in current):
            move = list(row)                    # the path starts where the head was
            move[KIND], move[X], move[Y] = int(OpKind.MOVE), point[0], point[1]
            current.append((index, move))
        if kind in DRAWING_KINDS:
            piece_aperture = row[TOOL]
        current.append((index, row))
        if kind in _POSITIONED:
            point = (row[X], row[Y])
        if kind == OpKind.FLASH:
            close_piece()
    close_piece()

    rank: dict[int, int] = {}
    for aperture, _rows in pieces:
        rank.setdefault(aperture, len(rank))
    pieces.sort(key=lambda piece: rank[piece[0]])          # stable: file order within
    ordered = []
    for aperture, rows in pieces:
        select = [0] * len(rows[0][1])
        select[KIND], select[TOOL] = int(OpKind.SELECT), aperture
        ordered.append((rows[0][0], select))
        ordered.extend(rows)
    return ordered


def pure_geometry(program: Program) -> bool:
    """Nothing but moves, draws, flashes, selects and markers (and PEN_DOWN, which in
    Gerber only repeats that a draw draws): rows whose order a reorder cannot break.
    Feeds, dwells and pen lifts could be broken."""
    stateful = [int(k) for k in (OpKind.FEED, OpKind.DWELL, OpKind.PEN_UP)]
    return not np.isin(program.table[:, KIND], stateful).any()


def optimized_order(program: Program, start: tuple[int, int], join_nm: int,
                    by_aperture: bool) -> list[tuple[int, list[int]]]:
    """(op index, row) pairs: the pieces of each pen chained and ordered to cut pen-up
    travel (paths.py), from `start` (program coordinates); with `by_aperture`
    one pen per aperture in first-use order, else everything as one pen. Where the
    Program names the areas its pens may link paths in (the ink's), short pen lifts
    become lines (links.py)."""
    rows = group_by_aperture(program) if by_aperture else list(enumerate(program.table.tolist()))
    groups: list[tuple[list[int] | None, list[tuple[int, list[int]]]]] = []
    for index, row in rows:
        if row[KIND] == OpKind.SELECT and by_aperture:
            if not groups or groups[-1][0][TOOL] != row[TOOL]:
                groups.append((row, []))
            continue
        if not groups:
            groups.append((None, []))
        groups[-1][1].append((index, row))
    ordered = []
    if not by_aperture:                     # one pen: keep the aperture it is selected as
        selects = [(i, r) for i, r in rows if r[KIND] == OpKind.SELECT]
        ordered.extend(selects[:1])
    whole = frozenset(first for first, _end in program.metadata.get(WHOLE_PATHS, ()))
    drawn_groups = optimize_groups([group_rows for _select, group_rows in groups], start,
                                   join_nm, whole)
    for (select, group_rows), drawn in zip(groups, drawn_groups):
        if select is not None:
            ordered.append((group_rows[0][0] if group_rows else 0, select))
        ordered.extend(drawn)
    areas = program.metadata.get(LINK_AREAS)
    return linked_pairs(ordered, areas, len(COLUMNS)) if areas else ordered


def optimize_groups(groups: list[list[tuple[int, list[int]]]], start: tuple[int, int],
                    join_nm: int, whole: frozenset[int] = frozenset()
                    ) -> list[list[tuple[int, list[int]]]]:
    """Each pen's rows chained and ordered (paths.optimize; `whole`: the op indices
    that start paths kept whole), pen after pen from `start`, each pen's work ending
    near the ends of the next pen's pieces (where that pen may start) rather than
    wherever its own travel was shortest."""
    out, here = [], start
    for g, rows in enumerate(groups):
        goal = group_goal(groups[g + 1]) if g + 1 < len(groups) else None
        drawn, here = optimize(rows, here, join_nm, goal=goal, whole=whole)
        out.append(drawn)
    return out


def group_goal(rows: list[tuple[int, list[int]]]) -> list[tuple[int, int]]:
    """Where a pen's work may start: both ends of each of its pieces (every piece
    group_by_aperture makes starts with a MOVE, so no head position is needed)."""
    return [p for piece in cut_pieces(rows, (0, 0)) for p in (piece.start, piece.end)]
