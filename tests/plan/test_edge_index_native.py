"""The compiled grid index of the ink (plan/ink/edge_index.c through plan/native.py)
answers as numpy's plan/ink/edges.py does, to the bit: cell_keys gives the same
(cell, edge) pairs, and the nearest-edge search (EdgeIndex.nearest_many) the same edge
(the lowest index among equally near ones), t and distance, on random rings and points
(far ones, ones on vertices, ties) and on a pour's rings (whole layers planned either
way: test_tour_native.py, GALILEO_NATIVE=0 turns every compiled part off); and an index
of some of the rings taken out of one of all of them (EdgeIndex.rings_part, the fill's
joins) is the index those rings would get alone."""

from __future__ import annotations

import os

import numpy as np
import pytest

from galileo_cnc.plan import native
from galileo_cnc.plan.ink import fill
from galileo_cnc.plan.ink.edges import EdgeIndex, cell_keys

from compiled import require


@pytest.fixture(autouse=True)
def compiled():
    os.environ.pop("GALILEO_NATIVE", None)
    require(native.nearest_edges() is not None and native.cell_keys() is not None,
            "edge index")


def both(index: EdgeIndex, points: np.ndarray, search: int, monkeypatch):
    answers = []
    for setting in ("0", "1"):
        monkeypatch.setenv("GALILEO_NATIVE", setting)
        answers.append(index.nearest_many(points, search))
    return answers


def random_rings(rng: np.random.Generator) -> list[np.ndarray]:
    rings = [rng.integers(-10 ** 6, 10 ** 6, (int(rng.integers(3, 40)), 2))
             for _ in range(int(rng.integers(1, 30)))]
    # an axis-parallel square and its copy moved: points between them are equally near
    square = np.array([[0, 0], [4000, 0], [4000, 4000], [0, 4000]])
    rings += [square, square + [8000, 0]]
    rings[0][1] = rings[0][0]                          # an edge of no length
    return rings


@pytest.mark.parametrize("seed", range(8))
def test_compiled_cells_equal_numpys(seed, monkeypatch):
    rng = np.random.default_rng(50 + seed)
    count = int(rng.integers(1, 400))
    a = rng.integers(-10 ** 8, 10 ** 8, (count, 2))
    b = a + rng.integers(-10 ** 6, 10 ** 6, (count, 2))
    b[: count // 4] = a[: count // 4]                        # segments of no length
    cell = int(rng.integers(1, 2 * 10 ** 6))
    answers = []
    for setting in ("0", "1"):
        monkeypatch.setenv("GALILEO_NATIVE", setting)
        answers.append(cell_keys(a, b, cell))
    (keys_np, owners_np), (keys_c, owners_c) = answers
    assert np.array_equal(keys_c, keys_np) and np.array_equal(owners_c, owners_np)
    # sorted by cell, then segment, each pair once, every segment in a cell
    pairs = np.stack([keys_c, owners_c], axis=1)
    assert (np.lexsort((owners_c, keys_c)) == np.arange(len(keys_c))).all()
    assert len(np.unique(pairs, axis=0)) == len(pairs)
    assert set(owners_c.tolist()) == set(range(count))


@pytest.mark.parametrize("seed", range(12))
def test_compiled_nearest_edges_equal_numpys(seed, monkeypatch):
    rng = np.random.default_rng(seed)
    rings = random_rings(rng)
    index = EdgeIndex(rings, int(rng.integers(500, 300_000)))
    points = np.concatenate([
        rng.integers(-3 * 10 ** 6, 3 * 10 ** 6, (200, 2)),       # inside and around
        rng.integers(-10 ** 10, 10 ** 10, (20, 2)),              # far outside the grid
        np.concatenate(rings)[:30],                              # on vertices
        [[6000, 2000], [6000, 1000], [2000, 2000]]])             # ties, inside a ring
    search = int(rng.integers(1, 10 ** 6))
    (edge_np, t_np, d_np), (edge_c, t_c, d_c) = both(index, points, search, monkeypatch)
    assert np.array_equal(edge_c, edge_np)
    assert np.array_equal(t_c, t_np)
    assert np.array_equal(d_c, d_np)
    # and the answers are the nearest edges: no edge is nearer than the one found
    a, b = index.a.astype(np.float64), index.b.astype(np.float64)
    for (x, y), k, d in zip(points.tolist(), edge_c.tolist(), d_c.tolist()):
        gap = b - a
        t = np.clip(((x - a[:, 0]) * gap[:, 0] + (y - a[:, 1]) * gap[:, 1])
                    / np.maximum((gap ** 2).sum(axis=1), 1), 0, 1)
        every = np.hypot(a[:, 0] + gap[:, 0] * t - x, a[:, 1] + gap[:, 1] * t - y)
        assert d == pytest.approx(every.min(), abs=1e-6)
        assert every[k] == pytest.approx(d, abs=1e-6)


def test_the_tie_goes_to_the_lowest_edge(monkeypatch):
    square = np.array([[0, 0], [4000, 0], [4000, 4000], [0, 4000]])
    index = EdgeIndex([square, square + [8000, 0]], 1000)
    (edge_np, _t, _d), (edge_c, _t2, d_c) = both(index, np.array([[6000, 2000]]), 1000,
                                                 monkeypatch)
    # 2000 nm from edge 1 (the first square's right side) and edge 7 (the second's left)
    assert edge_c.tolist() == edge_np.tolist() == [1]
    assert d_c.tolist() == [2000.0]


@pytest.mark.parametrize("seed", range(4))
def test_a_part_of_an_index_is_the_index_of_its_rings(seed):
    rng = np.random.default_rng(100 + seed)
    rings = random_rings(rng)
    index = EdgeIndex(rings, int(rng.integers(500, 300_000)))
    first = int(rng.integers(0, len(rings)))
    end = int(rng.integers(first + 1, len(rings) + 1))
    part, alone = index.rings_part(first, end), EdgeIndex(rings[first:end], index.cell)
    for name in ("a", "b", "ring", "edge", "_keys", "_members", "_cells_lo", "_cells_hi"):
        assert np.array_equal(getattr(part, name), getattr(alone, name)), name
    assert len(index.rings_part(end, end)) == 0


def test_the_joins_of_a_pour_are_the_same_either_way(monkeypatch):
    # a pour with holes: rings at several depths, joined depth to depth
    mm = 1_000_000
    pour = [[[0, 0], [30 * mm, 0], [30 * mm, 20 * mm], [0, 20 * mm]]] + [
        [[x, y], [x, y + 2 * mm], [x + 3 * mm, y + 2 * mm], [x + 3 * mm, y]]
        for x in range(2 * mm, 28 * mm, 6 * mm) for y in (3 * mm, 12 * mm)]
    areas = [pour]
    while areas[-1]:
        areas.append(fill.clip.offset(areas[-1], -240_000, 16_000))
    depths = [fill.clip.rings_as_arrays(area) for area in areas[:-1]]
    joins = []
    for setting in ("0", "1"):
        monkeypatch.setenv("GALILEO_NATIVE", setting)
        every = EdgeIndex([ring for at_depth in depths for ring in at_depth], 240_000)
        joins.append(fill._ring_joins(depths, 240_000, every))
    assert joins[0] == joins[1]
    assert len(joins[0]) >= len(depths) - 1 > 10
