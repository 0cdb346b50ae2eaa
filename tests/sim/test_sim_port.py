"""The built-in simulated machine behind `sim://` speaks the firmware's protocol.

The link is the firmware tests' `FirmwareLink` (tests/firmware_support.py) on a
`sim://` port, so both ends are driven by the same host code, and the bad-input
sequence is the firmware test's own (`check_bad_input_replies`).
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import serial

from galileo_cnc import protocol as P
from galileo_cnc.config.hardware import TICKS_PER_S
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import (ArcTo, Dwell, EndJob, Flash, Home, Jog, LineTo, PenDown, PenUp,
                             Rapid, SetFeed, SetOrigin)
from galileo_cnc.machine import Hold, simulate
from galileo_cnc.sim import simulator
from galileo_cnc.sim.simulator import forget_named_machines
from galileo_cnc.transport.port import open_port

from firmware_support import FirmwareLink, check_bad_input_replies, status_when
from firmware_support import framed as _framed

CENTRE = [SetFeed(20000), Jog(3000, 3000, 0), SetOrigin(), SetFeed(800)]
#: what a job streamed as plain commands (no exit index on the wire) runs with: every
#: move from rest to rest (docs/motion.md §5.7)
STOPS = MachineConfig(junction_deviation_mm=0.0)


def sim_link(url: str = "sim://?speed=0", timeout: float = 2.0) -> FirmwareLink:
    link = FirmwareLink.__new__(FirmwareLink)
    link.port = open_port(url, 115200, timeout=timeout)
    link.banner = P.parse_reply(link.port.readline())
    assert link.banner.kind == "banner", link.banner
    P.check_banner(link.banner.banner)
    link.seq = 0
    link.unsolicited = []
    return link


@pytest.fixture
def link():
    link = sim_link()
    yield link
    link.close()


def test_serial_for_url_gives_the_firmware_banner():
    port = serial.serial_for_url("sim://?speed=0", baudrate=115200, timeout=1)
    try:
        banner = P.parse_reply(port.readline())
        assert banner.kind == "banner"
        assert P.check_banner(banner.banner).protocol_version == P.PROTOCOL_VERSION
        assert (banner.banner.rx_buffer_bytes, banner.banner.queue_blocks) == (
            P.RX_BUFFER_BYTES, P.QUEUE_BLOCKS)
        port.write(P.encode_command(P.QueryVersion(), 0))
        reply = P.parse_reply(port.readline())
        assert reply.kind == "ok" and reply.seq == 0 and reply.banner == banner.banner
        assert port.in_waiting == 0
    finally:
        port.close()


def test_moves_are_answered_and_end_where_commanded(link):
    job = CENTRE + [PenDown(), LineTo(700, 0), ArcTo(0, 0, -350, 0, cw=True),
                    Rapid(200, 100), Flash(), Dwell(30), LineTo(-500, 120, 40), PenUp()]
    replies = link.stream(job)
    assert [r.kind for r in replies] == ["ok"] * len(job)
    assert [r.seq for r in replies] == list(range(len(job)))
    status = link.status()
    ref = simulate(job, MachineConfig(junction_deviation_mm=0.0))   # plain moves: stop to stop
    assert status == P.Status("idle", *ref.final_position, 0, len(job) - 1)
    assert (status.x_steps, status.y_steps) == (-500, 120)
    trace = link.port.trace()
    assert trace.same_steps(ref)
    assert trace.final_position == ref.final_position
    assert trace.total_ticks == ref.total_ticks


def test_bad_input_gets_the_firmwares_reply_and_the_next_line_works(link):
    check_bad_input_replies(link, idle_timeout_s=5)


@pytest.mark.parametrize("raw, expected", [
    (b"\n\r\n", None),                                           # empty lines: no reply
    (_framed(b"N1 S 1"), ("error", 4, 1)),                       # S takes no argument
    (_framed(b"N1 L 1 2 3 4"), ("error", 4, 1)),                 # too many
    (_framed(b"N1 L 1 1234567890"), ("error", 4, 1)),            # 10 digits
    (_framed(b"N1 L 1 10000000"), ("error", 4, 1)),              # outside COORD
    (_framed(b"N1 M 2"), ("error", 4, 1)),                       # FLAG is 0/1
    (_framed(b"N1 LXQW 1 2"), ("error", 3, 1)),                  # 4-letter mnemonic
    (_framed(b"N1 l 1 2"), ("error", 3, 1)),
    (_framed(b"X1 S"), ("error", 1, None)),                      # no N
    (_framed(b"N123456 S"), ("error", 1, None)),
    (_framed(b"N1S"), ("error", 1, None)),
    (b"N1 S*f4\n", ("rs", None, 1)),                             # lower-case hex
    (_framed(b"N1 CW 10 0 5 999999"), ("error", 7, 1)),          # arc too large
    (b"N1 J " + b"1" * 58 + b"\n", ("rs", None, 1)),            # 64 bytes: fits, no CRC
    (b"N1 J " + b"1" * 59 + b"\n", ("error", 2, None)),         # 65 bytes: too long
])
def test_more_bad_lines(link, raw, expected):
    assert link.send(P.QueryStatus()).kind == "ok"
    link.port.write(raw)
    if expected is None:
        assert link.status().last_seq == 0 and link.port.in_waiting == 0
        return
    r = link.read_reply()
    kind, code, seq = expected
    assert r.kind == kind and r.seq == seq and (kind == "rs" or r.code == code), r


def test_carriage_returns_are_ignored_and_leading_zeros_accepted(link):
    link.port.write(b"\r" * 3 + _framed(b"N00000 F 000000800")[:-1] + b"\r\n")
    assert link.read_reply() == P.Reply("ok", 0)


def test_version_and_end_of_job(link):
    r = link.send(P.QueryVersion())
    assert r.kind == "ok" and r.banner == link.banner.banner
    assert link.send(EndJob()).kind == "ok"
    assert link.send(Jog(1, 0, 0)).code == 8
    assert link.send(P.Unlock()).kind == "ok"
    assert link.send(Jog(1, 0, 0)).kind == "ok"


def test_hold_queues_blocks_and_resume_runs_them(link):
    assert all(r.kind == "ok" for r in link.stream(CENTRE))
    link.port.write(P.RT_HOLD)
    assert link.status().state == "hold"
    job = [LineTo(100 * (i + 1), 50) for i in range(P.QUEUE_BLOCKS)]
    assert all(r.kind == "ok" for r in link.stream(job))
    held = link.status()
    assert held == P.Status("hold", 0, 0, 0, P.QUEUE_BLOCKS, len(CENTRE) + len(job) - 1)
    # The queue is full: the next line waits unanswered (flow control) ...
    link.port.timeout = 0.2
    link.port.write(P.encode_command(LineTo(0, 0), link.seq))
    link.seq = P.next_seq(link.seq)
    assert link.port.readline() == b""
    # ... real-time bytes still act while it waits, in the middle of a line too.
    line = P.encode_command(Jog(5, 0, 0), link.seq)
    link.seq = P.next_seq(link.seq)
    link.port.write(line[:4] + P.RT_STATUS + line[4:])
    assert link.read_reply().status.queue_blocks == P.QUEUE_BLOCKS
    link.port.timeout = 2
    link.port.write(P.RT_RESUME)
    assert link.read_reply() == P.Reply("ok", len(CENTRE) + len(job))
    assert link.read_reply() == P.Reply("ok", len(CENTRE) + len(job) + 1)
    status = link.wait_idle(5)
    assert (status.state, status.x_steps, status.y_steps, status.queue_blocks) == (
        "idle", 5, 0, 0)
    ref = simulate(CENTRE + job + [LineTo(0, 0), Jog(5, 0, 0)], STOPS)
    assert link.port.trace().same_steps(ref)


def test_abort_drops_the_queue_keeps_the_position_and_locks(link):
    assert all(r.kind == "ok" for r in link.stream(CENTRE + [LineTo(300, 200)]))
    link.port.write(P.RT_HOLD)
    assert all(r.kind == "ok" for r in link.stream([LineTo(2400, 800), LineTo(0, 0)]))
    link.port.write(P.RT_ABORT)
    alarm = link.read_reply()
    assert (alarm.kind, alarm.code) == ("alarm", 14)
    status = link.status()
    assert (status.state, status.x_steps, status.y_steps, status.queue_blocks) == (
        "alarm", 300, 200, 0)
    assert link.send(Jog(1, 0, 0)).code == 9                   # locked
    assert link.send(P.Unlock()).kind == "ok"
    assert link.send(LineTo(0, 0)).kind == "ok"                # planned from where it stopped
    assert link.status() == P.Status("idle", 0, 0, 0, 0, link.seq - 1)
    assert link.port.trace().same_steps(simulate(CENTRE + [LineTo(300, 200), LineTo(0, 0)]))


def test_abort_when_idle_still_alarms(link):
    link.port.write(P.RT_ABORT)
    assert link.read_reply() == P.Reply("alarm", None, 14, "aborted")
    assert link.status().state == "alarm"


def test_homing_failure_arrives_as_an_alarm(tmp_path):
    profile = tmp_path / "m.toml"
    profile.write_text(MachineConfig(sim_x_endstop_steps=-100000).to_toml())
    link = sim_link(f"sim://?speed=0&config={profile}")
    try:
        assert link.send(Home()).kind == "ok"
        alarm = link.read_reply()
        assert (alarm.kind, alarm.code) == ("alarm", 11)
        assert link.send(Jog(1, 0, 0)).code == 9
    finally:
        link.close()


def test_config_in_the_url_sets_the_travel(tmp_path):
    profile = tmp_path / "small.toml"
    profile.write_text(MachineConfig(x_travel_mm=1.0).to_toml())   # 160 steps
    link = sim_link(f"sim://?speed=0&config={profile}")
    try:
        r = link.send(LineTo(161, 0))
        assert (r.code, r.text) == (5, "soft limit: X would reach 161, above 160")
    finally:
        link.close()
    with pytest.raises(serial.SerialException):
        open_port("sim://?pace=3")


def test_a_reader_thread_and_a_writer_share_the_port(link):
    job = CENTRE + [LineTo(i % 37, i % 23) for i in range(200)]
    lines = []
    for cmd in job:
        lines.append(P.encode_command(cmd, link.seq))
        link.seq = P.next_seq(link.seq)
    got = []

    def reader():
        while len(got) < len(job):
            raw = link.port.readline()
            if not raw:
                return
            reply = P.parse_reply(raw)
            if reply.kind == "ok":
                got.append(reply.seq)

    thread = threading.Thread(target=reader)
    thread.start()
    for line in lines:
        link.port.write(line)
        link.port.write(P.RT_STATUS)
    thread.join(10)
    assert got == list(range(len(job)))
    assert link.port.trace().same_steps(simulate(job))


# ---- sim:// in time: pacing, hold / resume / abort mid-move, named machines ------------------

SPEED = 10          # machine seconds per wall second: a 1.8 s move takes 180 ms
LONG_MOVE = [SetFeed(8000), LineTo(8000, 0)]     # 1.8 s of machine time


@pytest.fixture
def paced():
    link = sim_link(f"sim://?speed={SPEED}")
    yield link
    link.close()


@pytest.fixture
def wall_paced():
    """sim:// at the wall clock's pace, for a test whose blocks must all be queued
    before the machine could run out of them even on a host loaded for a moment (at
    SPEED, once under a full load, a machine braked early on seven blocks sent at once)."""
    link = sim_link("sim://?speed=1")
    yield link
    link.close()


@pytest.fixture
def forget_named():
    forget_named_machines()
    yield
    forget_named_machines()


def machine_ticks(trace, ref):
    """The trace's ticks on the reference's clock: an idle machine starts the first
    block when it is queued, so a paced trace is the reference shifted once."""
    return trace.tick - (trace.tick[0] - ref.tick[0])


def stopped(link, timeout_s=5.0):
    """Status once the position stops changing (a hold's deceleration is over)."""
    last = link.status()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        time.sleep(0.01)
        status = link.status()
        if status == last:
            return status
        last = status
    raise AssertionError(f"still moving: {last}")


def test_paced_status_shows_the_move_running(paced):
    assert all(r.kind == "ok" for r in paced.stream(LONG_MOVE))
    first = status_when(paced, lambda s: s.x_steps > 0)
    later = status_when(paced, lambda s: s.x_steps > first.x_steps)
    assert (first.state, first.queue_blocks) == ("run", 1) and later.state == "run"
    assert later.x_steps < 8000 and (later.y_steps, later.z_steps) == (0, 0)
    done = paced.wait_idle(5)
    assert (done.state, done.x_steps, done.queue_blocks) == ("idle", 8000, 0)
    trace, ref = paced.port.trace(), simulate(LONG_MOVE)
    assert np.array_equal(machine_ticks(trace, ref), ref.tick)
    assert np.array_equal(trace.axis, ref.axis) and np.array_equal(trace.dir, ref.dir)


@pytest.fixture
def fast():
    link = sim_link("sim://?speed=20")
    yield link
    link.close()


def test_a_host_that_keeps_the_queue_full_gets_the_reference_trace(fast):
    # More lines than the queue holds: the waiting line's `ok` comes from the waker
    # when a block finishes, and the loop answers it with the next line at once.
    # 2.2 s of machine time: 16 lines of ~7 ms each at speed 20.
    job = [SetFeed(2000)] + [LineTo(200 * (i % 2), 200 * (i // 2)) for i in range(16)]
    replies = fast.stream(job)
    assert [r.kind for r in replies] == ["ok"] * len(job)
    assert fast.wait_idle(5).y_steps == 1400
    trace, ref = fast.port.trace(), simulate(job)
    assert np.array_equal(machine_ticks(trace, ref), ref.tick)
    assert np.array_equal(trace.axis, ref.axis) and np.array_equal(trace.dir, ref.dir)
    assert trace.total_ticks - (trace.tick[0] - ref.tick[0]) == ref.total_ticks


def test_an_idle_machine_starts_a_block_when_it_is_queued(paced):
    move = [SetFeed(8000), Jog(400, 0, 0)]
    assert all(r.kind == "ok" for r in paced.stream(move))
    first = paced.wait_idle(5)
    time.sleep(0.05)
    assert paced.send(Jog(400, 0, 0)).kind == "ok"
    assert paced.wait_idle(5).x_steps == first.x_steps + 400 == 800
    trace, one = paced.port.trace(), simulate(move)
    gap = int(trace.tick[400] - trace.tick[399])
    assert gap >= 0.05 * SPEED * TICKS_PER_S            # the idle time is in the trace
    assert np.array_equal(trace.tick[400:] - trace.tick[400], one.tick - one.tick[0])


def hold_candidates(trace, job):
    """Ticks (on the reference's clock) at which a hold would explain `trace`.

    The hold was seen by an event shortly before the first one whose tick departs
    from an uninterrupted run (a slower interval shows in the integer tick only
    once its subticks add up), so a few candidates are tried.
    """
    ref = simulate(job)
    t = machine_ticks(trace, ref)
    n = min(len(t), len(ref.tick))
    departs = int(np.flatnonzero(t[:n] != ref.tick[:n])[0])
    return t, [int(ref.tick[k]) for k in range(departs - 1, max(departs - 64, -1), -1)]


def held_reference(trace, job):
    """The reference run with the one hold (docs/motion.md §6) that gives `trace`."""
    t, candidates = hold_candidates(trace, job)
    resumed = int(np.argmax(np.diff(t))) + 1
    for at in candidates:
        unpaused = simulate(job, holds=[Hold(at, 0)])
        pause = int(t[resumed] - unpaused.tick[resumed])
        ref = simulate(job, holds=[Hold(at, pause)])
        if np.array_equal(ref.tick, t):
            return t, ref
    raise AssertionError("no hold of the reference gives this trace")


def test_hold_mid_move_decelerates_and_resume_ends_where_an_uninterrupted_run_ends(paced):
    assert all(r.kind == "ok" for r in paced.stream(LONG_MOVE))
    status_when(paced, lambda s: s.x_steps > 1000)
    paced.port.write(P.RT_HOLD)
    held = stopped(paced)
    assert held.state == "hold" and held.queue_blocks == 1 and 1000 < held.x_steps < 8000
    time.sleep(0.03)
    assert paced.status() == held                       # stopped, position known
    paced.port.write(P.RT_RESUME)
    assert paced.status().state == "run"
    done = paced.wait_idle(5)
    assert (done.state, done.x_steps) == ("idle", 8000)
    trace = paced.port.trace()
    t, ref = held_reference(trace, LONG_MOVE)
    assert np.array_equal(t, ref.tick)                  # exactly the reference's hold
    assert np.array_equal(trace.axis, ref.axis) and np.array_equal(trace.dir, ref.dir)
    assert trace.final_position == ref.final_position == (8000, 0, 0)
    gaps = np.diff(t)
    stop = int(np.argmax(gaps))
    assert gaps[stop] >= 0.03 * SPEED * TICKS_PER_S
    period = TICKS_PER_S / 8000
    assert gaps[stop - 1] > 2.9 * period and gaps[stop - 400] < gaps[stop - 1]  # slowed down
    assert gaps[stop + 1] > 2.9 * period and gaps[stop + 400] < gaps[stop + 1]  # ramps up


def test_lines_sent_during_a_hold_wait_for_the_resume(paced):
    assert all(r.kind == "ok" for r in paced.stream(LONG_MOVE))
    status_when(paced, lambda s: s.x_steps > 1000)
    paced.port.write(P.RT_HOLD)
    job = [LineTo(8000, 10 * (i + 1)) for i in range(P.QUEUE_BLOCKS - 1)]
    assert all(r.kind == "ok" for r in paced.stream(job))
    held = stopped(paced)
    assert (held.state, held.queue_blocks, held.y_steps) == ("hold", P.QUEUE_BLOCKS, 0)
    paced.port.timeout = 0.1
    paced.port.write(P.encode_command(LineTo(0, 0), paced.seq))   # no room: waits
    paced.seq = P.next_seq(paced.seq)
    assert paced.port.readline() == b""
    paced.port.timeout = 2
    paced.port.write(P.RT_RESUME)
    assert paced.read_reply() == P.Reply("ok", paced.seq - 1)
    done = paced.wait_idle(5)
    assert (done.x_steps, done.y_steps) == (0, 0)
    full = LONG_MOVE + job + [LineTo(0, 0)]
    trace, ref = paced.port.trace(), simulate(full)
    assert np.array_equal(trace.axis, ref.axis) and np.array_equal(trace.dir, ref.dir)


def test_abort_mid_move_decelerates_then_alarms_with_the_position_known(paced):
    assert all(r.kind == "ok" for r in paced.stream(LONG_MOVE + [LineTo(0, 0)]))
    status_when(paced, lambda s: s.x_steps > 1000)
    paced.port.write(P.RT_ABORT)
    alarm = paced.read_reply()                          # after the deceleration
    assert (alarm.kind, alarm.code) == ("alarm", 14)
    status = paced.status()
    assert (status.state, status.queue_blocks) == ("alarm", 0)
    assert 1000 < status.x_steps < 8000
    trace = paced.port.trace()
    assert trace.final_position == (status.x_steps, 0, 0)
    t, candidates = hold_candidates(trace, LONG_MOVE)    # exactly the reference's abort
    assert any(np.array_equal(t, simulate(LONG_MOVE, abort_at_tick=at).tick)
               for at in candidates)
    assert paced.send(Jog(1, 0, 0)).code == 9           # locked
    assert paced.send(P.Unlock()).kind == "ok"
    assert paced.send(LineTo(0, 0)).kind == "ok"        # planned from where it stopped
    assert paced.wait_idle(5).x_steps == 0
    assert paced.port.trace().final_position == (0, 0, 0)


def test_a_named_machine_keeps_power_while_the_port_is_closed(forget_named):
    url = f"sim://bench?speed={SPEED}"
    job = [SetFeed(4000)] + [LineTo(400 * (i + 1), 0) for i in range(12)]
    link = sim_link(url)
    assert link.send(P.QueryVersion()).kind == "ok"
    for cmd in job:                 # more than the queue: the rest waits in the buffer
        link.port.write(P.encode_command(cmd, link.seq))
        link.seq = P.next_seq(link.seq)
    link.close()                    # the cable is pulled mid-job
    machine = simulator.named_machine("bench")
    moved = len(machine.trace())
    deadline = time.monotonic() + 5                     # a loaded host may be slow to
    while len(machine.trace()) == moved and time.monotonic() < deadline:   # schedule it
        time.sleep(0.01)
    assert len(machine.trace()) > moved                 # still executing
    port = open_port(url, timeout=2)
    try:
        with pytest.raises(serial.SerialException):
            open_port(url)                              # one host at a time
        port.write(P.encode_command(P.QueryVersion(), 0))   # the host rule: N0 V
        replies = [P.parse_reply(port.readline())]      # answers to lines of the last
        while replies[-1].seq != 0:                     # session may come first ...
            replies.append(P.parse_reply(port.readline()))
        assert replies[-1].kind == "ok" and replies[-1].banner is not None
        assert all(r.kind == "ok" for r in replies)     # ... but no banner: no reset
        link.port, link.seq = port, 1
        done = link.wait_idle(5)
        assert (done.x_steps, done.queue_blocks) == (4800, 0)
        trace, ref = port.trace(), simulate(job, STOPS)
        assert np.array_equal(machine_ticks(trace, ref), ref.tick)
        assert trace.final_position == ref.final_position
    finally:
        port.close()
    with pytest.raises(serial.SerialException):
        open_port("sim://bench?speed=5")                # another machine by that name
    forget_named_machines()
    fresh = sim_link(url)                               # forgotten: a fresh power-on
    assert fresh.status() == P.Status("idle", 0, 0, 0, 0, 0)
    fresh.close()


@pytest.mark.parametrize("url", ["sim://?speed=-1", "sim://?speed=fast", "sim://?speed=inf",
                                 "sim://a/b", "sim://a b"])
def test_bad_sim_urls_do_not_open(url):
    with pytest.raises(serial.SerialException):
        open_port(url)


# ---- junction speeds (docs/motion.md §5.7): sim:// runs the exit indices as the firmware --
JUNCTIONS_ON = MachineConfig(junction_deviation_mm=0.05, vertex_speed_change_mm_s=3.0)
OCTAGON = [LineTo(round(900 * np.cos(a)), round(900 * np.sin(a)))
           for a in (k * np.pi / 4 + 0.3 for k in range(9))]


def test_exit_indices_on_the_wire_give_the_reference_with_junction_speeds(link):
    from galileo_cnc.machine.planner import with_exit_indices
    job = CENTRE + [SetFeed(1600)] + OCTAGON + [ArcTo(0, 0, -450, 0, cw=True), LineTo(0, 0)]
    wire = with_exit_indices(job, JUNCTIONS_ON)
    assert sum(1 for c in wire if getattr(c, "exit_index", None)) >= 7
    assert all(r.kind == "ok" for r in link.stream(wire))
    ref = simulate(job, JUNCTIONS_ON)
    assert ref.total_ticks < simulate(job).total_ticks
    trace = link.port.trace()
    assert np.array_equal(trace.tick, ref.tick) and trace.same_steps(ref)


def test_a_late_block_finds_the_machine_braked_to_the_end_of_its_queue(wall_paced):
    # Never overrun: the first side ends at a junction speed, but the next one comes
    # when the machine has stopped: it braked to the end of what it had, as the
    # reference's starved link (Starved) does, and the next side starts from rest.
    from galileo_cnc.machine import Starved
    from galileo_cnc.machine.planner import with_exit_indices
    paced = wall_paced
    job = CENTRE + [SetFeed(1600)] + OCTAGON[:4]
    wire = with_exit_indices(job, JUNCTIONS_ON)
    assert wire[6].exit_index
    assert all(r.kind == "ok" for r in paced.stream(wire[:7]))
    paced.wait_idle(5)
    time.sleep(0.05)
    assert all(r.kind == "ok" for r in paced.stream(wire[7:]))
    paced.wait_idle(5)
    trace = paced.port.trace()
    n1 = len(simulate(job[:7]).tick)
    ref = simulate(job, JUNCTIONS_ON, starved=[Starved(7, 100_000)])
    assert np.array_equal(trace.axis, ref.axis) and np.array_equal(trace.dir, ref.dir)
    for part in (slice(0, n1), slice(n1, None)):      # each part on the reference's ticks
        t, r = trace.tick[part], ref.tick[part]
        assert np.array_equal(t - t[0], r - r[0])
    free = simulate(job, JUNCTIONS_ON).tick
    assert not np.array_equal(free[:n1] - free[0], ref.tick[:n1] - ref.tick[0])
