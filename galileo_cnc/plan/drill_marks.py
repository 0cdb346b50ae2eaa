"""Drill marks: the ink leaves each hole's centre bare, so etching leaves a pit that
centres the bit (KiCad's plot option "drill marks", for toner and pen transfer).

- `none`: the pads are inked solid, as without holes;
- `small` (the default): a dot `size_nm` wide (0.3 mm), never wider than the hole,
  at each hole's centre; a slot gets a dot at each end of its path (where a hand
  drill starts the slot), or, where the copper between the two dots is too thin for
  the pen to ink, one mark along its path (that copper is inside the slot);
- `actual`: the whole hole; a slot its whole stadium (an arc slot swept along its arc).

The copper around a mark is still inked. A mark must leave a ring the smallest pen
can fill (its width plus the edge margins, as the ink's `limit`, ink/inking.py):
where the copper round a hole is thinner, the copper wins: the mark shrinks, down
to MIN_MARK_NM, or is left out, and a warning names the hole's place in mm. Two dots too
close for the pen to pass between share the room between them the same way. A mark
whose centre is off the copper (an unplated hole without a pad) is left out quietly:
the board is bare there already.

In ink mode the marks reach the ink as `bare` (ink_paths): out of the copper before
the fill, centre lines cut a pen radius short of them. In centre mode a flash on a
hole is drawn as a ring around its mark instead of a dot (`ring_flashes`), and straight
draws (a trace to its pad's centre) stop a pen radius short of the marks
(`clear_centre_lines`); arcs are drawn as they are.
Registration crosses (sides.py) on holes keep out of the marks and of every other
copper island (`clear_strokes`): ink on the hole's own pad is ink on ink.
Everything is in integer nm; the discs are pyclipper's round offsets (clip.py).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Sequence, Union

import numpy as np
import pyclipper as pc

from galileo_cnc.plan import curves
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.edges import EdgeIndex
from galileo_cnc.plan.order.nearby import near_pairs
from galileo_cnc.plan.widths import aperture_width, mm_text
from galileo_cnc.program.drills import Hole, Slot
from galileo_cnc.program.ops import (COL, COLUMNS, I, J, KIND, LINE, NM_PER_MM, TOOL, X, Y,
                                     OpKind, Program)

DRILL_MARK_MODES = ("none", "small", "actual")
#: the small mark's width (KiCad's small drill marks are 0.3 mm wide too)
DEFAULT_DRILL_MARK_NM = 300_000
#: a mark shrunk below this width is left out: too small a pit to find
MIN_MARK_NM = 100_000
#: the ink keeps this far from a mark: the stepped path strays up to ~0.7 step (8.75 um),
#: the fitted arcs and the discs' chords a tolerance (2 um) each
MARK_CLEARANCE_NM = 20_000
#: a slot's path is measured against the copper at points this far apart
_SAMPLE_NM = 10_000
#: drill-mark warnings shown before a job: a board of vias has a hundred and more (the
#: mark left out in each via's thin ring); one line counts the rest (as the ink's bridges)
SHOWN_MARK_WARNINGS = 20

Drill = Union[Hole, Slot]


@dataclass(frozen=True)
class DrillMark:
    """One bare area: the disc of `radius_nm` swept along `path` (one point: a dot)."""

    path: tuple[tuple[int, int], ...]
    radius_nm: int
    drill: Drill

    @property
    def where(self) -> str:
        x, y = self.path[0]
        what = "slot" if isinstance(self.drill, Slot) else "hole"
        return (f"the {mm_text(self.drill.diameter_nm)} mm {what} at "
                f"X {x / NM_PER_MM:.3f}, Y {y / NM_PER_MM:.3f} mm")

    def polygons(self, tolerance_nm: int, grown_nm: int = 0) -> list:
        """The mark's area (grown by `grown_nm`), a pyclipper set."""
        return clip.stroke([list(self.path)], self.radius_nm + grown_nm, tolerance_nm)


