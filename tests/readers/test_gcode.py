"""G-code reader, sniffer and writer: the dialect, one behaviour at a time."""

from __future__ import annotations

from pathlib import Path

import pytest

from corpus import CORPUS, corpus_paths

from galileo_cnc.errors import GcodeError, GalileoError
from galileo_cnc.program.ops import NO_TOOL, OpKind, ProgramBuilder
from galileo_cnc.readers.gcode import (GcodeExportError, looks_like_gcode, read_gcode,
                                       write_gcode)

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "samples" / "square-and-circle.nc"

MM = 1_000_000
K = OpKind


def read(text: str):
    return read_gcode("t.nc", text)


def ops(text: str) -> list[tuple]:
    """(kind, x, y, i, j, tool, value) per op, kind as OpKind."""
    return [(K(r[0]), *r[1:7]) for r in read(text).table.tolist()]


def kinds(text: str) -> list[OpKind]:
    return [K(r[0]) for r in read(text).table.tolist()]


def positions(text: str) -> list[tuple[int, int, int]]:
    """(kind, line, col) per op."""
    return [(K(r[0]), r[7], r[8]) for r in read(text).table.tolist()]


def fails(text: str, message_part: str, line: int | None = None, col: int | None = None) -> GcodeError:
    with pytest.raises(GcodeError) as info:
        read(text)
    err = info.value
    assert message_part in err.message, err.message
    if line is not None:
        assert err.pos.line == line, err
    if col is not None:
        assert err.pos.col == col, err
    assert err.pos.file == "t.nc"
    return err


def move(x, y):
    return (K.MOVE, x, y, 0, 0, NO_TOOL, 0)


def line(x, y, tool=NO_TOOL):
    return (K.LINE, x, y, 0, 0, tool, 0)


PEN_DOWN = (K.PEN_DOWN, 0, 0, 0, 0, NO_TOOL, 0)
PEN_UP = (K.PEN_UP, 0, 0, 0, 0, NO_TOOL, 0)


# ---- the sample -------------------------------------------------------------

def test_sample_drawing_reads_to_square_and_circle():
    program = read_gcode(SAMPLE)
    assert program.format == "gcode" and program.units == "mm"
    assert program.source == str(SAMPLE)
    assert program.warnings == []
    rows = [(K(r[0]), *r[1:7]) for r in program.table.tolist()]
    assert rows == [
        (K.FEED, 0, 0, 0, 0, NO_TOOL, 10 * MM),  # F600 mm/min = 10 mm/s
        move(0, 0), PEN_DOWN,
        line(20 * MM, 0), line(20 * MM, 20 * MM), line(0, 20 * MM), line(0, 0),
        PEN_UP, move(15 * MM, 10 * MM), PEN_DOWN,
        (K.ARC_CW, 15 * MM, 10 * MM, -5 * MM, 0, NO_TOOL, 0),  # full circle
        PEN_UP,
    ]
    assert program.line_count == len(SAMPLE.read_text().splitlines())


def test_sample_ops_carry_their_source_line():
    program = read_gcode(SAMPLE)
    text_lines = SAMPLE.read_text().splitlines()
    arc = program.op(10)
    assert arc.kind == K.ARC_CW
    assert text_lines[arc.pos.line - 1].startswith("G02")
    assert str(arc.pos) == f"{SAMPLE}:{arc.pos.line}:1"


def test_path_and_text_give_the_same_program():
    from_path = read_gcode(SAMPLE)
    from_text = read_gcode(str(SAMPLE), SAMPLE.read_text())
    assert (from_path.table == from_text.table).all()


def test_missing_file_is_a_reader_error():
    with pytest.raises(GcodeError, match="cannot read the file"):
        read_gcode(ROOT / "no-such-file.nc")


# ---- numbers and units ------------------------------------------------------

@pytest.mark.parametrize("text, nm", [
    ("X1", MM), ("X1.5", 1_500_000), ("X.5", 500_000), ("X5.", 5 * MM), ("X+2", 2 * MM),
    ("X-0.000001", -1), ("X0.0000005", 1), ("X-0.0000005", -1), ("X0.00000049", 0),
    ("X0.1", 100_000), ("X 12.345678", 12_345_678), ("X-.25", -250_000),
    ("X0.30000000000000004", 300_000),  # what float 0.1+0.2 would print: still exact
])
def test_millimetres_are_exact_and_round_half_away_from_zero(text, nm):
    assert ops(f"G0 {text}") == [move(nm, 0)]


