/* test_progressive.c: progressive photon passes (photons.progressive; bake/passes.c, Knaus &
 * Zwicker 2011 with a 3-D kernel) against single scattering in a homogeneous medium, whose
 * image is a 1-D integral per pixel (Simpson), not an estimate.
 *
 * The scene: an isotropic point light of intensity I inside a homogeneous, isotropic medium
 * (sigma_t, albedo a) much larger than the light's reach (its faces, where a kernel would be
 * cut, are 4 mean free paths away), seen by an orthographic camera through pixel centres from
 * inside the medium. With photons.max_depth = 1 the photon map holds
 * only first collisions, so the marcher (`uniform`, march.ls = photons) estimates single
 * scattering, exactly
 *     L(pixel) = int T(z_cam, z) sigma_s (1 / 4 pi) I exp(-sigma_t d) / d^2 dz,   d = |x(z) - p|,
 * up to the kernel's bias, which is what the passes must remove.
 *
 * What is checked:
 *  - the radius schedule is r_{i+1}^3 = r_i^3 (i + alpha) / (i + 1) and the passes' seeds differ;
 *  - the squared gap to the closed form, G(N) after N passes (the render's convergence curve
 *    against the closed-form image), falls at least at the slowest rate the error model allows
 *    (bake/passes.c: photon variance ~ 1/r^3, the marcher's noise ~ 1/N, kernel bias ~ r^2 in
 *    the interior and ~ r where the kernel is cut; the slowest, first-order bias, gives
 *    G(N) / G(4) <= s(N) / s(4), s(N) = ((1/N) sum_i r_i / r_1)^2),
 *    and no faster than the fastest term (the marcher's noise, 1/N);
 *  - at 64 passes the progressive image is nearer the closed form than 64 samples on one fixed
 *    map, whose bias and photon noise never average out, and the kernel's bias^2 left in the
 *    runs' mean image is smaller.
 * The light stands beside the view (the pixels see its fluence at 0.35-1.6 m), where the kernel's
 * bias is second order; a pixel ray through the light's singularity would add a heavy tail.
 * Measured here (12 runs): G(64)/G(4) = 0.30 +- 0.04, G(16)/G(4) = 0.58 +- 0.08; the balanced
 * asymptotic rate (N/4)^(-4/7) gives 0.205 and 0.45 (the runs are not yet asymptotic: most of
 * G(64) is the bias^2 still left, whose rate is the balanced one only in the limit).
 * Each G is a mean over R = 12 independent runs (photon seeds 1..12, render seeds 1..12); the
 * bounds are taken 4 standard errors of those means wide (each side), so a correct estimator
 * fails them with probability well under 1e-4. */
#include "support/rd_test.h"

#include "bake/rd_photons.h"

#include <math.h>

#define RES 8
#define RUNS 12
#define PASSES 64
#define SIGMA_T 1.0
#define ALBEDO 0.8
#define LIGHT_I 2.0
static const double LIGHT[3] = {0.95, 0.1, 0.05};
#define CAM_Z 1.5

static const char *scene_json(int progressive, int photon_seed)
{
    static char buf[2048];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"type\":\"orthographic\",\"position\":[0,0,%g],\"direction\":[0,0,-1],"
             "\"width\":1.2,\"resolution\":[%d,%d],\"jitter\":false},"
             "\"media\":[{\"bounds\":{\"min\":[-5,-5,-5],\"max\":[5,5,5]},"
             "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":%g,\"albedo\":%g,\"g\":0}],"
             "\"lights\":[{\"type\":\"point\",\"position\":[%g,%g,%g],\"intensity\":%g}],"
             "\"photons\":{\"count\":3000,\"max_depth\":1,\"seed\":%d,\"progressive\":%s},"
             "\"guide\":{\"k\":64},"
             "\"march\":{\"samples\":8,\"ls\":\"photons\"},"
             "\"settings\":{\"method\":\"uniform\"}}",
             CAM_Z, RES, RES, SIGMA_T, ALBEDO, LIGHT[0], LIGHT[1], LIGHT[2], LIGHT_I, photon_seed,
             progressive ? "true" : "false");
    return buf;
}

/* The single-scattering integrand along the pixel ray at (x, y), as a function of z. */
typedef struct { double x, y; } ray_xy;
static double integrand(double z, const void *ctx)
{
    const ray_xy *p = ctx;
    double dx = p->x - LIGHT[0], dy = p->y - LIGHT[1], dz = z - LIGHT[2];
    double d2 = dx * dx + dy * dy + dz * dz, d = sqrt(d2);
    double T_cam = exp(-SIGMA_T * (CAM_Z - z));
    return T_cam * ALBEDO * SIGMA_T / (4.0 * M_PI) * LIGHT_I * exp(-SIGMA_T * d) / d2;
}

