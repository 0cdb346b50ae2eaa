"""Ink the copper, first step: every Gerber object as its exact dark shape in integer nm,
dark united and clear subtracted in file order (galileo_cnc/plan/ink, docs/ink.md).

Curves are inscribed polygons within the chord tolerance, so a curved outline of
length L loses at most L x tolerance of area (and a hole of perimeter L gives it back
at most); straight outlines are exact."""

from __future__ import annotations

import math

import numpy as np
import pytest
from corpus import CORPUS, corpus_paths, manifest

from galileo_cnc.plan.ink import DEFAULT_TOLERANCE_NM, dark_geometry
from galileo_cnc.plan.ink.copper import looks_like_copper
from galileo_cnc.plan.ink.shapes import (
    capsules,
    circle_segments,
    circle_template,
    regular_polygon,
)
from galileo_cnc.program.extents import extents
from galileo_cnc.readers import read_file
from galileo_cnc.readers.gerber import read_gerber

MM = 1_000_000
MM2 = MM * MM
TOL = DEFAULT_TOLERANCE_NM
HEADER = "%FSLAX46Y46*%\n%MOMM*%\nG75*\n"


def ink(tmp_path, body: str, tolerance_nm: int = TOL, name: str = "t.gbr"):
    path = tmp_path / name
    path.write_text(HEADER + body + "M02*\n")
    program = read_file(path)
    return dark_geometry(program, tolerance_nm=tolerance_nm), program


def within_curve_bound(area: float, exact: float, curve_length_mm: float,
                       tolerance_nm: int = TOL, hole_length_mm: float = 0.0) -> bool:
    """Inscribed chords lose at most length x tolerance; holes lose it on the other side.
    One nm of vertex rounding is inside the tolerance (curves.chord_budget)."""
    lost = curve_length_mm * MM * tolerance_nm
    gained = hole_length_mm * MM * tolerance_nm
    return exact - lost <= area <= exact + gained


def holes(image) -> list[int]:
    return [len(h) for _, h in image.polygons()]


def is_integer_geometry(image) -> bool:
    return all(ring.dtype == np.int64 for shell, hs in image.polygons() for ring in [shell, *hs])


# --- flashes -----------------------------------------------------------------------


def test_square_pad_flash_is_exactly_the_square(tmp_path):
    image, _ = ink(tmp_path, "%ADD10R,1.5X1.5*%\nD10*\nX2000000Y3000000D03*\n")
    assert image.area_nm2() == 1.5 * 1.5 * MM2
    assert image.bounds() == (1_250_000, 2_250_000, 2_750_000, 3_750_000)
    assert holes(image) == [0]
    assert is_integer_geometry(image)


def test_rectangle_with_odd_nm_sides_keeps_its_size(tmp_path):
    # 0.000001 mm = 1 nm: sides of odd nanometres cannot be centred exactly; the size
    # is kept, the centre moves by half a nanometre.
    image, _ = ink(tmp_path, "%ADD10R,1.000001X0.500001*%\nD10*\nX0Y0D03*\n")
    xmin, ymin, xmax, ymax = image.bounds()
    assert (xmax - xmin, ymax - ymin) == (1_000_001, 500_001)
    assert image.area_nm2() == 1_000_001 * 500_001


@pytest.mark.parametrize("tolerance_nm", [TOL, 10 * TOL])
def test_circle_flash_area_within_the_tolerance_bound(tmp_path, tolerance_nm):
    image, _ = ink(tmp_path, "%ADD10C,1.0*%\nD10*\nX0Y0D03*\n", tolerance_nm)
    r = 0.5
    assert within_curve_bound(image.area_nm2(), math.pi * r * r * MM2, 2 * math.pi * r,
                              tolerance_nm)
    # vertices at 0, 90, 180, 270 degrees: the bounds are the circle's
    assert image.bounds() == (-500_000, -500_000, 500_000, 500_000)
    assert image.vertex_count() == circle_segments(r * MM, tolerance_nm)


def test_circle_polygon_chords_stay_within_tolerance():
    for diameter in (1_000, 100_000, 254_000, 1_000_000, 25_400_000, 100 * MM):
        ring = circle_template(diameter, TOL)
        r = diameter / 2
        assert len(ring) % 4 == 0
        # the sagitta of the chords, plus the rounding of the vertices
        sagitta = r * (1 - math.cos(math.pi / len(ring)))
        rounding = np.abs(np.hypot(ring[:, 0], ring[:, 1]) - r).max()
        assert sagitta + rounding <= TOL


