"""`plot BOARD --mill JOB` (issue 35) through the machine interface (cli/mill.py's
run_mill_plot, reached from run_plot with PlotOptions.mill): on GRBL 1.1h in simavr
with its probe pin (simavr://?firmware=grbl&probe=0) the drilling runs with its bit
change asked like a pen change and ends on the last hole's step; on sim:// a dry run
that says what it does, lists the M0 pauses and draws the paths."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import pytest

from galileo_cnc.cli.mill import run_mill_plot
from galileo_cnc.grbl.mill_plan import DRY_RUN_NOTE, dry_run_gcode
from galileo_cnc.cli.plot import PlotOptions
from galileo_cnc.config.profile import load_profile
from galileo_cnc.grbl.mill_plan import MillRequest
from galileo_cnc.grbl.mill_job import MILL_JOURNAL_NAME
from galileo_cnc.stream.journal import FINISHED, Journal

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "grbl"))
from grbl_support import QUICK_ACCEL, SETTINGS, grbl_elf  # noqa: E402
from mill_support import square_pad_board  # noqa: E402
from test_cli import galileo  # noqa: E402

#: the mill's [mill] options over the default profile: a probe, fast feeds, a thin board
MILL_SET = ("probe=true", "safe_height_mm=1", "feed_mm_min=4000", "plunge_feed_mm_min=2000",
            "board_thickness_mm=0.4", "breakthrough_mm=0.1", "tab_height_mm=0.2")
GRBL_URL = "simavr://?firmware=grbl&realtime=0&probe=0&" + "&".join(
    f"${number}={value}" for number, value in {**SETTINGS, **QUICK_ACCEL}.items())


@pytest.fixture
def board(tmp_path, monkeypatch):
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path / "home"))
    return square_pad_board(tmp_path / "board")


def plot_mill(board: Path, port: str, job: str, capsys, extra: tuple[str, ...] = ()
              ) -> tuple[int, str]:
    profile = dataclasses.replace(load_profile(None), port=port)
    code = run_mill_plot(PlotOptions(str(board), profile, yes=True,
                                     mill=MillRequest(job, MILL_SET + extra)))
    out, err = capsys.readouterr()
    return code, out + err


def test_plot_mill_drill_on_grbl_asks_for_the_bit_and_probes(board, capsys):
    grbl_elf()                      # built (or skipped with the missing package) first
    code, out = plot_mill(board, GRBL_URL, "drill", capsys)
    assert code == 0, out[-2000:]
    assert "board (--mill drill): 3 holes and slots with 0.8, 1 mm bits, 1 bit " \
           "change" in out
    assert out.count("paused for a bit change: put in the 1.000 mm bit") == 1
    assert "paused (M0): PROBE: clip the probe to the 1.000 mm bit" in out
    # the last hole (1.0 mm, at 3, 7) drilled, the tool up at the safe height
    assert "mill job finished; GRBL stands at X 3.000 Y 7.000 Z 1.000 mm (work)" in out


def test_plot_mill_with_a_height_map_probes_first_and_journals_the_map(board, tmp_path,
                                                                     capsys):
    """[mill] height_map = true: the grid over the cuts probed before the job (the
    user asked to clip the probe on, then to take it off), the isolation cut by the
    map, and the map kept with the job's journal for a resume."""
    grbl_elf()
    code, out = plot_mill(board, GRBL_URL, "isolate", capsys,
                          ("height_map=true", "height_map_spacing_mm=6"))
    assert code == 0, out[-2000:]
    assert out.index("height map: clip the probe to the tool; it probes 2 x 2 points") \
        < out.index("surface lies at Z 0.000..0.000 mm") \
        < out.index("height map probed: take the probe clip off the tool") \
        < out.index("mill job finished")
    journal = Journal(tmp_path / "home" / MILL_JOURNAL_NAME)
    entry = journal.load()
    assert entry.state == FINISHED and entry.height_map is not None
    kept = journal.height_map(entry)
    assert (len(kept.xs_nm), len(kept.ys_nm)) == (2, 2)
    assert {z for row in kept.z_nm for z in row} == {0}


def test_plot_mill_on_sim_is_a_dry_run_that_says_so(board, tmp_path):
    # as a user types it: the command line, its --mill options, the built-in machine
    result = galileo("plot", str(board), "--mill", "all", "--port", "sim://?speed=0", "--yes",
                     *(f"--mill-set={pair}" for pair in MILL_SET), home=tmp_path / "home")
    out = result.stdout + result.stderr
    assert result.returncode == 0, out[-2000:]
    assert DRY_RUN_NOTE in out
    assert out.count(": TOOL CHANGE: put in the ") == 3         # listed, not waited for
    assert "process has finished" in out


def test_dry_run_gcode_probes_at_the_plate_and_keeps_the_pauses_as_comments():
    text = ("M5\nM0 (TOOL CHANGE: put in the 1.000 mm bit)\nG38.2 Z-10 F600\nG92 Z0.5\n"
            "G0 Z2\n")
    assert dry_run_gcode(text) == (
        "M5\n(M0: TOOL CHANGE: put in the 1.000 mm bit)\n"
        "G1 Z0.5 F600 (G38.2: the probe touches the plate's top)\n"
        "(G92 Z0.5: the zero stays)\nG0 Z2\n")
