/* Per-move arc setup (docs/motion.md §4.4, §4.5, §5.3, §7), main loop only.
 * A port of galileo_cnc/machine/arcs.py (_Walker, arc_geometry, arc_bbox,
 * band_table) that keeps counts and the bounding box instead of segments. */
#include <avr/pgmspace.h>

#include "arcs.h"
#include "config.h"
#include "intmath.h"

static const uint16_t BAND_SIN_Q16[CFG_N_BANDS] PROGMEM = CFG_BAND_SIN_Q16;
static const uint16_t BAND_RHO_Q15[CFG_N_BANDS] PROGMEM = CFG_BAND_RHO_Q15;
/* atan(2^-i) in Q32 turns: arcs.py ATAN_Q32 (a test compares the two). */
#define N_ATAN 28
static const uint32_t ATAN_Q32[N_ATAN] PROGMEM = {
    536870912, 316933406, 167458907, 85004756, 42667331, 21354465, 10679838, 5340245,
    2670163, 1335087, 667544, 333772, 166886, 83443, 41722, 20861, 10430, 5215, 2608,
    1304, 652, 326, 163, 81, 41, 20, 10, 5};
#define TWO_PI_Q29 3373259426ULL
#define SCALE_BITS 20

/* The walker: the current point (p.px, p.py), F, counts and the box of visited
 * points, kept in the plan arc_walk hands back (no copy on the caller's stack). */
static struct {
    struct arc_plan p;            /* px, py: the current point; n_arc; first_key; box */
    int32_t f;
    uint32_t r2;
    uint8_t ccw;
    uint16_t band_v[CFG_N_BANDS]; /* raw thresholds V_b (not compacted) */
    uint32_t weight_lo, weight_hi; /* sum of the table rho over the events (§5.3), 64 bits */
    uint32_t r16;                 /* isqrt(R2 << 32): radius, Q16 */
} w;

/* weight += a (64 bits) with a 32-bit add and a carry: no 64-bit temporaries. */
static inline __attribute__((always_inline)) void add_weight(uint32_t a)
{
    uint32_t lo = w.weight_lo + a;
    if (lo < a)
        w.weight_hi++;
    w.weight_lo = lo;
}

/* (r8 * s + 2^23) >> 24 without a 64-bit product (slow on the AVR):
 * with r8 = a * 2^16 + c (r8 < 2^24), every partial sum fits 32 bits. */
static uint16_t band_threshold(uint32_t r8, uint16_t s)
{
    uint16_t a = (uint16_t)(r8 >> 16), c = (uint16_t)r8;
    return (uint16_t)(((uint32_t)a * s + (((uint32_t)c * s + (1UL << 23)) >> 16)) >> 8);
}

/* isqrt(r2 << 32) = floor(sqrt(r2) * 2^16) in 32 bits (r2 < 2^31): 16 more
 * digits of the digit-by-digit root; rem = N - root^2 <= 2 root. */
static uint32_t isqrt_q16(uint32_t r2)
{
    uint32_t root = isqrt32(r2), rem = r2 - root * root;
    for (uint8_t j = 0; j < 16; j++) {
        uint8_t one = rem > root; /* (2 root + 1)^2 <= 4 N */
        if (j < 15) /* the last rem is not needed (and would not fit) */
            rem = one ? ((rem - root) << 2) - 1 : rem << 2;
        root = (root << 1) + one;
    }
    return root;
}

/* v >> n, arithmetic, by constant shifts (a variable shift is a bit loop on the AVR). */
static inline int32_t asr32(int32_t v, uint8_t n)
{
    if (n & 16) v >>= 16;
    if (n & 8) v >>= 8;
    if (n & 4) v >>= 4;
    if (n & 2) v >>= 2;
    if (n & 1) v >>= 1;
    return v;
}

/* P(k): the table rho summed over the keys 0..k-1 (< 2^32: k <= 23 171 + 1). */
static uint32_t key_prefix(uint16_t k)
{
    uint32_t sum = 0;
    for (uint8_t b = 0; b < CFG_N_BANDS && w.band_v[b] < k; b++) {
        uint16_t hi = (b + 1 < CFG_N_BANDS && w.band_v[b + 1] < k) ? w.band_v[b + 1] : k;
        sum += (uint32_t)(uint16_t)(hi - w.band_v[b]) * pgm_read_word(&BAND_RHO_Q15[b]);
    }
    return sum;
}

