"""The two sides of a board in register: the bottom mirrored, one offset for both.

A board's bottom layers are drawn as seen from the top. Plotted on the blank's other
face they must be mirrored, about an axis the user then turns the blank over about:

- the axis is a line in board coordinates: the vertical centre line of the outline's
  box (else of the holes' box) by default, or `("x", nm)` / `("y", nm)` (the line
  x = nm or y = nm). It is kept doubled (`twice_nm`) so a centre line between two
  nanometres mirrors exactly: x -> twice_nm - x (transform.mirrored);
- both sides use one offset, worked out over the board's box and its mirror image,
  so each side fits the travel and the axis lies at the same place on the machine:
  board point p is at p - offset on the machine, and the axis at twice_nm / 2 minus the
  offset's x (or y). Turning the blank over about that line on the machine puts every
  bottom hole on its top hole, exactly in nm (to the step once stepped);
- registration marks: crosses on two or three holes far apart (else outside the
  outline's corners), drawn on both sides: after the turn-over each bottom cross lies
  on its top one (the ink keeps them off other islands: drill_marks.clear_strokes).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Sequence, Union

import numpy as np

from galileo_cnc.plan.offsets import DEFAULT_MARGIN_NM, offset_for_box, offset_from_text
from galileo_cnc.plan.transform import TransformError, mirrored
from galileo_cnc.program.drills import Hole, Slot
from galileo_cnc.program.extents import union_box
from galileo_cnc.program.ops import (COLUMNS, KIND, TOOL, X, Y, Aperture, NM_PER_MM, OpKind,
                                     Program)

SIDES = ("top", "bottom")
#: a registration cross's arms, centre to tip
CROSS_ARM_NM = 1_500_000
#: crosses outside the outline stand this far off its box's corners
CROSS_OUTSIDE_NM = 3_000_000

Box = tuple[int, int, int, int]
Drill = Union[Hole, Slot]


@dataclass(frozen=True)
class MirrorAxis:
    """The line a board turns over about: x = twice_nm / 2 (axis "x": vertical) or
    y = twice_nm / 2 (axis "y": horizontal), board nm."""

    axis: str
    twice_nm: int

    def __post_init__(self) -> None:
        if self.axis not in ("x", "y"):
            raise TransformError(f"--mirror-axis: expected x=MM or y=MM, got {self.axis!r}")

    @classmethod
    def at(cls, axis: str, position_nm: int) -> "MirrorAxis":
        return cls(axis, 2 * int(position_nm))

    def point(self, x: int, y: int) -> tuple[int, int]:
        return (self.twice_nm - x, y) if self.axis == "x" else (x, self.twice_nm - y)

    def box(self, box: Box | None) -> Box | None:
        if box is None:
            return None
        x0, y0 = self.point(box[0], box[1])
        x1, y1 = self.point(box[2], box[3])
        return (min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1))

    def on_machine_mm(self, offset_nm: tuple[int, int]) -> float:
        """Where the axis lies on the machine (work coordinates, mm) with this offset."""
        shift = offset_nm[0] if self.axis == "x" else offset_nm[1]
        return (self.twice_nm / 2 - shift) / NM_PER_MM

    def describe(self, side: str, offset_nm: tuple[int, int]) -> str:
        """The one line a side's job starts with: which axis, where on the machine."""
        line = "vertical" if self.axis == "x" else "horizontal"
        name = self.axis.upper()
        board = self.twice_nm / 2 / NM_PER_MM
        machine = self.on_machine_mm(offset_nm)
        what = "mirrored about" if side == "bottom" else "to be turned over about"
        return (f"{side} side, {what} the {line} line {name} {board:.4f} mm (board), "
                f"{name} {machine:.4f} mm on the machine (work): turn the blank over "
                f"about it between the sides")


def parse_axis(text: str) -> tuple[str, int]:
    """--mirror-axis x=MM or y=MM: (axis, nm); ValueError says what was expected."""
    name, _, value = text.partition("=")
    name = name.strip().lower()
    try:
        nm = offset_from_text(f"{value},0")[0] if name in ("x", "y") else None
    except ValueError:
        nm = None
    if nm is None:
        raise ValueError(f"--mirror-axis: expected x=MM or y=MM (board mm), got {text!r}")
    return name, nm


def default_axis(outline_box: Box | None, holes_box: Box | None,
                 artwork_box: Box | None = None) -> MirrorAxis:
    """The vertical centre line of the outline's box, else of the holes', else of the
    artwork's (a layer alone)."""
    box = outline_box or holes_box or artwork_box
    if box is None:
        return MirrorAxis("x", 0)
    return MirrorAxis("x", box[0] + box[2])


def shared_offset(board_box: Box | None, axis: MirrorAxis,
                  margin_nm: int = DEFAULT_MARGIN_NM) -> tuple[int, int]:
    """The one offset both sides use: the box of the board and its mirror image to the
    origin plus the margin (offsets.offset_for_box)."""
    return offset_for_box(union_box(board_box, axis.box(board_box)), margin_nm)


