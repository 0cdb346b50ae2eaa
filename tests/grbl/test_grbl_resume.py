"""`plot --resume` on GRBL after a lost port, against GRBL 1.1h in simavr with the
harness's limit switches: the first plot's port dies mid-job (FaultyPort, as the
resume tests of our firmware cut theirs), GRBL runs on with what it had, then
`plot --resume` homes, goes back to where the job stood (pen up), and finishes it.
From the pins: the two sessions together draw the whole job, every end point exact
and every step within one step of its line, and the only lines drawn twice are
those GRBL had not yet acknowledged when the port died (in flight). Also: a resume
started while GRBL still moves (its reset drops the queue: ALARM:3, the resume goes
back over it), a machine without switches ($22=0: the user re-zeroes), Ctrl-C."""

from __future__ import annotations

import re
from contextlib import contextmanager
from types import SimpleNamespace

import numpy as np
import serial

from galileo_cnc.cli import main as cli
from galileo_cnc.cli import plot as plot_cli
from galileo_cnc.grbl.job import cut_short, grbl_journal
from galileo_cnc.transport.discovery import GRBL
from galileo_cnc.config.profile import load_profile
from galileo_cnc.grbl.gcode import GcodeLine, GrblPen, pen_from_config
from galileo_cnc.grbl.link import GrblLink
from galileo_cnc.grbl.resume import PREAMBLE_TEXT, lead_in, rewind
from galileo_cnc.plan.offsets import DEFAULT_MARGIN_NM
from galileo_cnc.stream.journal import ABORTED, FINISHED, INTERRUPTED, JournalEntry

from grbl_support import profile  # noqa: F401  (the fixture)
from grbl_support import (LIMITS, QUICK_ACCEL, QUICK_HOMED, SAMPLE, SCALE, SETTINGS,
                          RecordingPort, check_resumed, grbl_machine, motion_lines, motions,
                          planned_gcode,
                          positions_and_ticks, sent_job_lines, set_work_zero, settled_trace,
                          wait_until_still)


# GRBL as HOMING and SETTINGS set it, but at QUICK_ACCEL and locating its switches at
# 1000 mm/min (QUICK_HOMED): each test's two sessions and two homings take 10.4 s of
# machine time, not 14.2. What is checked holds at any rate: the pins against the G-code,
# the switches closing on their trip step, the queue's 20 blocks.
RESUME_NO_SWITCHES = {**SETTINGS, **QUICK_ACCEL, 10: "3"}



@contextmanager
def homed_at_work_zero():
    """GRBL in simavr with its switches and G54's zero set: (board, the pins' trace of
    that setting up, which the job's drawing follows)."""
    with grbl_machine(QUICK_HOMED, limits=LIMITS) as (board, link):
        set_work_zero(link)
        yield board, settled_trace(board)


def sample_options(profile: str, board) -> plot_cli.PlotOptions:
    """`plot SAMPLE --mode centre --yes` on the board, as the first plot of a test."""
    return plot_cli.PlotOptions(SAMPLE, load_profile(profile, port=board.port),
                                mode="centre", margin_nm=DEFAULT_MARGIN_NM, yes=True,
                                kind=GRBL)


def run_grbl_plot(options: plot_cli.PlotOptions, port=None) -> int:
    """`plot` on the GRBL board over `port` (already open) when given."""
    options.handle = port
    return plot_cli.run_plot(options)


