/* galileo-cnc firmware: a pen plotter controller for the ATmega328p (Arduino Uno).
 *
 * Streams machine commands over the serial line (docs/protocol.md, 115200 baud)
 * and steps them exactly as docs/motion.md specifies, so its step trace equals
 * the Python reference machine's (galileo_cnc/machine/). Open this folder in the
 * Arduino IDE, or build with `make -C firmware` (arduino-mk).
 *
 * Pins, feeds and travel: config.h (generated from galileo_cnc/config.py).
 * Modules: serial (UART), commands (lines, replies), planner + arcs (per-move
 * setup), stepper (block queue, Timer1 interrupt), intmath. */
#include <avr/interrupt.h>
#include <avr/io.h>

#include "commands.h"
#include "config.h"
#include "planner.h"
#include "serial.h"
#include "stepper.h"

static void home_inputs_init(void)
{
#if CFG_X_HOME_PIN >= 0
    pinMode(CFG_X_HOME_PIN, INPUT_PULLUP);
#endif
#if CFG_Y_HOME_PIN >= 0
    pinMode(CFG_Y_HOME_PIN, INPUT_PULLUP);
#endif
#if CFG_Z_HOME_PIN >= 0
    pinMode(CFG_Z_HOME_PIN, INPUT_PULLUP);
#endif
}

void setup()
{
    cli();
    TIMSK0 = 0; /* no millis(): its interrupt would delay step edges */
    home_inputs_init();
    serial_init();
    stepper_init();
    planner_init();
    sei();
    commands_banner();
}

void loop()
{
    commands_service();
}
