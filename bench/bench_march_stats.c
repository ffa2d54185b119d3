/* bench_march_stats: the statistics of bench/bench_march.sh (issue 9), from renders on disk.
 *
 *   bench_march_stats --ref REF.exr [--lit F] [--time-key KEY] --group NAME A1.exr ... AK.exr [--group NAME ...]
 *   bench_march_stats --rmse REF.exr X1.exr ... XN.exr
 *
 * Each group holds K >= 4 independent renders (different --seed) of one scene by one method;
 * beside each OUTk.exr the tool reads OUTk.json (the render report) for its wall time
 * ("seconds", bake included; --time-key render_seconds leaves the bake out). Per group, over all pixels and the three channels
 * (THEORY.md §7):
 *
 *   var    = mean over pixels of s^2, the unbiased sample variance of the K runs at the pixel
 *            against the group's own mean image (not the reference: the marching methods
 *            share the photon estimate's bias, which is not noise);
 *   time   = mean of the K runs' wall times;
 *   eff    = 1 / (var x time)    (the usual efficiency, THEORY.md §7);
 *   bias^2 = mean over pixels of (mean_K - ref)^2 - var/K - se_ref^2, where se_ref is the
 *            reference's own standard error (REF-stderr.exr): the expected squared difference
 *            minus both noise floors, so an unbiased method scores about 0 (+- its noise);
 *   homogeneity: over the lit pixels (reference channel mean >= F x its 99th percentile,
 *            F = 0.1 unless --lit), the per-pixel relative standard deviation
 *            r = s / ref; the tool prints its median, IQR / median and coefficient of variation.
 *            A method that spreads noise evenly over the image has a small IQR / median.
 *
 * The first group is the one compared: the tool prints eff(first) / eff(other) for every other
 * group, from all K runs and separately from the first and second half of the runs (the spread
 * of the ratio), and the min-max of each group's run times.
 *
 * --rmse prints, for each image, the RMSE against REF over all pixels and channels, with the
 * render's seconds and spp_mean from its report (the equal-time comparison).
 *
 * When run with no groups (as `make bench` runs every tool in bench/), it says so and exits 0:
 * this tool needs the renders bench/bench_march.sh makes. */
#include "renderer.h"

#include <cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_GROUPS 16
#define MAX_RUNS 64

typedef struct {
    const char *name;
    const char *path[MAX_RUNS];
    int k;
    const char *time_key; /* report field of the run time: "seconds" (bake included) or
                           * "render_seconds" (--time-key; for settings that share one bake) */
} group;

/* ---- Files ---------------------------------------------------------------------------------- */

static void die(const char *msg)
{
    fprintf(stderr, "bench_march_stats: %s\n", msg);
    exit(2);
}

static rd_image read_exr(const char *path)
{
    rd_image img;
    char err[RD_ERRLEN];
    if (rd_image_read(path, &img, err, sizeof err) != RD_OK) die(err);
    return img;
}

/* The path with ".exr" replaced by suffix (caller frees). */
static char *sibling(const char *exr, const char *suffix)
{
    size_t n = strlen(exr);
    if (n < 4 || strcmp(exr + n - 4, ".exr")) die("expected a path ending in .exr");
    char *p = malloc(n - 4 + strlen(suffix) + 1);
    if (!p) die("out of memory");
    memcpy(p, exr, n - 4);
    strcpy(p + n - 4, suffix);
    return p;
}

/* A number from the render report OUT.json beside OUT.exr. */
static double report_number(const char *exr, const char *key)
{
    char *path = sibling(exr, ".json");
    FILE *f = fopen(path, "rb");
    if (!f) die(path);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *text = malloc((size_t)n + 1);
    if (!text || fread(text, 1, (size_t)n, f) != (size_t)n) die(path);
    text[n] = 0;
    fclose(f);
    cJSON *root = cJSON_Parse(text);
    const cJSON *v = root ? cJSON_GetObjectItemCaseSensitive(root, key) : NULL;
    if (!cJSON_IsNumber(v)) die(path);
    double x = v->valuedouble;
    cJSON_Delete(root);
    free(text);
    free(path);
    return x;
}

static void check_size(const rd_image *a, const rd_image *ref, const char *path)
{
    if (a->w != ref->w || a->h != ref->h) {
        fprintf(stderr, "bench_march_stats: %s: %dx%d, reference %dx%d\n", path, a->w, a->h, ref->w, ref->h);
        exit(2);
    }
}

