"""Planned moves: the per-move setup both step generators execute.

The machine turns commands into these records once (docs/motion.md §2, the
"setup" column): integer geometry, cruise intervals and ramp parameters. The
vectorised reference (vector.py) and the per-step loop (loop.py, the firmware's
form) both take them as input, so they can only differ in how they step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

from galileo_cnc.machine.arcs import ArcGeometry


@dataclass(frozen=True, slots=True)
class LineMove:
    """Straight move; every event has the same cruise interval `base_sub`."""

    start: tuple[int, int, int]      # machine steps
    delta: tuple[int, int, int]
    n: int                           # events = max |delta|
    base_sub: int                    # subticks per event at cruise
    ramp: int                        # R, events
    step_sub: int                    # interval change per ramp event, subticks
    entry: int = 0                   # ramp index of the first event (0: from rest, §5.7)
    exit: int = 0                    # ramp index of the last event (0: to rest)
    to_rest: bool = False            # its command carries no exit index (Rapid, Jog)


@dataclass(frozen=True, slots=True)
class ArcMove:
    """Arc in XY (then the end correction); cruise interval per timing band."""

    start: tuple[int, int, int]
    center: tuple[int, int]          # machine steps
    geom: ArcGeometry
    band_base_sub: tuple[int, ...]   # subticks per event, per compact band
    n: int
    ramp: int
    step_sub: int
    entry: int = 0
    exit: int = 0


@dataclass(frozen=True, slots=True)
class SeekMove:
    """Homing seek: constant interval, stops on the debounced end-stop."""

    start: tuple[int, int, int]
    axis: int
    direction: int
    n: int                           # closed form: steps until tripped
    base_sub: int
    debounce_reads: int
    phys_start: int                  # simulated world: physical axis position
    switch_at: int                   # switch reads active when dir*(p - switch_at) >= 0
    max_steps: int
    ramp: int = 0
    step_sub: int = 0
    entry: int = 0
    exit: int = 0


@dataclass(frozen=True, slots=True)
class Pause:
    """Idle time (dwell, flash dwell)."""

    ticks: int


@dataclass(frozen=True, slots=True)
class Hold:
    """A feed hold raised at `at_tick`; motion resumes `resume_after_ticks` after the stop."""

    at_tick: int
    resume_after_ticks: int = 0


@dataclass(frozen=True, slots=True)
class Starved:
    """Command `command` (its index in the run) reaches the machine late: the link
    starved. The machine brakes where it must to stop at the end of the moves before
    it (never overrunning what it has), stands `wait_ticks`, then starts the command
    from rest (docs/motion.md §5.7)."""

    command: int
    wait_ticks: int = 0


Motion = Union[LineMove, ArcMove, SeekMove]
Item = Union[LineMove, ArcMove, SeekMove, Pause]
