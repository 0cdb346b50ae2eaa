"""Ink a Gerber layer with the user's pens: the copper becomes pen paths (docs/ink.md).

`ink_program(program, pens_nm)` works out the copper (geometry.py), fills it pen by
pen, widest first (fill.py), draws what is narrower than the smallest pen as centre
lines that never join two islands (narrow.py), and returns the ink as a Program of
its own: one SELECT per pen, then MOVE/LINE/ARC/FLASH rows. The planner takes that
Program like any other Gerber file, so path order, pen changes, soft limits,
previews and resume work on ink unchanged. Ring rows carry line 0 (they come from
the union of many objects); centre lines keep their object's line and column.

`bare(copper)` (pipeline.py: drill marks, plan/drill_marks.py) gives areas the ink
leaves bare, and centre lines are cut a pen radius short of them. With one pen the
copper is filled as without them, the fill's walks cut a pen radius short of them and
a loop drawn round each at that distance (`_around_bare`): the loop inks what the cut
took, so the copper outside them is inked as before (a fill of the copper less the
areas leaves crescents between the rings round an off-centre hole and the pad's own).
With several pens they come out of the copper before anything is filled.

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
from galileo_cnc.plan.ink.beside import into_walks, past_the_fills
from galileo_cnc.plan.ink.fill import (BACKGROUND_VERTICES, DEFAULT_OVERLAP, GAP_NM, PenFill,
                                      boxes_of, fill_region, inked_area_nm2,
                                      met_by_other_ink)
from galileo_cnc.plan.ink.geometry import DarkImage, dark_geometry
from galileo_cnc.plan.ink.islands import (CLEARANCE_NM, ClosePlaces, Islands, close_places,
                                         keep_back)
from galileo_cnc.plan.ink.narrow import (Bridge, NarrowFeature, find_narrow,
                                        keep_islands_apart)
from galileo_cnc.plan.ink.necks import attach_to_walks, neck_features, spliced
from galileo_cnc.plan.ink.walk_order import Skeleton, WalkOrder, touching_walks
from galileo_cnc.plan.order.links import LINK_AREAS
from galileo_cnc.plan.order.pieces import WHOLE_PATHS
from galileo_cnc.plan.widths import mm_text
from galileo_cnc.program.extents import extents
from galileo_cnc.program.ops import (COL, COLUMNS, I, J, KIND, LINE, NM_PER_MM, NO_TOOL, TOOL, X,
                                     Y, Aperture, OpKind, Program, ProgramBuilder)
from galileo_cnc.readers.gerber.transformed import aperture_label

#: Bridge warnings shown before a job (plot, getg): a board of tight traces has
#: pages of them (arduino-uno.cmp with the default 0.4 mm pen: 1,548) before the pen
#: prompt; one line counts the rest, and `info` lists every one.
SHOWN_BRIDGES = 20

#: The ink's polygon tolerance: the copper's curves as chords within it, the fill's
#: offsets' round joins, the arcs fitted to E0 (and DEEP_TOLERANCE times it inside E0:
#: fill.py). A third of a motor step (6.25 um). At 1 um (geometry.py's default)
#: hellboard planned in 7.5-7.9 s against 6.0-6.3 s with 28 % more commands, and the
#: corpus inked as it does at this (docs/ink.md, "The ink's tolerance").
INK_TOLERANCE_NM = 2_000

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
    coverage: Coverage | tuple[float, float]
    warnings: list[ReaderWarning] = field(default_factory=list)
    seconds: float = 0.0
    bare: list = field(default_factory=list)   # the area left bare (drill marks), program nm
    bridge_warnings: slice = field(default_factory=lambda: slice(0, 0))  # theirs in `warnings`
    #: the necks drawn (necks.py): spurs of the walks, and those in `narrow` as lines
    necks: list[NarrowFeature] = field(default_factory=list)
    #: the necks left bare: a line along them would come near another island
    necks_left: list[NarrowFeature] = field(default_factory=list)

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
        return sum(len(f.paths) for f in self.fills) + sum(len(n.pieces) for n in self.narrow
                                                           if not n.spur)

    def pen_label(self, key: int) -> str:
        return f"{mm_text(self.pens_nm[key - 1])} mm pen"


def ink_program(program: Program, pens_nm: tuple[int, ...] | list[int], *,
                tolerance_nm: int = INK_TOLERANCE_NM, overlap: float = DEFAULT_OVERLAP,
                edge_margin_nm: int = DEFAULT_EDGE_MARGIN_NM,
                on_stage: Callable[[str], None] | None = None) -> InkPlan:
    """The ink of a Gerber Program for the pens (widths in nm, any order).
    `on_stage(text)` hears what it starts on ("inking: filling with the 0.3 mm pen"): the
    largest layers take seconds a stage, and a front end can say so."""
    return ink_paths(program, pens_nm, tolerance_nm=tolerance_nm, overlap=overlap,
                     edge_margin_nm=edge_margin_nm, on_stage=on_stage).finish()


def ink_paths(program: Program, pens_nm: tuple[int, ...] | list[int], *,
              tolerance_nm: int = INK_TOLERANCE_NM, overlap: float = DEFAULT_OVERLAP,
              edge_margin_nm: int = DEFAULT_EDGE_MARGIN_NM,
              on_stage: Callable[[str], None] | None = None,
              bare: Callable[[list], list] | None = None) -> InkPaths:
    """ink_program up to the pen paths: the fills and the centre lines, not yet rows.
    `bare(copper)`: the area to leave bare, from the copper's polygon set (module doc)."""
    began = time.perf_counter()
    pens = tuple(sorted({int(p) for p in pens_nm if int(p) > 0}, reverse=True))
    if not pens:
        raise ValueError("no pen: give at least one pen width above 0")
    stage = on_stage or (lambda _text: None)
    stage("inking: working out the copper")
    copper = dark_geometry(program, tolerance_nm)
    region = copper.native
    bare_area = bare(region) if bare is not None else []
    # one pen: filled as without the bare areas, then cut round them (module doc)
    around = bool(bare_area) and len(pens) == 1
    if bare_area and not around:
        region = clip.difference(region, bare_area)
    islands = Islands.of(region)
    close = close_places(islands)
    keep_out = keep_back(close, CLEARANCE_NM // 2, tolerance_nm)
    big = sum(len(ring) for ring in region) >= BACKGROUND_VERTICES
    smallest = pens[-1]
    limit = smallest + 2 * edge_margin_nm + 4 * tolerance_nm
    stage("inking: finding features too narrow to fill")
    narrow, zero_size = find_narrow(program, limit, smallest, tolerance_nm)
    # where centre lines would join islands is worked out from the copper alone: on a
    # large board in a second process while this one fills (ekf2 l1: 6 s for 12k lines)
    apart = Deferred(_kept_apart, narrow, islands, smallest, fork=big and bool(narrow))
    # a batch of the one pen's fill that no centre line can meet has its coverage
    # worked out meanwhile (fill.InkRecipe.area); a narrower pen's ink meets most
    lines_near = boxes_of([piece for f in narrow for piece in f.pieces if len(piece)],
                          smallest // 2 + 2 * tolerance_nm) if len(pens) == 1 else None
    fills: list[PenFill] = []
    inked: list = []                      # what the wider pens ink, for the narrower ones
    try:
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
                               islands=islands.parts if number == 0 else None,
                               area_unless_near=lines_near if number == 0 else None
                               ) if target else PenFill(width)
            fills.append(fill)
            if number + 1 < len(pens):
                inked = clip.union(inked, fill.ink) if inked else list(fill.ink)
        narrow, bridges = apart.result()
        if around:
            region = clip.difference(region, bare_area)
            _around_bare(fills[0], bare_area, pens[0] // 2 + tolerance_nm, tolerance_nm)
        if bare_area:
            narrow = _clear_of(narrow, bare_area, smallest // 2 + tolerance_nm, tolerance_nm)
        narrow, alone = past_the_fills(narrow, fills, edge_margin_nm, tolerance_nm)
        stage("inking: looking for necks too narrow to fill")
        narrow, necks, necks_left = _with_necks(program.source, islands, fills, narrow,
                                                smallest, edge_margin_nm, tolerance_nm,
                                                bare_area)
        into_walks(alone, narrow, fills[-1], islands, smallest, tolerance_nm,
                   lambda lines: _clear_of(lines, bare_area, smallest // 2 + tolerance_nm,
                                           tolerance_nm) if bare_area else lines)
    finally:
        apart.cancel()
    as_lines = {id(feature) for feature in narrow}
    spurs = [neck.pieces[0] for neck in necks if id(neck) not in as_lines]
    coverage = Coverage(fills, [piece for f in narrow for piece in f.pieces] + spurs,
                        smallest // 2, region, tolerance_nm, fork=big)
    return InkPaths(program, pens, copper, fills, narrow, bridges, zero_size, close,
                    clip.area_nm2(region), coverage, big, began, stage, tolerance_nm,
                    bare=bare_area, necks=necks, necks_left=necks_left)


def _around_bare(fill: PenFill, bare_area: list, reach_nm: int, tolerance_nm: int) -> None:
    """The fill's walks cut `reach_nm` short of the bare areas and a closed loop at that
    distance round each; the coverage counts its batches less the bare areas."""
    grown = clip.offset(bare_area, reach_nm, tolerance_nm)
    loops = [np.vstack([ring, ring[:1]]) for ring in clip.rings_as_arrays(grown)]
    boxes = boxes_of(grown)
    paths, coarse = [], []
    fine = len(fill.coarse) == len(fill.paths)
    for k, path in enumerate(fill.paths):
        (x0, y0), (x1, y1) = path.min(axis=0), path.max(axis=0)
        near = np.flatnonzero((boxes[:, 0] <= x1) & (boxes[:, 2] >= x0) & (boxes[:, 1] <= y1)
                              & (boxes[:, 3] >= y0))
        if not len(near):
            paths.append(path)
            coarse.append(fill.coarse[k] if fine else np.full(len(path), tolerance_nm))
            continue
        for piece in clip.open_difference([path], [grown[n] for n in near.tolist()]):
            paths.append(piece)
            coarse.append(np.full(len(piece), tolerance_nm))
    fill.paths = paths + loops
    fill.coarse = coarse + [np.full(len(loop), tolerance_nm) for loop in loops]
    recipes = []
    for batch, recipe in fill.recipes:
        low = np.min([np.min(ring, axis=0) for ring in batch], axis=0)
        high = np.max([np.max(ring, axis=0) for ring in batch], axis=0)
        if not np.any((boxes[:, 0] <= high[0]) & (boxes[:, 2] >= low[0])
                      & (boxes[:, 1] <= high[1]) & (boxes[:, 3] >= low[1])):
            recipes.append((batch, recipe))
            continue
        # its ink counted as polygons, within the batch less the bare areas
        if isinstance(recipe.area, Deferred):
            recipe.area.cancel()
        recipe.area = None
        recipe.ink()
        recipes.append((clip.rings_as_arrays(clip.difference(batch, bare_area)), recipe))
    fill.recipes = recipes


def _clear_of(narrow: list[NarrowFeature], bare_area: list, reach_nm: int,
              tolerance_nm: int) -> list[NarrowFeature]:
    """The centre lines cut `reach_nm` short of the bare area (a trace ends at its pad's
    centre, where the drill mark is); a feature left with nothing is dropped."""
    grown = clip.offset(bare_area, reach_nm, tolerance_nm)
    boxes = boxes_of(grown)
    kept = []
    for feature in narrow:
        points = np.concatenate(feature.pieces) if feature.pieces else None
        if points is None or not len(points):
            continue
        x0, y0 = points.min(axis=0) - reach_nm
        x1, y1 = points.max(axis=0) + reach_nm
        near = (boxes[:, 0] <= x1) & (boxes[:, 2] >= x0) & (boxes[:, 1] <= y1) & \
            (boxes[:, 3] >= y0)
        if not near.any():
            kept.append(feature)
            continue
        pieces = clip.open_difference(feature.pieces,
                                      [grown[k] for k in np.flatnonzero(near).tolist()])
        if pieces:
            feature.pieces, feature.cut = pieces, True
            kept.append(feature)
    return kept


def _with_necks(source: str, islands: Islands, fills: list[PenFill],
                narrow: list[NarrowFeature], pen_nm: int, edge_margin_nm: int,
                tolerance_nm: int, bare_area: list
                ) -> tuple[list[NarrowFeature], list[NarrowFeature], list[NarrowFeature]]:
    """A line along each neck the fills leave bare (necks.py): a neck whose line keeps
    apart from other islands as the centre lines do, and clear of the bare area, is
    drawn, as a spur of the walk beside it (necks.spliced: no pen lift of its own) or
    else as a centre line; any other is left bare, as it was (a part of it drawn would
    be a stub). (The centre lines with those necks, the necks drawn, the necks left.)"""
    necks = neck_features(source, fills,
                          [piece for feature in narrow for piece in feature.pieces],
                          pen_nm, edge_margin_nm, tolerance_nm)
    if not necks:
        return narrow, [], []
    fill = fills[-1]
    attached = attach_to_walks(necks, fill.paths, pen_nm, islands)
    planned = {id(neck): neck.pieces[0].copy() for neck in necks}
    drawn_lines = [feature for feature in narrow if feature.pieces]
    keep_islands_apart(drawn_lines + necks, islands, pen_nm, settled=len(drawn_lines))
    clear = _clear_of(necks, bare_area, pen_nm // 2 + tolerance_nm, tolerance_nm) \
        if bare_area else necks
    # (Clipper may hand a line back the other way round)
    whole = {id(neck) for neck in clear if len(neck.pieces) == 1 and any(
        np.array_equal(line, planned[id(neck)]) for line in (neck.pieces[0],
                                                             neck.pieces[0][::-1]))}
    drawn = [neck for neck in necks if id(neck) in whole]
    for neck in drawn:
        neck.pieces = [planned[id(neck)]]
    left = [neck for neck in necks if id(neck) not in whole]
    spurs = spliced(fill, [(neck, attached[id(neck)]) for neck in drawn
                           if id(neck) in attached], tolerance_nm)
    spurred = {id(neck) for neck, _where in spurs}
    return narrow + [neck for neck in drawn if id(neck) not in spurred], drawn, left


def _kept_apart(narrow: list[NarrowFeature], islands: Islands, pen_nm: int
                ) -> tuple[list[NarrowFeature], list[Bridge]]:
    """keep_islands_apart, and the features it cut (sent back from a second process)."""
    bridges = keep_islands_apart(narrow, islands, pen_nm)
    return narrow, bridges


@dataclass
class InkPaths:
    """The ink as pen paths (ink_paths), before `finish` makes them rows: where they go
    is known (`box_nm`), so path order can start on the walks' ends (`start_order`,
    walk_order.py) while `finish` fits their arcs."""

    source: Program
    pens_nm: tuple[int, ...]
    copper: DarkImage
    fills: list[PenFill]
    narrow: list[NarrowFeature]
    bridges: list[Bridge]
    zero_size: int
    close: ClosePlaces
    copper_nm2: float
    coverage: Coverage
    big: bool                             # worth a second process
    began: float
    stage: Callable[[str], None]
    tolerance_nm: int                     # the ink's (ink_paths): its arcs are fitted to it
    bare: list = field(default_factory=list)       # the area left bare (drill marks)
    necks: list = field(default_factory=list)      # InkPlan.necks
    necks_left: list = field(default_factory=list)  # InkPlan.necks_left
    _fitted: dict = field(default_factory=dict)    # (fill, path) -> its arcs, once fitted
    _narrow: np.ndarray | None = None              # the centre lines' rows, once made

    def box_nm(self) -> tuple[int, int, int, int] | None:
        """The box of every point the ink's rows visit, arcs but by their ends: an arc
        of a walk strays from its vertices by at most its tolerance (16 um), far inside
        the offset's margin, and this box is known before the arcs are fitted."""
        points = [path for fill in self.fills for path in fill.paths]
        narrow = self._narrow_rows()
        box = extents(Program(self.source.source, "gerber", self.source.units, narrow),
                      visited=True) if len(narrow) else None
        if points:
            every = np.concatenate(points)
            low, high = every.min(axis=0).tolist(), every.max(axis=0).tolist()
            box = (low[0], low[1], high[0], high[1]) if box is None else (
                min(box[0], low[0]), min(box[1], low[1]),
                max(box[2], high[0]), max(box[3], high[1]))
        return box

    def add_strokes(self, strokes: list[np.ndarray]) -> None:
        """Open polylines (registration crosses, plan/sides.py) drawn with the smallest
        pen as walks of its own: path order takes them with the pen's other walks.
        Before `start_order` and `finish`."""
        fill = self.fills[-1]
        fill.with_coarse(self.tolerance_nm)
        for stroke in strokes:
            if len(stroke) >= 2:
                fill.paths.append(np.ascontiguousarray(stroke, dtype=np.int64))
                fill.coarse.append(np.full(len(stroke), self.tolerance_nm))

    def start_order(self, start: tuple[int, int], join_nm: int) -> WalkOrder:
        """Path order from `start` (program nm) worked out on the walks' ends, in a
        second process on a large board, while `finish` fits the arcs; its `rows`
        are what optimized_order gives on finish's program."""
        last = len(self.fills) - 1
        touched = touching_walks(self.fills[last].paths if self.fills else [],
                                 self._narrow_rows()[:, [X, Y]], join_nm)
        self._fit(last, np.flatnonzero(touched).tolist())     # these keep their rows
        short = {(last, k) for k in np.flatnonzero(~touched).tolist()}
        short |= {(number, k) for number, fill in enumerate(self.fills[:last])
                  for k in range(len(fill.paths))}
        short = {(number, k) for number, k in short if len(self.fills[number].paths[k]) > 1}
        program = _rows(self.source, self.pens_nm, self.fills, self._narrow_rows(),
                        self._segments(short))
        shortened = np.array([key in short for key in self._walk_keys()], dtype=bool)
        return WalkOrder(Skeleton(program, shortened), start, join_nm, fork=self.big)

    def finish(self) -> InkPlan:
        """The ink as rows (arcs fitted) and its warnings."""
        self.stage("inking: fitting arcs")
        for number, fill in enumerate(self.fills):
            self._fit(number, [k for k in range(len(fill.paths))
                               if (number, k) not in self._fitted])
        rows = _rows(self.source, self.pens_nm, self.fills, self._narrow_rows(),
                     self._fitted, self.link_areas())
        self._fitted = {}        # 100k small tuples on a pour: freed before the collector runs
        plan = InkPlan(rows, self.pens_nm, self.copper, self.fills, self.narrow, self.bridges,
                       self.zero_size, self.close, self.copper_nm2, self.coverage,
                       bare=self.bare, necks=self.necks, necks_left=self.necks_left)
        plan.warnings, plan.bridge_warnings = _warnings(self.source, plan)
        plan.program.warnings = list(self.source.warnings) + plan.warnings
        plan.seconds = time.perf_counter() - self.began
        return plan

    def link_areas(self) -> dict[int, list]:
        """Per pen key, where path order may join two of its paths by a pen-down line
        (plan/order/links.py): where the pen's centre may go (each batch's E0, the
        keep-outs left out already), less the bare areas grown as the walks are kept
        from them (_around_bare). Inside it a line inks only copper of one island."""
        areas = {}
        for number, fill in enumerate(self.fills):
            area = [ring for _batch, recipe in fill.recipes for ring in recipe.centre_area]
            if area and self.bare:
                area = clip.difference(area, clip.offset(
                    self.bare, fill.width_nm // 2 + self.tolerance_nm, self.tolerance_nm))
            if area:
                areas[number + 1] = area
        return areas

    def _fit(self, number: int, which: list[int]) -> None:
        """The arcs of fill `number`'s paths `which`, all in one fit_paths."""
        if not which:
            return
        fill = self.fills[number]
        coarse = [fill.coarse[k] for k in which] if len(fill.coarse) == len(fill.paths) \
            else None
        for k, segments in zip(which, fit_paths([fill.paths[k] for k in which],
                                                self.tolerance_nm, coarse=coarse, rows=True)):
            self._fitted[(number, k)] = segments

    def _segments(self, short: set) -> dict:
        """Per (fill, path): its arcs, or for the `short` ones a LINE to its end."""
        segments = {}
        for number, fill in enumerate(self.fills):
            for k, path in enumerate(fill.paths):
                if (number, k) in short:
                    end = path[-1]
                    segments[(number, k)] = np.array([[_LINE, end[0], end[1], 0, 0]],
                                                     dtype=np.int64)
                else:
                    segments[(number, k)] = self._fitted.get((number, k))
        return segments

    def _walk_keys(self) -> list[tuple[int, int]]:
        """(fill, path) of each walk, in the rows' order (_rows)."""
        return [(number, k) for number, fill in enumerate(self.fills) if fill.paths
                for k in range(len(fill.paths))]

    def _narrow_rows(self) -> np.ndarray:
        """The centre lines' rows, drawn with the smallest pen (made once)."""
        if self._narrow is None:
            out = ProgramBuilder(self.source.source)
            for feature in self.narrow:
                if not feature.spur:          # drawn in its walk (beside.into_walks)
                    _emit_feature(out, feature, len(self.pens_nm), self.tolerance_nm)
            self._narrow = out.table().copy()
        return self._narrow


class Coverage:
    """(filled_nm2, inked_nm2): the copper the fills cover, and the fills and centre
    lines. A batch of the first pen's fill that no other ink meets counts its recipe's
    area (fill.InkRecipe: worked out meanwhile on a large batch); where a narrower
    pen's ink or a centre line meets one, the ink is needed as polygons, and on a large
    board a second process makes them while this one goes on to the rows and path
    order."""

    def __init__(self, fills: list[PenFill], centre_lines: list[np.ndarray], radius_nm: int,
                 region: list, tolerance_nm: int, fork: bool):
        self._recipes = [recipe for _batch, recipe in fills[0].recipes] if fills else []
        # a batch no other ink meets counts its recipe's area: here where a second
        # process works it out (or worked it out) already, else with the batches that
        # need polygons (all of them where no area is worked out meanwhile: then
        # whether other ink meets a batch is not asked here)
        meanwhile = [recipe.area is not None for recipe in self._recipes]
        self._here_filled = self._here_inked = [False] * len(self._recipes)
        if any(meanwhile):
            by_pens = met_by_other_ink(fills, np.zeros((0, 4), dtype=np.int64))
            by_lines = met_by_other_ink(fills, boxes_of(
                [line for line in centre_lines if len(line)], radius_nm + 2 * tolerance_nm))
            self._here_filled = [ready and not met for ready, met in zip(meanwhile, by_pens)]
            self._here_inked = [ready and not met for ready, met in zip(meanwhile, by_lines)]
        rest = not self._recipes or not all(self._here_inked)
        self._polygons = Deferred(_coverage_of_polygons, fills, centre_lines, radius_nm,
                                  region, tolerance_nm, self._here_filled, self._here_inked,
                                  fork=fork and rest)

    def result(self) -> tuple[float, float]:
        filled, inked = self._polygons.result()
        for recipe, here_filled, here_inked in zip(self._recipes, self._here_filled,
                                                   self._here_inked):
            if here_filled:
                filled += recipe.area_nm2()
            if here_inked:
                inked += recipe.area_nm2()
        return filled, inked

    def cancel(self) -> None:
        self._polygons.cancel()


def _coverage_of_polygons(fills: list[PenFill], centre_lines: list[np.ndarray],
                          radius_nm: int, region: list, tolerance_nm: int,
                          skip_filled: list[bool], skip_inked: list[bool]
                          ) -> tuple[float, float]:
    """Coverage's share: all batches but the `skip` ones (whose recipes' areas it
    counts itself), strip by strip (inked_area_nm2), not in one board-wide sweep."""
    filled = inked_area_nm2(fills, [], region, skip_filled)
    narrow_ink = clip.stroke_in_strips(centre_lines, radius_nm, tolerance_nm) \
        if centre_lines else []
    return filled, (inked_area_nm2(fills, narrow_ink, region, skip_inked) if narrow_ink
                    else filled)


def _rows(program: Program, pens: tuple[int, ...], fills: list[PenFill],
          narrow_rows: np.ndarray, segments: dict, link_areas: dict | None = None) -> Program:
    """The ink as a Program: per pen a SELECT, its fill's walks (`segments`: per (fill,
    path) what _emit_path draws) and, for the smallest pen, the centre lines' rows.
    `link_areas` (InkPaths.link_areas) go into its metadata for path order."""
    out = ProgramBuilder(program.source)
    # each walk is one island's rings and joins drawn as one stroke already (fill.py):
    # path order moves and reverses it, but has nothing to chain or leave out in it
    walks: list[tuple[int, int]] = []
    for number, fill in enumerate(fills):
        key = number + 1
        centre_lines = number == len(fills) - 1 and len(narrow_rows)
        if not fill.paths and not centre_lines:
            continue
        out.emit(_SELECT, tool=key)
        for k, path in enumerate(fill.paths):
            first = out.count()
            _emit_path(out, path, key, 0, 0, segments[(number, k)])
            walks.append((first, out.count()))
        if centre_lines:
            out.rows.frombytes(np.ascontiguousarray(narrow_rows, dtype=np.int64).tobytes())
    apertures = {k + 1: Aperture(k + 1, "circle", (w,), extent_nm=(-(w // 2), -(w // 2),
                                                                   w // 2, w // 2))
                 for k, w in enumerate(pens)}
    return out.build("gerber", program.units, apertures=apertures,
                     metadata={"ink": True, "pens_nm": list(pens),
                               WHOLE_PATHS: walks,
                               **({LINK_AREAS: link_areas} if link_areas else {}),
                               "source_metadata": program.metadata},
                     line_count=program.line_count)


def _emit_path(out: ProgramBuilder, path: np.ndarray, key: int, line: int, col: int,
               segments: list | np.ndarray | None = None,
               tolerance_nm: int = INK_TOLERANCE_NM) -> None:
    """A MOVE and the path's `segments` (else its arcs fitted to `tolerance_nm`, the
    one its chords were made with), or a FLASH for a path of one point."""
    x, y = int(path[0][0]), int(path[0][1])
    if len(path) == 1:
        out.emit(_FLASH, x, y, tool=key, line=line, col=col)
        return
    out.emit(_MOVE, x, y, tool=key, line=line, col=col)
    if segments is None:
        closed = len(path) > 3 and np.array_equal(path[0], path[-1])
        segments = fit_arcs(path[:-1] if closed else path, tolerance_nm, closed=closed)
    if not len(segments):
        return
    # all the path's rows at once: a fill's walk has up to 100k of them
    rows = np.zeros((len(segments), len(COLUMNS)), dtype=np.int64)
    rows[:, [KIND, X, Y, I, J]] = np.array(segments, dtype=np.int64)
    rows[:, TOOL], rows[:, LINE], rows[:, COL] = key, line, col
    out.rows.frombytes(rows.tobytes())


def _emit_feature(out: ProgramBuilder, feature: NarrowFeature, key: int,
                  tolerance_nm: int) -> None:
    row = feature.row
    line, col = row[LINE], row[COL]
    if not feature.cut and row[KIND] != _FLASH:
        out.emit(_MOVE, *feature.start_nm, tool=key, line=line, col=col)
        drawn = list(row)
        drawn[TOOL] = key
        out.emit(*drawn)
        return
    for piece in feature.pieces:
        _emit_path(out, piece, key, line, col, tolerance_nm=tolerance_nm)


def _warnings(program: Program, plan: InkPlan) -> tuple[list[ReaderWarning], slice]:
    """One warning per aperture drawn as centre lines (and one per aperture whose
    flashes' walls are drawn as loops), one per bridge avoided; and where the
    bridges' are in the list."""
    found: list[ReaderWarning] = []
    by_aperture: dict[tuple[int, bool], list[NarrowFeature]] = {}
    necks = plan.necks
    for feature in plan.narrow:
        if feature.neck:
            continue
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
    if necks or plan.necks_left:
        count, left = len(necks), len(plan.necks_left)
        drawn = (f"drawn along {'their' if count != 1 else 'its'} middle, the ink "
                 f"spilling beside {'them' if count != 1 else 'it'} (the first at "
                 f"{_xy(necks[0].inside_nm)})") if count else "none drawn"
        bare = (f"; {left} left bare, a line along {'them' if left != 1 else 'it'} would "
                f"come within {mm_text(CLEARANCE_NM)} mm of another island (the first at "
                f"{_xy(plan.necks_left[0].inside_nm)})") if left else ""
        found.append(ReaderWarning(SourcePos(program.source, 0, 0), (
            f"{count + left} neck{'s' * (count + left != 1)} of copper too narrow to fill "
            f"with the {pen} mm pen (thermal relief spokes, pours between traces) between "
            f"inked parts of one island: {drawn}{bare}")))
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
