"""`plot --trace` against the firmware in simavr: the steps its pins made, and the
reference's trace (said so) from a port that cannot report steps, as a real board.

`simavr://` records the step and direction pins' edges (`trace=1`, added by `plot
--trace`); the same board reached through its bare pseudo-terminal is a real board to
the host. Both files must hold the job's steps in the reference's order; only the
first can carry the firmware's own ticks.
"""

from __future__ import annotations

import numpy as np
import pytest
import serial

from galileo_cnc.cli.main import main
from galileo_cnc.machine import simulate
from galileo_cnc.machine.trace import Trace
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.simavr.board import SimulatedBoard

from firmware_support import ELF, build_firmware, build_harness

SQUARE = "samples/square-and-circle.nc"


@pytest.fixture(autouse=True)
def built(monkeypatch, tmp_path):
    build_firmware()
    build_harness()
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    monkeypatch.setenv("GALILEO_FIRMWARE", str(ELF))


@pytest.fixture(scope="module")
def reference():
    return simulate(plan_file(SQUARE, offset="none", options=PlanOptions()).job.commands)


def test_plot_trace_on_simavr_writes_the_steps_the_firmware_made(tmp_path, capsys, reference):
    out_file = tmp_path / "steps.npz"
    assert main(["plot", SQUARE, "--port", "simavr://?realtime=0", "--yes", "--offset", "none",
                 "--trace", str(out_file)]) == 0
    out = capsys.readouterr().out
    saved = Trace.load(out_file)
    assert f"({len(saved)} steps, as the firmware's step pins in simavr reported them)" in out
    assert np.array_equal(saved.axis, reference.axis)
    assert np.array_equal(saved.dir, reference.dir)
    assert saved.final_position == reference.final_position
    # the firmware's own clock: it started after the greeting, never at the reference's 0
    assert saved.tick[0] > reference.tick[0]


def test_plot_trace_from_a_port_that_reports_no_steps_writes_the_reference_and_says_so(
        tmp_path, capsys, reference, monkeypatch):
    # the named port is probed (our firmware or GRBL?) and plotted over one open: an
    # Uno resets each time its port is opened
    opened = []
    real_open = serial.serial_for_url
    monkeypatch.setattr(serial, "serial_for_url",
                        lambda url, *a, **k: opened.append(url) or real_open(url, *a, **k))
    out_file = tmp_path / "steps.npz"
    with SimulatedBoard(ELF, trace=False) as board:
        assert main(["plot", SQUARE, "--port", board.port, "--yes", "--offset", "none",
                     "--trace", str(out_file)]) == 0
    assert opened == [board.port]
    out = capsys.readouterr().out
    assert f"the reference machine's, since {board.port} cannot report its steps" in out
    assert Trace.load(out_file).same_steps(reference)
