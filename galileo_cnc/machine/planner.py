"""The reference machine: executes commands, keeps state, yields the step trace.

State: machine position (steps from power-on or from the last homing), the work
origin, the feed, motor enable, the simulated world (where the end-stops are)
and the clock. Commands are planned into moves once (soft limits are checked
here, before any step of the command); the moves are then stepped by the
vectorised reference or, for cross-checks, by the per-step loop.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Iterable, Sequence

import numpy as np

from galileo_cnc.config.machine import MIN_FEED_STEPS_PER_S, MachineConfig
from galileo_cnc.job import (AXIS_NAMES, ArcTo, Command, Dwell, EndJob, Flash, Home, Jog,
                             LineTo, MachineError, Motors, PenDown, PenUp, Rapid, SetFeed,
                             SetOrigin)
from galileo_cnc.machine import stepper as loop, vector
from galileo_cnc.machine.arcs import MAX_ARC_COORD, arc_setup
from galileo_cnc.command_text import command_text, feed_text, mm_text
from galileo_cnc.machine.blocks import (ArcMove, Hold, Item, LineMove, Pause, SeekMove,
                                        Starved)
from galileo_cnc.machine.junctions import JunctionLimits, plan_junctions
from galileo_cnc.machine.ramps import (FRAC_BITS, TICKS_PER_MS, axial_interval_sub,
                                       line_rho_q15, ramp_events, ramp_step_sub,
                                       weighted_interval_sub)
from galileo_cnc.machine.trace import Trace

BACKENDS = {"numpy": vector.execute, "loop": loop.execute}


class ReferenceMachine:
    """The Python mirror of the firmware (DESIGN.md §2, docs/motion.md)."""

    def __init__(self, config: MachineConfig | None = None,
                 position: tuple[int, int, int] = (0, 0, 0)):
        self.config = config or MachineConfig()
        # looked up for every move: the config works them out from mm on each call
        self._travel = (self.config.travel_min_steps, self.config.travel_max_steps)
        self.position = list(position)          # machine steps
        self.origin = [0, 0, 0]                 # machine steps of work zero
        # Z without an end-stop: its travel floats with the lowest and highest Z
        # planned since power-on and the pen heights (planner.cpp, z_seen)
        self._z_floats = self.config.home_pins[2] == -1
        pens = (self.config.pen_down_z_steps, self.config.pen_up_z_steps)
        self.z_seen = [min(*pens, position[2]), max(*pens, position[2])]
        self.phys_offset = [0, 0, 0]            # simulated world: physical - machine
        self.feed_steps_per_s = self.config.feed_steps_per_s
        self.motors_on = True
        self.ended = False
        self.clock_ticks = 0
        self._index = 0
        self._command: Command | None = None

    # ---- public API -------------------------------------------------------------
    @property
    def work_position(self) -> tuple[int, int, int]:
        p, o = self.position, self.origin
        return (p[0] - o[0], p[1] - o[1], p[2] - o[2])

    def plan(self, commands: Iterable[Command]) -> list[Item]:
        """Turn commands into moves; raises MachineError before any step of a bad one.

        A refused job leaves the machine state as it was (nothing has moved).
        """
        items: list[Item] = []
        saved = self._state()
        try:
            for index, cmd in enumerate(commands):
                self._index, self._command = index, cmd
                if self.ended:
                    raise MachineError(f"command {index} ({cmd}): the job has ended",
                                       index=index)
                handler = _HANDLERS.get(type(cmd))
                if handler is None:
                    raise MachineError(f"command {index}: unknown command {cmd!r}", index=index)
                handler(self, cmd, items)
        except MachineError:
            self._restore(saved)
            raise
        return items

    def plan_speeds(self, items: list[Item]) -> list[Item]:
        """The planned moves with their junction speeds (junctions.py), when the config
        asks for them (junction_deviation_mm > 0, the default); else every move starts
        and ends at rest. The firmware runs the exit indices the streamer sends
        (`exit_indices`)."""
        return plan_junctions(items, JunctionLimits.of(self.config))

    def _state(self) -> tuple:
        return (list(self.position), list(self.origin), list(self.phys_offset),
                self.feed_steps_per_s, self.motors_on, self.ended, list(self.z_seen))

    def _restore(self, state: tuple) -> None:
        (self.position, self.origin, self.phys_offset, self.feed_steps_per_s,
         self.motors_on, self.ended, self.z_seen) = state

    def run(self, commands: Iterable[Command], holds: Sequence[Hold] = (),
            abort_at_tick: int | None = None, backend: str = "numpy",
            starved: Sequence[Starved] = ()) -> Trace:
        """Plan and step `commands`; ticks continue from this machine's clock."""
        commands = list(commands)
        start_state = self._state()
        items = self.plan_speeds(self.plan(commands))
        stops = self._starved_events(commands, start_state, starved) if starved else ()
        tick, axis, direction, end, aborted = BACKENDS[backend](
            items, self.clock_ticks, holds, abort_at_tick, stops)
        self.clock_ticks = end
        if aborted:
            moved = np.bincount(axis, weights=direction, minlength=3).astype(int)
            self.origin = self._origin_when_stopped(commands, start_state,
                                                    events_done=len(np.unique(tick)))
            self.position = [start_state[0][a] + int(moved[a]) for a in range(3)]
        return Trace(tick, axis, direction, self.work_position, end)

    def _starved_events(self, commands: list[Command], start_state: tuple,
                        starved: Sequence[Starved]) -> list[tuple[int, int]]:
        """(event, wait) of each late command: the last event before its first one."""
        probe = ReferenceMachine(self.config)
        probe._restore(tuple(list(v) if isinstance(v, list) else v for v in start_state))
        before = [0]
        for command in commands:
            before.append(before[-1] + sum(item.n for item in probe.plan([command])
                                           if not isinstance(item, Pause)))
        return [(before[late.command] - 1, late.wait_ticks) for late in starved
                if 0 < before[late.command] < before[-1]]

    def _origin_when_stopped(self, commands: list[Command], start_state: tuple,
                             events_done: int) -> list[int]:
        """The work origin as the machine had it when an abort stopped it (§6).

        A SetOrigin is a queued block: it took effect only if every move before it
        ran; the abort drops the rest of the queue. The feed, by contrast, is the
        planner's and stays as the last command received set it (the firmware's
        rule), so it is left as planned.
        """
        probe = ReferenceMachine(self.config)
        probe._restore(tuple(list(v) if isinstance(v, list) else v for v in start_state))
        origin, done = list(start_state[1]), 0
        for command in commands:
            if done >= events_done:
                break
            done += sum(item.n for item in probe.plan([command]) if not isinstance(item, Pause))
            origin = list(probe.origin)
        return origin

    # ---- helpers ----------------------------------------------------------------
    def _mm(self, steps: int) -> str:
        return mm_text(steps, self.config.steps_per_mm)

    def _fail(self, message: str, axis: str = "", limit: int | None = None,
              value: int | None = None) -> MachineError:
        what = command_text(self._command, self.config.steps_per_mm)
        return MachineError(f"command {self._index + 1} ({what}): {message}",
                            axis=axis, limit=limit, index=self._index, value=value)

    def travel_bounds(self, axis: int) -> tuple[int, int]:
        """The travel a move on `axis` is checked against, machine steps: the
        configured one, or for a Z without an end-stop one travel's length around
        every Z planned so far (its travel is a length, not a place)."""
        tmin, tmax = self._travel
        if axis == 2 and self._z_floats:
            span = tmax[2] - tmin[2]
            return self.z_seen[1] - span, self.z_seen[0] + span
        return tmin[axis], tmax[axis]

    def _check_travel(self, lo: Sequence[int], hi: Sequence[int]) -> None:
        """Refuse a move whose visited box [lo, hi] (machine steps) leaves the travel.
        A head outside the travel (a failed or stopped homing) may move back towards
        it, never further out: the travel is widened to where the head stands."""
        for a in range(3):
            tmin, tmax = self.travel_bounds(a)
            here = self.position[a]
            if lo[a] < tmin and lo[a] < here:
                raise self._fail(f"{AXIS_NAMES[a]} would reach {self._mm(lo[a])} "
                                 f"(machine), below the travel's start at "
                                 f"{self._mm(tmin)} [{lo[a]} steps]", AXIS_NAMES[a], tmin, lo[a])
            if hi[a] > tmax and hi[a] > here:
                raise self._fail(f"{AXIS_NAMES[a]} would reach {self._mm(hi[a])} "
                                 f"(machine), beyond the travel's end at "
                                 f"{self._mm(tmax)} [{hi[a]} steps]", AXIS_NAMES[a], tmax, hi[a])

    def _work_to_machine(self, x: int, y: int, z: int | None) -> list[int]:
        o = self.origin
        return [x + o[0], y + o[1], self.position[2] if z is None else z + o[2]]

    def _line(self, target: list[int], feed: int, items: list[Item], ramped: bool = True,
              check: bool = True) -> None:
        if check:
            self._check_travel([min(p, t) for p, t in zip(self.position, target)],
                               [max(p, t) for p, t in zip(self.position, target)])
        delta = (target[0] - self.position[0], target[1] - self.position[1],
                 target[2] - self.position[2])
        n = max(abs(delta[0]), abs(delta[1]), abs(delta[2]))
        if n == 0:
            return
        self.motors_on = True
        cfg = self.config
        base = weighted_interval_sub(axial_interval_sub(feed), line_rho_q15(*delta, n))
        ramp = ramp_events(feed, cfg.accel_steps_per_s2, cfg.ramp_start_factor) if ramped else 0
        items.append(LineMove(tuple(self.position), delta, n, base, ramp,
                              ramp_step_sub(base, ramp, cfg.ramp_start_factor)))
        self.position = list(target)
        self.z_seen = [min(self.z_seen[0], target[2]), max(self.z_seen[1], target[2])]

    def _z_to(self, z_work: int, items: list[Item]) -> None:
        target = list(self.position)
        target[2] = z_work + self.origin[2]
        self._line(target, self.config.z_feed_steps_per_s, items)

    # ---- command handlers ---------------------------------------------------------
    def _rapid(self, cmd: Rapid, items: list[Item]) -> None:
        target = self._work_to_machine(cmd.x_steps, cmd.y_steps, None)
        target[2] = self.config.pen_up_z_steps + self.origin[2]
        self._check_travel([min(p, t) for p, t in zip(self.position, target)],
                           [max(p, t) for p, t in zip(self.position, target)])
        self._z_to(self.config.pen_up_z_steps, items)
        before = len(items)
        self._line(target, self.config.rapid_steps_per_s, items)
        _ends_at_rest(items, before)

    def _line_to(self, cmd: LineTo, items: list[Item]) -> None:
        self._line(self._work_to_machine(cmd.x_steps, cmd.y_steps, cmd.z_steps),
                   self.feed_steps_per_s, items)

    def _arc_to(self, cmd: ArcTo, items: list[Item]) -> None:
        end = self._work_to_machine(cmd.x_steps, cmd.y_steps, None)
        center = (self.position[0] + cmd.i_steps, self.position[1] + cmd.j_steps)
        rel_s = (self.position[0] - center[0], self.position[1] - center[1])
        rel_e = (end[0] - center[0], end[1] - center[1])
        if max(abs(rel_s[0]), abs(rel_s[1]), abs(rel_e[0]), abs(rel_e[1])) > MAX_ARC_COORD:
            raise self._fail(f"arc radius too large (more than "
                             f"{self._mm(MAX_ARC_COORD)} [{MAX_ARC_COORD} steps] from the "
                             f"centre on an axis)")
        geom, (x0, x1, y0, y1) = arc_setup(rel_s, rel_e, not cmd.cw)
        z = self.position[2]
        self._check_travel([x0 + center[0], y0 + center[1], z], [x1 + center[0], y1 + center[1], z])
        if geom.n == 0:
            return
        self.motors_on = True
        cfg = self.config
        axial = axial_interval_sub(self.feed_steps_per_s)
        ramp = ramp_events(self.feed_steps_per_s, cfg.accel_steps_per_s2,
                           cfg.ramp_start_factor)
        # The length scale (§5.3) can take a band below 1 step per event: the
        # minimum step period still bounds the major axis (§5.6).
        floor = cfg.min_step_period_ticks << FRAC_BITS
        items.append(ArcMove(tuple(self.position), center, geom,
                             band_intervals(geom.band_rho, axial, floor),
                             geom.n, ramp, ramp_step_sub(axial, ramp, cfg.ramp_start_factor)))
        self.position = [end[0], end[1], z]

    def _pen_up(self, cmd: PenUp, items: list[Item]) -> None:
        self._z_to(self.config.pen_up_z_steps, items)

    def _pen_down(self, cmd: PenDown, items: list[Item]) -> None:
        self._z_to(self.config.pen_down_z_steps, items)

    def _flash(self, cmd: Flash, items: list[Item]) -> None:
        ms = self.config.flash_dwell_ms if cmd.dwell_ms is None else cmd.dwell_ms
        if ms < 0:
            raise self._fail(f"negative dwell {ms} ms")
        self._z_to(self.config.pen_down_z_steps, items)
        items.append(Pause(ms * TICKS_PER_MS))
        self._z_to(self.config.pen_up_z_steps, items)

    def _dwell(self, cmd: Dwell, items: list[Item]) -> None:
        if cmd.ms < 0:
            raise self._fail(f"negative dwell {cmd.ms} ms")
        items.append(Pause(cmd.ms * TICKS_PER_MS))

    def _set_feed(self, cmd: SetFeed, items: list[Item]) -> None:
        hi = self.config.max_feed_steps_per_s
        if not MIN_FEED_STEPS_PER_S <= cmd.feed_steps_per_s <= hi:
            spm = self.config.steps_per_mm
            raise self._fail(f"feed {feed_text(cmd.feed_steps_per_s, spm)} outside "
                             f"{MIN_FEED_STEPS_PER_S / spm:g} .. {hi / spm:g} mm/s")
        self.feed_steps_per_s = cmd.feed_steps_per_s

    def _jog(self, cmd: Jog, items: list[Item]) -> None:
        p, before = self.position, len(items)
        self._line([p[0] + cmd.dx_steps, p[1] + cmd.dy_steps, p[2] + cmd.dz_steps],
                   self.feed_steps_per_s, items)
        _ends_at_rest(items, before)

    def _set_origin(self, cmd: SetOrigin, items: list[Item]) -> None:
        self.origin = list(self.position)

    def _home(self, cmd: Home, items: list[Item]) -> None:
        cfg = self.config
        base = axial_interval_sub(cfg.home_feed_steps_per_s)
        for a in (2, 0, 1):
            if cfg.home_pins[a] == -1:
                continue
            direction = cfg.home_dirs[a]
            phys = self.position[a] + self.phys_offset[a]
            switch_at = cfg.sim_endstop_steps[a]
            reads = cfg.home_debounce_reads
            if direction * (phys - switch_at) >= 0:
                raise self._fail(f"{AXIS_NAMES[a]} end-stop already active; jog away "
                                 f"before homing", AXIS_NAMES[a])
            span = cfg.travel_max_steps[a] - cfg.travel_min_steps[a]
            max_steps = span + 2 * cfg.home_pulloff_steps + reads
            n = direction * (switch_at - phys) + reads - 1
            if n > max_steps:
                # The machine finds this out at the seek's end: what it stepped until
                # the alarm (sim:// runs it) goes with the refusal.
                items.append(SeekMove(tuple(self.position), a, direction, max_steps, base,
                                      reads, phys, switch_at, max_steps))
                self.position[a] += direction * max_steps
                refused = self._fail(f"{AXIS_NAMES[a]} end-stop not found within "
                                     f"{self._mm(max_steps)} [{max_steps} steps]",
                                     AXIS_NAMES[a])
                refused.moves_until_alarm = list(items)
                refused.state_at_alarm = (tuple(self.position), tuple(self.origin),
                                          tuple(self.phys_offset))
                raise refused
            self.motors_on = True
            items.append(SeekMove(tuple(self.position), a, direction, n, base, reads,
                                  phys, switch_at, max_steps))
            self.position[a] += direction * n
            if cfg.home_pulloff_steps <= reads - 1:
                raise self._fail(f"{AXIS_NAMES[a]} end-stop still active after the "
                                 f"pull-off; raise home_pulloff_steps", AXIS_NAMES[a])
            target = list(self.position)
            target[a] -= direction * cfg.home_pulloff_steps
            self._line(target, cfg.home_feed_steps_per_s, items, ramped=False, check=False)
            self.phys_offset[a] += self.position[a]
            self.position[a] = 0
            self.origin[a] = 0

    def _motors(self, cmd: Motors, items: list[Item]) -> None:
        self.motors_on = bool(cmd.on)

    def _end_job(self, cmd: EndJob, items: list[Item]) -> None:
        self._z_to(self.config.pen_up_z_steps, items)
        self.ended = True


