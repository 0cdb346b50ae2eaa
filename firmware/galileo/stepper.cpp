/* Timer1 step interrupt: executes queued blocks event by event.
 *
 * Timing (docs/motion.md §5.5): Timer1 runs free at 16 MHz / 8 (one tick =
 * 0.5 us) and is never written or stopped; every event is a compare match at an
 * absolute tick, OCR1A += delta. Deltas above 65535 ticks take extra "wrap"
 * wake-ups that step nothing. No CTC mode and no TCNT1 writes, so simavr's
 * quirks (OCR = 0 in CTC never fires, TCNT writes ignored while stopped) do not
 * apply.
 *
 * Pin edge latency: the compare vector is a naked stub that writes the whole
 * step/dir port from `st_port_pulse` (prepared by the previous interrupt) before
 * anything else, so each step's rising edge follows its compare match by a fixed
 * number of cycles whatever this event computes. The body then ends the pulse,
 * accounts the event, and prepares the next one (directions are written then,
 * one full interval before their step).
 *
 * Two bodies: the stub jumps to stepper_fast_isr when the previous event set
 * st_fast (a line event that is neither the first nor the last of its run,
 * intervals below 2^24 subticks, n < 2^15: 16- and 24-bit arithmetic, no
 * calls, so a short prologue), else to stepper_event_isr (everything else).
 * Budget (bench/bench_firmware.py, simavr, `make PROFILE=1`): a fast two-axis
 * line event costs ~320 cycles in all (~200 of computation, entry and exit
 * included: 364 at most), a one-axis one ~290; the general body ~500 for a
 * line event and ~900 for an arc event. 50 ticks (the fastest interval) are
 * 400 cycles. A compare match that would already be in
 * the past is moved 8 ticks ahead and counted in st_overruns (reported as
 * msg:13): the rate is clamped, never skipped. The interrupt never re-enables
 * interrupts, so it cannot nest.
 */
#include <avr/interrupt.h>
#include <avr/io.h>

#include "arcs.h"
#include "config.h"
#include "pins.h"
#include "stepper.h"

/* `make -C firmware PROFILE=1`: Uno pin A0 is high while a step event is
 * computed (bench/bench_firmware.py measures it in simavr's pin trace). */
#ifdef GALILEO_PROFILE
#define PROFILE_BEGIN() (PORTC |= _BV(0))
#define PROFILE_END() (PORTC &= ~_BV(0))
#else
#define PROFILE_BEGIN()
#define PROFILE_END()
#endif

#define QUEUE_SLOTS (PROTO_QUEUE_BLOCKS + 1) /* one slot stays empty: full != empty */
#define KICK_TICKS 64                       /* start of work after an idle machine */
#define LATE_MARGIN_TICKS 8

static struct block queue[QUEUE_SLOTS];
static volatile uint8_t q_head, q_tail;

struct band_table st_band_tables[N_BAND_TABLES];
volatile uint8_t st_phase = PHASE_IDLE;
volatile uint8_t st_alarm_code;
volatile uint8_t st_hold_request, st_abort_request;
volatile uint16_t st_overruns;

/* Live machine position, steps; the fast path updates the low half and carries. */
static volatile union {
    int32_t v;
    struct {
        uint16_t lo, hi;
    } h;
} st_pos_u[3];
#define st_pos(a) (st_pos_u[a].v)
static volatile int32_t st_origin[3]; /* live work origin, machine steps */

extern "C" {
volatile uint8_t st_port_pulse; /* written to the port by the naked stub */
}
static uint8_t port_rest;  /* port without step bits, with the pending event's directions */
static uint8_t port_base;  /* bits of the port that are not ours */
static uint8_t pulse_bits; /* step bits of the pending event */
static uint8_t ev_axes, ev_neg; /* pending event: axes that step, those toward minus */

static uint16_t ocr;   /* compare value of the pending (or last) event */
static uint16_t wraps; /* empty wake-ups before the pending event */