@pytest.mark.parametrize("text, nm", [
    ("X1", 25_400_000), ("X0.001", 25_400), ("X-0.00001", -254),
    ("X0.0000001", 3),  # 2.54 nm
    ("X0.00000002", 1), ("X-0.00000002", -1),  # 0.508 nm: away from zero
    ("X0.00000001", 0),  # 0.254 nm
])
def test_inches_are_exact(text, nm):
    assert ops(f"G20 G0 {text}") == [move(nm, 0)]


def test_units_come_from_the_first_g20_or_g21():
    assert read("G0 X1").units == "mm"
    assert read("G20\nG0 X1\nG21").units == "in"
    assert read("G21\nG20").units == "mm"


def test_units_switch_mid_file_and_apply_to_their_whole_line():
    assert ops("G0 X1\nG0 X1 G20\nG21 Y1") == [move(MM, 0), move(25_400_000, 0),
                                               move(25_400_000, MM)]


def test_feed_is_nm_per_second_in_the_files_units():
    assert ops("F60") == [(K.FEED, 0, 0, 0, 0, NO_TOOL, MM)]
    assert ops("G20 F1") == [(K.FEED, 0, 0, 0, 0, NO_TOOL, 423_333)]  # 25.4 mm/min
    assert ops("F100") == [(K.FEED, 0, 0, 0, 0, NO_TOOL, 1_666_667)]  # rounded once
    assert kinds("F100\nG1 X1 F100\nF200") == [K.FEED, K.LINE, K.FEED]  # only changes


@pytest.mark.parametrize("text", ["F0", "F-5", "F0.0000001"])
def test_feed_must_be_positive(text):
    fails(text, "positive feed rate", 1, 1)


def test_huge_numbers_are_refused_not_crashed_on():
    fails("G0 X" + "9" * 5000, "at most 12 digits before the point", 1, 4)
    fails("G0 X1000000.000001", "out of range")
    fails("G91\n" + "G0 X900000\n" * 2, "out of range", 3)
    fails("G0 X1." + "3" * 31, "30 after it", 1, 4)
    assert ops("G0 X1." + "3" * 30) == [move(1_333_333, 0)]


# ---- lexical --------------------------------------------------------------------

def test_comments_blank_lines_case_and_spacing():
    text = "(header)\n\n  g1 x 1 y2 ; move (not a comment)\n(a;b) G1 X3 (c) Y4\n\t; only\n"
    assert ops(text) == [line(MM, 2 * MM), line(3 * MM, 4 * MM)]


def test_words_may_be_packed_without_spaces():
    assert ops("G1X1Y-2") == [line(MM, -2 * MM)]


def test_percent_lines_are_tape_markers():
    assert ops("%\nG0 X1\n%") == [move(MM, 0)]


def test_columns_point_at_the_causing_word():
    text = "N5 M3\n  G0 X1 (c) Y2\n(c) X3\nG1 Z-1 X4\nT2\nF50 G4 P10"
    assert positions(text) == [
        (K.PEN_DOWN, 1, 4), (K.MOVE, 2, 3), (K.MOVE, 3, 5),
        (K.PEN_DOWN, 4, 4), (K.LINE, 4, 1), (K.SELECT, 5, 1),
        (K.FEED, 6, 1), (K.DWELL, 6, 5),
    ]


def test_line_numbers_and_checksums():
    assert ops("N10 G1 X1*80") == [line(MM, 0)]  # XOR of "N10 G1 X1" is 80
    assert ops("  N10 G1 X1*80 ; comment") == [line(MM, 0)]  # leading blanks not counted
    assert ops("N10 G1 X1 *112") == [line(MM, 0)]  # a blank before * is
    fails("N10 G1 X1*81", "checksum mismatch", 1, 10)
    fails("N10 G1 X1*", "expected a checksum", 1, 10)
    fails("G1 N10 X1", "must be the first word", 1, 4)
    fails("N1.5 G1", "whole line number", 1, 1)


