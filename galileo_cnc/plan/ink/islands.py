"""Copper islands, and the places where two come closer than the pens can keep apart.

Ink never joins two islands the artwork keeps apart. Two inks a few um apart are one
line on the board (ink bleeds; the stepped path strays up to 4.4 um from the planned
one), so everything the pens draw keeps CLEARANCE_NM between the inks of different
islands:

- centre lines keep it from other islands' copper and lines (narrow.py);
- fills reach their island's edge, so where another island comes within
  CLEARANCE_NM of that edge (pads 30 um apart on ekf2's power planes, 33 um on the
  led-display's pad grid) both sides are cut back: `close_places` finds the stretches
  of outline that near another island, and the fill keeps its ink half the clearance
  behind them (`fill_region(keep_out=...)`), so the two inks end at least the
  clearance plus the copper's own gap apart.

Two segments that do not cross are nearest at an end of one of them, so every close
stretch has an outline vertex within the clearance of the other island: the search
asks, for every vertex, which other islands' edges lie that near, then cuts out of
both edges the part within the clearance of the other (exact, per pair).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.edges import EdgeIndex, point_to_edges

#: Gap kept between the ink of different islands (see the module doc).
CLEARANCE_NM = 50_000
#: Islands this close are one: copper that touches at a vertex (Clipper keeps it as
#: two pieces), or a sliver of a gap under a motor step (OrCAD's plane splits of
#: 2.5 um, 1.7 um on ekf2) that no board house etches and no pen can draw.
TOUCH_NM = 5_000


@dataclass
class Islands:
    """The copper's connected pieces: (outer ring, holes) each, and every ring with
    the island it belongs to."""

    parts: list[tuple[np.ndarray, list[np.ndarray]]]
    rings: list[np.ndarray]
    owner: np.ndarray            # island number of each ring

    @classmethod
    def of(cls, copper: list) -> "Islands":
        parts = clip.components(copper)
        rings, owner = [], []
        for number, (outer, holes) in enumerate(parts):
            for ring in (outer, *holes):
                rings.append(ring)
                owner.append(number)
        return cls(parts, rings, np.array(owner, dtype=np.int64))


@dataclass
class ClosePlaces:
    """Where islands come closer than the clearance."""

    stretches: list[np.ndarray]   # (2, 2) int64: outline parts within the clearance of another island
    count: int                    # island pairs that close
    closest_nm: float             # the smallest gap
    at_nm: tuple[int, int] | None             # a point of the closest gap, on one island
    other_nm: tuple[int, int] | None          # and the nearest point of the other


def close_places(islands: Islands, clearance_nm: int = CLEARANCE_NM) -> ClosePlaces:
    """The stretches of outline within `clearance_nm` of another island (module doc)."""
    none = ClosePlaces([], 0, float("inf"), None, None)
    if len(islands.parts) < 2:
        return none
    index = EdgeIndex(islands.rings, cell_nm=clearance_nm)
    owner = islands.owner[index.ring]
    # a cell is the clearance: every other island's edge that near a vertex is found
    vertex, edge = index.around_vertices(owner)
    if not len(vertex):
        return none
    _t, gap = point_to_edges(index.a[vertex].astype(np.float64), index.a[edge], index.b[edge])
    # islands that touch are one: no ink parts them, near the touch or elsewhere
    touch = gap < TOUCH_NM
    joined = _joined(len(islands.parts), owner[vertex[touch]], owner[edge[touch]])
    close = (gap < clearance_nm) & (joined[owner[vertex]] != joined[owner[edge]])
    vertex, edge, gap = vertex[close], edge[close], gap[close]
    if not len(vertex):
        return none
    # the two edges that meet at each vertex, each against the other island's edge
    before = _edge_before(index, vertex)
    mine = np.concatenate([vertex, before])
    theirs = np.concatenate([edge, edge])
    stretches = []
    for ours, other in ((mine, theirs), (theirs, mine)):
        lo, hi = _within(index.a[ours], index.b[ours], index.a[other], index.b[other],
                         clearance_nm)
        keep = lo <= hi
        a, d = index.a[ours][keep].astype(np.float64), (index.b[ours] - index.a[ours])[keep]
        ends = np.stack([a + d * lo[keep, None], a + d * hi[keep, None]], axis=1)
        stretches.append(np.rint(ends).astype(np.int64))
    # a stretch is found from each vertex near it: keep one of each
    stretches = list(np.unique(np.concatenate(stretches).reshape(-1, 4), axis=0).reshape(-1, 2, 2))
    pairs = {tuple(sorted(p)) for p in zip(joined[owner[vertex]].tolist(),
                                           joined[owner[edge]].tolist())}
    best = int(np.argmin(gap))
    t, _d = point_to_edges(index.a[vertex[best]].astype(np.float64),
                           index.a[edge[best]:edge[best] + 1], index.b[edge[best]:edge[best] + 1])
    a, b = index.a[edge[best]], index.b[edge[best]]
    other = a + (b - a) * t[0]
    return ClosePlaces(stretches, len(pairs), float(gap[best]),
                       (int(index.a[vertex[best]][0]), int(index.a[vertex[best]][1])),
                       (int(round(other[0])), int(round(other[1]))))


def keep_back(places: ClosePlaces, distance_nm: int, tolerance_nm: int) -> list:
    """The area within `distance_nm` of the close stretches (a polygon set)."""
    return clip.stroke(places.stretches, distance_nm, tolerance_nm) if places.stretches else []


def _joined(count: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Each island's representative once the pairs (a[k], b[k]) are joined."""
    parent = np.arange(count)

    def root(n: int) -> int:
        while parent[n] != n:
            parent[n] = parent[parent[n]]
            n = parent[n]
        return n

    for x, y in zip(a.tolist(), b.tolist()):
        parent[root(x)] = root(y)
    return np.array([root(n) for n in range(count)], dtype=np.int64)