_HANDLERS = {
    Rapid: ReferenceMachine._rapid, LineTo: ReferenceMachine._line_to,
    ArcTo: ReferenceMachine._arc_to, PenUp: ReferenceMachine._pen_up,
    PenDown: ReferenceMachine._pen_down, Flash: ReferenceMachine._flash,
    Dwell: ReferenceMachine._dwell, SetFeed: ReferenceMachine._set_feed,
    Jog: ReferenceMachine._jog, SetOrigin: ReferenceMachine._set_origin,
    Home: ReferenceMachine._home, Motors: ReferenceMachine._motors,
    EndJob: ReferenceMachine._end_job,
}


def simulate(commands: Iterable[Command], config: MachineConfig | None = None,
             holds: Sequence[Hold] = (), abort_at_tick: int | None = None,
             backend: str = "numpy", position: tuple[int, int, int] = (0, 0, 0),
             starved: Sequence[Starved] = ()) -> Trace:
    """Run a job on a fresh reference machine and return its step trace."""
    return ReferenceMachine(config, position).run(commands, holds, abort_at_tick, backend,
                                                  starved)


def _ends_at_rest(items: list[Item], before: int) -> None:
    """A Rapid's or Jog's line (appended after `before`): the wire carries no exit
    index for it (docs/motion.md §5.7), so no junction speed at its end."""
    if len(items) > before and isinstance(items[-1], LineMove):
        from dataclasses import replace
        items[-1] = replace(items[-1], to_rest=True)


