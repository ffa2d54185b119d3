/* Thin-media probability biasing of delta tracking (rd_sample_free_path_thin, transport/
 * tracking.c; settings.thin_bias):
 *  - with a tight majorant (a homogeneous slab) the biased chain has a closed-form law: a
 *    collision with probability P' = max(P, q), P = 1 - exp(-tau), at t with density
 *    P' sigma exp(-sigma (t - t0)) / P. Chi-square of the sampled distances and passes against it
 *    (cells with an expected count < 5 pooled, p = 1e-4), and the weights are exactly P / P' and
 *    exp(-tau) / (1 - P');
 *  - whatever the majorant and the media, the weighted outcomes have delta tracking's law:
 *    E[W 1{pass}] = T(0, t_end) and E[W 1{collision in [a, b]}] = T(0, a) - T(0, b) (the integral
 *    of sigma_t T over the bin), for loose majorants, a noise medium and a flight through two
 *    media; q = 1 (a forced collision) keeps the collisions' law. Each bin and the pass are
 *    z-tests at 4.5 standard errors: under the hypothesis each |z| > 4.5 has probability
 *    6.8e-6 (the sample means of 200000 bounded weights are normal to that depth), and the 9
 *    tests of 7 configurations give about 4e-4 chance of a false alarm in all. */
#include "support/rd_test.h"

/* A slab 2 m thick along x (x in [-1, 1]), wide in y and z, constant sigma_t. */
static rd_scene *slab(double sigma)
{
    char json[512];
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
             "\"media\":[{\"bounds\":{\"min\":[-1,-50,-50],\"max\":[1,50,50]},"
             "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":%g}]}", sigma);
    return rt_scene("slab.json", json);
}

Test(thin_bias, tight_majorant_chi_square_and_weights)
{
    const double sigmas[] = {0.05, 0.4};
    const double qs[] = {0.5, 0.9, 1.0};
    enum { NB = 40 };
    for (int si = 0; si < 2; si++)
        for (int qi = 0; qi < 3; qi++) {
            rd_scene *s = slab(sigmas[si]);
            double sig = sigmas[si], q = qs[qi];
            ray3 r = {v3(-3, 0.1, 0.2), v3(1, 0, 0)}; /* enters at t = 2, leaves at 4 */
            double tau = 2.0 * sig, P = -expm1(-tau), Pb = fmax(P, q);
            double obs[NB + 1] = {0}, frac[NB + 1];
            int n = 200000;
            rd_track_counters c = {0};
            for (int i = 0; i < n; i++) {
                pcg32 rng = pcg32_seed(31 + si, (uint64_t)i, 7 + qi);
                rd_collision col = rd_sample_free_path_thin(s, -1, r, INFINITY, q, &rng, &c);
                if (col.hit) {
                    cr_assert(col.t >= 2.0 && col.t <= 4.0);
                    cr_assert(fabs(col.weight - P / Pb) < 1e-12 * P / Pb, "collision weight %g, expected %g", col.weight, P / Pb);
                    int b = (int)((col.t - 2.0) / 2.0 * NB);
                    obs[b >= NB ? NB - 1 : b] += 1;
                } else {
                    cr_assert(fabs(col.weight - exp(-tau) / (1.0 - Pb)) < 1e-12 * col.weight, "pass weight %g", col.weight);
                    obs[NB] += 1;
                }
            }
            for (int b = 0; b < NB; b++)
                frac[b] = Pb * (exp(-sig * 2.0 * b / NB) - exp(-sig * 2.0 * (b + 1) / NB)) / P;
            frac[NB] = 1.0 - Pb;
            double chi2 = 0, pool_o = 0, pool_e = 0;
            int dof = -1;
            for (int b = 0; b <= NB; b++) {
                double e = n * frac[b];
                if (e < 5) { pool_o += obs[b]; pool_e += e; continue; }
                chi2 += (obs[b] - e) * (obs[b] - e) / e;
                dof++;
            }
            if (pool_e >= 5) { chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e; dof++; }
            double crit = rt_chi2_quantile(dof, 3.719);
            cr_expect(chi2 < crit, "sigma %g q %g: chi2 %.1f >= %.1f (dof %d)", sig, q, chi2, crit, dof);
            rd_scene_free(s);
        }
}

/* E[W 1{outcome}] per distance bin and for the pass, against the exact integrals: T at the
 * bin edges from a midpoint rule of sigma_t along the ray (exact for constant media, far below
 * the tolerance for the smooth noise). */
