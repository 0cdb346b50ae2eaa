"""The console driven as a user drives it: keys in, screen text out.

Most tests run `run_console` in a thread with prompt_toolkit's pipe input and a
VT100 output that writes into `Screen`; one runs the console in its own process
on a pseudo-terminal. All of them talk to `sim://`, the built-in simulated
machine, and check what the machine did through the console's own `status`.
Waits are on the screen text with timeouts, never sleeps.
"""

from __future__ import annotations

import codecs
import fcntl
import os
import re
import struct
import subprocess
import sys
import termios
import threading
import time
import traceback
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import pytest
from prompt_toolkit.data_structures import Size
from prompt_toolkit.input import create_pipe_input
from prompt_toolkit.output.vt100 import Vt100_Output

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.console import run_console
from galileo_cnc.console.helptext import load_help
from galileo_cnc.console.keypad import REFRESH_S, KeypadJog
from galileo_cnc.console.units import jog_units_to_steps
from galileo_cnc.machine import Trace, simulate
from galileo_cnc.plan import pipeline
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.readers import read_file
from galileo_cnc.sim.simulator import forget_named_machines, named_machine
from galileo_cnc.simavr.board import SimulatedBoard, step_trace
from galileo_cnc.stream.journal import INTERRUPTED, Journal
from galileo_cnc.stream.resume import position_after
from galileo_cnc.stream.streamer import JobStreamer
from galileo_cnc.transport import link as link_module
from galileo_cnc.transport.link import MachineLink, PortGone
from galileo_cnc.transport.port import open_port

from faults import FaultyPort
from firmware_support import ELF, build_firmware, build_harness
from inked import inked_points

ROOT = Path(__file__).resolve().parents[2]
BOARD = ROOT / "samples" / "led-blinker.gbr"
WAIT_S = 20.0
#: The simulated machine with instant motion; REAL_TIME_SIM moves at the machine's speed.
INSTANT_SIM = "sim://?speed=0"
CENTRE = PlanOptions(mode="centre")
#: what a pen change says: an aperture's pen (centre mode) or a pen of the set (ink)
PEN_PROMPT = r"insert (?:pen for aperture|the \d[\d.]* mm pen)"
TWO_PENS = MachineConfig().replace(pen_widths_mm=(0.3, 0.8))
REAL_TIME_SIM = "sim://"
_ESCAPES = re.compile(r"\x1b\[[0-9;?<=>]*[ -/]*[@-~]"           # CSI: cursor, colour, modes
                      r"|\x1b\][^\x07\x1b]*(?:\x07|\x1b\\)"     # OSC: window title
                      r"|\x1b[()][0-9A-Za-z]|\x1b[=>78]")
_STATUS = re.compile(r"state (\w+), .*?\(steps X (-?\d+) Y (-?\d+) Z (-?\d+)\)")


def plain(raw: str) -> str:
    """Terminal output without escape sequences and carriage returns."""
    return _ESCAPES.sub("", raw).replace("\r", "")


def _thread_stacks() -> str:
    """Where every thread is, for a console that stopped answering."""
    names = {thread.ident: thread.name for thread in threading.enumerate()}
    return "\n".join(f"thread {names.get(ident, ident)}:\n"
                     + "".join(traceback.format_stack(frame)[-6:])
                     for ident, frame in sys._current_frames().items())


class Screen:
    """A text stream for prompt_toolkit's VT100 output that tests can wait on."""

    encoding = "utf-8"

    def __init__(self) -> None:
        self._raw: list[str] = []
        self._changed = threading.Condition()

    def write(self, data: str) -> int:
        with self._changed:
            self._raw.append(data)
            self._changed.notify_all()
        return len(data)

    def flush(self) -> None:
        pass

    @property
    def raw(self) -> str:
        with self._changed:
            return "".join(self._raw)

    @property
    def text(self) -> str:
        return plain(self.raw)

    def wait_until(self, found, timeout_s: float):
        """Wait until `found(text)` returns something true; return it."""
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while True:
                result = found(plain("".join(self._raw)))
                if result:
                    return result
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._changed.wait(min(left, 0.2))


class ConsoleUser:
    """Types into the console and reads what it printed since the last `expect`."""

    def __init__(self, screen, send) -> None:
        self.screen = screen
        self.send = send
        self.seen = 0          # screen text before this offset has been consumed

    def type(self, text: str) -> None:
        self.send(text)

    def line(self, text: str) -> None:
        self.send(text + "\r")

    def expect(self, pattern: str, timeout_s: float = WAIT_S) -> re.Match:
        regex = re.compile(pattern)
        match = self.screen.wait_until(lambda text: regex.search(text, self.seen), timeout_s)
        if match is None:
            tail = self.screen.text[self.seen:][-3000:]
            pytest.fail(f"{pattern!r} did not appear within {timeout_s} s; the screen "
                        f"since the last expectation:\n{tail}\n\n{_thread_stacks()}")
        self.seen = match.end()
        return match

    def status(self) -> tuple[str, int, int, int]:
        self.line("status")
        found = self.expect(_STATUS.pattern)
        return found.group(1), int(found.group(2)), int(found.group(3)), int(found.group(4))


