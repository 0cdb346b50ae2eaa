"""Inking constructed boards: measured from the steps the reference machine makes.

Each case is planned in ink mode, stepped by the reference machine (the firmware's
twin), and the pen-down steps swept by the pen are compared with the copper.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from corpus import CORPUS
from inked import ink_of_trace

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import PenDown
from galileo_cnc.machine.planner import simulate
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.edges import EdgeIndex, point_to_edges
from galileo_cnc.plan.ink.fill import (_Stop, _Walker, fill_region, inked_area_nm2,
                                      island_batches)
from galileo_cnc.plan.ink.geometry import dark_geometry
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.readers import read_file

MM = 1_000_000
HEADER = "%FSLAX46Y46*%\n%MOMM*%\nG75*\n"
CONFIG = MachineConfig()
STEP = CONFIG.nm_per_step


def plot(tmp_path, body: str, pens=(300_000,)):
    path = tmp_path / "board.gbr"
    path.write_text(HEADER + body + "M02*\n")
    planned = plan_file(path, CONFIG, "auto", options=PlanOptions(mode="ink", pens_nm=pens))
    trace = simulate(planned.job.commands, CONFIG)
    ink = ink_of_trace(trace, CONFIG, planned.offset_nm, list(pens))
    return planned, ink


def square(x0, y0, x1, y1):
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def test_a_square_pad_is_inked_as_a_square(tmp_path):
    planned, ink = plot(tmp_path, "%ADD10R,1.7X1.7*%\nD10*\nX5000000Y5000000D03*\n")
    pad = [square(4_150_000, 4_150_000, 5_850_000, 5_850_000)]
    r = 150_000
    corners = 4 * (1 - math.pi / 4) * r * r        # a round pen cannot reach square corners
    perimeter = 4 * 1_700_000
    uninked = clip.area_nm2(clip.difference(pad, ink))
    outside = clip.area_nm2(clip.difference(ink, pad))
    assert uninked <= corners * 1.05 + perimeter * 4_000       # corners + the edge margin
    assert outside <= perimeter * 2_000                        # stepping, never a pen width
    x0, y0, x1, y1 = clip.components(ink)[0][0].min(0).tolist() + \
        clip.components(ink)[0][0].max(0).tolist()
    for got, want in zip((x0, y0, x1, y1), (4_150_000, 4_150_000, 5_850_000, 5_850_000)):
        assert abs(got - want) <= 2 * STEP                     # square to within the steps
    # one island, rings joined inside the copper: one pen lift
    assert sum(isinstance(c, PenDown) for c in planned.job.commands) == 1


def test_a_pour_with_a_clear_cut_out_keeps_its_hole(tmp_path):
    body = ("G36*\nX0Y0D02*\nX10000000Y0D01*\nX10000000Y6000000D01*\nX0Y6000000D01*\n"
            "X0Y0D01*\nG37*\n%LPC*%\n%ADD10R,2X2*%\nD10*\nX5000000Y3000000D03*\n%LPD*%\n")
    planned, ink = plot(tmp_path, body)
    hole = [square(4_000_000, 2_000_000, 6_000_000, 4_000_000)]
    copper = planned.ink.copper.native
    assert clip.area_nm2(clip.intersection(ink, hole)) <= 4 * 2_000_000 * 2_000
    assert clip.area_nm2(clip.intersection(ink, copper)) >= 0.99 * clip.area_nm2(copper)
    assert sum(isinstance(c, PenDown) for c in planned.job.commands) <= 2


def test_a_narrow_trace_near_another_island_is_cut_not_bridged(tmp_path):
    # pad A at x 0..1 mm, pad B at x 1.5..2.5 mm; a 0.1 mm trace from A runs up at
    # x = 1.4 mm, 0.1 mm from B: a 0.3 mm pen there would ink B.
    body = ("%ADD10R,1X1*%\n%ADD11C,0.1*%\nD10*\nX500000Y500000D03*\nX2000000Y2500000D03*\n"
            "D11*\nX500000Y500000D02*\nX1400000Y500000D01*\nX1400000Y4000000D01*\n")
    planned, ink = plot(tmp_path, body)
    pad_a = [square(0, 0, 1_000_000, 1_000_000)]
    pad_b = [square(1_500_000, 2_000_000, 2_500_000, 3_000_000)]
    pieces = [[outer, *holes] for outer, holes in clip.components(ink)]
    touching = [(clip.area_nm2(clip.intersection(p, pad_a)) > 0,
                 clip.area_nm2(clip.intersection(p, pad_b)) > 0) for p in pieces]
    assert (True, False) in touching and (False, True) in touching
    assert (True, True) not in touching                  # no ink joins A to B
    bridges = planned.ink.bridges
    assert bridges and all(b.feature.pos.line == 12 for b in bridges)
    text = " ".join(str(w) for w in planned.ink.warnings)
    assert "would join another copper island at X 1.500" in text
    # the rest of the trace is still drawn (below and above pad B)
    trace_below = [square(1_350_000, 600_000, 1_450_000, 1_500_000)]
    assert clip.area_nm2(clip.difference(trace_below, ink)) == 0


def test_narrow_features_are_warned_with_their_place_and_overdraw(tmp_path):
    planned, _ink = plot(tmp_path, "%ADD11C,0.2*%\nD11*\nX0Y0D02*\nX5000000Y0D01*\n")
    (warning,) = planned.ink.warnings
    assert warning.pos.line == 7
    assert "0.2 mm wide" in warning.message and "0.05 mm overdraw per side" in warning.message


def test_two_pens_widest_first_and_the_narrow_one_reaches_the_corners(tmp_path):
    body = "%ADD10R,3X3*%\nD10*\nX5000000Y5000000D03*\n"
    one, ink_one = plot(tmp_path, body, pens=(800_000,))
    two, ink_two = plot(tmp_path, body, pens=(800_000, 300_000))
    pad = [square(3_500_000, 3_500_000, 6_500_000, 6_500_000)]
    assert list(two.job.pen_labels[k] for k in sorted(set(two.job.pen_changes.values()))) == \
        ["the 0.8 mm pen", "the 0.3 mm pen"]
    assert len(two.job.pen_changes) == 2
    left_one = clip.area_nm2(clip.difference(pad, ink_one))
    assert left_one >= 4 * (1 - math.pi / 4) * 400_000 ** 2 * 0.9
    # the narrow pen reaches into the corners the wide one left (planned areas: the
    # steps are swept with one width only here)
    assert two.ink.copper_nm2 - two.ink.inked_nm2 < (one.ink.copper_nm2 - one.ink.inked_nm2) / 3


@pytest.mark.parametrize("mode", ["ink", "centre"])
def test_modes_plan_the_sample_board(mode):
    from pathlib import Path
    sample = Path(__file__).resolve().parents[2] / "samples" / "led-blinker.gbr"
    planned = plan_file(sample, CONFIG, "auto", options=PlanOptions(mode=mode))
    assert planned.mode == mode and planned.job.mode == mode
    assert (planned.ink is not None) == (mode == "ink")
    if mode == "ink":
        assert planned.plotted.metadata["ink"] and planned.ink.inked_nm2 > 0.99 * planned.ink.copper_nm2
    else:
        assert planned.plotted is planned.program


def test_the_auto_offset_keeps_the_margin_from_the_ink_not_the_flash_point(tmp_path):
    # a 3 mm pad at the origin: its fill reaches 1.35 mm left of the flash point
    path = tmp_path / "pad.gbr"
    path.write_text(HEADER + "%ADD10R,3X3*%\nD10*\nX0Y0D03*\nM02*\n")
    planned = plan_file(path, CONFIG, "auto", options=PlanOptions(mode="ink", pens_nm=(300_000,)))
    assert planned.artwork.proposal_nm == (-1_000_000, -1_000_000)
    assert planned.offset_nm == (-1_348_000 - 1_000_000,) * 2



def test_islands_filled_in_batches_ink_the_same_as_all_at_once():
    # twelve pads and a pour with a pad-shaped hole holding a pad of its own: an island
    # inside a hole is an island too, and no batch may lose or split one
    pads = [square(x * 3 * MM, y * 3 * MM, x * 3 * MM + 2 * MM, y * 3 * MM + MM)
            for x in range(4) for y in range(3)]
    pour = [square(0, 10 * MM, 8 * MM, 16 * MM), square(3 * MM, 12 * MM, 5 * MM, 14 * MM)[::-1],
            square(3_600_000, 12_600_000, 4_400_000, 13_400_000)]
    region = clip.union(pads + pour)
    batches = island_batches(region, most_vertices=10)
    assert len(batches) > 3
    assert sum(len(clip.components(b)) for b in batches) == len(clip.components(region)) == 14
    assert sum(clip.area_nm2(b) for b in batches) == clip.area_nm2(region)

    apart = fill_region(region, 300_000, 1_000, batch_vertices=10)
    together = fill_region(region, 300_000, 1_000, batch_vertices=10 ** 9)
    assert len(apart.paths) == len(together.paths) == 14       # one pen lift an island
    assert apart.rings == together.rings
    both = clip.area_nm2(clip.intersection(apart.ink, together.ink))
    assert both == pytest.approx(clip.area_nm2(together.ink), rel=1e-9)
    assert both == pytest.approx(clip.area_nm2(apart.ink), rel=1e-9)


def test_nearest_many_finds_the_nearest_edge_as_a_full_search_does():
    # rings of many sizes, points near, inside and far from them: every answer is
    # the nearest edge of all (the lowest index among equally near ones)
    rng = np.random.default_rng(5)
    rings = []
    for _ in range(30):
        centre = rng.integers(-20 * MM, 20 * MM, 2)
        angles = np.sort(rng.uniform(0, 2 * np.pi, rng.integers(3, 40)))
        radius = rng.integers(100_000, 3 * MM)
        rings.append(np.rint(centre + radius * np.stack([np.cos(angles), np.sin(angles)], 1))
                     .astype(np.int64))
    rings.append(np.array(square(0, 0, MM, MM)))          # equally near edges: ties
    index = EdgeIndex(rings, cell_nm=240_000)
    points = np.concatenate([rng.integers(-25 * MM, 25 * MM, (400, 2)),
                             rng.integers(-MM, 2 * MM, (100, 2)),
                             [[500_000, 500_000], [10 ** 9, -10 ** 9]]])
    edge, t, distance = index.nearest_many(points, 240_000)
    for p, k, tk, d in zip(points, edge.tolist(), t.tolist(), distance.tolist()):
        tt, dd = point_to_edges(p.astype(np.float64), index.a, index.b)
        best = int(np.argmin(dd))
        assert (k, tk, d) == (best, float(tt[best]), float(dd[best]))
        assert index.nearest((int(p[0]), int(p[1])), 240_000) == (k, tk, d)


def test_inked_area_batch_by_batch_is_the_area_over_the_whole_board():
    # a real layer with hundreds of islands: the fill's ink, plus strokes of another
    # pen that cross islands and stick out of the copper
    layer = CORPUS / "allegro" / "tracespace-371" / "l1_primary.art"
    region = dark_geometry(read_file(layer), 1_000).native
    fill = fill_region(region, 300_000, 1_000, edge_margin_nm=2_000)
    assert len(fill.parts) > 3
    low = np.min([np.min(r, axis=0) for r in region], axis=0)
    high = np.max([np.max(r, axis=0) for r in region], axis=0)
    lines = [np.array([low, high]), np.array([[low[0], high[1]], [high[0], low[1]]])]
    extra = clip.stroke(lines, 400_000, 1_000)
    for more in ([], extra):
        whole = clip.area_nm2(clip.intersection(clip.union(fill.ink, more), region))
        assert inked_area_nm2([fill], more, region) == pytest.approx(whole, rel=1e-8)
        # counted in two shares (ink_coverage: the batches other ink meets elsewhere)
        skip = [k % 3 == 0 for k in range(len(fill.recipes))]
        shares = inked_area_nm2([fill], more, region, skip) + inked_area_nm2(
            [fill], more, region, [not s for s in skip])
        assert shares == pytest.approx(whole, rel=1e-8)
    for batch, recipe in fill.recipes:      # a recipe's area, without its polygons
        assert recipe.ink_area_nm2() == pytest.approx(
            clip.area_nm2(clip.intersection(recipe.ink(), batch)), rel=1e-8, abs=1e3)
    second = fill_region(extra, 200_000, 1_000)
    whole = clip.area_nm2(clip.intersection(clip.union(fill.ink, second.ink), region))
    assert inked_area_nm2([fill, second], [], region) == pytest.approx(whole, rel=1e-8)
    assert inked_area_nm2([fill], extra, region) > inked_area_nm2([fill], [], region)


def test_the_rings_stop_where_the_shrunk_area_has_no_ring_of_three_points():
    # a 2 mm square with spacing 0.4 mm: depths at 0, 0.4, 0.8 mm in (2, 1.2, 0.4 mm
    # squares); the next offset leaves nothing. A set of only degenerate rings (two
    # points) is no area at all: no depth, not a depth with no ring.
    from galileo_cnc.plan.ink.fill import _concentric
    square = [[[0, 0], [2 * MM, 0], [2 * MM, 2 * MM], [0, 2 * MM]]]
    areas = _concentric(square, 400_000, 1_000)
    sides = [int(np.ptp(np.asarray(a[0])[:, 0])) for a in areas]
    assert sides == [2 * MM, 1_200_000, 400_000]
    assert _concentric([[[0, 0], [MM, 0]]], 400_000, 1_000) == []


def _segments(path: np.ndarray) -> list[tuple]:
    """The path's segments, each as (a, b) with a <= b (either way drawn)."""
    points = [tuple(p) for p in path.tolist()]
    return [tuple(sorted(pair)) for pair in zip(points, points[1:]) if pair[0] != pair[1]]


