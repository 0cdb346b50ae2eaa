"""Exact integer geometry for G02/G03: the centre of an R-form arc, radius checks.

All inputs and results are integer nanometres. Square roots are taken with
math.isqrt and the rounding is decided exactly, so the same file gives the same
centre on every machine, to the nanometre.
"""

from __future__ import annotations

from math import isqrt

# How far a radius may fall short of half the chord and still be taken as a
# half circle: 0.0001 in, the finest step an inch file usually writes, so an R
# rounded by the CAM to its output precision does not fail.
R_SHORTFALL_TOLERANCE_NM = 2_540

# Start and end radius of an I/J arc may differ by this much (absolute, or
# relative to the radius, whichever is larger) before the arc is refused.
RADIUS_MISMATCH_NM = 5_000
RADIUS_MISMATCH_RELATIVE = 1_000  # 1/1000 of the radius


def round_half_away(numerator: int, denominator: int) -> int:
    """numerator / denominator to the nearest integer, ties away from zero (denominator > 0)."""
    if numerator >= 0:
        return (2 * numerator + denominator) // (2 * denominator)
    return -((-2 * numerator + denominator) // (2 * denominator))


def _nearest_half_sum(base: int, sign: int, num: int, den: int) -> int:
    """Nearest integer to (base + sign * sqrt(num / den)) / 2, ties away from zero.

    num >= 0, den > 0, sign is +1 or -1.
    """
    root = isqrt(num // den)  # floor(sqrt(num / den)), exactly
    if root * root * den == num:  # rational root: exact
        return round_half_away(base + sign * root, 2)
    # Irrational root: no ties. For sign -1, with root < sqrt < root + 1, the
    # nearest integer to (base - sqrt) / 2 is floor((base - root) / 2); the
    # sign +1 case is its mirror image.
    if sign < 0:
        return (base - root) // 2
    return -((-base - root) // 2)


def r_form_centre_offset(dx: int, dy: int, r: int, clockwise: bool) -> tuple[int, int] | None:
    """(i, j): centre minus start of an arc to start + (dx, dy) with signed radius r.

    Positive r takes the shorter arc (at most 180 degrees), negative r the longer.
    The centre lies on the chord's perpendicular bisector at distance
    h = sqrt(r^2 - (d/2)^2) from the chord's midpoint, left of the chord for a
    short counter-clockwise (or long clockwise) arc. With k^2 = (4 r^2 - d^2) / d^2:
        i = (dx - s * dy * k) / 2,   j = (dy + s * dx * k) / 2,   s = +1 on the left,
    each rounded to the nearest nanometre (ties away from zero).

    Returns None when |r| is shorter than half the chord by more than the
    tolerance; within it the arc is a half circle about the chord's midpoint.
    The caller refuses dx == dy == 0 (a full circle has no R form).
    """
    chord_sq = dx * dx + dy * dy
    excess = 4 * r * r - chord_sq  # (2h)^2 * ... in nm^2; negative when r is too short
    if excess < 0:
        shortfall_limit = isqrt(chord_sq) - 2 * R_SHORTFALL_TOLERANCE_NM
        if 2 * abs(r) < shortfall_limit:
            return None
        return round_half_away(dx, 2), round_half_away(dy, 2)
    left = (r > 0) != clockwise
    s = 1 if left else -1
    # s * dy * k = sign(s * dy) * sqrt(dy^2 * excess / chord_sq), likewise for dx.
    i = _nearest_half_sum(dx, -_sign(s * dy), dy * dy * excess, chord_sq)
    j = _nearest_half_sum(dy, _sign(s * dx), dx * dx * excess, chord_sq)
    return i, j


def _sign(value: int) -> int:
    return 1 if value >= 0 else -1


def radius_mismatch(start_dx: int, start_dy: int, end_dx: int, end_dy: int) -> int | None:
    """How far the end point is off the circle through the start, if beyond tolerance.

    Arguments are start and end minus the centre. Returns the difference of the
    two radii in nm (rounded down) when it is too large, else None.
    """
    r_start = isqrt(start_dx * start_dx + start_dy * start_dy)
    r_end = isqrt(end_dx * end_dx + end_dy * end_dy)
    difference = abs(r_start - r_end)
    allowed = max(RADIUS_MISMATCH_NM, max(r_start, r_end) // RADIUS_MISMATCH_RELATIVE)
    return difference if difference > allowed else None
