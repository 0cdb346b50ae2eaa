"""Path order (galileo_cnc/plan/order/paths.py): chaining with reversal, ordering, and the
promise that a reordered job draws exactly the same segments."""

from __future__ import annotations

import math
import random
from pathlib import Path

import pytest

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import ArcTo, Rapid
from galileo_cnc.machine import simulate
from galileo_cnc.plan.order import paths
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.plan.order.apertures import group_by_aperture, optimized_order
from galileo_cnc.plan.pipeline import plan_file
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.program.ops import I, J, KIND, NO_TOOL, X, Y, OpKind, ProgramBuilder
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
    """Every segment drawn, in either direction: one end exact, the other within
    join_nm (a chain joined across a gap under a step; before an arc the gap is a
    line of its own), arcs round the same centre;
    an original left out only where the same segment is drawn (a repeat, drawn once:
    plan/order/repeats.py) or, for a dot, where a drawn segment ends."""
    originals = segments(original)
    by_end: dict = {}
    for k, (a, b, centre) in enumerate(originals):
        by_end.setdefault(a, []).append(k)
        by_end.setdefault(b, []).append(k)
    left = set(range(len(originals)))
    for a, b, centre in segments(reordered):
        # an original not drawn yet; else one drawn before (drawn again instead of a
        # lift: plan/order/retrace.py): no new ink either way
        for fresh in (True, False):
            match = next((k for exact, other in ((a, b), (b, a))
                          for k in by_end.get(exact, ()) if (k in left or not fresh)
                          and originals[k][2] == centre
                          and math.dist(other, originals[k][1] if originals[k][0] == exact
                                        else originals[k][0]) <= join_nm), None)
            if match is not None:
                left.discard(match)
                break
        else:
            if centre is None and math.dist(a, b) <= join_nm and b in by_end:
                continue                  # the line across a gap, into an arc's own start
            raise AssertionError(f"segment {a} -> {b} (centre {centre}) is not in the original")

    def key(k):
        a, b, centre = originals[k]
        return (frozenset((a, b)), centre)
    drawn = {key(k) for k in range(len(originals)) if k not in left}
    ends = {p for k in range(len(originals)) if k not in left for p in originals[k][:2]}
    missing = [originals[k] for k in sorted(left) if key(k) not in drawn
               and not (originals[k][0] == originals[k][1] and originals[k][0] in ends)]
    assert not missing, f"{len(missing)} original segments are not drawn, e.g. {missing[0]}"


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


def test_a_gap_under_a_step_joins_and_the_arc_keeps_its_own_ends():
    a = path((0, 0), (10 * MM, 0))
    b = path((10 * MM + 4000, 0), (20 * MM, 0, 5 * MM - 4000, 0, True))   # 4 um away
    (joined,) = paths.chain([a, b], STEP)
    bridge, arc = joined.rows[-2][1], joined.rows[-1][1]
    assert (bridge[KIND], bridge[X], bridge[Y]) == (LINE, 10 * MM + 4000, 0)   # the gap
    assert (arc[X], arc[Y]) == (20 * MM, 0)
    assert (10 * MM + 4000 + arc[I], arc[J]) == (15 * MM, 0)           # the same centre


def test_a_sliver_arc_joined_at_its_own_end_stays_a_sliver():
    # LimeSDR: a 0.4 um arc (0.88 mm radius) whose end is another trace's end. Moved to
    # that end, its start was its end: a whole 1.76 mm circle of ink over other copper.
    config = MachineConfig()
    trace = path((0, 0), (10 * MM + 400, 0))
    sliver = path((10 * MM, 0), (10 * MM + 400, 0, 200, 881_200, False))
    (joined,) = paths.chain([trace, sliver], STEP)
    assert_same_drawing([r for p in (trace, sliver) for r in p.rows], joined.rows)
    program = ProgramBuilder("sliver.gbr")
    for _index, r in joined.rows:
        program.emit(*r[:5], tool=NO_TOOL)
    job = plan_program(program.build("gerber", "mm"), config, (0, 0))
    assert not [c for c in job.commands if isinstance(c, ArcTo)]
    assert simulate(job.commands, config).steps_per_axis()[:2].sum() == 1600   # the trace


def _sample_rows():
    program = read_file(SAMPLE)
    offset = proposed_offset(program)
    return program, offset


