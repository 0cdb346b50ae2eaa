"""The console on stock GRBL 1.1h in simavr, driven as a user drives it: one
session on one board, command after command (tests/console/test_console.py has
the screen and keyboard helpers; tests/grbl/grbl_support.py builds and boots GRBL).

The board is paced to the wall clock (a jog must still be running when its 0x85
comes) and has the harness's limit switches at +2, +3, +1 mm (X, Y, Z) from where
it powers up, homing on ($22=1), soft limits off ($20=0) so a jog may take the head
beyond the switches' reach, as a user can. What the console printed is checked
against what GRBL reports (`status`, `?`) and, at the end, against GRBL's step pins.
"""

from __future__ import annotations

import re
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
import serial
from prompt_toolkit.application import create_app_session
from prompt_toolkit.data_structures import Size
from prompt_toolkit.input import create_pipe_input
from prompt_toolkit.output.vt100 import Vt100_Output

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.console.app import Console
from galileo_cnc.grbl.job import grbl_journal
from galileo_cnc.grbl.gcode import expected_end_steps, job_to_gcode, pen_from_config
from galileo_cnc.grbl.session import pen_pieces
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.stream.journal import ABORTED, FINISHED, INTERRUPTED
from galileo_cnc.transport import discovery

from test_console import WAIT_S, ConsoleUser, Screen, console_in_thread, home  # noqa: F401

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "grbl"))
from grbl_support import (CONFIG, LIMITS, QUICK_HOMED, QUICK_HOMING, SCALE,  # noqa: E402
                          SETTINGS, check_resumed, grbl_machine, motion_lines, positions,
                          set_work_zero, settled_trace, wait_until_still)

ROOT = Path(__file__).resolve().parents[2]
BOARD = ROOT / "samples" / "led-blinker.gbr"
STEPS_PER_MM = 160
#: switches close at these GRBL steps from power-up (2, 3 and 1 mm)
SWITCHES = (("X", 320), ("Y", 480), ("Z", 160))
#: the evening keeps SETTINGS' acceleration: at 8000 mm/s^2 a 2.5 mm keypad jog can end
#: between two status reports, and the jog line never shows "Jog"
HOMING = {**SETTINGS, 22: "1", 20: "0", 130: "50", 131: "50", 132: "10",
          25: "1000", **QUICK_HOMING}
#: what comes once GRBL has drawn a pen's lines or the rest of a job: machine time,
#: which a loaded host stretches several times over (WAIT_S is for the console's replies)
JOB_WAIT_S = 120.0
_STATUS = re.compile(r"state (\w+(?::\d)?), X (\S+)  Y (\S+)  Z (\S+) mm work "
                     r"\(steps X (-?\d+) Y (-?\d+) Z (-?\d+)\), machine X (\S+)  Y (\S+)  "
                     r"Z (\S+) mm")


@contextmanager
def console_object(home_dir: Path, port: str, config: MachineConfig):  # noqa: F811
    """console_in_thread, keeping the Console: its bottom toolbar is asked directly
    (the pipe terminal answers no cursor-position query, so prompt_toolkit draws none)."""
    screen = Screen()
    output = Vt100_Output(screen, lambda: Size(rows=30, columns=120), term="xterm",
                          enable_cpr=False)
    with create_pipe_input() as keys:
        made, exit_code = [], []

        def run() -> None:
            with create_app_session(input=keys, output=output):
                made.append(Console(port, 115200, config, home_dir / "history"))
                exit_code.append(made[0].run())

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        user = ConsoleUser(screen, keys.send_text)
        user.expect(r"connected to ")
        user.expect(r">>")
        yield user, made[0]
        user.line("exit")
        thread.join(WAIT_S)
        assert not thread.is_alive(), f"the console did not leave:\n{screen.text[-2000:]}"
        assert exit_code == [0]


