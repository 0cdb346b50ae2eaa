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
