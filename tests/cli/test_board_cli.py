"""A board on the command line (issue 32): `info BOARD` names every file's role and
why, `--layer FILE=ROLE` places a file; a real subprocess on a real KiCad export (the
corpus's flashpads board: its Gerber folder and its drill folder, as KiCad writes them
into one)."""

from __future__ import annotations

import json
import shutil

import pytest

from corpus import CORPUS
from test_cli import galileo

BOARD = "kicad/flashpads-x2ap"


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    """The board's folder as the user exported it: copper, mask, paste, silk, outline
    and both drill files side by side."""
    folder = tmp_path_factory.mktemp("flashpads")
    for source in (CORPUS / BOARD, CORPUS / "drill" / BOARD):
        for path in sorted(source.iterdir()):       # the curated corpus has both
            if not path.name.startswith("UPSTREAM"):
                shutil.copy(path, folder / path.name)
    return folder


def test_info_names_every_file_of_a_board_with_its_role(board):
    result = galileo("info", str(board), "--json")
    assert result.returncode == 0, result.stderr
    layers = {layer["file"]: layer for layer in json.loads(result.stdout)["board"]["layers"]}
    assert layers["Flashpads-F_Cu.gbr"]["role"] == "top-copper"
    assert layers["Flashpads-B_Cu.gbr"]["role"] == "bottom-copper"
    assert layers["Flashpads-Edge_Cuts.gbr"]["role"] == "outline"
    assert layers["Flashpads-PTH.drl"]["role"] == "drill-plated"
    assert layers["Flashpads-NPTH.drl"]["role"] == "drill-unplated"
    assert "X2" in layers["Flashpads-F_Cu.gbr"]["why"]
    text = galileo("info", str(board)).stdout
    assert "Flashpads-F_Cu.gbr" in text and "top-copper" in text


def test_layer_places_a_file_and_a_wrong_role_is_named(board):
    moved = galileo("info", str(board), "--json", "--layer", "Flashpads-F_Paste.gbr=other")
    assert moved.returncode == 0, moved.stderr
    layers = {layer["file"]: layer["role"] for layer in json.loads(moved.stdout)["board"]["layers"]}
    assert layers["Flashpads-F_Paste.gbr"] == "other"
    wrong = galileo("info", str(board), "--layer", "Flashpads-F_Paste.gbr=top-coper")
    assert wrong.returncode != 0
    assert "top-coper" in wrong.stderr and "Traceback" not in wrong.stderr
    axis = galileo("convert", str(board), "--mirror-axis", "z=3", "-o", "/dev/null")
    assert axis.returncode != 0 and "Traceback" not in axis.stderr
    assert "--mirror-axis: expected x=MM or y=MM" in axis.stderr
    lone = galileo("convert", str(board / "Flashpads-F_Cu.gbr"), "--silk", "-o", "/dev/null")
    assert lone.returncode != 0 and "Traceback" not in lone.stderr
    assert "--outline, --silk and --layer are for a board" in lone.stderr


def test_plot_both_sides_lands_the_bottom_holes_on_the_top_ones_and_inks_no_mark(tmp_path):
    # The steps of `plot BOARD --side top` and `--side bottom` (sim://, --trace): the
    # pen never comes down within a pen radius of a drill mark's edge on either side,
    # and the bottom's marks, turned over about the axis, are the top's.
    import re

    import numpy as np

    from galileo_cnc.config.machine import MachineConfig
    from galileo_cnc.machine import Trace
    from boards import make_board

    board = make_board(tmp_path / "board")
    config = MachineConfig()                       # one 0.4 mm pen
    holes_mm = [(3, 3), (7, 3), (3, 7)]
    seen = {}
    for side in ("top", "bottom"):
        trace = tmp_path / f"{side}.npz"
        result = galileo("plot", str(board), "--side", side, "--port", "sim://?speed=0",
                         "--yes", "--trace", str(trace))
        assert result.returncode == 0, result.stderr
        line = re.search(rf"{side} side, .* vertical line X 6\.0000 mm \(board\), X "
                         rf"(-?[\d.]+) mm on the machine \(work\)", result.stdout)
        offset = re.search(r"offset (-?[\d.]+), (-?[\d.]+) mm", result.stdout)
        assert line and offset, result.stdout
        ox, oy = float(offset.group(1)), float(offset.group(2))
        seen[side] = (ox, oy, float(line.group(1)))
        where = Trace.load(trace).positions()
        down = where[where[:, 2] == config.pen_down_z_steps][:, :2] / config.steps_per_mm
        for x, y in holes_mm:
            x = 12 - x if side == "bottom" else x          # mirrored about X 6 mm
            nearest = np.hypot(down[:, 0] - (x - ox), down[:, 1] - (y - oy)).min()
            # the 0.3 mm mark's edge, the 0.4 mm pen's radius, 20 um of clearance
            assert nearest >= 0.15 + 0.2 + 0.02 - 1 / config.steps_per_mm, (side, x, y)
    assert seen["top"] == seen["bottom"]           # one offset, one axis on the machine


def test_convert_and_preview_of_a_side(tmp_path):
    import re

    # with the outline and the silk: each after the copper and a pen change that names
    # it, and the silk left off the copper said in mm (tests/plan/test_board_lines.py)
    from boards import make_board

    board = make_board(tmp_path / "board", silk=True)
    gcode = tmp_path / "bottom.nc"
    converted = galileo("convert", str(board), "--side", "bottom", "--outline", "--silk",
                        "-o", str(gcode))
    assert converted.returncode == 0, converted.stderr
    text = gcode.read_text()
    assert "; bottom side, mirrored about the vertical line X 6.0000 mm (board)" in text
    assert text.index("insert the 0.4 mm pen") < text.index("insert the outline pen (0.4 mm)") \
        < text.index("insert the silk pen (0.4 mm)")
    # the line across the 3 mm pad: the pad and 0.25 mm each side (and up to 30 um of
    # the keep-out's tolerance, board_lines.KEEP_OUT_TOLERANCE_NM)
    cut = re.search(r"--silk: ([\d.]+) mm of the silk left out within 0\.250 mm of copper",
                    converted.stderr)
    assert cut and 3.5 <= float(cut.group(1)) <= 3.56, converted.stderr
    picture = tmp_path / "bottom.png"
    previewed = galileo("preview", str(board), "--side", "bottom", "--outline", "--silk",
                        "-o", str(picture))
    assert previewed.returncode == 0, previewed.stderr
    assert "a board's bottom side is drawn mirrored" in previewed.stdout
    assert picture.stat().st_size > 0

