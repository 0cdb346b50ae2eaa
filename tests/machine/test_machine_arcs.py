"""Arc stepping: within 1/2 step of the circle, exact end, full circles, loop == numpy."""

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings, strategies as st

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import ArcTo, SetFeed
from galileo_cnc.machine import ReferenceMachine
from galileo_cnc.machine.analysis import event_positions, segment_radial_deviation
from galileo_cnc.machine.arcs import (BAND_RHO_Q15, BAND_SIN_Q16, N_BANDS, arc_geometry,
                                      arc_points, classify, round_sqrt)
from galileo_cnc.machine.blocks import ArcMove
from galileo_cnc.machine.lines import bresenham_points
from galileo_cnc.machine.stepper import ArcStepper

BIG = MachineConfig(x_travel_mm=500, y_travel_mm=500)
C = (40000, 40000)
ARC_BOUND = 0.5  # steps: every point of an arc on its circle, vertices and the moves between


def run_arc(start, end, cw, backend="numpy", feed=800):
    """Arc around C from C + start to C + end (relative coordinates)."""
    m = ReferenceMachine(BIG, (C[0] + start[0], C[1] + start[1], 0))
    cmd = ArcTo(C[0] + end[0], C[1] + end[1], -start[0], -start[1], cw)
    return m.run([SetFeed(feed), cmd], backend=backend)


def path(trace, start):
    _t, pos = event_positions(trace, (C[0] + start[0], C[1] + start[1], 0))
    return np.vstack([[C[0] + start[0], C[1] + start[1]], pos[:, :2]]) - np.asarray(C)


def geometry_points(g):
    """Closed-form points of the whole move (arc then correction), relative."""
    pts, _keys = arc_points(g)
    corr = bresenham_points(g.p_star, g.correction)
    return np.vstack([[g.start], pts, corr])


def loop_points(g):
    st_ = ArcStepper(ArcMove((0, 0, 0), (0, 0), g, tuple(range(len(g.band_v))), g.n, 0, 0))
    c = list(g.start)
    out = [tuple(c)]
    for _ in range(g.n):
        steps, _base = st_.event()
        for a, d in steps:
            c[a] += d
        out.append(tuple(c))
    return np.array(out)


def on_circle_pairs(r2):
    r = math.isqrt(r2) + 1
    return [(x, y) for x in range(-r, r + 1) for y in range(-r, r + 1) if x * x + y * y == r2]


@pytest.mark.parametrize("r2", [1, 2, 4, 5, 8, 9, 10, 13, 25, 50, 65, 85, 125, 169, 325])
def test_small_circles_exhaustive(r2):
    pts = on_circle_pairs(r2)
    for s in pts:
        for e in pts:
            for ccw in (True, False):
                g = arc_geometry(s, e, ccw)
                closed = geometry_points(g)
                assert np.array_equal(closed, loop_points(g))
                assert tuple(closed[-1]) == e
                assert g.n_corr == 0  # end on the circle: no correction
                dev = segment_radial_deviation(closed, (0, 0), math.sqrt(r2))
                assert dev <= ARC_BOUND
                if s == e:
                    assert g.n_arc >= 4  # a full circle, not nothing


def angle_travel(points):
    ang = np.unwrap(np.arctan2(points[:, 1].astype(float), points[:, 0].astype(float)))
    return ang[-1] - ang[0], np.diff(ang)


radii = st.one_of(st.integers(1, 40), st.integers(40, 3000), st.integers(3000, 30000))
angles = st.floats(0, 2 * math.pi, allow_nan=False)


@settings(max_examples=120, deadline=None)
@given(radii, angles, angles, st.booleans(), st.sampled_from([True, False]))
def test_random_arcs_on_circle(radius, a0, a1, cw, full):
    s = (round(radius * math.cos(a0)), round(radius * math.sin(a0)))
    assume(s != (0, 0))
    r2 = s[0] ** 2 + s[1] ** 2
    if full:
        e = s
    else:  # an end point exactly on the circle: nearest lattice point that is on it
        e = s if radius > 3000 else min(on_circle_pairs(r2), key=lambda p: (
            (p[0] - radius * math.cos(a1)) ** 2 + (p[1] - radius * math.sin(a1)) ** 2))
    g = arc_geometry(s, e, not cw)
    assert g.n_corr == 0
    closed = geometry_points(g)
    assert tuple(closed[-1]) == e
    assert segment_radial_deviation(closed, (0, 0), math.sqrt(r2)) <= ARC_BOUND
    travel, steps = angle_travel(closed)
    sign = -1 if cw else 1
    assert np.all(sign * steps >= -1e-12)  # never runs backwards
    if e == s:
        assert abs(abs(travel) - 2 * math.pi) < 1e-9
    if radius <= 3000:
        assert np.array_equal(closed, loop_points(g))


