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
from galileo_cnc.plan.ink.background import Deferred
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
#: A batch whose pen-centre area has this many vertices has its gap tests done in a
#: forked process (background.py): a fork costs milliseconds, this many vertices'
#: gap tests a few tenths of a second.
BACKGROUND_VERTICES = 20_000
#: Share of the gap tests below depth 0 done after the joins, not in the second
#: process (the deepest depths): with the joins' edge index compiled, hellboard's pour
#: waited 0.6 s for that process; from concentric rings to gap strokes it took 1.4 s
#: at 0.45, 1.55 s at 0.3 and 1.65 s at 0.6 (two runs each)
MAIN_GAP_SHARE = 0.45
#: The rings inside E0 and the gap tests are offset with this many times the tolerance
#: (E0 keeps it: it runs along the copper's edge), and those rings' arcs are fitted to
#: it: 16 um at the ink's 2 um (inking.INK_TOLERANCE_NM), far inside the 60 um by which
#: neighbouring rings overlap. At 1 um, 4 um took hellboard's fill from 11 to 7 s CPU
#: and 344k to 140k rows, 8 um (and the deep rings started from E0 cleaned to it) 140k
#: to 127k rows; each time eight or ten layers measured from the steps inked within
#: 0.012 % of before, and the corpus at 2 um (16 um here) as at 1 um (docs/ink.md,
#: "Measured on the corpus").
DEEP_TOLERANCE = 8


@dataclass
class InkRecipe:
    """What one batch's ink is made of: the pen-centre area E0 swept by the pen (its
    reach), less the gaps, plus the gap strokes. Only the coverage figures and the
    next, narrower pen need that polygon set, and on a large pour it costs a tenth of
    the planning (the reach is a dilation of a 100k-vertex outline), so it is made
    when asked for (`ink`), not while filling. The coverage needs only its area
    where no other ink meets the batch (`area_nm2`)."""

    centre_area: list
    gaps: list
    strokes: list[np.ndarray]
    radius_nm: int
    tolerance_nm: int
    #: ink_area_nm2, worked out meanwhile in a second process on a large batch
    area: Deferred | float | None = None
    _ink: list | None = field(default=None, repr=False)

    @property
    def has_ink(self) -> bool:
        """Whether `ink()` was made already (a narrower pen needed it)."""
        return self._ink is not None

    def ink(self) -> list:
        if self._ink is None:
            ink = clip.difference(self._reach(), self.gaps)
            if self.strokes:
                ink = clip.union(ink, self._strokes_ink())
            self._ink = ink
        return self._ink

    def ink_area_nm2(self) -> float:
        """The area of `ink()` without making it: the reach, less the gaps (which lie
        inside it), plus what the gap strokes ink in the gaps (their ink lies inside
        the reach). Two thirds less Clipper work than the polygons; the same area to
        within 2e-9 on hellboard."""
        if not self.centre_area:
            return 0.0
        area = clip.area_nm2(self._reach()) - clip.area_nm2(self.gaps)
        if self.strokes:
            area += clip.area_nm2(clip.intersection(self._strokes_ink(), self.gaps))
        return area

    def _reach(self) -> list:
        """Where the pen's disc reaches with its centre anywhere in E0."""
        return clip.offset(self.centre_area, self.radius_nm, self.tolerance_nm, cleaned=True)

    def _strokes_ink(self) -> list:
        return clip.stroke(self.strokes, self.radius_nm, self.tolerance_nm)

    def area_nm2(self) -> float:
        """ink_area_nm2, from the second process where one works it out."""
        if isinstance(self.area, Deferred):
            self.area = self.area.result()
        if self.area is None:
            self.area = self.ink_area_nm2()
        return self.area


@dataclass
class PenFill:
    """What one pen draws in one region: paths drawn pen-down, each after one lift."""

    width_nm: int
    paths: list[np.ndarray] = field(default_factory=list)   # int64 (n, 2) polylines
    rings: int = 0
    gap_strokes: int = 0
    coarse: list = field(default_factory=list)  # per path: each vertex's tolerance (nm)
    recipes: list = field(default_factory=list)  # (batch of the region, its InkRecipe)

    @property
    def parts(self) -> list:
        """(batch of the region, its ink): see inked_area_nm2."""
        return [(batch, recipe.ink()) for batch, recipe in self.recipes]

    @property
    def ink(self) -> list:
        """The polygon set the pen covers (the batches' inks are disjoint)."""
        return [ring for _batch, ink in self.parts for ring in ink]

    def with_coarse(self, tolerance_nm: int) -> None:
        """`coarse` for every path (each vertex `tolerance_nm`) where the fill kept none,
        before paths are added or changed (InkPaths.add_strokes, necks.spliced)."""
        if len(self.coarse) != len(self.paths):
            self.coarse = [np.full(len(path), tolerance_nm) for path in self.paths]

    def settled(self) -> "PenFill":
        """This fill with its recipes' areas asked for (a forked process sends it back:
        nothing in it may wait on a process of its own)."""
        for _batch, recipe in self.recipes:
            if isinstance(recipe.area, Deferred):
                recipe.area_nm2()
        return self


