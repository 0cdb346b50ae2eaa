"""Both front ends run the same job engine, on each kind of machine: one session per
kind, as a user has it. The shell's `plot` of a small board is stopped with Ctrl-C
at its second pen change and `plot --resume` finishes it; then the console's `getg`
of it is stopped with q at the second pen change and `resume` finishes it. Checked:
where the machine stands after each (the job's end, the pen up), the journal each
front end left (the machine's own: journal.json for our firmware, journal-grbl.json
for GRBL, finished, every line confirmed), and that every job and resume of both
front ends was run by the one Machine class open_machine gives for that port.

Machines: sim:// (a named machine, so it keeps its position between the sessions'
ports), our firmware in simavr, stock GRBL 1.1h in simavr (homing on, its work zero
set: a stopped job's resume homes). Both simavr boards run as fast as they can, the
board is three short lines in three pens.
"""

from __future__ import annotations

import io
import sys
from pathlib import Path

import pytest
import serial

from galileo_cnc.__main__ import main
from galileo_cnc.backends import open_machine
from galileo_cnc.backends.galileo import GalileoMachine
from galileo_cnc.backends.grbl import GrblMachine
from galileo_cnc.config.profile import load_profile
from galileo_cnc.grbl.gcode import expected_end_steps, job_to_gcode, pen_from_config
from galileo_cnc.grbl.job import grbl_journal
from galileo_cnc.grbl.link import GrblLink
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.sim.simulator import forget_named_machines
from galileo_cnc.simavr.board import SimulatedBoard
from galileo_cnc.stream.journal import FINISHED, Journal
from galileo_cnc.stream.resume import position_after

TESTS = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(TESTS / "console"), str(TESTS / "grbl")]
from test_console import console_in_thread  # noqa: E402
from firmware_support import ELF, build_firmware, build_harness  # noqa: E402
from grbl_support import (LIMITS, PROFILE, QUICK_HOMED, SCALE, grbl_machine,  # noqa: E402
                          set_work_zero)

CENTRE = PlanOptions(mode="centre")
#: the smallest board that has what the sessions need: three pens, so the job stops
#: at a pen change after drawing and goes on with a pen change still to come
THREE_PENS = """%FSLAX26Y26*%
%MOMM*%
%ADD10C,0.3*%
%ADD11C,0.5*%
%ADD12C,0.8*%
D10*
X1000000Y1000000D02*
X4000000Y1000000D01*
D11*
X1000000Y2000000D02*
X4000000Y2000000D01*
D12*
X1000000Y3000000D02*
X4000000Y3000000D01*
M02*
"""


@pytest.fixture
def board_file(tmp_path) -> str:
    path = tmp_path / "three-pens.gbr"
    path.write_text(THREE_PENS)
    return str(path)


class PenAnswers(io.StringIO):
    """The shell user at the pen prompts: Enter at the first, Ctrl-C at the second."""

    def __init__(self):
        super().__init__()
        self.asked = 0

    def readline(self, *args) -> str:
        self.asked += 1
        if self.asked == 2:
            raise KeyboardInterrupt
        return "\n"


@pytest.fixture
def engines(tmp_path, monkeypatch):
    """The Machine class that ran each job, front end by front end (the real run_job,
    recorded on the way in)."""
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path / "home"))
    monkeypatch.setenv("GALILEO_CNC_NO_PROBE", "1")
    ran: list[str] = []
    for kind in (GalileoMachine, GrblMachine):
        real = kind.run_job

        def recorded(self, job, operator, real=real):
            ran.append(type(self).__name__)
            return real(self, job, operator)
        monkeypatch.setattr(kind, "run_job", recorded)
    return ran


def shell_session(file: str, port: str, capsys, monkeypatch, *extra: str) -> None:
    """plot stopped with Ctrl-C at the second pen change, then plot --resume."""
    answers = PenAnswers()
    monkeypatch.setattr(sys, "stdin", answers)
    args = ["plot", file, "--mode", "centre", "--port", port, *extra]
    assert main(args) == 130
    out = capsys.readouterr().out
    assert answers.asked == 2 and "stopped: " in out
    assert main(args + ["--resume", "--yes"]) == 0
    out = capsys.readouterr().out
    assert "process has finished" in out


