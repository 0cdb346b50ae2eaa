"""Line-distance stepping (docs/motion.md §3), closed form and vectorised.

A line of (dx, dy, dz) steps has n = max(|dx|, |dy|, |dz|) step events. After
event k (1-based) axis a, with d = |delta_a|, stands at

    q_a(k) = floor((2*k*d + n) / (2*n))        (= k*d/n rounded, halves step)

so it is never more than half a step from the ideal line, q_a(n) = d exactly,
and the major axis (d = n) steps at every event. The per-step form is the
Bresenham accumulator: e_a = n; each event e_a += 2d; if e_a >= 2n: e_a -= 2n,
step a. Solving q_a(k) >= j for k gives the event of the j-th step of axis a,

    k_j = ceil((2j - 1) * n / (2d)),   j = 1..d,

which is what the vectorised reference uses: work proportional to the steps.
"""

from __future__ import annotations

import numpy as np

from galileo_cnc.machine.ramps import _ranges


def line_events(delta: tuple[int, int, int]) -> int:
    return max(abs(delta[0]), abs(delta[1]), abs(delta[2]))


def minor_position(k: int, d: int, n: int) -> int:
    """q(k): steps of an axis with |delta| = d after event k of n (exact)."""
    return (2 * k * d + n) // (2 * n)


def fill_line_steps(table: np.ndarray, first_event: np.ndarray, n: np.ndarray,
                    delta: np.ndarray) -> None:
    """Write the minor-axis steps of many lines into the (N x 3) int8 step table.

    Line i owns events first_event[i] .. first_event[i] + n[i] - 1 and moves
    delta[i] (M x 3). Major axes (|delta| == n) step at every event and are
    filled by the caller; entries are dir * (axis + 1).
    """
    flat = table.reshape(-1)
    for axis in range(3):
        d_signed = delta[:, axis]
        d = np.abs(d_signed)
        minor = (d < n) & (d > 0)
        if not minor.any():
            continue
        dm, nm = d[minor], n[minor]
        j = _ranges(np.ones_like(dm), dm)  # 1..d per line
        # k_j = ceil((2j - 1) n / (2d)): operands < 2^35, so the float64 quotient is
        # exact enough that ceil() never lands on the wrong integer (|q - int| >= 1/2d).
        num = (2 * j - 1) * np.repeat(nm, dm)
        k = np.ceil(num / np.repeat(2.0 * dm, dm)).astype(np.int64)
        k += np.repeat(first_event[minor] - 1, dm)
        k *= 3
        k += axis
        code = np.sign(d_signed[minor]).astype(np.int8) * np.int8(axis + 1)
        flat[k] = np.repeat(code, dm)




def bresenham_points(start: tuple[int, int], delta: tuple[int, int]) -> np.ndarray:
    """The n points a 2-D line visits after each event (n x 2), closed form."""
    n = max(abs(delta[0]), abs(delta[1]))
    if n == 0:
        return np.zeros((0, 2), dtype=np.int64)
    k = np.arange(1, n + 1, dtype=np.int64)
    out = np.empty((n, 2), dtype=np.int64)
    for a in range(2):
        d = abs(delta[a])
        s = 1 if delta[a] >= 0 else -1
        out[:, a] = start[a] + s * ((2 * k * d + n) // (2 * n))
    return out
