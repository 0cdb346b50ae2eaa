"""Junction speeds: how fast the pen may pass each vertex of a job (docs/motion.md §5.7).

The host sees the whole job, so it plans every move's entry and exit speed before
the machine runs it. A speed is a *ramp index* m (0 … R) of the integer ramp law
(§5.4): the interval of an event at index m is base + (R − m) · step, m = 0 is the
speed a move starts at from rest (1/K of the feed, K the ramp_start_factor, 3 by
default), m = R the feed. Two moves that blend share the index at their vertex: the
first one's last event and the second one's first event run at that index; m = 0 on
both sides is today's stop.

Per vertex the index is capped by
- a stop (0) where the moves cannot blend: a pause (dwell, flash) between them, a
  pen lift or any Z motion, a homing seek, the end of a Rapid or a Jog (no exit index
  on the wire), a different feed (ramp length), a
  reversal (a turn of more than 90°), the first and last move of the job;
- GRBL's junction deviation: v² = A · δ · sin(θ/2) / (1 − sin(θ/2)), θ the angle
  between the reversed first direction and the second (so θ = 180° is straight on);
- the per-axis speed change: every axis changes speed at the vertex by at most
  `vertex_speed_change` (the speed each axis already takes from rest at a start);
- on an arc's end, the centripetal limit v² ≤ A · r;
- next to a line of length L, Klipper's mid-move limit v² ≤ A · (L/2) · tan(θ/2): the
  circle standing for the corner touches the line no farther out than its middle, so
  a curve drawn as short lines passes at the speed its radius allows.
Then a backward and a forward pass keep every move able to reach its exit from its
entry along the ramp law, which changes the index by at most one per event:
|entry − exit| ≤ n − 1 (a one-event move keeps its index).

Integers in and out (steps, steps/s, subticks, ramp indices); the directions and
speeds in between are floats, as the host's planner is not mirrored by the firmware:
the firmware only executes the indices it is sent.
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass, replace
from math import ceil, hypot, inf, sqrt
from typing import Sequence

from galileo_cnc.machine.blocks import ArcMove, Item, LineMove, Pause
from galileo_cnc.machine.ramps import RHO_ONE, SUBTICKS_PER_S

#: a turn sharper than a right angle (cos of the turn below 0, with room for the
#: rounding of exact right angles) is a reversal: a stop
REVERSAL_COS = -1e-9


@dataclass(frozen=True, slots=True)
class JunctionLimits:
    """The bounds a vertex is planned with, in the machine's integer units."""

    accel_steps_per_s2: int
    deviation_nm: int            # GRBL's $11; 0: stop at every vertex
    nm_per_step: int
    axis_change_steps_per_s: int  # largest per-axis speed change at a vertex

    @classmethod
    def of(cls, config) -> "JunctionLimits":
        return cls(config.accel_steps_per_s2, config.junction_deviation_nm,
                   config.nm_per_step, config.vertex_speed_change_steps_per_s)

    @property
    def enabled(self) -> bool:
        return self.deviation_nm > 0


@dataclass(frozen=True, slots=True)
class MoveEnd:
    """One end of a move as a vertex sees it: unit direction, and the interval law of
    the event there (path per event rho in steps, cruise interval, ramp step)."""

    direction: tuple[float, float, float]
    rho: float
    base_sub: int
    step_sub: int
    ramp: int
    radius: float = inf          # an arc's radius (steps): the centripetal limit

    def speed(self, m: int) -> float:
        """Path speed (steps/s) of the event at ramp index m."""
        return self.rho * SUBTICKS_PER_S / (self.base_sub + (self.ramp - m) * self.step_sub)

    def index_at_most(self, speed: float) -> int:
        """The largest ramp index whose event is no faster than `speed`."""
        if speed == inf:
            return self.ramp
        if speed <= 0 or self.step_sub == 0:
            return 0
        need = self.rho * SUBTICKS_PER_S / speed - self.base_sub   # ≥ (R − m) · step
        if need <= 0:
            return self.ramp
        return max(0, self.ramp - ceil(need / self.step_sub))


def _unit(x: float, y: float, z: float = 0.0) -> tuple[float, float, float]:
    length = sqrt(x * x + y * y + z * z)
    return (x / length, y / length, z / length)


def _line_end(move: LineMove) -> MoveEnd:
    dx, dy, dz = move.delta
    length = sqrt(dx * dx + dy * dy + dz * dz)
    return MoveEnd(_unit(dx, dy, dz), length / move.n, move.base_sub, move.step_sub,
                   move.ramp)


def _arc_end(move: ArcMove, at_end: bool) -> MoveEnd:
    g = move.geom
    if g.n_arc == 0:      # all correction: a line
        cx, cy = g.correction
        return MoveEnd(_unit(cx, cy), hypot(cx, cy) / g.n_corr, move.band_base_sub[0],
                       move.step_sub, move.ramp)
    px, py = g.p_star if at_end else g.start
    tangent = (-py, px) if g.ccw else (py, -px)
    if at_end:   # the band of the last event: its key is about P*'s smaller coordinate
        band = max(0, bisect_right(g.band_v, max(0, min(abs(px), abs(py)) - 1)) - 1)
    else:
        band = g.band0
    return MoveEnd(_unit(*tangent), g.band_rho[band] / RHO_ONE, move.band_base_sub[band],
                   move.step_sub, move.ramp, sqrt(g.r2))


def move_ends(move: LineMove | ArcMove) -> tuple[MoveEnd, MoveEnd]:
    """The move's first and last event as vertices see them."""
    if isinstance(move, LineMove):
        end = _line_end(move)
        return end, end
    return _arc_end(move, False), _arc_end(move, True)


