"""`galileo-cnc plot` on stock GRBL 1.1h running in simavr, as a user runs it:
the board answers on a pty, the command finds GRBL there, plans, streams and
finishes; the pins show every end point exact. A steps/mm mismatch is refused
before anything moves; `plot --check` lists the lines GRBL rejects.

GRBL's EEPROM starts empty in simavr (250 steps/mm): the setup writes the
profile's 160 steps/mm and fast rates with `$` commands, as a user would once."""

from __future__ import annotations

import re
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import serial

from galileo_cnc.cli import main as cli
from galileo_cnc.grbl import job as grbl_job
from galileo_cnc.grbl import firmware
from galileo_cnc.grbl.gcode import GcodeLine, expected_end_steps, job_to_gcode
from galileo_cnc.grbl.link import GrblLink
from galileo_cnc.machine.trace import Trace
from galileo_cnc.simavr import board as simavr_board
from galileo_cnc.simavr import grbl_firmware
from galileo_cnc.transport.port import open_port

# the GRBL tests' helpers (build, settings, pin trace) live beside them
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "grbl"))
from grbl_support import profile  # noqa: F401,E402  (the fixture)
from grbl_support import (PROFILE, QUICK_ACCEL, SAMPLE, SCALE, SETTINGS, check_trace,  # noqa: E402
                          grbl_elf, planned_gcode, positions)




#: the test machine accelerating at 8000 mm/s^2: these tests check the pins, GRBL's
#: replies and the messages, which hold at any acceleration (grbl_support.QUICK_ACCEL)
QUICK = {**SETTINGS, **QUICK_ACCEL}


@contextmanager
def grbl(settings: dict[int, str], **board_kwargs):
    """GRBL booted in simavr with `settings` written; the setup's port closed again."""
    with firmware.grbl_board(grbl_elf(), **board_kwargs) as board:
        with serial.Serial(board.port, 115200, timeout=0.2) as port:
            link = GrblLink.connect(port)
            for number, value in settings.items():
                link.command_checked(f"${number}={value}")
        yield board


def test_plot_on_grbl_draws_the_sample_exactly(profile, tmp_path, capsys, monkeypatch):
    preview = tmp_path / "plotted.png"
    trace_file = tmp_path / "plan.npz"
    with grbl(QUICK) as board:
        # probed (GRBL or ours?) and plotted over one open: an Uno resets at each open
        opened = []
        real_open = serial.serial_for_url
        monkeypatch.setattr(serial, "serial_for_url",
                            lambda url, *a, **k: opened.append(url) or real_open(url, *a, **k))
        code = cli.main(["plot", SAMPLE, "--port", board.port, "--mode", "centre", "--yes",
                         "--profile", profile, "--preview", str(preview),
                         "--trace", str(trace_file)])
        board.stop()
    assert opened == [board.port]
    out, err = capsys.readouterr()
    assert code == 0, err
    assert f"GRBL 1.1h on {board.port} (RX 128 B, 15 blocks, 160 steps/mm)" in out
    assert "G-code lines, about 0:" in out and "on GRBL" in out
    # six apertures, six pens asked for (announced: --yes), the first before any line
    assert out.count("insert pen for aperture D") == 6
    assert "process has finished" in out
    assert preview.stat().st_size > 0 and "GRBL cannot report its steps" in out
    assert board.summary["overruns"] == "0" and board.summary["dropped"] == "0"
    # every end point reached exactly, in order, every step within one of the path
    checked = check_trace(positions(board), planned_gcode(profile))
    assert checked["motions"] > 40
    # a board on a port cannot report its steps: --trace is the plan's, and says so
    trace = Trace.load(trace_file)
    assert (f"step trace: {trace_file} ({len(trace)} steps): the reference machine's, "
            f"since {board.port} cannot report its steps") in out
    assert trace.final_position == expected_end_steps(planned_gcode(profile), SCALE)[-1]


def test_a_servo_pen_chosen_in_the_profile_lifts_with_the_spindle_output(tmp_path, capsys,
                                                                         monkeypatch):
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    servo = tmp_path / "servo.toml"
    servo.write_text(PROFILE + '[grbl]\npen = "servo"\nservo_down_s = 500\n'
                     'servo_dwell_ms = 40\n')
    with grbl(QUICK, extra_pins=(grbl_firmware.SPINDLE_PWM_PIN,)) as board:
        code = cli.main(["plot", SAMPLE, "--port", board.port, "--mode", "centre", "--yes",
                         "--profile", str(servo)])
        board.stop()
    out, err = capsys.readouterr()
    assert code == 0, err
    lines = planned_gcode(str(servo))
    texts = [line.text for line in lines]
    assert "M3 S500" in texts and "M5" in texts and "G4 P0.04" in texts
    assert not any(" Z" in text for text in texts[1:])          # no pen heights
    pos = positions(board)
    assert (pos[:, 2] == 0).all()                               # Z never stepped
    _cycle, pin, _level = board.trace()
    assert (pin == grbl_firmware.SPINDLE_PWM_PIN).sum() > 2 * texts.count("M3 S500")
    moves = sum(text.split()[0] in ("G0", "G1", "G2", "G3") for text in texts)
    assert moves > 30 and check_trace(pos, lines)["motions"] == moves   # every end exact


