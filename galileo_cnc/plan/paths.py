"""Path order: chain pen paths whose ends meet and order them to cut pen-up travel.

The seed's CAM aligned DXF entities so each started where the last one ended
(reversing where needed); this does that for every format's pieces, then orders
the chains:

1. **Pieces.** A piece is a pen path (a MOVE to its start, then LINE/ARC rows) or a
   flash (a point). Rows that draw nothing are dropped: the planner ignores them.
2. **Reversal** keeps the geometry exactly: the rows are walked backwards, each
   segment ends where it began, and an arc swaps its direction and takes its
   centre relative to its new start (same centre, integer nm).
3. **Chaining** as an Euler problem. A path is first cut at each inner vertex
   that meets (within `join_nm`, one step) a vertex of another path, or of itself
   further on (only between rows: the second part gets a MOVE to that vertex, every
   segment stays as it was). Path ends within `join_nm` of each other are one node
   (joined closest pair first, never into a node with two ends more than `join_nm`
   apart, so any two ends of a node may join); each path is an edge between the
   nodes of its ends. A connected set of paths with 2k nodes of odd degree cannot
   be drawn in fewer than max(1, k) strokes, and Hierholzer's walk (with a virtual
   node tied to every odd node) draws it in exactly that many: at a junction every
   arriving path leaves by another, not only the first one found. A joined path
   keeps its own first end point (the gap is under `join_nm`); an arc keeps its
   centre. A trail is drawn the way its first piece in the file is drawn.
4. **Ordering** as a travelling-salesman path over chain ends: the start (the
   machine's position) and each chain's two ends are nodes, a chain's ends are tied
   together (drawn one after the other, either way round), and a free end node at
   zero distance from all closes the open path into a cycle. Up to EXACT chains,
   dynamic programming finds the shortest order. Above, greedy matching over the k
   nearest ends builds a first tour (its fragments joined nearest first from the
   start), then local search with neighbour lists and don't-look bits: 2-opt
   (reversing a run of chains, each flipped; a run of one chain is that chain
   flipped in place, and the run may reach the free end: a new last chain) and
   Or-opt (moving a run of one to three chains elsewhere, either way round), then
   perturbation (two neighbouring runs of chains swapped at random, the local
   search run from the six ends touched, kept only if the tour got shorter). Every
   bound is a count of moves tried, never a time, and the perturbation draws from a
   seeded generator: the same file plans to the same job on any machine (resume
   replans and continues by command index).

Everything stays in integer nm; travel is compared as Euclidean distances in float
only to choose, never to place.
"""

from __future__ import annotations

import array
import math
import random
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind

_MOVE, _LINE = int(OpKind.MOVE), int(OpKind.LINE)
_CW, _CCW, _FLASH = int(OpKind.ARC_CW), int(OpKind.ARC_CCW), int(OpKind.FLASH)
_SEGMENTS = (_LINE, _CW, _CCW)
#: moves tried per group at most (one candidate end examined by the local search or
#: the perturbation is one): a count, not a time, so that planning the same file twice
#: gives the same job (resume replans and continues by command index)
TWO_OPT_MOVES = 2_000_000
#: chains up to which the order is searched exhaustively (the shortest there is)
EXACT = 8
#: nearest ends each end's moves look at
NEIGHBOURS = 8
#: and the nearest ends in each quadrant around an end (up to BRUTE_FORCE nodes)
QUADRANT = 2
#: nodes up to which neighbours are found exactly (above: along Z-order curves)
BRUTE_FORCE = 2000
ZORDER_WINDOW = 6
#: perturbations (two neighbouring runs of chains swapped, then local search) per
#: chain, and at most (10,000 paths then plan in about 1.3 s here); the runs are 1 to
#: KICK_PAIRS chains long
PERTURB_PER_CHAIN = 5
PERTURB_MAX = 1_500
KICK_PAIRS = 20
_SEED = 20240617                 # the perturbation's generator: the same every run
_EPS = 1e-3                      # nm: a move must gain more than this

Row = list[int]
Point = tuple[int, int]


