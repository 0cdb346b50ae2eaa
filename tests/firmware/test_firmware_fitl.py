"""Firmware in the loop: the real firmware in simavr against the reference machine.

Each job is streamed over the pseudo-terminal to the firmware (built by
`make -C firmware`, run by firmware/harness's galileo-simavr) and run through
`galileo_cnc.machine.simulate`. The step traces must be equal: the same steps,
axes, directions and order, and every step edge at the reference tick plus one
job-wide offset (where the firmware's clock started), give or take
LATENCY_JITTER_TICKS (docs/protocol.md, "Step timing").
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from galileo_cnc import protocol as P
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import (ArcTo, Dwell, EndJob, Flash, Home, Jog, LineTo, PenDown, PenUp,
                             Rapid, SetFeed, SetOrigin)
from galileo_cnc.job import MachineError
from galileo_cnc.machine import ReferenceMachine, simulate
from galileo_cnc.simavr.board import SimulatedBoard, step_trace

from firmware_support import (ELF, FirmwareLink, build_firmware, build_firmware_for,
                              build_harness, check_bad_input_replies, status_when)

# Every step edge lies within [offset, offset + LATENCY_JITTER_TICKS] of its
# reference tick: the compare match is exact, the edge follows it by a fixed
# 12-15 cycles (naked vector, one `out`), plus at most one receive interrupt.
LATENCY_JITTER_TICKS = 2

# Away from the travel's lower limits, quickly: simavr runs about as fast as the chip.
CENTRE = [SetFeed(20000), Jog(3000, 3000, 0), SetOrigin(), SetFeed(800)]


@pytest.fixture(scope="module")
def firmware():
    build_firmware()
    build_harness()
    return ELF


def run_on_firmware(elf, commands, endstops=(), during=None):
    """Stream `commands`; returns (tick, axis, dir), the replies and the final status."""
    with SimulatedBoard(elf, endstops=endstops) as board:
        link = FirmwareLink(board.port)
        try:
            replies = link.stream(commands)
            if during is not None:
                during(link)
            final = link.wait_idle()
            unsolicited = list(link.unsolicited)
        finally:
            link.close()
        board.stop()
        trace = step_trace(board.trace())
    return trace, replies, final, unsolicited


def assert_same_trace(fw, ref):
    tick, axis, direction = fw
    assert len(tick) == len(ref.tick), f"{len(tick)} firmware steps, {len(ref.tick)} reference"
    assert np.array_equal(axis, ref.axis), "axes differ"
    assert np.array_equal(direction, ref.dir), "directions differ"
    if len(tick):
        delay = tick - ref.tick
        spread = int(delay.max() - delay.min())
        assert spread <= LATENCY_JITTER_TICKS, (
            f"step edges spread over {spread} ticks around the reference "
            f"(worst at step {int(np.argmax(delay))})")
    return delay if len(tick) else np.zeros(0)


def check_job(elf, commands, config=None, endstops=()):
    """The job on the firmware, each move with the exit index `config` plans for it (the
    default config's junction speeds), against the reference with that config."""
    from galileo_cnc.machine.planner import with_exit_indices
    ref = simulate(commands, config)
    fw, replies, final, unsolicited = run_on_firmware(
        elf, with_exit_indices(commands, config), endstops)
    assert all(r.kind == "ok" for r in replies), [r for r in replies if r.kind != "ok"]
    assert not [u for u in unsolicited if u.kind in ("alarm", "msg")], unsolicited
    assert_same_trace(fw, ref)
    assert (final.x_steps, final.y_steps, final.z_steps) == ref.final_position
    return ref


OCTANT_LINES = [LineTo(x, y) for x, y in
                [(900, 310), (310, 900), (-310, 900), (-900, 310), (-900, -310),
                 (-310, -900), (310, -900), (900, -310), (0, 0)]]


def test_lines_in_every_octant(firmware):
    job = CENTRE + [SetFeed(2500)]
    for target in OCTANT_LINES:
        job += [target, LineTo(0, 0)]
    check_job(firmware, job)


def test_pure_axis_and_diagonal_moves(firmware):
    job = CENTRE + [LineTo(700, 0), LineTo(700, 700), LineTo(0, 700), LineTo(0, 0),
                    LineTo(-500, -500), LineTo(0, 0), SetFeed(12000), LineTo(3000, 1)]
    check_job(firmware, job)


def test_z_moves_and_3d_lines(firmware):
    job = CENTRE + [PenUp(), PenDown(), LineTo(100, 50, 200), LineTo(-40, 80, 0),
                    Jog(0, 0, 150), Jog(0, 0, -150)]
    check_job(firmware, job)


def test_arcs_both_ways(firmware):
    job = CENTRE + [ArcTo(400, 400, 400, 0, cw=False), ArcTo(0, 0, -400, 0, cw=True),
                    ArcTo(-300, -100, -150, -50, cw=True), ArcTo(0, 0, 150, 50, cw=False),
                    SetFeed(3000), ArcTo(700, 0, 350, 0, cw=True)]
    check_job(firmware, job)


def test_full_circles_and_off_circle_ends(firmware):
    job = CENTRE + [ArcTo(0, 0, 300, 0, cw=False), ArcTo(0, 0, 0, -250, cw=True),
                    SetFeed(400), ArcTo(0, 0, 12, 5, cw=False),
                    SetFeed(1600), ArcTo(205, 3, 100, 0, cw=True),   # end 2+ steps off
                    ArcTo(0, 0, -102, 0, cw=False)]
    check_job(firmware, job)


def test_tiny_arcs_are_scaled_to_their_length(firmware):
    # Radii 1..8: the per-arc length scale (motion.md 5.3) moves every band (the
    # minimum period floor needs feeds near F_MAX, where arc events overrun the ISR).
    job = CENTRE + [SetFeed(100), ArcTo(0, 0, -1, 0, cw=False), ArcTo(1, 1, 0, 1, cw=True),
                    ArcTo(0, 0, 1, -1, cw=False), SetFeed(800), ArcTo(0, 0, 2, 0, cw=False),
                    ArcTo(-5, 5, -5, 0, cw=True), ArcTo(0, 0, 0, -5, cw=False),
                    ArcTo(3, 4, 3, 4, cw=True), ArcTo(0, 0, -3, -4, cw=False),
                    SetFeed(3000), ArcTo(0, 0, 2, 0, cw=True), ArcTo(0, 0, 4, 7, cw=False)]
    check_job(firmware, job)


def test_a_run_of_one_step_arcs_as_planned_keeps_time(firmware):
    # 60 one-step pieces of a 12.5 mm circle back to back at the default feed: each
    # arc cost the firmware a band table and setup, about 6.7 ms a move for 3.75 ms of
    # steps, and the trace fell 180 ms behind. The planner sends an arc whose chord is
    # within half a step of it as a line (docs/motion.md, "Short arcs").
    from galileo_cnc.plan.planner import plan_program
    from galileo_cnc.readers.gcode import read_gcode

    def on_circle(k):
        return 12.5 * math.cos(k / 2000) - 7.5, 5 + 12.5 * math.sin(k / 2000)

    lines = ["G21 G90", "G0 X5 Y5", "M3"]
    for k in range(1, 61):
        (x0, y0), (x, y) = on_circle(k - 1), on_circle(k)
        lines.append(f"G3 X{x:.6f} Y{y:.6f} I{-7.5 - x0:.6f} J{5 - y0:.6f}")
    # and the shortest arcs it keeps: semicircles of one step's radius
    lines += ["G0 X20 Y5", "M3"] + [f"G{2 + k % 2} X{20 + 0.0125 * (k + 1):.4f} Y5 "
                                    f"I0.00625 J0" for k in range(40)]
    job = plan_program(read_gcode("short-arcs.nc", "\n".join(lines) + "\n"), MachineConfig())
    assert sum(isinstance(c, ArcTo) for c in job.commands) == 40
    check_job(firmware, job.commands)


def test_flashes_rapids_and_dwells(firmware):
    job = CENTRE + [Rapid(200, 100), Flash(), Rapid(400, 100), Flash(50), Dwell(30),
                    PenDown(), LineTo(500, 200), EndJob()]
    check_job(firmware, job)


def test_jogs_at_the_seed_feeds(firmware):
    job = CENTRE + [Jog(1000, 0, 0), Jog(0, -1000, 0), Jog(-1, 1, 0), SetFeed(1000),
                    Jog(37, 1000, 0), Jog(0, 0, 300), Jog(0, 0, -300)]
    check_job(firmware, job)


def test_homing_against_simulated_end_stops(firmware):
    config = MachineConfig(sim_x_endstop_steps=-60, sim_y_endstop_steps=-45)
    job = [Home(), Jog(300, 200, 0), LineTo(100, 50), Home(), Jog(100, 100, 0)]
    # The harness drives pin 7 (X) and 6 (Y) low while the axis is at or below TRIP.
    ref = check_job(firmware, job, config, endstops=("X:7:-60", "Y:6:-45"))
    assert ref.final_position == (100, 100, 0)


def test_step_edges_hold_their_latency_while_the_uart_receives(firmware):
    job = CENTRE + [SetFeed(8000), LineTo(6000, 2000)]
    ref = simulate(job)

    def flood(link):  # status queries (RX interrupts, replies) during the move
        for _ in range(40):
            link.status()

    fw, replies, final, _ = run_on_firmware(firmware, job, during=flood)
    assert all(r.kind == "ok" for r in replies)
    assert_same_trace(fw, ref)


# ---- bad input over the wire ----------------------------------------------------------

def test_bad_input_gets_the_documented_reply_and_the_next_line_works(firmware):
    with SimulatedBoard(firmware, trace=False) as board:
        link = FirmwareLink(board.port)
        try:
            check_bad_input_replies(link, idle_timeout_s=60)
        finally:
            link.close()


def test_version_and_end_of_job(firmware):
    with SimulatedBoard(firmware, trace=False) as board:
        link = FirmwareLink(board.port)
        try:
            assert link.banner.banner.protocol_version == P.PROTOCOL_VERSION
            r = link.send(P.QueryVersion())
            assert r.kind == "ok" and r.banner == link.banner.banner
            assert link.send(EndJob()).kind == "ok"
            assert link.send(Jog(1, 0, 0)).code == 8       # refused after EndJob
            assert link.send(P.Unlock()).kind == "ok"
            assert link.send(Jog(1, 0, 0)).kind == "ok"
        finally:
            link.close()


# ---- feed hold, resume, abort (real-time bytes) ------------------------------------------

def _wait_state(link, state, timeout_s=60.0):
    import time
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        status = link.status()
        if status.state == state:
            return status
        time.sleep(0.01)
    raise AssertionError(f"machine never reached {state!r}: {status}")


def _wait_into_the_line(link, lines_queued, x_steps=300, timeout_s=60.0):
    """Until the job is well inside its first LineTo (work X past `x_steps`):
    CENTRE's blocks are done when only the lines are left in the queue."""
    import time
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        status = link.status()
        if (status.state == "run" and status.queue_blocks <= lines_queued
                and x_steps <= status.x_steps < 1500):
            return status
        time.sleep(0.005)
    raise AssertionError(f"the line never started: {status}")


def _split_at_pause(tick):
    gaps = np.diff(tick)
    stop = int(np.argmax(gaps))
    return stop, int(gaps[stop])


def assert_hold_as_the_reference(tick, job, full, config=None):
    """The firmware's steps `tick` of `job`, held once and resumed: the reference with
    a hold seen at some event j stops at the same step, with the same ramp down, and
    resumed ramps up again exactly like the firmware (`full`: the job unheld)."""
    from galileo_cnc.machine import Hold
    stop, gap = _split_at_pause(tick)
    assert gap > 100_000
    for j in range(stop, max(0, stop - 200), -1):
        ref = simulate(job, config, holds=[Hold(int(full.tick[j]), gap)])
        if _split_at_pause(ref.tick)[0] == stop:
            break
    else:
        raise AssertionError("no reference hold stops at the firmware's stop")
    for part in (slice(0, stop + 1), slice(stop + 1, None)):
        delay = tick[part] - ref.tick[part]
        assert delay.max() - delay.min() <= LATENCY_JITTER_TICKS


def test_feed_hold_decelerates_and_resume_continues_as_the_reference(firmware):
    import time
    job = CENTRE + [SetFeed(1600), LineTo(2400, 800)]
    full = simulate(job)

    def hold_then_resume(link):
        _wait_into_the_line(link, 1)
        link.port.write(P.RT_HOLD)
        _wait_state(link, "hold")
        time.sleep(0.3)
        held = link.status()
        time.sleep(0.2)
        assert link.status() == held          # stopped, position known
        assert held.x_steps < 2400
        link.port.write(P.RT_RESUME)

    fw, replies, final, _ = run_on_firmware(firmware, job, during=hold_then_resume)
    tick, axis, direction = fw
    assert np.array_equal(axis, full.axis) and np.array_equal(direction, full.dir)
    assert (final.x_steps, final.y_steps) == (2400, 800)
    assert_hold_as_the_reference(tick, job, full)


def test_abort_decelerates_keeps_the_position_and_locks_until_unlock(firmware):
    job = CENTRE + [SetFeed(1600), LineTo(2400, 800), LineTo(0, 0)]
    full = simulate(job)
    with SimulatedBoard(firmware) as board:
        link = FirmwareLink(board.port)
        try:
            assert all(r.kind == "ok" for r in link.stream(job))
            _wait_into_the_line(link, 2)
            link.port.write(P.RT_ABORT)
            alarm = link.read_reply()
            assert (alarm.kind, alarm.code) == ("alarm", 14)
            status = link.status()
            assert status.state == "alarm" and status.queue_blocks == 0
            assert link.send(Jog(1, 0, 0)).code == 9           # locked
            assert link.send(P.Unlock()).kind == "ok"
            assert link.send(Jog(0, 0, 0)).kind == "ok"
        finally:
            link.close()
        board.stop()
        tick, axis, direction = step_trace(board.trace())
    n = len(tick)
    assert 0 < n < len(full.tick)
    assert np.array_equal(axis, full.axis[:n]) and np.array_equal(direction, full.dir[:n])
    moved = np.bincount(axis, weights=direction, minlength=3).astype(int)
    assert (status.x_steps, status.y_steps) == (moved[0] - 3000, moved[1] - 3000)
    x_gaps = np.diff(tick[axis == 0])[-20:]
    assert np.all(np.diff(x_gaps) >= -LATENCY_JITTER_TICKS)   # slowing down to the stop


def _refusal(machine, command):
    """The reference's refusal of `command` as the firmware words it (error:5's detail)."""
    with pytest.raises(MachineError) as refused:
        machine.plan([command])
    e = refused.value
    return P.soft_limit_detail(e.axis, e.value, e.limit)


def test_z_without_an_end_stop_goes_below_its_power_on_height(firmware):
    # Issue 31 item 10: powered on with the pen lifted, the user lowers it by the pen
    # lift, sets the origin there and draws; Z has no end-stop, so its travel is a
    # length around where Z has been (and the pen heights), not a place.
    job = [SetFeed(4000), Jog(0, 0, -300), SetOrigin(), PenDown(), LineTo(400, 200), PenUp(),
           PenDown(), LineTo(0, 0), PenUp()]
    ref = check_job(firmware, job)
    assert ref.final_position == (0, 0, 300)        # up: machine Z 0, the power-on height
    beyond = Jog(0, 0, -301)                        # one step past a travel below Z 300
    machine = ReferenceMachine()
    machine.plan(job)
    assert _refusal(machine, beyond) == "Z would reach -301, below -300"
    with SimulatedBoard(firmware) as board:
        link = FirmwareLink(board.port)
        try:
            assert all(r.kind == "ok" for r in link.stream(job))
            r = link.send(beyond)
            assert (r.code, r.text) == (5, "soft limit: Z would reach -301, below -300")
        finally:
            link.close()


def test_a_head_outside_the_travel_moves_back_towards_it_never_further(firmware):
    # Issue 31 item 6: a homing that stops outside the travel (alarm 11 after its whole
    # seek, or stopped as here) left every jog refused, even back towards the travel.
    with SimulatedBoard(firmware) as board:            # no end-stops: the X seek runs on
        link = FirmwareLink(board.port)
        try:
            assert link.send(Home()).kind == "ok"
            status_when(link, lambda s: s.x_steps < -200, timeout_s=30)
            link.port.write(P.RT_ABORT)
            assert link.read_reply().code == 14
            assert link.send(P.Unlock()).kind == "ok"
            outside = link.status()
            machine = ReferenceMachine(position=(outside.x_steps, outside.y_steps,
                                                 outside.z_steps))
            further = Jog(-1, 0, 0)
            r = link.send(further)
            assert r.code == 5 and r.text == f"soft limit: {_refusal(machine, further)}"
            assert r.text == f"soft limit: X would reach {outside.x_steps - 1}, below 0"
            back = [Jog(100, 0, 0), Jog(0, 50, 0), Rapid(200, 100)]
            assert [link.send(c).kind for c in back] == ["ok"] * 3
            machine.plan(back)
            final = link.wait_idle()
        finally:
            link.close()
    assert (final.x_steps, final.y_steps, final.z_steps) == (200, 100, 300) == \
        tuple(machine.work_position)


# ---- junction speeds (docs/motion.md §5.7): the firmware ramps between planned indices --
JUNCTIONS_ON = MachineConfig(junction_deviation_mm=0.05, vertex_speed_change_mm_s=3.0)


def check_junction_job(elf, commands, config=JUNCTIONS_ON):
    from galileo_cnc.machine.planner import with_exit_indices
    wire = with_exit_indices(commands, config)
    assert any(getattr(c, "exit_index", None) for c in wire), "no vertex was blended"
    ref = simulate(commands, config)
    fw, replies, final, unsolicited = run_on_firmware(elf, wire)
    assert all(r.kind == "ok" for r in replies), [r for r in replies if r.kind != "ok"]
    assert not [u for u in unsolicited if u.kind in ("alarm", "msg")], unsolicited
    assert_same_trace(fw, ref)
    assert (final.x_steps, final.y_steps, final.z_steps) == ref.final_position
    return ref, fw


def test_junction_speeds_on_a_star_in_every_octant(firmware):
    # An octagon's sides run in every octant; each vertex turns by 45 degrees, so
    # they blend (the spokes from the centre stop at the reversals).
    pts = [(round(500 * math.cos(a)), round(500 * math.sin(a)))
           for a in (k * math.pi / 4 + 0.3 for k in range(9))]
    job = CENTRE + [SetFeed(1600)] + [LineTo(x, y) for x, y in pts] + [LineTo(0, 0)]
    ref, fw = check_junction_job(firmware, job)
    assert ref.seconds < simulate(job).seconds


def test_a_firmware_built_for_another_ramp_start_steps_as_the_reference(firmware,
                                                                       tmp_path):
    # A user's profile whose moves start at 2x the period, not 3x (ramp_start_factor),
    # with a gentler acceleration: the ramp length, ceil((k - 1) F^2 / A), and every
    # interval on it come out the same in the firmware built for it and the reference
    config = JUNCTIONS_ON.replace(ramp_start_factor=2, accel_mm_s2=180.0)
    elf = build_firmware_for(config, tmp_path)
    pts = [(round(500 * math.cos(a)), round(500 * math.sin(a)))
           for a in (k * math.pi / 4 + 0.3 for k in range(9))]
    job = CENTRE + [LineTo(x, y) for x, y in pts] + [LineTo(0, 0)] \
        + [ArcTo(0, 0, 400, 0, True), Rapid(-700, 200)]
    ref, (tick, _, _) = check_junction_job(elf, job, config)
    default = simulate(job, JUNCTIONS_ON)
    assert abs((tick[-1] - tick[0]) - (default.tick[-1] - default.tick[0])) > 10_000


def test_junction_speeds_hold_brakes_across_moves_and_resumes_exactly(firmware):
    # A 48-gon of 39-step sides at 800 steps/s (a ramp of 32 events): a hold's stop
    # lies in a later side more often than not; the reference brakes the same way.
    import time
    from galileo_cnc.machine.planner import with_exit_indices
    pts = [(round(300 * math.cos(a)) - 300, round(300 * math.sin(a)))
           for a in (k * math.pi / 24 for k in range(49))]
    job = CENTRE + [LineTo(x, y) for x, y in pts]
    full = simulate(job, JUNCTIONS_ON)

    def hold_then_resume(link):
        status_when(link, lambda s: s.state == "run" and s.queue_blocks >= 2)
        link.port.write(P.RT_HOLD)
        _wait_state(link, "hold")
        time.sleep(0.2)
        link.port.write(P.RT_RESUME)

    fw, replies, final, _ = run_on_firmware(firmware, with_exit_indices(job, JUNCTIONS_ON),
                                            during=hold_then_resume)
    tick, axis, direction = fw
    assert np.array_equal(axis, full.axis) and np.array_equal(direction, full.dir)
    assert_hold_as_the_reference(tick, job, full, JUNCTIONS_ON)


def test_junction_speeds_a_starved_link_brakes_to_the_end_of_the_queue(firmware):
    # Never overrun: the second side is planned to end at a junction speed, but the
    # third arrives only once the machine has used up its queue. The firmware braked to
    # a stop at the end of what it had, exactly as the reference's starved link
    # (Starved) does, and the rest starts from rest.
    from galileo_cnc.machine import Starved
    from galileo_cnc.machine.planner import with_exit_indices
    pts = [(round(500 * math.cos(a)), round(500 * math.sin(a)))
           for a in (k * math.pi / 4 + 0.3 for k in range(4))]
    job = CENTRE + [SetFeed(1600), LineTo(0, 0)] + [LineTo(x, y) for x, y in pts]
    wire = with_exit_indices(job, JUNCTIONS_ON)
    assert wire[7].exit_index         # the second side ends at a junction speed

    def starve(link):
        link.wait_idle()
        assert all(r.kind == "ok" for r in link.stream(wire[8:]))

    fw, replies, final, _ = run_on_firmware(firmware, wire[:8], during=starve)
    tick = fw[0]
    ref = simulate(job, JUNCTIONS_ON, starved=[Starved(8, 100_000)])
    free = simulate(job, JUNCTIONS_ON)
    n1 = len(simulate(job[:8]).tick)
    assert np.array_equal(fw[1], ref.axis) and np.array_equal(fw[2], ref.dir)
    for part in (slice(0, n1), slice(n1, None)):
        delay = tick[part] - ref.tick[part]
        assert delay.max() - delay.min() <= LATENCY_JITTER_TICKS
    assert not np.array_equal(ref.tick[:n1], free.tick[:n1])   # it did brake early
    assert (final.x_steps, final.y_steps) == ref.final_position[:2]
