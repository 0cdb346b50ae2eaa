"""The reference machine: the Python mirror of the firmware (docs/motion.md).

Files are named after the firmware files they mirror: planner.py ~ planner.cpp,
stepper.py ~ stepper.cpp (the per-step interrupt), arcs.py ~ arcs.cpp,
blocks.py ~ struct block (stepper.h); vector.py is the same spec over whole jobs.

Commands in steps go in; the step trace (tick, axis, dir per step) comes out.
`simulate` runs a job with the vectorised reference; `backend="loop"` runs the
per-step form the firmware implements, for cross-checks and benchmarks.
"""

from galileo_cnc.machine.blocks import Hold, Starved
from galileo_cnc.machine.planner import ReferenceMachine, estimate_seconds, simulate
from galileo_cnc.machine.ramps import SUBTICKS_PER_TICK
from galileo_cnc.machine.trace import TRACE_KEYS, Trace

__all__ = ["Hold", "ReferenceMachine", "SUBTICKS_PER_TICK", "Starved", "TRACE_KEYS", "Trace",
           "estimate_seconds", "simulate"]
