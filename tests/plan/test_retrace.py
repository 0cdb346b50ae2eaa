"""Retracing (galileo_cnc/plan/order/retrace.py): a short stretch of a pen's own ink drawn
again instead of a lift, only where that saves a stroke and costs less than one."""

from __future__ import annotations

import math

import pytest

from galileo_cnc.machine.planner import estimate_seconds
from galileo_cnc.plan.order import paths, retrace
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.plan.order.apertures import group_by_aperture, optimized_order
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.readers import read_file

from corpus import CORPUS
from test_paths import MM, STEP, assert_same_drawing, path, segments

USBVIL = CORPUS / "altium" / "usbvil" / "pic18f14k50.gtl"


def star(arm_nm: int) -> list[paths.Piece]:
    """Four arms out of one centre: four odd ends, so two strokes without retracing."""
    return [path((0, 0), (dx * arm_nm, dy * arm_nm), index=k)
            for k, (dx, dy) in enumerate(((1, 0), (0, 1), (-1, 0), (0, -1)))]


def drawn_nm(chains: list[paths.Piece]) -> float:
    return sum(math.dist(a, b) for c in chains for a, b, _centre in segments(c.rows))


def test_a_star_of_short_arms_is_one_stroke_with_two_arms_drawn_twice():
    pieces = star(1 * MM)
    assert len(paths.chain(pieces, STEP, retrace=False)) == 2
    chains = paths.chain(pieces, STEP)
    assert len(chains) == 1
    # two ends are paired through the centre: the four arms, and two of them again
    assert drawn_nm(chains) == pytest.approx(6 * MM)
    assert_same_drawing([r for p in pieces for r in p.rows], chains[0].rows, 0)


def test_a_star_of_long_arms_keeps_its_lift():
    # drawing a 10 mm arm again costs more than the stroke it saves
    chains = paths.chain(star(10 * MM), STEP)
    assert len(chains) == 2
    assert drawn_nm(chains) == pytest.approx(40 * MM)


def test_two_odd_ends_are_one_stroke_already_and_nothing_is_drawn_twice():
    # a path with a loop at one end has two odd nodes: one stroke, nothing to pair
    edges = [(0, 1), (1, 2), (2, 3), (3, 1)]
    assert retrace.retraced_edges(edges, lambda e: MM, 4) == []


def test_each_odd_node_is_paired_once_cheapest_first():
    # a row of five short paths 0-1-2-3-4-5 and spurs at 2 and 3: odd nodes 0, 5 and
    # the spur ends 6, 7, and 2 and 3 (degree 3). Cheapest pair: 2-3 (the middle path)
    edges = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (2, 6), (3, 7)]
    costs = [3 * MM, 3 * MM, 1 * MM, 3 * MM, 3 * MM, 4.5 * MM, 4.5 * MM]
    again = retrace.retraced_edges(edges, costs.__getitem__, 8)
    assert again == [2]


def test_a_real_copper_layer_plots_faster_with_fewer_strokes_and_the_same_ink():
    program = read_file(USBVIL)
    offset = proposed_offset(program)
    plain = plan_program(program, None, offset, optimize=True)
    rows = optimized_order(program, offset, STEP, True)
    assert_same_drawing(group_by_aperture(program), rows)
    original = paths.chain
    try:
        paths.chain = lambda pieces, join_nm: original(pieces, join_nm, retrace=False)
        without = plan_program(program, None, offset, optimize=True)
    finally:
        paths.chain = original
    strokes = [sum(type(c).__name__ == "Rapid" for c in job.commands)
               for job in (plain, without)]
    assert strokes[0] < strokes[1]
    assert estimate_seconds(plain.commands) < estimate_seconds(without.commands)