def toolbar_shows(console, pattern: str) -> str:
    """The toolbar (refreshed from GRBL's `?` every 0.5 s at the prompt) matches."""
    deadline = time.monotonic() + WAIT_S
    while not re.search(pattern, text := console.toolbar()):
        assert time.monotonic() < deadline, f"toolbar {text!r} never matched {pattern!r}"
        time.sleep(0.1)
    return text


def status(user) -> tuple[str, tuple[int, ...], tuple[int, ...]]:
    """(state, work steps, machine steps) from the console's own `status`."""
    user.line("status")
    found = user.expect(_STATUS.pattern)
    machine = tuple(round(float(found.group(i)) * STEPS_PER_MM) for i in (8, 9, 10))
    return found.group(1), tuple(int(found.group(i)) for i in (5, 6, 7)), machine


def jog_screen(user, units: int) -> None:
    """setup, 1), the distance: the keypad screen is up."""
    user.line("1")
    user.expect(r"jog distance in units of 10 um")
    user.line(str(units))
    user.expect(r"q: back")


def jog_to_rest(user, key: str) -> None:
    """One key; waits until the jog line has shown the head jogging, then at rest
    (prompt_toolkit redraws only the characters that changed, so the state words
    are what can be waited on; the position is read when the screen closes)."""
    user.type(key)
    user.expect(r"Jog")
    user.expect(r"Idle")


def set_feed(user, mm_s: str) -> None:
    user.line("2")
    user.expect(r"feed rate in mm/s")
    user.line(mm_s)
    user.expect(rf"feed rate {mm_s} mm/s \(\d+ steps/s, \d+ rpm\), sent to GRBL as "
                rf"F{float(mm_s) * 60:g}")
    user.expect(r"choice:")


def planned_lines(config: MachineConfig):
    planned = plan_file(BOARD, config, options=PlanOptions(mode="centre"))
    return planned.job, job_to_gcode(planned.job, SCALE, pen_from_config(config),
                                     feed_steps_per_s=config.feed_steps_per_s,
                                     flash_dwell_ms=config.flash_dwell_ms)


