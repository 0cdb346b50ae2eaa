"""Cutting a board out along its outline on a GRBL mill: what `convert --mill cutout`
is to write (docs/mill.md, "Cut-out").

- The outline layer's strokes (lines and arcs, each drawn on its own as KiCad does, or
  in runs) are chained end to end into closed contours; ends within 0.1 mm join (CAD
  exports leave such gaps). Strokes that close nothing (dimension lines, marks) are
  left out and reported with their place; an outline with no closed contour is an error.
- The board's edge is the outline's centre line: the board keeps the size drawn. The
  tool (the profile's end mill, `diameter_mm`) runs outside it, its centre the tool's
  radius off (plus 4 um for the chords of arcs and round corners), so it cuts nothing of
  the board. A contour inside another is a hole in the board (cut from inside it, the
  tool's radius in); one inside a hole is a board again, and so on.
- Holes are cut first, then the edges: the board stays held until its last cut.
  Edges run clockwise, holes counter-clockwise: climb milling with the spindle's M3.
- Depth passes: equal steps of at most `cutout_step_down_mm` down to
  `board_thickness_mm` (Z = 0 at the board's top).
- Tabs on the board's edges: `tabs` of them (or one every `tab_spacing_mm`), spread
  evenly along each edge by its length, the first half a spacing from where the cut
  starts; an edge too short for them gets as many as fit with a tab's room between
  (reported). A tab leaves `tab_width_mm` of board; its top is `tab_height_mm` above the
  board's bottom. Passes deeper than that top rise to it over the tab: over the tab's
  width plus the tool's diameter along the tool's path, since the tool's edge reaches a
  radius either side of its centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pyclipper as pc

from galileo_cnc.config.mill import MillConfig
from galileo_cnc.errors import GalileoError
from galileo_cnc.plan.mill.drill import depth_levels, mm_text as _mm
from galileo_cnc.plan.mill.gcode import _comment
from galileo_cnc.plan.mill.isolate import JOIN_SAGITTA_FACTOR
from galileo_cnc.program.ops import OpKind, Program
from galileo_cnc.readers.gcode.writer import mm

#: Stroke ends this close are one point of the contour.
JOIN_NM = 100_000
#: The chords of arcs (the outline's and the offset's round corners) stay this close.
ARC_TOLERANCE_NM = 1_000


class CutoutError(GalileoError):
    """An outline that does not close, tabs that do not fit, a tool too wide."""


@dataclass
class Cut:
    """One closed path of the tool centre (int64 rows x, y, not repeating its first),
    whether it is a board's edge (tabs) or a hole's, and its tab spans (start, end)
    as lengths along the path from its first point."""

    ring: np.ndarray
    edge: bool
    tabs: list[tuple[float, float]]


@dataclass
class CutoutPlan:
    """The cuts in order and what the user should read (strokes left out, tabs
    fewer than asked)."""

    cuts: list[Cut]
    notes: list[str]


def cutout_gcode(outline: Program, mill: MillConfig) -> str:
    """The cut-out G-code of an outline layer (module doc)."""
    plan = plan_cutout(outline, mill)
    return cuts_gcode(plan.cuts, mill, outline.source, plan.notes)


def plan_cutout(outline: Program, mill: MillConfig) -> CutoutPlan:
    """The tool's paths round the outline, holes first (module doc)."""
    notes: list[str] = []
    contours = chain_outline(outline, notes)
    if not contours:
        raise CutoutError(f"{outline.source}: no closed contour on the outline layer"
                          f"{': ' + notes[0] if notes else ''}")
    radius = mill.diameter_nm // 2 + clearance_margin_nm()
    depths = _nesting(contours)
    cuts = []
    for contour, depth in zip(contours, depths):
        edge = depth % 2 == 0
        if not pc.Orientation(contour.tolist()):
            contour = contour[::-1]
        engine = pc.PyclipperOffset(2.0, float(ARC_TOLERANCE_NM))
        engine.AddPath(contour.tolist(), pc.JT_ROUND, pc.ET_CLOSEDPOLYGON)
        rings = engine.Execute(float(radius if edge else -radius))
        if not rings:
            x, y = contour[0].tolist()
            raise CutoutError(f"{outline.source}: the hole in the outline at X {_mm(x)} "
                              f"Y {_mm(y)} mm is narrower than the {_mm(mill.diameter_nm)} "
                              f"mm end mill (diameter_mm): a smaller one cuts it")
        for ring in rings:
            ring = np.array(ring, dtype=np.int64)
            # clockwise round a board (Clipper's rings come counter-clockwise)
            ring = ring[::-1] if edge else ring
            tabs = _tabs(ring, mill, outline.source, notes) if edge else []
            cuts.append(Cut(ring, edge, tabs))
    return CutoutPlan(sorted(cuts, key=lambda cut: cut.edge), notes)