def test_obround_flash(tmp_path):
    image, _ = ink(tmp_path, "%ADD10O,2X1*%\nD10*\nX0Y0D03*\n")
    exact = 1 * 1 + math.pi * 0.5 ** 2
    assert within_curve_bound(image.area_nm2(), exact * MM2, math.pi * 1.0)
    assert image.bounds() == (-MM, -500_000, MM, 500_000)


def test_polygon_flash_with_hole_and_rotation(tmp_path):
    image, _ = ink(tmp_path, "%ADD10P,2X6X30X0.5*%\nD10*\nX0Y0D03*\n")
    hexagon = 3 * math.sqrt(3) / 2 * 1.0 ** 2
    hole = math.pi * 0.25 ** 2
    assert within_curve_bound(image.area_nm2(), (hexagon - hole) * MM2, 0.0,
                              hole_length_mm=2 * math.pi * 0.25)
    assert holes(image) == [1]
    # rotated 30 degrees: corners at 30, 90, 150 ...; the top corner is at y = r
    xmin, ymin, xmax, ymax = image.bounds()
    assert (ymin, ymax) == (-MM, MM)
    assert xmax == -xmin == round(MM * math.cos(math.radians(30)))


def test_a_pad_hole_does_not_clear_the_copper_below(tmp_path):
    # Gerber: the hole is clear in the aperture only, it shows what lies beneath.
    image, _ = ink(tmp_path, "%ADD10R,4X4*%\n%ADD11C,2X1*%\n"
                             "D10*\nX0Y0D03*\nD11*\nX0Y0D03*\n")
    assert image.area_nm2() == 16 * MM2
    assert holes(image) == [0]


def test_rectangle_hole_in_a_rectangle(tmp_path):
    image, _ = ink(tmp_path, "%ADD10R,3X2X1X0.5*%\nD10*\nX0Y0D03*\n")
    assert image.area_nm2() == (6 - 0.5) * MM2
    assert holes(image) == [1]


# --- macros ---------------------------------------------------------------------------


def test_macro_with_clear_primitives(tmp_path):
    body = ("%AMCUT*21,1,2,2,0,0*21,0,1,1,0,0*%\n"     # 2x2 square, 1x1 cleared in its middle
            "%AMDONUT*1,1,1.0,3,0*1,0,0.5,3,0*%\n"      # disc with a clear disc: a ring at x=3
            "%ADD10CUT*%\n%ADD11DONUT*%\n"
            "D10*\nX0Y0D03*\nD11*\nX0Y0D03*\n")
    image, _ = ink(tmp_path, body)
    ring = math.pi * (0.5 ** 2 - 0.25 ** 2)
    assert within_curve_bound(image.area_nm2(), (3 + ring) * MM2, 2 * math.pi * 0.5,
                              hole_length_mm=2 * math.pi * 0.25)
    assert sorted(holes(image)) == [1, 1]


def test_a_clear_macro_primitive_clears_only_the_macro(tmp_path):
    image, _ = ink(tmp_path, "%AMCUT*21,1,2,2,0,0*21,0,1,1,0,0*%\n%ADD10CUT*%\n%ADD11R,3X3*%\n"
                             "D11*\nX0Y0D03*\nD10*\nX0Y0D03*\n")
    assert image.area_nm2() == 9 * MM2
    assert holes(image) == [0]


def test_macro_outline_thermal_and_rotation(tmp_path):
    # an outline triangle rotated 90 degrees, and a thermal; both exposed dark
    body = ("%AMTRI*4,1,3,0,0,2,0,0,1,0,0,90*%\n%AMTH*7,0,0,2,1,0.2,0*%\n"
            "%ADD10TRI*%\n%ADD11TH*%\nD10*\nX0Y0D03*\nD11*\nX10000000Y0D03*\n")
    image, _ = ink(tmp_path, body)
    triangle = 0.5 * 2 * 1
    polygons = image.polygons()
    assert len(polygons) == 5  # the triangle and the four thermal spokes
    tri = [p for p, _ in polygons if p[:, 0].max() < 5 * MM]
    assert len(tri) == 1
    assert abs(_ring_area(tri[0]) - triangle * MM2) <= 2  # rounded corners of a rotation
    assert tuple(tri[0].min(axis=0)) == (-MM, 0) and tuple(tri[0].max(axis=0)) == (0, 2 * MM)


def _ring_area(ring: np.ndarray) -> float:
    x, y = ring[:, 0].astype(float), ring[:, 1].astype(float)
    return abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))) / 2


# --- draws and arcs ---------------------------------------------------------------------


