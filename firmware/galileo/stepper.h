/* The block queue and the Timer1 step interrupt (docs/motion.md §3.2, §4.2, §5.5, §6).
 *
 * The main loop plans commands into blocks (planner.cpp) and appends them; the
 * interrupt executes them back to back. The queue is single-producer (main loop
 * writes the tail) / single-consumer (interrupt pops the head), so the only
 * shared writes are one-byte indices. */
#ifndef GALILEO_STEPPER_H
#define GALILEO_STEPPER_H

#include <stdint.h>
#include "config.h"
#include "protocol.h"

enum block_kind {
    BLOCK_LINE,      /* Bresenham line (§3), also the homing pull-off */
    BLOCK_ARC,       /* midpoint arc then the end correction line (§4) */
    BLOCK_SEEK,      /* homing seek: constant interval until the debounced switch (§8) */
    BLOCK_PAUSE,     /* dwell: `n` ticks without steps */
    BLOCK_ORIGIN,    /* marker: live work origin := u.origin */
    BLOCK_ZERO_AXIS  /* marker: homed axis position and origin := 0 (§8.4) */
};

#define BLOCK_FLAG_HOMING 1      /* status reports "homing" */
#define BLOCK_FLAG_HOME_FIRST 2  /* first seek of a Home: every switch must read inactive */
#define SEEK_UNKNOWN_EVENTS 0x7FFFFFFFUL
#define NO_BAND_TABLE 0xFF

struct block {
    uint8_t kind, flags;
    uint32_t n;               /* events (pause: ticks) */
    uint32_t base_sub;        /* cruise subticks per event (line, seek) */
    __uint24 ramp;            /* R, events (< 2^24: planner.cpp) */
    uint32_t step_sub;        /* interval change per ramp event, subticks */
    uint32_t ramp_total_sub;  /* R * step_sub: the extra interval of a run's first event */
    __uint24 exit;            /* ramp index the block ends at (<= R; 0: at rest, §5.7) */
    union {
        struct {
            uint32_t inc[3];  /* 2 |d_a| */
            uint8_t neg;      /* bit a: axis a moves toward minus */
        } line;
        struct {
            int16_t x0, y0;       /* start relative to the centre (|.| <= MAX_ARC_COORD) */
            uint32_t axial_sub;   /* C1 of the feed: the band bases are C1 * rho */
            uint32_t scale;       /* band rho scale, Q20: the arc's length (§5.3) */
            uint32_t n_arc;       /* arc events; n - n_arc correction events follow */
            int32_t corr_x, corr_y;
            uint16_t first_key;   /* band key of the first arc event */
            uint8_t ccw;
            volatile uint8_t table; /* band table, NO_BAND_TABLE until filled */
        } arc;
        struct {
            uint32_t max_steps;
            uint8_t axis;
            int8_t dir;
        } seek;
        int32_t origin[3];
        uint8_t axis;
    } u;
};

/* Compact band table of one arc (§5.3): thresholds and cruise subticks. */
struct band_table {
    uint16_t v[CFG_N_BANDS];
    uint32_t base_sub[CFG_N_BANDS];
    uint8_t count, band0;
    volatile uint8_t busy;
};
#define N_BAND_TABLES 2

enum stepper_phase {
    PHASE_IDLE,      /* nothing scheduled: queue empty, or head not ready */
    PHASE_WAIT,      /* a wake-up without steps is scheduled (start, pause end) */
    PHASE_EVENT,     /* a step event is scheduled */
    PHASE_HELD,      /* stopped by a hold (or an abort) */
    PHASE_ALARM      /* stopped by a homing failure; st_alarm_code says why */
};

extern struct band_table st_band_tables[N_BAND_TABLES];
extern volatile uint8_t st_phase;
extern volatile uint8_t st_alarm_code;
extern volatile uint8_t st_hold_request, st_abort_request;
extern volatile uint16_t st_overruns;
extern "C" volatile uint8_t st_fast; /* the next event takes the fast body */

void stepper_init(void);
uint8_t queue_free(void);
uint8_t queue_depth(void);
struct block *queue_slot(uint8_t i);   /* i-th free slot after the tail, to fill */
void queue_commit(uint8_t count);      /* hand `count` filled slots to the interrupt */
/* Main loop: fill band tables, start the interrupt when there is work. */
void stepper_service(void);
/* Main loop, machine stopped: drop every queued block (abort, alarm). */
uint8_t stepper_flush(void); /* 0 while still decelerating */
void stepper_position(int32_t pos[3], int32_t origin[3]);
uint8_t stepper_homing(void);

#endif
