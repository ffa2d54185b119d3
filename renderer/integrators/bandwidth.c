/* bandwidth.c: r_1(x), the kernel bandwidth of the photon sources' progressive passes
 * (march.c's point gather, march_beams.c's balls), from pass 1's photon map. */
#include "integrators/rd_march.h"
#include "photonmap.h"

/* r_1(x), the k-NN bandwidth of seed 001's fixed map (k = guide.k) in pass 1's map (or the fixed
 * map), read from a nearer neighbour: under a locally uniform photon density the distance d_j to the
 * j-th nearest grows as j^(1/3), so
 *     r_1(x) = d_j(x) (k / j)^(1/3),   j = min(k, max(PASS_RADIUS_MIN_J, ceil(k / 4))).
 * At the default k = 64 (j = 16) the renders' camera time fell by 29% against the 64-NN query
 * (docs/benchmarks.md "Session 18"; j = 8 took no less), and the radius of 16 photons spreads by
 * about 1 / (3 sqrt(16)) = 8% from point to point where that of 64 spreads by 4%. j never falls
 * below 8 (below k = 8, j = k as before): the ball through the nearest photon alone has a
 * volume V with E[1/V] infinite, and a later pass's variance grows as 1/V. Where pass 1 holds
 * fewer than j photons in all, the farthest of them stands in for the j-th.
 * Any r_1 > 0 fixed by pass 1 keeps the passes' average consistent: r_1 depends on pass 1's
 * photons only, so every later pass's estimate is a fixed-kernel estimate, independent of its
 * own photons. -1 where the map holds no photon at all. */
#define PASS_RADIUS_MIN_J 8
double rd_march_knn_bandwidth(const pm_map *first, int k, vec3 x)
{
    if (k > RD_MAX_GATHER) k = RD_MAX_GATHER;
    int j = (k + 3) / 4;
    if (j < PASS_RADIUS_MIN_J) j = PASS_RADIUS_MIN_J;
    if (j > k) j = k;
    int idx[RD_MAX_GATHER];
    float d2[RD_MAX_GATHER];
    double xd[3] = {x.x, x.y, x.z};
    int n = pm_map_knn(first, xd, j, idx, d2); /* n < j only when pass 1 holds fewer photons */
    if (n <= 0 || !(d2[n - 1] > 0.0f)) return -1.0;
    return sqrt((double)d2[n - 1]) * cbrt((double)k / n);
}

