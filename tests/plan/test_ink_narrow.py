"""Narrow features never join two copper islands: constructed boards, planned in ink
mode, stepped by the reference machine (the firmware's twin), and the pen-down steps
swept by the pen compared with the copper islands (tests/inked.py).

`joined_islands(ink, copper, GAP_NM)` lists the islands the ink joins or brings
within GAP_NM of each other: a few um of gap is no gap on a real pen, and the
planner keeps narrow.CLEARANCE_NM (less the stepping, 2 x 4.4 um) between inks.
"""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from corpus import CORPUS
from inked import box, joined_islands, plan_and_ink

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan.ink import clip
from galileo_cnc.cli import plot as plot_cli
from galileo_cnc.plan.ink import inking, narrow
from galileo_cnc.plan.ink.edges import point_to_edges, segment_gaps, segments_near
from galileo_cnc.plan.ink.geometry import dark_geometry
from galileo_cnc.plan.ink.islands import Islands
from galileo_cnc.plan.ink.narrow import CLEARANCE_NM, find_narrow, keep_islands_apart
from galileo_cnc.plan.open_traces import open_traces
from galileo_cnc.readers import read_file

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
    return plan_and_ink(path, PEN, CONFIG)


def uninked(ink, area) -> float:
    return clip.area_nm2(clip.difference(area, ink))


def test_clearance_leaves_a_gap_after_stepping():
    assert CLEARANCE_NM - 2 * 4_400 - 1_000 > GAP_NM


@pytest.mark.parametrize("forked", [False, True])
def test_a_trace_between_two_pads_closer_than_the_overdraw_does_not_bridge(tmp_path,
                                                                           monkeypatch,
                                                                           forked):
    # (forked: the cuts worked out in a second process while the pads are filled)
    monkeypatch.setattr(inking, "BACKGROUND_VERTICES", 0 if forked else 10 ** 12)
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


def test_segments_near_finds_every_pair_within_reach_and_measures_it():
    # random segments of many lengths and dots: every pair whose ends come within
    # reach of the other segment is among the candidates, and segment_gaps measures
    # the pairs as a brute-force point-to-segment distance does
    rng = np.random.default_rng(5)
    starts = rng.integers(0, 20 * MM, (1200, 2))
    ends = starts + rng.integers(-3 * MM, 3 * MM, (1200, 2)) * (rng.random((1200, 1)) < 0.8)
    reach = 400_000
    # and the hard case: each of the first 600 with a twin shifted sideways by just
    # under the reach and along by up to the reach (their samples may lie a cell and
    # a half apart)
    direction = (ends[:600] - starts[:600]).astype(np.float64)
    direction /= np.maximum(np.hypot(*direction.T), 1.0)[:, None]
    side = np.stack([-direction[:, 1], direction[:, 0]], axis=1) * 0.999 * reach
    side[np.all(direction == 0, axis=1)] = (0.999 * reach, 0)
    along = direction * rng.random((600, 1)) * reach
    shift = np.rint(side + along).astype(np.int64)
    a0, a1 = starts[:600], ends[:600]
    b0 = np.concatenate([starts[600:], starts[:600] + shift])
    b1 = np.concatenate([ends[600:], ends[:600] + shift])
    i, j = segments_near(a0, a1, b0, b1, reach)
    found = set(zip(i.tolist(), j.tolist()))
    assert len(found) == len(i)                           # each pair once
    every_i, every_j = np.divmod(np.arange(600 * 1200), 1200)
    p0, p1, q0, q1 = a0[every_i], a1[every_i], b0[every_j], b1[every_j]
    gaps = segment_gaps(p0, p1, q0, q1)
    brute = np.min([point_to_edges(e.astype(np.float64), f0, f1)[1]
                    for e, f0, f1 in ((p0, q0, q1), (p1, q0, q1), (q0, p0, p1), (q1, p0, p1))],
                   axis=0)
    assert np.allclose(gaps, brute, rtol=0, atol=1e-6)
    near = set(zip(every_i[gaps < reach].tolist(), every_j[gaps < reach].tolist()))
    assert near <= found
    assert 600 < len(near) < len(found) < 600 * 1200 // 4