@pytest.fixture
def home(tmp_path, monkeypatch) -> Path:
    """The user's directories (history, journal, edited help file) for this test only."""
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path / "home"))
    monkeypatch.setenv("GALILEO_CNC_NO_PROBE", "1")
    return tmp_path / "home"


@contextmanager
def console_in_thread(home: Path, port: str = INSTANT_SIM, config: MachineConfig | None = None):
    """The console on `port`, in a thread of this process, typed into through a pipe."""
    screen = Screen()
    output = Vt100_Output(screen, lambda: Size(rows=30, columns=120), term="xterm",
                          enable_cpr=False)
    with create_pipe_input() as keys:
        exit_code = []
        thread = threading.Thread(
            target=lambda: exit_code.append(run_console(
                port, 115200, config or MachineConfig(), history_path=home / "history",
                input=keys, output=output)),
            daemon=True)
        thread.start()
        user = ConsoleUser(screen, keys.send_text)
        user.expect(r"connected to ")
        user.expect(r">>")
        yield user
        user.line("exit")
        thread.join(WAIT_S)
        assert not thread.is_alive(), f"the console did not leave:\n{screen.text[-2000:]}"
        assert exit_code == [0]


@contextmanager
def console_on_a_pty(home: Path):
    """`python -m galileo_cnc` (no command: the console) in its own process on a
    pseudo-terminal of 30 x 120; answers the cursor-position queries a terminal answers."""
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 120, 0, 0))
    python_path = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    env = {**os.environ, "GALILEO_CNC_HOME": str(home), "GALILEO_CNC_NO_PROBE": "1",
           "TERM": "xterm", "PYTHONPATH": python_path}
    process = subprocess.Popen([sys.executable, "-m", "galileo_cnc", "--port", INSTANT_SIM],
                               stdin=slave, stdout=slave, stderr=slave, cwd=ROOT, env=env,
                               start_new_session=True)
    os.close(slave)
    screen = Screen()

    def read_terminal() -> None:
        decoder = codecs.getincrementaldecoder("utf-8")("replace")
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:              # the console closed the terminal
                return
            if not data:
                return
            if b"\x1b[6n" in data:        # where is the cursor? (bottom toolbar placement)
                os.write(master, b"\x1b[1;1R")
            screen.write(decoder.decode(data))

    reader = threading.Thread(target=read_terminal, daemon=True)
    reader.start()
    try:
        yield ConsoleUser(screen, lambda text: os.write(master, text.encode())), process
    finally:
        if process.poll() is None:
            process.kill()
        process.wait(WAIT_S)
        os.close(master)
        reader.join(WAIT_S)


# ---- help ------------------------------------------------------------------------------------
def test_help_prints_the_help_file_and_one_command(home):
    with console_in_thread(home) as user:
        user.line("help")
        user.expect(r"galileo-cnc console")
        user.expect(r"(?s)getg \[--mode ink\|centre\] .*?\[FILE\]")
        user.expect(r"setup\n")
        user.expect(r"exit\n")
        user.line("help setup")
        section = user.expect(r"(?s)setup\n(.*?)>>").group(1)
        assert "7 / 1   Z up / down" in section
        assert "getg [" not in section           # only the one command


def test_an_edited_help_file_in_the_config_dir_wins(home):
    home.mkdir(parents=True)
    (home / "helpfile.f").write_text("My own notes.\n\n[getg]\ngetg: use the red pen first\n")
    with console_in_thread(home) as user:
        user.line("help")
        user.expect(r"My own notes\.")
        user.line("help getg")
        user.expect(r"getg: use the red pen first")
        assert "Plot a Gerber" not in user.screen.text


def test_every_command_has_a_section_in_the_shipped_help_file():
    from galileo_cnc.console.commands import build_registry

    sections = load_help(None).sections
    assert sorted(sections) == sorted(build_registry().names)


def test_the_progress_title_fits_the_terminal_and_keeps_the_file_name():
    # issue 31, item 19: the bar's title (the whole path, then the key hint) was cut at
    # the terminal's width, the file name and the hint lost
    from galileo_cnc.console.job_screen import fit_title
    path = "/home/user/boards/a/long/folder/name/led-blinker-top-copper.gbr"
    assert fit_title(path, 120) == path + "   (q or Ctrl-C stops, the machine ramps down)"
    for columns in (80, 60, 45):
        title = fit_title(path, columns)
        assert len(title) < columns and title.endswith("/led-blinker-top-copper.gbr  (q stops)")
    assert len(fit_title(path, 30)) < 30 and fit_title(path, 30).startswith("...")