@settings(max_examples=100, deadline=None)
@given(st.integers(5, 3000), angles, angles, st.integers(-4, 4), st.booleans())
@example(450, 5.25, 3.9375, -4, False)  # near a diagonal: the correction is 6 steps for 3.98
def test_end_off_the_circle_gets_a_straight_correction(radius, a0, a1, dr, cw):
    s = (round(radius * math.cos(a0)), round(radius * math.sin(a0)))
    assume(s != (0, 0))
    r_end = radius + dr
    e = (round(r_end * math.cos(a1)), round(r_end * math.sin(a1)))
    g = arc_geometry(s, e, not cw)
    closed = geometry_points(g)
    assert tuple(closed[-1]) == e
    assert np.array_equal(closed, loop_points(g))
    rs = math.sqrt(g.r2)
    arc_part = closed[:g.n_arc + 1]
    assert segment_radial_deviation(arc_part, (0, 0), rs) <= ARC_BOUND
    # The correction is short: it closes the radius mismatch, measured along u on
    # the end's side, so up to sqrt(2) times it near a diagonal (motion.md 4.6).
    re = math.hypot(*e)
    assert g.n_corr <= math.sqrt(2) * abs(re - rs) + 2
    assert segment_radial_deviation(closed, (0, 0), rs) <= abs(re - rs) + 1


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 1500), angles, angles, st.booleans(), st.integers(-2, 2))
def test_arc_trace_vectorised_equals_loop(radius, a0, a1, cw, dr):
    s = (round(radius * math.cos(a0)), round(radius * math.sin(a0)))
    assume(s != (0, 0))
    e = (round((radius + dr) * math.cos(a1)), round((radius + dr) * math.sin(a1)))
    a = run_arc(s, e, cw)
    b = run_arc(s, e, cw, backend="loop")
    assert a.same_steps(b) and a.total_ticks == b.total_ticks
    assert a.final_position == (C[0] + e[0], C[1] + e[1], 0)


def test_arc_of_a_few_steps_and_quarter_circles():
    for s, e, cw in [((10, 0), (9, 4), False), ((10, 0), (0, 10), False), ((10, 0), (0, -10), True),
                     ((0, 3), (-3, 0), False), ((1, 0), (0, 1), False), ((1, 0), (1, 0), True)]:
        trace = run_arc(s, e, cw)
        assert trace.final_position == (C[0] + e[0], C[1] + e[1], 0)
        pts = path(trace, s)
        assert segment_radial_deviation(pts, (0, 0), math.hypot(*s)) <= ARC_BOUND


def test_diagonal_points_belong_to_the_side_entered_next():
    # ccw through (5, 5): x shrinks next, so x is major (TOP); cw: y major (RIGHT).
    assert classify(5, 5, True) == 1 and classify(5, 5, False) == 0
    assert classify(-5, 5, True) == 2 and classify(-5, 5, False) == 1
    assert round_sqrt(0) == 0 and round_sqrt(2) == 1 and round_sqrt(3) == 2


def test_band_tables_follow_their_formula():
    assert N_BANDS == 32
    t = [math.sqrt(1 - 2 ** (-b / 32)) for b in range(32)] + [math.sqrt(0.5)]
    assert list(BAND_SIN_Q16) == [round(x * 65536) for x in t[:32]]
    rho = [round((math.asin(t[b + 1]) - math.asin(t[b])) / (t[b + 1] - t[b]) * 32768)
           for b in range(32)]
    assert list(BAND_RHO_Q15) == rho


