"""Feed and ramps, measured from the trace: path speed, minimum period, ramp shape."""

import math

import numpy as np
from hypothesis import assume, given, settings, strategies as st

from galileo_cnc.config import MachineConfig
from galileo_cnc.machine import (ArcTo, Dwell, LineTo, Rapid, ReferenceMachine, SetFeed,
                                 estimate_seconds, simulate)
from galileo_cnc.machine.analysis import (arc_speed_steps_per_s, event_positions,
                                          line_speed_steps_per_s, min_step_gap_ticks)
from galileo_cnc.machine.ramps import ramp_events

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
    ramp = ramp_events(feed, ACCEL)
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
    ramp = ramp_events(feed, ACCEL)
    a, b = ramp, len(ticks) - 1 - ramp
    assume(b - a > 400)
    r = math.hypot(*s)
    assert abs(arc_speed_steps_per_s(ticks, pos, HOME[:2], r, a, b) / feed - 1) < 0.01
    window = max(200, int(r / 8))
    for i in range(a, b - window, window):
        local = arc_speed_steps_per_s(ticks, pos, HOME[:2], r, i, i + window)
        assert abs(local / feed - 1) < 0.01


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
    ramp = ramp_events(feed, ACCEL)
    assert ramp == 32
    assert abs(gaps[0] / period - 3) < 0.01
    assert np.all(np.diff(gaps[:ramp + 1]) <= 0)            # speeding up
    assert np.all(np.abs(gaps[ramp:-ramp] - period) <= 1)   # cruise at the step period
    assert np.all(np.abs(gaps[::-1][:ramp] - gaps[:ramp]) <= 1)  # decelerates like it started
    assert abs(gaps[-1] / period - 3) < 0.01


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
    ramp = ramp_events(c.rapid_steps_per_s, c.accel_steps_per_s2)
    speed = line_speed_steps_per_s(ticks, pos, ramp, len(ticks) - 1 - ramp)
    assert abs(speed / c.rapid_steps_per_s - 1) < 0.01


def test_estimate_is_the_trace_duration():
    cmds = [LineTo(1000, 500), Dwell(250), LineTo(0, 0)]
    trace = simulate(cmds)
    assert estimate_seconds(cmds) == trace.seconds
    assert trace.total_ticks == trace.tick[-1]
    with_tail = simulate(cmds + [Dwell(100)])
    assert with_tail.total_ticks == trace.total_ticks + 200_000
