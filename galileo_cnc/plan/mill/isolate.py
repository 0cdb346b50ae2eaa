"""Isolation passes round every copper island, from the exact copper, and the shorts.

`isolate(program, mill)` takes the copper the ink uses (ink/geometry.py: every object's
exact dark shape, curves as inscribed chords within `tolerance_nm`), and returns the
tool's paths: pass k (1..passes) is the outline of the copper grown by

    r_k = cut_width / 2 + margin + (k - 1) * cut_width * (1 - overlap)

so the first pass's tool centre runs half the cut width off the copper and each next
one a cut less the overlap further out. `margin` covers what the polygons leave out:
the copper's chords (the true copper lies up to `tolerance_nm` outside them), the
offset's own chords and cleaning (inside the true round corner), the chords of the
proof's swept area (proof.py), and rounding to the nanometre. Clipper's round joins
are not within their arc tolerance: a join takes round(angle x steps per radian)
chords, so an angle worth just under 1.5 chords gets one, 1.5 times as wide, whose
sagitta is 2.25 times the tolerance (measured: 2.8 um off at a 2 um tolerance). The copper of all islands is grown as one set, so a pass never runs between
two islands the tool cannot pass between: it goes round both.

Those places are the shorts: two islands whose gap is under 2 r_1 (the tool does not
fit) stay joined by the copper left between them. `shorts` lists each pair once with
the narrowest gap and its midpoint (work coordinates), and `refuse_shorts` stops a job
that has any unless the user accepts them. Islands that touch (Clipper keeps copper
that meets at a vertex as two pieces) are one; any gap at all between two islands is a
short when the tool does not fit, even a plane split of a few um that no board house
etches (the ink joins those below ink/islands.TOUCH_NM): the user is told and decides.

proof.py proves that no pass enters the copper, before anything is cut.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from galileo_cnc.config.mill import MillConfig
from galileo_cnc.errors import GalileoError
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.edges import EdgeIndex, point_to_edges
from galileo_cnc.plan.ink.geometry import dark_geometry
from galileo_cnc.plan.ink.islands import Islands, _joined
from galileo_cnc.plan.widths import mm_text
from galileo_cnc.program.ops import Program

#: The copper's chord tolerance, and the passes' (the ink's: a third of a motor step).
MILL_TOLERANCE_NM = 2_000
#: Rounding to the nanometre, twice (the copper's vertices, the offset's).
ROUNDING_NM = 2
#: Shorts listed in the refusal: a dense board under a wide cut has thousands (LimeSDR's
#: top: 2,322 under the 0.154 mm V-bit).
SHOWN_SHORTS = 20
#: Islands closer than this touch (module doc): nothing but rounding lies between them.
TOUCH_NM = 1
#: A round join's chords stray up to this many times the arc tolerance (module doc).
JOIN_SAGITTA_FACTOR = 2.25


class ShortsError(GalileoError):
    """Islands the tool cannot separate, and the user has not accepted them."""


@dataclass(frozen=True)
class Short:
    """Two islands closer than the tool can pass between: `gap_nm` at its narrowest,
    `at_nm` the midpoint of that gap (work coordinates)."""

    islands: tuple[int, int]
    gap_nm: float
    at_nm: tuple[int, int]

    def describe(self) -> str:
        x, y = self.at_nm
        return (f"islands {self.islands[0]} and {self.islands[1]}: {mm_text(round(self.gap_nm))} "
                f"mm apart at X{x / 1e6:.3f} Y{y / 1e6:.3f} mm (work)")


@dataclass
class Isolation:
    """The passes of one copper layer for one tool."""

    source: str
    copper: list                      # pyclipper rings, the exact copper (module doc)
    islands: Islands
    passes: list[list[np.ndarray]]    # passes[k - 1]: pass k's closed rings, int64 nm
    radii_nm: list[int]               # r_k: how far pass k's tool centre runs off the copper
    cut_width_nm: int
    margin_nm: int
    tolerance_nm: int
    shorts: list[Short]
    seconds: dict = field(default_factory=dict)

    @property
    def rings(self) -> list[np.ndarray]:
        """Every pass's rings, first pass first."""
        return [ring for rings in self.passes for ring in rings]


