"""The Job: machine commands, what the planner emits and the firmware executes.

This module is the contract between the planner, the wire protocol and the
reference machine; it depends on nothing but the error types.


Every field is an integer (steps, steps/s, milliseconds) or None for "use the
configured default", so a command means the same thing on the host, on the wire
and in the firmware. Coordinates are absolute work coordinates in steps (work =
machine position minus the origin set by `SetOrigin`); `Jog` is relative.
The semantics, including what each one costs in time, are in docs/motion.md §2.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum
from fractions import Fraction
from typing import Union

from galileo_cnc.errors import GalileoError


class MachineError(GalileoError):
    """The machine refuses a command (soft limit, bad feed, homing failure, ...).

    `axis` ("X", "Y", "Z" or ""), `limit` (the violated bound in machine steps, or
    None) and `value` (where the move would have taken the axis) are kept for
    callers that want to say it in the user's units.
    """

    def __init__(self, message: str, axis: str = "", limit: int | None = None,
                 index: int | None = None, value: int | None = None):
        self.axis = axis
        self.limit = limit
        self.index = index
        self.value = value
        super().__init__(message)


class Axis(IntEnum):
    X = 0
    Y = 1
    Z = 2


AXIS_NAMES = ("X", "Y", "Z")


@dataclass(frozen=True, slots=True)
class Rapid:
    """Pen up (if not already), then travel to (x, y) at the rapid feed."""

    x_steps: int
    y_steps: int


@dataclass(frozen=True, slots=True)
class LineTo:
    """Straight move to (x, y[, z]) at the current feed; the pen stays as it is.

    `exit_index`: the ramp index the move ends at (docs/motion.md §5.7), planned by
    the host with junction speeds; None ends it at rest."""

    x_steps: int
    y_steps: int
    z_steps: int | None = None
    exit_index: int | None = None


@dataclass(frozen=True, slots=True)
class ArcTo:
    """Circular move in XY to (x, y) around centre = start + (i, j) at the current feed.

    `cw` True is clockwise (G02), False counter-clockwise (G03). End == start is a
    full circle. An end point off the start circle is reached by a short straight
    correction after the arc (docs/motion.md §4.6).
    """

    x_steps: int
    y_steps: int
    i_steps: int
    j_steps: int
    cw: bool
    exit_index: int | None = None   # as LineTo's


@dataclass(frozen=True, slots=True)
class PenUp:
    """Z to the pen-up height (pen_down_z_steps + pen_lift_steps) at the Z feed."""


@dataclass(frozen=True, slots=True)
class PenDown:
    """Z to the drawing height (pen_down_z_steps) at the Z feed."""


@dataclass(frozen=True, slots=True)
class Flash:
    """Pen down, dwell (`dwell_ms`, default flash_dwell_ms = 200), pen up."""

    dwell_ms: int | None = None


@dataclass(frozen=True, slots=True)
class Dwell:
    """Wait `ms` milliseconds (2000 ticks each)."""

    ms: int


@dataclass(frozen=True, slots=True)
class SetFeed:
    """Feed for LineTo/ArcTo/Jog in steps/s (path speed), 10 ..= max step rate."""

    feed_steps_per_s: int


@dataclass(frozen=True, slots=True)
class Jog:
    """Relative move at the current feed (the setup screen's keypad)."""

    dx_steps: int = 0
    dy_steps: int = 0
    dz_steps: int = 0


@dataclass(frozen=True, slots=True)
class SetOrigin:
    """Make the current position the work origin (0, 0, 0) on all three axes."""


@dataclass(frozen=True, slots=True)
class Home:
    """Home every axis that has an end-stop pin (Z first, then X, then Y)."""


@dataclass(frozen=True, slots=True)
class Motors:
    """Enable (True) or disable (False) the stepper drivers."""

    on: bool


@dataclass(frozen=True, slots=True)
class EndJob:
    """Pen up; the job is over (further commands are refused)."""


Command = Union[Rapid, LineTo, ArcTo, PenUp, PenDown, Flash, Dwell, SetFeed, Jog,
                SetOrigin, Home, Motors, EndJob]


#: op index of the commands the planner adds itself (the closing PenUp, EndJob).
NO_OP = -1


@dataclass(slots=True)
class Job:
    """Machine commands plus, per command, the source op index and the aperture."""

    source: str
    offset_nm: tuple[int, int]
    commands: list[Command] = field(default_factory=list)
    op_index: list[int] = field(default_factory=list)
    aperture: list[int] = field(default_factory=list)
    grouped: bool = False                   # work grouped by aperture (plan/order/apertures.py)
    mode: str = "centre"                    # "ink" or "centre" (plan/pipeline.py)
    ordered: bool = False                   # paths chained and ordered (plan/order/paths.py)
    pens_nm: tuple = ()                     # ink mode: the pen set it was inked for
    layers: tuple = ()                      # DXF: the layers read (empty: all)
    units: str | None = None                # DXF: units given instead of $INSUNITS
    scale: Fraction = Fraction(1)           # the drawing scaled (plan/transform.py), exact
    rotate_deg: int = 0                     # and turned clockwise (0, 90, 180, 270)
    #: a board's side: what plans it again (plan/board_plan.py, BoardChoice.as_dict);
    #: None: a file alone
    board: dict | None = None
    #: command index -> aperture: stop before that command for a pen change.
    pen_changes: dict[int, int] = field(default_factory=dict)
    #: aperture (pen key) -> what to ask for: "the 0.3 mm pen", "pen for aperture D11 (...)"
    pen_labels: dict[int, str] = field(default_factory=dict)
    #: aperture (pen key) -> the width its pen draws (nm; 0 when the aperture has none)
    pen_widths_nm: dict[int, int] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.commands)

    def add(self, command: Command, op: int, aperture: int) -> None:
        self.commands.append(command)
        self.op_index.append(op)
        self.aperture.append(aperture)
