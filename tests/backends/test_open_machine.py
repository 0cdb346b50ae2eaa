"""open_machine picks the kind from what answers, and both front ends' jobs run through
the Machine's engine: the shell's plot on sim:// is journalled by our firmware's
JobStreamer (journal.json), finished, the pen up at the end."""

from __future__ import annotations

from pathlib import Path

import pytest

from galileo_cnc.__main__ import main
from galileo_cnc.backends import open_machine
from galileo_cnc.backends.galileo import GalileoMachine
from galileo_cnc.config.profile import load_profile
from galileo_cnc.stream.journal import FINISHED, Journal

SAMPLE = str(Path(__file__).resolve().parents[2] / "samples" / "square-and-circle.nc")


@pytest.fixture
def home(tmp_path, monkeypatch):
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    return tmp_path


def test_sim_opens_our_firmware_and_plot_runs_its_engine(home, capsys):
    machine = open_machine("sim://", load_profile(None))
    try:
        assert type(machine) is GalileoMachine and machine.simulated
        assert not machine.queues_jogs and not machine.checks_jobs
    finally:
        machine.close()
    assert main(["plot", SAMPLE, "--yes", "--port", "sim://?speed=0"]) == 0
    out = capsys.readouterr().out
    assert "process has finished" in out
    entry = Journal.default().load()
    assert entry.state == FINISHED and entry.confirmed == entry.total - 1
    # nothing is left to resume: plot --resume says so, through the same machine
    assert main(["plot", SAMPLE, "--resume", "--yes", "--port", "sim://?speed=0"]) == 1
    assert "no interrupted job of" in capsys.readouterr().err
