/* rng.h — deterministic pseudo-random numbers (xoshiro256** seeded by
 * splitmix64), so the same --seed gives the same bytes on every machine.
 * No global state: each user owns a crom_rng. */
#ifndef CROM_RNG_H
#define CROM_RNG_H

#include <stdint.h>

typedef struct {
    uint64_t s[4];
} crom_rng;

/* Seed the generator; any 64-bit value is fine (0 included). */
void crom_rng_seed(crom_rng *r, uint64_t seed);

/* Next raw 64-bit value. */
uint64_t crom_rng_next(crom_rng *r);

/* Uniform double in [0, 1). */
double crom_rng_uniform(crom_rng *r);

/* Standard normal (Box–Muller, no cached second value). */
double crom_rng_normal(crom_rng *r);

/* Uniform integer in [0, n) without modulo bias; n > 0. */
uint64_t crom_rng_below(crom_rng *r, uint64_t n);

/* Fisher–Yates shuffle of an int array. */
void crom_rng_shuffle(crom_rng *r, int *a, int n);

#endif
