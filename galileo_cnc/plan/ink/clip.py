"""The polygon operations the fill needs, on pyclipper, in integer nm.

A polygon set is what pyclipper returns: a list of rings (lists of [x, y] or int64
arrays), outers counter-clockwise and holes clockwise, filled by the positive
winding rule (the form `DarkImage.native` has with the clipper backend). Offsets
round every curve they make within `tolerance_nm` (Clipper's ArcTolerance), so
nothing here ever leaves the integer grid.
"""

from __future__ import annotations

import itertools

import numpy as np
import pyclipper as pc

from galileo_cnc.plan.ink.edges import point_to_edges, segments_near

PolygonSet = list
#: Paths per strip in stroke_in_strips.
STROKE_STRIP = 300
#: Cells of the grid piece_owners finds a clipped piece's path on.
OWNER_CELL_NM = 500_000


def offset(polygons: PolygonSet, delta_nm: int, tolerance_nm: int, *,
           cleaned: bool = False) -> PolygonSet:
    """Grow (delta > 0) or shrink (delta < 0) the set by |delta| with round corners.

    Input and result are cleaned of vertices within a quarter of the tolerance of
    their neighbours' line: outlines made of many overlapping strokes (Eagle's
    vector-filled pours) carry tens of thousands of collinear or nearly coincident
    points that every offset keeps and Clipper's union is slow on (3 s instead of
    3 ms an offset on a real pour). `cleaned`: the input is an offset's result,
    already clean (cleaning again changes nothing and costs a sixth of the offset)."""
    if not polygons:
        return []
    if delta_nm == 0:
        return list(polygons)
    engine = pc.PyclipperOffset(2.0, float(tolerance_nm))
    engine.AddPaths(polygons if cleaned else clean(polygons, tolerance_nm), pc.JT_ROUND,
                    pc.ET_CLOSEDPOLYGON)
    return clean(engine.Execute(float(delta_nm)), tolerance_nm)


def offset_mitred(polygons: PolygonSet, delta_nm: int) -> PolygonSet:
    """Grow or shrink an already clean set by |delta| with mitred corners (limit
    2), not cleaned after: for measuring against a tolerance a few um wide, where a
    corner's shape moves nothing that counts, at 3/4 of a round offset's cost."""
    if not polygons or delta_nm == 0:
        return list(polygons)
    engine = pc.PyclipperOffset(2.0)
    engine.AddPaths(polygons, pc.JT_MITER, pc.ET_CLOSEDPOLYGON)
    return engine.Execute(float(delta_nm))


def clean(polygons: PolygonSet, tolerance_nm: int) -> PolygonSet:
    """The set without vertices that move the outline by less than tolerance / 4
    (Clipper's CleanPolygons); rings left with fewer than three points are dropped.

    A ring only a few cleaning distances thin can come out turned the other way round
    (a thin island as a hole): such a ring is kept as it was. Turned round, it would be wrong,
    and if it held the lowest vertex of the set, Clipper's offset, which orients the
    whole set by that ring, would turn every ring round and return nothing."""
    cleaned = pc.CleanPolygons(polygons, max(tolerance_nm / 4, 1.0))
    kept = []
    for before, after in zip(polygons, cleaned):    # one cleaned ring per ring, in order
        if len(after) < 3:
            continue
        kept.append(after if (pc.Area(after) > 0) == (pc.Area(before) > 0) else before)
    return kept


def stroke(paths: list, radius_nm: int, tolerance_nm: int) -> PolygonSet:
    """The area a round pen of `radius_nm` covers along open polylines (a path of one
    point is a dot)."""
    lines = [p for p in paths if len(p) >= 2]
    dots = [p for p in paths if len(p) == 1]
    engine = pc.PyclipperOffset(2.0, float(tolerance_nm))
    if lines:
        engine.AddPaths(lines, pc.JT_ROUND, pc.ET_OPENROUND)
    for dot in dots:
        x, y = (int(v) for v in dot[0])
        engine.AddPath([[x, y], [x + 1, y]], pc.JT_ROUND, pc.ET_OPENROUND)
    if not lines and not dots:
        return []
    return engine.Execute(float(radius_nm))


def stroke_in_strips(paths: list, radius_nm: int, tolerance_nm: int,
                     per_strip: int = STROKE_STRIP) -> PolygonSet:
    """`stroke`'s area as polygon sets that may overlap, one per strip of `per_strip`
    paths taken left to right: what positive winding (every boolean here) reads as
    their union. One stroke of ekf2 l1's 12k centre lines took 6.0 s, in strips of
    300 1.0 s: Clipper's union sweeps fewer edges at a time."""
    paths = [np.asarray(path, dtype=np.int64) for path in paths if len(path)]
    order = np.argsort([int(path[:, 0].min()) for path in paths], kind="stable")
    out: PolygonSet = []
    for first in range(0, len(paths), per_strip):
        out += stroke([paths[k] for k in order[first:first + per_strip]], radius_nm,
                      tolerance_nm)
    return out


