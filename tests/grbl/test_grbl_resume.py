"""`plot --resume` on GRBL after a lost port, against GRBL 1.1h in simavr with the
harness's limit switches: the first plot's port dies mid-job (FaultyPort, as the
resume tests of our firmware cut theirs), GRBL runs on with what it had, then
`plot --resume` homes, goes back to where the job stood (pen up), and finishes it.
From the pins: the two sessions together draw the whole job, every end point exact
and every step within one step of its line, and the only lines drawn twice are
those GRBL had not yet acknowledged when the port died (in flight)."""

from __future__ import annotations

import re
import time

import numpy as np
import pytest
import serial

from galileo_cnc.cli import main as cli
from galileo_cnc.cli import plot_grbl
from galileo_cnc.config.profile import load_profile
from galileo_cnc.grbl.gcode import GcodeLine, GrblPen, pen_from_config
from galileo_cnc.grbl.link import GrblLink
from galileo_cnc.grbl.numbers import grbl_steps
from galileo_cnc.grbl.resume import PREAMBLE_TEXT, lead_in, rewind, state_before
from galileo_cnc.plan.offsets import DEFAULT_MARGIN_NM
from galileo_cnc.plan.pipeline import PlanOptions
from galileo_cnc.stream.journal import ABORTED, FINISHED, INTERRUPTED

from faults import FaultyPort
from grbl_support import (PROFILE, SAMPLE, SCALE, SETTINGS, check_trace, grbl_machine,
                          motions, planned_gcode, positions_and_ticks)

MM = 160                # steps
# homing on, switches at +2, +3, +1 mm (GRBL homes toward +, pulls off $27 = 1 mm);
# $10=3 adds the buffer state to status reports (Bf:15,128: planner and RX buffer empty)
HOMING = {**SETTINGS, 10: "3", 22: "1", 130: "100", 131: "100", 132: "20",
          25: "1000", 24: "200"}
LIMITS = (("X", 2 * MM), ("Y", 3 * MM), ("Z", 1 * MM))
WORK_ZERO_MM = (-60, -60, -10)          # machine position of the job's work zero
HOMED = (-MM, -MM, -MM)                 # machine position after $H


class RecordingPort(FaultyPort):
    """FaultyPort that keeps every line that reached the board."""

    def __init__(self, port, **faults):
        super().__init__(port, **faults)
        self.sent: list[str] = []

    def write(self, data: bytes) -> int:
        written = super().write(data)
        if data.endswith(b"\n"):
            self.sent.append(data.decode().strip())
        return written


def wait_until_still(port_path: str) -> None:
    """As the user is told to: wait until the machine stands still (the pty, unlike
    an Uno, does not reset GRBL on opening, so it can be asked)."""
    with serial.Serial(port_path, 115200, timeout=0.2) as port:
        link = GrblLink(port)
        while link.read_line(0.5) is not None:     # replies nobody read after the cut
            pass
        for _ in range(20000):
            status = link.status()
            if status.state == "Idle" and (status.planner_free, status.rx_free) == (15, 128):
                return
    raise AssertionError(f"GRBL never came to rest (last {status})")


def settled_trace(board):
    """The pin trace once the harness has flushed it (GRBL is standing still)."""
    count = -1
    while True:
        edges = board.trace()
        if len(edges[0]) == count:
            return edges
        count = len(edges[0])
        time.sleep(0.3)


def sent_job_lines(sent: list[str], lines: list[GcodeLine]) -> int:
    """The index of the last job line that reached GRBL (the rest of `sent` is $I,
    $$, $#, G4 P0 and status queries)."""
    index = 0
    for text in sent:
        if index < len(lines) and text == lines[index].text:
            index += 1
    return index - 1


def set_work_zero(link: GrblLink) -> None:
    """The user's set-up: home, go to the job's work zero, store it in G54; the
    port is closed again for the plot."""
    link.command_checked("$H")
    work = " ".join(f"{'XYZ'[a]}{v}" for a, v in enumerate(WORK_ZERO_MM))
    link.command_checked(f"G0 {work}")
    link.command_checked("G10 L20 P1 X0 Y0 Z0")
    link.wait_idle()
    link.port.close()


@pytest.fixture
def profile(tmp_path, monkeypatch):
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    path = tmp_path / "fast.toml"
    path.write_text(PROFILE)
    return str(path)


