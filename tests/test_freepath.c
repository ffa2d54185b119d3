/* Trackers and transmittance estimators of the free-path engine (renderer/media/freepath.c).
 *
 * Every unbiased tracker (Woodcock, super-voxel grid with constant and tri-linear bounds, octree,
 * weighted delta tracking with b < 1, = 1, > 1, weighted decomposition tracking) must reproduce
 *  - the exact transmittance (mean escape weight) of a homogeneous slab and of a trilinear grid,
 *  - the exact free-path distribution: chi-square test of the (weighted) histogram of sampled
 *    distances against P(bin) = T(a) - T(b) from the exact optical depth.
 * Tolerances: 5 standard errors for means; the chi-square statistic sum z_i^2 (z_i = (mean_i -
 * p_i)/se_i, se from the sample variance, so it also covers weighted samples) against the
 * Wilson-Hilferty quantile at z = 3.719 (upper tail 1e-4). Fixed seeds throughout. */
#include "support/rd_test.h"

#include <stdio.h>

static rd_scene *grid_scene_st(const char *majorant, double sigma_t)
{
    enum { NX = 7, NY = 5, NZ = 6 };
    float vox[NX * NY * NZ];
    pcg32 g = pcg32_seed(3, 4, 5);
    for (int i = 0; i < NX * NY * NZ; i++) {
        double u = pcg32_uniform(&g);
        vox[i] = (float)(u < 0.3 ? 0.05 * u : 2.0 * u * u);
    }
    char path[256], json[1024];
    snprintf(path, sizeof path, "%s/fgrid.raw", rt_tmpdir());
    rt_write_file(path, vox, sizeof vox);
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
             "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
             "\"density\":{\"type\":\"raw\",\"file\":\"fgrid.raw\",\"dims\":[7,5,6]},\"sigma_t\":%g,"
             "\"majorant\":%s}]}",
             sigma_t, majorant);
    return rt_scene("fgrid.json", json);
}

static rd_scene *grid_scene(const char *majorant) { return grid_scene_st(majorant, 1.5); }

typedef struct {
    const char *name;
    const char *majorant;
    rd_fp_params p;
} config;

static config configs[] = {
    {"woodcock", "{\"type\":\"none\"}", {RD_FP_WOODCOCK, RD_TR_RATIO_GLOBAL, 1, 1, 0}},
    {"supervoxel grid", "{\"type\":\"grid\",\"resolution\":4}", {RD_FP_SUPERVOXEL, RD_TR_RATIO, 1, 1, 0}},
    {"supervoxel auto", "{\"type\":\"auto\"}", {RD_FP_AUTO, RD_TR_RESIDUAL, 1, 1, 0}},
    {"supervoxel trilinear", "{\"type\":\"grid\",\"resolution\":3,\"bound\":\"trilinear\"}", {RD_FP_SUPERVOXEL, RD_TR_RESIDUAL, 1, 1, 0}},
    {"supervoxel octree", "{\"type\":\"octree\",\"fail\":2}", {RD_FP_SUPERVOXEL, RD_TR_RESIDUAL, 1, 1, 0}},
    {"weighted b=0.5", "{\"type\":\"grid\",\"resolution\":4}", {RD_FP_WEIGHTED, RD_TR_RATIO, 0.5, 1, 0}},
    {"weighted b=1", "{\"type\":\"grid\",\"resolution\":4}", {RD_FP_WEIGHTED, RD_TR_RATIO, 1.0, 1, 0}},
    {"weighted b=1.7 octree", "{\"type\":\"octree\"}", {RD_FP_WEIGHTED, RD_TR_RATIO, 1.7, 1, 0}},
    {"decomposition m=1", "{\"type\":\"grid\",\"resolution\":4}", {RD_FP_DECOMPOSITION, RD_TR_RESIDUAL, 1.0, 1.0, 0}},
    {"decomposition m=0.5 b=0.7", "{\"type\":\"grid\",\"resolution\":4}", {RD_FP_DECOMPOSITION, RD_TR_EXACT, 0.7, 0.5, 0}},
    {"decomposition m=2 (non-bounding)", "{\"type\":\"grid\",\"resolution\":2,\"bound\":\"trilinear\"}", {RD_FP_DECOMPOSITION, RD_TR_EXACT, 1.0, 2.0, 0}},
};
#define NCONFIG (int)(sizeof configs / sizeof configs[0])

