/*
 * simavr 1.6 timer quirks that stock GRBL 1.1h meets (measured with GRBL in
 * this harness, see docs/harness.md):
 *
 * - A CTC timer with TOP = 0 at clk/1 never fires in simavr (silicon: every
 *   tick). GRBL enables its step interrupt with OCR1A still 0 and sets it in
 *   the first interrupt, so its first move stalls. --ocr1a-at-start N puts N
 *   in OCR1A at cycle 0, before any firmware code runs; GRBL never relies on
 *   OCR1A's reset value, it overwrites it in that first interrupt.
 * - simavr ignores a TCNT0 write while Timer0 is stopped (the count restarts
 *   at 0 when the clock starts). GRBL ends each step pulse with a Timer0
 *   overflow preloaded that way, so pulses last 256 ticks instead of
 *   $0 us and merge at high step rates. --replay-tcnt0 writes the preload
 *   again in the instruction that starts the timer.
 */
#include "timer_quirks.h"

#include <stddef.h>

#include <sim_io.h>
#include <sim_irq.h>

/* ATmega328p data addresses (datasheet register summary). */
#define REG_TCCR0B 0x45
#define REG_TCNT0 0x46
#define REG_OCR1AL 0x88
#define REG_OCR1AH 0x89
#define TIMER0_CS_MASK 0x07

static void tcnt0_written(struct avr_irq_t *irq, uint32_t value, void *param)
{
	timer_quirks_t *q = param;
	(void)irq;
	q->tcnt0_written = (uint8_t)value;
}

/* Raised after simavr's own TCCR0B handler has (re)started the timer. */
static void tccr0b_written(struct avr_irq_t *irq, uint32_t value, void *param)
{
	timer_quirks_t *q = param;
	avr_t *avr = q->avr;
	(void)irq;
	int running = (value & TIMER0_CS_MASK) != 0;
	if (running && !q->timer0_running) {
		avr_io_addr_t io = AVR_DATA_TO_IO(REG_TCNT0);
		if (avr->io[io].w.c)
			avr->io[io].w.c(avr, REG_TCNT0, q->tcnt0_written, avr->io[io].w.param);
		q->replays++;
	}
	q->timer0_running = (uint8_t)running;
}

int timer_quirks_attach(timer_quirks_t *q, avr_t *avr)
{
	q->avr = avr;
	if (!q->replay_tcnt0)
		return 0;
	avr_irq_t *tcnt = avr_iomem_getirq(avr, REG_TCNT0, NULL, AVR_IOMEM_IRQ_ALL);
	avr_irq_t *tccr = avr_iomem_getirq(avr, REG_TCCR0B, NULL, AVR_IOMEM_IRQ_ALL);
	if (!tcnt || !tccr)
		return -1;
	/* Every write counts, also one that repeats the last value. */
	tcnt->flags &= ~IRQ_FLAG_FILTERED;
	tccr->flags &= ~IRQ_FLAG_FILTERED;
	avr_irq_register_notify(tcnt, tcnt0_written, q);
	avr_irq_register_notify(tccr, tccr0b_written, q);
	return 0;
}

void timer_quirks_start(timer_quirks_t *q)
{
	q->timer0_running = 0; /* stopped at power-up and after a reset */
	if (q->ocr1a_at_start < 0)
		return;
	/* simavr reads OCR1A from data memory when the firmware configures
	 * Timer1, so a plain store before the first instruction is enough. */
	q->avr->data[REG_OCR1AL] = (uint8_t)(q->ocr1a_at_start & 0xff);
	q->avr->data[REG_OCR1AH] = (uint8_t)(q->ocr1a_at_start >> 8);
}
