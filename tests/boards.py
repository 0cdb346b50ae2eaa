"""A small double-sided board written by the tests (issue 32): what a KiCad export of
it holds, in a folder: both copper layers, the outline and a plated drill file, and
on request both sides' silkscreen."""

from __future__ import annotations

from pathlib import Path

_HEADER = "%FSLAX46Y46*%\n%MOMM*%\n%LPD*%\n"


def _gerber(function: str, body: str) -> str:
    return f"%TF.FileFunction,{function}*%\n{_HEADER}{body}M02*\n"


def _pads(points) -> str:
    return "D10*\n" + "".join(f"X{x * 10**6}Y{y * 10**6}D03*\n" for x, y in points)


def make_board(folder: Path, silk: bool = False) -> Path:
    """A 12 x 12 mm KiCad-style export: three 1.6 mm pads with 0.8 mm holes, a 3 mm
    pad and a trace on each side, the outline and a plated drill file (small: the
    firmware in simavr runs both sides); with `silk`, both sides' silkscreen too
    (SILK_DOTS_MM: their dots off the copper, board mm)."""
    folder.mkdir()
    if silk:
        write_silk(folder)
    pads = [(3, 3), (7, 3), (3, 7)]
    # a 3 mm pad wants the 0.8 mm pen, the rings round the holes the 0.3 mm one: both
    # pens on each side
    apertures = "%ADD10C,1.600000*%\n%ADD11C,0.250000*%\n%ADD13R,3.000000X3.000000*%\n"
    big = "D13*\nX8500000Y8500000D03*\n"
    (folder / "board-F_Cu.gbr").write_text(_gerber(
        "Copper,L1,Top", apertures + _pads(pads) + big + "D11*\nX3000000Y3000000D02*\n"
        "X7000000Y3000000D01*\n"))
    (folder / "board-B_Cu.gbr").write_text(_gerber(
        "Copper,L2,Bot", apertures + _pads(pads) + big + "D11*\nX3000000Y3000000D02*\n"
        "X3000000Y7000000D01*\n"))
    (folder / "board-Edge_Cuts.gbr").write_text(_gerber(
        "Profile,NP", "%ADD12C,0.100000*%\nD12*\nX0Y0D02*\nX12000000Y0D01*\n"
        "X12000000Y12000000D01*\nX0Y12000000D01*\nX0Y0D01*\n"))
    (folder / "board-PTH.drl").write_text(
        "M48\n; #@! TF.FileFunction,Plated,1,2,PTH\nFMAT,2\nMETRIC\nT1C0.800\n%\nG90\nG05\nT1\n"
        + "".join(f"X{x}.0Y{y}.0\n" for x, y in pads) + "M30\n")
    return folder


#: each side's silk dot that lies off the copper (board mm): where the pen puts it down
SILK_DOTS_MM = {"top": (1.0, 11.0), "bottom": (10.5, 1.0)}


def write_silk(folder: Path) -> None:
    """Both sides' silkscreen: on the top a diagonal across two pads (cut away near
    them), an arc, a dot off the copper and one on a pad (left out); on the bottom a
    line, a dot off the copper and a line across the 3 mm pad."""
    apertures = "%ADD10C,0.150000*%\n%ADD11C,0.400000*%\n"
    top = ("D10*\nX1000000Y1000000D02*\nX11000000Y11000000D01*\n"
           "G75*\nX9500000Y2000000D02*\nG03X11500000Y2000000I1000000J0D01*\nG01*\n"
           "D11*\nX1000000Y11000000D03*\nX3000000Y7000000D03*\n")
    bottom = ("D10*\nX1000000Y10500000D02*\nX5000000Y10500000D01*\n"
              "X6000000Y8500000D02*\nX11000000Y8500000D01*\n"
              "D11*\nX10500000Y1000000D03*\n")
    (folder / "board-F_SilkS.gbr").write_text(_gerber("Legend,Top", apertures + top))
    (folder / "board-B_SilkS.gbr").write_text(_gerber("Legend,Bot", apertures + bottom))
