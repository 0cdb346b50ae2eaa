"""Drilling a board's holes and slots on a GRBL mill: what `convert --mill drill` is to
write (docs/mill.md, "Drilling").

GRBL has no drill cycle (G81) and no tool change (M6), so every hole is spelt out:

- a hole takes the largest bit of the profile's `drills` not wider than it (10 um of
  the file's rounding allowed); a hole smaller than the smallest bit takes that bit
  and is reported (a note in the plan and a comment in the file);
- a hole the bit fits within 0.1 mm is drilled: a rapid at the safe height over it, a
  plunge at the plunge feed to the board's thickness plus the breakthrough, a rapid up;
- a wider hole is milled as a helix at radius (hole - bit) / 2, so the bit stays
  inside the hole: full G2 turns each going down at most `cutout_step_down`, then one
  full circle at the depth (the middle falls out as a slug);
- a slot is milled along its path (straight, or its arc) in depth passes, back and
  forth; a slot wider than its bit by 0.1 mm is milled round its contour instead (the
  path offset each side by (slot - bit) / 2, round ends), one ring a depth pass;
- holes go by plating first ("plated-first": plated, then unplated; holes a file
  leaves unsaid count as plated), then by bit, smallest first; within a group the
  next is the nearest to where the bit is (nearest neighbour);
- a bit change is `M0` with a comment naming the bit in mm, then a Z re-zero: with
  `probe = true` a G38.2 probe down onto the touch plate and G92 Z = plate thickness,
  else a touch-off pause (module `_touch_off`). The first bit is named at the top:
  it is in the spindle, Z = 0 at the board's top, when the job starts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from galileo_cnc.config.mill import MillConfig
from galileo_cnc.errors import GalileoError
from galileo_cnc.plan.mill.gcode import _comment
from galileo_cnc.program.drills import Hole, Slot
from galileo_cnc.readers.gcode.writer import mm

DRILL_ORDERS = ("plated-first", "unplated-first")
#: A bit this much wider than the hole still fits it (inch files round diameters).
FIT_NM = 10_000
#: A hole or slot wider than its bit by more than this is milled, not drilled.
MILL_ABOVE_NM = 100_000
#: How far below the old Z = 0 the probe searches before GRBL gives up (alarm).
PROBE_REACH_NM = 10_000_000


class DrillError(GalileoError):
    """Nothing to drill, or an option the drilling cannot take."""


@dataclass
class DrillGroup:
    """The holes and slots one bit makes in one plating phase, in cutting order."""

    bit_nm: int
    plated: bool
    items: list = field(default_factory=list)


@dataclass
class DrillPlan:
    """The groups in cutting order and what the user should read (holes too small)."""

    groups: list[DrillGroup]
    notes: list[str]

    @property
    def tool_changes(self) -> int:
        return sum(1 for a, b in zip(self.groups, self.groups[1:]) if a.bit_nm != b.bit_nm)


def plan_drilling(drills: list, mill: MillConfig, order: str = "plated-first") -> DrillPlan:
    """The holes and slots grouped and ordered (module doc)."""
    if order not in DRILL_ORDERS:
        raise DrillError(f"drill order {order!r}: must be one of "
                         f"{', '.join(repr(o) for o in DRILL_ORDERS)}")
    if not drills:
        raise DrillError("no holes or slots to drill")
    bits = sorted(mill.drills_nm)
    too_small: dict[int, list] = {}
    groups: dict[tuple[bool, int], list] = {}
    for item in drills:
        fitting = [bit for bit in bits if bit <= item.diameter_nm + FIT_NM]
        if not fitting:
            too_small.setdefault(item.diameter_nm, []).append(item)
        bit = fitting[-1] if fitting else bits[0]
        groups.setdefault((item.plated is not False, bit), []).append(item)
    notes = [_too_small_note(items, bits[0]) for _, items in sorted(too_small.items())]
    plated_first = order == "plated-first"
    keys = sorted(groups, key=lambda key: (key[0] != plated_first, key[1]))
    at = (0, 0)
    ordered = []
    for plated, bit in keys:
        items = _nearest_first(groups[(plated, bit)], at)
        ordered.append(DrillGroup(bit, plated, items))
        at = _end(items[-1])
    return DrillPlan(ordered, notes)


def drill_gcode(drills: list, mill: MillConfig, order: str = "plated-first",
                source: str = "") -> str:
    """The drilling G-code of `drills` (Hole and Slot, e.g. board_holes(board))."""
    plan = plan_drilling(drills, mill, order)
    return plan_gcode(plan, mill, source)


def plan_gcode(plan: DrillPlan, mill: MillConfig, source: str = "") -> str:
    """A DrillPlan as GRBL G-code lines (module doc)."""
    safe = mm(mill.safe_height_nm)
    first = plan.groups[0].bit_nm
    lines = [f"(galileo-cnc mill: drilling{' of ' + _comment(source) if source else ''})",
             f"(start with the {mm_text(first)} mm bit in the spindle, Z = 0 at the board's top)"]
    lines += [f"({_comment(note)})" for note in plan.notes]
    lines += ["G21 G90 G17 G94", f"G0 Z{safe}", f"M3 S{mill.spindle_rpm}"]
    bit = first
    for group in plan.groups:
        if group.bit_nm != bit:
            lines += _tool_change(group.bit_nm, mill)
            bit = group.bit_nm
        lines.append(f"({'plated' if group.plated else 'unplated'}, "
                     f"{mm_text(group.bit_nm)} mm bit: {len(group.items)})")
        for item in group.items:
            if isinstance(item, Hole):
                lines += _hole(item, group.bit_nm, mill)
            else:
                lines += _slot(item, group.bit_nm, mill)
    lines += ["M5", "M2"]
    return "\n".join(lines) + "\n"


def _tool_change(bit_nm: int, mill: MillConfig) -> list[str]:
    return tool_change_lines(f"{mm_text(bit_nm)} mm bit", mill)


#: What every tool change's M0 comment begins with: a sender finds the changes by it
#: (grbl/mill_job.py names the tool to the user and re-zeroes again on a resume).
TOOL_CHANGE = "TOOL CHANGE: put in the "
#: The dwell after the spindle is switched on again: it comes up to speed.
SPIN_UP = "G4 P2"


def tool_change_lines(tool: str, mill: MillConfig) -> list[str]:
    """Spindle off at the safe height, M0 naming the tool (`tool`: "0.800 mm bit"), Z
    re-zeroed (probe or touch-off), spindle on again and up to speed."""
    safe = mm(mill.safe_height_nm)
    lines = [f"G0 Z{safe}", "M5", f"M0 ({TOOL_CHANGE}{tool})"]
    if mill.probe:
        lines += [f"M0 (PROBE: clip the probe to the {tool}, the plate on the board)",
                  f"G38.2 Z{mm(-PROBE_REACH_NM)} F{mm(mill.plunge_feed_um_min * 1000)}",
                  f"G92 Z{mm(mill.probe_plate_nm)}",
                  f"G0 Z{safe}",
                  "M0 (PROBE DONE: take the probe clip and the plate away)"]
    else:
        lines += _touch_off(tool, mill)
    lines += [f"M3 S{mill.spindle_rpm}", SPIN_UP]
    return lines


def _touch_off(tool: str, mill: MillConfig) -> list[str]:
    """No probe: the collet-drop touch-off any sender can run (M0 and cycle start only).
    The spindle goes down to Z = 0 with the new bit loose in its collet, so the bit
    rests on the board's top; the user tightens it there: Z = 0 holds for the new bit."""
    return [f"M0 (TOUCH OFF: leave the {tool} loose in the collet, its tip "
            f"above the board; resume: the spindle goes down to Z = 0)",
            f"G1 Z0 F{mm(mill.plunge_feed_um_min * 1000)}",
            "M0 (TOUCH OFF: let the bit rest on the board's top, tighten the collet, resume)",
            f"G0 Z{mm(mill.safe_height_nm)}"]