def check_mode(mode: str) -> str:
    if mode not in DRILL_MARK_MODES:
        raise ValueError(f"--drill-marks: expected none, small or actual, got {mode!r}")
    return mode


def marks_for(drills: Sequence[Drill], mode: str = "small",
              size_nm: int = DEFAULT_DRILL_MARK_NM, tolerance_nm: int = 2_000
              ) -> list[DrillMark]:
    """The marks the holes and slots ask for, before the copper is asked (module doc)."""
    if check_mode(mode) == "none":
        return []
    marks = []
    for drill in drills:
        radius = drill.diameter_nm // 2 if mode == "actual" \
            else min(size_nm, drill.diameter_nm) // 2
        if radius <= 0:
            continue
        if isinstance(drill, Hole):
            marks.append(DrillMark(((drill.x_nm, drill.y_nm),), radius, drill))
        elif mode == "small":
            ends = {(drill.x0_nm, drill.y0_nm), (drill.x1_nm, drill.y1_nm)}
            marks += [DrillMark((end,), radius, drill) for end in sorted(ends)]
        else:
            marks.append(DrillMark(slot_path(drill, tolerance_nm), radius, drill))
    return marks


def slot_path(slot: Slot, tolerance_nm: int) -> tuple[tuple[int, int], ...]:
    """A slot's centre line as points: its ends, or its arc in chords within the tolerance."""
    if slot.arc:
        points = curves.arc_points(slot.x0_nm, slot.y0_nm, slot.x1_nm, slot.y1_nm,
                                   slot.cx_nm - slot.x0_nm, slot.cy_nm - slot.y0_nm,
                                   slot.arc == "cw", tolerance_nm)
        return tuple((int(x), int(y)) for x, y in np.asarray(points).tolist())
    ends = ((slot.x0_nm, slot.y0_nm), (slot.x1_nm, slot.y1_nm))
    return ends[:1] if ends[0] == ends[1] else ends


@dataclass
class FittedMarks:
    """The marks the copper leaves room for, and what became of the others."""

    marks: list[DrillMark]
    warnings: list[str]
    off_copper: int = 0          # marks left out quietly: no copper at their centre

    def bare(self, tolerance_nm: int, clearance_nm: int = MARK_CLEARANCE_NM) -> list:
        """The area the ink keeps out of: every mark grown by the clearance."""
        if not self.marks:
            return []
        return clip.union(*[mark.polygons(tolerance_nm, clearance_nm) for mark in self.marks])


def fit_marks(marks: list[DrillMark], copper: list, ring_nm: int, pen_nm: int,
              clearance_nm: int = MARK_CLEARANCE_NM, tolerance_nm: int = 2_000
              ) -> FittedMarks:
    """Each mark shrunk so that `ring_nm` of copper (what the pen `pen_nm` needs to
    fill) is left between its clearance and the copper's edge, or left out below
    MIN_MARK_NM (module doc). `copper`: a pyclipper set, positive winding."""
    rings = clip.rings_as_arrays(copper)
    if not marks or not rings:
        return FittedMarks([], [], len(marks))
    marks = _short_slots_joined(marks, ring_nm, clearance_nm, tolerance_nm)
    index = EdgeIndex(rings, cell_nm=max(ring_nm, 200_000))
    inside = _inside(rings, np.array([mark.path[0] for mark in marks], dtype=np.int64))
    kept, warnings, off = [], [], 0
    for mark, on_copper in zip(marks, inside.tolist()):
        if not on_copper:
            off += 1
            continue
        samples = _samples(mark.path)
        _edge, _t, distance = index.nearest_many(samples, ring_nm + mark.radius_nm)
        room = float(distance.min()) - _SAMPLE_NM / 2
        widest = math.floor(room - ring_nm - clearance_nm)
        reach = f"the copper reaches {room / NM_PER_MM:.2f} mm from its centre, and the " \
            f"{mm_text(pen_nm)} mm pen needs {(ring_nm + clearance_nm) / NM_PER_MM:.2f} mm of it"
        if widest >= mark.radius_nm:
            kept.append(mark)
        elif 2 * widest >= MIN_MARK_NM:
            kept.append(dataclasses.replace(mark, radius_nm=widest))
            warnings.append(f"drill mark of {mark.where} made {2 * widest / NM_PER_MM:.2f} mm "
                            f"wide, not {mm_text(2 * mark.radius_nm)} mm: {reach} round "
                            "the mark")
        else:
            warnings.append(f"drill mark of {mark.where} left out: {reach} round a mark at "
                            f"least {mm_text(MIN_MARK_NM)} mm wide; the pad is inked solid")
    kept, crowded = _crowded_marks_shrunk(kept, rings, ring_nm, pen_nm, clearance_nm)
    return FittedMarks(kept, warnings + crowded, off)