/* ---- Order statistics ------------------------------------------------------------------------ */

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The q-quantile of sorted v[0..n-1], by linear interpolation. */
static double quantile(const double *v, size_t n, double q)
{
    double pos = q * (double)(n - 1);
    size_t i = (size_t)pos;
    if (i + 1 >= n) return v[n - 1];
    return v[i] + (pos - (double)i) * (v[i + 1] - v[i]);
}

/* ---- Per-group statistics ------------------------------------------------------------------ */

typedef struct {
    double var, time, tmin, tmax, bias2, floor_k, rel_median, rel_iqr, rel_cv;
    double dmean, dmean_se; /* (image mean of the group - of the reference) / reference's, +- se */
    size_t lit;
} stats;

/* Mean variance over pixels and channels of runs [a, b) of group g; the per-pixel mean image
 * goes to mean (3 per pixel) and the per-pixel channel-mean variance to pvar when not NULL. */
static double group_variance(const group *g, int a, int b, size_t npix, const rd_image *ref,
                             double *mean, double *pvar)
{
    size_t nv = npix * 3;
    double *sum = calloc(nv, sizeof(double)), *sum2 = calloc(nv, sizeof(double));
    if (!sum || !sum2) die("out of memory");
    for (int k = a; k < b; k++) {
        rd_image img = read_exr(g->path[k]);
        check_size(&img, ref, g->path[k]);
        for (size_t i = 0; i < nv; i++) {
            sum[i] += img.rgb[i];
            sum2[i] += (double)img.rgb[i] * img.rgb[i];
        }
        rd_image_free_pixels(&img);
    }
    int K = b - a;
    double total = 0.0;
    for (size_t p = 0; p < npix; p++) {
        double pv = 0.0;
        for (int c = 0; c < 3; c++) {
            size_t i = 3 * p + c;
            double m = sum[i] / K, s2 = (sum2[i] - K * m * m) / (K - 1);
            if (s2 < 0) s2 = 0; /* rounding */
            if (mean) mean[i] = m;
            pv += s2 / 3.0;
        }
        if (pvar) pvar[p] = pv;
        total += pv;
    }
    free(sum);
    free(sum2);
    return total / npix;
}

static void group_times(const group *g, int a, int b, stats *st)
{
    st->time = 0.0;
    st->tmin = INFINITY;
    st->tmax = 0.0;
    for (int k = a; k < b; k++) {
        double t = report_number(g->path[k], g->time_key);
        st->time += t / (b - a);
        if (t < st->tmin) st->tmin = t;
        if (t > st->tmax) st->tmax = t;
    }
}

/* Noise homogeneity: relative standard deviation s / ref over the lit pixels. */
static void homogeneity(const double *pvar, const double *refc, size_t npix, double lit_level, stats *st)
{
    double *r = malloc(npix * sizeof(double));
    if (!r) die("out of memory");
    size_t n = 0;
    double s = 0.0, s2 = 0.0;
    for (size_t p = 0; p < npix; p++)
        if (refc[p] >= lit_level && refc[p] > 0.0) {
            double x = sqrt(pvar[p]) / refc[p];
            r[n++] = x;
            s += x;
            s2 += x * x;
        }
    st->lit = n;
    if (n < 2) {
        st->rel_median = st->rel_iqr = st->rel_cv = NAN;
    } else {
        qsort(r, n, sizeof(double), cmp_double);
        double m = s / n, sd = sqrt((s2 - n * m * m) / (n - 1));
        st->rel_median = quantile(r, n, 0.5);
        st->rel_iqr = (quantile(r, n, 0.75) - quantile(r, n, 0.25)) / st->rel_median;
        st->rel_cv = sd / m;
    }
    free(r);
}

/* The bias of the image mean, which averages the noise away where the per-pixel bias^2 cannot:
 * d = (mean over runs of the run's image mean - the reference's image mean) / the latter, with
 * its standard error from the spread of the K run means and the reference's per-pixel standard
 * errors (independent pixels: se of its mean = sqrt(sum se^2) / n). */
static void image_mean_bias(const group *g, const rd_image *ref, const rd_image *ref_se, stats *st)
{
    size_t nv = (size_t)ref->w * ref->h * 3;
    double r = 0.0, rse2 = 0.0, s = 0.0, s2 = 0.0;
    for (size_t i = 0; i < nv; i++) {
        r += ref->rgb[i] / nv;
        rse2 += (double)ref_se->rgb[i] * ref_se->rgb[i] / ((double)nv * nv);
    }
    for (int k = 0; k < g->k; k++) {
        rd_image img = read_exr(g->path[k]);
        double m = 0.0;
        for (size_t i = 0; i < nv; i++) m += img.rgb[i] / nv;
        s += m;
        s2 += m * m;
        rd_image_free_pixels(&img);
    }
    double m = s / g->k, v = (s2 - g->k * m * m) / (g->k - 1);
    st->dmean = (m - r) / r;
    st->dmean_se = sqrt(fmax(v, 0.0) / g->k + rse2) / r;
}

