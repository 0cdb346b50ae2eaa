"""What a job drew, whatever the order: the set of XY points where a step left the
head at the drawing height. A stopped and resumed job retraces part of a command
and travels pen up to it, so its trace differs from an uninterrupted one, but the
points it inked must be exactly the same."""

from __future__ import annotations

from galileo_cnc.config.machine import MachineConfig


def inked_points(trace, config: MachineConfig | None = None,
                 start: tuple[int, int, int] = (0, 0, 0)) -> set[tuple[int, int]]:
    config = config or MachineConfig()
    where = trace.positions(start)
    down = where[:, 2] == config.pen_down_z_steps
    return set(map(tuple, where[down, :2].tolist()))