@pytest.mark.parametrize("text, message, col", [
    ("G1 X", "expected a number after 'X'", 4),
    ("G1 X1 Y", "expected a number after 'Y'", 7),
    ("G", "expected a number after 'G'", 1),
    ("G1 X1 # 3", "unexpected character '#'", 7),
    ("G1 X1..2", "unexpected character '.'", 7),
    ("G1 X1 A3", "unknown word 'A'", 7),
    ("G1 E0.5", "unknown word 'E'", 4),
    ("G1 X1 (open", "')' to close the comment", 7),
    ("G1 X1 )", "'(' before ')'", 7),
    ("G1 X\u0663", "expected a number after 'X'", 4),  # Arabic-Indic digit
    ("G1 X1 X2", "two X words", 7),
    ("M-3", "M code number", 1),
])
def test_malformed_words_are_reported_at_their_column(text, message, col):
    fails(text, message, 1, col)


# ---- G codes --------------------------------------------------------------------

@pytest.mark.parametrize("text, message", [
    ("G5", "unknown G code G5"),
    ("G-1", "unknown G code G-1"),
    ("G18", "G18 (XZ plane) is not supported: this machine draws in the XY plane only"),
    ("G19", "G19 (YZ plane) is not supported"),
    ("G93", "inverse time"),
    ("G41", "cutter radius compensation"),
    ("G0 G1 X1", "two motion codes on one line: G0 and G1"),
    ("G90 G91", "two distance codes"),
    ("G20 G21", "two units codes"),
    ("G4 P1 G28", "two non-modal codes"),
])
def test_refused_g_codes(text, message):
    fails(text, message, 1)


def test_preamble_codes_are_accepted():
    assert ops("G17 G21 G40 G49 G54 G61 G64 G80 G90 G94 G91.1\nG00 X1") == [move(MM, 0)]


def test_motion_codes_are_modal_and_missing_axes_keep_their_value():
    assert ops("G1 X1 Y2\nX3\nY4\nG0 X5\nY6") == [
        line(MM, 2 * MM), line(3 * MM, 2 * MM), line(3 * MM, 4 * MM),
        move(5 * MM, 4 * MM), move(5 * MM, 6 * MM)]
    assert ops("G01\nX1") == [line(MM, 0)]


def test_coordinates_before_any_motion_code_travel_like_grbl():
    assert ops("X1 Y1") == [move(MM, MM)]


def test_incremental_mode():
    assert ops("G0 X10 Y10\nG91 G1 X1 Y-2\nX1\nG90 X0") == [
        move(10 * MM, 10 * MM), line(11 * MM, 8 * MM), line(12 * MM, 8 * MM), line(0, 8 * MM)]


def test_dwell_in_milliseconds_or_seconds():
    assert ops("G4 P500\nG04 X1.5\nG4 P0.5\nG4 P0") == [
        (K.DWELL, 0, 0, 0, 0, NO_TOOL, v) for v in (500, 1500, 1, 0)]


@pytest.mark.parametrize("text, message", [
    ("G4", "needs P (milliseconds) or X (seconds)"),
    ("G4 P-1", "dwell time of 0 or more"),
    ("G4 P1 X1", "only P (milliseconds) or X (seconds)"),
    ("G4 P1 Y1", "only P (milliseconds) or X (seconds)"),
    ("G4 G1 P1", "cannot share a line with a motion code"),
    ("G1 X1 P5", "P is only used with G4"),
])
def test_dwell_errors(text, message):
    fails(text, message, 1)


def test_home_travels_to_the_frame_origin_and_is_marked():
    program = read("G0 X5 Y5\nG28\nG0 X1\nG28 X3 Y4")
    assert [(K(r[0]), *r[1:3]) for r in program.table.tolist()] == [
        (K.MOVE, 5 * MM, 5 * MM), (K.MOVE, 0, 0), (K.MOVE, MM, 0),
        (K.MOVE, 3 * MM, 4 * MM), (K.MOVE, 0, 0)]
    assert program.metadata["home_rows"] == [1, 4]
    assert read("G0 X1").metadata["home_rows"] == []


