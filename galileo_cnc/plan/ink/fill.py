"""Fill a copper area with one round pen: concentric rings, joined into one path per island.

For a pen of width w (radius r) and a region C (integer nm polygons):

1. **Rings.** E0 = C shrunk by r (plus a small edge margin, so the stepped path
   does not bleed over the edge) is where the pen's centre may go; its outline is
   ring depth 0. E(k+1) = E(k) shrunk by the spacing s; every outline of every
   E(k) is a ring. Ink = the rings swept by the pen's disc, so everything within r
   of a ring is inked.
2. **Joins.** A point q inside E(k) and the point p of E(k)'s outline nearest to
   it are joined by a segment that stays inside E(k): the open disc around q
   through p holds no outline point. So each ring of depth k+1 is joined to the
   rings of depth k its vertices are nearest to, by such segments; those joins
   are pen-down moves that keep the ink inside the copper. A spanning tree of
   rings and joins (shortest joins first) is drawn as one path: walk a ring, at
   each join cross over, walk that ring (and its joins) and come back. An island
   costs one pen lift, not one per ring; the price is drawing each join twice.
3. **Gaps.** With spacing s > r a point can be more than r from every ring:
   beside sharp corners of the inner ring, and along the middle of the last one.
   The gaps are found exactly (the reach C shrunk and grown by r, minus the ink,
   opened by GAP_NM to drop rounding slivers) and each gets a stroke along its
   long axis, clipped to E0. Spacing could be r and leave no gaps, at twice the
   ink; the bench measures the trade (docs/ink.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pyclipper as pc

from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.edges import EdgeIndex

#: Share of the pen width that neighbouring rings overlap: spacing = width * (1 - overlap).
DEFAULT_OVERLAP = 0.2
#: Gaps thinner than twice this are rounding slivers, not gaps (a pen shows nothing there).
GAP_NM = 5_000
#: Vertices of a ring tried as ends of joins to the rings around it: one per JOIN_EVERY
#: spacings of its length, at least JOIN_SAMPLES and at most JOIN_MOST.
JOIN_SAMPLES, JOIN_EVERY, JOIN_MOST = 12, 8, 256
#: Outline vertices per batch of islands filled together (fill_region).
BATCH_VERTICES = 4_000


@dataclass
class PenFill:
    """What one pen draws in one region: paths drawn pen-down, each after one lift."""

    width_nm: int
    paths: list[np.ndarray] = field(default_factory=list)   # int64 (n, 2) polylines
    rings: int = 0
    gap_strokes: int = 0
    ink: list = field(default_factory=list)                 # polygon set the pen covers


def fill_region(region: list, width_nm: int, tolerance_nm: int, *,
                overlap: float = DEFAULT_OVERLAP, edge_margin_nm: int = 0,
                batch_vertices: int = BATCH_VERTICES) -> PenFill:
    """Rings, gap strokes and joins of one pen over `region` (a polygon set).

    Islands never share ink, so they are filled in batches of neighbours (see
    `island_batches`): each polygon operation then sweeps a few islands, not the
    board (Clipper's sweep slows with every outline a scanline crosses)."""
    fill = PenFill(width_nm)
    for batch in island_batches(region, batch_vertices):
        part = _fill_batch(batch, width_nm, tolerance_nm, overlap, edge_margin_nm)
        fill.paths.extend(part.paths)
        fill.rings += part.rings
        fill.gap_strokes += part.gap_strokes
        fill.ink.extend(part.ink)       # disjoint: each batch's ink stays in its islands
    return fill


def island_batches(region: list, most_vertices: int = BATCH_VERTICES) -> list[list]:
    """The region's islands (outer ring and holes) as polygon sets of neighbours: sorted
    by left edge and cut into runs of at most `most_vertices` (an island bigger than
    that is a batch of its own), so a batch is a narrow vertical strip of the board."""
    pieces = clip.components(region)
    pieces.sort(key=lambda piece: (int(piece[0][:, 0].min()), int(piece[0][:, 1].min())))
    batches, batch, count = [], [], 0
    for outer, holes in pieces:
        size = len(outer) + sum(len(h) for h in holes)
        if batch and count + size > most_vertices:
            batches.append(batch)
            batch, count = [], 0
        batch.extend([outer, *holes])
        count += size
    if batch:
        batches.append(batch)
    return batches


def _fill_batch(region: list, width_nm: int, tolerance_nm: int, overlap: float,
                edge_margin_nm: int) -> PenFill:
    radius = width_nm // 2
    spacing = max(int(round(width_nm * (1.0 - overlap))), 1)
    fill = PenFill(width_nm)
    centre_area = clip.offset(region, -(radius + edge_margin_nm), tolerance_nm)
    if not centre_area:
        return fill
    areas = _concentric(centre_area, spacing, tolerance_nm)
    depths = [clip.rings_as_arrays(area) for area in areas]
    fill.rings = sum(len(rings) for rings in depths)
    gaps = _gaps(areas, radius, tolerance_nm)
    reach = clip.offset(centre_area, radius, tolerance_nm)
    fill.ink = clip.difference(reach, gaps)
    gaps = clip.opening(gaps, GAP_NM, tolerance_nm)
    strokes = _gap_strokes(gaps, centre_area, radius) if gaps else []
    fill.gap_strokes = len(strokes)
    if strokes:
        fill.ink = clip.union(fill.ink, clip.stroke(strokes, radius, tolerance_nm))
    fill.paths = _tours(depths, strokes, spacing)
    return fill


def _concentric(centre_area: list, spacing: int, tolerance_nm: int) -> list[list]:
    """E0, E1, ... (polygon sets), until nothing is left."""
    areas = []
    area = centre_area
    while area and clip.rings_as_arrays(area):
        areas.append(area)
        area = clip.offset(area, -spacing, tolerance_nm)
    return areas


# ---- joins and the walk ---------------------------------------------------------------

@dataclass
class _Stop:
    """A join's end on a ring: on edge `edge` at parameter t, point `point`."""

    edge: int
    t: float
    point: tuple[int, int]
    join: int          # the join's number
    other: int         # the ring node at the join's other end


def _tours(depths: list[list[np.ndarray]], strokes: list[np.ndarray],
           spacing: int) -> list[np.ndarray]:
    """One pen-down polyline per tree of rings and gap strokes (see the module doc).

    A gap stroke is walked there and back, joined at its first point to the nearest
    point of any ring: that point is inside E0 and no outline of E0 is nearer to it
    than the ring point, so the join stays inside E0 too."""
    rings = [ring for at_depth in depths for ring in at_depth]
    nodes = rings + strokes
    first_node = np.cumsum([0] + [len(at_depth) for at_depth in depths])
    joins = []          # (length, node a, stop on a, node b, stop on b)
    if strokes and rings:
        every_ring = EdgeIndex(rings, cell_nm=spacing)
        for number, path in enumerate(strokes):
            q = (int(path[0][0]), int(path[0][1]))
            k, t, distance = every_ring.nearest(q, spacing)
            joins.append((distance, len(rings) + number, (0, 0.0, q), int(every_ring.ring[k]),
                          (int(every_ring.edge[k]), t, _point_on(every_ring, k, t))))
    for depth in range(1, len(depths)):
        outer = EdgeIndex(depths[depth - 1], cell_nm=spacing)
        for number, ring in enumerate(depths[depth]):
            node = int(first_node[depth]) + number
            best: dict[int, tuple] = {}       # outer ring -> the shortest join to it
            for vertex in _samples(ring, spacing):
                q = (int(ring[vertex][0]), int(ring[vertex][1]))
                found = outer.nearest(q, spacing)
                if found is None:
                    continue
                k, t, distance = found
                target = int(first_node[depth - 1]) + int(outer.ring[k])
                if target not in best or distance < best[target][0]:
                    best[target] = (distance, (vertex, 0.0, q),
                                    (int(outer.edge[k]), t, _point_on(outer, k, t)))
            for target, (distance, here, there) in best.items():
                joins.append((distance, node, here, target, there))
    stops: list[list[_Stop]] = [[] for _ in nodes]
    parent = list(range(len(nodes)))

    def root(n: int) -> int:
        while parent[n] != n:
            parent[n] = parent[parent[n]]
            n = parent[n]
        return n

    joins.sort(key=lambda j: (j[0], j[1], j[3]))
    for number, (_d, a, here, b, there) in enumerate(joins):
        ra, rb = root(a), root(b)
        if ra == rb:
            continue                       # already joined: a second join would make a loop
        parent[ra] = rb
        stops[a].append(_Stop(*here, join=number, other=b))
        stops[b].append(_Stop(*there, join=number, other=a))

    tours = []
    done = [False] * len(nodes)
    for start in range(len(nodes)):       # outermost rings first: each tree from its top
        if not done[start]:
            tours.append(_walk_tree(start, nodes, stops, done))
    return tours


def _point_on(index: EdgeIndex, k: int, t: float) -> tuple[int, int]:
    a, b = index.a[k], index.b[k]
    return (int(round(a[0] + (b[0] - a[0]) * t)), int(round(a[1] + (b[1] - a[1]) * t)))


def _samples(ring: np.ndarray, spacing: int) -> list[int]:
    """Vertices spread evenly along the ring by length (arcs have many vertices, long
    straight sides few): one per JOIN_EVERY spacings, at least JOIN_SAMPLES."""
    edges = np.hypot(*np.diff(np.vstack([ring, ring[:1]]), axis=0).astype(np.float64).T)
    along = np.concatenate([[0.0], np.cumsum(edges)[:-1]])
    count = int(min(max(along[-1] + edges[-1], 0) / (JOIN_EVERY * spacing), JOIN_MOST))
    count = max(count, JOIN_SAMPLES)
    if len(ring) <= count:
        return list(range(len(ring)))
    wanted = np.linspace(0.0, along[-1] + edges[-1], count, endpoint=False)
    return sorted(set(np.searchsorted(along, wanted, side="right").clip(1, len(ring)) - 1))


def _walk_tree(start: int, nodes: list[np.ndarray], stops: list[list[_Stop]],
               done: list[bool]) -> np.ndarray:
    """The tree of rings holding `start`, drawn as one closed walk from its vertex 0."""
    points: list[tuple[int, int]] = []
    stack = [_walk_ring(start, None, nodes[start], stops[start])]
    done[start] = True
    while stack:
        item = next(stack[-1], None)
        if item is None:
            stack.pop()
        elif isinstance(item, _Stop):       # cross the join, walk the ring behind it
            done[item.other] = True
            back = next(s for s in stops[item.other] if s.join == item.join)
            stack.append(_walk_ring(item.other, back, nodes[item.other], stops[item.other]))
        else:
            points.append(item)
    path = np.array(points, dtype=np.int64)
    keep = np.ones(len(path), dtype=bool)
    keep[1:] = np.any(path[1:] != path[:-1], axis=1)
    return path[keep]


def _walk_ring(node: int, entry: _Stop | None, ring: np.ndarray, stops: list[_Stop]):
    """Yield the ring's points once round from `entry` back to it, and at every other
    stop: the stop's point, the stop (to cross), and its point again (come back)."""
    count = len(ring)
    events = [((k, 0.0, 0), (int(ring[k][0]), int(ring[k][1]))) for k in range(count)]
    for stop in stops:
        edge, t = stop.edge, stop.t
        if t >= 1.0:
            edge, t = (edge + 1) % count, 0.0
        events.append(((edge, t, 1), stop))
    events.sort(key=lambda e: e[0])
    begin = 0 if entry is None else next(k for k, e in enumerate(events) if e[1] is entry)
    ordered = events[begin:] + events[:begin]
    first = ordered[0][1]
    first_point = first.point if isinstance(first, _Stop) else first
    yield first_point
    for _key, what in ordered[1:]:
        if isinstance(what, _Stop):
            yield what.point
            yield what
            yield what.point
        else:
            yield what
    yield first_point


# ---- gaps ----------------------------------------------------------------------------

def _gaps(areas: list[list], radius: int, tolerance_nm: int) -> list:
    """Where no ring comes within r: inside E(k) deeper than r, and farther than r from
    E(k+1) (rings outside E(k) are farther still, rings inside E(k+1) too)."""
    gaps = []
    for depth, area in enumerate(areas):
        deep = clip.offset(area, -radius, tolerance_nm)
        if not deep:
            continue
        inner = areas[depth + 1] if depth + 1 < len(areas) else []
        gaps.extend(clip.difference(deep, clip.offset(inner, radius, tolerance_nm)))
    return clip.union(gaps)


def _gap_strokes(gaps: list, centre_area: list, radius: int) -> list[np.ndarray]:
    """A stroke along each gap's long axis, ends pulled in by up to r/2, kept inside E0."""
    segments = []
    for outer, _holes in clip.components(gaps):
        points = outer.astype(np.float64)
        centre = points.mean(axis=0)
        spread = points - centre
        _values, vectors = np.linalg.eigh(spread.T @ spread)
        axis = vectors[:, -1]
        along = spread @ axis
        low, high = float(along.min()), float(along.max())
        pull = min(radius / 2, (high - low) / 2)
        a, b = centre + axis * (low + pull), centre + axis * (high - pull)
        a, b = np.rint(a).astype(np.int64), np.rint(b).astype(np.int64)
        if np.array_equal(a, b):
            b = a + np.array([1, 0])
        segments.append([a.tolist(), b.tolist()])
    clipper = pc.Pyclipper()
    clipper.AddPaths(segments, pc.PT_SUBJECT, False)
    try:
        clipper.AddPaths(centre_area, pc.PT_CLIP, True)
    except pc.ClipperException:
        return []
    tree = clipper.Execute2(pc.CT_INTERSECTION, pc.PFT_NONZERO, pc.PFT_POSITIVE)
    return [np.asarray(path, dtype=np.int64) for path in pc.OpenPathsFromPolyTree(tree)
            if len(path) >= 2]
