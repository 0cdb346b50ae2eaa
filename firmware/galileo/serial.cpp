#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/crc16.h>

#include "protocol.h"
#include "serial.h"
#include "stepper.h"

#define RX_SLOTS (PROTO_RX_BUFFER_BYTES + 1) /* the advertised size, plus the empty slot */
#define TX_SLOTS 48
#define UCSR0B_RUNNING (_BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0))

static volatile uint8_t rx_buf[RX_SLOTS];
static volatile uint8_t rx_head, rx_tail;
static uint8_t tx_buf[TX_SLOTS];
static uint8_t tx_head, tx_tail;
static uint16_t tx_crc = PROTO_CRC16_INIT; /* over the line being written */
static uint8_t tx_count;                   /* its bytes so far: the separator's parity */
static char line_buf[PROTO_MAX_LINE_BYTES];
static uint8_t line_len, line_too_long;

volatile uint8_t serial_status_request;
volatile uint8_t serial_rx_overflows;

void serial_init(void)
{
    UCSR0A = _BV(U2X0);
    uint16_t ubrr = (uint16_t)((F_CPU / 8 + SERIAL_BAUD / 2) / SERIAL_BAUD - 1);
    UBRR0H = ubrr >> 8;
    UBRR0L = ubrr & 0xFF;
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00); /* 8N1 */
    UCSR0B = UCSR0B_RUNNING;
}

/* The receive interrupt must not delay a step edge by more than a few cycles,
 * so it runs with interrupts enabled: a naked stub masks RXCIE0 (the byte stays
 * in UDR0, so the interrupt cannot re-enter), re-enables interrupts and jumps to
 * the body, which unmasks RXCIE0 when done. Only the stub's 6 instructions (plus
 * the hardware's entry, 18 cycles in all) can delay the step compare interrupt. */
ISR(USART_RX_vect, ISR_NAKED)
{
    /* ldi/sts leave SREG alone, so nothing else needs saving: 11 cycles. */
    __asm__ __volatile__("push r24\n\t"
                         "ldi r24, %[masked]\n\t"
                         "sts %[ucsrb], r24\n\t"
                         "pop r24\n\t"
                         "sei\n\t"
                         "jmp serial_rx_body\n\t" ::[ucsrb] "n"(_SFR_MEM_ADDR(UCSR0B)),
                         [masked] "M"(UCSR0B_RUNNING & ~_BV(RXCIE0)));
}

#pragma GCC diagnostic ignored "-Wmisspelled-isr"
extern "C" void serial_rx_body(void) __attribute__((signal, used, externally_visible));
void serial_rx_body(void)
{
    uint8_t c = UDR0;
    switch (c) {
    case PROTO_RT_STATUS: serial_status_request = 1; break;
    case PROTO_RT_HOLD: st_hold_request = 1; st_fast = 0; break; /* the slow path sees it */
    case PROTO_RT_RESUME: if (!st_abort_request) st_hold_request = 0; break;
    case PROTO_RT_ABORT: st_abort_request = 1; st_hold_request = 1; st_fast = 0; break;
    default: {
        uint8_t h = rx_head, next = h + 1 == RX_SLOTS ? 0 : h + 1;
        if (next == rx_tail) {
            serial_rx_overflows++; /* the line loses a byte: its checksum asks for a resend */
        } else {
            rx_buf[h] = c;
            rx_head = next;
        }
    }
    }
    /* Work done: a byte waiting in the FIFO may interrupt the epilogue now. */
    UCSR0B = UCSR0B_RUNNING;
}

uint8_t serial_read_line(char **line, uint8_t *len)
{
    while (rx_tail != rx_head) {
        uint8_t t = rx_tail;
        char c = rx_buf[t];
        rx_tail = t + 1 == RX_SLOTS ? 0 : t + 1;
        if (c == '\r')
            continue;
        if (c == '\n') {
            uint8_t n = line_len, too_long = line_too_long;
            line_len = 0;
            line_too_long = 0;
            if (too_long)
                return LINE_TOO_LONG;
            if (n == 0)
                continue; /* empty lines are ignored, not answered */
            line_buf[n] = 0;
            *line = line_buf;
            *len = n;
            return LINE_READY;
        }
        if (line_len < PROTO_MAX_LINE_BYTES - 1)
            line_buf[line_len++] = c;
        else
            line_too_long = 1;
    }
    return LINE_NONE;
}

void serial_service(void)
{
    /* The first byte goes out without looking at UDRE0: it is set after reset
     * on the chip, but simavr 1.6 leaves it clear once the Arduino core's init()
     * has written UCSR0B = 0, and raises it again only after a UDR0 write. */
    static uint8_t tx_started;
    if (tx_tail != tx_head && (!tx_started || (UCSR0A & _BV(UDRE0)))) {
        tx_started = 1;
        UDR0 = tx_buf[tx_tail];
        tx_tail = tx_tail + 1 == TX_SLOTS ? 0 : tx_tail + 1;
    }
}

static void tx_put(char c)
{
    uint8_t next = tx_head + 1 == TX_SLOTS ? 0 : tx_head + 1;
    while (next == tx_tail)
        serial_service();
    tx_buf[tx_head] = c;
    tx_head = next;
}

void serial_write(char c)
{
    tx_crc = _crc_xmodem_update(tx_crc, (uint8_t)c);
    tx_count++;
    tx_put(c);
}

void serial_end_line(void)
{
    char sep = tx_count & 1 ? PROTO_CHECK_SEP_ODD : PROTO_CHECK_SEP_EVEN;
    uint16_t crc = _crc_xmodem_update(tx_crc, (uint8_t)sep);
    tx_put(sep);
    for (int8_t shift = 12; shift >= 0; shift -= 4) {
        uint8_t v = (crc >> shift) & 0xF;
        tx_put(v < 10 ? '0' + v : 'A' - 10 + v);
    }
    tx_put('\n');
    tx_crc = PROTO_CRC16_INIT;
    tx_count = 0;
}

void serial_print(const char *s)
{
    while (*s)
        serial_write(*s++);
}

void serial_print_P(const char *s)
{
    char c;
    while ((c = pgm_read_byte(s++)))
        serial_write(c);
}

void serial_print_int(int32_t v)
{
    char digits[11];
    uint8_t n = 0;
    uint32_t u = v < 0 ? -(uint32_t)v : (uint32_t)v;
    if (v < 0)
        serial_write('-');
    do {
        digits[n++] = '0' + u % 10;
        u /= 10;
    } while (u);
    while (n)
        serial_write(digits[--n]);
}
