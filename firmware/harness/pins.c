/*
 * Pin edges with their exact cycle, and end-stops driven from counted steps.
 *
 * simavr raises a port's pin IRQs on every write to PORTx/DDRx/PINx, changed
 * or not, so each hook keeps the last level and acts on changes only.
 */
#include "pins.h"

#include <math.h>
#include <string.h>

#include <avr_ioport.h>
#include <sim_io.h>
#include <sim_irq.h>

static const struct {
	uint8_t step, dir;
} axis_pins[AXES] = {
	{11, 10}, /* X: PB3 step, PB2 dir */
	{9, 8},   /* Y: PB1 step, PB0 dir */
	{13, 12}, /* Z: PB5 step, PB4 dir */
};

int pins_arduino(int pin, char *port, int *bit)
{
	if (pin >= 0 && pin <= 7) {
		*port = 'D';
		*bit = pin;
	} else if (pin >= 8 && pin <= 13) {
		*port = 'B';
		*bit = pin - 8;
	} else if (pin >= 14 && pin <= 19) {
		*port = 'C';
		*bit = pin - 14;
	} else {
		return -1;
	}
	return 0;
}

void pins_axis_default(int axis, uint8_t *step_pin, uint8_t *dir_pin)
{
	*step_pin = axis_pins[axis].step;
	*dir_pin = axis_pins[axis].dir;
}

/* PINB, PINC, PIND in the ATmega328P's data space. */
static const uint16_t pin_register[3] = {0x23, 0x26, 0x29};

static avr_irq_t *pin_irq(avr_t *avr, int pin)
{
	char port;
	int bit;
	if (pins_arduino(pin, &port, &bit) < 0)
		return NULL;
	return avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit);
}

static void write_record(pins_t *p, uint64_t cycle, uint8_t pin, uint8_t level)
{
	if (!p->trace)
		return;
	uint8_t rec[TRACE_RECORD_BYTES];
	for (int i = 0; i < 8; i++)
		rec[i] = (uint8_t)(cycle >> (8 * i));
	rec[8] = pin;
	rec[9] = level;
	fwrite(rec, sizeof(rec), 1, p->trace);
	p->records++;
}

static void record(pins_t *p, uint8_t pin, uint8_t level)
{
	write_record(p, p->cycle_base + p->avr->cycle, pin, level);
}

/* Drives an input pin from outside (a switch, the probe). The "external" value
 * is what simavr re-raises on an input pin at every PORTx/DDRx write; without it
 * the firmware's pull-up (PORT bit 1) would overwrite the switch on the next
 * write to that port. */
static void drive_input(pins_t *p, uint8_t pin, int level)
{
	char port = 'B';
	int bit = 0;
	pins_arduino(pin, &port, &bit);
	int k = port - 'B';
	p->ext_mask[k] |= (uint8_t)(1u << bit);
	p->ext_value[k] = (uint8_t)((p->ext_value[k] & ~(1u << bit)) | ((unsigned)level << bit));
	avr_ioport_external_t ext = {.name = (unsigned)port, .mask = p->ext_mask[k], .value = p->ext_value[k]};
	avr_ioctl(p->avr, AVR_IOCTL_IOPORT_SET_EXTERNAL(port), &ext);
	avr_raise_irq(pin_irq(p->avr, pin), (uint32_t)level);
}

static void drive_home(pins_t *p, endstop_t *e)
{
	int level = e->position_steps <= e->trip_steps ? 0 : 1;
	if (level == e->home_level)
		return;
	e->home_level = level;
	drive_input(p, e->home_pin, level);
}

static double surface(const probe_t *pr)
{
	if (pr->amp == 0.0)
		return pr->z0;
	return pr->z0 + pr->amp * sin(2.0 * M_PI * (double)pr->position[0] / pr->px) *
				 sin(2.0 * M_PI * (double)pr->position[1] / pr->py);
}

static void drive_probe(pins_t *p)
{
	probe_t *pr = &p->probe;
	int level = (double)pr->position[2] <= surface(pr) ? 0 : 1;
	if (level == pr->level)
		return;
	if (!level)
		pr->touches++;
	pr->level = level;
	drive_input(p, pr->pin, level);
}

static void pin_hook(struct avr_irq_t *irq, uint32_t value, void *param)
{
	pin_state_t *s = param;
	pins_t *p = s->pins;
	uint8_t level = value & 1;
	(void)irq;
	if (level == s->level)
		return;
	s->level = level;
	if (s->traced)
		record(p, s->arduino, level);
	if (!level)
		return;
	for (int a = 0; a < AXES; a++) {
		endstop_t *e = &p->axis[a];
		if (e->active && e->step_pin == s->arduino) {
			e->position_steps += p->pin[e->dir_pin].level ? 1 : -1;
			drive_home(p, e);
		}
	}
	probe_t *pr = &p->probe;
	if (!pr->active)
		return;
	for (int a = 0; a < AXES; a++) {
		if (pr->step_pin[a] == s->arduino) {
			int up = p->pin[pr->dir_pin[a]].level != pr->dir_low_positive;
			pr->position[a] += up ? 1 : -1;
			drive_probe(p);
		}
	}
}

