/*
 * UART0 <-> host bridge. See uart_bridge.h for what it promises.
 *
 * simavr's own uart_pty part is not used: it pushes host bytes into the UART's
 * 64-byte FIFO as fast as they come, and it symlinks a fixed /tmp name that two
 * harnesses would fight over. Here the host side is polled from the run loop
 * (no thread, so the simulation stays deterministic for a given byte stream)
 * and bytes enter the UART at the wire's pace.
 */
#define _GNU_SOURCE
#include "uart_bridge.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <sim_io.h>
#include <sim_irq.h>
#include <sim_cycle_timers.h>

DEFINE_FIFO(uint16_t, uart_fifo);

/* The 328p's UPMn1:0 (parity mode) bits in UCSRnC; simavr's UART does not
 * describe them. */
#define UCSRC_UPM_SHIFT 4
#define UCSRC_UPM_MASK 0x3

/* On hardware a byte is lost (DOR) when its stop bit arrives while the
 * two-byte receive buffer is still full; in simavr's FIFO that is a third
 * completed, unread byte. */
#define HW_RX_BUFFER 2

/* Waiting for the host to open the pty: poll period, and how long after the
 * open to start anyway when no input flush is seen (a host other than
 * pyserial). */
#define WAIT_POLL_MS 2
#define OPEN_SETTLE_MS 200

int uart_bridge_open_pty(uart_bridge_t *b, const char *link)
{
	int master = posix_openpt(O_RDWR | O_NOCTTY);
	if (master < 0 || grantpt(master) < 0 || unlockpt(master) < 0)
		return -1;
	const char *slave_name = ptsname(master);
	if (!slave_name)
		return -1;
	snprintf(b->slave_path, sizeof(b->slave_path), "%s", slave_name);
	/* Raw mode, set once (it outlives this descriptor), so the line
	 * discipline neither echoes host bytes back into the AVR nor rewrites
	 * CR/LF before pyserial has opened the port. The slave is then closed:
	 * the master reports POLLHUP until the host opens it. */
	int slave = open(b->slave_path, O_RDWR | O_NOCTTY);
	if (slave < 0)
		return -1;
	struct termios tio;
	if (tcgetattr(slave, &tio) == 0) {
		cfmakeraw(&tio);
		tcsetattr(slave, TCSANOW, &tio);
	}
	close(slave);
	/* Packet mode: every read starts with a status byte, which tells when
	 * the host flushes its input (pyserial does so while opening). */
	int one = 1;
	if (ioctl(master, TIOCPKT, &one) < 0)
		return -1;
	fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
	if (link) {
		unlink(link); /* a stale link from an earlier run */
		if (symlink(b->slave_path, link) < 0)
			return -1;
	}
	b->pty_master = master;
	b->in_fd = b->out_fd = master;
	return 0;
}

void uart_bridge_open_stdio(uart_bridge_t *b)
{
	b->pty_master = -1;
	b->in_fd = STDIN_FILENO;
	b->out_fd = STDOUT_FILENO;
}

static uint32_t in_count(const uart_bridge_t *b) { return b->in_head - b->in_tail; }
static uint32_t out_count(const uart_bridge_t *b) { return b->out_head - b->out_tail; }

static void uart_output_hook(struct avr_irq_t *irq, uint32_t value, void *param)
{
	uart_bridge_t *b = param;
	(void)irq;
	if (out_count(b) == UB_OUT_SIZE) {
		b->out_tail++; /* the host is not reading: keep the newest output */
		b->dropped_out++;
	}
	b->out_q[b->out_head++ % UB_OUT_SIZE] = (uint8_t)value;
	b->tx_bytes++;
}

/* Feeds one host byte per frame time; stops itself when the queue is empty. */
static avr_cycle_count_t feed_timer(avr_t *avr, avr_cycle_count_t when, void *param)
{
	uart_bridge_t *b = param;
	avr_uart_t *u = b->uart;
	avr_cycle_count_t frame = u->cycles_per_byte;
	if (in_count(b) == 0) {
		b->feeding = 0;
		return 0;
	}
	/* Receiver off, or simavr's FIFO full (its XOFF): hold the byte, the
	 * host's bytes are never dropped. */
	if (!avr_regbit_get(avr, u->rxen) || uart_fifo_isfull(&u->input))
		return when + frame;
	if (uart_fifo_get_read_size(&u->input) > HW_RX_BUFFER)
		b->overruns++;
	uint8_t byte = b->in_q[b->in_tail++ % UB_IN_SIZE];
	avr_raise_irq(b->irq + UART_IRQ_INPUT, byte);
	b->rx_bytes++;
	b->last_feed_cycle = when;
	return when + frame;
}

