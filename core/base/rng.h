/* core/base/rng.h: seeded, splittable random numbers (xoshiro256**, normal deviates).
 *
 * Every random draw in wavetomo comes from a wt_rng seeded by (seed, stream): the same pair gives the
 * same sequence on every machine and for every thread count. Give each independent consumer (a layer,
 * a sensor in a frame) its own stream so results do not depend on the order of evaluation.
 * wt_rng is a plain value (no allocation); copy it freely.
 */
#ifndef WT_RNG_H
#define WT_RNG_H

#include <stdint.h>

typedef struct wt_rng {
    uint64_t s[4];
    int have_spare;  /* Box-Muller makes normals in pairs */
    double spare;
} wt_rng;

/* Initialise from a seed and a stream number (SplitMix64 expansion of both). */
void wt_rng_init(wt_rng *rng, uint64_t seed, uint64_t stream);
uint64_t wt_rng_u64(wt_rng *rng);
/* Uniform on [0, 1), 53 random bits. */
double wt_rng_uniform(wt_rng *rng);
/* Standard normal N(0, 1). */
double wt_rng_normal(wt_rng *rng);

#endif
