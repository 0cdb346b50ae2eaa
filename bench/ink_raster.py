"""Rasters for bench/bench_ink.py: the pen's ink from the machine's steps, the copper
from pygerber and from our exact geometry, and connected components, all on one
pixel grid sampled at pixel centres.

Everything here is numpy on whole arrays (no per-pixel or per-step Python loop):

- `Grid`: the pixel grid (aligned to pygerber's raster), program nm <-> pixels.
- `SpanCanvas`: horizontal spans (row, first column, last column) collected in a
  difference image (int32) and turned into a bool mask a band of rows at a time.
- `capsule_spans`: the pixels whose centre lies within r of a segment (a disc swept
  along it, or a dot when both ends are the same), exactly, row by row.
- `polygon_spans`: even-odd scanline fill of polygon rings at pixel centres.
- `steps_segments`: walk the reference machine's step trace of a job, part by part
  (one pen each), and turn every pen-down stretch into chords of the stepped path.
- `mask_runs`, `label_runs`, `bridges`: connected components (8-connectivity) on
  the runs of a mask, so no int32 label image is ever built; `join_by_outline`
  joins the raster islands of one exact island (copper thinner than a pixel).
- `pygerber_mask`: pygerber's raster (alpha of a dark-on-transparent render).
"""

from __future__ import annotations

import logging
import math
import re
import warnings
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

NM_PER_MM = 1_000_000
#: pixel centres on a boundary count as inside (closed sets), on both sides
EPS = 1e-9


# ---- the grid ----------------------------------------------------------------------------

@dataclass(frozen=True)
class Grid:
    """Pixel (col, row) has its centre at x = left + (col + 0.5) / dpmm, y = top -
    (row + 0.5) / dpmm (program nm, Y up; row 0 at the top, as an image)."""

    left_nm: float
    top_nm: float
    dpmm: int
    width: int
    height: int

    @property
    def scale(self) -> float:
        """Pixels per nm."""
        return self.dpmm / NM_PER_MM

    @property
    def pitch_nm(self) -> float:
        return NM_PER_MM / self.dpmm

    @property
    def pixels(self) -> int:
        return self.width * self.height

    @property
    def pixel_mm2(self) -> float:
        return 1.0 / (self.dpmm * self.dpmm)

    def u(self, x_nm) -> np.ndarray:
        """Column coordinate (pixel centres at integers)."""
        return (np.asarray(x_nm, dtype=np.float64) - self.left_nm) * self.scale - 0.5

    def v(self, y_nm) -> np.ndarray:
        """Row coordinate (pixel centres at integers, growing downwards)."""
        return (self.top_nm - np.asarray(y_nm, dtype=np.float64)) * self.scale - 0.5

    @classmethod
    def around(cls, box_nm, dpmm: int, anchor_nm=(0.0, 0.0), pad_px: int = 2) -> "Grid":
        """The smallest grid whose pixel edges fall on anchor + k / dpmm (pygerber's
        phase) and that covers box_nm = (x0, y0, x1, y1) plus `pad_px` on each side."""
        pitch = NM_PER_MM / dpmm
        ax, ay = anchor_nm
        k0 = math.floor((box_nm[0] - ax) / pitch) - pad_px
        k1 = math.ceil((box_nm[2] - ax) / pitch) + pad_px
        j0 = math.floor((box_nm[1] - ay) / pitch) - pad_px
        j1 = math.ceil((box_nm[3] - ay) / pitch) + pad_px
        return cls(ax + k0 * pitch, ay + j1 * pitch, dpmm, k1 - k0, j1 - j0)

    def place(self, left_nm: float, top_nm: float) -> tuple[int, int]:
        """(col, row) of this grid where an image aligned to it, with its top-left
        pixel edge at (left_nm, top_nm), starts."""
        return (round((left_nm - self.left_nm) * self.scale),
                round((self.top_nm - top_nm) * self.scale))


def grid_for(box_nm, px_per_mm: int, max_pixels: int, anchor_nm=(0.0, 0.0),
             pad_px: int = 2) -> Grid:
    """The grid at `px_per_mm`, or at the finest whole px/mm that keeps it within
    `max_pixels` (pygerber takes whole dots per mm)."""
    dpmm = max(1, int(px_per_mm))
    while True:
        grid = Grid.around(box_nm, dpmm, anchor_nm, pad_px)
        if grid.pixels <= max_pixels or dpmm == 1:
            return grid
        area_mm2 = grid.pixels / dpmm ** 2
        dpmm = max(1, min(dpmm - 1, int(math.sqrt(max_pixels / area_mm2))))


