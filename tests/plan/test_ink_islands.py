"""Islands closer than the clearance: the fills keep their inks apart (islands.py).

Constructed boards planned in ink mode, stepped by the reference machine, and the
pen-down steps swept by the pen (tests/inked.py). Before the keep-back, fills reached
within 2 um of their island's edge, so two pads 30 um apart were inked 34 um apart:
one line on paper (ekf2's power planes, the led-display's pad grid).
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from inked import box, ink_of_trace

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine.planner import simulate
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.islands import CLEARANCE_NM, Islands, _within, close_places
from galileo_cnc.plan.pipeline import PlanOptions, plan_file

MM = 1_000_000
PEN = 300_000
HEADER = "%FSLAX46Y46*%\n%MOMM*%\nG75*\n"
CONFIG = MachineConfig()
#: what the stepped paths may lose of the clearance: 4.4 um each side, and rounding
STEPPING_NM = 2 * 4_400 + 1_000
#: how far short of a copper edge a fill's ink may end: the 2 um edge margin, stepping
EDGE_NM = 2_000 + 4_400


def plot(tmp_path, body: str):
    path = tmp_path / "board.gbr"
    path.write_text(HEADER + body + "M02*\n")
    planned = plan_file(path, CONFIG, "auto", options=PlanOptions(mode="ink", pens_nm=(PEN,)))
    trace = simulate(planned.job.commands, CONFIG)
    return planned, ink_of_trace(trace, CONFIG, planned.offset_nm, [PEN])


def inks_apart(ink) -> float:
    """The smallest distance between two separate pieces of ink (nm)."""
    pieces = [shapely.Polygon(outer, holes) for outer, holes in clip.components(ink)]
    return min(a.distance(b) for k, a in enumerate(pieces) for b in pieces[k + 1:])


def test_two_pads_30_um_apart_are_inked_at_least_the_clearance_apart(tmp_path):
    body = "%ADD10R,1X1*%\nD10*\nX500000Y500000D03*\nX1530000Y500000D03*\n"
    planned, ink = plot(tmp_path, body)
    assert len(clip.components(planned.ink.copper.native)) == 2
    assert inks_apart(ink) >= CLEARANCE_NM + 30_000 - STEPPING_NM
    # only the facing sides are cut back (half the clearance): the pads are inked
    corners = 4 * (1 - math.pi / 4) * (PEN // 2) ** 2
    for pad in (box(0, 0, MM, MM), box(1_030_000, 0, 2_030_000, MM)):
        left = clip.area_nm2(clip.difference(pad, ink))
        assert left <= corners * 1.05 + 4 * MM * 4_000 + MM * (CLEARANCE_NM // 2 + 4_400)
    # the far sides are inked to the edge as before (less the margin and the stepping)
    assert clip.area_nm2(clip.difference(box(EDGE_NM, 200_000, 10_000, 800_000), ink)) == 0
    (warning,) = [str(w) for w in planned.ink.warnings if "come within" in str(w)]
    assert "1 pair of copper islands come within 0.05 mm" in warning
    assert "the closest 0.030 mm apart at X 1.000" in warning or \
        "the closest 0.030 mm apart at X 1.030" in warning


def test_only_the_stretch_near_the_other_island_is_cut_back(tmp_path):
    # a 10 x 1 mm bar and a 1 mm round pad 30 um above its middle: the bar's top edge
    # is cut back where the pad comes within the clearance, nowhere else
    body = ("%ADD10R,10X1*%\n%ADD11C,1*%\n"
            "D10*\nX5000000Y500000D03*\nD11*\nX5000000Y1530000D03*\n")
    planned, ink = plot(tmp_path, body)
    assert inks_apart(ink) >= CLEARANCE_NM + 30_000 - STEPPING_NM
    top_edge = (lambda x0, x1: clip.area_nm2(clip.difference(
        box(x0, 990_000, x1, MM - EDGE_NM), ink)))
    assert top_edge(500_000, 4_500_000) == 0 and top_edge(5_500_000, 9_500_000) == 0
    assert top_edge(4_950_000, 5_050_000) == 100_000 * (10_000 - EDGE_NM)  # cut back there


def test_islands_under_a_step_apart_are_one_and_fill_to_the_gap(tmp_path):
    # 3 um apart: no board house etches that and no pen draws it; no keep-back
    body = "%ADD10R,1X1*%\nD10*\nX500000Y500000D03*\nX1503000Y500000D03*\n"
    planned, ink = plot(tmp_path, body)
    assert planned.ink.close.count == 0
    assert not [w for w in planned.ink.warnings if "come within" in str(w)]
    assert clip.area_nm2(clip.difference(box(990_000, 200_000, MM - EDGE_NM, 800_000), ink)) == 0


def test_close_places_name_the_gap_and_both_sides():
    pads = box(0, 0, MM, MM) + box(1_030_000, 0, 2_030_000, MM)
    found = close_places(Islands.of(clip.union(pads)))
    assert found.count == 1 and found.closest_nm == 30_000
    assert {found.at_nm[0], found.other_nm[0]} == {1_000_000, 1_030_000}
    # both facing sides whole, and the ends of the sides meeting them at the corners
    # (x 0.98 .. 1 mm is within 0.05 mm of the other pad's corner)
    # (a stretch is found once per pair of edges: some lie inside others)
    whole = [((980_000, 0), (1_000_000, 0)), ((980_000, MM), (1_000_000, MM)),
             ((1_000_000, 0), (1_000_000, MM)), ((1_030_000, 0), (1_030_000, MM)),
             ((1_030_000, 0), (1_050_000, 0)), ((1_030_000, MM), (1_050_000, MM))]
    stretches = {tuple(sorted(map(tuple, s.tolist()))) for s in found.stretches}
    assert set(whole) <= stretches
    lines = shapely.MultiLineString(whole)
    assert all(lines.buffer(1).contains(shapely.LineString(s)) for s in stretches)


def test_within_finds_the_part_of_a_segment_near_another():
    a, b = np.array([[0, 0]] * 4), np.array([[10_000, 0]] * 4)
    fa = np.array([[4_000, 30], [4_000, 100], [-100, 0], [10_030, 20]])
    fb = np.array([[6_000, 30], [6_000, 100], [-100, 5_000], [10_030, 20]])
    lo, hi = _within(a, b, fa, fb, 50)
    assert np.allclose([lo[0], hi[0]], [0.396, 0.604])        # beside f, and round its ends
    assert lo[1] > hi[1] and lo[2] > hi[2]                       # 100 away; beyond a's end
    assert np.isclose(lo[3], (10_030 - math.sqrt(50 ** 2 - 20 ** 2)) / 10_000) and hi[3] == 1


def test_info_tells_the_user_which_islands_are_kept_apart(tmp_path):
    import json
    import os
    import subprocess
    import sys

    path = tmp_path / "close.gbr"
    path.write_text(HEADER + "%ADD10R,1X1*%\nD10*\nX500000Y500000D03*\nX1530000Y500000D03*\n"
                    "M02*\n")
    run = lambda *extra: subprocess.run(                           # noqa: E731
        [sys.executable, "-m", "galileo_cnc", "info", str(path), "--pens", "0.3", *extra],
        env=dict(os.environ, GALILEO_CNC_NO_PROBE="1"), capture_output=True, text=True,
        timeout=120)
    text = run()
    assert text.returncode == 0, text.stderr
    assert "1 pair of islands too close kept apart" in text.stdout
    assert "the ink keeps 0.025 mm behind the copper's edge there" in text.stdout
    assert json.loads(run("--json").stdout)["ink"]["close_island_pairs"] == 1
