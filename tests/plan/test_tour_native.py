"""The compiled local search of path order (plan/order/tour_search.c through plan/native.py)
gives the tour the Python search gives: the same moves in the same order, node for
node, on random instances with and without a goal, with budgets that run out, and on
real layers planned whole."""

from __future__ import annotations

import os
import random

import pytest

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan import native
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.plan.order.tour import Tour

from compiled import require
from corpus import CORPUS


@pytest.fixture(autouse=True)
def compiled():
    os.environ.pop("GALILEO_NATIVE", None)
    require(native.tour_search() is not None, "path-order search")


def chains(count: int, seed: int, spread: int = 10 ** 8) -> tuple[list[float], list[float]]:
    """A start, the free end and `count` chains' two ends (nm, as paths.order lays
    them out): random, and some ends shared, as chained paths have."""
    rng = random.Random(seed)
    xs, ys = [float(rng.randrange(spread)), 0.0], [float(rng.randrange(spread)), 0.0]
    for _ in range(count):
        x, y = rng.randrange(spread), rng.randrange(spread)
        if rng.random() < 0.2 and len(xs) > 2:        # starts where another ends
            x, y = int(xs[-1]), int(ys[-1])
        xs += [float(x), float(x + rng.randrange(-spread // 50, spread // 50))]
        ys += [float(y), float(y + rng.randrange(-spread // 50, spread // 50))]
    return xs, ys


def searched(xs, ys, tail, moves, perturbations, monkeypatch, python: bool) -> Tour:
    monkeypatch.setenv("GALILEO_NATIVE", "0" if python else "1")
    tour = Tour(xs, ys, tail)
    tour.build()
    tour.search(moves, perturbations)
    return tour


@pytest.mark.parametrize("count, seed, moves, goal", [
    (5, 1, 2_000_000, False), (12, 2, 2_000_000, False), (120, 3, 2_000_000, False),
    (400, 4, 2_000_000, True), (1500, 5, 2_000_000, False),
    (60, 6, 400, False), (200, 7, 6_000, True), (40, 8, 90, True)])
def test_compiled_search_gives_the_python_tour(count, seed, moves, goal, monkeypatch):
    xs, ys = chains(count, seed)
    rng = random.Random(seed)
    tail = [0.0, 0.0] + [float(rng.randrange(10 ** 7)) for _ in xs[2:]] if goal else None
    perturbations = min(1000, 5 * count)
    python = searched(xs, ys, tail, moves, perturbations, monkeypatch, python=True)
    compiled = searched(xs, ys, tail, moves, perturbations, monkeypatch, python=False)
    assert list(compiled.tour) == list(python.tour)
    assert list(compiled.pos) == list(python.pos)
    assert compiled.travel == python.travel
    assert compiled.walk() == python.walk()
    # and the search did something: the tour is shorter than the greedy one
    greedy = Tour(xs, ys, tail)
    greedy.build()
    if count > 12 and moves > 1000:
        assert compiled.length() < greedy.length()


@pytest.mark.parametrize("layer, mode", [
    ("eagle/pcb-tools-example/copper.GTL", "centre"),
    ("eagle/pcb-tools-example/copper.GTL", "ink"),
    ("allegro/tracespace-371/l1_primary.art", "centre")])
def test_a_layer_plans_to_the_same_job_either_way(layer, mode, monkeypatch):
    # GALILEO_NATIVE turns every compiled part off: in ink mode the nearest-edge
    # search of the fill's joins too (test_nearest_native.py)
    path = CORPUS / layer
    if not path.exists():
        pytest.skip(f"corpus layer missing: {path}")
    jobs = []
    for setting in ("0", "1"):
        monkeypatch.setenv("GALILEO_NATIVE", setting)
        job = plan_file(path, MachineConfig(x_travel_mm=2000.0, y_travel_mm=2000.0),
                        options=PlanOptions(mode=mode, pens_nm=(300_000,))).job
        jobs.append((job.commands, job.op_index, job.aperture, job.pen_changes))
    assert jobs[0] == jobs[1]
    assert len(jobs[0][0]) > 1000
