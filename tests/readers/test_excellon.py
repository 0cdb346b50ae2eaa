"""The Excellon reader: every corpus drill file, gerbonara's reading of them, each
feature on small hand-written files with exact nm, and positioned errors."""

import json
import warnings
from pathlib import Path

import pytest

from corpus import CORPUS
from galileo_cnc.cli.info import drill_report
from galileo_cnc.errors import GalileoError
from galileo_cnc.program.drills import Hole, Slot
from galileo_cnc.readers import detect_format, is_drill_file, read_drill, read_file
from galileo_cnc.readers.excellon import ExcellonError, read_excellon

DRILL = CORPUS / "drill"
INCH = 25_400_000

# Where gerbonara 1.5 and we disagree, and why we are right (the copper of the same
# board, or the same board written by another tool, says so):
GERBONARA_WRONG = {
    # gEDA PCB before 2007 wrote mils (INCH,TZ, tools as T01F00S00C0.020); gerbonara
    # reads 2.4, a tenth of the size: the holes then miss the board's copper, ours
    # land on its pads (test_old_geda_mils_land_on_the_copper_pads).
    "geda-pcb/numpres/numpres.pcb.output_plated-drill.grb": "tenfold",
    # Zuken's 8-digit INCH,LZ coordinates are 4.4 (the board's KiCad file has the same
    # holes); gerbonara reads them as 2.4, a hundredth of the size.
    "zuken-emulated/8seg-driver/8seg_Driver__routed_Drill_thru_nplt.fdr": "hundredfold",
    "zuken-emulated/8seg-driver/8seg_Driver__routed_Drill_thru_plt.fdr": "hundredfold",
    # The header defines T0C0.006 (vias) and the body drills with it (every such hole
    # is on a copper pad); gerbonara takes T0 for "unload the tool": it drops some of
    # those holes and gives the rest the size of the tool before.
    "unknown/ekf2/drill20.exc": "drops T0",
    "unknown/ekf2/drill30.exc": "drops T0",
}


def _drill_files() -> list[Path]:
    return sorted(p for p in DRILL.rglob("*") if p.is_file() and not p.name.startswith("UPSTREAM"))


def _gerbonara(path: Path):
    """gerbonara's holes and slots in nm, or None where it cannot read the file."""
    from gerbonara.excellon import ExcellonFile
    from gerbonara.graphic_objects import Arc, Flash, Line
    from gerbonara.utils import MM

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            objects = ExcellonFile.open(path).objects
        except Exception:           # its own SyntaxError and friends: "cannot read"
            return None

    def nm(value, unit):
        return round(value * (1_000_000 if unit == MM else INCH))
    holes = [(nm(o.x, o.unit), nm(o.y, o.unit), nm(o.aperture.diameter, o.aperture.unit))
             for o in objects if isinstance(o, Flash)]
    slots = [(nm(o.x1, o.unit), nm(o.y1, o.unit), nm(o.x2, o.unit), nm(o.y2, o.unit),
              nm(o.aperture.diameter, o.aperture.unit))
             for o in objects if isinstance(o, (Line, Arc))]
    return holes, slots


