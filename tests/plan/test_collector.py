"""The planner runs with the cycle collector paused (plan/collector.py), so it must
leave no cycles behind: the one library structure that has them, Clipper's PolyTree,
is taken apart after use (ink/clip.py)."""

from __future__ import annotations

import gc
from pathlib import Path

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan import pipeline
from galileo_cnc.plan.collector import collector_paused
from galileo_cnc.plan.ink import clip, fill
from galileo_cnc.plan.pipeline import PlanOptions, plan_file

MM = 1_000_000
SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "led-blinker.gbr"


def square(x: int, y: int, side: int) -> list[list[int]]:
    return [[x, y], [x + side, y], [x + side, y + side], [x, y + side]]


def cycles_left_by(work, runs: int = 3) -> int:
    """Objects in cycles that `work()` made and dropped (the collector finds them): the
    fewest of `runs` runs, as a thread a test before this one left running (a board's
    reader) may drop cycles of its own meanwhile; cycles of `work` are in every run."""
    found = []
    for _ in range(runs):
        gc.collect()
        with collector_paused():
            work()
            found.append(gc.collect())
    return min(found)


def test_islands_and_gap_strokes_leave_no_cycles():
    # two pads, one with a hole holding an island: a PolyTree three levels deep
    pads = [square(0, 0, 4 * MM), square(MM, MM, 2 * MM)[::-1],
            square(int(1.5 * MM), int(1.5 * MM), MM // 2), square(6 * MM, 0, MM)]
    found = []
    assert cycles_left_by(lambda: found.__setitem__(slice(None), clip.components(pads))) == 0
    assert len(found) == 3 and sorted(len(holes) for _outer, holes in found) == [0, 0, 1]
    # the gap strokes clip open paths with a PolyTree too
    centre = clip.offset([square(0, 0, 3 * MM)], -150_000, 1_000)
    strokes = []
    gaps = [square(MM, MM, 40_000), square(2 * MM, MM, 40_000)]
    assert cycles_left_by(lambda: strokes.__setitem__(
        slice(None), fill._gap_strokes(gaps, centre, 150_000))) == 0
    assert len(strokes) == 2


def test_plan_file_pauses_the_collector_and_restores_it(monkeypatch):
    seen = []
    real = pipeline.plan_program

    def spy(*args, **kwargs):
        seen.append(gc.isenabled())
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline, "plan_program", spy)
    assert gc.isenabled()
    planned = plan_file(SAMPLE, MachineConfig(),
                        options=PlanOptions(mode="ink", pens_nm=(300_000,)))
    assert seen == [False] and gc.isenabled()
    assert len(planned.job) > 0
    gc.disable()
    try:                               # a caller's choice is kept
        plan_file(SAMPLE, MachineConfig())
        assert not gc.isenabled()
    finally:
        gc.enable()