enum { NBIN = 12 };

/* Sample n free paths along r and test the (weighted) distance histogram against the exact
 * distribution from the grid's exact optical depth. */
static void check_distribution(const config *cf, const rd_medium *m, ray3 r, int n, uint64_t seed)
{
    double t0, t1;
    cr_assert(rd_box_intersect(m->bmin, m->bmax, r, 0, INFINITY, &t0, &t1));
    rd_fp_medium fm = rd_fp_view(m);
    rd_track_counters c = {0};
    /* Exact bin probabilities: bins of equal length over [t0, t1] plus the escape bin. */
    double p[NBIN + 1], Tprev = 1.0;
    for (int b = 0; b < NBIN; b++) {
        double tb = t0 + (t1 - t0) * (b + 1) / NBIN;
        double T = m->kind == RD_DENSITY_GRID
                       ? exp(-m->sigma_t_scale * rd_grid_optical_depth(&m->grid, r, t0, tb, &c))
                       : exp(-m->constant * m->sigma_t_scale * (tb - t0));
        p[b] = Tprev - T;
        Tprev = T;
    }
    p[NBIN] = Tprev;
    double s1[NBIN + 1] = {0}, s2[NBIN + 1] = {0};
    for (int i = 0; i < n; i++) {
        pcg32 rng = pcg32_seed(seed, i, 99);
        rd_fp_event ev = rd_fp_sample(&cf->p, &fm, r, t0, t1, &rng, &c);
        int b = NBIN;
        if (ev.hit) {
            cr_assert(ev.t >= t0 && ev.t <= t1, "%s: collision outside the medium", cf->name);
            b = (int)((ev.t - t0) / (t1 - t0) * NBIN);
            if (b >= NBIN) b = NBIN - 1;
        }
        s1[b] += ev.weight;
        s2[b] += ev.weight * ev.weight;
    }
    double chi2 = 0.0;
    int dof = 0;
    for (int b = 0; b <= NBIN; b++) {
        double mean = s1[b] / n, var = s2[b] / n - mean * mean;
        /* The variance of the bin indicator from the exact p is used when the sample shows none
         * (an empty bin must still count). */
        double se = sqrt(fmax(var, p[b] * (1 - p[b])) / n);
        if (p[b] * n < 5 && s1[b] == 0) continue;
        double z = (mean - p[b]) / se;
        chi2 += z * z;
        dof++;
    }
    double q = rt_chi2_quantile(dof, 3.719);
    cr_expect(chi2 < q, "%s: chi-square %.2f > %.2f (%d bins)", cf->name, chi2, q, dof);
    /* Transmittance: mean escape weight within 5 standard errors. */
    double meanT = s1[NBIN] / n, seT = sqrt(fmax(s2[NBIN] / n - meanT * meanT, p[NBIN] * (1 - p[NBIN])) / n);
    cr_expect(fabs(meanT - p[NBIN]) < 5 * seT, "%s: T %.5f vs exact %.5f (se %.5f)", cf->name, meanT, p[NBIN], seT);
}

Test(freepath, every_tracker_samples_the_exact_distribution_in_a_grid, .timeout = 240)
{
    for (int k = 0; k < NCONFIG; k++) {
        rd_scene *s = grid_scene(configs[k].majorant);
        const rd_medium *m = &s->media[0];
        ray3 r1 = {v3(-2.0, -0.3, 0.1), v3_norm(v3(1.0, 0.15, 0.1))};
        ray3 r2 = {v3(0.3, 2.0, -0.4), v3_norm(v3(-0.2, -1.0, 0.3))};
        check_distribution(&configs[k], m, r1, 60000, 100 + k);
        check_distribution(&configs[k], m, r2, 60000, 200 + k);
        rd_scene_free(s);
    }
}

Test(freepath, every_tracker_samples_the_exact_distribution_in_a_slab)
{
    for (int k = 0; k < NCONFIG; k++) {
        char json[1024];
        snprintf(json, sizeof json,
                 "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                 "\"media\":[{\"bounds\":{\"min\":[-1,-5,-5],\"max\":[1,5,5]},\"density\":0.5,\"sigma_t\":1.6,"
                 "\"majorant\":%s}]}",
                 configs[k].majorant);
        rd_scene *s = rt_scene("fslab.json", json);
        ray3 r = {v3(-3, 0.1, 0.2), v3_norm(v3(1, 0.5, -0.3))};
        check_distribution(&configs[k], &s->media[0], r, 40000, 300 + k);
        rd_scene_free(s);
    }
}

