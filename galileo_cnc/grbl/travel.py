"""Refuse a job that would leave GRBL's travel, before a byte of it is sent.

GRBL 1.1h (HOMING_FORCE_SET_ORIGIN off, the default) homes to machine zero at
the switch end, so its travel is negative space: an axis may go from
-$130..2 up to 0 mm (settings stores max_travel negated; system.c
system_check_travel_limits). Machine = work + WCO. GRBL checks every line
target and every arc segment in mc_line; here a whole arc is checked by its
extremes, so nothing GRBL would stop at passes. All arithmetic in integer nm.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from galileo_cnc.grbl.numbers import decimal_text_to_nm
from galileo_cnc.grbl.reports import GrblError

_WORD = re.compile(r"([A-Z])([-+]?[0-9]*\.?[0-9]*)")
_COMMENT = re.compile(r"\([^)]*\)")
AXES = "XYZ"


class TravelError(GrblError):
    """A job line would take an axis outside GRBL's travel."""


@dataclass(frozen=True, slots=True)
class Overrun:
    index: int          # G-code line index
    axis: int
    machine_nm: int     # where the axis would go, machine coordinates
    low_nm: int         # the travel: low_nm .. 0
    where: str

    def __str__(self) -> str:
        place = f"{self.where}: " if self.where else ""
        return (f"{place}G-code line {self.index + 1} takes {AXES[self.axis]} to "
                f"{_mm(self.machine_nm)} mm (machine), outside GRBL's travel "
                f"{_mm(self.low_nm)}..0 mm (${130 + self.axis}={_mm(-self.low_nm)})")


def _mm(nm: int) -> str:
    sign = "-" if nm < 0 else ""
    return f"{sign}{abs(nm) // 1_000_000}.{abs(nm) % 1_000_000:06d}".rstrip("0").rstrip(".")


def applies(settings) -> bool:
    """Machine coordinates mean something only on a homed machine: soft limits
    ($20, which GRBL allows only with homing) or homing ($22) on."""
    return settings.soft_limits or settings.homing


def first_overrun(lines: Sequence, settings, wco_nm, mpos_nm, *,
                  where: Callable[[int], str] = lambda command: "",
                  axes: Sequence[int] = (0, 1, 2)) -> Overrun | None:
    """The first line that leaves the travel, None if all stay inside.
    `mpos_nm`/`wco_nm`: GRBL's machine position and work offset before the job.
    `axes`: the axes checked; a G92 or a G38.2 probe that moves only axes left out
    (a mill job's Z, zeroed where the bit touches) is passed over."""
    low = [-settings.max_travel_nm(a) for a in range(3)]
    wco = list(wco_nm)
    work = [m - w for m, w in zip(mpos_nm, wco)]
    motion = "G0"
    for index, line in enumerate(lines):
        text = _COMMENT.sub(" ", getattr(line, "text", line)).split(";")[0].strip().upper()
        if text.startswith("$"):
            if text.startswith(("$H", "$J=")):
                return None         # a new origin: beyond here nothing is known
            continue
        words = _WORD.findall(text)
        gs = {float(v) for k, v in words if k == "G"}
        values = {k: decimal_text_to_nm(v) for k, v in words if k in "XYZIJ"}
        if 10 in gs:                # G10 L20 P0 X0 Y0 Z0: here becomes work zero
            for a in range(3):
                if AXES[a] in values:
                    wco[a] = work[a] + wco[a] - values[AXES[a]]
                    work[a] = values[AXES[a]]
            continue
        unchecked_only = all(AXES.index(k) not in axes for k, _ in words if k in AXES)
        if 92.1 in gs or (92 in gs and unchecked_only):
            continue                # offsets of the axes left out only
        if 38.2 in gs and unchecked_only:
            continue                # a probe down: where it stops is not known here
        if 4 in gs or 92 in gs or 53 in gs:
            if 92 in gs or 53 in gs:
                raise TravelError(f"G-code line {index + 1} uses "
                                  f"G{53 if 53 in gs else 92}: not checked")
            continue
        for g in (0, 1, 2, 3):
            if g in gs:
                motion = f"G{g}"
        if not any(k in AXES for k, _ in words):
            continue
        target = [values.get(AXES[a], work[a]) for a in range(3)]
        reach = [(t, t) for t in target]
        if motion in ("G2", "G3"):
            reach = _arc_extent(work, target, values.get("I", 0), values.get("J", 0),
                                motion == "G2")
        for a in axes:
            lo, hi = min(reach[a][0], work[a]), max(reach[a][1], work[a])
            for value in (lo + wco[a], hi + wco[a]):
                if value > 0 or value < low[a]:
                    command = getattr(line, "command", -1)
                    return Overrun(index, a, value, low[a], where(command))
        work = target
    return None


def _arc_extent(start, target, i_nm, j_nm, clockwise):
    """(min, max) per axis of the arc from start to target around start+(I, J)."""
    cx, cy = start[0] + i_nm, start[1] + j_nm
    r = math.hypot(start[0] - cx, start[1] - cy)
    a0 = math.atan2(start[1] - cy, start[0] - cx)
    a1 = math.atan2(target[1] - cy, target[0] - cx)
    sweep = (a1 - a0) % (2 * math.pi)
    if clockwise:
        sweep = sweep - 2 * math.pi if sweep > 0 else -2 * math.pi if sweep == 0 else sweep
    elif sweep == 0:
        sweep = 2 * math.pi
    xs, ys = [start[0], target[0]], [start[1], target[1]]
    for k in range(-6, 7):          # axis crossings the sweep passes (|angle| < 3 pi)
        angle = k * math.pi / 2
        if min(a0, a0 + sweep) < angle < max(a0, a0 + sweep):
            xs.append(cx + round(r * math.cos(angle)))
            ys.append(cy + round(r * math.sin(angle)))
    return [(min(xs), max(xs)), (min(ys), max(ys)), (min(start[2], target[2]),
                                                     max(start[2], target[2]))]


def check_travel(lines: Sequence, settings, wco_nm, mpos_nm, *,
                 where: Callable[[int], str] = lambda command: "",
                 axes: Sequence[int] = (0, 1, 2)) -> None:
    """Raises TravelError naming the file line, axis, value and limit."""
    if not applies(settings):
        return
    overrun = first_overrun(lines, settings, wco_nm, mpos_nm, where=where, axes=axes)
    if overrun is not None:
        raise TravelError(f"job refused before sending: {overrun}")
