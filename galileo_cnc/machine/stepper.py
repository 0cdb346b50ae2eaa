"""The per-step reference: the firmware's interrupt, written as a plain Python loop.

Per event it does only what docs/motion.md §7 allows in the Timer1 ISR: integer
adds, subtracts, compares, sign tests and shifts by constants. Everything else
(divisions, square roots, tables) comes precomputed in the planned moves. The
tests prove that this loop and the vectorised closed forms give identical traces;
the firmware ports this file.
"""

from __future__ import annotations

from typing import Sequence

from galileo_cnc.machine.arcs import CANON, classify
from galileo_cnc.machine.blocks import ArcMove, Hold, Item, LineMove, Pause, SeekMove
from galileo_cnc.machine.ramps import FRAC_BITS

FRAC_MASK = (1 << FRAC_BITS) - 1
UNKNOWN_LAST = 1 << 62  # a seek's last event is known only when the switch trips


class LineStepper:
    """Bresenham accumulators, one per axis: e += 2d; if e >= 2n: e -= 2n, step."""

    def __init__(self, delta: Sequence[int], n: int, base_sub: int):
        self.inc = [2 * abs(d) for d in delta]
        self.sign = [1 if d > 0 else -1 for d in delta]
        self.wrap = 2 * n
        self.err = [n, n, n]
        self.base_sub = base_sub
        self.last = n - 1

    def event(self) -> tuple[list[tuple[int, int]], int]:
        steps = []
        for a in (0, 1, 2):
            self.err[a] += self.inc[a]
            if self.err[a] >= self.wrap:
                self.err[a] -= self.wrap
                steps.append((a, self.sign[a]))
        return steps, self.base_sub


class ArcStepper:
    """Midpoint circle stepping on F = x^2 + y^2 - R2, then the end correction line."""

    def __init__(self, move: ArcMove):
        g = move.geom
        self.g = g
        self.ccw = g.ccw
        self.c = [g.start[0], g.start[1]]
        self.f = 0
        self.left_arc = g.n_arc
        self.band = g.band0
        self.band_v = g.band_v
        self.band_base = move.band_base_sub
        self.corr: LineStepper | None = None
        self.last = g.n - 1

    def event(self) -> tuple[list[tuple[int, int]], int]:
        if self.left_arc == 0:
            if self.corr is None:
                assert tuple(self.c) == self.g.p_star
                self.corr = LineStepper((*self.g.correction, 0), self.g.n_corr,
                                        self.band_base[self.band])
            return self.corr.event()
        self.left_arc -= 1
        c = self.c
        maj, sg, mnr, tau = CANON[classify(c[0], c[1], self.ccw), self.ccw]
        v = c[maj] if sg > 0 else -c[maj]
        f_major = self.f + (c[maj] + c[maj] if sg > 0 else -(c[maj] + c[maj])) + 1
        s = -tau if v >= 0 else tau
        f_diag = f_major + (c[mnr] + c[mnr] if s > 0 else -(c[mnr] + c[mnr])) + 1
        steps = [(maj, sg)]
        if abs(f_diag) < abs(f_major):
            c[mnr] += s
            self.f = f_diag
            steps.append((mnr, s))
            if mnr < maj:
                steps.reverse()
        else:
            self.f = f_major
        c[maj] += sg
        key = min(abs(v), abs(v + 1))
        b, bv = self.band, self.band_v
        while b + 1 < len(bv) and key >= bv[b + 1]:
            b += 1
        while key < bv[b]:
            b -= 1
        self.band = b
        return steps, self.band_base[b]


class SeekStepper:
    """Homing seek: step, read the (simulated) switch, trip on N active reads in a row."""

    def __init__(self, move: SeekMove):
        self.m = move
        self.p = move.phys_start
        self.count = 0
        self.k = 0
        self.last = UNKNOWN_LAST

    def event(self) -> tuple[list[tuple[int, int]], int]:
        m = self.m
        self.p += m.direction
        active = (self.p - m.switch_at) * m.direction >= 0
        self.count = self.count + 1 if active else 0
        if self.count == m.debounce_reads:
            self.last = self.k
        self.k += 1
        if self.last == UNKNOWN_LAST and self.k >= m.max_steps:
            raise AssertionError("end-stop not found (the planner should have refused)")
        return [(m.axis, m.direction)], m.base_sub


def _stepper(item):
    if isinstance(item, LineMove):
        return LineStepper(item.delta, item.n, item.base_sub)
    if isinstance(item, ArcMove):
        return ArcStepper(item)
    return SeekStepper(item)


