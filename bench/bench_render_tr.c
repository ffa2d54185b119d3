/* bench_render_tr: which transmittance estimator gives the most efficient render?
 *
 * The estimator (`settings.transmittance`) only enters a render through its shadow rays (next
 * event estimation in `delta`), so what matters is not the variance of one transmittance
 * estimate but the efficiency of the whole render (Veach 1997, §2.4: efficiency = 1 / (variance
 * x time)). For each density kind, one small scene:
 *
 *   constant: scenes/homogeneous.json     grid: scenes/smoke-vdb.json     noise: scenes/default.json
 *
 * each rendered at a low resolution and spp with every estimator (ratio-global = the current
 * `auto`, ratio, residual, exact) and K independent seeds. The renders go through the same
 * public API as `photonmarch render` (rd_scene_load with --set style overrides, rd_render), on
 * one thread. Per pixel, the variance of the pixel value (mean of R, G, B) over the K seeds is
 * the variance of that pixel's estimate; its mean over the pixels, times the median render time,
 * is the variance x time of the render. The renders are interleaved (seed 1: estimators 1..4,
 * seed 2: estimators 1..4, ...) so that load from other jobs falls on every estimator alike.
 *
 * Uncertainty: the mean per-pixel variance is an average over P pixels; its standard error is
 * the standard deviation of the per-pixel variances over sqrt(P), printed beside it. Two
 * estimators differ in variance only when their difference exceeds 4-5 of these errors.
 *
 *   bench_render_tr [--quick] [--json FILE] [--seeds K]
 */
#include "renderer.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { NEST = 4, NSCENE = 3, MAXK = 32 };
static const char *est[NEST] = {"ratio-global", "ratio", "residual", "exact"};

typedef struct {
    const char *kind, *path, *res;
    int spp;
} scene_case;

static const scene_case cases[NSCENE] = {
    {"constant", "scenes/homogeneous.json", "[64,64]", 8},
    {"grid", "scenes/smoke-vdb.json", "[80,60]", 8},
    {"noise", "scenes/default.json", "[80,60]", 8},
};

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(const double *v, int n)
{
    double s[MAXK];
    memcpy(s, v, (size_t)n * sizeof *s);
    qsort(s, (size_t)n, sizeof *s, cmp_d);
    return n % 2 ? s[n / 2] : 0.5 * (s[n / 2 - 1] + s[n / 2]);
}

static rd_scene *load(const scene_case *sc, const char *estimator, int spp)
{
    char spp_s[16];
    snprintf(spp_s, sizeof spp_s, "%d", spp);
    rd_override ov[3] = {{"camera.resolution", sc->res}, {"settings.transmittance", estimator}, {"settings.spp", spp_s}};
    rd_scene *s = NULL;
    char err[RD_ERRLEN];
    if (rd_scene_load(&s, sc->path, ov, 3, err, sizeof err) != RD_OK) {
        fprintf(stderr, "bench_render_tr: %s\n", err);
        exit(1);
    }
    return s;
}

/* Running per-pixel sums of the pixel value (mean of R, G, B) over the seeds. */
typedef struct {
    double *s1, *s2;
    double seconds[MAXK];
    double shadow_rays, lookups; /* per camera path, last seed */
} accum;

static void render_once(const rd_scene *s, int spp, uint64_t seed, accum *a, int k)
{
    rd_render_opts o;
    memset(&o, 0, sizeof o);
    o.method = "delta";
    o.spp = spp;
    o.seed = seed;
    o.threads = 1;
    rd_render_result res;
    char err[RD_ERRLEN];
    if (rd_render(s, &o, &res, err, sizeof err) != RD_OK) {
        fprintf(stderr, "bench_render_tr: %s\n", err);
        exit(1);
    }
    const rd_image img = res.image;
    const rd_render_stats st = res.stats;
    for (int p = 0; p < img.w * img.h; p++) {
        double v = (img.rgb[3 * p] + img.rgb[3 * p + 1] + img.rgb[3 * p + 2]) / 3.0;
        a->s1[p] += v;
        a->s2[p] += v * v;
    }
    a->seconds[k] = st.seconds;
    a->shadow_rays = (double)st.shadow_rays / (double)st.paths;
    a->lookups = (double)st.lookups / (double)st.paths;
    rd_render_result_free(&res);
}