def test_other_steps_per_mm_refused_before_anything_moves(profile, capsys):
    with grbl({}) as board:         # GRBL's own defaults: 250 steps/mm
        assert cli._probe(board.port, 115200) == "GRBL 1.1h"      # ports --probe's tag
        code = cli.main(["plot", SAMPLE, "--port", board.port, "--mode", "centre", "--yes",
                         "--profile", profile])
        board.stop()
    out, err = capsys.readouterr()
    assert code == 1
    assert "GRBL has $100=250.000, $101=250.000, $102=250.000" in err
    assert "160 steps/mm" in err and "Send GRBL $100=160 $101=160 $102=160" in err
    assert "Nothing was sent" in err and "finished" not in out
    assert positions(board).tolist() == [[0, 0, 0]]     # not one step edge on the pins


def test_check_mode_reports_rejected_lines_and_moves_nothing(profile, capsys, monkeypatch,
                                                              tmp_path):
    with grbl(QUICK) as board:
        args = ["plot", SAMPLE, "--port", board.port, "--mode", "centre", "--check",
                "--profile", profile]
        assert cli.main(args + ["--trace", str(tmp_path / "none.npz")]) == 1
        assert "check mode moves nothing, so there are no steps to trace" in \
            capsys.readouterr().err
        assert cli.main(args) == 0
        clean, _ = capsys.readouterr()

        # our planned jobs never hold a line GRBL rejects: spoil two on the way out
        def spoiled(*a, **k):
            lines = job_to_gcode(*a, **k)
            for n in (5, 9):
                lines[n] = GcodeLine("G5 " + lines[n].text[3:], lines[n].command)
            return lines
        monkeypatch.setattr(grbl_job, "job_to_gcode", spoiled)
        assert cli.main(args) == 1
        board.stop()
    out, _ = capsys.readouterr()
    total = len(planned_gcode(profile))
    assert f"{total} lines checked, 0 rejected" in clean
    assert f"{total} lines checked, 2 rejected:" in out
    rejected = [line for line in out.splitlines() if "error:20" in line]
    assert len(rejected) == 2
    assert "led-blinker.gbr:" in rejected[0] and "in G-code line 6 'G5 " in rejected[0]
    assert "in G-code line 10 'G5 " in rejected[1]
    assert positions(board).tolist() == [[0, 0, 0]]     # check mode moves nothing


def test_check_is_a_grbl_option(profile, capsys):
    code = cli.main(["plot", SAMPLE, "--port", "sim://", "--check", "--profile", profile])
    assert code == 1
    err = capsys.readouterr().err
    assert "plot --check runs GRBL's check mode ($C)" in err and "galileo-cnc firmware" in err


def test_a_line_grbl_refuses_stops_the_plot_naming_it(profile, capsys, monkeypatch):
    def spoiled(*a, **k):           # as above: our own jobs never hold such a line
        lines = job_to_gcode(*a, **k)
        lines[9] = GcodeLine("G5 " + lines[9].text[3:], lines[9].command)
        return lines
    monkeypatch.setattr(grbl_job, "job_to_gcode", spoiled)
    with grbl(QUICK) as board:
        code = cli.main(["plot", SAMPLE, "--port", board.port, "--mode", "centre", "--yes",
                         "--profile", profile])
        board.stop()
    out, _ = capsys.readouterr()
    assert code == 1 and "finished" not in out
    # numbered in the whole job, though streamed in pieces between pen changes
    refused = next(line for line in out.splitlines() if "GRBL refused a line" in line)
    assert "led-blinker.gbr:" in refused and "error:20: Unsupported command" in refused
    assert refused.endswith("in G-code line 10 'G5 Z1.875'")
    assert board.summary["overruns"] == "0"


# ---- simavr://?firmware=grbl: GRBL in simavr as a port, no hardware ------------------------

#: GRBL's settings in the URL (its simulated EEPROM starts empty each time): the test
#: machine's, as QUICK; realtime=0 lets simavr run as fast as it can.
GRBL_URL = "simavr://?firmware=grbl&realtime=0&" + "&".join(
    f"${number}={value}" for number, value in QUICK.items())
