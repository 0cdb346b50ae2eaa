"""--scale, --rotate and --fit (issue 31, item 20): a drawing too big for the machine is
scaled to fit, turned, or both, exactly in integer nm, before the offset, in every front
end (plot, preview, convert, info, and the console's getg)."""

from __future__ import annotations

import json
import sys
from fractions import Fraction
from pathlib import Path
from types import SimpleNamespace

import ezdxf
import numpy as np
import pytest

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine import Trace
from galileo_cnc.plan.pipeline import PlanOptions, load_artwork, plan_file
from galileo_cnc.plan.transform import Transform, TransformError, parse_scale
from galileo_cnc.program.ops import I, J, KIND, NM_PER_MM, X, Y, OpKind
from galileo_cnc.readers import read_file

sys.path[:0] = [str(Path(__file__).resolve().parents[1] / "console")]
from test_console import console_in_thread, home  # noqa: E402,F401  (home: the fixture)

CONFIG = MachineConfig()
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def shell(capsys, monkeypatch, tmp_path):
    """`galileo-cnc ARGS` as test_cli.galileo runs it, in this process (no interpreter to
    start): returncode, stdout and stderr; the user's folders are the test's own."""
    from galileo_cnc.cli.main import main

    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path / "home"))
    monkeypatch.setenv("GALILEO_CNC_NO_PROBE", "1")
    monkeypatch.chdir(ROOT)

    def run(*args: str) -> SimpleNamespace:
        capsys.readouterr()
        code = main(list(args))
        out, err = capsys.readouterr()
        return SimpleNamespace(returncode=code, stdout=out, stderr=err)
    return run


@pytest.fixture
def wide_dxf(tmp_path):
    """A DXF drawing 240 mm wide (the machine's travel is 200 mm), as CAD writes it."""
    drawing = ezdxf.new("R2010")
    drawing.header["$INSUNITS"] = 4                     # mm
    space = drawing.modelspace()
    space.add_lwpolyline([(10, 20), (250, 20), (250, 80), (10, 80)], close=True)
    space.add_circle((130, 50), 20)
    path = tmp_path / "wide.dxf"
    drawing.saveas(path)
    return path


def test_a_dxf_240_mm_wide_is_refused_then_plots_inside_the_travel_with_fit(tmp_path, wide_dxf, shell):
    refused = shell("plot", str(wide_dxf), "--port", "sim://?speed=0", "--yes")
    assert refused.returncode == 1
    assert "the job is 240.0 mm wide" in refused.stderr and "--fit" in refused.stderr

    trace_file = tmp_path / "wide.npz"
    result = shell("plot", str(wide_dxf), "--fit", "--port", "sim://?speed=0", "--yes",
                   "--trace", str(trace_file))
    assert result.returncode == 0, result.stderr
    # 198 mm of the 200 mm travel for 240 mm: x0.825, a 1 mm margin either side
    assert "scaled x0.825 to fit the travel" in result.stdout
    where = Trace.load(trace_file).positions()
    x_max, y_max, _ = CONFIG.travel_max_steps
    drawn = where[where[:, 2] == CONFIG.pen_down_z_steps]
    assert where[:, 0].min() >= 0 and where[:, 1].min() >= 0
    assert where[:, 0].max() <= x_max and where[:, 1].max() <= y_max
    # the rectangle's 240 mm are 198 mm now, from the margin (1 mm) to 199 mm
    assert (drawn[:, 0].min(), drawn[:, 0].max()) == (CONFIG.mm_to_steps(1),
                                                      CONFIG.mm_to_steps(199))
    assert drawn[:, 1].max() - drawn[:, 1].min() == CONFIG.mm_to_steps(60 * 0.825)


def test_info_preview_and_convert_take_the_same_options(tmp_path, wide_dxf, shell):
    info = shell("info", str(wide_dxf), "--fit", "--rotate", "90", "--json")
    assert info.returncode == 0, info.stderr
    summary = json.loads(info.stdout)
    assert summary["misfit"] is None
    assert summary["transform"] == "scaled x0.825 to fit the travel, rotated 90 degrees clockwise"
    # turned, the 240 mm side is along Y: the fit is still 0.825 (60 mm across)
    box = summary["bbox_mm"]
    assert (box["min_x"], box["max_x"]) == (20 * 0.825, 80 * 0.825)
    assert (box["min_y"], box["max_y"]) == (-250 * 0.825, -10 * 0.825)
    png = tmp_path / "wide.png"
    preview = shell("preview", str(wide_dxf), "--scale", "0.5", "-o", str(png))
    assert preview.returncode == 0, preview.stderr and png.exists()
    out = tmp_path / "wide.nc"
    convert = shell("convert", str(wide_dxf), "--scale", "0.5", "-o", str(out))
    assert convert.returncode == 0, convert.stderr
    back = read_file(out)
    drawn = back.table[back.table[:, KIND] == OpKind.LINE]
    # 240 x 60 mm at half size from the 1 mm margin: X 1 .. 121 mm, Y 1 .. 31 mm
    assert (drawn[:, X].min(), drawn[:, X].max()) == (1 * NM_PER_MM, 121 * NM_PER_MM)
    assert (drawn[:, Y].min(), drawn[:, Y].max()) == (1 * NM_PER_MM, 31 * NM_PER_MM)
    assert "scaled x0.5" in out.read_text().splitlines()[1]


