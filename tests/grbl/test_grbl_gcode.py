"""A planned Job as GRBL G-code: mm words GRBL rounds back to the job's steps,
arcs as G2/G3, feeds in mm/min, short lines, the pen as Z or as a servo."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from galileo_cnc import job as J
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.grbl.gcode import (
    MAX_LINE_CHARS, PREAMBLE, AxisScale, GcodeError, GrblPen, expected_end_steps,
    job_to_gcode, pen_from_config, source_of,
)
from galileo_cnc.plan.pipeline import PlanOptions, plan_file

REPO = Path(__file__).resolve().parents[2]
SCALE = AxisScale.from_texts(["160.000"] * 3)


def make_job(*commands) -> J.Job:
    job = J.Job(source="test", offset_nm=(0, 0))
    for c in commands:
        job.add(c, J.NO_OP, 0)
    return job


def test_small_job_words_and_feeds():
    job = make_job(J.Rapid(160, 320), J.PenDown(), J.SetFeed(16000), J.LineTo(1601, 320),
                   J.ArcTo(1601, 1920, 0, 800, cw=False), J.Dwell(250), J.EndJob())
    lines = job_to_gcode(job, SCALE, GrblPen(up_z_steps=300, down_z_steps=0,
                                             z_feed_steps_per_s=8000),
                         feed_steps_per_s=800)
    assert [line.text for line in lines] == [
        "G21 G90 G17 G94 G54",
        "G1 Z1.875 F3000",          # pen up first: its height was unknown
        "G0 X1 Y2",
        "G1 Z0",
        "G1 X10.006 F6000",          # 16000 steps/s at 160 steps/mm = 6000 mm/min
        "G3 Y12 I0 J5",
        "G4 P0.25",
        "G1 Z1.875 F3000",
    ]
    assert [line.command for line in lines] == [PREAMBLE, 0, 0, 1, 3, 4, 5, 6]
    assert expected_end_steps(lines, SCALE) == [(0, 0, 300), (160, 320, 300), (160, 320, 0),
                                                (1601, 320, 0), (1601, 1920, 0),
                                                (1601, 1920, 300)]


def test_servo_pen_dwells_after_every_change():
    job = make_job(J.Rapid(0, 0), J.PenDown(), J.LineTo(10, 0), J.Flash(dwell_ms=40),
                   J.EndJob())
    pen = GrblPen(servo=True, down_s=900, up_s=None, servo_dwell_ms=150)
    text = [line.text for line in job_to_gcode(job, SCALE, pen, feed_steps_per_s=1600)]
    assert text == ["G21 G90 G17 G94 G54", "M5", "G4 P0.15", "G0 X0 Y0", "M3 S900",
                    "G4 P0.15", "G1 X0.062 F600", "G4 P0.04", "M5", "G4 P0.15"]
    # Flash with the pen already down keeps it down for the dwell, then lifts
    assert "Z" not in " ".join(text)


def test_full_circle_names_its_end_point_and_off_circle_end_is_corrected():
    job = make_job(J.Rapid(1000, 0), J.PenDown(),
                   J.ArcTo(1000, 0, -1000, 0, cw=True),
                   # 3 steps off the start circle (r = 100 steps): GRBL would refuse it
                   J.ArcTo(1000, 103, -100, 0, cw=False))
    lines = job_to_gcode(job, SCALE, GrblPen(), feed_steps_per_s=1600)
    text = [line.text for line in lines]
    assert text[4] == "G2 X6.25 Y0 I-6.25 J0 F600"
    assert text[5].startswith("G3 ") and text[6] == "G1 X6.25 Y0.644"
    arc_end = expected_end_steps(lines, SCALE)[-2]
    assert abs((arc_end[0] - 900) ** 2 + arc_end[1] ** 2 - 100 ** 2) <= 2 * 100


def test_lines_fit_grbls_buffer_and_arcs_stay_arcs():
    config = MachineConfig()
    planned = plan_file(REPO / "samples" / "led-blinker.gbr", config,
                        options=PlanOptions(mode="centre"))
    lines = job_to_gcode(planned.job, SCALE, pen_from_config(config),
                         feed_steps_per_s=config.feed_steps_per_s,
                         flash_dwell_ms=config.flash_dwell_ms)
    assert max(len(line.text) for line in lines) <= MAX_LINE_CHARS
    arcs = Counter(type(c).__name__ for c in planned.job.commands)["ArcTo"]
    assert arcs > 0
    assert sum(line.text.split()[0] in ("G2", "G3") for line in lines) == arcs
    places = {source_of(planned.plotted, planned.job, line.command) for line in lines}
    assert any(p.endswith("led-blinker.gbr:" + p.rsplit(":", 1)[-1]) and
               p.rsplit(":", 1)[-1].isdigit() for p in places if p)


def test_a_move_without_a_position_for_an_arc_is_refused():
    with pytest.raises(GcodeError, match="before any position"):
        job_to_gcode(make_job(J.ArcTo(10, 0, 5, 0, cw=True)), SCALE, GrblPen(),
                     feed_steps_per_s=1600)
