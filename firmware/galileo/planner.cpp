/* Per-command setup (docs/motion.md §2, §3.1, §5.1-5.2, §7, §8), main loop only.
 * A port of galileo_cnc/machine/machine.py: commands become queued blocks, with
 * every division and square root done here, never in the interrupt. Blocks of
 * one command are staged and committed together, so a refused command leaves
 * nothing behind (the reference refuses a command before any of its steps). */
#include <avr/pgmspace.h>
#include <string.h>

#include "arcs.h"
#include "config.h"
#include "intmath.h"
#include "planner.h"

#if CFG_X_TRAVEL_MAX_STEPS - CFG_X_TRAVEL_MIN_STEPS > 46000L \
    || CFG_Y_TRAVEL_MAX_STEPS - CFG_Y_TRAVEL_MIN_STEPS > 46000L
#error "travel above 46000 steps per axis: the line setup's 32-bit n*n would overflow"
#endif
#if CFG_MAX_FEED_STEPS_PER_S > 65535L
#error "MAX_FEED_STEPS_PER_S above 65535: its square leaves the ramp length's 32 bits"
#endif
#if CFG_RAMP_START_FACTOR < 2 || CFG_RAMP_START_FACTOR > 8 || (CFG_RAMP_START_FACTOR - 1) \
    * (CFG_MAX_FEED_STEPS_PER_S * CFG_MAX_FEED_STEPS_PER_S / CFG_ACCEL_STEPS_PER_S2 + 1) > 0xFFFFFFL
#error "RAMP_START_FACTOR outside 2..8, or ACCEL_STEPS_PER_S2 so low that R leaves its 24 bits"
#endif

/* Z without an end-stop (§7): its travel is a length, not a place. The machine
 * keeps Z within one travel's length of every Z it has been planned at since
 * power-on and of the pen heights (where a pen may stand at power-on), so a
 * user who powered on with the pen lifted can still lower it. */
#define Z_FLOATS (CFG_Z_HOME_PIN < 0)
#define PEN_Z_LO (CFG_PEN_DOWN_Z_STEPS < CFG_PEN_UP_Z_STEPS ? CFG_PEN_DOWN_Z_STEPS : CFG_PEN_UP_Z_STEPS)
#define PEN_Z_HI (CFG_PEN_DOWN_Z_STEPS < CFG_PEN_UP_Z_STEPS ? CFG_PEN_UP_Z_STEPS : CFG_PEN_DOWN_Z_STEPS)

struct planner pl;
struct limit_violation pl_violation;

static uint8_t staged;
static uint8_t block_flags;

void planner_init(void)
{
    memset(&pl, 0, sizeof(pl));
    pl.feed_steps_per_s = CFG_FEED_STEPS_PER_S;
    pl.z_seen[0] = PEN_Z_LO;
    pl.z_seen[1] = PEN_Z_HI;
}

static struct block *stage(uint8_t kind)
{
    struct block *b = queue_slot(staged++);
    memset(b, 0, sizeof(*b));
    b->kind = kind;
    b->flags = block_flags;
    return b;
}

/* Subticks per step along one axis at `feed`: round(512e6 / F) (§5.1). */
static uint32_t axial_interval_sub(uint32_t feed)
{
    return (2UL * CFG_TICKS_PER_S * 256UL + feed) / (2 * feed);
}

/* R = ceil((k - 1) F^2 / A), k = CFG_RAMP_START_FACTOR (§5.2). F < 65536 keeps F^2 in
 * 32 bits; (k - 1) F^2 is split as (k - 1) (q A + r) so no product leaves them. */
static uint32_t ramp_events(uint32_t feed)
{
    const uint32_t k1 = CFG_RAMP_START_FACTOR - 1, a = CFG_ACCEL_STEPS_PER_S2;
    uint32_t f2 = feed * feed;
    return k1 * (f2 / a) + (k1 * (f2 % a) + a - 1) / a;
}

static void set_ramp(struct block *b, uint32_t ref_sub, uint32_t ramp)
{
    b->ramp = ramp;
    b->step_sub = ramp ? (2UL * (CFG_RAMP_START_FACTOR - 1) * ref_sub + ramp) / (2 * ramp) : 0;
    b->ramp_total_sub = ramp * b->step_sub;
}

static const int32_t TRAVEL_MIN[3] = {CFG_X_TRAVEL_MIN_STEPS, CFG_Y_TRAVEL_MIN_STEPS,
                                      CFG_Z_TRAVEL_MIN_STEPS};
static const int32_t TRAVEL_MAX[3] = {CFG_X_TRAVEL_MAX_STEPS, CFG_Y_TRAVEL_MAX_STEPS,
                                      CFG_Z_TRAVEL_MAX_STEPS};

