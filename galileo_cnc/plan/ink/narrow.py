"""Narrow features: copper thinner than the smallest pen, drawn as centre lines.

A draw or arc whose aperture is narrower than the smallest pen (plus the edge
margin) cannot be filled: no pen centre fits inside it. It is drawn along its
centre line with the smallest pen, which overdraws (pen - width) / 2 on each side.
A flash that narrow is a dot (round or square-ish apertures) or a stroke along its
long axis, ends pulled in by the pen's radius (rectangles, obrounds, macros by
their box). A flash whose aperture has a hole leaving a wall thinner than that is
a loop just inside its outer edge (a circle for a round aperture): the ink covers
the wall and spills into the hole, which the drill takes away.

Ink must never join two copper islands the artwork keeps apart, and a gap of a few
um between two inks is no gap on a real pen (ink bleeds; the stepped path strays up
to 4.4 um). So the ink of different islands keeps CLEARANCE_NM apart (islands.py;
the fills keep it there too):

- a centre line keeps its centre pen radius + CLEARANCE_NM from every other
  island's copper (the copper's own fill ink stays inside it);
- two centre lines of different islands keep a pen width + CLEARANCE_NM apart.
  Features are taken largest first (length x width), each cut against the other
  islands' lines already kept, so of two traces too close for both one is drawn
  whole rather than both cut.

The parts that come closer are cut out (samples every SAMPLE_NM along the line);
each cut is reported with both places: where the line stops and the nearest point
of the other island's copper, or of the other line (with its source line).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from galileo_cnc.errors import SourcePos
from galileo_cnc.plan import curves
from galileo_cnc.plan.ink.edges import (EdgeIndex, point_to_edges, points_to_edges,
                                       segment_gaps, segments_near)
from galileo_cnc.plan.ink.islands import CLEARANCE_NM, Islands
from galileo_cnc.plan.widths import aperture_width, macro_axis
from galileo_cnc.program.extents import dark_mask, region_mask, start_points
from galileo_cnc.program.ops import (COL, I, J, KIND, LINE, NO_TOOL, TOOL, X, Y,
                                     Aperture, OpKind, Program)

#: Spacing of the samples along a centre line where it comes near other copper.
SAMPLE_NM = 5_000
#: Samples measured together against the edges near them (_distances).
DISTANCE_BLOCK = 256
#: The first look at the whole board (_nearby) marks a feature when it comes this
#: much nearer than the reach or closer: the pieces of a cut line are rounded to
#: whole nm off its segments, and the floats of the two measures may differ.
SURE_NM = 4

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
    inside_nm: tuple[int, int] | None = None  # a point of its copper (None: mid-line)
    island: int = -1          # its copper island (keep_islands_apart)
    neck: bool = False        # a neck of a region (necks.py), not an object of its own
    spur: bool = False        # drawn as a spur of a fill's walk, not after a lift of its own

    @property
    def overdraw_nm(self) -> int:
        """Ink beyond the copper on each side."""
        return max(0, (self.pen_nm - self.width_nm) // 2)


@dataclass
class Bridge:
    """A centre line cut short where its ink would have touched another island."""

    feature: NarrowFeature
    at_nm: tuple[int, int]       # the first left-out point of the centre line
    other_nm: tuple[int, int]    # the nearest point of the other island's copper or line
    left_out_nm: int             # length not drawn
    other: NarrowFeature | None = None   # the other island's centre line, when it was that
    # the widest pen whose line would not have been cut here (0: none): its ink keeps
    # the clearance from the nearest copper and line the left-out part comes to
    widest_pen_nm: int = 0


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
    # per aperture, once (a macro's hull, per flash: 0.9 s of LimeSDR GTL's 1.0 s here)
    walls: dict[int, int] = {}
    axes: dict[int, tuple | None] = {}
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
        aperture = program.apertures[code]
        start = (int(starts[op][0]), int(starts[op][1]))
        pos = SourcePos(program.source, row[LINE], row[COL])
        if width >= limit_nm:
            if row[KIND] == _FLASH and code not in walls:
                walls[code] = wall_width(aperture)
            wall = walls[code] if row[KIND] == _FLASH else width
            if wall >= limit_nm:
                continue
            path, inside = _wall_loop(row[X], row[Y], aperture, pen_nm, tolerance_nm)
            features.append(NarrowFeature(op, pos, wall, pen_nm, row, start, [path],
                                          inside_nm=inside))
            continue
        if aperture.shape == "macro" and code not in axes:
            axes[code] = macro_axis(aperture)
        path = _centre_line(row, start, aperture, pen_nm, tolerance_nm, axes.get(code))
        features.append(NarrowFeature(op, pos, width, pen_nm, row, start, [path]))
    return features, zero


def wall_width(aperture: Aperture) -> int:
    """The copper left between a flashed aperture's hole and its outer edge (nm): the
    aperture's width when it has no hole (the hole of a draw is ignored)."""
    width = aperture_width(aperture)
    if not aperture.hole_nm or aperture.shape not in ("circle", "rectangle", "obround",
                                                      "polygon"):
        return width
    return max(0, (width - max(aperture.hole_nm)) // 2)


def _wall_loop(x: int, y: int, aperture: Aperture, pen_nm: int, tolerance_nm: int
               ) -> tuple[np.ndarray, tuple[int, int]]:
    """A closed loop a pen radius inside the outer edge of a flash with a hole whose
    wall is too thin to fill, and a point of the wall (its island)."""
    radius = pen_nm // 2
    p = aperture.params_nm
    hole = max(aperture.hole_nm) // 2
    if aperture.shape in ("circle", "polygon"):
        outer = p[0] // 2 if aperture.shape == "circle" else \
            int(p[0] / 2 * math.cos(math.pi / max(aperture.vertices, 3)))
        inside = (x + (outer + hole) // 2, y)
        loop = outer - radius
        if loop <= tolerance_nm:
            return np.array([(x, y)], dtype=np.int64), inside
        return curves.arc_points(x + loop, y, x + loop, y, -loop, 0, False, tolerance_nm), inside
    half_w, half_h = p[0] // 2 - radius, p[1] // 2 - radius
    inside = (x + (p[0] // 2 + hole) // 2, y)
    if min(half_w, half_h) <= 0:
        ends = [(x - max(half_w, 0), y), (x + max(half_w, 0), y)] if half_w > 0 else \
            [(x, y - max(half_h, 0)), (x, y + max(half_h, 0))]
        return np.array(ends, dtype=np.int64), inside
    if aperture.shape == "obround":      # a stadium: two half circles and their sides
        bend = min(half_w, half_h)
        ax, ay = half_w - bend, half_h - bend
        # a quarter circle per corner, chords within 0.2 % of the bend (inside it)
        angles = np.linspace(0, 2 * np.pi, 65)
        cx = np.where(np.cos(angles) >= 0, ax, -ax)
        cy = np.where(np.sin(angles) >= 0, ay, -ay)
        points = np.stack([x + cx + bend * np.cos(angles), y + cy + bend * np.sin(angles)], 1)
        points = np.rint(points).astype(np.int64)
        points[-1] = points[0]
        return points, inside
    corners = [(x - half_w, y - half_h), (x + half_w, y - half_h), (x + half_w, y + half_h),
               (x - half_w, y + half_h), (x - half_w, y - half_h)]
    return np.array(corners, dtype=np.int64), inside


def _centre_line(row: list[int], start: tuple[int, int], aperture: Aperture, pen_nm: int,
                 tolerance_nm: int, axis: tuple | None = None) -> np.ndarray:
    """The centre line of a draw or arc, or a flash's dot or stroke; `axis`: a macro's
    macro_axis."""
    kind, x, y = row[KIND], row[X], row[Y]
    if kind == _LINE:
        return np.array([start, (x, y)], dtype=np.int64)
    if kind in (_CW, _CCW):
        if row[I] == 0 and row[J] == 0:
            return np.array([start, (x, y)], dtype=np.int64)
        return curves.arc_points(start[0], start[1], x, y, row[I], row[J], kind == _CW,
                                 tolerance_nm)
    # a flash: a dot, or a stroke along the long side of the aperture's box
    x0, y0, x1, y1 = aperture.extent_nm
    radius = pen_nm // 2
    if aperture.shape == "circle" or aperture.shape == "polygon":
        return np.array([(x, y)], dtype=np.int64)
    if axis is not None:            # along the hull's long axis, whatever its angle
        _width, direction, centre, length = axis
        half = max(0.0, length / 2 - radius)
        ends = [centre - direction * half, centre + direction * half]
        ends = np.rint(np.array(ends) + (x, y)).astype(np.int64)
        return ends if half else ends[:1]
    cx, cy = x + (x0 + x1) // 2, y + (y0 + y1) // 2
    if x1 - x0 >= y1 - y0:
        half = max(0, (x1 - x0) // 2 - radius)
        ends = [(cx - half, cy), (cx + half, cy)]
    else:
        half = max(0, (y1 - y0) // 2 - radius)
        ends = [(cx, cy - half), (cx, cy + half)]
    return np.array(ends if half else ends[:1], dtype=np.int64)


def keep_islands_apart(features: list[NarrowFeature], islands: Islands,
                       pen_nm: int, settled: int = 0) -> list[Bridge]:
    """Cut every centre line where its ink would come near another island's copper or
    another island's centre-line ink (module doc); the cuts, each with both places.
    The first `settled` features were kept apart already: they stay as they are, and
    the others keep apart from every piece of them."""
    if len(features) <= settled or not islands.rings:
        return []
    rings, owner_of_ring = islands.rings, islands.owner
    radius = pen_nm // 2
    # samples lie SAMPLE_NM apart: the line between two kept ones may pass half a
    # sample spacing nearer than either
    near_copper = radius + CLEARANCE_NM + SAMPLE_NM // 2
    near_ink = 2 * radius + CLEARANCE_NM + SAMPLE_NM // 2
    copper_index = EdgeIndex(rings, cell_nm=max(near_copper, 100_000))
    new = features[settled:]        # the settled ones have their islands and flags
    # each feature's island: the one whose outline is nearest to a point inside its
    # copper (its own outline is nearer than any other island's: the point is inside)
    inside = np.array([inside_point(f) for f in new], dtype=np.int64)
    edge, _t, _d = copper_index.nearest_many(inside, near_copper)
    for feature, k in zip(new, edge.tolist()):
        feature.island = int(owner_of_ring[copper_index.ring[k]]) if k >= 0 else -1
    near_copper_new, near_line_new = _nearby(new, copper_index, owner_of_ring, near_copper,
                                             near_ink)
    near_other_copper = np.concatenate([np.zeros(settled, dtype=bool), near_copper_new])
    near_other_line = np.concatenate([np.zeros(settled, dtype=bool), near_line_new])
    lines = _LineIndex(features, cell_nm=max(near_ink, 250_000))
    if settled:
        # _nearby saw the new ones' lines only: they get the exact look against all
        near_other_line[settled:] = True
        for number in range(settled):
            for piece in features[number].pieces:
                lines.keep(number, piece)
    bridges: list[Bridge] = []
    for number in sorted(range(settled, len(features)), key=lambda k: -_size(features[k])):
        feature = features[number]
        path = feature.pieces[0]
        others = np.zeros(0, dtype=np.int64)
        if near_other_copper[number]:
            lo, hi = path.min(axis=0), path.max(axis=0)
            near = copper_index.in_box(int(lo[0]) - near_copper, int(lo[1]) - near_copper,
                                       int(hi[0]) + near_copper, int(hi[1]) + near_copper)
            others = near[owner_of_ring[copper_index.ring[near]] != feature.island]
            if len(others) and _segments_apart(path, copper_index.a[others],
                                               copper_index.b[others], near_copper):
                others = others[:0]
        a = b = np.zeros((0, 2), dtype=np.int64)
        whose = np.zeros(0, dtype=np.int64)
        if near_other_line[number]:
            a, b, whose = lines.near(path, near_ink, feature.island)
            if len(a) and _segments_apart(path, a, b, near_ink):
                a = a[:0]
        if not len(others) and not len(a):
            if near_other_line[number]:     # only then may another line look it up
                lines.keep(number, path)
            continue
        points, vertex = _samples_and_vertices(path)
        to_copper = _distances(points, copper_index.a[others], copper_index.b[others],
                               near_copper)
        to_ink = _distances(points, a, b, near_ink)
        by_copper, by_ink = to_copper < near_copper, to_ink < near_ink
        close = by_copper | by_ink
        if not close.any():
            lines.keep(number, path)
            continue
        feature.cut = True
        feature.pieces = [_piece(points, vertex, run) for run in _runs(~close)]
        if near_other_line[number]:
            for piece in feature.pieces:
                lines.keep(number, piece)
        for run in _runs(close):
            first = points[run[0]]
            length = float(np.hypot(*np.diff(points[run], axis=0).T).sum())
            copper_first = np.flatnonzero(by_copper[run])
            if len(copper_first):
                at = points[run[copper_first[0]]]
                other = _nearest_point(at, copper_index.a[others], copper_index.b[others])
                other_feature = None
            else:
                t, distance = point_to_edges(first.astype(np.float64), a, b)
                best = int(np.argmin(distance))
                point = a[best] + (b[best] - a[best]) * t[best]
                other = (round(float(point[0])), round(float(point[1])))
                other_feature = features[int(whose[best])]
            bridges.append(Bridge(feature, (int(first[0]), int(first[1])), other,
                                  round(length), other_feature,
                                  _widest_pen(to_copper[run], to_ink[run])))
    return bridges


def _widest_pen(to_copper: np.ndarray, to_ink: np.ndarray) -> int:
    """The widest pen (nm) for which samples this far from other copper and from another
    island's line (the same pen draws it) would not have been cut: the reaches of
    keep_islands_apart solved for the pen."""
    slack = CLEARANCE_NM + SAMPLE_NM // 2
    limits = [2 * (float(to_copper.min()) - slack), float(to_ink.min()) - slack]
    return max(0, math.floor(min(limits)))


def _nearby(features: list[NarrowFeature], copper: EdgeIndex, owner_of_ring: np.ndarray,
            near_copper: int, near_ink: int) -> tuple[np.ndarray, np.ndarray]:
    """Per feature, whether its centre line comes near another island's copper (within
    near_copper + SURE_NM) and whether near another island's centre line (near_ink +
    SURE_NM), all features at once. A feature near neither is drawn whole and no other
    line's check needs it: keep_islands_apart's exact look, one feature after another
    (7 of MinnowMax lyr1's 17 s of planning when every feature had it), is left for
    the features that are."""
    paths = [feature.pieces[0] for feature in features]
    sizes = np.array([max(len(path) - 1, 1) for path in paths])
    owner = np.repeat(np.arange(len(features)), sizes)
    # each polyline's segments; a dot is a segment from the point to itself
    start = np.concatenate([path[:-1] if len(path) > 1 else path for path in paths])
    end = np.concatenate([path[1:] if len(path) > 1 else path for path in paths])
    island = np.array([feature.island for feature in features], dtype=np.int64)[owner]
    marked = []
    for b0, b1, their_island, reach in (
            (copper.a, copper.b, owner_of_ring[copper.ring], near_copper),
            (start, end, island, near_ink)):
        i, j = segments_near(start, end, b0, b1, reach + SURE_NM)
        apart = island[i] != their_island[j]
        i, j = i[apart], j[apart]
        near = segment_gaps(start[i], end[i], b0[j], b1[j]) < reach + SURE_NM
        flags = np.zeros(len(features), dtype=bool)
        flags[owner[i[near]]] = True
        marked.append(flags)
    return marked[0], marked[1]


def _size(feature: NarrowFeature) -> int:
    """The copper a feature stands for, to take the largest first: length x width."""
    path = feature.pieces[0]
    length = float(np.hypot(*np.diff(path, axis=0).T).sum()) if len(path) > 1 else 0.0
    return int(length + feature.width_nm) * feature.width_nm


def inside_point(feature: NarrowFeature) -> tuple[int, int]:
    """A point of the feature's copper: the middle of its centre line, or the one given."""
    if feature.inside_nm is not None:
        return feature.inside_nm
    points = _samples(feature.pieces[0])
    middle = points[len(points) // 2]
    return int(middle[0]), int(middle[1])


class _LineIndex:
    """The centre-line segments kept so far, on a grid: which of other islands' lie
    near a path. A dot is a segment from a point to itself."""

    def __init__(self, features: list[NarrowFeature], cell_nm: int):
        self.features = features
        self.cell = cell_nm
        self.cells: dict[tuple[int, int], list[int]] = {}
        self.a: list[np.ndarray] = []
        self.b: list[np.ndarray] = []
        self.whose: list[int] = []

    def keep(self, number: int, piece: np.ndarray) -> None:
        """Enter a drawn piece: each segment in the cells of samples half a cell apart
        along it (so a query grown by one cell finds it), not its whole box."""
        a, b = (piece, piece) if len(piece) == 1 else (piece[:-1], piece[1:])
        first = len(self.a)
        self.a.extend(a.tolist())
        self.b.extend(b.tolist())
        self.whose.extend([number] * len(a))
        length = np.hypot(*(b - a).T.astype(np.float64))
        count = np.ceil(length / (self.cell / 2)).astype(np.int64) + 1
        owner = np.repeat(np.arange(len(a)), count)
        t = (np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)) / \
            np.maximum(np.repeat(count, count) - 1, 1)
        cells = np.floor((a[owner] + (b[owner] - a[owner]) * t[:, None]) / self.cell)
        for slot, cx, cy in set(zip((owner + first).tolist(), *cells.astype(np.int64).T.tolist())):
            self.cells.setdefault((cx, cy), []).append(slot)

    def near(self, path: np.ndarray, reach: int, island: int):
        """(a, b, owning feature) of the kept segments of other islands that may come
        within `reach` of the path."""
        lo = (path.min(axis=0) - reach) // self.cell - 1
        hi = (path.max(axis=0) + reach) // self.cell + 1
        slots: set[int] = set()
        if (hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) <= 4 * len(self.cells) + 16:
            for cx in range(int(lo[0]), int(hi[0]) + 1):
                for cy in range(int(lo[1]), int(hi[1]) + 1):
                    slots.update(self.cells.get((cx, cy), ()))
        else:                       # a box wider than the kept lines: look at them all
            for (cx, cy), members in self.cells.items():
                if lo[0] <= cx <= hi[0] and lo[1] <= cy <= hi[1]:
                    slots.update(members)
        slots_list = [s for s in sorted(slots)
                      if self.features[self.whose[s]].island != island]
        if not slots_list:
            empty = np.zeros((0, 2), dtype=np.int64)
            return empty, empty, np.zeros(0, dtype=np.int64)
        return (np.array([self.a[s] for s in slots_list], dtype=np.int64).reshape(-1, 2),
                np.array([self.b[s] for s in slots_list], dtype=np.int64).reshape(-1, 2),
                np.array([self.whose[s] for s in slots_list], dtype=np.int64))


def _samples(path: np.ndarray) -> np.ndarray:
    """Points along the polyline at most SAMPLE_NM apart, its vertices included."""
    return _samples_and_vertices(path)[0]


def _samples_and_vertices(path: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """_samples, and which of them are the polyline's own vertices."""
    if len(path) == 1:
        return path.copy(), np.ones(1, dtype=bool)
    out, vertex = [path[:1]], [np.ones(1, dtype=bool)]
    for a, b in zip(path[:-1], path[1:]):
        count = max(1, math.ceil(math.hypot(*(b - a)) / SAMPLE_NM))
        t = np.arange(1, count + 1) / count
        out.append(np.rint(a + (b - a) * t[:, None]).astype(np.int64))
        flags = np.zeros(count, dtype=bool)
        flags[-1] = True
        vertex.append(flags)
    return np.concatenate(out), np.concatenate(vertex)


def _piece(points: np.ndarray, vertex: np.ndarray, run: np.ndarray) -> np.ndarray:
    """The samples of a run as a polyline: its ends and the path's vertices between
    (the samples between lie on the path's segments)."""
    keep = vertex[run].copy()
    keep[0] = keep[-1] = True
    return points[run[keep]]


def _segments_apart(path: np.ndarray, a: np.ndarray, b: np.ndarray, reach: int) -> bool:
    """True when no segment of the path comes within `reach` of an edge a-b. (Two
    segments that do not cross are nearest at an end of one of them; a centre line
    never crosses another island's outline without first coming near it.)"""
    ends = np.concatenate([a, b])
    if _distances(path, a, b, reach).min() < reach:
        return False
    return len(path) == 1 or bool(_distances(ends, path[:-1], path[1:], reach).min() >= reach)


def _distances(points: np.ndarray, a: np.ndarray, b: np.ndarray, reach: int) -> np.ndarray:
    """points_to_edges where it is below `reach` (else inf or a distance of at least
    `reach`: callers only ask which points are nearer), in blocks of DISTANCE_BLOCK
    points, each against the edges whose box comes within `reach` of the block's: a
    long line beside a big pour measured every sample to every edge (4 s on GND2.art)."""
    out = np.full(len(points), np.inf)
    if not len(a) or not len(points):
        return out
    if len(points) * len(a) <= DISTANCE_BLOCK ** 2:    # small: no sorting out
        return points_to_edges(points, a, b)
    low, high = np.minimum(a, b), np.maximum(a, b)
    for k in range(0, len(points), DISTANCE_BLOCK):
        block = points[k:k + DISTANCE_BLOCK]
        lo, hi = block.min(axis=0) - reach, block.max(axis=0) + reach
        near = np.flatnonzero(np.all((high >= lo) & (low <= hi), axis=1))
        # farther than reach along x or y: farther than reach, never a near edge
        for m in range(0, len(near), max(1, 2_000_000 // len(block))):
            edges = near[m:m + max(1, 2_000_000 // len(block))]
            out[k:k + DISTANCE_BLOCK] = np.minimum(
                out[k:k + DISTANCE_BLOCK], points_to_edges(block, a[edges], b[edges]))
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
