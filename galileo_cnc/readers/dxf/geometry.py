"""Plane geometry in drawing units (floats, WCS): affine maps, bulges, and the
approximation of curves by circular arcs and lines within a tolerance.

A drawn path is a start point and a list of segments `(kind, x, y, cx, cy, vertex)`:
kind LINE, CW or CCW, (x, y) the end point, (cx, cy) the arc centre (unused for
lines), `vertex` an index into the entity's vertex lines (-1: the entity's own line).
A full circle is an arc whose end is its start (the end point is the very same
float pair, so it rounds to the same nanometre).
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

LINE, CW, CCW = 0, 1, 2
FULL = 4  # or-ed into CW / CCW: a full circle (end = start)

Point = tuple[float, float]
Segment = tuple[int, float, float, float, float, int]
Affine = tuple[float, float, float, float, float, float]  # a, b, c, d, e, f: (ax+by+e, cx+dy+f)

IDENTITY: Affine = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0)

# Two columns of a 2x2 map agree (same length, at right angles) to this relative
# precision: the map is a similarity and takes circles to circles.
SIMILAR_EPS = 1e-9
# Interior samples per piece when fitting a curve (plus both ends).
_SAMPLES = 7
_MAX_DEPTH = 32
# Pieces one curve may be cut into before the rest is drawn as plain chords: a bound on
# the work for a tolerance far below what the drawing's floats can resolve.
_MAX_PIECES = 100_000


def apply(m: Affine, x: float, y: float) -> Point:
    a, b, c, d, e, f = m
    return (a * x + b * y + e, c * x + d * y + f)


def determinant(m: Affine) -> float:
    return m[0] * m[3] - m[1] * m[2]


def similarity_scale(m: Affine) -> float | None:
    """The uniform scale of `m` if it maps circles to circles (a rotation, a uniform
    scale and perhaps a mirror), else None (also for a degenerate map)."""
    a, b, c, d = m[0], m[1], m[2], m[3]
    s1 = a * a + c * c
    s2 = b * b + d * d
    big = max(s1, s2)
    if big == 0.0:
        return None
    if abs(s1 - s2) > SIMILAR_EPS * big or abs(a * b + c * d) > SIMILAR_EPS * big:
        return None
    if abs(a * d - b * c) < SIMILAR_EPS * big:
        return None
    return math.sqrt(s1) if s1 == s2 else math.sqrt((s1 + s2) / 2)


def bulge_centre(x0: float, y0: float, x1: float, y1: float, bulge: float) -> Point:
    """Centre of the arc from (x0, y0) to (x1, y1) whose bulge is `bulge` (tan of a
    quarter of the included angle; positive: counter-clockwise)."""
    dx, dy = x1 - x0, y1 - y0
    k = (1.0 - bulge * bulge) / (4.0 * bulge)
    return ((x0 + x1) / 2 - dy * k, (y0 + y1) / 2 + dx * k)


def _circle(p0: Point, p1: Point, p2: Point) -> tuple[float, float, float] | None:
    """Centre and radius of the circle through three points, None if they are in a line."""
    ax, ay = p0
    bx, by = p1[0] - ax, p1[1] - ay
    cx, cy = p2[0] - ax, p2[1] - ay
    d = 2.0 * (bx * cy - by * cx)
    if d == 0.0:
        return None
    b2, c2 = bx * bx + by * by, cx * cx + cy * cy
    ux = (cy * b2 - by * c2) / d
    uy = (bx * c2 - cx * b2) / d
    return ax + ux, ay + uy, math.hypot(ux, uy)


def _off_chord(p: Point, a: Point, b: Point) -> float:
    """Distance from p to the segment a-b."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    px, py = p[0] - a[0], p[1] - a[1]
    if length2 == 0.0:
        return math.hypot(px, py)
    t = (px * dx + py * dy) / length2
    if t <= 0.0:
        return math.hypot(px, py)
    if t >= 1.0:
        return math.hypot(p[0] - b[0], p[1] - b[1])
    return abs(px * dy - py * dx) / math.sqrt(length2)


def _as_arc(p0: Point, pts: Sequence[Point], p1: Point, tol: float):
    """(cx, cy, kind) of an arc through p0, the middle sample and p1 that every sample
    lies on within `tol`, turning one way and less than a full turn; else None."""
    mid = pts[len(pts) // 2]
    circle = _circle(p0, mid, p1)
    if circle is None:
        return None
    cx, cy, r = circle
    chain = [p0, *pts, p1]
    sweep = 0.0
    sign = 0.0
    previous = (p0[0] - cx, p0[1] - cy)
    for p in chain[1:]:
        v = (p[0] - cx, p[1] - cy)
        if abs(math.hypot(*v) - r) > tol:
            return None
        cross = previous[0] * v[1] - previous[1] * v[0]
        dot = previous[0] * v[0] + previous[1] * v[1]
        step = math.atan2(cross, dot)
        if step == 0.0 or (sign and (step > 0) != (sign > 0)):
            return None
        sign = step
        sweep += step
        previous = v
    if abs(sweep) > math.pi:  # keep fitted arcs to half a turn at most
        return None
    return cx, cy, (CCW if sweep > 0 else CW)


def fit_curve(points_at: Callable[[list[float]], list[Point]], t0: float, t1: float,
              p0: Point, p1: Point, tol: float, out: list[Segment], vertex: int = -1) -> None:
    """Append lines and arcs that follow the curve `points_at` from parameter t0 (point
    p0) to t1 (point p1) within `tol`: a piece becomes a line when all its samples are
    within `tol` of the chord, an arc when they are within `tol` of the circle through
    its ends and middle, else it is halved. Checked at 7 samples per piece."""
    stack = [(t0, t1, p0, p1, 0)]
    budget = _MAX_PIECES
    while stack:
        a, b, pa, pb, depth = stack.pop()
        budget -= 1
        if budget < 0:
            out.append((LINE, pb[0], pb[1], 0.0, 0.0, vertex))
            continue
        ts = [a + (b - a) * k / (_SAMPLES + 1) for k in range(1, _SAMPLES + 1)]
        pts = points_at(ts)
        if all(_off_chord(p, pa, pb) <= tol for p in pts):
            out.append((LINE, pb[0], pb[1], 0.0, 0.0, vertex))
            continue
        arc = _as_arc(pa, pts, pb, tol) if depth < _MAX_DEPTH else None
        if arc is not None:
            out.append((arc[2], pb[0], pb[1], arc[0], arc[1], vertex))
            continue
        if depth >= _MAX_DEPTH:
            out.append((LINE, pb[0], pb[1], 0.0, 0.0, vertex))
            continue
        tm = (a + b) / 2
        pm = pts[len(pts) // 2]
        # second half first: the stack pops the first half next
        stack.append((tm, b, pm, pb, depth + 1))
        stack.append((a, tm, pa, pm, depth + 1))


def reverse(start, segments: list) -> tuple:
    """The same path walked backwards (arcs change direction); works on float and on
    integer paths alike."""
    points = [start] + [(s[1], s[2]) for s in segments]
    out: list[Segment] = []
    for index in range(len(segments) - 1, -1, -1):
        kind, _, _, cx, cy, vertex = segments[index]
        x, y = points[index]
        if kind != LINE:
            kind = (kind & FULL) | (CW if kind & 3 == CCW else CCW)
        out.append((kind, x, y, cx, cy, vertex))
    return points[-1], out
