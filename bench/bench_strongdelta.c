/* bench_strongdelta: efficiency of `delta` with its thin-media strategies (issue 21 item 4:
 * settings.equiangular, settings.thin_bias), and of the guided methods beside them, against
 * plain `delta` at equal time.
 *
 *   bench_strongdelta SCENE --reference REF.exr [--set KEY=VAL]...
 *                     --variant LABEL [--set KEY=VAL]... [--variant LABEL ...]...
 *                     [--seconds S] [--runs K] [--threads N] [--seed N] [--mask-outliers]
 *                     [--save DIR]
 *
 * Each variant is the scene with its own --set overrides (those before the first --variant
 * apply to all, e.g. camera.resolution), rendered by its settings.method (`delta` unless a
 * --set names another: --set settings.method=guided-unbiased; a method that bakes bakes in
 * every round, inside the timed render, as `render --no-cache` would). Round k renders every
 * variant once with seed + k for S seconds (rd_render with a time limit, the public API of
 * `photonmarch render`), variants in turn, so that load from other jobs on a shared machine
 * falls on all of them alike. Each render's error against the reference: MSE = mean over
 * pixels and channels of (x - r)^2, less the reference's own variance (mean of REF-stderr.exr
 * squared, when that file is beside it: E[(x - r)^2] = MSE_true + var_r for an independent r),
 * and its efficiency 1 / (MSE x seconds)
 * (THEORY.md §7, Veach 1997 §2.4). --mask-outliers leaves out, in every render alike, the pixels
 * where the reference's variance is over 1000x its median over the pixels with any variance: a
 * few pixels that one camera chain, common to every method, makes far noisier than the rest
 * (hard-lens-caustic's image of the small light through the ball, a specular chain every method
 * follows alike), which would otherwise be the whole MSE. It says how many pixels that left out
 * and what share of the reference's variance they held, and warns when they are more than 1% of
 * the pixels with variance: against a `delta` reference the rule also takes every pixel where the reference drew
 * one of its own rare paths (hard-lens-caustic against session 38's 200-s reference: 1786 of
 * 19200 pixels, 99.6% of its variance; docs/benchmarks.md "Session 43"). Printed per variant: the medians over
 * the K rounds with min-max of seconds, samples per pixel, MSE and efficiency, and of the
 * efficiency ratio to the first variant within the same round (the figure to quote: one round's
 * variants share one load), and that ratio taken apart (its inverse is their product): the
 * time a camera sample took (the bake's share included) and the MSE times the samples a pixel
 * (the variance of one sample, where the error is variance), each over the first variant's in
 * the same round; and the seconds of bake and set-up inside each render (a guided method's
 * bake and its tile selection's pilot, charged to it) and, for a method other than `delta`, the
 * share of its camera samples its selection left on the method's own estimators (the rest went
 * to delta's path: select.c; 1 for a method without a selection, "-" for `delta`, whose
 * "tiles" count something else), and for `guided` the part of it on guided-unbiased's paths
 * (march.guided_paths). --save DIR writes every render as DIR/LABEL-rK.exr (K = 1..runs), to
 * measure the same renders against another reference afterwards (DIR must exist; a label is
 * one file name, no '/'). The reference is yours to render, 20x longer or more, by the
 * strongest `delta` for the scene (with a point or spot light, settings.equiangular true or
 * "tiles": a plain reference's own noise can be as large as the best variant's error,
 * docs/benchmarks.md "Session 26"):
 *     build/photonmarch render SCENE --set ... --time 600 --seed 99 -o REF.exr
 * Without arguments (as `make bench` runs every tool) it says so and exits 0. */
#include "renderer.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

enum { MAXV = 8, MAXSET = 16, MAXK = 64 };

typedef struct {
    const char *label;
    rd_override set[MAXSET];
    int n_set;
    rd_scene *scene;
    double seconds[MAXK], spp[MAXK], mse[MAXK], eff[MAXK], ratio[MAXK];
    double cost[MAXK], var[MAXK]; /* time a sample and MSE x samples, over the first variant's */
    double setup[MAXK];           /* seconds of bake and set-up (a selection's pilot) */
    double own[MAXK];             /* a guided method's share of samples on its own estimator
                                     (the rest its selection gave to delta's path); -1: not one */
    double paths[MAXK];           /* `guided`'s share on guided-unbiased's paths (part of own;
                                     march.guided_paths); -1: another method */
} variant;

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static void stats(const double *v, int n, double *med, double *lo, double *hi)
{
    double s[MAXK];
    memcpy(s, v, (size_t)n * sizeof *s);
    qsort(s, (size_t)n, sizeof *s, cmp_d);
    *med = n % 2 ? s[n / 2] : 0.5 * (s[n / 2 - 1] + s[n / 2]);
    *lo = s[0];
    *hi = s[n - 1];
}