def test_every_corpus_drill_file_reads_and_agrees_with_gerbonara():
    files = _drill_files()
    if len(files) < 40:
        pytest.skip(f"no drill folder in {CORPUS}")
    read = compared = 0
    for path in files:
        name = str(path.relative_to(DRILL))
        assert detect_format(path.read_text(errors="replace")) == "excellon", name
        drill = read_drill(path)
        read += 1
        assert drill.holes or drill.slots or "unplated" in name, name
        ours = ([(h.x_nm, h.y_nm, h.diameter_nm) for h in drill.holes],
                [(s.x0_nm, s.y0_nm, s.x1_nm, s.y1_nm, s.diameter_nm) for s in drill.slots])
        theirs = _gerbonara(path)
        if theirs is None:
            continue
        compared += 1
        why = GERBONARA_WRONG.get(name)
        if why == "drops T0":
            assert {(x, y) for x, y, _ in theirs[0]} <= {(x, y) for x, y, _ in ours[0]}, name
            assert {d for hole, (_, _, d) in zip(drill.holes, ours[0]) if hole.tool != "T00"} \
                <= {d for _, _, d in theirs[0]}
            continue
        if why in ("tenfold", "hundredfold"):
            factor = 10 if why == "tenfold" else 100
            theirs = ([(x * factor, y * factor, d) for x, y, d in theirs[0]], theirs[1])
        for mine, other in ((ours[0], theirs[0]), (ours[1], theirs[1])):
            assert len(mine) == len(other), name
            for a, b in zip(mine, other):
                # the scaled-up gerbonara values carry its rounding times the factor
                limit = 1000 * (100 if why in ("tenfold", "hundredfold") else 1)
                assert max(abs(p - q) for p, q in zip(a, b)) <= limit, (name, a, b)
    assert read == len(files) >= 48
    assert compared >= 40


def test_zuken_and_kicad_files_of_one_board_give_the_same_holes():
    for zuken, kicad in (("8seg_Driver__routed_Drill_thru_plt.fdr", "driver-PTH"),
                         ("8seg_Driver__routed_Drill_thru_nplt.fdr", "driver-NPTH")):
        a = read_drill(DRILL / "zuken-emulated/8seg-driver" / zuken)
        b = read_drill(DRILL / "kicad/8seg-driver" / kicad)
        assert [(h.x_nm, h.y_nm, h.diameter_nm, h.plated) for h in a.holes] == \
            [(h.x_nm, h.y_nm, h.diameter_nm, h.plated) for h in b.holes]


def test_old_geda_mils_land_on_the_copper_pads():
    from galileo_cnc.program.ops import KIND, X, Y, OpKind
    copper = CORPUS / "geda-pcb/numpres/numpres.pcb.output_group1.grb"
    if not copper.is_file():
        pytest.skip("numpres copper not in this corpus")
    table = read_file(copper).table
    pads = {(int(x), int(y)) for x, y in table[table[:, KIND] == int(OpKind.FLASH)][:, [X, Y]]}
    drill = read_drill(DRILL / "geda-pcb/numpres/numpres.pcb.output_plated-drill.grb")
    assert drill.metadata["generator"] == "gEDA PCB (mils)"
    assert sum((h.x_nm, h.y_nm) in pads for h in drill.holes) >= 0.9 * len(drill.holes)


def test_plating_comes_from_x2_the_tool_groups_or_the_name():
    kicad = read_drill(DRILL / "kicad/8seg-driver/driver-NPTH")
    assert (kicad.plated, kicad.metadata["plated_from"]) == (False, "X2 comment")
    altium = read_drill(DRILL / "altium/limesdr-qpcie/LimeSDR-QPCIe_1v2-RoundHoles.TXT")
    assert altium.plated is None and {h.plated for h in altium.holes} == {True, False}
    assert {h.plated for h in altium.holes if h.tool == "T11"} == {False}
    geda = read_drill(DRILL / "geda-pcb/stepper-lights-controller/controller.unplated-drill.cnc")
    assert (geda.plated, geda.metadata["plated_from"]) == (False, "the file name")
    allegro = read_drill(DRILL / "allegro/tracespace-371/ncdrill-1-4.drl")
    assert allegro.tools["T01"] == 12 * 25_400 and allegro.tools["T06"] == 125 * 25_400
    assert {h.plated for h in allegro.holes if h.tool == "T06"} == {False}


# ---- hand-written files: each feature, exact nm --------------------------------------

def read_text(tmp_path, text: str, name: str = "t.drl"):
    path = tmp_path / name
    path.write_text(text)
    return read_drill(path)


def holes(drill):
    return [(h.x_nm, h.y_nm, h.diameter_nm) for h in drill.holes]