int pins_set_axis(pins_t *p, int axis, int step_pin, int dir_pin)
{
	char port;
	int bit;
	if (axis < 0 || axis >= AXES || pins_arduino(step_pin, &port, &bit) < 0 ||
	    pins_arduino(dir_pin, &port, &bit) < 0)
		return -1;
	if (!p->map_set) {
		for (int a = 0; a < AXES; a++)
			pins_axis_default(a, &p->map_step[a], &p->map_dir[a]);
		p->map_set = 1;
	}
	p->map_step[axis] = (uint8_t)step_pin;
	p->map_dir[axis] = (uint8_t)dir_pin;
	return 0;
}

int pins_add_endstop(pins_t *p, int axis, int home_pin, int64_t trip_steps)
{
	char port;
	int bit;
	if (axis < 0 || axis >= AXES || pins_arduino(home_pin, &port, &bit) < 0)
		return -1;
	endstop_t *e = &p->axis[axis];
	e->active = 1;
	e->step_pin = axis_pins[axis].step;
	e->dir_pin = axis_pins[axis].dir;
	e->home_pin = (uint8_t)home_pin;
	e->trip_steps = trip_steps;
	e->position_steps = 0;
	e->home_level = -1;
	return 0;
}

int pins_add_probe(pins_t *p, int pin, double z0, double amp, double px, double py,
		   int dir_low_positive)
{
	char port;
	int bit;
	if (pins_arduino(pin, &port, &bit) < 0 || (amp != 0.0 && (px == 0.0 || py == 0.0)))
		return -1;
	probe_t *pr = &p->probe;
	pr->active = 1;
	pr->pin = (uint8_t)pin;
	pr->z0 = z0;
	pr->amp = amp;
	pr->px = px;
	pr->py = py;
	pr->dir_low_positive = dir_low_positive;
	pr->level = -1;
	return 0;
}

static void hook(pins_t *p, int pin)
{
	pin_state_t *s = &p->pin[pin];
	if (s->hooked)
		return;
	s->hooked = 1;
	avr_irq_register_notify(pin_irq(p->avr, pin), pin_hook, s);
}

int pins_attach(pins_t *p, avr_t *avr, FILE *trace, const uint8_t *traced, int ntraced)
{
	p->avr = avr;
	p->trace = trace;
	for (int i = 0; i < PINS_MAX; i++) {
		p->pin[i].pins = p;
		p->pin[i].arduino = (uint8_t)i;
	}
	for (int i = 0; i < ntraced; i++) {
		if (traced[i] >= PINS_MAX)
			return -1;
		p->pin[traced[i]].traced = trace != NULL;
		hook(p, traced[i]);
	}
	/* Every end-stop takes its --axis-pins (which may come after --endstop) before
	 * any home pin is driven: a home pin driven while another axis still counts on
	 * its default step pin would count as that axis' step (GRBL's X switch, D9, is
	 * our Y step pin: GRBL's Y switch then closed one step early). */
	for (int a = 0; a < AXES; a++) {
		endstop_t *e = &p->axis[a];
		if (e->active && p->map_set) {
			e->step_pin = p->map_step[a];
			e->dir_pin = p->map_dir[a];
		}
	}
	for (int a = 0; a < AXES; a++) {
		endstop_t *e = &p->axis[a];
		if (!e->active)
			continue;
		hook(p, e->step_pin);
		hook(p, e->dir_pin);
		hook(p, e->home_pin);
		drive_home(p, e);
	}
	probe_t *pr = &p->probe;
	if (pr->active) {
		for (int a = 0; a < AXES; a++) {
			if (p->map_set) {
				pr->step_pin[a] = p->map_step[a];
				pr->dir_pin[a] = p->map_dir[a];
			} else {
				pins_axis_default(a, &pr->step_pin[a], &pr->dir_pin[a]);
			}
			hook(p, pr->step_pin[a]);
			hook(p, pr->dir_pin[a]);
		}
		hook(p, pr->pin);
		drive_probe(p);
	}
	return 0;
}

/* The switch is where it was, and the port's "external" value still holds it;
 * only the PIN bit needs setting again, directly: simavr would filter an IRQ of
 * the level it last raised. */
static void restore_input(pins_t *p, uint8_t pin, int level)
{
	char port = 'B';
	int bit = 0;
	pins_arduino(pin, &port, &bit);
	uint8_t *pin_reg = &p->avr->data[pin_register[port - 'B']];
	*pin_reg = (uint8_t)((*pin_reg & ~(1u << bit)) | ((unsigned)level << bit));
}

void pins_reset(pins_t *p, uint64_t cycle)
{
	write_record(p, cycle, TRACE_RESET_PIN, 0);
	p->cycle_base = cycle;
	for (int a = 0; a < AXES; a++) {
		endstop_t *e = &p->axis[a];
		if (e->active)
			restore_input(p, e->home_pin, e->home_level);
	}
	if (p->probe.active)
		restore_input(p, p->probe.pin, p->probe.level);
}