def test_a_walk_draws_its_longest_join_once_and_every_other_twice():
    # a 6 x 4 mm pour with two holes: rings at several depths, joined into one tree
    pour = [square(0, 0, 6 * MM, 4 * MM), square(MM, MM, 2 * MM, 3 * MM)[::-1],
            square(4 * MM, MM, 5 * MM, 3 * MM)[::-1]]
    fill = fill_region(clip.union(pour), 300_000, 1_000)
    assert len(fill.paths) == 1 and fill.rings > 3
    walk = fill.paths[0]
    counts: dict[tuple, int] = {}
    for segment in _segments(walk):
        counts[segment] = counts.get(segment, 0) + 1
    assert max(counts.values()) == 2           # joins (and gap strokes): there and back
    # open: it ends across the join it draws once, where it first came to its end
    end = tuple(walk[-1].tolist())
    first = int(np.flatnonzero(np.all(walk == walk[-1], axis=1))[0])
    opened = tuple(sorted((tuple(walk[first - 1].tolist()), end)))
    assert not np.array_equal(walk[0], walk[-1]) and counts[opened] == 1
    # that one saves most: no segment drawn twice is longer than it (and the gap
    # stroke the walk starts with, when it does not start round a ring)
    saved = math.dist(*opened)
    if not np.array_equal(walk[0], walk[first - 1]):
        saved += sum(math.dist(*s) for s in _segments(walk[:first]))
    assert all(math.dist(*s) <= saved + 1 for s, n in counts.items() if n == 2)


