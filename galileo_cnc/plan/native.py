"""The compiled parts of the planner, where setup.py could build them: path order's
local search (plan/order/tour_search.c) and the ink's grid index of edges, its cells and
its nearest-edge search (plan/ink/edge_index.c).

`tour_search()`, `cell_keys()` and `nearest_edges()` give a function that runs the
work compiled, or None where the extension is missing (no C compiler at install time),
cannot be loaded, or GALILEO_NATIVE=0 asks for the Python (the tests compare the two).
The extensions are plain C loaded with ctypes: they hold no Python objects, so they
cannot leak or crash on a reference, and the answer is the same either way.
"""

from __future__ import annotations

import ctypes
import importlib.util
import os
from functools import lru_cache
from typing import Callable

import numpy as np

_DOUBLES = ctypes.POINTER(ctypes.c_double)
_INTS = ctypes.POINTER(ctypes.c_int64)
_INT = ctypes.c_int64
_TOUR, _EDGES = "galileo_cnc.plan.order._tour_search", "galileo_cnc.plan.ink._edge_index"
#: per extension module: its functions, what each returns and its arguments' types
_FUNCTIONS = {
    _TOUR: {"tour_search": (_INT, [_INT, _DOUBLES, _DOUBLES, _DOUBLES, _INTS, _INTS, _DOUBLES,
                                   _INTS, _INTS, _DOUBLES, _INT, _INT, _INTS])},
    _EDGES: {"nearest_edges": (None, [_INT, _INTS, _INT, _INT, _INT, _INTS, _INTS, _INTS,
                                      _INTS, _INTS, _INTS, _DOUBLES, _DOUBLES]),
             "cell_samples": (_INT, [_INT, _INTS, _INTS, _INT]),
             "cell_keys": (_INT, [_INT, _INTS, _INTS, _INT, _INTS, _INTS])},
}


@lru_cache(maxsize=None)
def _library(module: str) -> ctypes.CDLL | None:
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.origin:
        return None
    try:
        library = ctypes.CDLL(spec.origin)
    except OSError:
        return None
    for name, (returns, arguments) in _FUNCTIONS[module].items():
        function = getattr(library, name)
        function.restype, function.argtypes = returns, arguments
    return library


def _wanted(module: str) -> ctypes.CDLL | None:
    """The module's library, unless GALILEO_NATIVE=0 asks for the Python."""
    if os.environ.get("GALILEO_NATIVE", "1") == "0":
        return None
    return _library(module)


def tour_search() -> Callable | None:
    """search(tour, moves, perturbations, kicks) for plan/order/tour.py's Tour (its tour and
    pos are changed in place, its travel lengths refreshed; `kicks`: Tour.kicks);
    None where only the Python search is at hand."""
    library = _wanted(_TOUR)
    return _search_with(library) if library is not None else None


def nearest_edges() -> Callable | None:
    """nearest(index, points, search_nm) -> (edge, t, distance) for a
    plan/ink/edges.py EdgeIndex with edges, as its nearest_many; None where only numpy's
    search is at hand."""
    library = _wanted(_EDGES)
    return _nearest_with(library) if library is not None else None


def cell_keys() -> Callable | None:
    """cells(a, b, cell_nm) -> (keys, owners) as plan/ink/edges.py's cell_keys; None
    where only numpy's is at hand."""
    library = _wanted(_EDGES)
    return _cells_with(library) if library is not None else None


def _search_with(library: ctypes.CDLL) -> Callable:
    def search(tour, moves: int, perturbations: int, kicks: list) -> None:
        m = tour.m
        xs = np.ascontiguousarray(tour.xs, dtype=np.float64)
        ys = np.ascontiguousarray(tour.ys, dtype=np.float64)
        tail = np.ascontiguousarray(tour.tail, dtype=np.float64)
        counts = np.array([len(c) for c in tour.cand], dtype=np.int64)
        cand_at = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        cand = np.array([v for c in tour.cand for v in c], dtype=np.int64)
        cand_d = np.array([d for c in tour.cand_d for d in c], dtype=np.float64)
        travel = np.array(tour.travel, dtype=np.float64)
        draws = np.array(kicks, dtype=np.int64).reshape(-1)
        # tour.tour_np and tour.pos_np are views of the Tour's own arrays
        found = library.tour_search(
            m, _p(xs, _DOUBLES), _p(ys, _DOUBLES), _p(tail, _DOUBLES),
            _p(cand_at, _INTS), _p(cand, _INTS), _p(cand_d, _DOUBLES),
            _p(tour.tour_np, _INTS), _p(tour.pos_np, _INTS), _p(travel, _DOUBLES),
            moves, perturbations, _p(draws, _INTS))
        if found < 0:
            raise MemoryError("path order: out of memory in the compiled search")
        tour.travel = travel.tolist()
    return search


def _nearest_with(library: ctypes.CDLL) -> Callable:
    def nearest(index, points: np.ndarray, search_nm: int):
        count = len(points)
        points = np.ascontiguousarray(points, dtype=np.int64)
        keys = np.ascontiguousarray(index._keys, dtype=np.int64)
        members = np.ascontiguousarray(index._members, dtype=np.int64)
        a = np.ascontiguousarray(index.a, dtype=np.int64)
        b = np.ascontiguousarray(index.b, dtype=np.int64)
        grid = np.ascontiguousarray([*index._cells_lo, *index._cells_hi], dtype=np.int64)
        edge = np.empty(count, dtype=np.int64)
        t = np.empty(count, dtype=np.float64)
        distance = np.empty(count, dtype=np.float64)
        library.nearest_edges(count, _p(points, _INTS), int(search_nm), index.cell, len(keys),
                              _p(keys, _INTS), _p(members, _INTS), _p(a, _INTS), _p(b, _INTS),
                              _p(grid, _INTS), _p(edge, _INTS), _p(t, _DOUBLES),
                              _p(distance, _DOUBLES))
        return edge, t, distance
    return nearest


def _cells_with(library: ctypes.CDLL) -> Callable:
    def cells(a: np.ndarray, b: np.ndarray, cell: int) -> tuple[np.ndarray, np.ndarray]:
        a = np.ascontiguousarray(a, dtype=np.int64)
        b = np.ascontiguousarray(b, dtype=np.int64)
        room = library.cell_samples(len(a), _p(a, _INTS), _p(b, _INTS), cell)
        keys, owners = np.empty(room, dtype=np.int64), np.empty(room, dtype=np.int64)
        count = library.cell_keys(len(a), _p(a, _INTS), _p(b, _INTS), cell, _p(keys, _INTS),
                                  _p(owners, _INTS))
        if count < 0:
            raise MemoryError("the ink's edge index: out of memory in the compiled cells")
        return keys[:count].copy(), owners[:count].copy()
    return cells


def _p(array: np.ndarray, kind):
    return array.ctypes.data_as(kind)