def test_resume_after_a_lost_port_homes_and_finishes_the_job(profile, capsys):
    lines = planned_gcode(profile)
    config = load_profile(profile).config
    pen = pen_from_config(config)
    with homed_at_work_zero() as (board, setup_end):

        # the first plot: its port dies in the middle of the job
        port = RecordingPort(serial.Serial(board.port, 115200, timeout=0.2), die_after=45)
        assert run_grbl_plot(sample_options(profile, board),
                                       port=port) == plot_cli.EXIT_PORT_LOST
        out, _ = capsys.readouterr()
        assert f"galileo-cnc plot {SAMPLE} --resume" in out
        entry = grbl_journal().load()
        assert entry.state == INTERRUPTED and entry.total == len(lines)
        confirmed, last_sent = entry.confirmed, sent_job_lines(port.sent, lines)
        assert 10 < confirmed <= last_sent < len(lines) - 10      # cut in the middle
        wait_until_still(board.port)
        cut = settled_trace(board)

        code = cli.main(["plot", SAMPLE, "--resume", "--yes", "--port", board.port,
                         "--profile", profile])
        out, err = capsys.readouterr()
        # the job is done: nothing left to resume
        assert grbl_journal().pending() is None, (code, err, out[-1500:])
        assert cli.main(["plot", SAMPLE, "--resume", "--yes", "--port", board.port,
                         "--profile", profile]) == 1
        assert "no interrupted GRBL job of" in capsys.readouterr().err
        board.stop()
    assert code == 0, err
    assert "ALARM" not in out + err and "error" not in out + err
    start = int(re.search(r"resuming at G-code line (\d+) of", out)[1]) - 1
    assert start == confirmed + 1 and "after the last line GRBL acknowledged" in out
    assert "homing ($H)" in out and "process has finished" in out
    assert grbl_journal().load().state == FINISHED
    # one pen asked for before going on (the one in use at the resumed line)
    assert out.count("(the pen the job goes on with)") <= 1

    # the pins, split at the sessions' ends (GRBL stood still at each): the first
    # session a prefix of the job, the second homing, lead-in and the rest, together
    # the whole job
    drawn = check_resumed(board, setup_end, cut, lines, start, pen)
    ran = motion_lines(lines)[drawn - 1]        # the last line the first session drew
    # drawn twice only the lines in flight at the cut (GRBL ran its queue to the end)
    assert start <= ran + 1
    twice = range(start, ran + 1)
    assert all(confirmed < k <= last_sent for k in twice), (confirmed, last_sent, start, ran)


class FreezingPort(RecordingPort):
    """The port dies (die_after) at the very moment simulated time stops: GRBL is
    frozen in the middle of its queue, still moving, until `ThawingPort` lets it go."""

    def __init__(self, port, board, **faults):
        super().__init__(port, **faults)
        self.board = board

    def write(self, data: bytes) -> int:
        if data.endswith(b"\n") and self.lines_written + 1 == self.die_after:
            self.board.freeze()
        return super().write(data)


class ThawingPort(RecordingPort):
    """The resume's port: its soft reset (0x18) reaches the frozen GRBL, which goes on
    from where it stood, so the reset comes while it still moves. `cut` is the pin
    trace when the resume sends $H (GRBL at rest after the reset: the first session
    is complete on the pins)."""

    def __init__(self, port, board):
        super().__init__(port)
        self.board = board
        self.cut = None

    def write(self, data: bytes) -> int:
        if data == b"$H\n" and self.cut is None:
            self.cut = settled_trace(self.board)
        written = super().write(data)
        if data == b"\x18":
            self.board.thaw()
        return written


def resume_options(profile: str, board) -> plot_cli.PlotOptions:
    """`plot SAMPLE --resume --yes` on the board."""
    options = sample_options(profile, board)
    options.resume = True
    return options


