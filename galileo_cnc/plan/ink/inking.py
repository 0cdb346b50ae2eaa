"""Ink a Gerber layer with the user's pens: the copper becomes pen paths (docs/ink.md).

`ink_program(program, pens_nm)` works out the copper (geometry.py), fills it pen by
pen, widest first (fill.py), draws what is narrower than the smallest pen as centre
lines that never join two islands (narrow.py), and returns the ink as a Program of
its own: one SELECT per pen, then MOVE/LINE/ARC/FLASH rows. The planner takes that
Program like any other Gerber file, so path order, pen changes, soft limits,
previews and resume work on ink unchanged. Ring rows carry line 0 (they come from
the union of many objects); centre lines keep their object's line and column.

A narrower pen fills what the wider ones left: the copper not yet inked (opened by
GAP_NM so rounding slivers along the edges do not count), where this pen reaches,
grown by twice its radius and cut back to the copper (so it has room to move).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from galileo_cnc.errors import ReaderWarning, SourcePos
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.arcs import fit_arcs, fit_paths
from galileo_cnc.plan.ink.background import Deferred
from galileo_cnc.plan.ink.fill import (BACKGROUND_VERTICES, DEFAULT_OVERLAP, GAP_NM, PenFill,
                                      fill_region, inked_area_nm2)
from galileo_cnc.plan.ink.geometry import DarkImage, dark_geometry
from galileo_cnc.plan.ink.islands import (CLEARANCE_NM, ClosePlaces, Islands, close_places,
                                         keep_back)
from galileo_cnc.plan.ink.narrow import (Bridge, NarrowFeature, find_narrow,
                                        keep_islands_apart)
from galileo_cnc.plan.ink.shapes import DEFAULT_TOLERANCE_NM
from galileo_cnc.plan.pieces import WHOLE_PATHS
from galileo_cnc.program.ops import (COL, KIND, LINE, NM_PER_MM, NO_TOOL, TOOL, Aperture,
                                     OpKind, Program, ProgramBuilder)
from galileo_cnc.readers.gerber.transformed import aperture_label

#: Bridge warnings shown before a job (plot, getg): a board of tight traces has
#: pages of them (arduino-uno.cmp with the default 0.4 mm pen: 1,548) before the pen
#: prompt; one line counts the rest, and `info` lists every one.
SHOWN_BRIDGES = 20

#: Default pen margin from the copper's edge: the stepped path strays up to ~0.7 step
#: from the planned one, half of that is the usual error (docs/ink.md, "Edge margin").
DEFAULT_EDGE_MARGIN_NM = 2_000

_MOVE, _LINE, _SELECT, _FLASH = (int(OpKind.MOVE), int(OpKind.LINE), int(OpKind.SELECT),
                                 int(OpKind.FLASH))


@dataclass
class InkPlan:
    """The ink of one layer for one pen set, and what it covers."""

    program: Program                      # the ink, as rows (module doc)
    pens_nm: tuple[int, ...]              # widest first; pen key k + 1 is pens_nm[k]
    copper: DarkImage
    fills: list[PenFill]
    narrow: list[NarrowFeature]
    bridges: list[Bridge]
    zero_size: int                        # objects of zero-size apertures (no copper)
    close: ClosePlaces                    # where islands come too close for two inks
    copper_nm2: float
    # (filled_nm2, inked_nm2): worked out meanwhile, a tuple once asked for
    coverage: Deferred | tuple[float, float]
    warnings: list[ReaderWarning] = field(default_factory=list)
    seconds: float = 0.0
    bridge_warnings: slice = field(default_factory=lambda: slice(0, 0))  # theirs in `warnings`

    def warnings_to_show(self) -> list[str]:
        """The warnings to print before a job: all but the bridges' past the first
        SHOWN_BRIDGES, which one line counts."""
        texts = [str(w) for w in self.warnings]
        first, end = self.bridge_warnings.start, self.bridge_warnings.stop
        hidden = end - first - SHOWN_BRIDGES
        if hidden <= 0:
            return texts
        return texts[:first + SHOWN_BRIDGES] + [
            f"... and {hidden:,} more places where a centre line is left short of another "
            "copper island (galileo-cnc info lists every one)"] + texts[end:]

    @property
    def filled_nm2(self) -> float:
        """Copper the fills cover."""
        return self._coverage()[0]

    @property
    def inked_nm2(self) -> float:
        """Copper the fills and the centre lines cover."""
        return self._coverage()[1]

    def _coverage(self) -> tuple[float, float]:
        if not isinstance(self.coverage, tuple):
            self.coverage = self.coverage.result()
        return self.coverage

    @property
    def pen_lifts(self) -> int:
        return sum(len(f.paths) for f in self.fills) + sum(len(n.pieces) for n in self.narrow)

    def pen_label(self, key: int) -> str:
        return f"{mm_text(self.pens_nm[key - 1])} mm pen"


def mm_text(nm: int) -> str:
    return f"{nm / NM_PER_MM:.3f}".rstrip("0").rstrip(".")


def ink_program(program: Program, pens_nm: tuple[int, ...] | list[int], *,
                tolerance_nm: int = DEFAULT_TOLERANCE_NM, overlap: float = DEFAULT_OVERLAP,
                edge_margin_nm: int = DEFAULT_EDGE_MARGIN_NM,
                on_stage: Callable[[str], None] | None = None) -> InkPlan:
    """The ink of a Gerber Program for the pens (widths in nm, any order).
    `on_stage(text)` hears what it starts on ("inking: filling with the 0.3 mm pen"): the
    largest layers take seconds a stage, and a front end can say so."""
    began = time.perf_counter()
    pens = tuple(sorted({int(p) for p in pens_nm if int(p) > 0}, reverse=True))
    if not pens:
        raise ValueError("no pen: give at least one pen width above 0")
    stage = on_stage or (lambda _text: None)
    stage("inking: working out the copper")
    copper = dark_geometry(program, tolerance_nm)
    region = copper.native
    islands = Islands.of(region)
    close = close_places(islands)
    keep_out = keep_back(close, CLEARANCE_NM // 2, tolerance_nm)
    fills: list[PenFill] = []
    inked: list = []                      # what the wider pens ink, for the narrower ones
    for number, width in enumerate(pens):
        stage(f"inking: filling with the {mm_text(width)} mm pen")
        radius = width // 2
        if number == 0:
            target = region
        else:
            left = clip.opening(clip.difference(region, inked), GAP_NM, tolerance_nm)
            reach = clip.opening(region, radius + edge_margin_nm, tolerance_nm)
            left = clip.intersection(left, reach)
            target = (clip.intersection(clip.offset(left, 2 * radius + edge_margin_nm,
                                                    tolerance_nm), region) if left else [])
        fill = fill_region(target, width, tolerance_nm, overlap=overlap,
                           edge_margin_nm=edge_margin_nm, keep_out=keep_out,
                           islands=islands.parts if number == 0 else None
                           ) if target else PenFill(width)
        fills.append(fill)
        if number + 1 < len(pens):
            inked = clip.union(inked, fill.ink) if inked else list(fill.ink)

    smallest = pens[-1]
    limit = smallest + 2 * edge_margin_nm + 4 * tolerance_nm
    stage("inking: finding features too narrow to fill")
    narrow, zero_size = find_narrow(program, limit, smallest, tolerance_nm)
    bridges = keep_islands_apart(narrow, islands, smallest)
    # the coverage figures need the ink as polygons (fill.InkRecipe): on a large board
    # a second process makes them while this one goes on to the rows and path order
    coverage = Deferred(_coverage, fills, [piece for f in narrow for piece in f.pieces],
                        smallest // 2, region, tolerance_nm,
                        fork=sum(len(ring) for ring in region) >= BACKGROUND_VERTICES)
    stage("inking: fitting arcs")
    plan = InkPlan(_rows(program, pens, fills, narrow), pens, copper, fills, narrow, bridges,
                   zero_size, close, clip.area_nm2(region), coverage)
    plan.warnings, plan.bridge_warnings = _warnings(program, plan)
    plan.program.warnings = list(program.warnings) + plan.warnings
    plan.seconds = time.perf_counter() - began
    return plan


def _coverage(fills: list[PenFill], centre_lines: list[np.ndarray], radius_nm: int,
              region: list, tolerance_nm: int) -> tuple[float, float]:
    """(copper the fills cover, copper the fills and the centre lines cover), nm2,
    worked out strip by strip (inked_area_nm2), not in one board-wide sweep."""
    filled = inked_area_nm2(fills, [], region)
    narrow_ink = clip.stroke(centre_lines, radius_nm, tolerance_nm) if centre_lines else []
    return filled, (inked_area_nm2(fills, narrow_ink, region) if narrow_ink else filled)


def _rows(program: Program, pens: tuple[int, ...], fills: list[PenFill],
          narrow: list[NarrowFeature]) -> Program:
    out = ProgramBuilder(program.source)
    # each walk is one island's rings and joins drawn as one stroke already (fill.py):
    # path order moves and reverses it, but has nothing to chain or leave out in it
    walks: list[tuple[int, int]] = []
    for number, fill in enumerate(fills):
        key = number + 1
        drawn = [n for n in narrow if n.pen_nm == fill.width_nm] if number == len(fills) - 1 else []
        if not fill.paths and not drawn:
            continue
        out.emit(_SELECT, tool=key)
        coarse = fill.coarse if len(fill.coarse) == len(fill.paths) else None
        for path, segments in zip(fill.paths, fit_paths(fill.paths, coarse=coarse)):  # at once
            first = out.count()
            _emit_path(out, path, key, 0, 0, segments)
            walks.append((first, out.count()))
        for feature in drawn:
            _emit_feature(out, feature, key)
    apertures = {k + 1: Aperture(k + 1, "circle", (w,), extent_nm=(-(w // 2), -(w // 2),
                                                                   w // 2, w // 2))
                 for k, w in enumerate(pens)}
    return out.build("gerber", program.units, apertures=apertures,
                     metadata={"ink": True, "pens_nm": list(pens),
                               WHOLE_PATHS: walks,
                               "source_metadata": program.metadata},
                     line_count=program.line_count)


def _emit_path(out: ProgramBuilder, path: np.ndarray, key: int, line: int, col: int,
               segments: list | None = None) -> None:
    x, y = int(path[0][0]), int(path[0][1])
    if len(path) == 1:
        out.emit(_FLASH, x, y, tool=key, line=line, col=col)
        return
    out.emit(_MOVE, x, y, tool=key, line=line, col=col)
    if segments is None:
        closed = len(path) > 3 and np.array_equal(path[0], path[-1])
        segments = fit_arcs(path[:-1] if closed else path, closed=closed)
    for kind, ex, ey, i, j in segments:
        out.emit(kind, ex, ey, i, j, tool=key, line=line, col=col)


def _emit_feature(out: ProgramBuilder, feature: NarrowFeature, key: int) -> None:
    row = feature.row
    line, col = row[LINE], row[COL]
    if not feature.cut and row[KIND] != _FLASH:
        out.emit(_MOVE, *feature.start_nm, tool=key, line=line, col=col)
        drawn = list(row)
        drawn[TOOL] = key
        out.emit(*drawn)
        return
    for piece in feature.pieces:
        _emit_path(out, piece, key, line, col)


def _warnings(program: Program, plan: InkPlan) -> tuple[list[ReaderWarning], slice]:
    """One warning per aperture drawn as centre lines (and one per aperture whose
    flashes' walls are drawn as loops), one per bridge avoided; and where the
    bridges' are in the list."""
    found: list[ReaderWarning] = []
    by_aperture: dict[tuple[int, bool], list[NarrowFeature]] = {}
    for feature in plan.narrow:
        key = (int(feature.row[TOOL]), feature.inside_nm is not None)
        by_aperture.setdefault(key, []).append(feature)
    pen = mm_text(plan.pens_nm[-1])
    for (code, _loop), features in sorted(by_aperture.items(),
                                          key=lambda kv: kv[1][0].op_index):
        first = features[0]
        count = len(features)
        what = f"{count} object{'s' * (count != 1)} of {aperture_label(program, code)}" \
            if code != NO_TOOL else \
            f"{count} object{'s' * (count != 1)}"
        where = f" (first here, last at line {features[-1].pos.line})" if count > 1 else ""
        if first.inside_nm is not None:     # flashes whose hole leaves a thin wall
            found.append(ReaderWarning(first.pos, (
                f"{what} leave a wall {mm_text(first.width_nm)} mm wide round the hole, too "
                f"thin to fill with the {pen} mm pen: drawn as a loop a pen radius inside "
                f"the outer edge, the ink spilling into the hole{where}")))
            continue
        found.append(ReaderWarning(first.pos, (
            f"{what} ({mm_text(first.width_nm)} mm wide) too narrow to fill with the {pen} mm pen: "
            f"drawn as centre lines, {mm_text(first.overdraw_nm)} mm overdraw per side{where}")))
    first_bridge = len(found)
    for bridge in plan.bridges:
        other = "another copper island" if bridge.other is None else \
            f"the ink of line {bridge.other.pos.line} (another copper island)"
        found.append(ReaderWarning(bridge.feature.pos, (
            f"the centre line would join {other} at "
            f"{_xy(bridge.other_nm)}: left out for {mm_text(bridge.left_out_nm)} mm "
            f"from {_xy(bridge.at_nm)}")))
    bridges = slice(first_bridge, len(found))
    close = plan.close
    if close.count:
        found.append(ReaderWarning(SourcePos(program.source, 0, 0), (
            f"{close.count} pair{'s' * (close.count != 1)} of copper islands come within "
            f"{mm_text(CLEARANCE_NM)} mm of each other, the closest "
            f"{close.closest_nm / NM_PER_MM:.3f} mm apart at {_xy(close.at_nm)} and "
            f"{_xy(close.other_nm)}: the ink keeps {mm_text(CLEARANCE_NM // 2)} mm behind "
            "the copper's edge there, so the islands stay apart on paper")))
    if plan.zero_size:
        found.append(ReaderWarning(SourcePos(program.source, 0, 0), (
            f"{plan.zero_size} draw{'s' * (plan.zero_size != 1)} with zero-size apertures "
            "make no copper and are not inked (--mode centre draws them)")))
    return found, bridges


def _xy(point: tuple[int, int]) -> str:
    return f"X {point[0] / NM_PER_MM:.3f}, Y {point[1] / NM_PER_MM:.3f} mm"