def test_the_sample_board_reordered_draws_the_same_segments_with_less_travel():
    program, offset = _sample_rows()
    grouped = group_by_aperture(program)
    reordered = optimized_order(program, offset, STEP, by_aperture=True)
    assert_same_drawing(grouped, reordered)
    filed = plan_program(program, None, offset)
    optimized = plan_program(program, None, offset, optimize=True)
    assert list(optimized.pen_changes.values()) == list(filed.pen_changes.values())
    assert _travel(optimized) < _travel(filed)
    assert _lifts(optimized) <= _lifts(filed)
    again = plan_program(program, None, offset, optimize=True)
    assert again.commands == optimized.commands     # deterministic: resume replans it


def test_a_real_copper_layer_loses_most_of_its_travel():
    program = read_file(COPPER)
    offset = proposed_offset(program)
    filed = plan_program(program, None, offset)
    optimized = plan_program(program, None, offset, optimize=True)
    assert_same_drawing(group_by_aperture(program), optimized_order(program, offset, STEP, True))
    assert _travel(optimized) < 0.5 * _travel(filed)
    assert _lifts(optimized) < 0.7 * _lifts(filed)


def test_programs_with_feeds_or_pen_moves_keep_their_order():
    # G-code is reordered only when the user asks (--optimize: tests/plan/test_gcode_order.py)
    sample = Path(__file__).resolve().parents[2] / "samples" / "square-and-circle.nc"
    planned = plan_file(sample, offset="none")
    assert not planned.job.ordered
    assert planned.job.commands == plan_program(read_file(sample), None, (0, 0)).commands


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


# --------------------------------------------------------------------------- chaining


