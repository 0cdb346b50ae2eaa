/*
 * The firmware's stack high-water mark: see stack.h and docs/harness.md.
 */
#include "stack.h"

#include <string.h>

/* ELF data addresses carry the linker's 0x800000 offset. */
static int find_symbol(const elf_firmware_t *fw, const char *name, uint16_t *addr)
{
	for (uint32_t i = 0; i < fw->symbolcount; i++) {
		if (fw->symbol[i] && !strcmp(fw->symbol[i]->symbol, name)) {
			*addr = (uint16_t)(fw->symbol[i]->addr & 0xffff);
			return 0;
		}
	}
	return -1;
}

int stack_watch_init(stack_watch_t *s, avr_t *avr, const elf_firmware_t *fw, uint8_t pattern)
{
	memset(s, 0, sizeof(*s));
	s->avr = avr;
	s->pattern = pattern;
	s->ramend = avr->ramend;
	if (find_symbol(fw, "_end", &s->end) < 0 && find_symbol(fw, "__heap_start", &s->end) < 0) {
		fprintf(stderr, "galileo-simavr: --stack-paint: the ELF has no symbol _end "
			"(the end of its static data)\n");
		return -1;
	}
	if (find_symbol(fw, "__data_start", &s->ram_start) < 0)
		s->ram_start = (uint16_t)(avr->ioend + 1);
	if (s->end < s->ram_start || s->end > s->ramend + 1u) {
		fprintf(stderr, "galileo-simavr: --stack-paint: _end 0x%04x is outside SRAM "
			"0x%04x..0x%04x\n", s->end, s->ram_start, s->ramend);
		return -1;
	}
	s->sp_min = s->ramend;
	s->enabled = 1;
	return 0;
}

void stack_watch_report(const stack_watch_t *s, FILE *out)
{
	const uint8_t *ram = s->avr->data;
	unsigned lowest = s->end;
	while (lowest <= s->ramend && ram[lowest] == s->pattern)
		lowest++;
	/* Pushes write at SP and then decrement it: nothing below the deepest SP
	 * should have been written. */
	unsigned clobbered = 0;
	for (unsigned a = s->end; a <= s->sp_min && a <= s->ramend; a++)
		clobbered += ram[a] != s->pattern;
	fprintf(out,
		"galileo-simavr: stack: pattern=0x%02x ram_start=0x%04x ramend=0x%04x static=%u end=0x%04x "
		"lowest=0x%04x peak=%u free=%u sp_min=0x%04x sp_peak=%u sp_min_pc=0x%04x clobbered=%u\n",
		s->pattern, s->ram_start, s->ramend, (unsigned)(s->end - s->ram_start), s->end,
		lowest, s->ramend + 1u - lowest, lowest - s->end, s->sp_min,
		(unsigned)(s->ramend - s->sp_min), (unsigned)s->sp_min_pc, clobbered);
}
