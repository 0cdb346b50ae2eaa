"""Gerber reader: one test per feature of the format, on small hand-written files."""

from fractions import Fraction

import numpy as np
import pytest

from galileo_cnc.errors import GerberError
from galileo_cnc.program.ops import KIND, OpKind
from galileo_cnc.readers.gerber import looks_like_gerber, read_gerber
from galileo_cnc.readers.gerber.macros import MacroError, evaluate_expression

HEADER_MM = "%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.5*%\nD10*\n"


def read(text: str):
    return read_gerber("test.gbr", text)


def ops(program, *kinds):
    """(kind, x, y, i, j, tool) tuples of the rows of the given kinds."""
    wanted = [int(k) for k in kinds] if kinds else None
    return [tuple(row[:6]) for row in program.table.tolist()
            if wanted is None or row[KIND] in wanted]


def points(program, *kinds):
    return [(x, y) for _, x, y, *_ in ops(program, *kinds)]


# --- coordinate formats -------------------------------------------------------------

@pytest.mark.parametrize("integer, decimal", [(2, 4), (2, 5), (3, 5), (4, 6), (6, 6), (2, 6)])
def test_leading_zero_omission_any_format_mm(integer, decimal):
    scale = 10 ** decimal
    program = read(f"%FSLAX{integer}{decimal}Y{integer}{decimal}*%%MOMM*%%ADD10C,0.1*%D10*"
                   f"X{int(1.5 * scale)}Y-{scale // 4}D02*X{3 * scale}Y{scale}D01*M02*")
    assert points(program, OpKind.MOVE, OpKind.LINE) == [(1_500_000, -250_000), (3_000_000, 1_000_000)]


def test_trailing_zero_omission_pads_on_the_right():
    # 2.4 with trailing zeros omitted: "015" means 01.5000 -> 1.5 in, "-3" means -30.0000 in.
    program = read("%FSTAX24Y24*%%MOIN*%%ADD10C,0.01*%D10*X015Y-3D02*X0001Y00001D01*M02*")
    # "0001" is 00.0100 in, "00001" is 00.0010 in.
    assert points(program, OpKind.MOVE, OpKind.LINE) == [(38_100_000, -762_000_000), (254_000, 25_400)]


def test_inch_is_exact_to_the_nanometre():
    program = read("%FSLAX25Y25*%%MOIN*%%ADD10C,0.01*%D10*X1Y99999D02*M02*")
    assert points(program, OpKind.MOVE) == [(254, 25_399_746)]


def test_incremental_notation_accumulates():
    program = read("%FSLIX24Y24*%%MOMM*%%ADD10C,0.1*%D10*X10000Y10000D02*X10000D01*Y-5000D01*M02*")
    assert points(program, OpKind.MOVE, OpKind.LINE) == [(1_000_000, 1_000_000), (2_000_000, 1_000_000),
                                                         (2_000_000, 500_000)]


def test_modal_coordinates_keep_the_missing_axis():
    program = read(HEADER_MM + "X1000000Y2000000D02*X3000000D01*Y0D01*M02*")
    assert points(program, OpKind.LINE) == [(3_000_000, 2_000_000), (3_000_000, 0)]


def test_units_by_deprecated_g70_g71():
    program = read("%FSLAX24Y24*%G70*%ADD10C,0.01*%D10*X10000Y0D02*G71*X10000Y0D01*M02*")
    assert points(program, OpKind.MOVE, OpKind.LINE) == [(25_400_000, 0), (1_000_000, 0)]


def test_coordinates_without_d_code_repeat_the_last_one_with_a_warning():
    program = read(HEADER_MM + "X0Y0D02*X1000000D01*X2000000*M02*")
    assert points(program, OpKind.LINE) == [(1_000_000, 0), (2_000_000, 0)]
    assert any("repeat the last D code" in w.message for w in program.warnings)


# --- apertures ------------------------------------------------------------------

def test_standard_apertures_with_holes():
    program = read("%FSLAX46Y46*%%MOIN*%%ADD10C,0.01X0.005*%%ADD11R,0.1X0.05X0.02*%"
                   "%ADD12O,0.2X0.1*%%ADD13P,0.1X6X30X0.01*%M02*")
    ap = program.apertures
    assert (ap[10].shape, ap[10].params_nm, ap[10].hole_nm) == ("circle", (254_000,), (127_000,))
    assert (ap[11].shape, ap[11].params_nm, ap[11].hole_nm) == ("rectangle", (2_540_000, 1_270_000), (508_000,))
    assert ap[12].extent_nm == (-2_540_000, -1_270_000, 2_540_000, 1_270_000)
    assert (ap[13].vertices, ap[13].rotation_udeg, ap[13].params_nm) == (6, 30_000_000, (2_540_000,))
    assert ap[10].describe() == "0.254 mm round"


