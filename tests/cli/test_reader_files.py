"""What the readers make of a user's files, as the user meets it through `info` and
`plot`: where the drawing lands and how large it is (issue 31, items 1 and 3), and the
files a Gerber file includes (item 18)."""

import json

import pytest

from galileo_cnc.cli.main import main
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine import Trace


@pytest.fixture
def galileo(tmp_path, monkeypatch, capsys):
    """The galileo-cnc command in this process (a subprocess costs a second of imports):
    its exit code, stdout and stderr; no board probed, the journal in tmp_path."""
    monkeypatch.setenv("GALILEO_CNC_NO_PROBE", "1")
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))

    def run(*args: str) -> tuple[int, str, str]:
        code = main(list(args))
        captured = capsys.readouterr()
        return code, captured.out, captured.err
    return run

# A 10 mm line at (X, Y) mm repeated twice, 20 mm apart: `%SRX2Y1I20.0J0*%`.
STEP_REPEAT = ("%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.2*%\n%SRX2Y1I20.0J0*%\nD10*\n"
               "X{x}000000Y{y}000000D02*\nX{x2}000000Y{y}000000D01*\n%SR*%\nM02*\n")


def _info(galileo, path):
    code, out, err = galileo("info", str(path), "--json")
    assert code == 0, err
    return json.loads(out)


def test_step_and_repeat_proposes_the_offset_of_what_it_draws_and_draws_there(tmp_path, galileo):
    board = tmp_path / "repeat.gbr"
    board.write_text(STEP_REPEAT.format(x=100, x2=110, y=100))
    info = _info(galileo, board)
    assert info["bbox_mm"] == {"min_x": 100.0, "min_y": 100.0, "max_x": 130.0, "max_y": 100.0}
    assert info["proposed_offset_mm"] == {"x": 99.0, "y": 99.0}  # not X 19 (a move to 20, 0)

    trace_file = tmp_path / "repeat.npz"
    code, out, err = galileo("plot", str(board), "--port", "sim://?speed=0", "--yes",
                             "--mode", "centre", "--trace", str(trace_file))
    assert code == 0, err
    assert "offset 99.000, 99.000 mm" in out
    config = MachineConfig()
    where = Trace.load(trace_file).positions()
    drawn = where[where[:, 2] == config.pen_down_z_steps]
    # the strokes are where the box minus the offset says: work X 1..31 mm, Y 1 mm
    assert (drawn[:, 0].min(), drawn[:, 0].max()) == (config.mm_to_steps(1),
                                                      config.mm_to_steps(31))
    assert set(drawn[:, 1].tolist()) == {config.mm_to_steps(1)}
    assert where[:, 0].min() >= 0 and where[:, 1].min() >= 0  # no travel below the origin


def test_a_step_and_repeat_far_from_the_origin_fits(tmp_path, galileo):
    board = tmp_path / "far.gbr"
    board.write_text(STEP_REPEAT.format(x=300, x2=310, y=300))
    info = _info(galileo, board)
    assert info["proposed_offset_mm"] == {"x": 299.0, "y": 299.0}
    assert info["misfit"] is None  # it was "310.0 mm wide (with its travel moves)"


# A gEDA-style panel (inches, 2.5 digits, %LN): a 60 x 95.8 mm board outline, lying
# 11.1 mm from the origin, stacked twice 95.8 mm apart: 191.6 mm tall in all. The block
# selects its aperture before its first move, where the current point is still 0, 0.
GEDA_PANEL = """G04 start of page 1 for group 0 idx 0 *
G04 Title: panel, outline *
G04 Creator: pcb 4.0.2 *
G04 Format: Gerber/RS-274X *
G04 PCB-Dimensions (mil): 2800.00 7980.00 *
G04 PCB-Coordinate-Origin: lower left *
%MOIN*%
%FSLAX25Y25*%
%LNOUTLINE*%
%ADD11C,0.0100*%
%SRX1Y2I0J3.77165*%
G54D11*X43701Y43701D02*
X279921Y43701D01*
X279921Y420866D01*
X43701Y420866D01*
X43701Y43701D01*
%SR*%
M02*
"""