def test_the_help_fits_80_columns_and_homes_z_only_with_a_switch():
    from galileo_cnc.console.commands import build_registry

    help_text = load_help(None)
    too_wide = [line for line in help_text.full().splitlines() if len(line) > 80]
    assert too_wide == []
    for command in build_registry():        # what `help` says for a section it lacks
        assert len(command.usage) <= 80 and len(f"    {command.summary}") <= 80, command
    assert "Z first, then X" not in help_text.sections["home"]
    assert "Z first only\n    when the profile gives Z an end stop" in help_text.sections["home"]


def test_the_console_on_a_terminal_plots_and_keeps_its_history(home):
    job = plan_file(BOARD, MachineConfig(), options=CENTRE).job
    with console_on_a_pty(home) as (user, process):
        user.expect(r"galileo-cnc \d+\.\d+\.\d+")
        user.expect(r"type help")
        user.expect(r"connected to sim://\?speed=0 \(built-in simulated machine\), firmware")
        user.expect(r"sim://\?speed=0 \| idle \| X 0\.000  Y 0\.000  Z 0\.000 mm")  # toolbar
        user.line("help getg")
        user.expect(r"Plot a Gerber")
        user.line("ports")
        user.expect(r"\* sim://\?speed=0")
        user.line(f"getg --mode centre {BOARD}")
        user.expect(r"use these offsets\? \[Y/n\]")
        user.line("y")
        for _ in job.pen_changes:
            user.expect(r"\ainsert pen for aperture D\d+ \(")
            user.type("\r")
        user.expect(r"\aprocess has finished in \d+:\d\d")
        user.expect(r"sim://\?speed=0 \| idle \| X ")
        user.type("\x04")                          # Ctrl-D leaves
        assert process.wait(WAIT_S) == 0
    history = (home / "history").read_text()
    assert "help getg" in history and f"getg --mode centre {BOARD}" in history
    assert "Traceback" not in user.screen.text


def test_tab_completes_command_names_and_file_names(home, monkeypatch):
    monkeypatch.chdir(ROOT)
    with console_in_thread(home) as user:
        user.type("sta\t")                       # completion runs in the background:
        user.expect(r"tus")                         # wait until it has filled the word in
        user.type("\r")
        user.expect(r"state idle")
        user.type("help set\t")                  # "se" is setup or send
        user.expect(r"up")
        user.type("\r")
        user.expect(r"7 / 1   Z up / down")
        user.type("getg samples/led-b")
        user.expect(r"led-b")
        user.type("\t")
        user.expect(r"linker\.gbr")
        user.type("\r")
        user.expect(r"use these offsets\?")
        user.type("\x03")                         # Ctrl-C cancels the question
        user.expect(r"cancelled\ntype getg to start it again\n")
        user.line("status")
        user.expect(r"state idle, X 0\.000")


# ---- unknown commands ------------------------------------------------------------------------
def test_an_unknown_command_says_so_and_hints(home):
    with console_in_thread(home) as user:
        user.line("getgg board.gbr")
        user.expect(r"Unknown command! Did you mean getg\?")
        user.line("frobnicate")
        hint = user.expect(r"Unknown command!([^\n]*)").group(1)
        assert "Did you mean" not in hint
        user.line("status")                      # the console goes on
        user.expect(r"state idle")


# ---- a command line for the machine ----------------------------------------------------------
def test_gcode_lines_typed_at_the_prompt_run_as_jobs_of_one_line(home):
    """What UGS or CNCjs users type first, on our firmware: G-code lines are planned and
    streamed as jobs of one line (their modes kept from line to line), `$` lines get
    our firmware's answer, never "Unknown command!"."""
    with console_in_thread(home) as user:
        user.line("G0 X10")
        user.expect(r"ok: the head stands at X 10\.000  Y 0\.000  Z \S+ mm \(work\)")
        assert user.status()[1:3] == (1600, 0)              # 160 steps/mm
        user.line("g1 y5 f600")                              # lower case, a feed of 10 mm/s
        user.expect(r"ok: the head stands at X 10\.000  Y 5\.000")
        user.line("G91")                                     # relative from now on
        user.expect(r"ok \(nothing moves: what the line set holds for the next lines\)")
        user.line("send G0 X-2.5 Y1")
        user.expect(r"ok: the head stands at X 7\.500  Y 6\.000")
        user.line("G0 X-900")                                # leaves the travel: nothing sent
        user.expect(r"typed line:1:\d+: .*X would reach -892\.500 mm, below the travel")
        assert user.status()[1:3] == (1200, 960)
        user.line("$$")
        user.expect(r"steps/mm 160 \(GRBL's \$100-\$102\)")
        user.line("$22=1")
        user.expect(r"\$22=1: `\$` commands are GRBL's, and this machine runs the "
                    r"galileo-cnc firmware")
    assert "Unknown command" not in user.screen.text


