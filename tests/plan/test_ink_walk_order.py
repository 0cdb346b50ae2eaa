"""Path order worked out from the ink walks' ends (walk_order.py) gives the very job
that ordering the real rows gives: on constructed boards whose centre lines touch
walks, with one pen and two, forked and not, and on real copper layers."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from corpus import corpus_file

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan.ink import clip, inking, walk_order
from galileo_cnc.plan.ink import fill as fill_module
from galileo_cnc.plan.order.paths import touching
from galileo_cnc.plan.order.pieces import Piece, WHOLE_PATHS
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.program.ops import OpKind

MM = 1_000_000
HEADER = "%FSLAX46Y46*%\n%MOMM*%\nG75*\n"
CONFIG = dataclasses.replace(MachineConfig(), x_travel_mm=600.0, y_travel_mm=600.0)

#: pads of several shapes, a pour, and 0.2 mm traces (narrower than the 0.3 mm pen:
#: centre lines) that end on pads, so their walks touch centre lines
BOARD = """%ADD10C,1.6*%
%ADD11R,2.0X1.2*%
%ADD12C,0.2*%
%ADD13C,0.5*%
D10*
X0Y0D03*
X5000000Y0D03*
X10000000Y3000000D03*
D11*
X0Y6000000D03*
X8000000Y8000000D03*
D12*
X0Y0D02*
X5000000Y0D01*
X10000000Y3000000D01*
X8000000Y8000000D02*
X0Y6000000D01*
D13*
X15000000Y0D02*
X15000000Y8000000D01*
G36*
X20000000Y0D02*
X26000000Y0D01*
X26000000Y6000000D01*
G03X20000000Y6000000I-3000000J0D01*
X20000000Y0D01*
G37*
"""


def the_same_job(planned) -> None:
    """The job planned_file made equals ordering the ink's real rows afresh."""
    again = plan_program(planned.plotted, CONFIG, planned.offset_nm, optimize=True)
    assert planned.job.commands == again.commands
    assert planned.job.op_index == again.op_index
    assert planned.job.aperture == again.aperture
    assert planned.job.pen_changes == again.pen_changes


@pytest.mark.parametrize("pens", [(300_000,), (800_000, 300_000)])
@pytest.mark.parametrize("fork", [False, True])
def test_the_order_from_the_walks_ends_is_the_order_of_the_rows(tmp_path, monkeypatch,
                                                                  pens, fork):
    monkeypatch.setattr(inking, "BACKGROUND_VERTICES", 0 if fork else 10 ** 12)
    started = []
    real_start = inking.InkPaths.start_order

    def spy(self, start, join_nm):
        order = real_start(self, start, join_nm)
        started.append(order)
        return order
    monkeypatch.setattr(inking.InkPaths, "start_order", spy)
    path = tmp_path / "board.gbr"
    path.write_text(HEADER + BOARD + "M02*\n")
    planned = plan_file(path, CONFIG, "auto", options=PlanOptions(mode="ink", pens_nm=pens))
    (order,) = started
    short = order.skeleton.short
    assert short.any()
    if len(pens) == 1:      # walks ending where the traces do keep their rows
        assert not short.all()
    assert len(order.skeleton.program) < len(planned.plotted)
    assert planned.ink.narrow                   # the traces are centre lines
    the_same_job(planned)


def test_file_order_starts_no_path_order(tmp_path, monkeypatch):
    monkeypatch.setattr(inking.InkPaths, "start_order",
                        lambda *_args: pytest.fail("path order started for --file-order"))
    path = tmp_path / "board.gbr"
    path.write_text(HEADER + BOARD + "M02*\n")
    planned = plan_file(path, CONFIG, "auto",
                        options=PlanOptions(mode="ink", pens_nm=(300_000,), file_order=True))
    assert not planned.job.ordered
    walks = planned.plotted.metadata[WHOLE_PATHS]
    first_moves = [i for i in planned.job.op_index if i >= 0][:1]
    assert first_moves == [walks[0][0]]          # the fill's first walk comes first