static void check_weighted_law(const rd_scene *s, ray3 r, double ta, double tb, double q, int n,
                               uint64_t seed, const char *what)
{
    enum { NB = 8, STEPS = 400000 };
    double edge_T[NB + 1];
    double h = (tb - ta) / STEPS, tau = 0.0;
    edge_T[0] = 1.0;
    for (int i = 0, b = 1; i < STEPS; i++) {
        const rd_medium *m = rd_scene_medium_at(s, -1, ray_at(r, ta + (i + 0.5) * h));
        if (m) tau += rd_medium_sigma_t(m, ray_at(r, ta + (i + 0.5) * h)) * h;
        if ((i + 1) % (STEPS / NB) == 0) edge_T[b++] = exp(-tau);
    }
    double sum[NB + 1] = {0}, sum2[NB + 1] = {0};
    rd_track_counters c = {0};
    for (int i = 0; i < n; i++) {
        pcg32 rng = pcg32_seed(seed, (uint64_t)i, 3);
        rd_collision col = rd_sample_free_path_thin(s, -1, r, INFINITY, q, &rng, &c);
        int b = NB;
        if (col.hit) {
            b = (int)((col.t - ta) / (tb - ta) * NB);
            b = b < 0 ? 0 : (b >= NB ? NB - 1 : b);
        }
        sum[b] += col.weight;
        sum2[b] += col.weight * col.weight;
    }
    for (int b = 0; b <= NB; b++) {
        if (b == NB && q >= 1.0) continue; /* a forced flight never passes: its pass is worth 0 */
        double exact = b < NB ? edge_T[b] - edge_T[b + 1] : edge_T[NB];
        double mean = sum[b] / n, se = sqrt(fmax(0.0, sum2[b] / n - mean * mean) / n);
        cr_expect(fabs(mean - exact) < 4.5 * se + 1e-12, "%s q %g, %s %d: %.6f vs exact %.6f (se %.6f)", what, q,
                  b < NB ? "bin" : "pass", b, mean, exact, se);
    }
}

Test(thin_bias, weighted_outcomes_have_delta_trackings_law, .timeout = 120)
{
    /* Thin slab with the majorant loosened to 3 sigma_t (null collisions, rebiased after each) */
    rd_scene *s = slab(0.1);
    s->media[0].sigma_maj = 0.3;
    ray3 r = {v3(-3, 0.1, 0.2), v3(1, 0, 0)};
    check_weighted_law(s, r, 2.0, 4.0, 0.5, 200000, 1, "loose slab");
    check_weighted_law(s, r, 2.0, 4.0, 1.0, 200000, 2, "loose slab");
    rd_scene_free(s);

    /* Noise medium over its super-voxel majorant grid */
    s = rt_scene("noise.json",
                 "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                 "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                 "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":2,\"amplitude\":2,\"seed\":4},"
                 "\"sigma_t\":0.6}]}");
    r = (ray3){v3(-3, 0.2, 0.1), v3_norm(v3(1, 0.05, -0.02))};
    double t0, t1;
    cr_assert(rd_box_intersect(s->media[0].bmin, s->media[0].bmax, r, 0, INFINITY, &t0, &t1));
    check_weighted_law(s, r, t0, t1, 0.3, 200000, 3, "noise");
    check_weighted_law(s, r, t0, t1, 0.8, 200000, 4, "noise");
    check_weighted_law(s, r, t0, t1, 1.0, 200000, 5, "noise");
    rd_scene_free(s);

    /* A flight through two media with a gap between them (the chain's odds span both) */
    s = rt_scene("two.json",
                 "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                 "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[0,1,1]},\"density\":1,\"sigma_t\":0.15},"
                 "{\"bounds\":{\"min\":[0.5,-1,-1],\"max\":[1.5,1,1]},\"density\":1,\"sigma_t\":0.3}]}");
    s->media[1].sigma_maj = 0.5;
    r = (ray3){v3(-3, 0.1, 0.2), v3(1, 0, 0)};
    check_weighted_law(s, r, 2.0, 4.5, 0.6, 200000, 6, "two media");
    rd_scene_free(s);
}

/* The boost stops once the chain's weight is below 0.01 (tracking.c, THIN_BOOST_W). A slab whose
 * majorant is 500x its sigma_t (nearly every tentative collision null), with q = 1: before that
 * bound the chain forced a collision into ever shorter remainders of the flight until T_maj
 * underflowed, hundreds of tentative collisions a flight (measured: 191 density lookups a path
 * on beam-vdb, against 1.7 without the bias). Now each forced step multiplies the weight by
 * P_k <= P_0 = 1 - exp(-1) (tau_left only shrinks) and a step is forced only while the weight
 * is >= 0.01, so at most 1 + floor(ln 0.01 / ln P_0) = 11 steps are forced, and delta
 * tracking's own chain over what is left (majorant depth <= 1) adds at most 1 tentative
 * collision in expectation: the mean must stay below 12 plus 4.5 standard errors. The
 * weighted collisions keep delta tracking's law (as above). */
Test(thin_bias, a_forced_chain_over_empty_space_ends, .timeout = 120)
{
    rd_scene *s = slab(0.001);
    s->media[0].sigma_maj = 0.5; /* majorant depth 1 over the slab's 2 m */
    ray3 r = {v3(-3, 0.1, 0.2), v3(1, 0, 0)};
    enum { N = 20000 };
    double sum = 0.0, sum2 = 0.0;
    for (int i = 0; i < N; i++) {
        pcg32 rng = pcg32_seed(9, (uint64_t)i, 3);
        rd_track_counters c = {0};
        rd_sample_free_path_thin(s, -1, r, INFINITY, 1.0, &rng, &c);
        sum += (double)c.collisions;
        sum2 += (double)c.collisions * (double)c.collisions;
    }
    double mean = sum / N, se = sqrt(fmax(0.0, sum2 / N - mean * mean) / N);
    cr_expect(mean < 12.0 + 4.5 * se, "%.2f tentative collisions a flight (se %.3f)", mean, se);
    cr_log_info("forced chain over empty space: %.2f tentative collisions a flight (se %.3f)", mean, se);
    check_weighted_law(s, r, 2.0, 4.0, 1.0, 200000, 7, "near-empty slab");
    check_weighted_law(s, r, 2.0, 4.0, 0.5, 200000, 8, "near-empty slab");
    rd_scene_free(s);
}
