"""The compiled part of path order, where setup.py could build it (plan/tour_search.c).

`tour_search()` gives a function that runs Tour.search's local search compiled, or
None where the extension is missing (no C compiler at install time), cannot be loaded,
or GALILEO_NATIVE=0 asks for the Python search (the tests compare the two). The
extension is plain C loaded with ctypes: it holds no Python objects, so it cannot
leak or crash on a reference, and the answer is the same either way.
"""

from __future__ import annotations

import ctypes
import importlib.util
import os
from functools import lru_cache
from typing import Callable

import numpy as np

_MODULE = "galileo_cnc.plan._tour_search"
_DOUBLES = ctypes.POINTER(ctypes.c_double)
_INTS = ctypes.POINTER(ctypes.c_int64)


@lru_cache(maxsize=1)
def _library() -> ctypes.CDLL | None:
    try:
        spec = importlib.util.find_spec(_MODULE)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.origin:
        return None
    try:
        library = ctypes.CDLL(spec.origin)
    except OSError:
        return None
    library.tour_search.restype = ctypes.c_int64
    library.tour_search.argtypes = [ctypes.c_int64, _DOUBLES, _DOUBLES, _DOUBLES, _INTS,
                                    _INTS, _DOUBLES, _INTS, _INTS, _DOUBLES, ctypes.c_int64,
                                    ctypes.c_int64, _INTS]
    return library


def tour_search() -> Callable | None:
    """search(tour, moves, perturbations, kicks) for plan/tour.py's Tour (its tour and
    pos are changed in place, its travel lengths refreshed; `kicks`: Tour.kicks);
    None where only the Python search is at hand."""
    if os.environ.get("GALILEO_NATIVE", "1") == "0":
        return None
    library = _library()
    return _search_with(library) if library is not None else None


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


def _p(array: np.ndarray, kind):
    return array.ctypes.data_as(kind)
