"""A board side's outline and silkscreen as centre lines (`--outline`, `--silk`).

Both are drawn after the copper, each with a tool of its own (so the job stops for
a pen change: "the outline pen", "the silk pen"), a round pen as wide as the finest
pen of the profile (or of --pens): the lines are a drawing, not copper to fill.

- `centre_lines`: each draw's centre line as polylines (arcs as chords within the
  ink's tolerance: they are clipped as polylines), a flash as a dot (the pen put
  down once), region contours as their outlines; clear-polarity objects erase and
  are not drawn;
- `keep_out`: where the pen must not go. Ink on the substrate between two copper
  islands etches as copper and shorts them, so a line is cut away within the pen's
  radius plus the islands' clearance (ink/islands.CLEARANCE_NM) of any copper ink (the
  copper, the centre lines and registration crosses drawn past its edge) and of any
  drill mark: then it touches no island, and joins none;
- `clear_of` cuts the lines to the keep-out and says how much length it cut away;
- `with_lines` appends them to the side's program, one tool each, in path order, the
  chords of each arc (and of a circle the file drew as lines) fitted back into arcs
  within the same tolerance, as the ink's walks are (ink/arcs.py).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from galileo_cnc.plan import curves
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.arcs import fit_paths
from galileo_cnc.plan.order import paths as path_order
from galileo_cnc.program.extents import dark_mask, start_points
from galileo_cnc.program.ops import COLUMNS, I, J, KIND, NM_PER_MM, TOOL, X, Y, Aperture, \
    OpKind, Program

OUTLINE, SILK = "outline", "silk"
#: the keep-out's curves are flattened within this, and it is grown by what the
#: flattening and cleaning may take (keep_out): a fifth of the time of the ink's 2 um
#: on arduino-uno's pours, for 20 to 30 um more left out
KEEP_OUT_TOLERANCE_NM = 10_000
#: what a pen change asks for (with the pen's width)
PEN_NAMES = {OUTLINE: "the outline pen", SILK: "the silk pen"}

_MOVE, _LINE, _ARC_CW, _ARC_CCW, _FLASH, _SELECT = (
    int(OpKind[name]) for name in ("MOVE", "LINE", "ARC_CW", "ARC_CCW", "FLASH", "SELECT"))


@dataclass(frozen=True)
class BoardLines:
    """One layer's lines as plotted (program nm): open polylines, a point alone a dot;
    `dropped_nm`: the length cut away near copper, `dropped_dots` the dots."""

    role: str
    strokes: tuple[np.ndarray, ...]
    dropped_nm: int = 0
    dropped_dots: int = 0

    def warning(self, pen_nm: int, clearance_nm: int) -> str | None:
        """One line for the user when something was cut away (None: nothing was)."""
        if not self.dropped_nm and not self.dropped_dots:
            return None
        dots = (f" and {self.dropped_dots} dot{'s' if self.dropped_dots > 1 else ''}"
                if self.dropped_dots else "")
        reach = (pen_nm // 2 + clearance_nm) / NM_PER_MM
        return (f"--{self.role}: {self.dropped_nm / NM_PER_MM:.2f} mm of the {self.role}"
                f"{dots} left out within {reach:.3f} mm of copper or a drill mark "
                f"(its ink there would join copper islands)")


def centre_lines(program: Program, tolerance_nm: int) -> list[np.ndarray]:
    """The program's draws as polylines (consecutive draws joined, arcs chorded within
    `tolerance_nm`) and its flashes as one-point arrays; clear polarity left out."""
    table = program.table
    if not len(table):
        return []
    starts = start_points(table)
    dark = dark_mask(table)
    out: list[np.ndarray] = []
    run: list[np.ndarray] = []

    def close() -> None:
        if run:
            out.append(np.concatenate(run))
            run.clear()

    for k, row in enumerate(table.tolist()):
        kind = row[KIND]
        if kind == _MOVE or not dark[k]:
            close()
            continue
        sx, sy = int(starts[k, 0]), int(starts[k, 1])
        if kind == _FLASH:
            close()
            out.append(np.array([[row[X], row[Y]]], dtype=np.int64))
        elif kind == _LINE:
            if not run:
                run.append(np.array([[sx, sy]], dtype=np.int64))
            run.append(np.array([[row[X], row[Y]]], dtype=np.int64))
        elif kind in (_ARC_CW, _ARC_CCW):
            points = curves.arc_points(sx, sy, row[X], row[Y], row[I], row[J],
                                       kind == _ARC_CW, tolerance_nm)
            run.append(points if not run else points[1:])
    close()
    return out


def keep_out(copper: list, lines: Sequence[np.ndarray], line_radius_nm: int, bare: list,
             pen_nm: int, clearance_nm: int) -> list:
    """Where a line drawn with a pen of `pen_nm` must not go, a pyclipper set: within
    the pen's radius plus `clearance_nm` of the copper, of the centre lines inked past
    it (`lines`, drawn `line_radius_nm` wide each side) and of the bare drill marks
    (Clipper's flattened curves lie inside the true ones: grown by what they may
    miss, KEEP_OUT_TOLERANCE_NM, it holds them all)."""
    tolerance = KEEP_OUT_TOLERANCE_NM
    inked = clip.stroke_in_strips([line for line in lines if len(line)],
                                  line_radius_nm + tolerance, tolerance) if len(lines) else []
    reach = pen_nm // 2 + clearance_nm + 2 * tolerance
    return clip.offset(clip.union(copper, inked, bare), reach, tolerance)


def clear_of(role: str, strokes: Sequence[np.ndarray], forbidden: list) -> BoardLines:
    """The strokes cut to outside `forbidden`, and how much was cut away.

    A stroke whose box meets no ring's box is kept whole without Clipper (most of an
    outline, far from the copper). Dots go through Clipper together (_dots_outside)."""
    boxes = np.array([(*np.min(ring, axis=0), *np.max(ring, axis=0)) for ring in forbidden],
                     dtype=np.int64).reshape(-1, 4)
    strokes = [clip.without_repeats(stroke) for stroke in strokes if len(stroke)]
    kept, near, near_dots = [], [], []
    for stroke in strokes:
        low, high = np.min(stroke, axis=0), np.max(stroke, axis=0)
        meets = ((boxes[:, 0] <= high[0]) & (boxes[:, 2] >= low[0]) &
                 (boxes[:, 1] <= high[1]) & (boxes[:, 3] >= low[1])).any()
        if not meets:
            kept.append(stroke)
        else:
            (near_dots if len(stroke) == 1 else near).append(stroke)
    kept += clip.open_difference(near, forbidden) + _dots_outside(near_dots, forbidden)
    dots = sum(1 for s in strokes if len(s) == 1)
    dropped_dots = dots - sum(1 for s in kept if len(s) == 1)
    dropped = max(0, round(_length(strokes) - _length(kept)))
    return BoardLines(role, tuple(kept), dropped, dropped_dots)


def _dots_outside(dots: list[np.ndarray], forbidden: list) -> list[np.ndarray]:
    """The dots outside `forbidden`, all in one Clipper pass: each as a diagonal of
    one nm (kept if any of it is outside; Clipper tests a point alone ring by ring, in
    Python, and a pour's ring is slow to hand over each time)."""
    if not dots:
        return []
    points = np.concatenate(dots)
    pieces = clip.open_difference([np.array([p, p + 1]) for p in points], forbidden)
    out = {tuple(q) for piece in pieces for q in piece.tolist()}
    return [dot for dot in dots if tuple(dot[0].tolist()) in out
            or tuple((dot[0] + 1).tolist()) in out]


def _length(strokes: Sequence[np.ndarray]) -> float:
    total = 0.0
    for stroke in strokes:
        if len(stroke) >= 2:
            d = np.diff(np.asarray(stroke, dtype=np.float64), axis=0)
            total += float(np.hypot(d[:, 0], d[:, 1]).sum())
    return total


def with_lines(program: Program, layers: Sequence[BoardLines], pen_nm: int,
               join_nm: int, tolerance_nm: int
               ) -> tuple[Program, dict[int, str], list[tuple[int, list[int]]]]:
    """`program` with each layer's lines appended after everything else, one new
    aperture (a round pen of `pen_nm`) a layer, each layer's paths in path order
    (plan/order/paths.py) from where the rows before it end, arcs fitted within
    `tolerance_nm` (the one the chords were made with). (The program, tool -> role,
    the appended rows in plotting order as (op index, row) pairs.)"""
    tool = max(program.apertures, default=0) + 1
    apertures = dict(program.apertures)
    tables = [program.table]
    at = len(program.table)
    here = (int(program.table[-1, X]), int(program.table[-1, Y])) if len(program.table) \
        else (0, 0)
    roles: dict[int, str] = {}
    ordered: list[tuple[int, list[int]]] = []
    r = pen_nm // 2
    for layer in layers:
        rows = _rows(layer.strokes, tool, here, tolerance_nm)
        if len(rows) <= 1:
            continue
        apertures[tool] = Aperture(tool, "circle", (pen_nm,), extent_nm=(-r, -r, r, r))
        roles[tool] = layer.role
        pairs = list(zip(range(at, at + len(rows)), rows.tolist()))
        drawn, end = path_order.optimize(pairs[1:], here, join_nm)
        ordered += [pairs[0], *drawn]
        here = (int(end[0]), int(end[1]))
        tables.append(rows)
        at += len(rows)
        tool += 1
    if not roles:
        return program, {}, []
    return (dataclasses.replace(program, table=np.concatenate(tables), apertures=apertures),
            roles, ordered)


def _rows(strokes: Sequence[np.ndarray], tool: int, here: tuple[int, int],
          tolerance_nm: int) -> np.ndarray:
    """A SELECT of `tool`, then each stroke as a MOVE and its lines and arcs, a dot as
    a FLASH."""
    strokes = [clip.without_repeats(s) for s in strokes if len(s)]
    fitted = fit_paths(strokes, tolerance_nm, rows=True)
    count = 1 + sum(1 if segments is None else 1 + len(segments) for segments in fitted)
    rows = np.zeros((count, len(COLUMNS)), dtype=np.int64)
    rows[:, TOOL] = tool
    rows[0, KIND] = _SELECT
    rows[0, [X, Y]] = here
    n = 1
    for stroke, segments in zip(strokes, fitted):
        rows[n, [X, Y]] = stroke[0]
        rows[n, KIND] = _FLASH if segments is None else _MOVE
        n += 1
        if segments is not None:
            rows[n:n + len(segments), [KIND, X, Y, I, J]] = segments
            n += len(segments)
    return rows
