"""Measurements on step traces: event positions, path speed, deviation from a path.

These are how tests and benchmarks check the machine from its output alone,
without trusting the formulas that produced it.
"""

from __future__ import annotations

import numpy as np

from galileo_cnc.config.hardware import TICKS_PER_S
from galileo_cnc.machine.trace import Trace


def event_positions(trace: Trace, start: tuple[int, int, int] = (0, 0, 0)
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(ticks, positions) after each step event (steps sharing a tick are one event)."""
    pos = trace.positions(start)
    if len(pos) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 3), dtype=np.int64)
    last_of_event = np.flatnonzero(np.diff(trace.tick, append=trace.tick[-1] + 1))
    return trace.tick[last_of_event], pos[last_of_event]


def line_speed_steps_per_s(ticks: np.ndarray, pos: np.ndarray, a: int, b: int) -> float:
    """Straight-line path speed between events a and b."""
    dist = float(np.linalg.norm((pos[b] - pos[a]).astype(np.float64)))
    return dist * TICKS_PER_S / float(ticks[b] - ticks[a])


def arc_speed_steps_per_s(ticks: np.ndarray, pos: np.ndarray, center: tuple[int, int],
                          radius: float, a: int, b: int) -> float:
    """Path speed along the true circle between events a and b (angles unwrapped)."""
    rel = pos[a:b + 1, :2].astype(np.float64) - np.asarray(center, dtype=np.float64)
    ang = np.unwrap(np.arctan2(rel[:, 1], rel[:, 0]))
    return abs(ang[-1] - ang[0]) * radius * TICKS_PER_S / float(ticks[b] - ticks[a])


def min_step_gap_ticks(trace: Trace) -> int:
    """Smallest time between consecutive steps of one axis (any axis)."""
    gaps = []
    for axis in range(3):
        t = trace.tick[trace.axis == axis]
        if len(t) > 1:
            gaps.append(int(np.diff(t).min()))
    return min(gaps) if gaps else 1 << 62


def segment_radial_deviation(points: np.ndarray, center: tuple[float, float],
                             radius: float) -> float:
    """Largest distance from the circle of any point on the polyline through `points`."""
    p = points[:, :2].astype(np.float64) - np.asarray(center, dtype=np.float64)
    outer = np.abs(np.hypot(p[:, 0], p[:, 1]) - radius).max()
    a, b = p[:-1], p[1:]
    ab = b - a
    length2 = (ab * ab).sum(axis=1)
    t = np.clip(-(a * ab).sum(axis=1) / np.where(length2 > 0, length2, 1), 0.0, 1.0)
    closest = a + t[:, None] * ab
    inner = (radius - np.hypot(closest[:, 0], closest[:, 1])).max() if len(ab) else 0.0
    return float(max(outer, inner))
