"""Narrow features never join two copper islands: constructed boards, planned in ink
mode, stepped by the reference machine (the firmware's twin), and the pen-down steps
swept by the pen compared with the copper islands (tests/inked.py).

`joined_islands(ink, copper, GAP_NM)` lists the islands the ink joins or brings
within GAP_NM of each other: a few um of gap is no gap on a real pen, and the
planner keeps narrow.CLEARANCE_NM (less the stepping, 2 x 4.4 um) between inks.
"""

from __future__ import annotations

import math

import numpy as np
from inked import ink_of_trace, joined_islands

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine.planner import simulate
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.narrow import CLEARANCE_NM
from galileo_cnc.plan.pipeline import PlanOptions, plan_file

MM = 1_000_000
PEN = 300_000
HEADER = "%FSLAX46Y46*%\n%MOMM*%\nG75*\n"
CONFIG = MachineConfig()
GAP_NM = 30_000


def plot(tmp_path, body: str):
    """(planned job, ink from the steps, copper) of a Gerber body; line 4 is the
    body's first line."""
    path = tmp_path / "board.gbr"
    path.write_text(HEADER + body + "M02*\n")
    planned = plan_file(path, CONFIG, "auto", options=PlanOptions(mode="ink", pens_nm=(PEN,)))
    trace = simulate(planned.job.commands, CONFIG)
    ink = ink_of_trace(trace, CONFIG, planned.offset_nm, [PEN])
    return planned, ink, planned.ink.copper.native


def box(x0, y0, x1, y1):
    return [[[x0, y0], [x1, y0], [x1, y1], [x0, y1]]]


def uninked(ink, area) -> float:
    return clip.area_nm2(clip.difference(area, ink))


def test_clearance_leaves_a_gap_after_stepping():
    assert CLEARANCE_NM - 2 * 4_400 - 1_000 > GAP_NM


