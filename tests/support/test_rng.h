/* test_rng.h: the small PCG32 (O'Neill 2014) the sh/ tests draw from, header-only so each
 * test file gets its own static copy. Fixed seeds; no state outside the rng value. */
#ifndef TEST_RNG_H
#define TEST_RNG_H

#include <math.h>
#include <stdint.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

typedef struct {
    uint64_t s, inc;
} rng;
static inline uint32_t rng_u32(rng *r)
{
    uint64_t old = r->s;
    r->s = old * 6364136223846793005ull + r->inc;
    uint32_t xs = (uint32_t)(((old >> 18u) ^ old) >> 27u), rot = (uint32_t)(old >> 59u);
    return (xs >> rot) | (xs << ((-rot) & 31));
}
static inline rng rng_new(uint64_t seed)
{
    rng r = {0, (seed << 1u) | 1u};
    rng_u32(&r);
    r.s += 0x853c49e6748fea9bull;
    rng_u32(&r);
    return r;
}
static inline double rng_u01(rng *r) { return rng_u32(r) * 0x1.0p-32; }
/* Standard normal (Box-Muller). */
static inline double rng_normal(rng *r)
{
    double u = fmax(rng_u01(r), 1e-300), v = rng_u01(r);
    return sqrt(-2.0 * log(u)) * cos(2.0 * M_PI * v);
}
/* Uniform direction on the sphere. */
static inline void rng_dir(rng *r, double w[3])
{
    double z = 1.0 - 2.0 * rng_u01(r), phi = 2.0 * M_PI * rng_u01(r);
    double s = sqrt(fmax(0.0, 1.0 - z * z));
    w[0] = s * cos(phi), w[1] = s * sin(phi), w[2] = z;
}

#endif