def test_home_lifts_the_pen_until_the_file_lowers_it():
    assert kinds("M3\nG28\nG1 X1") == [K.PEN_DOWN, K.MOVE, K.LINE]
    assert kinds("G1 Z-1\nG28\nG1 X1\nZ-1\nX2") == [K.PEN_DOWN, K.MOVE, K.LINE, K.PEN_DOWN, K.LINE]


def test_home_through_the_current_point_is_one_travel():
    program = read("G0 X5 Y5 Z1\nG28 G91 Z0\nG90 G0 X1\nG91 G28 X0 Y0")  # CAM retract idioms
    assert [(K(r[0]), *r[1:3]) for r in program.table.tolist()] == [
        (K.MOVE, 5 * MM, 5 * MM), (K.MOVE, 0, 0), (K.MOVE, MM, 0), (K.MOVE, 0, 0)]
    assert program.warnings == []


def test_set_position_shifts_later_coordinates():
    text = "G0 X10 Y10\nG92 X0 Y0\nG1 X1 Y1\nG92 X5\nX6\nG92.1\nX6\nG92\nY0"
    assert ops(text) == [move(10 * MM, 10 * MM), line(11 * MM, 11 * MM),
                         line(12 * MM, 11 * MM), line(6 * MM, 11 * MM), line(6 * MM, 11 * MM)]


def test_set_position_applies_to_arcs_and_incremental_moves():
    assert ops("G0 X10\nG92 X0\nG91 G1 X1\nG90 G2 X3 Y0 I1 J0") == [
        move(10 * MM, 0), line(11 * MM, 0), (K.ARC_CW, 13 * MM, 0, MM, 0, NO_TOOL, 0)]


@pytest.mark.parametrize("text, message", [
    ("G92 G1 X1", "both want the axis words"),
    ("G92.1 X1", "takes no axis words"),
    ("G92 I1", "I belongs to an arc"),
    ("G28 R1", "R belongs to an arc"),
])
def test_set_position_and_home_errors(text, message):
    fails(text, message, 1)


# ---- arcs -------------------------------------------------------------------

def test_arcs_with_centre_offsets():
    assert ops("G0 X10\nG3 X0 Y10 I-10 J0\nG2 X10 Y0 J-10") == [
        move(10 * MM, 0),
        (K.ARC_CCW, 0, 10 * MM, -10 * MM, 0, NO_TOOL, 0),
        (K.ARC_CW, 10 * MM, 0, 0, -10 * MM, NO_TOOL, 0)]


def test_full_circle_when_end_is_start():
    assert ops("G0 X5\nG2 I-5")[1] == (K.ARC_CW, 5 * MM, 0, -5 * MM, 0, NO_TOOL, 0)


def test_incremental_arcs_keep_centre_relative_to_start():
    assert ops("G0 X10 Y0\nG91 G3 X-10 Y10 I-10 J0")[1] == (
        K.ARC_CCW, 0, 10 * MM, -10 * MM, 0, NO_TOOL, 0)


def test_absolute_arc_centres_with_g90_1():
    assert ops("G90.1 G0 X10\nG3 X0 Y10 I0 J0")[1] == (K.ARC_CCW, 0, 10 * MM, -10 * MM, 0, NO_TOOL, 0)
    fails("G90.1\nG3 X0 Y10 I0", "needs both I and J", 2)


@pytest.mark.parametrize("code, r, centre", [
    ("G3", "5", (5, 0)),   # counter-clockwise, short (90 degrees)
    ("G3", "-5", (0, 5)),  # counter-clockwise, long (270 degrees)
    ("G2", "5", (0, 5)),
    ("G2", "-5", (5, 0)),
])
def test_r_form_picks_the_short_or_long_arc(code, r, centre):
    # Start (5, 5) mm, end (0, 0): the circles of radius 5 through both are
    # centred at (5, 0), left of the chord, and (0, 5), right of it.
    arc = read(f"G0 X5 Y5\n{code} X0 Y0 R{r}").op(1)
    assert (arc.x_nm, arc.y_nm) == (0, 0)
    assert (5 * MM + arc.i_nm, 5 * MM + arc.j_nm) == (centre[0] * MM, centre[1] * MM)