def _edge_before(index: EdgeIndex, vertex: np.ndarray) -> np.ndarray:
    """The edge that ends at each vertex (the ring's previous edge, wrapping round)."""
    ring, number = index.ring[vertex], index.edge[vertex]
    last = np.searchsorted(index.ring, ring, "right") - 1
    return np.where(number == 0, last, vertex - 1)


def _within(a: np.ndarray, b: np.ndarray, fa: np.ndarray, fb: np.ndarray, reach: int
            ) -> tuple[np.ndarray, np.ndarray]:
    """For segments a-b and f = fa-fb (arrays of pairs): the interval [lo, hi] of t in
    [0, 1] where a + t (b - a) lies within `reach` of f (lo > hi: nowhere). The points
    within reach of a segment form a convex stadium (two discs and a rectangle), so
    the interval is the union of the line's intervals in the three."""
    a, d = a.astype(np.float64), (b - a).astype(np.float64)
    fa, fb = fa.astype(np.float64), fb.astype(np.float64)
    lo, hi = np.full(len(a), np.inf), np.full(len(a), -np.inf)
    dd = np.einsum("ij,ij->i", d, d)
    for q in (fa, fb):                                 # the discs round f's ends
        w = a - q
        half_b = np.einsum("ij,ij->i", w, d)
        c = np.einsum("ij,ij->i", w, w) - float(reach) ** 2
        disc = half_b ** 2 - dd * c
        ok = (disc >= 0) & (dd > 0)
        root = np.sqrt(np.where(ok, disc, 0.0))
        safe = np.where(dd > 0, dd, 1.0)
        lo = np.where(ok, np.minimum(lo, (-half_b - root) / safe), lo)
        hi = np.where(ok, np.maximum(hi, (-half_b + root) / safe), hi)
    f = fb - fa
    length = np.hypot(f[:, 0], f[:, 1])
    u = f / np.where(length > 0, length, 1.0)[:, None]
    w = a - fa
    # along f within [0, length], across it within (-reach, reach): two slabs
    s0, s1 = np.einsum("ij,ij->i", w, u), np.einsum("ij,ij->i", d, u)
    p0 = w[:, 0] * u[:, 1] - w[:, 1] * u[:, 0]
    p1 = d[:, 0] * u[:, 1] - d[:, 1] * u[:, 0]
    r_lo, r_hi = _slab(s0, s1, 0.0, length)
    q_lo, q_hi = _slab(p0, p1, -float(reach), float(reach))
    r_lo, r_hi = np.maximum(r_lo, q_lo), np.minimum(r_hi, q_hi)
    ok = (length > 0) & (r_lo <= r_hi)
    lo = np.where(ok, np.minimum(lo, r_lo), lo)
    hi = np.where(ok, np.maximum(hi, r_hi), hi)
    return np.maximum(lo, 0.0), np.minimum(hi, 1.0)


def _slab(start: np.ndarray, rate: np.ndarray, low, high) -> tuple[np.ndarray, np.ndarray]:
    """The t interval where start + t * rate lies in [low, high] (all t, or none, when
    the rate is 0)."""
    moving = rate != 0
    safe = np.where(moving, rate, 1.0)
    t0, t1 = (low - start) / safe, (high - start) / safe
    inside = (start >= low) & (start <= high)
    lo = np.where(moving, np.minimum(t0, t1), np.where(inside, -np.inf, np.inf))
    hi = np.where(moving, np.maximum(t0, t1), np.where(inside, np.inf, -np.inf))
    return lo, hi