# ---- spans -> mask -------------------------------------------------------------------------

class SpanCanvas:
    """Spans painted into an int32 difference image (+1 at the first column, -1
    after the last); `mask()` is where the running sum along a row is positive."""

    def __init__(self, height: int, width: int):
        self.height, self.width = height, width
        self.diff = np.zeros((height, width + 1), dtype=np.int32)
        self.clipped = 0          # spans (partly) off the grid

    def clear(self) -> None:
        self.diff.fill(0)
        self.clipped = 0

    def add(self, row, c0, c1) -> None:
        row, c0, c1 = (np.asarray(a, dtype=np.int64) for a in (row, c0, c1))
        live = c0 <= c1
        row, c0, c1 = row[live], c0[live], c1[live]
        inside = (row >= 0) & (row < self.height) & (c1 >= 0) & (c0 < self.width)
        off = (c0 < 0) | (c1 >= self.width) | ~inside
        self.clipped += int(off.sum())
        row, c0, c1 = row[inside], np.maximum(c0[inside], 0), np.minimum(c1[inside], self.width - 1)
        flat = self.diff.reshape(-1)
        base = row * (self.width + 1)
        np.add.at(flat, base + c0, 1)
        np.add.at(flat, base + c1 + 1, -1)

    def mask(self, band: int = 512) -> np.ndarray:
        out = np.empty((self.height, self.width), dtype=bool)
        for r0 in range(0, self.height, band):
            running = np.cumsum(self.diff[r0:r0 + band], axis=1, dtype=np.int32)
            np.greater(running[:, :self.width], 0, out=out[r0:r0 + band])
        return out


# ---- capsules: a disc swept along segments -------------------------------------------------

def capsule_spans(ax, ay, bx, by, r, max_pairs: int = 1 << 22):
    """(rows, first cols, last cols) of the pixels whose centre is within r of the
    segment a-b (pixel coordinates; r a scalar or one per segment), in chunks of
    about `max_pairs` (segment, row) pairs. a == b is a dot.

    Per row the capsule (convex) meets the row in one interval: the union of what
    the two end discs and the band between them give, each solved exactly."""
    ax, ay, bx, by = (np.asarray(a, dtype=np.float64) for a in (ax, ay, bx, by))
    r = np.broadcast_to(np.asarray(r, dtype=np.float64), ax.shape)
    if not len(ax):
        return
    k0 = np.ceil(np.minimum(ay, by) - r - EPS).astype(np.int64)
    k1 = np.floor(np.maximum(ay, by) + r + EPS).astype(np.int64)
    rows_per = np.maximum(k1 - k0 + 1, 0)
    ends = np.cumsum(rows_per)
    lo = 0
    while lo < len(ax):
        hi = int(np.searchsorted(ends, (ends[lo - 1] if lo else 0) + max_pairs, "right"))
        hi = max(hi, lo + 1)
        yield _capsule_chunk(ax[lo:hi], ay[lo:hi], bx[lo:hi], by[lo:hi], r[lo:hi],
                             k0[lo:hi], rows_per[lo:hi])
        lo = hi


def _expand(counts: np.ndarray):
    """(owner, rank) for counts: owner i repeated counts[i] times, rank 0.. within it."""
    owner = np.repeat(np.arange(len(counts)), counts)
    rank = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts)
    return owner, rank


