"""Path order (galileo_cnc/plan/paths.py): chaining with reversal, ordering, and the
promise that a reordered job draws exactly the same segments."""

from __future__ import annotations

import math
import random
from pathlib import Path

import pytest

from galileo_cnc.job import Rapid
from galileo_cnc.plan import paths
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.plan.order import group_by_aperture, optimised_order
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind
from galileo_cnc.readers import read_file

from corpus import CORPUS

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "led-blinker.gbr"
COPPER = CORPUS / "kicad" / "atmega328-motor-board" / "ATMEGA328_Motor_Board-F.Cu.gtl"
MOVE, LINE, CW, CCW = (int(k) for k in (OpKind.MOVE, OpKind.LINE, OpKind.ARC_CW,
                                        OpKind.ARC_CCW))
MM = 1_000_000
STEP = 6250


def row(kind: int, x: int, y: int, i: int = 0, j: int = 0) -> list[int]:
    r = [0] * 9
    r[KIND], r[X], r[Y], r[I], r[J] = kind, x, y, i, j
    return r


def path(*points, index: int = 0) -> paths.Piece:
    """A MOVE to the first point, then LINEs (a point given as (x, y, i, j, cw) is an arc)."""
    rows = [(index, row(MOVE, *points[0]))]
    for p in points[1:]:
        rows.append((index, row(CW if p[4] else CCW, *p[:4]) if len(p) == 5
                     else row(LINE, *p)))
    return paths.Piece(rows)


def segments(rows):
    """The drawn segments: (start, end, centre or None), in drawing direction."""
    out, here = [], None
    for _index, r in rows:
        kind = r[KIND]
        if kind in (LINE, CW, CCW) and here is not None:
            centre = (here[0] + r[I], here[1] + r[J]) if kind != LINE else None
            out.append((here, (r[X], r[Y]), centre))
        if kind in (MOVE, LINE, CW, CCW, int(OpKind.FLASH)):
            here = (r[X], r[Y])
    return out


def assert_same_drawing(original, reordered, join_nm: int = STEP):
    """Every segment drawn once, in either direction: one end exact, the other within
    join_nm (a chain joined across a gap under a step), arcs round the same centre."""
    by_end: dict = {}
    for k, (a, b, centre) in enumerate(segments(original)):
        by_end.setdefault(a, []).append(k)
        by_end.setdefault(b, []).append(k)
    originals = segments(original)
    left = set(range(len(originals)))
    for a, b, centre in segments(reordered):
        for exact, other in ((a, b), (b, a)):
            match = next((k for k in by_end.get(exact, ()) if k in left
                          and originals[k][2] == centre
                          and math.dist(other, originals[k][1] if originals[k][0] == exact
                                        else originals[k][0]) <= join_nm), None)
            if match is not None:
                left.discard(match)
                break
        else:
            raise AssertionError(f"segment {a} -> {b} (centre {centre}) is not in the original")
    assert not left, f"{len(left)} original segments are not drawn, e.g. {originals[min(left)]}"


def test_reversing_keeps_the_geometry_exactly():
    piece = path((0, 0), (10 * MM, 0), (10 * MM, 10 * MM, 0, 5 * MM, False), (3 * MM, 7 * MM))
    back = piece.reversed()
    assert (back.start, back.end) == (piece.end, piece.start)
    assert_same_drawing(piece.rows, back.rows, 0)
    assert [r for _i, r in back.reversed().rows] == [r for _i, r in piece.rows]
    arc = [r for _i, r in back.rows if r[KIND] in (CW, CCW)][0]
    assert arc[KIND] == CW                         # counter-clockwise drawn backwards


@pytest.mark.parametrize("case", ["end meets end", "start meets start",
                                  "start meets the end of a later entity"])
def test_the_seeds_three_alignment_cases_make_one_chain(case):
    a, b = {
        "end meets end": (path((0, 0), (10 * MM, 0)), path((20 * MM, 0), (10 * MM, 0))),
        "start meets start": (path((10 * MM, 0), (0, 0)), path((10 * MM, 0), (20 * MM, 0))),
        "start meets the end of a later entity": (path((10 * MM, 0), (20 * MM, 0)),
                                                  path((0, 0), (10 * MM, 0))),
    }[case]
    chains = paths.chain([a, b], STEP)
    assert len(chains) == 1
    assert len(chains[0].rows) == 3                # one MOVE, two segments: no lift
    assert_same_drawing(a.rows + b.rows, chains[0].rows, 0)