def test_an_evening_on_grbl(home):  # noqa: F811  (the fixture)
    job, lines = planned_lines(CONFIG)
    end_work = expected_end_steps(lines, SCALE)[-1]
    # homing off ($22=0) as GRBL ships: the user turns it on from the console
    with grbl_machine({**HOMING, 22: "0"}, limits=SWITCHES,
                      realtime=True) as (board, setup_link):
        setup_link.port.close()             # the console opens the board itself
        with console_object(home, board.port, CONFIG) as (user, console):
            # ---- connected: GRBL named, the toolbar from its status reports
            user.screen.wait_until(lambda text: "connected to GRBL" in text, 1)
            assert (f"connected to GRBL 1.1h on {board.port} (RX 128 B, 15 blocks, "
                    f"160 steps/mm)") in user.screen.text
            assert toolbar_shows(console, "GRBL Idle") == (
                f" {board.port} | GRBL Idle | X 0.000  Y 0.000  Z 0.000 mm | feed 100 mm/s")
            assert status(user) == ("Idle", (0, 0, 0), (0, 0, 0))

            # ---- the lines the console says to send, sent from its prompt: homing
            # turned on, GRBL's settings read, a G-code move; each reply on the screen
            user.line("home")
            user.expect(r"homing is off on this GRBL \(\$22=0\): turn it on with \$22=1")
            user.line("$22=1")
            user.expect(r"\$22=1\nok\n")
            user.line("$$")
            settings = user.expect(r"\$\$\n((?:\$\d+=\S+\n)+)ok\n").group(1).split()
            assert "$22=1" in settings and "$100=160.000" in settings, settings
            user.line("G0 X10")
            user.expect(r"G0 X10\nok\nGRBL stands at X 10\.000  Y 0\.000  Z 0\.000 mm "
                        r"\(work\)")
            assert status(user) == ("Idle", (1600, 0, 0), (1600, 0, 0))
            user.line("G0 X0")
            user.expect(r"GRBL stands at X 0\.000  Y 0\.000  Z 0\.000 mm \(work\)")

            user.line("resume")                 # the GRBL journal is empty
            user.expect(r"no interrupted GRBL job to resume \(journal .*journal-grbl\.json\)")

            # ---- setup: keypad jogs land exactly; 2.5 mm = 400 steps (all below
            # the switches, which close at +2/+3/+1 mm), at 10 mm/s: a quarter second
            # each, so the jog line's status, asked as the jog is sent, shows it
            # jogging (at 100 mm/s it lasts 70 ms, and a late answer saw it at rest)
            user.line("setup")
            user.expect(r"choice:")
            set_feed(user, "10")
            jog_screen(user, 250)
            jog_to_rest(user, "2")
            jog_to_rest(user, "4")
            jog_to_rest(user, "\x1b[C")  # Right: X+
            jog_to_rest(user, "1")       # Z down
            jog_to_rest(user, "7")
            jog_to_rest(user, "4")
            user.type("q")
            user.expect(r"position X -2\.500  Y -2\.500  Z 0\.000 mm \(work\)")
            user.expect(r"choice:")

            # ---- a slow feed, a long jog cancelled with q, a held key let go
            set_feed(user, "5")
            jog_screen(user, 1000)                                # 10 mm at 5 mm/s: 2 s
            user.type("4")
            user.expect(r"Jog")
            time.sleep(0.5)                     # the user lets it run half a second
            user.type("q")
            cancelled = user.expect(r"position X (\S+)  Y -2\.500  Z 0\.000 mm \(work\)")
            x_cancelled = float(cancelled.group(1))
            assert -12.0 < x_cancelled < -3.0                    # stopped short of -12.5
            jog_screen(user, 1000)
            user.type("4444")                   # a held key: the terminal repeats it
            user.expect(r"key released: jog cancelled \(0x85\)")
            user.type("q")
            released = user.expect(r"position X (\S+)  Y -2\.500  Z 0\.000 mm \(work\)")
            moved = x_cancelled - float(released.group(1))
            assert 0 < moved < 5.0, moved       # not 10 mm (one jog), let alone 40
            set_feed(user, "100")
            user.line("q")
            state, work, machine = status(user)
            assert state == "Idle" and work == machine
            assert work[1:] == (-400, 0) and work[0] == round(float(released.group(1)) * 160)

            # ---- Z far below its switch: homing (Z first) fails, ALARM:9, unlock
            user.line("setup")
            user.expect(r"choice:")
            jog_screen(user, 2000)                                # 20 mm
            jog_to_rest(user, "1")
            user.type("q")
            user.expect(r"position X")
            user.line("q")
            user.line("home")
            user.expect(r"homing \(\$H\)")
            user.expect(r"ALARM:9: Homing fail")
            user.expect(r"GRBL is locked \(Alarm\): type home \(\$H\) to home it, or unlock "
                        r"\(\$X\)")
            toolbar_shows(console, r"\| GRBL Alarm \| X \S+  Y -2\.500  Z 15\.000 mm")
            user.line("unlock")
            user.expect(r"unlocked \(\$X\) \(it was ALARM:9: Homing fail.*\): state Idle")
            state, work, machine = status(user)
            assert state == "Idle" and work[:2] == machine[:2] == (round(float(
                released.group(1)) * 160), -400)
            # GRBL counted Z's search from 0: 15 mm (1.5 x $132) up; its Z is lost
            # (the unlock line says so): the head is 20 - 15 = 5 mm below its start
            assert work[2] == machine[2] == 15 * 160

            # ---- back within reach of the Z switch: $H finds all three
            user.line("setup")
            user.expect(r"choice:")
            jog_screen(user, 500)                               # 5 mm up: Z 0
            jog_to_rest(user, "7")
            user.type("q")
            user.expect(r"position X")
            user.line("q")
            user.line("home")
            user.expect(r"homed: X -1\.000  Y -1\.000  Z -1\.000 mm work, machine "
                        r"X -1\.000  Y -1\.000  Z -1\.000 mm")
            user.expect(r"the work origin is now the home position \(GRBL's G54 offset is "
                        r"zero\)")
            toolbar_shows(console, r"GRBL Idle \| X -1\.000  Y -1\.000  Z -1\.000 mm")

            # ---- homed, the travel is -50..0: a job at the work zero = machine
            # zero leaves it, and is refused before a byte is sent
            user.line(f"getg --mode centre {BOARD}")
            user.expect(r"use these offsets\? \[Y/n\]")
            user.line("")
            user.expect(rf"{len(lines)} G-code lines, {len(job.pen_changes)} pen changes, "
                        r"about \d+:\d\d on GRBL")
            user.expect(r"job refused before sending: .*led-blinker\.gbr:\d+: G-code line "
                        r"\d+ takes [XYZ] to .* outside GRBL's travel")
            assert status(user)[2] == (-160, -160, -160)          # nothing moved

            # ---- the origin where the paper is: 44 mm in X and Y, 4 mm down
            user.line("setup")
            user.expect(r"choice:")
            jog_screen(user, 4400)
            jog_to_rest(user, "4")
            jog_to_rest(user, "2")
            user.type("q")
            user.expect(r"choice:")
            jog_screen(user, 400)
            jog_to_rest(user, "1")
            user.type("o")
            user.expect(r"origin set here: X, Y and Z are 0 now")
            user.type("q")
            user.expect(r"position X 0\.000  Y 0\.000  Z 0\.000 mm \(work\), machine "
                        r"X -45\.000  Y -45\.000  Z -5\.000 mm")
            user.line("q")

            # ---- a job stopped with q: feed hold, reset, the position kept
            user.line(f"getg --mode centre {BOARD}")
            user.expect(r"use these offsets\? \[Y/n\]")
            user.line("y")
            user.expect(r"\ainsert pen for aperture D\d+ \(")
            user.type("\r")
            user.expect(r"lines\s+\d")
            user.type("q")
            user.expect(rf"job stopped after \d+ of {len(lines)} G-code lines: stopped by "
                        r"the user; GRBL held the feed and was reset.*type resume to "
                        r"continue it")
            assert grbl_journal().load().state == ABORTED       # journalled as plot does
            state, work, machine = status(user)
            assert state == "Idle"
            assert tuple(m - w for m, w in zip(machine, work)) == (-7200, -7200, -800)

            # ---- the whole job: every pen asked for, "finished", where the G-code ends
            user.line(f"getg --mode centre {BOARD}")
            user.expect(r"use these offsets\? \[Y/n\]")
            user.line("")
            for aperture in job.pen_changes.values():
                user.expect(rf"\ainsert pen for aperture D{aperture} \(", JOB_WAIT_S)
                user.type("\r")
            finished = user.expect(r"\aprocess has finished in \d+:\d\d \(\d+ G-code lines\); "
                                   r"GRBL stands at X (\S+) Y (\S+) Z (\S+) mm \(work\)",
                                   JOB_WAIT_S)
            stands = tuple(round(float(v) * STEPS_PER_MM) for v in finished.groups())
            assert stands == end_work
            state, work, machine = status(user)           # and the console goes on
            assert (state, work) == ("Idle", end_work)
            x, y, z = (f"{v / STEPS_PER_MM:.3f}" for v in end_work)
            toolbar_shows(console, rf"GRBL Idle \| X {x}  Y {y}  Z {z} mm \| feed 100 mm/s")
            assert grbl_journal().load().state == FINISHED
        board.stop()
    text = user.screen.text
    assert text.count("ALARM:9") == 2                  # the alarm, then the unlock's cause
    assert "Traceback" not in text and "error:" not in text
    assert "Unknown command" not in text
    # GRBL's pins: its machine position, counted from power-up, is the switches'
    # trip points away from the one homing set (homed at trip - 1 mm = -1 mm),
    # exactly on every axis (Y was one step off until the harness stopped counting
    # X's switch as a Y step at power-up: test_grbl_simavr.py's homing test)
    pins = tuple(int(v) for v in positions(board)[-1])
    off = [p - (m + trip) for p, m, (_, trip) in zip(pins, machine, SWITCHES)]
    assert off == [0, 0, 0], (pins, machine, off)
    assert board.summary["overruns"] == "0" and board.summary["dropped"] == "0"


