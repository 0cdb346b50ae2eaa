"""Preview images: what the machine will plot, over a rendering of the artwork.

`render_preview` draws, in work coordinates (mm, Y up):

1. the artwork (artwork.py): pygerber's raster of the Gerber file where pygerber
   reads it (small files only, it is slow), else our own light rendering of the
   Program with Pillow ("galileo"); for G-code, its own drawn paths;
2. pen-up travel as thin grey lines and pen-down strokes in dark blue, both
   rebuilt from the reference machine's step trace, so the picture shows what
   the machine does, not what the file says;
3. given the `job`, each pen's strokes at that pen's width (round ends, a flash
   as the pen's disc); given the `copper` as well (an ink plan's), the copper the
   ink leaves bare and the ink outside the copper in colours of their own, with
   their areas in PreviewInfo (docs/preview.md, "Ink"); a board's outline and silk
   pens (`pen_roles`) in colours of their own (LINE_COLOURS), not counted as ink
   outside the copper: they are drawn off it on purpose (docs/boards.md).

Artwork coordinates are the file's (nm); subtracting `offset_nm` gives work
coordinates, the frame the job and its trace use (docs/preview.md).

Traces run to tens of millions of steps: they are read in chunks (_CHUNK_STEPS),
never turned into whole-trace position or pixel arrays, so the memory a preview
adds is the image and a few MB, whatever the trace's length.
"""

from __future__ import annotations

import math
import os
from typing import Union
from dataclasses import dataclass, field

import numpy as np
from PIL import Image, ImageDraw

from galileo_cnc.preview.artwork import (BACKGROUND, DEFAULT_PYGERBER_LIMIT, PixelFrame,
                                         artwork_box, draw_program, paste_pygerber)
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import ArcTo, Flash, Job, LineTo, PenDown
from galileo_cnc.machine.blocks import Pause
from galileo_cnc.machine.planner import JobSteps, ReferenceMachine
from galileo_cnc.machine.trace import Trace
from galileo_cnc.preview.job_path import JobPath
from galileo_cnc.program.ops import NM_PER_MM, Program

#: a step trace in memory, one stepped piece by piece as it is read, or the job's
#: path from its commands (JobPath: no stepping)
Steps = Union[Trace, JobSteps, JobPath]

# Colours (RGB): strong strokes over the light artwork (artwork.ART), so both stay readable.
STROKE = (20, 40, 160)          # dark blue
TRAVEL = (190, 190, 190)        # light grey
UNINKED = (255, 120, 0)         # orange: copper the ink leaves bare
OUTSIDE = (220, 0, 200)         # magenta: ink outside the copper
DRILL_MARK = (255, 255, 255)    # white: a drill mark the ink leaves bare, as the hole will be
#: a board's outline and silkscreen pens (plan/board_lines.py): green and ochre
LINE_COLOURS = {"outline": (0, 140, 70), "silk": (200, 150, 0)}

DEFAULT_PX_PER_MM = 20.0
DEFAULT_MAX_PX = 4000


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
    # Given the copper (mm², counted in pixels of the image; None without copper):
    uninked_mm2: float | None = None    # copper no stroke covers
    outside_mm2: float | None = None    # strokes outside the copper

    def summary(self) -> str:
        """One line for the user: size, artwork renderer, what the pen drew (and,
        with copper, what it left bare and drew outside)."""
        art = {"pygerber": "artwork by pygerber", "galileo": "artwork by galileo-cnc",
               "none": "no artwork"}.get(self.renderer, self.renderer)
        why = f" ({'; '.join(self.notes)})" if self.notes else ""
        ink = ""
        if self.uninked_mm2 is not None:
            ink = (f", {self.uninked_mm2:.2f} mm² copper uninked, "
                   f"{self.outside_mm2:.2f} mm² ink outside the copper")
        return (f"{self.width_px}x{self.height_px} px, {art}{why}, {self.strokes} pen strokes, "
                f"{self.drawn_mm:.1f} mm drawn{ink}")

    def pixel(self, x_mm: float, y_mm: float) -> tuple[int, int]:
        """(column, row) of the pixel showing work point (x_mm, y_mm)."""
        col = (x_mm - self.view_mm[0]) * self.px_per_mm
        row = (self.view_mm[3] - y_mm) * self.px_per_mm
        return int(math.floor(col)), int(math.floor(row))


