"""A grid index over the edges of a set of rings: which edges lie near a point or a box.

The fill asks it for the nearest outline point of a ring (to join rings with a
pen-down move) and the narrow-feature check asks which other copper lies near a
centre line. Edges are entered in every grid cell that a sample along them falls
in (samples half a cell apart, so any point of an edge is within half a cell of a
sample); a query looks at every cell a box covers, grown by one cell.
"""

from __future__ import annotations

import math

import numpy as np

from galileo_cnc.plan import native

_KEY = 1 << 31   # cell key = column * _KEY + row (columns and rows fit in 31 bits)


def _key(cells: np.ndarray) -> np.ndarray:
    return (cells[..., 0] + _KEY // 2) * _KEY + (cells[..., 1] + _KEY // 2)


def cell_keys(a: np.ndarray, b: np.ndarray, cell: int) -> tuple[np.ndarray, np.ndarray]:
    """The grid cells of segments a[k]-b[k]: (cell key, k) pairs, each once, sorted by
    key then k. Each segment is entered in the cells of samples half a cell apart
    along it (both ends included), so every point of it is within a quarter cell of
    a sample."""
    compiled = native.cell_keys()           # the same pairs, compiled (native.py)
    if compiled is not None and len(a) and a.dtype.kind == b.dtype.kind == "i":
        return compiled(a, b, int(cell))
    a, b = a.astype(np.float64), b.astype(np.float64)
    length = np.hypot(*(b - a).T)
    samples = np.maximum(np.ceil(length / (cell / 2)).astype(np.int64), 1) + 1
    owner = np.repeat(np.arange(len(a)), samples)
    first = np.cumsum(samples) - samples
    t = (np.arange(len(owner)) - first[owner]) / (samples[owner] - 1)
    points = a[owner] + (b[owner] - a[owner]) * t[:, None]
    keys = _key(np.floor(points / cell).astype(np.int64))
    # distinct (key, edge) pairs sorted by key, then edge: neighbouring samples of
    # one edge mostly share a cell, so drop those repeats before the sort
    keep = np.ones(len(keys), dtype=bool)
    keep[1:] = (keys[1:] != keys[:-1]) | (owner[1:] != owner[:-1])
    keys, owner = keys[keep], owner[keep]
    order = np.lexsort((owner, keys))
    keys, owner = keys[order], owner[order]
    keep = np.ones(len(keys), dtype=bool)
    keep[1:] = (keys[1:] != keys[:-1]) | (owner[1:] != owner[:-1])
    return keys[keep], owner[keep]


class EdgeIndex:
    """Edges of closed rings: `a[k]` to `b[k]`, from ring `ring[k]`, its edge `edge[k]`."""

    def __init__(self, rings: list[np.ndarray], cell_nm: int):
        self.cell = max(int(cell_nm), 1)
        if not rings:
            self.a = self.b = np.zeros((0, 2), dtype=np.int64)
            self.ring = self.edge = np.zeros(0, dtype=np.int64)
            self._keys = self._members = np.zeros(0, dtype=np.int64)
            return
        sizes = np.array([len(ring) for ring in rings], dtype=np.int64)
        first = np.repeat(np.cumsum(sizes) - sizes, sizes)
        self.a = np.concatenate(rings).astype(np.int64, copy=False)
        self.ring = np.repeat(np.arange(len(rings), dtype=np.int64), sizes)
        self.edge = np.arange(len(self.a), dtype=np.int64) - first
        # each edge ends at the ring's next vertex, the last at the ring's first
        after = np.arange(len(self.a)) + 1
        after[np.cumsum(sizes)[sizes > 0] - 1] = (np.cumsum(sizes) - sizes)[sizes > 0]
        self.b = self.a[after]
        self._build()

    def _build(self) -> None:
        self._keys, self._members = cell_keys(self.a, self.b, self.cell)
        self._bounds()

    def _bounds(self) -> None:
        cells = np.floor(np.concatenate([self.a, self.b]) / self.cell).astype(np.int64)
        self._cells_lo, self._cells_hi = cells.min(axis=0), cells.max(axis=0)

    def rings_part(self, first: int, end: int) -> "EdgeIndex":
        """The index of rings first .. end-1 alone, as EdgeIndex(those rings) would be
        (numbered from 0), taken out of this one: a ring's cells are its own, and
        the (cell, edge) pairs stay sorted when some are left out (the fill's joins
        look up each depth of rings, its walks all of them)."""
        part = EdgeIndex([], self.cell)
        lo, hi = np.searchsorted(self.ring, [first, end])
        if hi <= lo:
            return part
        part.a, part.b = self.a[lo:hi], self.b[lo:hi]
        part.ring, part.edge = self.ring[lo:hi] - first, self.edge[lo:hi]
        mine = (self._members >= lo) & (self._members < hi)
        part._keys, part._members = self._keys[mine], self._members[mine] - lo
        part._bounds()
        return part

    def __len__(self) -> int:
        return len(self.a)

    def in_box(self, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
        """Indices of the edges that may pass through the box (a superset, no repeats)."""
        if not len(self.a):
            return np.zeros(0, dtype=np.int64)
        c = self.cell
        # cells outside the grid's bounds hold no edge
        (gx0, gy0), (gx1, gy1) = self._cells_lo.tolist(), self._cells_hi.tolist()
        cx = np.arange(max(math.floor(x0 / c) - 1, gx0), min(math.floor(x1 / c) + 2, gx1 + 1))
        cy = np.arange(max(math.floor(y0 / c) - 1, gy0), min(math.floor(y1 / c) + 2, gy1 + 1))
        if not len(cx) or not len(cy):
            return np.zeros(0, dtype=np.int64)
        keys = _key(np.stack(np.meshgrid(cx, cy, indexing="ij"), axis=-1).reshape(-1, 2))
        lo = np.searchsorted(self._keys, keys, "left")
        hi = np.searchsorted(self._keys, keys, "right")
        found = [self._members[s:e] for s, e in zip(lo.tolist(), hi.tolist()) if e > s]
        return distinct(np.concatenate(found)) if found else np.zeros(0, dtype=np.int64)

    def around_vertices(self, group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(vertex, edge) pairs of different groups (`group[k]`: edge k's and vertex
        k's), each once: every vertex (edge k starts at vertex k) against the edges
        entered in its cell and the eight around it, so every edge within a cell of
        the vertex (and some farther)."""
        # vertices crowd round curves: look each occupied cell up once
        key = _key(np.floor_divide(self.a, self.cell))
        by_cell = np.argsort(key, kind="stable")
        starts = np.flatnonzero(np.concatenate(([True], key[by_cell][1:] != key[by_cell][:-1])))
        in_cell = np.diff(np.append(starts, len(key)))
        cells = np.floor_divide(self.a[by_cell[starts]], self.cell)
        cell_first = np.cumsum(in_cell) - in_cell
        found = []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                keys = _key(cells + np.array([dx, dy]))
                first = np.searchsorted(self._keys, keys, "left")
                count = np.searchsorted(self._keys, keys, "right") - first
                # (cell, edge) pairs, then each of the cell's vertices with the edge
                cell = np.repeat(np.arange(len(cells)), count)
                rank = np.arange(len(cell)) - np.repeat(np.cumsum(count) - count, count)
                per = in_cell[cell]
                vertex = by_cell[np.repeat(cell_first[cell], per)
                                 + np.arange(per.sum()) - np.repeat(np.cumsum(per) - per, per)]
                edge = np.repeat(self._members[first[cell] + rank], per)
                apart = group[vertex] != group[edge]
                found.append(vertex[apart] * len(self.a) + edge[apart])
        # each pair as one int64 key, sorted and repeats dropped: a unique over a column
        # of two (or numpy's hashing unique) was most of the mill's short search
        pairs = np.sort(np.concatenate(found))
        pairs = pairs[np.concatenate(([True], pairs[1:] != pairs[:-1]))] if len(pairs) else pairs
        return pairs // len(self.a), pairs % len(self.a)

    def nearest(self, point: tuple[int, int], search_nm: int) -> tuple[int, float, float] | None:
        """(edge index, t along it, distance) of the outline point nearest to `point`,
        searching ever wider from `search_nm`; None when there are no edges."""
        if not len(self.a):
            return None
        x, y = point
        radius = max(int(search_nm), self.cell)
        while True:
            found = self.in_box(x - radius, y - radius, x + radius, y + radius)
            if len(found):
                t, distance = point_to_edges(np.array(point, dtype=np.float64),
                                             self.a[found], self.b[found])
                best = int(np.argmin(distance))
                # only an edge within the searched radius is surely the nearest
                if distance[best] <= radius or len(found) == len(self.a):
                    return int(found[best]), float(t[best]), float(distance[best])
            if radius > (1 << 40):
                return None
            radius *= 2


    def nearest_many(self, points: np.ndarray, search_nm: int
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`nearest` for every point of `points` (k, 2) at once: edge indices, t and
        distances, (k,) arrays; the same answers (the nearest edge, the lowest index
        among equally near ones), without a Python loop per point."""
        count = len(points)
        edge = np.full(count, -1, dtype=np.int64)
        t = np.zeros(count)
        distance = np.full(count, np.inf)
        if not len(self.a) or not count:
            return edge, t, distance
        compiled = native.nearest_edges()       # the same search, compiled (native.py)
        if compiled is not None:
            return compiled(self, points, search_nm)
        p = np.asarray(points, dtype=np.int64)
        todo = np.arange(count)
        radius = max(int(search_nm), self.cell)
        while len(todo):
            # chunks bound the (point, edge) pairs held at once
            step = max(1, 4096 // (1 + (2 * radius // self.cell)) ** 2 * 16)
            left = []
            for lo in range(0, len(todo), step):
                part = todo[lo:lo + step]
                done, k, tt, d = self._nearest_within(p[part], radius)
                edge[part[done]], t[part[done]], distance[part[done]] = k, tt, d
                left.append(part[~done])
            todo = np.concatenate(left)
            radius *= 2
        return edge, t, distance

    def _nearest_within(self, p: np.ndarray, radius: int):
        """For points p (k, 2): which are answered by the edges in their box of
        `radius` (the nearest is within it, or the box holds every edge), and for
        those the nearest edge, t and distance (ties: the lowest edge index)."""
        c = self.cell
        lo = np.floor_divide(p - radius, c) - 1
        hi = np.floor_divide(p + radius, c) + 1
        everything = np.all((lo <= self._cells_lo) & (hi >= self._cells_hi), axis=1)
        # no edge lies in a cell outside the grid's bounds: a far point looks at few cells
        lo, hi = np.maximum(lo, self._cells_lo), np.minimum(hi, self._cells_hi)
        span = max(int((hi - lo).max()) + 1, 1)
        offsets = np.arange(span)
        cx = lo[:, 0:1] + offsets                      # (k, span) columns, rows
        cy = lo[:, 1:2] + offsets
        inside = (cx[:, :, None] <= hi[:, 0, None, None]) & (cy[:, None, :] <= hi[:, 1, None, None])
        keys = _key(np.stack(np.broadcast_arrays(cx[:, :, None], cy[:, None, :]), axis=-1))
        first = np.searchsorted(self._keys, keys, "left")
        last = np.searchsorted(self._keys, keys, "right")
        sizes = np.where(inside, last - first, 0).reshape(len(p), -1)
        first = first.reshape(len(p), -1)
        # every (point, edge) pair found, grouped by point (an edge may repeat)
        per_point = sizes.sum(axis=1)
        flat = sizes.ravel()
        pair_first = np.repeat(first.ravel(), flat)
        pair_rank = np.arange(len(pair_first)) - np.repeat(np.cumsum(flat) - flat, flat)
        member = self._members[pair_first + pair_rank]
        owner = np.repeat(np.arange(len(p)), per_point)
        # point k against segment k: point_to_edges broadcasts a (k, 2) p the same way
        tt, d = point_to_edges(p[owner].astype(np.float64), self.a[member], self.b[member])
        has = per_point > 0
        starts = (np.cumsum(per_point) - per_point)[has]
        best_d = np.full(len(p), np.inf)
        best_d[has] = np.minimum.reduceat(d, starts)
        tie = np.where(d == best_d[owner], member, np.iinfo(np.int64).max)
        best_k = np.full(len(p), -1, dtype=np.int64)
        best_k[has] = np.minimum.reduceat(tie, starts)
        done = has & ((best_d <= radius) | everything)
        # t of the chosen pair: the first pair of the point with that edge
        chosen = (member == best_k[owner]) & done[owner]
        pick = np.flatnonzero(chosen)
        pick = pick[np.concatenate([[True], owner[pick][1:] != owner[pick][:-1]])] \
            if len(pick) else pick
        done_points = np.flatnonzero(done)
        return done, best_k[done_points], tt[pick], best_d[done_points]


def segments_near(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray,
                  reach: int) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i, j), each once, of segments a0[i]-a1[i] and b0[j]-b1[j] that may
    come within `reach` of each other: every pair that does, and some farther.

    On a grid of cells 2 * reach wide: two points nearer than reach have samples
    (cell_keys) nearer than reach + half a cell, which is one cell, so in the same
    or neighbouring cells."""
    if not len(a0) or not len(b0):
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    cell = 2 * max(int(reach), 1)
    keys_a, owner_a = cell_keys(a0, a1, cell)
    keys_b, owner_b = cell_keys(b0, b1, cell)
    found = []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            shifted = keys_a + dx * _KEY + dy
            first = np.searchsorted(keys_b, shifted, "left")
            count = np.searchsorted(keys_b, shifted, "right") - first
            rank = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
            found.append(np.repeat(owner_a, count) * len(b0)
                         + owner_b[np.repeat(first, count) + rank])
    pairs = distinct(np.concatenate(found))
    return pairs // len(b0), pairs % len(b0)


def distinct(values: np.ndarray) -> np.ndarray:
    """np.unique of a 1-d array, by sorting: numpy 2's np.unique hashes, 3 to 30 times
    slower (100 to a million int64 values, numpy 2.4 here)."""
    values = np.sort(values)
    return values[np.concatenate([[True], values[1:] != values[:-1]])]


def segment_gaps(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """For each k, the least distance from an end of segment a0[k]-a1[k] to segment
    b0[k]-b1[k] or from an end of that one to this one: the distance between the two
    unless they cross."""
    gaps = [point_to_edges(p.astype(np.float64), q0, q1)[1] for p, q0, q1 in
            ((a0, b0, b1), (a1, b0, b1), (b0, a0, a1), (b1, a0, a1))]
    return np.minimum(np.minimum(gaps[0], gaps[1]), np.minimum(gaps[2], gaps[3]))


def point_to_edges(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For point p (or points p[k], one per segment) and segments a[k]-b[k]: the
    parameter t in [0, 1] of the nearest point of each segment, and the distance to it."""
    a = a.astype(np.float64)
    d = b.astype(np.float64) - a
    # products and sums written out: edge_index.c does the same operations
    length2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]
    q = p - a
    t = (q[:, 0] * d[:, 0] + q[:, 1] * d[:, 1]) / np.where(length2 > 0, length2, 1.0)
    t = np.clip(t, 0.0, 1.0)
    closest = a + d * t[:, None]
    return t, np.hypot(*(closest - p).T)


def points_to_edges(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from each of `points` (k, 2) to the nearest of the segments a-b: (k,)."""
    if not len(a):
        return np.full(len(points), np.inf)
    p = points.astype(np.float64)[:, None, :]
    a = a.astype(np.float64)[None, :, :]
    d = b.astype(np.float64)[None, :, :] - a
    length2 = np.sum(d * d, axis=2)
    t = np.sum((p - a) * d, axis=2) / np.where(length2 > 0, length2, 1.0)
    t = np.clip(t, 0.0, 1.0)
    closest = a + d * t[:, :, None]
    return np.min(np.hypot(closest[..., 0] - p[..., 0], closest[..., 1] - p[..., 1]), axis=1)
