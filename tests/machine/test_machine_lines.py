"""Line-distance stepping: exact endpoints, <= 1/2 step off the line, loop == numpy."""

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import LineTo, SetFeed
from galileo_cnc.machine import ReferenceMachine
from galileo_cnc.machine.analysis import event_positions
from galileo_cnc.machine.lines import minor_position

BIG = MachineConfig(x_travel_mm=400, y_travel_mm=400, z_min_steps=-70000, z_max_steps=70000)
HOME = (32000, 32000, 0)


def run(delta, feed=800, backend="numpy"):
    m = ReferenceMachine(BIG, HOME)
    target = [HOME[a] + delta[a] for a in range(3)]
    return m.run([SetFeed(feed), LineTo(*target)], backend=backend)


def check_line(delta, trace):
    n = max(abs(d) for d in delta)
    # Endpoint exact and per-axis step count equals |delta|.
    assert tuple(trace.displacement()) == tuple(delta)
    assert list(trace.steps_per_axis()) == [abs(d) for d in delta]
    if n == 0:
        assert len(trace) == 0
        return
    ticks, pos = event_positions(trace)
    assert len(ticks) == n  # one event per major step
    # Each axis moves monotonically and stays within half a step of the ideal line
    # (exact rational check: |n*q - k*d| <= n/2).
    k = np.arange(1, n + 1)
    for a in range(3):
        q = (pos[:, a] * np.sign(delta[a]) if delta[a] else pos[:, a]).astype(np.int64)
        d = abs(delta[a])
        assert np.all(np.abs(2 * n * q - 2 * k * d) <= n)
        assert np.all(np.diff(q, prepend=0) >= 0)
        assert set(np.unique(trace.dir[trace.axis == a]).tolist()) <= {1 if delta[a] > 0 else -1}


deltas = st.tuples(st.integers(-2500, 2500), st.integers(-2500, 2500), st.integers(-300, 300))


@settings(max_examples=150, deadline=None)
@given(deltas, st.sampled_from([50, 800, 3000, 40000]))
def test_random_lines(delta, feed):
    a = run(delta, feed)
    check_line(delta, a)
    b = run(delta, feed, backend="loop")
    assert a.same_steps(b) and a.total_ticks == b.total_ticks


@pytest.mark.parametrize("delta", [
    (1000, 0, 0), (-1000, 0, 0), (0, 1000, 0), (0, -1000, 0), (0, 0, 300), (0, 0, -300),
    (1000, 1000, 0), (-1000, 1000, 0), (1000, -1000, 0), (-1000, -1000, 0),
    (1000, 300, 0), (300, 1000, 0), (-300, 1000, 0), (-1000, 300, 0),
    (-1000, -300, 0), (-300, -1000, 0), (300, -1000, 0), (1000, -300, 0),
    (7, 3, 2), (1, 0, 0), (1, 1, 1), (2, 1, 0), (0, 0, 0), (3, 2, -1),
])
def test_octants_pure_axes_and_tiny(delta):
    a = run(delta)
    check_line(delta, a)
    assert a.same_steps(run(delta, backend="loop"))


def test_tie_breaking_rounds_halves_toward_the_end():
    # (2, 1): the minor axis ideal after event 1 is 1/2: it steps at event 1.
    trace = run((2, 1, 0))
    assert trace.axis.tolist() == [0, 1, 0]
    assert minor_position(1, 1, 2) == 1
    assert [minor_position(k, 3, 4) for k in range(5)] == [0, 1, 2, 2, 3]  # 3/4 -> 1, 6/4 -> 2 (tie), 9/4 -> 2
    # The closed form is what the Bresenham accumulator produces, for every k.
    for n in range(1, 40):
        for d in range(n + 1):
            e, q = n, 0
            for k in range(1, n + 1):
                e += 2 * d
                if e >= 2 * n:
                    e -= 2 * n
                    q += 1
                assert q == minor_position(k, d, n)
                assert abs(Fraction(q) - Fraction(k * d, n)) <= Fraction(1, 2)


def test_steps_of_one_event_share_a_tick_in_axis_order():
    trace = run((500, -500, 300))
    ticks, counts = np.unique(trace.tick, return_counts=True)
    assert counts.max() == 3
    first = np.searchsorted(trace.tick, ticks)
    for i in first[counts == 3][:10]:
        assert trace.axis[i:i + 3].tolist() == [0, 1, 2]
