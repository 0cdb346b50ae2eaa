"""Real-time control of GRBL in simavr: feed hold and resume, soft reset while
moving (ALARM:3, unlocked with $X only when asked), homing against the harness's
limit switches, and a soft-limit alarm named with its file line."""

from __future__ import annotations

import time

import pytest

from galileo_cnc.grbl.gcode import GcodeLine
from galileo_cnc.grbl.link import CYCLE_START, FEED_HOLD, STATUS_QUERY
from galileo_cnc.grbl.reports import GrblError
from galileo_cnc.grbl.session import held
from galileo_cnc.grbl.stream import GrblStreamError, stream

from grbl_support import QUICK_HOMING, SETTINGS, check_trace, grbl_machine, positions, \
    reset_while_moving

MM = 1_000_000     # nm
# Paced to the wall clock: a host held up by a loaded machine must not find the
# move already over when its `!` or reset arrives (free-running, simavr is ~5x faster).
PACED = {"realtime": True}


def wait_state(link, wanted, limit=2000):
    """Status reports until GRBL is in `wanted` (each report is one round trip)."""
    for _ in range(limit):
        status = link.status()
        if status.state == wanted or f"{status.state}:{status.substate}" == wanted:
            return status
    raise AssertionError(f"GRBL never reached {wanted} (last {status})")


def test_feed_hold_stops_on_the_path_and_resume_finishes_it():
    lines = [GcodeLine("G1 X40 Y10 F1500", 0)]
    with grbl_machine(**PACED) as (board, link):
        link.write_line(lines[0].text)
        assert link.wait_reply().ok
        moving = wait_state(link, "Run")
        link.realtime(FEED_HOLD)
        held = wait_state(link, "Hold:0")           # decelerated to a stop
        assert 0 < held.mpos_nm[0] < 40 * MM and held.mpos_nm != moving.mpos_nm
        again = [link.status() for _ in range(5)]
        assert all(s.state == "Hold" and s.mpos_nm == held.mpos_nm for s in again)
        link.realtime(CYCLE_START)
        done = wait_state(link, "Idle")
        assert done.mpos_nm == (40 * MM, 10 * MM, 0)
        board.stop()
    check_trace(positions(board), lines)             # the hold left the line nowhere


def test_soft_reset_while_moving_alarms_and_unlocks_only_on_request():
    with grbl_machine(**PACED) as (board, link):

        def move_under_way():
            # 8 s long: a host held up for a moment still finds it moving; back to 0
            # from where a move that ended before its reset left it
            far = link.status().mpos_nm[0] > 20 * MM
            link.command_checked(f"G1 X{0 if far else 40} F300")
            wait_state(link, "Run")

        reset_while_moving(link, move_under_way)
        assert link.alarms == [3] and link.version == "1.1h"   # position lost
        status = link.status()
        assert status.state == "Alarm"
        refused = link.command("G1 X0")
        assert not refused.ok and refused.code == 9  # G-code locked out during alarm
        unlocked = link.command("$X")
        assert unlocked.ok and any("Unlocked" in m for m in link.messages)
        idle = link.status()
        assert idle.state == "Idle"
        board.stop()
    # GRBL counts a step when its interrupt computes it and pulses it in the next
    # one: a reset between the two leaves GRBL's count one step ahead of the pins
    # (one reason GRBL says the position is lost). Never more than that.
    steps_x = int(positions(board)[-1][0])
    assert abs(idle.mpos_nm[0] - steps_x * 6250) <= 6250 + 500


def test_homing_then_soft_limit_alarm_names_the_file_line():
    settings = {**SETTINGS, 22: "1", 20: "1", 130: "50", 131: "50", 132: "10",
                25: "1000", **QUICK_HOMING}
    limits = (("X", 320), ("Y", 480), ("Z", 160))    # switches at +2, +3, +1 mm
    with grbl_machine(settings, limits=limits) as (board, link):
        assert link.settings.homing and link.settings.soft_limits
        link.command_checked("$H")
        homed = link.status()
        # homed toward +, pulled off $27 = 1 mm: machine space is -travel..0
        assert homed.state == "Idle" and homed.mpos_nm == (-MM, -MM, -MM)
        lines = [GcodeLine("G1 X-10 Y-10 F2000", 0), GcodeLine("G0 X5", 1),
                 GcodeLine("G0 X-20", 2)]
        with pytest.raises(GrblStreamError) as raised:
            # our own check would refuse it first (test_grbl_travel.py): GRBL's is tested here
            stream(link, lines, where=lambda command: f"board.gbr:{17 + command}",
                   travel_check=False)
        assert raised.value.alarm and raised.value.code == 2
        assert "board.gbr:18: ALARM:2: Soft limit" in str(raised.value)
        assert link.alarms == [2]
        # a limit alarm is critical: GRBL answers nothing (not even ?) until reset
        while "[MSG:Reset to continue]" not in link.messages:
            line = link.read_line()
            assert line is not None, "no [MSG:Reset to continue]"
            link.classify(line)
        with pytest.raises(GrblError, match="no status report"):
            link.status(timeout_s=1.0)
        link.soft_reset()
        assert link.status().state == "Alarm"
        assert link.command("$X").ok and link.status().state == "Idle"
        board.stop()
    assert board.summary["overruns"] == "0"


def test_a_stop_waits_for_the_hold_past_a_report_asked_before_it():
    """The streamer's status watch may have a `?` out when the user stops: its answer,
    Idle from before the move began, comes back first. The stop must wait for Hold:0
    (a feed hold makes even an idle GRBL Hold:0), or its reset lands in the
    deceleration: ALARM:3, the position lost (a console test met it under load)."""
    with grbl_machine(**PACED) as (board, link):
        link.realtime(STATUS_QUERY)             # answered Idle, left unread for now
        link.port.write(b"G1 X40 F300\n")       # its ok left unread too
        time.sleep(0.3)                         # moving
        link.realtime(FEED_HOLD)
        status = held(link)
        assert (status.state, status.substate) == ("Hold", 0)
        link.soft_reset()
        assert link.alarms == []                # reset at rest: the position kept
        assert link.status().state == "Idle"
        board.stop()
