/* core/base/rng.c: xoshiro256** (Blackman & Vigna) seeded by SplitMix64; Box-Muller normals. */
#include "rng.h"

#include <math.h>

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static inline uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

void wt_rng_init(wt_rng *rng, uint64_t seed, uint64_t stream)
{
    /* Mix the stream into the seed so that nearby (seed, stream) pairs give unrelated states. */
    uint64_t x = seed ^ 0x6a09e667f3bcc909ULL;
    uint64_t y = splitmix64(&x) ^ (stream * 0xd1342543de82ef95ULL + 0x2545f4914f6cdd1dULL);
    for (int i = 0; i < 4; i++) rng->s[i] = splitmix64(&y);
    rng->have_spare = 0;
    rng->spare = 0.0;
}

uint64_t wt_rng_u64(wt_rng *rng)
{
    uint64_t *s = rng->s;
    uint64_t result = rotl(s[1] * 5, 7) * 9;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double wt_rng_uniform(wt_rng *rng) { return (double)(wt_rng_u64(rng) >> 11) * 0x1.0p-53; }

double wt_rng_normal(wt_rng *rng)
{
    if (rng->have_spare) {
        rng->have_spare = 0;
        return rng->spare;
    }
    double u1, u2;
    do u1 = wt_rng_uniform(rng);
    while (u1 <= 0.0);
    u2 = wt_rng_uniform(rng);
    double r = sqrt(-2.0 * log(u1));
    double a = 2.0 * M_PI * u2;
    rng->spare = r * sin(a);
    rng->have_spare = 1;
    return r * cos(a);
}