def render_preview(program: Program, trace: Steps, config: MachineConfig,
                   offset_nm: tuple[int, int], out_path: str | os.PathLike, *,
                   start: tuple[int, int, int] = (0, 0, 0),
                   px_per_mm: float = DEFAULT_PX_PER_MM, max_px: int = DEFAULT_MAX_PX,
                   margin_mm: float = 2.0, pen_width_mm: float = 0.15,
                   artwork: bool = True, travel: bool = True,
                   pygerber_limit: int = DEFAULT_PYGERBER_LIMIT,
                   job: Job | None = None, pen_widths_nm: dict[int, int] | None = None,
                   copper=None, ink_tolerance_nm: int | None = None,
                   marks=None, pen_roles: dict[int, str] | None = None) -> PreviewInfo:
    """Draw the trace's pen strokes over the artwork and save the image (PNG etc.).

    `trace` must be the run of the job planned from `program` with `offset_nm`,
    starting from work position `start` (steps). `pygerber_limit` is the largest
    Gerber file (bytes) handed to pygerber; 0 never uses it.

    The trace is read in chunks of _CHUNK_STEPS steps, twice: once for the view
    and the pen-up/pen-down runs, once to draw (docs/preview.md, "Cost").

    Ink (docs/preview.md, "Ink"): given `job` (the job `trace` is the run of), each
    pen-down run is drawn as the pen inks it: at the width of the pen in the holder
    (`pen_widths_nm`, pen key -> nm, by default `job.pen_widths_nm`; `pen_width_mm`
    for a pen of width 0 or unknown), round, a flash as the pen's disc. `copper`
    (an ink plan's `DarkImage`, or a pyclipper polygon set; program nm, like the
    artwork) paints the copper no stroke covers in UNINKED and the strokes outside
    it in OUTSIDE, and fills in `uninked_mm2` and `outside_mm2`; misses and spills
    within `ink_tolerance_nm` (default one motor step) are not counted. `marks` (a
    board's drill marks, a pyclipper polygon set in program nm) are painted in
    DRILL_MARK where no stroke covers them, and are not counted as bare copper.
    `pen_roles` (pen key -> "outline" | "silk", PlannedFile.pen_roles): those pens'
    strokes are painted in LINE_COLOURS over the rest, and are neither ink outside
    the copper nor ink over it.
    """
    if pen_widths_nm is not None and job is None:
        raise ValueError("pen_widths_nm needs the job: it says which pen draws when")
    as_inked = job is not None or copper is not None
    notes: list[str] = []
    sample = getattr(trace, "length_sample", _LENGTH_SAMPLE)
    runs = _scan_runs(trace, start, config)
    # The artwork's box and the head path decide the view and the scale.
    parsed, art_box = (artwork_box(program, offset_nm, pygerber_limit, notes)
                       if artwork else (None, None))

    spm = config.steps_per_mm
    view, scale, size = _view(runs.lo_steps / spm, runs.hi_steps / spm, art_box,
                              px_per_mm, max_px, margin_mm)
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

    # Travel goes straight onto the canvas; strokes onto a mask painted over it at
    # the end, so one pass draws both and the strokes still cover the travel.
    if as_inked:
        # each pen's sweep, exactly (_SweepPainter): one painter per pen width
        ink = np.zeros((size[1], size[0]), dtype=np.uint8)
        default_nm = round(pen_width_mm * NM_PER_MM)
        keys = [None] * len(runs.strokes) if job is None else \
            pen_stretches(job, config, start, trace).key_at(runs.strokes[:, 0])
        widths = np.full(len(runs.strokes), default_nm, dtype=np.int64) if job is None else \
            _stroke_widths_nm(keys, default_nm,
                              job.pen_widths_nm if pen_widths_nm is None else pen_widths_nm)
        # the outline's and silk's strokes on masks of their own, painted over the ink
        roles = np.array([(pen_roles or {}).get(key, "") for key in keys], dtype=object)
        lines = {role: np.zeros_like(ink) for role in set(roles.tolist()) - {""}}
        pens = sorted(set(zip(widths.tolist(), roles.tolist()))) or [(default_nm, "")]
        strokes = [_SweepPainter(runs.strokes[(widths == w) & (roles == role)],
                                 lines.get(role, ink), w / 2 / NM_PER_MM * scale, to_px, spm,
                                 sample)
                   for w, role in pens]
    else:
        stroke_mask = Image.new("L", size, 0)
        pen_px = max(1, round(pen_width_mm * scale))
        strokes = [_RunPainter(runs.strokes, ImageDraw.Draw(stroke_mask), 255, pen_px,
                               box=True, length_sample=sample)]
    travels = _RunPainter(runs.travel, ImageDraw.Draw(canvas) if travel else None, TRAVEL, 1,
                          length_sample=sample)
    previous = None                         # pixel of the event before the chunk
    for first, x, y in _events(trace, start, axes=2):
        col, row = to_px.xy(x / spm, y / spm)
        col, row = np.rint(col), np.rint(row)
        change = np.empty(len(col), dtype=bool)   # the event is in another pixel
        change[1:] = (col[1:] != col[:-1]) | (row[1:] != row[:-1])
        change[0] = previous is None or (col[0], row[0]) != previous
        previous = (col[-1], row[-1])
        for painter in (*strokes, travels):
            painter.feed(first, x, y, col, row, change)
    uninked = outside = None
    if as_inked:
        outlines = None
        if copper is not None:
            tolerance = config.nm_per_step if ink_tolerance_nm is None else ink_tolerance_nm
            outlines = _copper_outlines(copper, to_px, offset_nm, max(0, int(tolerance)))
        mark_edges = _copper_edges(copper_rings(marks), to_px, offset_nm) if marks else None
        bare, stray = _paint_ink(canvas, ink, outlines, mark_edges)
        if copper is not None:
            uninked, outside = bare / scale ** 2, stray / scale ** 2
        for role, mask in sorted(lines.items()):
            canvas.paste(LINE_COLOURS.get(role, STROKE), (0, 0) + size, Image.fromarray(mask))
        del ink, lines
    else:
        canvas.paste(STROKE, (0, 0) + size, stroke_mask)
    canvas.save(out_path)

    boxes = [b for b in (p.box_mm(spm) for p in strokes) if b is not None]
    box = (min(b[0] for b in boxes), min(b[1] for b in boxes),
           max(b[2] for b in boxes), max(b[3] for b in boxes)) if boxes else None
    drawn = sum(p.length_steps for p in strokes) / spm
    return PreviewInfo(str(out_path), size[0], size[1], scale, renderer,
                       len(runs.strokes), drawn, travels.length_steps / spm, box, view, notes,
                       uninked, outside)


