"""The board's fixed facts, defined once: clock, step timer, serial line.

These do not change with the machine profile; `python -m galileo_cnc.firmware_headers`
writes them into firmware/galileo/config.h (with an `#error` if the build's F_CPU
disagrees), and the host, the reference machine and the simavr harness import them.
"""

#: The ATmega328p's clock on an Uno.
F_CPU_HZ = 16_000_000
#: Timer1 runs at clk/8, so one tick is 0.5 us.
TIMER1_PRESCALER = 8
TICKS_PER_S = F_CPU_HZ // TIMER1_PRESCALER          # 2_000_000

#: Our firmware's line speed; the seed used 9600, and every rate here is accepted.
DEFAULT_BAUD = 115_200
BAUD_RATES = (9600, 19200, 38400, 57600, 115_200)

#: An Uno resets when its port opens; the boot loader takes up to ~2 s before the banner.
BANNER_WAIT_S = 2.5