def test_r_form_centre_is_rounded_to_the_nearest_nm():
    # Chord 1 mm along X, R 1 mm: centre at (0.5, +-sqrt(0.75)) = 0.866025403... mm.
    arc = read("G2 X1 R1").op(0)
    assert (arc.i_nm, arc.j_nm) == (500_000, -866_025)
    arc = read("G3 X1 R1").op(0)
    assert (arc.i_nm, arc.j_nm) == (500_000, 866_025)
    arc = read("G3 X0.000001 R0.000001").op(0)  # 1 nm chord: centre x 0.5 nm rounds away
    assert (arc.i_nm, arc.j_nm) == (1, 1)


def test_half_circle_tolerates_a_radius_rounded_by_the_cam():
    arc = read("G2 X10 R4.999").op(0)  # 1 um short of half the 10 mm chord
    assert (arc.i_nm, arc.j_nm) == (5 * MM, 0)


@pytest.mark.parametrize("text, message, line_no", [
    ("G1 X10\nG2 X0 Y0 R4", "R4 is too small", 2),
    ("G2 X1 R0", "zero radius", 1),
    ("G2 X1 I0 J0", "zero radius", 1),
    ("G2 I0", "zero radius", 1),
    ("G2 R5", "cannot be a full circle", 1),
    ("G2 X1 R1 I1", "either R or I/J", 1),
    ("G2 X1", "needs the centre (I, J) or the radius (R)", 1),
    ("G3 X10 I3 J0", "not on the arc", 1),
    ("G1 X1 R2", "R belongs to an arc", 1),
])
def test_arc_errors_name_the_line(text, message, line_no):
    fails(text, message, line_no)


def test_small_radius_mismatch_is_tolerated():
    assert kinds("G3 X10.004 I5 J0") == [K.ARC_CCW]


# ---- pen, tools, program end ----------------------------------------------------

def test_m3_m5_are_pen_down_and_up():
    assert ops("M3\nM5\nM03\nM4\nM05") == [PEN_DOWN, PEN_UP, PEN_DOWN, PEN_DOWN, PEN_UP]
    fails("M3 M5", "two pen (M3/M4/M5) codes", 1, 4)


def test_z_is_pen_height():
    assert kinds("G0 Z5\nG1 Z0\nZ-1\nG1 Z2\nZ0.001") == [K.PEN_DOWN, K.PEN_UP]
    assert kinds("G1 Z-1 X1") == [K.PEN_DOWN, K.LINE]
    assert kinds("G1 Z1 X1") == [K.LINE]  # pen already up


def test_z_follows_distance_mode_and_g92():
    assert kinds("G0 Z1\nG91 Z-1\nZ1") == [K.PEN_DOWN, K.PEN_UP]
    assert kinds("G0 Z5\nG92 Z0\nZ-0.5\nG92.1\nZ5") == [K.PEN_DOWN, K.PEN_UP]


def test_incremental_z_before_any_absolute_z_counts_from_zero():
    program = read("G91 Z-1")
    assert [K(k) for k in program.kind] == [K.PEN_DOWN]
    assert "incremental Z" in program.warnings[0].message


def test_travel_lifts_the_pen_and_drawing_resumes_where_the_file_wants_it():
    assert ops("M3\nG0 X5\nG1 X6") == [PEN_DOWN, move(5 * MM, 0), PEN_DOWN, line(6 * MM, 0)]
    assert kinds("M3\nG0 X5\nM5\nG1 X6") == [K.PEN_DOWN, K.MOVE, K.PEN_UP, K.LINE]
    assert kinds("G1 Z-1\nG0 X5\nG2 X5 I1") == [K.PEN_DOWN, K.MOVE, K.PEN_DOWN, K.ARC_CW]
    assert kinds("G1 Z-1\nG0 X5\nZ3\nG1 X6") == [K.PEN_DOWN, K.MOVE, K.LINE]


def test_travel_that_lowers_the_pen_lowers_it_on_arrival():
    assert positions("G0 X5 Z-1") == [(K.MOVE, 1, 1), (K.PEN_DOWN, 1, 7)]
    assert kinds("M3\nG0 X5 Z5\nG1 X6") == [K.PEN_DOWN, K.MOVE, K.LINE]


