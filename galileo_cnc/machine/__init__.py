"""The reference machine: the Python mirror of the firmware (docs/motion.md).

Commands in steps go in; the step trace (tick, axis, dir per step) comes out.
`simulate` runs a job with the vectorised reference; `backend="loop"` runs the
per-step form the firmware implements, for cross-checks and benchmarks.
"""

from .commands import (AXIS_NAMES, ArcTo, Axis, Command, Dwell, EndJob, Flash, Home, Jog,
                       LineTo, MachineError, Motors, PenDown, PenUp, Rapid, SetFeed,
                       SetOrigin)
from .machine import ReferenceMachine, estimate_seconds, simulate
from .moves import Hold
from .ramps import SUBTICKS_PER_TICK, TICKS_PER_S
from .trace import TRACE_KEYS, Trace

__all__ = [
    "AXIS_NAMES", "ArcTo", "Axis", "Command", "Dwell", "EndJob", "Flash", "Home", "Hold",
    "Jog", "LineTo", "MachineError", "Motors", "PenDown", "PenUp", "Rapid", "SetFeed",
    "SetOrigin", "ReferenceMachine", "SUBTICKS_PER_TICK", "TICKS_PER_S", "TRACE_KEYS",
    "Trace", "estimate_seconds", "simulate",
]
