"""The local search behind path order: a tour over chain ends, improved by 2-opt,
Or-opt and perturbation.

A travelling-salesman path: the start (the machine's position) and each chain's two
ends are nodes, a chain's ends are tied together (drawn one after the other, either
way round), and a free end node (at zero distance from all, or at each end's distance
from where the work after this pen starts) closes the open path into a cycle. Greedy
matching over the k nearest ends builds a first tour (its fragments joined nearest
first from the start), then local search with neighbour lists and don't-look bits:
2-opt (reversing a run of chains, each flipped; a run of one chain is that chain
flipped in place, and the run may reach the free end: a new last chain) and Or-opt
(moving a run of one to three chains elsewhere, either way round), then perturbation
(two neighbouring runs of chains swapped at random, the local search run from the six
ends touched, kept only if the tour got shorter). Every bound is a count of moves
tried, never a time, and the perturbation draws from a seeded generator: the same
file plans to the same job on any machine (resume replans and continues by command
index).

The search itself (`Tour.search`) runs compiled where setup.py could build
tour_search.c (plan/native.py), else here in Python: the same moves in the same order,
to the same tour.
"""

from __future__ import annotations

import array
import math
import random
from collections import deque

import numpy as np

from galileo_cnc.plan import native
from galileo_cnc.plan.order.nearby import EndFinder, nearest

#: nearest ends each end's moves look at
NEIGHBOURS = 8
#: and the nearest ends in each quadrant around an end (up to BRUTE_FORCE nodes)
QUADRANT = 2
#: perturbations (two neighbouring runs of chains swapped, then local search) per
#: chain, and at most; the runs are 1 to KICK_PAIRS chains long. The cap bounds the
#: time on big pens: 10,000 random paths optimize in about 1.7 s on the 2-core test
#: machine (1.9 s with 1,500, for 0.5 % less travel there; on the corpus 1,000
#: instead of 1,500 adds 0.85 m of travel over the 39 layers it touches, of 20 km)
PERTURB_PER_CHAIN = 5
PERTURB_MAX = 1_000
KICK_PAIRS = 20
_SEED = 20240617                 # the perturbation's generator: the same every run
_EPS = 1e-3                      # nm: a move must gain more than this


class Tour:
    """A cycle over the nodes as a position array: mates (node ^ 1) always next to
    each other, the edges between pairs are the pen-up travel. Node 1, the free end,
    is at `tail[v]` from node v (zero for all without a goal: the path may end
    anywhere), so the open path from the start (node 0) away from node 1 is the
    drawing order."""

    def __init__(self, xs: list[float], ys: list[float],
                 tail: list[float] | None = None) -> None:
        self.xs, self.ys = xs, ys
        self.tail = tail if tail is not None else [0.0] * len(xs)
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
        near, gaps = nearest(ax, ay, NEIGHBOURS, QUADRANT)
        self.near = near
        # every end may become the last one (node 1, at its tail's distance), nearest
        # first like the rest; the start never (its mate)
        self.cand, self.cand_d = [], []
        for u in range(self.m):
            pairs = [(g, v) for v, g in zip(near[u], gaps[u]) if v != 1]
            if u:                               # before the ends as far or farther
                at = next((k for k, (g, _v) in enumerate(pairs) if g >= self.tail[u]),
                          len(pairs))
                pairs.insert(at, (self.tail[u], 1))
            self.cand.append([v for _g, v in pairs])
            self.cand_d.append([g for g, _v in pairs])

    # ------------------------------------------------------------------ geometry

    def dist(self, a: int, b: int) -> float:
        if a == 1 or b == 1:
            return self.tail[a + b - 1]
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
        finder = EndFinder(xs, ys, free)
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

    # ------------------------------------------------------------------ the search

    def search(self, moves: int, perturbations: int) -> None:
        """2-opt and Or-opt from every node, then `perturbations` perturbations, within
        `moves` candidates tried in all: compiled where it is built (native.py)."""
        compiled = native.tour_search()
        if compiled is not None:
            compiled(self, moves, perturbations, self.kicks(perturbations))
            return
        tries = self.improve(deque(range(self.m)), moves)
        self.perturb(perturbations, moves - tries)

    def kicks(self, count: int) -> list[tuple[int, int, int]]:
        """The perturbations' random draws from the seeded generator: where each kick's
        runs start, and their lengths in chains (they never depend on the tour, so the
        compiled search takes them drawn here)."""
        rng = random.Random(_SEED)
        most = max(1, min(KICK_PAIRS, (self.m // 2 - 1) // 2))
        return [(rng.randrange(self.m), rng.randint(1, most), rng.randint(1, most))
                for _ in range(count)]

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

        tail = self.tail

        def dist(a: int, b: int) -> float:
            if a == 1 or b == 1:
                return tail[a + b - 1]
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
                # Or-opt: a run of 1 to 3 chains from a (away from its partner ap)
                # put between b and bp, a next to b; both ways round: the run from v
                # between u and up, then the run from u between v and vp
                best = None
                q = pos[v]
                for a, ap, aside, pa, b, bp in ((v, vp, vside, q, u, up),
                                                (u, up, uside, pu, v, vp)):
                    step = -aside
                    pb = pos[b]
                    for length in range(1, 4):
                        if length + 2 > pairs:
                            break
                        pe = (pa + step * (2 * length - 1)) % m
                        if ((pb - pa) * step) % m < 2 * length or \
                                ((pos[bp] - pa) * step) % m < 2 * length:
                            break
                        e, en = tour[pe], tour[(pe + step) % m]
                        if ap == 1 or en == 1:
                            gain = base + travel[e] - tail[ap + en - 1]
                        else:
                            dx = xs[ap] - xs[en]
                            dy = ys[ap] - ys[en]
                            gain = base + travel[e] - sqrt(dx * dx + dy * dy)
                        if gain <= _EPS:             # bound: the last edge adds more
                            continue
                        if e != 1 != bp:
                            dx = xs[e] - xs[bp]
                            dy = ys[e] - ys[bp]
                            gain -= sqrt(dx * dx + dy * dy)
                        else:
                            gain -= tail[e + bp - 1]
                        if gain > _EPS and (best is None or gain > best[0]):
                            best = (gain, a, ap, e, en, b, bp)
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
        m = self.m
        pairs = m // 2
        if pairs < 4:
            return
        tour, pos = self.tour, self.pos
        dist = self.dist
        for start, l1, l2 in self.kicks(count):
            if budget <= 0:
                break
            budget -= 1
            # a travel edge (a node and its travel partner on the following side),
            # then the runs of l1 and l2 chains after it swap places
            if tour[(start + 1) % m] == tour[start] ^ 1:
                start = (start + 1) % m
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
