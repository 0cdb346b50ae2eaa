"""The vectorised reference: closed forms over whole jobs with numpy.

Geometry (which axes step at each event) and timing (when each event fires) are
separate: a feed hold only changes the timing, never the steps (§6).
"""

from __future__ import annotations

from bisect import bisect_left
from dataclasses import replace
from functools import lru_cache
from typing import Sequence

import numpy as np

from galileo_cnc.machine.arcs import arc_points, arc_setup
from galileo_cnc.machine.blocks import ArcMove, Hold, Item, LineMove, Pause, SeekMove
from galileo_cnc.machine.lines import bresenham_points, fill_line_steps
from galileo_cnc.machine.ramps import FRAC_BITS, Run, ramp_sum, run_ticks


def build_events(items: Sequence[Item]) -> tuple[np.ndarray, np.ndarray, list[Run], int]:
    """Step table (N x 3 int8, dir * (axis + 1)), cruise interval per event, runs, tail."""
    motions: list = []
    runs: list[Run] = []
    pause = 0
    offset = 0
    for item in items:
        if isinstance(item, Pause):
            pause += item.ticks
            continue
        if item.n == 0:
            continue
        motions.append((offset, item))
        runs.append(Run(offset, offset + item.n - 1, item.ramp, item.step_sub, pause,
                        item.entry, item.exit))
        pause = 0
        offset += item.n
    n_events = offset
    count = len(motions)
    is_arc = np.fromiter((isinstance(it, ArcMove) for _o, it in motions), bool, count)
    base_move = np.fromiter((0 if isinstance(it, ArcMove) else it.base_sub
                             for _o, it in motions), np.int64, count)
    n_move = np.fromiter((it.n for _o, it in motions), np.int64, count)
    first = np.fromiter((o for o, _it in motions), np.int64, count)
    delta = np.array([(0, 0, 0) if isinstance(it, ArcMove) else _delta(it)
                      for _o, it in motions], dtype=np.int64).reshape(-1, 3)
    base = np.repeat(base_move, n_move)
    table = np.empty((n_events, 3), dtype=np.int8)
    # Major axes step at every event of their line: one repeat per column.
    for axis in range(3):
        d = delta[:, axis]
        major = (np.abs(d) == n_move) & ~is_arc
        code = (np.sign(d) * major * (axis + 1)).astype(np.int8)
        table[:, axis] = np.repeat(code, n_move)
    lines = ~is_arc
    fill_line_steps(table, first[lines], n_move[lines], delta[lines])
    for o, it in motions:
        if isinstance(it, ArcMove):
            _fill_arc(table, base, o, it)
    return table, base, runs, pause


def _delta(item: LineMove | SeekMove) -> tuple[int, int, int]:
    if isinstance(item, SeekMove):
        d = [0, 0, 0]
        d[item.axis] = item.direction * item.n
        return d[0], d[1], d[2]
    return item.delta


def _fill_arc(table: np.ndarray, base: np.ndarray, offset: int, move: ArcMove) -> None:
    g = move.geom
    pts, keys = arc_points(g)
    corr = bresenham_points(g.p_star, g.correction)
    allp = np.empty((g.n + 1, 2), dtype=np.int64)
    allp[0] = g.start
    allp[1:g.n_arc + 1] = pts
    allp[g.n_arc + 1:] = corr
    steps = np.diff(allp, axis=0)
    steps[:, 1] *= 2
    table[offset:offset + g.n, :2] = steps
    table[offset:offset + g.n, 2] = 0
    base[offset:offset + g.n] = _arc_bases(move, keys)


def _arc_bases(move: ArcMove, keys: np.ndarray) -> np.ndarray:
    """The cruise interval of each of the arc's events: its band's along the arc (by
    each point's key), the last band's through the end correction."""
    return np.asarray(move.band_base_sub, dtype=np.int64)[_event_bands(move.geom, keys)]


def _event_bands(g, keys: np.ndarray) -> np.ndarray:
    """The band of each of the arc's events (see _arc_bases)."""
    if not g.n_arc:
        return np.zeros(g.n, dtype=np.int64)
    band = np.searchsorted(np.asarray(g.band_v), keys, side="right") - 1
    return np.concatenate([band, np.full(g.n - g.n_arc, band[-1])])