/* The closed-form image (every channel alike): pixel centres of the orthographic camera. */
static void exact_image(rd_image *img)
{
    img->w = img->h = RES;
    img->rgb = malloc(sizeof(float) * 3 * RES * RES);
    cr_assert(img->rgb);
    for (int j = 0; j < RES; j++)
        for (int i = 0; i < RES; i++) {
            ray_xy p = {(2.0 * (i + 0.5) / RES - 1.0) * 0.6, (1.0 - 2.0 * (j + 0.5) / RES) * 0.6};
            /* Split at the point nearest the light, where the integrand peaks; the medium ends
             * at z = -5. 20000 intervals: converged far below the estimates' noise. */
            double L = rt_simpson(integrand, &p, -5.0, LIGHT[2], 20000) +
                       rt_simpson(integrand, &p, LIGHT[2], CAM_Z, 20000);
            for (int c = 0; c < 3; c++) img->rgb[3 * (j * RES + i) + c] = (float)L;
        }
}

/* G(N) for N = 1..PASSES (squared RMSE after N samples per pixel) of one run. */
static void run_curve(int progressive, int run, const rd_image *exact, double *G, float *img)
{
    rd_scene *s = rt_scene("progressive.json", scene_json(progressive, run));
    rd_render_opts o = {.method = "uniform", .spp = PASSES, .seed = (uint64_t)run, .threads = 2,
                        .reference = exact};
    rd_render_result r;
    char err[RD_ERRLEN];
    cr_assert(rd_render(s, &o, &r, err, sizeof err) == RD_OK, "%s", err);
    if (progressive) {
        cr_assert_eq(r.stats.photon_passes, PASSES, "one photon pass per sample: %d", r.stats.photon_passes);
        cr_assert_eq(r.n_curve, PASSES, "one curve point per pass");
    }
    /* Without passes the render's own passes may hold several samples: read the curve by
     * samples per pixel. */
    for (int n = 1; n <= PASSES; n++) G[n] = NAN;
    for (int k = 0; k < r.n_curve; k++) {
        int n = (int)lround(r.curve[k].spp_mean);
        if (n >= 1 && n <= PASSES) G[n] = r.curve[k].rmse * r.curve[k].rmse;
    }
    memcpy(img, r.image.rgb, sizeof(float) * 3 * RES * RES);
    rd_render_result_free(&r);
    rd_scene_free(s);
}

/* The kernel's bias^2 left in the image after the runs: the squared gap of the runs' mean image
 * to the closed form, less the part the runs' own spread explains,
 *     B = mean_p [ (mean_k x_k(p) - exact(p))^2 - s^2(p) / R ],
 * an unbiased estimate of mean_p bias(p)^2; its standard error by the jackknife over runs. */
static double bias2_of(float img[][3 * RES * RES], int R, const int *skip, const rd_image *exact)
{
    double B = 0.0;
    int n = 0;
    for (int k = 0; k < R; k++) n += !(skip && k == *skip);
    for (int p = 0; p < 3 * RES * RES; p++) {
        double m = 0.0, v = 0.0;
        for (int k = 0; k < R; k++) if (!(skip && k == *skip)) m += img[k][p];
        m /= n;
        for (int k = 0; k < R; k++) if (!(skip && k == *skip)) v += (img[k][p] - m) * (img[k][p] - m);
        v /= n - 1;
        double e = m - exact->rgb[p];
        B += e * e - v / n;
    }
    return B / (3 * RES * RES);
}

static void bias2_jackknife(float img[][3 * RES * RES], int R, const rd_image *exact, double *B, double *se)
{
    *B = bias2_of(img, R, NULL, exact);
    double mean = 0.0, loo[64];
    for (int k = 0; k < R; k++) mean += (loo[k] = bias2_of(img, R, &k, exact));
    mean /= R;
    double ss = 0.0;
    for (int k = 0; k < R; k++) ss += (loo[k] - mean) * (loo[k] - mean);
    *se = sqrt((R - 1.0) / R * ss);
}

/* Mean and standard error of G(n) over the runs. */
static void mean_se(double G[RUNS][PASSES + 1], int n, double *m, double *se)
{
    double s = 0.0, s2 = 0.0;
    for (int k = 0; k < RUNS; k++) s += G[k][n];
    *m = s / RUNS;
    for (int k = 0; k < RUNS; k++) s2 += (G[k][n] - *m) * (G[k][n] - *m);
    *se = sqrt(s2 / (RUNS - 1) / RUNS);
}

