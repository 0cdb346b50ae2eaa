"""How long GRBL 1.1h takes to run a list of G-code lines, from a model of its
planner (planner.c) and stepper (stepper.c).

What is modelled, as GRBL does it:
- blocks: targets rounded to steps (lround), each block's length and unit vector
  from those step deltas; acceleration and rapid rate limited per axis
  ($110-$112, $120-$122: limit_value_by_axis_maximum); a block with no step is
  dropped;
- junctions: `$11` junction deviation gives the max junction speed from the
  angle between unit vectors; a block added to an empty buffer starts from rest;
  entry speeds capped by both nominal speeds (plan_compute_profile_parameters);
- look-ahead: GRBL plans over the blocks in its buffer only (`$I` planner
  blocks, 15): each block's exit speed is the backward pass over the next
  blocks with the last one stopping, and the forward pass from the actual entry;
- arcs: split as mc_arc splits them (`$12` arc tolerance), segment ends from the
  exact angle (GRBL's small-angle rotation differs by far less than a step);
- execution: the trapezoid (accelerate, cruise, decelerate) of each block;
- GRBL's own pace: the AVR needs time to make each block (parse a line, or
  compute an arc segment, then replan): 3.5 ms, measured in simavr twice: the
  ceiling of 283 lines/s of bench/bench_grbl.py, and a 2.5 mm circle at 75 mm/s
  with $12=0.0005 (157 segments of 0.1 mm: 0.487 s, not the feed's 0.21 s). A block starts no sooner than it is made, and is made
  only when one of the buffer's slots is free; short blocks then run late (their
  speeds are planned as if the buffer were full: GRBL then also slows, a little
  more than modelled);
- stops: G4 (a dwell runs as ceil(20 s) slices of 50 ms: delay_sec), M3/M4/M5
  (spindle_sync) and G10 (EEPROM write) first drain the buffer to a stop, and
  every stop costs `$1` ms more: st_go_idle holds the motors that long
  (delay_ms) before GRBL goes on (none when `$1=255`, motors always on).

Left out (together 2 % on a corpus board, docs/grbl.md; a 2.5 mm circle in
0.1 mm arc segments, where a starved buffer drops its exit speeds, 6.5 %): the
slower planning of a starved buffer, the stepper's 10 ms segments
and cycles-per-step rounding, float32 arithmetic, overrides, a few ms per stop
(the first step after a start, parsing the line after a dwell), a host that
cannot keep the buffer full, and `$H`/`$J=` (homing and jogging times are
unknown: counted in `Estimate.unmodelled`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from galileo_cnc.grbl.numbers import lround_f32, read_float, steps_per_mm_f32

N_AXIS = 3
DWELL_STEP_S = 0.050            # config.h DWELL_TIME_STEP
MINIMUM_FEED_MM_MIN = 1.0       # config.h MINIMUM_FEED_RATE
PLANNER_BLOCKS = 15             # $I's default: BLOCK_BUFFER_SIZE 16, one kept free
#: GRBL's time to make one block on a 16 MHz AVR, measured in simavr (docstring)
BLOCK_MAKE_S = 0.0035
_WORD = re.compile(r"([A-Z])([-+]?[0-9]*\.?[0-9]*)")


@dataclass(frozen=True, slots=True)
class Machine:
    """The settings the estimate needs, in mm, mm/s and mm/s^2."""

    steps_per_mm: tuple[np.float32, ...]
    max_rate: tuple[float, ...]         # mm/s
    accel: tuple[float, ...]            # mm/s^2
    junction_deviation: float           # mm
    arc_tolerance: float                # mm
    planner_blocks: int = PLANNER_BLOCKS
    idle_lock_s: float = 0.025          # $1, spent at every stop

    @classmethod
    def from_settings(cls, settings, planner_blocks: int | None = None) -> Machine:
        """From GrblSettings (`$$` texts) and `$I`'s planner blocks."""
        f = lambda n: float(read_float(settings[n]))
        return cls(tuple(steps_per_mm_f32(settings[100 + a]) for a in range(N_AXIS)),
                   tuple(f(110 + a) / 60 for a in range(N_AXIS)),
                   tuple(f(120 + a) for a in range(N_AXIS)),
                   f(11), f(12), planner_blocks or PLANNER_BLOCKS,
                   0.0 if settings.integer(1) == 255 else settings.integer(1) / 1000)