def test_a_job_stopped_with_q_resumes_in_the_same_session(home):  # noqa: F811
    """The user's machine is homed and its work zero stored in G54 (60 mm in, as
    test_grbl_resume.py sets it up). In one console session: getg, q while the fifth
    pen draws (the pen lifted), `resume` (from where GRBL kept its position: goes back
    over what GRBL may not have run, pen up, asks for the pen in use), to "finished",
    then `status`. GRBL's pins: the two parts
    together draw the whole job."""
    job, lines = planned_lines(CONFIG)
    pen = pen_from_config(CONFIG)
    pieces = pen_pieces(lines, job.pen_changes)
    end_work = expected_end_steps(lines, SCALE)[-1]
    with grbl_machine(QUICK_HOMED, limits=LIMITS, realtime=True) as (board, setup_link):
        set_work_zero(setup_link)               # homed, G54 set, the set-up's port closed
        setup_end = settled_trace(board)
        with console_object(home, board.port, CONFIG) as (user, console):
            getg_through_pens(user, pieces, 5)
            time.sleep(0.5)                     # the fifth pen draws for half a second
            user.type("q")
            user.expect(rf"job stopped after \d+ of {len(lines)} G-code lines: stopped by "
                        r"the user; GRBL held the feed and was reset.*type resume to "
                        r"continue it")
            stopped = grbl_journal().load()
            assert stopped.state == ABORTED and stopped.reason == "stopped by the user"
            assert pieces[4][0] <= stopped.confirmed + 1 < len(lines)
            state, stood, _ = status(user)
            assert state == "Idle" and stood[2] == pen.up_z_steps    # the pen lifted
            cut = settled_trace(board)

            user.line("resume")
            found = user.expect(rf"led-blinker\.gbr: resuming at G-code line (\d+) of "
                                rf"{len(lines)}: the job was aborted \(stopped by the user\)")
            start = int(found.group(1)) - 1
            # back over what GRBL had queued, never past a dwell (the flashes' G4)
            assert pieces[3][0] < start <= stopped.confirmed + 1
            user.expect(r"continue the job\? \[Y/n\]")
            user.line("")
            # GRBL kept its position: neither homed nor re-zeroed (issue 31, item 8)
            user.expect(r"GRBL kept its position since the job stopped: GRBL stands at "
                        r"X \S+ Y \S+ Z 1\.875 mm \(work\); the job goes on from there")
            answer_pens_of_the_rest(user, pieces, start)
            finished = user.expect(r"\aprocess has finished in \d+:\d\d \(\d+ G-code "
                                   r"lines\); GRBL stands at X (\S+) Y (\S+) Z (\S+) mm",
                                   JOB_WAIT_S)
            stands = tuple(round(float(v) * STEPS_PER_MM) for v in finished.groups())
            assert stands == end_work
            state, work, machine = status(user)           # and the console goes on
            assert (state, work) == ("Idle", end_work)
            assert grbl_journal().load().state == FINISHED
            user.line("resume")                           # nothing left
            user.expect(r"no interrupted GRBL job to resume")
        board.stop()
    text = user.screen.text
    assert "Traceback" not in text and "error:" not in text and "ALARM" not in text
    # the first part stopped where the hold ramped down and lifted the pen; the second
    # went back from there pen up and drew from line `start`: together every motion
    check_resumed(board, setup_end, cut, lines, start, pen, resumed_from=stood)
    # homed once, GRBL's machine position is its pins' less the switches' trip points
    pins = tuple(int(v) for v in positions(board)[-1])
    assert tuple(p - m for p, m in zip(pins, machine)) == tuple(t for _, t in LIMITS)
    assert board.summary["overruns"] == "0" and board.summary["dropped"] == "0"


