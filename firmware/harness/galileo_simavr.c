/*
 * galileo-simavr: runs a firmware ELF in simavr with UART0 on a pseudo-terminal
 * (or stdin/stdout), a cycle-exact trace of pin edges, and simulated end-stops.
 * docs/harness.md is the manual; tests/test_simavr_harness.py shows it working.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#include <sim_avr.h>
#include <sim_core.h>
#include <sim_cycle_timers.h>
#include <sim_elf.h>

#include "pins.h"
#include "stack.h"
#include "timer_quirks.h"
#include "uart_bridge.h"

#define DEFAULT_FREQ 16000000u
#define DEFAULT_MCU "atmega328p"
/* Host I/O is serviced every SERVICE_US of simulated time. */
#define SERVICE_US 250u
/* The trace file is flushed at least this often (wall clock). */
#define TRACE_FLUSH_NS 100000000LL

enum { EXIT_OK = 0, EXIT_USAGE = 1, EXIT_SETUP = 2, EXIT_CRASH = 3 };

static const uint8_t default_pins[] = {8, 9, 10, 11, 12, 13};

struct options {
	uint32_t freq;
	const char *mcu;
	const char *pty_link;
	int stdio;
	const char *trace_path;
	uint8_t pins[PINS_MAX];
	int npins;
	double max_seconds;
	double max_speed; /* simulated seconds per wall-clock second; 0: no limit */
	int no_wait;
	int keep_simavr_timing;
	int stack_paint; /* the pattern byte of --stack-paint, or -1 */
	int ocr1a_at_start; /* --ocr1a-at-start, or -1 */
	int replay_tcnt0;
	int exit_with_parent;
	int verbose;
	const char *elf;
};

static volatile sig_atomic_t stop_signal;
static int log_level = LOG_WARNING;

static void on_signal(int sig) { stop_signal = sig; }

/* --exit-with-parent: a harness whose host died (a test run killed) would
 * otherwise simulate on, a core busy, until someone kills it. Checked twice a
 * second from SIGALRM; getppid() is async-signal-safe. */
static pid_t parent_pid;
static volatile sig_atomic_t parent_gone;
static void on_parent_check(int sig)
{
	if (getppid() != parent_pid) {
		parent_gone = 1;
		stop_signal = sig;
	}
}

static const char *stop_reason(void)
{
	return parent_gone ? "parent exited" : strsignal(stop_signal);
}

static void watch_parent(void)
{
	parent_pid = getppid();
	struct sigaction sa;
	memset(&sa, 0, sizeof(sa));
	sa.sa_handler = on_parent_check;
	sa.sa_flags = SA_RESTART; /* the bridge's reads and writes go on */
	sigaction(SIGALRM, &sa, NULL);
	struct itimerval every = {.it_interval = {0, 500000}, .it_value = {0, 500000}};
	setitimer(ITIMER_REAL, &every, NULL);
}

/* SIGUSR1 presses the reset button (as an Uno's auto-reset when a port opens). */
static volatile sig_atomic_t reset_requested;
static void on_reset_signal(int sig) { (void)sig; reset_requested = 1; }

/* simavr's messages go to stderr: stdout carries "pty:" or the UART itself. */
static void logger(avr_t *avr, const int level, const char *format, va_list ap)
{
	(void)avr;
	if (level <= log_level)
		vfprintf(stderr, format, ap);
}

/* simavr's raw sleep callback usleep()s to keep sleeping firmware at wall-clock
 * pace; the harness runs as fast as it can (or paces itself, --realtime). */
static void no_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
	(void)avr;
	(void)how_long;
}

static int64_t now_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