def exit_indices(commands: Iterable[Command], config: MachineConfig | None = None,
                 position: tuple[int, int, int] = (0, 0, 0)) -> list[int | None]:
    """Per command, the exit index of its last move where the config plans junction
    speeds and it is above 0 (docs/motion.md §5.7), else None: what LineTo's and
    ArcTo's `exit_index` carry on the wire. The reference plans the same indices."""
    commands = list(commands)
    machine = ReferenceMachine(config, position)
    if not JunctionLimits.of(machine.config).enabled:
        return [None] * len(commands)
    spans, items = [], []
    for cmd in commands:
        planned = machine.plan([cmd])
        spans.append((len(items), len(items) + len(planned)))
        items += planned
    items = machine.plan_speeds(items)
    out: list[int | None] = []
    for cmd, (lo, hi) in zip(commands, spans):
        moves = [it for it in items[lo:hi] if not isinstance(it, Pause) and it.n]
        blended = isinstance(cmd, (LineTo, ArcTo)) and moves and moves[-1].exit > 0
        out.append(moves[-1].exit if blended else None)
    return out


def with_exit_indices(commands: Iterable[Command], config: MachineConfig | None = None,
                      position: tuple[int, int, int] = (0, 0, 0)) -> list[Command]:
    """The commands with their planned exit indices set (`exit_indices`)."""
    from dataclasses import replace
    commands = list(commands)
    return [cmd if e is None else replace(cmd, exit_index=e)
            for cmd, e in zip(commands, exit_indices(commands, config, position))]