def _capsule_chunk(ax, ay, bx, by, r, k0, rows_per):
    seg, rank = _expand(rows_per)
    row = k0[seg] + rank
    y = row.astype(np.float64)
    AX, AY, BX, BY, R = ax[seg], ay[seg], bx[seg], by[seg], r[seg]
    r2 = R * R + EPS
    lo = np.full(len(row), np.inf)
    hi = np.full(len(row), -np.inf)
    for px, py in ((AX, AY), (BX, BY)):           # the end discs
        d = y - py
        h2 = r2 - d * d
        ok = h2 >= 0
        h = np.sqrt(np.where(ok, h2, 0.0))
        lo = np.where(ok, np.minimum(lo, px - h), lo)
        hi = np.where(ok, np.maximum(hi, px + h), hi)
    dx, dy = BX - AX, BY - AY
    length = np.hypot(dx, dy)
    has = length > 0
    ux = np.where(has, dx / np.where(has, length, 1.0), 0.0)
    uy = np.where(has, dy / np.where(has, length, 1.0), 0.0)
    # the band: t = (x - AX) ux + c1 in [0, L], s = -(x - AX) uy + c2 in [-R, R]
    c1 = (y - AY) * uy
    c2 = (y - AY) * ux
    slo = np.full(len(row), -np.inf)
    shi = np.full(len(row), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        nx = ux != 0
        ta, tb = -c1 / ux, (length - c1) / ux
        slo = np.where(nx, np.maximum(slo, np.minimum(ta, tb)), slo)
        shi = np.where(nx, np.minimum(shi, np.maximum(ta, tb)), shi)
        bad = ~nx & ((c1 < 0) | (c1 > length))
        ny = uy != 0
        sa, sb = (c2 + R) / uy, (c2 - R) / uy
        slo = np.where(ny, np.maximum(slo, np.minimum(sa, sb)), slo)
        shi = np.where(ny, np.minimum(shi, np.maximum(sa, sb)), shi)
        bad |= ~ny & (np.abs(c2) > R)
    band = has & ~bad & (slo <= shi)
    lo = np.where(band, np.minimum(lo, AX + slo), lo)
    hi = np.where(band, np.maximum(hi, AX + shi), hi)
    live = np.isfinite(lo) & np.isfinite(hi)
    c0 = np.ceil(lo[live] - EPS).astype(np.int64)
    c1_ = np.floor(hi[live] + EPS).astype(np.int64)
    return row[live], c0, c1_


# ---- polygons: even-odd scanline at pixel centres ----------------------------------------

def polygon_spans(rings, grid: Grid, band_rows: int = 1024):
    """Spans of the pixels whose centre is inside the rings (even-odd), per band of rows.
    `rings`: int (n, 2) arrays in program nm, closed or not."""
    rings = [np.asarray(ring) for ring in rings if len(ring) >= 3]
    if not rings:
        return
    points = np.concatenate(rings)
    sizes = np.array([len(ring) for ring in rings])
    first = np.repeat(np.cumsum(sizes) - sizes, sizes)
    nxt = np.arange(len(points)) + 1
    closing = nxt == np.repeat(np.cumsum(sizes), sizes)
    nxt[closing] = first[closing]
    u, v = grid.u(points[:, 0]), grid.v(points[:, 1])
    u0, v0, u1, v1 = u, v, u[nxt], v[nxt]
    slanted = v0 != v1
    u0, v0, u1, v1 = u0[slanted], v0[slanted], u1[slanted], v1[slanted]
    # a row k crosses the edge when min(v) <= k < max(v) (each vertex once)
    k0 = np.ceil(np.minimum(v0, v1)).astype(np.int64)
    k1 = np.ceil(np.maximum(v0, v1)).astype(np.int64)
    k0, k1 = np.maximum(k0, 0), np.minimum(k1, grid.height)
    live = k1 > k0
    u0, v0, u1, v1, k0, k1 = u0[live], v0[live], u1[live], v1[live], k0[live], k1[live]
    slope = (u1 - u0) / (v1 - v0)
    for b0 in range(0, grid.height, band_rows):
        b1 = min(b0 + band_rows, grid.height)
        take = (k0 < b1) & (k1 > b0)
        if not take.any():
            continue
        lo, hi = np.maximum(k0[take], b0), np.minimum(k1[take], b1)
        edge, rank = _expand(hi - lo)
        row = lo[edge] + rank
        x = u0[take][edge] + (row - v0[take][edge]) * slope[take][edge]
        order = np.lexsort((x, row))
        row, x = row[order], x[order]
        yield row[0::2], np.ceil(x[0::2] - EPS).astype(np.int64), \
            np.floor(x[1::2] + EPS).astype(np.int64)


def rings_of(polygons) -> list[np.ndarray]:
    """All rings of [(shell, [holes])]."""
    out = []
    for shell, holes in polygons:
        out.append(shell)
        out.extend(holes)
    return out


# ---- morphology (square structuring element) ----------------------------------------------

def dilate(mask: np.ndarray, b: int) -> np.ndarray:
    """Pixels within Chebyshev distance b of the mask."""
    out = mask.copy()
    for s in range(1, b + 1):
        out[:, s:] |= mask[:, :-s]
        out[:, :-s] |= mask[:, s:]
    rows = out.copy()
    for s in range(1, b + 1):
        out[s:] |= rows[:-s]
        out[:-s] |= rows[s:]
    return out


def erode(mask: np.ndarray, b: int) -> np.ndarray:
    """Pixels whose whole (2b+1)^2 neighbourhood is in the mask (off-grid is not)."""
    return ~dilate(~mask, b)


# ---- runs and connected components (8-connectivity) ----------------------------------------

@dataclass
class Runs:
    """Horizontal runs of a mask in row-major order: row, first and last column."""

    row: np.ndarray
    start: np.ndarray
    end: np.ndarray
    width: int

    def __len__(self) -> int:
        return len(self.row)

    def keys(self, col) -> np.ndarray:
        return self.row * (self.width + 3) + (np.asarray(col) + 1)


def mask_runs(mask: np.ndarray, band: int = 512) -> Runs:
    height, width = mask.shape
    rows, starts, ends = [], [], []
    padded = np.zeros((min(band, height), width + 2), dtype=np.int8)
    for r0 in range(0, height, band):
        part = mask[r0:r0 + band]
        pad = padded[:len(part)]
        pad[:, 1:-1] = part
        d = np.diff(pad, axis=1)                # (h, width + 1)
        s = np.flatnonzero(d == 1)
        e = np.flatnonzero(d == -1)
        rows.append(s // (width + 1) + r0)
        starts.append(s % (width + 1))
        ends.append(e % (width + 1) - 1)
    cat = (lambda parts: np.concatenate(parts).astype(np.int64)) if rows else \
        (lambda parts: np.zeros(0, np.int64))
    return Runs(cat(rows), cat(starts), cat(ends), width)


def label_runs(runs: Runs) -> np.ndarray:
    """Component label (the smallest run index in it) of every run; runs touch when
    they are in neighbouring rows and overlap or meet at a corner."""
    n = len(runs)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    key_start, key_end = runs.keys(runs.start), runs.keys(runs.end)
    above = runs.row - 1
    stride = runs.width + 3
    lo = np.searchsorted(key_end, above * stride + runs.start, "left")      # end >= start-1
    hi = np.searchsorted(key_start, above * stride + runs.end + 2, "right")  # start <= end+1
    counts = np.maximum(hi - lo, 0)
    b, rank = _expand(counts)
    a = lo[b] + rank
    return _components(n, a, b)


def _components(n: int, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Union-find on whole arrays: hook the larger root under the smaller, then
    compress all paths; repeat until every edge has one root."""
    parent = np.arange(n)
    while len(u):
        pu, pv = parent[u], parent[v]
        differ = pu != pv
        if not differ.any():
            break
        u, v, pu, pv = u[differ], v[differ], pu[differ], pv[differ]
        np.minimum.at(parent, np.maximum(pu, pv), np.minimum(pu, pv))
        while True:
            grand = parent[parent]
            if np.array_equal(grand, parent):
                break
            parent = grand
    return parent


def islands(copper: np.ndarray) -> tuple[Runs, np.ndarray, int]:
    """Runs of the copper, each run's island (component) label, and the island count."""
    runs = mask_runs(copper)
    labels = label_runs(runs)
    return runs, labels, int(len(np.unique(labels)))


def join_by_outline(runs: Runs, labels: np.ndarray, grid: Grid, polygons,
                    touch_nm: float = 0.0) -> np.ndarray:
    """Labels with the raster islands of one exact island joined: copper thinner than a
    pixel (a 10 um fiducial ring at 25 um a pixel) samples as a row of dots, each its
    own 8-connected island, and ink over it would count as a bridge between them.
    `polygons`: the exact copper as (shell, [holes]) in program nm, one per island; a
    raster island takes the island nearest its first pixel's centre (within a pixel).
    Exact islands less than `touch_nm` apart are one (the planner's islands.TOUCH_NM:
    copper that meets at a vertex, gaps under a step)."""
    import shapely

    if not len(runs) or not polygons:
        return labels
    first = np.unique(labels)                       # a label is its first run's index
    points = shapely.points(grid.left_nm + (runs.start[first] + 0.5) * grid.pitch_nm,
                            grid.top_nm - (runs.row[first] + 0.5) * grid.pitch_nm)
    shapes = [shapely.Polygon(shell, holes) for shell, holes in polygons]
    tree = shapely.STRtree(shapes)
    which, island = tree.query_nearest(points, max_distance=grid.pitch_nm, all_matches=False)
    if touch_nm > 0:
        a, b = tree.query(shapes, predicate="dwithin", distance=touch_nm)
        island = _components(len(shapes), a, b)[island]
    # one edge from every raster island to the first raster island of its exact island
    order = np.argsort(island, kind="stable")
    which, island = which[order], island[order]
    head = np.r_[0, np.flatnonzero(np.diff(island)) + 1]
    lead = np.repeat(first[which[head]], np.diff(np.r_[head, len(island)]))
    parent = _components(len(runs), first[which], lead)
    return parent[labels]


def bridges(copper_runs: Runs, copper_labels: np.ndarray, union: np.ndarray) -> tuple[int, int]:
    """(components of ink | copper holding 2+ copper islands, islands merged away): every
    copper run lies inside one run of the union; count the islands per component."""
    if not len(copper_runs):
        return 0, 0
    runs = mask_runs(union)
    labels = label_runs(runs)
    inside = np.searchsorted(runs.keys(runs.start), copper_runs.keys(copper_runs.start),
                             "right") - 1
    pairs = np.unique(np.stack([labels[inside], copper_labels]), axis=1)
    per = np.unique(pairs[0], return_counts=True)[1]
    return int((per >= 2).sum()), int((per[per >= 2] - 1).sum())


def _touching(a: Runs, b: Runs) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (run of a, run of b) that touch (8-connectivity; the runs are disjoint)."""
    key_start, key_end = b.keys(b.start), b.keys(b.end)
    stride = b.width + 3
    firsts, seconds = [], []
    for shift in (-1, 0, 1):
        row = a.row + shift
        lo = np.searchsorted(key_end, row * stride + a.start, "left")
        hi = np.searchsorted(key_start, row * stride + a.end + 2, "right")
        owner, rank = _expand(np.maximum(hi - lo, 0))
        firsts.append(owner)
        seconds.append(lo[owner] + rank)
    return np.concatenate(firsts), np.concatenate(seconds)


def bridge_places(copper_runs: Runs, copper_labels: np.ndarray, outside: np.ndarray,
                  limit: int = 5) -> list[tuple[int, int, int, int]]:
    """Where the bridges are: (row0, col0, row1, col1) of the components of the ink
    outside the copper that touch 2+ copper islands, largest first."""
    return [box for box, _ in bridge_touches(copper_runs, copper_labels, outside, limit)]


def bridge_touches(copper_runs: Runs, copper_labels: np.ndarray, outside: np.ndarray,
                   limit: int = 5) -> list[tuple[tuple[int, int, int, int], list]]:
    """bridge_places with, per component, one (row, col) of outside ink next to each
    island it touches (at most 4): the places a planner's diagnostics can look up."""
    runs = mask_runs(outside)
    if not len(runs) or not len(copper_runs):
        return []
    labels = label_runs(runs)
    a, b = _touching(runs, copper_runs)
    pairs, first = np.unique(np.stack([labels[a], copper_labels[b]]), axis=1,
                             return_index=True)
    components, per = np.unique(pairs[0], return_counts=True)
    out = []
    for component in components[per >= 2]:
        mine = labels == component
        box = (int(runs.row[mine].min()), int(runs.start[mine].min()),
               int(runs.row[mine].max()), int(runs.end[mine].max()))
        touches = []
        for k in np.flatnonzero(pairs[0] == component)[:4]:
            ink_run, cu_run = a[first[k]], b[first[k]]
            # the ink run's column nearest to the copper run it touches
            col = int(np.clip(copper_runs.start[cu_run], runs.start[ink_run], runs.end[ink_run]))
            touches.append((int(runs.row[ink_run]), col))
        out.append((box, touches))
    out.sort(key=lambda item: -(item[0][2] - item[0][0] + 1) * (item[0][3] - item[0][1] + 1))
    return out[:limit]


# ---- the ink from the machine's steps ----------------------------------------------------

#: commands that draw with the pen in force (their aperture/pen key decides the width)
DRAWING = ("LineTo", "ArcTo", "Flash", "PenDown")


def job_parts(job) -> list[tuple[int, int, object]]:
    """(first command, end, pen key) per part of the job drawn by one pen: cut at the
    pen changes and wherever the pen key of a drawing command changes."""
    cuts = set(job.pen_changes) | {0}
    last = None
    pens: dict[int, object] = {}
    for index, command in enumerate(job.commands):
        if type(command).__name__ in DRAWING:
            key = job.aperture[index]
            if last is not None and key != last:
                cuts.add(index)
            last = key
            pens.setdefault(index, key)
    cuts = sorted(c for c in cuts if c < len(job.commands)) or [0]
    ends = cuts[1:] + [len(job.commands)]
    firsts = sorted(pens)
    parts = []
    for start, end in zip(cuts, ends):
        at = np.searchsorted(firsts, start)
        key = pens[firsts[at]] if at < len(firsts) and firsts[at] < end else \
            job.pen_changes.get(start)
        parts.append((start, end, key))
    return parts


@dataclass
class StrokeSet:
    """Chords of the stepped pen-down path (work steps), per pen width (nm)."""

    by_width: dict               # width_nm -> list of (ax, ay, bx, by) int64 arrays
    length_steps: float          # pen-down path length along the chords
    stretches: int               # pen-down stretches (each ends with a lift)
    events: int                  # trace events walked
    down_events: int
    zero_width_stretches: int    # drawn with a pen of unknown (0) width: no ink

    def arrays(self, width):
        parts = self.by_width.get(width, [])
        if not parts:
            return (np.zeros(0, np.int64),) * 4
        return tuple(np.concatenate([p[k] for p in parts]) for k in range(4))

    def box_nm(self, offset_nm, nm_per_step: int):
        """(x0, y0, x1, y1) in program nm of all the ink: each pen's chords widened by
        its radius; None when nothing is drawn."""
        box = None
        for width, parts in self.by_width.items():
            for ax, ay, bx, by in parts:
                if not len(ax):
                    continue
                pad = width / 2
                here = (min(ax.min(), bx.min()) * nm_per_step + offset_nm[0] - pad,
                        min(ay.min(), by.min()) * nm_per_step + offset_nm[1] - pad,
                        max(ax.max(), bx.max()) * nm_per_step + offset_nm[0] + pad,
                        max(ay.max(), by.max()) * nm_per_step + offset_nm[1] + pad)
                box = here if box is None else (min(box[0], here[0]), min(box[1], here[1]),
                                                max(box[2], here[2]), max(box[3], here[3]))
        return box


def steps_segments(job, config, widths: dict, tol_steps: float = 0.5) -> StrokeSet:
    """Step the job on the reference machine part by part (one machine, so every part
    continues from where the last one stood) and turn each pen-down stretch (Z ==
    config.pen_down_z_steps) into chords of the stepped path within `tol_steps` of
    every step position. A stretch that never moves is a dot (a Flash)."""
    from galileo_cnc.machine import ReferenceMachine
    from galileo_cnc.machine.vector import execute_in_pieces

    machine = ReferenceMachine(config)
    down_z = config.pen_down_z_steps
    at = [0, 0, 0]                 # position after the last event walked
    carry_down = None              # the last event was pen-down (None: the start)
    out = StrokeSet({}, 0.0, 0, 0, 0, 0)
    for start, end, pen in job_parts(job):
        width = int(widths.get(pen, 0) or 0)
        items = machine.plan(job.commands[start:end])
        for tick, axis, step in execute_in_pieces(items, [0]):
            if not len(tick):
                continue
            last = np.ones(len(tick), dtype=bool)
            last[:-1] = tick[1:] != tick[:-1]
            pos = []
            for k in range(3):
                walked = np.cumsum(np.where(axis == k, step, 0), dtype=np.int64)
                pos.append(np.concatenate(([at[k]], walked[last] + at[k])))
                at[k] += int(walked[-1])
            x, y, z = pos                   # [the event before the piece] + its events
            out.events += len(x) - 1
            down = z == down_z
            down[0] = bool(carry_down) if carry_down is not None else down[0]
            out.down_events += int(down[1:].sum())
            _stretches(out, x, y, down, carry_down, width, tol_steps)
            carry_down = bool(down[-1])
    return out


def _stretches(out: StrokeSet, x, y, down, carry_down, width: int, tol: float) -> None:
    edges = np.diff(np.concatenate(([0], down.view(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # [s, e)
    if not len(starts):
        return
    keep = np.ones(len(starts), dtype=bool)
    if starts[0] == 0:
        moves = ends[0] - starts[0] > 1
        if carry_down is None:
            # the pen resting where the machine began is not a dot the job makes
            keep[0] = bool(moves and np.any((x[:ends[0]] != x[0]) | (y[:ends[0]] != y[0])))
            new = keep.copy()
        else:
            keep[0] = moves          # a stretch that ended with the last piece
            new = keep.copy()
            new[0] = False           # continues a stretch already counted
    else:
        new = keep.copy()
    starts, ends, new = starts[keep], ends[keep], new[keep]
    if not len(starts):
        return
    out.stretches += int(new.sum())
    if width <= 0:
        out.zero_width_stretches += int(new.sum())
    kept = _thin(x, y, starts, ends, tol)
    run = np.searchsorted(starts, kept, "right") - 1
    pair = run[1:] == run[:-1]
    a, b = kept[:-1][pair], kept[1:][pair]
    dots = starts[ends - starts == 1]
    a, b = np.concatenate((a, dots)), np.concatenate((b, dots))
    out.length_steps += float(np.hypot(x[b] - x[a], y[b] - y[a]).sum())
    if width > 0 and len(a):
        out.by_width.setdefault(width, []).append((x[a], y[a], x[b], y[b]))


def _thin(x, y, starts, ends, tol: float, levels=(64, 16, 4, 1)) -> np.ndarray:
    """Indices kept along each run [s, e): both ends, and enough in between that every
    event lies within `tol` (steps) of the chord joining the kept ones around it.
    Blocks of 64 events are tried first, those that stray cut into 16, 4, 1."""
    last = ends - 1
    keep = [starts, last]
    span = last - starts
    K = levels[0]
    count = (span + K - 1) // K
    run, rank = _expand(count)
    bs = starts[run] + rank * K
    be = np.minimum(bs + K, last[run])
    for index, K in enumerate(levels):
        if not len(bs):
            break
        if K == 1:
            keep.append(bs)
            break
        idx = np.minimum(bs[:, None] + np.arange(K + 1), be[:, None])
        px, py = x[idx].astype(np.float64), y[idx].astype(np.float64)
        ax, ay = px[:, :1], py[:, :1]
        dx, dy = x[be][:, None] - ax, y[be][:, None] - ay
        dd = dx * dx + dy * dy
        t = np.clip(((px - ax) * dx + (py - ay) * dy) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
        gap = np.hypot(px - ax - t * dx, py - ay - t * dy).max(axis=1)
        ok = gap <= tol
        keep.append(bs[ok])
        bs, be = bs[~ok], be[~ok]
        nxt = levels[index + 1]
        count = (be - bs + nxt - 1) // nxt
        block, rank = _expand(count)
        bs, be = bs[block] + rank * nxt, np.minimum(bs[block] + (rank + 1) * nxt, be[block])
    return np.unique(np.concatenate(keep))


# ---- pygerber ------------------------------------------------------------------------------

@contextmanager
def quiet_pygerber():
    """pygerber logs style advice and its grammar raises deprecation warnings."""
    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        logging.disable(previous)


def pygerber_parse(source):
    """pygerber's parsed file, its bounding box (min_x, min_y, max_x, max_y) in file nm
    (apertures included), and "raw" or "normalised": the input pygerber could read.
    `source` is a path or Gerber text. When pygerber 2.4 rejects the text as written,
    it gets `pygerber_text(text)`, and the error is the first attempt's if that fails too."""
    from pathlib import Path

    text = Path(source).read_text(encoding="latin-1") if isinstance(source, Path) else source
    try:
        return (*_parse(text), "raw")
    except Exception as first:  # noqa: BLE001 (its grammar raises many kinds)
        normalised = pygerber_text(text)
        if normalised == text:
            raise
        try:
            return (*_parse(normalised), "normalised")
        except Exception:  # noqa: BLE001
            raise first from None


def _parse(text: str):
    with quiet_pygerber():
        from pygerber.gerberx3.api.v2 import GerberFile
        parsed = GerberFile.from_str(text).parse()
        bb = parsed._command_buffer.get_bounding_box()
        box = tuple(float(v.as_millimeters()) * NM_PER_MM
                    for v in (bb.min_x, bb.min_y, bb.max_x, bb.max_y))
    return parsed, box


_COMMENT = re.compile(r"G0?4[^*]*\*")
_BLOCK = re.compile(r"%([^%]*)%")
#: parameters that change nothing with these values (and names, which draw nothing)
_NO_OP = re.compile(r"IR0+(\.0*)?|IPPOS|OFA[-+]?0*(\.0*)?B[-+]?0*(\.0*)?|MIA0B0|"
                    r"SFA0*1(\.0*)?B0*1(\.0*)?|IC[A-Z]*|IN.*|LN.*|ASAXBY", re.S)
_MACRO_NAME = re.compile(r"[A-Za-z_.$][A-Za-z_.0-9$]*")


def pygerber_text(text: str) -> str:
    """The same image in the dialect pygerber 2.4's grammar takes: comments dropped;
    several parameters in one %...% block split into one block each (RS-274X allows
    both); deprecated parameters that change nothing (IR0, IPPOS, OF 0, MIA0B0, SF 1,
    AS AXBY, IC, IN, LN) dropped, other values kept (pygerber then fails or differs,
    and the disputed pixels say so); N/G/D/M digit counts out of FS; G54 before a D
    code and G55 before D03 dropped; D codes without leading zeros; macro names with
    characters outside the standard's renamed."""
    text = _COMMENT.sub("", text)
    renamed: dict[str, str] = {}

    def block(match: re.Match) -> str:
        body = match.group(1).strip()
        if body.startswith("AM"):
            head, _, rest = body.partition("*")
            name = head[2:].strip()
            if not _MACRO_NAME.fullmatch(name):
                renamed.setdefault(name, f"BENCHMACRO{len(renamed)}")
                head = "AM" + renamed[name]
            return f"%{head}*{rest}%"
        out = []
        for part in (p.strip() for p in body.split("*")):
            if not part or _NO_OP.fullmatch(part):
                continue
            if part.startswith("FS"):
                part = re.sub(r"[NGDM]\d+", "", part)
            out.append(f"%{part}*%")
        return "".join(out)

    text = _BLOCK.sub(block, text)
    for old, new in renamed.items():
        text = re.sub(r"(%ADD\d+)" + re.escape(old) + r"(?=[,*])", r"\g<1>" + new, text)
    text = re.sub(r"G54(?=D\d)", "", text)
    text = re.sub(r"G55(?=D0*3\D)", "", text)
    return re.sub(r"(?<![0-9])D0+(\d\d+)", r"D\1", text)


def pygerber_mask(parsed, dpmm: int) -> np.ndarray:
    """pygerber's raster at `dpmm` as a bool array (row 0 at the top): its column c
    spans [min_x + c/dpmm, min_x + (c+1)/dpmm), its last row ends at min_y."""
    from pygerber.common.rgba import RGBA
    from pygerber.gerberx3.api.v2 import ColorScheme
    from pygerber.gerberx3.renderer2.raster import RasterRenderer2, RasterRenderer2Hooks

    dark, none = RGBA.from_rgba(255, 255, 255, 255), RGBA.from_rgba(0, 0, 0, 0)
    scheme = ColorScheme(background_color=none, clear_color=none, solid_color=dark,
                         clear_region_color=none, solid_region_color=dark)
    with quiet_pygerber():
        image = RasterRenderer2(RasterRenderer2Hooks(color_scheme=scheme, dpmm=dpmm)) \
            .render(parsed._command_buffer).get_image()
    alpha = image.getchannel("A")
    del image
    return np.asarray(alpha) >= 128