int uart_bridge_attach(uart_bridge_t *b, avr_t *avr)
{
	b->avr = avr;
	for (avr_io_t *io = avr->io_port; io; io = io->next) {
		if (io->kind && strcmp(io->kind, "uart") == 0 && ((avr_uart_t *)io)->name == '0')
			b->uart = (avr_uart_t *)io;
	}
	if (!b->uart)
		return -1;
	/* No console echo of UART output, no usleep() when the firmware polls
	 * UCSR0A: the simulation runs as fast as it can. */
	uint32_t flags = 0;
	avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
	b->irq = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), 0);
	avr_irq_register_notify(b->irq + UART_IRQ_OUTPUT, uart_output_hook, b);
	memset(b->seen_regs, 0xff, sizeof(b->seen_regs));
	b->frame_cycles = 0;
	uart_bridge_check_frame(b);
	return 0;
}

void uart_bridge_check_frame(uart_bridge_t *b)
{
	if (b->keep_simavr_timing)
		return;
	avr_t *avr = b->avr;
	avr_uart_t *u = b->uart;
	const uint8_t regs[5] = {
		avr->data[u->ubrrl.reg], avr->data[u->ubrrh.reg], avr->data[u->r_ucsra],
		avr->data[u->r_ucsrb], avr->data[u->r_ucsrc],
	};
	if (u->cycles_per_byte == b->frame_cycles && memcmp(regs, b->seen_regs, sizeof(regs)) == 0)
		return;
	memcpy(b->seen_regs, regs, sizeof(regs));
	static const int databits[8] = {5, 6, 7, 8, 8, 8, 8, 9};
	uint32_t ubrr = regs[0] | ((uint32_t)(regs[1] & 0x0f) << 8);
	uint32_t cycles_per_bit = (ubrr + 1) * (avr_regbit_get(avr, u->u2x) ? 8 : 16);
	int data = databits[avr_regbit_get(avr, u->ucsz) | (avr_regbit_get(avr, u->ucsz2) << 2)];
	int parity = ((regs[4] >> UCSRC_UPM_SHIFT) & UCSRC_UPM_MASK) ? 1 : 0;
	int stop = 1 + avr_regbit_get(avr, u->usbs);
	b->frame_cycles = cycles_per_bit * (uint32_t)(1 + data + parity + stop);
	u->cycles_per_byte = b->frame_cycles;
}

static void start_feeding(uart_bridge_t *b)
{
	if (b->feeding || in_count(b) == 0)
		return;
	avr_cycle_count_t now = b->avr->cycle;
	avr_cycle_count_t next = b->last_feed_cycle + b->uart->cycles_per_byte;
	avr_cycle_timer_register(b->avr, next > now ? next - now : 1, feed_timer, b);
	b->feeding = 1;
}

void uart_bridge_reset(uart_bridge_t *b)
{
	b->in_tail = b->in_head;
	b->feeding = 0;
	b->last_feed_cycle = 0;
	memset(b->seen_regs, 0, sizeof(b->seen_regs));
	b->frame_cycles = 0;
}

static int readable(int fd)
{
	struct pollfd p = {.fd = fd, .events = POLLIN};
	return poll(&p, 1, 0) > 0 && (p.revents & (POLLIN | POLLHUP));
}

static void queue_host_bytes(uart_bridge_t *b, const uint8_t *data, size_t n)
{
	for (size_t i = 0; i < n; i++)
		b->in_q[b->in_head++ % UB_IN_SIZE] = data[i];
}

/* One read from the pty master in packet mode: a status byte, then data if
 * the status is TIOCPKT_DATA. Returns the bytes queued, -1 if none could be
 * read (EAGAIN, or the host has the port closed: EIO). */