def test_cordic_table_follows_its_formula_and_matches_the_firmware():
    import re
    from pathlib import Path
    from galileo_cnc.machine.arcs import ATAN_Q32, TWO_PI_Q29
    assert list(ATAN_Q32) == [round(math.atan(2.0 ** -i) / (2 * math.pi) * 2 ** 32)
                              for i in range(len(ATAN_Q32))]
    assert TWO_PI_Q29 == round(2 * math.pi * 2 ** 29)
    src = (Path(__file__).resolve().parents[2] / "firmware" / "galileo" / "arcs.cpp").read_text()
    body = re.search(r"ATAN_Q32\[N_ATAN\] PROGMEM = \{([^}]*)\}", src).group(1)
    assert [int(v) for v in body.replace("\n", " ").split(",")] == list(ATAN_Q32)
    assert f"#define N_ATAN {len(ATAN_Q32)}" in src
    assert f"#define TWO_PI_Q29 {TWO_PI_Q29}ULL" in src


coord = st.one_of(st.integers(-46341, 46341), st.integers(-2 ** 31 + 1, 2 ** 31 - 1))


@settings(max_examples=300, deadline=None)
@given(coord, coord)
@example(1, 0)
@example(-1, 0)
@example(0, -1)
@example(-46341, -1)
@example(-(2 ** 31 - 1), 2 ** 31 - 1)
def test_integer_angle_is_within_1e_7_rad(x, y):
    from galileo_cnc.machine.arcs import angle_q32
    assume((x, y) != (0, 0))
    a = angle_q32(x, y)
    assert 0 <= a < 2 ** 32
    d = (a / 2 ** 32 * 2 * math.pi - math.atan2(y, x)) % (2 * math.pi)
    assert min(d, 2 * math.pi - d) < 1e-7


def length_error_bound(r2: int) -> float:
    """How far length_q15 may be from r x the swept angle, in steps, from its arithmetic
    (docs/motion.md §5.3): r times the angle's error (the CORDIC's, below 1e-7 rad as
    test_integer_angle_is_within_1e_7_rad asserts, and sweep >> 4 dropping up to 15 of
    2^32 turn) and times TWO_PI_Q29's rounding (0.14 of 2^29 per turn); r16's floor (under
    2^-16 step times the angle, at most 2 pi); circ16's rounding (2^-17 step) and L's
    (2^-16 step)."""
    r = math.sqrt(r2)
    return r * (1e-7 + 2 * math.pi * 15 / 2 ** 32 + 2 * math.pi * 0.14 / 2 ** 29) \
        + 2 * math.pi / 2 ** 16 + 2 ** -17 + 2 ** -16


@settings(max_examples=100, deadline=None)
@given(radii, angles, angles, st.booleans(), st.integers(-3, 3))
# found by hypothesis: r2 = 645274129, start (-25148, 3585), end (-666, -25393), ccw;
# 0.0012 step off, the CORDIC's 2.5e-8 rad and sweep >> 4's floor adding up at r = 25402
@example(25402, 2.9999906646987804, 4.6861672913005545, False, 0)
def test_arc_length_and_scale_follow_the_walked_arc(radius, a0, a1, cw, dr):
    """length_q15 = r x the swept angle start -> P*; weight = sum of the events' band rho."""
    s = (round(radius * math.cos(a0)), round(radius * math.sin(a0)))
    assume(s != (0, 0))
    e = (round((radius + dr) * math.cos(a1)), round((radius + dr) * math.sin(a1)))
    g = arc_geometry(s, e, not cw)
    if g.n_arc == 0:
        assert g.scale == 1 << 20
        return
    pts, keys = arc_points(g)
    p = np.vstack([[g.start], pts]).astype(float)
    ang = np.unwrap(np.arctan2(p[:, 1], p[:, 0]))
    error = abs(g.length_q15 / 2 ** 15 - abs(ang[-1] - ang[0]) * math.sqrt(g.r2))
    assert error <= length_error_bound(g.r2), (g.r2, error)
    from galileo_cnc.machine.arcs import band_table
    bv, brho = band_table(g.r2)
    band = np.searchsorted(np.asarray(bv), keys, side="right") - 1
    assert g.weight_q15 == int(np.asarray(brho)[band].sum())
    assert abs(g.scale / 2 ** 20 - g.length_q15 / g.weight_q15) < 2 ** -19
