"""Junction speeds (machine/junctions.py, docs/motion.md §5.7): the planned indices, the
ramp between given speeds, holds and aborts through junctions, the timing."""

from __future__ import annotations

import math
from itertools import product

import numpy as np
from hypothesis import given, settings, strategies as st

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import (ArcTo, Dwell, EndJob, Jog, LineTo, PenDown, PenUp, Rapid, SetFeed,
                             SetOrigin)
from galileo_cnc.machine import Hold, ReferenceMachine, Starved, simulate
from galileo_cnc.machine.analysis import min_step_gap_ticks
from galileo_cnc.machine.blocks import LineMove, Pause
from galileo_cnc.machine.junctions import (JunctionLimits, move_ends, plan_indices,
                                          vertex_index, vertex_speed)
from galileo_cnc.machine.ramps import ramp_sum
from galileo_cnc.machine.timing import job_timing

OFF = MachineConfig(junction_deviation_mm=0.0)
ON = MachineConfig(junction_deviation_mm=0.01)
LIMITS = JunctionLimits.of(ON)


def polygon_job() -> list:
    """A 59-gon of 0.08 mm sides... 5 mm across, an arc, a hairpin, a dwell, a line."""
    commands = [Jog(12000, 12000, 0), SetOrigin(), Rapid(0, 0), PenDown()]
    for k in range(1, 60):
        a = k * 2 * math.pi / 59
        commands.append(LineTo(round(400 * math.cos(a)) - 400, round(400 * math.sin(a))))
    commands += [ArcTo(-800, 0, -400, 0, False), LineTo(-800, 5), LineTo(-798, 40),
                 ArcTo(-798, 200, 0, 80, True), LineTo(-700, 300), LineTo(-800, 300),
                 Dwell(20), LineTo(-800, 400), PenUp(), EndJob()]
    return commands


def test_ramp_sum_is_the_sum_of_the_ramp_indices():
    for length, ramp in product(range(1, 30), range(0, 9)):
        for entry, exit_ in product(range(ramp + 1), repeat=2):
            if abs(entry - exit_) <= length - 1:
                brute = sum(ramp - min(entry + k, exit_ + length - 1 - k, ramp)
                            for k in range(length))
                assert ramp_sum(length, ramp, entry, exit_) == brute


@settings(max_examples=80, deadline=None)
@given(st.lists(st.integers(1, 6), min_size=1, max_size=7), st.data())
def test_the_passes_give_the_fastest_indices_every_move_can_ramp_between(counts, data):
    caps = data.draw(st.lists(st.integers(0, 8), min_size=len(counts) - 1,
                              max_size=len(counts) - 1))
    m = plan_indices(counts, caps)
    assert m[0] == m[-1] == 0
    assert all(0 <= m[j + 1] <= caps[j] for j in range(len(caps)))
    assert all(abs(m[i] - m[i + 1]) <= counts[i] - 1 for i in range(len(counts)))
    # the largest: no feasible choice has a faster vertex (brute force)
    for choice in product(*[range(c + 1) for c in caps]):
        full = [0, *choice, 0]
        if all(abs(full[i] - full[i + 1]) <= counts[i] - 1 for i in range(len(counts))):
            assert all(a <= b for a, b in zip(full, m))


def test_the_vertex_speed_rules():
    x, y, diag = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (math.sqrt(0.5), math.sqrt(0.5), 0.0)
    assert vertex_speed(x, x, LIMITS) == math.inf               # straight on
    assert vertex_speed(x, (-1.0, 0.0, 0.0), LIMITS) == 0.0     # a reversal stops
    assert vertex_speed(x, (-0.1, 0.995, 0.0), LIMITS) == 0.0
    # a right angle: each axis changes by the whole speed, so the per-axis bound rules
    # (320 steps/s = 2.0 mm/s); the deviation alone would allow 2.46 mm/s
    assert vertex_speed(x, y, LIMITS) == LIMITS.axis_change_steps_per_s
    loose = JunctionLimits(LIMITS.accel_steps_per_s2, 10_000, 6250, 10**6)
    assert round(vertex_speed(x, y, loose)) == round(math.sqrt(40000 * 1.6 * 0.70711 / 0.29289))
    # 45 degrees: y changes by 0.71 of the speed, x by 0.29
    assert LIMITS.axis_change_steps_per_s == 320
    assert round(vertex_speed(x, diag, LIMITS)) == round(320 / math.sqrt(0.5))