def sample_options(profile: str, board) -> plot_grbl.GrblPlotOptions:
    """`plot SAMPLE --mode centre --yes` on the board, as the first plot of a test."""
    return plot_grbl.GrblPlotOptions(SAMPLE, load_profile(profile, port=board.port),
                                     board.port, PlanOptions(mode="centre"),
                                     margin_nm=DEFAULT_MARGIN_NM, yes=True)


def test_resume_after_a_lost_port_homes_and_finishes_the_job(profile, capsys):
    lines = planned_gcode(profile)
    config = load_profile(profile).config
    pen = pen_from_config(config)
    with grbl_machine(HOMING, limits=LIMITS) as (board, link):
        set_work_zero(link)
        setup_end = settled_trace(board)

        # the first plot: its port dies in the middle of the job
        port = RecordingPort(serial.Serial(board.port, 115200, timeout=0.2), die_after=45)
        assert plot_grbl.run_grbl_plot(sample_options(profile, board),
                                       port=port) == plot_grbl.EXIT_PORT_LOST
        out, _ = capsys.readouterr()
        assert f"galileo-cnc plot {SAMPLE} --resume" in out
        entry = plot_grbl.grbl_journal().load()
        assert entry.state == INTERRUPTED and entry.total == len(lines)
        confirmed, last_sent = entry.confirmed, sent_job_lines(port.sent, lines)
        assert 10 < confirmed <= last_sent < len(lines) - 10      # cut in the middle
        wait_until_still(board.port)
        cut = settled_trace(board)

        code = cli.main(["plot", SAMPLE, "--resume", "--yes", "--port", board.port,
                         "--profile", profile])
        out, err = capsys.readouterr()
        # the job is done: nothing left to resume
        assert plot_grbl.grbl_journal().pending() is None
        assert cli.main(["plot", SAMPLE, "--resume", "--yes", "--port", board.port,
                         "--profile", profile]) == 1
        assert "no interrupted GRBL job of" in capsys.readouterr().err
        board.stop()
    assert code == 0, err
    assert "ALARM" not in out + err and "error" not in out + err
    start = int(re.search(r"resuming at G-code line (\d+) of", out)[1]) - 1
    assert start == confirmed + 1 and "after the last line GRBL acknowledged" in out
    assert "homing ($H)" in out and "process has finished" in out
    assert plot_grbl.grbl_journal().load().state == FINISHED
    # one pen asked for before going on (the one in use at the resumed line)
    assert out.count("(the pen the job goes on with)") <= 1

    # the pins, split at the sessions' ends (GRBL stood still at each)
    pos, tick = positions_and_ticks(board.trace())
    rows = [int(np.searchsorted(tick, edges[0][-1] // 8, side="right")) - 1
            for edges in (setup_end, cut)]
    at_zero = pos[rows[0]]                   # the pins at the job's work zero
    work = pos - at_zero
    # session 1: the job from its start up to some line X the queue ended with
    first = work[rows[0]:rows[1] + 1]
    ran = None
    for last in range(confirmed, last_sent + 1):
        try:
            check_trace(first, lines[:last + 1])
            ran = last
            break
        except AssertionError:
            continue
    assert ran is not None, "the first session is no prefix of the job"
    # session 2: homing, then the lead-in from the homed position, then the rest
    homed = tuple(np.subtract(HOMED, np.multiply(WORK_ZERO_MM, MM)))
    second = work[rows[1]:]
    back_home = np.nonzero(np.all(second == homed, axis=1))[0]
    assert len(back_home), "the resume never reached the homed position"
    resumed = second[back_home[-1]:]
    lead = lead_in(lines, start, SCALE, pen)
    assert lead[0].text == PREAMBLE_TEXT
    checked = check_trace(resumed, lead + lines[start:], start=homed)
    assert checked["worst_axis_steps"] <= 1.0
    # pen up (at or above its up height) while travelling to where line `start` begins
    begin = _state_steps(lines, start)
    arrive = int(np.nonzero(np.all(resumed == begin, axis=1))[0][0])
    travel = resumed[:arrive + 1]
    elsewhere = np.any(travel[:, :2] != begin[:2], axis=1)
    assert elsewhere.any() and np.all(travel[elsewhere, 2] >= pen.up_z_steps)
    # together the whole job; drawn twice only the lines in flight at the cut
    assert start <= ran + 1
    twice = range(start, ran + 1)
    assert all(confirmed < k <= last_sent for k in twice), (confirmed, last_sent, start, ran)
    assert tuple(resumed[-1]) == next(reversed(list(motions(lines))))[2]


def _state_steps(lines, start) -> tuple[int, int, int]:
    """Where the job stands before lines[start], in steps (the texts GRBL reads)."""
    state = state_before(lines, start)
    return tuple(grbl_steps(text, SCALE.steps_per_mm[a]) for a, text in enumerate(state.axes))


# ---- the G-code side, without a board -------------------------------------------------------

def test_lead_in_restores_pen_position_and_feed():
    lines = [GcodeLine(t, i) for i, t in enumerate([
        PREAMBLE_TEXT, "G1 Z1.875 F3000", "G0 X5 Y4", "G1 Z0 F3000", "G1 X6 F6000",
        "G2 X7 Y5 I0 J1", "G1 Z1.875 F3000", "G0 X9 Y9", "G1 Z0", "G1 X10 F6000"])]
    pen = GrblPen(up_z_steps=300, down_z_steps=0, z_feed_steps_per_s=400)
    assert lead_in(lines, 0, SCALE, pen) == []
    assert [line.text for line in lead_in(lines, 5, SCALE, pen)] == [
        PREAMBLE_TEXT, "G0 Z1.875", "G0 X6 Y4", "G1 Z0 F150", "F6000"]
    assert all(line.command == 5 for line in lead_in(lines, 5, SCALE, pen))
    # pen up before line 8: no lowering; the modal feed is the pen's last F
    assert [line.text for line in lead_in(lines, 8, SCALE, pen)] == [
        PREAMBLE_TEXT, "G0 Z1.875", "G0 X9 Y9", "F3000"]


def test_rewind_goes_back_over_the_queue_but_not_past_a_dwell():
    texts = ["G21 G90 G17 G94 G54", "G0 X1", "G4 P0.02"] + [f"G1 X{k}" for k in range(2, 40)]
    lines = [GcodeLine(t, i) for i, t in enumerate(texts)]
    assert rewind(lines, 40, 0, 20) == 40 - 20 + 1     # the 20 motion lines before may be lost
    assert rewind(lines, 10, 0, 20) == 3               # everything before the dwell had run
    assert rewind(lines, 10, 6, 20) == 6               # not before the session's first line


class CtrlCPort(RecordingPort):
    """The user presses Ctrl-C while the plot sends the line after `after` lines."""

    def __init__(self, port, after: int):
        super().__init__(port)
        self.after = after
        self.raw = bytearray()          # every byte written, real-time ones included

    def write(self, data: bytes) -> int:
        if data.endswith(b"\n") and len(self.sent) == self.after:
            self.after = -1
            raise KeyboardInterrupt
        self.raw += data
        return super().write(data)


def test_ctrl_c_holds_then_resets_and_resume_finishes_the_job(profile, capsys):
    lines = planned_gcode(profile)
    with grbl_machine(HOMING, limits=LIMITS) as (board, link):
        set_work_zero(link)
        setup_end = settled_trace(board)

        port = CtrlCPort(serial.Serial(board.port, 115200, timeout=0.2), after=60)
        assert plot_grbl.run_grbl_plot(sample_options(profile, board),
                                       port=port) == plot_grbl.EXIT_INTERRUPTED
        out, _ = capsys.readouterr()
        assert "stopped: GRBL held the feed, then was reset" in out
        entry = plot_grbl.grbl_journal().load()
        assert entry.state == ABORTED and 0 < entry.confirmed < len(lines) - 10
        # the feed hold (!) came first, then the soft reset (0x18): the position is kept
        held = port.raw.index(b"!")
        assert b"\x18" in port.raw[held:]

        code = cli.main(["plot", SAMPLE, "--resume", "--yes", "--port", board.port,
                         "--profile", profile])
        out, err = capsys.readouterr()
        board.stop()
    assert code == 0, err
    assert "ALARM" not in out + err and "process has finished" in out
    assert plot_grbl.grbl_journal().load().state == FINISHED
    pos, tick = positions_and_ticks(board.trace())
    at_zero = pos[int(np.searchsorted(tick, setup_end[0][-1] // 8, side="right")) - 1]
    end = next(reversed(list(motions(lines))))[2]
    assert tuple(pos[-1] - at_zero) == end          # the job's last point, exactly
