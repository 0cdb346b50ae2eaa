"""Short pen lifts left out (plan/order/links.py): a path runs on to the next one of its
pen pen-down only through the area the pen's centre may go, so the ink stays on the
copper of one island; on an ink job the lifts drop and every link is such a line."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import PenDown
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.order import links
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.program.ops import COLUMNS, KIND, TOOL, X, Y, OpKind

MM = 1_000_000
MOVE, LINE = int(OpKind.MOVE), int(OpKind.LINE)
#: a 4 x 2 mm area with a 1 mm square hole in its right half, pen 1
AREA = {1: [[[0, 0], [4 * MM, 0], [4 * MM, 2 * MM], [0, 2 * MM]],
            [[2500000, 500000], [2500000, 1500000], [3500000, 1500000], [3500000, 500000]]]}


def rows(*points_and_kinds) -> np.ndarray:
    table = np.zeros((len(points_and_kinds), len(COLUMNS)), dtype=np.int64)
    for k, (kind, x, y) in enumerate(points_and_kinds):
        table[k, [KIND, X, Y, TOOL]] = kind, x, y, 1
    return table


def linked_after(end, start, most_nm=None, area=AREA) -> bool:
    """Whether a path ending at `end` runs on to one starting at `start`."""
    table = rows((MOVE, 100000, 100000), (LINE, *end), (MOVE, *start),
                 (LINE, start[0] + 1000, start[1]))
    return links.linked_moves(table, area, most_nm).tolist() == [2]


@pytest.mark.parametrize("end, start, linked", [
    ((200000, 1 * MM), (1200000, 1 * MM), True),          # inside
    ((200000, 1 * MM), (200000, 1 * MM), True),           # the same point, inside
    ((0, 1 * MM), (1 * MM, 1 * MM), True),                # from the outline in
    ((2 * MM, 1 * MM), (3900000, 1 * MM), False),         # across the hole
    ((1 * MM, 1 * MM), (1 * MM, 2500000), False),         # out of the area
    ((4100000, 1 * MM), (4100000, 1200000), False),       # a dot outside
    ((200000, 200000), (1800000, 1800000), True),         # 2.26 mm: too long by default
])
def test_a_link_lies_inside_the_pens_area(end, start, linked):
    long = np.hypot(start[0] - end[0], start[1] - end[1]) > links.LINK_MOST_NM
    assert linked_after(end, start, 3 * MM) is linked
    assert linked_after(end, start) is (linked and not long)


@pytest.mark.parametrize("end, start", [
    ((200000, 0), (1200000, 0)), ((1200000, 0), (200000, 0)),                  # bottom
    ((4 * MM, 200000), (4 * MM, 1200000)), ((4 * MM, 1200000), (4 * MM, 200000)),
    ((1200000, 2 * MM), (200000, 2 * MM)), ((200000, 2 * MM), (1200000, 2 * MM)),
    ((0, 1200000), (0, 200000)), ((0, 200000), (0, 1200000)),                  # left
    ((2500000, 600000), (2500000, 1400000)), ((3500000, 1400000), (3500000, 600000)),
    ((2600000, 1500000), (3400000, 1500000)), ((3400000, 500000), (2600000, 500000)),
])
def test_a_link_along_the_areas_outline_is_inside(end, start):
    """A walk that ends on E0's outline and a path that starts on it: the link runs
    along the outline, either way round, on the outer ring and on a hole's. Clipper's
    clipping of an open path along an edge answers inside on some edges and outside
    on others; the area grown by LINK_SLACK_NM holds every one."""
    assert linked_after(end, start)


def test_no_link_between_pens_or_without_an_area():
    table = rows((MOVE, 0, 1 * MM), (LINE, 200000, 1 * MM), (MOVE, 300000, 1 * MM),
                 (LINE, 400000, 1 * MM))
    assert links.linked_moves(table, AREA).tolist() == [2]
    table[2:, TOOL] = 2
    assert links.linked_moves(table, AREA).size == 0
    assert links.linked_moves(table, {}).size == 0


#: two pads 0.3 mm apart (two islands) and a pad with a trace narrower than the pen
#: (a centre line) from its centre: the pen may link inside one island, never across
#: the 0.3 mm
BOARD = """%FSLAX46Y46*%
%MOMM*%
%ADD10R,1.5X1.5*%
%ADD11C,0.2*%
D10*
X0Y0D03*
X1800000Y0D03*
X6000000Y0D03*
D11*
X6000000Y0D02*
X6000000Y4000000D01*
M02*
"""


def test_ink_jobs_lift_less_and_link_only_inside_an_island(tmp_path, monkeypatch):
    path = tmp_path / "board.gbr"
    path.write_text(BOARD)
    config = dataclasses.replace(MachineConfig(), x_travel_mm=100.0, y_travel_mm=100.0)
    options = PlanOptions(mode="ink", pens_nm=(300_000,))
    found = []
    real = links.linked_moves

    def spy(table, areas, most_nm=None):
        at = real(table, areas, most_nm)
        found.append((table[at - 1][:, [X, Y]], table[at][:, [X, Y]], areas))
        return at
    monkeypatch.setattr(links, "linked_moves", spy)
    monkeypatch.setattr("galileo_cnc.plan.ink.walk_order.linked_moves", spy)
    planned = plan_file(path, config, "auto", options=options)
    lifts = sum(isinstance(c, PenDown) for c in planned.job.commands)
    (ends, starts, areas), = [f for f in found if len(f[0])]
    area = areas[1]
    assert len(clip.components(area)) == 3
    for a, b in zip(ends.tolist(), starts.tolist()):
        # inside one component of the area: no part outside it
        assert not clip.open_difference([np.array([a, b])], area)
    monkeypatch.setattr(links, "LINK_MOST_NM", -1)
    unlinked = plan_file(path, config, "auto", options=options)
    assert lifts < sum(isinstance(c, PenDown) for c in unlinked.job.commands)