STEP_NM = 6250      # 160 steps/mm


def reported_work_steps(out: str) -> tuple[int, ...]:
    """The end position plot prints, in steps (GRBL reports 3 decimals of a mm)."""
    match = re.search(r"GRBL stands at X (\S+) Y (\S+) Z (\S+) mm \(work\)", out)
    assert match, out[-500:]
    nm = [round(float(text) * 1_000_000) for text in match.groups()]
    steps = tuple(round(v / STEP_NM) for v in nm)
    assert all(abs(v - s * STEP_NM) <= 500 for v, s in zip(nm, steps))   # a step's report
    return steps


def trace_positions(trace: Trace) -> np.ndarray:
    """A --trace file's positions as grbl_support.positions() gives the pins': one row
    per step interrupt (the steps of one tick together), from (0, 0, 0)."""
    pos = trace.positions()
    last_of_tick = np.r_[trace.tick[1:] != trace.tick[:-1], True]
    return np.vstack([np.zeros((1, 3), np.int64), pos[last_of_tick]])


def test_plot_over_the_simavr_grbl_url_finishes_exactly(profile, capsys, tmp_path):
    grbl_elf()                      # built (or skipped with the missing package) first
    assert cli._probe(GRBL_URL, 115200) == "GRBL 1.1h"      # ports --probe's tag
    trace_file = tmp_path / "grbl.npz"
    code = cli.main(["plot", SAMPLE, "--port", GRBL_URL, "--mode", "centre", "--yes",
                     "--profile", profile, "--trace", str(trace_file)])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert f"GRBL 1.1h on {GRBL_URL} (RX 128 B, 15 blocks, 160 steps/mm)" in out
    assert out.count("insert pen for aperture D") == 6 and "process has finished" in out
    assert "ALARM" not in out + err and "error" not in out + err
    lines = planned_gcode(profile)
    end = expected_end_steps(lines, SCALE)[-1]
    assert reported_work_steps(out) == end
    # --trace: the steps GRBL's pins made, in plot --trace's format (tick, axis, dir)
    trace = Trace.load(trace_file)
    assert f"step trace: {trace_file} ({len(trace)} steps, as GRBL's step pins in simavr " \
           f"reported them)" in out
    assert trace.final_position == end == tuple(trace.displacement())
    assert np.all(np.diff(trace.tick) >= 0) and set(np.unique(trace.dir)) == {-1, 1}
    # every end point exact, every step within one of the path: the directions are
    # GRBL's (a dir pin high is its negative direction), not the pins' levels
    checked = check_trace(trace_positions(trace), lines)
    assert checked["motions"] > 40


def test_simavr_grbl_url_bad_options_and_missing_pieces(profile, capsys, monkeypatch, tmp_path):
    grbl_elf()
    for url, words in [
            ("simavr://?firmware=grbl&speed=2", "bad option speed='2'"),
            ("simavr://?firmware=marlin", "bad option firmware='marlin'"),
            ("simavr://?firmware=grbl&$100=fast", "bad option $100='fast'"),
            ("simavr://?$100=160", "$100=160 is a GRBL setting: add firmware=grbl"),
            ("simavr://?firmware=grbl&realtime=0&$999=1", "GRBL refused $999=1: error:3")]:
        assert cli.main(["plot", SAMPLE, "--port", url, "--yes", "--profile", profile]) == 1
        err = capsys.readouterr().err
        assert f"cannot open {url}" in err and words in err, err
    # GRBL's own defaults (250 steps/mm): the refusal says what to add to the URL
    url = "simavr://?firmware=grbl&realtime=0"
    assert cli.main(["plot", SAMPLE, "--port", url, "--yes", "--profile", profile]) == 1
    err = capsys.readouterr().err
    assert "Add $100=160&$101=160&$102=160 to the simavr:// URL" in err
    # nothing built yet and no avr-gcc: the Debian packages are named
    monkeypatch.setattr(grbl_firmware, "BUILD_DIR", tmp_path / "build-grbl")
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    with pytest.raises(serial.SerialException, match=r"install the Debian packages "
                       r"gcc-avr make \(sudo apt install gcc-avr make\)"):
        open_port("simavr://?firmware=grbl")
    monkeypatch.setenv(simavr_board.HARNESS_ENV, str(tmp_path / "no-harness"))
    with pytest.raises(serial.SerialException, match=r"galileo-simavr is not built.*"
                       r"Debian packages: libsimavr-dev"):
        open_port("simavr://?firmware=grbl")
