"""The time estimate from a model of GRBL's planner (grbl/estimate.py): exact on
cases with a closed form, and within 5 % (the issue's target) of the real GRBL
1.1h in simavr, first step to last step from its pins, on a small job and on a
corpus board (measured: 0.977 and 0.973, docs/grbl.md). The corpus board's test is
in test_grbl_simavr.py: it measures the run whose pins are checked there, streamed
once for both."""

from __future__ import annotations

import pytest
from grbl_support import (CONFIG, ESTIMATE_TOLERANCE as TOLERANCE, SCALE, SETTINGS,
                          estimate_and_pins, grbl_machine)

from galileo_cnc import job as J
from galileo_cnc.grbl.estimate import Machine, estimate
from galileo_cnc.grbl.gcode import job_to_gcode, pen_from_config
from galileo_cnc.grbl.reports import GrblSettings
from galileo_cnc.grbl.stream import stream


def machine(**changes) -> Machine:
    texts = {1: "25", 11: "0.010", **SETTINGS, **{int(k[1:]): v for k, v in changes.items()}}
    return Machine.from_settings(GrblSettings(texts))


def test_one_line_is_a_trapezoid():
    # 50 mm at 100 mm/s, 2000 mm/s^2: 0.05 s up, 0.05 s down (2.5 mm each), 45 mm cruise
    e = estimate(["G21 G90", "G1 X50 F6000"], machine())
    assert e.motion_span_s == pytest.approx(0.55, rel=1e-9) and e.blocks == 1
    # too short to cruise: 2 * sqrt(d / a)
    e = estimate(["G1 X2 F6000"], machine())
    assert e.motion_span_s == pytest.approx(2 * (2 / 2000) ** 0.5, rel=1e-9)
    # G0 at the axis' max rate ($110 8000 mm/min), limited per axis on a diagonal
    assert estimate(["G0 X50"], machine()).motion_span_s > estimate(["G0 X50 Y50"], machine(
    )).motion_span_s * 0.7


def test_junctions_dwells_and_stops():
    straight = estimate(["G1 X25 F6000", "G1 X50"], machine()).motion_span_s
    assert straight == pytest.approx(0.55, rel=1e-9)          # no slowdown straight on
    reverse = estimate(["G1 X25 F6000", "G1 X0"], machine()).motion_span_s
    assert reverse == pytest.approx(2 * estimate(["G1 X25 F6000"], machine()).motion_span_s)
    corner = ["G1 X25 F6000", "G1 X25 Y25"]
    tight, loose = (estimate(corner, machine(**{"$11": jd})).motion_span_s
                    for jd in ("0.001", "0.1"))
    assert straight < loose < tight < reverse
    # a G4 stops, holds the motors $1 ms, then sleeps in 50 ms slices
    e = estimate(["G1 X25 F6000", "G4 P0.02", "G1 X0"], machine())
    assert e.dwell_s == pytest.approx(0.05) and e.idle_lock_s == pytest.approx(0.05)
    assert e.motion_span_s == pytest.approx(reverse + 0.025 + 0.05)
    assert estimate(["G4 P0.1"], machine()).seconds == pytest.approx(0.1)


def test_arc_is_split_by_arc_tolerance():
    arc = ["G0 X10", "G2 X-10 I-10 J0 F600"]                  # half circle at 10 mm/s
    fine, coarse = (estimate(arc, machine(**{"$12": t})) for t in ("0.0005", "0.01"))
    assert fine.blocks > coarse.blocks > 10
    # slow enough that junctions barely matter: pi * 10 mm at 10 mm/s, + the G0
    g0 = estimate(["G0 X10"], machine()).motion_span_s
    assert fine.motion_span_s - g0 == pytest.approx(3.14159, rel=0.01)


def measured(lines) -> tuple[float, float]:
    """(estimate, simavr) seconds from the first step to the last."""
    with grbl_machine() as (board, link):
        model = Machine.from_settings(link.settings, link.build.planner_blocks)
        result = stream(link, lines)
        board.stop()
    assert result.errors == [] and link.alarms == []
    return estimate_and_pins(lines, model, board.trace())


def test_estimate_matches_grbl_in_simavr_small_job():
    job = J.Job(source="test", offset_nm=(0, 0))
    commands = [J.Rapid(800, 800), J.PenDown(), J.SetFeed(12000)]
    for dx, dy in [(803, 311), (-311, 803), (-803, -311), (500, 0), (0, 500)]:
        commands += [J.LineTo(800 + dx, 800 + dy), J.LineTo(800, 800)]
    commands += [J.ArcTo(1600, 800, 400, 0, cw=True), J.ArcTo(800, 800, -400, 0, cw=False),
                 J.Flash(), J.Dwell(120), J.Rapid(3000, 200), J.EndJob()]
    for c in commands:
        job.add(c, J.NO_OP, 0)
    lines = job_to_gcode(job, SCALE, pen_from_config(CONFIG), feed_steps_per_s=8000,
                         flash_dwell_ms=20)
    model, sim = measured(lines)
    print(f"small job: estimate {model:.4f} s, simavr {sim:.4f} s, ratio {model / sim:.4f}")
    assert abs(model / sim - 1) <= TOLERANCE