def test_a_stop_that_found_grbl_still_moving_trusts_no_position(home, monkeypatch):  # noqa: F811
    """q, but the feed hold is never seen to settle (held() gave up): GRBL was reset
    while it may still have moved, and GRBL 1.1h can lose that reset's ALARM:3
    (docs/grbl.md). So `resume` does not go on from where GRBL stands: it homes."""
    from galileo_cnc.grbl import job as grbl_job

    real = grbl_job.hold_and_reset
    monkeypatch.setattr(grbl_job, "hold_and_reset", lambda link: real(link) and None)
    _job, lines = planned_lines(CONFIG)
    pieces = pen_pieces(lines, _job.pen_changes)
    with grbl_machine(QUICK_HOMED, limits=LIMITS, realtime=True) as (board, setup_link):
        set_work_zero(setup_link)
        with console_object(home, board.port, CONFIG) as (user, console):
            getg_through_pens(user, pieces, 2)
            time.sleep(0.5)                     # the second pen draws
            user.type("q")
            user.expect(r"job stopped after \d+ of \d+ G-code lines: stopped by the user; "
                        r"GRBL was reset without being seen to stand still")
            user.line("resume")
            user.expect(r"continue the job\? \[Y/n\]")
            user.line("")
            user.expect(r"homing \(\$H\): the reset lost GRBL's position")
            user.expect(r"\ainsert pen for aperture D\d+ .*\(q stops\)", JOB_WAIT_S)
            user.type("q")                      # enough: stopped again at the pen
            user.expect(r"job stopped after", JOB_WAIT_S)
        board.stop()
    assert "GRBL kept its position" not in user.screen.text


