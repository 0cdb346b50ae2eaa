"""Necks (plan/ink/necks.py): copper thinner than the pen between two inked parts of one
island, measured from the steps the reference machine makes. A pad in a pour, held by
four thermal spokes narrower than the pen: without ink on the spokes, etching leaves
the pad off its pour."""

from __future__ import annotations

import numpy as np
import pyclipper as pc
from inked import joined_islands

from galileo_cnc.job import PenDown
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.fill import GAP_NM
from galileo_cnc.plan.ink.necks import _feature, _follows

from test_ink_fill import MM, plot

PEN = 400_000


def _region(x0: int, y0: int, x1: int, y1: int) -> str:
    return (f"G36*\nX{x0}Y{y0}D02*\nX{x1}Y{y0}D01*\nX{x1}Y{y1}D01*\nX{x0}Y{y1}D01*\n"
            f"X{x0}Y{y0}D01*\nG37*\n")


#: a 10 x 10 mm pour, a 2.4 mm round clearance at its middle, a 1.6 mm pad in it and
#: four spokes across the 0.4 mm gap, 0.25 mm wide: regions, as a pour's thermal
#: reliefs are (a narrow draw would be a centre line, plan/ink/narrow.py)
THERMAL = (_region(0, 0, 10 * MM, 10 * MM)
           + "%LPC*%\n%ADD10C,2.4*%\nD10*\nX5000000Y5000000D03*\n%LPD*%\n"
           "%ADD11C,1.6*%\nD11*\nX5000000Y5000000D03*\n"
           + _region(5_700_000, 4_875_000, 6_300_000, 5_125_000)
           + _region(3_700_000, 4_875_000, 4_300_000, 5_125_000)
           + _region(4_875_000, 5_700_000, 5_125_000, 6_300_000)
           + _region(4_875_000, 3_700_000, 5_125_000, 4_300_000))


def _square(x0, y0, x1, y1):
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def _holding(ink, point) -> int:
    """The number of the piece of ink (clip.components) that holds `point`, else -1."""
    for number, (outer, holes) in enumerate(clip.components(ink)):
        if pc.PointInPolygon(point, outer.tolist()) and not any(
                pc.PointInPolygon(point, hole.tolist()) == 1 for hole in holes):
            return number
    return -1


def test_thermal_spokes_are_inked_so_the_pad_stays_on_its_pour(tmp_path):
    planned, ink = plot(tmp_path, THERMAL, pens=(PEN,))
    assert len(planned.ink.necks) == 4 and planned.ink.necks_left == []
    copper = planned.ink.copper.native
    # the pad's ink and the pour's are one piece: joined over every spoke
    piece = _holding(ink, (5 * MM, 5 * MM))
    assert piece >= 0 and _holding(ink, (1 * MM, 1 * MM)) == piece
    for x, y in ((6 * MM, 5 * MM), (4 * MM, 5 * MM), (5 * MM, 6 * MM), (5 * MM, 4 * MM)):
        spoke = [_square(x - 100_000, y - 100_000, x + 100_000, y + 100_000)]
        on_spoke = clip.intersection(spoke, copper)
        assert clip.area_nm2(clip.intersection(on_spoke, ink)) >= \
            0.99 * clip.area_nm2(on_spoke)
    # beside a spoke the ink spills (0.4 - 0.25) / 2 mm into the gap, never further
    beyond = clip.difference(ink, clip.offset(copper, 75_000 + 8_000, 1_000))
    assert clip.area_nm2(beyond) == 0
    # drawn as spurs of the walks: no pen lift of their own
    lifts = sum(isinstance(c, PenDown) for c in planned.job.commands)
    assert lifts == 2                                   # the pour's walk and the pad's
    text = " ".join(str(w) for w in planned.ink.warnings)
    assert "4 necks of copper too narrow to fill with the 0.4 mm pen" in text


def test_a_neck_whose_ink_would_come_near_another_island_is_left_bare(tmp_path):
    # a 0.1 mm dot of another net in the gap, 0.095 mm above the right spoke: a line
    # along that spoke would ink it
    body = THERMAL + "%ADD13C,0.1*%\nD13*\nX6000000Y5270000D03*\n"
    planned, ink = plot(tmp_path, body, pens=(PEN,))
    assert len(planned.ink.necks) == 3 and len(planned.ink.necks_left) == 1
    left = planned.ink.necks_left[0].inside_nm
    assert abs(left[1] - 5 * MM) < 130_000 and left[0] > 5 * MM        # the right spoke
    text = " ".join(str(w) for w in planned.ink.warnings)
    assert "4 necks of copper too narrow to fill with the 0.4 mm pen" in text
    assert "1 left bare, a line along it would come within 0.05 mm of another island" \
        in text
    assert joined_islands(ink, planned.ink.copper.native, GAP_NM) == []


def test_a_line_that_leaves_its_bent_piece_is_no_neck_line():
    """A long bent bare piece's axis runs off it, over copper the clearance check cannot
    see into (led-display TOP.art: such a line crossed two other islands): only a line
    that stays within its piece (or half a pen radius of it) is drawn."""
    spoke = np.array(_square(0, 0, 600_000, 250_000), dtype=np.int64)
    line = _feature("x", spoke, PEN).pieces[0]
    assert _follows(line, spoke, PEN // 4)
    assert abs(int(line[0][1]) - 125_000) <= 1 and abs(int(line[1][1]) - 125_000) <= 1
    bent = np.array([[0, 0], [10 * MM, 0], [10 * MM, 10 * MM], [9_800_000, 10 * MM],
                     [9_800_000, 200_000], [0, 200_000]], dtype=np.int64)    # an L, 0.2 mm
    assert not _follows(_feature("x", bent, PEN).pieces[0], bent, PEN // 4)