def test_a_trace_between_two_pads_closer_than_the_overdraw_does_not_bridge(tmp_path):
    # pads A (x 0..1 mm) and B (x 1.2..2.2 mm); a 0.1 mm trace of its own runs up
    # between them at x = 1.1 mm: 0.05 mm from each pad, its overdraw is 0.1 mm
    body = ("%ADD10R,1X1*%\n%ADD11C,0.1*%\n"          # lines 4, 5
            "D10*\nX500000Y500000D03*\nX1700000Y500000D03*\n"    # 6..8
            "D11*\nX1100000Y-3000000D02*\nX1100000Y4000000D01*\n")  # 9..11
    planned, ink, copper = plot(tmp_path, body)
    assert len(clip.components(copper)) == 3
    assert joined_islands(ink, copper, GAP_NM) == []
    # the trace is drawn where it is clear of the pads, left out between them
    (feature,) = planned.ink.narrow
    assert feature.cut and feature.pos.line == 11
    assert uninked(ink, box(1_050_000, -3_000_000, 1_150_000, -500_000)) == 0
    assert uninked(ink, box(1_050_000, 1_500_000, 1_150_000, 4_000_000)) == 0
    between = box(1_050_000, 0, 1_150_000, 1_000_000)
    assert clip.area_nm2(clip.intersection(ink, between)) == 0
    # the pads are filled as ever (less the corners a round pen cannot reach)
    corners = 4 * (1 - math.pi / 4) * (PEN // 2) ** 2
    for pad in (box(0, 0, MM, MM), box(1_200_000, 0, 2_200_000, MM)):
        assert uninked(ink, pad) <= corners * 1.05 + 4 * MM * 4_000
    # the cut is warned with both places: the trace's line, where it stops, the pad
    (bridge,) = planned.ink.bridges
    assert bridge.feature is feature and bridge.other is None
    assert bridge.other_nm[0] in (1_000_000, 1_200_000)
    text = [str(w) for w in planned.ink.warnings if "would join" in str(w)]
    assert len(text) == 1 and ":11:" in text[0]
    assert "another copper island at X 1.000" in text[0] or \
        "another copper island at X 1.200" in text[0]
    assert bridge.left_out_nm >= 1_300_000             # y -0.17 .. 1.17 mm at least


def test_two_narrow_traces_of_different_islands_running_close_do_not_bridge(tmp_path):
    # two 0.15 mm traces 0.16 mm apart: each pen line alone stays clear of the other
    # trace's copper, but the two inks (0.075 mm overdraw each) would overlap. The
    # longer one (P) is drawn whole; the other (Q) where it runs beside P is left out.
    body = ("%ADD11C,0.15*%\nD11*\n"                               # lines 4, 5
            "X0Y0D02*\nX10000000Y0D01*\n"                           # P: 6, 7
            "X2000000Y310000D02*\nX6000000Y310000D01*\n"            # Q: 8, 9
            "X6000000Y3000000D01*\n")                               # Q goes up: 10
    planned, ink, copper = plot(tmp_path, body)
    assert len(clip.components(copper)) == 2
    assert joined_islands(ink, copper, GAP_NM) == []
    lines = {f.pos.line: f for f in planned.ink.narrow}
    assert not lines[7].cut                                   # P: drawn whole
    assert uninked(ink, box(0, -75_000, 10 * MM, 75_000)) <= 2 * 10 * MM * 4_000
    assert lines[9].cut                                        # Q beside P: left out
    assert clip.area_nm2(clip.intersection(ink, box(2_500_000, 235_000, 5_500_000,
                                                    385_000))) == 0
    # Q's way up, away from P, is drawn
    assert uninked(ink, box(5_925_000, 1_000_000, 6_075_000, 3_000_000)) == 0
    # each cut names both places: Q's line and P's
    cuts = [b for b in planned.ink.bridges if b.feature is lines[9]]
    assert cuts and all(b.other is lines[7] for b in cuts)
    assert all(abs(b.other_nm[1]) <= 1 for b in cuts)          # a point on P's centre line
    text = " ".join(str(w) for w in planned.ink.warnings)
    assert ":9:1: warning: the centre line would join the ink of line 7" in text
    # and no narrow feature is cut without a warning
    for feature in planned.ink.narrow:
        assert not feature.cut or any(b.feature is feature for b in planned.ink.bridges)


def test_traces_far_enough_apart_are_both_drawn(tmp_path):
    # the same two traces with 0.25 mm between them: both inks fit, nothing is cut
    body = ("%ADD11C,0.15*%\nD11*\nX0Y0D02*\nX10000000Y0D01*\n"
            "X2000000Y400000D02*\nX6000000Y400000D01*\n")
    planned, ink, copper = plot(tmp_path, body)
    assert not planned.ink.bridges and not any(f.cut for f in planned.ink.narrow)
    assert joined_islands(ink, copper, GAP_NM) == []
    assert uninked(ink, copper) <= clip.area_nm2(copper) * 0.002


def test_a_pad_whose_hole_leaves_a_thin_wall_is_inked_as_a_ring(tmp_path):
    # a 1 mm round pad with a 0.7 mm hole: a 0.15 mm wall, too thin for the pen to
    # fill; drawn as a circle a pen radius inside the outer edge
    planned, ink, copper = plot(tmp_path, "%ADD12C,1.0X0.7*%\nD12*\nX0Y0D03*\n")
    (feature,) = planned.ink.narrow
    assert feature.width_nm == 150_000 and feature.inside_nm is not None
    ring_nm2 = clip.area_nm2(copper)
    assert abs(ring_nm2 - math.pi * (0.5 ** 2 - 0.35 ** 2) * MM * MM) < 0.01 * ring_nm2
    assert uninked(ink, copper) <= 0.005 * ring_nm2
    # no ink outside the pad's outer edge beyond the stepping
    pad = clip.stroke([np.array([[0, 0]])], MM // 2, 1000)
    assert clip.area_nm2(clip.difference(ink, pad)) <= math.pi * MM * 5_000
    text = " ".join(str(w) for w in planned.ink.warnings)
    assert "wall 0.15 mm wide round the hole" in text