@pytest.mark.parametrize("end", [(10, 0), (6, 8), (-3, 7.5)])
def test_round_draw_is_a_capsule(tmp_path, end):
    ex, ey = end
    image, _ = ink(tmp_path, f"%ADD10C,0.5*%\nD10*\nX0Y0D02*\nG01*\n"
                             f"X{round(ex * MM)}Y{round(ey * MM)}D01*\n")
    length, r = math.hypot(ex, ey), 0.25
    exact = length * 2 * r + math.pi * r * r
    assert within_curve_bound(image.area_nm2(), exact * MM2, 2 * math.pi * r + 2 * length)
    assert holes(image) == [0]


def test_capsule_of_the_polygon_is_its_convex_hull():
    template = circle_template(500_000, TOL)
    starts = np.array([[0, 0], [5, 5], [0, 0]], dtype=np.int64) * MM
    ends = np.array([[3, 4], [5, 5], [-7, 1]], dtype=np.int64) * MM
    for ring, s, e in zip(capsules(template, starts, ends), starts, ends):
        hull = _hull(np.concatenate([template + s, template + e]))
        assert abs(_ring_area(ring) - _ring_area(hull)) <= 1e-6 * _ring_area(hull)


def _hull(points: np.ndarray) -> np.ndarray:
    pts = sorted(set(map(tuple, points.tolist())))

    def half(seq):
        out = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    return np.array(half(pts)[:-1] + half(pts[::-1])[:-1])


def test_rectangle_draw_is_the_minkowski_sum(tmp_path):
    # 1 x 0.5 rectangle swept by (3, 4): area w*h + |dx|*h + |dy|*w, exactly
    image, _ = ink(tmp_path, "%ADD10R,1X0.5*%\nD10*\nX0Y0D02*\nG01*\nX3000000Y4000000D01*\n")
    assert image.area_nm2() == (1 * 0.5 + 3 * 0.5 + 4 * 1) * MM2
    assert image.bounds() == (-500_000, -250_000, 3_500_000, 4_250_000)


def test_macro_draw_is_the_minkowski_sum_of_a_non_convex_aperture(tmp_path):
    # two 1x1 squares at y = +-1 (a gap between them) drawn 3 mm along x: two 4x1
    # bars with the gap kept (the convex hull would fill it); then diagonally
    body = ("%AMTWO*21,1,1,1,0,1*21,1,1,1,0,-1*%\n%ADD10TWO*%\nD10*\n"
            "X0Y0D02*\nG01*\nX3000000Y0D01*\n")
    image, _ = ink(tmp_path, body)
    assert image.area_nm2() == 8 * MM2
    assert len(image.polygons()) == 2
    image, _ = ink(tmp_path, "%AMSQ*21,1,1,1,0,0*%\n%ADD10SQ*%\nD10*\nX0Y0D02*\nG01*\n"
                             "X3000000Y4000000D01*\n")
    assert image.area_nm2() == (1 + 3 + 4) * MM2


def test_polygon_and_obround_draws_are_their_convex_sweeps(tmp_path):
    # a square polygon aperture (diagonal 2, turned 45 degrees: sides 2/sqrt 2 along
    # the axes) drawn along x is a rectangle; an obround drawn along its long axis too
    image, _ = ink(tmp_path, "%ADD10P,2X4X45*%\nD10*\nX0Y0D02*\nG01*\nX5000000Y0D01*\n")
    side = math.sqrt(2)
    assert abs(image.area_nm2() - (side * side + 5 * side) * MM2) <= 4 * MM
    image, _ = ink(tmp_path, "%ADD10O,2X1*%\nD10*\nX0Y0D02*\nG01*\nX5000000Y0D01*\n")
    assert within_curve_bound(image.area_nm2(), (6 * 1 + math.pi * 0.25) * MM2, math.pi)


def test_round_arc_draw_is_an_annular_sector_with_round_ends(tmp_path):
    # quarter circle of radius 5 around the origin, 0.5 wide
    image, _ = ink(tmp_path, "%ADD10C,0.5*%\nD10*\nX5000000Y0D02*\nG03*\n"
                             "X0Y5000000I-5000000J0D01*\n")
    R, r = 5.0, 0.25
    exact = (math.pi / 2) * 2 * R * r + math.pi * r * r
    curves = (math.pi / 2) * (2 * R) + 2 * math.pi * r
    assert within_curve_bound(image.area_nm2(), exact * MM2, curves,
                              hole_length_mm=(math.pi / 2) * (R - r))
    xmin, ymin, xmax, ymax = image.bounds()
    assert abs(xmax - (R + r) * MM) <= TOL and abs(ymax - (R + r) * MM) <= TOL
    assert abs(xmin + r * MM) <= TOL and abs(ymin + r * MM) <= TOL