def _strokes_needed(pieces, join_nm: int = STEP) -> int:
    """The fewest strokes that draw `pieces` (paths only, ends that meet exactly):
    per connected group of paths, half its odd-degree ends, at least one."""
    parent: dict = {}

    def find(p):
        parent.setdefault(p, p)
        while parent[p] != p:
            p = parent[p]
        return p

    degree: dict = {}
    for piece in pieces:
        a, b = piece.start, piece.end
        degree[a] = degree.get(a, 0) + 1
        degree[b] = degree.get(b, 0) + 1
        parent[find(a)] = find(b)
    odd: dict = {}
    for point, d in degree.items():
        odd[find(point)] = odd.get(find(point), 0) + d % 2
    return sum(max(1, count // 2) for count in odd.values())


def test_a_junction_is_drawn_in_as_few_strokes_as_its_ends_allow():
    # a lollipop: a stem A-B, a loop B-C-B of two arcs, and a second stem B-D, in an
    # order where joining the first path found at B leaves the loop as a stroke of its
    # own: 2 strokes. Every arrival at B can leave by another path: A-B-C-B-D, one.
    stem = path((0, 0), (10 * MM, 0), index=0)
    other_stem = path((10 * MM, 0), (10 * MM, -10 * MM), index=1)
    arc_up = path((10 * MM, 0), (20 * MM, 0, 5 * MM, 0, True), index=2)
    arc_down = path((20 * MM, 0), (10 * MM, 0, -5 * MM, 0, True), index=3)
    pieces = [stem, other_stem, arc_up, arc_down]
    chains = paths.chain(pieces, STEP)
    assert len(chains) == 1
    assert len(chains[0].rows) == 5                # one MOVE, four segments
    assert_same_drawing([r for p in pieces for r in p.rows], chains[0].rows, 0)


@pytest.mark.parametrize("seed", range(6))
def test_chaining_random_grid_drawings_needs_no_more_strokes_than_the_ends_force(seed):
    # unit segments on a small grid, each drawn either way, shuffled: many junctions
    # of three and four paths
    rng = random.Random(seed)
    edges = set()
    while len(edges) < 40:
        x, y = rng.randrange(6), rng.randrange(6)
        dx, dy = rng.choice(((1, 0), (0, 1)))
        edges.add(((x, y), (x + dx, y + dy)))
    pieces = []
    for k, (a, b) in enumerate(sorted(edges)):
        a, b = (b, a) if rng.random() < 0.5 else (a, b)
        pieces.append(path((a[0] * MM, a[1] * MM), (b[0] * MM, b[1] * MM), index=k))
    rng.shuffle(pieces)
    chains = paths.chain(pieces, STEP, retrace=False)
    assert len(chains) == _strokes_needed(pieces)
    assert_same_drawing([r for p in pieces for r in p.rows],
                        [r for c in chains for r in c.rows], 0)
    # drawing short stretches again (plan/order/retrace.py) only ever saves strokes
    chains = paths.chain(pieces, STEP)
    assert len(chains) <= _strokes_needed(pieces)
    assert_same_drawing([r for p in pieces for r in p.rows],
                        [r for c in chains for r in c.rows], 0)


def test_ends_linked_through_a_third_end_join_only_within_a_step():
    # three ends 4 um apart in a row: the outer two are 8 um apart, more than a step,
    # so one of them must stay apart (assert_same_drawing allows a step of gap)
    a = path((0, 0), (10 * MM, 0), index=0)
    b = path((10 * MM + 4000, 0), (10 * MM + 4000, 10 * MM), index=1)
    c = path((10 * MM + 8000, 0), (20 * MM, 0), index=2)
    chains = paths.chain([a, b, c], STEP)
    assert len(chains) == 2
    assert_same_drawing(a.rows + b.rows + c.rows, [r for ch in chains for r in ch.rows])


# --------------------------------------------------------------------------- ordering


def _best_travel(chains, start) -> float:
    """Shortest pen-up travel over every order and direction (brute force)."""
    import itertools

    best = math.inf
    for perm in itertools.permutations(range(len(chains))):
        for flips in itertools.product((False, True), repeat=len(chains)):
            here, total = start, 0.0
            for k, flip in zip(perm, flips):
                c = chains[k]
                a, b = (c.end, c.start) if flip else (c.start, c.end)
                total += math.dist(here, a)
                here = b
            best = min(best, total)
    return best


def test_a_comb_is_drawn_up_and_down_flipping_every_other_tooth():
    # teeth 1 mm apart, all given bottom to top: only flipping teeth in place gives
    # the known optimum, 1 mm of travel between teeth
    teeth = [path((k * MM, 0), (k * MM, 10 * MM), index=k) for k in range(12)]
    tour, end = paths.order(teeth, (0, 0))
    assert paths.travel_nm(tour, (0, 0)) == pytest.approx(11 * MM, abs=1)
    assert end in ((11 * MM, 0), (11 * MM, 10 * MM))
    assert sorted(min(c.rows[0][0], c.rows[-1][0]) for c in tour) == list(range(12))


@pytest.mark.parametrize("seed", range(8))
def test_few_chains_take_the_shortest_order(seed):
    rng = random.Random(seed)
    chains = []
    for k in range(rng.randint(2, 6)):
        a = (rng.randrange(50 * MM), rng.randrange(50 * MM))
        b = (a[0] + rng.randrange(-20 * MM, 20 * MM), a[1] + rng.randrange(-20 * MM, 20 * MM))
        chains.append(path(a, b, index=k))
    start = (rng.randrange(50 * MM), rng.randrange(50 * MM))
    tour, _end = paths.order(chains, start)
    assert paths.travel_nm(tour, start) == pytest.approx(_best_travel(chains, start), abs=1)


def test_a_single_chain_flip_in_the_middle_of_a_long_tour():
    # a row of 30 short paths left to right, one of them given right to left; more
    # chains than the exhaustive search takes, so the local search must turn it
    row = [path((k * 3 * MM, 0), (k * 3 * MM + 2 * MM, 0), index=k) for k in range(30)]
    row[17] = row[17].reversed()
    tour, _end = paths.order(row, (0, 0))
    assert paths.travel_nm(tour, (0, 0)) == pytest.approx(29 * MM, abs=1)


def _random_paths(seed: int, count: int):
    """`count` random pieces: open paths of lines and arcs, closed loops, flashes."""
    rng = random.Random(seed)
    rows = []
    for k in range(count):
        x, y = rng.randrange(100 * MM), rng.randrange(100 * MM)
        if k % 7 == 0:
            r = [0] * 9
            r[KIND], r[X], r[Y] = int(OpKind.FLASH), x, y
            rows.append((k, r))
            continue
        rows.append((k, row(MOVE, x, y)))
        for _ in range(rng.randint(1, 3)):
            nx, ny = x + rng.randrange(-3 * MM, 3 * MM), y + rng.randrange(-3 * MM, 3 * MM)
            if rng.random() < 0.3:       # a half circle to (nx, ny)
                rows.append((k, row(CW, nx, ny, (nx - x) // 2, (ny - y) // 2)))
            else:
                rows.append((k, row(LINE, nx, ny)))
            x, y = nx, ny
        if k % 5 == 0:                   # closed
            rows.append((k, row(LINE, *rows[-1 - 0][1][X:Y + 1])))
    return rows


def test_ordering_is_deterministic_and_draws_the_same():
    rows = _random_paths(11, 600)
    first, end = paths.optimize(rows, (0, 0), STEP)
    again, end_again = paths.optimize([(i, list(r)) for i, r in rows], (0, 0), STEP)
    assert first == again and end == end_again
    assert_same_drawing(rows, first)
    ours = paths.travel_nm(paths.cut_pieces(first, (0, 0)), (0, 0))
    assert ours < 0.5 * paths.travel_nm(paths.cut_pieces(rows, (0, 0)), (0, 0))


def test_a_move_budget_of_zero_still_orders_every_chain():
    rows = _random_paths(5, 200)
    drawn, _end = paths.optimize(rows, (0, 0), STEP, moves=0)
    assert_same_drawing(rows, drawn)


def test_many_paths_order_better_than_nearest_neighbour():
    # 800 random short paths: greedy + 2-opt + Or-opt must beat a plain nearest
    # neighbour tour by a clear margin (no timing here: the bench measures time)
    rng = random.Random(2)
    chains = []
    for k in range(800):
        a = (rng.randrange(120 * MM), rng.randrange(120 * MM))
        b = (a[0] + rng.randrange(-2 * MM, 2 * MM), a[1] + rng.randrange(-2 * MM, 2 * MM))
        chains.append(path(a, b, index=k))
    left, here, nn = set(range(len(chains))), (0, 0), 0.0
    while left:
        k, flip = min(((k, f) for k in left for f in (False, True)),
                      key=lambda kf: math.dist(here, chains[kf[0]].end if kf[1]
                                               else chains[kf[0]].start))
        left.discard(k)
        c = chains[k].reversed() if flip else chains[k]
        nn += math.dist(here, c.start)
        here = c.end
    tour, _end = paths.order(chains, (0, 0))
    assert len(tour) == len(chains)
    assert paths.travel_nm(tour, (0, 0)) < 0.85 * nn


def test_a_whole_path_is_ordered_as_it_is_unless_another_path_touches_it():
    # out 10 mm and back along the same line: a repeat worth leaving out (over 5 mm),
    # unless the path is a whole stroke already (the ink's fill walks: WHOLE_PATHS)
    there_and_back = [row(MOVE, 0, 0), row(LINE, 10 * MM, 0), row(LINE, 10 * MM, 10 * MM),
                      row(LINE, 10 * MM, 0), row(LINE, 0, 0)]
    rows = list(enumerate(there_and_back))
    kept, _end = paths.optimize(rows, (0, 0), STEP, whole=frozenset({0}))
    assert kept in (rows, paths.Piece(rows).reversed().rows)      # either way round
    cut, _end = paths.optimize(rows, (0, 0), STEP)
    assert len(cut) < len(rows)                   # the repeat is left out
    # a second path apart from a whole one: the whole one is drawn as it is
    other = [row(MOVE, 30 * MM, 10 * MM), row(LINE, 40 * MM, 10 * MM)]
    rows = list(enumerate(there_and_back + other))
    drawn, _end = paths.optimize(rows, (0, 0), STEP, whole=frozenset({0}))
    block = [k for k, (index, _row) in enumerate(drawn) if index <= 4]
    assert block == list(range(block[0], block[0] + 5))       # its five rows, together
    assert len(drawn) == 7
    # one that ends on a vertex of it (a centre line into a pad's walk): chained with
    # it as any path is, one stroke for both
    touching = [row(MOVE, 20 * MM, 10 * MM), row(LINE, 10 * MM, 10 * MM)]
    rows = list(enumerate(there_and_back + touching))
    drawn, _end = paths.optimize(rows, (0, 0), STEP, whole=frozenset({0}))
    assert sum(r[KIND] == MOVE for _index, r in drawn) == 1
    assert paths.touching([paths.Piece(list(enumerate(there_and_back)))],
                          [paths.Piece(list(enumerate(touching)))], STEP) == [True]
    assert paths.touching([paths.Piece(list(enumerate(there_and_back)))],
                          [paths.Piece(list(enumerate(other)))], STEP) == [False]