/* Keys k0..k1 (empty when k1 < k0). A key is in the last band b with V_b <= key,
 * as with the compacted table. */
static void add_key_weight(int32_t k0, int32_t k1)
{
    if (k1 >= k0)
        add_weight(key_prefix((uint16_t)(k1 + 1)) - (k0 ? key_prefix((uint16_t)k0) : 0));
}

/* Events into v = lo..hi of a formula bulk: key -v for v <= 0, v - 1 for v >= 1. */
static void add_formula_weight(int32_t lo, int32_t hi)
{
    add_key_weight(hi < 0 ? -hi : 0, -lo);
    add_key_weight((lo > 1 ? lo : 1) - 1, hi - 1);
}

/* Angle of (x, y) != (0, 0) in Q32 turns: the CORDIC of arcs.py angle_q32. */
static uint32_t angle_q32(int32_t x, int32_t y)
{
    uint32_t z = 0;
    if (x < 0) { /* CORDIC converges for |angle| < 99 degrees */
        x = -x;
        y = -y;
        z = 0x80000000UL;
    }
    while (x >= (1L << 28) || y >= (1L << 28) || y <= -(1L << 28)) {
        x >>= 1; /* to [2^27, 2^28): room for the CORDIC gain (1.65) */
        y >>= 1;
    }
    while (x < (1L << 27) && (y < 0 ? -y : y) < (1L << 27)) {
        x <<= 1;
        y <<= 1;
    }
    for (uint8_t i = 0; i < N_ATAN; i++) {
        int32_t dx = asr32(y, i), dy = asr32(x, i);
        uint32_t a = pgm_read_dword(&ATAN_Q32[i]);
        if (y > 0) {
            x += dx;
            y -= dy;
            z += a;
        } else {
            x -= dx;
            y += dy;
            z -= a;
        }
    }
    return z;
}

/* §5.3: length of the arc part / its table weight, Q20 (1.0 for an empty arc). */
static __attribute__((noinline)) uint32_t length_scale(int32_t sx, int32_t sy)
{
    uint64_t wt = ((uint64_t)w.weight_hi << 32) | w.weight_lo;
    if (w.p.n_arc == 0 || wt == 0)
        return 1UL << SCALE_BITS;
    /* P* seen from the start: |dot|, |cross| <= |s| |P*| < 2^31 (P* is within
     * 1/2 step of the circle), so uint32 sums give the exact int32 values. */
    int32_t dot = (int32_t)((uint32_t)(sx * w.p.px) + (uint32_t)(sy * w.p.py));
    int32_t cross = (int32_t)((uint32_t)(sx * w.p.py) - (uint32_t)(sy * w.p.px));
    uint64_t sweep = 1ULL << 32; /* a full circle */
    if (w.p.px != sx || w.p.py != sy) {
        uint32_t turn = angle_q32(dot, cross);
        sweep = (uint32_t)(w.ccw ? turn : 0 - turn);
    }
    uint64_t circ16 = ((uint64_t)w.r16 * TWO_PI_Q29 + (1UL << 28)) >> 29;
    uint64_t len = (circ16 * (sweep >> 4) + (1UL << 28)) >> 29;
    while (wt >> 32) {
        wt >>= 1;
        len >>= 1;
    }
    return udiv64_32((len << SCALE_BITS) + (wt >> 1), (uint32_t)wt);
}

static void box_add(int32_t x, int32_t y)
{
    if (x < w.p.xmin) w.p.xmin = x;
    if (x > w.p.xmax) w.p.xmax = x;
    if (y < w.p.ymin) w.p.ymin = y;
    if (y > w.p.ymax) w.p.ymax = y;
}

/* Canonical frame (§4.1): v = sigma * major, u = tau * minor. */
static int32_t canon_v(int32_t x, int32_t y, uint8_t side)
{
    int32_t c_maj = (side & 1) ? x : y;
    return ((side == SIDE_RIGHT || side == SIDE_BOTTOM) == (w.ccw != 0)) ? c_maj : -c_maj;
}

static int32_t canon_u(int32_t x, int32_t y, uint8_t side)
{
    int32_t c_mnr = (side & 1) ? y : x;
    return (side == SIDE_RIGHT || side == SIDE_TOP) ? c_mnr : -c_mnr;
}

