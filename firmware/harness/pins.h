/*
 * Arduino Uno pins in simavr: the edge trace and the simulated end-stops.
 */
#ifndef PINS_H
#define PINS_H

#include <stdint.h>
#include <stdio.h>

#include <sim_avr.h>

#define PINS_MAX 20 /* Uno digital pins 0..13 and A0..A5 as 14..19 */
#define AXES 3      /* X, Y, Z */

/* One trace record on disk: little-endian u64 cycle, u8 pin, u8 level. */
#define TRACE_RECORD_BYTES 10
/* The pin of the record that marks a reset (the cycle it came at, level 0). */
#define TRACE_RESET_PIN 0xff

struct pins_t;

typedef struct pin_state_t {
	struct pins_t *pins;
	uint8_t arduino;
	uint8_t level;  /* last level seen (every pin is low at reset) */
	uint8_t traced;
	uint8_t hooked;
} pin_state_t;

typedef struct endstop_t {
	int active;
	uint8_t step_pin, dir_pin, home_pin;
	int64_t trip_steps;     /* home pin low while position <= trip */
	int64_t position_steps; /* from power-up, + when dir is high */
	int home_level;         /* -1 until first driven */
} endstop_t;

/* --probe: a touch probe on a surface of Z step counts over X and Y. */
typedef struct probe_t {
	int active;
	uint8_t pin;
	double z0, amp, px, py;  /* surface(x, y) = z0 + amp sin(2 pi x/px) sin(2 pi y/py) */
	int dir_low_positive;    /* count + when dir is low (GRBL's sense with $3=0) */
	int64_t position[AXES];  /* X, Y, Z steps from power-up */
	uint8_t step_pin[AXES], dir_pin[AXES];
	int level;               /* -1 until first driven; 0 = touching */
	uint64_t touches;        /* times the pin went low */
} probe_t;

typedef struct pins_t {
	avr_t *avr;
	FILE *trace;
	uint64_t records;
	uint64_t cycle_base; /* cycles before the last reset: records count from power-up */
	pin_state_t pin[PINS_MAX];
	endstop_t axis[AXES];
	uint8_t ext_mask[3], ext_value[3]; /* driven inputs of ports B, C, D */
	uint8_t map_step[AXES], map_dir[AXES]; /* --axis-pins, when map_set */
	int map_set;
	probe_t probe;
} pins_t;

/* The AVR port ('B', 'C', 'D') and bit of an Uno pin; -1 if there is none. */
int pins_arduino(int pin, char *port, int *bit);
/* Default step/dir pins of an axis (0 = X, 1 = Y, 2 = Z). */
void pins_axis_default(int axis, uint8_t *step_pin, uint8_t *dir_pin);
/* Before pins_attach(): the step/dir pins an end-stop counts on (GRBL's map
 * differs from the seed's). */
int pins_set_axis(pins_t *p, int axis, int step_pin, int dir_pin);
/* Before pins_attach(): drive `home_pin` from the axis' step count. */
int pins_add_endstop(pins_t *p, int axis, int home_pin, int64_t trip_steps);
/* Before pins_attach(): a touch probe on `pin`, low (touching) while the Z step
 * count is <= z0 + amp sin(2 pi x/px) sin(2 pi y/py) (amp 0: flat). */
int pins_add_probe(pins_t *p, int pin, double z0, double amp, double px, double py,
		   int dir_low_positive);
/* Hooks the traced pins and the end-stop axes' pins; drives the home pins. */
int pins_attach(pins_t *p, avr_t *avr, FILE *trace, const uint8_t *traced, int ntraced);
/* After avr_reset() at `cycle` (since power-up): writes the reset mark and drives
 * the home pins again (the reset cleared the PIN registers). The pins' levels are
 * kept: the firmware's first writes after the reset record whatever changed. */
void pins_reset(pins_t *p, uint64_t cycle);

#endif
