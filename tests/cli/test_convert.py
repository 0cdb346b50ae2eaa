"""`galileo-cnc convert`: the plot as G-code that reads back to the same drawing.

The converted file is read with our G-code reader, planned as it is (offset none,
file order) and stepped by the reference machine; its pen-down runs must be the
original plan's, point for point and in the same order."""

from __future__ import annotations

from pathlib import Path

from corpus import DXF_CORPUS, corpus_file
from test_cli import galileo

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