def boolean(operation, subject: PolygonSet, clip: PolygonSet) -> PolygonSet:
    """Clipper's `operation` (pc.CT_...) of two sets, positive winding; degenerate
    rings (no area) are ignored."""
    clipper = pc.Pyclipper()
    added = False
    for paths, role in ((subject, pc.PT_SUBJECT), (clip, pc.PT_CLIP)):
        if paths:
            try:
                clipper.AddPaths(paths, role, True)
                added = True
            except pc.ClipperException:  # only degenerate rings (no area)
                pass
    if not added:
        return []
    return clipper.Execute(operation, pc.PFT_POSITIVE, pc.PFT_POSITIVE)


def without_repeats(path) -> np.ndarray:
    """The polyline without repeats of a point right after itself (a dot: one point)."""
    points = np.asarray(path, dtype=np.int64).reshape(-1, 2)
    if len(points) < 2:
        return points
    keep = np.ones(len(points), dtype=bool)
    keep[1:] = np.any(points[1:] != points[:-1], axis=1)
    return points[keep]


def open_difference(paths: list, polygons: PolygonSet) -> list[np.ndarray]:
    """The parts of open polylines outside the set (positive winding), as int64
    arrays; a path of one point (a dot) is kept whole or dropped."""
    if not polygons:
        return [np.asarray(path, dtype=np.int64) for path in paths]
    kept = []
    # a polyline whose points all coincide is a dot: Clipper refuses a subject of
    # zero length ("All paths are invalid for clipping")
    paths = [without_repeats(path) for path in paths]
    lines = [path for path in paths if len(path) >= 2]
    for dot in (path for path in paths if len(path) == 1):
        x, y = (int(v) for v in dot[0])
        if sum((1 if pc.Area(ring) > 0 else -1) for ring in polygons
               if pc.PointInPolygon((x, y), ring) != 0) <= 0:
            kept.append(np.array([[x, y]], dtype=np.int64))
    lines = [np.asarray(p, dtype=np.int64) for p in lines]
    flat = [p for p in lines if _flat(p)]
    steep = [p for p in lines if not _flat(p)]
    kept += _faithful(_open_outside(steep, polygons), steep, polygons)
    if flat:
        kept += _faithful([path[:, ::-1] for path in _open_outside(
            [p[:, ::-1] for p in flat], _swapped(polygons))], flat, polygons)
    return kept


def _flat(path: np.ndarray) -> bool:
    """Whether all the path's points share one y. Clipper 6 loses such an open path
    when it lies below every clip polygon (a horizontal trace or walk just under a
    drill mark): those are clipped with x and y swapped (_swapped), where they are
    vertical, and swapped back."""
    return bool((path[:, 1] == path[0, 1]).all())


def _swapped(polygons: PolygonSet) -> PolygonSet:
    """The set with x and y swapped (each ring reversed, so it keeps its winding)."""
    return [np.asarray(ring)[::-1, ::-1].tolist() for ring in polygons]


def open_difference_by_path(paths: list, polygons: PolygonSet) -> list[list[np.ndarray]]:
    """open_difference path by path: for each path, its parts outside the set. Clipper
    cuts them all at once; a path whose pieces leave it (_faithful) is cut again alone
    and exactly, not every path of the call."""
    paths = [without_repeats(path) for path in paths]
    if not polygons:
        return [[path] for path in paths]
    out: list[list[np.ndarray]] = [[] for _path in paths]
    # a dot goes in as a line 1 nm long, up from it, and is kept when any of it is:
    # Clipper sweeps a board's thousands of vias with the lines
    dots = {k for k, path in enumerate(paths) if len(path) == 1}
    paths = [np.vstack([path, path + [0, 1]]) if k in dots else path
             for k, path in enumerate(paths)]
    lines = [k for k, path in enumerate(paths) if len(path) >= 2]
    flat = [k for k in lines if _flat(paths[k])]
    steep = [k for k in lines if not _flat(paths[k])]
    swapped = _swapped(polygons) if flat else []
    for group, swap in ((steep, False), (flat, True)):
        if not group:
            continue
        subjects = [paths[k][:, ::-1] if swap else paths[k] for k in group]
        rings = swapped if swap else polygons
        pieces = _open_outside(subjects, rings)
        owners = piece_owners(pieces, subjects)
        mine: dict[int, list[np.ndarray]] = {}
        for piece, owner in zip(pieces, owners.tolist()):
            mine.setdefault(owner, []).append(piece)
        lost = bool(np.any(owners < 0))       # a piece on no path: which lost it?
        for i, k in enumerate(group):
            got = mine.get(i, [])
            if lost or not _on_paths(got, [subjects[i]]):
                got = _exact_outside(subjects[i], rings)
            out[k] = [piece[:, ::-1] for piece in got] if swap else got
    for k in dots:
        out[k] = [paths[k][:1]] if out[k] else []
    return out


