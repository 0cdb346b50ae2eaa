"""Native arcs for ink pen paths (galileo_cnc/plan/ink/arcs.py): runs of polyline
vertices on one circle come back as ARC_CW/ARC_CCW segments, everything else as lines.

Each output is walked by `walk`, which checks every guarantee independently of the
fitting code: end points are input vertices, replaced vertices and edge midpoints are
within the tolerance of the arc, angles progress one way by less than 90 degrees an
edge and at most 270 degrees an arc, the arc is really curved."""

from __future__ import annotations

import math
import random

import numpy as np
import pyclipper
import pytest

from galileo_cnc.plan.ink.arcs import fit_arcs, fit_paths
from galileo_cnc.plan.curves import chord_step
from galileo_cnc.plan.ink.shapes import (
    capsules,
    circle_segments,
    circle_template,
)
from galileo_cnc.program.ops import OpKind

LINE, CW, CCW = int(OpKind.LINE), int(OpKind.ARC_CW), int(OpKind.ARC_CCW)
TOL = 1_000
MM = 1_000_000


def walk(points, segments, tol=TOL, closed=False, min_edges=4) -> list[dict]:
    """Check `segments` against `points` and every guarantee; return the arcs as dicts
    (first, last: vertex indices; kind; centre; radius; sweep: signed radians)."""
    path = [tuple(p) for p in np.asarray(points).tolist()]
    if closed:
        path.append(path[0])
    arcs = []
    k = 0
    for segment in segments:
        assert len(segment) == 5 and all(type(v) is int for v in segment), segment
        kind, x, y, i, j = segment
        if kind == LINE:
            assert (i, j) == (0, 0)
            k += 1
            assert path[k] == (x, y), f"line {segment} does not end at vertex {k}"
            continue
        assert kind in (CW, CCW), segment
        end = path.index((x, y), k + 1)                  # an input vertex, further on
        assert end - k >= min_edges
        sx, sy = path[k]
        cx, cy = sx + i, sy + j
        r_start, r_end = math.hypot(sx - cx, sy - cy), math.hypot(x - cx, y - cy)
        assert abs(r_start - r_end) <= tol
        assert r_start <= 1e9
        direction = 1 if kind == CCW else -1
        sweep = 0.0
        for q in range(k, end):
            (ax, ay), (bx, by) = path[q], path[q + 1]
            for px, py in ((bx, by), ((ax + bx) / 2, (ay + by) / 2)):
                d = math.hypot(px - cx, py - cy)
                assert abs(d - r_start) <= tol and abs(d - r_end) <= tol, (segment, q, d)
            turn = math.atan2((ax - cx) * (by - cy) - (ay - cy) * (bx - cx),
                              (ax - cx) * (bx - cx) + (ay - cy) * (by - cy))
            assert 0 < direction * turn < math.pi / 2, (segment, q, turn)
            sweep += turn
        assert abs(sweep) <= 1.5 * math.pi + 1e-9
        assert (x, y) != (sx, sy)
        assert r_start * (1 - math.cos(abs(sweep) / 2)) > tol, "not curved enough"
        arcs.append({"first": k, "last": end, "kind": kind, "centre": (cx, cy),
                     "radius": r_start, "sweep": sweep})
        k = end
    assert k == len(path) - 1, "the segments do not reach the end of the path"
    return arcs


def rounded(xy) -> np.ndarray:
    return np.rint(np.asarray(xy, dtype=np.float64)).astype(np.int64)


def arc_vertices(cx, cy, r, a0, sweep, count=None) -> list[tuple[float, float]]:
    """count + 1 points on a circle from angle a0 over a signed sweep (float); by
    default as many chords as the tolerance needs (as shapes.py makes them)."""
    if count is None:
        count = math.ceil(abs(sweep) / chord_step(r, TOL))
    return [(cx + r * math.cos(a0 + sweep * t / count), cy + r * math.sin(a0 + sweep * t / count))
            for t in range(count + 1)]


@pytest.mark.parametrize("ccw", [True, False])
def test_a_1_mm_round_pad_becomes_a_few_arcs(ccw):
    centre = (12_345_678, -3_210_987)
    ring = circle_template(1 * MM, TOL) + centre
    assert len(ring) == 52
    if not ccw:
        ring = ring[::-1]
    segments = fit_arcs(ring, TOL, closed=True)
    arcs = walk(ring, segments, closed=True)
    assert 2 <= len(arcs) == len(segments) <= 4
    assert {a["kind"] for a in arcs} == {CCW if ccw else CW}
    for a in arcs:
        assert math.dist(a["centre"], centre) <= TOL
        assert abs(a["radius"] - 0.5 * MM) <= TOL
    assert sum(a["sweep"] for a in arcs) == pytest.approx(2 * math.pi if ccw else -2 * math.pi)