def test_the_first_look_at_the_whole_board_changes_no_cut():
    # keep_islands_apart looks closely only at the features _nearby marks; marking
    # them all (the exact look at every feature, as before) gives the same cuts on a
    # real layer where a 0.8 mm pen makes 751 centre lines and cuts 53 of them
    layer = CORPUS / "allegro" / "tracespace-371" / "l1_primary.art"
    program = read_file(layer)
    islands = Islands.of(dark_geometry(program, 1_000).native)
    pen = 800_000

    def cuts(first_look):
        features, _zero = find_narrow(program, pen + 8_000, pen, 1_000)
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(narrow, "_nearby", first_look)
            bridges = keep_islands_apart(features, islands, pen)
        return ([(f.op_index, f.cut, [p.tolist() for p in f.pieces]) for f in features],
                [(b.feature.op_index, b.at_nm, b.other_nm, b.left_out_nm,
                  b.other.op_index if b.other else None) for b in bridges])

    marked, first_look = [], narrow._nearby

    def counted(features, *args):
        marked.append(first_look(features, *args))
        return marked[-1]

    def everything(features, *_args):
        return np.ones(len(features), dtype=bool), np.ones(len(features), dtype=bool)

    pieces, bridges = cuts(counted)
    assert (pieces, bridges) == cuts(everything)
    assert len(bridges) == 53
    near_copper, near_line = marked[0]
    assert near_copper.sum() + near_line.sum() < len(pieces)   # most are never looked at


def test_before_a_job_only_the_first_bridges_are_named_and_the_rest_counted(tmp_path,
                                                                            monkeypatch):
    # three pairs of traces too close for both inks: three cuts, three warnings; plot
    # (and getg, with the same list) names the first and counts the other two
    pair = ("X0Y{y}D02*\nX10000000Y{y}D01*\n"
            "X2000000Y{q}D02*\nX6000000Y{q}D01*\n")
    body = "%ADD11C,0.15*%\nD11*\n" + "".join(
        pair.format(y=k * 2 * MM, q=k * 2 * MM + 310_000) for k in range(3))
    planned, _ink, _copper = plot(tmp_path, body)
    texts = [str(w) for w in planned.ink.warnings]
    bridges = [t for t in texts if "would join the ink of line" in t]
    assert len(bridges) == len(planned.ink.bridges) == 3
    assert planned.ink.warnings_to_show() == texts             # 20 are shown whole
    monkeypatch.setattr(inking, "SHOWN_BRIDGES", 1)
    shown = planned.ink.warnings_to_show()
    assert [t for t in shown if "would join" in t] == bridges[:1]
    assert "... and 2 more places where a centre line is left short of another copper " \
           "island (galileo-cnc info lists every one)" in shown
    assert [t for t in shown if "would join" not in t and "... and" not in t] == \
        [t for t in texts if t not in bridges]                # the other warnings all stay
    # plot and getg say the left-out pieces as one summary (plan/open_traces.py)
    out = io.StringIO()
    plot_cli._say_ink(planned.ink, out)
    said = out.getvalue().splitlines()[1:]
    assert [t for t in said if "would join" in t] == [open_traces(planned.ink).text()]
    assert said[0] == shown[0]                                # the narrow features' warning


def test_a_length_too_short_for_three_decimals_is_not_said_as_zero():
    # issue 31, item 19: "left out for 0 mm" for a piece of a few hundred nm
    from galileo_cnc.plan.widths import mm_text
    assert [mm_text(nm) for nm in (0, 300, -300, 1_000, 250_000, -1_000)] == \
        ["0", "<0.001", ">-0.001", "0.001", "0.25", "-0.001"]