/* The run (§5.4): up = k - first, down = last - k, m = min(up, down, R). */
static struct block *cur;
/* 24-bit counters (avr-gcc's __uint24): R < 2^24 (planner.cpp) and n < 2^24 events. */
typedef __uint24 events_t;
#define EVENTS_UNKNOWN ((events_t)0xFFFFFF) /* a seek's length until the switch trips */
/* up_sat, down and m_ramp, also as their low 16 bits: the fast path's runs
 * have fewer than 2^15 events, so the high byte stays 0 there. */
typedef union {
    events_t v;
    uint16_t lo;
} events_u;
static events_u up_u;     /* up_sat = min(k - first, R) */
static events_u down_u;   /* down = last - k */
static events_u m_u;      /* m_ramp = min(up, fall) */
/* fall = min(exit + down, events to a committed stop): the ramp's falling bound
 * (§5.7). Both terms lose one per event, so their minimum does too. */
static events_u fall_u;
#define fall (fall_u.v)
/* A committed stop beyond the current block (a hold, or the end of what the queue
 * holds: never overrun): the events after the block's last one up to it; 0: none. */
static events_t stop_beyond;
static events_t m_left;   /* ramp index of the last event: the next block enters at it */
/* fall - down, constant between the slow path's changes: the fast path keeps only
 * fall, and the slow path finds down again from it. */
static events_t exit_eff;
/* The fast path may run while fall > guard16 (= exit_eff + the events before the end
 * of the queue could bound the index: checked in the slow path): the next event is
 * then not its run's last. */
static uint16_t guard16;
/* Events of the queued line and arc blocks, cumulative, counted by the interrupt: the
 * ready ones (committed; an arc once its band table is filled) and the entered ones;
 * their difference is what lies ahead. The main loop writes nothing for it. */
static events_t ready_events, entered_events; /* modulo 2^24: only differences count */
static uint8_t ready_slot;  /* the first queued block not yet counted in ready_events */
#define up_sat (up_u.v)
#define down (down_u.v)
#define m_ramp (m_u.v)
static uint16_t ramp16;   /* min(R, 0xFFFF) */
static events_t ramp;     /* R */
static events_t cut;      /* events a hold removed from this run: the block's rest */
static events_t run_events; /* events of the next run of `cur` (all of it, or the rest) */
static uint32_t seek_steps;
static uint32_t step_sub, base_sub;
static uint8_t frac;
/* extra_sub (= (R - m) * step_sub) as a 32-bit value and, when it is below
 * 2^24, as its low 24 bits: the fast path works on those. */
static union {
    uint32_t v;
    __uint24 lo;
} extra;
#define extra_sub (extra.v)

/* The fast path (stepper_fast_isr): a line run whose every interval is below
 * 2^24 subticks, so 24-bit arithmetic and one compare per event suffice. */
static uint8_t run_fast;            /* this run may use the fast path */
static __uint24 base24, step24;     /* base_sub and step_sub of that run */
static __uint24 ival24;             /* base24 + extra.lo: the pending interval */
extern "C" {
volatile uint8_t st_fast;           /* bit 0: the pending event takes the fast path */
}

/* Line and arc-correction Bresenham state (§3.2). */
typedef union {
    __uint24 v;
    uint16_t lo;
} u24_u;
static u24_u err_u[3];                 /* err[a], also as 16 bits when 2n < 2^16 */
#define err(a) (err_u[a].v)
static __uint24 inc[3], wrap; /* 2n < 2^24 */
/* Fast path (n < 2^15, so 2n < 2^16): err += inc; if err >= wrap, err -= wrap
 * is "if err >= thr: err -= thr else err += inc" with thr = wrap - inc. */
static uint16_t thr16[3], inc16[3];
static uint8_t line_axes;              /* axes with inc != 0 */
static uint8_t line_neg, line_port; /* line directions, as masks and on the port */

/* Arc state (§4.2) and its band table (§5.3). */
static int32_t arc_x, arc_y, arc_f;
static uint32_t arc_left;
static uint8_t arc_ccw, band, corr_started;
static struct band_table *bands;

static uint8_t seek_count;


