"""Native arcs for pen paths: runs of polyline vertices on one circle become arcs.

The ink planner's pen paths are pyclipper polylines, and every round pad or rounded
corner in them is a run of short chords whose vertices lie on a circle (to the
nanometre of rounding, or to pyclipper's ArcTolerance for its round joins). The
plotter's firmware draws arcs natively, and one arc is much faster to plot than the
dozens of short lines it replaces. `fit_arcs` finds those runs:

1. **Triples.** For every inner vertex, the circle through it and its two
   neighbours (all in one numpy pass). A triple is usable when the points turn,
   the radius is at most `MAX_RADIUS_NM` and each of its edges turns by less
   than 90 degrees about the centre.
2. **Chains.** Neighbouring triples are linked when they turn the same way and
   the fourth point lies within the tolerance of the first one's circle; a
   maximal run of linked triples is a chain, a candidate arc (neighbouring
   chains share a triple's edges: the earlier chain keeps them).
3. **Pieces.** A chain is cut into equal pieces of at most about 260 degrees of
   estimated sweep (the sum of the turning angles), so a full circle becomes two
   arcs or more and an arc's start never equals its end.
4. **Check.** Each piece gets the circle through its first, middle and last
   vertex, its centre rounded to the nanometre, and is checked against the
   guarantees below (all pieces at once, with numpy). Almost every piece of a
   real outline passes. One that fails (a curve that is no circle, such as an
   ellipse or a spiral, or a chain that took in a vertex of the next straight)
   is grown again greedily from its start: the longest run whose circle fits
   becomes an arc if it is curved enough, and the search goes on from its end;
   edges from which no run of `min_edges` fits stay lines.

What every arc guarantees (each is checked, none is assumed): it replaces at least
`min_edges` consecutive edges and ends on input vertices; every vertex it replaces
and every replaced edge's midpoint (so each chord's sagitta) lies within
`tolerance_nm` of the arc, measured from the integer centre and widened by the
difference between the start and end radii (the planner draws from start to end
around the centre); the vertices' angles about the centre progress one way, each
edge by more than 0 and less than 90 degrees, at most 270 degrees in all; the
radius is at most 1 m and the arc's sagitta over its sweep exceeds the tolerance,
so a straight run (even one with vertex noise below the tolerance) stays lines.
Everything else is a LINE to the next vertex; collinear lines are not merged. A
closed path is drawn from points[0] and back, so an arc through points[0] is cut
there (a remainder shorter than `min_edges` stays lines).

Floats are used only to decide (coordinates are exact in them below 2^53 nm);
every returned coordinate is an input vertex and every centre an integer offset
from its arc's start.
"""

from __future__ import annotations

import math

import numpy as np

from galileo_cnc.program.ops import OpKind

_LINE, _CW, _CCW = int(OpKind.LINE), int(OpKind.ARC_CW), int(OpKind.ARC_CCW)
#: No larger radius: a nearly straight run is lines, never a 1 m bulge of an arc.
MAX_RADIUS_NM = 1_000_000_000
#: One arc turns at most this far, so a circle is two arcs or more and no arc has
#: start == end (which the planner would read as a full circle).
MAX_SWEEP = 1.5 * math.pi
#: Chains are cut into pieces of about this sweep: below MAX_SWEEP, so an uneven
#: polygon whose estimate is a little short still passes the check.
_PIECE_SWEEP = math.radians(260)
#: End points tried at once when a failed piece is grown again.
_BATCH = 32

Segment = tuple[int, int, int, int, int]
Arc = tuple[int, int, int, int, int]        # (start index, end index, kind, i, j)


def fit_arcs(points: np.ndarray, tolerance_nm: int = 1000, closed: bool = False,
             min_edges: int = 4) -> list[tuple[int, int, int, int, int]]:
    """Segments (kind, x, y, i, j) drawn from points[0] that replace each run of at
    least `min_edges` edges on a common circle by an arc (see the module docstring
    for the guarantees); a closed path ends back at points[0]."""
    path = np.asarray(points, dtype=np.int64)
    if path.ndim != 2 or path.shape[1] != 2:
        raise ValueError(f"points must be an (n, 2) array, got shape {path.shape}")
    if len(path) < (3 if closed else 2):
        raise ValueError(f"a {'closed' if closed else 'open'} path needs more than "
                         f"{len(path)} points")
    if tolerance_nm <= 0:
        raise ValueError(f"tolerance must be positive, got {tolerance_nm} nm")
    if min_edges < 2:
        raise ValueError(f"an arc needs at least 2 edges, got min_edges={min_edges}")
    if closed:
        # an arc cannot run through points[0], where the path starts and ends
        path = np.concatenate([path, path[:1]])
    # complex coordinates: exact (integers below 2^53), and the geometry reads short
    z = np.ascontiguousarray(path, dtype=np.float64).view(np.complex128).ravel()
    return _segments(path, _arcs(z, tolerance_nm, min_edges))


