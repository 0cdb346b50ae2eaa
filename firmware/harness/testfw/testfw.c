/*
 * Test firmware for the simavr harness (not the plotter firmware).
 *
 * It exercises exactly what tests/test_simavr_harness.py checks: the UART
 * bridge, the pin trace with known cycle counts, the simulated end-stops, and
 * the simavr 1.6 quirks the real firmware must design around.
 *
 * Boot: UART0 at 115200 the way the Arduino core sets it up (U2X, UBRR 16, so
 * really 117 647 baud: 136 cycles a bit, 1360 cycles a 10-bit frame), then
 * Timer1 in CTC mode toggles pin 13 (PB5) TOGGLES times, every TOGGLE_CYCLES
 * cycles, from its interrupt while the CPU sleeps (so every edge has the same
 * latency), then "testfw\n". The first byte received afterwards picks a mode:
 *
 *   E  echo every byte (all 256 values)
 *   B  busy: ignore the UART for BUSY_FRAMES frame times, then echo
 *   R  echo, and toggle pin 12 (PB4) in the RX interrupt for every byte
 *   T  send TX_BURST bytes from the UDRE interrupt, toggling pin 12 at each
 *      UDR write, then "\n"
 *   S  step X and Y and report the home pins (see mode_steps)
 *   Q  report the Timer1 quirks (see mode_quirks)
 *   H  cli; sleep: the harness must stop ("sleeping with interrupts off")
 *   X  jump into erased flash: the harness must report a crash
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <stdint.h>
#include <stdlib.h>
#include <util/delay_basic.h>

#define UBRR_115200_U2X 16
#define TOGGLES 20
#define TOGGLE_CYCLES 1000u
#define BUSY_FRAMES 200u
#define TX_BURST 32
#define RX_SIZE 64 /* power of two, like the Arduino core's buffer */

/* Uno pin map, as in the plotter's defaults. */
#define Y_DIR _BV(PB0)  /* pin 8 */
#define Y_STEP _BV(PB1) /* pin 9 */
#define X_DIR _BV(PB2)  /* pin 10 */
#define X_STEP _BV(PB3) /* pin 11 */
#define PIN12 _BV(PB4)
#define PIN13 _BV(PB5)
#define Y_HOME _BV(PD6) /* pin 6 */
#define X_HOME _BV(PD7) /* pin 7 */

static volatile uint8_t rx_buf[RX_SIZE];
static volatile uint8_t rx_head, rx_tail;
static volatile uint8_t rx_toggle;
static volatile uint8_t toggles_left;
static volatile uint8_t tx_left;
static volatile uint16_t ctc_count;

ISR(USART_RX_vect)
{
	uint8_t byte = UDR0;
	if (rx_toggle)
		PINB = PIN12; /* writing 1 to PINx toggles PORTx */
	uint8_t next = (rx_head + 1) & (RX_SIZE - 1);
	if (next != rx_tail) {
		rx_buf[rx_head] = byte;
		rx_head = next;
	}
}

ISR(USART_UDRE_vect)
{
	if (tx_left) {
		UDR0 = 'U';
		PINB = PIN12;
		tx_left--;
	} else {
		UCSR0B &= ~_BV(UDRIE0);
	}
}

ISR(TIMER1_COMPA_vect)
{
	if (toggles_left) {
		PINB = PIN13;
		toggles_left--;
	}
	ctc_count++;
}

/* Sleep until an interrupt, without the race between the test and sleeping. */
static void idle_until(volatile uint8_t *flag_nonzero_to_wait)
{
	for (;;) {
		cli();
		if (!*flag_nonzero_to_wait)
			break;
		sleep_enable();
		sei();
		sleep_cpu();
		sleep_disable();
	}
	sei();
}

static uint8_t rx_get(void)
{
	for (;;) {
		cli();
		if (rx_head != rx_tail)
			break;
		sleep_enable();
		sei();
		sleep_cpu();
		sleep_disable();
	}
	uint8_t byte = rx_buf[rx_tail];
	rx_tail = (rx_tail + 1) & (RX_SIZE - 1);
	sei();
	return byte;
}

static void tx_put(uint8_t byte)
{
	while (!(UCSR0A & _BV(UDRE0)))
		;
	UDR0 = byte;
}

static void tx_str(const char *s)
{
	while (*s)
		tx_put((uint8_t)*s++);
}

static void tx_uint(const char *label, uint16_t value)
{
	char digits[6];
	tx_str(label);
	tx_str(utoa(value, digits, 10));
}

static void delay_cycles_x4(uint16_t n) { _delay_loop_2(n); }

static void mode_echo(void)
{
	for (;;)
		tx_put(rx_get());
}

static void mode_busy(void)
{
	/* RX interrupt off and UDR unread: on hardware bytes past the 2-byte
	 * receive buffer are lost; the harness keeps them and counts overruns. */
	UCSR0B &= ~_BV(RXCIE0);
	for (uint16_t i = 0; i < BUSY_FRAMES; i++)
		delay_cycles_x4(1360 / 4);
	UCSR0B |= _BV(RXCIE0);
	mode_echo();
}

