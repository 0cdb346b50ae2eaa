"""Stroke widths: how wide a line an aperture draws (the pen it needs) and a width as
mm text. Shared by the ink (which pens fill, which features are narrow) and the planner
(the pen each aperture asks for).
"""

from __future__ import annotations

import math

import numpy as np

from galileo_cnc.program.ops import NM_PER_MM, Aperture


def aperture_width(aperture: Aperture) -> int:
    """The width of the narrowest stroke the aperture makes (nm); 0 when it makes none."""
    p = aperture.params_nm
    if aperture.shape == "circle":
        return p[0] if p else 0
    if aperture.shape in ("rectangle", "obround"):
        return min(p[0], p[1]) if len(p) >= 2 else 0
    if aperture.shape == "polygon":
        return int(p[0] * math.cos(math.pi / max(aperture.vertices, 3))) if p else 0
    axis = macro_axis(aperture)
    if axis is not None:
        return axis[0]
    x0, y0, x1, y1 = aperture.extent_nm
    return min(x1 - x0, y1 - y0)


def macro_axis(aperture: Aperture) -> tuple[int, np.ndarray, np.ndarray, float] | None:
    """(width, unit direction of the long axis, centre, length along it) of a macro's dark primitives'
    convex hull: its narrowest width over every edge direction (a bar turned by %LR30
    is as narrow as before it was turned), None without primitives."""
    points = []
    for primitive in aperture.primitives:
        if not primitive[1]:
            continue
        if primitive[0] == "circle":
            _, _, x, y, diameter = primitive
            angles = np.linspace(0, 2 * np.pi, 32, endpoint=False)
            points.append(np.stack([x + diameter / 2 * np.cos(angles),
                                    y + diameter / 2 * np.sin(angles)], axis=1))
        elif primitive[0] == "polygon":
            points.append(np.asarray(primitive[2], dtype=np.float64).reshape(-1, 2))
    if not points:
        return None
    hull = _convex_hull(np.concatenate(points))
    if len(hull) < 3:
        return None
    edges = np.roll(hull, -1, axis=0) - hull
    lengths = np.hypot(edges[:, 0], edges[:, 1])
    keep = lengths > 0
    along = edges[keep] / lengths[keep, None]
    normal = np.stack([-along[:, 1], along[:, 0]], axis=1)
    # width across each edge: the spread of the hull's points along its normal
    spread = hull @ normal.T
    widths = spread.max(axis=0) - spread.min(axis=0)
    best = int(np.argmin(widths))
    direction = along[best]
    lengthwise = hull @ direction
    across = hull @ normal[best]
    centre = direction * (lengthwise.max() + lengthwise.min()) / 2 + \
        normal[best] * (across.max() + across.min()) / 2
    return (int(round(widths[best])), direction, centre,
            float(lengthwise.max() - lengthwise.min()))


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """The hull's vertices, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted(set(map(tuple, points.tolist())))
    if len(pts) < 3:
        return np.array(pts, dtype=np.float64)

    def half(sequence):
        chain = []
        for q in sequence:
            while len(chain) >= 2 and ((chain[-1][0] - chain[-2][0]) * (q[1] - chain[-2][1])
                                       - (chain[-1][1] - chain[-2][1]) * (q[0] - chain[-2][0])) <= 0:
                chain.pop()
            chain.append(q)
        return chain
    return np.array(half(pts)[:-1] + half(reversed(pts))[:-1], dtype=np.float64)


def mm_text(nm: int) -> str:
    """Nanometres as mm to 3 decimals, no trailing zeros: '0.25'; a length too short
    for 3 decimals is '<0.001' (never '0' for something there), and never '-0'."""
    text = f"{nm / NM_PER_MM:.3f}".rstrip("0").rstrip(".")
    if text in ("0", "-0"):
        return "<0.001" if nm > 0 else ">-0.001" if nm < 0 else "0"
    return text