@dataclass(slots=True)
class Estimate:
    seconds: float = 0.0            # everything: motion, dwells, idle locks
    motion_s: float = 0.0
    dwell_s: float = 0.0
    blocks: int = 0                 # planner blocks (arcs count their segments)
    stops: int = 0                  # buffer drained to a stop (G4, M3/M5, G10)
    idle_lock_s: float = 0.0        # $1 at each stop
    unmodelled: list[str] = field(default_factory=list)    # $H, $J= lines
    first_motion_s: float | None = None     # when the first block starts
    last_motion_s: float = 0.0              # when the last block ends

    @property
    def motion_span_s(self) -> float:
        """First step to last step: what a pin trace measures."""
        return 0.0 if self.first_motion_s is None else self.last_motion_s - self.first_motion_s


@dataclass(slots=True)
class _Block:
    mm: float
    accel: float
    nominal: float                  # mm/s
    max_entry: float                # mm/s, from the junction and nominal speeds
    make_s: float                   # GRBL's time to make it


def _limit_by_axis(limits, unit) -> float:
    """planner.c limit_value_by_axis_maximum."""
    return min((abs(limits[a] / unit[a]) for a in range(N_AXIS) if unit[a]), default=math.inf)


class _Planner:
    def __init__(self, machine: Machine):
        self.m = machine
        self.pos = [0, 0, 0]                # steps, pl.position
        self.prev_unit: list[float] | None = None   # None: the buffer is empty
        self.prev_nominal = 0.0
        self.run: list[_Block] = []         # blocks since the last stop

    def line(self, target_mm, feed_mm_s: float | None, make_s: float = BLOCK_MAKE_S) -> None:
        m = self.m
        target = [lround_f32(np.float32(target_mm[a]) * m.steps_per_mm[a])
                  for a in range(N_AXIS)]
        delta = [(target[a] - self.pos[a]) / float(m.steps_per_mm[a]) for a in range(N_AXIS)]
        if target == self.pos:
            return                                           # PLAN_EMPTY_BLOCK
        self.pos = target
        length = math.sqrt(sum(d * d for d in delta))
        unit = [d / length for d in delta]
        accel = _limit_by_axis(m.accel, unit)
        rapid = _limit_by_axis(m.max_rate, unit)
        nominal = max(MINIMUM_FEED_MM_MIN / 60, min(rapid, feed_mm_s or rapid))
        if self.prev_unit is None:
            junction = 0.0
        else:
            cos_theta = -sum(p * u for p, u in zip(self.prev_unit, unit))
            if cos_theta > 0.999999:            # a reversal: stop
                junction = 0.0
            elif cos_theta < -0.999999:         # straight on
                junction = math.inf
            else:
                ju = [u - p for p, u in zip(self.prev_unit, unit)]
                jn = math.sqrt(sum(j * j for j in ju))
                j_accel = _limit_by_axis(m.accel, [j / jn for j in ju])
                sin_half = math.sqrt(0.5 * (1.0 - cos_theta))
                junction = math.sqrt(j_accel * m.junction_deviation * sin_half
                                     / (1.0 - sin_half))
            junction = min(junction, nominal, self.prev_nominal)
        self.run.append(_Block(length, accel, nominal, junction, make_s))
        self.prev_unit, self.prev_nominal = unit, nominal

    def drain(self) -> tuple[float, int]:
        """Runs the blocks buffered since the last stop, to a stop: (seconds, blocks)."""
        blocks, self.run = self.run, []
        self.prev_unit = None
        return _run_time(blocks, self.m.planner_blocks), len(blocks)


def _run_time(blocks: list[_Block], window: int) -> float:
    """Seconds for blocks that start and end at rest, each planned with only the
    `window` blocks GRBL's buffer holds while it runs (itself included), none
    starting before GRBL has made it (the clock starts with the first block)."""
    n = len(blocks)
    clock = 0.0
    made = -blocks[0].make_s if blocks else 0.0
    ends: list[float] = []
    entry = 0.0
    for k, b in enumerate(blocks):
        # made once the one before is made and a slot is free (block k-window done)
        made = max(made, ends[k - window] if k >= window else made) + b.make_s
        clock = max(clock, made)
        # backward pass: the last buffered block stops
        exit_sq = 0.0
        for j in range(min(n, k + window) - 1, k, -1):
            bj = blocks[j]
            exit_sq = min(bj.max_entry ** 2, exit_sq + 2 * bj.accel * bj.mm)
        # forward pass from the speed the block really starts with
        exit_sq = min(exit_sq, entry * entry + 2 * b.accel * b.mm)
        exit_v = math.sqrt(exit_sq)
        clock += _trapezoid_s(b.mm, b.accel, entry, exit_v, b.nominal)
        ends.append(clock)
        entry = exit_v
    return clock


