/* perlin_2002.h: Perlin's improved noise exactly as he wrote it (Perlin 2002: grad() chooses
 * the gradient by branches on the hash), the formula that rd_perlin_grad's table replaced. The
 * reference of tests/test_volume.c (same doubles) and the "before" of bench/bench_photons.c's
 * timing. Header-only, no test framework: static functions, one copy per file. */
#ifndef PERLIN_2002_H
#define PERLIN_2002_H

#include "media/rd_medium.h"

#include <math.h>

static inline double perlin_grad_2002(int h, double x, double y, double z)
{
    h &= 15;
    double u = h < 8 ? x : y;
    double v = h < 4 ? y : (h == 12 || h == 14 ? x : z);
    return ((h & 1) ? -u : u) + ((h & 2) ? -v : v);
}

static inline double lerp_2002(double t, double a, double b) { return a + t * (b - a); }

static inline double perlin_noise_2002(const rd_noise *n, vec3 p)
{
    double fx = floor(p.x), fy = floor(p.y), fz = floor(p.z);
    int X = (int)((long long)fx & 255), Y = (int)((long long)fy & 255), Z = (int)((long long)fz & 255);
    double x = p.x - fx, y = p.y - fy, z = p.z - fz;
    double u = rd_perlin_fade(x), v = rd_perlin_fade(y), w = rd_perlin_fade(z);
    const uint8_t *P = n->perm;
    int A = P[X] + Y, AA = P[A] + Z, AB = P[A + 1] + Z;
    int B = P[X + 1] + Y, BA = P[B] + Z, BB = P[B + 1] + Z;
    return lerp_2002(w,
        lerp_2002(v, lerp_2002(u, perlin_grad_2002(P[AA], x, y, z), perlin_grad_2002(P[BA], x - 1, y, z)),
                  lerp_2002(u, perlin_grad_2002(P[AB], x, y - 1, z), perlin_grad_2002(P[BB], x - 1, y - 1, z))),
        lerp_2002(v, lerp_2002(u, perlin_grad_2002(P[AA + 1], x, y, z - 1), perlin_grad_2002(P[BA + 1], x - 1, y, z - 1)),
                  lerp_2002(u, perlin_grad_2002(P[AB + 1], x, y - 1, z - 1), perlin_grad_2002(P[BB + 1], x - 1, y - 1, z - 1))));
}

#endif /* PERLIN_2002_H */
