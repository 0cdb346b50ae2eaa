"""Previews of inked jobs (galileo_cnc/preview/render.py, docs/preview.md "Ink"): each
pen at its width, the copper left bare and the ink outside the copper."""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import Job, LineTo, PenDown
from galileo_cnc.machine import simulate
from galileo_cnc.machine.planner import JobSteps
from galileo_cnc.machine.timing import job_timing
from galileo_cnc.machine.trace import Trace
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.preview import render
from galileo_cnc.preview.artwork import PixelFrame
from galileo_cnc.preview.render import (OUTSIDE, STROKE, UNINKED, pen_stretches,
                                        render_preview)
from galileo_cnc.readers import read_file

REPO = Path(__file__).resolve().parents[2]
SAMPLES = REPO / "samples"
CONFIG = MachineConfig()
STEP_MM = CONFIG.nm_per_step / 1e6

# A 3 mm square pad at (5, 5) and a 0.2 mm trace from its right edge to x = 10,
# narrower than the 0.3 mm pen (so it is drawn as a centre line, overdrawn).
SQUARE_GERBER = """%FSLAX46Y46*%
%MOMM*%
%LPD*%
%ADD10R,3.000000X3.000000*%
%ADD11C,0.200000*%
D10*
X5000000Y5000000D03*
D11*
X6500000Y5000000D02*
X10000000Y5000000D01*
M02*
"""
# Program nm -> work: the square spans 1.5 .. 4.5 (x) and 3.5 .. 6.5 - 1 (y) mm of work,
# the trace runs along y = 4 from x = 4.5 to 8.
OFFSET = (2_000_000, 1_000_000)
SQUARE = (1.5, 2.5, 4.5, 5.5)
TRACE_Y, TRACE_END = 4.0, 8.0
PEN_R = 0.15
PX_PER_MM = 100            # 10 um pixels: the pens' 50 um overdraw is 5 px a side


def square_plan(tmp_path, pens):
    source = tmp_path / "square.gbr"
    source.write_text(SQUARE_GERBER)
    planned = plan_file(source, CONFIG, OFFSET, options=PlanOptions(mode="ink", pens_nm=pens))
    assert planned.ink is not None and planned.offset_nm == OFFSET
    return planned


def draw(planned, out, **options):
    """render_preview of a planned file with its job; the image and the info."""
    trace = options.pop("trace", None) or simulate(planned.job.commands, CONFIG)
    options.setdefault("px_per_mm", PX_PER_MM)
    options.setdefault("pygerber_limit", 0)
    info = render_preview(planned.program, trace, CONFIG, planned.offset_nm, out,
                          job=planned.job, **options)
    return info, np.asarray(Image.open(out).convert("RGB"))


def where(image, colour) -> np.ndarray:
    return np.all(image == np.asarray(colour, dtype=np.uint8), axis=-1)


def centres_mm(info, mask):
    """Work mm (x, y) of the pixel centres of a mask."""
    rows, cols = np.nonzero(mask)
    return (info.view_mm[0] + (cols + 0.5) / info.px_per_mm,
            info.view_mm[3] - (rows + 0.5) / info.px_per_mm)


def corner_distance(x, y):
    """Chebyshev distance (mm) from each point to the nearest corner of the square."""
    corners = [(SQUARE[i], SQUARE[j]) for i in (0, 2) for j in (1, 3)]
    return np.min([np.maximum(abs(x - cx), abs(y - cy)) for cx, cy in corners], axis=0)


def column_runs(mask_column) -> list[tuple[int, int]]:
    """(first, last) rows of each run of True in a column."""
    padded = np.concatenate(([0], mask_column.astype(np.int8), [0]))
    edges = np.diff(padded)
    return list(zip(np.flatnonzero(edges == 1).tolist(),
                    (np.flatnonzero(edges == -1) - 1).tolist()))


# Corners a round pen of radius r cannot reach: (4 - pi) r^2 for the four.
CORNERS_MM2 = (4 - math.pi) * PEN_R ** 2
# The trace's overdraw: (0.3 - 0.2) mm along its 3.5 mm, and the pen's half disc
# round its end beyond the trace's.
OVERDRAW_MM2 = (TRACE_END - SQUARE[2]) * (2 * PEN_R - 0.2) + math.pi * (PEN_R ** 2 - 0.1 ** 2) / 2