def test_a_curve_of_short_lines_passes_at_the_speed_its_radius_allows():
    """Each 11.25-degree turn alone would let 7 mm/s through (the deviation of 0.05 mm
    and the per-axis bound), but the 32 sides lie on a circle of 400 steps (2.5 mm),
    and at 5 mm/s² the centripetal speed there is sqrt(A r), 3.5 mm/s: the mid-move
    rule (Klipper's) gives that, within the sides' rounding to whole steps. Long
    lines at the same turn pass at the feed."""
    gentle = ON.replace(accel_mm_s2=5.0, junction_deviation_mm=0.05)
    limits = JunctionLimits.of(gentle)
    radius, sides = 400, 32

    def drawn(points):
        commands = [Jog(12000, 12000, 0), SetOrigin(), PenDown()] + [
            LineTo(x, y) for x, y in points]
        return [it for it in ReferenceMachine(gentle).plan(commands)
                if isinstance(it, LineMove) and not it.delta[2] and it.n][-len(points):]

    def speeds(moves):
        indices = [vertex_index(a, b, limits) for a, b in zip(moves, moves[1:])]
        return [move_ends(a)[1].speed(m) for a, m in zip(moves, indices)]

    turn = 2 * math.pi / sides
    circle = drawn([(round(radius * math.cos(k * turn)) - radius,
                     round(radius * math.sin(k * turn))) for k in range(1, sides + 1)])
    centripetal = math.sqrt(limits.accel_steps_per_s2 * radius)
    assert centripetal < 0.75 * gentle.feed_steps_per_s
    got = speeds(circle)
    assert max(got) <= centripetal * 1.05
    assert min(got) >= centripetal * 0.9
    long = drawn([(9000, 0), (9000 + round(9000 * math.cos(turn)), round(9000 * math.sin(turn)))])
    assert vertex_index(*long, limits) == long[0].ramp


def test_junction_speeds_keep_the_steps_shorten_the_job_and_brake_in_time():
    commands = polygon_job()
    stops, blended = simulate(commands, OFF), simulate(commands, ON)
    assert np.array_equal(stops.axis, blended.axis) and np.array_equal(stops.dir, blended.dir)
    assert blended.final_position == stops.final_position
    assert blended.total_ticks < 0.9 * stops.total_ticks
    assert min_step_gap_ticks(blended) >= ON.min_step_period_ticks
    machine = ReferenceMachine(ON)
    items = machine.plan_speeds(machine.plan(commands))
    moves = [it for it in items if not isinstance(it, Pause) and it.n]
    assert any(it.entry for it in moves)
    for it in moves:           # every move can ramp from its entry to its exit
        assert abs(it.entry - it.exit) <= it.n - 1 and max(it.entry, it.exit) <= it.ramp
        if isinstance(it, LineMove) and it.delta[2]:
            assert it.entry == it.exit == 0          # pen lifts and lowers stop
    for a, b in zip(items, items[1:]):
        if isinstance(b, Pause):
            assert a.exit == 0                       # so does a dwell
        elif not isinstance(a, Pause) and a.n and b.n:
            assert a.exit == b.entry                 # both sides share the vertex's index
    # Off: the planned items are today's, every move from rest to rest.
    plain = ReferenceMachine(OFF)
    assert all(not it.entry and not it.exit
               for it in plain.plan_speeds(plain.plan(commands)) if not isinstance(it, Pause))