@lru_cache(maxsize=1 << 13)
def _band_counts(start: tuple[int, int], end: tuple[int, int], ccw: bool) -> np.ndarray:
    """Events per band of the arc (relative to its centre): all the sum of its
    intervals needs of its points; kept, as arcs repeat (arcs.arc_setup)."""
    g = arc_setup(start, end, ccw)[0]
    return np.bincount(_event_bands(g, arc_points(g)[1]), minlength=len(g.band_v))


def last_event_ticks(items: Sequence[Item], t0: int = 0) -> tuple[np.ndarray, int]:
    """The tick of each item's last step event (-1 for a pause or an item without
    steps), and the end tick: the ticks of `execute`'s trace, without making it.

    A run's events fire at (256 * start + running interval sum) >> 8 (run_ticks), so
    its last one fires at start + (sum of its intervals >> 8); the sum is the events'
    cruise intervals plus step_sub * ramp_sum. Only an arc's intervals need its points
    (each point's band); a line's are n * base. job_timing wants only these ticks:
    stepping hellboard's job for them took 7.7 s of the 21 s its timing took."""
    last = np.full(len(items), -1, dtype=np.int64)
    moving, sums, pauses = [], [], []
    pause = 0
    for index, item in enumerate(items):
        if isinstance(item, Pause):
            pause += item.ticks
            continue
        if item.n == 0:
            continue
        if isinstance(item, ArcMove):
            g = item.geom
            bases = int(_band_counts(g.start, g.end, g.ccw)
                        @ np.asarray(item.band_base_sub, dtype=np.int64))
        else:
            bases = item.n * item.base_sub
        moving.append(index)
        sums.append(bases + item.step_sub * ramp_sum(item.n, item.ramp, item.entry, item.exit))
        pauses.append(pause)
        pause = 0
    if not moving:
        return last, t0 + pause
    duration = np.array(sums, dtype=np.int64) >> FRAC_BITS
    starts = t0 + np.cumsum(pauses) + np.concatenate(([0], np.cumsum(duration)[:-1]))
    last[moving] = starts + duration
    return last, int(starts[-1] + duration[-1]) + pause


def apply_starving(runs: list[Run], stops: Sequence[tuple[int, int]]) -> list[Run]:
    """The runs when the link starves (§5.7): for each (event, wait), the machine stops
    at that event, the end of what it has, and waits. Every event before it keeps an
    index at most its distance to the stop (the braking starts where it must), the
    run that ends there leaves at rest, the next one starts `wait` ticks later."""
    runs = list(runs)
    lasts = [r.last for r in runs]
    for stop, wait in stops:
        q = bisect_left(lasts, stop)
        if q == len(runs) or runs[q].last != stop:
            continue              # not the end of a move: nothing to stop for
        while q >= 0 and stop - runs[q].last <= runs[q].ramp:   # within a ramp of it
            braking = runs[q]
            runs[q] = replace(braking, exit=min(braking.exit, stop - braking.last),
                              entry=min(braking.entry, stop - braking.first))
            q -= 1
        after = bisect_left(lasts, stop + 1)
        if after < len(runs):
            runs[after] = replace(runs[after], pause_ticks=runs[after].pause_ticks + wait)
    _enter_at_most_the_exit(runs)
    return runs


def apply_holds(base: np.ndarray, runs: list[Run], tail: int, t0: int,
                holds: Sequence[Hold], abort_at_tick: int | None):
    """Timing with holds and an abort (§6). Returns ticks, runs, end, stop event."""
    runs = list(runs)
    events: list[tuple[int, int, int]] = [(h.at_tick, 0, h.resume_after_ticks) for h in holds]
    if abort_at_tick is not None:
        events.append((abort_at_tick, 1, 0))
    events.sort()
    for at_tick, is_abort, resume in events:
        ticks, starts, end = run_ticks(base, runs, t0, tail)
        last_ticks = np.array([ticks[r.last] for r in runs], dtype=np.int64)
        r = int(np.searchsorted(last_ticks, at_tick, side="left"))
        if r == len(runs):
            continue  # after the last step: nothing left to hold
        run = runs[r]
        start = int(starts[r])
        if at_tick <= start:  # before the run began: stop at its start
            stop_tick = start
            if is_abort:
                return _abort(base, runs[:r], t0, stop_tick)
            runs[r] = replace(run, pause_ticks=run.pause_ticks + resume)
            continue
        seg = ticks[run.first:run.last + 1]
        k = run.first + int(np.searchsorted(seg, at_tick, side="left"))
        stop = k + min(run.entry + k - run.first, run.exit + run.last - k, run.ramp)
        # Brake: a run ending at a junction speed carries the braking into the next
        # ones; every event stays at most its distance to the stop (§6, §5.7).
        q = r
        while runs[q].last < stop:
            braking = runs[q]
            runs[q] = replace(braking, exit=min(braking.exit, stop - braking.last),
                              entry=braking.entry if q == r
                              else min(braking.entry, stop - braking.first))
            q += 1
        run = runs[q]
        head = replace(run, last=stop, exit=0,
                       entry=run.entry if q == r else min(run.entry, stop - run.first))
        if is_abort:
            t2, _s, _e = run_ticks(base, runs[:q] + [head], t0, 0)
            return _abort(base, runs[:q] + [head], t0, int(t2[stop]))
        if stop == run.last:    # the run's own end: the resume delays the next run
            runs[q] = head
            _enter_at_most_the_exit(runs)
            if q + 1 < len(runs):
                nxt = runs[q + 1]
                runs[q + 1] = replace(nxt, pause_ticks=nxt.pause_ticks + resume)
            continue
        runs[q:q + 1] = [head, Run(stop + 1, run.last, run.ramp, run.step_sub, resume,
                                   0, run.exit)]
        _enter_at_most_the_exit(runs)
    ticks, _starts, end = run_ticks(base, runs, t0, tail)
    return ticks, runs, end, len(base)


