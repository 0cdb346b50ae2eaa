"""Necks: copper thinner than the pen between two inked parts of one island.

A thermal relief's spokes between a pad and its pour, a pour squeezed between two
traces: no pen centre fits inside them, so the fill (fill.py) cannot reach them, and
a neck left bare etches away: the pad comes off its pour, the pour falls in two. Each
bare piece of copper that touches the ink in two places or more is drawn along its
long axis with the smallest pen, its ink spilling into the clearance beside it as a
narrow feature's does (narrow.py), and it is kept as far from other islands as a
centre line is (`narrow.keep_islands_apart`). A bare piece that touches the ink once
(the corner a round pen cannot reach, a sliver along an edge) joins nothing and is
left bare.
"""

from __future__ import annotations

import numpy as np
import pyclipper as pc

from galileo_cnc.errors import SourcePos
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.edges import EdgeIndex
from galileo_cnc.plan.ink.fill import GAP_NM, PenFill
from galileo_cnc.plan.ink.islands import Islands
from galileo_cnc.plan.ink.narrow import NarrowFeature
from galileo_cnc.program.ops import COLUMNS, KIND, OpKind

#: A bare piece smaller than this share of r x r is a corner or a sliver, not a neck
#: (the corner a round pen leaves at a right angle is 0.21 r x r).
LEAST_NECK_SHARE = 0.5