def piece_owners(pieces: list[np.ndarray], paths: list[np.ndarray]) -> np.ndarray:
    """For each piece of clipped open paths, the index of the path it was cut from:
    the one nearest to the middle of its first segment (on it within Clipper's
    rounding of a cut point; of two paths drawn over each other, either), or -1 where
    none passes within OWNER_CELL_NM / 2. A piece Clipper made off its path goes to
    the nearest, whose check (_on_paths) then fails."""
    if not pieces:
        return np.zeros(0, dtype=np.int64)
    a = np.concatenate([path[:-1] for path in paths]).astype(np.int64)
    b = np.concatenate([path[1:] for path in paths]).astype(np.int64)
    owner = np.repeat(np.arange(len(paths)), [len(path) - 1 for path in paths])
    probe = np.array([(piece[0] + piece[1]) // 2 for piece in pieces], dtype=np.int64)
    # cells OWNER_CELL_NM wide: a finer grid samples long paths too often
    i, j = segments_near(probe, probe, a, b, OWNER_CELL_NM // 2)
    _t, gap = point_to_edges(probe[i].astype(np.float64), a[j], b[j])
    found = np.full(len(pieces), -1, dtype=np.int64)
    order = np.argsort(-gap)          # the nearest written last
    found[i[order]] = owner[j[order]]
    return found


def _faithful(pieces: list[np.ndarray], paths: list[np.ndarray],
              polygons: PolygonSet) -> list[np.ndarray]:
    """Clipper's pieces of `paths`, or where one leaves its path, the pieces made again
    exactly: Clipper 6 joins an open path's pieces out of order when the path passes its
    own start again, and a fill's walk round a via's pad came back with a corner cut
    across the via's drill mark (minnowmax-80101's bottom)."""
    if _on_paths(pieces, paths):
        return pieces
    return [piece for path in paths for piece in _exact_outside(path, polygons)]


def _on_paths(pieces: list[np.ndarray], paths: list[np.ndarray]) -> bool:
    """Whether each piece runs along the paths it was cut from: two of its points that
    are both the paths' points are neighbours on a path, and a cut point lies on a
    segment from its neighbour point (within 2 nm)."""
    if not pieces:
        return True
    edges, incident = set(), {}
    for path in paths:
        points = [tuple(p) for p in path.tolist()]
        for u, v in zip(points, points[1:]):
            edges.add(u + v)
            edges.add(v + u)
            incident.setdefault(u, []).append(v)
            incident.setdefault(v, []).append(u)
    for piece in pieces:
        points = [tuple(p) for p in piece.tolist()]
        for u, v in zip(points, points[1:]):
            if u + v in edges:
                continue
            known_u, known_v = u in incident, v in incident
            if known_u and known_v:
                return False
            if known_u or known_v:
                w, c = (u, v) if known_u else (v, u)
                if not any(_on_segment(c, w, o) for o in incident[w]):
                    return False
    return True


def _on_segment(c: tuple, a: tuple, b: tuple, slack_nm: float = 2.0) -> bool:
    """Whether point c lies on segment a-b within `slack_nm`."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    length = (dx * dx + dy * dy) ** 0.5
    if length == 0:
        return False
    cx, cy = c[0] - a[0], c[1] - a[1]
    along = (cx * dx + cy * dy) / length
    return abs(cx * dy - cy * dx) / length <= slack_nm and -slack_nm <= along <= length + slack_nm


def _exact_outside(path: np.ndarray, polygons: PolygonSet) -> list[np.ndarray]:
    """The parts of one polyline outside the set (positive winding), cut where its
    segments cross the rings' edges: each segment is split at the crossings and each
    stretch kept by its midpoint's winding; kept stretches that meet are one piece."""
    a = path[:-1].astype(np.float64)
    b = path[1:].astype(np.float64)
    low, high = np.minimum(a, b), np.maximum(a, b)
    segs, params = [np.arange(len(a)), np.arange(len(a))], [np.zeros(len(a)), np.ones(len(a))]
    rings = [np.asarray(ring, dtype=np.float64) for ring in polygons]
    for ring in rings:
        r0, r1 = ring.min(axis=0), ring.max(axis=0)
        near = np.flatnonzero((high[:, 0] >= r0[0]) & (low[:, 0] <= r1[0])
                              & (high[:, 1] >= r0[1]) & (low[:, 1] <= r1[1]))
        if not len(near):
            continue
        p, e = ring, np.roll(ring, -1, axis=0) - ring
        for chunk in np.array_split(near, max(1, len(near) * len(ring) // 1_000_000 + 1)):
            d = (b[chunk] - a[chunk])[:, None, :]
            w = p[None, :, :] - a[chunk][:, None, :]
            den = d[..., 0] * e[None, :, 1] - d[..., 1] * e[None, :, 0]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (w[..., 0] * e[None, :, 1] - w[..., 1] * e[None, :, 0]) / den
                u = (w[..., 0] * d[..., 1] - w[..., 1] * d[..., 0]) / den
            hit = (den != 0) & (t > 0) & (t < 1) & (u >= 0) & (u <= 1)
            si, ej = np.nonzero(hit)
            segs.append(chunk[si])
            params.append(t[si, ej])
    seg, t = np.concatenate(segs), np.concatenate(params)
    order = np.lexsort((t, seg))
    seg, t = seg[order], t[order]
    same = seg[1:] == seg[:-1]
    s, t0, t1 = seg[:-1][same], t[:-1][same], t[1:][same]
    length = t1 > t0
    s, t0, t1 = s[length], t0[length], t1[length]
    mid = a[s] + ((t0 + t1) / 2)[:, None] * (b[s] - a[s])
    winding = np.zeros(len(mid), dtype=np.int64)
    for ring in rings:
        winding += _winding(ring, mid)
    keep = winding <= 0
    s, t0, t1 = s[keep], t0[keep], t1[keep]
    if not len(s):
        return []
    joined = np.zeros(len(s), dtype=bool)
    joined[1:] = ((s[1:] == s[:-1]) & (t0[1:] == t1[:-1])) | \
        ((s[1:] == s[:-1] + 1) & (t1[:-1] == 1) & (t0[1:] == 0))
    starts = np.round(a[s] + t0[:, None] * (b[s] - a[s])).astype(np.int64)
    ends = np.round(a[s] + t1[:, None] * (b[s] - a[s])).astype(np.int64)
    pieces = []
    for first, last in zip(np.flatnonzero(~joined), [*np.flatnonzero(~joined)[1:], len(s)]):
        piece = without_repeats(np.vstack([starts[first:first + 1], ends[first:last]]))
        if len(piece) >= 2:
            pieces.append(piece)
    return pieces


def _winding(ring: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Per point, the ring's winding number about it (counter-clockwise: +1)."""
    x, y = points[:, 0], points[:, 1]
    winding = np.zeros(len(points), dtype=np.int64)
    r0, r1 = ring.min(axis=0), ring.max(axis=0)
    inside_box = np.flatnonzero((x >= r0[0]) & (x <= r1[0]) & (y >= r0[1]) & (y <= r1[1]))
    if not len(inside_box):
        return winding
    px, py = x[inside_box][:, None], y[inside_box][:, None]
    x0, y0 = ring[:, 0][None, :], ring[:, 1][None, :]
    x1, y1 = np.roll(ring[:, 0], -1)[None, :], np.roll(ring[:, 1], -1)[None, :]
    side = (x1 - x0) * (py - y0) - (px - x0) * (y1 - y0)
    up = (y0 <= py) & (y1 > py) & (side > 0)
    down = (y1 <= py) & (y0 > py) & (side < 0)
    winding[inside_box] = up.sum(axis=1) - down.sum(axis=1)
    return winding


def _open_outside(lines: list[np.ndarray], polygons: PolygonSet) -> list[np.ndarray]:
    """Clipper's difference of open polylines and a polygon set (positive winding)."""
    if not lines:
        return []
    clipper = pc.Pyclipper()
    clipper.AddPaths([p.tolist() for p in lines], pc.PT_SUBJECT, False)
    clipper.AddPaths(polygons, pc.PT_CLIP, True)
    tree = clipper.Execute2(pc.CT_DIFFERENCE, pc.PFT_POSITIVE, pc.PFT_POSITIVE)
    kept = [np.array(path, dtype=np.int64) for path in pc.OpenPathsFromPolyTree(tree)
            if len(path) >= 2]
    free_tree(tree)
    return kept


def union(*sets: PolygonSet) -> PolygonSet:
    return boolean(pc.CT_UNION, [ring for s in sets for ring in s], [])


def difference(subject: PolygonSet, clip: PolygonSet) -> PolygonSet:
    if not subject or not clip:
        return list(subject)
    return boolean(pc.CT_DIFFERENCE, subject, clip)


def intersection(subject: PolygonSet, clip: PolygonSet) -> PolygonSet:
    if not subject or not clip:
        return []
    return boolean(pc.CT_INTERSECTION, subject, clip)


def opening(polygons: PolygonSet, radius_nm: int, tolerance_nm: int) -> PolygonSet:
    """What is left of the set where a disc of `radius_nm` fits: slivers thinner
    than 2 * radius (rounding noise between two outlines) disappear."""
    return offset(offset(polygons, -radius_nm, tolerance_nm), radius_nm, tolerance_nm,
                  cleaned=True)


def area_nm2(polygons: PolygonSet) -> float:
    return float(sum(pc.Area(ring) for ring in polygons))


def rings_as_arrays(polygons: PolygonSet) -> list[np.ndarray]:
    """Each ring as an int64 (n, 2) array; rings of fewer than 3 points dropped. Every
    coordinate read in one pass: half the time of an array per ring (hellboard's 250k
    ring vertices)."""
    return _arrays([ring for ring in polygons if len(ring) >= 3])


def _arrays(rings: list) -> list[np.ndarray]:
    """Each ring ([x, y] lists) as an int64 (n, 2) array, every coordinate read in one
    pass."""
    if not rings:
        return []
    sizes = np.array([len(ring) for ring in rings], dtype=np.int64)
    flat = np.fromiter(itertools.chain.from_iterable(itertools.chain.from_iterable(rings)),
                       dtype=np.int64, count=2 * int(sizes.sum())).reshape(-1, 2)
    return np.split(flat, np.cumsum(sizes)[:-1])


def components(polygons: PolygonSet, strict: bool = False
               ) -> list[tuple[np.ndarray, list[np.ndarray]]]:
    """The set's connected pieces: (outer ring, [hole rings]), an island inside a
    hole being a piece of its own. `strict`: no ring touches itself or another at a
    vertex (valid OGC polygons)."""
    if not polygons:
        return []
    clipper = pc.Pyclipper()
    clipper.StrictlySimple = strict
    try:
        clipper.AddPaths(polygons, pc.PT_SUBJECT, True)
    except pc.ClipperException:
        return []
    tree = clipper.Execute2(pc.CT_UNION, pc.PFT_POSITIVE, pc.PFT_POSITIVE)
    pieces = []                  # (outer, holes) contours, then made arrays at once
    stack = list(tree.Childs)
    while stack:
        outer = stack.pop()
        holes = []
        for hole in outer.Childs:
            holes.append(hole.Contour)
            stack.extend(hole.Childs)
        pieces.append((outer.Contour, holes))
    free_tree(tree)
    arrays = iter(_arrays([ring for outer, holes in pieces for ring in (outer, *holes)]))
    return [(next(arrays), [next(arrays) for _ in holes]) for _outer, holes in pieces]


def free_tree(tree) -> None:
    """Take a PolyTree apart: each node points to its parent and its children, a
    cycle that only the cycle collector would free (with every contour point a list
    of its own: hellboard's copper, 270k lists), and the planner pauses it
    (plan/collector.py). Without the links reference counting frees it all."""
    stack = [tree]
    while stack:
        node = stack.pop()
        stack.extend(node.Childs)
        node.Childs = []
        node.Parent = None


def strips(polygons: PolygonSet, most_vertices: int,
           pieces: list[tuple[np.ndarray, list[np.ndarray]]] | None = None
           ) -> list[list[np.ndarray]]:
    """The set's islands (outer ring and holes) sorted by left edge, in runs of at
    most `most_vertices` outline vertices (a bigger island is a run of its own).
    `pieces`: components(polygons), where the caller has them already."""
    pieces = list(components(polygons) if pieces is None else pieces)
    pieces.sort(key=lambda piece: (int(piece[0][:, 0].min()), int(piece[0][:, 1].min())))
    strips, strip, count = [], [], 0
    for outer, holes in pieces:
        size = len(outer) + sum(len(h) for h in holes)
        if strip and count + size > most_vertices:
            strips.append(strip)
            strip, count = [], 0
        strip.extend([outer, *holes])
        count += size
    if strip:
        strips.append(strip)
    return strips