def check_classes(info, image, tolerance_mm: float, exact: bool):
    """Copper uninked only at the corners, ink outside only along the trace, and
    the numbers to match (pixels of 10 um: a row or column either side)."""
    px = 1 / info.px_per_mm
    bare, stray = where(image, UNINKED), where(image, OUTSIDE)
    # The uninked copper: in the corners, all four of them.
    x, y = centres_mm(info, bare)
    assert len(x) and corner_distance(x, y).max() <= PEN_R + px
    corners = {(bool(u > 3), bool(v > 4)) for u, v in zip(x, y)}
    assert len(corners) == 4
    # The ink outside: along the narrow trace, in its overdraw, nowhere else.
    x, y = centres_mm(info, stray)
    assert len(x)
    assert x.min() >= SQUARE[2] - px
    from_trace = np.hypot(np.maximum(x - TRACE_END, 0), y - TRACE_Y)  # its centre line
    assert from_trace.min() >= 0.1 - px and from_trace.max() <= PEN_R + px
    assert np.count_nonzero(stray) == pytest.approx(info.outside_mm2 * info.px_per_mm ** 2)
    assert np.count_nonzero(bare) == pytest.approx(info.uninked_mm2 * info.px_per_mm ** 2)
    # The overdraw beyond the tolerance on either side (whole rows of pixels), and
    # round the trace's end.
    side = math.floor((PEN_R - tolerance_mm - 0.1) / px + 0.5) * px
    assert info.outside_mm2 == pytest.approx(
        (TRACE_END - SQUARE[2]) * 2 * side
        + math.pi * (PEN_R ** 2 - (0.1 + tolerance_mm) ** 2) / 2, rel=0.05)
    if exact:
        assert info.uninked_mm2 == pytest.approx(CORNERS_MM2, rel=0.15)
    else:  # ink within a step of a corner's pixels counts: less of each corner
        assert 0.4 * CORNERS_MM2 < info.uninked_mm2 < CORNERS_MM2
    # Inside the square, away from the corners, every pixel is inked copper.
    rows, cols = np.indices(image.shape[:2])
    x, y = info.view_mm[0] + (cols + 0.5) * px, info.view_mm[3] - (rows + 0.5) * px
    inner = ((x > SQUARE[0] + px) & (x < SQUARE[2] - px) & (y > SQUARE[1] + px)
             & (y < SQUARE[3] - px) & (corner_distance(x, y) > PEN_R + px))
    assert np.all(where(image, STROKE)[inner])


@pytest.mark.parametrize("tolerance_nm", [0, None])
def test_one_pen_ink_over_the_copper(tmp_path, tolerance_nm):
    planned = square_plan(tmp_path, (300_000,))
    assert planned.job.pen_changes == {} and planned.job.pen_widths_nm == {1: 300_000}
    info, image = draw(planned, tmp_path / "ink.png", copper=planned.ink.copper,
                       ink_tolerance_nm=tolerance_nm)
    tolerance = 0.0 if tolerance_nm == 0 else STEP_MM
    check_classes(info, image, tolerance, exact=tolerance_nm == 0)
    # Across the trace (x = 6): the pen's 0.3 mm, of which the trace's 0.2 mm is
    # inked copper and the rest, less the tolerance, ink outside it.
    col, _ = info.pixel(6.0, TRACE_Y)
    inked = where(image, STROKE)[:, col] | where(image, OUTSIDE)[:, col]
    (top, bottom), = column_runs(inked)
    assert bottom - top + 1 == pytest.approx(2 * PEN_R * PX_PER_MM, abs=1)
    (top, bottom), = column_runs(where(image, STROKE)[:, col])
    assert bottom - top + 1 == pytest.approx((0.2 + 2 * tolerance) * PX_PER_MM, abs=1.5)
    line = info.summary()
    assert f"{info.uninked_mm2:.2f} mm² copper uninked, {info.outside_mm2:.2f} mm² ink " \
           "outside the copper" in line
    assert line.startswith(f"{info.width_px}x{info.height_px} px, artwork by galileo-cnc")