# ---- getg ------------------------------------------------------------------------------------
def test_getg_plots_the_sample_board_with_pen_changes(home):
    program = read_file(BOARD)
    config = MachineConfig()
    job = plan_file(BOARD, config, options=CENTRE).job
    assert job.pen_changes, "the sample board must switch pens for this test to mean much"
    end = position_after(job, len(job), config)

    with console_in_thread(home) as user:
        user.line(f"getg --mode centre {BOARD}")
        user.expect(r"minimum\s+X 6\.0000 mm, Y 5\.0000 mm")
        user.expect(r"offsets\s+X 5\.0000 mm, Y 4\.0000 mm")
        user.expect(r"use these offsets\? \[Y/n\]")
        user.line("")
        user.expect(rf"{len(job)} machine commands, {len(job.pen_changes)} pen changes?")
        for aperture in job.pen_changes.values():
            description = re.escape(program.apertures[aperture].describe())
            user.expect(rf"\a?insert pen for aperture D{aperture} \({description}\)")
            user.type("\r")
        user.expect(r"\aprocess has finished in \d+:\d\d")
        state, x, y, z = user.status()
    assert state == "idle"
    assert (x, y, z) == end
    assert user.screen.raw.count("\a") >= len(job.pen_changes) + 1


def test_getg_asks_for_the_file_and_takes_typed_offsets(home, tmp_path):
    drawing = ROOT / "samples" / "square-and-circle.nc"
    program = read_file(drawing)
    config = MachineConfig()
    job = plan_program(program, config, (-10_000_000, -20_000_000))
    with console_in_thread(home) as user:
        user.line("getg")
        user.expect(r"file to plot:")
        user.line(str(drawing))
        user.expect(r"use these offsets\? \[Y/n\]")
        user.line("n")
        user.expect(r"offsets X,Y in mm")
        user.line("-10, -20")
        user.expect(r"process has finished")
        assert user.status()[1:] == position_after(job, len(job), config)


def test_getg_takes_a_path_under_the_home_folder(home, tmp_path, monkeypatch):
    # Tab completion offers ~/... paths: getg must open what it offered
    user_home = tmp_path / "user"
    (user_home / "boards").mkdir(parents=True)
    (user_home / "boards" / "square.nc").write_text(SQUARE.read_text())
    monkeypatch.setenv("HOME", str(user_home))
    with console_in_thread(home) as user:
        user.line("getg ~/boards/square.nc")
        user.expect(r"use these offsets\? \[Y/n\]")
        user.line("")
        user.expect(r"process has finished")


#: two 2 mm pads joined by a thin trace: the pads' fills reach 0.8 mm below and left of
#: the flash points the centre-line proposal is made from
PADS = """%FSLAX46Y46*%
%MOMM*%
%ADD10C,2.0*%
%ADD11C,0.2*%
D10*
X10000000Y10000000D03*
X20000000Y15000000D03*
D11*
X10000000Y10000000D02*
X20000000Y15000000D01*
M02*
"""


def test_getg_in_ink_mode_asks_about_the_offset_it_then_uses(home, tmp_path):
    board = tmp_path / "pads.gbr"
    board.write_text(PADS)
    config = MachineConfig()
    inked = plan_file(board, config)
    asked = inked.offset_nm
    assert inked.mode == "ink" and asked != proposed_offset(read_file(board))  # it matters
    typed = plan_file(board, config, (8_000_000, 8_500_000))
    with console_in_thread(home) as user:
        user.line(f"getg {board}")
        offsets = user.expect(r"offsets +X (\S+) mm, Y (\S+) mm \(brings the ink to the "
                              r"origin plus a 1 mm margin\)")
        assert offsets.groups() == (f"{asked[0] / 1e6:.4f}", f"{asked[1] / 1e6:.4f}")
        user.expect(r"use these offsets\?")
        user.line("y")
        user.expect(r"process has finished")
        assert user.status()[1:] == position_after(inked.job, len(inked.job), config)
        user.line("getg " + str(board))
        user.expect(r"use these offsets\?")
        user.line("n")
        user.expect(r"offsets X,Y in mm")
        user.line("8, 8.5")
        user.expect(r"process has finished")
        assert user.status()[1:] == position_after(typed.job, len(typed.job), config)
    assert user.screen.text.count("offsets     X") == 2          # asked twice, said twice