static int split_set(const char *arg, rd_override *o)
{
    const char *eq = strchr(arg, '=');
    if (!eq || eq == arg) return 0;
    char *key = strndup(arg, (size_t)(eq - arg));
    o->key = key;
    o->value = eq + 1;
    return 1;
}

int main(int argc, char **argv)
{
    rd_steady_allocation(); /* every variant's render allocates as the first's (renderer.h) */
    const char *scene = NULL, *ref_path = NULL, *save_dir = NULL;
    double seconds = 10.0;
    int runs = 4, threads = 2, mask_outliers = 0;
    uint64_t seed = 1000;
    rd_override common[MAXSET];
    int n_common = 0, nv = 0;
    static variant v[MAXV];
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *next = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--mask-outliers")) {
            mask_outliers = 1;
            continue;
        }
        if (!strcmp(a, "--json") || !strcmp(a, "--quick")) {
            if (!strcmp(a, "--json")) i++;
            continue;
        }
        if (!next && a[0] == '-') { fprintf(stderr, "bench_strongdelta: %s needs a value\n", a); return 1; }
        if (!strcmp(a, "--reference")) ref_path = argv[++i];
        else if (!strcmp(a, "--save")) save_dir = argv[++i];
        else if (!strcmp(a, "--seconds")) seconds = atof(argv[++i]);
        else if (!strcmp(a, "--runs")) runs = atoi(argv[++i]);
        else if (!strcmp(a, "--threads")) threads = atoi(argv[++i]);
        else if (!strcmp(a, "--seed")) seed = strtoull(argv[++i], NULL, 10);
        else if (!strcmp(a, "--variant")) {
            if (nv >= MAXV) { fprintf(stderr, "bench_strongdelta: at most %d variants\n", MAXV); return 1; }
            v[nv++].label = argv[++i];
        } else if (!strcmp(a, "--set")) {
            rd_override o;
            if (!split_set(argv[++i], &o)) { fprintf(stderr, "bench_strongdelta: --set KEY=VALUE\n"); return 1; }
            if (nv == 0 && n_common < MAXSET) common[n_common++] = o;
            else if (nv > 0 && v[nv - 1].n_set < MAXSET) v[nv - 1].set[v[nv - 1].n_set++] = o;
        } else if (a[0] != '-' && !scene) scene = a;
        else { fprintf(stderr, "bench_strongdelta: unknown argument %s\n", a); return 1; }
    }
    if (!scene) {
        printf("bench_strongdelta: a tool for one scene and its variants (see its header); nothing to run here\n");
        return 0;
    }
    if (!ref_path || nv < 1 || runs < 1 || runs > MAXK || !(seconds > 0)) {
        fprintf(stderr, "usage: bench_strongdelta SCENE --reference REF.exr --variant LABEL [--set K=V]... [--seconds S] [--runs K]\n");
        return 1;
    }
    if (save_dir) {
        struct stat sb;
        if (stat(save_dir, &sb) != 0 || !S_ISDIR(sb.st_mode)) {
            fprintf(stderr, "bench_strongdelta: --save %s: not a folder\n", save_dir);
            return 1;
        }
        for (int k = 0; k < nv; k++)
            if (strchr(v[k].label, '/')) {
                fprintf(stderr, "bench_strongdelta: --save: the label %s has a '/'\n", v[k].label);
                return 1;
            }
    }
    char err[RD_ERRLEN];
    rd_image ref, ref_se = {0};
    if (rd_image_read(ref_path, &ref, err, sizeof err) != RD_OK) { fprintf(stderr, "bench_strongdelta: %s\n", err); return 1; }
    char se_path[1200];
    snprintf(se_path, sizeof se_path, "%.*s-stderr.exr", (int)(strlen(ref_path) - 4), ref_path);
    double ref_var = 0.0;
    int have_se = rd_image_read(se_path, &ref_se, err, sizeof err) == RD_OK && ref_se.w == ref.w && ref_se.h == ref.h;
    size_t npx = (size_t)ref.w * ref.h, nvals = 0;
    /* keep[p]: pixel p counts (all of them unless --mask-outliers) */
    unsigned char *keep = malloc(npx);
    double *pv = malloc(npx * sizeof *pv);
    if (!keep || !pv) { fprintf(stderr, "bench_strongdelta: out of memory\n"); return 1; }
    for (size_t p = 0; p < npx; p++) {
        pv[p] = 0.0;
        for (int c = 0; c < 3 && have_se; c++) pv[p] += (double)ref_se.rgb[3 * p + c] * ref_se.rgb[3 * p + c];
        keep[p] = 1;
    }
    if (mask_outliers && !have_se)
        fprintf(stderr, "bench_strongdelta: --mask-outliers needs %s; every pixel counts\n", se_path);
    size_t np = 0; /* pixels with some variance in the reference */
    if (mask_outliers && have_se) {
        /* the median over the pixels with some variance (a background that sees no medium has
         * none, and would put the median at 0) */
        double *sorted = malloc(npx * sizeof *sorted);
        if (!sorted) { fprintf(stderr, "bench_strongdelta: out of memory\n"); return 1; }
        for (size_t p = 0; p < npx; p++)
            if (pv[p] > 0.0) sorted[np++] = pv[p];
        qsort(sorted, np, sizeof *sorted, cmp_d);
        double median = np ? sorted[np / 2] : 0.0;
        for (size_t p = 0; p < npx; p++) keep[p] = !(np > 0) || pv[p] <= 1000.0 * median;
        free(sorted);
    }
    size_t masked = 0;
    double var_all = 0.0; /* the reference's variance summed over every pixel, left out or not */
    for (size_t p = 0; p < npx; p++) {
        var_all += pv[p];
        if (!keep[p]) { masked++; continue; }
        ref_var += pv[p];
        nvals += 3;
    }
    double var_left_out = var_all > 0.0 ? 1.0 - ref_var / var_all : 0.0;
    free(pv);
    if (nvals == 0) { fprintf(stderr, "bench_strongdelta: every pixel left out\n"); return 1; }
    ref_var /= (double)nvals;
    for (int k = 0; k < nv; k++) {
        rd_override ov[2 * MAXSET];
        int n = 0;
        for (int i = 0; i < n_common; i++) ov[n++] = common[i];
        for (int i = 0; i < v[k].n_set; i++) ov[n++] = v[k].set[i];
        if (rd_scene_load(&v[k].scene, scene, ov, n, err, sizeof err) != RD_OK) {
            fprintf(stderr, "bench_strongdelta: variant %s: %s\n", v[k].label, err);
            return 1;
        }
    }
    printf("bench_strongdelta %s: %d variants, %d rounds of %g s each, %d threads, reference %s (variance %.3g%s)",
           scene, nv, runs, seconds, threads, ref_path, ref_var, have_se ? "" : ", unknown: no stderr image");
    if (mask_outliers)
        printf(", %zu pixels left out (--mask-outliers: %.1f%% of the %zu with variance, %.1f%% of the "
               "reference's variance)", masked, np ? 100.0 * (double)masked / (double)np : 0.0, np,
               100.0 * var_left_out);
    printf("\n");
    if (mask_outliers && np && masked * 100 > np)
        /* The mask is for a few pixels one camera chain makes noisy in every render alike. More
         * than 1% of the pixels are the reference's own rare paths (one sample each, wherever such
         * paths land): leaving them out drops the image where the methods differ most. */
        printf("warning: --mask-outliers left out %zu of the %zu pixels with variance, more than the few one camera chain "
               "makes noisy: they are likely the reference's own rare paths (a single sample each), "
               "and the figures leave out where those paths land; measure without it too\n",
               masked, np);
    fflush(stdout);
    for (int r = 0; r < runs; r++) {
        for (int k = 0; k < nv; k++) {
            /* the variant's settings.method (a guided method bakes inside rd_render: charged) */
            const char *method = rd_scene_method(v[k].scene);
            rd_render_opts o = {.method = method, .spp = 1 << 24, .time_limit = seconds, .seed = seed + r, .threads = threads};
            rd_render_result res;
            if (rd_render(v[k].scene, &o, &res, err, sizeof err) != RD_OK) {
                fprintf(stderr, "bench_strongdelta: %s: %s\n", v[k].label, err);
                return 1;
            }
            if (res.image.w != ref.w || res.image.h != ref.h) {
                fprintf(stderr, "bench_strongdelta: the render is %dx%d, the reference %dx%d\n", res.image.w, res.image.h, ref.w, ref.h);
                return 1;
            }
            double se2 = 0.0;
            for (size_t q = 0; q < 3 * npx; q++) {
                double d = (double)res.image.rgb[q] - ref.rgb[q];
                if (keep[q / 3]) se2 += d * d;
            }
            double mse = se2 / nvals - ref_var;
            v[k].seconds[r] = res.stats.seconds;
            v[k].spp[r] = res.stats.spp_mean;
            v[k].mse[r] = mse;
            v[k].eff[r] = 1.0 / (mse * res.stats.seconds);
            v[k].ratio[r] = v[k].eff[r] / v[0].eff[r];
            /* The ratio taken apart: efficiency over the first variant's = 1 / (cost x var), with
             * cost the time a camera sample took (the bake's share included) and var the MSE
             * times the samples a pixel (the variance of one sample where the error is variance:
             * an unbiased method's, the reference's variance removed), each over the first's. */
            v[k].cost[r] = (res.stats.seconds / res.stats.spp_mean) / (v[0].seconds[r] / v[0].spp[r]);
            v[k].var[r] = (mse * res.stats.spp_mean) / (v[0].mse[r] * v[0].spp[r]);
            v[k].setup[r] = res.stats.bake_seconds + res.stats.prepare_seconds;
            v[k].own[r] = strcmp(method, "delta") && res.stats.paths
                              ? 1.0 - (double)res.stats.delta_samples / (double)res.stats.paths
                              : -1.0;
            v[k].paths[r] = strcmp(method, "guided") == 0 && res.stats.paths
                                ? (double)res.stats.path_samples / (double)res.stats.paths
                                : -1.0;
            fprintf(stderr, "round %d %-28s %6.2f s %8.1f spp  MSE %.4g  eff %.4g  x%.3f\n", r + 1, v[k].label,
                    res.stats.seconds, res.stats.spp_mean, mse, v[k].eff[r], v[k].ratio[r]);
            if (save_dir) {
                char out[1400];
                snprintf(out, sizeof out, "%s/%s-r%d.exr", save_dir, v[k].label, r + 1);
                if (rd_image_write_exr(out, &res.image, err, sizeof err) != RD_OK) {
                    fprintf(stderr, "bench_strongdelta: %s\n", err);
                    rd_render_result_free(&res);
                    return 1;
                }
            }
            rd_render_result_free(&res);
        }
    }
    printf("| variant | seconds | spp | MSE | efficiency | vs %s | time a sample vs %s | variance a sample vs %s |"
           " bake + set-up s | own samples | of them guided-unbiased's paths |\n"
           "|---|---|---|---|---|---|---|---|---|---|---|\n", v[0].label, v[0].label, v[0].label);
    for (int k = 0; k < nv; k++) {
        double m[10], lo[10], hi[10];
        stats(v[k].seconds, runs, &m[0], &lo[0], &hi[0]);
        stats(v[k].spp, runs, &m[1], &lo[1], &hi[1]);
        stats(v[k].mse, runs, &m[2], &lo[2], &hi[2]);
        stats(v[k].eff, runs, &m[3], &lo[3], &hi[3]);
        stats(v[k].ratio, runs, &m[4], &lo[4], &hi[4]);
        stats(v[k].cost, runs, &m[5], &lo[5], &hi[5]);
        stats(v[k].var, runs, &m[6], &lo[6], &hi[6]);
        stats(v[k].setup, runs, &m[7], &lo[7], &hi[7]);
        stats(v[k].own, runs, &m[8], &lo[8], &hi[8]);
        stats(v[k].paths, runs, &m[9], &lo[9], &hi[9]);
        printf("| %s | %.2f | %.1f (%.1f-%.1f) | %.3g (%.3g-%.3g) | %.3g (%.3g-%.3g) | %.2f (%.2f-%.2f) | %.2f (%.2f-%.2f) |"
               " %.3g (%.3g-%.3g) | %.2f (%.2f-%.2f) |",
               v[k].label, m[0], m[1], lo[1], hi[1], m[2], lo[2], hi[2], m[3], lo[3], hi[3], m[4], lo[4], hi[4], m[5],
               lo[5], hi[5], m[6], lo[6], hi[6], m[7], lo[7], hi[7]);
        if (m[8] < 0.0) printf(" - |");
        else printf(" %.3f (%.3f-%.3f) |", m[8], lo[8], hi[8]);
        if (m[9] < 0.0) printf(" - |\n");
        else printf(" %.3f (%.3f-%.3f) |\n", m[9], lo[9], hi[9]);
    }
    for (int k = 0; k < nv; k++) {
        rd_scene_free(v[k].scene);
        for (int i = 0; i < v[k].n_set; i++) free((char *)v[k].set[i].key);
    }
    for (int i = 0; i < n_common; i++) free((char *)common[i].key);
    rd_image_free_pixels(&ref);
    rd_image_free_pixels(&ref_se);
    free(keep);
    return 0;
}