def test_resume_while_grbl_still_moves_goes_back_over_its_queue(profile, capsys):
    """The user runs plot --resume at once, GRBL still running the lines it had: the
    resume's soft reset drops GRBL's queue (ALARM:3), so lines GRBL acknowledged never
    ran; the resume goes back over its planner and stepper blocks, homes, and the
    two sessions together draw the whole job."""
    lines = planned_gcode(profile)
    pen = pen_from_config(load_profile(profile).config)
    with homed_at_work_zero() as (board, setup_end):
        # the port dies while the plot sends the 61st line, in the middle of the job's
        # longest drawing (no dwell there): GRBL is frozen with its planner full
        port = FreezingPort(serial.Serial(board.port, 115200, timeout=0.2), board,
                            die_after=70)
        assert run_grbl_plot(sample_options(profile, board),
                                       port=port) == plot_cli.EXIT_PORT_LOST
        confirmed = grbl_journal().load().confirmed
        last_sent = sent_job_lines(port.sent, lines)
        resume_port = ThawingPort(serial.Serial(board.port, 115200, timeout=0.2), board)
        code = run_grbl_plot(resume_options(profile, board), port=resume_port)
        out, err = capsys.readouterr()
        board.stop()
    assert code == plot_cli.EXIT_OK, err
    # Run: GRBL lost its ALARM:3 (a race in GRBL 1.1h, docs/grbl.md), the `?` before
    # the reset said it moved
    found = re.search(r"resuming at G-code line (\d+) of \d+: GRBL was reset while it "
                      r"still moved \((?:ALARM:3|it reported Run)\), so the (\d+) lines "
                      r"before line (\d+) that GRBL had queued may not have run", out)
    assert found, out
    start = int(found[1]) - 1
    assert int(found[3]) == confirmed + 2 and int(found[2]) == confirmed + 1 - start
    # back over the planner's 15 and the stepper's 5 blocks (a line is at least one),
    # never past a dwell: GRBL answers one only once all before it has run
    moves = [k for k in motion_lines(lines) if start <= k <= confirmed]
    dwell = [k for k in range(start, confirmed + 1) if lines[k].text.startswith("G4")]
    assert start <= confirmed and not dwell and (len(moves) == 20 or
                                                 lines[start - 1].text.startswith("G4"))
    assert "homing ($H)" in out and "process has finished" in out
    assert grbl_journal().load().state == FINISHED
    # the first session stopped where the reset cut GRBL's queue (inside a line, and
    # before the end of what it had been sent); the resume drew the rest
    drawn = check_resumed(board, setup_end, resume_port.cut, lines, start, pen)
    # the reset dropped lines GRBL had acknowledged: going on after the last `ok`
    # would have skipped them
    assert start <= motion_lines(lines)[drawn] <= confirmed < last_sent


class HoldingPort(RecordingPort):
    """The user presses the shield's feed-hold button just as the cable goes: `!`
    reaches GRBL, then the port dies (die_after)."""

    def write(self, data: bytes) -> int:
        if data.endswith(b"\n") and self.lines_written + 1 == self.die_after:
            self.port.write(b"!")
        return super().write(data)


def test_resume_of_a_machine_held_when_the_port_went_goes_back_over_its_queue(profile,
                                                                                capsys):
    """GRBL held (feed hold) when the port was lost stands still with its queue: the
    resume's reset drops it without ALARM:3. The resume asks the state first (`?`,
    before the reset), sees Hold, and goes back over the queue as after ALARM:3; the
    two sessions together draw the whole job."""
    lines = planned_gcode(profile)
    pen = pen_from_config(load_profile(profile).config)
    with homed_at_work_zero() as (board, setup_end):
        port = HoldingPort(serial.Serial(board.port, 115200, timeout=0.2), die_after=70)
        assert run_grbl_plot(sample_options(profile, board),
                                       port=port) == plot_cli.EXIT_PORT_LOST
        confirmed = grbl_journal().load().confirmed
        cut = settled_trace(board)              # held: the head stands, lines queued
        code = cli.main(["plot", SAMPLE, "--resume", "--yes", "--port", board.port,
                         "--profile", profile])
        out, err = capsys.readouterr()
        board.stop()
    assert code == 0, err
    found = re.search(r"resuming at G-code line (\d+) of \d+: GRBL stood in Hold with "
                      r"lines still queued", out)
    assert found, out
    start = int(found[1]) - 1
    assert start <= confirmed and "ALARM" not in out + err
    drawn = check_resumed(board, setup_end, cut, lines, start, pen)
    # the hold stopped GRBL short of lines it had acknowledged: going on after the
    # last `ok` would have skipped them
    assert start <= motion_lines(lines)[drawn] <= confirmed


