/* Integer square roots and the wide products/quotients of the per-move setup.
 * Main loop only (docs/motion.md §10): never called from an interrupt. */
#ifndef GALILEO_INTMATH_H
#define GALILEO_INTMATH_H

#include <stdint.h>

uint16_t isqrt32(uint32_t w);               /* floor(sqrt(w)) */
uint32_t isqrt64(uint64_t w);               /* floor(sqrt(w)), w < 2^64 */
uint32_t round_sqrt32(uint32_t w);          /* u with (u - 1/2)^2 <= w < (u + 1/2)^2 */
/* floor(num / den) for a quotient known to fit 32 bits (num < den * 2^32). */
uint32_t udiv64_32(uint64_t num, uint32_t den);
/* (a * b + 2^(shift-1)) >> shift, with a 64-bit product. */
uint32_t mul_round_shift(uint32_t a, uint32_t b, uint8_t shift);

#endif