ISR(TIMER1_COMPA_vect, ISR_NAKED)
{
    /* The step edge first; then the body, chosen without touching SREG
     * (lds, sbrs, pop and jumps leave it alone). */
    __asm__ __volatile__("push r24\n\t"
                         "lds r24, st_port_pulse\n\t"
                         "out %[port], r24\n\t"
                         "lds r24, st_fast\n\t"
                         "sbrs r24, 0\n\t"
                         "rjmp 1f\n\t"
                         "pop r24\n\t"
                         "jmp stepper_fast_isr\n\t"
                         "1: pop r24\n\t"
                         "jmp stepper_event_isr\n\t" ::[port] "I"(_SFR_IO_ADDR(STEPPER_PORT)));
}

static inline uint8_t home_switch_active(uint8_t axis)
{
    switch (axis) {
#if CFG_X_HOME_PIN >= 0
    case 0: return HOME_ACTIVE(CFG_X_HOME_PIN);
#endif
#if CFG_Y_HOME_PIN >= 0
    case 1: return HOME_ACTIVE(CFG_Y_HOME_PIN);
#endif
#if CFG_Z_HOME_PIN >= 0
    case 2: return HOME_ACTIVE(CFG_Z_HOME_PIN);
#endif
    default: return 0;
    }
}

static void stop(uint8_t phase)
{
    TIMSK1 &= ~_BV(OCIE1A);
    st_fast = 0;
    m_left = 0;  /* a standing machine starts from rest */
    stop_beyond = 0;
    wraps = 0;
    ev_axes = 0;
    st_port_pulse = port_rest;
    st_phase = phase;
}

static void alarm(uint8_t code)
{
    st_alarm_code = code;
    stop(PHASE_ALARM);
}

/* Next compare `delta_ticks` (>= 1) after the current one. */
static inline __attribute__((always_inline)) void schedule(uint32_t delta_ticks)
{
    uint16_t now = TCNT1;
    uint16_t elapsed = now - ocr;
    uint16_t low = (uint16_t)delta_ticks;
    uint16_t w = (uint16_t)((delta_ticks - 1) >> 16);
    uint16_t next = ocr + low;
    /* Ticks to the first match: low, or a whole wrap when low == 0. */
    if (low != 0 && elapsed + LATE_MARGIN_TICKS >= low) {
        if (w) {
            w--; /* that match is missed; the next one is a wrap later */
        } else {
            next = now + LATE_MARGIN_TICKS;
            st_overruns++;
        }
    }
    ocr = next;
    OCR1A = next;
    wraps = w;
    st_port_pulse = w ? port_rest : (uint8_t)(port_rest | pulse_bits);
}

/* Step bits of an axis mask (bit 0 X, 1 Y, 2 Z). */
static const uint8_t STEP_BITS_OF[8] = {
    0, X_STEP_BIT, Y_STEP_BIT, X_STEP_BIT | Y_STEP_BIT, Z_STEP_BIT, X_STEP_BIT | Z_STEP_BIT,
    Y_STEP_BIT | Z_STEP_BIT, X_STEP_BIT | Y_STEP_BIT | Z_STEP_BIT};
/* Direction bits of a "toward minus" mask: high is toward plus. */
static uint8_t dir_bits_of(uint8_t neg)
{
    return ((neg & 1) ? 0 : X_DIR_BIT) | ((neg & 2) ? 0 : Y_DIR_BIT) | ((neg & 4) ? 0 : Z_DIR_BIT);
}

static void start_line(uint32_t n, const uint32_t *incs, uint8_t neg)
{
    err(0) = err(1) = err(2) = n;
    inc[0] = incs[0];
    inc[1] = incs[1];
    inc[2] = incs[2];
    line_axes = (incs[0] ? 1 : 0) | (incs[1] ? 2 : 0) | (incs[2] ? 4 : 0);
    wrap = n + n;
    for (uint8_t a = 0; a < 3; a++) {
        thr16[a] = (uint16_t)(wrap - inc[a]);
        inc16[a] = (uint16_t)inc[a];
    }
    line_neg = neg;
    line_port = port_base | dir_bits_of(neg);
}

