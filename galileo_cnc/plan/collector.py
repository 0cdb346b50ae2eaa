"""Python's cycle collector paused while a plan is made.

The planner makes and drops millions of small objects (rows as lists, tuples,
arrays) that reference counting frees: none of them sit in a cycle (Clipper's
PolyTree does, and is taken apart after use: ink/clip.py). Yet every 700 new
container objects start a collection, and each one that reaches the oldest
generation walks every live object of the process, the whole program included, for
nothing: on hellboard.group1 24 such walks took 2.3 s of a 12.4 s plan. What does
sit in cycles, a DXF drawing's ezdxf document once read (63k objects for a 2.3 MB
drawing), waits for the collector's next run after the plan.
"""

from __future__ import annotations

import gc
from contextlib import contextmanager
from typing import Iterator


@contextmanager
def collector_paused() -> Iterator[None]:
    """The cycle collector off inside, as it was after (nested uses keep it off)."""
    was_on = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_on:
            gc.enable()
