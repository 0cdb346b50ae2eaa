"""Job timing for progress and ETA (galileo_cnc/estimate.py) against the reference machine."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from hypothesis import given, settings, strategies as st

from galileo_cnc.config.hardware import TICKS_PER_S
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import ArcTo, Dwell, LineTo, PenDown, PenUp, Rapid, SetFeed
from galileo_cnc.machine import ReferenceMachine, simulate, vector
from galileo_cnc.machine.blocks import Pause
from galileo_cnc.machine.timing import duration_text, job_timing
from galileo_cnc.plan.pipeline import plan_file
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


def ends_from_the_trace(commands, config=None) -> np.ndarray:
    """Each command's end tick read off the whole trace (vector.execute): the tick of
    the last step event of the commands so far; the job's end for the last one."""
    machine = ReferenceMachine(config)
    items, events = [], []
    for command in commands:
        planned = machine.plan([command])
        items.extend(planned)
        events.append(sum(item.n for item in planned if not isinstance(item, Pause)))
    tick, _axis, _dir, end, _ = vector.execute(machine.plan_speeds(items), 0)
    event_ticks = tick[np.r_[True, tick[1:] != tick[:-1]]] if len(tick) else tick
    done = np.cumsum(events)
    ends = np.array([event_ticks[d - 1] if d else 0 for d in done.tolist()], dtype=np.int64)
    ends[-1] = end
    return ends


def test_the_timing_is_the_traces_on_an_inked_board_and_a_drawing():
    two_pens = MachineConfig().replace(pen_widths_mm=(0.3, 0.8))
    for path, config in ((REPO / "samples" / "led-blinker.gbr", two_pens),
                         (REPO / "samples" / "square-and-circle.nc", MachineConfig())):
        job = plan_file(path, config).job
        assert any(isinstance(c, ArcTo) for c in job.commands)
        assert np.array_equal(job_timing(job.commands, config).end_ticks,
                              ends_from_the_trace(job.commands, config)), path


XY = st.integers(3000, 9000)       # steps, well inside the travel, arcs included
MOVES = st.one_of(
    st.builds(LineTo, XY, XY), st.builds(Rapid, XY, XY),     # short ones: triangles
    st.builds(ArcTo, XY, XY, st.integers(-900, 900), st.integers(-900, 900),
              cw=st.booleans()),
    st.builds(Dwell, st.integers(0, 300)), st.builds(SetFeed, st.integers(200, 1600)),
    st.just(PenDown()), st.just(PenUp()))


@settings(max_examples=60, deadline=None)
@given(st.lists(MOVES, min_size=1, max_size=12))
def test_the_timing_is_the_traces_for_any_job(commands):
    commands = [Rapid(6000, 6000)] + commands
    assert np.array_equal(job_timing(commands).end_ticks, ends_from_the_trace(commands))
