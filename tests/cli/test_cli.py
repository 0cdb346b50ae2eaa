"""The galileo-cnc command as a user runs it: a real subprocess."""

import json
import re
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from PIL import Image

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine import Trace, simulate
from galileo_cnc.machine.timing import duration_text, job_timing
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.preview.render import UNINKED
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.readers import read_file

ROOT = Path(__file__).resolve().parents[2]


def galileo(*args: str, home: Path | None = None, stdin: str = "") -> subprocess.CompletedProcess:
    env = dict(os.environ, GALILEO_CNC_NO_PROBE="1")
    if home is not None:
        env["GALILEO_CNC_HOME"] = str(home)
    return subprocess.run([sys.executable, "-m", "galileo_cnc", *args], cwd=ROOT, env=env,
                          input=stdin, capture_output=True, text=True, timeout=120)


def test_info_json_of_the_sample_board():
    result = galileo("info", "samples/led-blinker.gbr", "--json", "--margin", "2")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    assert (info["format"], info["units"], info["format_spec"]) == ("gerber", "mm", "4.6")
    assert info["counts"] == {"draws": 12, "arcs": 3, "flashes": 10, "regions": 1}
    assert info["bbox_mm"] == {"min_x": 6.0, "min_y": 5.0, "max_x": 46.0, "max_y": 36.0}
    assert info["bbox_with_apertures_mm"]["min_y"] == 4.8  # the 0.4 mm track at Y 5
    assert info["proposed_offset_mm"] == {"x": 4.0, "y": 3.0}
    d13 = next(a for a in info["apertures"] if a["code"] == 13)
    assert (d13["description"], d13["draws"], d13["arcs"]) == ("0.4 mm round", 7, 1)


def test_info_text_of_a_gcode_drawing():
    result = galileo("info", "samples/square-and-circle.nc")
    assert result.returncode == 0, result.stderr
    assert "format      gcode" in result.stdout and "4 draws, 1 arcs" in result.stdout


