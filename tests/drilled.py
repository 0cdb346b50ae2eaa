"""Test helpers for boards with holes: the holes of a KiCad drill file (test-only: the
simple form KiCad writes, METRIC, `T1C0.800` tools, decimal `X..Y..` holes; the real
reader is readers/excellon/), the pen-down runs of a step trace, and a 10 um raster
count of a polygon set."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan.ink import clip
from galileo_cnc.program.drills import Hole

_TOOL = re.compile(r"T(\d+)C([\d.]+)")
_SELECT = re.compile(r"T(\d+)")
_HOLE = re.compile(r"X(-?[\d.]+)Y(-?[\d.]+)")


def kicad_holes(path: Path) -> list[Hole]:
    """The round holes of a KiCad metric decimal drill file, in nm."""
    tools, tool, holes = {}, None, []
    for number, line in enumerate(Path(path).read_text().splitlines(), 1):
        line = line.strip()
        if m := _TOOL.fullmatch(line):
            tools[m[1]] = round(float(m[2]) * 1_000_000)
        elif m := _SELECT.fullmatch(line):
            tool = m[1]
        elif m := _HOLE.fullmatch(line):
            holes.append(Hole(round(float(m[1]) * 1_000_000), round(float(m[2]) * 1_000_000),
                              tools[tool], f"T{tool}", line=number))
    assert holes, f"{path}: no holes read"
    return holes


def pen_down_runs(trace, config: MachineConfig) -> list[np.ndarray]:
    """Each pen-down run of the trace: (n, 2) machine steps."""
    where = trace.positions()
    down = where[:, 2] == config.pen_down_z_steps
    edges = np.flatnonzero(np.diff(np.concatenate([[0], down.astype(np.int8), [0]])))
    return [where[a:b, :2] for a, b in zip(edges[::2], edges[1::2])]


def _crossings(ring: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    winding = np.zeros(x.shape, dtype=np.int64)
    ring = np.asarray(ring, dtype=np.float64)
    for (x0, y0), (x1, y1) in zip(ring, np.roll(ring, -1, axis=0)):
        if y0 == y1:
            continue
        cross_x = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        winding += ((y0 <= y) & (y < y1) & (cross_x > x)).astype(np.int64)
        winding -= ((y1 <= y) & (y < y0) & (cross_x > x)).astype(np.int64)
    return winding


def pixels_inside(polygons: list, pixel_nm: int = 10_000) -> int:
    """How many centres of a `pixel_nm` grid lie inside the set (positive winding)."""
    count = 0
    for outer, holes in clip.components(polygons):
        (x0, y0), (x1, y1) = outer.min(axis=0), outer.max(axis=0)
        xs = np.arange(math.ceil(x0 / pixel_nm), math.floor(x1 / pixel_nm) + 1) * pixel_nm
        ys = np.arange(math.ceil(y0 / pixel_nm), math.floor(y1 / pixel_nm) + 1) * pixel_nm
        if not len(xs) or not len(ys):
            continue
        x, y = np.meshgrid(xs.astype(np.float64), ys.astype(np.float64))
        winding = sum((_crossings(ring, x, y) for ring in (outer, *holes)),
                      np.zeros(x.shape, dtype=np.int64))
        count += int((winding > 0).sum())
    return count


def ink_near(trace, config: MachineConfig, offset_nm: tuple[int, int], pen_nm: int,
                places: list) -> list:
    """The stepped ink near `places` (a polygon set, program nm): the pen-down runs'
    stretches within a pen radius (and two steps) of the places' boxes, swept by the
    pen, so a whole board's steps need not be swept. Every second step is kept (the
    chord past a step strays at most half a diagonal step from it, and sweeping a
    staircase vertex by vertex takes 20 times as long), so the pen's radius is grown by
    that: a little more ink than the steps make, never less."""
    where = trace.positions()
    down = where[:, 2] == config.pen_down_z_steps
    points = where[:, :2] * config.nm_per_step + np.asarray(offset_nm)
    near = np.zeros(len(points), dtype=bool)
    for outer, _holes in clip.components(places):
        reach = pen_nm // 2 + 2 * config.nm_per_step
        (x0, y0), (x1, y1) = outer.min(axis=0) - reach, outer.max(axis=0) + reach
        near |= (points[:, 0] >= x0) & (points[:, 0] <= x1) & (points[:, 1] >= y0) \
            & (points[:, 1] <= y1)
    chosen = down & near
    # a stretch also keeps its neighbours, so a step leaving the box still counts
    chosen[1:] |= chosen[:-1] & down[1:]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], chosen.astype(np.int8), [0]])))
    runs = [_corners(np.concatenate([points[a:b:2], points[b - 1:b]])).tolist()
            for a, b in zip(edges[::2], edges[1::2])]
    stray = math.ceil(config.nm_per_step / math.sqrt(2))
    return clip.stroke(runs, pen_nm // 2 + stray, 1000) if runs else []


def _corners(run: np.ndarray) -> np.ndarray:
    """The run without the points inside a straight stretch: the same line."""
    if len(run) < 3:
        return run
    step = np.diff(run, axis=0)
    turn = np.any(step[1:] != step[:-1], axis=1)
    return run[np.concatenate([[True], turn, [True]])]