/* Everything about one group against the reference (ref, its stderr image and its channel
 * means refc). */
static stats group_stats(const group *g, const rd_image *ref, const rd_image *ref_se,
                         const double *refc, double lit_level)
{
    size_t npix = (size_t)ref->w * ref->h;
    stats st;
    double *mean = malloc(npix * 3 * sizeof(double)), *pvar = malloc(npix * sizeof(double));
    if (!mean || !pvar) die("out of memory");
    st.var = group_variance(g, 0, g->k, npix, ref, mean, pvar);
    group_times(g, 0, g->k, &st);
    /* bias^2 = E[(mean_K - ref)^2] - var/K - se_ref^2 (THEORY.md §7) */
    double d2 = 0.0, se2 = 0.0;
    for (size_t i = 0; i < npix * 3; i++) {
        double d = mean[i] - ref->rgb[i];
        d2 += d * d;
        se2 += (double)ref_se->rgb[i] * ref_se->rgb[i];
    }
    st.floor_k = st.var / g->k + se2 / (npix * 3);
    st.bias2 = d2 / (npix * 3) - st.floor_k;
    homogeneity(pvar, refc, npix, lit_level, &st);
    image_mean_bias(g, ref, ref_se, &st);
    free(mean);
    free(pvar);
    return st;
}

/* eff = 1 / (var x time) of runs [a, b). */
static double half_efficiency(const group *g, int a, int b, const rd_image *ref)
{
    stats st;
    double var = group_variance(g, a, b, (size_t)ref->w * ref->h, ref, NULL, NULL);
    group_times(g, a, b, &st);
    return 1.0 / (var * st.time);
}

/* ---- Commands ------------------------------------------------------------------------------ */

static int cmd_rmse(int argc, char **argv)
{
    rd_image ref = read_exr(argv[0]);
    char *se_path = sibling(argv[0], "-stderr.exr");
    rd_image ref_se = read_exr(se_path);
    free(se_path);
    double se2 = 0.0;
    size_t n = (size_t)ref.w * ref.h * 3;
    for (size_t j = 0; j < n; j++) se2 += (double)ref_se.rgb[j] * ref_se.rgb[j] / n;
    rd_image_free_pixels(&ref_se);
    /* E[RMSE^2] = the image's own MSE + the reference's variance se_ref^2: the last column
     * removes the latter, the part of the RMSE that belongs to the reference. */
    printf("reference noise: mean se_ref^2 = %.4g (RMSE floor %.4g)\n\n", se2, sqrt(se2));
    printf("| image | seconds | spp_mean | RMSE | MSE - se_ref^2 |\n|---|---|---|---|---|\n");
    for (int i = 1; i < argc; i++) {
        rd_image img = read_exr(argv[i]);
        check_size(&img, &ref, argv[i]);
        double s = 0.0;
        size_t nv = (size_t)ref.w * ref.h * 3;
        for (size_t j = 0; j < nv; j++) {
            double d = (double)img.rgb[j] - ref.rgb[j];
            s += d * d;
        }
        printf("| %s | %.2f | %.2f | %.6g | %.4g |\n", argv[i], report_number(argv[i], "seconds"),
               report_number(argv[i], "spp_mean"), sqrt(s / nv), s / nv - se2);
        rd_image_free_pixels(&img);
    }
    rd_image_free_pixels(&ref);
    return 0;
}

static double *channel_means(const rd_image *ref, double *lit_level, double lit_fraction)
{
    size_t npix = (size_t)ref->w * ref->h;
    double *refc = malloc(npix * sizeof(double)), *sorted = malloc(npix * sizeof(double));
    if (!refc || !sorted) die("out of memory");
    for (size_t p = 0; p < npix; p++)
        sorted[p] = refc[p] = (ref->rgb[3 * p] + ref->rgb[3 * p + 1] + ref->rgb[3 * p + 2]) / 3.0;
    qsort(sorted, npix, sizeof(double), cmp_double);
    *lit_level = lit_fraction * quantile(sorted, npix, 0.99);
    free(sorted);
    return refc;
}