class JobSteps:
    """A job's step trace produced piece by piece as it is read, for readers that
    walk it in order (previews): memory stays one piece's, however long the job.
    Each reading steps the job again on a fresh reference machine."""

    def __init__(self, commands: Iterable[Command], config: MachineConfig | None = None,
                 position: tuple[int, int, int] = (0, 0, 0)):
        self.config = config or MachineConfig()
        self.position = position
        machine = ReferenceMachine(self.config, position)
        self.items = machine.plan_speeds(machine.plan(list(commands)))

    def pieces(self, size: int = 0):
        """(tick, axis, dir) of whole items in time order (`size` is the Trace's hint;
        pieces here follow the vectorised reference's own chunks)."""
        yield from vector.execute_in_pieces(self.items, [0])


def estimate_seconds(commands: Iterable[Command], config: MachineConfig | None = None) -> float:
    """Job duration from the same computation that makes the trace."""
    return simulate(commands, config).seconds


@lru_cache(maxsize=1 << 13)
def band_intervals(band_rho: tuple[int, ...], axial_sub: int, floor_sub: int) -> tuple[int, ...]:
    """The subticks per event of each band of an arc at one feed, never below the
    minimum step period: kept, as arc_setup is (the same arc shapes at the same feed
    recur thousands of times in an inked job; a fifth of its timing was this)."""
    return tuple(max(weighted_interval_sub(axial_sub, r), floor_sub) for r in band_rho)
