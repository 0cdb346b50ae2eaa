/*
 * UART0 <-> host bridge: a pseudo-terminal (or stdin/stdout) on the host side,
 * simavr's UART0 IRQs on the AVR side.
 *
 * Host bytes are queued here and fed to the UART one per frame time of
 * simulated cycles, never faster, so the firmware sees the wire's pacing and
 * nothing the host writes is lost. The bridge also corrects simavr 1.6's frame
 * length (it counts a parity bit in every frame, so 8N1 ran 11 bits long).
 */
#ifndef UART_BRIDGE_H
#define UART_BRIDGE_H

#include <signal.h>
#include <stdint.h>

#include <sim_avr.h>
#include <avr_uart.h>

#define UB_IN_SIZE (64u * 1024u)   /* host -> AVR queue (bytes) */
#define UB_OUT_SIZE (1024u * 1024u) /* AVR -> host queue (bytes) */

typedef struct uart_bridge_t {
	avr_t *avr;
	avr_uart_t *uart;
	avr_irq_t *irq; /* UART_IRQ_COUNT irqs of UART0 */
	int in_fd, out_fd;
	int pty_master;
	int host_flushed; /* the host flushed its input (TIOCPKT_FLUSHREAD) */
	char slave_path[128];
	int in_eof;
	int keep_simavr_timing; /* leave simavr's 11-bit frames alone */

	/* host -> AVR */
	uint8_t in_q[UB_IN_SIZE];
	uint32_t in_head, in_tail;
	int feeding;
	avr_cycle_count_t last_feed_cycle;

	/* AVR -> host */
	uint8_t out_q[UB_OUT_SIZE];
	uint32_t out_head, out_tail;

	/* frame-length correction: the registers it was computed from */
	uint8_t seen_regs[5];
	avr_cycle_count_t frame_cycles;

	/* what happened, for the exit summary */
	uint64_t rx_bytes, tx_bytes;
	uint64_t overruns;     /* bytes a real 328p would have lost (DOR) */
	uint64_t dropped_out;  /* AVR output dropped: host not reading */
} uart_bridge_t;

/* Opens a pty in packet mode, makes its slave raw, points `link` at the
 * slave. 0 or -1 (errno set). */
int uart_bridge_open_pty(uart_bridge_t *b, const char *link);
/* Blocks until the host has opened the pty and flushed its input (pyserial
 * does both in Serial()), or 200 ms after the open. -1 if *stop got set. */
int uart_bridge_wait_open(uart_bridge_t *b, volatile sig_atomic_t *stop);
/* Blocks until stdin has input or is closed. -1 if *stop got set. */
int uart_bridge_wait_input(uart_bridge_t *b, volatile sig_atomic_t *stop);
/* Uses stdin/stdout. */
void uart_bridge_open_stdio(uart_bridge_t *b);
/* Hooks UART0 of `avr`. 0, or -1 if the core has no UART0. */
int uart_bridge_attach(uart_bridge_t *b, avr_t *avr);
/* Call after every avr_run(): keeps the frame length right. */
void uart_bridge_check_frame(uart_bridge_t *b);
/* Moves bytes between the host and the queues; call every few thousand cycles. */
void uart_bridge_service(uart_bridge_t *b);
/* After avr_reset(): the feed timer is gone and undelivered host bytes are lost. */
void uart_bridge_reset(uart_bridge_t *b);
/* Last chance to hand the AVR's output to the host (blocking, bounded). */
void uart_bridge_flush(uart_bridge_t *b);
void uart_bridge_close(uart_bridge_t *b, const char *link);

#endif