@pytest.mark.parametrize("name", ["eagle/pcb-tools-example/copper.GTL",
                                  "allegro/tracespace-371/l1_primary.art"])
def test_real_layers_get_the_same_job(name):
    path = corpus_file(name)
    planned = plan_file(path, CONFIG, "auto", options=PlanOptions(mode="ink", pens_nm=(300_000,)))
    the_same_job(planned)


def test_reversed_table_is_piece_reversed():
    move, line, cw, ccw = (int(k) for k in (OpKind.MOVE, OpKind.LINE, OpKind.ARC_CW,
                                             OpKind.ARC_CCW))
    rows = [[move, 0, 0, 0, 0, 1, 0, 0, 0],
            [line, 1000, 0, 0, 0, 1, 0, 4, 2],
            [cw, 3000, 2000, 0, 2000, 1, 0, 5, 1],
            [ccw, 5000, 0, 2000, 0, 1, 0, 0, 0],
            [line, 5000, -700, 0, 0, 1, 7, 0, 0]]
    first = 40
    expected = Piece([(first + k, list(row)) for k, row in enumerate(rows)]).reversed().rows
    indices, table = walk_order.reversed_table(np.array(rows, dtype=np.int64), first)
    assert list(zip(indices.tolist(), table.tolist())) == expected


def test_touching_walks_agrees_with_path_orders_test_on_every_vertex():
    rng = np.random.default_rng(7)
    join = 6250
    walks = [rng.integers(-200_000, 200_000, size=(n, 2)) for n in (3, 40, 7, 120, 1)]
    others = rng.integers(-200_000, 200_000, size=(60, 2))
    others[0] = walks[1][17] + (join, -join)     # next to a vertex, a cell away
    others[1] = walks[3][0] + 3 * join           # three cells from its first vertex
    expected = touching([Piece([(0, [int(OpKind.MOVE), x, y, 0, 0, 0, 0, 0, 0])
                                for x, y in walk.tolist()]) for walk in walks],
                        [Piece([(0, [int(OpKind.FLASH), x, y, 0, 0, 0, 0, 0, 0])])
                         for x, y in others.tolist()], join)
    found = walk_order.touching_walks(walks, others, join)
    assert found.tolist() == expected
    assert found[1]


@pytest.mark.parametrize("pens", [(300_000,), (800_000, 300_000)])
@pytest.mark.parametrize("fork", [False, True])
def test_the_coverage_figures_are_those_of_the_ink_as_polygons(tmp_path, monkeypatch,
                                                                 pens, fork):
    # batches of the fill that no other ink meets count their recipe's area (in a
    # second process when forked), the others the polygons': the sums are the polygons'
    monkeypatch.setattr(inking, "BACKGROUND_VERTICES", 0 if fork else 10 ** 12)
    monkeypatch.setattr(fill_module, "BACKGROUND_VERTICES", 0 if fork else 10 ** 12)
    path = tmp_path / "board.gbr"
    path.write_text(HEADER + BOARD + "M02*\n")
    planned = plan_file(path, CONFIG, "auto", options=PlanOptions(mode="ink", pens_nm=pens))
    plan = planned.ink
    region = plan.copper.native
    fills_ink = [ring for f in plan.fills for ring in f.ink]
    lines = clip.stroke([p for f in plan.narrow for p in f.pieces], pens[-1] // 2,
                        inking.INK_TOLERANCE_NM)
    filled = clip.area_nm2(clip.intersection(clip.union(fills_ink), region))
    inked = clip.area_nm2(clip.intersection(clip.union(fills_ink, lines), region))
    # the recipe's area counts a gap stroke's round cap as inside the reach, where
    # it may poke out by the tolerance: a few um2 of this board's 65 mm2
    assert plan.filled_nm2 == pytest.approx(filled, rel=1e-6)
    assert plan.inked_nm2 == pytest.approx(inked, rel=1e-6)
    assert inked > filled
