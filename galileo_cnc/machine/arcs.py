"""Arc stepping (docs/motion.md §4): per-side closed forms, integer sqrt, bands.

Coordinates here are relative to the arc centre. The circle is the one through
the start point, R2 = sx^2 + sy^2 (an integer, so the start is exactly on it).

The plane is cut into four *sides* by the diagonals: RIGHT (|x| > |y|, x > 0),
TOP, LEFT, BOTTOM. On a side one axis is *major* (it steps at every event: y on
RIGHT/LEFT, x on TOP/BOTTOM) and the other is *minor*. In the side's canonical
frame (u = outward minor coordinate >= 0, v = major coordinate increasing along
the travel) the visited points are

    u = U(v) = round_sqrt(R2 - v^2),   round_sqrt(w) = (isqrt(4w) + 1) // 2,

i.e. the minor coordinate nearest the circle (|u^2 + v^2 - R2| smallest; never a
tie because R2 is an integer). Per step that is the firmware's midpoint choice
between "major only" and "major + minor" by the smaller |x^2 + y^2 - R2|.

A point on a diagonal (|x| == |y|) belongs to the side the travel enters next.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from math import isqrt

import numpy as np

RIGHT, TOP, LEFT, BOTTOM = 0, 1, 2, 3
SIDE_NAMES = ("RIGHT", "TOP", "LEFT", "BOTTOM")

#: (side, ccw) -> (major axis, sigma, minor axis, tau) with v = sigma * coord[major]
#: and u = tau * coord[minor]. A major step moves coord[major] by sigma.
CANON: dict[tuple[int, bool], tuple[int, int, int, int]] = {
    (RIGHT, True): (1, +1, 0, +1),
    (RIGHT, False): (1, -1, 0, +1),
    (TOP, True): (0, -1, 1, +1),
    (TOP, False): (0, +1, 1, +1),
    (LEFT, True): (1, -1, 0, -1),
    (LEFT, False): (1, +1, 0, -1),
    (BOTTOM, True): (0, +1, 1, -1),
    (BOTTOM, False): (0, -1, 1, -1),
}

#: Timing bands (§5.3): an event whose key |v| lies in [V_b, V_b+1) has the path
#: length BAND_RHO_Q15[b] / 2^15 steps. V_b = (r8 * BAND_SIN_Q16[b]) >> 24 with
#: r8 = isqrt(R2 << 16). Edges t_b = sqrt(1 - 2^(-b/32)) make 1/cos(angle) grow by
#: the same ratio 2^(1/64) across every band; rho_b is the mean of 1/cos over the
#: band, (asin t_b+1 - asin t_b) / (t_b+1 - t_b), with t_32 = 1/sqrt(2).
#: Every arc then scales its rho by S = its true length / the sum of its events'
#: table rho (arc_geometry), so a whole arc runs at the feed for any radius.
BAND_SIN_Q16 = (
    0, 9593, 13494, 16438, 18880, 20997, 22879, 24582, 26141, 27581, 28922, 30176,
    31354, 32466, 33519, 34518, 35468, 36374, 37239, 38066, 38859, 39619, 40350,
    41052, 41727, 42378, 43005, 43610, 44194, 44758, 45303, 45831)
BAND_RHO_Q15 = (
    32886, 33294, 33661, 34029, 34401, 34776, 35155, 35538, 35926, 36317, 36713,
    37112, 37517, 37925, 38338, 38756, 39178, 39605, 40036, 40472, 40913, 41358,
    41809, 42264, 42724, 43190, 43660, 44135, 44616, 45102, 45593, 46090)
N_BANDS = len(BAND_SIN_Q16)

#: Largest |coordinate| relative to the centre: keeps R2 < 2^31 for the firmware.
MAX_ARC_COORD = 32767

#: Per-arc length normalisation (§5.3): atan(2^-i) in Q32 turns for the CORDIC,
#: 2*pi in Q29, and the precision of the scale factor.
ATAN_Q32 = (
    536870912, 316933406, 167458907, 85004756, 42667331, 21354465, 10679838, 5340245,
    2670163, 1335087, 667544, 333772, 166886, 83443, 41722, 20861, 10430, 5215, 2608,
    1304, 652, 326, 163, 81, 41, 20, 10, 5)
TWO_PI_Q29 = 3373259426
SCALE_BITS = 20


def next_side(side: int, ccw: bool) -> int:
    return (side + 1) % 4 if ccw else (side - 1) % 4


def classify(x: int, y: int, ccw: bool) -> int:
    """The side a point belongs to; diagonal points go to the side entered next."""
    ax, ay = abs(x), abs(y)
    if ax > ay:
        return RIGHT if x > 0 else LEFT
    if ay > ax:
        return TOP if y > 0 else BOTTOM
    if x == 0:  # the centre itself (degenerate arc)
        return RIGHT
    # On a diagonal the axis whose |coordinate| shrinks next is major. ccw moves
    # along (-y, x): x shrinks when x*y > 0. cw is the mirror image.
    x_major = ((x > 0) == (y > 0)) == ccw
    if x_major:
        return TOP if y > 0 else BOTTOM
    return RIGHT if x > 0 else LEFT


def round_sqrt(w: int) -> int:
    """The integer u >= 0 with (u - 1/2)^2 <= w < (u + 1/2)^2."""
    return (isqrt(4 * w) + 1) >> 1


def to_canon(x: int, y: int, side: int, ccw: bool) -> tuple[int, int]:
    maj, sg, mnr, tau = CANON[side, ccw]
    c = (x, y)
    return tau * c[mnr], sg * c[maj]


def from_canon(u: int, v: int, side: int, ccw: bool) -> tuple[int, int]:
    maj, sg, mnr, tau = CANON[side, ccw]
    c = [0, 0]
    c[maj] = sg * v
    c[mnr] = tau * u
    return c[0], c[1]


def formula_end(r2: int, v: int) -> int:
    """Last v' >= v of the bulk where the formula point is provably what the ISR visits.

    The bulk continues while the next formula point keeps a margin of 2 from the
    diagonal (U(v') >= v' + 2): then |U(v') - U(v'-1)| <= 1 and the point is on
    the side (§4.3). Returns t - 1 for the first t >= max(v + 1, 1) with
    U(t) <= t + 1 (at most a few increments from isqrt(R2/2) - 2).
    """
    t = max(v + 1, 1, isqrt(r2 // 2) - 2)
    while round_sqrt(r2 - t * t) >= t + 2:
        t += 1
    return t - 1


def arc_event(x: int, y: int, f: int, ccw: bool) -> tuple[int, int, int, int]:
    """One ISR arc event from (x, y) with F = x^2 + y^2 - R2: new x, y, F and band key."""
    maj, sg, mnr, tau = CANON[classify(x, y, ccw), ccw]
    c = [x, y]
    v = sg * c[maj]
    f_major = f + 2 * sg * c[maj] + 1
    s = -tau if v >= 0 else tau
    f_diag = f_major + 2 * s * c[mnr] + 1
    if abs(f_diag) < abs(f_major):
        c[mnr] += s
        f = f_diag
    else:
        f = f_major
    c[maj] += sg
    return c[0], c[1], f, min(abs(v), abs(v + 1))


WALK, FORMULA = 0, 1


@dataclass(frozen=True, slots=True)
class ArcGeometry:
    """Everything fixed per arc move, in steps relative to the centre.

    `segments` list the arc events in order: (WALK, points, keys) are events
    stepped one by one with the ISR rule (near the diagonals, §4.4), and
    (FORMULA, side, v_lo, v_hi) are events whose points are (U(v), v) in the
    side's frame for v = v_lo..v_hi. `p_star` is where the arc part ends; the
    correction (cx, cy) is then done as a line (§4.6).
    """

    ccw: bool
    r2: int
    start: tuple[int, int]
    end: tuple[int, int]
    segments: tuple
    p_star: tuple[int, int]
    n_arc: int
    correction: tuple[int, int]
    n_corr: int
    band_v: tuple[int, ...]      # compact thresholds, strictly increasing, [0] == 0
    band_rho: tuple[int, ...]    # Q15 path length per event of each compact band, scaled
    band0: int                   # compact band index of the first arc event
    weight_q15: int = 0          # sum of the table rho over the arc events (unscaled)
    length_q15: int = 0          # true length of the arc part, Q15 steps
    scale: int = 1 << SCALE_BITS  # length / weight, Q20: applied to every band rho

    @property
    def n(self) -> int:
        return self.n_arc + self.n_corr


def angle_q32(x: int, y: int) -> int:
    """Angle of (x, y) != (0, 0) in Q32 turns, [0, 2^32): integer CORDIC (§5.3)."""
    base = 0
    if x < 0:  # CORDIC converges for |angle| < 99 degrees: fold into x >= 0
        x, y, base = -x, -y, 1 << 31
    while max(x, abs(y)) >= 1 << 28:  # normalise to [2^27, 2^28): room for the gain
        x, y = x >> 1, y >> 1
    while max(x, abs(y)) < 1 << 27:  # (1.65) and a precision that scales with |(x, y)|
        x, y = x << 1, y << 1
    z = 0
    for i, a in enumerate(ATAN_Q32):
        if y > 0:
            x, y, z = x + (y >> i), y - (x >> i), z + a
        else:
            x, y, z = x - (y >> i), y + (x >> i), z - a
    return (base + z) & 0xFFFFFFFF


def arc_length_q15(r2: int, start: tuple[int, int], p_star: tuple[int, int], ccw: bool,
                   n_arc: int) -> int:
    """True length of the arc part, r times the swept angle start -> P*, Q15 steps.

    The angle of P* seen from the start is one CORDIC of (dot, cross); both fit
    int32 (|s| |P*| < 2^31, as P* is within 1/2 step of the circle).
    """
    if n_arc == 0:
        return 0
    (sx, sy), (px, py) = start, p_star
    if p_star == start:
        sweep = 1 << 32  # a full circle
    else:
        turn = angle_q32(sx * px + sy * py, sx * py - sy * px)
        sweep = turn if ccw else -turn & 0xFFFFFFFF
    r16 = isqrt(r2 << 32)
    circ16 = (r16 * TWO_PI_Q29 + (1 << 28)) >> 29       # 2 pi r, Q16
    return (circ16 * (sweep >> 4) + (1 << 28)) >> 29    # times sweep / 2^32, Q15


def length_scale(length_q15: int, weight_q15: int) -> int:
    """round(length / weight) in Q20; 1.0 for an empty arc."""
    if weight_q15 == 0:
        return 1 << SCALE_BITS
    while weight_q15 >> 32:  # the firmware divides 64 by 32 bits
        weight_q15 >>= 1
        length_q15 >>= 1
    return ((length_q15 << SCALE_BITS) + (weight_q15 >> 1)) // weight_q15


def band_table(r2: int) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """Compact band thresholds: equal thresholds collapse, the later band wins."""
    r8 = isqrt(r2 << 16)
    vs: list[int] = []
    rhos: list[int] = []
    for s, rho in zip(BAND_SIN_Q16, BAND_RHO_Q15):
        v = (r8 * s + (1 << 23)) >> 24
        if vs and vs[-1] == v:
            rhos[-1] = rho
        else:
            vs.append(v)
            rhos.append(rho)
    return tuple(vs), tuple(rhos)


def key_weight(band_v: tuple[int, ...], band_rho: tuple[int, ...], k0: int, k1: int) -> int:
    """Sum of the band rho over the keys k0..k1 (an empty range gives 0)."""
    total = 0
    top = len(band_v)
    for i in range(top):
        lo = max(k0, band_v[i])
        hi = min(k1 + 1, band_v[i + 1] if i + 1 < top else k1 + 1)
        if hi > lo:
            total += (hi - lo) * band_rho[i]
    return total


def formula_weight(band_v, band_rho, lo: int, hi: int) -> int:
    """Sum of rho over the events into v = lo..hi: key -v for v <= 0, v - 1 for v >= 1."""
    return (key_weight(band_v, band_rho, max(-hi, 0), -lo)
            + key_weight(band_v, band_rho, max(lo, 1) - 1, hi - 1))


def band_of(band_v: tuple[int, ...], key: int) -> int:
    """Largest compact index i with band_v[i] <= key."""
    lo, hi = 0, len(band_v) - 1
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if band_v[mid] <= key:
            lo = mid
        else:
            hi = mid - 1
    return lo


class _Walker:
    """Per-move setup walk over the sides (§4.5): counts events, finds P*."""

    def __init__(self, r2: int, start: tuple[int, int], ccw: bool):
        self.r2, self.ccw = r2, ccw
        self.x, self.y, self.f = start[0], start[1], 0
        self.segments: list = []
        self.n = 0
        self.first_key: int | None = None
        self._pts: list[tuple[int, int]] = []
        self._keys: list[int] = []

    def _flush(self) -> None:
        if self._pts:
            self.segments.append((WALK, tuple(self._pts), tuple(self._keys)))
            self._pts, self._keys = [], []

    def step(self, side: int, stop_before_exit: bool) -> bool:
        """One ISR event; False (and no step) if it would leave `side` and we must stop."""
        x, y, f, key = arc_event(self.x, self.y, self.f, self.ccw)
        if stop_before_exit and classify(x, y, self.ccw) != side:
            return False
        self.x, self.y, self.f = x, y, f
        self._pts.append((x, y))
        self._keys.append(key)
        if self.first_key is None:
            self.first_key = key
        self.n += 1
        return True

    def on_formula(self, side: int) -> bool:
        u, v = to_canon(self.x, self.y, side, self.ccw)
        return u == round_sqrt(self.r2 - v * v)

    def side(self, side: int, target: int | None) -> bool:
        """Walk one side; with a target v, stop at it (or at the side's end). True if stopped."""
        ccw, r2 = self.ccw, self.r2
        _u, v = to_canon(self.x, self.y, side, ccw)
        if target is not None and target <= v:
            return True
        stop = target is not None
        # Phase 1: step by the ISR rule until back on the formula (entry resync).
        while not self.on_formula(side):
            if not self.step(side, stop):
                return True
            v += 1
            if classify(self.x, self.y, ccw) != side:
                return False
            if v == target:
                return True
        # Phase 2: the formula bulk.
        hi = formula_end(r2, v)
        if target is not None and target < hi:
            hi = target
        if hi > v:
            self._flush()
            self.segments.append((FORMULA, side, v + 1, hi))
            if self.first_key is None:
                self.first_key = min(abs(v), abs(v + 1))
            self.n += hi - v
            self.x, self.y = from_canon(round_sqrt(r2 - hi * hi), hi, side, ccw)
            self.f = self.x * self.x + self.y * self.y - r2
            v = hi
            if v == target:
                return True
        # Phase 3: step by the ISR rule until the side changes.
        for _ in range(64):
            if not self.step(side, stop):
                return True
            v += 1
            if classify(self.x, self.y, ccw) != side:
                return False
            if v == target:
                return True
        raise AssertionError("arc side did not end")  # pragma: no cover


def arc_geometry(start: tuple[int, int], end: tuple[int, int], ccw: bool) -> ArcGeometry:
    """Per-move setup of an arc (outside the interrupt): segments, P*, bands."""
    sx, sy = start
    ex, ey = end
    r2 = sx * sx + sy * sy
    w = _Walker(r2, start, ccw)
    if r2 > 0:
        side_e = classify(ex, ey, ccw)
        for i in range(6):
            side = classify(w.x, w.y, ccw)
            target = None
            if side == side_e:
                v_e = to_canon(ex, ey, side, ccw)[1]
                if i > 0 or v_e > to_canon(w.x, w.y, side, ccw)[1]:
                    target = v_e
            if w.side(side, target):
                break
        else:  # pragma: no cover - the end side is always met within a lap
            raise AssertionError("arc end side not reached")
    w._flush()
    cx, cy = ex - w.x, ey - w.y
    band_v, band_rho = band_table(r2)
    band0 = band_of(band_v, w.first_key) if w.first_key is not None else 0
    weight = 0
    for seg in w.segments:
        if seg[0] == WALK:
            weight += sum(band_rho[band_of(band_v, k)] for k in seg[2])
        else:
            weight += formula_weight(band_v, band_rho, seg[2], seg[3])
    length = arc_length_q15(r2, (sx, sy), (w.x, w.y), ccw, w.n)
    scale = length_scale(length, weight)
    half = 1 << (SCALE_BITS - 1)
    scaled = tuple((rho * scale + half) >> SCALE_BITS for rho in band_rho)
    return ArcGeometry(ccw=ccw, r2=r2, start=(sx, sy), end=(ex, ey),
                       segments=tuple(w.segments), p_star=(w.x, w.y), n_arc=w.n,
                       correction=(cx, cy), n_corr=max(abs(cx), abs(cy)),
                       band_v=band_v, band_rho=scaled, band0=band0,
                       weight_q15=weight, length_q15=length, scale=scale)


def arc_bbox(g: ArcGeometry) -> tuple[int, int, int, int]:
    """(xmin, xmax, ymin, ymax) of every point the move visits (exact, closed form)."""
    xs = [g.start[0], g.end[0], g.p_star[0]]
    ys = [g.start[1], g.end[1], g.p_star[1]]
    for seg in g.segments:
        if seg[0] == WALK:
            xs.extend(p[0] for p in seg[1])
            ys.extend(p[1] for p in seg[1])
            continue
        _kind, side, lo, hi = seg
        v_near0 = 0 if lo <= 0 <= hi else (lo if abs(lo) < abs(hi) else hi)
        for v in (lo, hi, v_near0):
            x, y = from_canon(round_sqrt(g.r2 - v * v), v, side, g.ccw)
            xs.append(x)
            ys.append(y)
    return min(xs), max(xs), min(ys), max(ys)


@lru_cache(maxsize=1 << 13)
def arc_setup(start: tuple[int, int], end: tuple[int, int],
              ccw: bool) -> tuple[ArcGeometry, tuple[int, int, int, int]]:
    """arc_geometry and its arc_bbox, kept: both depend on the arc relative to its
    centre alone, and inked boards repeat their arcs (hellboard's job: 48,491 arcs,
    4,793 different), while the setup is most of planning a job on the reference
    machine (the travel check, the timing). 8,192 kept arcs hold about 30 MB."""
    geom = arc_geometry(start, end, ccw)
    return geom, arc_bbox(geom)


# ---- vectorised closed form -------------------------------------------------------

def isqrt_array(w: np.ndarray) -> np.ndarray:
    """Exact floor(sqrt(w)) for int64 w in [0, 2^52): float sqrt, then corrected."""
    q = np.sqrt(w.astype(np.float64)).astype(np.int64)
    q -= (q * q > w).astype(np.int64)
    q += ((q + 1) * (q + 1) <= w).astype(np.int64)
    return q


def arc_points(g: ArcGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Points after each arc event (n_arc x 2, relative) and each event's band key."""
    pts = np.empty((g.n_arc, 2), dtype=np.int64)
    keys = np.empty(g.n_arc, dtype=np.int64)
    pos = 0
    for seg in g.segments:
        if seg[0] == WALK:
            cnt = len(seg[1])
            pts[pos:pos + cnt] = seg[1]
            keys[pos:pos + cnt] = seg[2]
            pos += cnt
            continue
        _kind, side, lo, hi = seg
        cnt = hi - lo + 1
        v = np.arange(lo - 1, hi + 1, dtype=np.int64)  # v before the first event .. last
        vv = v[1:]
        u = (isqrt_array(4 * (g.r2 - vv * vv)) + 1) >> 1
        maj, sg, mnr, tau = CANON[side, g.ccw]
        pts[pos:pos + cnt, maj] = vv if sg > 0 else -vv
        pts[pos:pos + cnt, mnr] = u if tau > 0 else -u
        av = np.abs(v)
        np.minimum(av[1:], av[:-1], out=keys[pos:pos + cnt])
        pos += cnt
    return pts, keys