static void from_canon(int32_t u, int32_t v, uint8_t side, int32_t *x, int32_t *y)
{
    int32_t c_maj = ((side == SIDE_RIGHT || side == SIDE_BOTTOM) == (w.ccw != 0)) ? v : -v;
    int32_t c_mnr = (side == SIDE_RIGHT || side == SIDE_TOP) ? u : -u;
    if (side & 1) {
        *x = c_maj;
        *y = c_mnr;
    } else {
        *x = c_mnr;
        *y = c_maj;
    }
}

static uint32_t square(int32_t v) { return (uint32_t)(v < 0 ? -v : v) * (uint32_t)(v < 0 ? -v : v); }

/* U(v) = round_sqrt(R2 - v^2); -1 where the circle has no point (|v| > r). */
static int32_t formula_u(int32_t v)
{
    uint32_t v2 = square(v);
    return v2 > w.r2 ? -1 : (int32_t)round_sqrt32(w.r2 - v2);
}

static int32_t formula_end(int32_t v)
{
    int32_t t = (int32_t)isqrt32(w.r2 / 2) - 2;
    if (t < v + 1) t = v + 1;
    if (t < 1) t = 1;
    while (formula_u(t) >= t + 2)
        t++;
    return t - 1;
}

/* One ISR event; 0 (and no step) if it would leave `side` while stopping there. */
static uint8_t walk_step(uint8_t side, uint8_t stop_before_exit)
{
    int32_t x = w.p.px, y = w.p.py, f = w.f;
    uint8_t axes, neg;
    uint32_t key = arc_event_step(&x, &y, &f, w.ccw, &axes, &neg);
    if (stop_before_exit && arc_side(x, y, w.ccw) != side)
        return 0;
    w.p.px = x;
    w.p.py = y;
    w.f = f;
    box_add(x, y);
    if (w.p.first_key == NO_FIRST_KEY)
        w.p.first_key = (uint16_t)key;
    uint8_t b = CFG_N_BANDS - 1; /* the event's band: the last with V_b <= key */
    while (w.band_v[b] > key)
        b--;
    add_weight(pgm_read_word(&BAND_RHO_Q15[b]));
    w.p.n_arc++;
    return 1;
}

enum { SIDE_LEFT_BEHIND, SIDE_STOPPED, SIDE_FAILED };

/* Phase 2 of §4.5: the formula bulk from v to hi > v (out of line: its
 * temporaries stay off the stack of the event-by-event phases). */
static __attribute__((noinline)) void walk_formula(uint8_t side, int32_t v, int32_t hi)
{
    int32_t lo = v + 1, near0;
    if (lo <= 0 && 0 <= hi)
        near0 = 0;
    else
        near0 = (lo < 0 ? -lo : lo) < (hi < 0 ? -hi : hi) ? lo : hi;
    for (uint8_t i = 0; i < 3; i++) {
        int32_t e = i == 0 ? lo : i == 1 ? hi : near0, x, y;
        from_canon(formula_u(e), e, side, &x, &y);
        box_add(x, y);
    }
    if (w.p.first_key == NO_FIRST_KEY)
        w.p.first_key = (uint16_t)(v >= 0 ? v : -(v + 1));
    add_formula_weight(v + 1, hi);
    w.p.n_arc += (uint32_t)(hi - v);
    from_canon(formula_u(hi), hi, side, &w.p.px, &w.p.py);
    w.f = (int32_t)(square(w.p.px) + square(w.p.py) - w.r2);
}

/* Phases 1-3 of §4.5 on one side, with or without a target v. */
static __attribute__((noinline)) uint8_t walk_side(uint8_t side, uint8_t has_target,
                                                   int32_t target)
{
    int32_t v = canon_v(w.p.px, w.p.py, side);
    if (has_target && target <= v)
        return SIDE_STOPPED;
    while (canon_u(w.p.px, w.p.py, side) != formula_u(v)) { /* phase 1: resync */
        if (!walk_step(side, has_target))
            return SIDE_STOPPED;
        v++;
        if (arc_side(w.p.px, w.p.py, w.ccw) != side)
            return SIDE_LEFT_BEHIND;
        if (has_target && v == target)
            return SIDE_STOPPED;
    }
    int32_t hi = formula_end(v); /* phase 2: the formula bulk */
    if (has_target && target < hi)
        hi = target;
    if (hi > v) {
        walk_formula(side, v, hi);
        v = hi;
        if (has_target && v == target)
            return SIDE_STOPPED;
    }
    for (uint8_t i = 0; i < 64; i++) { /* phase 3: to the side's end */
        if (!walk_step(side, has_target))
            return SIDE_STOPPED;
        v++;
        if (arc_side(w.p.px, w.p.py, w.ccw) != side)
            return SIDE_LEFT_BEHIND;
        if (has_target && v == target)
            return SIDE_STOPPED;
    }
    return SIDE_FAILED;
}

