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

`fit_paths` does the same for all pen paths of a fill in one pass (same answers):
the paths lie end to end in one array and each numpy step runs once for all. It
can hold each vertex to a tolerance of its own (an arc to the smallest of its
vertices'): the fill's inner rings are offset with a coarser one (fill.py).

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


def fit_arcs(points: np.ndarray, tolerance_nm: int = 1000, closed: bool = False,
             min_edges: int = 4) -> list[tuple[int, int, int, int, int]]:
    """Segments (kind, x, y, i, j) drawn from points[0] that replace each run of at
    least `min_edges` edges on a common circle by an arc (see the module docstring
    for the guarantees); a closed path ends back at points[0]."""
    _check_options(tolerance_nm, min_edges)
    return _as_tuples(_fit_many([_open_path(points, closed)], tolerance_nm, min_edges)[0])


def fit_paths(paths: list[np.ndarray], tolerance_nm: int = 1000,
              min_edges: int = 4, coarse: list[np.ndarray] | None = None,
              rows: bool = False) -> list[list[Segment] | np.ndarray | None]:
    """`fit_arcs` for many pen paths at once, with the same answers: a path of one
    point is a dot (None), one of more than 3 points that ends where it starts is
    closed. All paths go through each numpy step together (a fill's thousands of
    short paths would otherwise cost a few dozen numpy calls each). `coarse`: per
    path, a tolerance per vertex (nm, at least `tolerance_nm`: the one its ring was
    offset with); an arc is held to the smallest of its vertices'. `rows`: each path's
    segments as an (k, 5) int64 array (kind, x, y, i, j) instead of tuples."""
    _check_options(tolerance_nm, min_edges)
    found: list[list[Segment] | None] = [None] * len(paths)
    drawn = [k for k, path in enumerate(paths) if len(path) != 1]
    opened, tolerances = [], []
    for k in drawn:
        path = np.asarray(paths[k], dtype=np.int64)
        closed = len(path) > 3 and np.array_equal(path[0], path[-1])
        opened.append(_open_path(path[:-1] if closed else path, closed))
        if coarse is not None:
            tol = np.maximum(np.asarray(coarse[k], dtype=np.float64), tolerance_nm)
            tolerances.append(np.concatenate([tol[:-1], tol[:1]]) if closed else tol)
    for k, segments in zip(drawn, _fit_many(opened, tolerance_nm, min_edges,
                                            tolerances if coarse is not None else None)):
        found[k] = segments if rows else _as_tuples(segments)
    return found


def _as_tuples(rows: np.ndarray) -> list[Segment]:
    return list(map(tuple, rows.tolist()))


def _check_options(tolerance_nm: int, min_edges: int) -> None:
    if tolerance_nm <= 0:
        raise ValueError(f"tolerance must be positive, got {tolerance_nm} nm")
    if min_edges < 2:
        raise ValueError(f"an arc needs at least 2 edges, got min_edges={min_edges}")


def _open_path(points: np.ndarray, closed: bool) -> np.ndarray:
    """The points as an int64 path drawn open (a closed one with points[0] again at the end)."""
    path = np.asarray(points, dtype=np.int64)
    if path.ndim != 2 or path.shape[1] != 2:
        raise ValueError(f"points must be an (n, 2) array, got shape {path.shape}")
    if len(path) < (3 if closed else 2):
        raise ValueError(f"a {'closed' if closed else 'open'} path needs more than "
                         f"{len(path)} points")
    # an arc cannot run through points[0] of a closed path, where it starts and ends
    return np.concatenate([path, path[:1]]) if closed else path


def _fit_many(paths: list[np.ndarray], tol: int, min_edges: int,
              tolerances: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """The segments of each open path, as rows (_segments). The paths are laid end to
    end in one array of complex points (exact: integers below 2^53), a NaN between
    neighbours: no triple through a NaN is usable, so no chain crosses from one path
    into the next."""
    if not paths:
        return []
    sizes = np.array([len(path) for path in paths], dtype=np.int64)
    offsets = np.cumsum(sizes + 1) - (sizes + 1)
    # the paths end to end, one row between neighbours (the NaN's place in z)
    points = np.zeros((int(sizes.sum() + len(paths) - 1), 2), dtype=np.int64)
    for path, at in zip(paths, offsets.tolist()):
        points[at:at + len(path)] = path
    z = points.astype(np.float64).view(np.complex128).ravel()
    z[offsets[1:] - 1] = np.nan + 0j
    if tolerances is not None:          # per vertex (NaN gaps: the base tolerance)
        each = np.full(len(z), float(tol))
        for t, at in zip(tolerances, offsets.tolist()):
            each[at:at + len(t)] = t
        tol = each
    return _segments(points, offsets, sizes, *_arcs(z, tol, min_edges, offsets, sizes))


def _arcs(z: np.ndarray, tol: int | np.ndarray, min_edges: int, offsets: np.ndarray,
          sizes: np.ndarray) -> tuple[np.ndarray, ...]:
    """The arcs of the paths laid out in z (see `_fit_many`) as arrays, in no
    particular order (no two overlap): start and end point indices, kind, centre i
    and j."""
    starts, ends = _pieces(z, tol, min_edges, offsets, sizes)
    if not len(starts):
        return (np.zeros(0, np.int64),) * 5
    fits, curved, ccw, ij = _check(z, starts, ends, tol)
    good = fits & curved
    failed = np.flatnonzero(~good)
    # a piece that failed is grown again within itself: its arcs replace it
    s, e, left, centre = _regrow(z, starts[failed], ends[failed], tol, min_edges)
    s = np.concatenate([starts[good], s])
    e = np.concatenate([ends[good], e])
    kind = np.where(np.concatenate([ccw[good], left]), _CCW, _CW)
    centre = np.concatenate([ij[good], centre])
    return s, e, kind, centre[:, 0], centre[:, 1]


def _circumcentre(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Centre of the circle through 0, a and b (complex); inf or nan when collinear."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return ((a.real ** 2 + a.imag ** 2) * b - (b.real ** 2 + b.imag ** 2) * a) / (
            2j * (a.conj() * b).imag)


def _pieces(z: np.ndarray, tol: int | np.ndarray, min_edges: int, offsets: np.ndarray,
            sizes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
    if not np.isscalar(tol):            # the smallest of the four points' tolerances
        tol = np.minimum(np.minimum(tol[:-3], tol[1:-2]), np.minimum(tol[2:-1], tol[3:]))
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
    # summed along each path by itself (the triples of the path at o are o .. o + n - 3)
    total = np.zeros(len(turn) + 1)
    for at, n in zip(offsets.tolist(), sizes.tolist()):
        if n >= 3:
            total[at + 1:at + n - 1] = np.cumsum(turn[at:at + n - 2])
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
           tol: int | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
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
    if not np.isscalar(tol):            # the smallest of the piece's vertices' tolerances
        tol = np.minimum.reduceat(np.minimum(tol[edge], tol[edge + 1]), first)
    # the arc's sagitta over its whole sweep: real curvature, not a noisy straight run
    sagitta = 2.0 * r_start * np.sin(sweep / 4.0) ** 2
    fits = (finite & (ccw | cw) & (np.minimum.reduceat(w.real, first) > 0)
            & (sweep <= MAX_SWEEP) & (r_start <= MAX_RADIUS_NM)
            & (worst + np.abs(r_end - r_start) <= tol))
    return fits, sagitta > tol, ccw, ij


def _regrow(z: np.ndarray, s0: np.ndarray, e0: np.ndarray, tol: int | np.ndarray,
            min_edges: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Arcs within each piece s0[k] .. e0[k] that failed the check, greedily: from
    each start whose `min_edges` fit a circle, the longest run that fits (`_BATCH`
    end points tried per step), an arc if it is curved enough, then on from its
    end; edges no arc starts from stay lines. Arrays of their starts, ends, whether
    counter-clockwise, and (k, 2) centres (i, j), in no particular order.

    The pieces are grown side by side, each step one `_check` call for all of them
    (state in arrays, one entry per piece), not one call per piece and step."""
    no_arcs = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, bool),
               np.zeros((0, 2), np.int64))
    # a piece of min_edges edges has one start, the piece itself, which failed
    longer = np.flatnonzero(e0 - s0 > min_edges)
    if not len(longer):
        return no_arcs
    s0, e0 = s0[longer], e0[longer]
    # which starts fit at least the shortest run: one call for every piece
    counts = e0 - min_edges + 1 - s0
    piece = np.repeat(np.arange(len(s0)), counts)
    firsts = np.arange(len(piece)) - np.repeat(np.cumsum(counts) - counts, counts) + s0[piece]
    fits, curved, ccw, ij = _check(z, firsts, firsts + min_edges, tol)
    keep = np.flatnonzero(fits)
    # fitting starts, in path order; piece p owns F[bound[p]:bound[p + 1]]
    start_at, start_bent, start_left, start_ij = firsts[keep], curved[keep], ccw[keep], ij[keep]
    bound = np.searchsorted(piece[keep], np.arange(len(s0) + 1))
    n = len(s0)
    here = s0.copy()                          # no arc starts before here
    cursor = bound[:-1].copy()                # the next fitting start to try
    s = np.full(n, -1, np.int64)              # the start being grown (-1: none)
    lo = np.zeros(n, np.int64)                # s .. lo fits
    hi = np.zeros(n, np.int64)                # s .. hi is out of reach
    best_bent = np.zeros(n, bool)
    best_left = np.zeros(n, bool)
    best_ij = np.zeros((n, 2), np.int64)
    found = []                                # (piece, s, e, ccw, i, j) arrays, in time order
    while True:
        # finish runs that cannot grow, take the next start where none is grown
        for _ in range(3):
            ended = (s >= 0) & (hi - lo <= 1)
            kept = ended & best_bent
            if kept.any():
                w = np.flatnonzero(kept)
                found.append((w, s[w], lo[w], best_left[w], best_ij[w]))
                here[w] = lo[w]
            s[ended] = -1
            idle = np.flatnonzero(s < 0)
            if not len(idle):
                break
            # skip the starts inside the last arc
            at = np.maximum(cursor[idle], np.searchsorted(start_at, here[idle], "left"))
            live = at < bound[idle + 1]
            cursor[idle] = np.minimum(at, bound[idle + 1])
            w, at = idle[live], at[live]
            if not len(w):
                break
            s[w], lo[w], hi[w] = start_at[at], start_at[at] + min_edges, e0[w] + 1
            best_bent[w], best_left[w], best_ij[w] = start_bent[at], start_left[at], start_ij[at]
            cursor[w] = at + 1
        grow = np.flatnonzero((s >= 0) & (hi - lo > 1))
        if not len(grow):
            break
        # up to _BATCH end points spread over (lo, reach): at most 4 times as far as the
        # arc reaches so far, so the work stays in proportion to the arc (np.linspace's
        # arithmetic, then np.unique's, for all pieces at once)
        gs, glo, ghi = s[grow], lo[grow], hi[grow]
        reach = np.minimum(ghi, gs + 4 * (glo - gs) + 1)
        a, b = glo + 1, reach - 1
        num = np.minimum(_BATCH, reach - glo - 1)
        owner = np.repeat(np.arange(len(grow)), num)
        k = np.arange(len(owner)) - np.repeat(np.cumsum(num) - num, num)
        div = (num - 1)[owner]
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(div > 0, (b - a)[owner] / np.maximum(div, 1), 0.0)
        value = k * step + a[owner]
        value = np.where(k == div, b[owner], value)
        ends = np.rint(value).astype(np.int64)
        distinct = np.ones(len(ends), bool)
        distinct[1:] = (ends[1:] != ends[:-1]) | (owner[1:] != owner[:-1])
        ends, owner = ends[distinct], owner[distinct]
        passed, bent, left, centres = _check(z, gs[owner], ends, tol)
        groups = np.searchsorted(owner, np.arange(len(grow) + 1))
        index = np.arange(len(ends))
        last = np.maximum.reduceat(np.where(passed, index, -1), groups[:-1])
        none = last < 0
        hi[grow[none]] = ends[groups[:-1][none]]
        w, b_ = grow[~none], last[~none]
        lo[w], best_bent[w], best_left[w], best_ij[w] = ends[b_], bent[b_], left[b_], centres[b_]
        more = b_ + 1 < groups[1:][~none]
        hi[w[more]] = ends[b_[more] + 1]
    if not found:
        return no_arcs
    return tuple(np.concatenate([arcs[k] for arcs in found]) for k in range(1, 5))


def _segments(points: np.ndarray, offsets: np.ndarray, sizes: np.ndarray, s: np.ndarray,
              e: np.ndarray, kind: np.ndarray, i: np.ndarray, j: np.ndarray
              ) -> list[np.ndarray]:
    """Per path (laid out as in `_fit_many`, `points` its int64 vertices), the segments
    from its first point as (k, 5) rows kind, x, y, i, j: a LINE to each vertex that no
    arc (starts s, ends e) replaces, an arc's row at its end vertex (the vertices inside
    it left out). All paths at once: a fill's walk has 200k vertices."""
    count = len(points)
    kinds = np.full(count, _LINE, dtype=np.int64)
    centre_i = np.zeros(count, dtype=np.int64)
    centre_j = np.zeros(count, dtype=np.int64)
    kinds[e], centre_i[e], centre_j[e] = kind, i, j
    # vertices s + 1 .. e - 1 are replaced
    inside = np.bincount(s + 1, minlength=count + 1) - np.bincount(e, minlength=count + 1)
    keep = np.cumsum(inside[:count]) == 0
    keep[offsets] = False                            # each path drawn from its first point
    keep[offsets[1:] - 1] = False                    # the rows between paths
    rows = np.column_stack([kinds, points, centre_i, centre_j])[keep]
    path = np.repeat(np.arange(len(sizes)), sizes + 1)[:count]
    kept = np.bincount(path[keep], minlength=len(sizes))
    return np.split(rows, np.cumsum(kept)[:-1])
