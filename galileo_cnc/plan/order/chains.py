"""Chaining: pen paths whose ends meet joined into as few strokes as the ends allow.

An Euler problem. A path is first cut at each inner vertex that meets (within
`join_nm`, one step) a vertex of another path, or of itself further on (only between
rows: the second part gets a MOVE to that vertex, every segment stays as it was).
Path ends within `join_nm` of each other are one node (joined closest pair first,
never into a node with two ends more than `join_nm` apart, so any two ends of a node
may join); each path is an edge between the nodes of its ends. A connected set of
paths with 2k nodes of odd degree cannot be drawn in fewer than max(1, k) strokes,
and Hierholzer's walk (with a virtual node tied to every odd node) draws it in
exactly that many: at a junction every arriving path leaves by another, not only the
first one found. Where a set has more than two odd nodes, a short stretch between
two of them may be drawn twice instead (retrace.py): one stroke fewer, the same
ink. A joined path starts from the previous end (the gap is under `join_nm`); an arc
keeps its own ends, after a line across the gap. A trail is drawn the way its first
piece in the file is drawn.
"""

from __future__ import annotations

from galileo_cnc.plan.order.nearby import near_pairs
from galileo_cnc.plan.order.pieces import CCW, CW, LINE, MOVE, Piece, Point, with_kind
from galileo_cnc.plan.order.retrace import retrace_cost, retraced_edges
from galileo_cnc.program.ops import KIND, X, Y

def chain(pieces: list[Piece], join_nm: int, retrace: bool = True) -> list[Piece]:
    """Join paths whose ends meet within `join_nm` into as few chains as the ends
    allow (Euler trails), with `retrace` drawing short stretches twice where that
    saves a stroke (retrace.py); flashes stay alone. Chains come in the order
    of their first piece."""
    pieces = _split_at_junctions(pieces, join_nm)
    path_ids = [k for k, p in enumerate(pieces) if p.is_path]
    points = []
    for k in path_ids:
        rows = pieces[k].rows
        points.append((rows[0][1][X], rows[0][1][Y]))
        points.append((rows[-1][1][X], rows[-1][1][Y]))
    node = _cluster(points, join_nm)
    edges = [(node[2 * t], node[2 * t + 1]) for t in range(len(path_ids))]
    nodes = max(node, default=-1) + 1
    if retrace:
        for e in retraced_edges(edges, lambda e: retrace_cost(pieces[path_ids[e]]), nodes):
            edges.append(edges[e])
            path_ids.append(path_ids[e])
    trails = _euler_trails(edges, nodes)
    made: list[tuple[int, Piece]] = [(k, p) for k, p in enumerate(pieces) if not p.is_path]
    for trail in trails:
        if len(trail) == 1:                          # drawn as it is
            made.append((path_ids[trail[0][0]], pieces[path_ids[trail[0][0]]]))
            continue
        # the file's first piece of the trail drawn its own way round (and first, if
        # the trail is closed)
        low = min(range(len(trail)), key=lambda k: trail[k][0])
        if trail[low][1]:
            trail = [(t, not back) for t, back in reversed(trail)]
            low = len(trail) - 1 - low
        first, last = trail[0], trail[-1]
        if edges[first[0]][first[1]] == edges[last[0]][not last[1]]:
            trail = trail[low:] + trail[:low]
        parts = [pieces[path_ids[t]].reversed() if back else pieces[path_ids[t]]
                 for t, back in trail]
        made.append((min(path_ids[t] for t, _back in trail), join_all(parts)))
    made.sort(key=lambda item: item[0])
    return [p for _k, p in made]


def _split_at_junctions(pieces: list[Piece], join_nm: int) -> list[Piece]:
    """Paths cut at each inner vertex that meets (within `join_nm`) a vertex of
    another path, or of the same path after it went away: a path ending on another's
    corner, or two loops sharing one, can then be drawn as one stroke. Only row
    boundaries are cut (the second part gets a MOVE to the corner), so every segment
    stays exactly as it was."""
    points: list[Point] = []
    owner: list[tuple[int, int]] = []                 # (piece, row) of each vertex
    for k, piece in enumerate(pieces):
        if not piece.is_path:
            continue
        for r, (_index, row) in enumerate(piece.rows):
            points.append((row[X], row[Y]))
            owner.append((k, r))
    if len(points) == 2 * sum(p.is_path for p in pieces):
        return pieces                                  # no inner vertices at all
    unique, where = _distinct(points)
    # only a point with a second vertex on it or near it can be a junction: the
    # lists are kept for those alone (most points of a sparse drawing have none)
    at: dict[int, list[int]] = {}                      # vertices at each point
    for o, u in enumerate(where):
        at.setdefault(u, []).append(o)
    close: dict[int, list[int]] = {u: [u] for u, there in at.items() if len(there) > 1}
    for _d2, a, b in near_pairs(unique, join_nm):
        close.setdefault(a, [a]).append(b)
        close.setdefault(b, [b]).append(a)
    limit = join_nm * join_nm

    def away(k: int, r: int, r2: int) -> bool:
        """Whether path k goes farther than join_nm from vertex r between r and r2."""
        rows = pieces[k].rows
        x, y = rows[r][1][X], rows[r][1][Y]
        lo, hi = min(r, r2), max(r, r2)
        return any((rows[q][1][X] - x) ** 2 + (rows[q][1][Y] - y) ** 2 > limit
                   for q in range(lo + 1, hi))

    cuts: dict[int, list[int]] = {}
    for o, (k, r) in enumerate(owner):
        if r == 0 or r == len(pieces[k].rows) - 1:
            continue
        meets = False
        for v in close.get(where[o], ()):
            for o2 in at[v]:
                k2, r2 = owner[o2]
                if k2 != k or (r2 != r and away(k, r, r2)):
                    meets = True
                    break
            if meets:
                break
        if meets:
            kept = cuts.setdefault(k, [])
            row, last = pieces[k].rows[r][1], None
            if kept:
                last = pieces[k].rows[kept[-1]][1]
            if last is None or (row[X] - last[X]) ** 2 + (row[Y] - last[Y]) ** 2 > limit:
                kept.append(r)
    if not cuts:
        return pieces
    out: list[Piece] = []
    for k, piece in enumerate(pieces):
        if k not in cuts:
            out.append(piece)
            continue
        rows, begin = piece.rows, 0
        for r in cuts[k] + [len(rows) - 1]:
            part = rows[begin:r + 1]
            if begin:
                part[0] = with_kind(rows[begin + 1], MOVE, (rows[begin][1][X], rows[begin][1][Y]))
            out.append(Piece(part))
            begin = r
    return out