/* §7: refuse a move whose visited range [lo, hi] (machine steps) on axis a
 * leaves the travel, widened to where the head stands: a head outside the
 * travel (a failed or stopped homing) may move back towards it, never further
 * out. A move checks its axes in order 0, 1, 2: the first that leaves is
 * reported, with the travel's own limit. Scalars, not arrays: no box on the
 * caller's stack. */
static __attribute__((noinline)) uint8_t check_axis(uint8_t a, int32_t lo, int32_t hi)
{
    int32_t tmin = TRAVEL_MIN[a], tmax = TRAVEL_MAX[a];
    if (Z_FLOATS && a == 2) {
        tmin = pl.z_seen[1] - (CFG_Z_TRAVEL_MAX_STEPS - CFG_Z_TRAVEL_MIN_STEPS);
        tmax = pl.z_seen[0] + (CFG_Z_TRAVEL_MAX_STEPS - CFG_Z_TRAVEL_MIN_STEPS);
    }
    int32_t here = pl.pos[a];
    if ((lo < tmin && lo < here) || (hi > tmax && hi > here)) {
        pl_violation.axis = a;
        pl_violation.above = !(lo < tmin && lo < here);
        pl_violation.value = pl_violation.above ? hi : lo;
        pl_violation.limit = pl_violation.above ? tmax : tmin;
        return ERR_SOFT_LIMIT;
    }
    return 0;
}

static uint8_t check_segment(const int32_t target[3])
{
    for (uint8_t a = 0; a < 3; a++) {
        int32_t lo = pl.pos[a] < target[a] ? pl.pos[a] : target[a];
        int32_t hi = pl.pos[a] < target[a] ? target[a] : pl.pos[a];
        uint8_t err = check_axis(a, lo, hi);
        if (err)
            return err;
    }
    return 0;
}

/* §3.1 + §5.1: one line block to `target` (machine steps). */
static uint8_t line_to(const int32_t target[3], uint32_t feed, uint8_t ramped, uint8_t check)
{
    if (check) {
        uint8_t err = check_segment(target);
        if (err)
            return err;
    }
    uint32_t d_abs[3], n = 0;
    uint8_t neg = 0;
    for (uint8_t a = 0; a < 3; a++) {
        int32_t d = target[a] - pl.pos[a];
        d_abs[a] = d < 0 ? -d : d;
        if (d < 0)
            neg |= 1 << a;
        if (d_abs[a] > n)
            n = d_abs[a];
    }
    if (n == 0)
        return 0;
    struct block *b = stage(BLOCK_LINE);
    b->n = n;
    for (uint8_t a = 0; a < 3; a++)
        b->u.line.inc[a] = 2 * d_abs[a];
    b->u.line.neg = neg;
    uint64_t d2 = (uint64_t)d_abs[0] * d_abs[0] + (uint64_t)d_abs[1] * d_abs[1]
                  + (uint64_t)d_abs[2] * d_abs[2];
    uint32_t n2 = n * n;
    uint32_t rho = d2 == n2 ? 1UL << CFG_RHO_BITS : isqrt32(udiv64_32(d2 << 30, n2));
    b->base_sub = mul_round_shift(axial_interval_sub(feed), rho, CFG_RHO_BITS);
    set_ramp(b, b->base_sub, ramped ? ramp_events(feed) : 0);
    for (uint8_t a = 0; a < 3; a++)
        pl.pos[a] = target[a];
    if (target[2] < pl.z_seen[0])
        pl.z_seen[0] = target[2];
    if (target[2] > pl.z_seen[1])
        pl.z_seen[1] = target[2];
    return 0;
}

static uint8_t z_to(int32_t z_work)
{
    int32_t target[3] = {pl.pos[0], pl.pos[1], z_work + pl.origin[2]};
    return line_to(target, CFG_Z_FEED_STEPS_PER_S, 1, 1);
}

static uint8_t pause(uint32_t ms)
{
    if (ms) {
        struct block *b = stage(BLOCK_PAUSE);
        b->n = ms * (CFG_TICKS_PER_S / 1000);
    }
    return 0;
}

static uint8_t rapid(const int32_t *args)
{
    int32_t target[3] = {args[0] + pl.origin[0], args[1] + pl.origin[1],
                         CFG_PEN_UP_Z_STEPS + pl.origin[2]};
    uint8_t err = check_segment(target);
    if (!err)
        err = z_to(CFG_PEN_UP_Z_STEPS);
    if (!err)
        err = line_to(target, CFG_RAPID_STEPS_PER_S, 1, 1);
    return err;
}

static uint8_t line(const int32_t *args, uint8_t nargs)
{
    int32_t target[3] = {args[0] + pl.origin[0], args[1] + pl.origin[1],
                         nargs > 2 ? args[2] + pl.origin[2] : pl.pos[2]};
    return line_to(target, pl.feed_steps_per_s, 1, 1);
}