def test_getg_refuses_a_job_wider_than_the_travel_before_asking(home, tmp_path):
    wide = tmp_path / "wide.nc"                 # 203.4 mm from the first X to the last
    wide.write_text("G21 G90\nG0 X0 Y0\nM3\nG1 X203.4 Y10\nM5\n")
    with console_in_thread(home) as user:
        user.line(f"getg {wide}")
        user.expect(r"the job is 203\.4 mm wide \(with its travel moves\); the machine's "
                    r"travel is 200 mm")
        user.expect(r">>")
        assert "use these offsets" not in user.screen.text


def test_getg_with_a_bad_file_prints_one_error_line(home, tmp_path):
    bad = tmp_path / "bad.gbr"
    bad.write_text("%FSLAX24Y24*%\n%MOMM*%\nX100Y100D02*\nG99*\nM02*\n")
    with console_in_thread(home) as user:
        user.line(f"getg {tmp_path / 'missing.gbr'}")
        user.expect(r"missing\.gbr: cannot read")
        user.line(f"getg {bad}")
        user.expect(rf"{re.escape(str(bad))}:\d+:\d+: ")
        user.line("status")
        user.expect(r"state idle")
        assert "Traceback" not in user.screen.text


def test_getg_refuses_a_job_that_leaves_the_travel(home):
    with console_in_thread(home) as user:
        user.line(f"getg --mode centre {BOARD}")
        user.expect(r"use these offsets\?")
        user.line("n")
        user.expect(r"offsets X,Y in mm")
        user.line("0, 30")                       # Y 5 mm - 30 mm: below the travel
        user.expect(rf"{re.escape(str(BOARD))}:\d+:\d+: .*Y")
        state, x, y, z = user.status()
        assert (state, x, y) == ("idle", 0, 0)   # nothing was sent


@pytest.mark.parametrize("stop_key", ["q", "\x03"], ids=["q", "ctrl-c"])
def test_a_job_stopped_while_moving_leaves_the_machine_standing(home, stop_key):
    config = MachineConfig()
    job = plan_file(BOARD, config, options=CENTRE).job
    end = position_after(job, len(job), config)
    with console_in_thread(home, REAL_TIME_SIM) as user:
        user.type("\x03")                        # Ctrl-C at the prompt: a new prompt
        user.expect(r"\(Ctrl-C stops a command or a job; exit or Ctrl-D leaves\)\n>>")
        user.line(f"getg --mode centre {BOARD}")
        user.expect(r"use these offsets\?")
        user.line("y")
        user.expect(r"insert pen for aperture")
        user.type("\r")
        user.expect(r"lines\s+\d")              # the bar is up and the head moves
        user.type(stop_key)
        user.expect(r"job stopped after \d+ of \d+ commands: stopped by the user")
        state, x, y, z = user.status()
    assert state == "idle"
    assert (x, y, z) != end


def test_q_at_a_pen_change_stops_the_job_and_resume_finishes_it(home):
    config = MachineConfig()
    job = plan_file(BOARD, config, options=CENTRE).job
    with console_in_thread(home) as user:
        user.line(f"getg --mode centre {BOARD}")
        user.expect(r"use these offsets\?")
        user.line("y")
        user.expect(r"insert pen for aperture")
        user.type("\r")
        second = user.expect(r"insert pen for aperture (D\d+) ")
        user.type("q")
        user.expect(r"job stopped after \d+ of \d+ commands.*type resume to continue it")
        assert user.status()[0] == "idle"
        user.line("resume")
        user.expect(r"continue the job\? \[Y/n\]")
        user.type("\x03")                         # not yet: the console says how to go on
        user.expect(rf"cancelled\ntype resume to continue the stopped job of "
                    rf"{re.escape(str(BOARD))}\n")
        user.line(f"getg --mode centre {BOARD}")
        user.expect(r"use these offsets\?")
        user.type("\x03")
        user.expect(r"cancelled\ntype getg to start it again, or resume to continue the "
                    r"stopped job of ")
        user.line("resume")
        user.expect(r"continue the job\? \[Y/n\]")
        user.line("")
        # the pen the job stopped for is asked for first, then the rest of the job runs
        user.expect(rf"insert pen for aperture {second.group(1)} ")
        for _ in range(len(job.pen_changes) - 2):
            user.type("\r")
            user.expect(r"insert pen for aperture")
        user.type("\r")
        user.expect(r"process has finished")
        assert user.status() == ("idle", *position_after(job, len(job), config))
        user.line("resume")
        user.expect(r"no interrupted job to resume")


