"""`q` in the console mid-line, as a user stops a fineliner: once the machine has
ramped down and stands still the pen is lifted (within a second of machine time, read
from the Z steps), and `resume` lowers it again where it stopped, so the two parts
draw exactly what one uninterrupted run draws.

On sim:// and on the firmware in simavr, both paced to the wall clock (the lift comes
from the host once the machine reports it stands still); the drawing is one 15 mm
line at 10 mm/s, long enough to stop it in the middle.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest

from galileo_cnc.config.hardware import TICKS_PER_S
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine import Trace, simulate
from galileo_cnc.plan.pipeline import plan_file
from galileo_cnc.sim.simulator import forget_named_machines, named_machine
from galileo_cnc.simavr.board import SimulatedBoard, step_trace

from firmware_support import ELF, build_firmware, build_harness
from inked import inked_points
from test_console import WAIT_S, console_in_thread, home  # noqa: F401  (the fixture)

CONFIG = MachineConfig()
STOPPED = (r"job stopped after \d+ of \d+ commands: stopped by the user; the machine "
           r"ramped down; the pen lifted; type resume")


@pytest.fixture
def drawing(tmp_path) -> Path:
    path = tmp_path / "line.nc"
    path.write_text("G21 G90\nF600\nG00 X0 Y0\nM03\nG01 X15\nG01 Y1\nM05\nM02\n")
    return path


def wait_drawing(position, far: int) -> None:
    """Until `position()` (work steps) shows the pen down at X `far` or beyond."""
    deadline = time.monotonic() + WAIT_S
    while True:
        x, _, z = position()
        if z == CONFIG.pen_down_z_steps and x >= far:
            return
        assert time.monotonic() < deadline, f"the job never drew: at {(x, _, z)}"
        time.sleep(0.02)


#: A board in simavr paced to the wall clock counts the host's round trips between the
#: stop and the lift (GRBL: hold, reset, banner, $I, $$) as machine time: 0.10 s on an
#: idle host, 1.28 s once on a loaded CI machine. The bound still catches a lift that
#: waited for one of the link's 3 s timeouts.
PACED_LIFT_TICKS = int(2.5 * TICKS_PER_S)


def the_lift(trace: Trace) -> tuple[int, int]:
    """The stop's lift: the run of Z steps up that first follows a drawn X step. (machine
    ticks from the last X/Y step before it, the stop's ramp-down, to its last step; the
    Z it ends at.)"""
    z_up = (trace.axis == 2) & (trace.dir == 1)
    first = int(np.flatnonzero(z_up & (np.arange(len(z_up)) > np.flatnonzero(
        trace.axis == 0)[0]))[0])
    end = first
    while end < len(z_up) and z_up[end]:
        end += 1
    assert trace.axis[first - 1] != 2           # straight after the ramp-down, no Z before
    return int(trace.tick[end - 1] - trace.tick[first - 1]), int(trace.positions()[end - 1, 2])


def stop_then_resume(user, drawing: Path, position, whole: Trace) -> tuple:
    """getg, q 2 mm into the line, `status`; then resume to the end and `status`."""
    user.line(f"getg {drawing}")
    user.expect(r"use these offsets\? \[Y/n\]")
    user.line("")
    wait_drawing(position, min(x for x, _ in inked_points(whole)) + 2 * 160)
    user.type("q")
    user.expect(STOPPED)
    stopped = user.status()
    user.line("resume")
    user.expect(r"commands were done \(stopped by the user\)")
    user.expect(r"continue the job\? \[Y/n\]")
    user.line("")
    user.expect(r"process has finished")
    return stopped, user.status()


def test_q_on_sim_lifts_the_pen_and_resume_lowers_it(home, drawing):  # noqa: F811
    whole = simulate(plan_file(drawing, CONFIG).job.commands)
    try:
        with console_in_thread(home, "sim://stop") as user:
            machine = named_machine("stop")

            def position():
                s = machine.status()
                return s.x_steps, s.y_steps, s.z_steps

            stopped, finished = stop_then_resume(user, drawing, position, whole)
        trace = machine.trace()
    finally:
        forget_named_machines()
    assert stopped[0] == "idle" and stopped[3] == CONFIG.pen_up_z_steps
    assert finished == ("idle", *whole.final_position)
    ticks, z = the_lift(trace)
    assert z == CONFIG.pen_up_z_steps and ticks < TICKS_PER_S
    # the resume's lead-in lowered the pen where it stopped: every point is inked
    assert inked_points(trace) == inked_points(whole)


def test_q_on_the_firmware_in_simavr_lifts_the_pen_and_resume_lowers_it(home, drawing):  # noqa: F811
    build_firmware()
    build_harness()
    whole = simulate(plan_file(drawing, CONFIG).job.commands)
    with SimulatedBoard(ELF, realtime=True) as board:
        def position():
            tick, axis, direction = step_trace(board.trace())
            moved = [int(direction[axis == a].sum()) for a in range(3)]
            return tuple(moved)

        with console_in_thread(home, board.port) as user:
            stopped, finished = stop_then_resume(user, drawing, position, whole)
        board.stop()
        trace = Trace(*step_trace(board.trace()), whole.final_position, 0)
    assert stopped[0] == "idle" and stopped[3] == CONFIG.pen_up_z_steps
    assert finished == ("idle", *whole.final_position)
    ticks, z = the_lift(trace)
    assert z == CONFIG.pen_up_z_steps and ticks < PACED_LIFT_TICKS
    assert inked_points(trace) == inked_points(whole)


def test_q_on_grbl_lifts_the_pen_and_resume_goes_on_where_grbl_kept_its_position(
        home, drawing):  # noqa: F811
    """GRBL without homing ($22=0), its work zero where it powered up: q mid-line holds
    the feed and resets GRBL (the position kept), then lifts the pen (GRBL's pins and
    its own report say Z is up); `resume` asks nothing about the position and goes on
    from where GRBL stands, lowering the pen where the line was cut."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "grbl"))
    from grbl_support import CONFIG as GRBL_CONFIG, QUICK_ACCEL, SETTINGS, grbl_machine, \
        positions_and_ticks

    whole = simulate(plan_file(drawing, GRBL_CONFIG).job.commands)
    with grbl_machine({**SETTINGS, **QUICK_ACCEL}, realtime=True) as (board, setup):
        setup.port.close()

        def position():
            return tuple(int(v) for v in positions_and_ticks(board.trace())[0][-1])

        with console_in_thread(home, board.port, GRBL_CONFIG) as user:
            user.line(f"getg {drawing}")
            user.expect(r"use these offsets\? \[Y/n\]")
            user.line("")
            wait_drawing(position, min(x for x, _ in inked_points(whole)) + 2 * 160)
            user.type("q")
            user.expect(r"job stopped after \d+ of \d+ G-code lines: stopped by the user; "
                        r"GRBL held the feed and was reset \(its queue dropped, the "
                        r"position kept\); the pen lifted.*type resume to continue it")
            user.line("status")
            stopped = user.expect(r"state (\w+), .* Z (\S+) mm work")
            user.line("resume")
            user.expect(r"continue the job\? \[Y/n\]")
            user.line("")
            user.expect(r"GRBL kept its position since the job stopped: GRBL stands at "
                        r"X \S+ Y \S+ Z 1\.875 mm \(work\); the job goes on from there")
            user.expect(r"process has finished")
            user.expect(r">>")
        board.stop()
        pos, tick = positions_and_ticks(board.trace())
    text = user.screen.text
    assert "work zero" not in text and "homing" not in text and "Traceback" not in text
    assert stopped.groups() == ("Idle", "1.875")          # 300 steps: the pen up
    assert tuple(pos[-1]) == whole.final_position
    # the lift: Z steps up straight after the ramp-down
    trace = Trace(tick[1:], np.argmax(np.diff(pos, axis=0) != 0, axis=1),
                  np.diff(pos, axis=0).sum(axis=1), whole.final_position, 0)
    ticks, z = the_lift(trace)
    assert z == GRBL_CONFIG.pen_up_z_steps and ticks < PACED_LIFT_TICKS
    down = {tuple(p[:2]) for p in pos if p[2] == GRBL_CONFIG.pen_down_z_steps}
    assert down >= inked_points(whole)          # every point of the line inked