/* §3.2: three accumulators; at most one wrap each per event. */
static inline __attribute__((always_inline)) void line_event(void)
{
    uint8_t axes = 0, active = line_axes;
    __uint24 w = wrap, e;
    if (active & 1) {
        e = err(0) + inc[0];
        if (e >= w) { e -= w; axes = 1; }
        err(0) = e;
    }
    if (active & 2) {
        e = err(1) + inc[1];
        if (e >= w) { e -= w; axes |= 2; }
        err(1) = e;
    }
    if (active & 4) {
        e = err(2) + inc[2];
        if (e >= w) { e -= w; axes |= 4; }
        err(2) = e;
    }
    ev_axes = axes;
    ev_neg = line_neg;
    port_rest = line_port;
}

/* §4.2 and §5.3, then §4.6 (the correction line); out of line so that line
 * events do not pay for its registers. */
static void __attribute__((noinline)) arc_event(void)
{
    if (arc_left == 0) {
        if (!corr_started) {
            int32_t cx = cur->u.arc.corr_x, cy = cur->u.arc.corr_y;
            uint32_t incs[3] = {(uint32_t)(cx < 0 ? -cx : cx) << 1,
                                (uint32_t)(cy < 0 ? -cy : cy) << 1, 0};
            uint32_t n = (incs[0] > incs[1] ? incs[0] : incs[1]) >> 1;
            start_line(n, incs, (cx < 0 ? 1 : 0) | (cy < 0 ? 2 : 0));
            base_sub = bands->base_sub[band];
            corr_started = 1;
        }
        line_event();
        return;
    }
    arc_left--;
    uint8_t axes, neg;
    uint32_t key = arc_event_step(&arc_x, &arc_y, &arc_f, arc_ccw, &axes, &neg);
    ev_axes = axes;
    ev_neg = neg;
    uint8_t rest = port_rest;
    if (axes & 1)
        rest = (neg & 1) ? rest & ~X_DIR_BIT : rest | X_DIR_BIT;
    if (axes & 2)
        rest = (neg & 2) ? rest & ~Y_DIR_BIT : rest | Y_DIR_BIT;
    port_rest = rest;
    uint8_t b = band;
    while (b + 1 < bands->count && key >= bands->v[b + 1])
        b++;
    while (key < bands->v[b])
        b--;
    band = b;
    base_sub = bands->base_sub[b];
}

/* Geometry of the next event, its directions on the port, its time. */
static inline __attribute__((always_inline)) void prepare_event(uint8_t kind)
{
    if (kind == BLOCK_LINE) {
        line_event();
    } else if (kind == BLOCK_ARC) {
        arc_event();
    } else { /* BLOCK_SEEK: ev_axes, ev_neg and port_rest were set on entry */
    }
    STEPPER_PORT = port_rest; /* directions now, the step edge one interval later */
    pulse_bits = STEP_BITS_OF[ev_axes];
    uint32_t sum = frac + base_sub + extra_sub;
    frac = (uint8_t)sum;
    schedule(sum >> CFG_FRAC_BITS);
}

static void enter_block(struct block *b)
{
    cur = b;
    run_events = b->kind == BLOCK_SEEK ? EVENTS_UNKNOWN : (events_t)b->n;
    if (b->kind == BLOCK_LINE || b->kind == BLOCK_ARC)
        entered_events += b->n;
    else
        m_left = 0;
    base_sub = b->base_sub;
    if (b->kind == BLOCK_LINE) {
        start_line(b->n, b->u.line.inc, b->u.line.neg);
    } else if (b->kind == BLOCK_ARC) {
        arc_x = b->u.arc.x0;
        arc_y = b->u.arc.y0;
        arc_f = 0;
        arc_left = b->u.arc.n_arc;
        arc_ccw = b->u.arc.ccw;
        bands = &st_band_tables[b->u.arc.table];
        band = bands->band0;
        corr_started = 0;
    } else if (b->kind == BLOCK_SEEK) {
        seek_count = 0;
        seek_steps = 0;
        ev_axes = 1 << b->u.seek.axis;
        ev_neg = b->u.seek.dir < 0 ? ev_axes : 0;
        port_rest = port_base | dir_bits_of(ev_neg);
    }
}