def execute(items: Sequence[Item], t0: int = 0, holds: Sequence[Hold] = (),
            abort_at_tick: int | None = None, starved: Sequence[tuple[int, int]] = ()):
    """Step planned items one event at a time; same result tuple as vector.execute.

    A hold seen at an event with ramp index m stops the machine m events later
    (§6), in this move or, when it ends at a junction speed, in the moves after it:
    `stop_at` is that event's index over the whole job; until it, every event's
    index stays at most its distance to the stop. A starved link (`starved`: the
    event a move ends at, the wait after it) is a stop known in advance: every event
    keeps an index at most its distance to the next such end."""
    pending = sorted([(h.at_tick, 0, h.resume_after_ticks) for h in holds]
                     + ([(abort_at_tick, 1, 0)] if abort_at_tick is not None else []))
    out_tick: list[int] = []
    out_axis: list[int] = []
    out_dir: list[int] = []
    t = t0           # tick of the last event (or the job start)
    pause = 0        # idle time queued before the next run
    aborted = False
    offset = 0       # job-wide index of the item's first event
    stop_at = None   # job-wide index of the event a hold stops at
    stop_aborts, stop_resume = False, 0
    m_left = 0       # ramp index of the last event: the next run enters no higher
    ends, total = set(), 0
    for item in items:
        if not isinstance(item, Pause) and item.n:
            total += item.n
            ends.add(total - 1)
    starving = sorted(s for s in starved if s[0] in ends) + [(1 << 62, 0)]
    for item in items:
        if isinstance(item, Pause):
            pause += item.ticks
            continue
        if item.n == 0:
            continue
        st = _stepper(item)
        first, k = 0, 0
        ramp, step_sub, entry = item.ramp, item.step_sub, item.entry
        while True:  # one run per iteration; a hold splits the move into runs
            start = t + pause
            pause = 0
            while pending and pending[0][0] <= start:
                _at, is_abort, resume = pending.pop(0)
                if is_abort:
                    return _result(out_tick, out_axis, out_dir, start, True)
                start += resume
            last, exit_ = st.last, item.exit
            if stop_at is not None:   # still braking for a hold seen in a move before
                last, exit_, entry = _brake(stop_at - offset, last, exit_, entry, first)
            entry = min(entry, m_left)
            m = min(entry, exit_ + last - first, ramp, starving[0][0] - offset - first)
            ramp_sub, frac, tt = (ramp - m) * step_sub, 0, start
            while True:
                steps, base = st.event()
                if last == UNKNOWN_LAST:
                    last = st.last
                frac += base + ramp_sub
                tt += frac >> FRAC_BITS
                frac &= FRAC_MASK
                for a, d in steps:
                    out_tick.append(tt)
                    out_axis.append(a)
                    out_dir.append(d)
                while pending and pending[0][0] <= tt:
                    _at, is_abort, resume = pending.pop(0)
                    if stop_at is None or offset + k + m < stop_at:
                        stop_at = offset + k + m
                    last, exit_, entry = _brake(stop_at - offset, last, exit_, entry, first)
                    stop_aborts = stop_aborts or bool(is_abort)
                    stop_resume += resume
                if k == last:
                    break
                k += 1
                m_next = min(entry + k - first, exit_ + last - k, ramp,
                             starving[0][0] - offset - k)
                if m_next > m:
                    ramp_sub -= step_sub
                elif m_next < m:
                    ramp_sub += step_sub
                m = m_next
            t, m_left = tt, m
            if offset + k == starving[0][0]:    # the end of what the machine had
                pause += starving.pop(0)[1]
            if stop_at is not None and offset + k == stop_at:
                stop_at = None
                if stop_aborts:
                    aborted = k < st.last or _more_motion(items, item)
                    return _result(out_tick, out_axis, out_dir, t, aborted)
                pause += stop_resume
                stop_resume = 0
            if k == st.last:
                break
            k += 1
            first, entry = k, 0     # a resumed run starts from rest
        offset += st.last + 1
    return _result(out_tick, out_axis, out_dir, t + _tail(items), aborted)


def _brake(stop: int, last: int, exit_: int, entry: int, first: int) -> tuple[int, int, int]:
    """A run's last event, exit and entry index once a hold stops the machine at its
    event `stop` (local index): the run ends there from rest if the stop is in it,
    else its indices stay at most their distance to the stop."""
    if stop <= last:
        return stop, 0, entry
    return last, min(exit_, stop - last), min(entry, stop - first)


def _more_motion(items: Sequence[Item], current: Item) -> bool:
    after = False
    for it in items:
        if it is current:
            after = True
        elif after and not isinstance(it, Pause) and it.n > 0:
            return True
    return False


def _tail(items: Sequence[Item]) -> int:
    """Idle time after the last motion (a trailing dwell)."""
    tail = 0
    for it in reversed(items):
        if isinstance(it, Pause):
            tail += it.ticks
        elif it.n > 0:
            break
    return tail


def _result(ticks, axes, dirs, end, aborted):
    import numpy as np
    return (np.asarray(ticks, dtype=np.int64), np.asarray(axes, dtype=np.int8),
            np.asarray(dirs, dtype=np.int8), int(end), aborted)