def _crowded_marks_shrunk(marks: list[DrillMark], rings: list[np.ndarray], ring_nm: int,
                          pen_nm: int, clearance_nm: int) -> tuple[list[DrillMark], list[str]]:
    """Two dots closer than the pen can pass between (less than `ring_nm` of copper
    between their clearances, the copper whole between them) share what room there is:
    each shrinks to half of it, or is left out below MIN_MARK_NM. A pour stitched with
    vias 0.635 mm apart otherwise keeps a lens of copper between each two marks that
    no 0.4 mm pen reaches, bare beside inked copper. Returns the marks and a warning
    for each mark changed."""
    dots = [k for k, mark in enumerate(marks) if len(mark.path) == 1]
    if len(dots) < 2:
        return marks, []
    reach = 2 * max(marks[k].radius_nm for k in dots) + 2 * clearance_nm + ring_nm
    pairs = []
    for _d2, a, b in near_pairs([marks[k].path[0] for k in dots], reach):
        k, j = dots[a], dots[b]
        distance = math.dist(marks[k].path[0], marks[j].path[0])
        if distance < marks[k].radius_nm + marks[j].radius_nm + 2 * clearance_nm + ring_nm:
            pairs.append((k, j, distance))
    if not pairs:
        return marks, []
    middles = np.array([[(marks[k].path[0][0] + marks[j].path[0][0]) // 2,
                         (marks[k].path[0][1] + marks[j].path[0][1]) // 2]
                        for k, j, _ in pairs], dtype=np.int64)
    allowed: dict[int, tuple[int, int]] = {}     # mark -> (radius, the neighbour that set it)
    for (k, j, distance), between_on_copper in zip(pairs, _inside(rings, middles).tolist()):
        if not between_on_copper:
            continue
        share = math.floor((distance - 2 * clearance_nm - ring_nm) / 2)
        for mark, other in ((k, j), (j, k)):
            if share < allowed.get(mark, (marks[mark].radius_nm, -1))[0]:
                allowed[mark] = (share, other)
    kept, warnings = [], []
    for k, mark in enumerate(marks):
        if k not in allowed:
            kept.append(mark)
            continue
        radius, other = allowed[k]
        ox, oy = marks[other].path[0]
        why = (f"the hole at X {ox / NM_PER_MM:.3f}, Y {oy / NM_PER_MM:.3f} mm is "
               f"{math.dist(mark.path[0], (ox, oy)) / NM_PER_MM:.3f} mm away and the "
               f"{mm_text(pen_nm)} mm pen needs {(ring_nm + 2 * clearance_nm) / NM_PER_MM:.2f} "
               "mm between the marks")
        if 2 * radius >= MIN_MARK_NM:
            kept.append(dataclasses.replace(mark, radius_nm=radius))
            warnings.append(f"drill mark of {mark.where} made {2 * radius / NM_PER_MM:.2f} mm "
                            f"wide, not {mm_text(2 * mark.radius_nm)} mm: {why}")
        else:
            warnings.append(f"drill mark of {mark.where} left out: {why}; the pad is inked "
                            "solid")
    return kept, warnings


def _short_slots_joined(marks: list[DrillMark], ring_nm: int, clearance_nm: int,
                        tolerance_nm: int) -> list[DrillMark]:
    """A slot's two end dots too close for the pen to ink the copper between them
    (less than `ring_nm` between their clearances) become one mark along the slot's
    path: that copper is inside the slot, which takes it away, and left between the
    dots it would be a sliver no pen fills, bare beside inked copper."""
    ends: dict[int, list[int]] = {}
    for k, mark in enumerate(marks):
        if isinstance(mark.drill, Slot) and len(mark.path) == 1:
            ends.setdefault(id(mark.drill), []).append(k)
    joined: dict[int, DrillMark | None] = {}
    for pair in ends.values():
        if len(pair) != 2:
            continue
        a, b = marks[pair[0]], marks[pair[1]]
        gap = math.dist(a.path[0], b.path[0]) - a.radius_nm - b.radius_nm - 2 * clearance_nm
        if gap < ring_nm:
            joined[pair[0]] = DrillMark(slot_path(a.drill, tolerance_nm),
                                        min(a.radius_nm, b.radius_nm), a.drill)
            joined[pair[1]] = None
    if not joined:
        return marks
    return [joined.get(k, mark) for k, mark in enumerate(marks) if joined.get(k, mark)]


def warnings_to_show(warnings: Sequence[str], shown: int = SHOWN_MARK_WARNINGS) -> list[str]:
    """The first `shown` warnings and a line counting the rest (every one for `info`)."""
    hidden = len(warnings) - shown
    if hidden <= 0:
        return list(warnings)
    return list(warnings[:shown]) + [f"... and {hidden:,} more drill marks shrunk or left "
                                     "out (galileo-cnc info lists every one)"]


def _samples(path: tuple[tuple[int, int], ...]) -> np.ndarray:
    """Points along the path at most _SAMPLE_NM apart, its vertices included."""
    points = np.array(path, dtype=np.float64)
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:]):
        count = max(1, math.ceil(math.hypot(*(b - a)) / _SAMPLE_NM))
        t = np.arange(1, count + 1)[:, None] / count
        out.append(a + (b - a) * t)
    return np.rint(np.concatenate(out)).astype(np.int64)