def test_a_shuffled_nineteen_entity_outline_becomes_one_chain_and_a_circle():
    # 18 segments round a closed outline (lines and arcs), each entity drawn in either
    # direction and in shuffled order, like the seed's 19-entity CAM example, plus a circle
    rng = random.Random(7)
    corners = [(round(20 * MM * math.cos(k * math.tau / 18)),
                round(20 * MM * math.sin(k * math.tau / 18))) for k in range(18)]
    pieces = []
    for k in range(18):
        start, end = corners[k], corners[(k + 1) % 18]
        if k % 3 == 0:      # an arc round the origin
            piece = path(start, (end[0], end[1], -start[0], -start[1], False), index=k)
        else:
            piece = path(start, end, index=k)
        pieces.append(piece.reversed() if rng.random() < 0.5 else piece)
    rng.shuffle(pieces)
    circle = path((50 * MM, 0), (50 * MM, 0, -5 * MM, 0, True), index=18)
    everything = pieces + [circle]
    chains = paths.chain(everything, STEP)
    assert len(chains) == 2
    assert sorted(len(c.rows) for c in chains) == [2, 19]   # 18 segments, one MOVE
    assert_same_drawing([r for p in everything for r in p.rows],
                        [r for c in chains for r in c.rows], 0)


def test_a_gap_under_a_step_joins_and_the_arc_keeps_its_centre():
    a = path((0, 0), (10 * MM, 0))
    b = path((10 * MM + 4000, 0), (20 * MM, 0, 5 * MM - 4000, 0, True))   # 4 um away
    (joined,) = paths.chain([a, b], STEP)
    arc = joined.rows[-1][1]
    assert (arc[X], arc[Y]) == (20 * MM, 0)
    assert (10 * MM + arc[I], arc[J]) == (15 * MM, 0)                  # the same centre


def _sample_rows():
    program = read_file(SAMPLE)
    offset = proposed_offset(program)
    return program, offset


def test_the_sample_board_reordered_draws_the_same_segments_with_less_travel():
    program, offset = _sample_rows()
    grouped = group_by_aperture(program)
    reordered = optimised_order(program, offset, STEP, by_aperture=True)
    assert_same_drawing(grouped, reordered)
    filed = plan_program(program, None, offset)
    optimised = plan_program(program, None, offset, optimize=True)
    assert list(optimised.pen_changes.values()) == list(filed.pen_changes.values())
    assert _travel(optimised) < _travel(filed)
    assert _lifts(optimised) <= _lifts(filed)
    again = plan_program(program, None, offset, optimize=True)
    assert again.commands == optimised.commands     # deterministic: resume replans it


def test_a_real_copper_layer_loses_most_of_its_travel():
    program = read_file(COPPER)
    offset = proposed_offset(program)
    filed = plan_program(program, None, offset)
    optimised = plan_program(program, None, offset, optimize=True)
    assert_same_drawing(group_by_aperture(program), optimised_order(program, offset, STEP, True))
    assert _travel(optimised) < 0.5 * _travel(filed)
    assert _lifts(optimised) < 0.7 * _lifts(filed)


def test_programs_with_feeds_or_pen_moves_keep_their_order():
    program = read_file(Path(__file__).resolve().parents[2] / "samples" / "square-and-circle.nc")
    assert plan_program(program, None, (0, 0), optimize=True).commands == \
        plan_program(program, None, (0, 0)).commands


def _travel(job) -> float:
    here, total = (0, 0), 0.0
    for command in job.commands:
        if isinstance(command, Rapid):
            total += math.dist(here, (command.x_steps, command.y_steps))
        if hasattr(command, "x_steps"):
            here = (command.x_steps, command.y_steps)
    return total


def _lifts(job) -> int:
    return sum(isinstance(c, Rapid) for c in job.commands)