@pytest.mark.parametrize("header, coordinate, expected", [
    ("METRIC,TZ", "X12345Y-500", (12_345_000, -500_000)),            # 3.3, leading cut
    ("METRIC,LZ", "X012345Y-0005", (12_345_000, -500_000)),           # 3.3, trailing cut
    ("METRIC,TZ,0000.00", "X1234Y5", (12_340_000, 50_000)),          # 4.2 from the template
    ("INCH,TZ", "X15Y-25000", (15 * 2540, -25000 * 2540)),           # 2.4
    ("INCH,LZ", "X01Y-0025", (INCH, -25 * INCH // 100)),
    ("INCH\n;FILE_FORMAT=3:5", "X100000Y2", (INCH, 2 * 254)),        # Altium's digits
    ("METRIC", "X1.5Y-.25", (1_500_000, -250_000)),                  # decimal point
    ("INCH", "X2.1142Y55.", (21142 * 2540, 55 * INCH)),
])
def test_number_formats(tmp_path, header, coordinate, expected):
    drill = read_text(tmp_path, f"M48\n{header}\nT1C1.0\n%\nT1\n{coordinate}\nM30\n")
    assert (drill.holes[0].x_nm, drill.holes[0].y_nm) == expected


def test_tool_sizes_follow_the_unit_and_inline_tools_define_and_select(tmp_path):
    drill = read_text(tmp_path, "M48\nINCH\nT01C0.0400\n%\nT01\nX10000Y10000\n"
                      "T2C0.8F200S100\nX20000Y10000\nM30\n")
    assert drill.tools == {"T01": 1_016_000, "T02": 20_320_000}
    assert [h.tool for h in drill.holes] == ["T01", "T02"]


def test_fmat_1_and_eagle_m72_header(tmp_path):
    drill = read_text(tmp_path, "%\nM48\nM72\nFMAT,1\nT01C0.0118\n%\nT01\nX1743Y1155\nM30\n")
    assert holes(drill) == [(1743 * 2540, 1155 * 2540, 299_720)]
    assert drill.metadata["fmat"] == 1 and drill.units == "in"


def test_incremental_g91_and_ici(tmp_path):
    text = "M48\nMETRIC,TZ\nT1C1.0\n%\nT1\nX1000Y1000\nG91\nX500\nY-250\nG90\nX0Y0\nM30\n"
    assert [h[:2] for h in holes(read_text(tmp_path, text))] == \
        [(1_000_000, 1_000_000), (1_500_000, 1_000_000), (1_500_000, 750_000), (0, 0)]
    text = "M48\nMETRIC,TZ\nICI,ON\nT1C1.0\n%\nT1\nX1000\nX1000Y1000\nM30\n"
    assert [h[:2] for h in holes(read_text(tmp_path, text))] == \
        [(1_000_000, 0), (2_000_000, 1_000_000)]


def test_repeat_codes_step_from_the_last_hole(tmp_path):
    text = "M48\nINCH,TZ\nT1C0.012\n%\nT1\nX1000Y2000\nR03X1000\nR02Y-500\nM30\n"
    assert [h[:2] for h in holes(read_text(tmp_path, text))] == [
        (254_0000, 508_0000), (508_0000, 508_0000), (762_0000, 508_0000),
        (1016_0000, 508_0000), (1016_0000, 381_0000), (1016_0000, 254_0000)]


def test_g85_slots_and_g93_zero(tmp_path):
    text = ("M48\nMETRIC\nT1C0.8\n%\nG93X10.Y20.\nT1\nX1.Y1.G85X3.\nX5.Y5.\nM30\n")
    drill = read_text(tmp_path, text)
    assert drill.slots == [Slot(11_000_000, 21_000_000, 13_000_000, 21_000_000, 800_000,
                                "T01", None, 7)]
    assert holes(drill) == [(15_000_000, 25_000_000, 800_000)]


def test_routed_slots_lines_and_arcs(tmp_path):
    text = ("M48\nMETRIC\nT1C1.0\n%\nT1\nG00X10.Y0.\nM15\nG01X20.\nG03X30.Y10.I0.J10.\n"
            "G02X20.Y20.A10.\nM16\nG00X0.Y0.\nG05\nX1.Y1.\nM30\n")
    drill = read_text(tmp_path, text)
    assert [(s.x0_nm, s.y0_nm, s.x1_nm, s.y1_nm, s.arc, s.cx_nm, s.cy_nm) for s in drill.slots] == [
        (10_000_000, 0, 20_000_000, 0, "", 0, 0),
        (20_000_000, 0, 30_000_000, 10_000_000, "ccw", 20_000_000, 10_000_000),
        (30_000_000, 10_000_000, 20_000_000, 20_000_000, "cw", 30_000_000, 20_000_000)]
    assert holes(drill) == [(1_000_000, 1_000_000, 1_000_000)]       # G05: drilling again
    # the quarter circles bulge no further than their ends: their box plus the radius
    assert drill.box_nm() == (-500_000 + 1_000_000, -500_000, 30_500_000, 20_500_000)


def test_routing_with_the_tool_up_cuts_nothing(tmp_path):
    drill = read_text(tmp_path, "M48\nMETRIC\nT1C1.0\n%\nT1\nG00X1.Y1.\nG01X2.\nM30\n")
    assert drill.slots == [] and drill.holes == []


def test_plating_from_x2_type_groups_and_file_names(tmp_path):
    x2 = read_text(tmp_path, "M48\n; #@! TF.FileFunction,NonPlated,1,2,NPTH\nMETRIC\nT1C3.0\n"
                   "%\nT1\nX1.Y1.\nM30\n")
    assert x2.plated is False and x2.holes[0].plated is False
    grouped = read_text(tmp_path, "M48\nMETRIC,LZ\n;TYPE=PLATED\nT1C0.8\n;TYPE=NON_PLATED\n"
                        "T2C3.0\n%\nT1\nX001Y001\nT2\nX002Y002\nM30\n")
    assert [h.plated for h in grouped.holes] == [True, False] and grouped.plated is None
    for name, plated in (("board-NPTH.drl", False), ("board-PTH.drl", True),
                         ("x.unplated-drill.cnc", False), ("ThruHoleNonPlated.ncd", False),
                         ("board.drl", None)):
        assert read_text(tmp_path, "M48\nMETRIC\nT1C1.0\n%\nT1\nX1.Y1.\nM30\n",
                         name).plated is plated, name


def test_an_unstated_format_is_inferred_and_said(tmp_path):
    # PADS: no header, a leading zero on short numbers: leading zeros kept, inch 2.4
    drill = read_text(tmp_path, "%\nT1C.015F095S3\nX01095Y01056\nX01095Y0127\nM30\n")
    assert holes(drill)[1][:2] == (1095 * 25_400, 127 * 254_000)
    assert any("leading zeros kept" in note for note in drill.metadata["assumed"])
    assert any("unit not stated" in note for note in drill.metadata["assumed"])


def test_a_defined_t0_drills_and_an_undefined_one_unloads(tmp_path):
    drill = read_text(tmp_path, "M48\nMETRIC\nT0C0.15\nT1C1.0\n%\nT0\nX1.Y1.\nT1\nX2.Y2.\n"
                      "T0\nX3.Y3.\nM30\n")
    assert [h.tool for h in drill.holes] == ["T00", "T01", "T00"]
    with pytest.raises(ExcellonError, match=r"t.drl:7:1: a hole or slot before any tool"):
        read_text(tmp_path, "M48\nMETRIC\nT1C1.0\n%\nT1\nT0\nX3.Y3.\nM30\n")


# ---- errors: file:line:col --------------------------------------------------------

@pytest.mark.parametrize("body, where, what", [
    ("T1\nX1.Y1.\nX1.&Y2\n", "8:4", "unexpected '&'"),
    ("T1\n  G37X1.\n", "7:3", "G37 is not supported"),
    ("T1\nX1.Y1.Q5\n", "7:7", "Q5: not an Excellon word"),
    ("X1.Y1.\n", "6:1", "before any tool"),
    ("T1\nX1.X2.\n", "7:4", "X given twice"),
    ("T1\nG00X0Y0\nM15\nG02X10.Y0A1.\n", "9:10", "radius 1 mm cannot join"),
    ("T1\nX1e5Y0\n", "7:3", "E5: not an Excellon word"),
    ("T1\nX1.Y\n", "7:4", "Y without a number"),
])
def test_malformed_lines_name_file_line_and_column(tmp_path, body, where, what):
    path = tmp_path / "bad.drl"
    path.write_text(f"M48\nMETRIC\nT1C1.0\n%\n\n{body}M30\n")
    with pytest.raises(ExcellonError) as caught:
        read_drill(path)
    assert str(caught.value).startswith(f"{path}:{where}: ") and what in str(caught.value)


def test_lz_numbers_longer_than_the_stated_format_are_refused(tmp_path):
    path = tmp_path / "long.drl"
    path.write_text("M48\n;FILE_FORMAT=2:4\nINCH,LZ\nT1C0.01\n%\nT1\nX0123456Y0\nM30\n")
    with pytest.raises(ExcellonError, match=r"long.drl:7:2: '0123456' has 7 digits"):
        read_drill(path)


def test_hostile_repeats_and_coordinates_are_refused_early(tmp_path, monkeypatch):
    monkeypatch.setenv("GALILEO_MAX_OPS", "1000")
    path = tmp_path / "huge.drl"
    path.write_text("M48\nMETRIC,TZ\nT1C1.0\n%\nT1\nX0Y0\nR999999999X1\nM30\n")
    with pytest.raises(ExcellonError, match=r"huge.drl:7:1: the file makes more than 1,000 "):
        read_drill(path)
    path.write_text("M48\nMETRIC,TZ\nT1C1.0\n%\nT1\nX" + "9" * 30 + "Y0\nM30\n")
    with pytest.raises(ExcellonError, match=r"huge.drl:6:2: .* from the origin"):
        read_drill(path)
    # sums: incremental steps, a zero set, a repeat, each within the bound on its own
    for body, where in (("G91\n" + "X9000000\n" * 3, "8:1"), ("G93X9000000\nX9000000\n", "7:1"),
                        ("X0Y0\nR3X4000000\n", "7:1")):
        path.write_text(f"M48\nMETRIC,TZ\nT1C1.0\n%\nT1\n{body}M30\n")
        with pytest.raises(ExcellonError, match=rf"huge.drl:{where}: the point .* more than 10 m"):
            read_drill(path)


def test_read_file_names_a_drill_file_and_info_lists_it(tmp_path):
    path = tmp_path / "board-PTH.drl"
    path.write_text("M48\nMETRIC\nT1C0.8\nT2C1.0\n%\nT1\nX1.Y2.\nX3.Y4.\nT2\nX1.Y1.G85X5.Y1.\n"
                    "M30\n")
    assert is_drill_file(path) and not is_drill_file(tmp_path / "missing.drl")
    with pytest.raises(GalileoError, match="board-PTH.drl:1:1: an Excellon drill file"):
        read_file(path)
    text = drill_report(str(path), as_json=False)
    assert "2 holes, 1 slots" in text and "T01     0.8000 mm       2 holes     0 slots" in text
    assert "X 0.5000 .. 5.5000 mm, Y 0.5000 .. 4.4000 mm" in text and "plated" in text
    data = json.loads(drill_report(str(path), as_json=True))
    assert data["holes"][1] == {"x_mm": 3.0, "y_mm": 4.0, "diameter_mm": 0.8, "tool": "T01",
                                "plated": True, "line": 8}
    assert data["slots"][0]["x1_mm"] == 5.0 and data["counts"] == {"holes": 2, "slots": 1}
    gerber = tmp_path / "x.gbr"
    gerber.write_text("%FSLAX24Y24*%\n%MOIN*%\nM02*\n")
    assert drill_report(str(gerber), as_json=False) is None


def test_reading_is_deterministic_and_keeps_line_numbers(tmp_path):
    drill = read_text(tmp_path, "M48\nMETRIC\nT1C1.0\n%\nT1\nX1.Y1.\n\nX2.Y2.\nM30\nX9.Y9.\n")
    assert drill.holes == [Hole(1_000_000, 1_000_000, 1_000_000, "T01", None, 6),
                           Hole(2_000_000, 2_000_000, 1_000_000, "T01", None, 8)]


def test_the_box_of_an_arc_slot_holds_its_bulge():
    from galileo_cnc.program.drills import DrillFile
    half = Slot(10_000, 0, -10_000, 0, 2_000, arc="ccw")          # the upper half circle
    assert DrillFile("x", slots=[half]).box_nm() == (-11_000, -1_000, 11_000, 11_000)
    other = Slot(10_000, 0, -10_000, 0, 2_000, arc="cw")          # the lower one
    assert DrillFile("x", slots=[other]).box_nm() == (-11_000, -11_000, 11_000, 1_000)
    full = Slot(10_000, 0, 10_000, 0, 0, arc="cw")
    assert DrillFile("x", slots=[full]).box_nm() == (-10_000, -10_000, 10_000, 10_000)


def test_kicad_mixed_plating_marks_each_tool(tmp_path):
    drill = read_text(tmp_path, "M48\n; #@! TF.FileFunction,MixedPlating,1,2\nFMAT,2\nMETRIC\n"
                      "; #@! TA.AperFunction,Plated,PTH,ViaDrill\nT1C0.400\n"
                      "; #@! TA.AperFunction,NonPlated,NPTH,ComponentDrill\nT2C3.000\n%\nG90\n"
                      "G05\nT1\nX1.Y1.\nT2\nX5.Y5.\nT0\nM30\n", "board.drl")
    assert [h.plated for h in drill.holes] == [True, False] and drill.plated is None


def test_patterns_are_refused_not_misread(tmp_path):
    for body, where in (("M25\nX1.Y1.\nM01\nM02X10.Y0.\nM08\n", "6:1"),
                        ("X1.Y1.\nM02X10.Y0.\n", "7:1"), ("M70\n", "6:1")):
        path = tmp_path / "pattern.drl"
        path.write_text(f"M48\nMETRIC\nT1C1.0\n%\nT1\n{body}M30\n")
        with pytest.raises(ExcellonError, match=rf"pattern.drl:{where}: M\d+.*not read"):
            read_drill(path)


def test_galileo_cnc_info_on_a_corpus_drill_file():
    import os
    import subprocess
    import sys
    path = DRILL / "kicad/flashpads-x2ap/Flashpads-PTH.drl"
    env = dict(os.environ, GALILEO_CNC_NO_PROBE="1")
    run = subprocess.run([sys.executable, "-m", "galileo_cnc", "info", "--json", str(path)],
                         env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    data = json.loads(run.stdout)
    assert data["counts"] == {"holes": 60, "slots": 16} and data["plated"] is True
    assert len(data["holes"]) == 60 and len(data["slots"]) == 16
    assert data["tools"][0] == {"tool": "T01", "diameter_mm": 0.6, "holes": 0, "slots": 10}


def test_info_of_a_board_folder_counts_its_holes_with_this_reader(capsys, monkeypatch):
    from galileo_cnc.cli.main import main
    monkeypatch.setenv("GALILEO_CNC_NO_PROBE", "1")
    assert main(["info", "--json", str(DRILL / "kicad/8seg-driver")]) == 0
    board = json.loads(capsys.readouterr().out)["board"]
    assert {layer["role"] for layer in board["layers"]} == {"drill-plated", "drill-unplated"}
    assert sum(h["holes"] for h in board["holes"]) == 363 + 12
    assert {"diameter_mm": 3.2004, "holes": 8, "slots": 0} in board["holes"]