def getg_through_pens(user, pieces, count: int) -> None:
    """getg the board with the proposed offsets, and insert its first `count` pens."""
    user.line(f"getg --mode centre {BOARD}")
    user.expect(r"use these offsets\? \[Y/n\]")
    user.line("")
    for _, aperture in pieces[:count]:
        user.expect(rf"\ainsert pen for aperture D{aperture} \(", JOB_WAIT_S)
        user.type("\r")


def answer_pens_of_the_rest(user, pieces, start: int) -> None:
    """Enter at each pen the resume asks for: the one in use at line `start` (unless a
    change comes right there), then each change after it."""
    asked = [(a, True) for first, a in pieces if first < start][-1:]
    if any(first == start for first, _ in pieces):
        asked = []
    asked += [(a, False) for first, a in pieces if first >= start]
    for aperture, resuming in asked:
        goes_on = r".*\(the pen the job goes on with\)" if resuming else ""
        user.expect(rf"\ainsert pen for aperture D{aperture} \({goes_on}", JOB_WAIT_S)
        user.type("\r")


class DyingPort:
    """The console's port to GRBL, pulled out (SerialException from then on) just as
    the job's line `at` is about to be written."""

    def __init__(self, port, lines, at: int):
        self.port, self.lines, self.at = port, lines, at
        self.sent = 0                   # job lines written, in order
        self.dead = False

    def write(self, data: bytes) -> int:
        if self.dead:
            raise serial.SerialException("device disconnected")
        if self.sent < len(self.lines) and data == self.lines[self.sent].text.encode() + b"\n":
            if self.sent == self.at:
                self.dead = True
                raise serial.SerialException("device disconnected")
            self.sent += 1
        return self.port.write(data)

    def readline(self, *args) -> bytes:
        if self.dead:
            raise serial.SerialException("device disconnected")
        return self.port.readline(*args)

    def close(self) -> None:
        self.port.close()

    def __getattr__(self, name):
        return getattr(self.port, name)


