"""`galileo-cnc convert`: the plot as G-code that reads back to the same drawing.

The converted file is read with our G-code reader, planned as it is (offset none,
file order) and stepped by the reference machine; its pen-down runs must be the
original plan's, point for point and in the same order."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from corpus import DXF_CORPUS, corpus_file
from test_cli import galileo
from test_transform import shell  # noqa: F401  (the fixture)

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine import simulate
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.readers import read_file

ROOT = Path(__file__).resolve().parents[2]
BOARD = ROOT / "samples" / "led-blinker.gbr"


def pen_down_runs(job, config: MachineConfig) -> list[list[tuple[int, int]]]:
    """Each pen-down stretch of the machine's steps as XY points (repeats dropped)."""
    where = simulate(job.commands, config).positions()
    runs, current = [], []
    for x, y, z in where.tolist():
        if z == config.pen_down_z_steps:
            if not current or current[-1] != (x, y):
                current.append((x, y))
        elif current:
            runs.append(current)
            current = []
    return runs + ([current] if current else [])


def converted_and_back(tmp_path, source: Path, *args: str, config=MachineConfig()):
    out = tmp_path / "out.nc"
    result = galileo("convert", str(source), "-o", str(out), *args, home=tmp_path)
    assert result.returncode == 0, result.stderr
    program = read_file(out)
    assert program.format == "gcode" and program.warnings == []
    back = plan_file(program, config, "none", options=PlanOptions(file_order=True))
    return result.stdout, out.read_text(), back


def test_the_sample_board_in_centre_mode_reads_back_to_the_same_plot(tmp_path):
    stdout, text, back = converted_and_back(tmp_path, BOARD, "--mode", "centre")
    planned = plan_file(BOARD, options=PlanOptions(mode="centre"))
    assert planned.job.ordered
    config = MachineConfig()
    assert pen_down_runs(back.job, config) == pen_down_runs(planned.job, config)
    # one pen change per aperture, each a T word and a pause GRBL understands
    assert text.count(" M0") == 0 and text.count("\nM0\n") == len(planned.job.pen_changes) == 6
    assert "T5 ; insert pen for aperture D13 (0.4 mm round)" in text
    assert len(back.job.pen_changes) == len(planned.job.pen_changes)
    lines = len(text.splitlines())
    assert stdout.startswith(f"{tmp_path / 'out.nc'}: {lines} lines, ")
    assert "paths ordered" in stdout


def test_ink_with_two_pens_reads_back_to_the_same_plot(tmp_path):
    stdout, text, back = converted_and_back(tmp_path, BOARD, "--pens", "0.3,0.8")
    config = MachineConfig().replace(pen_widths_mm=(0.3, 0.8))
    planned = plan_file(BOARD, config)
    assert pen_down_runs(back.job, config) == pen_down_runs(planned.job, config)
    assert text.index("T1 ; insert the 0.8 mm pen") < text.index("T2 ; insert the 0.3 mm pen")
    assert "ink mode" in stdout


def test_a_dxf_drawing_converts_with_its_arcs(tmp_path):
    # 13 lines and 9 arcs like the seed's CAD2G example: chained into one stroke
    drawing = corpus_file("autocad/ezdxf-AC1003_LINE_Example.dxf", DXF_CORPUS)
    stdout, text, back = converted_and_back(tmp_path, drawing)
    planned = plan_file(drawing)
    config = MachineConfig()
    assert pen_down_runs(back.job, config) == pen_down_runs(planned.job, config)
    assert text.count("\nG2 ") + text.count("\nG3 ") == 9
    # the profile's pen is on Z (grbl_pen = "z"): lowered once, to Z0
    assert "1 pen lift (" in stdout and text.count("\nG1 Z0 F300\n") == 1