def test_no_axis_changes_speed_at_a_vertex_by_more_than_the_bound():
    """From the trace: each line's direction and, at its ends, its path speed (the
    path per event over the interval of the last / first event)."""
    commands = polygon_job()[:64]
    trace = simulate(commands, ON)
    machine = ReferenceMachine(ON)
    items = [it for it in machine.plan_speeds(machine.plan(commands))
             if not isinstance(it, Pause) and it.n]
    t = np.unique(trace.tick)                # one tick per event (they are >= 50 apart)
    assert len(t) == sum(it.n for it in items)
    ends = np.cumsum([it.n for it in items]) - 1
    checked = 0
    for (a, b), last_a in zip(zip(items, items[1:]), ends):
        if not (isinstance(a, LineMove) and isinstance(b, LineMove) and a.exit):
            continue
        interval_a, interval_b = t[last_a] - t[last_a - 1], t[last_a + 1] - t[last_a]
        ua = np.array(a.delta) / math.dist((0, 0, 0), a.delta)
        ub = np.array(b.delta) / math.dist((0, 0, 0), b.delta)
        va = 2e6 * math.dist((0, 0, 0), a.delta) / a.n / interval_a
        vb = 2e6 * math.dist((0, 0, 0), b.delta) / b.n / interval_b
        # the trace's ticks round each interval by up to a tick
        slack = va / (interval_a - 1) + vb / (interval_b - 1)
        assert np.max(np.abs(va * ua - vb * ub)) <= LIMITS.axis_change_steps_per_s + slack
        checked += 1
    assert checked > 30