def test_a_rectangle_stays_four_lines():
    ring = np.array([[0, 0], [2 * MM, 0], [2 * MM, MM], [0, MM]])
    assert fit_arcs(ring, TOL, closed=True) == [(LINE, 2 * MM, 0, 0, 0), (LINE, 2 * MM, MM, 0, 0),
                                                (LINE, 0, MM, 0, 0), (LINE, 0, 0, 0, 0)]


@pytest.mark.parametrize("seed", range(5))
def test_a_straight_run_with_noise_below_the_tolerance_stays_lines(seed):
    rng = np.random.default_rng(seed)
    t = np.arange(300) * 20_000.0
    line = rounded(np.stack([1e6 + t * 0.8, 2e6 + t * 0.6], axis=1))
    line += rng.integers(-250, 251, size=line.shape)
    segments = fit_arcs(line, TOL)
    assert all(s[0] == LINE for s in segments)
    assert [s[1:3] for s in segments] == [tuple(p) for p in line[1:].tolist()]


@pytest.mark.parametrize("angle", [0, 30, 90, 135, 200, 333])
def test_a_capsule_is_two_lines_and_arcs(angle):
    width, length = 250_000, 3 * MM
    a = math.radians(angle)
    start = np.array([[5 * MM, 7 * MM]])
    end = start + rounded([[length * math.cos(a), length * math.sin(a)]])
    ring = capsules(circle_template(width, TOL), start, end)[0]
    segments = fit_arcs(ring, TOL, closed=True)
    arcs = walk(ring, segments, closed=True)
    lines = [s for s in segments if s[0] == LINE]
    assert len(arcs) >= 2 and len(lines) == 2
    ends = [tuple(start[0]), tuple(end[0])]
    for arc in arcs:                      # every arc is round one end of the trace
        assert min(math.dist(arc["centre"], e) for e in ends) <= TOL
        assert abs(arc["radius"] - width / 2) <= TOL
    assert sum(abs(a["sweep"]) for a in arcs) == pytest.approx(2 * math.pi, abs=0.2)


def test_an_s_bend_is_an_arc_a_line_and_an_arc_the_other_way():
    r1, r2, straight = 2 * MM, 1.5 * MM, 3 * MM
    # quarter turn left about (0, r1) from (0, 0), then up, then a quarter turn right
    first = arc_vertices(0, r1, r1, -math.pi / 2, math.pi / 2)
    x0, y0 = first[-1]
    second = arc_vertices(x0 + r2, y0 + straight, r2, math.pi, -math.pi / 2)
    path = rounded(first + second)
    segments = fit_arcs(path, TOL)
    arcs = walk(path, segments)
    kinds = [s[0] for s in segments]
    assert kinds[0] == CCW and kinds[-1] == CW and LINE in kinds
    line_at = kinds.index(LINE)
    assert set(kinds[:line_at]) == {CCW} and set(kinds[line_at + 1:]) == {CW}
    assert kinds.count(LINE) == 1
    assert segments[line_at][1:3] == tuple(path[len(first)].tolist())   # the straight
    for arc in arcs:
        true_centre = (0, r1) if arc["kind"] == CCW else (x0 + r2, y0 + straight)
        assert math.dist(arc["centre"], true_centre) <= TOL
    assert arcs[0]["first"] == 0 and arcs[-1]["last"] == len(path) - 1


def test_two_micron_noise_on_a_10_mm_radius_still_gives_arcs():
    rng = np.random.default_rng(7)
    radius = 10 * MM
    n = circle_segments(radius, TOL)
    ring = rounded(arc_vertices(0, 0, radius, 0.3, 2 * math.pi, n)[:-1])
    ring += rng.integers(-2, 3, size=ring.shape)
    segments = fit_arcs(ring, TOL, closed=True)
    arcs = walk(ring, segments, closed=True)
    assert 2 <= len(arcs) == len(segments) <= 4
    assert all(math.dist(a["centre"], (0, 0)) <= TOL for a in arcs)