def test_two_pens_draw_at_their_widths(tmp_path):
    planned = square_plan(tmp_path, (800_000, 300_000))
    job = planned.job
    assert sorted(job.pen_changes.values()) == [1, 2]
    assert job.pen_widths_nm == {1: 800_000, 2: 300_000}
    info, image = draw(planned, tmp_path / "two.png", copper=planned.ink.copper,
                       ink_tolerance_nm=0)
    # The 0.8 mm pen fills the square to its edges, the 0.3 mm pen its corners and
    # the trace: the same classes as one 0.3 mm pen.
    check_classes(info, image, 0.0, exact=True)
    # Drawn with the 0.3 mm pen's width, the 0.8 mm pen's rings leave a band of
    # copper along every edge of the square.
    thin, _ = draw(planned, tmp_path / "thin.png", copper=planned.ink.copper,
                   ink_tolerance_nm=0, pen_widths_nm={1: 300_000, 2: 300_000})
    assert thin.uninked_mm2 > 0.5 > 10 * info.uninked_mm2
    # The wide pen's strokes: where it alone drew, the ink reaches 0.4 mm from its path.
    trace = simulate(job.commands, CONFIG)
    stretches = pen_stretches(job, CONFIG)
    assert stretches.keys[1:] == [1, 2]
    positions = trace.positions()
    events = np.vstack([[0, 0, 0], positions[np.r_[trace.tick[1:] != trace.tick[:-1], True]]])
    wide = events[stretches.first_event[1]:stretches.first_event[2]]
    wide = wide[wide[:, 2] <= CONFIG.pen_down_z_steps, :2] * STEP_MM
    # the leftmost point of the wide pen's path, on the square's left side
    x0 = wide[:, 0].min()
    assert x0 == pytest.approx(SQUARE[0] + 0.4, abs=STEP_MM)
    y0 = float(np.median(wide[wide[:, 0] == wide[:, 0].min(), 1]))
    col, row = info.pixel(x0, y0)
    left = where(image, STROKE)[row, :col + 1]
    assert col - np.flatnonzero(~left).max() == pytest.approx(0.4 * PX_PER_MM, abs=1.5)


def test_centre_mode_pens_at_their_apertures_widths(tmp_path):
    # Two apertures, two pens: a 0.8 mm line and a 0.3 mm line, each drawn as wide
    # as its pen (the job's pen_widths_nm), not at pen_width_mm.
    source = tmp_path / "two-lines.gbr"
    source.write_text("%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.800000*%\n%ADD11C,0.300000*%\n"
                      "D10*\nX1000000Y1000000D02*\nX9000000Y1000000D01*\n"
                      "D11*\nX1000000Y4000000D02*\nX9000000Y4000000D01*\nM02*\n")
    planned = plan_file(source, CONFIG, "auto", options=PlanOptions(mode="centre"))
    assert planned.job.pen_widths_nm == {10: 800_000, 11: 300_000}
    assert len(planned.job.pen_changes) == 2
    info, image = draw(planned, tmp_path / "lines.png", px_per_mm=50, artwork=False)
    assert info.uninked_mm2 is None and info.outside_mm2 is None
    assert "uninked" not in info.summary()
    ox, oy = (v / 1e6 for v in planned.offset_nm)
    col, _ = info.pixel(5 - ox, 0)
    runs = column_runs(where(image, STROKE)[:, col])
    assert len(runs) == 2
    heights = sorted(b - a + 1 for a, b in runs)
    assert heights == [pytest.approx(15, abs=1), pytest.approx(40, abs=1)]
    # a round pen's ends: the 0.8 mm line reaches 0.4 mm beyond its end points
    _, row = info.pixel(0, 1 - oy)
    drawn = np.flatnonzero(where(image, STROKE)[row])
    assert (drawn.min(), drawn.max()) == (pytest.approx(info.pixel(0.6 - ox, 0)[0], abs=1),
                                          pytest.approx(info.pixel(9.4 - ox, 0)[0], abs=1))


@pytest.mark.parametrize("source, options, offset", [
    ("square", PlanOptions(mode="ink", pens_nm=(800_000, 300_000)), OFFSET),
    (SAMPLES / "led-blinker.gbr", PlanOptions(mode="centre"), "auto"),
    (SAMPLES / "led-blinker.gbr", PlanOptions(mode="ink", pens_nm=(800_000, 400_000, 300_000)),
     (4_000_000, 3_000_000)),
])
def test_pen_stretches_match_the_timing_model(tmp_path, source, options, offset):
    # A pen's stretch begins at the first event of its pen-change command: the
    # trace's event right after the tick at which the timing model ends the
    # command before, tick for tick.
    if source == "square":
        source = tmp_path / "square.gbr"
        source.write_text(SQUARE_GERBER)
    job = plan_file(source, CONFIG, offset, options=options).job
    assert len(job.pen_changes) >= 2
    trace = simulate(job.commands, CONFIG)
    event_ticks = np.unique(trace.tick)          # event k >= 1 has tick event_ticks[k - 1]
    timing = job_timing(job.commands, CONFIG)
    stretches = pen_stretches(job, CONFIG)
    changes = sorted(job.pen_changes.items())
    assert stretches.keys[1:] == [key for _, key in changes]
    assert stretches.first_event[0] == 0
    for (command, _), first in zip(changes, stretches.first_event[1:].tolist()):
        end_before = int(timing.end_ticks[command - 1]) if command else 0
        # events up to and including the tick that ends command - 1 come before
        assert int(np.searchsorted(event_ticks, end_before, side="right")) == first - 1
        if command:
            assert event_ticks[first - 2] == end_before
        assert event_ticks[first - 1] > end_before


