"""%LM/%LR/%LS on aperture outlines: a flash or draw under a load transform uses the
aperture's image (mirrored, then rotated, then scaled about its origin), registered
as a derived aperture (galileo_cnc/readers/gerber/transformed.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from corpus import CORPUS

from galileo_cnc.errors import GerberError
from galileo_cnc.program.extents import extents
from galileo_cnc.program.ops import KIND, NO_TOOL, TOOL, OpKind
from galileo_cnc.readers.gerber import read_gerber
from galileo_cnc.readers.gerber.load import LoadTransform
from galileo_cnc.readers.gerber.transformed import (aperture_label, source_code,
                                                    with_source_apertures)

MM = 1_000_000
HEADER = "%FSLAX46Y46*%%MOMM*%"
# An asymmetric macro: a right triangle with its right angle at the origin, legs 1 mm
# along +X and 2 mm along +Y, and a 0.4 mm dot centred at (1, 1).
TRIANGLE = "%AMTRI*4,1,3,0,0,1,0,0,2,0,0,0*1,1,0.4,1,1*%"


def read(body: str, min_run: int = 10**9):
    return read_gerber("t.gbr", HEADER + body + "M02*", min_run=min_run)


def tools_of(program, kind: OpKind) -> list[int]:
    return program.table[program.table[:, KIND] == int(kind), TOOL].tolist()


def flashed(program):
    """The aperture of the only flash."""
    (tool,) = tools_of(program, OpKind.FLASH)
    return program.apertures[tool]


def shoelace(points) -> float:
    p = np.array(points, dtype=np.float64)
    return 0.5 * float(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))


# --- standard apertures ------------------------------------------------------------

def test_a_rectangle_flashed_under_lr90_is_the_rotated_rectangle():
    program = read("%ADD10R,2X1*%D10*%LR90*%X0Y0D03*")
    aperture = flashed(program)
    assert (aperture.shape, aperture.params_nm) == ("rectangle", (1 * MM, 2 * MM))
    assert aperture.extent_nm == (-MM // 2, -MM, MM // 2, MM)
    (tool,) = tools_of(program, OpKind.FLASH)
    assert tool != 10 and source_code(tool) == 10
    assert tools_of(program, OpKind.SELECT) == [10]  # what the file selected
    assert program.apertures[10].params_nm == (2 * MM, 1 * MM)  # the file's aperture stays
    assert aperture_label(program, tool) == "D10 under %LR90"
    assert not program.warnings


def test_a_rectangle_at_30_degrees_becomes_its_rotated_outline_with_the_hole():
    program = read("%ADD10R,2X1X0.4*%%LR30*%D10*X0Y0D03*")
    aperture = flashed(program)
    assert aperture.shape == "macro"
    (_, dark, corners), (kind, hole_dark, cx, cy, diameter) = aperture.primitives
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    expected = [(round(x * c - y * s), round(x * s + y * c))
                for x, y in [(-MM, -MM / 2), (MM, -MM / 2), (MM, MM / 2), (-MM, MM / 2)]]
    assert dark and list(corners) == expected
    assert (kind, hole_dark, cx, cy, diameter) == ("circle", False, 0, 0, 400_000)
    width = 2 * MM * c + 1 * MM * s  # the turned rectangle's bounding box
    height = 2 * MM * s + 1 * MM * c
    x0, y0, x1, y1 = aperture.extent_nm
    assert abs((x1 - x0) - width) <= 2 and abs((y1 - y0) - height) <= 2


@pytest.mark.parametrize("template, size, scaled", [
    ("C,1", (MM,), (MM // 2,)),
    ("O,2X1", (2 * MM, MM), (MM, MM // 2)),
    ("R,0.003X0.001", (3_000, 1_000), (1_500, 500)),
])
def test_ls_half_halves_circles_obrounds_and_rectangles(template, size, scaled):
    program = read(f"%ADD10{template}*%%LS0.5*%D10*X0Y0D03*")
    aperture = flashed(program)
    assert aperture.shape == program.apertures[10].shape
    assert program.apertures[10].params_nm == size
    assert aperture.params_nm == scaled


def test_ls_scales_the_hole_and_rounds_half_nanometres_away_from_zero():
    program = read("%ADD10C,0.000003X0.000001*%%LS0.5*%D10*X0Y0D03*")
    assert (flashed(program).params_nm, flashed(program).hole_nm) == ((2,), (1,))


def test_a_circle_only_turned_or_mirrored_is_the_same_aperture():
    program = read("%ADD10C,1X0.3*%D10*%LMXY*%%LR33*%X0Y0D03*X1000000Y0D01*")
    assert tools_of(program, OpKind.FLASH) == [10] and tools_of(program, OpKind.LINE) == [10]
    assert list(program.apertures) == [10]
    assert "derived_apertures" not in program.metadata


def test_a_polygon_aperture_takes_the_mirror_and_turn_into_its_phase():
    # Mirrored in X a vertex at 10 degrees goes to 170; turned by 20 it is at 190.
    program = read("%ADD10P,1X5X10*%%LMX*%%LR20*%D10*X0Y0D03*")
    aperture = flashed(program)
    assert (aperture.shape, aperture.vertices, aperture.rotation_udeg) == ("polygon", 5, 190_000_000)
    assert aperture.params_nm == (MM,)


def test_obround_quarter_turns_swap_its_sides_and_other_angles_make_a_stadium():
    quarter = flashed(read("%ADD10O,2X1*%%LR270*%D10*X0Y0D03*"))
    assert (quarter.shape, quarter.params_nm) == ("obround", (MM, 2 * MM))
    turned = flashed(read("%ADD10O,2X1*%%LR45*%D10*X0Y0D03*"))
    kinds = [p[0] for p in turned.primitives]
    assert kinds == ["polygon", "circle", "circle"]
    ends = [(p[2], p[3]) for p in turned.primitives[1:]]
    r = MM / 2 / math.sqrt(2)  # the end circles sit 0.5 mm out, now at 45 degrees
    assert ends == [(round(-r), round(-r)), (round(r), round(r))]
    assert all(p[4] == MM for p in turned.primitives[1:])


# --- macros ------------------------------------------------------------------------

def test_lmx_mirrors_an_asymmetric_macro():
    program = read(TRIANGLE + "%ADD10TRI*%%LMX*%D10*X0Y0D03*")
    (_, _, triangle), (_, _, cx, cy, diameter) = flashed(program).primitives
    assert set(triangle) == {(0, 0), (-MM, 0), (0, 2 * MM)}  # the outline repeats its start
    assert (cx, cy, diameter) == (-MM, MM, 400_000)
    assert shoelace(triangle) > 0  # written counter-clockwise, still counter-clockwise
    assert flashed(program).extent_nm == (-MM - 200_000, 0, 0, 2 * MM)


def test_lmy_then_lr90_then_ls2_in_that_order():
    # (1, 0) mirrored in Y stays (1, 0), turned a quarter is (0, 1), doubled (0, 2);
    # (0, 2) mirrored is (0, -2), turned (2, 0), doubled (4, 0).
    program = read(TRIANGLE + "%ADD10TRI*%%LMY*%%LR90*%%LS2*%D10*X0Y0D03*")
    (_, _, triangle), (_, _, cx, cy, diameter) = flashed(program).primitives
    assert set(triangle) == {(0, 0), (0, 2 * MM), (4 * MM, 0)}
    assert (cx, cy, diameter) == (2 * MM, 2 * MM, 800_000)


def test_a_macro_turned_30_degrees_rounds_each_point_once():
    program = read(TRIANGLE + "%ADD10TRI*%%LR30*%%LS0.5*%D10*X0Y0D03*")
    (_, _, triangle), _ = flashed(program).primitives
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    expected = [(round((x * c - y * s) * 0.5), round((x * s + y * c) * 0.5))
                for x, y in [(0, 0), (MM, 0), (0, 2 * MM), (0, 0)]]
    assert list(triangle) == expected
    assert "TRI %LR30 %LS0.5" in flashed(program).describe()


# --- draws, caching, state ------------------------------------------------------------

def test_draws_and_arcs_use_the_transformed_aperture_too():
    program = read("%ADD10C,0.2*%%ADD11R,0.3X0.1*%%LS2*%D10*X0Y0D02*X1000000Y0D01*G75*G03X0Y0"
                   "I-500000J0D01*%LR90*%D11*G01*X0Y1000000D01*")
    line, arc, rect_line = (program.table[program.table[:, KIND] == int(k), TOOL].tolist()
                            for k in (OpKind.LINE, OpKind.ARC_CCW, OpKind.LINE))
    assert program.apertures[line[0]].params_nm == (400_000,)
    assert arc == [line[0]]
    assert program.apertures[line[1]].params_nm == (200_000, 600_000)  # turned, doubled


def test_one_derived_aperture_per_aperture_and_transform():
    program = read("%ADD10R,2X1*%%ADD11R,1X1*%D10*%LR30*%X0Y0D03*X1000000Y0D03*%LR0*%"
                   "X2000000Y0D03*%LR30*%X3000000Y0D03*D11*X4000000Y0D03*D10*%LR390*%X0Y0D03*")
    tools = tools_of(program, OpKind.FLASH)
    assert tools[2] == 10  # no transform: the file's aperture
    assert tools[0] == tools[1] == tools[3] == tools[5]  # 390 degrees is 30
    assert source_code(tools[4]) == 11 and tools[4] != tools[0]
    assert len(program.apertures) == 4
    assert program.metadata["derived_apertures"] == {tools[0]: (10, "%LR30"), tools[4]: (11, "%LR30")}


def test_a_redefined_aperture_gets_a_new_image():
    program = read("%ADD10R,2X1*%%LR90*%D10*X0Y0D03*%ADD10R,4X1*%X0Y0D03*")
    first, second = tools_of(program, OpKind.FLASH)
    assert first != second
    assert program.apertures[first].params_nm == (MM, 2 * MM)
    assert program.apertures[second].params_nm == (MM, 4 * MM)


def test_regions_are_not_transformed():
    program = read("%ADD10R,2X1*%D10*%LR30*%G36*X0Y0D02*X1000000Y0D01*Y1000000D01*X0D01*G37*")
    assert set(tools_of(program, OpKind.LINE)) == {NO_TOOL}
    assert "derived_apertures" not in program.metadata


def test_a_block_flashed_under_a_transform_transforms_the_apertures_inside_it():
    program = read("%ADD10R,2X1*%%ABD20*%D10*X1000000Y0D03*%AB*%%LR90*%%LS0.5*%D20*X0Y0D03*")
    (x, y), = program.table[program.table[:, KIND] == int(OpKind.FLASH)][:, 1:3].tolist()
    assert (x, y) == (0, 500_000)
    assert flashed(program).params_nm == (500_000, MM)  # turned and halved
    assert aperture_label(program, tools_of(program, OpKind.FLASH)[0]) == "D10 under %LR90 %LS0.5"


def test_a_block_with_its_own_transform_flashed_under_another_composes_both():
    program = read("%ADD10R,2X1*%%ABD20*%%LR90*%D10*X0Y0D03*%LR0*%%AB*%%LS0.5*%D20*X0Y0D03*")
    tool = tools_of(program, OpKind.FLASH)[0]
    assert flashed(program).params_nm == (500_000, MM)
    assert aperture_label(program, tool) == "D10 under %LR90, then %LS0.5"


def test_an_image_out_of_range_is_an_error_at_the_flash():
    with pytest.raises(GerberError) as caught:
        read("%ADD10C,900000*%%LS1000*%D10*\nX0Y0D03*")
    assert caught.value.pos.line == 2 and "D10 under %LS1000" in str(caught.value)


def test_images_count_against_the_aperture_limit(monkeypatch):
    monkeypatch.setenv("GALILEO_MAX_APERTURES", "3")
    body = "%ADD10R,2X1*%D10*%LR10*%X0Y0D03*%LR20*%X0Y0D03*\n%LR30*%X0Y0D03*"
    with pytest.raises(GerberError) as caught:
        read(body)
    assert caught.value.pos.line == 2 and "GALILEO_MAX_APERTURES" in str(caught.value)
    monkeypatch.setenv("GALILEO_MAX_APERTURES", "4")
    assert len(read(body).apertures) == 4


def test_centre_mode_sees_the_file_apertures():
    program = read("%ADD10R,2X1*%D10*%LR30*%X0Y0D03*X1000000Y0D01*")
    plain = with_source_apertures(program)
    assert set(plain.table[np.isin(plain.table[:, KIND], (int(OpKind.FLASH), int(OpKind.LINE))),
                           TOOL].tolist()) == {10}
    assert list(plain.apertures) == [10]
    assert len(program.apertures) == 2  # the original is left as it was


def test_both_ways_of_reading_make_the_same_apertures():
    body = TRIANGLE + "%ADD10TRI*%%ADD11R,1X0.5*%%LR30*%D10*" + "".join(
        f"X{k * 100000}Y0D03*" for k in range(40)) + "D11*X0Y0D02*" + "".join(
        f"X{k * 100000}Y{k % 2 * 100000}D01*" for k in range(40))
    fast, reference = read(body, min_run=1), read(body)
    assert np.array_equal(fast.table, reference.table)
    assert fast.apertures == reference.apertures and fast.metadata == reference.metadata
    assert len(fast.apertures) == 4


def test_load_transform_rounds_once_and_quarter_turns_are_exact():
    load = LoadTransform()
    load.apply_command("LR90")
    load.apply_command("LS0.5")
    x, y = load.transform_xy(np.array([3, -3]), np.array([1, 1]))
    assert (x.tolist(), y.tolist()) == ([-1, -1], [2, -2])  # (-0.5 -> -1, 1.5 -> 2)
    load.apply_command("LR30")
    x, y = load.transform_xy(np.array([10**9]), np.array([0]))
    assert (x[0], y[0]) == (round(10**9 * math.cos(math.pi / 6) * 0.5), 250_000_000)


# --- the corpus files that use them -----------------------------------------------------

LOAD_FILES = sorted(p.relative_to(CORPUS).as_posix() for p in CORPUS.rglob("*.grb")
                    if any(c in p.read_text(errors="replace") for c in ("%LM", "%LR", "%LS")))


def test_the_corpus_has_files_with_load_transforms():
    assert len(LOAD_FILES) >= 10


@pytest.mark.parametrize("path", LOAD_FILES)
def test_corpus_files_with_load_transforms_read_and_keep_area_and_size(path):
    text = (CORPUS / path).read_text(errors="replace")
    program, reference = read_gerber(path, text, min_run=1), read_gerber(path, text, min_run=10**9)
    assert np.array_equal(program.table, reference.table)
    assert program.apertures == reference.apertures
    for key, (source, transform) in program.metadata.get("derived_apertures", {}).items():
        load = LoadTransform()
        for command in transform.split(", then ")[-1].split():
            load.apply_command(command[1:])
        original, image = program.apertures[source], program.apertures[key]
        if original.shape == "circle":
            assert image.params_nm == (load.scale_length(original.params_nm[0]),)
        if original.shape == "rectangle" and image.shape == "macro":
            (_, _, corners), = image.primitives  # turning keeps the area (times scale squared)
            w, h = original.params_nm
            assert abs(abs(shoelace(corners)) - w * h * float(load.scale) ** 2) < 2 * (w + h)
            angle = math.radians(float(load.rotation_deg))
            x0, y0, x1, y1 = image.extent_nm
            assert abs((x1 - x0) - w * abs(math.cos(angle)) - h * abs(math.sin(angle))) <= 2


def test_the_rotated_rectangles_widen_the_file_extents():
    path = "synthetic-pygerber/flashes_with_transform/00_rectangle_rotation_30.grb"
    program = read_gerber(path, (CORPUS / path).read_text())
    _, _, max_x, max_y = extents(program, with_apertures=True)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    # The last flash, at X 16.5 mm, is the 8 x 4 mm rectangle turned 30 degrees
    # (unturned it would reach 20.5 mm and 2 mm).
    assert abs(max_x - (16.5 * MM + (8 * c + 4 * s) / 2 * MM)) <= 2
    assert abs(max_y - (8 * s + 4 * c) / 2 * MM) <= 2
