"""What one pen would draw twice, drawn once (plan/order/repeats.py), and a pen's order
ending near the next pen's work (paths.order's goal): the ink stays the same."""

from __future__ import annotations

import math

from galileo_cnc.plan.order import paths
from galileo_cnc.plan.order.apertures import group_by_aperture, optimize_groups
from galileo_cnc.plan.order.repeats import LIFT_NM, segment_length_nm, drop_repeats
from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind
from galileo_cnc.readers import read_file

from corpus import CORPUS

COPPER = CORPUS / "kicad" / "atmega328-motor-board" / "ATMEGA328_Motor_Board-F.Cu.gtl"
MOVE, LINE, CW, CCW, FLASH = (int(k) for k in (OpKind.MOVE, OpKind.LINE, OpKind.ARC_CW,
                                               OpKind.ARC_CCW, OpKind.FLASH))
MM = 1_000_000


def row(kind: int, x: int, y: int, i: int = 0, j: int = 0) -> list[int]:
    r = [0] * 9
    r[KIND], r[X], r[Y], r[I], r[J] = kind, x, y, i, j
    return r


def ink(rows) -> tuple[set, int]:
    """(what the pen covers, segments drawn): lines by their two ends, arcs by centre
    and ends counter-clockwise, dots (zero-length lines) unless a segment ends there,
    flash points."""
    covered, dots, drawn, here = set(), set(), 0, None
    for _index, r in rows:
        kind, end = r[KIND], (r[X], r[Y])
        if kind == LINE and end == here:
            dots.add(end)
            drawn += 1
        elif kind == LINE:
            covered.add(("line", frozenset((here, end))))
            drawn += 1
        elif kind in (CW, CCW):
            centre = (here[0] + r[I], here[1] + r[J])
            covered.add(("arc", centre) + ((here, end) if kind == CCW else (end, here)))
            drawn += 1
        elif kind == FLASH:
            covered.add(("flash", end))
            drawn += 1
        here = end
    ends = {p for item in covered if item[0] != "flash"
            for p in (item[1] if item[0] == "line" else item[2:])}
    return covered | {("dot", p) for p in dots - ends}, drawn


def drawn_nm(pieces) -> float:
    return sum(segment_length_nm(p.rows[k - 1][1][X:Y + 1], p.rows[k][1]) for p in pieces
               if p.is_path for k in range(1, len(p.rows)))


def test_repeated_segments_dots_and_flashes_are_drawn_once():
    a, b, c, q = (0, 0), (10 * MM, 0), (10 * MM, 2 * MM), (30 * MM, 30 * MM)
    rows = [
        (0, row(MOVE, *a)), (0, row(LINE, *b)), (0, row(CW, *c, 0, MM)),
        (1, row(MOVE, *c)), (1, row(CCW, *b, 0, -MM)),         # the arc backwards
        (1, row(LINE, *a)),                                    # the line backwards
        (1, row(LINE, 0, 20 * MM)),                            # new: stays
        (2, row(MOVE, *b)), (2, row(LINE, *b)),                # a dot where lines end
        (3, row(MOVE, *q)), (3, row(LINE, *q)),                # a dot on its own
        (4, row(MOVE, *q)), (4, row(LINE, *q)),                # ... twice
        (5, row(FLASH, *q)), (6, row(FLASH, *q)), (7, row(FLASH, *c)),
    ]
    pieces = paths.cut_pieces(rows, (0, 0))
    kept = drop_repeats(pieces)
    flat = [entry for p in kept for entry in p.rows]
    assert ink(flat)[0] == ink(rows)[0]
    # A-B, the 3 mm arc twice (once would leave B and C odd: a second stroke, which
    # costs more than 3 mm of drawing), the new line, one dot at q, flashes at q and c
    assert ink(flat)[1] == 7 < ink(rows)[1] == 11
    assert len(paths.chain(kept, 0)) == 4         # one path, the dot, two flashes
    # the path that repeated two segments goes on from where its new segment starts
    assert any(p.rows[0][1][KIND] == MOVE and p.start == a and p.end == (0, 20 * MM)
               for p in kept)


def test_a_long_repeat_is_left_out_even_where_that_costs_a_stroke():
    # an open line with a spur out and back at its middle: one stroke; the spur once
    # leaves four odd ends (two strokes), worth it for 20 mm of drawing, not for 1 mm
    for spur_mm, drawn, strokes in ((20, 3, 2), (1, 4, 1)):
        rows = [(0, row(MOVE, 0, 0)), (0, row(LINE, 10 * MM, 0)),
                (0, row(LINE, 10 * MM, spur_mm * MM)), (0, row(LINE, 10 * MM, 0)),
                (0, row(LINE, 20 * MM, 0))]
        kept = drop_repeats(paths.cut_pieces(rows, (0, 0)))
        assert ink([entry for p in kept for entry in p.rows]) == (ink(rows)[0], drawn)
        assert len(paths.chain(kept, 0)) == strokes


def test_nothing_repeated_leaves_the_pieces_as_they_are():
    rows = [(0, row(MOVE, 0, 0)), (0, row(LINE, MM, 0)), (1, row(MOVE, MM, 0)),
            (1, row(LINE, 2 * MM, 0)), (2, row(FLASH, 5 * MM, 5 * MM))]
    pieces = paths.cut_pieces(rows, (0, 0))
    assert drop_repeats(pieces) is pieces


def test_a_real_copper_layer_keeps_its_ink_and_draws_less_in_no_more_strokes():
    # the KiCad layer draws thousands of segments twice with the same aperture; with
    # joins only where ends are equal (join 0) the covered set must be the same exactly
    program = read_file(COPPER)
    rows = group_by_aperture(program)
    groups, current = [], None
    for index, r in rows:
        if r[KIND] == OpKind.SELECT:
            current = []
            groups.append(current)
        else:
            current.append((index, r))
    before = after = 0
    for group, drawn in zip(groups, optimize_groups(groups, (0, 0), 0)):
        covered, count = ink(group)
        covered_after, count_after = ink(drawn)
        assert covered_after == covered                 # same pen, same points
        assert len(covered) <= count_after <= count
        before, after = before + count, after + count_after
        # a stroke more only for every LIFT_NM of drawing saved
        pieces = paths.cut_pieces(group, (0, 0))
        kept = drop_repeats(pieces)
        added = len(paths.chain(kept, 0)) - len(paths.chain(pieces, 0))
        assert added <= max(0, (drawn_nm(pieces) - drawn_nm(kept)) // LIFT_NM)
    assert after < before


def test_a_pens_order_ends_near_where_the_next_pens_work_is():
    # flashes at x = -1 and 1..10 mm, head at 0: alone the shortest order ends at 10;
    # with the next pen's work at x = -30 it goes right first and ends at -1
    for xs in ([-1, 3], [-1] + list(range(1, 11))):         # exact and local search
        chains = [paths.Piece([(k, row(FLASH, x * MM, 0))]) for k, x in enumerate(xs)]
        goal = [(-30 * MM, 0)]
        alone, end_alone = paths.order(chains, (0, 0))
        aimed, end_aimed = paths.order(chains, (0, 0), goal=goal)
        assert end_alone == (xs[-1] * MM, 0) and end_aimed == (-MM, 0)

        def whole(tour, end):
            return paths.travel_nm(tour, (0, 0)) + math.dist(end, goal[0])
        assert whole(aimed, end_aimed) < whole(alone, end_alone)
