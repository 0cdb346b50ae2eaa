/*
 * Two simavr 1.6 timer quirks that stock GRBL 1.1 meets, corrected on request
 * (docs/harness.md, "Timer quirks"). Our own firmware follows the rules that
 * avoid them and runs without these corrections.
 */
#ifndef TIMER_QUIRKS_H
#define TIMER_QUIRKS_H

#include <stdint.h>

#include <sim_avr.h>

typedef struct timer_quirks_t {
	avr_t *avr;
	int ocr1a_at_start;   /* -1: leave OCR1A at 0 */
	int replay_tcnt0;     /* replay a TCNT0 preload written while Timer0 was stopped */
	uint8_t tcnt0_written;
	uint8_t timer0_running;
	uint64_t replays;
} timer_quirks_t;

/* Hooks the registers; call after the firmware is loaded. */
int timer_quirks_attach(timer_quirks_t *q, avr_t *avr);
/* Right before the AVR leaves reset (cycle 0): the OCR1A poke. */
void timer_quirks_start(timer_quirks_t *q);

#endif