static void print_groups(group *gs, int ng, const rd_image *ref, const rd_image *ref_se, double lit_fraction)
{
    double lit_level;
    double *refc = channel_means(ref, &lit_level, lit_fraction);
    size_t npix = (size_t)ref->w * ref->h;
    double ref_mean = 0.0;
    for (size_t p = 0; p < npix; p++) ref_mean += refc[p] / npix;
    stats st[MAX_GROUPS];
    printf("| method | K | time s (min-max) | var | eff = 1/(var t) | bias^2 | noise floor | rel. RMS bias | image-mean bias (+- se) | lit px | median rel. sd | IQR/median | CV |\n");
    printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int i = 0; i < ng; i++) {
        st[i] = group_stats(&gs[i], ref, ref_se, refc, lit_level);
        double rb = st[i].bias2 > 0 ? sqrt(st[i].bias2) / ref_mean : 0.0;
        printf("| %s | %d | %.2f (%.2f-%.2f) | %.4g | %.4g | %.3g | %.3g | %.3g | %+.2f%% (%.2f%%) | %zu | %.3g | %.3g | %.3g |\n",
               gs[i].name, gs[i].k, st[i].time, st[i].tmin, st[i].tmax, st[i].var, 1.0 / (st[i].var * st[i].time),
               st[i].bias2, st[i].floor_k, rb, 100 * st[i].dmean, 100 * st[i].dmean_se, st[i].lit, st[i].rel_median, st[i].rel_iqr, st[i].rel_cv);
    }
    printf("\nreference channel mean over pixels %.5g; lit pixels: reference >= %.3g (%.2f x its 99th percentile)\n\n",
           ref_mean, lit_level, lit_fraction);
    if (ng > 1) {
        int h = gs[0].k / 2;
        double e0 = 1.0 / (st[0].var * st[0].time);
        double e0a = half_efficiency(&gs[0], 0, h, ref), e0b = half_efficiency(&gs[0], h, gs[0].k, ref);
        printf("| ratio | all runs | first half | second half |\n|---|---|---|---|\n");
        for (int i = 1; i < ng; i++) {
            int hi = gs[i].k / 2;
            double ei = 1.0 / (st[i].var * st[i].time);
            printf("| eff %s / eff %s | %.3g | %.3g | %.3g |\n", gs[0].name, gs[i].name, e0 / ei,
                   e0a / half_efficiency(&gs[i], 0, hi, ref), e0b / half_efficiency(&gs[i], hi, gs[i].k, ref));
        }
    }
    free(refc);
}

static void usage(void)
{
    fprintf(stderr, "usage: bench_march_stats --ref REF.exr [--lit F] [--time-key KEY] --group NAME A1.exr ... AK.exr [--group ...]\n"
                    "       bench_march_stats --rmse REF.exr X1.exr ...\n");
    exit(1);
}

int main(int argc, char **argv)
{
    if (argc >= 3 && !strcmp(argv[1], "--rmse")) return cmd_rmse(argc - 2, argv + 2);
    const char *ref_path = NULL, *time_key = "seconds";
    double lit_fraction = 0.1;
    group gs[MAX_GROUPS];
    int ng = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--ref") && i + 1 < argc) {
            ref_path = argv[++i];
        } else if (!strcmp(argv[i], "--lit") && i + 1 < argc) {
            lit_fraction = atof(argv[++i]);
        } else if (!strcmp(argv[i], "--time-key") && i + 1 < argc) {
            time_key = argv[++i];
        } else if (!strcmp(argv[i], "--group") && i + 1 < argc) {
            if (ng == MAX_GROUPS) usage();
            gs[ng].name = argv[++i];
            gs[ng++].k = 0;
        } else if (!strcmp(argv[i], "--quick") || !strcmp(argv[i], "--json")) {
            if (!strcmp(argv[i], "--json")) i++; /* `make bench` passes these: nothing to do */
        } else if (ng > 0 && gs[ng - 1].k < MAX_RUNS && argv[i][0] != '-') {
            gs[ng - 1].path[gs[ng - 1].k++] = argv[i];
        } else {
            usage();
        }
    }
    if (ng == 0) {
        printf("bench_march_stats: no renders given; bench/bench_march.sh runs it (docs/guided-marching.md)\n");
        return 0;
    }
    if (!ref_path) usage();
    for (int i = 0; i < ng; i++) {
        if (gs[i].k < 4) usage();
        gs[i].time_key = time_key;
    }
    rd_image ref = read_exr(ref_path);
    char *se_path = sibling(ref_path, "-stderr.exr");
    rd_image ref_se = read_exr(se_path);
    check_size(&ref_se, &ref, se_path);
    free(se_path);
    print_groups(gs, ng, &ref, &ref_se, lit_fraction);
    rd_image_free_pixels(&ref);
    return 0;
}