# ---- which pen draws when ------------------------------------------------------------

@dataclass(frozen=True)
class PenStretches:
    """The pens of a job along its trace: pen `keys[k]` is in the holder from trace
    event `first_event[k]` (event 0 is the start, event n the head after the n-th
    tick) to the next stretch. `keys[k]` is None before the first pen is known."""

    first_event: np.ndarray        # int64, increasing, first_event[0] == 0
    keys: list[int | None]

    def key_at(self, events: np.ndarray) -> list[int | None]:
        """The pen in the holder at each of the trace events `events`."""
        at = np.searchsorted(self.first_event, np.asarray(events), side="right") - 1
        return [self.keys[k] for k in at.tolist()]


_DRAWING = (PenDown, LineTo, ArcTo, Flash)


def pen_stretches(job: Job, config: MachineConfig, start: tuple[int, int, int] = (0, 0, 0),
                  path=None) -> PenStretches:
    """Which pen is in the holder at which trace event, for the trace of `job` stepped
    from work position `start` by the reference machine.

    A pen change stops the job before command c (job.pen_changes), so the new pen's
    stretch begins at the first event of command c: 1 + the events of commands
    0 .. c-1. Each planned move of n events makes n events of the trace, each with a
    tick of its own (the timing model, machine/timing.py, counts them the same way:
    the trace's tick of event 1 + events before c is the timing's start of command
    c, tick for tick; tests/preview/test_ink.py checks it). The commands are planned
    on a reference machine from one change to the next, up to the last change (no
    stepping: memory is one stretch's planned moves). Before the first change, the
    pen is the aperture of the first drawing command (a job with one pen has no
    change at all).

    Given the job's `path` as a JobPath, its own count of events is used instead:
    it knows each command's first event without planning."""
    changes = sorted(job.pen_changes.items())
    first_change = changes[0][0] if changes else len(job.commands)
    initial = next((job.aperture[k] for k in range(min(first_change, len(job.commands)))
                    if isinstance(job.commands[k], _DRAWING)), None)
    firsts, keys = [0], [initial]
    if isinstance(path, JobPath):
        at = path.stretch_firsts([command for command, _ in changes])
        return PenStretches(np.asarray(firsts + at.tolist(), dtype=np.int64),
                            keys + [key for _, key in changes])
    machine = ReferenceMachine(config, start)
    done, events = 0, 0
    for command, key in changes:
        events += sum(item.n for item in machine.plan(job.commands[done:command])
                      if not isinstance(item, Pause))
        done = command
        firsts.append(1 + events)
        keys.append(key)
    return PenStretches(np.asarray(firsts, dtype=np.int64), keys)


