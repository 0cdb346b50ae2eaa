/* Stack painting: measures the stack's high-water mark (docs/harness.md, "Stack").
 *
 * Before main() runs, every byte of SRAM between the end of the static data
 * (_end: .data, .bss and .noinit) and the stack pointer is filled with
 * STACK_PAINT_BYTE. A byte the stack (or anything else) has written since no
 * longer holds the pattern, so the lowest such address is the deepest the stack
 * has ever reached: the simavr harness reads it out (`--stack-paint 0xC5`), and
 * on hardware a debugger can.
 *
 * The function lives in .init3: after avr-libc's .init2 has cleared r1 and set
 * SP to RAMEND, before .init4 copies .data and clears .bss. It is naked and
 * never called: the start-up code falls through it, so it costs about 6 cycles
 * a byte once at reset (~0.2 ms for 525 bytes) and nothing afterwards. It uses
 * only call-clobbered registers and keeps r1 == 0. */
#include <avr/io.h>

#define STACK_PAINT_BYTE 0xC5 /* keep in sync with galileo_cnc/simavr.py */

extern "C" {
extern unsigned char _end; /* from the linker script: first free SRAM byte */
void galileo_stack_paint(void) __attribute__((naked, used, section(".init3")));
}

void galileo_stack_paint(void)
{
    /* for (Z = &_end; Z <= SP; ) *Z++ = STACK_PAINT_BYTE; */
    asm volatile(
        "    ldi r30, lo8(_end)      \n"
        "    ldi r31, hi8(_end)      \n"
        "    in r26, __SP_L__        \n"
        "    in r27, __SP_H__        \n"
        "    adiw r26, 1             \n" /* one past SP: SP itself is free */
        "    ldi r24, %0             \n"
        "    rjmp 2f                 \n"
        "1:  st Z+, r24              \n"
        "2:  cp r30, r26             \n"
        "    cpc r31, r27            \n"
        "    brlo 1b                 \n"
        :
        : "M"(STACK_PAINT_BYTE)
        : "r24", "r26", "r27", "r30", "r31", "memory");
}