def test_the_walker_crosses_every_join_and_comes_back_round_each_ring():
    # an outer ring O with two stops on its first edge, a ring A joined at its vertex
    # 0 and a gap stroke S joined at its first point; column 2 is the inner class
    outer = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]])
    ring = np.array([[3, 3, 1], [7, 3, 1], [7, 7, 1], [3, 7, 1]])
    stroke = np.array([[8, 2, 0], [9, 2, 0]])
    stops = [[_Stop(0, 0.8, (8, 0), join=1, other=2), _Stop(0, 0.3, (3, 0), join=0, other=1)],
             [_Stop(0, 0.0, (3, 3), join=0, other=0)],
             [_Stop(0, 0.0, (8, 2), join=1, other=0)]]
    walker = _Walker([outer, ring, stroke], stops)
    done = [False] * 3
    walk, = walker.gather([[walker.tree(0, done)]])     # the tree's rows, as points
    assert walk[:, :2].tolist() == [
        [0, 0], [3, 0], [3, 3], [7, 3], [7, 7], [3, 7], [3, 3], [3, 0],   # along, A round
        [8, 0], [8, 2], [9, 2], [8, 2], [8, 0],                            # S there and back
        [10, 0], [10, 10], [0, 10], [0, 0]]                                # O closed
    assert done == [True, True, True]
    # A's stop sits on its vertex 0: the point keeps that vertex's inner class
    assert walk[2].tolist() == [3, 3, 1] and walk[1].tolist() == [3, 0, 0]
    # opened at the join O-A: A round from its stop, then O from the other end of it,
    # past the stroke (its stops at places after the entry come first)
    done = [False] * 3
    number = walker.stop_number(1, stops[1][0])
    head = walker.tree(1, done, number)
    rest = walker.tree(0, done, walker.back[number])
    head, rest = walker.gather([[head], [rest]])
    assert head[:, :2].tolist() == [[3, 3], [7, 3], [7, 7], [3, 7], [3, 3]]
    assert rest[:, :2].tolist() == [[3, 0], [8, 0], [8, 2], [9, 2], [8, 2], [8, 0],
                                    [10, 0], [10, 10], [0, 10], [0, 0], [3, 0]]