def _hole(hole: Hole, bit_nm: int, mill: MillConfig) -> list[str]:
    safe, depth = mm(mill.safe_height_nm), _depth_nm(mill)
    plunge = mm(mill.plunge_feed_um_min * 1000)
    x, y = hole.x_nm, hole.y_nm
    radius = (hole.diameter_nm - bit_nm) // 2
    if hole.diameter_nm - bit_nm <= MILL_ABOVE_NM:
        return [f"G0 X{mm(x)} Y{mm(y)}", f"G1 Z{mm(-depth)} F{plunge}", f"G0 Z{safe}"]
    lines = [f"G0 X{mm(x + radius)} Y{mm(y)}", f"G1 Z0 F{plunge}"]
    circle = f"G2 X{mm(x + radius)} Y{mm(y)} I{mm(-radius)} J0"
    for z in depth_levels(depth, mill.cutout_step_down_nm):
        lines.append(f"{circle} Z{mm(-z)} F{mm(mill.feed_um_min * 1000)}")
    lines += [circle, f"G0 Z{safe}"]
    return lines


def _slot(slot: Slot, bit_nm: int, mill: MillConfig) -> list[str]:
    """Depth passes along the path, back and forth, or round the contour (module doc)."""
    safe, depth = mm(mill.safe_height_nm), _depth_nm(mill)
    plunge, feed = mm(mill.plunge_feed_um_min * 1000), mm(mill.feed_um_min * 1000)
    offset = (slot.diameter_nm - bit_nm) // 2
    if slot.diameter_nm - bit_nm > MILL_ABOVE_NM:
        ring = _contour(slot, offset)
        lines = [f"G0 X{mm(ring[-1][1])} Y{mm(ring[-1][2])}"]
        for z in depth_levels(depth, mill.cutout_step_down_nm):
            lines.append(f"G1 Z{mm(-z)} F{plunge}")
            lines += [_move(move, feed) for move in ring]
    else:
        there, back = _path(slot), _path(_reversed(slot))
        lines = [f"G0 X{mm(slot.x0_nm)} Y{mm(slot.y0_nm)}"]
        for k, z in enumerate(depth_levels(depth, mill.cutout_step_down_nm)):
            lines.append(f"G1 Z{mm(-z)} F{plunge}")
            lines.append(_move(there if k % 2 == 0 else back, feed))
    lines.append(f"G0 Z{safe}")
    return lines