@dataclass
class Piece:
    """Rows (op index, row) that draw without a lift: [MOVE, segments...] or [FLASH]."""

    rows: list[tuple[int, Row]] = field(default_factory=list)

    @property
    def start(self) -> Point:
        row = self.rows[0][1]
        return (row[X], row[Y])

    @property
    def end(self) -> Point:
        row = self.rows[-1][1]
        return (row[X], row[Y])

    @property
    def is_path(self) -> bool:
        """A pen path (MOVE-led), which can join others; else a flash (a point)."""
        return self.rows[0][1][KIND] == _MOVE

    def reversed(self) -> "Piece":
        """The same path drawn from its end to its start (a flash is its own reverse)."""
        if not self.is_path:
            return self
        points = [(row[X], row[Y]) for _i, row in self.rows]
        out = [_with(self.rows[-1], kind=_MOVE, to=points[-1])]
        for k in range(len(self.rows) - 1, 0, -1):
            index, row = self.rows[k]
            back = list(row)
            back[X], back[Y] = points[k - 1]
            if row[KIND] in (_CW, _CCW):
                centre = (points[k - 1][0] + row[I], points[k - 1][1] + row[J])
                back[KIND] = _CCW if row[KIND] == _CW else _CW
                back[I], back[J] = centre[0] - points[k][0], centre[1] - points[k][1]
            out.append((index, back))
        return Piece(out)


def _with(entry: tuple[int, Row], kind: int, to: Point) -> tuple[int, Row]:
    index, row = entry
    new = list(row)
    new[KIND], new[X], new[Y] = kind, to[0], to[1]
    new[I] = new[J] = 0
    return (index, new)


def cut_pieces(rows: list[tuple[int, Row]], start: Point) -> list[Piece]:
    """Pieces of rows in plotting order; a path that does not begin with a MOVE gets
    one to where the head was, so it draws what it drew in order."""
    pieces: list[Piece] = []
    current: Piece | None = None
    point = start
    for index, row in rows:
        kind = row[KIND]
        if kind == _MOVE:
            current = Piece([(index, list(row))])
            pieces.append(current)
        elif kind == _FLASH:
            pieces.append(Piece([(index, list(row))]))
            current = None
        elif kind in _SEGMENTS:
            if current is None:
                current = Piece([_with((index, row), _MOVE, point)])
                pieces.append(current)
            current.rows.append((index, list(row)))
        else:
            continue                         # markers and selects draw nothing
        point = (row[X], row[Y])
    return [p for p in pieces if len(p.rows) > 1 or p.rows[0][1][KIND] == _FLASH]


# --------------------------------------------------------------------------- chaining


def chain(pieces: list[Piece], join_nm: int) -> list[Piece]:
    """Join paths whose ends meet within `join_nm` into as few chains as the ends
    allow (Euler trails); flashes stay alone. Chains come in the order of their
    first piece."""
    pieces = _split_at_junctions(pieces, join_nm)
    path_ids = [k for k, p in enumerate(pieces) if p.is_path]
    points = []
    for k in path_ids:
        rows = pieces[k].rows
        points.append((rows[0][1][X], rows[0][1][Y]))
        points.append((rows[-1][1][X], rows[-1][1][Y]))
    node = _cluster(points, join_nm)
    edges = [(node[2 * t], node[2 * t + 1]) for t in range(len(path_ids))]
    trails = _euler_trails(edges, max(node, default=-1) + 1)
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
        made.append((min(path_ids[t] for t, _back in trail), _join_all(parts)))
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
    at: list[list[int]] = [[] for _ in unique]         # vertices at each point
    for o, u in enumerate(where):
        at[u].append(o)
    close: list[list[int]] = [[u] for u in range(len(unique))]
    for _d2, a, b in _near_pairs(unique, join_nm):
        close[a].append(b)
        close[b].append(a)
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
        for v in close[where[o]]:
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
                part[0] = _with(rows[begin + 1], _MOVE, (rows[begin][1][X], rows[begin][1][Y]))
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