def test_fewer_than_min_edges_curved_edges_stay_lines():
    # straight, three chords of a 1 mm circle within the tolerance, straight on
    step = chord_step(MM, TOL)
    bend = arc_vertices(0, MM, MM, -math.pi / 2, 3 * step, 3)
    (x, y), heading = bend[-1], 3 * step
    path = rounded([(-2 * MM, 0)] + bend + [(x + 2 * MM * math.cos(heading),
                                             y + 2 * MM * math.sin(heading))])
    assert all(s[0] == LINE for s in fit_arcs(path, TOL))
    arcs = walk(path, fit_arcs(path, TOL, min_edges=3), min_edges=3)
    assert [(a["first"], a["last"], a["kind"]) for a in arcs] == [(1, 4, CCW)]


def test_rounded_corners_of_a_pyclipper_offset_become_arcs():
    offset = pyclipper.PyclipperOffset(arc_tolerance=250)
    offset.AddPath([[0, 0], [MM, 0], [MM, MM], [0, MM]], pyclipper.JT_ROUND,
                   pyclipper.ET_CLOSEDPOLYGON)
    ring = np.array(offset.Execute(200_000)[0], dtype=np.int64)
    arcs = walk(ring, fit_arcs(ring, TOL, closed=True), closed=True)
    corners = {(0, 0), (MM, 0), (MM, MM), (0, MM)}
    near = {min(corners, key=lambda c: math.dist(c, a["centre"])) for a in arcs}
    assert near == corners                                     # each corner is an arc
    assert all(math.dist(a["centre"], min(corners, key=lambda c: math.dist(c, a["centre"])))
               <= TOL for a in arcs)
    # the corner that points[0] cuts may leave an edge as a line; the rest is round
    assert sum(abs(a["sweep"]) for a in arcs) > 2 * math.pi - 0.2


def random_shape(rng: random.Random) -> tuple[np.ndarray, bool]:
    """A turtle path of random straights (sometimes cut into collinear pieces),
    arcs (random radius, sweep, direction and chord count; some of them spirals)
    and sharp corners, with vertex noise now and then."""
    x, y = rng.uniform(-5e7, 5e7), rng.uniform(-5e7, 5e7)
    heading = rng.uniform(0, 2 * math.pi)
    points = [(x, y)]
    for _ in range(rng.randint(1, 8)):
        roll = rng.random()
        if roll < 0.35:
            length, pieces = rng.uniform(5e3, 3e6), rng.choice([1, 1, 1, 2, 5])
            for _p in range(pieces):
                x += length / pieces * math.cos(heading)
                y += length / pieces * math.sin(heading)
                points.append((x, y))
        elif roll < 0.9:
            radius = math.exp(rng.uniform(math.log(3e3), math.log(5e7)))
            sweep = rng.choice([-1, 1]) * rng.uniform(0.05, 2.2 * math.pi)
            chord = min(math.pi / 2, 2 * math.acos(max(-1.0, 1 - rng.uniform(50, 1200) / radius)))
            count = max(1, min(400, math.ceil(abs(sweep) / chord)))
            left = 1 if sweep > 0 else -1
            cx = x - left * radius * math.sin(heading)
            cy = y + left * radius * math.cos(heading)
            a0 = math.atan2(y - cy, x - cx)
            # sometimes a spiral (the radius drifts along the sweep): no circle fits it all
            drift = rng.choice([0.0, 0.0, 0.0, rng.uniform(-0.4, 0.4)])
            for t in range(1, count + 1):
                r = radius * (1 + drift * t / count)
                a = a0 + sweep * t / count
                points.append((cx + r * math.cos(a), cy + r * math.sin(a)))
            x, y = points[-1]
            heading = a0 + sweep + left * math.pi / 2
        else:
            heading += rng.uniform(-3, 3)
    path = rounded(points)
    noise = rng.choice([0, 0, 1, 3, 50])
    if noise:
        path += np.array([[rng.randint(-noise, noise) for _ in range(2)] for _ in path],
                         dtype=np.int64)
    keep = np.concatenate([[True], np.any(np.diff(path, axis=0) != 0, axis=1)])
    path = path[keep]
    closed = len(path) >= 3 and rng.random() < 0.4
    if len(path) < 2:
        path = np.array([[0, 0], [1, 1]], dtype=np.int64)
    return path, closed


@pytest.mark.parametrize("seed", range(4))
def test_random_shapes_keep_every_guarantee(seed):
    rng = random.Random(seed)
    arcs_seen = 0
    for _ in range(60):
        path, closed = random_shape(rng)
        tol = rng.choice([TOL, TOL, 250, 5_000])
        min_edges = rng.choice([4, 4, 2, 3, 8])
        segments = fit_arcs(path, tol, closed=closed, min_edges=min_edges)
        arcs_seen += len(walk(path, segments, tol, closed, min_edges))
        assert segments == fit_arcs(path.copy(), tol, closed=closed, min_edges=min_edges)
    assert arcs_seen > 50                  # the shapes are mostly curves: arcs do come back


