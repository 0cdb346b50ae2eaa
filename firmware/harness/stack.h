/*
 * The firmware's stack high-water mark, two ways (docs/harness.md, "Stack"):
 *
 *  - painting: the firmware fills the free SRAM between the end of its static
 *    data (the ELF symbol _end) and the stack pointer with a pattern byte at
 *    reset (firmware/galileo/stackpaint.cpp); at exit the lowest byte that no
 *    longer holds it is the deepest the stack has written;
 *  - the stack pointer itself, sampled after every instruction: the deepest
 *    the stack has been allocated (a frame's bytes count even if unwritten).
 */
#ifndef STACK_H
#define STACK_H

#include <stdint.h>
#include <stdio.h>

#include <sim_avr.h>
#include <sim_elf.h>

typedef struct stack_watch_t {
	avr_t *avr;
	int enabled;
	uint8_t pattern;
	uint16_t ram_start; /* __data_start: the first SRAM byte */
	uint16_t end;       /* _end: the first byte after .data, .bss, .noinit */
	uint16_t ramend;
	uint16_t sp_min;
	uint32_t sp_min_pc; /* byte address of the next instruction at sp_min */
	/* An `out SPH` has run and its `out SPL` not yet: SP is half-written
	 * (avr-gcc's frame set-up), so it is not sampled. */
	int sp_half_written;
} stack_watch_t;

/* Finds _end in the ELF's symbols; -1 (with a message) if it has none. */
int stack_watch_init(stack_watch_t *s, avr_t *avr, const elf_firmware_t *fw, uint8_t pattern);

/* Around every avr_run() that may execute an instruction. */
static inline void stack_watch_before(stack_watch_t *s)
{
	avr_t *avr = s->avr;
	if (avr->state != cpu_Running)
		return;
	uint16_t op = (uint16_t)(avr->flash[avr->pc] | avr->flash[avr->pc + 1] << 8);
	if ((op & 0xf800) == 0xb800) { /* out A, Rr */
		unsigned io = ((op >> 5) & 0x30) | (op & 0x0f);
		if (io + 0x20 == R_SPH)
			s->sp_half_written = 1;
		else if (io + 0x20 == R_SPL)
			s->sp_half_written = 0;
	}
}

static inline void stack_watch_after(stack_watch_t *s)
{
	if (s->sp_half_written)
		return;
	uint16_t sp = (uint16_t)(s->avr->data[R_SPL] | s->avr->data[R_SPH] << 8);
	if (sp < s->sp_min) {
		s->sp_min = sp;
		s->sp_min_pc = s->avr->pc;
	}
}

/* One "galileo-simavr: stack: ..." line with the measurement. */
void stack_watch_report(const stack_watch_t *s, FILE *out);

#endif
