"""How much a planned job draws and travels, from its commands (for info and benches).

Lengths come from the commands' own geometry in steps (an arc by its radius and
sweep), so they are what the machine is asked to do; the step trace differs by the
staircase of line-distance stepping only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from galileo_cnc.job import ArcTo, Flash, Job, LineTo, PenDown, PenUp, Rapid


@dataclass(frozen=True)
class JobLengths:
    drawn_steps: float      # pen-down XY path
    travel_steps: float     # pen-up XY path
    lifts: int              # times the pen goes down to draw (flashes included)


def job_lengths(job: Job, start: tuple[int, int] = (0, 0)) -> JobLengths:
    x, y = start
    down = False
    drawn = travel = 0.0
    lifts = 0
    for command in job.commands:
        if isinstance(command, (Rapid, LineTo)):
            length = math.hypot(command.x_steps - x, command.y_steps - y)
            if isinstance(command, Rapid):
                down = False
            if down:
                drawn += length
            else:
                travel += length
            x, y = command.x_steps, command.y_steps
        elif isinstance(command, ArcTo):
            cx, cy = x + command.i_steps, y + command.j_steps
            radius = math.hypot(x - cx, y - cy)
            a0 = math.atan2(y - cy, x - cx)
            a1 = math.atan2(command.y_steps - cy, command.x_steps - cx)
            sweep = (a0 - a1) if command.cw else (a1 - a0)
            sweep %= 2 * math.pi
            if sweep == 0:
                sweep = 2 * math.pi                  # end == start: a full circle
            length = radius * sweep
            drawn, travel = (drawn + length, travel) if down else (drawn, travel + length)
            x, y = command.x_steps, command.y_steps
        elif isinstance(command, PenDown):
            if not down:
                lifts += 1
            down = True
        elif isinstance(command, PenUp):
            down = False
        elif isinstance(command, Flash):
            lifts += 1
            down = False
    return JobLengths(drawn, travel, lifts)