Test(progressive, radius_schedule_and_pass_seeds)
{
    double a = RD_PPM_ALPHA;
    cr_assert_float_eq(a, 4.0 / 7.0, 1e-15);
    cr_assert_float_eq(rd_ppm_radius_scale(1, a), 1.0, 1e-15);
    for (int i = 1; i < 200; i++) {
        double ri = rd_ppm_radius_scale(i, a), rn = rd_ppm_radius_scale(i + 1, a);
        double want = ri * ri * ri * (i + a) / (i + 1.0);
        cr_assert(fabs(rn * rn * rn - want) <= 1e-12 * want, "pass %d: r^3 %.15g, want %.15g", i + 1, rn * rn * rn, want);
    }
    /* r_i^3 ~ i^(alpha - 1): the ratio over a decade tends to 10^(alpha - 1). */
    double r1k = rd_ppm_radius_scale(1000, a), r10k = rd_ppm_radius_scale(10000, a);
    cr_assert_float_eq(pow(r10k / r1k, 3.0), pow(10.0, a - 1.0), 1e-3);
    /* Every (render seed, pass) its own photon stream. */
    uint64_t seen[4 * 64];
    int n = 0;
    for (uint64_t rs = 0; rs < 4; rs++)
        for (int i = 1; i <= 64; i++) {
            uint64_t v = rd_ppm_pass_seed(7, rs, i);
            for (int j = 0; j < n; j++) cr_assert_neq(v, seen[j], "render seed %d, pass %d: a seed seen before", (int)rs, i);
            cr_assert(v < (1ULL << 53), "a photon seed fits the scene's range");
            seen[n++] = v;
        }
}

Test(progressive, squared_gap_falls_and_beats_the_fixed_map, .timeout = 600)
{
    rd_image exact;
    exact_image(&exact);
    static double Gp[RUNS][PASSES + 1], Gf[RUNS][PASSES + 1];
    static float Ip[RUNS][3 * RES * RES], If[RUNS][3 * RES * RES];
    for (int k = 0; k < RUNS; k++) {
        run_curve(1, k + 1, &exact, Gp[k], Ip[k]);
        run_curve(0, k + 1, &exact, Gf[k], If[k]);
    }
    double Bp, sBp, Bf, sBf;
    bias2_jackknife(Ip, RUNS, &exact, &Bp, &sBp);
    bias2_jackknife(If, RUNS, &exact, &Bf, &sBf);
    cr_log_info("progressive: bias^2 after %d samples %.4g +- %.2g with passes, %.4g +- %.2g on one fixed map", PASSES, Bp, sBp, Bf, sBf);
    cr_expect(Bf - Bp > 4.0 * sqrt(sBf * sBf + sBp * sBp),
              "the passes leave as much kernel bias as one fixed map: bias^2 %.4g +- %.2g against %.4g +- %.2g",
              Bp, sBp, Bf, sBf);
    /* The error model's terms as functions of N (bake/passes.c), each relative to its value at
     * N = 1: the marcher's own noise 1/N (fastest), the photon variance (1/N^2) sum (r_1/r_i)^3,
     * second-order kernel bias^2 (mean (r_i/r_1)^2)^2, and first-order kernel bias^2
     * (mean r_i/r_1)^2 (slowest). G(N)/G(4) is a mixture of their ratios with positive weights,
     * so it lies between the fastest and the slowest. */
    double s[PASSES + 1], fast[PASSES + 1], acc = 0.0;
    for (int n = 1; n <= PASSES; n++) {
        acc += rd_ppm_radius_scale(n, RD_PPM_ALPHA);
        s[n] = (acc / n) * (acc / n);
        fast[n] = 1.0 / n;
    }
    double m4, se4;
    mean_se(Gp, 4, &m4, &se4);
    const int check[] = {16, 64};
    for (int c = 0; c < 2; c++) {
        int n = check[c];
        double m, se;
        mean_se(Gp, n, &m, &se);
        double bound = (m4 + 4.0 * se4) * s[n] / s[4];
        double floor_ = (m4 - 4.0 * se4) * fast[n] / fast[4];
        cr_log_info("progressive: G(4) = %.4g +- %.2g, G(%d) = %.4g +- %.2g (ratio %.3f; slowest predicted %.3f, N^-4/7 %.3f)",
                    m4, se4, n, m, se, m / m4, s[n] / s[4], pow(n / 4.0, -4.0 / 7.0));
        cr_expect(m - 4.0 * se <= bound,
                  "G(%d) = %.4g +- %.2g does not fall from G(4) = %.4g +- %.2g at the slowest predicted rate (bound %.4g)",
                  n, m, se, m4, se4, bound);
        cr_expect(m + 4.0 * se >= floor_,
                  "G(%d) = %.4g +- %.2g falls from G(4) = %.4g +- %.2g faster than any term can (floor %.4g)",
                  n, m, se, m4, se4, floor_);
    }
    double mp, sep, mf, sef;
    mean_se(Gp, PASSES, &mp, &sep);
    mean_se(Gf, PASSES, &mf, &sef);
    cr_log_info("progressive: after %d samples G = %.4g +- %.2g with passes, %.4g +- %.2g on one fixed map", PASSES, mp, sep, mf, sef);
    cr_expect(mp + 4.0 * sep < mf - 4.0 * sef,
              "after %d passes the progressive image (G = %.4g +- %.2g) is not nearer the closed form than one fixed map (%.4g +- %.2g)",
              PASSES, mp, sep, mf, sef);
    free(exact.rgb);
}