/* rel[i] of an arc command: start (i = 0, 1) and end (i = 2, 3) relative to the
 * centre, X for even i. */
static inline __attribute__((always_inline)) int32_t arc_rel(const int32_t *args, uint8_t i)
{
    uint8_t a = i & 1;
    int32_t c = pl.pos[a] + args[2 + a];
    int32_t p = (i & 2) ? args[a] + pl.origin[a] : pl.pos[a];
    return p - c;
}

/* The arc block once the walk has succeeded (out of line: its locals stay off
 * the stack during the walk). pl is unchanged since arc() started. */
static __attribute__((noinline)) uint8_t arc_queue(const int32_t *args, uint8_t ccw,
                                                   const struct arc_plan *p)
{
    int32_t ex = args[0] + pl.origin[0], ey = args[1] + pl.origin[1];
    int32_t cx = pl.pos[0] + args[2], cy = pl.pos[1] + args[3];
    uint8_t err = check_axis(0, p->xmin + cx, p->xmax + cx);
    if (!err)
        err = check_axis(1, p->ymin + cy, p->ymax + cy);
    if (!err)
        err = check_axis(2, pl.pos[2], pl.pos[2]);
    if (err)
        return err;
    int32_t corr_x = (ex - cx) - p->px, corr_y = (ey - cy) - p->py;
    uint32_t n_corr = (uint32_t)(corr_x < 0 ? -corr_x : corr_x);
    uint32_t n_corr_y = (uint32_t)(corr_y < 0 ? -corr_y : corr_y);
    if (n_corr_y > n_corr)
        n_corr = n_corr_y;
    if (p->n_arc + n_corr == 0)
        return 0;
    struct block *b = stage(BLOCK_ARC);
    b->n = p->n_arc + n_corr;
    b->u.arc.x0 = (int16_t)(pl.pos[0] - cx);
    b->u.arc.y0 = (int16_t)(pl.pos[1] - cy);
    b->u.arc.axial_sub = axial_interval_sub(pl.feed_steps_per_s);
    b->u.arc.n_arc = p->n_arc;
    b->u.arc.corr_x = corr_x;
    b->u.arc.corr_y = corr_y;
    b->u.arc.first_key = p->first_key;
    b->u.arc.scale = p->scale;
    b->u.arc.ccw = ccw;
    b->u.arc.table = NO_BAND_TABLE;
    set_ramp(b, b->u.arc.axial_sub, ramp_events(pl.feed_steps_per_s));
    pl.pos[0] = ex;
    pl.pos[1] = ey;
    return 0;
}

/* Changes pl only on success (in arc_queue's last lines): no snapshot needed. */
static __attribute__((noinline)) uint8_t arc(const int32_t *args, uint8_t ccw)
{
    for (uint8_t i = 0; i < 4; i++) {
        int32_t r = arc_rel(args, i);
        if (r > CFG_MAX_ARC_COORD || r < -CFG_MAX_ARC_COORD)
            return ERR_ARC_TOO_LARGE;
    }
    const struct arc_plan *p = arc_walk(arc_rel(args, 0), arc_rel(args, 1), arc_rel(args, 2),
                                        arc_rel(args, 3), ccw);
    if (!p)
        return ERR_BAD_ARGUMENT;
    return arc_queue(args, ccw, p);
}

#define HOME_AXES ((CFG_X_HOME_PIN >= 0) + (CFG_Y_HOME_PIN >= 0) + (CFG_Z_HOME_PIN >= 0))
static const int8_t HOME_PIN[3] = {CFG_X_HOME_PIN, CFG_Y_HOME_PIN, CFG_Z_HOME_PIN};
static const int8_t HOME_DIR[3] = {CFG_X_HOME_DIR, CFG_Y_HOME_DIR, CFG_Z_HOME_DIR};

/* §8: per axis with a switch, Z then X then Y: seek, pull-off, zero. */
static uint8_t home(void)
{
    static const uint8_t order[3] = {2, 0, 1};
    uint8_t first = BLOCK_FLAG_HOME_FIRST;
    block_flags = BLOCK_FLAG_HOMING;
    for (uint8_t i = 0; i < 3; i++) {
        uint8_t a = order[i];
        if (HOME_PIN[a] < 0)
            continue;
        struct block *b = stage(BLOCK_SEEK);
        b->flags |= first;
        first = 0;
        b->n = SEEK_UNKNOWN_EVENTS;
        b->base_sub = axial_interval_sub(CFG_HOME_FEED_STEPS_PER_S);
        b->u.seek.axis = a;
        b->u.seek.dir = HOME_DIR[a];
        b->u.seek.max_steps = (uint32_t)(TRAVEL_MAX[a] - TRAVEL_MIN[a])
                              + 2UL * CFG_HOME_PULLOFF_STEPS + CFG_HOME_DEBOUNCE_READS;
        /* The pull-off's geometry does not depend on where the switch tripped. */
        int32_t target[3] = {pl.pos[0], pl.pos[1], pl.pos[2]};
        target[a] -= HOME_DIR[a] * (int32_t)CFG_HOME_PULLOFF_STEPS;
        line_to(target, CFG_HOME_FEED_STEPS_PER_S, 0, 0);
        stage(BLOCK_ZERO_AXIS)->u.axis = a;
        pl.pos[a] = 0;
        pl.origin[a] = 0;
    }
    block_flags = 0;
    return 0;
}