def _enter_at_most_the_exit(runs: list[Run]) -> None:
    """A run enters at no higher index than the run before it left at (§5.7): after a
    stop the rest of a move starts from rest and may not reach its planned exit, so the
    moves after it enter lower. The index then still changes by at most one per event."""
    for i in range(1, len(runs)):
        before = runs[i - 1]
        left = min(before.entry + before.last - before.first, before.exit, before.ramp)
        if runs[i].entry > left:
            runs[i] = replace(runs[i], entry=left)


def _abort(base, runs, t0, stop_tick):
    n_done = runs[-1].last + 1 if runs else 0
    ticks, _s, _e = run_ticks(base[:n_done], runs, t0, 0)
    return ticks, runs, stop_tick, n_done


#: Events per chunk: the working arrays of a chunk stay in the CPU cache.
CHUNK_EVENTS = 1 << 20


def execute(items: Sequence[Item], t0: int = 0, holds: Sequence[Hold] = (),
            abort_at_tick: int | None = None, starved: Sequence[tuple[int, int]] = ()):
    """Run planned items; returns (tick, axis, dir, end_tick, aborted_early).
    `starved`: (event, wait) pairs, apply_starving's."""
    if holds or abort_at_tick is not None or starved:
        table, base, runs, tail = build_events(items)
        runs = apply_starving(runs, starved)
        ticks, runs, end, n_done = apply_holds(base, runs, tail, t0, holds, abort_at_tick)
        tick, axis, direction = step_rows(table[:n_done], ticks[:n_done])
        return tick, axis, direction, end, n_done < len(base)
    clock = [t0]
    parts = list(execute_in_pieces(items, clock))
    end = clock[0]
    if not parts:
        empty = np.zeros(0, dtype=np.int8)
        return np.zeros(0, dtype=np.int64), empty, empty, end, False
    if len(parts) == 1:
        return (*parts[0], end, False)
    return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
            np.concatenate([p[2] for p in parts]), end, False)


def execute_in_pieces(items: Sequence[Item], clock: list[int]):
    """(tick, axis, dir) of runs of whole items (about CHUNK_EVENTS events each), in
    order; `clock[0]` is the start tick and, once the pieces are consumed, the end.
    Memory stays that of one piece, however long the job."""
    for chunk in _chunks(items):
        table, base, runs, tail = build_events(chunk)
        ticks, _starts, clock[0] = run_ticks(base, runs, clock[0], tail, inplace=True)
        yield step_rows(table, ticks)


def _chunks(items: Sequence[Item]):
    start, events = 0, 0
    for i, item in enumerate(items):
        if not isinstance(item, Pause):
            events += item.n
            if events >= CHUNK_EVENTS:
                yield items[start:i + 1]
                start, events = i + 1, 0
    if start < len(items):
        yield items[start:]


def step_rows(table: np.ndarray, ticks: np.ndarray):
    """Rows in (event, axis) order: tick, axis, dir."""
    stepped = table != 0
    codes = table[stepped]
    per_event = stepped.view(np.uint8)
    count = per_event[:, 0] + per_event[:, 1] + per_event[:, 2]
    tick = np.repeat(ticks, count)
    return tick, np.abs(codes) - 1, np.sign(codes)
