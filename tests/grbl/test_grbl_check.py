"""GRBL's check mode ($C) in simavr: every rejected line reported with its file
line, nothing moves, and what leaving check mode (a soft reset) loses is put back."""

from __future__ import annotations

import numpy as np

from galileo_cnc.grbl import firmware
from galileo_cnc.grbl.check import check_job, parameters, parser_state
from galileo_cnc.grbl.gcode import GcodeLine

from grbl_support import QUICK_HOMING, SETTINGS, grbl_machine, positions

MM = 1_000_000     # nm


def step_edges(board) -> int:
    _, pin, _ = (np.asarray(a) for a in board.trace())
    return int(np.isin(pin, [step for step, _ in firmware.AXIS_PINS]).sum())


def where(command: int) -> str:
    return f"board.gbr:{10 + command}"


JOB = ["G21 G90", "G1 X10 Y5 F1200",
       "G5 X1",                         # error:20, no cubic splines in GRBL
       "G1 X1 Y",                       # error:2, a word without its number
       "G2 X10 Y15 I0 J3",              # error:33, end 7 mm from a 3 mm circle's centre
       "G10 L20 P1 X0 Y0",              # accepted, and written to EEPROM even in $C
       "G0 Z2", "G1 X2 Y2"]


def test_check_job_reports_every_rejected_line_and_restores_grbl():
    lines = [GcodeLine(text, i) for i, text in enumerate(JOB)]
    with grbl_machine(SETTINGS) as (board, link):
        # a state the reset would lose: G54 and G92 offsets, G91, G1, F, S
        for text in ("G10 L2 P1 X5 Y-3", "G92 X1 Y1", "G91 G1 F750 S300"):
            link.command_checked(text)
        modes, params, before = parser_state(link), parameters(link), link.status()
        assert params["G92"] == ("-6.000", "2.000", "0.000")

        report = check_job(link, lines, where=where)

        assert [(e.index, e.code, e.where) for e in report.errors] == \
            [(2, 20, "board.gbr:12"), (3, 2, "board.gbr:13"), (4, 33, "board.gbr:14")]
        text = str(report)
        assert text.startswith("8 lines checked, 3 rejected:\n")
        assert "board.gbr:12: error:20: Unsupported command" in text
        assert "[MSG:Enabled]" in link.messages and "[MSG:Disabled]" in link.messages
        # the reset cleared G92 and the modes, and the checked G10 rewrote G54
        assert any(s.startswith("G10 L2 P1 X5.000 Y-3.000") for s in report.restored)
        assert any(s.startswith("G92 ") for s in report.restored)
        assert parser_state(link) == modes
        assert parameters(link) == params
        after = link.status()
        assert after.state == "Idle"
        assert (after.mpos_nm, after.wpos_nm) == (before.mpos_nm, before.wpos_nm)
        board.stop()
    assert step_edges(board) == 0                       # check mode moved nothing


def test_check_mode_soft_limit_alarm_is_reported_and_grbl_left_unlocked():
    settings = {**SETTINGS, 22: "1", 20: "1", 130: "50", 131: "50", 132: "10",
                25: "1000", **QUICK_HOMING}
    limits = (("X", 320), ("Y", 480), ("Z", 160))      # switches at +2, +3, +1 mm
    lines = [GcodeLine(t, i) for i, t in enumerate(["G1 X-10 F1000", "G1 X5", "G1 X-20"])]
    with grbl_machine(settings, limits=limits) as (board, link):
        link.command_checked("$H")
        homed = link.status()
        report = check_job(link, lines, where=where)
        # GRBL checks soft limits in $C too, and alarms: the line is named
        assert "board.gbr:11: ALARM:2: Soft limit" in report.alarm and not report.ok
        assert str(report).startswith("3 lines checked, 0 rejected\n  stopped by board.gbr:11")
        after = link.status()
        assert after.state == "Idle" and after.mpos_nm == homed.mpos_nm == (-MM, -MM, -MM)
        board.stop()
    # the pins end where homing left them: at each switch less the 1 mm pull-off
    # (160 steps; the switch is found within a step), so the check moved nothing
    pulled_off = np.array([trip for _, trip in limits]) - 160
    assert np.all(np.abs(positions(board)[-1] - pulled_off) <= 1)