/* The blocks each command reserves come from the generated table (protocol.h),
 * the one definition the simulated machine reads too. */
uint8_t planner_blocks_needed(uint8_t cmd)
{
    uint8_t blocks = pgm_read_byte(&proto_commands[cmd].blocks);
    return cmd == CMD_HOME ? blocks * HOME_AXES : blocks;
}

/* Every command but the arcs. On an error, pl is restored: only pos and z_seen
 * can have changed by then (a first block queued: Rapid's or Flash's Z move), as
 * origin, feed and ended change only in commands that cannot fail after changing
 * them. */
static __attribute__((noinline)) uint8_t execute_other(uint8_t cmd, const int32_t *args,
                                                       uint8_t nargs)
{
    int32_t saved_pos[3] = {pl.pos[0], pl.pos[1], pl.pos[2]};
    int32_t saved_z_seen[2] = {pl.z_seen[0], pl.z_seen[1]};
    uint8_t err = 0;
    switch (cmd) {
    case CMD_RAPID: err = rapid(args); break;
    case CMD_LINE: err = line(args, nargs); break;
    case CMD_PEN_UP: err = z_to(CFG_PEN_UP_Z_STEPS); break;
    case CMD_PEN_DOWN: err = z_to(CFG_PEN_DOWN_Z_STEPS); break;
    case CMD_FLASH:
        err = z_to(CFG_PEN_DOWN_Z_STEPS);
        if (!err)
            err = pause(nargs ? (uint32_t)args[0] : CFG_FLASH_DWELL_MS);
        if (!err)
            err = z_to(CFG_PEN_UP_Z_STEPS);
        break;
    case CMD_DWELL: err = pause((uint32_t)args[0]); break;
    case CMD_FEED:
        if (args[0] < CFG_MIN_FEED_STEPS_PER_S || args[0] > CFG_MAX_FEED_STEPS_PER_S)
            err = ERR_FEED_RANGE;
        else
            pl.feed_steps_per_s = (uint32_t)args[0];
        break;
    case CMD_JOG: {
        int32_t target[3] = {pl.pos[0] + args[0], pl.pos[1] + args[1], pl.pos[2] + args[2]};
        err = line_to(target, pl.feed_steps_per_s, 1, 1);
        break;
    }
    case CMD_ORIGIN: {
        struct block *b = stage(BLOCK_ORIGIN);
        for (uint8_t a = 0; a < 3; a++)
            pl.origin[a] = b->u.origin[a] = pl.pos[a];
        break;
    }
    case CMD_HOME: err = home(); break;
    case CMD_MOTORS: break; /* the seed wiring has no driver enable pin */
    case CMD_END_JOB:
        err = z_to(CFG_PEN_UP_Z_STEPS);
        if (!err)
            pl.ended = 1;
        break;
    }
    if (err) {
        for (uint8_t a = 0; a < 3; a++)
            pl.pos[a] = saved_pos[a];
        pl.z_seen[0] = saved_z_seen[0];
        pl.z_seen[1] = saved_z_seen[1];
    }
    return err;
}

uint8_t planner_execute(uint8_t cmd, const int32_t *args, uint8_t nargs)
{
    uint8_t err;
    staged = 0;
    /* LX, CWX, CCX: the move's exit index first (§5.7), then LINE's or ARC's. */
    uint32_t exit = 0;
    if (cmd == CMD_LINE_X || cmd == CMD_ARC_CW_X || cmd == CMD_ARC_CCW_X) {
        exit = (uint32_t)*args++;
        nargs--;
        cmd = cmd == CMD_LINE_X ? CMD_LINE : cmd == CMD_ARC_CW_X ? CMD_ARC_CW : CMD_ARC_CCW;
    }
    if (cmd == CMD_ARC_CW || cmd == CMD_ARC_CCW) /* the deep one: no snapshot under it */
        err = arc(args, cmd == CMD_ARC_CCW);
    else
        err = execute_other(cmd, args, nargs);
    if (err)
        staged = 0;
    else if (staged) {
        struct block *b = queue_slot(staged - 1);
        b->exit = (__uint24)(exit < b->ramp ? exit : b->ramp);
        queue_commit(staged);
    }
    return err;
}

void planner_resync(void)
{
    stepper_position(pl.pos, pl.origin);
}