def fill_region(region: list, width_nm: int, tolerance_nm: int, *,
                overlap: float = DEFAULT_OVERLAP, edge_margin_nm: int = 0,
                batch_vertices: int = BATCH_VERTICES, keep_out: list | None = None,
                islands: list | None = None,
                area_unless_near: np.ndarray | None = None) -> PenFill:
    """Rings, gap strokes and joins of one pen over `region` (a polygon set).

    `keep_out`: a polygon set the ink stays out of (where two islands come too close
    to keep their inks apart, islands.py): the pen's centre keeps its radius from it.
    `islands`: clip.components(region), where the caller has them already.
    `area_unless_near`: boxes (x0, y0, x1, y1) of other ink; a large batch none of them
    meets has its ink's area worked out meanwhile (InkRecipe.area), for the coverage.
    Islands never share ink, so they are filled in batches of neighbours (see
    `island_batches`): each polygon operation then sweeps a few islands, not the
    board (Clipper's sweep slows with every outline a scanline crosses)."""
    fill = PenFill(width_nm)
    avoid = clip.offset(keep_out, width_nm // 2, tolerance_nm) if keep_out else []
    boxes = boxes_of(avoid)
    batches = [(batch, [avoid[k] for k in meeting(boxes, batch).tolist()],
                area_unless_near is not None and not len(meeting(area_unless_near, batch)))
               for batch in island_batches(region, batch_vertices, islands)]
    if not batches:
        return fill
    # the batches are independent: the later half of the work is done in a forked
    # process meanwhile (background.py), the parts joined in batch order. A batch's
    # work grows faster than its outline (LimeSDR GTL: 45k vertices 6 s CPU, 4k 0.13 s):
    # it is weighed as vertices ** 1.5
    sizes = np.array([sum(len(ring) for ring in batch) for batch, _near, _area in batches])
    work = np.cumsum(sizes.astype(np.float64) ** 1.5)
    half = int(np.searchsorted(work, work[-1] / 2)) + 1
    forked = half < len(batches) and sizes.sum() >= BACKGROUND_VERTICES
    later = Deferred(_fill_batches, batches[half:], width_nm, tolerance_nm, overlap,
                     edge_margin_nm, forked, fork=forked)
    try:
        parts = _fill_batches(batches[:half], width_nm, tolerance_nm, overlap,
                              edge_margin_nm) + later.result()
    finally:
        later.cancel()
    for part in parts:
        fill.paths.extend(part.paths)
        fill.coarse.extend(part.coarse)
        fill.rings += part.rings
        fill.gap_strokes += part.gap_strokes
        fill.recipes.extend(part.recipes)    # disjoint: each batch's ink stays in its islands
    return fill


def inked_area_nm2(fills: list[PenFill], extra: list, region: list,
                   skip: list[bool] | None = None) -> float:
    """area_nm2(intersection(union(every fill's ink, extra), region)), where fills[0]
    filled `region` itself, batch by batch: a batch's ink stays inside its islands
    (the pen's centre keeps r + margin from the edge), so it meets no other batch;
    the other pens' ink and `extra` (few rings) go to the batches whose box they
    meet (a ring that misses a batch's box cannot wind around a point in it), and a
    batch they miss counts its recipe's area. Clipper's sweep then crosses one strip
    of islands at a time, not the board. `skip`: per batch of fills[0], left out
    (another process counts it: inking.Coverage)."""
    if not fills or not fills[0].recipes:
        rest = [ring for f in fills for ring in f.ink] + list(extra)
        return clip.area_nm2(clip.intersection(clip.union(rest), region)) if rest else 0.0
    others = _other_ink(fills, extra)
    boxes = boxes_of(others)
    total = 0.0
    for number, (batch, recipe) in enumerate(fills[0].recipes):
        if skip is not None and skip[number]:
            continue
        near = [others[k] for k in meeting(boxes, batch).tolist()]
        if near or recipe.has_ink:      # the polygons' area where they are made anyway
            total += clip.area_nm2(clip.intersection(list(recipe.ink()) + near, batch))
        else:
            total += recipe.area_nm2()
    return total


def met_by_other_ink(fills: list[PenFill], extra_boxes: np.ndarray) -> list[bool]:
    """Per batch of fills[0]: whether the other pens' ink or one of `extra_boxes` (x0,
    y0, x1, y1) meets its box, so its coverage needs the polygons."""
    if not fills or not fills[0].recipes:
        return []
    boxes = np.concatenate([boxes_of(_other_ink(fills, [])),
                            extra_boxes.reshape(-1, 4).astype(np.int64)])
    return [len(meeting(boxes, batch)) > 0 for batch, _recipe in fills[0].recipes]


def _other_ink(fills: list[PenFill], extra: list) -> list[np.ndarray]:
    """The narrower pens' ink rings and `extra`'s, as arrays (those of 3 points or more)."""
    others = [np.asarray(ring, dtype=np.int64) for f in fills[1:] for ring in f.ink]
    others += [np.asarray(ring, dtype=np.int64) for ring in extra]
    return [ring for ring in others if len(ring) >= 3]


def boxes_of(rings: list, grown_nm: int = 0) -> np.ndarray:
    """(x0, y0, x1, y1) of each ring (or polyline), grown by `grown_nm` on every side."""
    rings = [np.asarray(ring, dtype=np.int64) for ring in rings]
    return np.array([[*(ring.min(axis=0) - grown_nm), *(ring.max(axis=0) + grown_nm)]
                     for ring in rings], dtype=np.int64) \
        if rings else np.zeros((0, 4), dtype=np.int64)


def meeting(boxes: np.ndarray, batch: list) -> np.ndarray:
    """Indices of the boxes that meet the batch's box."""
    low = np.min([ring.min(axis=0) for ring in batch], axis=0)
    high = np.max([ring.max(axis=0) for ring in batch], axis=0)
    return np.flatnonzero((boxes[:, 0] <= high[0]) & (boxes[:, 2] >= low[0])
                          & (boxes[:, 1] <= high[1]) & (boxes[:, 3] >= low[1]))


def island_batches(region: list, most_vertices: int = BATCH_VERTICES,
                   islands: list | None = None) -> list[list]:
    """The region's islands (outer ring and holes) as polygon sets of neighbours: sorted
    by left edge and cut into runs of at most `most_vertices` (an island bigger than
    that is a batch of its own), so a batch is a narrow vertical strip of the board.
    `islands`: clip.components(region), where the caller has them already."""
    return clip.strips(region, most_vertices, islands)


def _fill_batches(batches: list[tuple[list, list, bool]], width_nm: int, tolerance_nm: int,
                  overlap: float, edge_margin_nm: int, settled: bool = False) -> list[PenFill]:
    """The batches' fills; `settled` where they are sent to another process."""
    fills = [_fill_batch(batch, width_nm, tolerance_nm, overlap, edge_margin_nm, near, area)
             for batch, near, area in batches]
    return [fill.settled() for fill in fills] if settled else fills


def _fill_batch(region: list, width_nm: int, tolerance_nm: int, overlap: float,
                edge_margin_nm: int, avoid: list, area_meanwhile: bool = False) -> PenFill:
    radius = width_nm // 2
    spacing = max(int(round(width_nm * (1.0 - overlap))), 1)
    fill = PenFill(width_nm)
    centre_area = clip.offset(region, -(radius + edge_margin_nm), tolerance_nm)
    if centre_area and avoid:
        centre_area = clip.difference(centre_area, avoid)
    if not centre_area:
        fill.recipes = [(region, InkRecipe([], [], [], radius, tolerance_nm))]   # no ink
        return fill
    deep = tolerance_nm * DEEP_TOLERANCE
    # E0's own ring keeps the fine tolerance (it runs along the copper's edge); the
    # rings inside it and the gap tests start from E0 cleaned to theirs, which drops
    # half its vertices (chords of arcs at the fine tolerance; hellboard at 1 um:
    # 122k -> 58k) and two thirds of the first offset's work
    start = clip.clean(centre_area, deep) or centre_area
    first = clip.offset(start, -spacing, deep, cleaned=True)
    big = sum(len(ring) for ring in centre_area) >= BACKGROUND_VERTICES
    # the gap tests (a third of a large pour's fill) in second processes: depth 0's
    # (the largest) while the deeper rings are made, then most of the others while the
    # joins between the rings are made here; the deepest ones, their union and their
    # strokes here after the joins. The same result either way
    outermost = Deferred(_gaps, [start, first], radius, deep, 0, 1, fork=big)
    deeper = None
    try:
        coarse = [start] + _concentric(first, spacing, deep)
        areas = [centre_area] + coarse[1:]
        split = _gap_split(coarse)
        deeper = Deferred(_gaps, coarse, radius, deep, 1, split, fork=big)
        depths = [clip.rings_as_arrays(area) for area in areas]
        fill.rings = sum(len(rings) for rings in depths)
        # where the gap strokes join, and (a depth of it at a time) the rings
        every_ring = EdgeIndex([ring for at_depth in depths for ring in at_depth],
                               cell_nm=spacing)
        ring_joins = _ring_joins(depths, spacing, every_ring)
        deepest = _gaps(coarse, radius, deep, split)
        gaps, strokes = _gap_work(outermost.result() + deeper.result() + deepest,
                                  centre_area, radius, tolerance_nm)
    finally:
        outermost.cancel()
        if deeper is not None:
            deeper.cancel()
    fill.gap_strokes = len(strokes)
    recipe = InkRecipe(centre_area, gaps, strokes, radius, tolerance_nm)
    # the coverage figures' share of a large batch (a second of Clipper on hellboard's
    # pour) in a second process, which is free while the walks and the rows are made
    recipe.area = Deferred(recipe.ink_area_nm2, fork=True) if big and area_meanwhile else None
    fill.recipes = [(region, recipe)]
    walks = _tours(depths, strokes, spacing, ring_joins, every_ring)
    fill.paths = [np.ascontiguousarray(walk[:, :2]) for walk in walks]
    # the arcs of a ring inside E0 may stray as far as its chords (fit_paths); E0's
    # own vertices and the ends of joins (on E0's outline too) keep the fine tolerance
    fill.coarse = [np.where(walk[:, 2] != 0, deep, tolerance_nm)
                   for walk in walks]
    return fill


def _concentric(centre_area: list, spacing: int, tolerance_nm: int) -> list[list]:
    """E0, E1, ... (polygon sets), until nothing is left."""
    areas = []
    area = centre_area
    # the emptiness test only: the rings are made into arrays once, by the caller
    while any(len(ring) >= 3 for ring in area):
        areas.append(area)
        area = clip.offset(area, -spacing, tolerance_nm, cleaned=True)
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


def _ring_joins(depths: list[list[np.ndarray]], spacing: int,
                every_ring: EdgeIndex) -> list[tuple]:
    """The candidate joins between the rings of each depth and the depth outside it
    (see _joins_out), rings numbered depth after depth. `every_ring`: an EdgeIndex of
    all the rings in that order (cell: the spacing); each depth's is a part of it."""
    first_node = np.cumsum([0] + [len(at_depth) for at_depth in depths]).tolist()
    joins = []
    for depth in range(1, len(depths)):
        outer = every_ring.rings_part(first_node[depth - 1], first_node[depth])
        joins.extend(_joins_out(depths[depth], outer, first_node[depth],
                                first_node[depth - 1], spacing))
    return joins


def _tours(depths: list[list[np.ndarray]], strokes: list[np.ndarray], spacing: int,
           ring_joins: list[tuple], every_ring: EdgeIndex) -> list[np.ndarray]:
    """One pen-down polyline per tree of rings and gap strokes (see the module doc),
    as (n, 3) int64 rows x, y, inner: inner is 1 at the vertices of rings inside E0
    (their arcs may take the coarser tolerance), 0 elsewhere. `ring_joins` are
    _ring_joins(depths, spacing, every_ring), `every_ring` an EdgeIndex of all the
    rings in order.

    A gap stroke is walked there and back, joined at its first point to the nearest
    point of any ring: that point is inside E0 and no outline of E0 is nearer to it
    than the ring point, so the join stays inside E0 too."""
    rings = [ring for at_depth in depths for ring in at_depth]
    inner = len(depths[0]) if depths else 0         # nodes from here on: inside E0
    if not rings and not strokes:
        return []
    sizes = [len(node) for node in rings + strokes]
    rows = np.column_stack([np.concatenate(rings + strokes), np.repeat(
        (np.arange(len(sizes)) >= inner) & (np.arange(len(sizes)) < len(rings)), sizes)])
    nodes = np.split(rows.astype(np.int64, copy=False), np.cumsum(sizes)[:-1])
    joins = []          # (length, node a, stop on a, node b, stop on b)
    if strokes and rings:
        heads = np.array([path[0] for path in strokes], dtype=np.int64)
        k, t, distance = every_ring.nearest_many(heads, spacing)
        on = _points_on(every_ring, k, t)
        joins.extend((d, len(rings) + number, (0, 0.0, (hx, hy)), ring, (edge, tt, (px, py)))
                     for number, (d, hx, hy, ring, edge, tt, px, py) in enumerate(zip(
                         distance.tolist(), heads[:, 0].tolist(), heads[:, 1].tolist(),
                         every_ring.ring[k].tolist(), every_ring.edge[k].tolist(), t.tolist(),
                         on[:, 0].tolist(), on[:, 1].tolist())))
    joins.extend(ring_joins)
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

    lengths = [0.0] * len(rings) + [float(np.hypot(*np.diff(stroke, axis=0).T).sum())
                                    for stroke in strokes]
    opened = _opened_joins(lengths, stops, joins, len(rings), root)
    walker = _Walker(nodes, stops)
    tours = []                            # per walk: the rows' indices, in parts
    done = [False] * len(nodes)
    for start in range(len(nodes)):       # outermost rings first: each tree in its turn
        if done[start]:
            continue
        if root(start) not in opened:     # a ring alone: round from its vertex 0
            tours.append([walker.tree(start, done)])
            continue
        # one side of the opened join as a closed walk from the join (a gap stroke at
        # the end of it: from its far end in), over the join, and the other side as a
        # closed walk from there: the join (and such a stroke) is drawn once
        side, stop = opened[root(start)]
        number = walker.stop_number(side, stop)
        if side >= len(rings) and len(stops[side]) == 1:
            done[side] = True
            head = walker.node_rows(side)[::-1]
        else:
            head = walker.tree(side, done, number)
        tours.append([head, walker.tree(stop.other, done, walker.back[number])])
    return walker.gather(tours)


def _opened_joins(lengths: list[float], stops: list[list[_Stop]], joins: list[tuple],
                  strokes_from: int, root) -> dict[int, tuple[int, _Stop]]:
    """Per tree of joined nodes (by its root), the join its walk draws once: the node
    on the side walked first and its stop on the join. A walk is one stroke with two
    ends: at most one join can be drawn once (any other would leave more than two
    nodes of odd degree), and with a gap stroke at its end, that stroke too. So: the
    join that saves most, its length plus its stroke's (`lengths`: per node; ties: the
    first join)."""
    best: dict[int, tuple[float, int, int, _Stop]] = {}
    for node, at in enumerate(stops):
        for stop in at:
            length, first = joins[stop.join][0], joins[stop.join][1]
            if node != first:
                continue                  # each join once, from its first node's side
            if node >= strokes_from and len(at) == 1:
                length += lengths[node]
            key = root(node)
            if key not in best or (length, -stop.join) > (best[key][0], -best[key][1]):
                best[key] = (length, stop.join, node, stop)
    return {key: (node, stop) for key, (_length, _join, node, stop) in best.items()}


def _joins_out(inner: list[np.ndarray], index: EdgeIndex, first_inner: int,
               first_outer: int, spacing: int) -> list[tuple]:
    """For each ring of one depth, its shortest join to each ring of the depth outside
    it (`index`: their EdgeIndex) that one of its sampled vertices is nearest to (all
    samples queried at once; of equally short joins the earliest sample's)."""
    picked = _samples(inner, spacing)
    if not picked or not len(index):
        return []
    node = np.repeat(np.arange(len(inner)), [len(v) for v in picked])
    vertex = np.concatenate(picked)
    points = np.concatenate([ring[v] for ring, v in zip(inner, picked)])
    edge, t, distance = index.nearest_many(points, spacing)
    target = index.ring[edge]
    # per (ring, outer ring): the shortest, then the earliest sample
    order = np.lexsort((np.arange(len(node)), distance, target, node))
    first = np.ones(len(order), dtype=bool)
    first[1:] = (node[order][1:] != node[order][:-1]) | (target[order][1:] != target[order][:-1])
    chosen = order[first]
    k, tt = edge[chosen], t[chosen]
    on = _points_on(index, k, tt)
    return [(d, first_inner + n, (v, 0.0, (qx, qy)), first_outer + r, (e, u, (px, py)))
            for d, n, v, qx, qy, r, e, u, px, py in zip(
                distance[chosen].tolist(), node[chosen].tolist(), vertex[chosen].tolist(),
                points[chosen, 0].tolist(), points[chosen, 1].tolist(), target[chosen].tolist(),
                index.edge[k].tolist(), tt.tolist(), on[:, 0].tolist(), on[:, 1].tolist())]


def _points_on(index: EdgeIndex, k: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(n, 2): the points at t along the index's edges k, rounded to nm."""
    a, b = index.a[k], index.b[k]
    return np.round(a + (b - a) * t[:, None]).astype(np.int64)


def _samples(rings: list[np.ndarray], spacing: int) -> list[np.ndarray]:
    """Per ring, vertices spread evenly along it by length (arcs have many vertices,
    long straight sides few): one per JOIN_EVERY spacings, at least JOIN_SAMPLES, at
    most JOIN_MOST; every vertex of a ring that has no more. All rings at once."""
    if not rings:
        return []
    sizes = np.array([len(ring) for ring in rings], dtype=np.int64)
    first = np.cumsum(sizes) - sizes
    points = np.concatenate(rings)[:, :2]
    after = np.arange(len(points)) + 1                 # each vertex's successor
    after[first + sizes - 1] = first
    edges = np.hypot(*(points[after] - points).astype(np.float64).T)
    ends = np.cumsum(edges)
    base = np.repeat(ends[first] - edges[first], sizes)
    along = ends - edges - base                        # each vertex's place on its ring
    length = np.maximum(ends[first + sizes - 1] - ends[first] + edges[first], 0)
    count = np.maximum(np.minimum(length / (JOIN_EVERY * spacing), JOIN_MOST).astype(np.int64),
                       JOIN_SAMPLES)
    # rings with more vertices than wanted: `wanted` places evenly along (as
    # np.linspace(0, length, wanted, endpoint=False) puts them), each the last vertex
    # at or before it; searched for all rings at once, the ring number as the first key
    # (complex numbers sort by their real part, then their imaginary part)
    few = sizes <= count
    wanted = np.where(few, 0, count)
    ring = np.repeat(np.arange(len(rings)), wanted)
    j = np.arange(int(wanted.sum())) - np.repeat(np.cumsum(wanted) - wanted, wanted)
    places = j * (length / np.maximum(count, 1))[ring]
    keys = np.repeat(np.arange(len(rings)), sizes) + 1j * along
    at = np.searchsorted(keys, ring + 1j * places, side="right") - first[ring]
    at = at.clip(1, sizes[ring]) - 1
    # the places rise along a ring, so equal vertices are neighbours: keep the first
    keep = np.ones(len(at), dtype=bool)
    keep[1:] = (at[1:] != at[:-1]) | (ring[1:] != ring[:-1])
    kept = np.bincount(ring[keep], minlength=len(rings))
    sampled = np.split(at[keep], np.cumsum(kept)[:-1])
    return [np.arange(size, dtype=np.int64) if all_of else chosen
            for size, all_of, chosen in zip(sizes.tolist(), few.tolist(), sampled)]


class _Walker:
    """Walks trees of rings (and gap strokes) joined at their stops, as one closed path
    each (`tree`).

    Every node's vertices and stops are put in order along it once, for all nodes at
    once (vertex k of a ring sits at (k, 0) along it, a stop at (edge, t), a stop on a
    vertex after that vertex; stops at one place keep their order). A walk then only
    chooses ranges of that order, and one gather at the end makes the points: the
    nodes (thousands on a large pour) cost a few integer steps each, not array work."""

    def __init__(self, nodes: list[np.ndarray], stops: list[list[_Stop]]):
        self.stops = stops
        sizes = np.array([len(node) for node in nodes], dtype=np.int64)
        counts = np.array([len(at) for at in stops], dtype=np.int64)
        vertices = int(sizes.sum())
        flat = [stop for at in stops for stop in at]
        owner = np.repeat(np.arange(len(nodes)), counts)
        edge = np.array([stop.edge for stop in flat], dtype=np.int64)
        t = np.array([stop.t for stop in flat], dtype=np.float64)
        points = np.array([stop.point for stop in flat], dtype=np.int64).reshape(-1, 2)
        first = np.cumsum(sizes) - sizes
        self.first, self.sizes = first.tolist(), sizes.tolist()
        size = sizes[owner]
        # rows: every vertex of every node, then every stop's point (inner where the
        # stop sits on an inner vertex of its edge)
        vertex_rows = np.concatenate(nodes) if nodes else np.zeros((0, 3), np.int64)
        inner = np.zeros(len(flat), dtype=np.int64)
        for end in (edge % size, (edge + 1) % size):
            row = vertex_rows[first[owner] + end]
            on = np.all(row[:, :2] == points, axis=1)
            inner = np.maximum(inner, np.where(on, row[:, 2], 0))
        self.rows = np.concatenate([vertex_rows, np.column_stack([points, inner])])
        # the order along each node: node, place, t, vertices before stops, then as given
        wrap = t >= 1.0
        place = np.concatenate([np.arange(vertices) - np.repeat(first, sizes),
                                np.where(wrap, (edge + 1) % size, edge)])
        along = np.concatenate([np.zeros(vertices), np.where(wrap, 0.0, t)])
        kind = np.concatenate([np.zeros(vertices, np.int8), np.ones(len(flat), np.int8)])
        node = np.concatenate([np.repeat(np.arange(len(nodes)), sizes), owner])
        self.order = np.lexsort((kind, along, place, node))
        where = np.empty(len(self.order), dtype=np.int64)
        where[self.order] = np.arange(len(self.order))
        self.lo = (np.cumsum(sizes + counts) - sizes - counts).tolist()
        self.hi = np.cumsum(sizes + counts).tolist()
        # each stop's place in the order, and per node its stops' places, in order
        self.at = where[vertices:].tolist()
        first_stop = (np.cumsum(counts) - counts).tolist()
        self.first_stop = first_stop
        self.places = [sorted(self.at[f:f + c]) for f, c in zip(first_stop, counts.tolist())]
        self.stop_at: dict[int, int] = {}          # a stop's place -> its number
        self.back = [0] * len(flat)                # the stop at a join's other end
        ends: dict[int, int] = {}
        for number, stop in enumerate(flat):
            self.stop_at[self.at[number]] = number
            partner = ends.setdefault(stop.join, number)
            if partner != number:
                self.back[number], self.back[partner] = partner, number
        self.other = [stop.other for stop in flat]

    def stop_number(self, node: int, stop: _Stop) -> int:
        """The global number of `stop`, one of node's stops."""
        return self.first_stop[node] + next(k for k, s in enumerate(self.stops[node])
                                            if s is stop)

    def tree(self, start: int, done: list[bool], entry: int | None = None) -> np.ndarray:
        """The tree of nodes holding `start` (but for nodes done already) as one closed
        walk from its vertex 0, or from its stop number `entry` (not crossed): the
        indices of its rows (`gather` makes the points)."""
        ranges: list[int] = []             # begin, end, begin, end, ... in the order
        lo, hi, stop_at, other, back = self.lo, self.hi, self.stop_at, self.other, self.back
        done[start] = True
        stack = [self._enter(start, entry, -1, ranges)]
        while stack:
            frame = stack[-1]
            node, begin, ahead, k, here, come_back = frame
            low, high = lo[node], hi[node]
            span = high - low
            if k == len(ahead):                 # on round to where it began
                self._run(ranges, here, begin + span, low, high)
                ranges += (begin, begin + 1)
                if come_back >= 0:              # the stop it was entered by, again
                    ranges += (come_back, come_back + 1)
                stack.pop()
                continue
            place = ahead[k]
            unrolled = place if place > begin else place + span
            self._run(ranges, here, unrolled, low, high)
            ranges += (place, place + 1)        # the stop: cross, walk the node behind
            frame[3], frame[4] = k + 1, unrolled + 1
            number = stop_at[place]
            done[other[number]] = True
            stack.append(self._enter(other[number], back[number], place, ranges))
        pairs = np.array(ranges, dtype=np.int64).reshape(-1, 2)
        lengths = pairs[:, 1] - pairs[:, 0]
        skip = np.repeat(np.cumsum(lengths) - lengths - pairs[:, 0], lengths)
        return self.order[np.arange(int(lengths.sum())) - skip]

    def node_rows(self, node: int) -> np.ndarray:
        """The indices of a node's own vertices' rows, in its order."""
        return np.arange(self.first[node], self.first[node] + self.sizes[node])

    def _enter(self, node: int, entry: int | None, come_back: int, ranges: list[int]) -> list:
        """A walk's frame: node, where it begins in the order, the places of the stops
        ahead, how many are passed, the place next, the parent's stop to return to; the
        walk of the node starts at its beginning's point."""
        begin = self.lo[node] if entry is None else self.at[entry]
        ranges += (begin, begin + 1)
        places = self.places[node]
        ahead = [p for p in places if p > begin] + [p for p in places if p < begin]
        return [node, begin, ahead, 0, begin + 1, come_back]

    @staticmethod
    def _run(ranges: list[int], start: int, stop: int, low: int, high: int) -> None:
        """The places start..stop-1 of a node walked round (past `high`: from `low`)."""
        if stop <= start:
            return
        if stop <= high:
            ranges += (start, stop)
        elif start >= high:
            ranges += (start - (high - low), stop - (high - low))
        else:
            ranges += (start, high, low, stop - (high - low))

    def gather(self, walks: list[list[np.ndarray]]) -> list[np.ndarray]:
        """Each walk's rows (its parts' row indices in turn) without a point equal to
        the one before it (a point kept for several is inner if any of them is: a join's
        end on an inner ring's vertex), all walks in one gather."""
        if not walks:
            return []
        parts = [np.concatenate(parts) for parts in walks]
        sizes = np.array([len(part) for part in parts], dtype=np.int64)
        path = self.rows[np.concatenate(parts)]
        keep = np.ones(len(path), dtype=bool)
        keep[1:] = np.any(path[1:, :2] != path[:-1, :2], axis=1)
        keep[np.cumsum(sizes)[:-1]] = True          # each walk's first point
        out = path[keep]
        out[:, 2] = np.maximum.reduceat(path[:, 2], np.flatnonzero(keep))
        kept = np.add.reduceat(keep.astype(np.int64), np.cumsum(sizes) - sizes)
        return np.split(out, np.cumsum(kept)[:-1])


# ---- gaps ----------------------------------------------------------------------------

def _gaps(areas: list[list], radius: int, tolerance_nm: int, first: int = 0,
          end: int | None = None) -> list:
    """Where no ring comes within r: inside E(k) deeper than r, and farther than r from
    E(k+1) (rings outside E(k) are farther still, rings inside E(k+1) too); for the
    depths first..end-1, not merged (the gaps of two depths lie 2r apart at least)."""
    gaps = []
    for depth in range(first, len(areas) if end is None else end):
        deep = clip.offset(areas[depth], -radius, tolerance_nm, cleaned=True)
        if not deep:
            continue
        inner = areas[depth + 1] if depth + 1 < len(areas) else []
        gaps.extend(clip.difference(deep, clip.offset(inner, radius, tolerance_nm, cleaned=True)))
    return gaps


def _gap_split(areas: list[list]) -> int:
    """The first depth whose gaps are found after the joins, not in the second process
    (_fill_batch): the deepest, with about MAIN_GAP_SHARE of the gap tests' work
    (depth k's: the vertices of E(k) and E(k+1)) from depth 1 on."""
    sizes = [sum(len(ring) for ring in area) for area in areas] + [0]
    work = [sizes[k] + sizes[k + 1] for k in range(len(areas))]
    budget = MAIN_GAP_SHARE * sum(work[1:])
    split = len(areas)
    while split > 1 and work[split - 1] <= budget:
        split -= 1
        budget -= work[split]
    return split


def _gap_work(gaps: list, centre_area: list, radius: int,
              tolerance_nm: int) -> tuple[list, list[np.ndarray]]:
    """The gaps of every depth (_gaps, in depth order) as one set, and their strokes:
    the gaps opened by GAP_NM, a stroke along each (_gap_strokes)."""
    gaps = clip.union(gaps)
    opened = clip.opening(gaps, GAP_NM, tolerance_nm)
    return gaps, (_gap_strokes(opened, centre_area, radius) if opened else [])


def _gap_strokes(gaps: list, centre_area: list, radius: int) -> list[np.ndarray]:
    """A stroke along each gap's long axis, ends pulled in by up to r/2, kept inside E0.
    The axes of all the gaps' outer rings at once: each ring's points about their
    mean, the 2 x 2 moment matrices, their main eigenvectors in one batch."""
    outers = [outer for outer, _holes in clip.components(gaps)]
    sizes = np.array([len(outer) for outer in outers], dtype=np.int64)
    first = np.cumsum(sizes) - sizes
    points = np.concatenate(outers).astype(np.float64)
    centre = np.add.reduceat(points, first, axis=0) / sizes[:, None]
    spread = points - np.repeat(centre, sizes, axis=0)
    moments = np.stack([np.add.reduceat(spread[:, [i]] * spread, first, axis=0)
                        for i in (0, 1)], axis=1)          # (m, 2, 2): spread.T @ spread
    axis = np.linalg.eigh(moments)[1][:, :, -1]
    along = np.einsum("ij,ij->i", spread, np.repeat(axis, sizes, axis=0))
    low, high = np.minimum.reduceat(along, first), np.maximum.reduceat(along, first)
    pull = np.minimum(radius / 2, (high - low) / 2)
    a = np.rint(centre + axis * (low + pull)[:, None]).astype(np.int64)
    b = np.rint(centre + axis * (high - pull)[:, None]).astype(np.int64)
    b[np.all(a == b, axis=1), 0] += 1                     # a dot: one nm long
    segments = np.stack([a, b], axis=1).tolist()
    clipper = pc.Pyclipper()
    clipper.AddPaths(segments, pc.PT_SUBJECT, False)
    try:
        clipper.AddPaths(centre_area, pc.PT_CLIP, True)
    except pc.ClipperException:
        return []
    tree = clipper.Execute2(pc.CT_INTERSECTION, pc.PFT_NONZERO, pc.PFT_POSITIVE)
    paths = [np.asarray(path, dtype=np.int64) for path in pc.OpenPathsFromPolyTree(tree)
             if len(path) >= 2]
    clip.free_tree(tree)
    return paths