def clearance_margin_nm() -> int:
    """What the tool keeps off the outline beyond its radius: the chords of the
    outline's arcs and those of the offset's round corners (isolate.py measured how far
    a Clipper round join strays inside its arc)."""
    return ARC_TOLERANCE_NM + math.ceil(JOIN_SAGITTA_FACTOR * ARC_TOLERANCE_NM)


def cuts_gcode(cuts: list[Cut], mill: MillConfig, source: str = "",
               notes: list[str] = ()) -> str:
    """The cuts as GRBL G-code lines (module doc)."""
    safe = mm(mill.safe_height_nm)
    feed, plunge = mm(mill.feed_um_min * 1000), mm(mill.plunge_feed_um_min * 1000)
    thickness = mill.board_thickness_nm
    tab_top = thickness - mill.tab_height_nm
    lines = [f"(galileo-cnc mill: cut-out of {_comment(source)})",
             f"(end mill {_mm(mill.diameter_nm)} mm, Z = 0 at the board's top, through "
             f"{_mm(thickness)} mm)",
             *(f"({_comment(note)})" for note in notes),
             "G21 G90 G17 G94", f"G0 Z{safe}", f"M3 S{mill.spindle_rpm}"]
    for cut in cuts:
        points, in_tab = _split_at_tabs(cut)
        lines.append(f"G0 X{mm(int(points[0][0]))} Y{mm(int(points[0][1]))}")
        for level in depth_levels(thickness, mill.cutout_step_down_nm):
            lines.append(f"G1 Z{mm(-level)} F{plunge}")
            z = level
            for (x, y), tab in zip(points[1:], in_tab):
                want = tab_top if tab and level > tab_top else level
                if want != z:
                    lines.append(f"G1 Z{mm(-want)} F{plunge}")
                    z = want
                lines.append(f"G1 X{mm(int(x))} Y{mm(int(y))} F{feed}")
        lines.append(f"G0 Z{safe}")
    lines += ["M5", "M2"]
    return "\n".join(lines) + "\n"


def chain_outline(outline: Program, notes: list[str]) -> list[np.ndarray]:
    """The outline's strokes chained into closed contours (int64 rows, not repeating
    the first point); a chain that stays open is left out with a note naming its ends."""
    strokes = _strokes(outline)
    used = [False] * len(strokes)
    contours = []
    for first in range(len(strokes)):
        if used[first]:
            continue
        used[first] = True
        chain, found = [strokes[first]], strokes[first]
        while math.dist(chain[-1][-1], chain[0][0]) > JOIN_NM:
            found = _next(strokes, used, chain[-1][-1])
            if found is None:
                break
            chain.append(found)
        if found is None:
            (x0, y0), (x1, y1) = chain[0][0], chain[-1][-1]
            notes.append(f"{outline.source}: strokes from X {_mm(x0)} Y {_mm(y0)} to "
                         f"X {_mm(x1)} Y {_mm(y1)} mm close nothing: left out")
            continue
        points = np.vstack([part[:-1] for part in chain]).astype(np.int64)
        if len(points) >= 3:
            contours.append(points)
    return contours


def _next(strokes: list, used: list, end) -> np.ndarray | None:
    """The unused stroke with an end within JOIN_NM of `end`, turned to start there."""
    best, best_distance = None, JOIN_NM
    for k, stroke in enumerate(strokes):
        if used[k]:
            continue
        for forward, point in ((True, stroke[0]), (False, stroke[-1])):
            distance = math.dist(point, end)
            if distance <= best_distance:
                best, best_distance = (k, forward), distance
    if best is None:
        return None
    k, forward = best
    used[k] = True
    return strokes[k] if forward else strokes[k][::-1]


