"""The vector preview (galileo_cnc/preview/svg.py), `preview -o out.svg` as a user
runs it (issue 31, item 15): well-formed SVG in mm, the strokes where the file draws,
a legend, a scale bar and the origin; in ink mode the copper and the two clips that
colour bare copper and ink outside it."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan.measure import job_lengths
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.preview.render import OUTSIDE, STROKE, UNINKED
from galileo_cnc.preview.svg import render_svg
from galileo_cnc.program.extents import extents
from galileo_cnc.program.ops import NM_PER_MM

ROOT = Path(__file__).resolve().parents[2]
SVG = "{http://www.w3.org/2000/svg}"
XLINK = "{http://www.w3.org/1999/xlink}href"
NUMBER = re.compile(r"-?\d+(?:\.\d+)?")


def points(data: str) -> np.ndarray:
    """The end points of the M and L commands of path data (no arcs in them)."""
    found = re.findall(r"[ML](-?\d+\.\d+) (-?\d+\.\d+)", data)
    return np.array(found, dtype=np.float64)


def by_id(root, name: str):
    return next(e for e in root.iter() if e.get("id") == name)


def test_preview_o_svg_writes_a_drawing_a_browser_zooms(tmp_path):
    out = tmp_path / "drawing.svg"
    done = subprocess.run([sys.executable, "-m", "galileo_cnc", "preview",
                           "samples/square-and-circle.nc", "-o", str(out)], cwd=ROOT,
                          env=dict(os.environ, GALILEO_CNC_NO_PROBE="1"),
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    # the pen-down length the PNG preview reads off the step trace (tests/cli/test_cli.py)
    assert ", 2 pen strokes, 111.4 mm drawn," in done.stdout
    root = ET.parse(out).getroot()                    # well-formed XML
    assert root.tag == f"{SVG}svg"
    assert root.get("width").endswith("mm") and root.get("height").endswith("mm")
    view = [float(v) for v in root.get("viewBox").split()]
    assert abs(view[2] - float(root.get("width")[:-2])) < 0.001       # 1 unit = 1 mm
    assert abs(view[3] - float(root.get("height")[:-2])) < 0.001
    # the strokes lie where the file draws, less the offset: the file's box in work mm
    planned = plan_file(ROOT / "samples" / "square-and-circle.nc", MachineConfig())
    box = extents(planned.program)
    ox, oy = planned.offset_nm
    strokes = points(by_id(root, "strokes").find(f"{SVG}path").get("d"))
    lo, hi = strokes.min(axis=0), strokes.max(axis=0)
    step_mm = 1 / MachineConfig().steps_per_mm
    assert np.allclose(lo, [(box[0] - ox) / NM_PER_MM, (box[1] - oy) / NM_PER_MM], atol=step_mm)
    assert np.allclose(hi, [(box[2] - ox) / NM_PER_MM, (box[3] - oy) / NM_PER_MM], atol=step_mm)
    assert by_id(root, "travel").get("d").startswith("M0.0000 0.0000L")   # from the origin
    ink = by_id(root, "ink")
    assert ink.get(XLINK) == "#strokes" and ink.get("color") == "#%02x%02x%02x" % STROKE
    # the origin: a cross at work (0, 0), named; the scale; the legend (no copper here)
    cross = by_id(root, "origin").find(f"{SVG}path").get("d")
    arm = -float(NUMBER.findall(cross)[0])
    assert cross == f"M{-arm:.3f} 0H{arm:.3f}M0 {-arm:.3f}V{arm:.3f}"
    texts = [t.text for t in root.iter(f"{SVG}text")]
    assert "origin X 0, Y 0 (work)" in texts
    assert re.fullmatch(r"\d+(\.\d+)? mm", by_id(root, "scale").find(f"{SVG}text").text)
    legend = [t.text for t in by_id(root, "legend").iter(f"{SVG}text")]
    assert legend == ["ink", "pen-up travel"]


def test_ink_mode_shows_bare_copper_and_ink_outside(tmp_path):
    board = ROOT / "samples" / "led-blinker.gbr"
    config = MachineConfig()
    planned = plan_file(board, config, options=PlanOptions(mode="ink", pens_nm=(1_000_000,)))
    out = tmp_path / "board.svg"
    info = render_svg(planned.program, planned.job, config, planned.offset_nm, out,
                      copper=planned.copper)
    assert info.copper and info.strokes > 0
    lengths = job_lengths(planned.job)             # what convert and info report
    assert abs(info.drawn_mm - lengths.drawn_steps / config.steps_per_mm) < 1e-6
    assert abs(info.travel_mm - lengths.travel_steps / config.steps_per_mm) < 1e-6
    root = ET.parse(out).getroot()
    legend = [t.text for t in by_id(root, "legend").iter(f"{SVG}text")]
    assert legend == ["ink", "bare copper", "ink outside the copper", "pen-up travel"]
    colours = [r.get("fill") for r in by_id(root, "legend").iter(f"{SVG}rect")]
    assert colours[:3] == ["#%02x%02x%02x" % c for c in (STROKE, UNINKED, OUTSIDE)]
    # the copper: where the file's copper is (apertures included), in work mm
    copper = points(by_id(root, "copper").get("d"))
    box = extents(planned.program, with_apertures=True)
    ox, oy = planned.offset_nm
    assert np.allclose(copper.min(axis=0), [(box[0] - ox) / 1e6, (box[1] - oy) / 1e6], atol=0.01)
    assert np.allclose(copper.max(axis=0), [(box[2] - ox) / 1e6, (box[3] - oy) / 1e6], atol=0.01)
    assert by_id(root, "bare-copper").get("fill") == "#%02x%02x%02x" % UNINKED
    # the strokes twice: clipped inside the copper, and outside it
    assert by_id(root, "ink").get("clip-path") == "url(#in-copper)"
    assert by_id(root, "ink-outside").get("clip-path") == "url(#off-copper)"
    outside = by_id(root, "off-copper").find(f"{SVG}path").get("d")
    assert outside.endswith(by_id(root, "copper").get("d"))   # the frame less the copper
    # 1 mm pen strokes: the pen's width in mm
    widths = {p.get("stroke-width") for p in by_id(root, "strokes").iter(f"{SVG}path")}
    assert widths == {"1.0000"}
