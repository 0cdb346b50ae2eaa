"""Drill marks: the ink leaves each hole's centre bare (plan/drill_marks.py).

Measured from the steps of the reference machine (the firmware's twin): the pen-down
steps near the marks swept by the pen (tests/drilled.py) and the marks rasterised at
10 um: not one pixel of ink inside a mark. A real board of the curated corpus
(KiCad's flashpads, its bottom copper: pads of every shape, some with off-centre
holes; the holes from its own drill files by a test-only reader) and a
small hand-made board with thick and thin pads, a trace to a pad's centre and a slot.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from corpus import CORPUS
from drilled import ink_near, kicad_holes, pixels_inside
from inked import ink_of_trace, joined_islands

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine.planner import simulate
from galileo_cnc.plan import sides
from galileo_cnc.plan.drill_marks import (MARK_CLEARANCE_NM, clear_strokes, marks_for,
                                          warnings_to_show)
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.islands import CLEARANCE_NM
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.plan.planner import PlanError
from galileo_cnc.program.drills import Hole, Slot
from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind

MM = 1_000_000
CONFIG = MachineConfig()
STEP = CONFIG.nm_per_step
PEN = CONFIG.pen_widths_nm[0]
FLASHPADS = CORPUS / "kicad" / "flashpads-x2ap" / "Flashpads-B_Cu.gbr"
FLASHPADS_DRILL = CORPUS / "drill" / "kicad" / "flashpads-x2ap"

HEADER = "%FSLAX46Y46*%\n%MOMM*%\nG75*\n"
#: two 2 mm pads joined by a 0.2 mm trace (centre line to their centres), a 1.0 mm
#: pad (a mark shrunk), a 0.9 mm pad (no room for a mark), an oval pad with a slot
BOARD = HEADER + """%ADD10C,2.0*%
%ADD11C,0.2*%
%ADD12C,1.0*%
%ADD13C,0.9*%
%ADD14O,3.0X1.8*%
D10*
X5000000Y5000000D03*
X9000000Y5000000D03*
D11*
X5000000Y5000000D02*
X9000000Y5000000D01*
D12*
X5000000Y9000000D03*
D13*
X9000000Y9000000D03*
D14*
X13000000Y9000000D03*
M02*
"""
HOLES = (Hole(5 * MM, 5 * MM, 1_000_000), Hole(9 * MM, 5 * MM, 800_000),
         Hole(5 * MM, 9 * MM, 800_000), Hole(9 * MM, 9 * MM, 700_000),
         Slot(12_600_000, 9 * MM, 13_400_000, 9 * MM, 800_000))


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    path = tmp_path_factory.mktemp("board") / "board.gbr"
    path.write_text(BOARD)
    return path


def inside(polygons, x, y) -> bool:
    return sum(1 if clip.pc.Area(ring) > 0 else -1 for ring in polygons
               if clip.pc.PointInPolygon((x, y), ring) == 1) > 0


def test_a_real_board_leaves_every_drill_mark_bare_and_inks_the_rest():
    holes = kicad_holes(FLASHPADS_DRILL / "Flashpads-PTH.drl") + \
        kicad_holes(FLASHPADS_DRILL / "Flashpads-NPTH.drl")
    before = plan_file(FLASHPADS, CONFIG, options=PlanOptions(mode="ink"))
    planned = plan_file(FLASHPADS, CONFIG, options=PlanOptions(mode="ink", holes=holes))
    marks = clip.components(planned.marks)
    assert len(marks) >= 50                       # every plated hole on a pad
    trace = simulate(planned.job.commands, CONFIG)
    ink = ink_near(trace, CONFIG, planned.offset_nm, PEN, planned.marks)
    assert pixels_inside(clip.intersection(ink, planned.marks)) == 0
    # round each mark (0.8 mm: its pad) the copper outside the marks and their clearance
    # is inked as before, 99 % of it, from the steps; the pads with off-centre holes are
    # the test (a fill of the copper less the marks leaves crescents in them: 94 %)
    window = clip.offset(planned.marks, 800_000, 1000)
    ink = ink_near(trace, CONFIG, planned.offset_nm, PEN, window)
    ink_before = ink_near(simulate(before.job.commands, CONFIG), CONFIG, before.offset_nm,
                          PEN, window)
    copper = clip.difference(clip.intersection(planned.ink.copper.native, window),
                             planned.ink.bare)
    for outer, _holes in marks:
        pad = clip.intersection(copper, clip.offset([outer], 800_000, 1000))
        inked = clip.area_nm2(clip.intersection(ink, pad))
        assert inked >= 0.99 * clip.area_nm2(clip.intersection(ink_before, pad)), \
            outer.mean(axis=0) / MM
    # a mark shrunk for its pad's ring says where, in mm
    assert planned.drill_mark_warnings
    assert all(" mm hole at X " in w and " mm made " in w for w in planned.drill_mark_warnings)
    shown = warnings_to_show(planned.drill_mark_warnings, 2)
    assert shown[:2] == list(planned.drill_mark_warnings[:2]) and len(shown) == 3
    assert shown[2] == f"... and {len(planned.drill_mark_warnings) - 2} more drill marks " \
        "shrunk or left out (galileo-cnc info lists every one)"


@pytest.mark.parametrize("mode", ["actual", "small"])
def test_marks_stay_bare_the_copper_round_them_inked_and_thin_rings_kept(board, mode):
    planned = plan_file(board, CONFIG, options=PlanOptions(mode="ink", holes=HOLES,
                                                           drill_marks=mode))
    trace = simulate(planned.job.commands, CONFIG)
    ink = ink_of_trace(trace, CONFIG, planned.offset_nm, [PEN])
    assert pixels_inside(clip.intersection(ink, planned.marks)) == 0
    copper = planned.ink.copper.native
    assert joined_islands(ink, copper, 30_000) == []
    marks = planned.marks
    for x, y in ((5 * MM, 5 * MM), (9 * MM, 5 * MM), (12_600_000, 9 * MM), (13_400_000, 9 * MM)):
        assert inside(marks, x, y)
    # actual: the whole hole (and the slot's stadium); small: 0.3 mm dots, at a slot's ends
    assert inside(marks, 5 * MM + 450_000, 5 * MM) == (mode == "actual")
    assert inside(marks, 13 * MM, 9 * MM) == (mode == "actual")
    assert not inside(marks, 5 * MM + 520_000, 5 * MM)
    # the 0.9 mm pad has no room for a mark: inked solid, and said
    assert not inside(marks, 9 * MM, 9 * MM)
    warnings = "\n".join(planned.drill_mark_warnings)
    assert "hole at X 9.000, Y 9.000 mm left out" in warnings
    if mode == "actual":                          # the 1.0 mm pad's mark is shrunk
        assert "hole at X 5.000, Y 9.000 mm made 0.1" in warnings
    # the copper of each pad outside its mark (and the clearance) is inked: rings kept
    grown = clip.offset(marks, MARK_CLEARANCE_NM + 2 * STEP, 1000)
    for x, y, d in ((5, 5, 2.0), (5, 9, 1.0), (9, 9, 0.9)):
        pad = clip.stroke([[[x * MM, y * MM]]], round(d * MM) // 2, 1000)
        ring = clip.difference(pad, grown)
        covered = clip.area_nm2(clip.intersection(ring, ink)) / clip.area_nm2(ring)
        assert covered >= 0.95, (x, y, covered)
    # the trace's centre line stops short of both marks: no step of it inside
    assert pixels_inside(clip.intersection(ink, marks)) == 0


def test_no_drill_marks_ink_the_pads_as_without_holes(board):
    alone = plan_file(board, CONFIG, options=PlanOptions(mode="ink"))
    none = plan_file(board, CONFIG, options=PlanOptions(mode="ink", holes=HOLES,
                                                        drill_marks="none"))
    assert np.array_equal(alone.plotted.table, none.plotted.table)
    assert none.marks == [] and none.drill_mark_warnings == ()
    # holes without a side: a layer of one side, its own offset, no turn-over line
    small = plan_file(board, CONFIG, options=PlanOptions(mode="ink", holes=HOLES))
    assert none.offset_nm == small.offset_nm == alone.offset_nm
    assert none.side_line == small.side_line == ""


def test_centre_mode_draws_a_pad_with_a_hole_as_a_ring_round_its_mark(board):
    """...and its trace to the pad's centre stops short of the mark."""
    planned = plan_file(board, CONFIG, options=PlanOptions(mode="centre", holes=HOLES))
    rows = planned.plotted.table
    flashes = {(x, y) for x, y in rows[rows[:, KIND] == int(OpKind.FLASH)][:, [X, Y]].tolist()}
    circles = rows[(rows[:, KIND] == int(OpKind.ARC_CCW)) & (rows[:, J] == 0)]
    centres = {(x + i, y) for x, y, i in circles[:, [X, Y, I]].tolist()}
    # the 2 mm pads: rings a pen radius and the clearance round the 0.3 mm marks
    assert {(5 * MM, 5 * MM), (9 * MM, 5 * MM)} <= centres
    assert (5 * MM, 5 * MM) not in flashes and (9 * MM, 5 * MM) not in flashes
    radius = 150_000 + MARK_CLEARANCE_NM + PEN // 2
    assert set((-circles[:, I]).tolist()) == {radius}
    # the 1.0 and 0.9 mm pads hold no ring: their dots stay, said; the slot's pad too
    assert {(5 * MM, 9 * MM), (9 * MM, 9 * MM), (13 * MM, 9 * MM)} <= flashes
    assert sum("too small for a ring" in w for w in planned.drill_mark_warnings) == 2
    # stepped: the pen-down steps round (5, 5) keep out of the mark, the 0.2 mm trace's
    # centre line (to the pad's centre) by its own half width, the ring by the pen's
    trace = simulate(planned.job.commands, CONFIG)
    where = trace.positions()
    down = where[where[:, 2] == CONFIG.pen_down_z_steps][:, :2] * STEP + planned.offset_nm
    distance = np.hypot(*(down - (5 * MM, 5 * MM)).T)
    assert distance.min() >= 150_000 + MARK_CLEARANCE_NM + 100_000 - STEP
    off_trace = np.abs(down[:, 1] - 5 * MM) > PEN
    assert distance[off_trace].min() >= radius - 2 * STEP


