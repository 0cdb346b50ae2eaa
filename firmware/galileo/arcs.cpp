/* Per-move arc setup (docs/motion.md §4.4, §4.5, §5.3, §7), main loop only.
 * A port of galileo_cnc/machine/arcs.py (_Walker, arc_geometry, arc_bbox,
 * band_table) that keeps counts and the bounding box instead of segments. */
#include <avr/pgmspace.h>

#include "arcs.h"
#include "config.h"
#include "intmath.h"

static const uint16_t BAND_SIN_Q16[CFG_N_BANDS] PROGMEM = CFG_BAND_SIN_Q16;
static const uint16_t BAND_RHO_Q15[CFG_N_BANDS] PROGMEM = CFG_BAND_RHO_Q15;

/* The walker: the current point, F, counts and the box of visited points. */
static struct {
    int32_t x, y, f;
    uint32_t r2, n;
    uint16_t first_key;
    uint8_t ccw;
    int32_t xmin, xmax, ymin, ymax;
} w;

static void box_add(int32_t x, int32_t y)
{
    if (x < w.xmin) w.xmin = x;
    if (x > w.xmax) w.xmax = x;
    if (y < w.ymin) w.ymin = y;
    if (y > w.ymax) w.ymax = y;
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
    int32_t x = w.x, y = w.y, f = w.f;
    uint8_t axes, neg;
    uint32_t key = arc_event_step(&x, &y, &f, w.ccw, &axes, &neg);
    if (stop_before_exit && arc_side(x, y, w.ccw) != side)
        return 0;
    w.x = x;
    w.y = y;
    w.f = f;
    box_add(x, y);
    if (w.first_key == NO_FIRST_KEY)
        w.first_key = (uint16_t)key;
    w.n++;
    return 1;
}

enum { SIDE_LEFT_BEHIND, SIDE_STOPPED, SIDE_FAILED };

/* Phases 1-3 of §4.5 on one side, with or without a target v. */
static uint8_t walk_side(uint8_t side, uint8_t has_target, int32_t target)
{
    int32_t v = canon_v(w.x, w.y, side);
    if (has_target && target <= v)
        return SIDE_STOPPED;
    while (canon_u(w.x, w.y, side) != formula_u(v)) { /* phase 1: resync */
        if (!walk_step(side, has_target))
            return SIDE_STOPPED;
        v++;
        if (arc_side(w.x, w.y, w.ccw) != side)
            return SIDE_LEFT_BEHIND;
        if (has_target && v == target)
            return SIDE_STOPPED;
    }
    int32_t hi = formula_end(v); /* phase 2: the formula bulk */
    if (has_target && target < hi)
        hi = target;
    if (hi > v) {
        int32_t lo = v + 1, near0;
        if (lo <= 0 && 0 <= hi)
            near0 = 0;
        else
            near0 = (lo < 0 ? -lo : lo) < (hi < 0 ? -hi : hi) ? lo : hi;
        int32_t ends[3] = {lo, hi, near0};
        for (uint8_t i = 0; i < 3; i++) {
            int32_t x, y;
            from_canon(formula_u(ends[i]), ends[i], side, &x, &y);
            box_add(x, y);
        }
        if (w.first_key == NO_FIRST_KEY)
            w.first_key = (uint16_t)(v >= 0 ? v : -(v + 1));
        w.n += (uint32_t)(hi - v);
        from_canon(formula_u(hi), hi, side, &w.x, &w.y);
        w.f = (int32_t)(square(w.x) + square(w.y) - w.r2);
        v = hi;
        if (has_target && v == target)
            return SIDE_STOPPED;
    }
    for (uint8_t i = 0; i < 64; i++) { /* phase 3: to the side's end */
        if (!walk_step(side, has_target))
            return SIDE_STOPPED;
        v++;
        if (arc_side(w.x, w.y, w.ccw) != side)
            return SIDE_LEFT_BEHIND;
        if (has_target && v == target)
            return SIDE_STOPPED;
    }
    return SIDE_FAILED;
}

uint8_t arc_walk(int32_t sx, int32_t sy, int32_t ex, int32_t ey, uint8_t ccw,
                 struct arc_plan *out)
{
    w.x = sx;
    w.y = sy;
    w.f = 0;
    w.r2 = square(sx) + square(sy);
    w.n = 0;
    w.first_key = NO_FIRST_KEY;
    w.ccw = ccw;
    w.xmin = w.xmax = sx;
    w.ymin = w.ymax = sy;
    box_add(ex, ey);
    if (w.r2 > 0) {
        uint8_t side_e = arc_side(ex, ey, ccw), i;
        for (i = 0; i < 6; i++) {
            uint8_t side = arc_side(w.x, w.y, ccw), has_target = 0;
            int32_t target = 0;
            if (side == side_e) {
                int32_t v_e = canon_v(ex, ey, side);
                if (i > 0 || v_e > canon_v(w.x, w.y, side)) {
                    has_target = 1;
                    target = v_e;
                }
            }
            uint8_t r = walk_side(side, has_target, target);
            if (r == SIDE_STOPPED)
                break;
            if (r == SIDE_FAILED)
                return 1;
        }
        if (i == 6)
            return 1;
    }
    box_add(w.x, w.y);
    out->px = w.x;
    out->py = w.y;
    out->n_arc = w.n;
    out->first_key = w.first_key;
    out->xmin = w.xmin;
    out->xmax = w.xmax;
    out->ymin = w.ymin;
    out->ymax = w.ymax;
    return 0;
}

void band_table_fill(struct band_table *t, const struct block *b)
{
    int32_t x0 = b->u.arc.x0, y0 = b->u.arc.y0;
    uint32_t r2 = (uint32_t)(x0 * x0) + (uint32_t)(y0 * y0);
    uint32_t r8 = isqrt64((uint64_t)r2 << 16); /* radius, Q8 */
    uint16_t rho[CFG_N_BANDS];
    uint8_t count = 0;
    for (uint8_t i = 0; i < CFG_N_BANDS; i++) {
        uint16_t v = (uint16_t)mul_round_shift(r8, pgm_read_word(&BAND_SIN_Q16[i]), 24);
        uint16_t r = pgm_read_word(&BAND_RHO_Q15[i]);
        if (count && t->v[count - 1] == v) {
            rho[count - 1] = r; /* equal thresholds: the later band wins */
        } else {
            t->v[count] = v;
            rho[count++] = r;
        }
    }
    for (uint8_t i = 0; i < count; i++)
        t->base_sub[i] = mul_round_shift(b->u.arc.axial_sub, rho[i], CFG_RHO_BITS);
    t->count = count;
    uint8_t band0 = 0;
    if (b->u.arc.first_key != NO_FIRST_KEY)
        while (band0 + 1 < count && t->v[band0 + 1] <= b->u.arc.first_key)
            band0++;
    t->band0 = band0;
}