static void usage(FILE *out)
{
	fprintf(out,
		"usage: galileo-simavr [--freq HZ] [--mcu NAME] [--pty LINK | --stdio]\n"
		"                      [--trace FILE] [--pins N,N,...] [--endstop AXIS:HOMEPIN:TRIP]...\n"
		"                      [--max-seconds S] [--realtime | --max-speed F] [--no-wait]\n"
		"                      [--simavr-uart-timing] [--stack-paint BYTE]\n"
		"                      [--axis-pins SPEC] [--ocr1a-at-start N] [--replay-tcnt0]\n"
		"                      [--probe PIN:Z0[:AMP:PX:PY] [--probe-dir-low-positive]]\n"
		"                      [--exit-with-parent] [-v] ELF\n"
		"\n"
		"  --pty LINK        UART0 on a new pseudo-terminal, LINK a symlink to it;\n"
		"                    prints 'pty: <slave path>' on stdout when ready; the AVR\n"
		"                    leaves reset once the host has opened the port\n"
		"  --stdio           UART0 on stdin/stdout (the default); unless stdin is a\n"
		"                    terminal, the AVR leaves reset when stdin has input or ends\n"
		"  --no-wait         run at once, port opened or not, input or not\n"
		"  --trace FILE      pin edges as records <u64 cycle><u8 pin><u8 level> (LE)\n"
		"  --pins SPEC       traced Arduino pins (default 8,9,10,11,12,13)\n"
		"  --endstop A:P:T   axis A (X, Y, Z) drives home pin P low while its step\n"
		"                    count from power-up is <= T, high otherwise\n"
		"  --probe P:Z0[:AMP:PX:PY]  drive pin P low (touching) while the Z step\n"
		"                    count is <= Z0 + AMP sin(2 pi x/PX) sin(2 pi y/PY), x, y\n"
		"                    the X and Y step counts (flat at Z0 without AMP:PX:PY)\n"
		"  --probe-dir-low-positive  the probe counts a step + when its dir pin is\n"
		"                    low (GRBL's sense with $3=0; --endstop keeps high = +)\n"
		"  --max-seconds S   stop after S seconds of simulated time\n"
		"  --realtime        never run ahead of the wall clock (--max-speed 1)\n"
		"  --max-speed F     never run more than F times faster than the wall clock\n"
		"  --simavr-uart-timing  keep simavr's 11-bit 8N1 frames (for comparison)\n"
		"  --stack-paint BYTE  the firmware fills free SRAM with BYTE at reset: report\n"
		"                    the stack's high-water mark at exit ('stack:' line)\n"
		"  --axis-pins SPEC  step/dir pins the end-stops count on, e.g. GRBL's\n"
		"                    X:2:5,Y:3:6,Z:4:7 (default X:11:10,Y:9:8,Z:13:12)\n"
		"  --ocr1a-at-start N  OCR1A = N at cycle 0 (simavr never fires CTC TOP 0)\n"
		"  --replay-tcnt0    a TCNT0 preload written while Timer0 is stopped takes\n"
		"                    effect when it starts (silicon does, simavr drops it)\n"
		"  --exit-with-parent  stop when the process that started the harness ends\n");
}

