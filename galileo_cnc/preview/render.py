"""Preview images: what the machine will plot, over a rendering of the artwork.

`render_preview` draws, in work coordinates (mm, Y up):

1. the artwork (artwork.py): pygerber's raster of the Gerber file where pygerber
   reads it (small files only, it is slow), else our own light rendering of the
   Program with Pillow ("galileo"); for G-code, its own drawn paths;
2. pen-up travel as thin grey lines and pen-down strokes in dark blue, both
   rebuilt from the reference machine's step trace, so the picture shows what
   the machine does, not what the file says.

Artwork coordinates are the file's (nm); subtracting `offset_nm` gives work
coordinates, the frame the job and its trace use (docs/preview.md).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np
from PIL import Image, ImageDraw

from galileo_cnc.preview.artwork import (BACKGROUND, DEFAULT_PYGERBER_LIMIT, PixelFrame,
                                         artwork_box, draw_program, paste_pygerber)
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine.trace import Trace
from galileo_cnc.program.ops import Program

# Colours (RGB): strong strokes over the light artwork (artwork.ART), so both stay readable.
STROKE = (20, 40, 160)          # dark blue
TRAVEL = (190, 190, 190)        # light grey

DEFAULT_PX_PER_MM = 20.0
DEFAULT_MAX_PX = 4000
# Trace events between the points used for the drawn length: long enough that
# the one-step staircase of a slanted line adds < 0.5 %, short enough to follow
# small arcs.
_LENGTH_SAMPLE = 16


@dataclass(frozen=True)
class PreviewInfo:
    """What was drawn. Boxes are (xmin, ymin, xmax, ymax) in work mm."""

    path: str
    width_px: int
    height_px: int
    px_per_mm: float
    renderer: str                 # "pygerber", "galileo" or "none" (no artwork)
    strokes: int                  # pen-down strokes (a flash counts as one dot)
    drawn_mm: float               # pen-down path length
    travel_mm: float              # pen-up XY path length
    stroke_box_mm: tuple[float, float, float, float] | None
    view_mm: tuple[float, float, float, float]   # the area the image shows
    notes: list[str] = field(default_factory=list)  # e.g. why pygerber was not used

    def summary(self) -> str:
        """One line for the user: size, artwork renderer, what the pen drew."""
        art = {"pygerber": "artwork by pygerber", "galileo": "artwork by galileo-cnc",
               "none": "no artwork"}.get(self.renderer, self.renderer)
        why = f" ({'; '.join(self.notes)})" if self.notes else ""
        return (f"{self.width_px}x{self.height_px} px, {art}{why}, {self.strokes} pen strokes, "
                f"{self.drawn_mm:.1f} mm drawn")

    def pixel(self, x_mm: float, y_mm: float) -> tuple[int, int]:
        """(column, row) of the pixel showing work point (x_mm, y_mm)."""
        col = (x_mm - self.view_mm[0]) * self.px_per_mm
        row = (self.view_mm[3] - y_mm) * self.px_per_mm
        return int(math.floor(col)), int(math.floor(row))


def render_preview(program: Program, trace: Trace, config: MachineConfig,
                   offset_nm: tuple[int, int], out_path: str | os.PathLike, *,
                   start: tuple[int, int, int] = (0, 0, 0),
                   px_per_mm: float = DEFAULT_PX_PER_MM, max_px: int = DEFAULT_MAX_PX,
                   margin_mm: float = 2.0, pen_width_mm: float = 0.15,
                   artwork: bool = True, travel: bool = True,
                   pygerber_limit: int = DEFAULT_PYGERBER_LIMIT) -> PreviewInfo:
    """Draw the trace's pen strokes over the artwork and save the image (PNG etc.).

    `trace` must be the run of the job planned from `program` with `offset_nm`,
    starting from work position `start` (steps). `pygerber_limit` is the largest
    Gerber file (bytes) handed to pygerber; 0 never uses it.
    """
    notes: list[str] = []
    path = _head_path(trace, start, config)
    # The artwork's box and the head path decide the view and the scale.
    parsed, art_box = (artwork_box(program, offset_nm, pygerber_limit, notes)
                       if artwork else (None, None))

    view, scale, size = _view(path.xy_mm, art_box, px_per_mm, max_px, margin_mm)
    canvas = Image.new("RGB", size, BACKGROUND)
    to_px = PixelFrame(view, scale)

    renderer = "none"
    if artwork:
        if parsed is not None:
            try:
                paste_pygerber(canvas, parsed, to_px, offset_nm)
                renderer = "pygerber"
            except Exception as problem:  # pygerber has many ways to fail; fall back
                notes.append(f"pygerber could not render: {type(problem).__name__}: {problem}")
        if renderer == "none" and len(program):
            draw_program(ImageDraw.Draw(canvas), program, to_px, offset_nm)
            renderer = "galileo"

    draw = ImageDraw.Draw(canvas)
    if travel:
        _draw_runs(draw, to_px, path, path.travel_runs, TRAVEL, 1)
    pen_px = max(1, round(pen_width_mm * scale))
    _draw_runs(draw, to_px, path, path.stroke_runs, STROKE, pen_px)
    canvas.save(out_path)

    return PreviewInfo(str(out_path), size[0], size[1], scale, renderer,
                       len(path.stroke_runs), path.length_mm(path.stroke_runs),
                       path.length_mm(path.travel_runs), path.stroke_box(), view, notes)


# ---- the head path, from the trace -----------------------------------------------

@dataclass
class _HeadPath:
    """Head positions at the end of every trace event (steps sharing a tick), with
    index 0 the start; runs are (first, last) event indices, inclusive."""

    xy_mm: np.ndarray         # (E, 2) float, work mm
    stroke_runs: np.ndarray   # (S, 2) pen-down runs that draw (a line or a dot)
    travel_runs: np.ndarray   # (T, 2) pen-up runs that move in XY

    def length_mm(self, runs: np.ndarray) -> float:
        """Path length over `runs`, sampling every _LENGTH_SAMPLE-th event so that
        step staircases do not count as extra length."""
        if not len(runs):
            return 0.0
        index, run_id = _run_members(runs)
        offset = index - runs[run_id, 0]
        keep = (offset % _LENGTH_SAMPLE == 0) | (index == runs[run_id, 1])
        points, ids = self.xy_mm[index[keep]], run_id[keep]
        same = ids[1:] == ids[:-1]
        return float(np.hypot(*(points[1:] - points[:-1])[same].T).sum())

    def stroke_box(self) -> tuple[float, float, float, float] | None:
        if not len(self.stroke_runs):
            return None
        index, _ = _run_members(self.stroke_runs)
        pts = self.xy_mm[index]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))


def _run_members(runs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All event indices covered by `runs`, and the run each belongs to."""
    lengths = runs[:, 1] - runs[:, 0] + 1
    run_id = np.repeat(np.arange(len(runs)), lengths)
    index = np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths, lengths) \
        + runs[run_id, 0]
    return index, run_id