/* The walker's start at (sx, sy), the band thresholds and the end in the box. */
static __attribute__((noinline)) void walk_start(int32_t sx, int32_t sy, int32_t ex,
                                                 int32_t ey, uint8_t ccw)
{
    w.p.px = sx;
    w.p.py = sy;
    w.f = 0;
    w.r2 = square(sx) + square(sy);
    w.p.n_arc = 0;
    w.p.first_key = NO_FIRST_KEY;
    w.ccw = ccw;
    w.p.xmin = w.p.xmax = sx;
    w.p.ymin = w.p.ymax = sy;
    box_add(ex, ey);
    w.weight_lo = w.weight_hi = 0;
    w.r16 = isqrt_q16(w.r2);
    uint32_t r8 = w.r16 >> 8; /* = isqrt(R2 << 16) */
    for (uint8_t b = 0; b < CFG_N_BANDS; b++)
        w.band_v[b] = band_threshold(r8, pgm_read_word(&BAND_SIN_Q16[b]));
}

/* §4.5: the sides from the walker's start to P*, the end's side side_e at v_e; 0 on success. */
static inline __attribute__((always_inline)) uint8_t walk_sides(uint8_t side_e, int32_t v_e)
{
    for (uint8_t i = 0; i < 6; i++) {
        uint8_t side = arc_side(w.p.px, w.p.py, w.ccw), has_target = 0;
        if (side == side_e && (i > 0 || v_e > canon_v(w.p.px, w.p.py, side)))
            has_target = 1;
        uint8_t r = walk_side(side, has_target, has_target ? v_e : 0);
        if (r == SIDE_STOPPED)
            return 0;
        if (r == SIDE_FAILED)
            return 1;
    }
    return 1;
}

const struct arc_plan *arc_walk(int32_t sx, int32_t sy, int32_t ex, int32_t ey, uint8_t ccw)
{
    walk_start(sx, sy, ex, ey, ccw);
    if (w.r2 > 0) {
        uint8_t side_e = arc_side(ex, ey, ccw);
        if (walk_sides(side_e, canon_v(ex, ey, side_e)))
            return 0;
    }
    box_add(w.p.px, w.p.py);
    w.p.scale = length_scale(sx, sy);
    return &w.p;
}

void band_table_fill(struct band_table *t, const struct block *b)
{
    int32_t x0 = b->u.arc.x0, y0 = b->u.arc.y0;
    uint32_t r2 = (uint32_t)(x0 * x0) + (uint32_t)(y0 * y0);
    uint32_t r8 = isqrt64((uint64_t)r2 << 16); /* radius, Q8 */
    uint16_t rho[CFG_N_BANDS];
    uint8_t count = 0;
    for (uint8_t i = 0; i < CFG_N_BANDS; i++) {
        uint16_t v = band_threshold(r8, pgm_read_word(&BAND_SIN_Q16[i]));
        uint16_t r = pgm_read_word(&BAND_RHO_Q15[i]);
        if (count && t->v[count - 1] == v) {
            rho[count - 1] = r; /* equal thresholds: the later band wins */
        } else {
            t->v[count] = v;
            rho[count++] = r;
        }
    }
    for (uint8_t i = 0; i < count; i++) {
        uint32_t scaled = mul_round_shift(rho[i], b->u.arc.scale, SCALE_BITS);
        uint32_t base = mul_round_shift(b->u.arc.axial_sub, scaled, CFG_RHO_BITS);
        /* a scale below 1 must not beat the minimum step period (§5.6) */
        if (base < ((uint32_t)CFG_MIN_STEP_PERIOD_TICKS << CFG_FRAC_BITS))
            base = (uint32_t)CFG_MIN_STEP_PERIOD_TICKS << CFG_FRAC_BITS;
        t->base_sub[i] = base;
    }
    t->count = count;
    uint8_t band0 = 0;
    if (b->u.arc.first_key != NO_FIRST_KEY)
        while (band0 + 1 < count && t->v[band0 + 1] <= b->u.arc.first_key)
            band0++;
    t->band0 = band0;
}