Test(freepath, transmittance_estimators_are_unbiased)
{
    rd_scene *s = grid_scene("{\"type\":\"grid\",\"resolution\":4,\"bound\":\"trilinear\"}");
    const rd_medium *m = &s->media[0];
    rd_fp_medium fm = rd_fp_view(m);
    const rd_tr_kind kinds[] = {RD_TR_RATIO_GLOBAL, RD_TR_RATIO, RD_TR_RESIDUAL, RD_TR_AUTO};
    for (int q = 0; q < 3; q++) {
        ray3 r = {v3(-2.0, -0.6 + 0.4 * q, 0.3 - 0.2 * q), v3_norm(v3(1.0, 0.1 * q, 0.1))};
        double t0, t1;
        cr_assert(rd_box_intersect(m->bmin, m->bmax, r, 0, INFINITY, &t0, &t1));
        /* Exact optical depth against a 400000-step midpoint rule (error << 1e-6). */
        rd_track_counters c = {0};
        double tau = rd_grid_optical_depth(&m->grid, r, t0, t1, &c) * m->sigma_t_scale, mid = 0.0;
        int steps = 400000;
        double h = (t1 - t0) / steps;
        for (int i = 0; i < steps; i++) mid += rd_medium_sigma_t(m, ray_at(r, t0 + (i + 0.5) * h)) * h;
        cr_expect(fabs(tau - mid) < 1e-6 * (1 + mid), "exact optical depth %.9f vs quadrature %.9f", tau, mid);
        double exact = exp(-tau);
        rd_fp_params p;
        rd_fp_params_default(&p);
        p.transmittance = RD_TR_EXACT;
        cr_expect(fabs(rd_fp_transmittance(&p, &fm, r, t0, t1, NULL, &c) - exact) < 1e-12);
        for (int k = 0; k < 4; k++) {
            p.transmittance = kinds[k];
            double sum = 0, sum2 = 0;
            int n = 50000;
            for (int i = 0; i < n; i++) {
                pcg32 rng = pcg32_seed(q, i, 5 + k);
                double T = rd_fp_transmittance(&p, &fm, r, t0, t1, &rng, &c);
                cr_assert(T >= 0.0 && T <= 1.0 + 1e-12);
                sum += T;
                sum2 += T * T;
            }
            double mean = sum / n, se = sqrt(fmax(0, sum2 / n - mean * mean) / n);
            cr_expect(fabs(mean - exact) < 5 * se + 1e-12, "%s: %.6f vs %.6f (se %.6f)", rd_tr_name(kinds[k]), mean,
                      exact, se);
        }
        /* Ray marching is biased but converges with the step. */
        p.transmittance = RD_TR_RAYMARCH;
        p.step = 1e-3;
        pcg32 rng = pcg32_seed(1, 2, 3);
        cr_expect(fabs(rd_fp_transmittance(&p, &fm, r, t0, t1, &rng, &c) - exact) < 1e-2);
    }
    rd_scene_free(s);
}