def test_macro_with_variables_arithmetic_and_primitives():
    program = read("%FSLAX46Y46*%%MOMM*%"
                   "%AMBOX*0 a box with a circle*$3=$1x2*21,1,$3,$2,0,0,0*1,1,($1+1)/2,0,$2*%"
                   "%ADD20BOX,1.5X0.5*%D20*X0Y0D03*M02*")
    ap = program.apertures[20]
    assert ap.shape == "macro" and ap.macro == "BOX"
    # Centre line 3.0 x 0.5 mm, circle of 1.25 mm at (0, 0.5).
    assert ap.primitives[0][0] == "polygon"
    assert ap.primitives[1] == ("circle", True, 0, 500_000, 1_250_000)
    assert ap.extent_nm == (-1_500_000, -250_000, 1_500_000, 1_125_000)


@pytest.mark.parametrize("primitive, extent", [
    ("1,1,2,1,1", (0, 0, 2_000_000, 2_000_000)),                    # circle
    ("20,1,0.2,0,0,3,0,0", (0, -100_000, 3_000_000, 100_000)),        # vector line
    ("21,1,4,2,0,0,90", (-1_000_000, -2_000_000, 1_000_000, 2_000_000)),  # centre line, rotated
    ("4,1,3,0,0,1,0,1,1,0,0,0", (0, 0, 1_000_000, 1_000_000)),      # outline
    ("5,1,4,0,0,2,0", (-1_000_000, -1_000_000, 1_000_000, 1_000_000)),  # square as polygon
    ("7,0,0,4,3,0.5,0", None),                                       # thermal
])
def test_macro_primitives_have_the_right_extent(primitive, extent):
    program = read(f"%FSLAX46Y46*%%MOMM*%%AMPRIM*{primitive}*%%ADD10PRIM*%M02*")
    ap = program.apertures[10]
    if extent is None:  # thermal: four dark sectors inside the 4 mm circle
        assert len(ap.primitives) == 4
        assert -2_000_000 <= ap.extent_nm[0] < -1_900_000 and 1_900_000 < ap.extent_nm[2] <= 2_000_000
    else:
        assert ap.extent_nm == extent


def test_expression_evaluation_is_exact():
    assert evaluate_expression("($1+0.1)x3/2-$2", {1: Fraction(1), 2: Fraction(1, 10)}) == Fraction(155, 100)
    assert evaluate_expression("-$1X-2", {1: Fraction(3)}) == 6
    with pytest.raises(MacroError):
        evaluate_expression("1/(2-2)", {})


def test_aperture_select_deprecated_g54():
    program = read("%FSLAX46Y46*%%MOMM*%%ADD10C,0.1*%%ADD11C,0.2*%G54D11*X0Y0D03*D10*X1D03*M02*")
    assert [row[5] for row in ops(program, OpKind.FLASH)] == [11, 10]


# --- draws, arcs, flashes -------------------------------------------------------

def test_d01_d02_d03_make_lines_moves_and_flashes_with_pen_down_before_drawing():
    program = read(HEADER_MM + "X0Y0D02*X1000000Y0D01*X2000000Y0D03*X3000000Y0D01*M02*")
    kinds = [OpKind(k) for k, *_ in ops(program)]
    assert kinds == [OpKind.SELECT, OpKind.MOVE, OpKind.PEN_DOWN, OpKind.LINE, OpKind.FLASH,
                     OpKind.PEN_DOWN, OpKind.LINE]


def test_multi_quadrant_arc_and_full_circle():
    program = read(HEADER_MM + "G75*X1000000Y0D02*G03X0Y1000000I-1000000J0D01*"
                   "G02X0Y1000000I0J-1000000D01*M02*")
    arcs = ops(program, OpKind.ARC_CW, OpKind.ARC_CCW)
    assert arcs == [(int(OpKind.ARC_CCW), 0, 1_000_000, -1_000_000, 0, 10),
                    (int(OpKind.ARC_CW), 0, 1_000_000, 0, -1_000_000, 10)]  # start == end: full circle


