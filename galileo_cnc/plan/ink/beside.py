"""Centre lines beside a fill's ink: left out where they would only spill, and the
lines they joined spliced into the walks (docs/ink.md, "Centre lines beside a fill").

KiCad 4 strokes its pours' outlines with the zone's least width, narrower than a pen:
drawn along their centre lines (narrow.py), those strokes ink beside the fill's own
ring, (pen - width) / 2 beyond the copper, into the clearance. past_the_fills cuts
such lines out where the fill inks their copper already; into_walks draws the short
lines that the outlines had joined to the rest (thermal spokes) as spurs of the
walks, so they cost no pen lift of their own.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.edges import point_to_edges
from galileo_cnc.plan.ink.fill import PenFill, boxes_of, meeting
from galileo_cnc.plan.ink.islands import Islands
from galileo_cnc.plan.ink.narrow import NarrowFeature, inside_point, keep_islands_apart
from galileo_cnc.plan.ink.necks import attach_to_walks, spliced

#: A centre line's part cut out between two kept ones (past_the_fills) is put back
#: when shorter than this many pens.
BRIDGED_PENS = 2
#: The longest line into_walks draws as a spur, out and back: drawing it twice costs
#: its length at the feed, about what a pen lift and lower cost (0.75 s) at 5 mm/s.
SPUR_MOST_NM = 3_000_000
#: A line that ends on a walk and whose other end this many centre lines end at
#: (itself too) is left to path order, not made a spur (into_walks).
JUNCTION_LINES = 3


def past_the_fills(narrow: list[NarrowFeature], fills: list[PenFill], edge_margin_nm: int,
                   tolerance_nm: int) -> tuple[list[NarrowFeature], list[NarrowFeature]]:
    """The centre lines less where they would only spill beside ink the fills make
    already; (the features, and those now apart from the lines they met: the ones
    shortened, and those that ended where a line shortened or dropped did).

    KiCad 4 strokes its pours' outlines with the zone's least width (0.254 mm): a
    narrow feature lying along a wide area's edge, inside the reach of the area's
    fill. Its own line there adds nothing but (pen - width) / 2 of ink beyond the
    copper, into the clearance. So a line is cut out where

    - it lies outside E0 (within a pen radius of the copper's edge: inside E0 the
      pen's disc stays on the copper, and the line spills nothing), and
    - the fills' ink holds its copper's disc (less the edge margin and tolerances
      the fills leave at the copper's edge too).

    Of what is left, a piece shorter than the pen that lies in that band throughout is
    a stub round a corner, where the fill's round pen leaves the copper's corner bare
    as it does a pad's: cut out too, unless it holds a line's free end (a trace's end
    cap, which the fill does not ink). A cut between two kept pieces shorter than
    BRIDGED_PENS pens is put back (where a trace meets its pad or a spoke its pour,
    the line runs on into E0 as before, where path order links it to a walk), and so
    is one round the joint of two lines (a trace's bend). A feature left with nothing
    is dropped."""
    paths = [(k, piece) for k, feature in enumerate(narrow) for piece in feature.pieces
             if len(piece)]
    if not paths:
        return narrow, []
    band = _Band(fills, [piece for _k, piece in paths], tolerance_nm)
    by_shrink: dict[int, list[int]] = {}
    for n, (k, _piece) in enumerate(paths):
        shrink = narrow[k].width_nm // 2 - edge_margin_nm - 2 * tolerance_nm
        by_shrink.setdefault(max(shrink, 0), []).append(n)
    left: dict[int, list[np.ndarray]] = {}
    for shrink, members in by_shrink.items():
        sources = [paths[n][1] for n in members]
        cut = clip.open_difference_by_path(sources, band.of(sources, shrink))
        # Clipper may hand back a piece of no length where a line touches the band
        left.update((n, [p for p in pieces if len(clip.without_repeats(p)) > 1
                         or len(p) == 1]) for n, pieces in zip(members, cut) if pieces)
    ends = _line_ends(paths)
    free = {end for end, at in ends.items() if len(at) == 1}
    # a stub holding a line's free end (a trace's end cap) is that line's own copper
    stubs = [(n, piece) for n, pieces in left.items() for piece in pieces
             if _short(piece, narrow[paths[n][0]].pen_nm)
             and not {tuple(piece[0].tolist()), tuple(piece[-1].tolist())} & free]
    if stubs:
        lines = [piece for _n, piece in stubs]
        for (n, piece), held in zip(stubs, clip.open_difference_by_path(lines,
                                                                        band.of(lines, 0))):
            if not held:
                left[n] = [p for p in left[n] if p is not piece]
    gap = {n: BRIDGED_PENS * narrow[k].pen_nm for n, (k, _piece) in enumerate(paths)}
    # where each piece lies along its line: the joints and the bridging both ask
    placed = {n: _spans(paths[n][1], [p for p in pieces if len(p) > 1])
              for n, pieces in left.items()
              if len(paths[n][1]) > 1 and any(len(p) > 1 for p in pieces)}
    to_ends = _to_joints(placed, gap, ends)
    for n, where in placed.items():
        left[n] = _bridged(paths[n][1], left[n], gap[n], to_ends.get(n, (False, False)),
                           where)
    return _regrouped(narrow, paths, left)


class _Band:
    """Where a narrow line only spills beside the fills' ink: the ink shrunk by the
    line's half width, less E0; made near the lines asked about, from the batches
    that meet any of the lines (a pour's whole ink is large to shrink)."""

    def __init__(self, fills: list[PenFill], lines: list[np.ndarray], tolerance_nm: int):
        self.ink, self.centre = [], []
        boxes = boxes_of(lines)
        for fill in fills:
            for batch, recipe in fill.recipes:
                if len(meeting(boxes, batch)):
                    self.ink.extend(recipe.ink())
                    self.centre.extend(recipe.centre_area)
        self.ink_boxes, self.centre_boxes = boxes_of(self.ink), boxes_of(self.centre)
        self.tolerance_nm = tolerance_nm

    def of(self, lines: list[np.ndarray], shrink: int) -> list:
        """The band for lines of half width `shrink` (a hole of the ink too, as far
        as the shrink reaches)."""
        near = _meeting_boxes(self.ink_boxes, boxes_of(lines, shrink + self.tolerance_nm))
        if not len(near):
            return []
        rings = [self.ink[k] for k in near.tolist()]
        inner = clip.offset(rings, -shrink, self.tolerance_nm) if shrink else rings
        near = _meeting_boxes(self.centre_boxes, boxes_of(lines, self.tolerance_nm))
        return clip.difference(inner, [self.centre[k] for k in near.tolist()])


def _line_ends(paths: list[tuple[int, np.ndarray]]) -> dict[tuple, list[tuple[int, int]]]:
    """Per end point of the paths' lines: the (path, 0 start or 1 end) there."""
    ends: dict[tuple, list[tuple[int, int]]] = {}
    for n, (_k, source) in enumerate(paths):
        if len(source) > 1:
            for side, end in ((0, source[0]), (1, source[-1])):
                ends.setdefault(tuple(end.tolist()), []).append((n, side))
    return ends


def _to_joints(placed: dict[int, tuple[np.ndarray, list]], gap: dict[int, int],
               ends: dict[tuple, list[tuple[int, int]]]) -> dict[int, tuple[bool, bool]]:
    """Per path with pieces left (`placed`: _spans of each), whether to put back what
    was cut at its start and at its end: where it meets one other path end to end (a
    joint; a closed line meets itself) and the two cuts there are shorter than the
    gap together."""
    cut = {n: _end_gaps(*where) for n, where in placed.items()}
    to_ends = {n: [False, False] for n in cut}
    for pair in ends.values():
        if len(pair) != 2 or not all(n in cut for n, _side in pair):
            continue
        (n, side), (m, other) = pair
        if cut[n][side] + cut[m][other] < gap[n]:
            to_ends[n][side] = to_ends[m][other] = True
    return {n: (a, b) for n, (a, b) in to_ends.items()}


def _regrouped(narrow: list[NarrowFeature], paths: list[tuple[int, np.ndarray]],
               left: dict[int, list[np.ndarray]]
               ) -> tuple[list[NarrowFeature], list[NarrowFeature]]:
    """The features with the pieces left of their paths (past_the_fills' result)."""
    of_feature: dict[int, list[int]] = {}
    for n, (k, _piece) in enumerate(paths):
        of_feature.setdefault(k, []).append(n)
    kept, alone, changed_ends = [], [], set()
    for k, feature in enumerate(narrow):
        members = of_feature.get(k, [])
        if not members:                   # cut whole already (keep_islands_apart)
            kept.append(feature)
            continue
        pieces = [piece for n in members for piece in left.get(n, [])]
        if _same_lines(pieces, [paths[n][1] for n in members]):
            kept.append(feature)
            continue
        changed_ends.update(tuple(end) for n in members for end in paths[n][1][[0, -1]].tolist())
        if pieces:
            feature.pieces, feature.cut = pieces, True
            kept.append(feature)
            alone.append(feature)
    # a line that ended where one so changed did (a spoke at its pour's outline) may
    # have been drawn on from there, and no longer is
    shortened = {id(feature) for feature in alone}
    alone += [feature for feature in kept if id(feature) not in shortened and any(
        tuple(end) in changed_ends for piece in feature.pieces if len(piece) > 1
        for end in piece[[0, -1]].tolist())]
    return kept, alone


def into_walks(lines: list[NarrowFeature], narrow: list[NarrowFeature], fill: PenFill,
               islands: Islands, pen_nm: int, tolerance_nm: int,
               clear_of_bare: Callable[[list[NarrowFeature]], list[NarrowFeature]]) -> None:
    """The centre lines past_the_fills left alone, each piece drawn as a spur of the
    walk one of its ends lies within a pen width of (necks.attach_to_walks, spliced),
    where every piece of the line is at most SPUR_MOST_NM long and so placed: a
    pour's thermal spoke, or a trace, that the pour's outline strokes joined to the
    rest; alone each piece would cost a pen lift. A piece that ends on the walk and
    whose other end is a junction of JUNCTION_LINES lines or more is left to path
    order, which draws through it for less. The way from the walk keeps apart from
    other islands as a centre line does (keep_islands_apart) and clear of the bare
    area (`clear_of_bare`: the lines cut short of it); a line any of whose ways would
    not is drawn as it was. A spliced line keeps its pieces, each with its way (the
    ink's coverage and the narrow-feature allowance count them), and is marked
    `spur`, so it is not drawn twice."""
    lines = [line for line in lines if line.pieces and all(
        len(piece) >= 2 and _length(piece) <= SPUR_MOST_NM for piece in line.pieces)]
    if not lines or not fill.paths:
        return
    # each piece tried as a line of its own (attach_to_walks and the checks change
    # these, not the lines); a line is spliced when all its pieces are
    parts = [(line, replace(line, pieces=[piece])) for line in lines for piece in line.pieces]
    for _line, part in parts:     # attach_to_walks finds the island from a point inside
        part.inside_nm = inside_point(part)
    attached = attach_to_walks([part for _line, part in parts], fill.paths, pen_nm, islands)
    # a piece that ends on its walk, its other end where three lines or more meet (an
    # attached piece counted from its walk on): path order runs on through it (Eagle's
    # pour outlines on eagle/manifold-slave: 250 such spurs, 3 lifts fewer, 18 s more)
    tried_lines = {id(line) for line in lines}
    others = [f for f in narrow if id(f) not in tried_lines] + [part for _line, part in parts]
    meeting_there = {end: len(at) for end, at in _line_ends(
        [(k, piece) for k, feature in enumerate(others) for piece in feature.pieces]).items()}
    refused = {id(line) for line, part in parts if id(part) not in attached or (
        np.array_equal(part.pieces[0][0], part.pieces[0][1])
        and meeting_there.get(tuple(part.pieces[0][-1].tolist()), 0) >= JUNCTION_LINES)}
    tried = [part for line, part in parts if id(line) not in refused]
    planned = {id(part): part.pieces[0].copy() for part in tried}
    settled = [feature for feature in narrow if feature.pieces
               and (id(feature) not in tried_lines or id(feature) in refused)]
    keep_islands_apart(settled + tried, islands, pen_nm, settled=len(settled))
    whole = {id(part) for part in clear_of_bare(tried)
             if _same_lines(part.pieces, [planned[id(part)]])}
    refused |= {id(line) for line, part in parts if id(part) not in whole}
    spurs = [(line, part) for line, part in parts if id(line) not in refused]
    for line in {id(line): line for line, _part in spurs}.values():
        line.pieces, line.spur = [], True
    for line, part in spurs:
        part.pieces = [planned[id(part)]]
        line.pieces.append(part.pieces[0])
    spliced(fill, [(part, attached[id(part)]) for _line, part in spurs], tolerance_nm)


def _meeting_boxes(boxes: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Indices of `boxes` that meet any of `others` (both (n, 4): x0, y0, x1, y1)."""
    if not len(boxes) or not len(others):
        return np.zeros(0, dtype=np.int64)
    order = np.argsort(others[:, 0])
    others = others[order]
    reach = np.maximum.accumulate(others[:, 2])     # the widest x1 up to each
    met = []
    for k, (x0, y0, x1, y1) in enumerate(boxes.tolist()):
        # the others starting left of x1 (sorted), of which those ending right of x0
        end = int(np.searchsorted(others[:, 0], x1, side="right"))
        if not end or reach[end - 1] < x0:
            continue
        o = others[:end]
        if np.any((o[:, 2] >= x0) & (o[:, 1] <= y1) & (o[:, 3] >= y0)):
            met.append(k)
    return np.array(met, dtype=np.int64)


def _spans(source: np.ndarray, pieces: list[np.ndarray]) -> tuple[np.ndarray, list]:
    """(arclength of each vertex of the polyline `source`, its pieces `pieces` as
    [start, end, piece] along it, sorted; Clipper hands a piece either way round)."""
    a, b = source[:-1], source[1:]
    lengths = np.hypot(*(b - a).T.astype(np.float64))
    along = np.concatenate([[0.0], np.cumsum(lengths)])

    def positions(point: np.ndarray) -> np.ndarray:
        """Every place along the source the point lies at (within a few nm): two
        where a closed source's end meets its start."""
        t, gap = point_to_edges(np.repeat(point[None].astype(np.float64), len(a), axis=0),
                                a, b)
        on = np.flatnonzero(gap <= gap.min() + 4)
        return along[on] + t[on] * lengths[on]

    spans = []
    for piece in pieces:
        # an end is where it lies next to the piece's other points
        inner = positions(piece[len(piece) // 2]) if len(piece) > 2 else None
        ends = []
        for end, other in ((piece[0], piece[-1]), (piece[-1], piece[0])):
            places = positions(end)
            near = inner if inner is not None else positions(other)
            ends.append(float(places[np.argmin(np.abs(places[:, None] - near[None, :])
                                               .min(axis=1))]))
        s0, s1 = ends
        spans.append([s0, s1, piece] if s0 <= s1 else [s1, s0, piece[::-1]])
    return along, sorted(spans, key=lambda span: span[0])


def _bridged(source: np.ndarray, pieces: list[np.ndarray], gap_nm: int,
             to_ends: tuple[bool, bool] = (False, False),
             placed: tuple[np.ndarray, list] | None = None) -> list[np.ndarray]:
    """The pieces of the polyline `source`, with the parts cut out between two of them
    that are shorter than `gap_nm` put back, and those between the first piece and
    the source's start, the last and its end, where `to_ends` says so. `placed`: the
    lines' _spans, where the caller has them."""
    lines = [piece for piece in pieces if len(piece) > 1]
    if len(source) < 2 or not lines or (len(lines) < 2 and not any(to_ends)):
        return pieces
    along, spans = placed or _spans(source, lines)
    spans = [list(span) for span in spans]      # joined below in place
    if to_ends[0]:
        spans.insert(0, [0.0, 0.0, source[:1]])
    if to_ends[1]:
        spans.append([along[-1], along[-1], source[-1:]])
    joined = [spans[0]]
    for s0, s1, piece in spans[1:]:
        last = joined[-1]
        if s1 <= last[1] and len(piece) > 1:
            continue
        if s0 >= last[1] - 1 and (s0 - last[1] < gap_nm or len(piece) == 1
                                  or len(last[2]) == 1):
            between = source[1:-1][(along[1:-1] > last[1]) & (along[1:-1] < s0)]
            last[2] = np.vstack([last[2], between, piece])
            last[1] = max(last[1], s1)
        else:
            joined.append([s0, s1, piece])
    if len(joined) == 1 and joined[0][0] <= 1 and joined[0][1] >= along[-1] - 1:
        return [source]                   # put back whole
    return [piece for piece in pieces if len(piece) < 2] + \
        [clip.without_repeats(piece) for _s0, _s1, piece in joined]


def _end_gaps(along: np.ndarray, spans: list) -> tuple[float, float]:
    """How much of a line (`along`, `spans`: _spans of its pieces) is cut out before
    its first piece and after its last."""
    return spans[0][0], along[-1] - max(span[1] for span in spans)


def _short(piece: np.ndarray, pen_nm: int) -> bool:
    """A piece of a line shorter than the pen (a dot is not: it is a flash's own)."""
    return len(piece) > 1 and _length(piece) < pen_nm


def _length(line: np.ndarray) -> float:
    return float(np.hypot(*np.diff(line, axis=0).T).sum())


def _same_lines(pieces: list[np.ndarray], sources: list[np.ndarray]) -> bool:
    """The pieces are the sources whole: Clipper may hand a line back reversed, and a
    draw of no length back as its one point. Repeats count on neither side: a spur
    whose way from its walk has no length (the line ends on the walk) starts with its
    point twice, and keep_islands_apart hands it back so."""
    whole = [clip.without_repeats(q) for q in sources]
    return len(pieces) == len(sources) and all(
        any(len(p) == len(q) and (np.array_equal(p, q) or np.array_equal(p, q[::-1]))
            for q in whole) for p in (clip.without_repeats(p) for p in pieces))