def test_resume_without_switches_has_the_user_re_zero(profile, capsys):
    """GRBL without homing ($22=0): the resume cannot find the position by itself.
    Here the head keeps its place in simavr, so GRBL's work zero is spoiled first (as a
    reset of a real board loses it); the user puts the pen on the job's work zero, and
    the resume makes that G54's zero again, then goes on from there."""
    lines = planned_gcode(profile)
    pen = pen_from_config(load_profile(profile).config)
    with grbl_machine(RESUME_NO_SWITCHES) as (board, link):
        link.port.close()
        setup_end = settled_trace(board)        # the job's work zero: where GRBL woke
        port = RecordingPort(serial.Serial(board.port, 115200, timeout=0.2), die_after=45)
        assert run_grbl_plot(sample_options(profile, board),
                                       port=port) == plot_cli.EXIT_PORT_LOST
        confirmed = grbl_journal().load().confirmed
        wait_until_still(board.port)
        cut = settled_trace(board)
        with serial.Serial(board.port, 115200, timeout=0.2) as user_port:
            user = GrblLink.connect(user_port)
            user.command_checked("G90 G0 X0 Y0")            # the pen on the work zero
            user.command_checked(f"G1 Z{SCALE.mm(2, pen.down_z_steps)} F600")
            user.command_checked("G10 L2 P1 X3 Y-2 Z1")     # GRBL's idea of it lost
            user.wait_idle()
        code = run_grbl_plot(resume_options(profile, board))
        out, err = capsys.readouterr()
        board.stop()
    assert code == plot_cli.EXIT_OK, err
    assert f"resuming at G-code line {confirmed + 2} of {len(lines)}, after the last line " \
           f"GRBL acknowledged" in out
    assert ("GRBL has no homing ($22=0): the reset lost its position. The pen must stand "
            "at the job's work zero (X0 Y0, the pen down on the paper: Z0): move it there "
            "(--yes takes the machine as standing there)") in out
    assert "homing ($H)" not in out and "process has finished" in out
    check_resumed(board, setup_end, cut, lines, confirmed + 1, pen,
                  resumed_from=(0, 0, pen.down_z_steps))


# ---- the G-code side, without a board -------------------------------------------------------

def test_why_a_queue_was_cut_names_a_reset_while_moving_even_without_its_alarm():
    """GRBL 1.1h can lose the ALARM:3 of a reset while moving (docs/grbl.md): the `?`
    asked before the reset still says the queue was cut while it moved."""
    entry = JournalEntry(source="job.gbr", digest="", offset_nm=(0, 0), profile="",
                         group=False, total=10, confirmed=4, first_index=0, first_seq=0,
                         state=INTERRUPTED)
    link = SimpleNamespace(alarms=[3], state_before_reset=None)
    assert cut_short(link, entry) == "GRBL was reset while it still moved (ALARM:3)"
    for state in ("Run", "Jog"):
        link = SimpleNamespace(alarms=[], state_before_reset=state)
        assert cut_short(link, entry) == \
            f"GRBL was reset while it still moved (it reported {state})"
    link = SimpleNamespace(alarms=[], state_before_reset="Hold")
    assert cut_short(link, entry) == "GRBL stood in Hold with lines still queued"
    assert cut_short(SimpleNamespace(alarms=[], state_before_reset="Idle"), entry) is None


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
    with homed_at_work_zero() as (board, setup_end):

        port = CtrlCPort(serial.Serial(board.port, 115200, timeout=0.2), after=60)
        assert run_grbl_plot(sample_options(profile, board),
                                       port=port) == plot_cli.EXIT_INTERRUPTED
        out, _ = capsys.readouterr()
        assert "GRBL held the feed and was reset" in out
        entry = grbl_journal().load()
        assert entry.state == ABORTED and 0 < entry.confirmed < len(lines) - 10
        # the feed hold (!) came first, then the soft reset (0x18): the position is kept
        held = port.raw.index(b"!")
        assert b"\x18" in port.raw[held:]
        cut = settled_trace(board)

        code = cli.main(["plot", SAMPLE, "--resume", "--yes", "--port", board.port,
                         "--profile", profile])
        out, err = capsys.readouterr()
        board.stop()
    assert code == 0, err
    assert "ALARM" not in out + err and "process has finished" in out
    assert grbl_journal().load().state == FINISHED
    # stopped, GRBL's queue was dropped: back over what it may not have run
    start = int(re.search(r"resuming at G-code line (\d+) of \d+: the job was aborted "
                          r"\(stopped with Ctrl-C\)", out)[1]) - 1
    assert start <= entry.confirmed
    # the first session stopped where the hold ramped down, the resume drew the rest
    check_resumed(board, setup_end, cut, lines, start, pen_from_config(
        load_profile(profile).config))
    pos, tick = positions_and_ticks(board.trace())
    at_zero = pos[int(np.searchsorted(tick, setup_end[0][-1] // 8, side="right")) - 1]
    end = next(reversed(list(motions(lines))))[2]
    assert tuple(pos[-1] - at_zero) == end          # the job's last point, exactly
