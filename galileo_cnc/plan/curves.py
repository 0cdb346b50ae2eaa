"""Arcs as chords within a tolerance: shared by the ink's shapes (ink/shapes.py) and
the planner, which draws an arc too far from its centre for the machine as chords.

`arc_angles` gives an arc's start angle and signed sweep, `arc_points` its points
(both ends exact, integer nm), `chord_step` the largest angle whose chord stays within
the tolerance (one nm of it goes to rounding vertices: `chord_budget`).
"""

from __future__ import annotations

import math

import numpy as np


def chord_budget(tolerance_nm: int) -> float:
    """What the chords may use of the tolerance: one nm goes to rounding vertices."""
    if tolerance_nm <= 0:
        raise ValueError(f"chord tolerance must be positive, got {tolerance_nm} nm")
    return tolerance_nm - 1 if tolerance_nm > 2 else tolerance_nm / 2


def chord_step(radius: float, tolerance_nm: int) -> float:
    """Largest angle (radians) whose chord on a circle of `radius` nm stays within tolerance."""
    budget = chord_budget(tolerance_nm)
    if radius <= budget:
        return math.pi  # the whole curve is within tolerance of its chord
    return 2.0 * math.acos(1.0 - budget / radius)


def arc_angles(sx: int, sy: int, ex: int, ey: int, cx: int, cy: int,
               clockwise: bool) -> tuple[float, float]:
    """(start angle, signed sweep) of an arc; start == end is a full turn."""
    a0 = math.atan2(sy - cy, sx - cx)
    if (sx, sy) == (ex, ey):
        return a0, -2.0 * math.pi if clockwise else 2.0 * math.pi
    a1 = math.atan2(ey - cy, ex - cx)
    if clockwise:
        return a0, -((a0 - a1) % (2.0 * math.pi))
    return a0, (a1 - a0) % (2.0 * math.pi)


def arc_points(sx: int, sy: int, ex: int, ey: int, i: int, j: int, clockwise: bool,
               tolerance_nm: int, extra_radius: float = 0.0) -> np.ndarray:
    """(k + 1, 2) int64 points along an arc from start to end, both exact, centre
    start + (i, j). The chords stay within tolerance of the curve at radius + extra.

    An end point off the start circle (the reader keeps it as written) makes the
    radius change linearly with the angle: a spiral that ends where the file says.
    """
    cx, cy = sx + i, sy + j
    r0 = math.hypot(sx - cx, sy - cy)
    r1 = math.hypot(ex - cx, ey - cy)
    a0, sweep = arc_angles(sx, sy, ex, ey, cx, cy, clockwise)
    steps = max(1, math.ceil(abs(sweep) / chord_step(max(r0, r1) + extra_radius, tolerance_nm)))
    t = np.arange(steps + 1) / steps
    radius = r0 + (r1 - r0) * t
    angle = a0 + sweep * t
    points = np.stack([np.rint(cx + radius * np.cos(angle)),
                       np.rint(cy + radius * np.sin(angle))], axis=1).astype(np.int64)
    points[0] = (sx, sy)
    points[-1] = (ex, ey)
    return points
