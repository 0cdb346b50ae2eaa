"""Job time from the reference machine: the progress bar's ETA and `plot`'s estimate.

The times are those of the trace itself (docs/motion.md): each command is planned
and stepped on the reference machine, so `end_ticks[k]` is the machine clock when
command k has finished on a machine that never waits for the host.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import MachineConfig
from .machine import TICKS_PER_S, ReferenceMachine, simulate
from .machine import vector

#: Above this many commands the per-command walk costs seconds; the ETA then
#: spreads the whole job's time evenly over its commands.
PER_COMMAND_LIMIT = 20_000


@dataclass(frozen=True, slots=True)
class JobTiming:
    end_ticks: np.ndarray        # int64, machine clock after each command

    @property
    def total_s(self) -> float:
        return int(self.end_ticks[-1]) / TICKS_PER_S if len(self.end_ticks) else 0.0

    def remaining_s(self, done: int) -> float:
        """Machine time left once commands 0..done-1 have run."""
        if done <= 0:
            return self.total_s
        return self.total_s - int(self.end_ticks[min(done, len(self.end_ticks)) - 1]) / TICKS_PER_S

    def seconds_between(self, first: int, end: int) -> float:
        """Machine time of commands first..end-1."""
        before = int(self.end_ticks[first - 1]) if first > 0 else 0
        return (int(self.end_ticks[end - 1]) - before) / TICKS_PER_S if end > first else 0.0


def job_timing(commands, config: MachineConfig | None = None,
               position: tuple[int, int, int] = (0, 0, 0)) -> JobTiming:
    commands = list(commands)
    if len(commands) > PER_COMMAND_LIMIT:
        total = simulate(commands, config, position=position).total_ticks
        spread = np.arange(1, len(commands) + 1, dtype=np.int64) * total // len(commands)
        return JobTiming(spread)
    machine = ReferenceMachine(config, position)
    ends = np.empty(len(commands), dtype=np.int64)
    clock = 0
    for k, command in enumerate(commands):
        items = machine.plan([command])
        if items:
            clock = vector.execute(items, clock)[3]
        ends[k] = clock
    return JobTiming(ends)


def duration_text(seconds: float) -> str:
    """1:05, or 1:02:05 past an hour."""
    whole = int(round(seconds))
    hours, rest = divmod(whole, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"
