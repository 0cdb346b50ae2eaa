/* Arduino Uno pin numbers -> AVR ports, for direct port access (GRBL's cpu_map).
 *
 * The stepper interrupt writes the step and direction pins with ONE `out`
 * instruction, so all six must sit on one AVR port; the seed wiring puts them on
 * PORTB (Uno pins 8..13). Other pin maps stop the build here. */
#ifndef GALILEO_PINS_H
#define GALILEO_PINS_H

#include <avr/io.h>
#include "config.h"

/* Uno: pins 0..7 are PORTD, 8..13 PORTB, 14..19 (A0..A5) PORTC. */
#define UNO_PORT_ID(pin) ((pin) < 8 ? 2 : (pin) < 14 ? 0 : 1) /* 0 B, 1 C, 2 D */
#define UNO_BIT(pin) ((pin) < 8 ? (pin) : (pin) < 14 ? (pin) - 8 : (pin) - 14)

#define STEPPER_PORT_ID UNO_PORT_ID(CFG_X_STEP_PIN)
#if UNO_PORT_ID(CFG_Y_STEP_PIN) != STEPPER_PORT_ID || UNO_PORT_ID(CFG_Z_STEP_PIN) != STEPPER_PORT_ID \
    || UNO_PORT_ID(CFG_X_DIR_PIN) != STEPPER_PORT_ID || UNO_PORT_ID(CFG_Y_DIR_PIN) != STEPPER_PORT_ID \
    || UNO_PORT_ID(CFG_Z_DIR_PIN) != STEPPER_PORT_ID
#error "all step and direction pins must be on one AVR port (the seed: Uno pins 8..13, PORTB)"
#endif
#if STEPPER_PORT_ID == 0
#define STEPPER_PORT PORTB
#define STEPPER_DDR DDRB
#elif STEPPER_PORT_ID == 1
#define STEPPER_PORT PORTC
#define STEPPER_DDR DDRC
#else
#error "step/dir pins on PORTD would collide with the UART (pins 0, 1)"
#endif

#define X_STEP_BIT (1 << UNO_BIT(CFG_X_STEP_PIN))
#define Y_STEP_BIT (1 << UNO_BIT(CFG_Y_STEP_PIN))
#define Z_STEP_BIT (1 << UNO_BIT(CFG_Z_STEP_PIN))
#define X_DIR_BIT (1 << UNO_BIT(CFG_X_DIR_PIN))
#define Y_DIR_BIT (1 << UNO_BIT(CFG_Y_DIR_PIN))
#define Z_DIR_BIT (1 << UNO_BIT(CFG_Z_DIR_PIN))
#define STEP_MASK (X_STEP_BIT | Y_STEP_BIT | Z_STEP_BIT)
#define DIR_MASK (X_DIR_BIT | Y_DIR_BIT | Z_DIR_BIT)
#if (STEP_MASK & DIR_MASK) || ((X_STEP_BIT | Y_STEP_BIT) & Z_STEP_BIT) || (X_STEP_BIT & Y_STEP_BIT)
#error "step and direction pins must all be different"
#endif

/* End-stop inputs (INPUT_PULLUP, active LOW). A pin of -1 has no switch. */
#define HOME_PIN_REG(pin) (UNO_PORT_ID(pin) == 0 ? PINB : UNO_PORT_ID(pin) == 1 ? PINC : PIND)
#define HOME_ACTIVE(pin) (!(HOME_PIN_REG(pin) & (1 << UNO_BIT(pin))))

#endif
