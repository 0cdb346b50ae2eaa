"""A board's two sides in register (plan/sides.py): the bottom mirrored exactly about
the axis, one offset for both, registration crosses on holes far apart.

The real board is KiCad's flashpads of the curated corpus (both copper layers, the
outline, the holes from its drill files by a test-only reader), planned in ink mode
for each side and stepped by the reference machine (the firmware's twin): the crosses
are found in the steps, and every bottom cross, turned over about the axis where the
side's first line says it lies on the machine, lands on its top cross to the step.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from corpus import CORPUS
from drilled import ink_near, kicad_holes, pen_down_runs, pixels_inside
from inked import ink_of_trace, joined_islands

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine.planner import simulate
from galileo_cnc.plan import sides
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.plan.planner import PlanError
from galileo_cnc.plan.transform import Transform, mirrored
from galileo_cnc.program.drills import Hole, Slot
from galileo_cnc.program.extents import extents
from galileo_cnc.program.ops import I, KIND, X, Y, OpKind
from galileo_cnc.readers import read_file

MM = 1_000_000
CONFIG = MachineConfig()
STEP = CONFIG.nm_per_step
PEN = CONFIG.pen_widths_nm[0]
ARM_STEPS = sides.CROSS_ARM_NM // STEP
BOARD = CORPUS / "kicad" / "flashpads-x2ap"
DRILLS = CORPUS / "drill" / "kicad" / "flashpads-x2ap"
HEADER = "%FSLAX46Y46*%\n%MOMM*%\nG75*\n"


def crosses_in_steps(trace, near: list[tuple[float, float]]) -> list[tuple[int, int]]:
    """Each cross's centre as the steps drew it: the x of its vertical arm's pen-down
    runs and the y of its horizontal arm's, looked for within two steps of `near`."""
    runs = [run for run in pen_down_runs(trace, CONFIG) if len(run) >= 10]
    found = []
    for cx, cy in near:
        xs = {int(r[0, 0]) for r in runs if (r[:, 0] == r[0, 0]).all()
              and abs(r[0, 0] - cx) <= 2 and abs(r[:, 1] - cy).max() <= ARM_STEPS + 2}
        ys = {int(r[0, 1]) for r in runs if (r[:, 1] == r[0, 1]).all()
              and abs(r[0, 1] - cy) <= 2 and abs(r[:, 0] - cx).max() <= ARM_STEPS + 2}
        assert len(xs) == 1 and len(ys) == 1, f"no single cross near {cx, cy} steps: {xs} {ys}"
        found.append((xs.pop(), ys.pop()))
    return found


def test_the_bottom_turned_over_about_the_axis_lands_on_the_top_to_the_step():
    holes = kicad_holes(DRILLS / "Flashpads-PTH.drl") + kicad_holes(DRILLS / "Flashpads-NPTH.drl")
    outline = read_file(BOARD / "Flashpads-Edge_Cuts.gbr")
    box = extents(outline)
    board_crosses = sides.registration_points(holes, None)
    planned, measured = {}, {}
    for side, layer in (("top", "F_Cu"), ("bottom", "B_Cu")):
        options = PlanOptions(mode="ink", holes=holes, side=side, outline_program=outline,
                              registration=True)
        plan = planned[side] = plan_file(BOARD / f"Flashpads-{layer}.gbr", CONFIG,
                                         options=options)
        trace = simulate(plan.job.commands, CONFIG)
        crosses = board_crosses if side == "top" else \
            [(box[0] + box[2] - x, y) for x, y in board_crosses]
        measured[side] = crosses_in_steps(
            trace, [((x - plan.offset_nm[0]) / STEP, (y - plan.offset_nm[1]) / STEP)
                    for x, y in crosses])
        if side == "bottom":
            # the bottom's own marks stay bare too, and its crosses join no islands
            ink = ink_near(trace, CONFIG, plan.offset_nm, PEN, plan.marks)
            assert plan.marks and pixels_inside(clip.intersection(ink, plan.marks)) == 0
            around = clip.union(*[clip.stroke([[c]], sides.CROSS_ARM_NM, 1000)
                                  for c in crosses])
            ink = ink_near(trace, CONFIG, plan.offset_nm, PEN, around)
            assert joined_islands(ink, plan.ink.copper.native, 30_000) == []
    top, bottom = planned["top"], planned["bottom"]
    assert top.offset_nm == bottom.offset_nm                   # one offset for both
    # the axis: the vertical centre line of the outline's box, where the first line says
    centre = Fraction(box[0] + box[2], 2)
    axis_machine = (centre - top.offset_nm[0]) / STEP         # in steps
    for plan, side in ((top, "top"), (bottom, "bottom")):
        assert plan.side_line.startswith(f"{side} side")
        assert f"vertical line X {float(centre) / MM:.4f} mm (board)" in plan.side_line
        assert f"X {float(centre - plan.offset_nm[0]) / MM:.4f} mm on the machine" \
            in plan.side_line
    # every bottom hole mirrored about the axis is its top hole, exactly in nm
    assert len(bottom.holes) == len(top.holes) == len(holes)
    for t, b in zip(top.holes, bottom.holes):
        assert (2 * centre - b.x_nm, b.y_nm) == (t.x_nm, t.y_nm)
    # from the steps: each bottom cross turned over lands on its top cross to the step,
    # and each top cross on its hole's place on the machine
    assert len(measured["top"]) == 3
    for (tx, ty), (bx, by), (hx, hy) in zip(measured["top"], measured["bottom"],
                                            board_crosses):
        assert abs(2 * axis_machine - bx - tx) <= 1 and by == ty
        assert abs(tx - (hx - top.offset_nm[0]) / STEP) <= 1
        assert abs(ty - (hy - top.offset_nm[1]) / STEP) <= 1


