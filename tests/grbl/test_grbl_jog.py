"""Jogging, homing and unlocking GRBL in simavr: `$J=` moves exactly its steps,
0x85 stops a long jog early and decelerating, soft limits refuse a jog (ours
first, GRBL's error:15 otherwise), `$H` against the harness's switches."""

from __future__ import annotations

import numpy as np
import pytest

from galileo_cnc.grbl import firmware
from galileo_cnc.grbl.jog import JogError, cancel_jog, home, jog, keypad_jog, unlock, wait_jog
from galileo_cnc.grbl.travel import TravelError
from galileo_cnc.simavr.board import step_trace

from grbl_support import QUICK_HOMING, SETTINGS, grbl_machine, positions, reset_while_moving

MM = 1_000_000          # nm
STEP_NM = 6250          # 160 steps/mm
# Paced to the wall clock so a loaded host still finds the long jog running
# when its 0x85 or reset arrives (test_grbl_realtime.py does the same).
PACED = {"realtime": True}


def test_keypad_jog_maps_the_console_keys():
    assert [keypad_jog(k, 0.5) for k in "864217"] == [
        ("Y", 0.5), ("X", 0.5), ("X", -0.5), ("Y", -0.5), ("Z", -0.5), ("Z", 0.5)]
    assert keypad_jog("5", 0.5) is None and keypad_jog("q", 1.0) is None


def wait_y_beyond(link, y_nm, sign=1):
    """The first report of the jog past Y y_nm (going up; `sign` -1: going down)."""
    for _ in range(5000):
        status = link.status()
        if status.state == "Jog" and sign * status.mpos_nm[1] > sign * y_nm:
            return status
    raise AssertionError(f"the jog never passed Y {y_nm} nm (last {status})")


def test_jog_moves_its_steps_and_cancel_stops_early_decelerating():
    with grbl_machine(**PACED) as (board, link):
        with pytest.raises(JogError, match=r"homing is off on this GRBL \(\$22=0\)"):
            home(link)
        assert jog(link, "x", 2.5, 1000) == "$J=G91 G21 X2.5 F1000"
        assert wait_jog(link).mpos_nm == (2.5 * MM, 0, 0)
        assert link.command("$G").ok and link.command("G0 X2.5").ok   # no G91 left behind
        jog(link, "Y", 40, 1500)
        wait_y_beyond(link, 5 * MM)                    # at its 25 mm/s cruise
        stopped = cancel_jog(link)
        assert stopped.state == "Idle"
        assert 5 * MM < stopped.mpos_nm[1] < 40 * MM   # stopped early
        assert link.status().mpos_nm == stopped.mpos_nm
        board.stop()
    final = positions(board)[-1]
    assert tuple(int(s) * STEP_NM for s in final) == stopped.mpos_nm
    assert final[0] == 400                              # 2.5 mm at 160 steps/mm, exactly
    tick, axis, direction = step_trace(board.trace(), firmware.AXIS_PINS)
    assert np.all(direction[axis == 0] == -1)           # X only forward: no overshoot
    y_ticks = tick[axis == 1]
    gaps = np.diff(y_ticks)
    cruise = np.median(gaps[len(gaps) // 4: 3 * len(gaps) // 4])
    # the stop was a ramp: the last steps come far slower than at cruise
    assert gaps[-1] > 4 * cruise and np.all(gaps[-5:] > cruise)


def test_home_then_jog_inside_the_soft_limits_and_unlock_after_a_reset():
    settings = {**SETTINGS, 22: "1", 20: "1", 130: "50", 131: "50", 132: "10",
                25: "1000", **QUICK_HOMING}
    limits = (("X", 320), ("Y", 480), ("Z", 160))      # switches at +2, +3, +1 mm
    with grbl_machine(settings, limits=limits, **PACED) as (board, link):
        homed = home(link)
        assert homed.state == "Idle" and homed.mpos_nm == (-MM, -MM, -MM)
        with pytest.raises(TravelError, match=r"X would go to -101 mm .* -50\.\.0 mm \(\$130=50"):
            jog(link, "X", -100, 1000)
        with pytest.raises(JogError, match="leave the soft limits.*error:15") as refused:
            jog(link, "X", -100, 1000, check_travel=False)
        assert refused.value.code == 15 and not link.alarms     # refused, no alarm
        jog(link, "X", -2, 1000)
        assert wait_jog(link).mpos_nm == (-3 * MM, -MM, -MM)

        def jog_under_way():
            # 14 mm at 5 mm/s, reset 2 mm in: a loaded host still finds it running
            start_y = link.status().mpos_nm[1]
            jog(link, "Y", -14, 300)
            wait_y_beyond(link, start_y - 2 * MM, sign=-1)

        reset_while_moving(link, jog_under_way)         # mid-jog: ALARM:3
        assert link.alarms == [3]
        assert link.status().state == "Alarm"
        with pytest.raises(JogError, match="error:8: Not idle"):   # $J= needs Idle or Jog
            jog(link, "Y", 1, 1000)
        assert unlock(link).state == "Idle"
        board.stop()
    assert board.summary["overruns"] == "0"
