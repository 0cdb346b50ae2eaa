"""`galileo-cnc plot` on stock GRBL 1.1h running in simavr, as a user runs it:
the board answers on a pty, the command finds GRBL there, plans, streams and
finishes; the pins show every end point exact. A steps/mm mismatch is refused
before anything moves; `plot --check` lists the lines GRBL rejects.

GRBL's EEPROM starts empty in simavr (250 steps/mm): the setup writes the
profile's 160 steps/mm and fast rates with `$` commands, as a user would once."""

from __future__ import annotations

import sys
from contextlib import contextmanager
from pathlib import Path

import pytest
import serial

from galileo_cnc.cli import main as cli
from galileo_cnc.cli import plot_grbl
from galileo_cnc.config.profile import load_profile
from galileo_cnc.grbl import firmware
from galileo_cnc.grbl.gcode import GcodeLine, job_to_gcode, pen_from_config
from galileo_cnc.grbl.link import GrblLink
from galileo_cnc.plan.pipeline import PlanOptions, plan_file

# the GRBL tests' helpers (build, settings, pin trace) live beside them
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "grbl"))
from grbl_support import SCALE, SETTINGS, check_trace, grbl_elf, positions  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = str(ROOT / "samples" / "led-blinker.gbr")
# the default profile's mechanics (160 steps/mm), run fast so the simulated job is short
PROFILE = """[machine]
feed_mm_s = 100
rapid_feed_mm_s = 100
z_feed_mm_s = 50
feed_warn_mm_s = 100
flash_dwell_ms = 20
"""


@pytest.fixture
def profile(tmp_path, monkeypatch):
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    path = tmp_path / "fast.toml"
    path.write_text(PROFILE)
    return str(path)


@contextmanager
def grbl(settings: dict[int, str]):
    """GRBL booted in simavr with `settings` written; the setup's port closed again."""
    with firmware.grbl_board(grbl_elf()) as board:
        with serial.Serial(board.port, 115200, timeout=0.2) as port:
            link = GrblLink.connect(port)
            for number, value in settings.items():
                link.command_checked(f"${number}={value}")
        yield board


def planned_gcode(profile_path: str) -> list[GcodeLine]:
    """What plot should send, computed here from the same profile."""
    config = load_profile(profile_path).config
    planned = plan_file(SAMPLE, config, options=PlanOptions(mode="centre"))
    return job_to_gcode(planned.job, SCALE, pen_from_config(config),
                        feed_steps_per_s=config.feed_steps_per_s,
                        flash_dwell_ms=config.flash_dwell_ms)


def test_plot_on_grbl_draws_the_sample_exactly(profile, tmp_path, capsys):
    preview = tmp_path / "plotted.png"
    with grbl(SETTINGS) as board:
        code = cli.main(["plot", SAMPLE, "--port", board.port, "--mode", "centre", "--yes",
                         "--profile", profile, "--preview", str(preview)])
        board.stop()
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


def test_check_mode_reports_rejected_lines_and_moves_nothing(profile, capsys, monkeypatch):
    with grbl(SETTINGS) as board:
        args = ["plot", SAMPLE, "--port", board.port, "--mode", "centre", "--check",
                "--profile", profile]
        assert cli.main(args) == 0
        clean, _ = capsys.readouterr()

        # our planned jobs never hold a line GRBL rejects: spoil two on the way out
        def spoiled(*a, **k):
            lines = job_to_gcode(*a, **k)
            for n in (5, 9):
                lines[n] = GcodeLine("G5 " + lines[n].text[3:], lines[n].command)
            return lines
        monkeypatch.setattr(plot_grbl, "job_to_gcode", spoiled)
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
    monkeypatch.setattr(plot_grbl, "job_to_gcode", spoiled)
    with grbl(SETTINGS) as board:
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
