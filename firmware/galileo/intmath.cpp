#include "intmath.h"

uint16_t isqrt32(uint32_t w)
{
    uint32_t root = 0, bit = 1UL << 30;
    while (bit > w)
        bit >>= 2;
    while (bit) {
        if (w >= root + bit) {
            w -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    return (uint16_t)root;
}

uint32_t isqrt64(uint64_t w)
{
    if (w < (1ULL << 32))
        return isqrt32((uint32_t)w);
    uint64_t root = 0, bit = 1ULL << 62;
    while (bit > w)
        bit >>= 2;
    while (bit) {
        if (w >= root + bit) {
            w -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    return (uint32_t)root;
}

uint32_t round_sqrt32(uint32_t w)
{
    /* isqrt(4w) = 2s + [ (2s+1)^2 <= 4w ] = 2s + [ s^2 + s < w ], s = isqrt(w);
     * then (isqrt(4w) + 1) / 2 = s + that bit. 32-bit only. */
    uint32_t s = isqrt32(w);
    return s + (s * s + s < w ? 1 : 0);
}

uint32_t udiv64_32(uint64_t num, uint32_t den)
{
    uint64_t rem = num >> 32; /* < den by the precondition */
    uint32_t low = (uint32_t)num, q = 0;
    for (uint8_t i = 0; i < 32; i++) {
        rem = (rem << 1) | (low >> 31);
        low <<= 1;
        q <<= 1;
        if (rem >= den) {
            rem -= den;
            q |= 1;
        }
    }
    return q;
}

uint32_t mul_round_shift(uint32_t a, uint32_t b, uint8_t shift)
{
    uint64_t p = (uint64_t)a * b + (1ULL << (shift - 1));
    return (uint32_t)(p >> shift);
}
