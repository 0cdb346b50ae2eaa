"""Feed and ramps, measured from the trace: path speed, minimum period, ramp shape."""

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

from galileo_cnc.config.hardware import TICKS_PER_S
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import ArcTo, Dwell, LineTo, Rapid, SetFeed
from galileo_cnc.machine import ReferenceMachine, estimate_seconds, simulate
from galileo_cnc.machine.analysis import (arc_speed_steps_per_s, event_positions,
                                          line_speed_steps_per_s, min_step_gap_ticks)
from galileo_cnc.machine.arcs import MAX_ARC_COORD
from galileo_cnc.machine.ramps import axial_interval_sub, ramp_events, ramp_step_sub

BIG = MachineConfig(x_travel_mm=500, y_travel_mm=500, z_min_steps=-70000, z_max_steps=70000)
HOME = (40000, 40000, 0)
ACCEL = BIG.accel_steps_per_s2


def line_trace(delta, feed):
    m = ReferenceMachine(BIG, HOME)
    return m.run([SetFeed(feed), LineTo(*[HOME[a] + delta[a] for a in range(3)])])


@settings(max_examples=80, deadline=None)
@given(st.floats(0, 2 * math.pi), st.floats(-0.6, 0.6), st.integers(1500, 20000),
       st.sampled_from([100, 800, 1000, 4000, 12000, 40000]))
def test_line_path_speed_is_the_feed_in_every_direction(theta, dip, length, feed):
    delta = (round(length * math.cos(theta) * math.cos(dip)),
             round(length * math.sin(theta) * math.cos(dip)),
             round(length * math.sin(dip) * 0.5))
    n = max(abs(d) for d in delta)
    ramp = ramp_events(feed, ACCEL, BIG.ramp_start_factor)
    assume(n - 2 * ramp > 400)
    ticks, pos = event_positions(line_trace(delta, feed), HOME)
    speed = line_speed_steps_per_s(ticks, pos, ramp, n - 1 - ramp)  # the cruise part
    assert abs(speed / feed - 1) < 0.01
    # ... and over shorter windows inside the cruise (no slow/fast stretches).
    for a in range(ramp, n - 1 - ramp - 300, 600):
        assert abs(line_speed_steps_per_s(ticks, pos, a, a + 300) / feed - 1) < 0.01


@settings(max_examples=40, deadline=None)
@given(st.integers(100, 15000), st.floats(0, 2 * math.pi), st.booleans(),
       st.sampled_from([200, 800, 2000, 8000]))
def test_arc_path_speed_is_the_feed(radius, a0, cw, feed):
    s = (round(radius * math.cos(a0)), round(radius * math.sin(a0)))
    m = ReferenceMachine(BIG, (HOME[0] + s[0], HOME[1] + s[1], 0))
    trace = m.run([SetFeed(feed), ArcTo(HOME[0] + s[0], HOME[1] + s[1], -s[0], -s[1], cw)])
    ticks, pos = event_positions(trace, (HOME[0] + s[0], HOME[1] + s[1], 0))
    ramp = ramp_events(feed, ACCEL, BIG.ramp_start_factor)
    a, b = ramp, len(ticks) - 1 - ramp
    assume(b - a > 400)
    r = math.hypot(*s)
    assert abs(arc_speed_steps_per_s(ticks, pos, HOME[:2], r, a, b) / feed - 1) < 0.01
    window = max(200, int(r / 8))
    for i in range(a, b - window, window):
        local = arc_speed_steps_per_s(ticks, pos, HOME[:2], r, i, i + window)
        assert abs(local / feed - 1) < 0.01


# ---- arcs of every radius: the per-arc length scale (motion.md 5.3) ---------------------

ARC_C = (40000, 40000)


def arc_run(s, e, cw, feed):
    """Arc around ARC_C from ARC_C + s to ARC_C + e: (event ticks, points incl. the start)."""
    start = (ARC_C[0] + s[0], ARC_C[1] + s[1], 0)
    trace = ReferenceMachine(BIG, start).run(
        [SetFeed(feed), ArcTo(ARC_C[0] + e[0], ARC_C[1] + e[1], -s[0], -s[1], cw)])
    ticks, pos = event_positions(trace, start)
    return ticks, np.vstack([[s], pos[:, :2] - np.asarray(ARC_C)]).astype(np.float64)