def _contour(slot: Slot, offset: int) -> list[tuple]:
    """The slot's path offset `offset` each side with round ends, as moves
    (code, x, y, i, j) from the outer start point back to it: the outer side (right of
    the travel), the far end's half circle, the inner side back, the near end's."""
    x0, y0, x1, y1 = slot.x0_nm, slot.y0_nm, slot.x1_nm, slot.y1_nm
    turn = "G2" if slot.arc == "cw" else "G3"
    if slot.arc:
        cx, cy = slot.cx_nm, slot.cy_nm
        sign = 1 if slot.arc == "ccw" else -1      # the right of the travel: out for ccw
        u0, u1 = _unit(x0 - cx, y0 - cy, sign), _unit(x1 - cx, y1 - cy, sign)
        back = "G2" if slot.arc == "ccw" else "G3"
    else:
        dx, dy = _unit(x1 - x0, y1 - y0, 1)
        u0 = u1 = (dy, -dx)
    o0 = (x0 + round(offset * u0[0]), y0 + round(offset * u0[1]))
    o1 = (x1 + round(offset * u1[0]), y1 + round(offset * u1[1]))
    i0 = (x0 - round(offset * u0[0]), y0 - round(offset * u0[1]))
    i1 = (x1 - round(offset * u1[0]), y1 - round(offset * u1[1]))
    if slot.arc:
        side_out = (turn, *o1, cx - o0[0], cy - o0[1])
        side_in = (back, *i0, cx - i1[0], cy - i1[1])
    else:
        side_out, side_in = ("G1", *o1, 0, 0), ("G1", *i0, 0, 0)
    # from the right of the travel round the end to its left is a counter-clockwise half
    return [side_out, ("G3", *i1, x1 - o1[0], y1 - o1[1]),
            side_in, ("G3", *o0, x0 - i0[0], y0 - i0[1])]


