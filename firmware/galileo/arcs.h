/* Arc geometry (docs/motion.md §4): the sides, the one midpoint event rule that
 * both the interrupt and the setup walk use, and the per-move setup. */
#ifndef GALILEO_ARCS_H
#define GALILEO_ARCS_H

#include <stdint.h>
#include "stepper.h"

enum arc_side { SIDE_RIGHT, SIDE_TOP, SIDE_LEFT, SIDE_BOTTOM };
#define NO_FIRST_KEY 0xFFFF

/* §4.1: the side of (x, y); a diagonal point goes to the side the travel enters next. */
static inline uint8_t arc_side(int32_t x, int32_t y, uint8_t ccw)
{
    uint32_t ax = x < 0 ? -x : x, ay = y < 0 ? -y : y;
    if (ax > ay)
        return x > 0 ? SIDE_RIGHT : SIDE_LEFT;
    if (ay > ax)
        return y > 0 ? SIDE_TOP : SIDE_BOTTOM;
    if (x == 0)
        return SIDE_RIGHT;
    if (((x > 0) == (y > 0)) == (ccw != 0)) /* x shrinks next: x is major */
        return y > 0 ? SIDE_TOP : SIDE_BOTTOM;
    return x > 0 ? SIDE_RIGHT : SIDE_LEFT;
}

/* §4.2, one arc event from (*x, *y) with *f = x^2 + y^2 - R2. Sets the axes that
 * step (bit 0 X, bit 1 Y) and those that step toward minus; returns the band key
 * min(|v|, |v + 1|). Adds, compares and sign tests only. */
static inline uint32_t arc_event_step(int32_t *x, int32_t *y, int32_t *f, uint8_t ccw,
                                      uint8_t *axes, uint8_t *neg)
{
    uint8_t side = arc_side(*x, *y, ccw);
    uint8_t x_major = side & 1; /* TOP, BOTTOM */
    uint8_t sigma_pos = ((side == SIDE_RIGHT || side == SIDE_BOTTOM) == (ccw != 0));
    uint8_t tau_pos = (side == SIDE_RIGHT || side == SIDE_TOP);
    int32_t c_maj = x_major ? *x : *y, c_mnr = x_major ? *y : *x;
    int32_t v = sigma_pos ? c_maj : -c_maj;
    int32_t f_major = *f + v + v + 1;
    uint8_t s_pos = (v >= 0) ? !tau_pos : tau_pos; /* inward once past the axis */
    int32_t f_diag = f_major + (s_pos ? c_mnr + c_mnr : -(c_mnr + c_mnr)) + 1;
    uint8_t maj_bit = x_major ? 1 : 2, mnr_bit = x_major ? 2 : 1;
    uint8_t step = maj_bit, minus = sigma_pos ? 0 : maj_bit;
    if ((f_diag < 0 ? -f_diag : f_diag) < (f_major < 0 ? -f_major : f_major)) {
        c_mnr += s_pos ? 1 : -1;
        *f = f_diag;
        step |= mnr_bit;
        if (!s_pos)
            minus |= mnr_bit;
    } else {
        *f = f_major;
    }
    c_maj += sigma_pos ? 1 : -1;
    if (x_major) {
        *x = c_maj;
        *y = c_mnr;
    } else {
        *x = c_mnr;
        *y = c_maj;
    }
    *axes = step;
    *neg = minus;
    return v >= 0 ? (uint32_t)v : (uint32_t)(-(v + 1));
}

struct arc_plan {
    int32_t px, py;         /* P*, relative to the centre */
    uint32_t n_arc;
    uint16_t first_key;     /* NO_FIRST_KEY when the arc part is empty */
    uint32_t scale;         /* true length / table weight, Q20 (§5.3) */
    int32_t xmin, xmax, ymin, ymax; /* every visited point, relative (§7) */
};

/* §4.4-4.5: walk the sides from start to P*; the plan (static, valid until the
 * next call), or 0 on failure. */
const struct arc_plan *arc_walk(int32_t sx, int32_t sy, int32_t ex, int32_t ey, uint8_t ccw);
/* §5.3: compact thresholds and cruise intervals for a queued arc block. */
void band_table_fill(struct band_table *t, const struct block *b);

#endif
