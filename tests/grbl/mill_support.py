"""A board the mill tests run on GRBL (tests/grbl/test_mill_grbl.py, tests/cli/
test_plot_mill.py): small, with two drill sizes, and quick for GRBL to plan."""

from __future__ import annotations

from pathlib import Path

_HEADER = "%FSLAX46Y46*%\n%MOMM*%\n%LPD*%\n"


def _gerber(function: str, body: str) -> str:
    return f"%TF.FileFunction,{function}*%\n{_HEADER}{body}M02*\n"


def square_pad_board(folder: Path) -> Path:
    """A 10 x 10 mm board: three 1.6 mm square pads (isolation rings of a few corners:
    GRBL plans a block in 3.5 ms, a round pad's chords would be most of the job), two
    0.8 mm holes and a 1.0 mm one (two bits), the outline."""
    folder.mkdir()
    pads = ((3, 3), (7, 3), (3, 7))
    (folder / "board-F_Cu.gbr").write_text(_gerber(
        "Copper,L1,Top", "%ADD10R,1.600000X1.600000*%\nD10*\n"
        + "".join(f"X{x * 10**6}Y{y * 10**6}D03*\n" for x, y in pads)))
    (folder / "board-Edge_Cuts.gbr").write_text(_gerber(
        "Profile,NP", "%ADD12C,0.100000*%\nD12*\nX0Y0D02*\nX10000000Y0D01*\n"
        "X10000000Y10000000D01*\nX0Y10000000D01*\nX0Y0D01*\n"))
    (folder / "board-PTH.drl").write_text(
        "M48\n; #@! TF.FileFunction,Plated,1,2,PTH\nFMAT,2\nMETRIC\nT1C0.800\nT2C1.000\n%\n"
        "G90\nG05\nT1\nX3.0Y3.0\nX7.0Y3.0\nT2\nX3.0Y7.0\nM30\n")
    return folder
