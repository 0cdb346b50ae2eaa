"""The head path of a job from its commands, for `galileo-cnc preview`: what the
reference machine steps, to within a step, without planning or stepping it.

The commands are in steps already; the machine moves a line from step to step
within a step of the straight line between them, and an arc within half a step of
its circle (machine/arcs.py), then straight to the end. So the path here is the
commands' end points, Z as one event per pen move, and each arc as points within
a quarter step of its circle: a preview at 20 px/mm (8 steps a pixel at 160
steps/mm) differs from the stepped one only in pixels an edge grazes.

It reads as a step trace does in preview/render.py (`events`: the head position
after each event, event 0 the start), and knows where each command starts, so
which pen draws when needs no planning either (`pen_stretches`). Stepping the
job instead costs some 30 s of CPU on a 1 MB board (docs/preview.md, "Cost").
"""

from __future__ import annotations

import math
from typing import Iterator

import numpy as np

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import (ArcTo, Command, EndJob, Flash, Home, Jog, LineTo, PenDown,
                             PenUp, Rapid, SetOrigin)

#: Events per chunk handed to the preview (as many as the step trace's chunks).
CHUNK_EVENTS = 1 << 17
#: The largest distance (steps) between an arc's chord and its circle.
ARC_SAGITTA_STEPS = 0.25
#: A line that moves Z and XY together is cut into pieces of at most this many
#: steps, so the pen touches down where the machine's does, to this much.
PLUNGE_PIECE_STEPS = 8


class JobPath:
    """A job's head path as the preview reads a step trace (`events`), from the
    commands alone. `command_event[c]` is the first event of command c."""

    length_sample = 1           # every event is a vertex: lengths need them all

    def __init__(self, commands: list[Command], config: MachineConfig,
                 position: tuple[int, int, int] = (0, 0, 0)):
        self.config = config
        self.position = tuple(position)
        x, y, z, firsts = _walk(commands, config, self.position)
        self.x, self.y, self.z = x, y, z
        self.command_event = firsts

    def __len__(self) -> int:
        return len(self.x)

    def events(self, start: tuple[int, int, int], axes: int = 3) -> Iterator[tuple]:
        """(index of the first event, x, y[, z]) per chunk, int32 steps; event 0 (the
        start) alone first, as render._events gives a trace's."""
        if tuple(start) != self.position:
            raise ValueError(f"this path starts at {self.position}, not {tuple(start)}")
        columns = (self.x, self.y, self.z)[:axes]
        yield 0, *(c[:1] for c in columns)
        for first in range(1, len(self.x), CHUNK_EVENTS):
            yield first, *(c[first:first + CHUNK_EVENTS] for c in columns)

    def stretch_firsts(self, commands: list[int]) -> np.ndarray:
        """The first event of each of `commands` (indices; one past the last: the
        event after the path's end)."""
        at = np.asarray(commands, dtype=np.int64)
        out = np.full(len(at), len(self.x), dtype=np.int64)
        inside = at < len(self.command_event)
        out[inside] = self.command_event[at[inside]]
        return out