def arc_tolerance_nm(tolerance_nm: int) -> int:
    """The arc tolerance of the passes' offsets and of the proof's swept area."""
    return max(1, tolerance_nm // 4)


def join_sagitta_nm(tolerance_nm: int) -> int:
    """How far inside its true round corner a Clipper offset at arc_tolerance_nm may run."""
    return math.ceil(JOIN_SAGITTA_FACTOR * arc_tolerance_nm(tolerance_nm))


def margin_nm(tolerance_nm: int) -> int:
    """What the passes keep off the copper beyond half the cut (module doc): the copper's
    chords, the offset's round joins and its cleaning (a quarter of its arc tolerance,
    before and after), the proof's swept area's round joins, rounding."""
    arc = arc_tolerance_nm(tolerance_nm)
    return tolerance_nm + 2 * join_sagitta_nm(tolerance_nm) + 2 * (arc // 4) + ROUNDING_NM


def pass_radii(mill: MillConfig, tolerance_nm: int = MILL_TOLERANCE_NM) -> list[int]:
    """r_k for k = 1..passes (module doc)."""
    first = mill.cut_width_nm // 2 + margin_nm(tolerance_nm)
    return [first + k * mill.step_nm for k in range(mill.passes)]


def isolate(program: Program, mill: MillConfig,
            tolerance_nm: int = MILL_TOLERANCE_NM) -> Isolation:
    """The isolation passes of a Gerber copper layer for `mill`'s tool (module doc)."""
    clock = time.perf_counter()
    copper = dark_geometry(program, tolerance_nm).native
    return isolate_copper(copper, mill, tolerance_nm, source=program.source,
                          started=clock)


def isolate_copper(copper: list, mill: MillConfig, tolerance_nm: int = MILL_TOLERANCE_NM,
                   source: str = "", started: float | None = None) -> Isolation:
    """`isolate` on copper already made (pyclipper rings, integer nm)."""
    clock = time.perf_counter()
    seconds = {"copper": clock - started} if started is not None else {}
    islands = Islands.of(copper)
    radii = pass_radii(mill, tolerance_nm)
    arc = arc_tolerance_nm(tolerance_nm)
    passes = [_outline(clip.offset(copper, radius, arc)) for radius in radii]
    seconds["passes"] = time.perf_counter() - clock
    clock = time.perf_counter()
    shorts = find_shorts(islands, 2 * radii[0])
    seconds["shorts"] = time.perf_counter() - clock
    return Isolation(source, copper, islands, passes, radii, mill.cut_width_nm,
                     margin_nm(tolerance_nm), tolerance_nm, shorts, seconds)


def _outline(grown: list) -> list[np.ndarray]:
    """The rings of a grown copper set, each a closed tool path (int64 nm)."""
    return clip.rings_as_arrays(grown)


def find_shorts(islands: Islands, reach_nm: int, pairs=None) -> list[Short]:
    """Each pair of islands closer than `reach_nm`, once, at its narrowest gap.

    Two segments that do not cross are nearest at an end of one of them, so the gap
    between two islands is the least distance from a vertex of either to an edge of
    the other: the edge index gives every (vertex, edge) pair of different islands
    within a cell, and the cell is the reach. `pairs(index, owner)`: another source of
    those pairs, sorted by vertex then edge (the tests' exhaustive one)."""
    if len(islands.parts) < 2:
        return []
    index = EdgeIndex(islands.rings, cell_nm=reach_nm)
    owner = islands.owner[index.ring]
    vertex, edge = (pairs or EdgeIndex.around_vertices)(index, owner)
    if not len(vertex):
        return []
    t, gap = point_to_edges(index.a[vertex].astype(np.float64), index.a[edge], index.b[edge])
    # islands that touch are one (module doc): joined before pairs are made
    touch = gap < TOUCH_NM
    joined = _joined(len(islands.parts), owner[vertex[touch]], owner[edge[touch]])
    mine, theirs = joined[owner[vertex]], joined[owner[edge]]
    close = (gap < reach_nm) & (mine != theirs)
    if not close.any():
        return []
    vertex, edge, t, gap = vertex[close], edge[close], t[close], gap[close]
    low, high = np.minimum(mine[close], theirs[close]), np.maximum(mine[close], theirs[close])
    # the narrowest (vertex, edge) pair of each island pair
    order = np.lexsort((gap, high, low))
    first = np.ones(len(order), dtype=bool)
    first[1:] = (low[order][1:] != low[order][:-1]) | (high[order][1:] != high[order][:-1])
    shorts = []
    for k in order[first].tolist():
        a, b = index.a[edge[k]].astype(np.float64), index.b[edge[k]].astype(np.float64)
        nearest = a + (b - a) * t[k]
        middle = (index.a[vertex[k]] + nearest) / 2
        pair = sorted((int(owner[vertex[k]]), int(owner[edge[k]])))   # the islands at the gap
        shorts.append(Short((pair[0], pair[1]), float(gap[k]),
                            (int(round(middle[0])), int(round(middle[1])))))
    return shorts


def refuse_shorts(isolation: Isolation, accept_shorts: bool = False) -> None:
    """ShortsError listing every short, unless there are none or the user accepts them."""
    if not isolation.shorts or accept_shorts:
        return
    shown = isolation.shorts[:SHOWN_SHORTS]
    listed = "\n".join(f"  {short.describe()}" for short in shown)
    if len(isolation.shorts) > len(shown):
        listed += (f"\n  ... and {len(isolation.shorts) - len(shown)} more "
                   f"(--accept-shorts writes the passes; its G-code lists them all)")
    raise ShortsError(
        f"{isolation.source}: {len(isolation.shorts)} place(s) where two copper islands are "
        f"closer than the {mm_text(isolation.cut_width_nm)} mm cut: the tool cannot pass "
        f"between them and leaves them joined:\n{listed}\n"
        f"(a narrower tool or a shallower V-bit cut separates them; --accept-shorts "
        f"mills the board with them joined)")

