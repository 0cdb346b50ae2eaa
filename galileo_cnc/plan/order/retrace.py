"""Retracing: drawing a short stretch of a pen's own ink again instead of lifting.

A connected set of paths with 2k nodes of odd degree takes max(1, k) strokes
(chains.py). Drawing a path between two odd nodes a second time (pen down, over
ink the pen lays anyway) makes both even: one stroke fewer. The pen covers no new
point, so the ink is exactly the same; what changes is time. On the reference
machine a stroke costs a lift and a lowering (2 x 300 steps at 5 mm/s with their
ramps, about 0.85 s) plus the travel to the next stroke, about what drawing 5 mm
(LIFT_NM) takes; every segment drawn again costs its length and a stop and start
(about 80 ms: SEGMENT_NM of drawing). So a pair of odd nodes is joined when the
cheapest path between them along the pen's paths costs under LIFT_NM: the
repeats that repeats.py leaves out are the other side of the same rule.

Pairs are taken cheapest first (a greedy matching, each node at most once), and
only while their connected set still has more than two odd nodes (two odd nodes
make one stroke already).
"""

from __future__ import annotations

import heapq
import math

from galileo_cnc.plan.order.pieces import Piece
from galileo_cnc.plan.order.repeats import LIFT_NM, segment_length_nm
from galileo_cnc.program.ops import X, Y

#: what one segment drawn again costs beyond its length: a stop and a start of the
#: machine (about 80 ms at 5 mm/s, 0.4 mm of drawing)
SEGMENT_NM = 400_000


def retrace_cost(piece: Piece) -> float:
    """What drawing `piece` again costs, in nm of drawing (float: only to choose)."""
    total, here = 0.0, piece.start
    for _index, row in piece.rows[1:]:
        total += segment_length_nm(here, row)
        here = (row[X], row[Y])
    return total + SEGMENT_NM * (len(piece.rows) - 1)


def retraced_edges(edges: list[tuple[int, int]], cost_of, nodes: int,
                   limit: float = LIFT_NM) -> list[int]:
    """Edges to draw a second time (an edge may come more than once): for each chosen
    pair of odd nodes, the edges of the cheapest path between them, costing under
    `limit` in all; `cost_of(e)` is what drawing edge e again costs (asked only when
    some set of paths has more than two odd nodes)."""
    degree = [0] * nodes
    adjacency: list[list[int]] = [[] for _ in range(nodes)]
    for e, (a, b) in enumerate(edges):
        degree[a] += 1
        degree[b] += 1
        if a != b:
            adjacency[a].append(e)
            adjacency[b].append(e)
    odd = [v for v in range(nodes) if degree[v] % 2]
    if len(odd) < 4:
        return []
    component = _components(edges, nodes)
    odd_left: dict[int, int] = {}
    for v in odd:
        odd_left[component[v]] = odd_left.get(component[v], 0) + 1
    is_odd = [False] * nodes
    for v in odd:
        is_odd[v] = odd_left[component[v]] > 2
    if not any(is_odd):
        return []
    costs: dict[int, float] = {}
    candidates = []
    for source in odd:
        if is_odd[source]:
            for cost, target, path in _cheap_paths(source, edges, costs, cost_of,
                                                   adjacency, is_odd, limit):
                if source < target:
                    candidates.append((cost, source, target, path))
    candidates.sort(key=lambda c: (c[0], c[1], c[2]))
    matched = [False] * nodes
    again: list[int] = []
    for _cost, a, b, path in candidates:
        if matched[a] or matched[b] or odd_left[component[a]] <= 2:
            continue
        matched[a] = matched[b] = True
        odd_left[component[a]] -= 2
        again.extend(path)
    return again


def _cheap_paths(source: int, edges, costs, edge_cost, adjacency, is_odd, limit):
    """(cost, odd node, edges on the way) of the odd nodes reachable from `source`
    for less than `limit` (Dijkstra, stopped at the limit)."""
    best = {source: 0.0}
    via: dict[int, int] = {}
    heap = [(0.0, source)]
    found = []
    while heap:
        cost, v = heapq.heappop(heap)
        if cost > best.get(v, math.inf):
            continue
        if v != source and is_odd[v]:
            path, w = [], v
            while w != source:
                e = via[w]
                path.append(e)
                a, b = edges[e]
                w = a if b == w else b
            found.append((cost, v, path))
        for e in adjacency[v]:
            a, b = edges[e]
            w = b if a == v else a
            if e not in costs:
                costs[e] = edge_cost(e)
            reach = cost + costs[e]
            if reach < limit and reach < best.get(w, math.inf):
                best[w] = reach
                via[w] = e
                heapq.heappush(heap, (reach, w))
    return found


def _components(edges: list[tuple[int, int]], nodes: int) -> list[int]:
    parent = list(range(nodes))

    def find(v: int) -> int:
        while parent[v] != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v

    for a, b in edges:
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[ra] = rb
    return [find(v) for v in range(nodes)]