@pytest.mark.parametrize("start, end, ij, clockwise, centre", [
    ((1000, 0), (0, 1000), (1000, 0), False, (0, 0)),      # ccw quarter from +x to +y
    ((0, 1000), (1000, 0), (0, 1000), True, (0, 0)),       # cw back
    ((-1000, 0), (0, -1000), (1000, 0), False, (0, 0)),    # ccw third quadrant
    ((0, -1000), (1000, 0), (0, 1000), False, (0, 0)),     # ccw fourth quadrant
])
def test_single_quadrant_arc_picks_the_centre_by_the_spec(start, end, ij, clockwise, centre):
    g = "G02" if clockwise else "G03"
    program = read(f"%FSLAX46Y46*%%MOMM*%%ADD10C,0.1*%D10*G74*X{start[0]}Y{start[1]}D02*"
                   f"{g}X{end[0]}Y{end[1]}I{ij[0]}J{ij[1]}D01*M02*")
    (_, x, y, i, j, _), = ops(program, OpKind.ARC_CW, OpKind.ARC_CCW)
    assert (start[0] + i, start[1] + j) == centre


def test_regions_and_polarity():
    program = read(HEADER_MM + "%LPC*%G36*X0Y0D02*G01X1000000Y0D01*Y1000000D01*X0Y0D01*G37*%LPD*%M02*")
    kinds = [OpKind(k) for k, *_ in ops(program)]
    assert kinds[:4] == [OpKind.SELECT, OpKind.POLARITY, OpKind.REGION_BEGIN, OpKind.MOVE]
    assert kinds[-2:] == [OpKind.REGION_END, OpKind.POLARITY]
    region_lines = ops(program, OpKind.LINE)
    assert len(region_lines) == 3 and all(row[5] == -1 for row in region_lines)


def test_flash_inside_region_is_an_error():
    with pytest.raises(GerberError, match="not allowed inside a region"):
        read(HEADER_MM + "G36*X0Y0D03*G37*M02*")


def test_step_and_repeat_copies_the_block():
    program = read(HEADER_MM + "%SRX3Y2I5.0J10.0*%X0Y0D03*X1000000Y0D02*X2000000Y0D01*%SR*%M02*")
    flashes = sorted(points(program, OpKind.FLASH))
    assert flashes == sorted((x * 5_000_000, y * 10_000_000) for x in range(3) for y in range(2))
    assert len(ops(program, OpKind.LINE)) == 6


def test_step_and_repeat_moves_only_to_points_of_the_drawing():
    # issue 31, item 3: the block selects its aperture before any coordinate (a row at
    # 0, 0); no copy may travel there, and every row of a copy (its pen-down too) is moved
    program = read("%FSLAX46Y46*%%MOMM*%%ADD10C,0.2*%%SRX2Y1I20.0J0*%D10*"
                   "X100000000Y100000000D02*X110000000Y100000000D01*%SR*%M02*")
    assert points(program, OpKind.MOVE) == [(100_000_000, 100_000_000),
                                            (120_000_000, 100_000_000)]
    assert points(program, OpKind.PEN_DOWN) == points(program, OpKind.MOVE)
    assert points(program, OpKind.LINE) == [(110_000_000, 100_000_000),
                                            (130_000_000, 100_000_000)]


def test_a_step_and_repeat_block_that_draws_from_the_current_point_starts_there_moved():
    # the block's first draw starts where %SR found the pen (5, 0): each copy first goes
    # to that point moved, pen up, and lowers the pen there
    program = read(HEADER_MM + "X5000000Y0D02*X6000000Y0D01*%SRX1Y3I0J10.0*%"
                   "X5000000Y2000000D01*%SR*%M02*")
    table = [(OpKind(kind), x, y) for kind, x, y, *_ in ops(program)
             if kind in (OpKind.MOVE, OpKind.PEN_DOWN, OpKind.LINE)]
    mm = 1_000_000
    assert table[3:] == [(OpKind.PEN_DOWN, 6 * mm, 0), (OpKind.LINE, 5 * mm, 2 * mm)] + [
        row for k in (1, 2) for row in ((OpKind.MOVE, 6 * mm, 10 * k * mm),
                                        (OpKind.PEN_DOWN, 6 * mm, 10 * k * mm),
                                        (OpKind.LINE, 5 * mm, (10 * k + 2) * mm))]


def test_aperture_block_is_replayed_at_each_flash():
    program = read("%FSLAX46Y46*%%MOMM*%%ADD10C,0.1*%%ABD20*%D10*X0Y0D03*X1000000Y0D03*%AB*%"
                   "D20*X5000000Y5000000D03*X7000000Y5000000D03*M02*")
    assert points(program, OpKind.FLASH) == [(5_000_000, 5_000_000), (6_000_000, 5_000_000),
                                             (7_000_000, 5_000_000), (8_000_000, 5_000_000)]