static void mode_tx_burst(void)
{
	tx_left = TX_BURST;
	UCSR0B |= _BV(UDRIE0);
	idle_until(&tx_left);
	while (UCSR0B & _BV(UDRIE0))
		;
	tx_put('\n');
	mode_echo();
}

/* One step pulse: step high, a few cycles, step low, then let the harness's
 * end-stop settle (it is immediate, but a real switch is read after the step). */
static uint8_t step_and_read(uint8_t step_mask, uint8_t home_mask)
{
	PORTB |= step_mask;
	delay_cycles_x4(4);
	PORTB &= ~step_mask;
	delay_cycles_x4(25);
	return (PIND & home_mask) ? '1' : '0';
}

/* X: home level, 8 steps down, 8 steps up; Y: home level, 5 steps up.
 * Output "S<x0><8 levels><8 levels>|<y0><5 levels>\n". */
static void mode_steps(void)
{
	tx_put('S');
	tx_put((PIND & X_HOME) ? '1' : '0');
	PORTB &= ~X_DIR;
	for (uint8_t i = 0; i < 8; i++)
		tx_put(step_and_read(X_STEP, X_HOME));
	PORTB |= X_DIR;
	for (uint8_t i = 0; i < 8; i++)
		tx_put(step_and_read(X_STEP, X_HOME));
	tx_put('|');
	tx_put((PIND & Y_HOME) ? '1' : '0');
	PORTB |= Y_DIR;
	for (uint8_t i = 0; i < 5; i++)
		tx_put(step_and_read(Y_STEP, Y_HOME));
	tx_put('\n');
	mode_echo();
}

static uint16_t ctc_interrupts(uint16_t ocr, uint8_t clock_select)
{
	TCCR1A = 0;
	TCCR1B = _BV(WGM12);
	TCNT1 = 0;
	OCR1A = ocr;
	ctc_count = 0;
	TIFR1 = _BV(OCF1A);
	TIMSK1 = _BV(OCIE1A);
	TCCR1B = _BV(WGM12) | clock_select; /* CTC */
	delay_cycles_x4(1000);              /* 4000 cycles, stretched by the ISRs */
	TCCR1B = 0;
	TIMSK1 = 0;
	return ctc_count;
}

/* "Q stopped=<TCNT1> running=<TCNT1> ctc0=<n> ctc1=<n> ctc0_8=<n>\n":
 * stopped: TCNT1 = 50000 written while Timer1 is stopped, then started at
 *          clk/1 and read 404 cycles later (hardware: 50404);
 * running: the same, but written while running (hardware: ~50400);
 * ctc0, ctc1: compare-A interrupts in CTC mode at clk/1 with OCR1A = 0 and 1
 *          (hardware: back to back in both cases, as fast as the ISR runs);
 * ctc0_8: the same with OCR1A = 0 at clk/8. */
static void mode_quirks(void)
{
	uint16_t stopped, running;
	cli();
	TIMSK1 = 0;
	TCCR1A = 0;
	TCCR1B = 0;
	TCNT1 = 50000;
	TCCR1B = _BV(CS10);
	delay_cycles_x4(100);
	stopped = TCNT1;
	TCCR1B = _BV(CS10);
	TCNT1 = 50000;
	delay_cycles_x4(100);
	running = TCNT1;
	TCCR1B = 0;
	sei();
	tx_uint("Q stopped=", stopped);
	tx_uint(" running=", running);
	tx_uint(" ctc0=", ctc_interrupts(0, _BV(CS10)));
	tx_uint(" ctc1=", ctc_interrupts(1, _BV(CS10)));
	tx_uint(" ctc0_8=", ctc_interrupts(0, _BV(CS11)));
	tx_put('\n');
	mode_echo();
}

int main(void)
{
	DDRB = Y_DIR | Y_STEP | X_DIR | X_STEP | PIN12 | PIN13;
	PORTD |= X_HOME | Y_HOME; /* pull-ups, as the plotter firmware does */

	UCSR0A = _BV(U2X0);
	UBRR0H = 0;
	UBRR0L = UBRR_115200_U2X;
	UCSR0C = _BV(UCSZ01) | _BV(UCSZ00); /* 8N1 */
	UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);

	set_sleep_mode(SLEEP_MODE_IDLE);
	toggles_left = TOGGLES;
	TCCR1A = 0;
	TCCR1B = _BV(WGM12); /* CTC first: simavr warns of OCR writes in mode 0 */
	OCR1A = TOGGLE_CYCLES - 1;
	TIMSK1 = _BV(OCIE1A);
	TCCR1B = _BV(WGM12) | _BV(CS10); /* CTC, clk/1 */
	idle_until(&toggles_left);
	TCCR1B = 0;
	TIMSK1 = 0;

	tx_str("testfw\n");
	switch (rx_get()) {
	case 'B': mode_busy(); break;
	case 'R': rx_toggle = 1; mode_echo(); break;
	case 'T': mode_tx_burst(); break;
	case 'S': mode_steps(); break;
	case 'Q': mode_quirks(); break;
	case 'H': cli(); sleep_enable(); sleep_cpu(); break;
	case 'X': ((void (*)(void))0x3000)(); break;
	default: mode_echo(); break;
	}
	for (;;)
		;
}