def _inside(rings: list[np.ndarray], points: np.ndarray) -> np.ndarray:
    """Which points are inside the set (positive winding: outers count +1, holes -1),
    asking only the rings whose box holds the point."""
    lows = np.array([ring.min(axis=0) for ring in rings])
    highs = np.array([ring.max(axis=0) for ring in rings])
    signs = [1 if pc.Area(ring.tolist()) > 0 else -1 for ring in rings]
    result = np.zeros(len(points), dtype=bool)
    for k, (x, y) in enumerate(points.tolist()):
        near = np.flatnonzero((lows[:, 0] <= x) & (highs[:, 0] >= x) & (lows[:, 1] <= y)
                              & (highs[:, 1] >= y))
        winding = sum(signs[r] for r in near.tolist()
                      if pc.PointInPolygon((x, y), rings[r].tolist()) == 1)
        result[k] = winding > 0
    return result


class MarkCutter:
    """The `bare` hook ink_paths calls with the copper (module doc): fits the marks to
    it and keeps what it decided, for the warnings and the previews."""

    def __init__(self, marks: list[DrillMark], ring_nm: int, pen_nm: int, tolerance_nm: int):
        self.marks, self.ring_nm, self.pen_nm, self.tolerance_nm = marks, ring_nm, pen_nm, \
            tolerance_nm
        self.fitted = FittedMarks([], [])

    def __call__(self, copper: list) -> list:
        self.fitted = fit_marks(self.marks, copper, self.ring_nm, self.pen_nm,
                                tolerance_nm=self.tolerance_nm)
        return self.fitted.bare(self.tolerance_nm)


