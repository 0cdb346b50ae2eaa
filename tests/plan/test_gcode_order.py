"""G-code keeps its order unless --optimize, and only a pen drawing is reordered
(plan/order/gcode_order.py): less travel, the same ink; anything else refused by line."""

from __future__ import annotations

import types
from collections import Counter

import pytest

from galileo_cnc.cli.main import main
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.console.getg import parse_options
from galileo_cnc.job import ArcTo, LineTo, PenDown, PenUp, Rapid
from galileo_cnc.plan.measure import job_lengths
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.plan.planner import PlanError, plan_program
from galileo_cnc.readers import read_file

# four strokes and a dot, in a bad order: back and forth across 60 mm, one arc
BAD_ORDER = """G21 G90
F600
G0 X0 Y0
M3
G1 X10
M5
G0 X60 Y50
M3
G1 X70
M5
G0 X11 Y0
M3
G2 X21 Y0 I5 J0
M5
G0 X61 Y50
Z0
G1 X70 Y40
Z5
G0 X30 Y30
M3
M5
M2
"""


def ink(job) -> Counter:
    """The pen-down strokes of a job in steps, either way round: lines by their ends,
    arcs by centre and ends (clockwise), dots where the pen went down and up."""
    out: Counter = Counter()
    at, down, moved = (0, 0), False, False
    for command in job.commands:
        if isinstance(command, Rapid):                 # lifts the pen itself
            if down and not moved:
                out["dot", at] += 1
            at, down = (command.x_steps, command.y_steps), False
        elif isinstance(command, PenDown):
            down, moved = True, False
        elif isinstance(command, PenUp):
            if down and not moved:
                out["dot", at] += 1
            down = False
        elif isinstance(command, LineTo):
            end = (command.x_steps, command.y_steps)
            out["line", frozenset((at, end))] += 1
            at, moved = end, True
        elif isinstance(command, ArcTo):
            end = (command.x_steps, command.y_steps)
            centre = (at[0] + command.i_steps, at[1] + command.j_steps)
            out[("arc", centre) + ((at, end) if command.cw else (end, at))] += 1
            at, moved = end, True
    return out


@pytest.fixture
def bad(tmp_path):
    path = tmp_path / "bad-order.nc"
    path.write_text(BAD_ORDER)
    return path


def test_without_optimize_gcode_keeps_its_order(bad):
    planned = plan_file(bad)
    assert not planned.job.ordered
    assert planned.job.commands == plan_program(read_file(bad), None,
                                                planned.offset_nm).commands


def test_optimize_cuts_travel_and_draws_the_same(bad):
    filed = plan_file(bad)
    ordered = plan_file(bad, options=PlanOptions(optimize=True))
    assert ordered.job.ordered
    assert ink(ordered.job) == ink(filed.job)
    assert sum(key[0] == "dot" for key in ink(filed.job)) == 1    # M3 M5 at 30, 30
    assert job_lengths(ordered.job).travel_steps < 0.5 * job_lengths(filed.job).travel_steps
    # resume replans a journaled job with its `group` and `ordered`: the same job
    again = plan_file(bad, options=PlanOptions(file_order=True), optimize=True)
    assert again.job.commands == ordered.job.commands


@pytest.mark.parametrize("extra, line, why", [
    ("G4 P0.5\n", 4, "dwell"),
    ("G1 Z-2\nG1 X5\n", 4, "second drawing depth"),
    ("S1000\nG1 X5\nS2000\n", 6, "spindle"),
    ("M0\n", 4, "M0"),
    ("M8\n", 4, "M8"),
    ("T2 M6\n", 4, "tool change"),
    ("G1 X5 F100\n", 4, "second feed"),
    ("G92 X0 Y0\n", 4, "G92"),
    ("G28\n", 4, "G28"),
    ("G91\nG1 Z1\n", 5, "incremental Z"),
])
def test_state_a_reorder_would_break_is_refused_by_line(tmp_path, extra, line, why):
    path = tmp_path / "mill.nc"
    path.write_text("G21 G90\nF600\nG1 Z-1 X1\n" + extra + "G1 X20 Y20\nM2\n")
    plan_file(path)                                   # in its own order it plans
    with pytest.raises(PlanError, match=why) as refused:
        plan_file(path, options=PlanOptions(optimize=True))
    assert f"mill.nc:{line}:" in str(refused.value)


def test_a_pen_file_with_one_pen_height_one_feed_and_one_s_is_reordered(tmp_path):
    path = tmp_path / "pen.nc"
    path.write_text("G21 G90 G92 X0 Y0\nF600 S90\nG0 X0 Y0 Z5\nG1 Z0\nG1 X10\nG0 Z5\n"
                    "G0 X50\nG1 Z0 F600\nG1 X40\nG0 Z5\nM5 S90\nM2\n")
    assert plan_file(path, options=PlanOptions(optimize=True)).job.ordered


def test_the_command_line_and_getg_take_optimize(bad, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))      # plot's journal
    out = tmp_path / "out.nc"
    assert main(["convert", str(bad), "-o", str(out), "--optimize"]) == 0
    assert "paths ordered" in capsys.readouterr().out
    back = plan_file(out, offset="none")             # convert subtracted the offset
    assert ink(back.job) == ink(plan_file(bad, options=PlanOptions(optimize=True)).job)
    mill = tmp_path / "mill.nc"
    mill.write_text("G21 G90\nF600\nG1 Z-1 X1\nG1 Z-2 X2\nM2\n")
    for command in (["info"], ["preview", "-o", str(tmp_path / "p.png")],
                    ["convert", "-o", str(tmp_path / "m.nc")]):
        assert main(command[:1] + [str(mill), "--optimize"] + command[1:]) == 1
        assert "mill.nc:4:" in capsys.readouterr().err
    assert main(["convert", str(bad), "-o", str(out), "--optimize", "--file-order"]) == 1
    # plot: refused by line before connecting, and a pen file plots reordered
    assert main(["plot", str(mill), "--optimize", "--port", "sim://?speed=0", "--yes"]) == 1
    assert "mill.nc:4:" in capsys.readouterr().err
    assert main(["plot", str(bad), "--optimize", "--port", "sim://?speed=0", "--yes"]) == 0
    assert "process has finished" in capsys.readouterr().out
    console = types.SimpleNamespace(config=MachineConfig())
    options, _config, _board, rest = parse_options(console, ["--optimize", "--mode", "centre", "a.nc"])
    assert options.optimize and options.mode == "centre" and rest == ["a.nc"]