def test_full_circle_draw_is_an_annulus(tmp_path):
    # centre (5, 3), radius 2, drawn clockwise from the top
    image, _ = ink(tmp_path, "%ADD10C,0.2*%\nD10*\nX5000000Y5000000D02*\nG02*\n"
                             "X5000000Y5000000I0J-2000000D01*\n")
    exact = math.pi * (2.1 ** 2 - 1.9 ** 2)
    assert within_curve_bound(image.area_nm2(), exact * MM2, 2 * math.pi * 2.1,
                              hole_length_mm=2 * math.pi * 1.9)
    assert holes(image) == [1]
    xmin, ymin, xmax, ymax = image.bounds()
    assert abs(xmin - 2_900_000) <= TOL and abs(xmax - 7_100_000) <= TOL
    assert abs(ymin - 900_000) <= TOL and ymax == 5_100_000


def test_rectangle_stroked_arc_stays_within_tolerance_of_the_sweep(tmp_path):
    # deprecated, but real files have it: the rectangle is swept along the chords
    image, _ = ink(tmp_path, "%ADD10R,0.4X0.4*%\nD10*\nX5000000Y0D02*\nG03*\n"
                             "X-5000000Y0I-5000000J0D01*\n")
    xmin, ymin, xmax, ymax = image.bounds()
    assert (xmin, xmax) == (-5_200_000, 5_200_000)
    assert ymin == -200_000 and abs(ymax - 5_200_000) <= TOL
    # the band between radius 4.8 and 5.2 is dark at every angle (4.8 * sqrt(2) clears
    # the corners): its area is at least the half annulus
    assert image.area_nm2() >= math.pi / 2 * (5.2 ** 2 - 4.8 ** 2) * MM2


# --- regions and polarity -------------------------------------------------------------


def test_pour_with_a_clear_cut_out_has_its_hole(tmp_path):
    body = ("G36*\nX0Y0D02*\nG01*\nX10000000Y0D01*\nX10000000Y10000000D01*\n"
            "X0Y10000000D01*\nX0Y0D01*\nG37*\n"
            "%LPC*%\nG36*\nX3000000Y3000000D02*\nX7000000Y3000000D01*\nX7000000Y7000000D01*\n"
            "X3000000Y7000000D01*\nX3000000Y3000000D01*\nG37*\n")
    image, _ = ink(tmp_path, body)
    assert image.area_nm2() == (100 - 16) * MM2
    ((_shell, hs),) = image.polygons()
    assert len(hs) == 1
    assert tuple(hs[0].min(axis=0)) == (3 * MM, 3 * MM)
    assert tuple(hs[0].max(axis=0)) == (7 * MM, 7 * MM)


def test_polarity_is_applied_in_file_order(tmp_path):
    # dark square, clear middle, then a dark pad inside the cleared part again
    body = ("%ADD10R,10X10*%\n%ADD11R,4X4*%\n%ADD12R,2X2*%\n"
            "D10*\nX0Y0D03*\n%LPC*%\nD11*\nX0Y0D03*\n%LPD*%\nD12*\nX0Y0D03*\n")
    image, _ = ink(tmp_path, body)
    assert image.area_nm2() == (100 - 16 + 4) * MM2
    assert image.stats["runs"] == 3 and image.stats["clear_runs"] == 1


def test_region_with_an_arc(tmp_path):
    # a half disc of radius 5: a straight edge and a counter-clockwise arc back
    body = ("G36*\nX-5000000Y0D02*\nG01*\nX5000000Y0D01*\nG03*\n"
            "X-5000000Y0I-5000000J0D01*\nG37*\n")
    image, _ = ink(tmp_path, body)
    R = 5.0
    assert within_curve_bound(image.area_nm2(), math.pi * R * R / 2 * MM2, math.pi * R)
    xmin, ymin, xmax, ymax = image.bounds()
    assert (xmin, ymin, xmax) == (-5 * MM, 0, 5 * MM)
    assert 5 * MM - TOL <= ymax <= 5 * MM