def test_marks_for_sizes_and_options():
    hole, slot = Hole(0, 0, 200_000), Slot(0, 0, 1_000_000, 0, 600_000)
    small = marks_for([hole, slot], "small", 300_000)
    assert [m.radius_nm for m in small] == [100_000, 150_000, 150_000]   # never wider
    assert [m.path for m in small[1:]] == [((0, 0),), ((1_000_000, 0),)]
    actual = marks_for([hole, slot], "actual")
    assert [m.radius_nm for m in actual] == [100_000, 300_000]
    assert actual[1].path == ((0, 0), (1_000_000, 0))
    assert marks_for([hole, slot], "none") == []
    with pytest.raises(PlanError, match="--drill-marks: expected none, small or actual"):
        PlanOptions(drill_marks="big")


def test_with_two_pens_each_pen_keeps_out_of_the_marks(board):
    """Several pens fill the copper less the marks (ink_paths): each pen's paths,
    swept by its own width, stay out of them."""
    pens = (600_000, 300_000)
    planned = plan_file(board, CONFIG, options=PlanOptions(mode="ink", pens_nm=pens,
                                                           holes=HOLES))
    assert planned.marks
    for fill in planned.ink.fills:
        swept = clip.stroke([path.tolist() for path in fill.paths], fill.width_nm // 2, 1000)
        assert pixels_inside(clip.intersection(swept, planned.marks)) == 0
    lines = [piece.tolist() for feature in planned.ink.narrow for piece in feature.pieces]
    swept = clip.stroke(lines, pens[-1] // 2, 1000)
    assert pixels_inside(clip.intersection(swept, planned.marks)) == 0


def test_a_centre_line_of_zero_length_near_a_mark_is_a_dot_not_a_clipper_error():
    # Altium's usbvil bottom copper as a board side: a trace piece whose points all
    # coincide met the marks' clearance, and Clipper refused the whole cut ("All paths
    # are invalid for clipping"); it is a dot now, kept or cut as dots are.
    square = [[0, 0], [1000, 0], [1000, 1000], [0, 1000]]
    outside, inside = [[5000, 5000], [5000, 5000]], [[500, 500], [500, 500], [500, 500]]
    kept = clip.open_difference([outside, inside, [[2000, 0], [3000, 0]]], [square])
    assert sorted(sorted(p.tolist()) for p in kept) == [[[2000, 0], [3000, 0]], [[5000, 5000]]]


def test_a_cross_keeps_off_a_long_centre_line_whose_ends_are_far_away():
    """8bit-mixtape's bottom: a 0.2 mm trace of another net passes 0.15 mm from a pad
    and runs on for centimetres. Its centre line, drawn with the 0.4 mm pen, inks
    0.1 mm past its copper; a cross on the pad must stop short of that ink by the
    islands' clearance, though both ends of the line lie far from the cross."""
    pad = [[-1_125_000, -1_125_000], [1_125_000, -1_125_000], [1_125_000, 1_125_000],
           [-1_125_000, 1_125_000]]
    trace_y = -1_375_000                     # its copper -1.475 .. -1.275 mm
    trace = [[-40 * MM, trace_y - 100_000], [40 * MM, trace_y - 100_000],
             [40 * MM, trace_y + 100_000], [-40 * MM, trace_y + 100_000]]
    copper = clip.union([pad], [trace])
    line = np.array([[-40 * MM, trace_y], [40 * MM, trace_y]], dtype=np.int64)
    mark = clip.stroke([[[0, 0]]], 170_000, 2_000)
    strokes = sides.cross_strokes([(0, 0)])
    kept = clear_strokes(strokes, copper, mark, PEN, CLEARANCE_NM, 2_000, [line])
    assert any(k[:, 0].max() > 1_000_000 for k in kept)     # the horizontal arm is drawn
    ink = clip.stroke([k.tolist() for k in kept], PEN // 2, 1_000)
    line_ink = clip.stroke([line.tolist()], PEN // 2, 1_000)
    # the cross's ink keeps the clearance from the line's ink (less the tolerances)
    assert not clip.intersection(ink, clip.offset(line_ink, CLEARANCE_NM - 5_000, 1_000))
    assert joined_islands(clip.union(ink, line_ink), copper, 30_000) == []


def test_a_short_slots_two_dots_become_one_mark_along_it(tmp_path):
    """flashpads' bottom: a 0.65 mm slot 0.4 mm long in an oval pad. Its two 0.3 mm end
    dots would leave 0.06 mm of copper between them, which no 0.4 mm pen inks: bare
    beside inked copper. That copper is inside the slot: one mark along it instead, and
    the pad round it is inked as without marks."""
    path = tmp_path / "oval.gbr"
    path.write_text(HEADER + "%ADD10O,1.4X1.8*%\nD10*\nX5000000Y5000000D03*\nM02*\n")
    slot = Slot(5 * MM, 4_800_000, 5 * MM, 5_200_000, 650_000)
    plans = {marks: plan_file(path, CONFIG, options=PlanOptions(
        mode="ink", holes=[slot], drill_marks=marks)) for marks in ("small", "none")}
    planned = plans["small"]
    assert len(clip.components(planned.marks)) == 1
    assert inside(planned.marks, 5 * MM, 5 * MM)             # between the slot's ends
    assert not inside(planned.marks, 5 * MM + 200_000, 5 * MM)
    copper = clip.difference(planned.ink.copper.native, planned.ink.bare)
    inked = {marks: clip.area_nm2(clip.intersection(copper, ink_of_trace(
        simulate(plan.job.commands, CONFIG), CONFIG, plan.offset_nm, [PEN])))
        for marks, plan in plans.items()}
    assert inked["small"] >= 0.99 * inked["none"]
    assert inked["small"] >= 0.99 * clip.area_nm2(copper)


@pytest.fixture
def pad_trace(tmp_path):
    """A 1.1 mm pad at (5, 5) mm and a 0.3 mm trace from its centre down to (4.6, 4.6)
    and on to (2, 4.6) mm: its last stretch horizontal, under the pad's drill mark."""
    path = tmp_path / "pad-trace.gbr"
    path.write_text(HEADER + "%ADD10C,1.1*%\n%ADD11C,0.3*%\nD10*\nX5000000Y5000000D03*\n"
                    "D11*\nX5000000Y5000000D02*\nX4600000Y4600000D01*\n"
                    "X2000000Y4600000D01*\nM02*\n")
    return path


def test_a_horizontal_line_below_every_polygon_survives_the_cut(pad_trace):
    """Clipper 6 drops an open path whose points share one y when it lies below every
    clip polygon. arduino-uno's top: a trace leaves a pad diagonally and runs on
    horizontally just under it; cut a pen radius short of the pad's drill mark
    (inking._clear_of), its horizontal stretch vanished and the trace went unetched."""
    disc = clip.stroke([[[0, 0]]], 342_000, 2_000)
    below = np.array([[-437_000, -437_000], [-2 * MM, -437_000]], dtype=np.int64)
    assert [p.tolist() for p in clip.open_difference([below], disc)] == [below.tolist()]
    through = np.array([[-2 * MM, 0], [2 * MM, 0]], dtype=np.int64)
    pieces = clip.open_difference([through], disc)
    assert len(pieces) == 2 and all(abs(p[:, 0]).min() >= 340_000 for p in pieces)
    planned = plan_file(pad_trace, CONFIG, options=PlanOptions(
        mode="ink", holes=[Hole(5 * MM, 5 * MM, 600_000)], side="top",
        board_box_nm=(0, 0, 10 * MM, 10 * MM)))
    # drawn along y 4.6 to x 2 (as a line, or as a spur of the pad's walk)
    segments = [np.array(pair) for f in planned.ink.narrow for piece in f.pieces
                for pair in zip(piece, piece[1:])]
    assert any((segment[:, 1] == 4_600_000).all() and segment[:, 0].min() <= 2_000_000
               for segment in segments)


def test_a_walk_back_through_its_start_is_cut_along_itself():
    """Clipper 6 joins the pieces of an open path that passes its own start again out
    of order: minnowmax-80101's bottom, a fill's walk round a via's pad (a loop, a spur
    to the pad's centre, back and on) came back with a corner cut straight across the
    via's drill mark, 315 pixels of ink in it. Every piece runs along the walk, and
    none comes into the mark."""
    disc = clip.stroke([[[0, 0]]], 300_000, 2_000)
    loop = np.array([[5, 5], [-5, 5], [-5, -5], [5, -5], [5, 5], [8, 5]]) * 100_000
    assert [p.tolist() for p in clip.open_difference([loop], disc)] == [loop.tolist()]
    flat = np.array([[5, -4], [-5, -4], [5, -4], [8, -4]]) * 100_000   # clipped swapped
    assert [p.tolist() for p in clip.open_difference([flat], disc)] == [flat.tolist()]
    walk = np.array([[5, 5], [-5, 5], [-5, -5], [5, -5], [5, -2], [2, -2], [2, 2], [-2, 2],
                     [-2, -2], [0, -2], [0, 0], [0, -2], [2, -2], [5, -2], [5, 5], [8, 5]]
                    ) * 100_000
    pieces = clip.open_difference([walk], disc)
    assert clip._on_paths(pieces, [walk])
    for piece in pieces:
        a, b = piece[:-1].astype(float), piece[1:].astype(float)
        t = np.clip((-a * (b - a)).sum(axis=1) / ((b - a) ** 2).sum(axis=1), 0, 1)
        assert np.hypot(*(a + t[:, None] * (b - a)).T).min() >= 298_000
    # what is outside the disc is all kept: the walk's length less its stretches inside
    length = sum(np.hypot(*np.diff(p.astype(float), axis=0).T).sum() for p in pieces)
    # inside: the inner square's three sides and the spur (0.4 mm each way), the inner
    # square's bottom side to its corners, and 0.024 mm twice to the corner at (2, -2)
    inside = 3 * 400_000 + 4 * 200_000 + 2 * (math.sqrt(0.05) - 0.2) * MM
    assert length == pytest.approx(np.hypot(*np.diff(walk.astype(float), axis=0).T).sum()
                                   - inside, abs=10_000)


def test_a_pour_stitched_with_close_vias_is_inked_between_the_marks(tmp_path):
    """orcad/led-display-g4-arena's top: a pour with vias on a 0.635 mm grid. With
    0.3 mm marks the copper between two of them (a lens) is out of a 0.4 mm pen's
    reach: 95.4 % of a via's copper was inked against 100 % without marks. The
    crowded marks now shrink until the pen passes between them (a warning names each),
    and the copper outside the marks is inked as without them; nothing inside a mark.
    Vias closer still lose their marks: the pads are inked solid."""
    pitch, n = 635_000, 4
    side = (n + 1) * pitch
    text = HEADER + "%ADD10C,0.6*%\nG36*\n" + "".join(
        f"X{x}Y{y}D0{1 + (k == 0)}*\n"
        for k, (x, y) in enumerate([(0, 0), (side, 0), (side, side), (0, side), (0, 0)]))
    holes = [Hole(i * pitch, j * pitch, 300_000) for i in range(1, n + 1)
             for j in range(1, n + 1)]
    text += "G37*\nD10*\n" + "".join(f"X{h.x_nm}Y{h.y_nm}D03*\n" for h in holes) + "M02*\n"
    path = tmp_path / "stitched.gbr"
    path.write_text(text)
    planned = plan_file(path, CONFIG, options=PlanOptions(
        mode="ink", holes=holes, side="top", board_box_nm=(0, 0, side, side)))
    copper = planned.ink.copper.native
    ink = ink_near(simulate(planned.job.commands, CONFIG), CONFIG, planned.offset_nm, PEN,
                   copper)
    assert len(clip.components(planned.marks)) == n * n
    assert pixels_inside(clip.intersection(ink, planned.marks)) == 0
    shrunk = [w for w in planned.drill_mark_warnings if "mm between the marks" in w]
    assert len(shrunk) == n * n and "made 0.18 mm wide, not 0.3 mm" in shrunk[0], shrunk[:1]
    outside = clip.difference(copper, planned.ink.bare)
    assert clip.area_nm2(clip.intersection(ink, outside)) / clip.area_nm2(outside) >= 0.99
    no_marks = plan_file(path, CONFIG, options=PlanOptions(
        mode="ink", holes=holes, side="top", board_box_nm=(0, 0, side, side),
        drill_marks="none"))
    before = ink_near(simulate(no_marks.job.commands, CONFIG), CONFIG, no_marks.offset_nm,
                      PEN, copper)
    assert clip.area_nm2(clip.intersection(ink, outside)) >= \
        0.99 * clip.area_nm2(clip.intersection(before, outside))
    dense = [Hole(1_000_000 + i * 450_000, 1_000_000 + j * 450_000, 300_000) for i in range(2)
             for j in range(2)]
    planned = plan_file(path, CONFIG, options=PlanOptions(
        mode="ink", holes=dense, side="top", board_box_nm=(0, 0, side, side)))
    assert planned.marks == [] and len(planned.drill_mark_warnings) == 4
    assert "left out" in planned.drill_mark_warnings[0]