ARCS = HEADER + """%ADD10C,0.5*%
%ADD11R,1.0X0.4*%
D10*
X1000000Y1000000D02*
G01*
X3000001Y1500000D01*
G03*
X4000000Y2500000I500000J500001D01*
G02*
X5000000Y2500000I500000J0D01*
D11*
X2000000Y4000000D03*
M02*
"""


def test_the_mirror_is_exact_in_nm_and_its_own_inverse(tmp_path):
    path = tmp_path / "arcs.gbr"
    path.write_text(ARCS)
    program = read_file(path)
    twice = 6_000_001                              # an axis between two nm: still exact
    once = mirrored(program, "x", twice)
    table, flipped = program.table, once.table
    assert np.array_equal(flipped[:, X], twice - table[:, X])
    assert np.array_equal(flipped[:, Y], table[:, Y])
    assert np.array_equal(flipped[:, I], -table[:, I])
    cw, ccw = int(OpKind.ARC_CW), int(OpKind.ARC_CCW)
    assert np.array_equal(flipped[:, KIND] == cw, table[:, KIND] == ccw)
    assert np.array_equal(mirrored(once, "x", twice).table, table)
    # the apertures' images turn with it (a rectangle's box stays centred)
    assert once.apertures[11].extent_nm == program.apertures[11].extent_nm
    across = mirrored(program, "y", 2 * 3 * MM)
    assert np.array_equal(across.table[:, Y], 6 * MM - table[:, Y])


def test_the_axis_default_and_the_one_given(tmp_path):
    outline_box, holes_box = (0, 0, 10 * MM, 4 * MM), (MM, MM, 3 * MM, 3 * MM)
    assert sides.default_axis(outline_box, holes_box) == sides.MirrorAxis("x", 10 * MM)
    assert sides.default_axis(None, holes_box) == sides.MirrorAxis("x", 4 * MM)
    assert sides.parse_axis("y=12.5") == ("y", 12_500_000)
    with pytest.raises(ValueError, match="--mirror-axis: expected x=MM or y=MM"):
        sides.parse_axis("z=3")
    # a horizontal axis given: the bottom's holes and copper mirrored in y
    path = tmp_path / "pad.gbr"
    path.write_text(HEADER + "%ADD10C,2.0*%\nD10*\nX5000000Y2000000D03*\nM02*\n")
    hole = Hole(5 * MM, 2 * MM, 800_000)
    planned = plan_file(path, CONFIG, options=PlanOptions(
        mode="ink", holes=[hole], side="bottom", mirror_axis=("y", 10 * MM)))
    assert planned.holes == (Hole(5 * MM, 18 * MM, 800_000),)
    assert "horizontal line Y 10.0000 mm (board)" in planned.side_line
    assert planned.artwork.drawn_box_nm == (5 * MM, 18 * MM, 5 * MM, 18 * MM)
    arc_slot = Slot(0, 0, 2 * MM, 0, 600_000, arc="cw", cx_nm=MM, cy_nm=0)
    turned = sides.mirror_drills([arc_slot], sides.MirrorAxis.at("x", MM))[0]
    assert (turned.x0_nm, turned.x1_nm, turned.cx_nm, turned.arc) == (2 * MM, 0, MM, "ccw")


