"""A board reset mid-job, as a user meets it: `plot --home`, the reset, `plot --resume`.

In one process: `sim://NAME` machines keep power (and, across a reset, the head's
physical place) only within a process. A reset restarts the machine's trace, so what
the pen drew is taken in the simulated world's frame: the trace up to the reset from
the first power-on's place, the rest from where the head stood when resuming.
"""

import threading
import time
from pathlib import Path

import pytest

from galileo_cnc.cli.main import main
from galileo_cnc.sim.simulator import named_machine

from faults import ctrl_c_when
from inked import inked_points

SAMPLE = str(Path(__file__).resolve().parents[2] / "samples" / "led-blinker.gbr")


pytestmark = pytest.mark.usefixtures("fresh_sim")     # tests/conftest.py


class ResetButton:
    """Presses the reset of sim://NAME once the machine has accepted line `after`
    (its 23rd job command or so: the sample's longest stretch between pen changes,
    with the queue full of drawing)."""

    def __init__(self, name: str, after: int = 38):
        self.before = None
        self._thread = threading.Thread(target=self._watch, args=(name, after), daemon=True)
        self._thread.start()

    def _watch(self, name: str, after: int) -> None:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            try:
                machine = named_machine(name)
            except KeyError:                # not opened yet
                time.sleep(0.005)
                continue
            if machine.status().last_seq >= after:
                self.before = machine.reset()
                return
            time.sleep(0.005)

    def pressed(self):
        self._thread.join(60)
        assert self.before is not None, "the job ended before the reset"
        return self.before


def test_a_homed_job_reset_mid_way_resumes_to_the_uninterrupted_drawing(capsys):
    assert main(["plot", SAMPLE, "--home", "--yes", "--port", "sim://whole?speed=0"]) == 0
    whole = inked_points(named_machine("whole").trace())
    capsys.readouterr()

    url = "sim://reset?speed=20"
    button = ResetButton("reset")
    assert main(["plot", SAMPLE, "--home", "--yes", "--port", url]) == 3
    before = inked_points(button.pressed())
    said = capsys.readouterr().out
    assert "the machine was reset during the job" in said
    assert "`galileo-cnc plot --resume` (or `resume` in the console) homes the machine" in said

    # Z has no end stop: the user turns the pen back to its Z origin (the paper)
    machine = named_machine("reset")
    x, y, _ = machine.physical_position()
    machine.move_by_hand((x, y, 0))
    assert main(["plot", SAMPLE, "--resume", "--yes", "--port", url]) == 0
    said = capsys.readouterr().out
    assert "may not have run, so they are drawn again" in said and "homed" in said
    after = inked_points(machine.trace(), start=(x, y, 0))
    assert before and after and not after >= whole     # the resumed part is not everything
    assert before | after == whole


def test_an_unhomed_job_reset_mid_way_is_refused_saying_why(capsys):
    url = "sim://plain?speed=20"
    button = ResetButton("plain")
    assert main(["plot", SAMPLE, "--yes", "--port", url]) == 1
    button.pressed()
    said = capsys.readouterr().out
    assert "its position is lost, so the job cannot continue and must be started again" in said
    assert "`galileo-cnc plot --home` homes the machine before a job" in said
    assert main(["plot", SAMPLE, "--resume", "--yes", "--port", url]) == 1
    err = capsys.readouterr().err
    assert "reset during the job, and its frame was not the homed one" in err
    assert "must be started again" in err and "Traceback" not in err


def test_home_without_end_stops_is_refused_before_anything_moves(tmp_path, capsys):
    profile = tmp_path / "profile.toml"
    profile.write_text("[machine]\nx_home_pin = -1\n")
    assert main(["plot", SAMPLE, "--home", "--yes", "--profile", str(profile),
                 "--port", "sim://never?speed=0"]) == 1
    err = capsys.readouterr().err
    assert "--home: the profile has no end-stop pin for X (x_home_pin" in err
    with pytest.raises(KeyError):
        named_machine("never")                  # the port was never opened


def press_ctrl_c_while_drawing(name: str, after: int = 38) -> threading.Thread:
    """Ctrl-C (SIGINT's KeyboardInterrupt in the main thread, where `plot` runs) once
    sim://NAME has accepted line `after` and draws (its pen down)."""
    def drawing() -> bool:
        try:
            status = named_machine(name).status()
        except KeyError:                    # not opened yet
            return False
        return status.last_seq >= after and status.z_steps == 0
    return ctrl_c_when(drawing, timeout_s=60, poll_s=0.005)


def test_a_homed_job_stopped_with_ctrl_c_resumes_in_a_new_process(capsys):
    """`plot --home`, Ctrl-C, then `plot --resume` as a new process does it: on a fresh
    machine (a new sim://, as an Uno resets when its port is opened anew), which the
    resume homes, continuing in the command the stop ramped down in."""
    assert main(["plot", SAMPLE, "--home", "--yes", "--port", "sim://whole?speed=0"]) == 0
    whole = inked_points(named_machine("whole").trace())
    capsys.readouterr()

    ctrl_c = press_ctrl_c_while_drawing("first")
    assert main(["plot", SAMPLE, "--home", "--yes", "--port", "sim://first?speed=20"]) == 130
    ctrl_c.join(5)
    said = capsys.readouterr().out
    assert "stopped: stopped with Ctrl-C" in said or "stopped: stopped by the user" in said
    assert f"the job can continue: galileo-cnc plot {SAMPLE} --resume" in said
    first = named_machine("first")
    assert first.status().z_steps == first.config.pen_up_z_steps     # the pen lifted

    assert main(["plot", SAMPLE, "--resume", "--yes", "--port", "sim://second?speed=0"]) == 0
    said = capsys.readouterr().out
    assert "the machine does not stand where the job stopped" in said and "homed" in said
    assert "may not have run" not in said           # it knows where it stopped
    before = inked_points(first.trace())
    after = inked_points(named_machine("second").trace())
    assert before and after and not after >= whole
    assert before | after == whole
