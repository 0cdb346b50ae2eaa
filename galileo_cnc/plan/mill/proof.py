"""The proof that no isolation pass enters the copper, before anything is cut.

The copper polygons hold the true copper to within `tolerance_nm` (inscribed chords:
the true outline lies at most that far outside them), so the tool, a disc of half the
cut width round its centre, leaves the true copper whole when every point of every
pass lies at least cut_width / 2 + tolerance_nm from the copper polygons. That is
shown in three parts, all on the integer polygons, neither trusting the offset that
made the passes:

1. The clearance: the least distance from every pass vertex to the copper's edges and
   from every copper vertex to the passes' edges, exactly (the compiled nearest-edge
   search, float64 on integer nm).
2. No pass vertex lies inside the copper: each is on the outer side of the copper
   outline nearest to it (outlines run counter-clockwise round copper, clockwise round
   its holes; where the nearest point is a corner, the two edges that meet there decide,
   as the corner is convex or not).
3. No pass segment crosses a copper segment. Where segments PQ and AB cross at X, P
   lies within |PX| of AB, Q within |QX|, and so on: both are at least twice the
   clearance long. So only the long segments of both are tested, exactly (orientation
   signs), those that share a grid cell or its neighbours.

Then every pass lies outside the copper and two segments that do not cross are nearest
at an end of one of them: the clearance of part 1 is the least distance between the
passes and the copper.

A second witness: the tool's swept area (the passes stroked by half the cut plus the
tolerance, as Clipper's round offset of the closed paths, grown by what its round joins
may fall short: isolate.join_sagitta_nm) intersected with the copper has no area.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pyclipper as pc

from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.edges import _KEY as CELL_KEY
from galileo_cnc.plan.ink.edges import EdgeIndex, cell_keys
from galileo_cnc.plan.mill.isolate import Isolation, arc_tolerance_nm, join_sagitta_nm

#: The swept area inside the copper that still counts as none: Clipper's rounding.
SWEPT_AREA_ALLOWED_NM2 = 1_000_000      # 1 um^2
#: The smallest grid cell for the crossing test (part 3): long segments, few cells.
CROSSING_CELL_NM = 500_000
#: The copper's grid cell for the pass vertices' nearest edges, per mille of the search.
NEAR_CELL_PERMILLE = 550
#: Vertices of the passes stroked at once for the swept area.
STRIP_VERTICES = 5_000


@dataclass(frozen=True)
class Proof:
    """What `prove` found (module doc)."""

    clearance_nm: float            # least distance from any pass to the copper polygons
    required_nm: int               # half the cut plus the copper's chord tolerance
    entries: int                   # pass vertices inside the copper and crossings (2, 3)
    swept_in_copper_nm2: float     # the second witness; -1 when not computed
    seconds: float

    @property
    def holds(self) -> bool:
        return (self.entries == 0 and self.clearance_nm >= self.required_nm
                and self.swept_in_copper_nm2 <= SWEPT_AREA_ALLOWED_NM2)

    def describe(self) -> str:
        verdict = "no pass enters the copper" if self.holds else "A PASS ENTERS THE COPPER"
        # to 0.1 um: the margin that tells the two apart is a few um
        return (f"{verdict}: every pass keeps {self.clearance_nm / 1e6:.4f} mm from it "
                f"(the tool needs {self.required_nm / 1e6:.4f} mm)")


def prove(isolation: Isolation, swept: bool = True) -> Proof:
    """The proof for `isolation`'s passes (module doc); `swept`: the second witness too."""
    clock = time.perf_counter()
    rings = isolation.rings
    required = isolation.cut_width_nm // 2 + isolation.tolerance_nm
    # round the half cut up: the proof never claims a nanometre it lacks
    required += isolation.cut_width_nm % 2
    clearance, entries = _clearance_and_entries(rings, isolation.islands.rings, 2 * required)
    area = _swept_in_copper(rings, isolation.islands.parts, required,
                            isolation.tolerance_nm) if swept else -1.0
    return Proof(clearance, required, entries, area, time.perf_counter() - clock)