def test_region_full_circle_and_cut_in_contour(tmp_path):
    # contour 1: a full circle (G75, start = end); contour 2: a square with a square
    # hole joined by a cut-in, the hole traced the same way round as the outside
    body = ("G36*\nX2000000Y0D02*\nG03*\nX2000000Y0I-2000000J0D01*\n"
            "X10000000Y0D02*\nG01*\nX16000000Y0D01*\nX16000000Y6000000D01*\n"
            "X10000000Y6000000D01*\nX10000000Y0D01*\n"
            "X12000000Y2000000D01*\nX14000000Y2000000D01*\nX14000000Y4000000D01*\n"
            "X12000000Y4000000D01*\nX12000000Y2000000D01*\nX10000000Y0D01*\nG37*\n")
    image, _ = ink(tmp_path, body)
    disc = math.pi * 4
    assert within_curve_bound(image.area_nm2(), (disc + 36 - 4) * MM2, 2 * math.pi * 2)
    assert sorted(holes(image)) == [0, 1]


def test_empty_and_clear_only_programs(tmp_path):
    image, _ = ink(tmp_path, "%ADD10C,1*%\n")
    assert image.is_empty and image.polygons() == [] and image.area_nm2() == 0
    image, _ = ink(tmp_path, "%LPC*%\n%ADD10C,1*%\nD10*\nX0Y0D03*\n")
    assert image.is_empty


def test_shapely_backend_agrees_on_the_constructed_cases(tmp_path):
    pytest.importorskip("shapely")
    body = ("G36*\nX0Y0D02*\nG01*\nX10000000Y0D01*\nX10000000Y10000000D01*\n"
            "X0Y10000000D01*\nX0Y0D01*\nG37*\n%LPC*%\n%ADD10C,2X1*%\nD10*\nX5000000Y5000000D03*\n"
            "%LPD*%\n%ADD11C,0.3*%\nD11*\nX0Y0D02*\nX12000000Y3000000D01*\n")
    path = tmp_path / "t.gbr"
    path.write_text(HEADER + body + "M02*\n")
    program = read_file(path)
    clipper = dark_geometry(program, backend="clipper")
    shapely_image = dark_geometry(program, backend="shapely")
    assert abs(clipper.area_nm2() - shapely_image.area_nm2()) <= 1e-9 * clipper.area_nm2()
    assert clipper.bounds() == shapely_image.bounds()
    difference = clipper.to_shapely().symmetric_difference(shapely_image.to_shapely()).area
    assert difference <= 1e-9 * clipper.area_nm2()


def test_regular_polygon_is_counter_clockwise():
    assert _signed(regular_polygon(1000, 7)) > 0


def _signed(ring):
    x, y = ring[:, 0].astype(float), ring[:, 1].astype(float)
    return float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


# --- the corpus ------------------------------------------------------------------------


def _copper_layers(max_bytes: int) -> list[str]:
    if not (CORPUS / "MANIFEST.tsv").exists():
        return []
    found = []
    for row in manifest():
        if row["kind"] in ("real", "derived") and int(row["bytes"]) <= max_bytes:
            head = (CORPUS / row["path"]).read_bytes()[:4000].decode("latin-1")
            if looks_like_copper(row["path"], head):
                found.append(row["path"])
    return found


COPPER = _copper_layers(100_000)


def test_the_corpus_has_copper_layers_to_sweep():
    if not (CORPUS / "MANIFEST.tsv").exists():
        pytest.skip("corpus not found")
    assert len(COPPER) >= 40
    assert "kicad/carte-test/carte_test-F_Cu.gbr" in COPPER
    assert "kicad/carte-test/carte_test-F_Mask.gbr" not in COPPER


def _check_layer(path: str) -> None:
    shapely = pytest.importorskip("shapely")
    program = read_gerber(CORPUS / path)  # fixtures include headless fragments
    image = dark_geometry(program)
    box = extents(program, with_apertures=True)
    if image.is_empty:
        # nothing drawn, all of it cleared, or only zero-size (RS-274-D placeholder) apertures
        assert box is None or image.stats["clear_runs"] or box == extents(program)
        return
    xmin, ymin, xmax, ymax = image.bounds()
    bx0, by0, bx1, by1 = box
    assert bx0 <= xmin and by0 <= ymin and xmax <= bx1 and ymax <= by1, (image.bounds(), box)
    assert is_integer_geometry(image)
    assert shapely.is_valid(image.to_shapely()), shapely.is_valid_reason(image.to_shapely())


@pytest.mark.parametrize("path", COPPER)
def test_corpus_copper_layer_is_valid_and_inside_the_reader_extents(path):
    _check_layer(path)


@pytest.mark.parametrize("path", [p for p in corpus_paths("synthetic")
                                  if (CORPUS / p).stat().st_size <= 20_000])
def test_corpus_feature_fixture_inks(path):
    _check_layer(path)
