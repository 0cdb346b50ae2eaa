"""Open traces said as one summary by every command, and a plot that would leave
trace pieces out refused unless --allow-open (issue 31, item 11): what a user with
0.3 mm pens meets on a board of tight traces."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from galileo_cnc.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
HEADER = "%FSLAX46Y46*%\n%MOMM*%\nG75*\n"
# three pairs of 0.15 mm traces of different islands, 0.31 mm centre to centre: with
# a 0.3 mm pen the shorter of each pair is left out beside the longer, 4 mm each
PAIR = "X0Y{y}D02*\nX10000000Y{y}D01*\nX2000000Y{q}D02*\nX6000000Y{q}D01*\n"
SUMMARY = ("open traces: 3 trace pieces left out, 12 mm in all, the longest 4 mm (at {board}:9:1): "
           "the 0.3 mm pen's ink would join another copper island there; a pen of 0.25 mm "
           "or thinner (--pens) would draw every trace of this board")


@pytest.fixture
def board(tmp_path) -> Path:
    path = tmp_path / "tight.gbr"
    path.write_text(HEADER + "%ADD11C,0.15*%\nD11*\n" + "".join(
        PAIR.format(y=k * 2_000_000, q=k * 2_000_000 + 310_000) for k in range(3)) + "M02*\n")
    return path


def galileo(*args, home: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, GALILEO_CNC_NO_PROBE="1", GALILEO_CNC_HOME=str(home))
    return subprocess.run([sys.executable, "-m", "galileo_cnc", *map(str, args)], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=120)


def test_plot_refuses_a_board_with_open_traces_unless_allowed(board, tmp_path):
    done = galileo("plot", board, "--pens", "0.3", "--port", "sim://?speed=0", "--yes",
                   home=tmp_path)
    assert done.returncode == 1
    assert done.stderr == f"galileo-cnc: {SUMMARY.format(board=board)}. plot --allow-open " \
                          "plots it so\n"
    assert "connected" not in done.stdout            # refused before the machine opened
    done = galileo("plot", board, "--pens", "0.3", "--port", "sim://?speed=0", "--yes",
                   "--allow-open", home=tmp_path)
    assert done.returncode == 0, done.stderr
    assert SUMMARY.format(board=board) in done.stdout.splitlines()
    assert "would join the ink of line" not in done.stdout   # no line per piece
    assert "process has finished" in done.stdout
    # the pen the summary names draws it whole: nothing to refuse
    done = galileo("plot", board, "--pens", "0.25", "--port", "sim://?speed=0", "--yes",
                   home=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "open traces" not in done.stdout


def test_preview_convert_and_info_say_the_summary(board, tmp_path, capsys, monkeypatch):
    # in this process (main), not a child each: five commands
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))      # no profile of the user
    summary = SUMMARY.format(board=board)

    def said(*args) -> str:
        assert main([*map(str, args)]) == 0
        return capsys.readouterr().out

    for command, output in (("preview", "p.png"), ("convert", "p.nc")):
        out = said(command, board, "--pens", "0.3", "-o", tmp_path / output)
        assert out.splitlines()[-1] == summary
    text = said("info", board, "--pens", "0.3")
    assert f"  {summary}" in text.splitlines()
    assert "would join the ink of line" not in text
    every = said("info", board, "--pens", "0.3", "--verbose")
    assert every.count("would join the ink of line") == 3 and summary in every
    figures = json.loads(said("info", board, "--pens", "0.3", "--json"))["ink"]["open_traces"]
    assert figures["pieces"] == 3 and figures["total_mm"] == 12.0
    assert figures["longest_mm"] == 4.0 and 0.25 <= figures["widest_pen_mm"] < 0.3