/* Mean over pixels of the unbiased per-pixel variance over K seeds, and its standard error. */
static double mean_variance(const accum *a, int npix, int K, double *se)
{
    double m = 0, m2 = 0;
    for (int p = 0; p < npix; p++) {
        double mean = a->s1[p] / K;
        double v = fmax(0.0, (a->s2[p] / K - mean * mean) * K / (K - 1.0));
        m += v;
        m2 += v * v;
    }
    m /= npix;
    *se = sqrt(fmax(0.0, m2 / npix - m * m) / npix);
    return m;
}

static void run_case(const scene_case *sc, int K, int spp, FILE *js, int first)
{
    rd_scene *s[NEST];
    accum a[NEST];
    for (int e = 0; e < NEST; e++) s[e] = load(sc, est[e], spp);
    int npix = rd_scene_width(s[0]) * rd_scene_height(s[0]);
    for (int e = 0; e < NEST; e++) {
        memset(&a[e], 0, sizeof a[e]);
        a[e].s1 = calloc((size_t)npix, sizeof(double));
        a[e].s2 = calloc((size_t)npix, sizeof(double));
        if (!a[e].s1 || !a[e].s2) { fprintf(stderr, "bench_render_tr: out of memory\n"); exit(1); }
    }
    for (int k = 0; k < K; k++)
        for (int e = 0; e < NEST; e++) render_once(s[e], spp, 1000 + (uint64_t)k, &a[e], k);

    printf("| %s: %s, %s px, %d spp, %d seeds | mean pixel variance (+- 1 s.e.) | render s, median (min-max) | "
           "shadow rays/path | lookups/path | variance x time | efficiency x ratio-global |\n"
           "|---|---|---|---|---|---|---|\n", sc->kind, sc->path, sc->res, spp, K);
    fprintf(js, "%s    {\"kind\": \"%s\", \"scene\": \"%s\", \"resolution\": \"%s\", \"spp\": %d, \"seeds\": %d, \"estimators\": [",
            first ? "" : ",\n", sc->kind, sc->path, sc->res, spp, K);
    double vt0 = 0;
    for (int e = 0; e < NEST; e++) {
        double se, var = mean_variance(&a[e], npix, K, &se), lo = INFINITY, hi = 0;
        for (int k = 0; k < K; k++) { lo = fmin(lo, a[e].seconds[k]); hi = fmax(hi, a[e].seconds[k]); }
        double t = median(a[e].seconds, K), vt = var * t;
        if (e == 0) vt0 = vt;
        printf("| %s | %.4e (+- %.1e) | %.3f (%.3f-%.3f) | %.2f | %.1f | %.4e | %.2f |\n", est[e], var, se, t, lo, hi,
               a[e].shadow_rays, a[e].lookups, vt, vt0 / vt);
        fprintf(js, "%s{\"estimator\": \"%s\", \"variance\": %.6e, \"se\": %.3e, \"seconds\": %.5f, \"min_s\": %.5f, \"max_s\": %.5f, "
                "\"lookups_per_path\": %.3f}", e ? ", " : "", est[e], var, se, t, lo, hi, a[e].lookups);
        free(a[e].s1);
        free(a[e].s2);
        rd_scene_free(s[e]);
    }
    fprintf(js, "]}");
    printf("\n");
}

int main(int argc, char **argv)
{
    int quick = 0, K = 9;
    const char *json = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--quick")) quick = 1;
        else if (!strcmp(argv[i], "--json") && i + 1 < argc) json = argv[++i];
        else if (!strcmp(argv[i], "--seeds") && i + 1 < argc) K = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: %s [--quick] [--json FILE] [--seeds K]\n", argv[0]);
            return 2;
        }
    }
    if (quick) K = 3;
    if (K < 2 || K > MAXK) {
        fprintf(stderr, "bench_render_tr: --seeds must be in 2..%d\n", MAXK);
        return 2;
    }
    FILE *js = json ? fopen(json, "w") : fopen("/dev/null", "w");
    if (!js) { perror(json); return 1; }
    printf("# Render efficiency per transmittance estimator (delta, one thread, interleaved)%s\n\n",
           quick ? " (--quick: not the figures)" : "");
    FILE *la = fopen("/proc/loadavg", "r");
    char lbuf[64];
    if (la && fgets(lbuf, sizeof lbuf, la)) {
        lbuf[strcspn(lbuf, "\n")] = 0;
        printf("Load average at start: %s.\n\n", lbuf);
    }
    if (la) fclose(la);
    fprintf(js, "{\n  \"bench\": \"render_tr\", \"cases\": [\n");
    for (int c = 0; c < NSCENE; c++) run_case(&cases[c], K, quick ? 1 : cases[c].spp, js, c == 0);
    fprintf(js, "\n  ]\n}\n");
    fclose(js);
    return 0;
}
