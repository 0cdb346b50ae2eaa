"""The outline of each Gerber object as integer-nanometre polygons, library-free.

Everything here is numpy: rings are (n, 2) int64 arrays, not closed (the last
point is not the first again). A *polygon* is (shell, holes): the shell is filled,
each hole ring lies inside it. What a polygon library does with them (union,
difference) is in `backends.py`.

Curves become polygons whose vertices lie on the true curve (inscribed chords),
so every edge is within the chord tolerance of the true boundary; vertices are
then rounded to the nanometre. `circle_segments` chooses the count so that the
chord error plus the rounding stays within the tolerance.

A round aperture is one regular polygon (`circle_template`, a multiple of 4
vertices, one at 0, 90, 180 and 270 degrees, so axis-parallel traces get sides
exactly r from their centre line). Flashes and draws with it are exact Minkowski
sums of that polygon: a flash is the polygon moved to the flash point, a draw is
the polygon swept along the segment (`capsules`: n + 2 vertices). Arcs are
annular sectors (`arc_band`) with the polygon at both ends.
"""

from __future__ import annotations

import math

import numpy as np

from galileo_cnc.plan.curves import arc_angles, chord_step

#: Default chord tolerance: 1 um. The pens are 0.3 mm and wider and one motor step
#: is 6.25 um, so 1 um is invisible and keeps a 0.25 mm pad at 24 vertices.
DEFAULT_TOLERANCE_NM = 1_000