_MOVE, _FLASH, _CCW = int(OpKind.MOVE), int(OpKind.FLASH), int(OpKind.ARC_CCW)


def ring_flashes(program: Program, marks: list[DrillMark], pen_nm: int
                 ) -> tuple[Program, list[str]]:
    """Centre mode: each flash on a hole drawn as a circle a pen radius (and the
    clearance) outside its mark, with the flash's own aperture, instead of a dot; a pad
    too small to hold the ring keeps its dot, and a warning says so."""
    dots = {}
    for mark in marks:
        if isinstance(mark.drill, Hole):        # a slot's pad keeps its flash
            dots.setdefault(mark.path[0], mark)
    table = program.table
    flashes = np.flatnonzero(table[:, KIND] == _FLASH).tolist()
    if not dots or not flashes:
        return program, []
    centres = np.array(list(dots), dtype=np.int64)
    marks_at = list(dots.values())
    rows, warnings, last = [], [], 0
    for op in flashes:
        x, y = int(table[op, X]), int(table[op, Y])
        gap = np.abs(centres - (x, y)).max(axis=1)
        nearest = int(np.argmin(gap))
        mark = marks_at[nearest]
        if gap[nearest] > mark.drill.diameter_nm // 2:
            continue
        aperture = program.apertures.get(int(table[op, TOOL]))
        radius = mark.radius_nm + MARK_CLEARANCE_NM + pen_nm // 2
        pad = _pad_radius(aperture)
        if pad < radius + pen_nm // 2:
            warnings.append(f"{program.source}:{table[op, LINE]}:{table[op, COL]}: the pad "
                            f"on {mark.where} is too small for a ring round its drill mark "
                            f"with the {mm_text(pen_nm)} mm pen: drawn as a dot")
            continue
        rows.append(table[last:op])
        circle = np.zeros((2, len(COLUMNS)), dtype=np.int64)
        circle[:, [TOOL, LINE, COL]] = table[op, [TOOL, LINE, COL]]
        circle[0, [KIND, X, Y]] = (_MOVE, x + radius, y)
        circle[1, [KIND, X, Y, I, J]] = (_CCW, x + radius, y, -radius, 0)
        rows.append(circle)
        last = op + 1
    if not rows:
        return program, warnings
    rows.append(table[last:])
    return dataclasses.replace(program, table=np.concatenate(rows)), warnings


_LINE = int(OpKind.LINE)