def true_lengths(points, radius):
    """Length along the true circle up to each point (angles of the visited points)."""
    ang = np.unwrap(np.arctan2(points[:, 1], points[:, 0]))
    return np.abs(ang - ang[0]) * radius


def whole_arc_speed_error(s, e, cw, feed):
    """(speed / feed - 1, tick slack) over a whole arc with the ramp taken out.

    The move starts at tick 0; its duration minus the ramp's extra intervals
    (motion.md 5.4: (R - m_k) * step per event) is the time the arc takes at
    cruise. The last tick is floored, so one tick of slack is allowed.
    """
    ticks, pts = arc_run(s, e, cw, feed)
    n = len(ticks)
    ramp = ramp_events(feed, ACCEL, BIG.ramp_start_factor)
    step = ramp_step_sub(axial_interval_sub(feed), ramp, BIG.ramp_start_factor)
    k = np.arange(n)
    extra = int(((ramp - np.minimum(np.minimum(k, n - 1 - k), ramp)) * step).sum())
    cruise_ticks = ticks[-1] - extra / 256
    length = true_lengths(pts, math.hypot(*s))[-1]
    return length * TICKS_PER_S / cruise_ticks / feed - 1, 1 / cruise_ticks


WHOLE_ARC_BOUND = 1e-4  # motion.md 5.3: rounding of rho, the scale and C1, plus 1 tick


def assert_whole_arc_speed(s, e, cw, feed):
    err, slack = whole_arc_speed_error(s, e, cw, feed)
    assert abs(err) <= WHOLE_ARC_BOUND + slack, (s, e, cw, feed, err)
    return err, slack


def lattice_points(r2):
    r = math.isqrt(r2) + 1
    return [(x, y) for x in range(-r, r + 1) for y in range(-r, r + 1) if x * x + y * y == r2]


@pytest.mark.parametrize("r2", [1, 2, 4, 5, 8, 9, 10, 13, 16, 17, 25, 50, 65, 85])
def test_whole_arc_speed_small_circles_exhaustive(r2):
    """Every arc between lattice points of the circle, both ways: the feed within 0.01 %."""
    pts = lattice_points(r2)
    for s in pts:
        for e in pts:
            for cw in (False, True):
                assert_whole_arc_speed(s, e, cw, 800)


def test_whole_arc_speed_every_full_circle_up_to_r2_300():
    for r2 in range(1, 300):
        for s in lattice_points(r2):
            if s[0] >= 0 and s[1] >= 0:
                for cw in (False, True):
                    assert_whole_arc_speed(s, s, cw, 100)


@settings(max_examples=150, deadline=None)
@given(st.integers(1, MAX_ARC_COORD), st.floats(0, 2 * math.pi), st.integers(1, 4),
       st.booleans(), st.sampled_from([10, 100, 800, 4000, 20000, 36000]))
def test_whole_arc_speed_is_the_feed_for_every_radius(radius, a0, quarters, cw, feed):
    """Radii 1 .. MAX_ARC_COORD, quarter to full circles (ends exactly on the circle)."""
    s = (round(radius * math.cos(a0)), round(radius * math.sin(a0)))
    assume(s != (0, 0) and max(map(abs, s)) <= MAX_ARC_COORD)
    assume(radius < 3000 or feed >= 4000)  # keeps the slow feeds' event counts small
    e = s
    for _ in range(quarters % 4):  # a quarter turn the arc's way
        e = (e[1], -e[0]) if cw else (-e[1], e[0])
    err, slack = assert_whole_arc_speed(s, e, cw, feed)
    if slack < 0.005:  # the arc lasts >= 200 ticks: the tick grid is not the limit
        assert abs(err) < 0.01


@settings(max_examples=60, deadline=None)
@given(st.integers(20, 30000), st.floats(0, 2 * math.pi), st.booleans(),
       st.sampled_from([100, 200, 800, 2000]))