static void pop_block(void)
{
    if (cur->kind == BLOCK_ARC)
        bands->busy = 0;
    uint8_t h = q_head + 1;
    q_head = h == QUEUE_SLOTS ? 0 : h;
    cur = 0;
}

/* Never overrun (§5.7): the index stays at most the events left to the end of what
 * the queue holds. When that bounds it, the machine commits to stopping there (it
 * keeps braking even if the next block arrives meanwhile). Also sets guard16. */
static void count_ready(void)
{
    uint8_t slot = ready_slot;
    while (slot != q_tail) {
        struct block *b = &queue[slot];
        if (b->kind == BLOCK_ARC && b->u.arc.table == NO_BAND_TABLE)
            break;
        if (b->kind == BLOCK_LINE || b->kind == BLOCK_ARC)
            ready_events += (events_t)b->n;
        slot = slot + 1 == QUEUE_SLOTS ? 0 : slot + 1;
    }
    ready_slot = slot;
}

static void bound_by_queue(void)
{
    count_ready();
    events_t ahead = ready_events - entered_events;
    events_t least = up_sat < fall ? up_sat : fall;
    if (ahead < least && (uint32_t)down + ahead < least) {
        fall = down + ahead;
        stop_beyond = ahead;
    }
    exit_eff = fall - down;
    guard16 = (uint16_t)exit_eff + (ahead < exit_eff && ahead < ramp ? (uint16_t)(ramp - ahead) : 0);
}

/* Begin the next run: the rest of the current block after a hold, or the next
 * block (markers are applied on the way). Called at the end of a run, at a
 * pause's end and at a kick. */
static void start_next(void)
{
    while (!cur) {
        if (q_head == q_tail) {
            stop(PHASE_IDLE);
            return;
        }
        struct block *b = &queue[q_head];
        if (b->kind == BLOCK_ORIGIN || b->kind == BLOCK_ZERO_AXIS) {
            if (b->kind == BLOCK_ORIGIN) {
                st_origin[0] = b->u.origin[0];
                st_origin[1] = b->u.origin[1];
                st_origin[2] = b->u.origin[2];
            } else {
                if (home_switch_active(b->u.axis)) {
                    alarm(ERR_HOME_PULLOFF);
                    return;
                }
                st_pos(b->u.axis) = 0;
                st_origin[b->u.axis] = 0;
            }
            uint8_t h = q_head + 1;
            q_head = h == QUEUE_SLOTS ? 0 : h;
            continue;
        }
        if (b->kind == BLOCK_ARC && b->u.arc.table == NO_BAND_TABLE) {
            stop(PHASE_IDLE); /* the main loop fills the table and kicks again */
            return;
        }
        if (st_hold_request && !stop_beyond) { /* braking into this block: not yet */
            stop(PHASE_HELD);
            return;
        }
        if ((b->flags & BLOCK_FLAG_HOME_FIRST)
            && (home_switch_active(0) || home_switch_active(1) || home_switch_active(2))) {
            alarm(ERR_HOME_SWITCH_ACTIVE);
            return;
        }
        enter_block(b);
    }
    if (st_hold_request && !stop_beyond) {
        stop(PHASE_HELD);
        return;
    }
    if (cur->kind == BLOCK_PAUSE) {
        ev_axes = 0;
        pulse_bits = 0;
        st_phase = PHASE_WAIT;
        schedule(cur->n);
        return;
    }
    ramp = (events_t)cur->ramp;
    down = run_events - 1;
    cut = 0;
    /* §5.7: a block enters at the index the last event ran at (a resumed rest of a
     * held block from rest: stop() cleared m_left); a committed stop beyond the
     * block before bounds it, or ends the run inside it. */
    up_sat = m_left < ramp ? m_left : ramp;
    fall = down + cur->exit;
    if (stop_beyond) {
        events_t to_stop = stop_beyond - 1;
        if (to_stop <= down) {
            cut = down - to_stop;
            down = to_stop;
            stop_beyond = 0;
        } else {
            stop_beyond = to_stop - down;
        }
        if (to_stop < fall)
            fall = to_stop;
    }
    exit_eff = fall - down;
    if (up_sat) /* from rest the first event has m = 0 whatever bounds it */
        bound_by_queue();
    events_t m = up_sat < fall ? up_sat : fall;
    m_ramp = m;
    step_sub = cur->step_sub;
    extra_sub = m ? (uint32_t)(ramp - m) * step_sub : cur->ramp_total_sub;
    frac = 0;
    run_fast = cur->kind == BLOCK_LINE && cur->ramp_total_sub + base_sub < 0xFFFF00UL
               && cur->n < 0x8000UL && ramp < 0x4000;
    ramp16 = ramp > 0xFFFF ? 0xFFFF : (uint16_t)ramp;
    base24 = (__uint24)base_sub;
    step24 = (__uint24)step_sub;
    st_phase = PHASE_EVENT;
    prepare_event(cur->kind); /* the next event takes the slow path */
}

