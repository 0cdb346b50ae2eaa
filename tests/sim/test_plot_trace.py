"""`plot --trace` on sim://: the steps the simulated machine reports, not the plan's.

In process, so that the named machine (which keeps power between opens) can be asked
afterwards what it stepped. A jog before the job makes the machine's steps differ from
the reference's trace of the job (which starts at the origin): the file must hold the
machine's.
"""

from __future__ import annotations

import numpy as np
import pytest

from galileo_cnc.cli.main import main
from galileo_cnc.job import Jog
from galileo_cnc.machine import simulate
from galileo_cnc.machine.trace import Trace
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.sim.simulator import named_machine
from galileo_cnc.transport.link import MachineLink

SQUARE = "samples/square-and-circle.nc"
URL = "sim://plotted?speed=0"


pytestmark = pytest.mark.usefixtures("fresh_sim")     # tests/conftest.py


def test_plot_trace_on_sim_writes_the_steps_the_machine_stepped(tmp_path, capsys):
    link = MachineLink.open(URL)
    link.send(Jog(160, 80, 0))
    link.wait_idle(10)
    link.close()
    before = len(named_machine("plotted").trace())
    assert before == 240

    out_file = tmp_path / "steps.npz"
    assert main(["plot", SQUARE, "--port", URL, "--yes", "--offset", "none",
                 "--trace", str(out_file)]) == 0
    out = capsys.readouterr().out
    saved = Trace.load(out_file)
    assert f"({len(saved)} steps, as the simulated machine reported them)" in out

    machine = named_machine("plotted").trace()
    assert np.array_equal(saved.tick, machine.tick[before:])      # the job's, not the jog's
    assert np.array_equal(saved.axis, machine.axis[before:])
    assert saved.final_position == machine.final_position
    job = plan_file(SQUARE, offset="none", options=PlanOptions()).job
    reference = simulate(job.commands)
    # the machine started the job 1 mm right and 0.5 mm up of where the reference starts,
    # so its first travel differs; both end where the job ends
    assert not saved.same_steps(reference)
    assert tuple(saved.positions((160, 80, 0))[-1]) == reference.final_position
