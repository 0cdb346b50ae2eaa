"""Shared by the GRBL tests: build GRBL 1.1h and the harness once, boot GRBL in
simavr with the test machine's settings, and check a pin trace against the
G-code it ran (end points exact, every step within one step of the path).

Outside CI a missing Debian package skips with its name; under CI it fails.
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import serial

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.config.profile import load_profile
from galileo_cnc.grbl import firmware
from galileo_cnc.grbl.gcode import AxisScale, GcodeLine, job_to_gcode, pen_from_config
from galileo_cnc.grbl.link import GrblLink
from galileo_cnc.grbl.numbers import grbl_steps, read_float
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.simavr import board as simavr
from galileo_cnc.simavr.board import step_trace

from firmware_support import build_harness, require_packages

# The test machine: the seed's 160 steps/mm, run fast so simulated jobs stay short.
STEPS_PER_MM = "160"
# $12 arc tolerance 0.0005 mm (0.08 step): at GRBL's default 0.002 mm (0.32 step)
# its chords, their end points rounded to steps, and Bresenham along them put arc
# steps up to 1.14 steps (per axis) off the circle; docs/grbl.md has the numbers.
SETTINGS = {12: "0.0005",
            100: STEPS_PER_MM, 101: STEPS_PER_MM, 102: STEPS_PER_MM,
            110: "8000", 111: "8000", 112: "4000",       # mm/min
            120: "2000", 121: "2000", 122: "2000"}       # mm/s^2
CONFIG = MachineConfig(feed_mm_s=100, rapid_feed_mm_s=100, z_feed_mm_s=50,
                       feed_warn_mm_s=100, flash_dwell_ms=20)
#: CONFIG as a profile file: the default mechanics (160 steps/mm), run fast so a
#: whole simulated job is short
PROFILE = """[machine]
feed_mm_s = 100
rapid_feed_mm_s = 100
z_feed_mm_s = 50
feed_warn_mm_s = 100
flash_dwell_ms = 20
"""
SCALE = AxisScale.from_texts([STEPS_PER_MM] * 3)
#: the board the whole-plot tests draw
SAMPLE = str(Path(__file__).resolve().parents[2] / "samples" / "led-blinker.gbr")

_elf: list[Path] = []


def grbl_elf() -> Path:
    require_packages(simavr.HARNESS_PACKAGES + firmware.BUILD_PACKAGES)
    build_harness()
    if not _elf:
        _elf.append(firmware.build_grbl())
    return _elf[0]


@contextmanager
def grbl_machine(settings: dict[int, str] = SETTINGS, **board_kwargs):
    """(board, link): GRBL booted in simavr, detected, `settings` written and $$ re-read."""
    board = firmware.grbl_board(grbl_elf(), **board_kwargs)
    with board:
        port = serial.Serial(board.port, 115200, timeout=0.2)
        try:
            link = GrblLink.connect(port)
            for number, value in settings.items():
                link.command_checked(f"${number}={value}")
            link.read_info()
            yield board, link
        finally:
            port.close()


# ---- the pin trace ------------------------------------------------------------------

def positions(board) -> np.ndarray:
    """GRBL's machine position in steps after every step interrupt, (N+1, 3) from
    (0,0,0): steps of one interrupt share a cycle and count as one move."""
    return positions_and_ticks(board.trace())[0]


def positions_and_ticks(edges) -> tuple[np.ndarray, np.ndarray]:
    """positions() of a trace, with each row's Timer1 tick (-1 for the power-up row)."""
    tick, axis, direction = step_trace(edges, firmware.AXIS_PINS)
    delta = np.zeros((len(tick), 3), dtype=np.int64)
    delta[np.arange(len(tick)), axis] = -direction      # dir pin high = negative ($3=0)
    pos = np.cumsum(delta, axis=0)
    last_of_group = np.r_[tick[1:] != tick[:-1], True] if len(tick) else np.zeros(0, bool)
    return (np.vstack([np.zeros((1, 3), np.int64), pos[last_of_group]]),
            np.r_[-1, tick[last_of_group]].astype(np.int64))


def motions(lines: list[GcodeLine], scale: AxisScale = SCALE, start=(0, 0, 0)):
    """(kind, start, end, centre or None) in steps for every motion line, in GRBL's
    own arithmetic: `end` is where GRBL's planner targets (lround of its floats).
    `start`: where the head stands before the first line."""
    pos = list(start)
    for line in lines:
        words = line.text.split()
        if not words or words[0] not in ("G0", "G1", "G2", "G3"):
            continue
        start = tuple(pos)
        offset = {}
        for word in words[1:]:
            if word[0] in "XYZ":
                axis = "XYZ".index(word[0])
                pos[axis] = grbl_steps(word[1:], scale.steps_per_mm[axis])
            elif word[0] in "IJ":
                axis = "IJ".index(word[0])
                offset[axis] = float(read_float(word[1:])) * float(scale.steps_per_mm[axis])
        centre = None
        if words[0] in ("G2", "G3"):
            centre = (start[0] + offset.get(0, 0.0), start[1] + offset.get(1, 0.0))
        yield words[0], start, tuple(pos), centre


