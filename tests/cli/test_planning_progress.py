"""What plot, info, preview and getg show while a large file is inked and planned.

The largest copper layers take seconds per stage (the ink's, then path order)
before the first planning percentage: the front ends hear each stage from
plan_file (on_stage) and say it.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import pytest

from galileo_cnc.cli import plot
from galileo_cnc.cli.plot import PlotOptions, TextProgress, run_plot, stages_on_terminal
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.config.profile import Profile
from galileo_cnc.plan import pipeline
from galileo_cnc.plan.planner import PlanError
from galileo_cnc.plan.pipeline import PlanOptions, plan_file

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
BOARD = SAMPLES / "led-blinker.gbr"
DRAWING = SAMPLES / "square-and-circle.nc"
TWO_PENS = MachineConfig().replace(pen_widths_mm=(0.3, 0.8))


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_the_ink_stages_of_a_large_file_in_order(monkeypatch):
    monkeypatch.setattr(pipeline, "PLANNING_NOTICE_OPS", 1)    # the sample counts as large
    heard: list[str] = []
    plan_file(BOARD, TWO_PENS, on_stage=heard.append)
    assert heard == ["inking: working out the copper",
                     "inking: finding features too narrow to fill",
                     "inking: filling with the 0.8 mm pen",
                     "inking: filling with the 0.3 mm pen",
                     "inking: looking for necks too narrow to fill", "inking: fitting arcs",
                     "ordering the paths to cut pen-up travel"]


def test_a_small_file_plans_without_a_word():
    heard: list[str] = []
    plan_file(BOARD, TWO_PENS, on_stage=heard.append)
    assert heard == []


def test_a_large_drawing_in_file_order_hears_no_stage(monkeypatch):
    monkeypatch.setattr(pipeline, "PLANNING_NOTICE_OPS", 1)
    heard: list[str] = []
    plan_file(DRAWING, options=PlanOptions(file_order=True), on_stage=heard.append)
    assert heard == []                  # no ink, no path order: the percentage says it all
    plan_file(DRAWING, options=PlanOptions(optimize=True), on_stage=heard.append)
    assert heard == ["ordering the paths to cut pen-up travel"]


def test_a_terminal_sees_one_line_rewritten_then_the_planning_percentage():
    screen = Terminal()
    progress = TextProgress(screen)
    progress.stage("inking: working out the copper")
    progress.stage("inking: filling with the 0.3 mm pen")
    progress.planning(0, 10_000)
    progress.planning(10_000, 10_000)
    assert screen.getvalue() == (
        "\rinking: working out the copper ...\x1b[K"
        "\rinking: filling with the 0.3 mm pen ...\x1b[K"
        "\r\x1b[K"                                  # the stage line cleared first
        "planning 10000 operations ..."
        "\rplanning 10000 operations ... 100%\n")


def test_a_log_gets_a_line_per_stage():
    log = io.StringIO()
    progress = TextProgress(log)
    progress.stage("inking: working out the copper")
    progress.end_line()                             # nothing open: nothing written
    assert log.getvalue() == "inking: working out the copper ...\n"


def test_info_and_preview_tell_stages_to_a_terminal_only():
    with stages_on_terminal(io.StringIO()) as on_stage:
        assert on_stage is None                     # stderr piped: stdout stays the result
    screen = Terminal()
    with stages_on_terminal(screen) as on_stage:
        on_stage("inking: fitting arcs")
    assert screen.getvalue() == "\rinking: fitting arcs ...\x1b[K\r\x1b[K"


def test_a_plan_that_fails_leaves_no_stage_line_before_its_error(monkeypatch):
    # the ink plans, then path order and the travel check refuse the job: the error
    # must start on a clean line, not after "inking: fitting arcs ..."
    monkeypatch.setattr(pipeline, "PLANNING_NOTICE_OPS", 1)
    screen = Terminal()
    options = PlotOptions(file=str(BOARD), profile=Profile(TWO_PENS, "sim://?speed=0"),
                          offset="60,0", yes=True)
    with pytest.raises(PlanError, match="would reach"):
        run_plot(options, out=screen)
    assert "\rinking: fitting arcs ...\x1b[K" in screen.getvalue()
    assert screen.getvalue().endswith("\r\x1b[K")


def test_plot_times_a_large_job_beside_opening_the_port_with_the_same_estimate(
        monkeypatch, tmp_path):
    # the job's timing in a second process while the port opens (forked at 0 commands
    # here), or here: the same estimate, and the job runs to its end either way
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    made = []

    class Spy(plot.Deferred):
        def __init__(self, fn, *args, fork=True):
            made.append((fn.__name__, fork))
            super().__init__(fn, *args, fork=fork)
    monkeypatch.setattr(plot, "Deferred", Spy)
    estimates = []
    for threshold in (0, 10 ** 9):
        monkeypatch.setattr(plot, "BACKGROUND_COMMANDS", threshold)
        out = io.StringIO()
        options = PlotOptions(file=str(BOARD), profile=Profile(MachineConfig(), "sim://?speed=0"),
                              yes=True, mode="centre")
        assert run_plot(options, out=out) == 0
        assert "process has finished" in out.getvalue()
        estimates.append(re.search(r"\d+ commands, about .+ of machine time",
                                   out.getvalue()).group(0))
    assert made == [("job_timing", True), ("job_timing", False)]
    assert estimates[0] == estimates[1]