def _stroke_widths_nm(keys: list[int | None], default_nm: int,
                      widths_nm: dict[int, int]) -> np.ndarray:
    """Pen width (nm) of each stroke run, given the pen in the holder at its first
    event (`keys`, PenStretches.key_at); `default_nm` for a pen of width 0 or unknown."""
    width = {key: int(widths_nm.get(key) or 0) for key in set(keys)}
    return np.array([width[key] if width[key] > 0 else default_nm for key in keys],
                    dtype=np.int64)


# ---- ink over copper -------------------------------------------------------------------
#
# The copper is rasterised here, band of rows by band, on the image's own pixel grid
# (a pixel is copper when its centre is inside, by the positive winding rule of the
# polygon set), and compared with the same rows of the ink mask: no copper mask of
# the whole image is ever held.

# Cells (rows x (columns + 1)) of one band's winding accumulator: 8 MB of float64.
_BAND_CELLS = 1 << 20


def _paint_ink(canvas: Image.Image, ink: np.ndarray, outlines,
               mark_edges=None) -> tuple[int, int]:
    """Paint the strokes (`ink`, 255 where inked) in STROKE and, given the copper's
    `outlines` (_copper_outlines), the copper no stroke covers in UNINKED and the
    strokes outside the copper in OUTSIDE, but for the pixels within the tolerance
    of the copper's outline; given the drill marks' edges, the marks no stroke
    covers in DRILL_MARK (not bare copper); a band of rows at a time. (uninked
    pixels, outside pixels)."""
    width, height = canvas.size
    band = max(1, _BAND_CELLS // (width + 1))
    uninked = outside = 0
    for r0 in range(0, height, band):
        r1 = min(height, r0 + band)
        inked = ink[r0:r1] != 0
        paint = [(STROKE, inked)]
        if outlines is not None:
            inner, outer = (_copper_rows(edges, r0, r1, width) for edges in outlines)
            bare, stray = inner & ~inked, inked & ~outer
            if mark_edges is not None:
                marked = _copper_rows(mark_edges, r0, r1, width) & ~inked
                bare &= ~marked
                paint.append((DRILL_MARK, marked))
            uninked += int(np.count_nonzero(bare))
            outside += int(np.count_nonzero(stray))
            paint += [(UNINKED, bare), (OUTSIDE, stray)]
        for colour, mask in paint:
            if mask.any():
                canvas.paste(colour, (0, r0, width, r1), Image.fromarray(mask))
    return uninked, outside


def _copper_outlines(copper, to_px, offset_nm, tolerance_nm: int):
    """The edges (_copper_edges) of the copper shrunk and grown by the tolerance:
    bare copper counts inside the first, ink outside the copper outside the second,
    so a miss or a spill of less than the tolerance (the planner's edge margin, a
    step's rounding) is neither."""
    from galileo_cnc.plan.ink import clip     # pyclipper: only previews with copper need it

    rings = copper_rings(copper)
    if tolerance_nm <= 0:
        edges = _copper_edges(rings, to_px, offset_nm)
        return edges, edges
    rings = clip.clean(rings, tolerance_nm)
    return (_copper_edges(clip.offset_mitred(rings, -tolerance_nm), to_px, offset_nm),
            _copper_edges(clip.offset_mitred(rings, tolerance_nm), to_px, offset_nm))


def copper_rings(copper) -> list:
    """The rings of a DarkImage (its pyclipper set, or shells and holes of another
    backend's) or of a pyclipper polygon set."""
    native = getattr(copper, "native", copper)
    if isinstance(native, list):
        return [ring for ring in native if len(ring) >= 3]
    return [ring for shell, holes in copper.polygons() for ring in (shell, *holes)]


def _copper_edges(rings: list, to_px, offset_nm) -> np.ndarray:
    """(E, 5) float64: the edges of the rings (program nm) that cross a row of pixel
    centres, in pixel coordinates, as (top row, bottom row, column at the top,
    columns per row, winding): +1 going down the image (a counter-clockwise ring's
    left side)."""
    ox, oy = offset_nm
    parts = []
    for ring in rings:
        points = np.asarray(ring, dtype=np.float64).reshape(-1, 2)
        if len(points) < 3:
            continue
        col, row = to_px.xy((points[:, 0] - ox) / NM_PER_MM, (points[:, 1] - oy) / NM_PER_MM)
        c0, r0 = col, row
        c1, r1 = np.roll(col, -1), np.roll(row, -1)
        down = r1 > r0
        top, bottom = np.where(down, r0, r1), np.where(down, r1, r0)
        crosses = np.ceil(top) < np.ceil(bottom)          # some centre row in [top, bottom)
        top_col = np.where(down, c0, c1)
        slope = (np.where(down, c1, c0) - top_col)[crosses] / (bottom - top)[crosses]
        parts.append(np.stack([top[crosses], bottom[crosses], top_col[crosses], slope,
                               np.where(down, 1.0, -1.0)[crosses]], axis=1))
    return np.concatenate(parts) if parts else np.zeros((0, 5))


def _copper_rows(edges: np.ndarray, r0: int, r1: int, width: int) -> np.ndarray:
    """(r1 - r0, width) bool: pixels of rows r0 .. r1-1 whose centre is inside the
    copper (winding number > 0). Each edge crosses the rows of centres in
    [top, bottom); a crossing at column x adds its winding to the pixels from
    ceil(x) rightwards."""
    first = np.maximum(np.ceil(edges[:, 0]), r0).astype(np.int64)
    stop = np.minimum(np.ceil(edges[:, 1]), r1).astype(np.int64)
    here = stop > first
    if not here.any():
        return np.zeros((r1 - r0, width), dtype=bool)
    first, stop, edge = first[here], stop[here], edges[here]
    count = stop - first
    which = np.repeat(np.arange(len(first)), count)
    row = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) + first[which]
    column = edge[which, 2] + (row - edge[which, 0]) * edge[which, 3]
    at = np.clip(np.ceil(column), 0, width).astype(np.int64)
    winding = np.bincount((row - r0) * (width + 1) + at, weights=edge[which, 4],
                          minlength=(r1 - r0) * (width + 1))
    inside = np.cumsum(winding.reshape(r1 - r0, width + 1), axis=1)[:, :width]
    return inside > 0.5