def _runs(mask: np.ndarray) -> np.ndarray:
    """(first, last) index of every run of True in `mask`."""
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    return np.stack([np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1], axis=1)


def _head_path(trace: Trace, start: tuple[int, int, int], config: MachineConfig) -> _HeadPath:
    # One point per event: X and Y steps of a diagonal share a tick, and the
    # intermediate corner between them is not a place the pen really goes.
    last_of_tick = np.ones(len(trace), dtype=bool)
    last_of_tick[:-1] = trace.tick[1:] != trace.tick[:-1]
    # Cumulative sums per axis in int32 (positions are far inside its range):
    # a third of the memory of Trace.positions for the multi-million-step jobs.
    step = trace.dir.astype(np.int32)
    points = np.empty((int(last_of_tick.sum()) + 1, 3), dtype=np.int64)
    points[0] = start
    for axis in range(3):
        moved_axis = np.where(trace.axis == axis, step, np.int32(0))
        points[1:, axis] = start[axis] + np.cumsum(moved_axis, dtype=np.int32)[last_of_tick]
    down = points[:, 2] <= config.pen_down_z_steps
    moves = np.zeros(len(points), dtype=bool)     # event k changed X or Y
    moves[1:] = np.any(points[1:, :2] != points[:-1, :2], axis=1)
    moved_before = np.cumsum(moves)

    def moved(runs: np.ndarray) -> np.ndarray:   # XY moved within the run
        return moved_before[runs[:, 1]] - moved_before[runs[:, 0]] > 0

    pen_down = _runs(down)
    # A run at the start that never moves is the pen resting where the machine
    # began (it lifts before travelling), not a dot the job makes.
    keep = moved(pen_down) | (pen_down[:, 0] > 0)
    pen_up = _runs(~down)
    # An up run's first event may be the lift; include the point before it so a
    # travel line starts where the stroke ended.
    pen_up = pen_up[moved(pen_up)]
    pen_up[:, 0] = np.maximum(pen_up[:, 0] - 1, 0)
    xy_mm = points[:, :2] / config.steps_per_mm
    return _HeadPath(xy_mm, pen_down[keep], pen_up)


