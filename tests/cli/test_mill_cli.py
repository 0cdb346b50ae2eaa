"""`galileo-cnc convert FILE|BOARD --mill isolate -o out.nc` (issue 35): the isolation
passes of a copper layer as G-code, refused while islands lie closer than the cut
unless the user accepts them; `--mill-set` over the profile's [mill] table; a board's
bottom mirrored about the board's axis, as the plotter's bottom is."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np

from test_cli import galileo

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from boards import make_board  # noqa: E402

# two 1 mm pads 0.1 mm apart (closer than the 0.154 mm V-bit cut) and one far off
SHORTED = """%FSLAX46Y46*%
%MOMM*%
%ADD10C,1.0*%
D10*
X0Y0D03*
X1100000Y0D03*
X6000000Y0D03*
M02*
"""


def cut_points(path: Path) -> np.ndarray:
    """Every XY the tool reaches below the copper's top, in um (G1 moves at Z < 0)."""
    points, z, x, y = [], 2.0, None, None
    for line in path.read_text().splitlines():
        if line.startswith("("):
            continue
        words = dict(re.findall(r"([XYZ])(-?[\d.]+)", line))
        z = float(words.get("Z", z))
        x, y = float(words.get("X", x or 0)), float(words.get("Y", y or 0))
        if z < 0 and ("X" in words or "Y" in words):
            points.append((round(x * 1000), round(y * 1000)))
    return np.array(points, dtype=np.int64)


def test_shorts_refuse_the_file_until_accepted(tmp_path):
    layer = tmp_path / "shorted.gtl"
    layer.write_text(SHORTED)
    out = tmp_path / "iso.nc"
    refused = galileo("convert", str(layer), "--mill", "isolate", "-o", str(out))
    assert refused.returncode == 1 and not out.exists()
    assert "closer than the 0.154 mm cut" in refused.stderr
    assert "X0.550 Y0.000 mm" in refused.stderr and "--accept-shorts" in refused.stderr

    done = galileo("convert", str(layer), "--mill", "isolate", "--accept-shorts",
                   "--mill-set", "passes=2", "-o", str(out))
    assert done.returncode == 0, done.stderr
    text = out.read_text()
    assert "(short accepted:" in text and "2 pass[es]" in text
    assert text.count("G1 Z-0.1 F60") == int(re.search(r"(\d+) rings? round", done.stdout)[1])
    cuts = cut_points(out)
    # every cut point keeps half the cut (77 um) off both far pads' copper (0.5 mm radius)
    far = np.hypot(cuts[:, 0] - 6000, cuts[:, 1])
    assert far[far < 1000].min() >= 500 + 77


def test_a_mistyped_mill_key_is_named(tmp_path):
    result = galileo("convert", "samples/led-blinker.gbr", "--mill", "isolate",
                     "--mill-set", "pases=2", "-o", str(tmp_path / "x.nc"))
    assert result.returncode == 1
    assert "pases (did you mean passes?)" in result.stderr


def test_a_board_bottom_is_milled_mirrored_about_the_boards_axis(tmp_path):
    board = make_board(tmp_path / "board")
    bottom, raw = tmp_path / "bottom.nc", tmp_path / "raw.nc"
    for args, out in (((str(board), "--side", "bottom"), bottom),
                      ((str(board / "board-B_Cu.gbr"),), raw)):
        result = galileo("convert", *args, "--mill", "isolate", "-o", str(out))
        assert result.returncode == 0, result.stderr
    turned, plain = cut_points(bottom), cut_points(raw)
    # the axis: the outline's vertical centre line, X 6 mm; 2 um for Clipper's rounding
    assert abs(turned[:, 0].min() - (12_000 - plain[:, 0].max())) <= 2
    assert abs(turned[:, 0].max() - (12_000 - plain[:, 0].min())) <= 2
    assert abs(turned[:, 1].min() - plain[:, 1].min()) <= 2


def rapids(path: Path) -> list[tuple[float, float]]:
    """Where the tool goes at the safe height before each hole (G0 X.. Y..), mm."""
    return [tuple(float(v) for v in re.findall(r"[XY](-?[\d.]+)", line))
            for line in path.read_text().splitlines() if line.startswith("G0 X")]


def test_a_boards_holes_are_drilled_and_its_outline_cut_out_from_either_side(tmp_path):
    board = make_board(tmp_path / "board")
    top, bottom, edge = tmp_path / "top.nc", tmp_path / "bottom.nc", tmp_path / "edge.nc"
    for args, out in ((("--mill", "drill"), top),
                      (("--mill", "drill", "--side", "bottom"), bottom),
                      (("--mill", "cutout", "--mill-set", "tabs=2"), edge)):
        result = galileo("convert", str(board), *args, "-o", str(out))
        assert result.returncode == 0, result.stderr
    # the 0.8 mm holes with the default 0.8 mm bit: one plunge over each, the bottom's
    # turned over about X 6 mm
    holes = [(3.0, 3.0), (7.0, 3.0), (3.0, 7.0)]
    assert sorted(rapids(top)) == sorted(holes)
    assert sorted(rapids(bottom)) == sorted((12 - x, y) for x, y in holes)
    text = edge.read_text()
    assert "2 tabs" in result.stdout and "0.8 mm end mill" in result.stdout
    # the edge runs the end mill's radius (and a few um) outside the 12 mm square
    xs = [float(x) for x in re.findall(r"^G1 X(-?[\d.]+)", text, re.M)]
    assert -0.41 < min(xs) < -0.4 and 12.4 < max(xs) < 12.41

    alone = galileo("convert", str(board / "board-F_Cu.gbr"), "--mill", "drill",
                    "-o", str(tmp_path / "x.nc"))
    assert alone.returncode == 1 and "--mill drill needs a board" in alone.stderr