def test_info_names_the_units_a_drawing_is_in(tmp_path, capsys):
    # a DXF in metres said "units mm" (issue 31, item 1): its own unit, read exactly
    import ezdxf
    from galileo_cnc.cli.main import main
    drawing = ezdxf.new()
    drawing.header["$INSUNITS"] = 6                       # metres
    drawing.modelspace().add_line((0, 0), (0.04, 0.025))
    drawing.saveas(tmp_path / "part.dxf")
    assert main(["info", str(tmp_path / "part.dxf"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["units"] == "m" and summary["bbox_mm"] == {
        "min_x": 0.0, "min_y": 0.0, "max_x": 40.0, "max_y": 25.0}


def test_bad_files_give_one_line_with_the_position_and_exit_1(tmp_path):
    broken = tmp_path / "broken.gbr"
    broken.write_text("%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.1*%\nD11*\n")
    result = galileo("info", str(broken))
    assert result.returncode == 1
    assert result.stderr.startswith(f"galileo-cnc: {broken}:4:1: aperture D11 is used but not defined")
    assert "Traceback" not in result.stderr

    result = galileo("info", str(tmp_path / "missing.gbr"))
    assert result.returncode == 1 and "cannot read" in result.stderr

    notes = tmp_path / "notes.txt"
    notes.write_text("shopping list: pens, paper\n")
    result = galileo("info", str(notes))
    assert result.returncode == 1 and "neither a Gerber RS-274X, a G-code nor a DXF file" \
        in result.stderr


def test_plot_the_sample_board_on_sim_with_trace_and_preview(tmp_path):
    trace_file, png = tmp_path / "board.npz", tmp_path / "board.png"
    result = galileo("plot", "samples/led-blinker.gbr", "--port", "sim://?speed=0", "--yes",
                     "--mode", "centre", "--trace", str(trace_file), "--preview", str(png),
                     home=tmp_path)
    assert result.returncode == 0, result.stderr
    out = result.stdout
    planned = plan_file(ROOT / "samples" / "led-blinker.gbr", options=PlanOptions(mode="centre"))
    seconds = job_timing(planned.job.commands).total_s
    assert "connected to sim://?speed=0 (built-in simulated machine)" in out
    assert "minimum X 6.000 mm, Y 5.000 mm; offset 5.000, 4.000 mm" in out
    assert f"{len(planned.job)} commands, about {duration_text(seconds)} of machine time" in out
    assert out.count("insert pen for aperture") == 6
    assert "insert pen for aperture D13 (0.4 mm round)" in out
    assert "process has finished" in out and "\a" in out
    assert Trace.load(trace_file).same_steps(simulate(planned.job.commands))
    with Image.open(png) as image:
        assert image.size == (908, 724)
    assert json.loads((tmp_path / "journal.json").read_text())["state"] == "finished"


def test_plot_inks_the_sample_board_with_two_pens(tmp_path):
    trace_file, png = tmp_path / "board.npz", tmp_path / "board.png"
    result = galileo("plot", "samples/led-blinker.gbr", "--port", "sim://?speed=0", "--yes",
                     "--pens", "0.3,0.8", "--trace", str(trace_file), "--preview", str(png),
                     home=tmp_path)
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "ink: pens 0.8, 0.3 mm, " in out and "% of the copper inked" in out
    assert out.count("insert the ") == 2
    assert out.index("insert the 0.8 mm pen") < out.index("insert the 0.3 mm pen")
    config = MachineConfig().replace(pen_widths_mm=(0.3, 0.8))
    planned = plan_file(ROOT / "samples" / "led-blinker.gbr", config)
    assert planned.mode == "ink"
    assert Trace.load(trace_file).same_steps(simulate(planned.job.commands))
    journal = json.loads((tmp_path / "journal.json").read_text())
    assert journal["mode"] == "ink" and "widths_mm = [0.8, 0.3]" in journal["profile"]
    # the preview measures the ink against the copper: almost none left bare or spilt
    found = re.search(r"([\d.]+) mm² copper uninked, ([\d.]+) mm² ink outside", out)
    assert found, out
    copper_mm2 = planned.ink.copper_nm2 / NM_PER_MM ** 2
    assert float(found[1]) < 0.01 * copper_mm2 and float(found[2]) < 0.005 * copper_mm2
    with Image.open(png) as image:
        pixels = np.asarray(image.convert("RGB")).reshape(-1, 3)
    bare_px = np.all(pixels == UNINKED, axis=1).sum()
    assert bare_px <= float(found[1]) * 20 ** 2 * 2      # 20 px/mm, and the outlines' share


def test_plot_waits_for_enter_at_pen_changes_without_yes(tmp_path):
    result = galileo("plot", "samples/led-blinker.gbr", "--port", "sim://?speed=0",
                     "--mode", "centre", "--offset", "4,3", home=tmp_path, stdin="\n" * 6)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("then press Enter") == 6
    assert "offset 4.000, 3.000 mm" in result.stdout


def test_plot_refuses_bad_offsets_and_jobs_past_the_travel(tmp_path):
    result = galileo("plot", "samples/led-blinker.gbr", "--offset", "4;3", home=tmp_path)
    assert result.returncode == 1
    assert "--offset: expected auto, none or X,Y in mm" in result.stderr
    result = galileo("plot", "samples/led-blinker.gbr", "--offset", "10,0", "--yes",
                     "--mode", "centre", "--port", "sim://?speed=0", home=tmp_path)
    assert result.returncode == 1
    assert result.stderr.startswith("galileo-cnc: ") and (
        ":75:1: the line from X 6 Y 36 to X 6 Y 32 mm (file coordinates): " in result.stderr)
    assert "X would reach" in result.stderr and "Traceback" not in result.stderr


PAD = ("%FSLAX46Y46*%\n%MOMM*%\n%ADD10R,2X2*%\nD10*\nX10000000Y10000000D03*\n"
       "X20000000Y10000000D03*\nM02*\n")


def test_info_and_plot_propose_one_offset_in_ink_mode(tmp_path):
    # two 2 mm pads: their flash points are at X 10 and 20, the ink reaches X 9.202 (the
    # pad's edge at 9, the 0.4 mm pen's radius, the 2 um edge margin): the proposal
    # keeps the margin from the ink, as getg's does, and info says so once it planned
    board = tmp_path / "pads.gbr"
    board.write_text(PAD)
    text = galileo("info", str(board), home=tmp_path).stdout
    assert "offset      X 9.0000 mm, Y 9.0000 mm" in text
    assert "info --plan gives the offset getg and plot propose" in text
    planned = galileo("info", str(board), "--plan", home=tmp_path).stdout
    assert "minimum     X 9.2020 mm, Y 9.2020 mm (where the pen goes, fills included)" \
        in planned
    assert "offset      X 8.2020 mm, Y 8.2020 mm" in planned
    info = json.loads(galileo("info", str(board), "--plan", "--json", home=tmp_path).stdout)
    assert info["proposed_offset_mm"] == info["ink"]["proposed_offset_mm"] == \
        {"x": 8.202, "y": 8.202}
    plotted = galileo("plot", str(board), "--yes", "--port", "sim://?speed=0", home=tmp_path)
    assert plotted.returncode == 0, plotted.stderr
    assert "minimum X 9.202 mm, Y 9.202 mm; offset 8.202, 8.202 mm" in plotted.stdout


def test_a_negative_offset_is_taken_as_typed(tmp_path):
    # "-1,-1" looks like no number to argparse, which took it for an option
    result = galileo("plot", "samples/square-and-circle.nc", "--offset", "-1,-1", "--yes",
                     "--port", "sim://?speed=0", home=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "offset -1.000, -1.000 mm" in result.stdout


def test_a_profile_sets_the_machine_and_the_port(tmp_path):
    profile = tmp_path / "profile.toml"
    profile.write_text('[machine]\nx_travel_mm = 30.0\n[serial]\nport = "sim://?speed=0"\n')
    # the board is 40 mm wide: the profile's 30 mm travel refuses it before any planning
    result = galileo("plot", "samples/led-blinker.gbr", "--yes", home=tmp_path)
    assert result.returncode == 1
    assert "the job is 40.0 mm wide" in result.stderr
    assert "the machine's travel is 30 mm (x_travel_mm in the profile)" in result.stderr
    # info still tells all about it, the ink too, and says it does not fit
    result = galileo("info", "samples/led-blinker.gbr", "--json", "--plan", home=tmp_path)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert "the job is 40.0 mm wide" in summary["misfit"]
    roomy = json.loads(galileo("info", "samples/led-blinker.gbr", "--json", "--plan").stdout)
    assert roomy["misfit"] is None
    assert summary["ink"]["inked_mm2"] == roomy["ink"]["inked_mm2"] > 0
    text = galileo("info", "samples/led-blinker.gbr", home=tmp_path).stdout
    assert "travel      does not fit: the job is 40.0 mm wide" in text
    result = galileo("plot", "samples/square-and-circle.nc", "--yes", home=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "connected to sim://?speed=0" in result.stdout
    profile.write_text('[serial]\nbaud = 1234\n')
    result = galileo("plot", "samples/square-and-circle.nc", home=tmp_path)
    assert result.returncode == 1 and "baud rate 1234 not supported" in result.stderr


def test_preview_of_a_gcode_drawing(tmp_path):
    png = tmp_path / "drawing.png"
    result = galileo("preview", "samples/square-and-circle.nc", "-o", str(png))
    assert result.returncode == 0, result.stderr
    assert "2 pen strokes, 111.4 mm drawn" in result.stdout
    with Image.open(png) as image:
        pixels = np.asarray(image.convert("RGB"))
    assert pixels.shape[2] == 3 and (pixels.sum(axis=2) < 300).any()    # dark pen strokes


def test_ports_always_lists_the_simulated_machine():
    result = galileo("ports")
    assert result.returncode == 0, result.stderr
    assert "sim://" in result.stdout and "built-in simulated machine" in result.stdout


def test_plot_resume_continues_the_interrupted_job(tmp_path, monkeypatch):
    """In one process: `sim://NAME` machines keep power only within a process."""
    from galileo_cnc.cli.main import main
    from galileo_cnc.stream.journal import Journal
    from galileo_cnc.transport.link import MachineLink, PortGone
    from galileo_cnc.sim.simulator import forget_named_machines, named_machine
    from galileo_cnc.stream.streamer import JobStreamer
    from galileo_cnc.transport.port import open_port

    from faults import FaultyPort

    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    forget_named_machines()
    url = "sim://cli?speed=0"
    program = read_file(ROOT / "samples" / "led-blinker.gbr")
    job = plan_program(program, None, proposed_offset(program))
    link = MachineLink.attach(FaultyPort(open_port(url, timeout=0.1), die_after=20), url)
    try:
        JobStreamer(link, job, program, journal=Journal.default()).run()
    except PortGone:
        pass
    link.close()
    assert main(["plot", str(ROOT / "samples" / "led-blinker.gbr"), "--resume", "--yes",
                 "--port", url]) == 0
    assert named_machine("cli").trace().same_steps(simulate(job.commands))
    assert main(["plot", str(ROOT / "samples" / "led-blinker.gbr"), "--resume", "--yes",
                 "--port", url]) == 1         # nothing left to resume
    forget_named_machines()


def test_dxf_layers_and_units_on_the_command_line(tmp_path):
    import ezdxf

    drawing = ezdxf.new()                       # no $INSUNITS: read as mm unless told
    drawing.header["$INSUNITS"] = 0
    space = drawing.modelspace()
    space.add_line((0, 0), (2, 0), dxfattribs={"layer": "OUTLINE"})
    space.add_line((2, 0), (2, 1), dxfattribs={"layer": "OUTLINE"})
    space.add_circle((1, 3), 0.5, dxfattribs={"layer": "HOLES"})
    path = tmp_path / "panel.dxf"
    drawing.saveas(path)

    result = galileo("info", str(path))
    assert result.returncode == 0, result.stderr
    assert "layers      4 (--layers A,B picks them)" in result.stdout
    assert re.search(r"OUTLINE +2 entities", result.stdout)
    assert re.search(r"HOLES +1 entities", result.stdout)

    result = galileo("info", str(path), "--layers", "outline", "--units", "in", "--json")
    info = json.loads(result.stdout)
    assert info["selected_layers"] == ["OUTLINE"] and info["counts"]["draws"] == 2
    assert info["bbox_mm"] == {"min_x": 0.0, "min_y": 0.0, "max_x": 50.8, "max_y": 25.4}

    trace_file = tmp_path / "panel.npz"
    result = galileo("plot", str(path), "--layers", "OUTLINE", "--units", "in", "--yes",
                     "--port", "sim://?speed=0", "--offset", "none", "--trace", str(trace_file),
                     home=tmp_path)
    assert result.returncode == 0, result.stderr
    journal = json.loads((tmp_path / "journal.json").read_text())
    assert journal["layers"] == ["OUTLINE"] and journal["units"] == "in"   # resume reads so
    config = MachineConfig()
    where = Trace.load(trace_file).positions()
    drawn = where[where[:, 2] == config.pen_down_z_steps]
    assert drawn[:, 0].max() == round(50.8 * config.steps_per_mm)        # 2 in, not 2 mm
    assert drawn[:, 1].max() == round(25.4 * config.steps_per_mm)        # no circle at 3 in

    result = galileo("info", str(path), "--layers", "NOPE")
    assert result.returncode == 1 and "NOPE" in result.stderr and "OUTLINE" in result.stderr
    result = galileo("info", "samples/led-blinker.gbr", "--layers", "TOP")
    assert result.returncode == 1
    assert "--layers and --units are for DXF drawings; this is a Gerber file" in result.stderr


def test_a_bare_d02_before_the_first_coordinate_moves_nowhere(tmp_path):
    # issue 31, item 2: a P-CAD board far from the origin starts with `D10*` `D02*`; that
    # D02 names no point, so it adds nothing to the job's box and no travel to (0, 0)
    board = tmp_path / "far.gbr"
    board.write_text("%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.5*%\nD10*\nD02*\n"
                     "X300000000Y300000000D02*\nX310000000Y300000000D01*\nD02*\nM02*\n")
    info = json.loads(galileo("info", str(board), "--json", home=tmp_path).stdout)
    assert info["bbox_mm"] == {"min_x": 300.0, "min_y": 300.0, "max_x": 310.0, "max_y": 300.0}
    assert info["proposed_offset_mm"] == {"x": 299.0, "y": 299.0}
    assert info["misfit"] is None
    result = galileo("plot", str(board), "--yes", "--mode", "centre", "--port", "sim://?speed=0",
                     home=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "process has finished" in result.stdout


def test_info_sums_up_many_warnings_and_plans_only_on_request(tmp_path, capsys,
                                                              monkeypatch):
    # issue 31, item 13: info printed every warning (1,950 lines for one layer) and
    # planned the whole job (50 s on a 1.4 MB layer) for figures nobody asked for
    from galileo_cnc.cli.main import main
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))      # no profile of the user

    def info(*args) -> str:
        assert main(["info", *map(str, args)]) == 0
        return capsys.readouterr().out

    drawing = tmp_path / "mcodes.nc"
    drawing.write_text("G21 G90\nG1 X0 Y0 F300\n" + "".join(
        f"M1{k:02d}\nG1 X{k} Y0\n" for k in range(1, 31)) + "M2\n")
    text = info(drawing).splitlines()
    assert "warnings    30" in text
    shown = [line for line in text if ": warning: unknown M code" in line]
    assert len(shown) == 10 and shown[0].endswith("mcodes.nc:3:1: warning: unknown M code "
                                                  "M101 is ignored  [M101]")
    assert text[-1] == "  ... and 20 more (--verbose lists them all)"
    assert text[-13].startswith("plan        --plan works out the job")
    every = info(drawing, "--verbose")
    assert every.count(": warning: unknown M code") == 30 and "--verbose lists" not in every
    # the plan's figures on request only
    assert "ink" not in json.loads(info(ROOT / "samples" / "led-blinker.gbr", "--json"))
    planned = json.loads(info(drawing, "--json", "--plan"))
    assert planned["plan"]["pen_down_mm"] >= 30.0 and "ink" not in planned
    assert "ink         pens 0.4 mm: copper" in info(ROOT / "samples" / "led-blinker.gbr",
                                                      "--plan")