# ---- view and pixels ---------------------------------------------------------------

def _view(xy_mm: np.ndarray, art_box, px_per_mm: float, max_px: int, margin_mm: float):
    """View box (work mm), scale (px/mm) and image size: everything plus a margin,
    at `px_per_mm` unless that would exceed `max_px` on a side."""
    lo, hi = xy_mm.min(axis=0), xy_mm.max(axis=0)
    xmin, ymin, xmax, ymax = float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])
    if art_box is not None:
        xmin, ymin = min(xmin, art_box[0]), min(ymin, art_box[1])
        xmax, ymax = max(xmax, art_box[2]), max(ymax, art_box[3])
    xmin, ymin, xmax, ymax = xmin - margin_mm, ymin - margin_mm, xmax + margin_mm, ymax + margin_mm
    span = max(xmax - xmin, ymax - ymin, 1.0)
    scale = float(px_per_mm)
    if span * scale > max_px:
        scale = max_px / span
        # Whole px/mm keep pygerber's raster (integer dots per mm) unscaled.
        scale = float(math.floor(scale)) if scale >= 1 else scale
    size = (max(1, math.ceil((xmax - xmin) * scale)), max(1, math.ceil((ymax - ymin) * scale)))
    # Grow the box to the whole pixels so pixel() and the image agree.
    view = (xmin, ymax - size[1] / scale, xmin + size[0] / scale, ymax)
    return view, scale, size


def _draw_runs(draw: ImageDraw.ImageDraw, to_px: PixelFrame, path: _HeadPath, runs: np.ndarray,
               colour, width: int) -> None:
    """Each run as one polyline, thinned to the points that change pixel; a run
    without XY movement (a flash) as a dot."""
    if not len(runs):
        return
    col, row = to_px.xy(path.xy_mm[:, 0], path.xy_mm[:, 1])
    pix = np.stack([np.rint(col), np.rint(row)], axis=1)
    change = np.ones(len(pix), dtype=bool)
    change[1:] = np.any(pix[1:] != pix[:-1], axis=1)
    change[runs[:, 0]] = change[runs[:, 1]] = True
    kept = np.flatnonzero(change)
    lo = np.searchsorted(kept, runs[:, 0])
    hi = np.searchsorted(kept, runs[:, 1], side="right")
    dot = max(2.0, width)  # a flash: bigger than the pen so it shows
    for a, b in zip(lo.tolist(), hi.tolist()):
        pts = pix[kept[a:b]]
        if len(pts) > 1 and np.any(pts != pts[0]):
            draw.line(pts.ravel().tolist(), fill=colour, width=width, joint="curve")
        else:
            x, y = pts[0].tolist()
            draw.ellipse((x - dot, y - dot, x + dot, y + dot), fill=colour)
