/* The command interpreter and supervisor of the main loop (docs/protocol.md). */
#ifndef GALILEO_COMMANDS_H
#define GALILEO_COMMANDS_H

void commands_banner(void);
/* One pass: transmit, real-time requests, alarms, the stepper, one line. */
void commands_service(void);

#endif