# ---- setup -----------------------------------------------------------------------------------
def test_setup_jogs_with_the_keypad_and_sets_the_origin(home):
    config = MachineConfig()
    step = jog_units_to_steps(250, config)            # 2.5 mm
    assert step == 400
    with console_in_thread(home) as user:
        user.line("setup")
        user.expect(r"1\) jog")
        user.line("1")
        user.expect(r"jog distance in units of 10 um \(1000 = 1 cm, 0 goes back\)")
        user.line("250")
        user.expect(r"q: back")
        for key in "6686":                            # X+ X+ Y+ X+
            user.type(key)
        user.type("7")                                # Z up
        user.type("4")                                # X-
        user.type("q")
        user.expect(r"position X 5\.000  Y 2\.500  Z 2\.500 mm")
        user.line("q")
        assert user.status() == ("idle", 2 * step, step, step)

        user.line("setup")
        user.line("1")
        user.expect(r"jog distance")
        user.line("")                                 # the default, 100 = 1 mm
        user.expect(r"q: back")
        user.type("1")                                # Z down 160 steps
        user.type("o")                                # origin here
        user.expect(r"origin set here: X, Y and Z are 0 now")
        user.type("\x1b[B")                           # keypad 2 with NumLock off: Y-
        user.type("q")
        user.expect(r"position X 0\.000  Y -1\.000  Z 0\.000 mm")
        user.line("1")
        user.expect(r"jog distance")
        user.line("0")                                # the seed's way back to the menu
        user.expect(r"choice:")
        user.line("q")
        assert user.status() == ("idle", 0, -160, 0)

        user.line("home")                             # the origin goes to the switches
        user.expect(r"homed: X 0\.000  Y 0\.000")
        user.expect(r"the origin is now the home position \(X and Y 0 at the end stops; Z "
                    r"has no end stop and keeps its origin\): an origin set in setup before "
                    r"is replaced; set it again where the paper is \(setup, then o\)")
        assert user.status() == ("idle", 0, 0, 0)


def test_the_jog_line_follows_the_head_and_refusals_are_in_mm():
    # The keypad screen redraws its line every REFRESH_S (prompt_toolkit sends only
    # the changed characters, so this checks the line itself): after a key it must
    # come to show where the jog ended without another key, and a refusal in mm.
    link = MachineLink.open(REAL_TIME_SIM)
    try:
        keypad = KeypadJog(SimpleNamespace(link=link, config=MachineConfig()), 500)  # 5 mm
        keypad.jog((1, 0, 0))                       # about 1 s at 5 mm/s
        deadline = time.monotonic() + 10
        while "X 5.000  Y 0.000" not in keypad.line() and time.monotonic() < deadline:
            time.sleep(REFRESH_S)
        assert "X 5.000  Y 0.000" in keypad.line()
        link.wait_idle()
        keypad.jog((-1, 0, 0))
        keypad.jog((-1, 0, 0))                      # past the travel's start at X 0
        assert ("refused: X would reach -5.000 mm, below the travel's start at 0.000 mm "
                "[-800 steps]") in keypad.line()
    finally:
        link.close()


def test_connect_to_a_mistyped_port_keeps_the_working_one(home):
    with console_in_thread(home) as user:
        user.line("connect /dev/ttyNOPE")
        user.expect(r"cannot open /dev/ttyNOPE: no such port \(the ports command lists the "
                    r"ports there are\); still connected to sim://\?speed=0")
        assert "not connected" not in user.screen.text
        assert "Errno" not in user.screen.text
        assert user.status()[0] == "idle"


def test_setup_feed_rate_warns_above_6_25_and_refuses_outside_the_limits(home):
    with console_in_thread(home) as user:
        user.line("setup")
        user.line("2")
        user.expect(r"feed rate in mm/s \[5\]")
        user.line("7.5")
        user.expect(r"warning: 7\.5 mm/s \(360 rpm\) is above 6\.25 mm/s \(300 rpm\)")
        user.expect(r"use it anyway\? \[y/N\]")
        user.line("")                                 # the default is no
        user.expect(r"feed rate stays 5 mm/s")
        user.line("2")
        user.line("7.5")
        user.expect(r"use it anyway\?")
        user.line("y")
        user.expect(r"feed rate 7\.5 mm/s \(1200 steps/s, 360 rpm\)")
        user.line("2")
        user.expect(r"feed rate in mm/s \[7\.5\]")
        user.line("500")
        user.expect(r"refused: the machine runs 0\.0625 \.\. 250 mm/s")
        user.line("2")
        user.line("6")                                # below the warning: no question
        user.expect(r"feed rate 6 mm/s \(960 steps/s")
        assert "use it anyway" not in user.screen.text[user.seen - 200:]
        user.line("q")
        user.line("status")
        user.expect(r"feed 6 mm/s")