/* The body of the compare interrupt, entered by the stub's jmp: `signal` gives
 * it an interrupt prologue (saves SREG and registers) and a reti. */
#pragma GCC diagnostic ignored "-Wmisspelled-isr"
extern "C" void stepper_event_isr(void) __attribute__((signal, used, externally_visible));
void stepper_event_isr(void)
{
    STEPPER_PORT = port_rest; /* end of the step pulse */
    PROFILE_BEGIN();
    if (wraps) {
        if (--wraps == 0)
            st_port_pulse = port_rest | pulse_bits;
        return;
    }
    if (st_phase != PHASE_EVENT) { /* a kick or the end of a pause */
        if (cur && cur->kind == BLOCK_PAUSE)
            pop_block();
        start_next();
        return;
    }
    uint8_t axes = ev_axes, neg = ev_neg;
    if (axes & 1) { if (neg & 1) st_pos(0)--; else st_pos(0)++; }
    if (axes & 2) { if (neg & 2) st_pos(1)--; else st_pos(1)++; }
    if (axes & 4) { if (neg & 4) st_pos(2)--; else st_pos(2)++; }
    down = fall - exit_eff; /* the fast path kept fall only */
    uint8_t kind = cur->kind;
    if (kind == BLOCK_SEEK) { /* read the switch after the step (§8.2) */
        seek_steps++;
        if (home_switch_active(cur->u.seek.axis)) {
            if (++seek_count == CFG_HOME_DEBOUNCE_READS) {
                down = 0; /* tripped: this is the last event */
                cut = 0;
            }
        } else {
            seek_count = 0;
        }
        if (down && seek_steps >= cur->u.seek.max_steps) {
            alarm(ERR_HOME_NOT_FOUND);
            return;
        }
    }
    if (st_hold_request && fall > m_ramp) { /* §6: stop at k + m_k, maybe in a later block */
        if (down > m_ramp) {
            cut += down - m_ramp;
            down = m_ramp;
            stop_beyond = 0;
        } else {
            stop_beyond = m_ramp - down;
        }
        fall = m_ramp;
    }
    if (down == 0) {
        m_left = m_ramp;
        if (cut == 0) {
            pop_block();
            start_next();
        } else {
            run_events = cut; /* resume runs the rest with a fresh ramp */
            stop(PHASE_HELD);
        }
        return;
    }
    /* m' = min(up', fall') with up_sat = min(up, R). */
    if (up_sat < ramp)
        up_sat++;
    --down;
    --fall;
    bound_by_queue();
    events_t m = up_sat < fall ? up_sat : fall;
    if (m > m_ramp)
        extra_sub -= step_sub;
    else if (m < m_ramp)
        extra_sub += step_sub;
    m_ramp = m;
    prepare_event(kind);
    if (run_fast && !wraps && m && fall > guard16 && !st_hold_request) {
        ival24 = base24 + extra.lo;
        st_fast = 1;
    }
    PROFILE_END();
}

