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


class Recorder:
    """An Operator that stops the job once `stop_at` commands are confirmed."""

    def __init__(self, machine, stop_at: int | None = None):
        self.machine, self.stop_at, self.seen = machine, stop_at, []

    def say(self, text):
        pass

    def progress(self, p):
        self.seen.append((p.confirmed, p.total))
        if self.stop_at is not None and p.confirmed >= self.stop_at:
            self.stop_at = None
            self.machine.stop()

    def pen_change(self, c):
        pass

    def confirm(self, question):
        return True


def test_a_resumed_run_counts_the_whole_jobs_commands(home):
    # progress is in units of the whole job on every kind (GRBL's job counts its lines
    # so): a resume goes on from the commands done before it, never from 1 again
    from galileo_cnc.plan.pipeline import plan_file

    machine = open_machine("sim://resumed?speed=5", load_profile(None))
    try:
        planned = plan_file(Path(SAMPLE), machine.config)
        job = machine.prepare(planned, machine.config)
        first = Recorder(machine, stop_at=4)
        assert not machine.run_job(job, first).completed
        assert first.seen[0][1] == job.total
        resumption = machine.plan_resume(machine.pending(SAMPLE))
        assert resumption.job.start > 0         # where the machine stood, not what it queued
        again = Recorder(machine)
        assert machine.resume(resumption, again).completed
    finally:
        machine.close()
    assert all(total == job.total for _, total in again.seen)
    assert again.seen[0][0] >= resumption.job.start and again.seen[-1][0] == job.total
