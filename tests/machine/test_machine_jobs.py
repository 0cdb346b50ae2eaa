"""Whole jobs: loop == numpy, feed hold / abort, soft limits, homing, the .npz trace."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.errors import GalileoError
from galileo_cnc.job import (ArcTo, Dwell, EndJob, Flash, Home, Jog, LineTo, MachineError,
                             Motors, PenDown, PenUp, Rapid, SetFeed, SetOrigin)
from galileo_cnc.machine import Hold, ReferenceMachine, Trace, simulate
from galileo_cnc.machine.analysis import min_step_gap_ticks

CFG = MachineConfig()
START = [Jog(12000, 12000, 0), SetOrigin()]

coord = st.integers(-6000, 6000)
command = st.one_of(
    st.builds(LineTo, coord, coord),
    st.builds(LineTo, coord, coord, st.integers(0, 500)),
    st.builds(ArcTo, coord, coord, st.integers(-2000, 2000), st.integers(-2000, 2000),
              st.booleans()),
    st.builds(Rapid, coord, coord),
    st.builds(Jog, st.integers(-300, 300), st.integers(-300, 300), st.integers(-50, 50)),
    st.builds(SetFeed, st.sampled_from([30, 400, 800, 2500, 12000])),
    st.builds(Dwell, st.integers(0, 30)),
    st.just(Flash()), st.just(PenUp()), st.just(PenDown()), st.just(Motors(True)),
)
jobs = st.lists(command, min_size=1, max_size=8).map(lambda c: START + c + [EndJob()])


def plan_ok(cmds):
    try:
        simulate(cmds)
        return True
    except MachineError:
        return False


@settings(max_examples=60, deadline=None)
@given(jobs, st.lists(st.tuples(st.floats(0, 1), st.integers(0, 20000)), max_size=3),
       st.one_of(st.none(), st.floats(0, 1)))
def test_random_jobs_loop_equals_vectorised(cmds, holds, abort):
    if not plan_ok(cmds):
        return
    full = simulate(cmds)
    hs = [Hold(int(f * full.total_ticks), p) for f, p in holds]
    ab = None if abort is None else int(abort * full.total_ticks)
    a = simulate(cmds, holds=hs, abort_at_tick=ab)
    b = simulate(cmds, holds=hs, abort_at_tick=ab, backend="loop")
    assert a.same_steps(b)
    assert a.total_ticks == b.total_ticks and a.final_position == b.final_position
    assert min_step_gap_ticks(a) >= CFG.min_step_period_ticks
    if ab is None:
        # Hold then resume: same steps in the same order, same end, only later.
        assert np.array_equal(a.axis, full.axis) and np.array_equal(a.dir, full.dir)
        assert a.final_position == full.final_position
        assert a.total_ticks >= full.total_ticks


def test_hold_decelerates_then_resumes_with_a_ramp():
    cmds = START + [LineTo(8000, 0)]
    full = simulate(cmds)
    line = full.tick[24000:]  # after the set-up jog
    t_hold = int(line[4000])
    held = simulate(cmds, holds=[Hold(t_hold, 100_000)])
    assert np.array_equal(held.axis, full.axis) and np.array_equal(held.dir, full.dir)
    gaps = np.diff(held.tick[24000:])
    stop = int(np.argmax(gaps))  # the pause
    assert gaps[stop] >= 100_000
    period = 2_000_000 / CFG.feed_steps_per_s
    before = gaps[stop - 40:stop]
    assert np.all(np.diff(before) >= 0) and before[-1] > 2.9 * period  # slowed down to 3x
    after = gaps[stop + 1:stop + 40]
    assert after[0] > 2.9 * period and np.all(np.diff(after) <= 0)    # ramps up again
    assert held.final_position == full.final_position == (8000, 0, 0)


def test_abort_stops_with_a_ramp_and_known_position():
    cmds = START + [LineTo(8000, 0), LineTo(0, 0)]
    full = simulate(cmds)
    t = int(full.tick[24000 + 3000])
    m = ReferenceMachine()
    trace = m.run(cmds, abort_at_tick=t)
    assert len(trace) < len(full)
    assert trace.total_ticks == trace.tick[-1]
    moved_x = int(trace.displacement()[0])
    assert m.position[0] == moved_x and trace.final_position[0] == moved_x - 12000
    gaps = np.diff(trace.tick[-40:])
    assert np.all(np.diff(gaps) >= 0)  # decelerating into the stop


def test_an_abort_keeps_only_the_origins_set_before_the_stop():
    # SetOrigin is a queued block: one behind the running move never takes effect
    cmds = START + [LineTo(8000, 0), SetOrigin(), LineTo(2000, 0)]
    full = simulate(cmds)
    first_line_end = 12000 + 8000
    during_first = int(full.tick[24000 + 3000])
    m = ReferenceMachine()
    m.run(cmds, abort_at_tick=during_first)
    assert m.origin == [12000, 12000, 0]                      # START's origin only
    assert m.work_position[0] == m.position[0] - 12000 < 8000
    # aborted in the last line: the origin set after the first line holds
    during_last = int(full.tick[-200])
    m = ReferenceMachine()
    m.run(cmds, abort_at_tick=during_last)
    assert m.origin == [first_line_end, 12000, 0]
    assert 0 < m.work_position[0] < 2000
    # and the next command plans from the stop, in those coordinates
    trace = m.run([LineTo(0, 0)])
    assert trace.final_position == (0, 0, 0) and m.position[0] == first_line_end


def test_soft_limits_refuse_before_any_step():
    m = ReferenceMachine()
    with pytest.raises(MachineError, match=r"command 2 \(LineTo to X -0\.006 mm Y 0\.062 mm "
                       r"\(work\)\): X would reach -0\.006 mm \(machine\), below the "
                       r"travel's start at 0\.000 mm \[-1 steps\]") as e:
        m.run([LineTo(500, 500), LineTo(-1, 10)])
    assert e.value.axis == "X" and e.value.limit == 0 and isinstance(e.value, GalileoError)
    assert m.position == [0, 0, 0] and m.clock_ticks == 0  # nothing ran
    with pytest.raises(MachineError, match=r"Y would reach 200\.006 mm \(machine\), beyond the "
                       r"travel's end at "
                       r"200\.000 mm \[32001 steps\]"):
        simulate([LineTo(0, 32001)])
    with pytest.raises(MachineError, match="Z") as e:
        simulate([Jog(0, 0, 601)])
    assert e.value.axis == "Z" and e.value.limit == 600
    # An arc whose ends are inside but whose bulge is not.
    with pytest.raises(MachineError, match="X would reach -"):
        simulate([Jog(100, 1000, 0), ArcTo(100, 3000, 0, 1000, True)])
    simulate([Jog(100, 1000, 0), ArcTo(100, 3000, 0, 1000, False)])  # the other way round fits


def test_bad_feed_and_commands_after_end_are_refused():
    with pytest.raises(MachineError, match=r"feed 0\.03125 mm/s \(1\.875 mm/min\) "
                       r"\[5 steps/s\] outside 0\.0625 \.\. 250 mm/s"):
        simulate([SetFeed(5)])
    with pytest.raises(MachineError, match=r"feed 250\.00625 mm/s .*\[40001 steps/s\]"):
        simulate([SetFeed(40001)])
    with pytest.raises(MachineError, match="ended"):
        simulate([EndJob(), LineTo(1, 1)])
    with pytest.raises(MachineError, match="negative dwell"):
        simulate([Dwell(-1)])


def test_homing_trips_debounced_backs_off_and_zeroes():
    cfg = MachineConfig(sim_x_endstop_steps=-700, sim_y_endstop_steps=-300)
    m = ReferenceMachine(cfg)
    trace = m.run([Jog(200, 100, 0), Home(), LineTo(10, 10)])
    assert m.position == [10, 10, 0] and m.work_position == (10, 10, 0)
    seek_x = 900 + cfg.home_debounce_reads - 1  # from x=200 to the switch at -700, 3 more reads
    x = trace.axis == 0
    xd = trace.dir[x]
    assert np.count_nonzero(xd[200:200 + seek_x] == -1) == seek_x
    assert np.count_nonzero(xd[200 + seek_x:200 + seek_x + cfg.home_pulloff_steps] == 1) == \
        cfg.home_pulloff_steps
    looped = ReferenceMachine(cfg).run([Jog(200, 100, 0), Home(), LineTo(10, 10)], backend="loop")
    assert looped.same_steps(trace)
    # Homing runs at a constant, slow rate (no ramp needed at that speed).
    seek_ticks = trace.tick[x][200:200 + seek_x]
    assert len(set(np.diff(seek_ticks).tolist()) - {12500}) == 0


def test_homing_failures():
    with pytest.raises(MachineError, match="already active"):
        ReferenceMachine(MachineConfig(sim_x_endstop_steps=0)).run([Home()])
    with pytest.raises(MachineError, match="not found"):
        ReferenceMachine(MachineConfig(sim_x_endstop_steps=-10**6)).run([Home()])


def test_trace_npz_round_trip(tmp_path):
    trace = simulate([LineTo(300, 200), ArcTo(300, 200, -100, 0, True), Flash(), Dwell(5)])
    path = tmp_path / "job.npz"
    trace.save(path)
    with np.load(path) as data:
        assert set(data.files) == {"tick", "axis", "dir", "final_position", "total_ticks"}
        assert data["tick"].dtype == np.int64
        assert data["axis"].dtype == np.int8 and data["dir"].dtype == np.int8
    back = Trace.load(path)
    assert back.same_steps(trace)
    assert back.final_position == trace.final_position and back.total_ticks == trace.total_ticks


def test_machine_keeps_state_and_clock_between_runs():
    m = ReferenceMachine()
    first = m.run([LineTo(100, 0)])
    second = m.run([LineTo(0, 0)])          # a turn back: the whole job stops there too
    assert second.tick[0] > first.tick[-1]
    whole = simulate([LineTo(100, 0), LineTo(0, 0)])
    assert np.array_equal(np.concatenate([first.tick, second.tick]), whole.tick)
    assert m.work_position == (0, 0, 0)


def test_a_job_stepped_in_pieces_is_the_job_stepped_whole(monkeypatch):
    from galileo_cnc.machine import vector
    from galileo_cnc.machine.planner import JobSteps

    monkeypatch.setattr(vector, "CHUNK_EVENTS", 50)          # many pieces
    commands = [Rapid(300, 200), PenDown(), LineTo(900, 650), ArcTo(900, 650, 120, 0, True),
                Dwell(5), Flash(), Rapid(0, 0), PenUp(), EndJob()]
    whole = simulate(commands)
    pieces = list(JobSteps(commands).pieces())
    assert len(pieces) > 3
    for k, column in enumerate((whole.tick, whole.axis, whole.dir)):
        assert np.array_equal(np.concatenate([p[k] for p in pieces]), column)
    for before, after in zip(pieces, pieces[1:]):             # no event is cut in two
        assert before[0][-1] != after[0][0]