def _distinct(points: list[Point]) -> tuple[list[Point], list[int]]:
    """The distinct points, and each point's index among them."""
    index: dict[Point, int] = {}
    unique: list[Point] = []
    where = []
    for p in points:
        u = index.get(p)
        if u is None:
            u = index[p] = len(unique)
            unique.append(p)
        where.append(u)
    return unique, where


def _cluster(points: list[Point], join_nm: int) -> list[int]:
    """Node of each point: points joined closest pair first into groups whose every
    two points are within `join_nm` (any two ends of a node may join)."""
    limit = join_nm * join_nm
    unique, where = _distinct(points)
    group = list(range(len(unique)))
    members: dict[int, list[int]] = {}
    apart: set[tuple[int, int]] = set()     # groups with two points too far apart
    for _d2, a, b in near_pairs(unique, join_nm):
        ga, gb = group[a], group[b]
        if ga == gb or (min(ga, gb), max(ga, gb)) in apart:
            continue
        ma, mb = members.get(ga, [ga]), members.get(gb, [gb])
        if not all((unique[u][0] - unique[w][0]) ** 2
                   + (unique[u][1] - unique[w][1]) ** 2 <= limit for u in ma for w in mb):
            apart.add((min(ga, gb), max(ga, gb)))  # groups only grow: stays so
        else:
            if len(ma) < len(mb) or (len(ma) == len(mb) and ga > gb):
                ga, gb, ma, mb = gb, ga, mb, ma
            for w in mb:
                group[w] = ga
            members[ga] = ma + mb
            members.pop(gb, None)
    label: dict[int, int] = {}
    for g in group:
        label.setdefault(g, len(label))
    return [label[group[u]] for u in where]


def _euler_trails(edges: list[tuple[int, int]], nodes: int) -> list[list[tuple[int, bool]]]:
    """The fewest trails covering every edge once: lists of (edge, drawn from its
    second node to its first)."""
    virtual = nodes
    odd = [v for v, d in enumerate(_degrees(edges, nodes)) if d % 2]
    ends = list(edges) + [(virtual, v) for v in odd]
    adjacency: list[list[int]] = [[] for _ in range(nodes + 1)]
    for e, (a, b) in enumerate(ends):
        adjacency[a].append(e)
        if b != a:
            adjacency[b].append(e)
    used = [False] * len(ends)
    pointer = [0] * (nodes + 1)
    trails: list[list[tuple[int, bool]]] = []

    def walk(first: int) -> None:
        stack: list[tuple[int, int, bool]] = [(first, -1, False)]
        trail: list[tuple[int, bool]] = []
        while stack:
            v = stack[-1][0]
            incident, k = adjacency[v], pointer[v]
            while k < len(incident) and used[incident[k]]:
                k += 1
            pointer[v] = k
            if k == len(incident):
                _v, e, forward = stack.pop()
                if e < 0:
                    continue
                if e >= len(edges):                 # a virtual edge ends a trail
                    if trail:
                        trails.append(trail)
                    trail = []
                else:
                    trail.append((e, forward))      # popped: walked against the push
            else:
                e = incident[k]
                used[e] = True
                a, b = ends[e]
                stack.append((b, e, True) if a == v else (a, e, False))
        if trail:
            trails.append(trail)

    if odd:
        walk(virtual)
    for e, (a, _b) in enumerate(edges):
        if not used[e]:
            walk(a)
    return trails


def _degrees(edges: list[tuple[int, int]], nodes: int) -> list[int]:
    degree = [0] * nodes
    for a, b in edges:
        degree[a] += 1
        degree[b] += 1
    return degree


def join_all(parts: list[Piece]) -> Piece:
    """The parts drawn one after another without a lift: each part's rows without its
    MOVE. A part that starts off the previous end (under a step) starts with a line
    across the gap when it begins with an arc: moved to the previous end, an arc
    whose ends are that close (LimeSDR's 0.4 um arcs) would start where it ends, a
    whole circle, and a whole circle would start off its end, a sliver."""
    rows = list(parts[0].rows)
    for then in parts[1:]:
        end = rows[-1][1]
        if then.rows[1][1][KIND] in (CW, CCW) and then.start != (end[X], end[Y]):
            rows.append(with_kind(then.rows[1], LINE, then.start))
        rows.extend(then.rows[1:])
    return Piece(rows)


def _join(first: Piece, then: Piece) -> Piece:
    """`then` drawn on from `first`'s end without its MOVE; an arc keeps its centre."""
    return join_all([first, then])
