"""Spatial queries for path order: each end's nearest ends, the nearest free end, and
the pairs of points within a distance (near_pairs).

Exact for a few thousand points (numpy over blocks of rows); above, candidates from
windows along three shifted Z-order curves, near enough for the local search's moves.
"""

from __future__ import annotations

import math

import numpy as np

from galileo_cnc.plan.order.pieces import Point

#: nodes up to which neighbours are found exactly (above: along Z-order curves)
BRUTE_FORCE = 2000
ZORDER_WINDOW = 6

def nearest(xs: np.ndarray, ys: np.ndarray, k: int,
             quadrant: int = 0) -> tuple[list[list[int]], list[list[float]]]:
    """For each point, up to k others nearest first (its mate, index ^ 1, left out),
    ties by index, with their distances; and, for up to a few thousand points, the
    `quadrant` nearest in each quadrant around it too (ends in clusters then also
    see the next cluster). Exact for a few thousand points; above, candidates from
    windows along three shifted Z-order curves (near enough for move candidates)."""
    n = len(xs)
    k = min(k, n - 2)
    if k <= 0:
        return [[] for _ in range(n)], [[] for _ in range(n)]
    keep_per_row = k
    if n <= BRUTE_FORCE:
        rows_, cols = [], []
        block = max(1, 2_000_000 // n)
        for lo in range(0, n, block):
            hi = min(n, lo + block)
            dx = xs[None, :] - xs[lo:hi, None]
            dy = ys[None, :] - ys[lo:hi, None]
            d2 = dx * dx + dy * dy
            own = np.arange(lo, hi)
            d2[own - lo, own] = np.inf
            d2[own - lo, own ^ 1] = np.inf
            kth = np.partition(d2, k - 1, axis=1)[:, k - 1]
            r, c = np.nonzero(d2 <= kth[:, None])
            rows_.append(r + lo)
            cols.append(c)
            if quadrant:
                for side in ((dx > 0) & (dy >= 0), (dx <= 0) & (dy > 0),
                             (dx < 0) & (dy <= 0), (dx >= 0) & (dy < 0)):
                    dq = np.where(side, d2, np.inf)
                    q = min(quadrant, n - 1)
                    kth = np.partition(dq, q - 1, axis=1)[:, q - 1]
                    r, c = np.nonzero((dq <= kth[:, None]) & np.isfinite(dq))
                    rows_.append(r + lo)
                    cols.append(c)
        keep_per_row = k + 4 * quadrant
        i = np.concatenate(rows_)
        j = np.concatenate(cols)
    else:
        span = max(float(xs.max() - xs.min()), float(ys.max() - ys.min()), 1.0)
        scale = float((1 << 20) - 1) / (2.0 * span)
        pairs_i, pairs_j = [], []
        for shift in (0.0, span / 3.0, 2.0 * span / 3.0):
            qx = ((xs - xs.min() + shift) * scale).astype(np.uint64)
            qy = ((ys - ys.min() + shift) * scale).astype(np.uint64)
            code = (spread(qx) << np.uint64(1)) | spread(qy)
            rank = np.lexsort((np.arange(n), code))
            for w in range(1, ZORDER_WINDOW + 1):
                pairs_i += [rank[:-w], rank[w:]]
                pairs_j += [rank[w:], rank[:-w]]
        i = np.concatenate(pairs_i)
        j = np.concatenate(pairs_j)
        keep = j != (i ^ 1)
        i, j = i[keep], j[keep]
    key = np.sort(i.astype(np.int64) * n + j)            # by (i, j)
    fresh = np.ones(len(key), dtype=bool)
    fresh[1:] = key[1:] != key[:-1]
    key = key[fresh]
    i, j = key // n, key % n
    dx = xs[i] - xs[j]
    dy = ys[i] - ys[j]
    d = np.sqrt(dx * dx + dy * dy)
    by = np.lexsort((d, i))                                 # by i, then d, then j
    i, j, d = i[by], j[by], d[by]
    first = np.searchsorted(i, np.arange(n))
    keep = np.arange(len(i)) - first[i] < keep_per_row
    i, j, d = i[keep], j[keep], d[keep]
    cuts = np.searchsorted(i, np.arange(n + 1)).tolist()
    j_list, d_list = j.tolist(), d.tolist()
    return ([j_list[cuts[u]:cuts[u + 1]] for u in range(n)],
            [d_list[cuts[u]:cuts[u + 1]] for u in range(n)])


def spread(v: np.ndarray) -> np.ndarray:
    """Bits of v (under 2^21) spread to the even bit positions (a Z-order half)."""
    v = v & np.uint64(0x1FFFFF)
    v = (v | (v << np.uint64(16))) & np.uint64(0x0000FFFF0000FFFF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x00FF00FF00FF00FF)
    v = (v | (v << np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    v = (v | (v << np.uint64(2))) & np.uint64(0x3333333333333333)
    v = (v | (v << np.uint64(1))) & np.uint64(0x5555555555555555)
    return v


class EndFinder:
    """Free fragment ends on a grid: nearest to a point, then removed."""

    def __init__(self, xs: list[float], ys: list[float], ends: list[int]) -> None:
        self.xs, self.ys = xs, ys
        self.count = len(ends)
        if not ends:
            return
        # cells from the box of every point (queries come from anywhere in it: a cell
        # sized to the ends alone once was 1 nm, and the ring search spun for minutes)
        ex, ey = xs[:1] + xs[2:], ys[:1] + ys[2:]
        span = max(max(ex) - min(ex), max(ey) - min(ey), 1.0)
        self.cell = max(span / max(int(math.sqrt(len(ends))), 1), 1.0)
        self.grid: dict[tuple[int, int], list[int]] = {}
        for u in ends:
            self.grid.setdefault(self._key(xs[u], ys[u]), []).append(u)
        self.alive = set(ends)

    def __len__(self) -> int:
        return self.count

    def _key(self, x: float, y: float) -> tuple[int, int]:
        return (math.floor(x / self.cell), math.floor(y / self.cell))

    def remove(self, u: int) -> None:
        if u in self.alive:
            self.alive.discard(u)
            self.grid[self._key(self.xs[u], self.ys[u])].remove(u)
            self.count -= 1

    def nearest(self, x: float, y: float) -> int:
        hx, hy = self._key(x, y)
        best: tuple[float, int] | None = None
        ring = 0
        while True:
            for gx in range(hx - ring, hx + ring + 1):
                edge = gx in (hx - ring, hx + ring)
                for gy in ((range(hy - ring, hy + ring + 1)) if edge else (hy - ring, hy + ring)):
                    for u in self.grid.get((gx, gy), ()):
                        dx, dy = self.xs[u] - x, self.ys[u] - y
                        key = (math.sqrt(dx * dx + dy * dy), u)
                        if best is None or key < best:
                            best = key
            if best is not None and best[0] <= ring * self.cell:
                return best[1]
            ring += 1


def distances_to(xs: list[float], ys: list[float], goals: list[tuple[int, int]]) -> list[float]:
    """Each point's distance to the nearest of `goals` (a grid of about one goal a
    cell, searched ring by ring)."""
    if not goals:
        return [0.0] * len(xs)
    gx = [float(x) for x, _y in goals]
    gy = [float(y) for _x, y in goals]
    span = max(max(gx + xs) - min(gx + xs), max(gy + ys) - min(gy + ys), 1.0)
    cell = max(span / max(int(math.sqrt(len(goals))), 1), 1.0)
    grid: dict[tuple[int, int], list[int]] = {}
    for g in range(len(goals)):
        grid.setdefault((math.floor(gx[g] / cell), math.floor(gy[g] / cell)), []).append(g)
    out = []
    for x, y in zip(xs, ys):
        hx, hy = math.floor(x / cell), math.floor(y / cell)
        best, ring = math.inf, 0
        while best > ring * cell:        # a goal farther out is over ring cells away
            for cx in range(hx - ring, hx + ring + 1):
                edge = cx in (hx - ring, hx + ring)
                for cy in (range(hy - ring, hy + ring + 1) if edge else (hy - ring, hy + ring)):
                    for g in grid.get((cx, cy), ()):
                        best = min(best, math.hypot(gx[g] - x, gy[g] - y))
            ring += 1
        out.append(best)
    return out


def near_pairs(unique: list[Point], join_nm: int) -> list[tuple[int, int, int]]:
    """(squared distance, a, b), a < b, of the distinct points within `join_nm`,
    nearest first: a grid of `join_nm` cells, only the crowded points looked at."""
    limit = join_nm * join_nm
    cell = max(join_nm, 1)
    grid: dict[tuple[int, int], list[int]] = {}
    for u in _crowded(unique, cell):
        x, y = unique[u]
        grid.setdefault((x // cell, y // cell), []).append(u)
    pairs = []
    for (cx, cy), members in grid.items():
        for dx, dy in ((0, 0), (1, -1), (1, 0), (1, 1), (0, 1)):
            others = members if dx == dy == 0 else grid.get((cx + dx, cy + dy))
            if not others:
                continue
            for a in members:
                ax, ay = unique[a]
                for b in others:
                    if dx == dy == 0 and b <= a:
                        continue
                    bx, by = unique[b]
                    d2 = (ax - bx) ** 2 + (ay - by) ** 2
                    if d2 <= limit:
                        pairs.append((d2, min(a, b), max(a, b)))
    pairs.sort()
    return pairs


def _crowded(points: list[Point], cell: int) -> list[int]:
    """Indices of the points with another point in their grid cell or a cell next
    to it (the others cannot be within a cell's width of any point)."""
    if len(points) < 2:
        return []
    xy = np.array(points, dtype=np.int64) // cell
    xy -= xy.min(axis=0)
    height = int(xy[:, 1].max()) + 3
    if (int(xy[:, 0].max()) + 3) * height >= 1 << 62:     # keys would overflow
        return list(range(len(points)))
    key = (xy[:, 0] + 1) * height + (xy[:, 1] + 1)
    occupied, count = np.unique(key, return_counts=True)
    near = np.zeros(len(points), dtype=np.int64)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            probe = key + dx * height + dy
            at = np.minimum(np.searchsorted(occupied, probe), len(occupied) - 1)
            near += np.where(occupied[at] == probe, count[at], 0)
    return np.nonzero(near > 1)[0].tolist()