static ssize_t read_pty_packet(uart_bridge_t *b, uint32_t room)
{
	uint8_t packet[4097];
	if (room > sizeof(packet) - 1)
		room = sizeof(packet) - 1;
	ssize_t n = read(b->pty_master, packet, room + 1);
	if (n <= 0)
		return -1;
	if (packet[0] != TIOCPKT_DATA) {
		if (packet[0] & TIOCPKT_FLUSHREAD)
			b->host_flushed = 1;
		return 0;
	}
	queue_host_bytes(b, packet + 1, (size_t)n - 1);
	return n - 1;
}

static void read_host(uart_bridge_t *b)
{
	if (b->in_eof)
		return;
	/* A full queue leaves the bytes in the kernel: the host's write blocks
	 * instead of losing them. */
	while (in_count(b) < UB_IN_SIZE) {
		uint32_t room = UB_IN_SIZE - in_count(b);
		if (b->pty_master >= 0) {
			if (read_pty_packet(b, room) < 0)
				break;
			continue;
		}
		if (!readable(b->in_fd))
			break;
		uint8_t chunk[4096];
		ssize_t n = read(b->in_fd, chunk, room < sizeof(chunk) ? room : sizeof(chunk));
		if (n > 0) {
			queue_host_bytes(b, chunk, (size_t)n);
			continue;
		}
		if (n == 0)
			b->in_eof = 1; /* stdin closed; the AVR runs on */
		break;
	}
}

static int64_t monotonic_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

int uart_bridge_wait_open(uart_bridge_t *b, volatile sig_atomic_t *stop)
{
	int64_t opened_ms = -1;
	while (!*stop) {
		struct pollfd p = {.fd = b->pty_master, .events = POLLIN};
		poll(&p, 1, WAIT_POLL_MS);
		/* A flush status outlives a host that opened and closed the port
		 * again between two polls. */
		read_host(b);
		if (b->host_flushed || in_count(b))
			return 0;
		if (p.revents & POLLHUP) {
			opened_ms = -1; /* not open (any more); poll() returns at once */
			usleep(WAIT_POLL_MS * 1000);
			continue;
		}
		if (opened_ms < 0)
			opened_ms = monotonic_ms();
		if (monotonic_ms() - opened_ms >= OPEN_SETTLE_MS)
			return 0;
	}
	return -1;
}

int uart_bridge_wait_input(uart_bridge_t *b, volatile sig_atomic_t *stop)
{
	while (!*stop) {
		struct pollfd p = {.fd = b->in_fd, .events = POLLIN};
		if (poll(&p, 1, WAIT_POLL_MS) > 0) {
			read_host(b);
			return 0;
		}
	}
	return -1;
}

static void write_host(uart_bridge_t *b, int block)
{
	while (out_count(b)) {
		if (b->pty_master < 0 && !block) {
			struct pollfd p = {.fd = b->out_fd, .events = POLLOUT};
			if (poll(&p, 1, 0) <= 0)
				break;
		}
		uint32_t tail = b->out_tail % UB_OUT_SIZE;
		uint32_t len = out_count(b);
		if (len > UB_OUT_SIZE - tail)
			len = UB_OUT_SIZE - tail;
		ssize_t n = write(b->out_fd, b->out_q + tail, len);
		if (n > 0) {
			b->out_tail += (uint32_t)n;
			continue;
		}
		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0 && errno == EPIPE) {
			b->dropped_out += out_count(b);
			b->out_tail = b->out_head;
		}
		break;
	}
}

void uart_bridge_service(uart_bridge_t *b)
{
	write_host(b, 0);
	read_host(b);
	start_feeding(b);
}

void uart_bridge_flush(uart_bridge_t *b)
{
	if (b->pty_master >= 0) {
		/* Give a slow host up to ~0.5 s to take what is left. */
		for (int i = 0; i < 50 && out_count(b); i++) {
			write_host(b, 0);
			if (out_count(b))
				usleep(10000);
		}
	} else {
		write_host(b, 1);
	}
}

void uart_bridge_close(uart_bridge_t *b, const char *link)
{
	if (link) {
		char target[sizeof(b->slave_path)];
		ssize_t n = readlink(link, target, sizeof(target) - 1);
		if (n >= 0) {
			target[n] = 0;
			if (strcmp(target, b->slave_path) == 0)
				unlink(link);
		}
	}
	if (b->pty_master >= 0)
		close(b->pty_master);
}