def clearance_nm(paths: list[np.ndarray], copper_rings: list[np.ndarray],
                 search_nm: int) -> float:
    """The least distance between the closed `paths` and the copper's rings, when no
    path enters the copper (module doc, part 1); inf when either is empty."""
    return _clearance_and_entries(paths, copper_rings, search_nm)[0]


def _clearance_and_entries(paths: list[np.ndarray], copper_rings: list[np.ndarray],
                           search_nm: int) -> tuple[float, int]:
    """Parts 1 to 3 (module doc): the clearance, and how many pass vertices lie inside
    the copper plus how many pass segments cross a copper segment."""
    if not paths or not copper_rings:
        return float("inf"), 0
    # the pass vertices lie a little over half the search from the copper (the first
    # pass's radius): cells that size look at a quarter of the edges the search's would
    # (the answers do not depend on the cell: edges.nearest_many); the copper's
    # vertices lie farther off, more spread, and gain nothing from it
    near = search_nm * NEAR_CELL_PERMILLE // 1000
    copper = EdgeIndex(copper_rings, cell_nm=near)
    tool = EdgeIndex(paths, cell_nm=search_nm)
    edge, t, from_paths = copper.nearest_many(tool.a, near)
    _edge, _t, from_copper = tool.nearest_many(copper.a, search_nm)
    clearance = float(min(from_paths.min(), from_copper.min()))
    inside = int(np.count_nonzero(_inside(copper, tool.a, edge, t)))
    return clearance, inside + _crossings(tool, copper, clearance)