def _unit(dx: int, dy: int, sign: int) -> tuple[float, float]:
    length = math.hypot(dx, dy) or 1.0
    return sign * dx / length, sign * dy / length


def _path(slot: Slot) -> tuple:
    """The slot's path from its start as one move (code, x, y, i, j)."""
    if not slot.arc:
        return ("G1", slot.x1_nm, slot.y1_nm, 0, 0)
    return ("G2" if slot.arc == "cw" else "G3", slot.x1_nm, slot.y1_nm,
            slot.cx_nm - slot.x0_nm, slot.cy_nm - slot.y0_nm)


def _reversed(slot: Slot) -> Slot:
    arc = {"cw": "ccw", "ccw": "cw"}.get(slot.arc, "")
    return Slot(slot.x1_nm, slot.y1_nm, slot.x0_nm, slot.y0_nm, slot.diameter_nm,
                slot.tool, slot.plated, slot.line, arc, slot.cx_nm, slot.cy_nm)


def _move(move: tuple, feed: str) -> str:
    code, x, y, i, j = move
    arc = f" I{mm(i)} J{mm(j)}" if code != "G1" else ""
    return f"{code} X{mm(x)} Y{mm(y)}{arc} F{feed}"


def depth_levels(depth_nm: int, step_nm: int) -> list[int]:
    """Depths (positive, nm) down to `depth_nm` in equal passes of at most `step_nm`."""
    count = max(1, -(-depth_nm // step_nm))
    return [depth_nm * k // count for k in range(1, count + 1)]


def _depth_nm(mill: MillConfig) -> int:
    return mill.board_thickness_nm + mill.breakthrough_nm


def _nearest_first(items: list, start: tuple[int, int]) -> list:
    """Nearest neighbour from `start`; a slot is entered at its nearer end (reversed)."""
    starts = np.array([(i.x_nm, i.y_nm) if isinstance(i, Hole) else (i.x0_nm, i.y0_nm)
                       for i in items], dtype=np.float64)
    ends = np.array([(i.x_nm, i.y_nm) if isinstance(i, Hole) else (i.x1_nm, i.y1_nm)
                     for i in items], dtype=np.float64)
    left = np.ones(len(items), dtype=bool)
    at = np.array(start, dtype=np.float64)
    ordered = []
    for _ in range(len(items)):
        to_start = np.where(left, np.hypot(*(starts - at).T), np.inf)
        to_end = np.where(left, np.hypot(*(ends - at).T), np.inf)
        k = int(np.argmin(np.minimum(to_start, to_end)))
        left[k] = False
        item = items[k]
        if isinstance(item, Slot) and to_end[k] < to_start[k]:
            item = _reversed(item)
        ordered.append(item)
        at = np.array(_end(item), dtype=np.float64)
    return ordered


def _end(item) -> tuple[int, int]:
    return (item.x_nm, item.y_nm) if isinstance(item, Hole) else (item.x1_nm, item.y1_nm)


def _too_small_note(items: list, bit_nm: int) -> str:
    """One note per diameter below every bit: a board's vias are hundreds of holes."""
    size = f"{mm_text(items[0].diameter_nm)} mm"
    if len(items) == 1:
        what = f"{_where(items[0])}: {size} is"
    else:
        what = f"{len(items)} holes of {size} (the first {_where(items[0])}) are"
    return f"{what} smaller than the smallest bit, {mm_text(bit_nm)} mm: drilled with it"


def _where(item) -> str:
    line = f" line {item.line}" if item.line else ""
    x, y = (item.x_nm, item.y_nm) if isinstance(item, Hole) else (item.x0_nm, item.y0_nm)
    return f"{item.tool or 'hole'}{line} at X {mm_text(x)} Y {mm_text(y)} mm"


def mm_text(nm: int) -> str:
    """A length as a user reads it in a message: mm, to the micrometre."""
    return f"{nm / 1_000_000:.3f}"
