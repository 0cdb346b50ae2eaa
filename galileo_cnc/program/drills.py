"""What a drill file holds, in integer nm: round holes and slots, each with its
tool's diameter and, where the file or its name says so, whether it is plated.

The Excellon reader (readers/excellon/) makes a DrillFile; a board (readers/board/)
gathers the drill files of both kinds; the planner (plan/) leaves drill marks bare
in the ink and mirrors the holes with the bottom side. Coordinates are the file's own
frame, the one its copper layers share (Gerber and Excellon of one board agree).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from math import atan2, isqrt, tau


@dataclass(frozen=True, slots=True)
class Hole:
    """A round hole at (x_nm, y_nm)."""

    x_nm: int
    y_nm: int
    diameter_nm: int
    tool: str = ""                 # the file's tool name, e.g. "T01"
    plated: bool | None = None     # None: the file does not say
    line: int = 0                  # the file line it comes from (1-based; 0: unknown)


@dataclass(frozen=True, slots=True)
class Slot:
    """A slot: the tool swept along a path from (x0, y0) to (x1, y1), straight, or
    along an arc around (cx, cy) when `arc` is "cw" or "ccw" (routed slots)."""

    x0_nm: int
    y0_nm: int
    x1_nm: int
    y1_nm: int
    diameter_nm: int
    tool: str = ""
    plated: bool | None = None
    line: int = 0
    arc: str = ""                  # "", "cw" or "ccw"
    cx_nm: int = 0
    cy_nm: int = 0

    def path_extremes(self) -> list[tuple[int, int]]:
        """The ends of the path and, for an arc, the points of its circle furthest
        left, right, down and up that the arc passes (its box is theirs)."""
        points = [(self.x0_nm, self.y0_nm), (self.x1_nm, self.y1_nm)]
        if not self.arc:
            return points
        cx, cy = self.cx_nm, self.cy_nm
        radius = isqrt((self.x0_nm - cx) ** 2 + (self.y0_nm - cy) ** 2)
        start = atan2(self.y0_nm - cy, self.x0_nm - cx)
        end = atan2(self.y1_nm - cy, self.x1_nm - cx)
        if self.arc == "cw":
            start, end = end, start            # the same points, swept counter-clockwise
        sweep = (end - start) % tau or tau     # start == end: the full circle
        for quarter, (dx, dy) in enumerate(((1, 0), (0, 1), (-1, 0), (0, -1))):
            if (quarter * tau / 4 - start) % tau <= sweep:
                points.append((cx + dx * radius, cy + dy * radius))
        return points


@dataclass
class DrillFile:
    """One drill file: its holes and slots, its tools (name -> diameter nm) and what
    its header says."""

    source: str
    holes: list[Hole] = field(default_factory=list)
    slots: list[Slot] = field(default_factory=list)
    tools: dict[str, int] = field(default_factory=dict)
    units: str = "mm"              # the file's own unit: "mm" or "in"
    plated: bool | None = None     # the whole file's plating, when it says (X2, KiCad)
    line_count: int = 0
    metadata: dict = field(default_factory=dict)   # format, generator, comments

    def box_nm(self) -> tuple[int, int, int, int] | None:
        """(xmin, ymin, xmax, ymax) of every hole and slot, their radius included."""
        return drills_box([*self.holes, *self.slots])


def drills_box(drills) -> tuple[int, int, int, int] | None:
    """(xmin, ymin, xmax, ymax) of holes and slots (an arc slot by the points its
    arc passes), their radius included; None for none."""
    xs0, ys0, xs1, ys1 = [], [], [], []
    for d in drills:
        r = d.diameter_nm // 2
        xs, ys = zip(*([(d.x_nm, d.y_nm)] if isinstance(d, Hole) else d.path_extremes()))
        xs0.append(min(xs) - r)
        ys0.append(min(ys) - r)
        xs1.append(max(xs) + r)
        ys1.append(max(ys) + r)
    if not xs0:
        return None
    return min(xs0), min(ys0), max(xs1), max(ys1)