def test_load_transforms_mirror_then_rotate_aperture_blocks_and_the_point_survives_the_block():
    program = read("%FSLAX46Y46*%%MOMM*%%ADD10C,0.1*%X0Y7000000D02*"
                   "%ABD20*%D10*X0Y0D02*X1000000Y0D01*G75*G03X1000000Y0I-500000J0D01*%AB*%"
                   "%LMX*%%LR90*%D20*X5000000D03*M02*")
    # (1, 0) mirrored in X is (-1, 0), turned a quarter is (0, -1); the flash is at
    # (5, 7): the missing Y comes from before the block, not from inside it.
    assert points(program, OpKind.MOVE, OpKind.LINE) == [(0, 7_000_000), (5_000_000, 7_000_000),
                                                         (5_000_000, 6_000_000)]
    (kind, _, _, i, j, _), = ops(program, OpKind.ARC_CW, OpKind.ARC_CCW)
    assert (OpKind(kind), i, j) == (OpKind.ARC_CW, 0, 500_000)  # one mirror reverses arcs


def test_load_transforms_and_attributes_are_kept():
    program = read("%TF.FileFunction,Copper,L1,Top*%%FSLAX46Y46*%%MOMM*%%TA.AperFunction,SMDPad*%"
                   "%ADD10C,0.1*%%TD.AperFunction*%%LMXY*%%LR45*%%LS0.5*%D10*X0Y0D03*M02*")
    assert program.metadata["attributes"] == {"TF.FileFunction": "Copper,L1,Top"}
    assert program.metadata["load_transforms"] == ["LMXY", "LR45", "LS0.5"]
    assert points(program, OpKind.FLASH) == [(0, 0)]


# --- deprecated image parameters ----------------------------------------------------

@pytest.mark.parametrize("parameter, expected_point, expected_arc", [
    ("%MIA1B0*%", (-2_000_000, 1_000_000), OpKind.ARC_CW),
    ("%OFA1.0B-2.0*%", (3_000_000, -1_000_000), OpKind.ARC_CCW),
    ("%IR90*%", (-1_000_000, 2_000_000), OpKind.ARC_CCW),
    ("%SFA2B0.5*%", (4_000_000, 500_000), OpKind.ARC_CCW),
    ("%ASAYBX*%", (1_000_000, 2_000_000), OpKind.ARC_CW),
    ("%IPNEG*%", (2_000_000, 1_000_000), OpKind.ARC_CCW),
])
def test_image_parameters_move_the_geometry(parameter, expected_point, expected_arc):
    program = read(f"%FSLAX46Y46*%%MOMM*%{parameter}%ADD10C,0.1*%D10*X2000000Y1000000D03*"
                   "G75*G03X2000000Y1000000I1000000J0D01*M02*")
    assert points(program, OpKind.FLASH) == [expected_point]
    assert [OpKind(row[0]) for row in ops(program, OpKind.ARC_CW, OpKind.ARC_CCW)] == [expected_arc]
    assert any(parameter[1:3] in w.message for w in program.warnings)


def test_deprecated_commands_without_geometry_are_warnings():
    program = read("%INboard*%%LNcopper*%%IJA0B0*%%ICAS*%%FSLAX46Y46*%%MOMM*%M02*")
    assert {"IN", "LN", "IJ"} <= set(program.metadata["warning_counts"])


# --- file structure ---------------------------------------------------------------

def test_several_commands_on_one_line_and_one_command_over_several_lines_with_crlf():
    text = ("%FSLAX46Y46*\r\nMOMM*%\r\n%AMTWO*\r\n1,1,\r\n0.5,0,0*\r\n%\r\n"
            "%ADD10TWO*%D10*X0Y0D03*X1000000\r\nY0D03*M02*\r\n")
    program = read(text)
    assert points(program, OpKind.FLASH) == [(0, 0), (1_000_000, 0)]


def test_missing_m02_and_garbage_after_m02_are_warnings():
    assert any("M02" in w.message for w in read(HEADER_MM + "X0Y0D03*").warnings)
    program = read(HEADER_MM + "X0Y0D03*M02*\nthis is not gerber %% at all")
    assert any("after M02" in w.message for w in program.warnings)


def test_positions_are_recorded_per_operation():
    program = read(HEADER_MM + "X0Y0D02*\n  X1000000Y0D01*\n")
    line = program.op(len(program) - 1)
    assert (line.kind, line.pos.line, line.pos.col) == (OpKind.LINE, 6, 3)


def test_rs274d_file_without_header_uses_placeholder_apertures():
    program = read("X-1000Y0D02*\nG54D10*\nX1000Y0D01*\n")
    assert points(program, OpKind.LINE) == [(2_540_000, 0)]
    assert program.apertures[10].params_nm == (0,)
    assert {"no-fs", "rs274d"} <= set(program.metadata["warning_counts"])