def neck_features(source: str, fills: list[PenFill], centre_lines: list, pen_nm: int,
                  edge_margin_nm: int, tolerance_nm: int) -> list[NarrowFeature]:
    """A centre line of the smallest pen (`pen_nm`) along each neck that the fills' ink
    and the `centre_lines` (drawn with that pen) leave bare. The copper is the first
    pen's batches (fill.py's strips of islands), taken batch by batch; each batch's
    reach is grown by its edge margin and GAP_NM, so that the band the margin leaves
    along every edge and slivers thinner than 2 GAP_NM are no bare pieces."""
    if not fills:
        return []
    radius = pen_nm // 2
    reach, bare = [], []
    for batch, recipe in fills[0].recipes:
        grown = clip.offset(recipe.centre_area, recipe.radius_nm + edge_margin_nm + GAP_NM,
                            tolerance_nm, cleaned=True)
        reach.extend(grown)
        bare.extend(clip.difference(batch, grown))
    other = [ring for fill in fills[1:] for ring in fill.ink]
    lines = [line for line in centre_lines if len(line)]
    if lines:
        other = clip.union(other, clip.stroke_in_strips(lines, radius, tolerance_nm))
    if bare and other:
        bare = clip.difference(bare, other)
    least = LEAST_NECK_SHARE * radius * radius
    pieces = [outer for outer, _holes in clip.components(bare)
              if abs(pc.Area(outer.tolist())) >= least]
    if not pieces:
        return []
    touches = _touches(pieces, reach + other, tolerance_nm)
    necks = [piece for piece, count in zip(pieces, touches) if count >= 2]
    features = [_feature(source, piece, pen_nm) for piece in necks]
    # a long bent piece's axis leaves it, over other copper, perhaps another island's
    # (whose inside the clearance check, which measures to outlines, would not see)
    return [feature for feature, piece in zip(features, necks)
            if _follows(feature.pieces[0], piece, radius // 2)]


def _follows(line: np.ndarray, piece: np.ndarray, slack_nm: int, samples: int = 9) -> bool:
    """Whether the line stays inside the piece or within `slack_nm` of it."""
    a, b = line[0].astype(np.float64), line[-1].astype(np.float64)
    ring = piece.tolist()
    start, end = piece.astype(np.float64), np.roll(piece, -1, axis=0).astype(np.float64)
    edge = end - start
    length2 = np.maximum((edge * edge).sum(axis=1), 1.0)
    for t in np.linspace(0.0, 1.0, samples):
        point = a + (b - a) * t
        if pc.PointInPolygon(tuple(int(v) for v in np.rint(point)), ring) != 0:
            continue
        along = np.clip(((point - start) * edge).sum(axis=1) / length2, 0.0, 1.0)
        nearest = start + edge * along[:, None]
        if np.min(np.hypot(*(nearest - point).T)) > slack_nm:
            return False
    return True


def _touches(pieces: list[np.ndarray], ink: list, tolerance_nm: int) -> np.ndarray:
    """Per piece, in how many places the ink meets it: the pieces grown by a few
    tolerances, cut by the ink, counted in pieces, each given to the bare piece its
    first point lies nearest to."""
    reach = 4 * tolerance_nm
    met = clip.components(clip.intersection(clip.offset(pieces, reach, tolerance_nm), ink))
    if not met:
        return np.zeros(len(pieces), dtype=np.int64)
    index = EdgeIndex(pieces, cell_nm=8 * reach)
    first = np.array([outer[0] for outer, _holes in met], dtype=np.int64)
    edge, _t, _distance = index.nearest_many(first, 2 * reach)
    return np.bincount(index.ring[edge[edge >= 0]], minlength=len(pieces))


def _centre_and_axis(ring: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The polygon's centroid and the direction of its long axis, from its area's
    moments (its vertices' would lean towards a side drawn with many, an arc's)."""
    x, y = ring[:, 0] - ring[0, 0], ring[:, 1] - ring[0, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    cross = x * y1 - x1 * y
    area = cross.sum() / 2
    cx = ((x + x1) * cross).sum() / (6 * area)
    cy = ((y + y1) * cross).sum() / (6 * area)
    xx = ((x * x + x * x1 + x1 * x1) * cross).sum() / 12 - area * cx * cx
    yy = ((y * y + y * y1 + y1 * y1) * cross).sum() / 12 - area * cy * cy
    xy = ((x * y1 + 2 * x * y + 2 * x1 * y1 + x1 * y) * cross).sum() / 24 - area * cx * cy
    axis = np.linalg.eigh(np.array([[xx, xy], [xy, yy]]) * np.sign(area))[1][:, -1]
    return np.array([cx + ring[0, 0], cy + ring[0, 1]]), axis


def _feature(source: str, piece: np.ndarray, pen_nm: int) -> NarrowFeature:
    """The neck as a centre line along its long axis, end to end (the pen's round ends
    reach into the ink on both sides)."""
    centre, axis = _centre_and_axis(piece.astype(np.float64))
    along = (piece - centre) @ axis
    a = np.rint(centre + axis * along.min()).astype(np.int64)
    b = np.rint(centre + axis * along.max()).astype(np.int64)
    if np.array_equal(a, b):
        b[0] += 1
    length = float(np.hypot(*(b - a)))
    width = int(abs(pc.Area(piece.tolist())) / max(length, 1.0))
    row = [0] * len(COLUMNS)
    row[KIND] = int(OpKind.LINE)
    middle = tuple(int(v) for v in np.rint(centre))
    # a point of its copper, for the island it belongs to (a curved piece may not hold
    # its centroid: then a vertex, on its outline)
    inside = middle if pc.PointInPolygon(middle, piece.tolist()) else \
        tuple(int(v) for v in piece[0])
    return NarrowFeature(op_index=-1, pos=SourcePos(source, 0, 0), width_nm=width,
                         pen_nm=pen_nm, row=row, start_nm=(int(a[0]), int(a[1])),
                         pieces=[np.array([a, b], dtype=np.int64)], cut=True,
                         inside_nm=inside, neck=True)


def attach_to_walks(necks: list[NarrowFeature], walks: list[np.ndarray], pen_nm: int,
                    islands: Islands) -> dict[int, tuple[int, int, tuple[int, int]]]:
    """Each neck's line drawn from the walk its nearer end lies within a pen width of,
    a walk of the neck's own island: the line becomes [point on the walk, that end, the
    other end] (so the clearance check takes the way from the walk too). Per neck so
    attached (by id): the walk, the edge and the point. A walk's closing edge is the
    walk's own only where it ends where it began."""
    if not walks or not necks or not islands.rings:
        return {}
    index = EdgeIndex(walks, cell_nm=pen_nm)
    ends = np.array([line for neck in necks for line in (neck.pieces[0][0],
                                                         neck.pieces[0][-1])], dtype=np.int64)
    k, t, distance = index.nearest_many(ends, pen_nm)
    found = k >= 0
    points = np.zeros_like(ends)
    points[found] = np.rint(index.a[k[found]] + (index.b[k[found]] - index.a[k[found]])
                            * t[found][:, None]).astype(np.int64)
    # a point inside copper is nearer to its own island's outline than to any other's
    copper = EdgeIndex(islands.rings, cell_nm=max(pen_nm, 100_000))
    inside = np.array([neck.inside_nm for neck in necks], dtype=np.int64)
    rings = np.concatenate([inside, points])
    edge, _t, _d = copper.nearest_many(rings, pen_nm)
    island = np.where(edge >= 0, islands.owner[copper.ring[np.maximum(edge, 0)]], -1)
    own, at = island[:len(necks)], island[len(necks):]
    attached = {}
    for number, neck in enumerate(necks):
        pair = (2 * number, 2 * number + 1)
        side = min(pair, key=lambda e: distance[e])
        if not found[side] or distance[side] > pen_nm or at[side] != own[number]:
            continue
        walk, edge = int(index.ring[k[side]]), int(index.edge[k[side]])
        path = walks[walk]
        if edge == len(path) - 1 and not np.array_equal(path[0], path[-1]):
            continue
        line = neck.pieces[0] if side == pair[0] else neck.pieces[0][::-1]
        point = points[side]
        neck.pieces = [np.vstack([point[None, :], line]).astype(np.int64)]
        neck.start_nm = (int(point[0]), int(point[1]))
        attached[id(neck)] = (walk, edge, (int(point[0]), int(point[1])))
    return attached


def spliced(fill: PenFill, necks: list[tuple[NarrowFeature, tuple]], tolerance_nm: int
            ) -> list[tuple[NarrowFeature, tuple]]:
    """Each neck's line [on the walk, ...] put into its walk as a spur, out and back
    (`necks`: pairs of the neck and attach_to_walks' place); the pairs put in."""
    fill.with_coarse(tolerance_nm)
    by_walk: dict[int, list] = {}
    for neck, (walk, edge, point) in necks:
        start = fill.paths[walk][edge]
        along = abs(point[0] - int(start[0])) + abs(point[1] - int(start[1]))
        by_walk.setdefault(walk, []).append((edge, along, neck))
    for walk, items in by_walk.items():
        path, coarse = fill.paths[walk], fill.coarse[walk]
        # last place first (along an edge too): the earlier places' indices stay as
        # they were, and spurs on one edge come in their order along it
        for edge, _along, neck in sorted(items, key=lambda item: (-item[0], -item[1])):
            line = neck.pieces[0]
            spur = np.vstack([line, line[-2::-1]])
            path = np.vstack([path[:edge + 1], spur, path[edge + 1:]])
            coarse = np.concatenate([coarse[:edge + 1], np.full(len(spur), tolerance_nm),
                                     coarse[edge + 1:]])
        keep = np.ones(len(path), dtype=bool)
        keep[1:] = np.any(path[1:] != path[:-1], axis=1)
        fill.paths[walk] = np.ascontiguousarray(path[keep])
        fill.coarse[walk] = coarse[keep]
    return necks
