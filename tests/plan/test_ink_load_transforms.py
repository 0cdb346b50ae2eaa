"""%LM/%LR/%LS reach the ink: a transformed aperture is inked as its transformed shape
(the reader hands the ink geometry a derived aperture, readers/gerber/transformed.py)."""

from __future__ import annotations

import math

import pytest
from shapely import LineString, Point, Polygon, unary_union

from galileo_cnc.plan.ink import dark_geometry
from galileo_cnc.plan.ink.inking import ink_program
from galileo_cnc.readers.gerber import read_gerber

MM = 1_000_000
PEN_NM = 300_000
# A 4 x 1 mm bar along X with its left end at the origin: turning it about the origin
# moves its far end, so a wrong turn cannot hide inside the symmetric outline.
BAR = "%FSLAX46Y46*%%MOMM*%%AMBAR*21,1,4,1,2,0,0*%%ADD10BAR*%"


def bar_program(transform: str):
    return read_gerber("bar.gbr", BAR + transform + "D10*X0Y0D03*M02*")


def turned_bar(degrees: float) -> Polygon:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    corners = [(0, -0.5 * MM), (4 * MM, -0.5 * MM), (4 * MM, 0.5 * MM), (0, 0.5 * MM)]
    return Polygon([(x * c - y * s, x * s + y * c) for x, y in corners])


def inked_area(plan) -> object:
    """What the pens cover: every planned path stroked at its pen's width."""
    strokes = [LineString(path.tolist()).buffer(fill.width_nm / 2) if len(path) > 1
               else Point(path[0].tolist()).buffer(fill.width_nm / 2)
               for fill in plan.fills for path in fill.paths]
    return unary_union(strokes)


def test_a_macro_aperture_turned_by_lr30_is_inked_turned():
    plan = ink_program(bar_program("%LR30*%"), (PEN_NM,))
    expected = turned_bar(30)
    copper = plan.copper.to_shapely()
    assert copper.symmetric_difference(expected).area < 1e-6 * expected.area
    ink = inked_area(plan)
    assert ink.intersection(expected).area >= 0.97 * expected.area
    assert ink.difference(expected).area <= 0.005 * expected.area
    # Near the far corner of the turned bar, where the unturned bar never reaches...
    corner = (3.8 * MM * math.cos(math.radians(30)) - 0.3 * MM * math.sin(math.radians(30)),
              3.8 * MM * math.sin(math.radians(30)) + 0.3 * MM * math.cos(math.radians(30)))
    assert not turned_bar(0).contains(Point(corner))
    assert ink.contains(Point(corner))
    # ... and where the unturned bar's far end is, nothing is inked.
    assert not ink.intersects(Point(3.8 * MM, 0).buffer(0.1 * MM))


@pytest.mark.parametrize("transform, degrees", [("", 0), ("%LR90*%", 90), ("%LR30*%", 30),
                                                ("%LMY*%%LR30*%", 30), ("%LMX*%%LR30*%", 210)])
def test_the_copper_of_a_transformed_macro_is_the_transformed_shape(transform, degrees):
    # Mirror first, then turn: mirrored in X the bar points along -X (180 degrees) and
    # turns on to 210 (turned first and then mirrored it would point to 150).
    copper = dark_geometry(bar_program(transform)).to_shapely()
    expected = turned_bar(degrees)
    assert copper.symmetric_difference(expected).area < 1e-6 * expected.area


def test_lmx_inks_the_mirror_image_and_ls_the_smaller_one():
    mirrored = dark_geometry(bar_program("%LMX*%")).to_shapely()
    assert mirrored.symmetric_difference(turned_bar(180)).area < 1e-6 * mirrored.area
    halved = dark_geometry(bar_program("%LS0.5*%")).bounds()
    assert halved == (0, -MM // 4, 2 * MM, MM // 4)


def test_a_circle_drawn_under_ls_makes_a_trace_of_the_scaled_width():
    text = ("%FSLAX46Y46*%%MOMM*%%ADD10C,1*%%LS0.5*%D10*X0Y0D02*X10000000Y0D01*M02*")
    image = dark_geometry(read_gerber("trace.gbr", text))
    x0, y0, x1, y1 = image.bounds()
    assert (y0, y1) == (-MM // 4, MM // 4) and (x0, x1) == (-MM // 4, 10 * MM + MM // 4)


@pytest.mark.parametrize("degrees", [0, 30, 45, 90])
def test_a_thin_bar_macro_turned_any_angle_is_narrow_and_drawn_along_its_axis(degrees):
    # 4 x 0.2 mm: thinner than the 0.3 mm pen whatever the turn, so it is one centre
    # line along the bar (its bounding box at 30 degrees is 3.6 x 2.2 mm: not narrow
    # by the box, so this fails if the width is taken from the box).
    text = ("%FSLAX46Y46*%%MOMM*%%AMTHIN*21,1,4,0.2,2,0,0*%%ADD10THIN*%"
            f"%LR{degrees}*%D10*X0Y0D03*M02*")
    plan = ink_program(read_gerber("thin.gbr", text), (PEN_NM,))
    (feature,) = plan.narrow
    assert abs(feature.width_nm - 200_000) <= 2       # corners rounded to the nm once
    (piece,) = plan.narrow[0].pieces
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    # from 0.15 mm to 3.85 mm along the turned bar: its ends a pen radius inside
    expected = [(round(0.15 * MM * c), round(0.15 * MM * s)),
                (round(3.85 * MM * c), round(3.85 * MM * s))]
    ends = sorted(map(tuple, piece.tolist()))
    assert all(abs(a - b) <= 2 for got, want in zip(ends, sorted(expected))
               for a, b in zip(got, want))
    bar = Polygon([(x * c - y * s, x * s + y * c) for x, y in
                   [(0, -0.1 * MM), (4 * MM, -0.1 * MM), (4 * MM, 0.1 * MM), (0, 0.1 * MM)]])
    ink = LineString(piece.tolist()).buffer(PEN_NM / 2)
    assert ink.intersection(bar).area >= 0.99 * bar.area