def _left(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Twice the signed area of (a, b, p): > 0 where p lies left of a -> b. Differences
    first: float64 holds them exactly, their products to a few nm^2."""
    d, q = (b - a).astype(np.float64), (p - a).astype(np.float64)
    return d[:, 0] * q[:, 1] - d[:, 1] * q[:, 0]


def _inside(copper: EdgeIndex, points: np.ndarray, edge: np.ndarray, t: np.ndarray
            ) -> np.ndarray:
    """Which points lie inside the copper, from each one's nearest copper edge and where
    along it the nearest point is (module doc, part 2); a point on the outline counts."""
    left = _left(copper.a[edge], copper.b[edge], points) >= 0
    corner = (t <= 0) | (t >= 1)
    if not corner.any():
        return left
    # the corner's two edges: the one ending there and the one leaving it
    at = np.flatnonzero(corner)
    ending = np.where(t[at] >= 1, edge[at], _previous(copper, edge[at]))
    leaving = np.where(t[at] >= 1, _following(copper, edge[at]), edge[at])
    by_ending = _left(copper.a[ending], copper.b[ending], points[at]) >= 0
    by_leaving = _left(copper.a[leaving], copper.b[leaving], points[at]) >= 0
    convex = _left(copper.a[ending], copper.b[ending], copper.b[leaving]) > 0
    left[at] = np.where(convex, by_ending & by_leaving, by_ending | by_leaving)
    return left


def _previous(index: EdgeIndex, edge: np.ndarray) -> np.ndarray:
    """The edge before each one round its ring."""
    last = np.searchsorted(index.ring, index.ring[edge], "right") - 1
    return np.where(index.edge[edge] == 0, last, edge - 1)


def _following(index: EdgeIndex, edge: np.ndarray) -> np.ndarray:
    """The edge after each one round its ring."""
    first = np.searchsorted(index.ring, index.ring[edge], "left")
    last = np.searchsorted(index.ring, index.ring[edge], "right") - 1
    return np.where(edge == last, first, edge + 1)


def _crossings(tool: EdgeIndex, copper: EdgeIndex, clearance: float) -> int:
    """How many (pass segment, copper segment) pairs cross or touch (module doc, part 3):
    only segments at least twice the clearance long can."""
    long_tool = _long(tool, 2 * clearance)
    long_copper = _long(copper, 2 * clearance)
    if not len(long_tool) or not len(long_copper):
        return 0
    cell = max(int(2 * clearance), CROSSING_CELL_NM)
    tool_keys, tool_owner = cell_keys(tool.a[long_tool], tool.b[long_tool], cell)
    copper_keys, copper_owner = cell_keys(copper.a[long_copper], copper.b[long_copper], cell)
    # a crossing point lies within a quarter cell of a sample of each: the same cell or
    # a neighbour (edges.cell_keys)
    step = np.array([dx * CELL_KEY + dy for dx in (-1, 0, 1) for dy in (-1, 0, 1)])
    keys = (tool_keys[:, None] + step[None, :]).ravel()
    owner = np.repeat(tool_owner, len(step))
    lo = np.searchsorted(copper_keys, keys, "left")
    count = np.searchsorted(copper_keys, keys, "right") - lo
    mine = np.repeat(owner, count)
    rank = np.arange(len(mine)) - np.repeat(np.cumsum(count) - count, count)
    theirs = copper_owner[np.repeat(lo, count) + rank]
    if not len(mine):
        return 0
    # a pair met in several cells is tested more than once: cheaper than sorting them all
    ours, others = long_tool[mine], long_copper[theirs]
    p, q = tool.a[ours], tool.b[ours]
    a, b = copper.a[others], copper.b[others]
    cross = ((_left(a, b, p) * _left(a, b, q) <= 0) & (_left(p, q, a) * _left(p, q, b) <= 0))
    return len(np.unique(np.stack([ours[cross], others[cross]]), axis=1)[0])


def _long(index: EdgeIndex, length: float) -> np.ndarray:
    """The edges at least `length` long."""
    d = (index.b - index.a).astype(np.float64)
    return np.flatnonzero(np.hypot(d[:, 0], d[:, 1]) >= length)


def _swept_in_copper(paths: list[np.ndarray], islands: list, radius_nm: int,
                     tolerance_nm: int) -> float:
    """The area of the copper `islands` ((outer, holes) rings) that the passes stroked by
    `radius_nm` cover (nm^2), at least: the stroke's round joins may fall short of it by
    join_sagitta_nm, so it reaches so much further."""
    if not paths or not islands:
        return 0.0
    reach = radius_nm + join_sagitta_nm(tolerance_nm)
    low = np.array([outer.min(axis=0) for outer, _holes in islands])
    high = np.array([outer.max(axis=0) for outer, _holes in islands])
    area = 0.0
    # in strips of paths taken left to right, each against the islands in its reach:
    # one stroke of every path is a union of all their edges at once (6 s on a
    # 117k-vertex layer)
    for strip in _strips(paths):
        box_low = np.min([ring.min(axis=0) for ring in strip], axis=0) - reach
        box_high = np.max([ring.max(axis=0) for ring in strip], axis=0) + reach
        near = np.flatnonzero(np.all((low <= box_high) & (high >= box_low), axis=1))
        if not len(near):
            continue
        copper = [ring for k in near.tolist() for ring in (islands[k][0], *islands[k][1])]
        engine = pc.PyclipperOffset(2.0, float(arc_tolerance_nm(tolerance_nm)))
        engine.AddPaths([ring.tolist() for ring in strip], pc.JT_ROUND, pc.ET_CLOSEDLINE)
        area += clip.area_nm2(clip.intersection(engine.Execute(float(reach)), copper))
    return area


def _strips(paths: list[np.ndarray], most_vertices: int = STRIP_VERTICES
            ) -> list[list[np.ndarray]]:
    """The paths sorted by left edge, in runs of at most `most_vertices` vertices."""
    order = sorted(range(len(paths)), key=lambda k: int(paths[k][:, 0].min()))
    strips, strip, count = [], [], 0
    for k in order:
        if strip and count + len(paths[k]) > most_vertices:
            strips.append(strip)
            strip, count = [], 0
        strip.append(paths[k])
        count += len(paths[k])
    return strips + ([strip] if strip else [])