# ---- resume ----------------------------------------------------------------------------------
def test_resume_finishes_a_job_whose_port_died(home):
    """A board that keeps power while its USB cable is out (`sim://NAME`): the job's
    port dies at its second pen change; the console's `resume` finishes the job."""
    port = "sim://resume-board?speed=0"
    program = read_file(BOARD)
    config = MachineConfig()
    job = plan_program(program, config, proposed_offset(program))
    pen_changes = []

    def pull_the_cable(change) -> None:
        pen_changes.append(change)
        if len(pen_changes) == 2:
            link.close()

    try:
        link = MachineLink.open(port, 115200, config)
        with pytest.raises(PortGone):
            JobStreamer(link, job, program, journal=Journal.default()).run(
                on_pen_change=pull_the_cable)
        entry = Journal.default().pending()
        assert entry is not None and entry.state == INTERRUPTED
        assert 0 < entry.confirmed + 1 < len(job)

        with console_in_thread(home, port) as user:
            user.line("resume")
            user.expect(rf"{entry.confirmed + 1} of {len(job)} commands were done")
            user.expect(r"continue the job\? \[Y/n\]")
            user.line("")
            start = entry.confirmed + 1
            # first the pen in force where the job continues (it may have been taken
            # out meanwhile), then the changes still ahead
            in_force = job.pen_changes[max(i for i in job.pen_changes if i <= start)]
            ahead = [job.pen_changes[i] for i in sorted(job.pen_changes) if i > start]
            for aperture in [in_force] + ahead:
                user.expect(rf"insert pen for aperture D{aperture} ")
                user.type("\r")
            user.expect(r"process has finished")
            assert user.status() == ("idle", *position_after(job, len(job), config))
        assert Journal.default().pending() is None
    finally:
        forget_named_machines()


def test_a_homing_alarm_locks_the_machine_until_unlock(home, tmp_path):
    profile = tmp_path / "far-switches.toml"          # the X switch is out of reach
    profile.write_text("[machine]\nsim_x_endstop_steps = -100000\n")
    with console_in_thread(home, f"{INSTANT_SIM}&config={profile}") as user:
        user.line("home")
        user.expect(r"alarm:11 end-stop not found")
        user.expect(r"the machine is locked \(alarm\): check it, then type unlock")
        assert user.screen.text.count("end-stop not found") == 1      # said once
        assert user.status()[0] == "alarm"
        user.line("G0 X10")                           # a line for the machine waits too
        user.expect(r"G0 X10: not sent, the machine is locked \(alarm\): type unlock \(or "
                    r"home\), then send it again")
        user.line("unlock")
        user.expect(r"unlocked.*: state idle")
        assert user.status()[0] == "idle"
        user.line("G0 X10")
        user.expect(r"ok: the head stands at X 10\.000  Y 0\.000")


# ---- a whole evening: jobs back to back, setup, a stop and a resume -------------------------
SQUARE = ROOT / "samples" / "square-and-circle.nc"


def an_evening(user: ConsoleUser, path: Path, pens: int, pull_the_cable=None) -> None:
    """getg to "finished", getg again, setup (jog, feed), getg stopped with q (or, with
    `pull_the_cable`, its port lost: connect again), resume to "finished": every
    command works after the one before it."""

    def plot(stop: bool = False) -> None:
        user.line(f"getg {path}")
        user.expect(r"use these offsets\? \[Y/n\]")
        user.line("")
        for _ in range(pens):
            user.expect(PEN_PROMPT)
            user.type("\r")
        if stop and pull_the_cable is not None:
            user.expect(r"lines\s+\d")
            port = pull_the_cable()
            user.expect(r"the port is gone: type connect to reconnect, then resume")
            user.line(f"connect {port}")
            user.expect(r"connected to ")
        elif stop:
            user.expect(r"lines\s+\d")           # the bar is up and the head moves
            # a q typed as the bar first draws may come before it reads the keys (then
            # it reaches the next prompt, the job run to its end): the head moves a while
            time.sleep(0.5)
            user.type("q")
            user.expect(r"job stopped after \d+ of \d+ commands: stopped by the user; "
                        r"the machine ramped down; the pen lifted; type resume to continue it")
        else:
            user.expect(r"process has finished in")
            user.expect(r">>")

    plot()
    plot()                                      # the finished job left the machine ready
    user.line("setup")
    user.expect(r"choice:")
    user.line("1")
    user.expect(r"jog distance")
    user.line("")                               # 1 mm
    user.expect(r"q: back")
    user.type("6")
    user.type("8")
    user.type("q")
    user.expect(r"position X \S+  Y \S+  Z \S+ mm")
    user.expect(r"choice:")
    user.line("2")
    user.expect(r"feed rate in mm/s")
    user.line("6")
    user.expect(r"feed rate 6 mm/s")
    user.expect(r"choice:")
    user.line("q")
    user.expect(r">>")
    plot(stop=True)
    user.line("resume")
    user.expect(r"commands were done \((stopped by the user|.*the port went away.*)\)")
    user.expect(r"continue the job\? \[Y/n\]")
    user.line("")
    if pens:
        user.expect(PEN_PROMPT)    # the pen in force where it continues
        user.type("\r")
    while True:                                 # the pen changes still ahead, then the end
        found = user.expect(PEN_PROMPT + "|process has finished")
        if found.group(0) == "process has finished":
            break
        user.type("\r")
    assert "error" not in user.screen.text.lower(), user.screen.text[-3000:]
    assert "alarm" not in user.screen.text.lower(), user.screen.text[-3000:]
    assert "Traceback" not in user.screen.text