def test_points_as_lists_and_reversed_views_work():
    ring = circle_template(2 * MM, TOL)
    assert fit_arcs(ring.tolist(), closed=True) == fit_arcs(ring, closed=True)
    walk(ring[::-1], fit_arcs(ring[::-1], closed=True), closed=True)
    assert fit_arcs(np.array([[0, 0], [5, 7]])) == [(LINE, 5, 7, 0, 0)]


@pytest.mark.parametrize("points, closed, kwargs", [
    (np.zeros((1, 2), np.int64), False, {}),
    (np.zeros((2, 2), np.int64), True, {}),
    (np.zeros((4, 3), np.int64), False, {}),
    (np.zeros((4, 2), np.int64), False, {"tolerance_nm": 0}),
    (np.zeros((4, 2), np.int64), False, {"min_edges": 1}),
])
def test_bad_input_is_refused(points, closed, kwargs):
    with pytest.raises(ValueError):
        fit_arcs(points, closed=closed, **kwargs)


def test_fit_paths_answers_as_fit_arcs_does_path_by_path():
    # pen paths as the fill makes them: closed rings (rounded squares, circles), open
    # polylines with an ellipse's vertices, two-point strokes, dots, a spiral: all
    # laid end to end in one array, no arc may run from one path into the next
    rng = random.Random(11)
    paths = []
    for k in range(40):
        centre = np.array([rng.randrange(-50, 50), rng.randrange(-50, 50)]) * MM
        ring = circle_template(rng.randrange(200_000, 3 * MM), TOL) + centre
        if k % 4 == 0:
            paths.append(np.vstack([ring, ring[:1]]))                  # closed
        elif k % 4 == 1:
            t = np.linspace(0, 2.5, 60)
            paths.append(np.rint(np.stack([3 * MM * np.cos(t), MM * np.sin(t)], 1)).astype(np.int64)
                         + centre)                                      # ellipse, open
        elif k % 4 == 2:
            paths.append(centre[None, :] + np.array([[0, 0], [MM, 0]]))  # a stroke
            paths.append(centre[None, :])                               # a dot
        else:
            t = np.linspace(0, 12, 400)
            r = MM + 100_000 * t
            paths.append(np.rint(np.stack([r * np.cos(t), r * np.sin(t)], 1)).astype(np.int64)
                         + centre)                                      # spiral
    together = fit_paths(paths)
    assert len(together) == len(paths)
    arcs = 0
    for path, got in zip(paths, together):
        if len(path) == 1:
            assert got is None
            continue
        closed = len(path) > 3 and np.array_equal(path[0], path[-1])
        points = path[:-1] if closed else path
        assert got == fit_arcs(points, closed=closed)
        arcs += len(walk(points, got, closed=closed))
    assert arcs > 40                     # the circles became arcs


def test_fit_paths_rejects_what_fit_arcs_rejects():
    with pytest.raises(ValueError, match="tolerance"):
        fit_paths([np.array([[0, 0], [1, 0]])], tolerance_nm=0)
    with pytest.raises(ValueError, match="shape"):
        fit_paths([np.array([0, 1, 2])])
    assert fit_paths([]) == []


def test_per_vertex_tolerances_hold_each_arc_to_its_finest_vertex():
    # a 2 mm circle made with 4 um chords (as the fill's inner rings are): at 1 um it
    # is lines, at its own 4 um it is arcs within 4 um; one vertex held to 1 um keeps
    # every arc through it within 1 um, i.e. lines there
    radius, coarse = 2 * MM, 4 * TOL
    n = circle_segments(radius, coarse)
    ring = rounded(arc_vertices(0, 0, radius, 0.1, 2 * math.pi, n)[:-1])
    path = np.vstack([ring, ring[:1]])
    fine, = fit_paths([path])
    assert all(s[0] == LINE for s in fine)
    every = np.full(len(path), coarse)
    loose, = fit_paths([path], coarse=[every])
    arcs = walk(ring, loose, tol=coarse, closed=True)
    assert arcs and all(math.dist(a["centre"], (0, 0)) <= coarse for a in arcs)
    every[5] = TOL
    mixed, = fit_paths([path], coarse=[every])
    arcs = walk(ring, mixed, tol=coarse, closed=True)
    assert arcs and not any(a["first"] < 5 < a["last"] for a in arcs)