def test_pen_widths_need_the_job(tmp_path):
    program = read_file(SAMPLES / "led-blinker.gbr")
    with pytest.raises(ValueError, match="needs the job"):
        render_preview(program, Trace(np.zeros(0, np.int64), np.zeros(0, np.int8),
                                      np.zeros(0, np.int8), (0, 0, 0), 0),
                       CONFIG, (0, 0), tmp_path / "x.png", pen_widths_nm={10: 300_000})


@pytest.mark.parametrize("chunk", [97, 1 << 17])
def test_ink_is_the_same_whatever_the_chunks(tmp_path, monkeypatch, chunk):
    # Each pen's path continues across chunks: the same picture and numbers from a
    # trace in memory read in small chunks and from the job stepped as it is read.
    planned = square_plan(tmp_path, (800_000, 300_000))
    whole, whole_image = draw(planned, tmp_path / "whole.png", copper=planned.ink.copper,
                              px_per_mm=40)
    monkeypatch.setattr(render, "_CHUNK_STEPS", chunk)
    stepped, stepped_image = draw(planned, tmp_path / "stepped.png", px_per_mm=40,
                                  copper=planned.ink.copper,
                                  trace=JobSteps(planned.job.commands, CONFIG))
    assert np.array_equal(whole_image, stepped_image)
    assert (whole.strokes, whole.drawn_mm, whole.uninked_mm2, whole.outside_mm2) == \
        (stepped.strokes, stepped.drawn_mm, stepped.uninked_mm2, stepped.outside_mm2)


# ---- the copper, rasterised on the image's pixels ------------------------------------

def winding_inside(rings, x, y) -> np.ndarray:
    """Winding number > 0 of points (x, y) by brute force over every edge."""
    winding = np.zeros(x.shape, dtype=np.int64)
    for ring in rings:
        ring = np.asarray(ring, dtype=np.float64)
        for (x0, y0), (x1, y1) in zip(ring, np.roll(ring, -1, axis=0)):
            if y0 == y1:
                continue
            cross_x = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
            up = (y0 <= y) & (y < y1) & (cross_x > x)
            down = (y1 <= y) & (y < y0) & (cross_x > x)
            winding += up.astype(np.int64) - down
    return winding > 0


def test_copper_raster_holes_and_islands():
    # A square with a square hole holding a triangle island, and a lone slanted
    # quadrilateral; outers counter-clockwise, holes clockwise (pyclipper's form).
    rings = [
        [[0, 0], [9_000_000, 0], [9_000_000, 9_000_000], [0, 9_000_000]],
        [[2_000_000, 2_000_000], [2_000_000, 7_000_000], [7_000_000, 7_000_000],
         [7_000_000, 2_000_000]],
        [[3_000_000, 3_100_000], [6_300_000, 3_000_000], [4_100_000, 6_200_000]],
        [[10_000_000, 1_000_000], [12_300_000, 1_700_000], [11_900_000, 8_100_000],
         [10_400_000, 6_000_000]],
    ]
    offset = (-1_000_000, -500_000)
    view, scale, width, height = (0.0, 0.0, 14.3, 10.2), 7.3, 105, 75
    to_px = PixelFrame(view, scale)
    edges = render._copper_edges(rings, to_px, offset)
    got = np.vstack([render._copper_rows(edges, r0, min(height, r0 + 16), width)
                     for r0 in range(0, height, 16)])
    rows, cols = np.indices((height, width))
    x_nm = (view[0] + (cols + 0.5) / scale) * 1e6 + offset[0]
    y_nm = (view[3] - (rows + 0.5) / scale) * 1e6 + offset[1]
    assert got.any() and not got.all()
    assert np.array_equal(got, winding_inside(rings, x_nm, y_nm))