def clear_centre_lines(program: Program, marks: list[DrillMark], pen_nm: int,
                       tolerance_nm: int) -> Program:
    """Centre mode: each straight draw cut short of the marks by the clearance and half
    its aperture's width (the pen drawing it; `pen_nm` where the width is unknown); the
    head travels pen up across the gap and on to the draw's end, where the next op
    starts."""
    table = program.table
    lines = np.flatnonzero(table[:, KIND] == _LINE)
    if not marks or not len(lines):
        return program
    ends = table[lines][:, [X, Y]]
    starts = np.where((lines > 0)[:, None], table[np.maximum(lines - 1, 0)][:, [X, Y]], 0)
    widths = {code: aperture_width(a) for code, a in program.apertures.items()
              if a.shape != "block"}
    half = np.array([(widths.get(int(code)) or pen_nm) // 2 for code in table[lines, TOOL]],
                    dtype=np.int64)
    low, high = np.minimum(starts, ends), np.maximum(starts, ends)
    near: dict[int, list[DrillMark]] = {}
    for mark in marks:
        points = np.array(mark.path, dtype=np.int64)
        reach = half + mark.radius_nm + MARK_CLEARANCE_NM + tolerance_nm
        hit = np.flatnonzero((low[:, 0] - reach <= points[:, 0].max())
                             & (high[:, 0] + reach >= points[:, 0].min())
                             & (low[:, 1] - reach <= points[:, 1].max())
                             & (high[:, 1] + reach >= points[:, 1].min()))
        for k in hit.tolist():
            near.setdefault(k, []).append(mark)
    if not near:
        return program
    rows, last = [], 0
    for k in sorted(near):
        op = int(lines[k])
        grown = clip.union(*[m.polygons(tolerance_nm, MARK_CLEARANCE_NM + int(half[k])
                                        + tolerance_nm) for m in near[k]])
        pieces = clip.open_difference([np.array([starts[k], ends[k]])], grown)
        rows.append(table[last:op])
        row = table[op]
        out = []
        for piece in pieces:
            for n, (x, y) in enumerate(piece.tolist()):
                new = row.copy()
                new[KIND], new[X], new[Y], new[I], new[J] = (_MOVE if n == 0 else _LINE), x, y, 0, 0
                out.append(new)
        end = row.copy()
        end[KIND] = _MOVE                      # on to where the next op starts
        if not out or out[-1][X] != end[X] or out[-1][Y] != end[Y]:
            out.append(end)
        rows.append(np.array(out, dtype=np.int64))
        last = op + 1
    rows.append(table[last:])
    return dataclasses.replace(program, table=np.concatenate(rows))


def _pad_radius(aperture) -> int:
    """The largest circle about the flash point the aperture's box holds (0: unknown)."""
    if aperture is None or not getattr(aperture, "extent_nm", None):
        return 0
    x0, y0, x1, y1 = aperture.extent_nm
    return max(0, min(-x0, -y0, x1, y1))


def clear_strokes(strokes: list[np.ndarray], copper: list, bare: list, pen_nm: int,
                  clearance_nm: int, tolerance_nm: int,
                  lines: Sequence[np.ndarray] = ()) -> list[np.ndarray]:
    """The strokes (registration crosses: two a cross) cut a pen radius short of the
    bare marks, and `clearance_nm` plus a pen radius short of any copper island but the
    one at each cross's centre (its pad) and of the centre lines' ink (`lines`, drawn
    with the pen: their overdraw passes the copper's edge), so their ink joins no two
    islands."""
    reach = pen_nm // 2 + tolerance_nm
    islands = clip.components(copper)
    lines = [np.asarray(line, dtype=np.int64) for line in lines if len(line)]
    out = []
    for k in range(0, len(strokes), 2):             # a cross: its two strokes
        horizontal = strokes[k]
        centre = horizontal.mean(axis=0).round().astype(np.int64)
        own = [n for n, (outer, holes) in enumerate(islands)
               if _inside([outer, *holes], centre[None, :])[0]]
        others = [ring for n, (outer, holes) in enumerate(islands) if n not in own
                  for ring in (outer, *holes)]
        span = int(np.abs(strokes[k] - centre).max()) + pen_nm + clearance_nm + reach
        near = [line for line in lines if _passes_near(line, centre - span, centre + span)]
        inked = clip.stroke([line.tolist() for line in near], pen_nm // 2, tolerance_nm)
        keep_out = clip.union(clip.offset(others, clearance_nm + reach, tolerance_nm),
                              clip.offset(inked, clearance_nm + reach, tolerance_nm),
                              clip.offset(bare, reach, tolerance_nm))
        out += clip.open_difference(strokes[k:k + 2], keep_out)
    return out


def _passes_near(line: np.ndarray, low: np.ndarray, high: np.ndarray) -> bool:
    """Whether a polyline comes into the box low..high: a segment's box meets it. Its
    vertices alone do not tell: a long trace passes a cross with both ends far away."""
    if len(line) == 1:
        return bool(np.all((line[0] >= low) & (line[0] <= high)))
    seg_low, seg_high = np.minimum(line[:-1], line[1:]), np.maximum(line[:-1], line[1:])
    return bool(np.any(np.all(seg_low <= high, axis=1) & np.all(seg_high >= low, axis=1)))
