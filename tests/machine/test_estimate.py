"""Job timing for progress and ETA (galileo_cnc/estimate.py) against the reference machine."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from galileo_cnc.config.hardware import TICKS_PER_S
from galileo_cnc.job import ArcTo, Dwell, LineTo, PenDown, PenUp, Rapid, SetFeed
from galileo_cnc.machine import simulate
from galileo_cnc.machine.timing import duration_text, job_timing
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.readers import read_file

REPO = Path(__file__).resolve().parents[2]


def test_each_command_ends_where_the_reference_says():
    commands = [Rapid(1000, 1000), PenDown(), LineTo(3000, 1000), SetFeed(1600),
                ArcTo(3000, 1000, 0, 800, cw=False), Dwell(500), LineTo(1000, 1000), PenUp()]
    timing = job_timing(commands)
    for k in range(1, len(commands) + 1):
        alone = simulate(commands[:k])
        if isinstance(commands[k - 1], (SetFeed, Dwell)):
            continue            # no steps: its time shows in the next moving command
        assert timing.end_ticks[k - 1] == alone.tick[-1], commands[k - 1]
    assert timing.end_ticks[-1] == simulate(commands).total_ticks
    # the dwell's 500 ms lands in the line after it
    assert timing.end_ticks[5] == timing.end_ticks[4]
    assert timing.seconds_between(6, 7) > 0.5


def test_the_sample_board_total_equals_the_trace_and_time_only_runs_forward():
    program = read_file(REPO / "samples" / "led-blinker.gbr")
    job = plan_program(program, None, proposed_offset(program))
    timing = job_timing(job.commands)
    assert timing.total_s == simulate(job.commands).seconds
    assert np.all(np.diff(timing.end_ticks) >= 0)
    assert timing.remaining_s(0) == timing.total_s and timing.remaining_s(len(job)) == 0
    assert abs(timing.seconds_between(10, 30)
               - (timing.end_ticks[29] - timing.end_ticks[9]) / TICKS_PER_S) < 1e-9


def test_durations_read_as_minutes_or_hours():
    assert duration_text(65) == "1:05" and duration_text(3725) == "1:02:05"
    assert duration_text(0.4) == "0:00"
