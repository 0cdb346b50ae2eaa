"""Step timing: feed -> interval, ramps, and the absolute tick of every step event.

Time is kept in *subticks* (1/256 tick) so the average interval is exact to well
under 0.01 % while the interrupt only adds: the tick of an event is the integer
part of the running subtick sum (docs/motion.md §5). Everything per move is
computed once here with integer division/sqrt; per event there are adds and
compares only.

A *run* is a contiguous range of step events [first, last] of one move that is
executed without stopping. Its ramp index is

    m_k = min(entry + k - first, exit + last - k, R)

and the interval (in subticks) in front of event k is

    interval_k = base_k + (R - m_k) * step_sub

so a run from rest (entry 0) starts at base + R*step_sub (about K x base, K the
config's ramp_start_factor, 3 by default), reaches base after R events, and slows
down symmetrically to its exit index; runs shorter than 2R+1 events get a triangle. Entry and exit are 0 unless the host planned
junction speeds (junctions.py, docs/motion.md §5.7).
"""

from __future__ import annotations

from dataclasses import dataclass
from math import isqrt

import numpy as np

from galileo_cnc.config.hardware import TICKS_PER_S

FRAC_BITS = 8
SUBTICKS_PER_TICK = 1 << FRAC_BITS
SUBTICKS_PER_S = TICKS_PER_S * SUBTICKS_PER_TICK  # 512_000_000
RHO_BITS = 15
RHO_ONE = 1 << RHO_BITS  # path length per event 1.0 in Q15
TICKS_PER_MS = TICKS_PER_S // 1000


def axial_interval_sub(feed_steps_per_s: int) -> int:
    """Subticks per step along one axis at `feed`: round(512e6 / F), halves up."""
    return (2 * SUBTICKS_PER_S + feed_steps_per_s) // (2 * feed_steps_per_s)


def weighted_interval_sub(axial_sub: int, rho_q15: int) -> int:
    """Subticks per event whose path length is rho_q15 / 2^15 steps (rounded)."""
    return (axial_sub * rho_q15 + (1 << (RHO_BITS - 1))) >> RHO_BITS


