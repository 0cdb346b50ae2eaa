"""The cut-out: the tool runs the outline's strokes chained into contours, its radius
off the board (checked by shapely, which the planning never used), in equal depth
passes down to the board's thickness, rising over tabs of the width asked on the
passes below the tab's top; a hole in the board is cut from inside, before the edge."""

import math
import re

import numpy as np
import pytest
import shapely

from corpus import corpus_file
from galileo_cnc.config.mill import MillConfig
from galileo_cnc.plan.mill.cutout import CutoutError, chain_outline, cutout_gcode, plan_cutout
from galileo_cnc.readers import read_file

# a 30 x 20 mm board drawn a stroke at a time, two of them backwards (as KiCad does),
# a 6 mm round hole in it, and a dimension line beside it that closes nothing
OUTLINE = """%FSLAX46Y46*%
%MOMM*%
%ADD10C,0.1*%
D10*
G75*
X0Y0D02*
X30000000Y0D01*
X30000000Y20000000D02*
X30000000Y0D01*
X30000000Y20000000D02*
X0Y20000000D01*
X0Y0D02*
X0Y20000000D01*
X13000000Y10000000D02*
G03X13000000Y10000000I-3000000J0D01*
G01*
X40000000Y0D02*
X40000000Y20000000D01*
M02*
"""
# 1.0 mm end mill; 1.6 mm board in passes of at most 0.5 mm: four of 0.4 mm;
# tabs 2 mm wide, 0.5 mm high: their top 1.1 mm deep, the last two passes rise to it
MILL = MillConfig(tool="endmill", diameter_nm=1_000_000, tabs=4, tab_width_nm=2_000_000,
                  tab_height_nm=500_000, cutout_step_down_nm=500_000)
BOARD = shapely.Polygon([(0, 0), (30e6, 0), (30e6, 20e6), (0, 20e6)],
                        [shapely.Point(10e6, 10e6).buffer(3e6, quad_segs=256).exterior.coords])


@pytest.fixture(scope="module")
def outline(tmp_path_factory):
    path = tmp_path_factory.mktemp("cutout") / "board-Edge_Cuts.gbr"
    path.write_text(OUTLINE)
    return read_file(str(path))


def _cuts(text: str):
    """Each cut (from a rapid to the next rapid up) as its G1 points (x, y, z) in nm."""
    x = y = z = 0.0
    cuts = []
    for line in text.splitlines():
        words = dict(re.findall(r"([XYZ])(-?[\d.]+)", line))
        x = float(words.get("X", x / 1e6)) * 1e6
        y = float(words.get("Y", y / 1e6)) * 1e6
        z = float(words.get("Z", z / 1e6)) * 1e6
        if line.startswith("G0 X"):
            cuts.append([])
        elif line.startswith("G1") and cuts:
            cuts[-1].append((round(x), round(y), round(z)))
    return cuts


def test_the_tool_keeps_its_radius_off_the_board_the_hole_cut_first(outline):
    text = cutout_gcode(outline, MILL)
    hole, edge = _cuts(text)
    for cut in (hole, edge):
        path = shapely.LineString([(x, y) for x, y, _ in cut])
        # the tool's centre never nearer the board than its radius, nor far from it
        assert path.distance(BOARD) >= 500_000 - 1
        assert path.hausdorff_distance(BOARD.exterior if cut is edge else
                                       BOARD.interiors[0]) <= 500_000 + 5_000
    assert all(math.dist((x, y), (10e6, 10e6)) < 3e6 for x, y, _ in hole)
    # the dimension line closes nothing: left out, and said so
    assert "X 40.000 Y 0.000 to X 40.000 Y 20.000 mm close nothing: left out" in text