/* The body for a line event that is neither the first nor the last of its run
 * (st_fast, set by the event before): the same arithmetic as
 * stepper_event_isr's with 24-bit intervals and no calls, so that its prologue
 * saves few registers. With down >= 1 and m_ramp >= 1, a hold leaves down >= 1,
 * so this event never ends the run. */
extern "C" void stepper_fast_isr(void) __attribute__((signal, used, externally_visible));
void stepper_fast_isr(void)
{
    STEPPER_PORT = port_rest; /* end of the step pulse */
    PROFILE_BEGIN();
    uint8_t axes = ev_axes, neg = ev_neg;
    if (axes & 1) {
        uint16_t l = st_pos_u[0].h.lo;
        if (neg & 1) {
            if (l == 0) st_pos_u[0].h.hi--;
            st_pos_u[0].h.lo = l - 1;
        } else {
            if (++l == 0) st_pos_u[0].h.hi++;
            st_pos_u[0].h.lo = l;
        }
    }
    if (axes & 2) {
        uint16_t l = st_pos_u[1].h.lo;
        if (neg & 2) {
            if (l == 0) st_pos_u[1].h.hi--;
            st_pos_u[1].h.lo = l - 1;
        } else {
            if (++l == 0) st_pos_u[1].h.hi++;
            st_pos_u[1].h.lo = l;
        }
    }
    if (axes & 4) {
        uint16_t l = st_pos_u[2].h.lo;
        if (neg & 4) {
            if (l == 0) st_pos_u[2].h.hi--;
            st_pos_u[2].h.lo = l - 1;
        } else {
            if (++l == 0) st_pos_u[2].h.hi++;
            st_pos_u[2].h.lo = l;
        }
    }
    /* A hold makes the receive interrupt clear st_fast: the slow path sees it. */
    uint16_t mr = m_u.lo;
    uint16_t up = up_u.lo;
    if (up < ramp16)
        up_u.lo = ++up;
    uint16_t fl = fall_u.lo - 1;
    fall_u.lo = fl;
    uint16_t m = up < fl ? up : fl;
    __uint24 ival = ival24;
    if (m != mr) {
        if (m > mr) {
            extra.lo -= step24;
            ival -= step24;
        } else {
            extra.lo += step24;
            ival += step24;
        }
        ival24 = ival;
        m_u.lo = m;
    }
    /* §3.2 in 16 bits; the directions (port_rest, ev_neg) stay the line's. */
    uint8_t active = line_axes, ax = 0, pulse = 0;
    if (active & 1) {
        uint16_t e = err_u[0].lo;
        if (e >= thr16[0]) { e -= thr16[0]; ax = 1; pulse = X_STEP_BIT; }
        else e += inc16[0];
        err_u[0].lo = e;
    }
    if (active & 2) {
        uint16_t e = err_u[1].lo;
        if (e >= thr16[1]) { e -= thr16[1]; ax |= 2; pulse |= Y_STEP_BIT; }
        else e += inc16[1];
        err_u[1].lo = e;
    }
    if (active & 4) {
        uint16_t e = err_u[2].lo;
        if (e >= thr16[2]) { e -= thr16[2]; ax |= 4; pulse |= Z_STEP_BIT; }
        else e += inc16[2];
        err_u[2].lo = e;
    }
    ev_axes = ax;
    pulse_bits = pulse;
    __uint24 sum = ival + frac;
    frac = (uint8_t)sum;
    uint16_t low = (uint16_t)(sum >> 8); /* >= 1, < 2^16: no wrap wake-ups */
    uint16_t now = TCNT1;
    uint16_t next = ocr + low;
    if ((uint16_t)(now - ocr) + LATE_MARGIN_TICKS >= low) {
        next = now + LATE_MARGIN_TICKS;
        st_overruns++;
    }
    ocr = next;
    OCR1A = next;
    st_port_pulse = port_rest | pulse;
    st_fast = m != 0 && fl > guard16; /* the next event is not the run's last */
    PROFILE_END();
}

/* ---- main loop side ------------------------------------------------------------- */