def mirror_drills(drills: Sequence[Drill], axis: MirrorAxis) -> list[Drill]:
    """The holes and slots as the bottom side sees them (an arc slot turns the other way)."""
    out: list[Drill] = []
    for d in drills:
        if isinstance(d, Hole):
            x, y = axis.point(d.x_nm, d.y_nm)
            out.append(dataclasses.replace(d, x_nm=x, y_nm=y))
            continue
        (x0, y0), (x1, y1) = axis.point(d.x0_nm, d.y0_nm), axis.point(d.x1_nm, d.y1_nm)
        cx, cy = axis.point(d.cx_nm, d.cy_nm) if d.arc else (0, 0)
        turned = {"cw": "ccw", "ccw": "cw"}.get(d.arc, "")
        out.append(dataclasses.replace(d, x0_nm=x0, y0_nm=y0, x1_nm=x1, y1_nm=y1,
                                       cx_nm=cx, cy_nm=cy, arc=turned))
    return out


def side_program(program: Program, side: str, axis: MirrorAxis) -> Program:
    """The layer as plotted on `side`: the top as it is, the bottom mirrored."""
    if side not in SIDES:
        raise TransformError(f"--side: expected top or bottom, got {side!r}")
    return program if side == "top" else mirrored(program, axis.axis, axis.twice_nm)


def registration_points(drills: Sequence[Drill], outline_box: Box | None) -> list[tuple[int, int]]:
    """Where the crosses go, board nm: two or three holes far apart (the two farthest
    apart, and the one farthest from the line between them), else outside the corners
    of the outline's box (three of them)."""
    holes = sorted({(d.x_nm, d.y_nm) for d in drills if isinstance(d, Hole)})
    if len(holes) >= 2:
        points = np.array(holes, dtype=np.float64)
        hull = points if len(points) <= 400 else _extremes(points)
        gaps = np.hypot(*(hull[:, None, :] - hull[None, :, :]).transpose(2, 0, 1))
        a, b = np.unravel_index(int(np.argmax(gaps)), gaps.shape)
        chosen = [hull[a], hull[b]]
        d = hull[b] - hull[a]
        off_line = np.abs(d[0] * (hull[:, 1] - hull[a][1]) - d[1] * (hull[:, 0] - hull[a][0]))
        third = int(np.argmax(off_line))
        if off_line[third] > 0:
            chosen.append(hull[third])
        return [(int(x), int(y)) for x, y in chosen]
    if outline_box is None:
        return [(h[0], h[1]) for h in holes]
    x0, y0, x1, y1 = outline_box
    away = CROSS_OUTSIDE_NM
    return [(x0 - away, y0 - away), (x1 + away, y0 - away), (x0 - away, y1 + away)]


def _extremes(points: np.ndarray) -> np.ndarray:
    """The points extreme along 16 directions: the far-apart ones are among them."""
    angles = np.linspace(0, np.pi, 16, endpoint=False)
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    along = points @ directions.T
    which = np.unique(np.concatenate([along.argmin(axis=0), along.argmax(axis=0)]))
    return points[which]


_MOVE, _LINE, _SELECT = int(OpKind.MOVE), int(OpKind.LINE), int(OpKind.SELECT)


def cross_strokes(points: Sequence[tuple[int, int]]) -> list[np.ndarray]:
    """A cross at each point: a horizontal and a vertical stroke, CROSS_ARM_NM each way."""
    arm = CROSS_ARM_NM
    return [np.array(stroke, dtype=np.int64) for x, y in points
            for stroke in (((x - arm, y), (x + arm, y)), ((x, y - arm), (x, y + arm)))]


def with_strokes(program: Program, strokes: Sequence[np.ndarray], tool: int,
                 pen_nm: int) -> Program:
    """`program` with the polylines drawn after everything else with aperture `tool` (a
    round pen of `pen_nm`, added if the program has none)."""
    strokes = [s for s in strokes if len(s)]
    if not strokes:
        return program
    rows = np.zeros((1 + sum(len(s) for s in strokes), len(COLUMNS)), dtype=np.int64)
    rows[:, TOOL] = tool
    rows[0, KIND] = _SELECT
    if len(program.table):
        rows[0, [X, Y]] = program.table[-1, [X, Y]]
    at = 1
    for stroke in strokes:
        rows[at:at + len(stroke), [X, Y]] = stroke
        rows[at, KIND] = _MOVE
        rows[at + 1:at + len(stroke), KIND] = _LINE
        at += len(stroke)
    apertures = dict(program.apertures)
    if tool not in apertures:
        r = pen_nm // 2
        apertures[tool] = Aperture(tool, "circle", (pen_nm,), extent_nm=(-r, -r, r, r))
    return dataclasses.replace(program, table=np.concatenate([program.table, rows]),
                               apertures=apertures)