def test_equal_depth_passes_down_to_the_board_thickness(outline):
    hole, edge = _cuts(cutout_gcode(outline, MILL))
    assert sorted({z for _, _, z in hole}) == [-1_600_000, -1_200_000, -800_000, -400_000]
    assert sorted({z for _, _, z in edge}) == [-1_600_000, -1_200_000, -1_100_000,
                                               -800_000, -400_000]
    # each pass round the whole edge: its plunges are the passes and the tab rises
    assert len([1 for a, b in zip(edge, edge[1:]) if a[:2] == b[:2]]) == 3 + 2 * 4 * 2


def _tab_runs(cut, tab_z):
    """The lengths of the stretches the tool runs at the tabs' top, per pass."""
    runs, length, previous = [], None, cut[0]
    for point in cut[1:]:
        level = point[2] == tab_z and previous[2] == tab_z
        if level and point[:2] != previous[:2]:
            length = (length or 0.0) + math.dist(point[:2], previous[:2])
        elif length is not None and point[2] != tab_z:
            runs.append(length)
            length = None
        previous = point
    return runs


def test_tabs_where_asked_with_their_width_on_the_last_passes_only(outline):
    hole, edge = _cuts(cutout_gcode(outline, MILL))
    runs = _tab_runs(edge, -1_100_000)
    # four tabs on each of the two passes below their top; the tool's centre rises over
    # the tab's width plus its own diameter
    assert runs == pytest.approx([3_000_000] * 8, abs=2)
    assert _tab_runs(hole, -1_100_000) == []
    plan = plan_cutout(outline, MILL)
    (board_edge,) = [cut for cut in plan.cuts if cut.edge]
    length = shapely.LinearRing(board_edge.ring).length
    centres = [(a + b) / 2 for a, b in board_edge.tabs]
    assert centres == pytest.approx([(k + 0.5) * length / 4 for k in range(4)])


def test_tabs_by_spacing_none_when_zero_and_refused_when_they_hold_the_whole_board(outline):
    every_10mm = MillConfig(tool="endmill", diameter_nm=1_000_000, tab_spacing_nm=10_000_000)
    (edge,) = [cut for cut in plan_cutout(outline, every_10mm).cuts if cut.edge]
    assert len(edge.tabs) == round(shapely.LinearRing(edge.ring).length / 10_000_000) == 10
    none = MillConfig(tool="endmill", diameter_nm=1_000_000, tabs=0)
    assert "Z-1.1" not in cutout_gcode(outline, none)
    with pytest.raises(CutoutError, match="tabs 1.600 mm high on a board 1.600 mm thick"):
        plan_cutout(outline, MillConfig(tab_height_nm=1_600_000))


def test_real_outlines_chain_and_the_tool_keeps_off_their_centre_lines():
    # KiCad's lone strokes, a round board with a round hole (arcs), P-CAD's 58 um gaps
    mill = MillConfig(tool="endmill", diameter_nm=2_000_000)
    for name, edges, holes in (("kicad/simple-2layer/simple_2layer-Edge_Cuts.gbr", 1, 0),
                               ("kicad/world-clock-2/wc2-Edge_Cuts.gbr", 1, 1),
                               ("p-cad/zxinet/ZXINET.GKO", 1, 0)):
        outline = read_file(str(corpus_file(name)))
        plan = plan_cutout(outline, mill)
        assert [cut.edge for cut in plan.cuts] == [False] * holes + [True] * edges, name
        strokes = shapely.MultiLineString([np.vstack([c, c[:1]]) for c in
                                           chain_outline(outline, [])])
        for cut in plan.cuts:
            assert shapely.LinearRing(cut.ring).distance(strokes) >= 1_000_000, name
            assert len(cut.tabs) == (4 if cut.edge else 0)


def test_a_hole_in_the_outline_narrower_than_the_tool_is_refused_naming_its_place(outline):
    wide = MillConfig(tool="endmill", diameter_nm=7_000_000, tabs=0)
    with pytest.raises(CutoutError, match=r"the hole in the outline at X 13\.000 Y 10\.000 mm "
                                          r"is narrower than the 7\.000 mm end mill"):
        plan_cutout(outline, wide)