def test_pen_selection():
    assert ops("T2 M6\nG1 X1\nG0 X0\nT3\nG2 I1") == [
        (K.SELECT, 0, 0, 0, 0, 2, 0), line(MM, 0, tool=2), move(0, 0),
        (K.SELECT, 0, 0, 0, 0, 3, 0), (K.ARC_CW, 0, 0, MM, 0, 3, 0)]
    fails("T1.5", "whole pen number", 1, 1)


def test_motor_and_pause_codes_are_accepted_silently_and_unknown_m_codes_warn():
    program = read("M17\nM18\nM84\nM6\nM7\nM0\nM1\nM8")
    assert len(program) == 0
    assert [(w.pos.line, w.message) for w in program.warnings] == [
        (5, "unknown M code M7 is ignored"), (8, "unknown M code M8 is ignored")]


def test_s_words_are_ignored():
    assert kinds("M3 S1000\nG1 X1 S90") == [K.PEN_DOWN, K.LINE]


@pytest.mark.parametrize("end", ["M2", "M02", "M30"])
def test_program_end_ignores_the_rest_with_one_warning(end):
    program = read(f"G1 X1 {end}\n\n(comment)\n%\nG1 X2\nthis is not G-code\n")
    assert [K(k) for k in program.kind] == [K.LINE]
    assert len(program.warnings) == 1
    warning = program.warnings[0]
    assert (warning.pos.line, warning.pos.col) == (5, 1)
    assert "after the program end" in warning.message
    assert program.line_count == 6


def test_errors_print_as_one_line_with_position_and_excerpt():
    err = fails("G1 X1\nG1 X1 Q5", "unknown word 'Q'", 2, 7)
    assert str(err) == ("t.nc:2:7: unknown word 'Q': expected one of G M N X Y Z I J R F P T S"
                        "\n    G1 X1 Q5")
    assert isinstance(err, GalileoError)


def test_undecodable_bytes_in_comments_are_fine_and_in_code_are_errors(tmp_path):
    path = tmp_path / "latin1.nc"
    path.write_bytes(b"(Gr\xf6\xdfe)\nG0 X1\n")
    assert len(read_gcode(path)) == 1
    path.write_bytes(b"G0 X1\xf6\n")
    with pytest.raises(GcodeError) as info:
        read_gcode(path)
    assert (info.value.pos.line, info.value.pos.col) == (1, 6)


@pytest.mark.parametrize("ending", ["\n", "\r\n", "\r"])
def test_line_endings_and_byte_order_mark(tmp_path, ending):
    path = tmp_path / "endings.nc"
    path.write_bytes(b"\xef\xbb\xbf" + ending.join(["G0 X1", "G1 Y2", ""]).encode())
    assert [(K(r[0]), r[7], r[8]) for r in read_gcode(path).table.tolist()] == [
        (K.MOVE, 1, 1), (K.LINE, 2, 1)]
    path.write_bytes(ending.join(["G0 X1", "G1 Y2", "Q"]).encode())
    with pytest.raises(GcodeError) as info:
        read_gcode(path)
    assert info.value.pos.line == 3
    assert read_gcode("t.nc", "\ufeffG0 X1").op(0).pos.col == 1


# ---- sniffing ---------------------------------------------------------------

@pytest.mark.parametrize("text", [
    SAMPLE.read_text(),
    "G21\nG0 X1 Y1\n",
    "; generated\n(by hand)\n\n%\nN1 G1 X1*80\nM2\n",
    "g1 x1.5 y2\n",
    "G1 X1 ; a remark*\n",
])
def test_gcode_is_recognised(text):
    assert looks_like_gcode(text)


@pytest.mark.parametrize("text", [
    "", "\n\n", "(only a comment)\n",
    "%FSLAX26Y26*%\n%MOMM*%\n",
    "G04 a Gerber comment*\nG75*\n",
    "X100Y200D01*\n",
    "M48\nINCH,LZ\nT01C0.8\n%\n",
    "G90\nM72\nM48\n",
    "%\nG90\nT01\nX00130500Y00184500\n",
    "hello world\n",
    "G1 X1 (unclosed\n",
])
def test_other_text_is_not_gcode(text):
    assert not looks_like_gcode(text)