def _trapezoid_s(mm: float, accel: float, v0: float, v1: float, cruise: float) -> float:
    """Time to cover `mm` from v0 to v1, at most `cruise`, at +-accel."""
    peak_sq = (2 * accel * mm + v0 * v0 + v1 * v1) / 2
    if peak_sq <= cruise * cruise:
        peak = math.sqrt(peak_sq)
        return (2 * peak - v0 - v1) / accel
    ramps = (2 * cruise * cruise - v0 * v0 - v1 * v1) / (2 * accel)
    return (2 * cruise - v0 - v1) / accel + (mm - ramps) / cruise


def _arc_points(start, target, offset, radius, clockwise, tolerance):
    """mc_arc's segment end points (the last is the target itself)."""
    cx, cy = start[0] + offset[0], start[1] + offset[1]
    r0, r1 = -offset[0], -offset[1]
    t0, t1 = target[0] - cx, target[1] - cy
    travel = math.atan2(r0 * t1 - r1 * t0, r0 * t0 + r1 * t1)
    if clockwise and travel >= -5e-7:
        travel -= 2 * math.pi
    elif not clockwise and travel <= 5e-7:
        travel += 2 * math.pi
    segments = int(abs(0.5 * travel * radius)
                   / math.sqrt(tolerance * (2 * radius - tolerance)))
    points = []
    for i in range(1, segments):
        a = i * travel / segments
        points.append((cx + r0 * math.cos(a) - r1 * math.sin(a),
                       cy + r0 * math.sin(a) + r1 * math.cos(a),
                       start[2] + (target[2] - start[2]) * i / segments))
    points.append(tuple(target))
    return points


def estimate(lines: Sequence, machine: Machine) -> Estimate:
    """Seconds GRBL takes for `lines` (GcodeLine or str, mm, absolute, G17, G94),
    starting at rest at work (0, 0, 0)."""
    out = Estimate()
    planner = _Planner(machine)
    pos = [0.0, 0.0, 0.0]               # mm, gc_state.position
    motion = "G0"
    feed: float | None = None           # mm/s
    clock = 0.0

    def stop() -> None:
        nonlocal clock
        seconds, count = planner.drain()
        if count:
            out.first_motion_s = clock if out.first_motion_s is None else out.first_motion_s
            clock += seconds
            out.motion_s += seconds
            out.blocks += count
            out.stops += 1
            out.last_motion_s = clock
            clock += machine.idle_lock_s
            out.idle_lock_s += machine.idle_lock_s

    for line in lines:
        text = getattr(line, "text", line).strip().upper()
        if text.startswith("$"):
            if text.startswith(("$H", "$J=")):
                stop()
                out.unmodelled.append(text)
            continue
        words = [(letter, value) for letter, value in _WORD.findall(text.split(";")[0])]
        gs = {float(v) for letter, v in words if letter == "G"}
        ms = {float(v) for letter, v in words if letter == "M"}
        values = {letter: read_float(v) for letter, v in words if letter not in "GMN"}
        if "F" in values:
            feed = float(values["F"]) / 60
        if 4 in gs:
            stop()
            # delay_sec: ceil(20 * P) in float32 (P0.1 is 2 slices, not 3)
            slices = math.ceil(float(np.float32(1 / DWELL_STEP_S)
                                     * values.get("P", np.float32(0))))
            seconds = slices * DWELL_STEP_S
            clock += seconds
            out.dwell_s += seconds
            continue
        if ms & {3, 4, 5} or 10 in gs:
            stop()
            if 10 in gs:                 # G10 L20: the work origin is here now
                pos = [0.0, 0.0, 0.0]
            continue
        for g in (0, 1, 2, 3):
            if g in gs:
                motion = f"G{g}"
        target = [float(values.get("XYZ"[a], pos[a])) for a in range(N_AXIS)]
        if not any(letter in "XYZ" for letter, _ in words):
            continue
        rate = None if motion == "G0" else feed
        if motion in ("G2", "G3"):
            offset = (float(values.get("I", 0.0)), float(values.get("J", 0.0)))
            for point in _arc_points(pos, target, offset, math.hypot(*offset),
                                     motion == "G2", machine.arc_tolerance):
                planner.line(point, rate)
        else:
            planner.line(target, rate)
        pos = target
    stop()
    out.seconds = clock
    return out