def test_copper_area_in_pixels(tmp_path):
    # The DarkImage and its pyclipper rings give the same pixels, whose area is the
    # copper's (within the pixels along its outline).
    planned = square_plan(tmp_path, (300_000,))
    copper = planned.ink.copper
    to_px = PixelFrame((0.0, 0.0, 12.0, 8.0), 50.0)
    pixels = []
    for given in (copper, copper.native):
        edges = render._copper_edges(render.copper_rings(given), to_px, planned.offset_nm)
        pixels.append(render._copper_rows(edges, 0, 400, 600))
    assert np.array_equal(*pixels)
    assert pixels[0].sum() / 50 ** 2 == pytest.approx(copper.area_nm2() / 1e12, rel=0.01)


def test_working_memory_stays_bounded_with_ink(tmp_path):
    # The memory test of test_render.py with a job and copper: 4 M steps of pen-down
    # zigzag over a copper rectangle; the ink adds a byte per pixel, not per step.
    n = 4_000_000
    k = np.arange(n)
    axis = np.where(k % 4040 < 4000, 0, 1).astype(np.int8)
    step = np.where((axis == 0) & (k // 4040 % 2 == 1), -1, 1).astype(np.int8)
    trace = Trace(k * 3, axis, step, (0, 0, 0), 3 * n)
    job = Job("zigzag", (0, 0), [PenDown(), LineTo(4000, 0)], [0, 1], [1, 1],
              pen_widths_nm={1: 300_000})
    copper = [[[0, 0], [20_000_000, 0], [20_000_000, 20_000_000], [0, 20_000_000]]]
    program = read_file(SAMPLES / "square-and-circle.nc")
    tracemalloc.start()
    try:
        info = render_preview(program, trace, CONFIG, (0, 0), tmp_path / "long.png",
                              artwork=False, job=job, copper=copper)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    pixels = info.width_px * info.height_px
    assert peak < 24 * 2 ** 20 + pixels, peak
    assert info.strokes == 1
    # The zigzag's rows are 0.25 mm apart: the 0.3 mm pen covers the copper it
    # crosses, and spills over it where it runs past y = 20 mm.
    assert info.uninked_mm2 < 0.05 * 20 * 20
    assert info.outside_mm2 > 0


# ---- the old call draws what it drew --------------------------------------------------

# The last commit of render.py before the ink; its renderer is the reference.
BEFORE_INK = "e74cf0cf08dccf688a80c74764b90ac8e3b4fc93"


def renderer_before_ink(tmp_path):
    try:
        text = subprocess.run(["git", "-C", str(REPO), "show",
                               f"{BEFORE_INK}:galileo_cnc/preview/render.py"],
                              capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("the repository's history is not available")
    path = tmp_path / "render_before_ink.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("render_before_ink", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    try:
        spec.loader.exec_module(module)
    finally:
        del sys.modules[spec.name]
    return module


@pytest.mark.parametrize("path, options", [
    ("led-blinker.gbr", {}),
    ("led-blinker.gbr", dict(pygerber_limit=0, pen_width_mm=0.3)),
    ("square-and-circle.nc", dict(px_per_mm=33, travel=False)),
])
def test_old_call_draws_as_before(tmp_path, path, options):
    before = renderer_before_ink(tmp_path)
    program = read_file(SAMPLES / path)
    offset = proposed_offset(program)
    trace = simulate(plan_program(program, CONFIG, offset).commands, CONFIG)
    old = before.render_preview(program, trace, CONFIG, offset, tmp_path / "old.png", **options)
    new = render_preview(program, trace, CONFIG, offset, tmp_path / "new.png", **options)
    assert np.array_equal(np.asarray(Image.open(tmp_path / "old.png")),
                          np.asarray(Image.open(tmp_path / "new.png")))
    assert new.summary() == old.summary()
    assert (new.strokes, new.stroke_box_mm, new.view_mm) == \
        (old.strokes, old.stroke_box_mm, old.view_mm)
    # lengths are now summed once per segment length (chunk-independent): same to 1e-12
    assert (new.drawn_mm, new.travel_mm) == pytest.approx((old.drawn_mm, old.travel_mm), rel=1e-12)
    assert new.uninked_mm2 is None and new.outside_mm2 is None
