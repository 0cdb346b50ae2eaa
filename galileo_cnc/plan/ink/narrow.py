"""Narrow features: copper thinner than the smallest pen, drawn as centre lines.

A draw or arc whose aperture is narrower than the smallest pen (plus the edge
margin) cannot be filled: no pen centre fits inside it. It is drawn along its
centre line with the smallest pen, which overdraws (pen - width) / 2 on each side.
A flash that narrow is a dot (round or square-ish apertures) or a stroke along its
long axis, ends pulled in by the pen's radius (rectangles, obrounds, macros by
their box).

Overdraw must never join two copper islands the artwork keeps apart. A centre
line of island A keeps its centre at least R = pen radius + the largest overdraw
of any narrow feature (so its ink stays clear of B's copper and of B's own
overdraw) + CLEARANCE_NM from every other island's outline. The parts that come
closer are cut out (samples every SAMPLE_NM along the line); each cut is reported
with both places.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from galileo_cnc.errors import SourcePos
from galileo_cnc.plan.ink import clip, shapes
from galileo_cnc.plan.ink.edges import EdgeIndex, point_to_edges, points_to_edges
from galileo_cnc.program.extents import dark_mask, region_mask, start_points
from galileo_cnc.program.ops import (COL, I, J, KIND, LINE, NO_TOOL, TOOL, X, Y,
                                     Aperture, OpKind, Program)

#: Extra distance kept between a centre line's ink and other copper: the stepped
#: path strays up to ~0.7 step (4.4 um) from the planned one.
CLEARANCE_NM = 5_000
#: Spacing of the samples along a centre line where it comes near other copper.
SAMPLE_NM = 5_000

_LINE, _CW, _CCW, _FLASH = (int(OpKind.LINE), int(OpKind.ARC_CW), int(OpKind.ARC_CCW),
                            int(OpKind.FLASH))


@dataclass
class NarrowFeature:
    """One object drawn as a centre line (or a dot), in program nm."""

    op_index: int
    pos: SourcePos
    width_nm: int            # the copper's own width
    pen_nm: int              # the pen that draws it
    row: list[int]           # the op row drawn natively when nothing was cut
    start_nm: tuple[int, int]
    pieces: list[np.ndarray]  # what is drawn: polylines (a single point is a dot)
    cut: bool = False

    @property
    def overdraw_nm(self) -> int:
        """Ink beyond the copper on each side."""
        return max(0, (self.pen_nm - self.width_nm) // 2)


@dataclass
class Bridge:
    """A centre line cut short where its ink would have touched another island."""

    feature: NarrowFeature
    at_nm: tuple[int, int]       # the first left-out point of the centre line
    other_nm: tuple[int, int]    # the nearest point of the other island
    left_out_nm: int             # length not drawn


def aperture_width(aperture: Aperture) -> int:
    """The width of the narrowest stroke the aperture makes (nm); 0 when it makes none."""
    p = aperture.params_nm
    if aperture.shape == "circle":
        return p[0] if p else 0
    if aperture.shape in ("rectangle", "obround"):
        return min(p[0], p[1]) if len(p) >= 2 else 0
    if aperture.shape == "polygon":
        return int(p[0] * math.cos(math.pi / max(aperture.vertices, 3))) if p else 0
    x0, y0, x1, y1 = aperture.extent_nm
    return min(x1 - x0, y1 - y0)


def find_narrow(program: Program, limit_nm: int, pen_nm: int,
                tolerance_nm: int) -> tuple[list[NarrowFeature], int]:
    """Dark draws, arcs and flashes narrower than `limit_nm`, as centre lines for the pen
    `pen_nm`; also the count of zero-size objects (they make no copper)."""
    table = program.table
    kind = table[:, KIND]
    candidates = np.isin(kind, (_LINE, _CW, _CCW, _FLASH)) & dark_mask(table) & ~region_mask(table)
    starts = start_points(table)
    widths = {code: aperture_width(ap) for code, ap in program.apertures.items()
              if ap.shape != "block"}
    features, zero = [], 0
    for op in np.flatnonzero(candidates).tolist():
        row = table[op].tolist()
        code = row[TOOL]
        if code == NO_TOOL or code not in widths:
            continue
        width = widths[code]
        if width <= 0:
            zero += 1
            continue
        if width >= limit_nm:
            continue
        start = (int(starts[op][0]), int(starts[op][1]))
        path = _centre_line(row, start, program.apertures[code], pen_nm, tolerance_nm)
        features.append(NarrowFeature(op, SourcePos(program.source, row[LINE], row[COL]),
                                      width, pen_nm, row, start, [path]))
    return features, zero


def _centre_line(row: list[int], start: tuple[int, int], aperture: Aperture, pen_nm: int,
                 tolerance_nm: int) -> np.ndarray:
    kind, x, y = row[KIND], row[X], row[Y]
    if kind == _LINE:
        return np.array([start, (x, y)], dtype=np.int64)
    if kind in (_CW, _CCW):
        if row[I] == 0 and row[J] == 0:
            return np.array([start, (x, y)], dtype=np.int64)
        return shapes.arc_points(start[0], start[1], x, y, row[I], row[J], kind == _CW,
                                 tolerance_nm)
    # a flash: a dot, or a stroke along the long side of the aperture's box
    x0, y0, x1, y1 = aperture.extent_nm
    radius = pen_nm // 2
    if aperture.shape == "circle" or aperture.shape == "polygon":
        return np.array([(x, y)], dtype=np.int64)
    cx, cy = x + (x0 + x1) // 2, y + (y0 + y1) // 2
    if x1 - x0 >= y1 - y0:
        half = max(0, (x1 - x0) // 2 - radius)
        ends = [(cx - half, cy), (cx + half, cy)]
    else:
        half = max(0, (y1 - y0) // 2 - radius)
        ends = [(cx, cy - half), (cx, cy + half)]
    return np.array(ends if half else ends[:1], dtype=np.int64)


def keep_islands_apart(features: list[NarrowFeature], copper: list,
                       pen_nm: int) -> list[Bridge]:
    """Cut every centre line where its ink would come near another island (module doc)."""
    if not features:
        return []
    islands = clip.components(copper)
    rings, owner = [], []
    for number, (outer, holes) in enumerate(islands):
        for ring in [outer, *holes]:
            rings.append(ring)
            owner.append(number)
    if not rings:
        return []
    owner_of_ring = np.array(owner, dtype=np.int64)
    reach = pen_nm // 2 + max(f.overdraw_nm for f in features) + CLEARANCE_NM
    index = EdgeIndex(rings, cell_nm=max(reach, 100_000))
    bridges = []
    for feature in features:
        path = feature.pieces[0]
        lo, hi = path.min(axis=0), path.max(axis=0)
        near = index.in_box(int(lo[0]) - reach, int(lo[1]) - reach,
                            int(hi[0]) + reach, int(hi[1]) + reach)
        if not len(near):
            continue
        island_of_edge = owner_of_ring[index.ring[near]]
        points = _samples(path)
        # its own island: the one whose outline is nearest to the middle of the line
        middle = points[len(points) // 2].astype(np.float64)
        _t, to_middle = point_to_edges(middle, index.a[near], index.b[near])
        own = island_of_edge[int(np.argmin(to_middle))]
        others = near[island_of_edge != own]
        if not len(others) or _segments_apart(path, index.a[others], index.b[others], reach):
            continue
        distance = _distances(points, index.a[others], index.b[others])
        close = distance < reach
        if not close.any():
            continue
        feature.cut = True
        feature.pieces = [points[run] for run in _runs(~close)]
        for run in _runs(close):
            first = points[run[0]]
            other = _nearest_point(first, index.a[others], index.b[others])
            length = float(np.hypot(*np.diff(points[run], axis=0).T).sum()) if len(run) > 1 else 0.0
            bridges.append(Bridge(feature, (int(first[0]), int(first[1])), other,
                                  int(round(length))))
    return bridges


def _samples(path: np.ndarray) -> np.ndarray:
    """Points along the polyline at most SAMPLE_NM apart, its vertices included."""
    if len(path) == 1:
        return path.copy()
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        count = max(1, math.ceil(math.hypot(*(b - a)) / SAMPLE_NM))
        t = np.arange(1, count + 1) / count
        out.append(np.rint(a + (b - a) * t[:, None]).astype(np.int64))
    return np.concatenate(out)


def _segments_apart(path: np.ndarray, a: np.ndarray, b: np.ndarray, reach: int) -> bool:
    """True when no segment of the path comes within `reach` of an edge a-b. (Two
    segments that do not cross are nearest at an end of one of them; a centre line
    never crosses another island's outline without first coming near it.)"""
    ends = np.concatenate([a, b])
    if len(path) == 1:
        return bool(points_to_edges(path, a, b).min() >= reach)
    return bool(points_to_edges(path, a, b).min() >= reach
                and _distances(ends, path[:-1], path[1:]).min() >= reach)


def _distances(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """points_to_edges in blocks, so a long line near a big pour stays small in memory."""
    out = np.empty(len(points))
    block = max(1, 2_000_000 // max(len(a), 1))
    for k in range(0, len(points), block):
        out[k:k + block] = points_to_edges(points[k:k + block], a, b)
    return out


def _runs(mask: np.ndarray) -> list[np.ndarray]:
    """Index runs where mask is True."""
    change = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [np.arange(s, e) for s, e in zip(change[::2], change[1::2])]


def _nearest_point(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[int, int]:
    t, distance = point_to_edges(p.astype(np.float64), a, b)
    best = int(np.argmin(distance))
    point = a[best] + (b[best] - a[best]) * t[best]
    return (int(round(point[0])), int(round(point[1])))
