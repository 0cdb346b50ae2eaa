/* The planner: machine commands -> queued blocks, with the planned position. */
#ifndef GALILEO_PLANNER_H
#define GALILEO_PLANNER_H

#include <stdint.h>
#include "stepper.h"

struct planner {
    int32_t pos[3];            /* machine steps after the last queued block */
    int32_t origin[3];         /* machine steps of work zero, as planned */
    uint32_t feed_steps_per_s; /* LineTo, ArcTo, Jog */
    int32_t z_seen[2];         /* lowest, highest Z planned since power-on (Z without
                                  an end-stop: its travel floats with them) */
    uint8_t ended;             /* EndJob seen: refuse until Unlock */
};

struct limit_violation {
    uint8_t axis, above;       /* above: beyond the maximum, else below the minimum */
    int32_t value, limit;      /* machine steps */
};

extern struct planner pl;
extern struct limit_violation pl_violation; /* set with ERR_SOFT_LIMIT */

void planner_init(void);
/* Free queue blocks a command needs before planner_execute may run it. */
uint8_t planner_blocks_needed(uint8_t cmd);
/* Plan and queue one command; 0 or an ERR_ code (then nothing is queued). */
uint8_t planner_execute(uint8_t cmd, const int32_t *args, uint8_t nargs);
/* After an abort: the plan continues from where the machine stopped. */
void planner_resync(void);

#endif
