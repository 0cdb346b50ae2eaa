"""Job time from the reference machine: the progress bar's ETA and `plot`'s estimate.

The times are those of the trace itself (docs/motion.md): the job is planned and
stepped on the reference machine, so `end_ticks[k]` is the machine clock when
command k has finished on a machine that never waits for the host, with the junction
speeds the config asks for planned over the whole job (junctions.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from galileo_cnc.config.hardware import TICKS_PER_S
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine import ReferenceMachine
from galileo_cnc.machine import vector

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
    """The job planned on the reference machine; command k ends with its last step
    event, at the tick the trace gives it (vector.last_event_ticks: the ticks alone,
    not the steps). A command without steps (a dwell, a feed) ends where the one
    before it did; its time shows up in the next moving command. The total is exact.
    """
    commands = list(commands)
    machine = ReferenceMachine(config, position)
    items, owner = [], []
    for k, command in enumerate(commands):
        planned = machine.plan([command])
        items.extend(planned)
        owner.extend([k] * len(planned))
    last, end = vector.last_event_ticks(machine.plan_speeds(items), 0)
    ends = np.zeros(len(commands), dtype=np.int64)
    np.maximum.at(ends, np.asarray(owner, dtype=np.int64), last)   # no steps: 0
    np.maximum.accumulate(ends, out=ends)      # ticks only grow: the last event so far
    if len(ends):
        ends[-1] = end
    return JobTiming(ends)


def duration_text(seconds: float) -> str:
    """1:05, or 1:02:05 past an hour."""
    whole = int(round(seconds))
    hours, rest = divmod(whole, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"