def _uninterrupted(path: Path, config: MachineConfig | None = None):
    job = plan_file(path, config or MachineConfig()).job
    return job, simulate(job.commands)


@pytest.mark.parametrize("stop", ["q", "cable"], ids=["q", "port-lost"])
def test_a_whole_evening_on_sim(home, monkeypatch, stop):
    # ink mode with two pens: getg asks for exactly two, widest first
    job, whole = _uninterrupted(BOARD, TWO_PENS)
    assert list(job.pen_labels[k] for k in job.pen_changes.values()) == \
        ["the 0.8 mm pen", "the 0.3 mm pen"]
    # a board that keeps power when its port dies; at 100 times real time the 178 s ink
    # job runs 1.8 s, long enough for the q typed 0.5 s into it
    port = "sim://evening?speed=100"
    opened = []

    def open_faulty(*args, **kwargs):      # every port the console opens can be pulled
        opened.append(FaultyPort(open_port(*args, **kwargs)))
        return opened[-1]

    def pull_the_cable() -> str:
        opened[-1].dead = True
        return port

    monkeypatch.setattr(link_module, "open_port", open_faulty)
    # the sample counts as large: getg says what the ink is at, as it does for big layers
    monkeypatch.setattr(pipeline, "PLANNING_NOTICE_OPS", 1)
    try:
        with console_in_thread(home, port, TWO_PENS) as user:
            an_evening(user, BOARD, pens=2,
                       pull_the_cable=pull_the_cable if stop == "cable" else None)
            state, *position = user.status()
        trace = named_machine("evening").trace()
    finally:
        forget_named_machines()
    assert state == "idle" and tuple(position) == whole.final_position
    said = user.screen.text
    # three getg of the board and a resume, planned twice: the second getg and the
    # resume take the plan the console kept (console/plans.py); the third getg comes
    # after setup set another feed, so it plans for that machine. And what was
    # plotted is still exactly the uninterrupted job (above).
    planned = [m.start() for m in re.finditer(r"inking: working out the copper \.\.\.", said)]
    assert len(planned) == 2
    assert planned[0] < said.index("feed rate 6 mm/s") < planned[1] \
        < said.index("commands were done (")
    assert said.index("inking: working out the copper ...") \
        < said.index("inking: filling with the 0.8 mm pen ...") \
        < said.index("inking: filling with the 0.3 mm pen ...") \
        < said.index("insert the 0.8 mm pen")
    # three jobs of the same board (one stopped and resumed), jogs pen up: together
    # they inked exactly what one uninterrupted run inks
    assert inked_points(trace) == inked_points(whole)


#: SQUARE at half its size (a 10 mm square, a 5 mm circle): 10.6 s of machine time, not
#: 17.6, for each of the evening's three and a half runs on the firmware (simavr runs it
#: about 5 times faster than a board: the stopped run still has a second to go at its q)
SMALL_SQUARE = """G21 G90 G17
F600
G00 X0 Y0
M03
G01 X10
Y10
X0
Y0
M05
G00 X7.5 Y5
M03
G02 X7.5 Y5 I-2.5 J0
M05
M02
"""


def test_a_whole_evening_on_the_firmware_in_simavr(home):
    build_firmware()
    build_harness()
    square = home.parent / "small-square.nc"
    square.write_text(SMALL_SQUARE)
    job, whole = _uninterrupted(square)
    with SimulatedBoard(ELF) as board:
        with console_in_thread(home, board.port) as user:
            an_evening(user, square, pens=0)
            state, *position = user.status()
            user.line("G0 X10")         # a line for the machine, as a job of one line
            user.expect(r"ok: the head stands at X 10\.000  Y \S+  Z \S+ mm \(work\)")
            assert user.status()[1:3] == (1600, position[1])    # 160 steps/mm, Y kept
        board.stop()
        tick, axis, direction = step_trace(board.trace())
    assert state == "idle" and tuple(position) == whole.final_position
    trace = Trace(tick, axis, direction, whole.final_position, int(tick[-1]))
    assert inked_points(trace) == inked_points(whole)
