/* passes.c: the schedule of progressive photon mapping for volumes (Knaus & Zwicker 2011, "
 * Progressive photon mapping: a probabilistic approach", with the kernel in 3-D).
 *
 * Pass i (i = 1, 2, ...) traces a fresh batch of N photons, independent of every other pass,
 * and the samples rendered with it gather within radius r_i. The image is the running average
 * over the passes. The kernel estimate of pass i has
 *     bias      ~ c_b r_i^2          (a second-order kernel: the Laplacian of the radiance),
 *     variance  ~ c_v / (N r_i^3)    (the photons inside a ball of volume (4/3) pi r_i^3).
 * K&Z let the variance of each pass grow by (i + 1) / (i + alpha), which here is the radius rule
 *     r_{i+1}^3 = r_i^3 (i + alpha) / (i + 1),   so  r_i^3 ~ i^(alpha - 1).
 * Averaged over n passes the variance falls as n^-alpha (sum i^(1-alpha) / n^2) and the bias as
 * the mean of r_i^2 ~ n^(2(alpha - 1)/3); the squared error is
 *     MSE(n) ~ A n^-alpha + B n^(4(alpha - 1)/3),
 * and the two rates are equal, the asymptotic MSE smallest, at alpha = 4 (1 - alpha) / 3, i.e.
 *     alpha = 4/7  (the 2-D surface kernel gives K&Z's 2/3 by the same argument),
 * with MSE ~ n^(-4/7). The constant is derived, not tuned on any scene. */
#include "bake/rd_photons.h"

#include <math.h>

double rd_ppm_radius_scale(int pass, double alpha)
{
    /* r_pass / r_1 = (prod_{i=1}^{pass-1} (i + alpha) / (i + 1))^(1/3), the product in logs. */
    double log_v = 0.0;
    for (int i = 1; i < pass; i++) log_v += log((i + alpha) / (i + 1.0));
    return exp(log_v / 3.0);
}

/* SplitMix64's finaliser (Steele, Lea & Flood 2014). */
static uint64_t mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

uint64_t rd_ppm_pass_seed(uint64_t photon_seed, uint64_t render_seed, int pass)
{
    /* Each (photons.seed, render seed, pass) its own photon stream (the photon tracer keys
     * photon k of a batch by (seed, k)): the passes of one render are independent, and so are
     * two renders with different seeds (compare's runs), as their camera samples are. */
    uint64_t z = mix64(photon_seed + 0x9e3779b97f4a7c15ULL * (mix64(render_seed) + 1));
    return mix64(z + 0x9e3779b97f4a7c15ULL * (uint64_t)(pass + 1)) & ((1ULL << 53) - 1);
}