def circle_segments(radius: float, tolerance_nm: int) -> int:
    """Vertex count (a multiple of 4, at least 8) of a circle polygon within tolerance."""
    n = math.ceil(2.0 * math.pi / chord_step(radius, tolerance_nm) - 1e-9)
    return max(8, -(-n // 4) * 4)


def regular_polygon(radius: float, vertices: int, phase: float = 0.0) -> np.ndarray:
    """CCW ring of `vertices` points on a circle of `radius` about the origin, rounded to nm."""
    angles = phase + 2.0 * np.pi * np.arange(vertices) / vertices
    return np.stack([np.rint(radius * np.cos(angles)), np.rint(radius * np.sin(angles))],
                    axis=1).astype(np.int64)


def circle_template(diameter_nm: int, tolerance_nm: int) -> np.ndarray:
    """The polygon that stands for a round aperture of this diameter (CCW, centred at 0)."""
    radius = diameter_nm / 2
    return regular_polygon(radius, circle_segments(radius, tolerance_nm))


def rectangle(width_nm: int, height_nm: int) -> np.ndarray:
    """CCW rectangle of exactly width x height nm centred at the origin (to 0.5 nm)."""
    x0, y0 = -(width_nm // 2), -(height_nm // 2)
    x1, y1 = x0 + width_nm, y0 + height_nm
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.int64)


def obround(width_nm: int, height_nm: int, tolerance_nm: int) -> np.ndarray:
    """CCW stadium: a circle of the smaller side swept along the difference of the sides."""
    if width_nm == height_nm:
        return circle_template(width_nm, tolerance_nm)
    template = circle_template(min(width_nm, height_nm), tolerance_nm)
    half = abs(width_nm - height_nm) // 2
    rest = abs(width_nm - height_nm) - half
    if width_nm > height_nm:
        start, end = (-half, 0), (rest, 0)
    else:
        start, end = (0, -half), (0, rest)
    return capsules(template, np.array([start], dtype=np.int64), np.array([end], dtype=np.int64))[0]


def capsules(template: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """(L, n + 2, 2) rings: the centred regular n-gon `template` (n even) swept from
    each start to each end, i.e. the convex hull of the polygon at both ends.

    The n-gon is centrally symmetric, so the vertex furthest to the right of the
    direction of travel and the one furthest to the left are n/2 apart: the ring is
    n/2 + 1 vertices of the polygon at the end (right to left, the front) and n/2 + 1
    at the start (left to right, the back). A zero-length draw gives the polygon.
    """
    n = len(template)
    half = n // 2
    direction = (ends - starts).astype(np.float64)
    # Right-hand normal of the direction; the vertex furthest along it starts the front.
    right = np.stack([direction[:, 1], -direction[:, 0]], axis=1)
    first = np.argmax(right @ template.T.astype(np.float64), axis=1)
    steps = np.arange(half + 1)
    front = (first[:, None] + steps[None, :]) % n
    back = (first[:, None] + half + steps[None, :]) % n
    return np.concatenate([template[front] + ends[:, None, :],
                           template[back] + starts[:, None, :]], axis=1)


def convex_sweep(template: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """CCW ring of a convex CCW polygon swept along a segment (its Minkowski sum with it)."""
    dx, dy = int(end[0] - start[0]), int(end[1] - start[1])
    if dx == 0 and dy == 0:
        return template + start
    along_left = template[:, 1] * dx - template[:, 0] * dy  # exact: template is small
    left, right = int(np.argmax(along_left)), int(np.argmin(along_left))
    n = len(template)
    front = [(right + k) % n for k in range((left - right) % n + 1)]
    back = [(left + k) % n for k in range((right - left) % n + 1)]
    return np.concatenate([template[front] + end, template[back] + start])


def edge_sweeps(rings: list[np.ndarray], start: np.ndarray, end: np.ndarray) -> list[np.ndarray]:
    """Quadrilaterals swept by every edge of `rings` along start -> end (zero-area ones
    left out). With the rings at both ends they make up the exact Minkowski sum of any
    polygon set and a segment: a point the sweep covers either lies in one of the two
    end copies or was crossed by the boundary on the way."""
    v = end - start
    quads = []
    for ring in rings:
        p = ring
        q = np.roll(ring, -1, axis=0)
        edge = q - p
        cross = edge[:, 0].astype(np.float64) * v[1] - edge[:, 1].astype(np.float64) * v[0]
        keep = cross != 0
        if not keep.any():
            continue
        p, q, cross = p[keep], q[keep], cross[keep]
        quad = np.stack([p + start, q + start, q + end, p + end], axis=1)
        # The quad p, q, q+v, p+v is CCW when edge x v > 0; turn the others around.
        quad[cross < 0] = quad[cross < 0][:, ::-1]
        quads.extend(quad)
    return quads


def arc_band(sx: int, sy: int, ex: int, ey: int, i: int, j: int, clockwise: bool,
             half_width: float, tolerance_nm: int) -> list[tuple[np.ndarray, list[np.ndarray]]]:
    """The band a disc of radius `half_width` sweeps along an arc, without its end caps:
    an annular sector between radius - w and radius + w (a pie when radius < w), or
    an annulus for a full circle. Returned as polygons (shell, holes), shells CCW.

    With the disc at both ends this is exactly the swept area: the nearest point of
    an arc to any point is either its radial projection (inside the sector) or an end.
    """
    cx, cy = sx + i, sy + j
    r0 = math.hypot(sx - cx, sy - cy)
    r1 = math.hypot(ex - cx, ey - cy)
    a0, sweep = arc_angles(sx, sy, ex, ey, cx, cy, clockwise)
    outer_max = max(r0, r1) + half_width
    full = (sx, sy) == (ex, ey)
    if full:
        centre = np.array([cx, cy], dtype=np.int64)
        outer = regular_polygon(r0 + half_width, circle_segments(outer_max, tolerance_nm), a0)
        inner_radius = r0 - half_width
        if inner_radius <= 0:
            return [(outer + centre, [])]
        inner = regular_polygon(inner_radius, len(outer), a0)[::-1]
        return [(outer + centre, [inner + centre])]
    steps = max(1, math.ceil(abs(sweep) / chord_step(outer_max, tolerance_nm)))
    t = np.arange(steps + 1) / steps
    radius = r0 + (r1 - r0) * t
    angle = a0 + sweep * t
    cos, sin = np.cos(angle), np.sin(angle)
    out_r = radius + half_width
    in_r = np.maximum(radius - half_width, 0.0)
    outer = np.stack([cx + out_r * cos, cy + out_r * sin], axis=1)
    inner = np.stack([cx + in_r * cos, cy + in_r * sin], axis=1)[::-1]
    if not in_r.any():
        inner = np.array([[cx, cy]], dtype=np.float64)
    ring = np.rint(np.concatenate([outer, inner])).astype(np.int64)
    if sweep < 0:
        ring = ring[::-1]
    return [(ring, [])]


def signed_area2(ring: np.ndarray) -> float:
    """Twice the signed area (positive = CCW), in float, taken relative to the first
    point so that large board coordinates lose nothing that matters to the sign."""
    r = (ring - ring[0]).astype(np.float64)
    x, y = r[:, 0], r[:, 1]
    return float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def ccw(ring: np.ndarray) -> np.ndarray:
    return ring if signed_area2(ring) >= 0 else ring[::-1]