def test_a_job_whose_port_is_lost_resumes_after_connect(home, monkeypatch):  # noqa: F811
    """The cable is pulled while getg streams (line 56 of 79, in the middle of the
    job's longest drawing): the journal says `interrupted`, GRBL runs on with what
    it had; once it stands still the user types `connect`, then `resume`: after the
    last line GRBL acknowledged, homed, to "finished". GRBL's pins: the two parts
    together draw the whole job, and nothing GRBL acknowledged is drawn twice."""
    job, lines = planned_lines(CONFIG)
    pen = pen_from_config(CONFIG)
    pieces = pen_pieces(lines, job.pen_changes)
    end_work = expected_end_steps(lines, SCALE)[-1]
    opened = []

    def open_dying(*args, **kwargs):    # the first port the console opens is pulled
        opened.append(real_open(*args, **kwargs))
        if len(opened) == 1:
            opened[0] = DyingPort(opened[0], lines, at=45)
        return opened[-1]

    real_open = discovery.open_port
    monkeypatch.setattr(discovery, "open_port", open_dying)
    with grbl_machine(QUICK_HOMED, limits=LIMITS) as (board, setup_link):
        set_work_zero(setup_link)
        setup_end = settled_trace(board)
        with console_object(home, board.port, CONFIG) as (user, console):
            getg_through_pens(user, pieces, 5)
            lost = user.expect(rf"GRBL had acknowledged (\d+) of {len(lines)} G-code lines "
                               r"and runs on with the lines it had; once the machine stands "
                               r"still, connect again and type resume")
            user.expect(r"the port is gone: type connect to reconnect, then resume")
            entry = grbl_journal().load()
            assert entry.state == INTERRUPTED and entry.confirmed + 1 == int(lost.group(1))
            assert pieces[4][0] - 1 <= entry.confirmed < 55     # in the fifth pen's lines
            wait_until_still(board.port)                        # as the user is told
            cut = settled_trace(board)
            user.line(f"connect {board.port}")
            user.expect(rf"connected to GRBL 1\.1h on {board.port}")
            user.line("resume")
            user.expect(rf"resuming at G-code line {entry.confirmed + 2} of {len(lines)}, "
                        r"after the last line GRBL acknowledged")
            user.expect(r"continue the job\? \[Y/n\]")
            user.line("")
            user.expect(r"homed; work offset")
            answer_pens_of_the_rest(user, pieces, entry.confirmed + 1)
            finished = user.expect(r"\aprocess has finished in \d+:\d\d \(\d+ G-code "
                                   r"lines\); GRBL stands at X (\S+) Y (\S+) Z (\S+) mm",
                                   JOB_WAIT_S)
            assert tuple(round(float(v) * STEPS_PER_MM) for v in finished.groups()) == end_work
            assert status(user)[:2] == ("Idle", end_work)
            assert grbl_journal().load().state == FINISHED
        board.stop()
    assert "Traceback" not in user.screen.text
    drawn = check_resumed(board, setup_end, cut, lines, entry.confirmed + 1, pen)
    # GRBL ran its queue to the end: the first part ends on a line's end point, at or
    # after the last acknowledged line (drawn again from there only what was in flight)
    assert motion_lines(lines)[drawn - 1] >= entry.confirmed


@pytest.mark.parametrize("port", ["sim://?speed=0"])
def test_galileo_connection_line_is_unchanged(home, port):  # noqa: F811
    with console_in_thread(home, port) as user:
        assert "connected to sim://?speed=0 (built-in simulated machine)" in user.screen.text
        assert "GRBL" not in user.screen.text