def _arcs(z: np.ndarray, tol: int, min_edges: int) -> list[Arc]:
    """The arcs of an open path (complex points), in order."""
    starts, ends = _pieces(z, tol, min_edges)
    if not len(starts):
        return []
    fits, curved, ccw, ij = _check(z, starts, ends, tol)
    arcs: list[Arc] = []
    for s, e, good, left, (i, j) in zip(starts.tolist(), ends.tolist(),
                                        (fits & curved).tolist(), ccw.tolist(), ij.tolist()):
        if good:
            arcs.append((s, e, _CCW if left else _CW, i, j))
        else:
            arcs.extend(_regrow(z, s, e, tol, min_edges))
    return arcs


def _circumcentre(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Centre of the circle through 0, a and b (complex); inf or nan when collinear."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return ((a.real ** 2 + a.imag ** 2) * b - (b.real ** 2 + b.imag ** 2) * a) / (
            2j * (a.conj() * b).imag)


def _pieces(z: np.ndarray, tol: int, min_edges: int) -> tuple[np.ndarray, np.ndarray]:
    """(start, end) point indices of the candidate arcs: chains of triples on one
    circle, cut into pieces of at most about `_PIECE_SWEEP`."""
    none = np.zeros(0, np.int64)
    if len(z) < 3:
        return none, none
    # each inner vertex's triple: vectors to its neighbours, the circle through them
    a, b = z[:-2] - z[1:-1], z[2:] - z[1:-1]
    ab = a.conj() * b                                  # imag: cross, real: dot
    centre = _circumcentre(a, b)
    with np.errstate(invalid="ignore"):
        radius = np.abs(centre)
        # usable: turns (else nan or inf), radius capped, each chord turns by less
        # than 90 degrees about the centre (shorter than r sqrt 2)
        limit = radius * math.sqrt(2.0)
        good = (radius <= MAX_RADIUS_NM) & (np.abs(a) < limit) & (np.abs(b) < limit)
    if not good.any():
        return none, none
    # link neighbouring triples: same turn, and the fourth point on the first's circle
    with np.errstate(invalid="ignore"):
        off = np.abs(np.abs(z[3:] - z[1:-2] - centre[:-1]) - radius[:-1])
    link = good[:-1] & good[1:] & ((ab.imag[:-1] > 0) == (ab.imag[1:] > 0)) & (off <= tol)
    # chains: maximal runs of linked triples [first, stop); triple t is vertex t + 1,
    # so a chain covers points first .. stop + 1
    cut = np.flatnonzero(~link) + 1
    first = np.concatenate([[0], cut])
    stop = np.concatenate([cut, [len(good)]])
    keep = good[first] & (stop + 1 - first >= min_edges)
    first, stop = first[keep], stop[keep]
    # neighbouring chains share up to two edges (a triple's points): the earlier keeps them
    start = np.maximum(first, np.concatenate([[0], stop[:-1] + 1]))
    keep = stop + 1 - start >= min_edges
    start, stop = start[keep], stop[keep]
    if not len(start):
        return none, none
    # estimated sweep: the turning angles, plus half an edge's at either end
    turn = np.abs(np.angle(-ab))
    total = np.concatenate([[0.0], np.cumsum(turn)])
    sweep = total[stop] - total[start] + 0.5 * (turn[start] + turn[stop - 1])
    edges = stop + 1 - start
    count = np.minimum(np.ceil(sweep / _PIECE_SWEEP), edges // min_edges)
    count = np.maximum(count, 1).astype(np.int64)
    # cut each chain into `count` pieces of (nearly) equal edge counts
    chain = np.repeat(np.arange(len(start)), count)
    k = np.arange(len(chain)) - np.repeat(np.cumsum(count) - count, count)
    n, c, s = edges[chain], count[chain], start[chain]
    return s + n * k // c, s + n * (k + 1) // c


def _check(z: np.ndarray, start: np.ndarray, end: np.ndarray,
           tol: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For each piece start[k] .. end[k]: (does its circle fit within the guarantees
    but for curvature, is its sagitta above the tolerance, is it counter-clockwise,
    its integer centre relative to its start as (i, j)). An arc needs both of the
    first two; growing a run only adds sagitta, so they are apart for `_regrow`."""
    p0 = z[start]
    # circle through the first, middle and last vertex, centre rounded to the nm
    u = _circumcentre(z[(start + end) // 2] - p0, z[end] - p0)
    finite = np.isfinite(u) & (np.abs(u) <= 2.0 * MAX_RADIUS_NM)
    u = np.where(finite, u, 0.0)
    ij = np.rint(np.stack([u.real, u.imag], axis=1)).astype(np.int64)
    u = ij[:, 0] + 1j * ij[:, 1]
    centre = p0 + u
    r_start, r_end = np.abs(u), np.abs(z[end] - centre)
    # every replaced edge of every piece, flattened; `first` is each piece's first edge
    n = end - start
    first = np.cumsum(n) - n
    piece = np.repeat(np.arange(len(n)), n)
    edge = np.arange(len(piece)) - first[piece] + start[piece]
    v0, v1 = z[edge] - centre[piece], z[edge + 1] - centre[piece]
    r = r_start[piece]
    off = np.maximum(np.abs(np.abs(v1) - r), np.abs(np.abs(v0 + v1) * 0.5 - r))
    w = v0.conj() * v1                                # imag: cross, real: dot
    worst = np.maximum.reduceat(off, first)
    ccw = np.minimum.reduceat(w.imag, first) > 0
    cw = np.maximum.reduceat(w.imag, first) < 0
    sweep = np.abs(np.add.reduceat(np.angle(w), first))
    # the arc's sagitta over its whole sweep: real curvature, not a noisy straight run
    sagitta = 2.0 * r_start * np.sin(sweep / 4.0) ** 2
    fits = (finite & (ccw | cw) & (np.minimum.reduceat(w.real, first) > 0)
            & (sweep <= MAX_SWEEP) & (r_start <= MAX_RADIUS_NM)
            & (worst + np.abs(r_end - r_start) <= tol))
    return fits, sagitta > tol, ccw, ij


def _regrow(z: np.ndarray, s0: int, e0: int, tol: int, min_edges: int) -> list[Arc]:
    """Arcs within a piece that failed the check, greedily: from each start whose
    `min_edges` fit a circle, the longest run that fits (`_BATCH` end points tried
    per call), an arc if it is curved enough, then on from its end; edges no arc
    starts from stay lines."""
    # which starts fit at least the shortest run: one call for the whole piece
    firsts = np.arange(s0, e0 - min_edges + 1)
    if not len(firsts):
        return []
    fits, curved, ccw, ij = _check(z, firsts, firsts + min_edges, tol)
    arcs: list[Arc] = []
    here = s0
    for k in np.flatnonzero(fits).tolist():
        s = int(firsts[k])
        if s < here:
            continue                                   # inside the last arc
        lo, hi = s + min_edges, e0 + 1                 # lo fits, hi is out of reach
        best = (bool(curved[k]), bool(ccw[k]), ij[k].tolist())
        while hi - lo > 1:
            # up to _BATCH end points spread over (lo, reach): at most 4 times as far
            # as the arc reaches so far, so the work stays in proportion to the arc
            reach = min(hi, s + 4 * (lo - s) + 1)
            ends = np.unique(np.rint(np.linspace(lo + 1, reach - 1, min(_BATCH, reach - lo - 1)))
                             .astype(np.int64))
            passed, bent, left, centres = _check(z, np.full(len(ends), s), ends, tol)
            if not passed.any():
                hi = int(ends[0])
                continue
            b = int(np.flatnonzero(passed)[-1])
            lo, best = int(ends[b]), (bool(bent[b]), bool(left[b]), centres[b].tolist())
            hi = int(ends[b + 1]) if b + 1 < len(ends) else hi
        if best[0]:
            arcs.append((s, lo, _CCW if best[1] else _CW, *best[2]))
            here = lo
    return arcs


def _segments(path: np.ndarray, arcs: list[Arc]) -> list[Segment]:
    """The segments from path[0]: a LINE to each vertex that no arc replaces."""
    points = path.tolist()
    out: list[Segment] = []
    here = 0
    for s, e, kind, i, j in arcs:
        out.extend((_LINE, x, y, 0, 0) for x, y in points[here + 1:s + 1])
        out.append((kind, points[e][0], points[e][1], i, j))
        here = e
    out.extend((_LINE, x, y, 0, 0) for x, y in points[here + 1:])
    return out