# ---- the head path, from the trace -----------------------------------------------
#
# Events are the steps sharing a tick (a diagonal step goes straight, not round the
# corner): event 0 is the start, event k the head position after the k-th tick.
# Positions are integer steps; whole-trace arrays are never built: multi-million-
# step jobs are read in chunks, and only the runs (a few per pen lift) are kept.

# Trace steps per chunk: a few MB of temporaries (smaller chunks are no faster).
_CHUNK_STEPS = 1 << 17
# Trace events between the points used for the drawn length: long enough that
# the one-step staircase of a slanted line adds < 0.5 %, short enough to follow
# small arcs.
_LENGTH_SAMPLE = 16


def _events(trace: Steps, start: tuple[int, int, int], axes: int = 3):
    """(index of the first event, x, y[, z]) per chunk of events, positions in
    int32 steps; the first chunk is event 0 (the start) alone. `axes=2` leaves Z out."""
    if isinstance(trace, JobPath):
        yield from trace.events(start, axes)
        return
    at = [int(v) for v in start[:axes]]
    yield 0, *(np.array([v], dtype=np.int32) for v in at)
    count = 1
    for tick, axis, step in _pieces(trace):
        # an event ends at the last step of its tick; a piece ends with an event
        ends = np.ones(len(tick), dtype=bool)
        ends[:-1] = tick[1:] != tick[:-1]
        position = []
        for k in range(axes):
            walked = np.cumsum(np.where(axis == k, step, np.int8(0)), dtype=np.int32)
            here = walked[ends]
            here += at[k]
            at[k] += int(walked[-1])
            position.append(here)
        if len(position[0]):
            yield count, *position
            count += len(position[0])


def _pieces(trace: Steps):
    """Pieces of at most about _CHUNK_STEPS steps, each ending with an event."""
    for tick, axis, step in trace.pieces(_CHUNK_STEPS):
        if len(tick) <= 2 * _CHUNK_STEPS:
            yield tick, axis, step
        else:                                   # a large piece of a JobSteps: cut it
            yield from Trace(tick, axis, step, (0, 0, 0), 0).pieces(_CHUNK_STEPS)


@dataclass
class _Runs:
    """The head path's extent and its runs: (first, last) event indices, inclusive."""

    lo_steps: np.ndarray      # (2,) x, y minimum over all events
    hi_steps: np.ndarray      # (2,) x, y maximum
    strokes: np.ndarray       # (S, 2) pen-down runs that draw (a line or a dot)
    travel: np.ndarray        # (T, 2) pen-up runs that move in XY, from the event before


