"""Time in the simulated machine: its clock and the timeline of planned steps.

`SimClock` follows wall time `speed` times faster (speed 0: the instant machine).
`Timeline` turns planned items into step events with the reference machine's own
timing (machine/vector.py, machine/ramps.py): a block queued while others run
starts where the previous one ends, so a host that keeps the queue full gets
exactly the reference's ticks; holds and aborts are the reference's
`apply_holds` at the tick they arrive. docs/sim.md describes the design.
"""

from __future__ import annotations

import bisect
import time
from dataclasses import replace
from typing import Sequence

import numpy as np

from galileo_cnc.config.hardware import TICKS_PER_S
from galileo_cnc.machine import Hold
from galileo_cnc.machine import vector
from galileo_cnc.machine.ramps import Run, run_ticks


# ---- time ---------------------------------------------------------------------------
class SimClock:
    """The machine's clock in Timer ticks since power-on.

    It follows wall time `speed` times faster; speed 0 is the instant machine,
    whose `now()` is None: "as late as needed", every scheduled step is done.
    Floats appear only here, where wall time becomes ticks.
    """

    def __init__(self, speed: float = 1.0):
        self.speed = speed
        self._wall0 = time.monotonic()

    @property
    def instant(self) -> bool:
        return self.speed == 0

    def now(self) -> int | None:
        if self.instant:
            return None
        return int((time.monotonic() - self._wall0) * self.speed * TICKS_PER_S)

    def seconds_until(self, tick: int) -> float:
        """Wall seconds until the clock reaches `tick` (0 if it has)."""
        due = self._wall0 + tick / (self.speed * TICKS_PER_S)
        return max(0.0, due - time.monotonic())