def _strokes(outline: Program) -> list[np.ndarray]:
    """Every line and arc of the outline as a polyline (float rows), in draw order;
    a run of strokes end to end stays one."""
    strokes, at = [], (0, 0)
    for op in outline:
        if op.kind == OpKind.MOVE:
            at = (op.x_nm, op.y_nm)
        elif op.kind in (OpKind.LINE, OpKind.ARC_CW, OpKind.ARC_CCW):
            end = (op.x_nm, op.y_nm)
            if op.kind == OpKind.LINE:
                points = [at, end]
            else:
                centre = (at[0] + op.i_nm, at[1] + op.j_nm)
                points = _arc_points(at, end, centre, op.kind == OpKind.ARC_CW)
            if strokes and strokes[-1][-1] == at:
                strokes[-1].extend(points[1:])
            else:
                strokes.append(list(points))
            at = end
    return [np.array(stroke, dtype=np.float64) for stroke in strokes
            if math.dist(stroke[0], stroke[-1]) > 0 or len(stroke) > 2]


def _arc_points(start, end, centre, clockwise: bool) -> list[tuple[int, int]]:
    """The arc in chords within ARC_TOLERANCE_NM; start == end: the full circle."""
    radius = math.dist(start, centre)
    a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
    a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
    sweep = (a0 - a1) % math.tau if clockwise else (a1 - a0) % math.tau
    sweep = sweep or math.tau
    step = 2 * math.acos(max(-1.0, 1 - ARC_TOLERANCE_NM / radius)) if radius else math.tau
    count = max(1, math.ceil(sweep / step))
    sign = -1 if clockwise else 1
    points = [(round(centre[0] + radius * math.cos(a0 + sign * sweep * k / count)),
               round(centre[1] + radius * math.sin(a0 + sign * sweep * k / count)))
              for k in range(count)]
    return [tuple(start), *points[1:], tuple(end)]


def _nesting(contours: list[np.ndarray]) -> list[int]:
    """How many other contours hold each one (its first point inside them)."""
    return [sum(1 for k, other in enumerate(contours) if k != j
                and pc.PointInPolygon(tuple(contour[0].tolist()), other.tolist()) == 1)
            for j, contour in enumerate(contours)]


def _tabs(ring: np.ndarray, mill: MillConfig, source: str,
          notes: list[str]) -> list[tuple[float, float]]:
    """The tab spans along the tool's path (module doc)."""
    length = float(_lengths(ring)[-1])
    if mill.tab_spacing_nm:
        count = max(1, round(length / mill.tab_spacing_nm))
    else:
        count = mill.tabs
    if count == 0:
        return []
    if mill.tab_height_nm >= mill.board_thickness_nm:
        raise CutoutError(f"{source}: tabs {_mm(mill.tab_height_nm)} mm high on a board "
                          f"{_mm(mill.board_thickness_nm)} mm thick hold the whole board")
    span = mill.tab_width_nm + mill.diameter_nm
    fit = int(length // (2 * span))
    if fit < count:
        x, y = ring[0].tolist()
        notes.append(f"{source}: the edge cut from X {_mm(x)} Y {_mm(y)} mm is "
                     f"{_mm(round(length))} mm long: {fit} tab(s) of {count} fit")
        count = fit
    if count == 0:
        return []
    spacing = length / count
    return [((k + 0.5) * spacing - span / 2, (k + 0.5) * spacing + span / 2)
            for k in range(count)]


def _lengths(ring: np.ndarray) -> np.ndarray:
    """The length along the closed ring at each point and back at the first."""
    closed = np.vstack([ring, ring[:1]]).astype(np.float64)
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(closed, axis=0).T))])


def _split_at_tabs(cut: Cut) -> tuple[list, list[bool]]:
    """The closed ring's points with the tab ends put in, and for each move after the
    first point whether it runs over a tab."""
    closed = np.vstack([cut.ring, cut.ring[:1]]).astype(np.float64)
    along = _lengths(cut.ring)
    marks = sorted(s for span in cut.tabs for s in span)
    points, at = [tuple(closed[0])], [0.0]
    for k in range(1, len(closed)):
        for s in marks:
            if along[k - 1] < s < along[k]:
                share = (s - along[k - 1]) / (along[k] - along[k - 1])
                points.append(tuple(np.rint(closed[k - 1] + share * (closed[k] - closed[k - 1]))))
                at.append(s)
        points.append(tuple(closed[k]))
        at.append(float(along[k]))
    middles = [(a + b) / 2 for a, b in zip(at, at[1:])]
    in_tab = [any(lo < s < hi for lo, hi in cut.tabs) for s in middles]
    return points, in_tab