def _scan_runs(trace: Steps, start: tuple[int, int, int], config: MachineConfig) -> _Runs:
    """First pass over the trace: extent, pen-down and pen-up runs.

    The pen is down while Z is at or below config.pen_down_z_steps. A run "moves"
    when X or Y changes at an event after its first.
    """
    lo = np.array(start[:2], dtype=np.int64)
    hi = lo.copy()
    firsts, downs, moved_at_first, moved_before_first = [], [], [], []
    prev_xy, prev_down, moved_so_far = None, None, 0   # the event before the chunk
    for first, x, y, z in _events(trace, start):
        lo = np.minimum(lo, (x.min(), y.min()))
        hi = np.maximum(hi, (x.max(), y.max()))
        down = z <= config.pen_down_z_steps
        moves = np.empty(len(x), dtype=bool)            # XY changed at the event
        moves[1:] = (x[1:] != x[:-1]) | (y[1:] != y[:-1])
        moves[0] = prev_xy is not None and (int(x[0]), int(y[0])) != prev_xy
        moved = moved_so_far + np.cumsum(moves, dtype=np.int64)   # moves up to the event
        new_run = np.empty(len(x), dtype=bool)
        new_run[1:] = down[1:] != down[:-1]
        new_run[0] = prev_down is None or bool(down[0]) != prev_down
        at = np.flatnonzero(new_run)
        firsts.append(at + first)
        downs.append(down[at])
        moved_at_first.append(moved[at])
        before = np.concatenate(([moved_so_far], moved[:-1]))   # up to the event before
        moved_before_first.append(before[at])
        prev_xy, prev_down = (int(x[-1]), int(y[-1])), bool(down[-1])
        moved_so_far = int(moved[-1])
        last_event = first + len(x) - 1
    first = np.concatenate(firsts)
    down = np.concatenate(downs)
    last = np.append(first[1:] - 1, last_event)
    moved_at_last = np.append(np.concatenate(moved_before_first)[1:], moved_so_far)
    moves = moved_at_last - np.concatenate(moved_at_first) > 0
    runs = np.stack([first, last], axis=1)
    # A pen-down run at the start that never moves is the pen resting where the
    # machine began (it lifts before travelling), not a dot the job makes.
    strokes = runs[down & (moves | (first > 0))]
    # An up run's first event may be the lift; include the point before it so a
    # travel line starts where the stroke ended.
    travel = runs[~down & moves]
    travel[:, 0] = np.maximum(travel[:, 0] - 1, 0)
    return _Runs(lo, hi, strokes, travel)


