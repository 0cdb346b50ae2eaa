/* UART0: receive ring with the real-time bytes picked off in the interrupt, line
 * assembly in the main loop, and a transmit ring drained by polling (so that no
 * transmit interrupt ever delays a step edge). */
#ifndef GALILEO_SERIAL_H
#define GALILEO_SERIAL_H

#include <stdint.h>
#include <avr/pgmspace.h>

#include "config.h"

#define SERIAL_BAUD CFG_SERIAL_BAUD

enum serial_line { LINE_NONE, LINE_READY, LINE_TOO_LONG };

extern volatile uint8_t serial_status_request; /* PROTO_RT_STATUS received */
extern volatile uint8_t serial_rx_overflows;

void serial_init(void);
void serial_service(void); /* move one byte to the transmitter if it is free */
/* A complete line (without newline, NUL-terminated) or an over-long one. */
uint8_t serial_read_line(char **line, uint8_t *len);
void serial_write(char c);
/* The line's check (separator, CRC-16 in hex) and its newline (docs/protocol.md). */
void serial_end_line(void);
void serial_print(const char *s);
void serial_print_P(const char *s); /* a string in flash (PSTR) */
void serial_print_int(int32_t v);

#endif
