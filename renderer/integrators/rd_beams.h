/* rd_beams.h: the photons of a map as spheres that a camera ray crosses, for the beam radiance
 * estimate (Jarosz, Zwicker & Jensen 2008; THEORY.md §6, march.ls = nee+beams): photon k is a
 * ball of radius r_k about its position, and one query per camera-ray segment returns every
 * ball the segment passes through, with the chord [ta, tb] it runs inside it. The balls live in
 * Embree's ray-facing disc points (one BVH per map; beams.c says why discs); FLANN stays the
 * k-NN index that sets the radii. Internal to integrators/ (march.c and its tests). */
#ifndef RD_BEAMS_H
#define RD_BEAMS_H

#include "core/rd_math.h"
#include "photonmap.h"
#include "renderer.h"

typedef struct rd_beams rd_beams;

/* A ball the segment crosses: photon idx of the map, and the part [ta, tb] of the segment
 * (ray parameter) inside it, ta < tb. */
typedef struct {
    int idx;
    float ta, tb;
} rd_beam_hit;

/* An empty set of balls (an Embree device whose BVH builds use `threads` threads, 0: all;
 * queries find nothing until rd_beams_build). */
rd_status rd_beams_new(rd_beams **out, int threads, char *err, size_t errlen);
/* Replace the balls with those of `map` (built or not), photon k with radius radius[k] > 0 (a
 * ball with radius <= 0 or not finite is left out). The map must outlive the balls' use: the
 * queries read its photons. Single-threaded caller; Embree builds with its own threads. */
rd_status rd_beams_build(rd_beams *b, const pm_map *map, const float *radius, char *err, size_t errlen);
void rd_beams_free(rd_beams *b);
/* Every ball that segment [t0, t1] of ray r (unit direction) crosses, each once. At most `cap`
 * are written: when m > cap balls are crossed, a uniform sample of cap of them (reservoir
 * sampling, from rng) is kept and *weight = m / cap (so that a sum over the kept hits times
 * *weight is unbiased for the sum over all m); otherwise *weight = 1. Returns the hits written.
 * Safe from many threads at once on a built set. */
int rd_beams_cross(const rd_beams *b, ray3 r, double t0, double t1, rd_beam_hit *hits, int cap,
                   pcg32 *rng, double *weight);
/* The map the balls were built from (NULL before the first build). */
const pm_map *rd_beams_map(const rd_beams *b);

#endif /* RD_BEAMS_H */