def _run_members(runs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All indices covered by `runs` (inclusive ranges), and the run each belongs to."""
    lengths = runs[:, 1] - runs[:, 0] + 1
    run_id = np.repeat(np.arange(len(runs)), lengths)
    index = np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths, lengths) \
        + runs[run_id, 0]
    return index, run_id


class _RunPainter:
    """One kind of run (disjoint, in order), fed the events chunk by chunk: draws
    each run as one polyline thinned to the points that change pixel (a run that
    stays in one pixel, e.g. a flash, as a dot), adds up its length and, with
    `box`, the extent of its points.

    A run crossing chunks is drawn in pieces; each piece starts with the last two
    points of the one before, so every segment and every joint of the whole
    polyline is drawn (Pillow draws no caps): the pixels are those of drawing it
    in one go. Nothing of a run is drawn until one of its points leaves its first
    pixel (a dot, until then).
    """

    def __init__(self, runs: np.ndarray, draw: ImageDraw.ImageDraw | None, colour, width: int,
                 box: bool = False, length_sample: int = _LENGTH_SAMPLE):
        self.first, self.last = runs[:, 0], runs[:, 1]
        self.length_sample = length_sample
        self.draw, self.colour, self.width = draw, colour, width
        # squared segment length (integer steps^2) -> count: the sum is taken once, in
        # key order, so the length does not depend on how the trace was chunked
        self._squared_lengths: dict[int, int] = {}
        self.want_box, self.lo, self.hi = box, None, None   # extent (x, y steps)
        self._sample = None    # (run, x, y): the last length sample so far
        self._open = None      # (run, last two points, first point, left its pixel)

    def box_mm(self, steps_per_mm: float):
        if self.lo is None:
            return None
        return (float(self.lo[0] / steps_per_mm), float(self.lo[1] / steps_per_mm),
                float(self.hi[0] / steps_per_mm), float(self.hi[1] / steps_per_mm))

    def feed(self, first: int, x, y, col, row, change) -> None:
        """Events first .. first + len(x) - 1: positions (steps), pixels, and
        whether each is in another pixel than the event before."""
        end = first + len(x)
        a = int(np.searchsorted(self.last, first))           # runs overlapping the chunk
        b = int(np.searchsorted(self.first, end))
        if a >= b:
            return
        local = np.stack([np.maximum(self.first[a:b], first),
                          np.minimum(self.last[a:b], end - 1)], axis=1) - first
        index, run = _run_members(local)
        run += a
        event = index + first
        starts, stops = event == self.first[run], event == self.last[run]
        self._length(x, y, index, run, event, stops)
        if self.want_box:
            xs, ys = x[index], y[index]
            lo, hi = (xs.min(), ys.min()), (xs.max(), ys.max())
            self.lo = lo if self.lo is None else np.minimum(self.lo, lo)
            self.hi = hi if self.hi is None else np.maximum(self.hi, hi)
        if self.draw is not None:
            keep = change[index] | starts | stops
            kept = index[keep]
            self._paint(self._points(x, y, col, row, kept), run[keep], end)

    def _points(self, x, y, col, row, kept) -> np.ndarray:
        """The kept events as the points to draw: their pixels."""
        return np.stack([col[kept], row[kept]], axis=1).astype(np.float32)

    @property
    def length_steps(self) -> float:
        return math.fsum(count * math.sqrt(value)
                         for value, count in sorted(self._squared_lengths.items()))

    def _length(self, x, y, index, run, event, stops) -> None:
        """Length over samples every `length_sample` events from each run's first,
        and its last, so step staircases do not count as extra length (a JobPath's
        events are its vertices: all of them count)."""
        take = ((event - self.first[run]) % self.length_sample == 0) | stops
        pick = index[take]
        xs, ys, ids = x[pick].astype(np.int64), y[pick].astype(np.int64), run[take]
        if self._sample is not None:
            r, sx, sy = self._sample
            xs, ys, ids = np.append(sx, xs), np.append(sy, ys), np.append(r, ids)
        if len(ids):
            same = ids[1:] == ids[:-1]
            squared = np.diff(xs)[same] ** 2 + np.diff(ys)[same] ** 2
            values, counts = np.unique(squared, return_counts=True)
            for value, count in zip(values.tolist(), counts.tolist()):
                self._squared_lengths[value] = self._squared_lengths.get(value, 0) + count
            self._sample = (ids[-1], xs[-1], ys[-1])

    def _paint(self, points: np.ndarray, run: np.ndarray, end: int) -> None:
        if not len(run):      # a run going on through the chunk within one pixel
            return
        cuts = np.flatnonzero(run[1:] != run[:-1]) + 1
        for lo, hi in zip([0, *cuts.tolist()], [*cuts.tolist(), len(run)]):
            r = int(run[lo])
            piece = points[lo:hi]
            if self._open is not None and self._open[0] == r:
                _, tail, origin, left = self._open
                piece = np.concatenate([tail, piece])
            else:
                origin, left = piece[0].copy(), False
            left = left or bool(np.any(piece != origin))
            if left and len(piece) > 1:
                flat = piece.ravel()
                # Pillow reads a float32 buffer directly; its curve joints (wide
                # pens only) need Python numbers.
                self.draw.line(flat.tolist() if self.width > 4 else flat, fill=self.colour,
                               width=self.width, joint="curve")
            if self.last[r] < end:                    # the run ends in this chunk
                self._open = None
                if not left:                          # a flash: bigger than the pen
                    dot = max(2.0, self.width)
                    x0, y0 = float(origin[0]), float(origin[1])
                    self.draw.ellipse((x0 - dot, y0 - dot, x0 + dot, y0 + dot), fill=self.colour)
            else:
                self._open = (r, piece[-2:].copy(), origin, left)


class _SweepPainter(_RunPainter):
    """Strokes as a round pen of `radius_px` inks them: 255 in `ink` (rows x columns,
    uint8) at the pixels whose centre is within the radius of the path. The path is
    the run's events thinned to those that change pixel, as for _RunPainter, but at
    their exact positions (Pillow would put them on whole pixels and draw a whole
    number of pixels wide, the odd one on a side that depends on the direction). A
    run's path continues across chunks from its last point; a run of one point is
    the pen's disc."""

    def __init__(self, runs: np.ndarray, ink: np.ndarray, radius_px: float,
                 to_px: PixelFrame, steps_per_mm: float, length_sample: int = _LENGTH_SAMPLE):
        super().__init__(runs, ink, 255, 0, box=True, length_sample=length_sample)
        self.radius, self.to_px, self.spm = float(radius_px), to_px, steps_per_mm

    def _points(self, x, y, col, row, kept) -> np.ndarray:
        c, r = self.to_px.xy(x[kept] / self.spm, y[kept] / self.spm)
        return np.stack([c, r], axis=1)

    def _paint(self, points: np.ndarray, run: np.ndarray, end: int) -> None:
        if not len(run):
            return
        starts, ends = [], []
        cuts = np.flatnonzero(run[1:] != run[:-1]) + 1
        for lo, hi in zip([0, *cuts.tolist()], [*cuts.tolist(), len(run)]):
            r = int(run[lo])
            piece = points[lo:hi]
            if self._open is not None and self._open[0] == r:
                piece = np.concatenate([self._open[1], piece])
            if len(piece) > 1:
                starts.append(piece[:-1])
                ends.append(piece[1:])
            else:                                     # a dot, so far
                starts.append(piece)
                ends.append(piece)
            self._open = None if self.last[r] < end else (r, piece[-1:].copy())
        _sweep(self.draw, *_short_segments(np.concatenate(starts), np.concatenate(ends)),
               self.radius)


#: _sweep tests a box of pixels around each segment: a longer one (a JobPath's
#: vertices, not a trace's steps) is cut into pieces at most this long (pixels).
_SWEEP_PIECE_PX = 2.0


def _short_segments(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segments a[k]-b[k] cut into pieces of at most _SWEEP_PIECE_PX."""
    pieces = np.maximum(1, np.ceil(np.hypot(*(b - a).T) / _SWEEP_PIECE_PX)).astype(np.int64)
    if np.all(pieces == 1):
        return a, b
    which = np.repeat(np.arange(len(a)), pieces)
    k = np.arange(len(which)) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    step = (b - a)[which] / pieces[which, None]
    start = a[which] + step * k[:, None]
    return start, start + step


# Candidate pixels tested at once by _sweep: some 20 MB of temporaries.
_SWEEP_BATCH = 1 << 18


def _sweep(ink: np.ndarray, a: np.ndarray, b: np.ndarray, radius: float) -> None:
    """Set to 255 the pixels of `ink` whose centre is within `radius` of a segment
    a[k]-b[k] (pixel coordinates, centres at integers). Each segment's box of pixels
    is tested; boxes of one size are tested together (the thinned paths' segments
    are a pixel or two long, so there are few sizes), a batch at a time."""
    height, width = ink.shape
    lo = np.ceil(np.minimum(a, b) - radius).astype(np.int64)
    hi = np.floor(np.maximum(a, b) + radius).astype(np.int64)
    np.maximum(lo, 0, out=lo)
    np.minimum(hi, (width - 1, height - 1), out=hi)
    span = hi - lo + 1
    inside = (span > 0).all(axis=1)
    if not inside.any():
        return
    a, b, lo, span = a[inside], b[inside], lo[inside], span[inside]
    flat = ink.reshape(-1)
    sizes, group = np.unique(span, axis=0, return_inverse=True)
    group = group.reshape(-1)
    for g, (columns, rows) in enumerate(sizes.tolist()):
        members = np.flatnonzero(group == g)
        per_batch = max(1, _SWEEP_BATCH // (columns * rows))
        for first in range(0, len(members), per_batch):
            k = members[first:first + per_batch]
            col = lo[k, 0, None, None] + np.arange(columns)[None, None, :]
            row = lo[k, 1, None, None] + np.arange(rows)[None, :, None]
            ax, ay = a[k, 0, None, None], a[k, 1, None, None]
            dx, dy = b[k, 0, None, None] - ax, b[k, 1, None, None] - ay
            length2 = dx * dx + dy * dy
            px, py = col - ax, row - ay
            t = np.clip((px * dx + py * dy) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
            px = px - t * dx
            py = py - t * dy
            near = px * px + py * py <= radius * radius
            flat[(row * width + col)[near]] = 255


# ---- view and pixels ---------------------------------------------------------------

def _view(lo_mm, hi_mm, art_box, px_per_mm: float, max_px: int, margin_mm: float):
    """View box (work mm), scale (px/mm) and image size: the head path (lo_mm ..
    hi_mm) and the artwork plus a margin, at `px_per_mm` unless that would exceed
    `max_px` on a side."""
    xmin, ymin, xmax, ymax = float(lo_mm[0]), float(lo_mm[1]), float(hi_mm[0]), float(hi_mm[1])
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
