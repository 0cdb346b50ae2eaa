"""The proof that no isolation pass enters the copper, before anything is cut.

The copper polygons hold the true copper to within `tolerance_nm` (inscribed chords:
the true outline lies at most that far outside them), so the tool, a disc of half the
cut width round its centre, leaves the true copper whole when every point of every
pass lies at least cut_width / 2 + tolerance_nm from the copper polygons. That is
shown in two parts, both on the integer polygons, neither trusting the offset that
made the passes:

1. No pass crosses or enters the copper: Clipper's intersection of the passes (as
   open paths) with the copper is empty.
2. Then two segments, one of a pass and one of the copper, do not cross, and such
   segments are nearest at an end of one of them: the least distance from every pass
   vertex to the copper's edges and from every copper vertex to the passes' edges is
   the clearance, exactly (the edge index's nearest-edge search, float64 on integer
   nm).

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
from galileo_cnc.plan.ink.edges import EdgeIndex
from galileo_cnc.plan.mill.isolate import Isolation, arc_tolerance_nm, join_sagitta_nm

#: The swept area inside the copper that still counts as none: Clipper's rounding.
SWEPT_AREA_ALLOWED_NM2 = 1_000_000      # 1 um^2
#: Vertices of the passes stroked at once for the swept area.
STRIP_VERTICES = 5_000


@dataclass(frozen=True)
class Proof:
    """What `prove` found (module doc)."""

    clearance_nm: float            # least distance from any pass to the copper polygons
    required_nm: int               # half the cut plus the copper's chord tolerance
    inside_nm: int                 # length of the passes inside the copper (part 1)
    swept_in_copper_nm2: float     # the second witness; -1 when not computed
    seconds: float

    @property
    def holds(self) -> bool:
        return (self.inside_nm == 0 and self.clearance_nm >= self.required_nm
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
    inside = _length_inside(rings, isolation.copper)
    clearance = clearance_nm(rings, isolation.islands.rings, search_nm=2 * required)
    area = _swept_in_copper(rings, isolation.islands.parts, required,
                            isolation.tolerance_nm) if swept else -1.0
    return Proof(clearance, required, inside, area, time.perf_counter() - clock)


def clearance_nm(paths: list[np.ndarray], copper_rings: list[np.ndarray],
                 search_nm: int) -> float:
    """The least distance between the closed `paths` and the copper's rings, when no
    path crosses the copper (module doc, part 2); inf when either is empty."""
    if not paths or not copper_rings:
        return float("inf")
    copper = EdgeIndex(copper_rings, cell_nm=search_nm)
    tool = EdgeIndex(paths, cell_nm=search_nm)
    _edge, _t, from_paths = copper.nearest_many(tool.a, search_nm)
    _edge, _t, from_copper = tool.nearest_many(copper.a, search_nm)
    return float(min(from_paths.min(), from_copper.min()))


def _length_inside(paths: list[np.ndarray], copper: list) -> int:
    """The length of the closed paths inside (or along) the copper, nm."""
    if not paths or not copper:
        return 0
    clipper = pc.Pyclipper()
    clipper.AddPaths([np.vstack([ring, ring[:1]]).tolist() for ring in paths],
                     pc.PT_SUBJECT, False)
    clipper.AddPaths(copper, pc.PT_CLIP, True)
    tree = clipper.Execute2(pc.CT_INTERSECTION, pc.PFT_POSITIVE, pc.PFT_POSITIVE)
    pieces = pc.OpenPathsFromPolyTree(tree)
    clip.free_tree(tree)
    length = 0.0
    for piece in pieces:
        points = np.asarray(piece, dtype=np.float64)
        length += float(np.hypot(*np.diff(points, axis=0).T).sum()) if len(points) > 1 else 1.0
    return int(np.ceil(length))


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