# ---- steps in time --------------------------------------------------------------------
class Timeline:
    """The step events the machine executes, with absolute ticks.

    Planned items become runs of events exactly as in the reference
    (`vector.build_events`, `ramps.run_ticks`), so a job streamed without a
    break has the reference's ticks. A feed hold re-times the runs with the
    reference's `apply_holds` (docs/motion.md §6): first as an abort at the hold
    tick (where the machine stops), then, on resume, as a hold whose pause ends
    at the resume tick. Events are numbered from power-on; events of blocks that
    have finished are trimmed into step rows so the arrays stay the queue's size.
    """

    def __init__(self):
        self._done: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._first = 0                     # number of the first kept event
        self._t0 = 0                        # tick the kept runs count from
        self._table = np.zeros((0, 3), dtype=np.int8)
        self._base = np.zeros(0, dtype=np.int64)
        self._ticks = np.zeros(0, dtype=np.int64)
        self._runs: list[Run] = []
        self._tail = 0                      # idle ticks after the last run (a dwell)
        self._end = 0                       # when the last scheduled item ends
        self._live = 0                      # kept events whose ticks are final
        self._hold: tuple[int, int, list[Run]] | None = None   # (at, stop, runs to the stop)
        self._planned: list[tuple[int, int]] = []   # (run, planned exit) capped at the queue end
        self._exit_m = 0                    # ramp index of the last scheduled event

    @property
    def count(self) -> int:
        """Events numbered so far (the next event's number)."""
        return self._first + len(self._base)

    @property
    def end(self) -> int:
        return self._end

    @property
    def held(self) -> bool:
        return self._hold is not None

    @property
    def stop(self) -> int:
        """Where a hold stops the machine (after its deceleration)."""
        assert self._hold is not None
        return self._hold[1]

    def append(self, items: Sequence, not_before: int | None) -> tuple[int, int]:
        """Schedule a block's items after the last one, not before `not_before`.

        An idle machine starts a new block when it is queued: the gap becomes
        part of the pause in front of its first run. Returns (number of its
        first event, tick at which it ends).
        """
        assert self._hold is None, "blocks queued during a hold are scheduled on resume"
        table, base, runs, tail = vector.build_events(items)
        gap = 0 if not_before is None else max(0, not_before - self._end)
        first = self.count
        if (runs and (self._exit_m or self._planned) and self._tail == 0 and gap == 0
                and runs[0].pause_ticks == 0):
            runs[0] = replace(runs[0], entry=self._enter(not_before))
        if runs:
            runs[0] = replace(runs[0], pause_ticks=runs[0].pause_ticks + self._tail + gap)
            ticks, _starts, end = run_ticks(base, runs, self._end - self._tail, tail)
            n = len(self._base)
            self._runs += [replace(r, first=r.first + n, last=r.last + n) for r in runs]
            self._table = np.concatenate((self._table, table))
            self._base = np.concatenate((self._base, base))
            self._ticks = np.concatenate((self._ticks, ticks))
            self._tail = tail
            if not_before is not None:      # an instant clock: the host is never late
                end = self._bound_to_the_queue_end(end)
            self._exit_m = self._last_index()
        else:
            self._tail += gap + tail
            end = self._end + gap + tail
        self._end = end
        self._live = len(self._base)
        return first, end

    # ---- never overrun (docs/motion.md §5.7): the firmware's index stays at most the
    # events left to the end of what its queue holds; once that bounds it, the machine
    # has committed to stopping there.
    def _bound_to_the_queue_end(self, end: int) -> int:
        """Cap the exits of the last runs so the machine stops at the last event queued;
        the planned exits are kept to restore if the next block comes in time."""
        last = self._runs[-1].last
        self._planned = []
        for i in range(len(self._runs) - 1, -1, -1):
            run = self._runs[i]
            cap = last - run.last
            if run.exit <= cap:
                break
            self._planned.append((i, run.exit))
            self._runs[i] = replace(run, exit=cap)
            if run.pause_ticks:
                break
        if not self._planned:
            return end
        return self._retime()

    def _retime(self) -> int:
        ticks, _starts, end = run_ticks(self._base, self._runs, self._t0, self._tail)
        self._ticks = ticks
        return end

    def _enter(self, now: int | None) -> int:
        """The entry index of a block queued after the last run, at tick `now`: the
        index the last event runs at. The planned exits come back if the machine had
        not begun to brake for the end of its queue by then (else it stops there, and
        the block starts from rest)."""
        planned = self._planned
        if planned:
            bounded = self._ticks.copy()
            for i, exit_ in planned:
                self._runs[i] = replace(self._runs[i], exit=exit_)
            free_end = self._retime()
            differ = np.flatnonzero(bounded != self._ticks)
            if len(differ) and now is not None and bounded[max(0, differ[0] - 1)] <= now:
                for i, _exit in planned:     # committed: keep braking to the stop
                    self._runs[i] = replace(self._runs[i], exit=min(
                        self._runs[i].exit, self._runs[-1].last - self._runs[i].last))
                self._retime()
                self._planned = []
                return 0
            self._end = free_end
            self._planned = []
            self._exit_m = self._last_index()
        return self._exit_m

    def _last_index(self) -> int:
        if not self._runs or self._tail:
            return 0
        run = self._runs[-1]
        return min(run.exit, run.entry + run.last - run.first, run.ramp)

    def hold(self, at: int) -> int:
        """A feed hold raised at tick `at`: decelerate and stop; returns the stop tick."""
        self._planned = []                   # a hold re-times (and splits) the runs
        ticks, runs, stop, n_done = vector.apply_holds(
            self._base, self._runs, self._tail, self._t0, (), at)
        self._ticks[:n_done] = ticks[:n_done]       # the deceleration re-times the last run
        self._live = n_done
        self._hold = (at, stop, runs)
        return stop

    def resume(self, at: int | None) -> tuple[int, int]:
        """Resume at tick `at` (None: at once) with a fresh ramp.

        Returns (stop tick, shift): everything that ended after the stop now
        ends `shift` ticks later.
        """
        hold_at, stop, _runs = self._hold
        pause = 0 if at is None else max(0, at - stop)
        ticks, runs, end, _n = vector.apply_holds(
            self._base, self._runs, self._tail, self._t0, [Hold(hold_at, pause)], None)
        shift = end - self._end
        self._ticks, self._runs, self._end = ticks, runs, end
        self._live = len(self._base)
        self._hold = None
        self._exit_m = self._last_index()
        return stop, shift

    def abort(self) -> None:
        """Make the hold's stop final: the events after it are dropped."""
        _at, stop, runs = self._hold
        n = self._live
        self._table, self._base, self._ticks = self._table[:n], self._base[:n], self._ticks[:n]
        self._runs = list(runs)
        last_run_end = int(self._ticks[runs[-1].last]) if runs else self._t0
        self._tail = stop - last_run_end
        self._end = stop
        self._hold = None
        self._exit_m = 0

    def executed(self, now: int | None) -> int:
        """Number of the first event not yet executed at tick `now`."""
        live = self._ticks[:self._live]
        k = self._live if now is None else int(np.searchsorted(live, now, side="right"))
        return self._first + k

    def displacement(self, first: int, end: int) -> np.ndarray:
        """Net steps per axis of events [first, end)."""
        rows = self._table[first - self._first:end - self._first]
        return np.sign(rows).sum(axis=0, dtype=np.int64)

    def trim(self, keep_from: int) -> None:
        """Turn the runs before event `keep_from` (finished blocks) into step rows."""
        if self._hold is not None:
            return                          # runs are about to be re-timed
        lasts = [r.last for r in self._runs]
        idx = bisect.bisect_left(lasts, keep_from - self._first)
        if idx == 0:
            return
        cut = self._runs[idx - 1].last + 1
        self._done.append(vector.step_rows(self._table[:cut], self._ticks[:cut]))
        self._t0 = int(self._ticks[cut - 1])    # the end of the last trimmed run
        self._table, self._base = self._table[cut:], self._base[cut:]
        self._ticks = self._ticks[cut:]
        self._runs = [replace(r, first=r.first - cut, last=r.last - cut)
                      for r in self._runs[idx:]]
        self._planned = [(i - idx, e) for i, e in self._planned if i >= idx]
        self._first += cut
        self._live -= cut

    def steps(self, now: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(tick, axis, dir) of every step executed by tick `now`."""
        k = self.executed(now) - self._first
        parts = self._done + [vector.step_rows(self._table[:k], self._ticks[:k])]
        return tuple(np.concatenate([p[i] for p in parts]) for i in range(3))
