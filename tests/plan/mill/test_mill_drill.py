"""Drilling on a GRBL mill: the G-code read back with the project's G-code reader visits
every hole once at its exact place, one bit change between two bits, a hole wider than
its bit milled as a helix inside it, plated and unplated in the order asked, slots
along their path or round their contour."""

import dataclasses
import math
import re

import pytest

from corpus import corpus_file
from galileo_cnc.config.mill import MillConfig
from galileo_cnc.plan.mill.drill import DrillError, drill_gcode, plan_drilling
from galileo_cnc.program.drills import Hole, Slot
from galileo_cnc.program.ops import OpKind
from galileo_cnc.readers import read_drill
from galileo_cnc.readers.gcode import read_gcode

MILL = MillConfig(drills_nm=(800_000, 1_000_000))
PLATED = [Hole(x, y, 800_000, "T1", True) for x, y in
          [(10_000_000, 0), (0, 0), (5_000_000, 5_000_000), (2_500_000, 7_000_000)]]
UNPLATED = [Hole(20_000_000, 3_000_000, 1_000_000, "T2", False),
            Hole(-4_000_000, 9_000_000, 3_200_000, "T3", False),   # milled: 1.0 mm bit
            Hole(30_000_000, 0, 1_050_000, "T2", False)]
SMALL = Hole(7_000_000, -2_000_000, 500_000, "T4", True, line=17)


def _visits(text: str):
    """(x, y, kind) per hole in the order cut: 'drill' for a rapid then straight down,
    'helix' (at the circle's centre, with its radius) for full circles, 'slot'."""
    ops = [op for op in read_gcode("drill.nc", text)
           if op.kind in (OpKind.MOVE, OpKind.LINE, OpKind.ARC_CW, OpKind.ARC_CCW)]
    runs, visits = [], []
    for op in ops:
        if op.kind == OpKind.MOVE:
            runs.append([op])
        else:
            runs[-1].append(op)
    for run in runs:
        start, cuts = run[-1] if len(run) == 1 else run[0], run[1:]
        if not cuts:
            visits.append((start.x_nm, start.y_nm, "drill", 0))
        elif all(c.kind == OpKind.ARC_CW and (c.x_nm, c.y_nm) == (start.x_nm, start.y_nm)
                 for c in cuts):
            centre = (start.x_nm + cuts[0].i_nm, start.y_nm + cuts[0].j_nm)
            visits.append((*centre, "helix", math.hypot(cuts[0].i_nm, cuts[0].j_nm)))
        else:
            visits.append((start.x_nm, start.y_nm, "slot", len(cuts)))
    return visits


def test_two_bits_one_change_every_hole_once_at_its_place_plated_first():
    text = drill_gcode(PLATED + UNPLATED, MILL, "plated-first")
    assert len(re.findall(r"^M0 \(TOOL CHANGE: put in the 1\.000 mm bit\)$", text, re.M)) == 1
    assert text.count("TOOL CHANGE") == 1
    visits = _visits(text)
    # the rapids of the touch-off go nowhere: only holes are visited
    holes = sorted((v[0], v[1]) for v in visits)
    assert holes == sorted((h.x_nm, h.y_nm) for h in PLATED + UNPLATED)
    plated = {(h.x_nm, h.y_nm) for h in PLATED}
    kinds = [(v[0], v[1]) in plated for v in visits]
    assert kinds == [True] * 4 + [False] * 3
    # every straight plunge goes through the board and the breakthrough: 1.8 mm
    assert text.count("G1 Z-1.8 F60") == 6


def test_unplated_first_when_asked_and_a_change_back_is_none_when_the_bits_agree():
    visits = _visits(drill_gcode(PLATED + UNPLATED, MILL, "unplated-first"))
    plated = {(h.x_nm, h.y_nm) for h in PLATED}
    assert [(v[0], v[1]) in plated for v in visits] == [False] * 3 + [True] * 4
    with pytest.raises(DrillError, match="drill order 'sideways'"):
        plan_drilling(PLATED, MILL, "sideways")