def test_without_holes_the_crosses_stand_outside_the_outline(tmp_path):
    path = tmp_path / "pad.gbr"
    path.write_text(HEADER + "%ADD10C,2.0*%\nD10*\nX5000000Y2000000D03*\nM02*\n")
    outline = read_file(path)
    box = extents(outline)
    points = sides.registration_points([], box)
    assert len(points) == 3
    assert all(not (box[0] <= x <= box[2] and box[1] <= y <= box[3]) for x, y in points)
    for side in sides.SIDES:
        planned = plan_file(path, CONFIG, options=PlanOptions(
            mode="ink", side=side, outline_program=outline, registration=True))
        rows = planned.plotted.table
        strokes = rows[np.isin(rows[:, KIND], (int(OpKind.MOVE), int(OpKind.LINE)))]
        ends = {(x, y) for x, y in strokes[:, [X, Y]].tolist()}
        drawn = [sides.MirrorAxis.at("x", 5 * MM).point(*p) if side == "bottom" else p
                 for p in points]
        arm = sides.CROSS_ARM_NM
        for x, y in drawn:                          # each cross's two arms, whole
            assert {(x - arm, y), (x + arm, y), (x, y - arm), (x, y + arm)} <= ends


def test_a_layer_alone_is_planned_as_before(tmp_path):
    path = tmp_path / "pad.gbr"
    path.write_text(HEADER + "%ADD10C,2.0*%\nD10*\nX5000000Y2000000D03*\nM02*\n")
    planned = plan_file(path, CONFIG, options=PlanOptions(mode="ink"))
    assert planned.side_line == "" and planned.holes == () and planned.marks == []
    # drill-mark settings without holes change nothing: the same offset and rows
    marked = plan_file(path, CONFIG, options=PlanOptions(mode="ink", drill_marks="actual",
                                                         drill_mark_nm=MM))
    assert marked.offset_nm == planned.offset_nm
    assert np.array_equal(marked.plotted.table, planned.plotted.table)
    with pytest.raises(PlanError, match="not a board's side"):
        PlanOptions(side="bottom", transform=Transform(rotate_deg=90))
    with pytest.raises(PlanError, match="--side: expected top or bottom"):
        PlanOptions(side="back")


def test_a_cross_keeps_off_another_islands_centre_line_ink(tmp_path):
    """A 0.2 mm trace of another net 0.4 mm from the pad: its centre line, drawn with
    the 0.4 mm pen, inks 0.1 mm past its copper; the cross's arm stops short of that
    ink by the islands' clearance, so the two islands stay apart (from the steps)."""
    path = tmp_path / "pads.gbr"
    path.write_text(HEADER + "%ADD10C,2.0*%\n%ADD11C,0.2*%\nD10*\nX5000000Y5000000D03*\n"
                    "X15000000Y5000000D03*\nD11*\nX6500000Y3000000D02*\nX6500000Y7000000D01*\n"
                    "M02*\n")
    holes = [Hole(5 * MM, 5 * MM, 800_000), Hole(15 * MM, 5 * MM, 800_000)]
    planned = plan_file(path, CONFIG, options=PlanOptions(mode="ink", holes=holes, side="top",
                                                          registration=True))
    arms = [p for p in planned.ink.fills[-1].paths if len(p) == 2 and p[0][1] == 5 * MM]
    assert arms, "no horizontal arm left"
    trace = simulate(planned.job.commands, CONFIG)
    ink = ink_of_trace(trace, CONFIG, planned.offset_nm, [PEN])
    assert joined_islands(ink, planned.ink.copper.native, 30_000) == []