def test_arc_speed_after_the_ramp_over_windows(radius, a0, cw, feed):
    """Inside the cruise part every stretch of >= 200 steps runs at the feed within 1 %."""
    s = (round(radius * math.cos(a0)), round(radius * math.sin(a0)))
    assume(radius < 4000 or feed >= 800)
    ticks, pts = arc_run(s, s, cw, feed)
    ramp = ramp_events(feed, ACCEL, BIG.ramp_start_factor)
    a, b = ramp, len(ticks) - 1 - ramp   # events with the cruise interval only
    length = true_lengths(pts[1:], math.hypot(*s))
    assume(b > a and length[b] - length[a] >= 200)
    speed = (length[b] - length[a]) * TICKS_PER_S / (ticks[b] - ticks[a])
    assert abs(speed / feed - 1) < 0.01
    starts = np.arange(a, b, max(1, (b - a) // 64))
    ends = np.searchsorted(length, length[starts] + 200)
    ok = ends <= b
    local = ((length[ends[ok]] - length[starts[ok]]) * TICKS_PER_S
             / (ticks[ends[ok]] - ticks[starts[ok]]))
    assert np.all(np.abs(local / feed - 1) < 0.01)


def test_diagonal_is_not_sqrt2_fast():
    straight = line_trace((10000, 0, 0), 800)
    diagonal = line_trace((10000, 10000, 0), 800)
    # Same major-axis count, the diagonal is sqrt(2) longer so takes sqrt(2) longer.
    assert abs(diagonal.total_ticks / straight.total_ticks - math.sqrt(2)) < 0.001


def test_ramp_starts_at_3x_reaches_1x_and_is_symmetric():
    feed = 800
    trace = line_trace((2000, 0, 0), feed)
    gaps = np.diff(np.concatenate(([0], trace.tick)))
    period = 2_000_000 / feed
    ramp = ramp_events(feed, ACCEL, BIG.ramp_start_factor)
    assert ramp == 32
    assert abs(gaps[0] / period - 3) < 0.01
    assert np.all(np.diff(gaps[:ramp + 1]) <= 0)            # speeding up
    assert np.all(np.abs(gaps[ramp:-ramp] - period) <= 1)   # cruise at the step period
    assert np.all(np.abs(gaps[::-1][:ramp] - gaps[:ramp]) <= 1)  # decelerates like it started
    assert abs(gaps[-1] / period - 3) < 0.01


@pytest.mark.parametrize("start_factor", [2, 3, 5, 8])
def test_a_ramp_from_any_start_keeps_the_acceleration_bound(start_factor):
    # ramp_start_factor k: the first interval is k x the period, and the ramp is long
    # enough, ceil((k - 1) F^2 / A) events, that no step changes speed faster than A
    feed = 800
    config = BIG.replace(ramp_start_factor=start_factor)
    trace = ReferenceMachine(config, HOME).run(
        [SetFeed(feed), LineTo(HOME[0] + 2000, HOME[1], 0)])
    gaps = np.diff(np.concatenate(([0], trace.tick))).astype(np.float64)
    period = TICKS_PER_S / feed
    ramp = ramp_events(feed, ACCEL, start_factor)
    assert ramp == math.ceil((start_factor - 1) * feed * feed / ACCEL)
    assert abs(gaps[0] / period - start_factor) < 0.01
    assert np.all(np.abs(gaps[ramp:-ramp] - period) <= 1)
    speed = TICKS_PER_S / gaps                          # steps/s over each interval
    accel = np.abs(np.diff(speed)) * TICKS_PER_S / gaps[1:]
    assert accel.max() <= 1.02 * ACCEL                  # the tick grid's rounding
    assert accel.max() >= 0.9 * ACCEL                   # and the bound is used


def test_short_moves_get_a_triangle():
    feed = 800
    trace = line_trace((40, 0, 0), feed)  # shorter than two ramps (2 * 32)
    gaps = np.diff(np.concatenate(([0], trace.tick)))
    assert gaps.min() > 2_000_000 / feed * 1.5  # never reached the feed
    assert int(np.argmin(gaps)) in (19, 20)
    assert np.all(np.abs(gaps - gaps[::-1]) <= 1)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(-3000, 3000), st.integers(-3000, 3000),
                          st.integers(-200, 200)), min_size=1, max_size=6),
       st.sampled_from([10, 800, 20000, 40000]))