static int parse_pins(const char *spec, struct options *o)
{
	char *copy = strdup(spec), *save = NULL;
	o->npins = 0;
	for (char *tok = strtok_r(copy, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
		char *end, port;
		int bit;
		long pin = strtol(tok, &end, 10);
		if (*end || pins_arduino((int)pin, &port, &bit) < 0 || o->npins == PINS_MAX) {
			fprintf(stderr, "galileo-simavr: --pins: '%s' is not an Uno pin (0..19)\n", tok);
			free(copy);
			return -1;
		}
		o->pins[o->npins++] = (uint8_t)pin;
	}
	free(copy);
	return 0;
}

static int parse_endstop(const char *spec, pins_t *pins)
{
	char axis_name;
	int home_pin, used = 0;
	long long trip;
	const char *axes = "XYZ";
	if (sscanf(spec, "%c:%d:%lld%n", &axis_name, &home_pin, &trip, &used) != 3 || spec[used] ||
	    !strchr(axes, axis_name) || !axis_name ||
	    pins_add_endstop(pins, (int)(strchr(axes, axis_name) - axes), home_pin, trip) < 0) {
		fprintf(stderr, "galileo-simavr: --endstop: expected AXIS:HOMEPIN:TRIP "
				"like X:7:-100, got '%s'\n", spec);
		return -1;
	}
	return 0;
}

static int parse_probe(const char *spec, pins_t *pins, int dir_low_positive)
{
	int pin, used = 0, fields;
	double z0, amp = 0.0, px = 0.0, py = 0.0;
	fields = sscanf(spec, "%d:%lf%n:%lf:%lf:%lf%n", &pin, &z0, &used, &amp, &px, &py, &used);
	if ((fields != 2 && fields != 5) || spec[used] ||
	    pins_add_probe(pins, pin, z0, amp, px, py, dir_low_positive) < 0) {
		fprintf(stderr, "galileo-simavr: --probe: expected PIN:Z0 or PIN:Z0:AMP:PX:PY (step "
				"counts, PX and PY not 0) like 19:-800:40:1600:1600, got '%s'\n", spec);
		return -1;
	}
	return 0;
}

static int parse_axis_pins(const char *spec, pins_t *pins)
{
	char *copy = strdup(spec), *save = NULL;
	const char *axes = "XYZ";
	int status = 0;
	for (char *tok = strtok_r(copy, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
		char axis_name = 0;
		int step, dir, used = 0;
		if (sscanf(tok, "%c:%d:%d%n", &axis_name, &step, &dir, &used) != 3 || tok[used] ||
		    !axis_name || !strchr(axes, axis_name) ||
		    pins_set_axis(pins, (int)(strchr(axes, axis_name) - axes), step, dir) < 0) {
			fprintf(stderr, "galileo-simavr: --axis-pins: expected AXIS:STEP:DIR like "
					"X:2:5, got '%s'\n", tok);
			status = -1;
			break;
		}
	}
	free(copy);
	return status;
}

static int parse_args(int argc, char **argv, struct options *o, pins_t *pins)
{
	enum { OPT_FREQ = 256, OPT_MCU, OPT_PTY, OPT_STDIO, OPT_TRACE, OPT_PINS, OPT_ENDSTOP,
	       OPT_MAX_SECONDS, OPT_REALTIME, OPT_MAX_SPEED, OPT_NO_WAIT, OPT_SIMAVR_UART,
	       OPT_STACK_PAINT, OPT_AXIS_PINS, OPT_OCR1A, OPT_REPLAY_TCNT0, OPT_EXIT_WITH_PARENT,
	       OPT_PROBE, OPT_PROBE_DIR_LOW };
	static const struct option longs[] = {
		{"freq", required_argument, 0, OPT_FREQ},
		{"mcu", required_argument, 0, OPT_MCU},
		{"pty", required_argument, 0, OPT_PTY},
		{"stdio", no_argument, 0, OPT_STDIO},
		{"trace", required_argument, 0, OPT_TRACE},
		{"pins", required_argument, 0, OPT_PINS},
		{"endstop", required_argument, 0, OPT_ENDSTOP},
		{"max-seconds", required_argument, 0, OPT_MAX_SECONDS},
		{"realtime", no_argument, 0, OPT_REALTIME},
		{"max-speed", required_argument, 0, OPT_MAX_SPEED},
		{"no-wait", no_argument, 0, OPT_NO_WAIT},
		{"simavr-uart-timing", no_argument, 0, OPT_SIMAVR_UART},
		{"stack-paint", required_argument, 0, OPT_STACK_PAINT},
		{"axis-pins", required_argument, 0, OPT_AXIS_PINS},
		{"ocr1a-at-start", required_argument, 0, OPT_OCR1A},
		{"replay-tcnt0", no_argument, 0, OPT_REPLAY_TCNT0},
		{"exit-with-parent", no_argument, 0, OPT_EXIT_WITH_PARENT},
		{"probe", required_argument, 0, OPT_PROBE},
		{"probe-dir-low-positive", no_argument, 0, OPT_PROBE_DIR_LOW},
		{"verbose", no_argument, 0, 'v'},
		{"help", no_argument, 0, 'h'},
		{0, 0, 0, 0},
	};
	o->freq = DEFAULT_FREQ;
	o->mcu = DEFAULT_MCU;
	o->stack_paint = -1;
	o->ocr1a_at_start = -1;
	memcpy(o->pins, default_pins, sizeof(default_pins));
	o->npins = (int)sizeof(default_pins);
	int c;
	char *end;
	const char *probe_spec = NULL;
	int probe_dir_low = 0;
	while ((c = getopt_long(argc, argv, "vh", longs, NULL)) != -1) {
		switch (c) {
		case OPT_FREQ:
			o->freq = (uint32_t)strtoul(optarg, &end, 10);
			if (*end || !o->freq) {
				fprintf(stderr, "galileo-simavr: --freq: '%s' is not a frequency in Hz\n", optarg);
				return -1;
			}
			break;
		case OPT_MCU: o->mcu = optarg; break;
		case OPT_PTY: o->pty_link = optarg; break;
		case OPT_STDIO: o->stdio = 1; break;
		case OPT_TRACE: o->trace_path = optarg; break;
		case OPT_PINS:
			if (parse_pins(optarg, o) < 0)
				return -1;
			break;
		case OPT_ENDSTOP:
			if (parse_endstop(optarg, pins) < 0)
				return -1;
			break;
		case OPT_MAX_SECONDS:
			o->max_seconds = strtod(optarg, &end);
			if (*end || o->max_seconds <= 0) {
				fprintf(stderr, "galileo-simavr: --max-seconds: '%s' is not a positive number\n", optarg);
				return -1;
			}
			break;
		case OPT_REALTIME: o->max_speed = 1.0; break;
		case OPT_MAX_SPEED:
			o->max_speed = strtod(optarg, &end);
			if (*end || o->max_speed <= 0) {
				fprintf(stderr, "galileo-simavr: --max-speed: '%s' is not a positive factor\n", optarg);
				return -1;
			}
			break;
		case OPT_NO_WAIT: o->no_wait = 1; break;
		case OPT_SIMAVR_UART: o->keep_simavr_timing = 1; break;
		case OPT_STACK_PAINT: {
			unsigned long byte = strtoul(optarg, &end, 0);
			if (*end || !*optarg || byte > 0xff) {
				fprintf(stderr, "galileo-simavr: --stack-paint: '%s' is not a byte (0..255, 0xC5)\n", optarg);
				return -1;
			}
			o->stack_paint = (int)byte;
			break;
		}
		case OPT_AXIS_PINS:
			if (parse_axis_pins(optarg, pins) < 0)
				return -1;
			break;
		case OPT_OCR1A: {
			unsigned long value = strtoul(optarg, &end, 0);
			if (*end || !*optarg || value > 0xffff) {
				fprintf(stderr, "galileo-simavr: --ocr1a-at-start: '%s' is not 0..65535\n", optarg);
				return -1;
			}
			o->ocr1a_at_start = (int)value;
			break;
		}
		case OPT_REPLAY_TCNT0: o->replay_tcnt0 = 1; break;
		case OPT_EXIT_WITH_PARENT: o->exit_with_parent = 1; break;
		case OPT_PROBE: probe_spec = optarg; break;
		case OPT_PROBE_DIR_LOW: probe_dir_low = 1; break;
		case 'v': o->verbose++; break;
		case 'h': usage(stdout); exit(EXIT_OK);
		default: usage(stderr); return -1;
		}
	}
	/* after the loop: --probe-dir-low-positive may come after --probe */
	if (probe_spec && parse_probe(probe_spec, pins, probe_dir_low) < 0)
		return -1;
	if (probe_dir_low && !probe_spec) {
		fprintf(stderr, "galileo-simavr: --probe-dir-low-positive needs --probe\n");
		return -1;
	}
	if (o->pty_link && o->stdio) {
		fprintf(stderr, "galileo-simavr: --pty and --stdio exclude each other\n");
		return -1;
	}
	if (optind != argc - 1) {
		usage(stderr);
		return -1;
	}
	o->elf = argv[optind];
	return 0;
}

static const char *state_name(int state)
{
	switch (state) {
	case cpu_Limbo: return "limbo";
	case cpu_Stopped: return "stopped";
	case cpu_Running: return "running";
	case cpu_Sleeping: return "sleeping";
	case cpu_Step: return "step";
	case cpu_StepDone: return "step-done";
	case cpu_Done: return "done";
	case cpu_Crashed: return "crashed";
	default: return "unknown";
	}
}

struct run {
	avr_t *avr;
	uart_bridge_t *uart;
	FILE *trace;
	double max_speed;
	int64_t start_ns, last_flush_ns;
	avr_cycle_count_t service_cycles;
	int out_of_time;
	int state_at_stop;
	uint64_t resets;
	avr_cycle_count_t cycle_base; /* cycles run before the last reset */
	avr_cycle_count_t max_cycles; /* --max-seconds in cycles, or 0 */
	pins_t *pins;
	timer_quirks_t *quirks;
};

/* Cycles since power-up: simavr's count restarts at every reset. */
static avr_cycle_count_t run_cycles(const struct run *r)
{
	return r->cycle_base + r->avr->cycle;
}

/* --max-seconds: a timer, so a sleeping AVR stops on the exact cycle too
 * (stopping the core keeps simavr from jumping on to the next timer). */
static avr_cycle_count_t max_seconds_timer(avr_t *avr, avr_cycle_count_t when, void *param)
{
	struct run *r = param;
	(void)when;
	r->out_of_time = 1;
	r->state_at_stop = avr->state;
	avr->state = cpu_Stopped;
	return 0;
}

/* Host I/O, trace flushing and wall-clock pacing, from a cycle timer. */
static avr_cycle_count_t service_timer(avr_t *avr, avr_cycle_count_t when, void *param)
{
	struct run *r = param;
	uart_bridge_service(r->uart);
	int64_t now = now_ns();
	if (r->trace && now - r->last_flush_ns > TRACE_FLUSH_NS) {
		fflush(r->trace);
		r->last_flush_ns = now;
	}
	if (r->max_speed > 0) {
		double sim_ns = (double)run_cycles(r) * 1e9 / avr->frequency;
		int64_t ahead_ns = (int64_t)(sim_ns / r->max_speed) - (now - r->start_ns);
		if (ahead_ns > 1000000)
			usleep((useconds_t)(ahead_ns / 1000));
	}
	return when + r->service_cycles;
}

/* The reset button. simavr's avr_reset() restarts the cycle count and drops
 * every cycle timer, so the trace carries on from a base (with a mark at the
 * reset) and the harness' timers start again. The head keeps its place: the
 * end-stops go on counting from where it stands. Host bytes not yet delivered
 * are lost, as a real board's are while it restarts. */
static void reset_board(struct run *r)
{
	avr_t *avr = r->avr;
	avr_cycle_count_t at = run_cycles(r);
	r->cycle_base = at;
	avr_reset(avr);
	pins_reset(r->pins, at);
	uart_bridge_reset(r->uart);
	timer_quirks_start(r->quirks);
	avr_cycle_timer_register(avr, r->service_cycles, service_timer, r);
	if (r->max_cycles) {
		if (at >= r->max_cycles)
			r->out_of_time = 1;
		else
			avr_cycle_timer_register(avr, r->max_cycles - at, max_seconds_timer, r);
	}
}

int main(int argc, char **argv)
{
	static struct options opt;
	static pins_t pins;
	static uart_bridge_t uart;
	static stack_watch_t stack;
	static timer_quirks_t quirks;

	if (parse_args(argc, argv, &opt, &pins) < 0)
		return EXIT_USAGE;
	log_level = opt.verbose ? LOG_TRACE : LOG_WARNING;
	avr_global_logger_set(logger);

	elf_firmware_t fw;
	memset(&fw, 0, sizeof(fw));
	if (elf_read_firmware(opt.elf, &fw) != 0) {
		fprintf(stderr, "galileo-simavr: cannot read ELF '%s'\n", opt.elf);
		return EXIT_SETUP;
	}
	const char *mcu = fw.mmcu[0] ? fw.mmcu : opt.mcu;
	avr_t *avr = avr_make_mcu_by_name(mcu);
	if (!avr) {
		fprintf(stderr, "galileo-simavr: simavr has no core '%s'\n", mcu);
		return EXIT_SETUP;
	}
	avr_init(avr);
	fw.frequency = opt.freq;
	avr_load_firmware(avr, &fw);
	avr->frequency = opt.freq;
	avr->sleep = no_sleep;
	if (opt.stack_paint >= 0 && stack_watch_init(&stack, avr, &fw, (uint8_t)opt.stack_paint) < 0)
		return EXIT_SETUP;

	uart.keep_simavr_timing = opt.keep_simavr_timing;
	if (opt.pty_link) {
		if (uart_bridge_open_pty(&uart, opt.pty_link) < 0) {
			fprintf(stderr, "galileo-simavr: cannot set up pty link '%s': %s\n", opt.pty_link,
				strerror(errno));
			return EXIT_SETUP;
		}
	} else {
		uart_bridge_open_stdio(&uart);
	}
	if (uart_bridge_attach(&uart, avr) < 0) {
		fprintf(stderr, "galileo-simavr: core '%s' has no UART0\n", mcu);
		return EXIT_SETUP;
	}

	FILE *trace = NULL;
	if (opt.trace_path) {
		trace = fopen(opt.trace_path, "wb");
		if (!trace) {
			fprintf(stderr, "galileo-simavr: cannot write trace '%s': %s\n", opt.trace_path,
				strerror(errno));
			return EXIT_SETUP;
		}
		setvbuf(trace, NULL, _IOFBF, 1 << 20);
	}
	if (pins_attach(&pins, avr, trace, opt.pins, opt.npins) < 0)
		return EXIT_SETUP;
	quirks.ocr1a_at_start = opt.ocr1a_at_start;
	quirks.replay_tcnt0 = opt.replay_tcnt0;
	if (timer_quirks_attach(&quirks, avr) < 0)
		return EXIT_SETUP;

	struct sigaction sa;
	memset(&sa, 0, sizeof(sa));
	sa.sa_handler = on_signal;
	sigaction(SIGTERM, &sa, NULL);
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGHUP, &sa, NULL);
	sa.sa_handler = on_reset_signal;
	sigaction(SIGUSR1, &sa, NULL);
	signal(SIGPIPE, SIG_IGN);
	if (opt.exit_with_parent)
		watch_parent();

	struct run run = {
		.avr = avr, .uart = &uart, .trace = trace, .max_speed = opt.max_speed,
		.service_cycles = (avr_cycle_count_t)opt.freq / 1000000u * SERVICE_US,
		.pins = &pins, .quirks = &quirks,
	};
	avr_cycle_timer_register(avr, run.service_cycles, service_timer, &run);

	if (opt.pty_link) {
		printf("pty: %s\n", uart.slave_path);
		fflush(stdout);
		/* Like an Uno's auto-reset on open: a banner sent before the host
		 * has opened (and flushed) the port would be lost. */
		if (!opt.no_wait && uart_bridge_wait_open(&uart, &stop_signal) < 0) {
			fprintf(stderr, "galileo-simavr: stop: %s before the port was opened; state=%s "
				"pc=0x0000 cycle=0 (0.000000 s)\n", stop_reason(), state_name(avr->state));
			if (trace)
				fclose(trace);
			uart_bridge_close(&uart, opt.pty_link);
			return EXIT_OK;
		}
	}
	/* A pipe's bytes would otherwise arrive after the simulation (much
	 * faster than the wall clock) has run past --max-seconds. */
	if (!opt.pty_link && !opt.no_wait && !isatty(STDIN_FILENO))
		uart_bridge_wait_input(&uart, &stop_signal);
	timer_quirks_start(&quirks);
	run.start_ns = run.last_flush_ns = now_ns();
	if (opt.max_seconds > 0) {
		run.max_cycles = (avr_cycle_count_t)(opt.max_seconds * opt.freq + 0.5);
		avr_cycle_timer_register(avr, run.max_cycles, max_seconds_timer, &run);
	}

	const char *reason = NULL;
	int status = EXIT_OK;
	for (;;) {
		if (stack.enabled)
			stack_watch_before(&stack);
		int state = avr_run(avr);
		if (stack.enabled)
			stack_watch_after(&stack);
		uart_bridge_check_frame(&uart);
		if (state == cpu_Done) {
			reason = avr->sreg[S_I] ? "done" : "sleeping with interrupts off";
			break;
		}
		if (state == cpu_Crashed) {
			reason = "crashed";
			status = EXIT_CRASH;
			break;
		}
		if (stop_signal) {
			reason = stop_reason();
			break;
		}
		if (reset_requested) {
			reset_requested = 0;
			reset_board(&run);
			run.resets++;
		}
		if (run.out_of_time) {
			reason = "max-seconds";
			avr->state = run.state_at_stop;
			break;
		}
	}

	uart_bridge_flush(&uart);
	if (trace)
		fclose(trace);
	if (stack.enabled)
		stack_watch_report(&stack, stderr);
	if (opt.replay_tcnt0) /* its own line, before the summary, which stays last */
		fprintf(stderr, "galileo-simavr: quirks: tcnt0_replays=%llu\n",
			(unsigned long long)quirks.replays);
	if (pins.probe.active)
		fprintf(stderr, "galileo-simavr: probe: touches=%llu x=%lld y=%lld z=%lld\n",
			(unsigned long long)pins.probe.touches, (long long)pins.probe.position[0],
			(long long)pins.probe.position[1], (long long)pins.probe.position[2]);
	fprintf(stderr,
		"galileo-simavr: stop: %s; state=%s pc=0x%04x cycle=%llu (%.6f s) "
		"uart0 rx=%llu tx=%llu frame=%llu cycles overruns=%llu dropped=%llu trace=%llu "
		"resets=%llu\n",
		reason, state_name(avr->state), (unsigned)avr->pc, (unsigned long long)run_cycles(&run),
		(double)run_cycles(&run) / opt.freq, (unsigned long long)uart.rx_bytes,
		(unsigned long long)uart.tx_bytes, (unsigned long long)uart.uart->cycles_per_byte,
		(unsigned long long)uart.overruns, (unsigned long long)uart.dropped_out,
		(unsigned long long)pins.records, (unsigned long long)run.resets);
	uart_bridge_close(&uart, opt.pty_link);
	return status;
}