# ---- the pen as the profile moves it (issue 31, item 5) ---------------------------------------
#: a drawing with a dwell between two strokes (G4 P300: this reader's milliseconds)
DOT_AND_DASH = ("G21 G90\nG0 X1 Y1\nM3\nG1 X6 Y1 F3000\nG4 P300\nG1 X6 Y3\nM5\n"
                "G0 X8 Y1\nM3\nG1 X9 Y1\nM5\n")


def test_grbl_with_its_pen_on_z_moves_the_pen_for_a_converted_file(tmp_path, shell):
    """The user converts for a GRBL plotter whose pen is on Z (the profile's default
    grbl_pen = "z") and streams the file as UGS or CNCjs would: GRBL in simavr lowers
    and lifts Z for each stroke, and dwells the file's 300 ms (G4 P0.3: seconds)."""
    sys.path[:0] = [str(Path(__file__).resolve().parents[1] / "grbl")]
    from grbl_support import (F_CPU, PROFILE, check_trace, grbl_machine, positions,
                              positions_and_ticks)
    from galileo_cnc.simavr.board import CYCLES_PER_TICK
    from galileo_cnc.grbl.gcode import GcodeLine
    from galileo_cnc.grbl.stream import stream

    source, profile = tmp_path / "dash.nc", tmp_path / "fast.toml"
    source.write_text(DOT_AND_DASH)
    profile.write_text(PROFILE)
    out = tmp_path / "dash-grbl.nc"
    result = shell("convert", str(source), "--offset", "none", "--profile", str(profile),
                   "-o", str(out))
    assert result.returncode == 0, result.stderr
    text = out.read_text()
    assert "M3" not in text and "G4 P0.3\n" in text
    lines = [GcodeLine(line.split(";")[0].strip(), number)
             for number, line in enumerate(text.splitlines()) if line.split(";")[0].strip()]
    with grbl_machine() as (board, link):
        stream(link, lines)
        board.stop()
    where = positions(board)
    check_trace(where, lines)
    z = where[:, 2]
    up = MachineConfig().pen_up_z_steps                  # 300 steps: 1.875 mm
    # up first, then down and up again for each of the two strokes
    changes = z[np.r_[True, np.diff(z) != 0]]
    assert [int(v) for v in changes if v in (0, up)] == [0, up, 0, up, 0, up]
    where, ticks = positions_and_ticks(board.trace())
    # the head at X6 Y1 with the pen down, then its first step towards Y3: the dwell
    at = int(np.flatnonzero(np.all(where == (960, 160, 0), axis=1))[-1])
    assert tuple(where[at + 1]) == (960, 161, 0)
    assert (ticks[at + 1] - ticks[at]) * CYCLES_PER_TICK >= 0.3 * F_CPU


def test_the_pen_can_be_a_servo_or_the_spindle_and_the_dwell_in_ms_for_galileo(tmp_path, shell):
    source = tmp_path / "dash.nc"
    source.write_text(DOT_AND_DASH)
    texts = {}
    for options in (("--pen", "servo"), ("--pen", "spindle"), ("--target", "galileo")):
        out = tmp_path / f"dash{options[1]}.nc"
        result = shell("convert", str(source), "-o", str(out), *options)
        assert result.returncode == 0, result.stderr
        texts[options[1]] = out.read_text()
    # the profile's servo: M3 S1000 down, M5 up, each followed by its 150 ms
    assert "\nM3 S1000\nG4 P0.15\nG1 X" in texts["servo"] and "\nM5\nG4 P0.15\n" in texts["servo"]
    assert "\nM3\nG1 X" in texts["spindle"] and "G4 P0.3\n" in texts["spindle"]
    assert "G4 P300\n" in texts["galileo"] and "\nG1 Z0 F300\n" in texts["galileo"]
    # what galileo-cnc reads back from its own target: the 300 ms
    back = read_file(tmp_path / "dashgalileo.nc")
    assert 300 in back.table[back.table[:, 0] == 8, 6].tolist()       # DWELL, value (ms)