def test_holds_and_aborts_through_junctions_loop_equals_vectorised():
    commands = polygon_job()
    full = simulate(commands, ON)
    rng = np.random.default_rng(5)
    for _ in range(12):
        holds = [Hold(int(rng.integers(full.total_ticks)), int(rng.integers(0, 20000)))
                 for _ in range(int(rng.integers(0, 3)))]
        abort = int(rng.integers(full.total_ticks)) if rng.random() < 0.4 else None
        a = simulate(commands, ON, holds=holds, abort_at_tick=abort)
        b = simulate(commands, ON, holds=holds, abort_at_tick=abort, backend="loop")
        assert a.same_steps(b), (holds, abort)
        assert a.total_ticks == b.total_ticks and a.final_position == b.final_position
        assert min_step_gap_ticks(a) >= ON.min_step_period_ticks
        if abort is None:         # a hold only delays: the same steps, the same end
            assert np.array_equal(a.axis, full.axis) and a.final_position == full.final_position
    # a hold at a junction brakes into the next moves and stops there, from the index
    # it had: the stop comes later than the hold's move's end
    machine = ReferenceMachine(ON)
    items = machine.plan_speeds(machine.plan(commands))
    held = simulate(commands, ON, holds=[Hold(full.tick[len(full.tick) // 3], 40000)])
    gaps = np.diff(np.unique(held.tick))
    assert gaps.max() >= 40000 and held.total_ticks > full.total_ticks
    assert any(it.exit for it in items if not isinstance(it, Pause))


def test_the_timing_follows_the_junction_speeds():
    commands = polygon_job()
    timing = job_timing(commands, ON)
    trace = simulate(commands, ON)
    assert timing.end_ticks[-1] == trace.total_ticks
    assert timing.end_ticks[-1] < job_timing(commands, OFF).end_ticks[-1]
    for k in (10, 40, 62, 66):
        assert timing.end_ticks[k] in set(trace.tick.tolist())


def test_after_a_stop_the_next_move_enters_no_faster_than_the_rest_left():
    """Two collinear lines blended at full speed; a hold stops the first one 8 events
    before its end. The rest (from rest) cannot reach the planned exit, so the second
    line enters at the index the rest reached: no jump in speed at the vertex."""
    commands = [Jog(4000, 4000, 0), SetOrigin(), PenDown(), LineTo(2000, 0), LineTo(4000, 0)]
    full = simulate(commands, ON)
    ticks = np.unique(full.tick)
    before = len(ticks) - 4000              # the jog's events
    hold_at = int(ticks[before + 1959])     # event 1960 of the first line, at index R
    for backend in ("numpy", "loop"):
        held = simulate(commands, ON, holds=[Hold(hold_at, 5000)], backend=backend)
        t = np.unique(held.tick)[before:]
        gaps = np.diff(t)
        vertex = 1999                       # the first line's last event
        step = ReferenceMachine(ON).plan(commands)[-1].step_sub
        assert gaps[vertex - 1] - gaps[vertex] <= step / 256 + 1, backend  # no jump
        assert gaps[vertex] < gaps[vertex - 8]     # still speeding up after the rest
    # without the hold both lines run through the vertex at the feed
    g = np.diff(ticks[before:])
    assert g[1998] == g[1999] == g[1000]


def test_a_starved_link_brakes_in_time_to_stop_where_the_moves_end():
    """Ten-step moves along X blend at the feed. Command 60 comes late: the machine
    brakes along its ramp (one step of the ramp per event, over the moves before it)
    to stand still at the end of command 59, waits, then goes on from rest."""
    commands = [Jog(4000, 4000, 0), SetOrigin(), PenDown()]
    commands += [LineTo(10 * k, 0) for k in range(1, 100)]
    full = simulate(commands, ON)
    wait = 30000
    for backend in ("numpy", "loop"):
        late = simulate(commands, ON, backend=backend, starved=[Starved(61, wait)])
        assert np.array_equal(late.axis, full.axis) and late.final_position == full.final_position
        t = np.unique(late.tick)[-990:]                 # the hundred lines' events
        gaps = np.diff(t)
        stop = 58 * 10 - 1                              # command 60's last event
        assert gaps[stop] >= wait
        line = ReferenceMachine(ON).plan(commands)[-1]
        cruise, ramp = line.base_sub // 256, line.ramp
        braking = gaps[stop - ramp:stop] * 256          # in front of its last R events
        assert np.all(np.diff(braking) > 0)             # slowing down at every event
        assert abs(int(braking[-1]) - (line.base_sub + ramp * line.step_sub)) < 512
        assert gaps[stop - ramp - 5] in (cruise, cruise + 1)   # at the feed before it
        assert late.total_ticks > full.total_ticks + wait
    a = simulate(commands, ON, starved=[Starved(61, wait), Starved(90, 0)],
                 holds=[Hold(int(full.tick[-300]), 7000)])
    b = simulate(commands, ON, starved=[Starved(61, wait), Starved(90, 0)],
                 holds=[Hold(int(full.tick[-300]), 7000)], backend="loop")
    assert a.same_steps(b) and a.total_ticks == b.total_ticks


def test_a_rapid_or_jog_ends_at_rest_as_the_wire_sends_it():
    # Two Rapids back to back (the pen stays up) are two blendable lines at the rapid
    # feed, but a Rapid's line carries no exit index on the wire: it stops; LineTos at
    # the same feed and angle blend.
    from galileo_cnc.machine.planner import exit_indices
    rapids = [Rapid(3000, 3000), Rapid(3600, 3100), Rapid(4200, 3000)]
    lines = [Rapid(3000, 3000), SetFeed(ON.rapid_steps_per_s), LineTo(3600, 3100),
             LineTo(4200, 3000)]
    jogs = [Rapid(3000, 3000), Jog(600, 100, 0), Jog(600, -100, 0)]
    assert simulate(rapids, ON).total_ticks == simulate(rapids, OFF).total_ticks
    assert simulate(jogs, ON).total_ticks == simulate(jogs, OFF).total_ticks
    assert simulate(lines, ON).total_ticks < simulate(lines, OFF).total_ticks
    assert exit_indices(lines, ON)[2] > 0 and exit_indices(rapids, ON) == [None] * 3
