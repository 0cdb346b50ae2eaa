"""Integer plane geometry shared by readers, info and planner."""

from __future__ import annotations

import numpy as np


def single_quadrant_centre(sx: int, sy: int, ex: int, ey: int, i: int, j: int,
                           clockwise: bool) -> tuple[int, int]:
    """Signed centre offset for a G74 (single-quadrant) arc with unsigned I/J.

    The Gerber spec leaves the signs open: of the four candidate centres, take the
    ones whose arc in the given direction spans at most 90 degrees and, among those,
    the one where start and end radius agree best. Decided with exact integer cross
    and dot products; if no candidate spans <= 90 degrees, the best radius match wins.
    """
    i, j = abs(i), abs(j)
    best = None
    for di, dj in ((i, j), (-i, j), (i, -j), (-i, -j)):
        cx, cy = sx + di, sy + dj
        ax, ay, bx, by = sx - cx, sy - cy, ex - cx, ey - cy
        cross = ax * by - ay * bx
        dot = ax * bx + ay * by
        within_quadrant = dot >= 0 and (cross <= 0 if clockwise else cross >= 0)
        radius_mismatch = abs((ax * ax + ay * ay) - (bx * bx + by * by))
        key = (not within_quadrant, radius_mismatch)
        if best is None or key < best[0]:
            best = (key, (di, dj))
    return best[1]


def arc_extremes(sx: int, sy: int, ex: int, ey: int, i: int, j: int, clockwise: bool):
    """Bounding box (xmin, ymin, xmax, ymax) of an arc's centre line, in nm.

    Start == end is a full circle. The radius is taken at the start point.
    """
    cx, cy = sx + i, sy + j
    r = int(np.sqrt(float(i * i + j * j)) + 0.5)
    xs, ys = [sx, ex], [sy, ey]
    if (sx, sy) == (ex, ey):
        return (cx - r, cy - r, cx + r, cy + r)
    # Axis crossings passed when sweeping from start to end in the given direction.
    a0 = _angle_order(sx - cx, sy - cy)
    a1 = _angle_order(ex - cx, ey - cy)
    for quadrant_point, (px, py) in enumerate(((cx + r, cy), (cx, cy + r), (cx - r, cy), (cx, cy - r))):
        a = float(quadrant_point)  # 0 = +x, 1 = +y, 2 = -x, 3 = -y, in quarter turns
        if _passes(a0, a1, a, clockwise):
            xs.append(px)
            ys.append(py)
    return (min(xs), min(ys), max(xs), max(ys))


def _angle_order(x: int, y: int) -> float:
    """Angle in quarter turns [0, 4), monotone with the true angle (exact enough for ordering)."""
    return (float(np.arctan2(y, x)) / (np.pi / 2)) % 4.0


def _passes(a0: float, a1: float, a: float, clockwise: bool) -> bool:
    if clockwise:
        a0, a1 = a1, a0
    span = (a1 - a0) % 4.0
    return 0.0 < (a - a0) % 4.0 < span