@pytest.mark.skipif(not corpus_paths("real"), reason="no Gerber corpus (tests/corpus.py)")
def test_no_corpus_file_is_taken_for_gcode():
    taken = []
    for path in corpus_paths("real", "synthetic", "derived", "invalid", "drill"):
        text = (CORPUS / path).read_bytes().decode("utf-8", "replace")
        if looks_like_gcode(text):
            taken.append(path)
    assert taken == []


# ---- writer -------------------------------------------------------------------

def same_ops(a, b) -> bool:
    return a.table[:, :7].tolist() == b.table[:, :7].tolist()


def test_written_sample_reads_back_to_the_same_ops():
    program = read_gcode(SAMPLE)
    text = write_gcode(program)
    assert text.splitlines()[1] == "G21 G90 G17" and text.endswith("M2\n")
    assert same_ops(read_gcode("w.nc", text), program)


def test_writer_keeps_units_exact_and_homes():
    program = read("G20 F7.5\nG0 X0.00001 Y-1.23456\nG28\nT4\nM3\nG4 P250\nG3 X1 Y0 I0.5 J0.25\nM5")
    again = read_gcode("w.nc", write_gcode(program))
    assert same_ops(again, program)
    assert again.metadata["home_rows"] == program.metadata["home_rows"] == [2]
    assert "G28" in write_gcode(program)


def test_writer_keeps_a_line_drawn_with_the_pen_up_after_a_travel():
    program = read("M3\nG0 X1\nG1 Z1 X2")  # the file lifted the pen: LINE without PEN_DOWN
    assert kinds("M3\nG0 X1\nG1 Z1 X2") == [K.PEN_DOWN, K.MOVE, K.LINE]
    assert same_ops(read_gcode("w.nc", write_gcode(program)), program)


def test_writer_numbers():
    from galileo_cnc.readers.gcode.writer import mm

    assert [mm(v) for v in (0, 1, -1, 1_500_000, -12_000_000, 123_456_789)] == [
        "0", "0.000001", "-0.000001", "1.5", "-12", "123.456789"]


def test_a_feed_is_written_as_the_file_wrote_it():
    # issue 31, item 19: F100 (1666667 nm/s) was written back as F100.00002
    for feed in ("100", "7.5", "0.00006", "6000", "333.3"):
        text = write_gcode(read(f"G21\nG1 X1 F{feed}"))
        assert f"F{feed}" in text.split(), text
        assert same_ops(read_gcode("w.nc", text), read(f"G21\nG1 X1 F{feed}"))


def _program(*rows):
    builder = ProgramBuilder("built")
    for row in rows:
        builder.emit(*row)
    return builder.build("gerber", "mm")


def test_writer_refuses_ops_without_a_gcode_equivalent():
    # in words and mm, not `FLASH` (issue 31, item 14)
    with pytest.raises(GcodeExportError, match=r"^built:7:3: the flash of D10 at X 2.5 Y 1 mm "
                       r"\(file coordinates\): G-code has no such thing") as info:
        write_gcode(_program((int(K.MOVE), 1, 1),
                             (int(K.FLASH), 2_500_000, 1_000_000, 0, 0, 10, 0, 7, 3)))
    assert str(info.value.pos) == "built:7:3"
    with pytest.raises(GcodeExportError, match="feed rate must be positive"):
        write_gcode(_program((int(K.FEED), 0, 0, 0, 0, NO_TOOL, 0)))


def test_writer_selects_the_pen_an_op_carries():
    program = _program((int(K.LINE), MM, 0, 0, 0, 5))
    text = write_gcode(program)
    assert "T5 M6" in text
    assert ops(text) == [(K.SELECT, 0, 0, 0, 0, 5, 0), line(MM, 0, tool=5)]


def test_a_bad_line_after_good_ones_is_reported_as_a_gcode_error(tmp_path):
    from galileo_cnc.readers import read_file

    path = tmp_path / "drawing.txt"
    path.write_text("G21\nG1 X10 Y\n")
    with pytest.raises(GcodeError) as caught:
        read_file(path)
    assert (caught.value.pos.line, caught.value.pos.col) == (2, 8)