Test(freepath, ratio_tracking_roulette_keeps_the_mean_through_a_thick_medium)
{
    /* sigma_t 8 x the grid's density: optical depth 5-9 along these rays, so every ratio
     * estimator's running estimate falls below the roulette's threshold (0.05, on_ratio) and
     * is killed or scaled up on the way. The mean must stay exp(-tau) (5 standard errors of
     * 50000 estimates), some estimates must have been ended by the roulette (a ratio product
     * reaches 0 otherwise only where the density meets its bound exactly), and none may exceed
     * 1 (a survivor is at most 0.05 / 0.25). */
    rd_scene *s = grid_scene_st("{\"type\":\"grid\",\"resolution\":4,\"bound\":\"trilinear\"}", 8.0);
    const rd_medium *m = &s->media[0];
    rd_fp_medium fm = rd_fp_view(m);
    const rd_tr_kind kinds[] = {RD_TR_RATIO_GLOBAL, RD_TR_RATIO, RD_TR_RESIDUAL};
    for (int q = 0; q < 2; q++) {
        ray3 r = {v3(-2.0, -0.4 + 0.5 * q, 0.2), v3_norm(v3(1.0, 0.05, 0.1 * q))};
        double t0, t1;
        cr_assert(rd_box_intersect(m->bmin, m->bmax, r, 0, INFINITY, &t0, &t1));
        rd_track_counters c = {0};
        double tau = rd_grid_optical_depth(&m->grid, r, t0, t1, &c) * m->sigma_t_scale, exact = exp(-tau);
        cr_assert(tau > 3.0, "the ray is too thin for the test: tau %.3f", tau);
        rd_fp_params p;
        rd_fp_params_default(&p);
        for (int k = 0; k < 3; k++) {
            p.transmittance = kinds[k];
            double sum = 0, sum2 = 0, Tmax = 0;
            int n = 50000, zeros = 0;
            for (int i = 0; i < n; i++) {
                pcg32 rng = pcg32_seed(40 + q, i, 9 + k);
                double T = rd_fp_transmittance(&p, &fm, r, t0, t1, &rng, &c);
                sum += T;
                sum2 += T * T;
                zeros += T == 0.0;
                Tmax = fmax(Tmax, T);
            }
            double mean = sum / n, se = sqrt(fmax(0, sum2 / n - mean * mean) / n);
            cr_log_info("%s, tau %.3f: %.6g vs %.6g (se %.2g), %d of %d ended by the roulette", rd_tr_name(kinds[k]),
                        tau, mean, exact, se, zeros, n);
            cr_expect(fabs(mean - exact) < 5 * se, "%s: %.6g vs %.6g (se %.2g)", rd_tr_name(kinds[k]), mean, exact, se);
            cr_expect(zeros > n / 10, "%s: the roulette ended only %d of %d estimates", rd_tr_name(kinds[k]), zeros, n);
            cr_expect(Tmax <= 1.0, "%s: an estimate of %.3g", rd_tr_name(kinds[k]), Tmax);
        }
    }
    rd_scene_free(s);
}

Test(freepath, supervoxel_tracking_in_noise_matches_quadrature)
{
    /* Procedural noise: bounds from the noise definition (seed 003 eq. 15). The transmittance of
     * super-voxel delta tracking (5 standard errors, binomial) against a midpoint rule. */
    rd_scene *s = rt_scene("fnoise.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":{\"type\":\"noise\",\"octaves\":4,\"frequency\":2,\"amplitude\":2},\"sigma_t\":6}]}");
    const rd_medium *m = &s->media[0];
    cr_assert(m->majorant->kind == RD_MAJ_GRID, "the cost model partitions a high-variation cloud");
    rd_fp_medium fm = rd_fp_view(m);
    ray3 r = {v3(-2, 0.1, -0.2), v3_norm(v3(1, 0.05, 0.1))};
    double t0, t1;
    cr_assert(rd_box_intersect(m->bmin, m->bmax, r, 0, INFINITY, &t0, &t1));
    int steps = 200000;
    double h = (t1 - t0) / steps, tau = 0;
    for (int i = 0; i < steps; i++) tau += rd_medium_sigma_t(m, ray_at(r, t0 + (i + 0.5) * h)) * h;
    double exact = exp(-tau);
    rd_fp_params p;
    rd_fp_params_default(&p);
    rd_track_counters c = {0};
    int n = 100000, esc = 0;
    for (int i = 0; i < n; i++) {
        pcg32 rng = pcg32_seed(4, i, 4);
        esc += !rd_fp_sample(&p, &fm, r, t0, t1, &rng, &c).hit;
    }
    double se = sqrt(exact * (1 - exact) / n);
    cr_expect(fabs((double)esc / n - exact) < 5 * se, "noise: %.5f vs %.5f", (double)esc / n, exact);
    rd_scene_free(s);
}

Test(freepath, settings_select_the_tracker)
{
    rd_scene *s = rt_scene("fset.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":0.5,\"sigma_t\":2}],"
                           "\"settings\":{\"tracker\":\"weighted\",\"b\":0.5,\"transmittance\":\"exact\"}}");
    cr_expect(s->settings.tracker == RD_FP_WEIGHTED && s->settings.track_b == 0.5);
    cr_expect(s->settings.transmittance == RD_TR_EXACT);
    pcg32 rng = pcg32_seed(1, 1, 1);
    rd_track_counters c = {0};
    ray3 r = {v3(-3, 0, 0), v3(1, 0, 0)};
    cr_expect(fabs(rd_transmittance(s, -1, r, 0.0, INFINITY, &rng, &c) - exp(-2.0)) < 1e-12, "exact transmittance");
    rd_scene_free(s);
}