def _near_pairs(unique: list[Point], join_nm: int) -> list[tuple[int, int, int]]:
    """(squared distance, a, b), a < b, of the distinct points within `join_nm`."""
    limit = join_nm * join_nm
    cell = max(join_nm, 1)
    grid: dict[tuple[int, int], list[int]] = {}
    for u in _crowded(unique, cell):
        x, y = unique[u]
        grid.setdefault((x // cell, y // cell), []).append(u)
    pairs = []
    for (cx, cy), members in grid.items():
        for dx, dy in ((0, 0), (1, -1), (1, 0), (1, 1), (0, 1)):
            others = members if dx == dy == 0 else grid.get((cx + dx, cy + dy))
            if not others:
                continue
            for a in members:
                ax, ay = unique[a]
                for b in others:
                    if dx == dy == 0 and b <= a:
                        continue
                    bx, by = unique[b]
                    d2 = (ax - bx) ** 2 + (ay - by) ** 2
                    if d2 <= limit:
                        pairs.append((d2, min(a, b), max(a, b)))
    pairs.sort()
    return pairs


def _cluster(points: list[Point], join_nm: int) -> list[int]:
    """Node of each point: points joined closest pair first into groups whose every
    two points are within `join_nm` (any two ends of a node may join)."""
    limit = join_nm * join_nm
    unique, where = _distinct(points)
    group = list(range(len(unique)))
    members: dict[int, list[int]] = {}
    apart: set[tuple[int, int]] = set()     # groups with two points too far apart
    for _d2, a, b in _near_pairs(unique, join_nm):
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


def _crowded(points: list[Point], cell: int) -> list[int]:
    """Indices of the points with another point in their grid cell or a cell next
    to it (the others cannot be within a cell's width of any point)."""
    if len(points) < 2:
        return []
    xy = np.array(points, dtype=np.int64) // cell
    xy -= xy.min(axis=0)
    height = int(xy[:, 1].max()) + 3
    if (int(xy[:, 0].max()) + 3) * height >= 1 << 62:     # keys would overflow
        return list(range(len(points)))
    key = (xy[:, 0] + 1) * height + (xy[:, 1] + 1)
    occupied, count = np.unique(key, return_counts=True)
    near = np.zeros(len(points), dtype=np.int64)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            probe = key + dx * height + dy
            at = np.minimum(np.searchsorted(occupied, probe), len(occupied) - 1)
            near += np.where(occupied[at] == probe, count[at], 0)
    return np.nonzero(near > 1)[0].tolist()


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


def _join_all(parts: list[Piece]) -> Piece:
    """The parts drawn one after another without a lift: each part's rows without its
    MOVE; an arc whose part starts off the previous end (under a step) keeps its
    centre."""
    rows = list(parts[0].rows)
    for then in parts[1:]:
        end = rows[-1][1]
        gap = (then.start[0] - end[X], then.start[1] - end[Y])
        index, row = then.rows[1]
        if row[KIND] in (_CW, _CCW) and gap != (0, 0):
            row = list(row)
            row[I], row[J] = row[I] + gap[0], row[J] + gap[1]
        rows.append((index, row))
        rows.extend(then.rows[2:])
    return Piece(rows)


def _join(first: Piece, then: Piece) -> Piece:
    """`then` drawn on from `first`'s end without its MOVE; an arc keeps its centre."""
    return _join_all([first, then])


# --------------------------------------------------------------------------- ordering


def order(chains: list[Piece], start: Point,
          moves: int = TWO_OPT_MOVES) -> tuple[list[Piece], Point]:
    """Chains in drawing order from `start` (greedy, then 2-opt, Or-opt and
    perturbation within `moves` moves tried); and where the head ends."""
    if not chains:
        return [], start
    # node 0 is the start, node 1 the free end (mates); chain c's ends are 2c+2, 2c+3
    xs = [float(start[0]), 0.0]
    ys = [float(start[1]), 0.0]
    for c in chains:
        xs += [float(c.start[0]), float(c.end[0])]
        ys += [float(c.start[1]), float(c.end[1])]
    if len(chains) <= EXACT:
        entries = _exact(xs, ys)
    else:
        tour = _Tour(xs, ys)
        tour.build()
        tries = tour.improve(deque(range(len(xs))), moves)
        perturbations = min(PERTURB_MAX, PERTURB_PER_CHAIN * len(chains))
        tour.perturb(perturbations, moves - tries)
        entries = tour.walk()
    out = []
    for v in entries:
        c = chains[(v - 2) >> 1]
        out.append(c if v % 2 == 0 else c.reversed())
    return out, (out[-1].end if out else start)


def _exact(xs: list[float], ys: list[float]) -> list[int]:
    """The shortest order for a few chains (dynamic programming over the sets of
    chains drawn and the end left at): the chain ends entered, in order."""
    n = (len(xs) - 2) // 2

    def dist(a: int, b: int) -> float:
        dx = xs[a] - xs[b]
        dy = ys[a] - ys[b]
        return math.sqrt(dx * dx + dy * dy)

    best: dict[tuple[int, int], tuple[float, tuple[int, int] | None, int]] = {}
    for c in range(n):
        for entry in (2 * c + 2, 2 * c + 3):
            best[(1 << c, entry ^ 1)] = (dist(0, entry), None, entry)
    for mask in range(1, 1 << n):
        for c in range(n):
            for leave in (2 * c + 2, 2 * c + 3):
                state = best.get((mask, leave))
                if state is None:
                    continue
                for c2 in range(n):
                    if mask >> c2 & 1:
                        continue
                    for entry in (2 * c2 + 2, 2 * c2 + 3):
                        key = (mask | 1 << c2, entry ^ 1)
                        cost = state[0] + dist(leave, entry)
                        if key not in best or cost < best[key][0]:
                            best[key] = (cost, (mask, leave), entry)
    full = (1 << n) - 1
    key: tuple[int, int] | None = min(
        ((full, leave) for c in range(n) for leave in (2 * c + 2, 2 * c + 3)),
        key=lambda k: best[k][0])
    entries = []
    while key is not None:
        _cost, before, entry = best[key]
        entries.append(entry)
        key = before
    return entries[::-1]


def _nearest(xs: np.ndarray, ys: np.ndarray, k: int,
             quadrant: int = 0) -> tuple[list[list[int]], list[list[float]]]:
    """For each point, up to k others nearest first (its mate, index ^ 1, left out),
    ties by index, with their distances; and, for up to a few thousand points, the
    `quadrant` nearest in each quadrant around it too (ends in clusters then also
    see the next cluster). Exact for a few thousand points; above, candidates from
    windows along three shifted Z-order curves (near enough for move candidates)."""
    n = len(xs)
    k = min(k, n - 2)
    if k <= 0:
        return [[] for _ in range(n)], [[] for _ in range(n)]
    keep_per_row = k
    if n <= BRUTE_FORCE:
        rows_, cols = [], []
        block = max(1, 2_000_000 // n)
        for lo in range(0, n, block):
            hi = min(n, lo + block)
            dx = xs[None, :] - xs[lo:hi, None]
            dy = ys[None, :] - ys[lo:hi, None]
            d2 = dx * dx + dy * dy
            own = np.arange(lo, hi)
            d2[own - lo, own] = np.inf
            d2[own - lo, own ^ 1] = np.inf
            kth = np.partition(d2, k - 1, axis=1)[:, k - 1]
            r, c = np.nonzero(d2 <= kth[:, None])
            rows_.append(r + lo)
            cols.append(c)
            if quadrant:
                for side in ((dx > 0) & (dy >= 0), (dx <= 0) & (dy > 0),
                             (dx < 0) & (dy <= 0), (dx >= 0) & (dy < 0)):
                    dq = np.where(side, d2, np.inf)
                    q = min(quadrant, n - 1)
                    kth = np.partition(dq, q - 1, axis=1)[:, q - 1]
                    r, c = np.nonzero((dq <= kth[:, None]) & np.isfinite(dq))
                    rows_.append(r + lo)
                    cols.append(c)
        keep_per_row = k + 4 * quadrant
        i = np.concatenate(rows_)
        j = np.concatenate(cols)
    else:
        span = max(float(xs.max() - xs.min()), float(ys.max() - ys.min()), 1.0)
        scale = float((1 << 20) - 1) / (2.0 * span)
        pairs_i, pairs_j = [], []
        for shift in (0.0, span / 3.0, 2.0 * span / 3.0):
            qx = ((xs - xs.min() + shift) * scale).astype(np.uint64)
            qy = ((ys - ys.min() + shift) * scale).astype(np.uint64)
            code = (_spread(qx) << np.uint64(1)) | _spread(qy)
            rank = np.lexsort((np.arange(n), code))
            for w in range(1, ZORDER_WINDOW + 1):
                pairs_i += [rank[:-w], rank[w:]]
                pairs_j += [rank[w:], rank[:-w]]
        i = np.concatenate(pairs_i)
        j = np.concatenate(pairs_j)
        keep = j != (i ^ 1)
        i, j = i[keep], j[keep]
    key = np.sort(i.astype(np.int64) * n + j)            # by (i, j)
    fresh = np.ones(len(key), dtype=bool)
    fresh[1:] = key[1:] != key[:-1]
    key = key[fresh]
    i, j = key // n, key % n
    dx = xs[i] - xs[j]
    dy = ys[i] - ys[j]
    d = np.sqrt(dx * dx + dy * dy)
    by = np.argsort(d, kind="stable")
    by = by[np.argsort(i[by], kind="stable")]               # by i, then d, then j
    i, j, d = i[by], j[by], d[by]
    first = np.searchsorted(i, np.arange(n))
    keep = np.arange(len(i)) - first[i] < keep_per_row
    i, j, d = i[keep], j[keep], d[keep]
    cuts = np.searchsorted(i, np.arange(n + 1)).tolist()
    j_list, d_list = j.tolist(), d.tolist()
    return ([j_list[cuts[u]:cuts[u + 1]] for u in range(n)],
            [d_list[cuts[u]:cuts[u + 1]] for u in range(n)])


def _spread(v: np.ndarray) -> np.ndarray:
    """Bits of v (under 2^21) spread to the even bit positions (a Z-order half)."""
    v = v & np.uint64(0x1FFFFF)
    v = (v | (v << np.uint64(16))) & np.uint64(0x0000FFFF0000FFFF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x00FF00FF00FF00FF)
    v = (v | (v << np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    v = (v | (v << np.uint64(2))) & np.uint64(0x3333333333333333)
    v = (v | (v << np.uint64(1))) & np.uint64(0x5555555555555555)
    return v


class _Tour:
    """A cycle over the nodes as a position array: mates (node ^ 1) always next to
    each other, the edges between pairs are the pen-up travel. Node 1, the free end,
    is at zero distance from every node, so the open path from the start (node 0)
    away from node 1 is the drawing order."""

    def __init__(self, xs: list[float], ys: list[float]) -> None:
        self.xs, self.ys = xs, ys
        self.m = len(xs)
        self.tour = array.array("q")
        self.pos = array.array("q")
        self.log: list[tuple[int, int]] | None = None
        self.queued = [False] * self.m
        self.touched: list[int] | None = None
        self.travel = [0.0] * self.m             # each node's travel edge length
        # node 1 is not a point: give the neighbour search node 0's place twice
        ax = np.array(xs)
        ay = np.array(ys)
        ax[1], ay[1] = ax[0], ay[0]
        near, gaps = _nearest(ax, ay, NEIGHBOURS, QUADRANT)
        self.near = near
        # every end may become the last one (node 1, at no distance); the start never
        # (its mate)
        self.cand, self.cand_d = [], []
        for u in range(self.m):
            pairs = [(g, v) for v, g in zip(near[u], gaps[u]) if v != 1]
            self.cand.append(([1] if u else []) + [v for _g, v in pairs])
            self.cand_d.append(([0.0] if u else []) + [g for g, _v in pairs])

    # ------------------------------------------------------------------ geometry

    def dist(self, a: int, b: int) -> float:
        if a == 1 or b == 1:
            return 0.0
        dx = self.xs[a] - self.xs[b]
        dy = self.ys[a] - self.ys[b]
        return math.sqrt(dx * dx + dy * dy)

    def length(self) -> float:
        return sum(self.dist(a, b) for a, b in self.travel_edges())

    def travel_edges(self):
        tour, m = self.tour, self.m
        for p in range(m):
            a, b = tour[p], tour[(p + 1) % m]
            if a ^ 1 != b:
                yield a, b

    # ------------------------------------------------------------------ first tour

    def build(self) -> None:
        """Greedy matching of ends over the neighbour lists (shortest first, no
        cycle), then the fragments joined nearest first from the start."""
        m, xs, ys = self.m, self.xs, self.ys
        a_list, b_list = [], []
        for u in range(m):
            if u == 1:
                continue
            for v in self.near[u]:
                if u < v and v != 1:
                    a_list.append(u)
                    b_list.append(v)
        partner = [-1] * m
        if a_list:
            a = np.array(a_list)
            b = np.array(b_list)
            ax, ay = np.array(xs), np.array(ys)
            d2 = (ax[a] - ax[b]) ** 2 + (ay[a] - ay[b]) ** 2
            by = np.lexsort((b, a, d2))
            parent = list(range(m // 2))

            def find(p: int) -> int:
                while parent[p] != p:
                    parent[p] = parent[parent[p]]
                    p = parent[p]
                return p

            for u, v in zip(a[by].tolist(), b[by].tolist()):
                if partner[u] >= 0 or partner[v] >= 0:
                    continue
                ru, rv = find(u >> 1), find(v >> 1)
                if ru == rv:
                    continue
                parent[ru] = rv
                partner[u], partner[v] = v, u
        # the other free end of each fragment
        other = [-1] * m
        for u in range(2, m):
            if partner[u] < 0 and other[u] < 0:
                v = u ^ 1
                while partner[v] >= 0:
                    v = partner[v] ^ 1
                other[u], other[v] = v, u
        # walk the start's fragment, then jump to the nearest free end
        here = 0
        while partner[here] >= 0:
            here = partner[here] ^ 1
        free = [u for u in range(2, m) if partner[u] < 0 and u != here]
        finder = _EndFinder(xs, ys, free)
        while len(finder):
            nxt = finder.nearest(xs[here], ys[here])
            finder.remove(nxt)
            finder.remove(other[nxt])
            partner[here], partner[nxt] = nxt, here
            here = other[nxt]
        partner[here], partner[1] = 1, here
        tour = [0]
        v = 0
        while v != 1:
            v = partner[v]
            tour.append(v)
            if v != 1:
                v ^= 1
                tour.append(v)
        self._set(tour)

    def _set(self, tour: list[int]) -> None:
        """Positions in array.array (read fast one by one) with numpy views (written
        fast in bulk by long reversals)."""
        self.tour = array.array("q", tour)
        self.pos = array.array("q", bytes(8 * self.m))
        self.tour_np = np.frombuffer(self.tour, dtype=np.int64)
        self.pos_np = np.frombuffer(self.pos, dtype=np.int64)
        self.pos_np[self.tour_np] = np.arange(self.m)
        self._refresh(range(self.m))

    def walk(self) -> list[int]:
        """The chain ends entered, in drawing order."""
        tour, pos, m = self.tour, self.pos, self.m
        p = pos[0]
        step = 1 if tour[(p - 1) % m] == 1 else -1
        out = []
        for k in range(1, m - 1, 2):
            out.append(tour[(p + step * k) % m])
        return out

    # ------------------------------------------------------------------ moves

    def _reverse(self, i: int, j: int) -> None:
        """Reverse the positions i..j (cyclic), or the rest of the cycle if shorter
        (the same cycle, the other way round)."""
        tour, pos, m = self.tour, self.pos, self.m
        if self.log is not None:
            self.log.append((i, j))
        length = (j - i) % m + 1
        if 2 * length > m:
            i, j, length = (j + 1) % m, (i - 1) % m, m - length
        if length > 48:
            if i <= j:
                seg = self.tour_np[i:j + 1][::-1].copy()
                self.tour_np[i:j + 1] = seg
                self.pos_np[seg] = np.arange(i, j + 1)
            else:
                where = np.arange(i, i + length) % m
                seg = self.tour_np[where][::-1].copy()
                self.tour_np[where] = seg
                self.pos_np[seg] = where
            return
        for _ in range(length // 2):
            a, b = tour[i], tour[j]
            tour[i], tour[j] = b, a
            pos[b], pos[a] = i, j
            i += 1
            if i == m:
                i = 0
            j -= 1
            if j < 0:
                j = m - 1

    def _move2(self, a: int, b: int, c: int, d: int) -> None:
        """Replace the travel edges (a, b) and (c, d), b and d on the same side of a
        and c, by (a, c) and (b, d)."""
        pos, m = self.pos, self.m
        pa, pb = pos[a], pos[b]
        if pb == pa + 1 or (pb == 0 and pa == m - 1):
            self._reverse(pb, pos[c])
        else:
            self._reverse(pa, pos[d])

    def _insert(self, v: int, vp: int, e: int, en: int, u: int, up: int) -> None:
        """Move the run v..e (v's travel edge to vp, e's to en) between u and up, v
        next to u."""
        tour, pos, m = self.tour, self.pos, self.m
        forward = tour[pos[v] - 1] == vp          # the run goes on after v
        pu = pos[u]
        after_u = tour[pu + 1 if pu + 1 < m else 0] == up
        x, y = (u, up) if after_u == forward else (up, u)
        self._move2(vp, v, x, y)
        self._move2(vp, x, en, e)
        if u == x:
            self._move2(x, e, v, y)

    def improve(self, queue: deque, budget: int) -> int:
        """2-opt and Or-opt from the nodes in `queue` until none gains (or `budget`
        candidates were tried); returns the candidates tried, and sets self.gained."""
        tour, pos, m, cand, travel = self.tour, self.pos, self.m, self.cand, self.travel
        xs, ys = self.xs, self.ys
        sqrt = math.sqrt
        cand_d = self.cand_d

        def dist(a: int, b: int) -> float:
            if a == 1 or b == 1:
                return 0.0
            dx = xs[a] - xs[b]
            dy = ys[a] - ys[b]
            return sqrt(dx * dx + dy * dy)
        queued = self.queued
        touched = self.touched
        for v in queue:
            queued[v] = True
        tries = 0
        gained = 0.0
        pairs = m // 2

        def partner(v: int) -> tuple[int, int]:
            """(travel partner, +1 if it follows v else -1)."""
            p = pos[v]
            s = tour[p + 1 if p + 1 < m else 0]
            if s == v ^ 1:
                return tour[p - 1], -1
            return s, 1

        def changed(nodes) -> None:
            for v in nodes:
                w = partner(v)[0]
                travel[v] = dist(v, w)
                if touched is not None:
                    touched.append(v)
                if not queued[v]:
                    queued[v] = True
                    queue.append(v)

        while queue and tries < budget:
            u = queue.popleft()
            queued[u] = False
            if u == 1:
                continue
            up, uside = partner(u)
            duu = travel[u]
            pu = pos[u]
            for v, duv in zip(cand[u], cand_d[u]):
                tries += 1
                g1 = duu - duv
                if g1 <= _EPS:
                    break
                if v == up:
                    continue
                vp, vside = partner(v)
                base = g1 + travel[v]
                if uside == vside:
                    gain = base - dist(up, vp)
                    if gain > _EPS:
                        self._move2(u, up, v, vp)
                        gained += gain
                        changed((u, up, v, vp))
                        break
                # Or-opt: the run from v (away from vp) between u and up, v next to u
                best = None
                q = pos[v]
                step = -vside
                for length in range(1, 4):
                    if length + 2 > pairs:
                        break
                    pe = (q + step * (2 * length - 1)) % m
                    if ((pu - q) * step) % m < 2 * length or \
                            ((pos[up] - q) * step) % m < 2 * length:
                        break
                    e, en = tour[pe], tour[(pe + step) % m]
                    if vp == 1 or en == 1:
                        gain = base + travel[e]
                    else:
                        dx = xs[vp] - xs[en]
                        dy = ys[vp] - ys[en]
                        gain = base + travel[e] - sqrt(dx * dx + dy * dy)
                    if gain <= _EPS:                 # bound: the last edge adds more
                        continue
                    if e != 1 != up:
                        dx = xs[e] - xs[up]
                        dy = ys[e] - ys[up]
                        gain -= sqrt(dx * dx + dy * dy)
                    if gain > _EPS and (best is None or gain > best[0]):
                        best = (gain, v, vp, e, en, u, up)
                # Or-opt: the run from u (away from up) between v and vp, u next to v
                step = -uside
                for length in range(1, 4):
                    if length + 2 > pairs:
                        break
                    pe = (pu + step * (2 * length - 1)) % m
                    if ((q - pu) * step) % m < 2 * length or \
                            ((pos[vp] - pu) * step) % m < 2 * length:
                        break
                    e, en = tour[pe], tour[(pe + step) % m]
                    if up == 1 or en == 1:
                        gain = base + travel[e]
                    else:
                        dx = xs[up] - xs[en]
                        dy = ys[up] - ys[en]
                        gain = base + travel[e] - sqrt(dx * dx + dy * dy)
                    if gain <= _EPS:
                        continue
                    if e != 1 != vp:
                        dx = xs[e] - xs[vp]
                        dy = ys[e] - ys[vp]
                        gain -= sqrt(dx * dx + dy * dy)
                    if gain > _EPS and (best is None or gain > best[0]):
                        best = (gain, u, up, e, en, v, vp)
                if best is not None:
                    gain, a, ap, e, en, b, bp = best
                    self._insert(a, ap, e, en, b, bp)
                    gained += gain
                    changed((a, ap, e, en, b, bp))
                    break
        for v in queue:                         # out of budget: leave no flag set
            queued[v] = False
        queue.clear()
        self.gained = gained
        return tries

    def _refresh(self, nodes) -> None:
        """Travel lengths of `nodes` from the tour as it is."""
        tour, pos, m = self.tour, self.pos, self.m
        for v in nodes:
            p = pos[v]
            w = tour[p + 1 if p + 1 < m else 0]
            if w == v ^ 1:
                w = tour[p - 1]
            self.travel[v] = self.dist(v, w)

    # ------------------------------------------------------------------ perturbation

    def perturb(self, count: int, budget: int) -> None:
        """`count` times: swap two short neighbouring runs of chains at random
        (a double bridge), run the local search from the six ends touched, and keep
        the result only if the tour got shorter (else undo it)."""
        rng = random.Random(_SEED)
        m = self.m
        pairs = m // 2
        if pairs < 4:
            return
        tour, pos = self.tour, self.pos
        dist = self.dist
        most = max(1, min(KICK_PAIRS, (pairs - 1) // 2))
        for _ in range(count):
            if budget <= 0:
                break
            budget -= 1
            # a travel edge (a node and its travel partner on the following side),
            # then the runs of l1 and l2 chains after it swap places
            start = rng.randrange(m)
            if tour[(start + 1) % m] == tour[start] ^ 1:
                start = (start + 1) % m
            l1 = rng.randint(1, most)
            l2 = rng.randint(1, most)
            p1 = start                            # cut after p1, after p2, after p3
            p2 = (p1 + 2 * l1) % m
            p3 = (p2 + 2 * l2) % m
            a, b = tour[p1], tour[(p1 + 1) % m]
            c, d = tour[p2], tour[(p2 + 1) % m]
            e, f = tour[p3], tour[(p3 + 1) % m]
            delta = (dist(a, d) + dist(e, b) + dist(c, f)
                     - dist(a, b) - dist(c, d) - dist(e, f))
            self.log, self.touched = [], [a, b, c, d, e, f]
            # a [b..c] [d..e] f  ->  a [d..e] [b..c] f: three reversals
            self._reverse((p1 + 1) % m, p3)
            for first, last, nodes in ((e, d, (p3 - p2) % m), (c, b, (p2 - p1) % m)):
                if (pos[last] - pos[first]) % m == nodes - 1:
                    self._reverse(pos[first], pos[last])
                else:
                    self._reverse(pos[last], pos[first])
            self._refresh((a, b, c, d, e, f))
            budget -= self.improve(deque([a, b, c, d, e, f]), budget)
            if self.gained - delta <= _EPS:
                log, self.log = self.log, None
                for i, j in reversed(log):
                    self._reverse(i, j)
                self._refresh(self.touched)
            self.log, self.touched = None, None


class _EndFinder:
    """Free fragment ends on a grid: nearest to a point, then removed."""

    def __init__(self, xs: list[float], ys: list[float], ends: list[int]) -> None:
        self.xs, self.ys = xs, ys
        self.count = len(ends)
        if not ends:
            return
        # cells from the box of every point (queries come from anywhere in it: a cell
        # sized to the ends alone once was 1 nm, and the ring search spun for minutes)
        ex, ey = xs[:1] + xs[2:], ys[:1] + ys[2:]
        span = max(max(ex) - min(ex), max(ey) - min(ey), 1.0)
        self.cell = max(span / max(int(math.sqrt(len(ends))), 1), 1.0)
        self.grid: dict[tuple[int, int], list[int]] = {}
        for u in ends:
            self.grid.setdefault(self._key(xs[u], ys[u]), []).append(u)
        self.alive = set(ends)

    def __len__(self) -> int:
        return self.count

    def _key(self, x: float, y: float) -> tuple[int, int]:
        return (math.floor(x / self.cell), math.floor(y / self.cell))

    def remove(self, u: int) -> None:
        if u in self.alive:
            self.alive.discard(u)
            self.grid[self._key(self.xs[u], self.ys[u])].remove(u)
            self.count -= 1

    def nearest(self, x: float, y: float) -> int:
        hx, hy = self._key(x, y)
        best: tuple[float, int] | None = None
        ring = 0
        while True:
            for gx in range(hx - ring, hx + ring + 1):
                edge = gx in (hx - ring, hx + ring)
                for gy in ((range(hy - ring, hy + ring + 1)) if edge else (hy - ring, hy + ring)):
                    for u in self.grid.get((gx, gy), ()):
                        dx, dy = self.xs[u] - x, self.ys[u] - y
                        key = (math.sqrt(dx * dx + dy * dy), u)
                        if best is None or key < best:
                            best = key
            if best is not None and best[0] <= ring * self.cell:
                return best[1]
            ring += 1


def travel_nm(tour: list[Piece], start: Point) -> float:
    """Pen-up travel of drawing `tour` from `start` (nm)."""
    total, here = 0.0, start
    for c in tour:
        total += math.dist(here, c.start)
        here = c.end
    return total


def optimise(rows: list[tuple[int, Row]], start: Point, join_nm: int,
             moves: int = TWO_OPT_MOVES) -> tuple[list[tuple[int, Row]], Point]:
    """Rows of one pen in an order that draws the same with less pen-up travel."""
    chains = chain(cut_pieces(rows, start), join_nm)
    tour, end = order(chains, start, moves)
    return [entry for c in tour for entry in c.rows], end