def test_min_step_period_holds_across_moves(targets, feed):
    cmds = [SetFeed(feed)] + [LineTo(HOME[0] + x, HOME[1] + y, z) for x, y, z in targets]
    cmds.append(ArcTo(HOME[0] + targets[0][0], HOME[1] + targets[0][1], 50, 0, True))
    trace = ReferenceMachine(BIG, HOME).run(cmds)
    assert min_step_gap_ticks(trace) >= BIG.min_step_period_ticks


def test_fastest_feed_runs_at_the_minimum_period():
    trace = line_trace((0, 5000, 0), BIG.max_feed_steps_per_s)
    assert min_step_gap_ticks(trace) == BIG.min_step_period_ticks


def test_rapid_uses_the_rapid_feed():
    c = MachineConfig()
    m = ReferenceMachine(c)
    m.run([Rapid(0, 0)])  # pen up first (300 Z steps)
    trace = m.run([Rapid(8000, 0)])
    ticks, pos = event_positions(trace)
    ramp = ramp_events(c.rapid_steps_per_s, c.accel_steps_per_s2, c.ramp_start_factor)
    speed = line_speed_steps_per_s(ticks, pos, ramp, len(ticks) - 1 - ramp)
    assert abs(speed / c.rapid_steps_per_s - 1) < 0.01


def test_estimate_is_the_trace_duration():
    cmds = [LineTo(1000, 500), Dwell(250), LineTo(0, 0)]
    trace = simulate(cmds)
    assert estimate_seconds(cmds) == trace.seconds
    assert trace.total_ticks == trace.tick[-1]
    with_tail = simulate(cmds + [Dwell(100)])
    assert with_tail.total_ticks == trace.total_ticks + 200_000


def arc_speed_table(per_range=24, seed=1):
    """Worst whole-arc speed error by radius range (python3 tests/test_machine_timing.py)."""
    import random
    rnd = random.Random(seed)
    ranges = [(1, 3), (3, 10), (10, 40), (40, 100), (100, 1000), (1000, 10000),
              (10000, MAX_ARC_COORD)]
    for lo, hi in ranges:
        worst = worst_excess = window = 0.0
        for _ in range(per_range):
            radius, a0 = rnd.randint(lo, hi), rnd.uniform(0, 2 * math.pi)
            s = (round(radius * math.cos(a0)), round(radius * math.sin(a0)))
            if s == (0, 0) or max(map(abs, s)) > MAX_ARC_COORD:
                continue
            cw = rnd.random() < 0.5
            for quarters in (1, 2, 4):
                e = s
                for _ in range(quarters % 4):
                    e = (e[1], -e[0]) if cw else (-e[1], e[0])
                for feed in ((800, 20000) if radius < 3000 else (20000,)):
                    err, slack = whole_arc_speed_error(s, e, cw, feed)
                    if feed == 800:
                        worst = max(worst, abs(err))
                    worst_excess = max(worst_excess, abs(err) - slack)
            if radius >= 20 and s != (0, 0):
                window = max(window, window_speed_error(s, cw, 200 if radius < 4000 else 2000))
        print(f"radius {lo:>5}..{hi:<5}  whole arc, worst |speed/F - 1| at 800 steps/s: "
              f"{100 * worst:.4f} %, beyond the 1-tick slack (800, 20000): "
              f"{100 * max(worst_excess, 0):.4f} %;  200-step windows after the ramp: "
              + (f"{100 * window:.3f} %" if window else "-"))


def window_speed_error(s, cw, feed, min_length=200):
    """Worst |speed/F - 1| over stretches >= min_length steps of a full circle's cruise."""
    ticks, pts = arc_run(s, s, cw, feed)
    ramp = ramp_events(feed, ACCEL, BIG.ramp_start_factor)
    a, b = ramp, len(ticks) - 1 - ramp
    length = true_lengths(pts[1:], math.hypot(*s))
    if b <= a or length[b] - length[a] < min_length:
        return 0.0
    starts = np.arange(a, b)
    ends = np.searchsorted(length, length[starts] + min_length)
    ok = ends <= b
    local = ((length[ends[ok]] - length[starts[ok]]) * TICKS_PER_S
             / (ticks[ends[ok]] - ticks[starts[ok]]))
    return float(np.abs(local / feed - 1).max())


if __name__ == "__main__":
    arc_speed_table()
