"""A board reset mid-job on the firmware in simavr, as a user meets it: `plot --home`
on the board's port, the reset button (or an Uno's auto-reset), `plot --resume`.

The harness keeps the head where it stood across the reset and its trace goes on
with a mark there, so what the pen drew is the steps before the mark from power-up,
then the rest from where the head stood with the pen turned back to its Z origin
(Z has no end-stop: the docs ask the user to). The whole job on sim://, whose
reference machine has its switches where the harness has them, is what it must be.

The job is a meander of short lines in one pen-down path, written by the test: far
more commands than the firmware queues (protocol QUEUE_BLOCKS = 8: the resume draws up
to nine confirmed commands again), so the reset lands well inside it with seconds of
machine time to spare, and it stays near the switches, so both homings are short: 48 s
of machine time in all, where the LED board took 86 s to draw and long homings. The
reset, the homed resume and the drawing put back together do not depend on the artwork.
"""

from __future__ import annotations

import re
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from galileo_cnc.cli.main import main
from galileo_cnc.machine import Trace
from galileo_cnc.simavr.board import SimulatedBoard, runs_between_resets, step_trace
from galileo_cnc.sim.simulator import named_machine
from galileo_cnc.stream.journal import RUNNING, Journal

from firmware_support import ELF, build_firmware, build_harness
from faults import ctrl_c_when
from inked import inked_points

pytestmark = pytest.mark.usefixtures("fresh_sim")     # tests/conftest.py

ENDSTOPS = ("X:7:-400", "Y:6:-400")    # MachineConfig's sim_x/y_endstop_steps


@pytest.fixture(autouse=True)
def built(monkeypatch, tmp_path):
    build_firmware()
    build_harness()
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))


def meander(folder: Path, lines: int = 60) -> str:
    """A G-code drawing: `lines` lines in one pen-down path, rows of 2 mm 0.125 mm apart
    (no point drawn twice), at 10 mm/s; it stays within 3 mm of its origin, so the
    homing after the reset (1 mm/s) is short too."""
    rows = [(f"G01 X{2 if r % 2 == 0 else 0}", f"G01 Y{0.125 * (r + 1):g}")
            for r in range(lines // 2)]
    path = folder / "meander.nc"
    path.write_text("\n".join(["G21 G90 G17", "F600", "G00 X0 Y0", "M03",
                                *(move for row in rows for move in row), "M05", "M02"]) + "\n")
    return str(path)


def press_reset_after_steps(board: SimulatedBoard, steps: int) -> threading.Thread:
    """Presses the board's reset once its pins have made `steps` steps (the record is
    flushed every 100 ms: a few more may have run)."""
    def watch():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and board.running:
            if len(step_trace(board.trace())[0]) >= steps:
                board.reset()
                return
            time.sleep(0.1)             # the harness flushes its record every 100 ms
    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


def drawn_across_the_reset(edges):
    runs = runs_between_resets(edges)
    assert len(runs) == 2                                # one reset
    first, rest = runs
    assert len(first) and len(rest)
    x, y, _ = (int(v) for v in first.displacement())
    return inked_points(first), inked_points(rest, start=(x, y, 0))


def test_a_homed_job_reset_on_the_firmware_resumes_to_the_uninterrupted_drawing(capsys,
                                                                                tmp_path):
    drawing = meander(tmp_path)
    assert main(["plot", drawing, "--home", "--yes", "--port", "sim://whole?speed=0"]) == 0
    whole = inked_points(named_machine("whole").trace())
    total = len(named_machine("whole").trace())
    capsys.readouterr()

    with SimulatedBoard(ELF, endstops=ENDSTOPS) as board:
        button = press_reset_after_steps(board, total // 2)
        assert main(["plot", drawing, "--home", "--yes", "--port", board.port]) == 3
        button.join(5)
        said = capsys.readouterr().out
        # its banner mid-stream, or (the whole job queued) a last line it never sent
        assert re.search(r"the machine was reset during the job|never sent: it was reset", said)
        assert "homes the machine and continues" in said

        assert main(["plot", drawing, "--resume", "--yes", "--port", board.port]) == 0
        said = capsys.readouterr().out
        assert "may not have run, so they are drawn again" in said and "homed" in said
        board.stop()
        edges = board.trace()
    assert "resets=1" in board.log

    before, after = drawn_across_the_reset(edges)
    assert before and after and not after >= whole      # the resumed part is not everything
    assert before | after == whole
    cycles = edges[0]
    assert np.all(np.diff(cycles) >= 0)                  # one clock from power-up


def ctrl_c_once_confirmed(journal_path: Path, commands: int) -> threading.Thread:
    """Ctrl-C (KeyboardInterrupt in the main thread, where `plot` runs) once the job's
    journal says the machine confirmed `commands` commands."""
    def confirmed() -> bool:
        entry = Journal(journal_path).load() if journal_path.exists() else None
        return entry is not None and entry.state == RUNNING and entry.confirmed >= commands
    return ctrl_c_when(confirmed, timeout_s=120, poll_s=0.02)


def test_a_homed_job_stopped_on_simavr_resumes_on_a_new_board(capsys, tmp_path):
    """simavr:// has the profile's end-stops (as sim://), so `plot --home` homes there;
    Ctrl-C, then `plot --resume` opens the port anew: a new board, as an Uno resets,
    homed again, and it draws the rest of the job."""
    drawing = meander(tmp_path, lines=24)
    assert main(["plot", drawing, "--home", "--yes", "--port", "sim://whole?speed=0"]) == 0
    whole = inked_points(named_machine("whole").trace())
    capsys.readouterr()

    ctrl_c = ctrl_c_once_confirmed(tmp_path / "journal.json", 16)
    assert main(["plot", drawing, "--home", "--yes", "--port", "simavr://?realtime=0"]) == 130
    ctrl_c.join(5)
    said = capsys.readouterr().out
    assert re.search(r"\nhomed: X \S+ Y \S+ mm\n", said), said
    assert "stopped: stopped by the user; the machine ramped down; the pen lifted" in said
    trace = tmp_path / "rest.npz"
    assert main(["plot", drawing, "--resume", "--yes", "--trace", str(trace),
                 "--port", "simavr://?realtime=0"]) == 0
    said = capsys.readouterr().out
    assert "the machine does not stand where the job stopped" in said and "homed" in said
    rest = inked_points(Trace.load(trace))
    assert rest and rest < whole                    # the rest of the job, not all of it