def test_a_hole_wider_than_its_bit_is_a_helix_inside_it_down_to_the_depth():
    text = drill_gcode(UNPLATED, MILL)
    (helix,) = [v for v in _visits(text) if v[2] == "helix"]
    wide = UNPLATED[1]
    assert helix[:2] == (wide.x_nm, wide.y_nm)
    # the bit's edge on the hole's edge: radius = (3.2 - 1.0) / 2 mm
    assert helix[3] + 1_000_000 / 2 == pytest.approx(wide.diameter_nm / 2, abs=1)
    # 1.8 mm in passes of at most 0.5 mm: four turns going down, one more at the depth
    turns = re.findall(r"^G2 X-2\.9 Y9 I-1\.1 J0(?: Z(\S+))?", text, re.M)
    assert [z for z in turns] == ["-0.45", "-0.9", "-1.35", "-1.8", ""]


def test_a_hole_smaller_than_every_bit_is_reported_and_drilled_with_the_smallest():
    plan = plan_drilling([SMALL, *PLATED], MILL)
    (note,) = plan.notes
    assert "T4 line 17 at X 7.000 Y -2.000 mm: 0.500 mm" in note and "0.800 mm" in note
    assert plan.groups[0].bit_nm == 800_000 and SMALL in plan.groups[0].items
    assert "(T4 line 17" in drill_gcode([SMALL, *PLATED], MILL)
    vias = [Hole(k * 1_000_000, 0, 300_000, "T7", True, line=30 + k) for k in range(3)]
    (note,) = plan_drilling([*vias, *PLATED], MILL).notes
    assert note.startswith("3 holes of 0.300 mm (the first T7 line 30 at X 0.000 Y 0.000 mm)")


def test_the_probe_re_zeroes_z_with_g38_2_on_the_plate():
    text = drill_gcode(PLATED + UNPLATED, MillConfig(probe=True, probe_plate_nm=50_000))
    change = text[text.index("TOOL CHANGE"):]
    assert re.search(r"G38\.2 Z-10 F60\nG92 Z0\.05\nG0 Z2\n", change)
    assert "TOUCH OFF" not in text


def test_slots_along_their_path_in_depth_passes_and_a_wide_one_round_its_contour():
    narrow = Slot(0, 0, 4_000_000, 0, 800_000, "T5", True)
    arc = Slot(10_000_000, 0, 12_000_000, 2_000_000, 800_000, "T5", True,
               arc="ccw", cx_nm=12_000_000, cy_nm=0)
    wide = Slot(0, 10_000_000, 4_000_000, 10_000_000, 1_400_000, "T6", True)
    text = drill_gcode([narrow, arc, wide], MILL)
    slots = [v for v in _visits(text) if v[2] == "slot"]
    assert len(slots) == 3
    # back and forth along the path: four depth passes, one move each
    assert sorted(v[3] for v in slots) == [4, 4, 16]
    ops = list(read_gcode("drill.nc", text))
    ring = [(op.x_nm, op.y_nm) for op in ops
            if op.kind in (OpKind.LINE, OpKind.ARC_CCW) and op.y_nm > 5_000_000]
    # the 1.0 mm bit 0.2 mm off the path each side: its edge on the slot's
    assert {y for _, y in ring} == {9_800_000, 10_200_000}
    assert {x for x, _ in ring} == {0, 4_000_000}


def test_a_real_board_every_hole_once_plated_then_unplated_slots_milled():
    plated = read_drill(str(corpus_file("drill/kicad/flashpads-x2ap/Flashpads-PTH.drl")))
    unplated = read_drill(str(corpus_file("drill/kicad/flashpads-x2ap/Flashpads-NPTH.drl")))
    drills = [dataclasses.replace(item, plated=item.plated is not False)
              for item in (*plated.holes, *plated.slots)]
    drills += [dataclasses.replace(item, plated=False)
               for item in (*unplated.holes, *unplated.slots)]
    text = drill_gcode(drills, MILL)
    visits = _visits(text)
    holes = [v for v in visits if v[2] != "slot"]
    assert sorted((x, y) for x, y, _, _ in holes) == sorted(
        (h.x_nm, h.y_nm) for h in (*plated.holes, *unplated.holes))
    assert len([v for v in visits if v[2] == "slot"]) == len(plated.slots) == 16
    unplated_at = {(h.x_nm, h.y_nm) for h in unplated.holes}
    kinds = [(v[0], v[1]) in unplated_at for v in holes]
    assert kinds == sorted(kinds)           # every unplated hole after every plated one