def line_rho_q15(dx: int, dy: int, dz: int, n: int) -> int:
    """Path length per major-axis event of a line, Q15: isqrt((L^2 << 30) // n^2)."""
    d2 = dx * dx + dy * dy + dz * dz
    return isqrt((d2 << (2 * RHO_BITS)) // (n * n))


def ramp_events(feed_steps_per_s: int, accel_steps_per_s2: int, start_factor: int) -> int:
    """R = ceil((K - 1) F^2 / A) for a ramp from K x the period: the ramp length that
    keeps every axis below A (§5.2); 2 F^2 / A at the default K = 3."""
    return ((start_factor - 1) * feed_steps_per_s * feed_steps_per_s
            + accel_steps_per_s2 - 1) // accel_steps_per_s2


def ramp_step_sub(ref_sub: int, ramp: int, start_factor: int) -> int:
    """Per-event interval change on the ramp: round((factor - 1) * ref / R), halves up."""
    if ramp == 0:
        return 0
    return (2 * (start_factor - 1) * ref_sub + ramp) // (2 * ramp)


@dataclass(frozen=True, slots=True)
class Run:
    """Events [first, last] (global event indices) run without a stop.

    `pause_ticks` is idle time between the previous run's last event (or the job
    start) and this run's start; the first event comes one interval after it.
    """

    first: int
    last: int
    ramp: int
    step_sub: int
    pause_ticks: int
    entry: int = 0       # ramp index of the first event
    exit: int = 0        # ramp index of the last event


def run_ticks(base_sub: np.ndarray, runs: list[Run], t0: int = 0, tail_ticks: int = 0,
              inplace: bool = False) -> tuple[np.ndarray, np.ndarray, int]:
    """Absolute tick of every event in `runs` (vectorised), run start ticks, end time.

    `base_sub` holds the cruise interval of every event (global indexing); events
    outside every run get tick -1. With `inplace` the array is reused for the result.

    One cumulative sum serves the whole job: the first interval of each run gets
    a gap so that the running sum stands at exactly 256 * (run start tick) when
    the run begins; then every tick is the running sum >> 8, which is the same
    as restarting the fraction at zero for each run, as the firmware does.
    """
    n_events = len(base_sub)
    if not runs:
        return (np.full(n_events, -1, dtype=np.int64), np.zeros(0, dtype=np.int64),
                t0 + tail_ticks)
    count = len(runs)
    first = np.fromiter((r.first for r in runs), np.int64, count)
    last = np.fromiter((r.last for r in runs), np.int64, count)
    ramp = np.fromiter((r.ramp for r in runs), np.int64, count)
    step = np.fromiter((r.step_sub for r in runs), np.int64, count)
    pause = np.fromiter((r.pause_ticks for r in runs), np.int64, count)
    entry = np.fromiter((r.entry for r in runs), np.int64, count)
    exit_ = np.fromiter((r.exit for r in runs), np.int64, count)
    length = last - first + 1
    contiguous = bool(first[0] == 0 and last[-1] == n_events - 1
                      and np.all(first[1:] == last[:-1] + 1))
    if contiguous:
        idx = None
        interval = base_sub if inplace else base_sub.copy()
    else:
        idx = _ranges(first, length)
        interval = base_sub[idx]
    offs = np.cumsum(length) - length  # run start in the (compacted) interval array
    has_ramp = ramp > 0
    if has_ramp.any():
        rr = np.flatnonzero(has_ramp)
        r_len, r_ramp, r_step, r_offs = length[rr], ramp[rr], step[rr], offs[rr]
        r_in, r_out = entry[rr], exit_[rr]
        head = np.minimum(r_ramp - r_in, r_len)                          # m < R at the start
        tail = np.minimum(r_ramp - r_out, np.maximum(r_len - head, 0))   # and at the end
        for starts_local, counts in ((np.zeros_like(head), head), (r_len - tail, tail)):
            k = _ranges(starts_local, counts)
            grp = np.repeat(np.arange(len(rr)), counts)
            m = np.minimum(np.minimum(r_in[grp] + k, r_out[grp] + r_len[grp] - 1 - k),
                           r_ramp[grp])
            interval[r_offs[grp] + k] += (r_ramp[grp] - m) * r_step[grp]
    sums = np.add.reduceat(interval, offs)
    duration = sums >> FRAC_BITS
    starts = t0 + np.cumsum(pause) + np.concatenate(([0], np.cumsum(duration)[:-1]))
    gap = SUBTICKS_PER_TICK * starts
    gap[1:] -= SUBTICKS_PER_TICK * starts[:-1] + sums[:-1]
    interval[offs] += gap
    np.cumsum(interval, out=interval)
    interval >>= FRAC_BITS
    if idx is None:
        ticks = interval
    else:
        ticks = np.full(n_events, -1, dtype=np.int64)
        ticks[idx] = interval
    end = int(starts[-1] + duration[-1]) + tail_ticks
    return ticks, starts, end


def ramp_sum(length: int, ramp: int, entry: int = 0, exit: int = 0) -> int:
    """sum over a run's events k of (R - m_k): what the ramps add to its intervals, in
    steps of step_sub. R - m_k = max(0, p - k, q - (L-1-k)) with p = R - entry,
    q = R - exit: the falling term wins up to the crossing c, the rising one after;
    each part is a clipped arithmetic series."""
    p, q = ramp - entry, ramp - exit
    c = min(max((p - q + length - 1) // 2 + 1, 0), length)
    t1 = min(c, max(p, 0))
    t2 = min(length - c, max(q, 0))
    return t1 * p - t1 * (t1 - 1) // 2 + t2 * q - t2 * (t2 - 1) // 2


def _ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Concatenation of arange(s, s + l) for every (s, l), vectorised."""
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    lengths = lengths.astype(np.int64)
    ends = np.cumsum(lengths)
    out = np.ones(total, dtype=np.int64)
    nz = lengths > 0
    s, l, e = starts[nz].astype(np.int64), lengths[nz], ends[nz]
    out[0] = s[0]
    # At each group boundary jump from the previous group's last value to s.
    jump_at = (e - l)[1:]
    out[jump_at] = s[1:] - (s[:-1] + l[:-1] - 1)
    return np.cumsum(out)


def ramp_index(k: int, first: int, last: int, ramp: int, entry: int = 0, exit: int = 0) -> int:
    """m_k for one event (used by the per-step loop and by hold handling)."""
    return min(entry + k - first, exit + last - k, ramp)
