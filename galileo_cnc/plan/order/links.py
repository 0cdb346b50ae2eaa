"""Pen lifts left out: where a path ends a short way from where the next path of the
same pen starts, and the straight line between them runs inside the area the pen's
centre may go, the pen runs on to it pen-down instead of lifting (docs/ink.md, "Links").

A lift and a lower cost the Z travel twice (0.75 s with the default profile) and two
ramps, a short pen-down line a fraction of that. The ink names per pen the area its
centre may go (`LINK_AREAS` in the Program's metadata: the copper shrunk by the pen's
radius and the edge margin, less the keep-outs and the bare areas), so a line inside it
inks only copper, and never joins islands (the area lies inside one island). Programs
without it (centre lines, DXF, G-code) are left as they are.
"""

from __future__ import annotations

import numpy as np
import pyclipper as pc

from galileo_cnc.program.ops import KIND, TOOL, X, Y, OpKind

#: Program metadata: {pen key: polygon set (nm)} where that pen's centre may go
LINK_AREAS = "link_areas"
#: The longest link: a lift and a lower cost about as much as 4 mm at the feed, and
#: a link draws over ink already there, so only the short ones are worth it
LINK_MOST_NM = 2_000_000
#: The area is grown by this much before the test: a link along one of its edges (a
#: walk ending on E0's outline, the next path starting on it) then lies inside it, where
#: Clipper's clipping of an open path decides it either way. It strays no farther than
#: E0's own arcs may (the ink's tolerance, 2 um) and stays inside the edge margin.
LINK_SLACK_NM = 1_000

_MOVE = int(OpKind.MOVE)
_PATH_KINDS = (int(OpKind.LINE), int(OpKind.ARC_CW), int(OpKind.ARC_CCW))


def linked_moves(table: np.ndarray, areas: dict, most_nm: int | None = None) -> np.ndarray:
    """Positions of the MOVE rows of `table` (rows in plotting order) that may be drawn
    as lines: between two path rows of one pen, at most `most_nm` (LINK_MOST_NM) long,
    inside that pen's area."""
    most_nm = LINK_MOST_NM if most_nm is None else most_nm
    if len(table) < 3 or not areas:
        return np.zeros(0, dtype=np.int64)
    kinds, tools = table[:, KIND], table[:, TOOL]
    path = np.isin(kinds, _PATH_KINDS)
    at = np.flatnonzero((kinds[1:-1] == _MOVE) & path[:-2] & path[2:]) + 1
    at = at[(tools[at - 1] == tools[at]) & (tools[at + 1] == tools[at])]
    a = table[at - 1][:, [X, Y]]
    b = table[at][:, [X, Y]]
    at = at[np.hypot(*(b - a).astype(np.float64).T) <= most_nm]
    kept = []
    for tool in np.unique(tools[at]).tolist():
        area = areas.get(tool)
        if not area:
            continue
        mine = at[tools[at] == tool]
        grown = pc.PyclipperOffset(2.0)
        grown.AddPaths(area, pc.JT_MITER, pc.ET_CLOSEDPOLYGON)
        inside = _inside(table[mine - 1][:, [X, Y]], table[mine][:, [X, Y]],
                         grown.Execute(float(LINK_SLACK_NM)))
        kept.append(mine[inside])
    return np.sort(np.concatenate(kept)) if kept else np.zeros(0, dtype=np.int64)


def _inside(a: np.ndarray, b: np.ndarray, area: list) -> np.ndarray:
    """Per segment a -> b: whether it lies inside the polygon set (positive winding),
    all segments in one Clipper run. A piece of the difference lies on the segment it
    came from: each piece's midpoint is matched to the segments it lies on (a piece on
    two overlapping segments counts against both). Clipper counts a segment along an
    edge as outside on some edges: such a link is left out, which only keeps a lift."""
    out = np.ones(len(a), dtype=bool)
    moving = np.any(a != b, axis=1)
    if not moving.any():
        return out
    segments = np.stack([a[moving], b[moving]], axis=1)
    clipper = pc.Pyclipper()
    clipper.AddPaths(segments.tolist(), pc.PT_SUBJECT, False)
    try:
        clipper.AddPaths(area, pc.PT_CLIP, True)
    except pc.ClipperException:
        return np.zeros(len(a), dtype=bool)
    tree = clipper.Execute2(pc.CT_DIFFERENCE, pc.PFT_NONZERO, pc.PFT_POSITIVE)
    pieces = [np.asarray(p, dtype=np.float64) for p in pc.OpenPathsFromPolyTree(tree)]
    if pieces:
        s, e = segments[:, 0].astype(np.float64), segments[:, 1].astype(np.float64)
        d = e - s
        length2 = (d * d).sum(axis=1)
        bad = np.zeros(len(segments), dtype=bool)
        for piece in pieces:
            mid = piece.mean(axis=0)
            t = ((mid - s) * d).sum(axis=1) / length2
            off = np.abs((mid[0] - s[:, 0]) * d[:, 1] - (mid[1] - s[:, 1]) * d[:, 0])
            bad |= (t >= -1e-9) & (t <= 1 + 1e-9) & (off <= 2.0 * np.sqrt(length2))
        out[np.flatnonzero(moving)[bad]] = False
    # a dot link (the same point) is inside if the point is
    for k in np.flatnonzero(~moving).tolist():
        x, y = int(a[k, 0]), int(a[k, 1])
        out[k] = sum((1 if pc.Area(ring) > 0 else -1) for ring in area
                     if pc.PointInPolygon((x, y), ring) != 0) > 0
    return out


def linked_pairs(ordered: list[tuple[int, list[int]]], areas: dict,
                 columns: int) -> list[tuple[int, list[int]]]:
    """(op index, row) pairs with the MOVE rows `linked_moves` finds drawn as lines."""
    if len(ordered) < 3 or not areas:
        return ordered
    table = np.array([row for _index, row in ordered], dtype=np.int64).reshape(-1, columns)
    ordered = list(ordered)
    for k in linked_moves(table, areas).tolist():
        index, row = ordered[k]
        row = list(row)
        row[KIND] = int(OpKind.LINE)
        ordered[k] = (index, row)
    return ordered