def console_session(user, file: str) -> None:
    """getg stopped with q at the second pen change, then resume to the end."""
    user.line(f"getg --mode centre {file}")
    user.expect(r"use these offsets\?")
    user.line("y")
    user.expect(r"insert pen for aperture")
    user.type("\r")
    user.expect(r"insert pen for aperture")
    user.type("q")
    user.expect(r"job stopped after \d+ of \d+ .*type resume to continue it")
    user.line("resume")
    user.expect(r"continue the job\? \[Y/n\]")
    user.line("")
    while user.expect(r"insert pen for aperture D\d+|process has finished",
                      60).group(0) != "process has finished":
        user.type("\r")                            # the pen is in


def finished(journal) -> None:
    entry = journal.load()
    assert entry.state == FINISHED and entry.confirmed == entry.total - 1


def our_firmware_session(file: str, port: str, capsys, monkeypatch, engines) -> None:
    config = load_profile(None).config
    job = plan_file(file, config, options=CENTRE).job
    end = position_after(job, len(job), config)     # the last command lifts the pen
    shell_session(file, port, capsys, monkeypatch)
    finished(Journal.default())
    with console_in_thread(Path(Journal.default().path).parent, port, config) as user:
        assert user.status() == ("idle", *end)      # where the shell's resume ended
        console_session(user, file)
        assert user.status() == ("idle", *end)
    finished(Journal.default())
    assert engines == ["GalileoMachine"] * 4        # plot, plot --resume, getg, resume
    machine = open_machine(port, load_profile(None))
    try:
        assert type(machine) is GalileoMachine
    finally:
        machine.close()


def test_both_front_ends_on_sim(engines, board_file, capsys, monkeypatch):
    try:
        our_firmware_session(board_file, "sim://fronts?speed=0", capsys, monkeypatch,
                             engines)
    finally:
        forget_named_machines()


def test_both_front_ends_on_our_firmware_in_simavr(engines, board_file, capsys, monkeypatch):
    build_firmware()
    build_harness()
    with SimulatedBoard(ELF) as board:
        our_firmware_session(board_file, board.port, capsys, monkeypatch, engines)
        board.stop()


def test_both_front_ends_on_grbl_in_simavr(engines, board_file, capsys, monkeypatch,
                                           tmp_path):
    profile = tmp_path / "fast.toml"
    profile.write_text(PROFILE)
    config = load_profile(profile).config
    job = plan_file(board_file, config, options=CENTRE).job
    lines = job_to_gcode(job, SCALE, pen_from_config(config),
                         feed_steps_per_s=config.feed_steps_per_s,
                         flash_dwell_ms=config.flash_dwell_ms)
    end = expected_end_steps(lines, SCALE)[-1]      # work steps, the pen up
    with grbl_machine(QUICK_HOMED, limits=LIMITS) as (board, link):
        set_work_zero(link)                         # homed, G54 where the paper is
        shell_session(board_file, board.port, capsys, monkeypatch, "--profile", str(profile))
        finished(grbl_journal())
        assert grbl_work_steps(board.port) == end
        with console_in_thread(tmp_path / "home", board.port, config) as user:
            console_session(user, board_file)
        finished(grbl_journal())
        assert grbl_work_steps(board.port) == end
        board.stop()
    assert engines == ["GrblMachine"] * 4


def grbl_work_steps(port: str) -> tuple[int, ...]:
    """GRBL's work position in steps, from its own status report."""
    with serial.Serial(port, 115200, timeout=0.2) as handle:
        status = GrblLink.connect(handle).status()
    return tuple(round(nm * float(SCALE.steps_per_mm[a]) / NM_PER_MM)
                 for a, nm in enumerate(status.wpos_nm))