def check_trace(pos: np.ndarray, lines: list[GcodeLine], start=(0, 0, 0)) -> dict:
    """Every motion's end point is reached exactly, in order, and every position
    between two end points lies within one step of that motion's path on every
    axis (the step grid's own measure: some point of the path is less than a
    step away along X, Y and Z). Returns the worst distances, per axis and
    Euclidean, in steps."""
    index = 0
    worst_axis = worst_euclid = 0.0
    count = 0
    for kind, start, end, centre in motions(lines, start=start):
        assert tuple(pos[index]) == start, (kind, start, tuple(pos[index]))
        first = index
        if centre is not None and end == start:      # a full circle: leave, come back
            while index < len(pos) - 1 and tuple(pos[index]) == start:
                index += 1
        hits = np.nonzero(np.all(pos[index:] == end, axis=1))[0]
        assert len(hits), f"{kind} end point {end} never reached (after {start})"
        index += int(hits[0])
        path = pos[first:index + 1].astype(float)
        if centre is None:
            axis_d, euclid_d = _segment_distance(path, start, end)
        else:
            assert np.all(path[:, 2] == start[2]), "an arc moved Z"
            axis_d, euclid_d = _circle_distance(path, centre, start)
        worst_axis, worst_euclid = max(worst_axis, axis_d), max(worst_euclid, euclid_d)
        count += 1
    assert index == len(pos) - 1, f"{len(pos) - 1 - index} step moves after the last end point"
    assert worst_axis <= 1.0, f"a step lies {worst_axis:.3f} steps from the commanded path"
    return {"motions": count, "worst_axis_steps": worst_axis, "worst_steps": worst_euclid}


def _segment_distance(path: np.ndarray, start, end) -> tuple[float, float]:
    """(per-axis, Euclidean) distance of the worst point to the segment, exact:
    per axis, the distance to a line of unit normal n is |n.(p-a)| / |n|_1."""
    a = np.array(start, float)
    d = np.array(end, float) - a
    length2 = float(d @ d)
    if length2 == 0:
        gap = np.abs(path - a)
        return float(gap.max()) if len(path) else 0.0, float(np.linalg.norm(gap, axis=1).max())
    t = ((path - a) @ d) / length2
    nearest = a + np.clip(t, 0.0, 1.0)[:, None] * d
    euclid = np.linalg.norm(path - nearest, axis=1)
    if np.count_nonzero(d) <= 2 and d[2] == 0:
        n = np.array([-d[1], d[0]]) / np.hypot(d[0], d[1])
        axis = np.abs((path[:, :2] - a[:2]) @ n) / np.abs(n).sum()
        ends = np.minimum(np.abs(path - a).max(axis=1), np.abs(path - a - d).max(axis=1))
        axis = np.where((t < 0) | (t > 1), ends, axis)
    else:   # 3-D and Z moves: the Euclidean distance bounds the per-axis one
        axis = euclid
    return float(axis.max()), float(euclid.max())


def _circle_distance(path: np.ndarray, centre, start) -> tuple[float, float]:
    """(per-axis, Euclidean) distance of the worst point to the circle. Per axis,
    by sampling the circle within 3 steps of the point's own angle (a subset of
    the circle: never less than the true distance)."""
    cx, cy = centre
    r = math.hypot(start[0] - cx, start[1] - cy)
    dx, dy = path[:, 0] - cx, path[:, 1] - cy
    euclid = np.abs(np.hypot(dx, dy) - r)
    span = 3.0 / max(r, 3.0)
    angles = np.arctan2(dy, dx)[:, None] + np.linspace(-span, span, 513)[None, :]
    gap = np.maximum(np.abs(cx + r * np.cos(angles) - path[:, :1]),
                     np.abs(cy + r * np.sin(angles) - path[:, 1:2]))
    return float(gap.min(axis=1).max()), float(euclid.max())


def planned_gcode(profile_path: str) -> list[GcodeLine]:
    """The G-code `plot` sends for SAMPLE in centre mode, computed here from the
    same profile."""
    config = load_profile(profile_path).config
    planned = plan_file(SAMPLE, config, options=PlanOptions(mode="centre"))
    return job_to_gcode(planned.job, SCALE, pen_from_config(config),
                        feed_steps_per_s=config.feed_steps_per_s,
                        flash_dwell_ms=config.flash_dwell_ms)