#: A ring of freeduino.sol's pen-centre area (0.3 mm pen), moved to the origin: an
#: island 11.3 mm long and 39 um thick. Cleaned at 2 um, Clipper turns it round.
SLIVER = [[19640, 15580], [51122, 30443], [99846, 38464], [11246764, 38464],
          [11281349, 34477], [11322110, 17961], [11288987, 37834], [11287609, 38317],
          [11279201, 39264], [46609, 39264], [38331, 38331], [0, 0]]


def test_cleaning_never_turns_a_thin_island_round_so_the_offset_inside_still_comes():
    import pyclipper

    assert pyclipper.Area(SLIVER) > 0
    assert pyclipper.Area(pyclipper.CleanPolygons([SLIVER], 2_000.0)[0]) < 0   # the trap
    cleaned = clip.clean([SLIVER], 8_000)
    assert len(cleaned) == 1 and pyclipper.Area(cleaned[0]) > 0
    # the sliver holds the set's lowest vertex: turned round, it turned the whole set
    # round in Clipper's offset, and a pour above it got no rings inside E0
    pour = [[0, MM], [10 * MM, MM], [10 * MM, 11 * MM], [0, 11 * MM]]
    inner = clip.offset(clip.clean([pour, SLIVER], 8_000), -240_000, 8_000, cleaned=True)
    assert clip.area_nm2(inner) == pytest.approx((10 * MM - 480_000) ** 2, rel=1e-3)


def test_strokes_in_strips_cover_what_one_stroke_covers():
    # random polylines and dots; strips of 50: overlapping sets that positive winding
    # (every boolean in clip.py) reads as the one stroke's union
    rng = np.random.default_rng(3)
    lines = [np.cumsum(rng.integers(-400_000, 400_000, size=(int(rng.integers(1, 6)), 2)),
                       axis=0) + rng.integers(0, 40 * MM, size=2) for _ in range(700)]
    whole = clip.stroke(lines, 150_000, 1_000)
    strips = clip.stroke_in_strips(lines, 150_000, 1_000, per_strip=50)
    assert len(strips) > len(whole)
    assert clip.area_nm2(clip.union(strips)) == pytest.approx(clip.area_nm2(whole), rel=1e-9)
    window = [[[5 * MM, 5 * MM], [30 * MM, 5 * MM], [30 * MM, 30 * MM], [5 * MM, 30 * MM]]]
    assert clip.area_nm2(clip.intersection(strips, window)) == pytest.approx(
        clip.area_nm2(clip.intersection(whole, window)), rel=1e-9)