def test_content_sniffing():
    assert looks_like_gerber("G04 comment*\n%FSLAX24Y24*%")
    assert looks_like_gerber("%MOMM*%\n%FSLAX46Y46*%")
    assert not looks_like_gerber("G21\nG90\nG0 X10 Y10\n")


# --- errors ---------------------------------------------------------------------

@pytest.mark.parametrize("text, line, col, message", [
    ("%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.1*%\nD11*\n", 4, 1, "D11 is used but not defined"),
    ("%FSLAX46Y46*%\n%MOMM*%\n%ADD10Q,0.1*%\n", 3, 1, "neither C, R, O, P nor a defined macro"),
    ("%FSLAX46Y46*%\n%MOMX*%\n", 2, 1, "expected %MOMM* or %MOIN*"),
    ("%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.1*%\nD10*\n  X1Y1D01*X$Y1D01*\n", 5, 11, "letter followed by a number"),
    ("%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.1*%\nD10*\nX0Y0D01*\nX1\n", 6, 1,
     "the file ends inside this statement (no closing '*'): is the file cut short?"),
    ("%FSLAX46Y46*%\n%MOMM*%\n%AMM*1,1,(2*%\n", 3, 1, "missing ')'"),
    ("%FSLAX46Y46*%\n%MOMM*%\nX0Y0D01*\n", 3, 1, "aperture (Dnn) to be selected"),
    ("%FSQ*%\n", 1, 1, "expected %FS"),
    ("%FSLAX46Y46*%\n%MOMM*%\n%LPD*\nM02*\n", 3, 1, "the file ends inside this extended command"),
    ("%FSLAX46Y46*%\n%MOMM*%\n%XY12*%\n", 3, 1, "unknown extended command %XY"),
    ("%FSLAX46Y46*%\n%MOMM*%\nG37*\n", 3, 1, "G37 without a G36"),
    ("%FSLAX46Y46*%\n%MOMM*%\nX1Y12175000750000750000D02*\n", 3, 1, "more than 12 digits"),
    # issue 31, item 16: a vertex count that sizes nothing real (was an IndexError)
    ("%FSLAX46Y46*%\n%MOMM*%\n%AMBAD*\n4,1,-9999999999999999999,0,0,1,0,1,1,0,0,0*%\n"
     "%ADD10BAD*%\n", 5, 1, "outline primitive in macro BAD needs 1 or more vertices"),
])
def test_bad_input_names_line_column_and_what_was_expected(text, line, col, message):
    with pytest.raises(GerberError) as caught:
        read(text)
    error = caught.value
    assert (error.pos.line, error.pos.col) == (line, col)
    assert message in str(error)
    assert str(error).startswith(f"test.gbr:{line}:{col}: ")


def test_table_is_compact():
    # A million draws must fit comfortably: 9 int64 columns per op, nothing else per row.
    program = read(HEADER_MM + "".join(f"X{k}Y{k}D01*" for k in range(1000)) + "M02*")
    assert program.table.dtype == np.int64 and program.table.nbytes == len(program) * 9 * 8


# --- fuzzing the macro language ------------------------------------------------------

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_expression = st.one_of(
    st.sampled_from(["0", "1", "-1", ".5", "12", "999999999999", "-9999999999999999999",
                     "1E30", "1E-30", "$1", "$2", "$9",
                     "-$1", "$1x2", "($1+1)/2", "1/0", "(", "1+", "x", "3.14.15", "", "90", "360"]),
    st.text(alphabet="0123456789.$+-x/()E", max_size=8))
_primitive = st.builds(lambda code, args: ",".join([code] + args),
                       st.sampled_from(["0", "1", "2", "4", "5", "6", "7", "20", "21", "22", "3", "99"]),
                       st.lists(_expression, max_size=14))


@settings(max_examples=400, deadline=None)
@given(body=st.lists(st.one_of(_primitive, st.builds(lambda n, e: f"${n}={e}", st.integers(0, 12), _expression)),
                     min_size=1, max_size=5),
       parameters=st.lists(st.sampled_from(["0.5", "1", "-2", "1E3", "0", "99999999"]), max_size=4))
def test_random_macros_raise_only_gerber_errors(body, parameters):
    macro = "*".join(body)
    text = (f"%FSLAX46Y46*%%MOMM*%%AMM*{macro}*%%ADD10M{(',' + 'X'.join(parameters)) if parameters else ''}*%"
            "D10*X0Y0D03*M02*")
    try:
        program = read(text)
    except GerberError as error:
        assert error.pos.line == 1
        return
    assert program.apertures[10].shape == "macro"
