"""The built-in simulated machine behind `sim://` speaks the firmware's protocol.

The link is the firmware tests' `FirmwareLink` (tests/firmware_support.py) on a
`sim://` port, so both ends are driven by the same host code, and the bad-input
sequence is the firmware test's own (`check_bad_input_replies`).
"""

from __future__ import annotations

import threading

import pytest
import serial

from galileo_cnc import protocol as P
from galileo_cnc.config import MachineConfig
from galileo_cnc.machine import (ArcTo, Dwell, EndJob, Flash, Home, Jog, LineTo, PenDown,
                                 PenUp, Rapid, SetFeed, SetOrigin, simulate)
from galileo_cnc.transport import open_port

from firmware_support import FirmwareLink, check_bad_input_replies
from firmware_support import framed as _framed

CENTRE = [SetFeed(20000), Jog(3000, 3000, 0), SetOrigin(), SetFeed(800)]


def sim_link(url: str = "sim://", timeout: float = 2.0) -> FirmwareLink:
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
    port = serial.serial_for_url("sim://", baudrate=115200, timeout=1)
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
    ref = simulate(job)
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
    (_framed(b"N1 LX 1 2"), ("error", 3, 1)),                    # 4-letter mnemonic
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
    ref = simulate(CENTRE + job + [LineTo(0, 0), Jog(5, 0, 0)])
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
    link = sim_link(f"sim://?config={profile}")
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
    link = sim_link(f"sim://?config={profile}")
    try:
        r = link.send(LineTo(161, 0))
        assert (r.code, r.text) == (5, "soft limit: X would reach 161, above 160")
    finally:
        link.close()
    with pytest.raises(serial.SerialException):
        open_port("sim://?speed=3")


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