def test_rotate_90_maps_every_corner_and_arc_centre_exactly(tmp_path):
    drawing = tmp_path / "corners.nc"
    drawing.write_text("G21 G90\nG0 X10.000001 Y20.000003\nM3\nG1 X150.123457 Y20.000003\n"
                       "G1 X150.123457 Y80.5\nG2 X140.123457 Y90.5 I-10 J0\nM5\n")
    source = read_file(drawing).table
    for degrees, (ax, ay) in {90: ((0, 1), (-1, 0)), 180: ((-1, 0), (0, -1)),
                              270: ((0, -1), (1, 0))}.items():
        turned = load_artwork(drawing, transform=Transform(rotate_deg=degrees)).program.table
        # clockwise on the paper: (x, y) -> (y, -x) for 90
        for columns in ((X, Y), (I, J)):
            x, y = source[:, columns[0]], source[:, columns[1]]
            assert np.array_equal(turned[:, columns[0]], ax[0] * x + ax[1] * y)
            assert np.array_equal(turned[:, columns[1]], ay[0] * x + ay[1] * y)
        assert np.array_equal(turned[:, KIND], source[:, KIND])   # arcs keep their turn
    # the plot of the turned drawing goes where the turned corners say, to the step
    planned = plan_file(drawing, CONFIG, options=PlanOptions(transform=Transform(rotate_deg=90)))
    assert planned.artwork.drawn_box_nm == (20_000_003, -150_123_457, 90_500_000, -10_000_001)
    assert planned.offset_nm == (19_000_003, -151_123_457)       # then the offset, 1 mm margin


def test_scale_is_exact_in_integer_nm_from_the_decimal_typed(tmp_path, shell):
    drawing = tmp_path / "tiny.nc"
    # 5 nm x 0.3 = 1.5 nm: 2 nm, half away from zero; the float 0.3 is 0.29999999999999998890
    # and gave 1 nm
    drawing.write_text("G21 G90\nG0 X0 Y0\nM3\nG1 X0.000005 Y-0.000005\n"
                       "G1 X123.456789 Y0.333333\nM5\n")
    assert parse_scale("0.3") == Fraction(3, 10) and parse_scale("80%") == Fraction(4, 5)
    lines = load_artwork(drawing, transform=Transform.asked(scale="0.3")).program.table
    drawn = lines[lines[:, KIND] == OpKind.LINE]
    assert drawn[:, [X, Y]].tolist() == [[2, -2], [37_037_037, 100_000]]
    out = tmp_path / "tiny-out.nc"
    result = shell("convert", str(drawing), "--scale", "0.3", "--offset", "none",
                   "--file-order", "-o", str(out))
    assert result.returncode == 0, result.stderr
    assert "G1 X0.000002 Y-0.000002" in out.read_text()


def test_options_that_cannot_be_used_are_refused_with_their_name(shell):
    with pytest.raises(TransformError, match="--fit and --scale"):
        Transform.asked(scale="2", fit=True)
    for bad in ("0", "-1", "abc", "1e9"):
        with pytest.raises(TransformError, match="--scale"):
            Transform.asked(scale=bad)
    with pytest.raises(TransformError, match="--rotate: expected 90, 180 or 270"):
        Transform.asked(rotate="45")
    result = shell("info", "samples/led-blinker.gbr", "--rotate", "45")
    assert result.returncode == 1 and "--rotate: expected 90, 180 or 270" in result.stderr


def test_getg_fits_and_turns_the_drawing_in_the_console(home, wide_dxf):  # noqa: F811
    with console_in_thread(home) as user:
        user.line(f"getg {wide_dxf}")
        user.expect(r"the job is 240\.0 mm wide .*--fit")
        user.expect(r">>")
        user.line(f"getg --fit --rotate 90 {wide_dxf}")
        user.expect(r"drawing     scaled x0\.825 to fit the travel, rotated 90 degrees "
                    r"clockwise")
        user.expect(r"use these offsets\? \[Y/n\]")
        user.line("y")
        user.expect(r"process has finished")
        state, x, y, z = user.status()
        assert state == "idle"
        # the last corner drawn is inside the travel
        assert 0 <= x <= CONFIG.travel_max_steps[0] and 0 <= y <= CONFIG.travel_max_steps[1]


def test_a_scaled_and_turned_job_resumes_as_it_was_planned(tmp_path, monkeypatch):
    """The journal keeps the scale and the turn: `plot --resume` replans the job with
    them (without, it would draw the rest of the board unturned). In one process:
    `sim://NAME` machines keep power only within a process."""
    from faults import FaultyPort

    from galileo_cnc.cli.main import main
    from galileo_cnc.machine import simulate
    from galileo_cnc.sim.simulator import forget_named_machines, named_machine
    from galileo_cnc.stream.journal import Journal
    from galileo_cnc.stream.streamer import JobStreamer
    from galileo_cnc.transport.link import MachineLink, PortGone
    from galileo_cnc.transport.port import open_port

    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    forget_named_machines()
    url, board = "sim://turned?speed=0", str(ROOT / "samples" / "led-blinker.gbr")
    planned = plan_file(board, CONFIG, options=PlanOptions(
        mode="centre", transform=Transform.asked(scale="1.5", rotate="180")))
    link = MachineLink.attach(FaultyPort(open_port(url, timeout=0.1), die_after=20), url)
    with pytest.raises(PortGone):
        JobStreamer(link, planned.job, planned.plotted, journal=Journal.default()).run()
    link.close()
    journal = json.loads((tmp_path / "journal.json").read_text())
    assert (journal["scale"], journal["rotate_deg"]) == ("3/2", 180)
    assert main(["plot", board, "--resume", "--yes", "--port", url]) == 0
    assert named_machine("turned").trace().same_steps(simulate(planned.job.commands))
    forget_named_machines()