def _walk(commands: list[Command], config: MachineConfig, position: tuple[int, int, int]):
    """The events (x, y, z int32 arrays, event 0 the start) and each command's
    first event (int64)."""
    up, down = config.pen_up_z_steps, config.pen_down_z_steps
    xs, ys, zs = [position[0]], [position[1]], [position[2]]
    firsts = np.empty(len(commands), dtype=np.int64)
    origin = [0, 0, 0]
    x, y, z = position

    def z_to(target: int) -> None:
        nonlocal z
        if target != z:
            z = target
            xs.append(x)
            ys.append(y)
            zs.append(z)

    def line_to(tx: int, ty: int, tz: int) -> None:
        nonlocal x, y, z
        if tz != z and (tx, ty) != (x, y):
            _plunge(xs, ys, zs, (x, y, z), (tx, ty, tz))
        elif (tx, ty, tz) != (x, y, z):
            xs.append(tx)
            ys.append(ty)
            zs.append(tz)
        x, y, z = tx, ty, tz

    for index, command in enumerate(commands):
        firsts[index] = len(xs)
        kind = type(command)
        if kind is LineTo:
            tx, ty = command.x_steps + origin[0], command.y_steps + origin[1]
            line_to(tx, ty, z if command.z_steps is None else command.z_steps + origin[2])
        elif kind is Rapid:
            z_to(up + origin[2])
            tx, ty = command.x_steps + origin[0], command.y_steps + origin[1]
            if (tx, ty) != (x, y):
                x, y = tx, ty
                xs.append(x)
                ys.append(y)
                zs.append(z)
        elif kind is ArcTo:
            ex, ey = command.x_steps + origin[0], command.y_steps + origin[1]
            px, py = _arc_points((x, y), (ex, ey), (command.i_steps, command.j_steps),
                                 command.cw)
            xs.extend(px)
            ys.extend(py)
            zs.extend([z] * len(px))
            x, y = ex, ey
        elif kind is PenDown:
            z_to(down + origin[2])
        elif kind is PenUp or kind is EndJob:
            z_to(up + origin[2])
        elif kind is Flash:
            z_to(down + origin[2])
            z_to(up + origin[2])
        elif kind is Jog:
            line_to(x + command.dx_steps, y + command.dy_steps, z + command.dz_steps)
        elif kind is SetOrigin:
            origin = [x, y, z]
        elif kind is Home:
            raise ValueError("a job that homes has no path before it runs: step it instead")
        # Dwell, SetFeed, Motors: the head stays where it is
    as_int32 = (lambda values: np.asarray(values, dtype=np.int32))
    return as_int32(xs), as_int32(ys), as_int32(zs), firsts


def _plunge(xs, ys, zs, start, end) -> None:
    """A line moving Z and XY together, as pieces of at most PLUNGE_PIECE_STEPS."""
    delta = [e - s for s, e in zip(start, end)]
    n = max(1, math.ceil(max(abs(d) for d in delta) / PLUNGE_PIECE_STEPS))
    for k in range(1, n + 1):
        xs.append(start[0] + round(delta[0] * k / n))
        ys.append(start[1] + round(delta[1] * k / n))
        zs.append(start[2] + round(delta[2] * k / n))


def _arc_points(start: tuple[int, int], end: tuple[int, int], centre_rel: tuple[int, int],
                cw: bool) -> tuple[list[int], list[int]]:
    """The points after the start of an arc (its circle through the start, to the
    end's angle, then straight to the end), within ARC_SAGITTA_STEPS of the circle.
    An end at the start's angle is a full circle, as the machine takes it."""
    cx, cy = start[0] + centre_rel[0], start[1] + centre_rel[1]
    sx, sy = start[0] - cx, start[1] - cy
    radius = math.hypot(sx, sy)
    if radius == 0:
        return ([end[0]], [end[1]]) if end != start else ([], [])
    a0 = math.atan2(sy, sx)
    a1 = math.atan2(end[1] - cy, end[0] - cx) if end != (cx, cy) else a0
    sweep = (a1 - a0) % (2 * math.pi)
    if cw:
        sweep -= 2 * math.pi
    on_start = (round(cx + radius * math.cos(a1)), round(cy + radius * math.sin(a1))) == start
    if on_start:                                      # the machine's full circle
        sweep = -2 * math.pi if cw else 2 * math.pi
    if radius <= ARC_SAGITTA_STEPS:
        step = math.pi
    else:
        step = 2 * math.acos(1 - ARC_SAGITTA_STEPS / radius)
    n = max(1, math.ceil(abs(sweep) / step))
    angles = a0 + sweep * np.arange(1, n + 1) / n
    px = np.rint(cx + radius * np.cos(angles)).astype(np.int64).tolist()
    py = np.rint(cy + radius * np.sin(angles)).astype(np.int64).tolist()
    if (px[-1], py[-1]) != end:
        px.append(end[0])
        py.append(end[1])
    return px, py