def test_a_geda_panel_is_as_tall_as_it_draws(tmp_path, galileo):
    panel = tmp_path / "panel.outline.gbr"
    panel.write_text(GEDA_PANEL)
    info = _info(galileo, panel)
    box = info["bbox_mm"]
    assert round(box["max_y"] - box["min_y"], 1) == 191.6
    offset = info["proposed_offset_mm"]  # the box's corner less the 1 mm margin
    assert abs(offset["x"] - (box["min_x"] - 1)) < 1e-4 and abs(offset["y"] - (box["min_y"] - 1)) < 1e-4
    assert info["misfit"] is None


def test_a_headerless_dxf_is_millimetres_with_a_warning(tmp_path, galileo):
    # an OpenSCAD export of a 40 x 25 mm part: ENTITIES only, no $INSUNITS
    pairs = [(999, "DXF from OpenSCAD"), (0, "SECTION"), (2, "ENTITIES")]
    corners = [(0, 0), (40, 0), (40, 25), (0, 25)]
    for (x0, y0), (x1, y1) in zip(corners, corners[1:] + corners[:1]):
        pairs += [(0, "LINE"), (8, "0"), (10, x0), (20, y0), (11, x1), (21, y1)]
    pairs += [(0, "ENDSEC"), (0, "EOF")]
    part = tmp_path / "part.dxf"
    part.write_text("".join(f"{code}\n{value}\n" for code, value in pairs))
    info = _info(galileo, part)
    assert info["bbox_mm"] == {"min_x": 0.0, "min_y": 0.0, "max_x": 40.0, "max_y": 25.0}
    assert info["misfit"] is None  # it was 40 m wide and refused
    assert any("no $INSUNITS: read as millimetres" in w for w in info["warnings"])


def test_an_included_file_is_read_beside_its_board_and_nothing_outside(tmp_path, galileo):
    board = tmp_path / "board"
    board.mkdir()
    (board / "outline.gbr").write_text("X0Y0D02*\nX40000000Y0D01*\nX40000000Y25000000D01*\n")
    top = board / "top.gbr"
    top.write_text("%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.2*%\nD10*\n%IFoutline.gbr*%\nM02*\n")
    info = _info(galileo, top)
    assert info["bbox_mm"] == {"min_x": 0.0, "min_y": 0.0, "max_x": 40.0, "max_y": 25.0}
    (tmp_path / "other.gbr").write_text("X0Y0D02*\nX90000000Y0D01*\n")
    top.write_text("%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.2*%\nD10*\n%IF../other.gbr*%\nM02*\n")
    code, out, err = galileo("info", str(top))
    assert code == 1 and out == ""
    assert err.startswith(f"galileo-cnc: {top}:5:1: include file '../other.gbr' (%IF) is not "
                          "inside the folder of top.gbr")


def test_a_refused_arc_is_told_in_words_and_mm_at_its_line(tmp_path, galileo):
    # issue 31, item 14: the refusal named `ARC_CCW (op 7)`
    drawing = tmp_path / "arc.nc"
    drawing.write_text("G21\nG90\nG0 X10 Y10\nM3\nG1 X20 Y10 F600\nG1 X195 Y10\n"
                       "G3 X195 Y30 I0 J10\nM5\nM2\n")
    code, out, err = galileo("plot", str(drawing), "--port", "sim://?speed=0", "--yes",
                             "--offset", "none")
    assert code == 1
    assert err.splitlines()[-1] == (
        f"galileo-cnc: {drawing}:7:1: the counter-clockwise arc from X 195 Y 10 to X 195 Y 30 "
        "mm (centre X 195 Y 20, file coordinates): X would reach 205.000 mm, beyond the "
        "travel's end at 200.000 mm [32800 steps]")