def vertex_speed(a: tuple[float, float, float], b: tuple[float, float, float],
                 limits: JunctionLimits) -> float:
    """The fastest path speed (steps/s) through a vertex from direction a to b: the
    junction deviation's and the per-axis bound's, 0 at a reversal."""
    dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    if dot < REVERSAL_COS:
        return 0.0
    change = max(abs(a[0] - b[0]), abs(a[1] - b[1]), abs(a[2] - b[2]))
    per_axis = limits.axis_change_steps_per_s / change if change > 0 else inf
    sin_half = sqrt(max(0.0, 0.5 * (1.0 + dot)))        # sin(θ/2), cos θ = −dot
    if sin_half >= 1.0:
        return per_axis
    deviation_steps = limits.deviation_nm / limits.nm_per_step
    deviation = sqrt(limits.accel_steps_per_s2 * deviation_steps * sin_half / (1.0 - sin_half))
    return min(per_axis, deviation)


def _blends(a: Item, b: Item) -> bool:
    """Whether two consecutive moves may pass their vertex without a stop."""
    for move in (a, b):
        if not isinstance(move, (LineMove, ArcMove)) or move.ramp == 0:
            return False
        if isinstance(move, LineMove) and move.delta[2] != 0:
            return False     # a pen lift or lower, or a 3-D line: stop
    if isinstance(a, LineMove) and a.to_rest:
        return False         # a Rapid's or Jog's end: the wire cannot carry its index
    return a.ramp == b.ramp   # the same feed: the index means the same speed


def vertex_index(a: LineMove | ArcMove, b: LineMove | ArcMove, limits: JunctionLimits) -> int:
    """The largest ramp index both moves may have at their vertex (before the passes)."""
    if not _blends(a, b):
        return 0
    end, start = move_ends(a)[1], move_ends(b)[0]
    speed = vertex_speed(end.direction, start.direction, limits)
    for side in (end, start):
        if side.radius != inf:
            speed = min(speed, sqrt(limits.accel_steps_per_s2 * side.radius))
    speed = min(speed, _within_half_moves(a, b, end.direction, start.direction, limits))
    m = min(end.index_at_most(speed), start.index_at_most(speed), a.ramp)
    # The two sides' event speeds differ a little (an arc's band, a line's rho): the
    # per-axis bound holds for the speeds the events really have.
    while m > 0 and _axis_change(end, start, m) > limits.axis_change_steps_per_s:
        m -= 1
    return m


def _within_half_moves(a: LineMove | ArcMove, b: LineMove | ArcMove,
                       u: tuple[float, float, float], v: tuple[float, float, float],
                       limits: JunctionLimits) -> float:
    """Klipper's bound for a corner between lines: the circle that stands for the
    corner touches each line no farther from the vertex than its middle, so the speed
    is at most the centripetal one on that circle, v² = A · (L / 2) · tan(θ/2) for each
    line of length L. A curve drawn as many short lines (a small round pad) then
    passes at the speed its radius allows, not at what each small turn alone would."""
    dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
    cos_half = sqrt(max(0.0, 0.5 * (1.0 - dot)))        # cos(θ/2), θ = 180° straight on
    if cos_half == 0.0:
        return inf
    tan_half = sqrt(max(0.0, 0.5 * (1.0 + dot))) / cos_half
    speed = inf
    for move in (a, b):
        if isinstance(move, LineMove):
            dx, dy, dz = move.delta
            half = 0.5 * sqrt(dx * dx + dy * dy + dz * dz)
            speed = min(speed, sqrt(limits.accel_steps_per_s2 * half * tan_half))
    return speed


def _axis_change(end: MoveEnd, start: MoveEnd, m: int) -> float:
    va, vb = end.speed(m), start.speed(m)
    return max(abs(va * end.direction[i] - vb * start.direction[i]) for i in range(3))


def plan_indices(counts: Sequence[int], caps: Sequence[int]) -> list[int]:
    """Vertex indices of a chain of moves with `counts` events each, given the cap of
    every inner vertex (len(caps) == len(counts) − 1); the chain starts and ends at 0.

    Backward pass: every move can slow down to its exit (entry ≤ exit + n − 1); forward
    pass: every move can reach its exit from its entry (exit ≤ entry + n − 1).
    """
    m = [0, *caps, 0]
    for j in range(len(counts) - 1, 0, -1):
        m[j] = min(m[j], m[j + 1] + counts[j] - 1)
    for j in range(1, len(counts)):
        m[j] = min(m[j], m[j - 1] + counts[j - 1] - 1)
    return m


def plan_junctions(items: Sequence[Item], limits: JunctionLimits) -> list[Item]:
    """The items with every move's entry and exit index planned over the whole list.

    Moves without events are skipped (they step nothing); a pause ends a chain.
    """
    items = list(items)
    if not limits.enabled:
        return items
    chain: list[int] = []         # item positions of the current chain of blended moves
    caps: list[int] = []

    def close() -> None:
        if len(chain) > 1:
            m = plan_indices([items[i].n for i in chain], caps)
            for k, i in enumerate(chain):
                items[i] = replace(items[i], entry=m[k], exit=m[k + 1])
        chain.clear()
        caps.clear()

    for i, item in enumerate(items):
        if isinstance(item, Pause):
            close()
            continue
        if item.n == 0:
            continue
        cap = vertex_index(items[chain[-1]], item, limits) if chain else 0
        if cap == 0:
            close()
        else:
            caps.append(cap)
        chain.append(i)
    close()
    return items