void stepper_init(void)
{
    port_base = STEPPER_PORT & (uint8_t)~(STEP_MASK | DIR_MASK);
    port_rest = port_base;
    STEPPER_PORT = port_rest;
    STEPPER_DDR |= STEP_MASK | DIR_MASK;
#ifdef GALILEO_PROFILE
    DDRC |= _BV(0) | _BV(1) | _BV(2); /* A0: step ISR; A1, A2: commands.cpp */
#endif
    st_port_pulse = port_rest;
    TCCR1A = 0;           /* normal mode: free-running, never stopped or written */
    TCCR1B = _BV(CS11);   /* clk / 8 */
    TIMSK1 = 0;
}

uint8_t queue_depth(void)
{
    uint8_t h = q_head, t = q_tail;
    return t >= h ? t - h : t + QUEUE_SLOTS - h;
}

uint8_t queue_free(void) { return PROTO_QUEUE_BLOCKS - queue_depth(); }

struct block *queue_slot(uint8_t i)
{
    uint8_t k = q_tail + i;
    return &queue[k >= QUEUE_SLOTS ? k - QUEUE_SLOTS : k];
}

void queue_commit(uint8_t count)
{
    uint8_t t = q_tail + count;
    q_tail = t >= QUEUE_SLOTS ? t - QUEUE_SLOTS : t;
}

static void kick(void)
{
    ocr = TCNT1;
    ev_axes = 0;
    pulse_bits = 0;
    st_phase = PHASE_WAIT;
    schedule(KICK_TICKS);
    TIFR1 = _BV(OCF1A);
    TIMSK1 |= _BV(OCIE1A);
}

void stepper_service(void)
{
    /* Fill a band table for the first queued arc without one. */
    uint8_t i = q_head;
    while (i != q_tail) {
        struct block *b = &queue[i];
        if (b->kind == BLOCK_ARC && b->u.arc.table == NO_BAND_TABLE) {
            for (uint8_t k = 0; k < N_BAND_TABLES; k++) {
                if (!st_band_tables[k].busy) {
                    st_band_tables[k].busy = 1;
                    band_table_fill(&st_band_tables[k], b);
                    b->u.arc.table = k;
                    break;
                }
            }
            break;
        }
        i = i + 1 == QUEUE_SLOTS ? 0 : i + 1;
    }
    uint8_t phase = st_phase;
    if (phase != PHASE_IDLE && phase != PHASE_HELD)
        return; /* running: the interrupt moves on by itself */
    /* Stopped, so the compare interrupt is off: this section delays no step. */
    cli();
    if ((st_phase == PHASE_IDLE || st_phase == PHASE_HELD) && !st_hold_request
        && !st_abort_request && (cur || q_head != q_tail)) {
        struct block *b = cur ? cur : &queue[q_head];
        if (b->kind != BLOCK_ARC || b->u.arc.table != NO_BAND_TABLE)
            kick();
    }
    sei();
}

uint8_t stepper_flush(void)
{
    cli();
    if (st_phase == PHASE_EVENT) { /* still decelerating */
        sei();
        return 0;
    }
    stop(PHASE_IDLE);
    q_head = q_tail;
    ready_slot = q_tail;
    ready_events = entered_events = 0;
    stop_beyond = 0;
    cur = 0;
    for (uint8_t k = 0; k < N_BAND_TABLES; k++)
        st_band_tables[k].busy = 0;
    sei();
    return 1;
}

/* Without blocking interrupts: a 32-bit value read twice alike is consistent,
 * because the interrupt changes it at most once per event (hundreds of cycles). */
static int32_t read_stable(const volatile int32_t *v)
{
    int32_t a = *v, b;
    while ((b = *v) != a)
        a = b;
    return a;
}

void stepper_position(int32_t pos[3], int32_t origin[3])
{
    for (uint8_t a = 0; a < 3; a++) {
        pos[a] = read_stable(&st_pos(a));
        origin[a] = read_stable(&st_origin[a]);
    }
}

uint8_t stepper_homing(void)
{
    struct block *b = cur;
    return b && (b->flags & BLOCK_FLAG_HOMING);
}
