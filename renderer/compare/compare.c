/* compare.c: `photonmarch compare`, the A/B comparison of rendering methods on one scene
 * (issue 11; THEORY.md §7; docs/compare.md).
 *
 * The steps: the reference (a file, the cache, or a long `delta` render), one bake per kind of
 * bake the methods need (its time charged to every run of those methods), K runs of every
 * method at equal time or equal samples, then per method the metrics of THEORY.md §7: RMSE,
 * relMSE, mean absolute relative error, bias^2 and variance from the K runs, efficiency
 * 1/(MSE x time), seed 002's TTUV (time x RMSE), cost counters and noise homogeneity. The
 * report (HTML, JSON, plots) is written by compare_report.c from what this file keeps. */
#define _DEFAULT_SOURCE /* mkdir, popen */
#include "rd_internal.h"

#include <ctype.h>
#include <cJSON.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define RD_CMP_MAX_METHODS 8
/* Seeds: run k (0-based) of every method uses seed + 1 + k, so method A's run k and method
 * B's run k are as independent as any two renders; the reference uses a seed no run uses. */
#define RUN_SEED(seed, k) ((seed) + 1u + (uint64_t)(k))
#define REF_SEED(seed) ((seed) ^ 0x9e3779b97f4a7c15ULL)

/* One method's runs. */
typedef struct {
    const char *name;
    unsigned needs;       /* RD_NEEDS_* of its bake */
    rd_baked *baked;      /* shared with the methods of the same needs; owned when owns_baked */
    int owns_baked;
    double bake_seconds;  /* the bake's wall time, charged to each run */
    int done;             /* runs finished */
    rd_image *img, *se;   /* [runs]: mean and standard error images */
    rd_render_stats *stats;
    rd_conv_point **curve;
    int *n_curve;
} cmp_method;

struct rd_comparison {
    rd_cmp_opts opts;     /* a copy; the arrays it points to are the caller's */
    int n_methods, w, h;
    double exposure;      /* camera.exposure, for the PNGs */
    rd_image ref, ref_se; /* ref_se.rgb is NULL when the reference's error is unknown */
    cmp_method *m;
    rd_image *extra_img;  /* [n_extras] */
    rd_cmp_row *rows;
    const rd_image **row_img; /* [n_rows]: the image shown for each row (a method's first run) */
    rd_cmp_summary sum;
    double planned_seconds; /* seconds the runs not yet started will take (progress) */
};

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static rd_status fail(char *err, size_t errlen, rd_status st, const char *fmt, const char *a)
{
    if (err) snprintf(err, errlen, fmt, a);
    return st;
}

/* ---- Metrics (THEORY.md §7) --------------------------------------------------------------- */

rd_status rd_cmp_errors_of(const rd_image *x, const rd_image *r, rd_cmp_errors *out, char *err,
                           size_t errlen)
{
    if (x->w != r->w || x->h != r->h) return fail(err, errlen, RD_ERR_ARG, "%s: image sizes differ", "compare");
    size_t n = (size_t)x->w * x->h * 3;
    double se = 0.0, rel = 0.0, abs_rel = 0.0;
    for (size_t i = 0; i < n; i++) {
        double d = (double)x->rgb[i] - r->rgb[i], ri = r->rgb[i];
        se += d * d;                             /* MSE */
        rel += d * d / (ri * ri + RD_CMP_EPS);   /* relMSE = mean (x-r)^2 / (r^2 + eps) */
        abs_rel += fabs(d) / (fabs(ri) + RD_CMP_EPS);
    }
    out->mse = n ? se / n : 0.0;
    out->rmse = sqrt(out->mse);
    out->relmse = n ? rel / n : 0.0;
    out->mare = n ? abs_rel / n : 0.0;
    return RD_OK;
}

/* Mean and unbiased sample variance over k images of value i. */
static void moments(const rd_image *runs, int k, size_t i, double *mean, double *var)
{
    double s = 0.0, s2 = 0.0;
    for (int j = 0; j < k; j++) s += runs[j].rgb[i];
    double m = s / k;
    for (int j = 0; j < k; j++) s2 += (runs[j].rgb[i] - m) * (runs[j].rgb[i] - m);
    *mean = m;
    *var = s2 / (k - 1);
}

rd_status rd_cmp_split_of(const rd_image *runs, int k, const rd_image *r, const rd_image *r_stderr,
                          rd_cmp_split *out, char *err, size_t errlen)
{
    if (k < 2) return fail(err, errlen, RD_ERR_ARG, "%s: bias and variance need at least 2 runs", "compare");
    for (int j = 0; j < k; j++)
        if (runs[j].w != r->w || runs[j].h != r->h) return fail(err, errlen, RD_ERR_ARG, "%s: image sizes differ", "compare");
    size_t n = (size_t)r->w * r->h * 3;
    /* Per value: d = (m - r)^2 - s^2 / k - ref_var, an unbiased estimate of bias^2 there
     * (E[(m - r)^2] = bias^2 + var / k + ref_var for a reference independent of the runs). */
    double var_sum = 0.0, d_sum = 0.0, d_sum2 = 0.0;
    for (size_t i = 0; i < n; i++) {
        double m, v;
        moments(runs, k, i, &m, &v);
        double rv = r_stderr ? (double)r_stderr->rgb[i] * r_stderr->rgb[i] : 0.0;
        double d = (m - r->rgb[i]) * (m - r->rgb[i]) - v / k - rv;
        var_sum += v;
        d_sum += d;
        d_sum2 += d * d;
    }
    out->variance = var_sum / n;
    out->bias2 = d_sum / n;
    /* Standard error of that mean over the n values (treated as independent). */
    double sd2 = n > 1 ? (d_sum2 - d_sum * d_sum / n) / (n - 1) : 0.0;
    out->bias2_se = sqrt(fmax(0.0, sd2) / n);
    return RD_OK;
}

static double luminance(const float *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

double rd_cmp_homogeneity(const rd_image *x, const rd_image *r)
{
    size_t np = (size_t)r->w * r->h, lit = 0;
    if (x->w != r->w || x->h != r->h || np == 0) return 0.0;
    double mean = 0.0;
    for (size_t p = 0; p < np; p++) mean += luminance(r->rgb + 3 * p);
    mean /= np;
    double *e = malloc(np * sizeof *e);
    if (!e) return 0.0;
    for (size_t p = 0; p < np; p++) {
        double lr = luminance(r->rgb + 3 * p);
        if (lr > 0.01 * mean && mean > 0) e[lit++] = fabs(luminance(x->rgb + 3 * p) - lr) / (lr + RD_CMP_EPS);
    }
    double h = 0.0;
    if (lit >= 10) {
        qsort(e, lit, sizeof *e, cmp_double);
        double p50 = e[lit / 2], p90 = e[(size_t)(0.9 * (lit - 1))];
        h = p50 > 0 ? p90 / p50 : 0.0;
    }
    free(e);
    return h;
}

rd_status rd_cmp_extra_parse(const char *arg, char *buf, size_t bufn, rd_cmp_extra *e, char *err,
                             size_t errlen)
{
    if (strlen(arg) >= bufn) return fail(err, errlen, RD_ERR_ARG, "--add %s: too long", arg);
    snprintf(buf, bufn, "%s", arg);
    char *eq = strchr(buf, '=');
    if (!eq || eq == buf || !eq[1] || eq - buf >= 48)
        return fail(err, errlen, RD_ERR_ARG, "--add %s: expected LABEL=IMAGE.exr[@SECONDS] (a label of 1 to 47 characters)", arg);
    *eq = 0;
    e->label = buf;
    e->path = eq + 1;
    e->seconds = 0.0;
    char *at = strrchr(eq + 1, '@');
    if (at) {
        char *end;
        double s = strtod(at + 1, &end);
        if (end == at + 1 || *end || !(s > 0 && s < 1e9))
            return fail(err, errlen, RD_ERR_ARG, "--add %s: the time after @ must be a number of seconds > 0", arg);
        *at = 0;
        e->seconds = s;
    }
    if (!e->path[0]) return fail(err, errlen, RD_ERR_ARG, "--add %s: no image path", arg);
    for (const char *c = e->label; *c; c++)
        if (!(isalnum((unsigned char)*c) || *c == '-' || *c == '_' || *c == '.'))
            return fail(err, errlen, RD_ERR_ARG, "--add %s: the label may have letters, digits, '-', '_' and '.' only", arg);
    return RD_OK;
}

/* ---- Reading images that must match the scene --------------------------------------------- */

/* Read `path` (what: "reference", "--add image") and check it has the scene's size. */
static rd_status read_matching(const char *path, const char *what, int w, int h, rd_image *img,
                               char *err, size_t errlen)
{
    char msg[RD_ERRLEN];
    rd_status st = rd_image_read(path, img, msg, sizeof msg);
    if (st == RD_ERR_IO || st == RD_ERR_FORMAT || st == RD_ERR_INTERNAL) {
        /* OpenImageIO says "could not open" for missing and unreadable files alike. */
        snprintf(err, errlen, "%s: %s", what, msg);
        return st == RD_ERR_INTERNAL ? RD_ERR_FORMAT : st;
    }
    if (st) { snprintf(err, errlen, "%s", msg); return st; }
    if (img->channels != 3 && img->channels != 4) {
        snprintf(err, errlen, "%s: %s has %d channel%s, expected RGB or RGBA (a render of the scene)", what, path,
                 img->channels, img->channels == 1 ? "" : "s");
        rd_image_free_pixels(img);
        return RD_ERR_FORMAT;
    }
    if (img->w != w || img->h != h) {
        snprintf(err, errlen, "%s: %s is %dx%d, the scene renders %dx%d", what, path, img->w, img->h, w, h);
        rd_image_free_pixels(img);
        return RD_ERR_FORMAT;
    }
    for (size_t i = 0; i < (size_t)w * h * 3; i++)
        if (!isfinite(img->rgb[i])) {
            snprintf(err, errlen, "%s: %s has non-finite pixels (pixel %zu)", what, path, i / 3);
            rd_image_free_pixels(img);
            return RD_ERR_FORMAT;
        }
    return RD_OK;
}

/* ---- The reference: given, cached, or rendered --------------------------------------------- */

static uint64_t fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 0x100000001b3ULL;
    return h;
}
static uint64_t hash_d(uint64_t h, double v) { return fnv1a(h, &v, sizeof v); }
static uint64_t hash_v(uint64_t h, vec3 v) { return hash_d(hash_d(hash_d(h, v.x), v.y), v.z); }

/* The cache key of the rendered reference: the scene's bake key (its JSON after overrides
 * without camera and render-only settings, plus every grid's voxels: scene.c bake_key), the
 * camera and the path settings it left out, and the reference's own settings. */
static uint64_t reference_key(const rd_scene *s, int spp, double time_cap, uint64_t seed)
{
    uint64_t h = fnv1a(0xcbf29ce484222325ULL, "photonmarch reference v1", 24);
    h = fnv1a(h, &s->bake_key, sizeof s->bake_key);
    const rd_camera *c = &s->camera;
    int ints[6] = {(int)c->kind, c->width, c->height, s->settings.max_depth, s->settings.rr_depth, spp};
    h = fnv1a(h, ints, sizeof ints);
    h = hash_v(hash_v(hash_v(hash_v(h, c->pos), c->forward), c->right), c->up);
    h = hash_d(hash_d(hash_d(h, c->fov_deg), c->ortho_width), time_cap);
    h = fnv1a(h, &seed, sizeof seed);
    h = fnv1a(h, &s->settings.tracker, sizeof s->settings.tracker);
    h = fnv1a(h, &s->settings.transmittance, sizeof s->settings.transmittance);
    h = hash_d(hash_d(hash_d(h, s->settings.track_b), s->settings.track_m), s->settings.track_step);
    return h;
}

/* Try the cache: both images present, readable and of the right size, and the JSON beside
 * them naming the same key. Anything else is a miss (the reference is rendered again). */
static int reference_from_cache(rd_comparison *c, const char *base, uint64_t key)
{
    char path[1200], msg[RD_ERRLEN];
    snprintf(path, sizeof path, "%.1000s.json", base);
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    char text[512] = {0};
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = 0;
    char want[64];
    snprintf(want, sizeof want, "\"key\": \"%016llx\"", (unsigned long long)key);
    double spp = 0, secs = 0;
    const char *ps = strstr(text, "\"spp\": "), *pt = strstr(text, "\"seconds\": ");
    if (!strstr(text, want) || !ps || !pt) return 0;
    spp = atof(ps + 7);
    secs = atof(pt + 11);
    snprintf(path, sizeof path, "%.1000s.exr", base);
    if (read_matching(path, "cache", c->w, c->h, &c->ref, msg, sizeof msg)) return 0;
    snprintf(path, sizeof path, "%.1000s-stderr.exr", base);
    if (read_matching(path, "cache", c->w, c->h, &c->ref_se, msg, sizeof msg)) {
        rd_image_free_pixels(&c->ref);
        return 0;
    }
    c->sum.ref_spp = spp;
    c->sum.ref_seconds = secs;
    snprintf(c->sum.ref_source, sizeof c->sum.ref_source, "%.1000s.exr", base);
    return 1;
}

static void reference_progress(void *user, int done, int total, double seconds)
{
    rd_comparison *c = user;
    const rd_cmp_opts *o = &c->opts;
    rd_cmp_progress p = {"reference", 1, 1, done, seconds, o->ref_time > 0 ? o->ref_time : total, 0.0};
    double eta = done > 0 ? seconds * (total - done) / done : 0.0;
    if (o->ref_time > 0) eta = fmin(eta, fmax(0.0, o->ref_time - seconds));
    p.left_seconds = eta + c->planned_seconds;
    if (o->progress) o->progress(o->progress_user, &p);
}

/* Render the reference with delta (unbiased) and save it in the cache (a failed save is not an
 * error: the comparison goes on, and says so in ref_source). */
static rd_status reference_render(rd_comparison *c, const rd_scene *s, const char *base,
                                  uint64_t key, char *err, size_t errlen)
{
    const rd_cmp_opts *o = &c->opts;
    rd_render_opts ro = {.method = "delta", .spp = o->ref_spp, .time_limit = o->ref_time,
                         .seed = REF_SEED(o->seed), .threads = o->threads, .cancel = o->cancel,
                         .progress = reference_progress, .progress_user = c};
    reference_progress(c, 0, o->ref_spp, 0.0);
    rd_render_result res;
    rd_status st = rd_render(s, &ro, &res, err, errlen);
    if (st) return st;
    if (res.stats.cancelled || res.stats.spp < 1) {
        rd_render_result_free(&res);
        c->sum.cancelled = 1;
        return RD_OK;
    }
    c->ref = res.image;
    c->ref_se = res.stderr_img;
    res.image.rgb = res.stderr_img.rgb = NULL;
    c->sum.ref_spp = res.stats.spp_mean;
    c->sum.ref_seconds = res.stats.seconds;
    c->sum.ref_rendered = 1;
    rd_render_result_free(&res);
    snprintf(c->sum.ref_source, sizeof c->sum.ref_source, "rendered now (not cached)");
    if (!base) return RD_OK;
    char path[1200], msg[RD_ERRLEN], meta[256];
    snprintf(path, sizeof path, "%.1000s.exr", base);
    int n = snprintf(meta, sizeof meta, "{\"key\": \"%016llx\", \"method\": \"delta\", \"spp\": %.6g, \"seconds\": %.6g}\n",
                     (unsigned long long)key, c->sum.ref_spp, c->sum.ref_seconds);
    if (rd_make_parent_dirs(path, msg, sizeof msg) == RD_OK && rd_image_write_exr(path, &c->ref, msg, sizeof msg) == RD_OK) {
        snprintf(path, sizeof path, "%.1000s-stderr.exr", base);
        if (rd_image_write_exr(path, &c->ref_se, msg, sizeof msg) == RD_OK) {
            snprintf(path, sizeof path, "%.1000s.json", base);
            if (rd_write_atomic(path, meta, (size_t)n, msg, sizeof msg) == RD_OK)
                snprintf(c->sum.ref_source, sizeof c->sum.ref_source, "%.1000s.exr", base);
        }
    }
    return RD_OK;
}

/* The reference given with --reference: REF.exr, and REF-stderr.exr beside it if present. */
static rd_status reference_given(rd_comparison *c, char *err, size_t errlen)
{
    const char *path = c->opts.reference;
    rd_status st = read_matching(path, "reference", c->w, c->h, &c->ref, err, errlen);
    if (st) return st;
    snprintf(c->sum.ref_source, sizeof c->sum.ref_source, "%.1000s", path);
    size_t n = strlen(path);
    if (n > 4 && !strcmp(path + n - 4, ".exr")) {
        char se[1200], msg[RD_ERRLEN];
        snprintf(se, sizeof se, "%.*s-stderr.exr", (int)(n - 4), path);
        FILE *f = fopen(se, "rb");
        if (f) {
            fclose(f);
            st = read_matching(se, "reference standard error", c->w, c->h, &c->ref_se, msg, sizeof msg);
            if (st) { snprintf(err, errlen, "%s", msg); return st; }
        }
    }
    return RD_OK;
}

static rd_status reference_get(rd_comparison *c, const rd_scene *s, char *err, size_t errlen)
{
    const rd_cmp_opts *o = &c->opts;
    if (o->reference) return reference_given(c, err, errlen);
    uint64_t key = reference_key(s, o->ref_spp, o->ref_time, REF_SEED(o->seed));
    char base[1200];
    if (o->cache_dir) {
        snprintf(base, sizeof base, "%.900s/reference-%016llx", o->cache_dir, (unsigned long long)key);
        if (reference_from_cache(c, base, key)) {
            c->sum.ref_rendered = 2;
            return RD_OK;
        }
    }
    return reference_render(c, s, o->cache_dir ? base : NULL, key, err, errlen);
}

/* Mean of stderr^2 over every value: the variance the reference adds to every measured MSE. */
static double image_mean_sq(const rd_image *im)
{
    size_t n = (size_t)im->w * im->h * 3;
    double s = 0.0;
    for (size_t i = 0; i < n; i++) s += (double)im->rgb[i] * im->rgb[i];
    return n ? s / n : 0.0;
}

/* ---- The runs ------------------------------------------------------------------------------ */

/* One bake per distinct set of needs, shared by the methods with those needs; its wall time
 * is charged to every run of each of them (docs/compare.md). */
static rd_status bake_for(rd_comparison *c, const rd_scene *s, int mi, char *err, size_t errlen)
{
    cmp_method *m = &c->m[mi];
    unsigned needs = rd_method_needs_for(m->name, s);
    if (!needs) return RD_OK;
    for (int j = 0; j < mi; j++)
        if (c->m[j].baked && c->m[j].needs == needs) {
            m->baked = c->m[j].baked;
            m->bake_seconds = c->m[j].bake_seconds;
            m->needs = needs;
            return RD_OK;
        }
    rd_bake_opts bo = {.seed = -1, .threads = c->opts.threads};
    rd_bake_opts_for(&bo, needs);
    double t0 = now_seconds();
    rd_status st = rd_bake(s, &bo, &m->baked, err, errlen);
    if (st) return st;
    m->bake_seconds = now_seconds() - t0;
    m->needs = needs;
    m->owns_baked = 1;
    return RD_OK;
}

typedef struct {
    rd_comparison *c;
    int mi, run;
    double started;
} run_ctx;

static void run_progress(void *user, int done, int total, double seconds)
{
    run_ctx *r = user;
    rd_comparison *c = r->c;
    const rd_cmp_opts *o = &c->opts;
    cmp_method *m = &c->m[r->mi];
    double left_run;
    if (!o->equal_spp) left_run = fmax(0.0, o->budget - seconds);
    else left_run = done > 0 ? (seconds - m->bake_seconds) * (total - done) / done : 0.0;
    rd_cmp_progress p = {m->name, r->run + 1, o->runs, done, seconds, o->budget, 0.0};
    p.left_seconds = left_run + c->planned_seconds;
    if (o->progress) o->progress(o->progress_user, &p);
}

/* Seconds the runs not yet started will take (equal time: exact; equal spp: the mean of the
 * runs finished so far, else unknown = 0). */
static double planned_after(const rd_comparison *c, int mi, int run)
{
    const rd_cmp_opts *o = &c->opts;
    int left = (c->n_methods - mi - 1) * o->runs + (o->runs - run - 1);
    if (!o->equal_spp) return left * o->budget;
    double sum = 0.0;
    int n = 0;
    for (int j = 0; j <= mi; j++)
        for (int k = 0; k < c->m[j].done; k++) sum += c->m[j].stats[k].seconds, n++;
    return n ? left * sum / n : 0.0;
}

static rd_status run_one(rd_comparison *c, const rd_scene *s, int mi, int run, char *err, size_t errlen)
{
    const rd_cmp_opts *o = &c->opts;
    cmp_method *m = &c->m[mi];
    run_ctx rc = {c, mi, run, now_seconds()};
    rd_render_opts ro = {.method = m->name, .seed = RUN_SEED(o->seed, run), .threads = o->threads,
                         .cancel = o->cancel, .progress = run_progress, .progress_user = &rc,
                         .baked = m->baked, .baked_seconds = m->bake_seconds, .reference = &c->ref};
    /* Equal time: the budget is the run's wall time, its share of the bake included; equal
     * spp: every method renders `budget` samples per pixel. */
    ro.spp = o->equal_spp ? (int)o->budget : 1 << 24;
    ro.time_limit = o->equal_spp ? 0.0 : o->budget;
    c->planned_seconds = planned_after(c, mi, run);
    run_progress(&rc, 0, ro.spp, m->bake_seconds);
    rd_render_result res;
    rd_status st = rd_render(s, &ro, &res, err, errlen);
    if (st) return st;
    if (res.stats.cancelled) {
        rd_render_result_free(&res); /* a run cut short is not one of the K: left out */
        c->sum.cancelled = 1;
        return RD_OK;
    }
    if (res.stats.spp < 1) {
        rd_render_result_free(&res);
        snprintf(err, errlen, "--budget %g: %s had no time to sample every pixel once (its bake took %.2f s; give it more)",
                 o->budget, m->name, m->bake_seconds);
        return RD_ERR_ARG;
    }
    int k = m->done++;
    m->img[k] = res.image;
    m->se[k] = res.stderr_img;
    m->stats[k] = res.stats;
    m->curve[k] = res.curve;
    m->n_curve[k] = res.n_curve;
    return RD_OK;
}

/* ---- Rows ------------------------------------------------------------------------------- */

static void row_nan(rd_cmp_row *r)
{
    double nan = NAN;
    r->seconds = r->bake_seconds = r->spp = nan;
    r->split.bias2 = r->split.variance = r->split.bias2_se = nan;
    r->efficiency = r->ttuv = nan;
    r->collisions_pp = r->lookups_pp = r->shadow_rays_pp = nan;
}

static void row_method(rd_comparison *c, const cmp_method *m, rd_cmp_row *r)
{
    size_t np = (size_t)c->w * c->h;
    snprintf(r->label, sizeof r->label, "%s", m->name);
    r->runs = m->done;
    rd_cmp_errors sum = {0};
    double secs = 0, spp = 0, col = 0, look = 0, shadow = 0;
    for (int k = 0; k < m->done; k++) {
        rd_cmp_errors e;
        rd_cmp_errors_of(&m->img[k], &c->ref, &e, NULL, 0);
        sum.mse += e.mse, sum.relmse += e.relmse, sum.mare += e.mare;
        const rd_render_stats *st = &m->stats[k];
        secs += st->seconds, spp += st->spp_mean;
        col += (double)st->collisions / np, look += (double)st->lookups / np, shadow += (double)st->shadow_rays / np;
    }
    double K = m->done;
    r->err = (rd_cmp_errors){sum.mse / K, sqrt(sum.mse / K), sum.relmse / K, sum.mare / K};
    r->seconds = secs / K, r->spp = spp / K, r->bake_seconds = m->bake_seconds;
    r->collisions_pp = col / K, r->lookups_pp = look / K, r->shadow_rays_pp = shadow / K;
    const rd_image *rse = c->ref_se.rgb ? &c->ref_se : NULL;
    if (m->done >= 2) {
        rd_cmp_split_of(m->img, m->done, &c->ref, rse, &r->split, NULL, 0);
        r->split_from_runs = 1;
    } else {
        /* One run: its variance from its own stderr image (stderr^2 = variance of the mean). */
        r->split.variance = image_mean_sq(&m->se[0]);
        r->split.bias2 = r->err.mse - r->split.variance - (rse ? c->sum.ref_var : 0.0);
        r->split.bias2_se = NAN;
    }
    r->efficiency = 1.0 / (r->err.mse * r->seconds); /* 1 / (MSE x time) */
    r->ttuv = r->seconds * r->err.rmse;              /* seed 002: TTUV = time x RMSE */
    r->homogeneity = rd_cmp_homogeneity(&m->img[0], &c->ref);
}

static void row_extra(rd_comparison *c, int i, rd_cmp_row *r)
{
    const rd_cmp_extra *e = &c->opts.extras[i];
    snprintf(r->label, sizeof r->label, "%s", e->label);
    r->is_extra = 1;
    r->runs = 1;
    rd_cmp_errors_of(&c->extra_img[i], &c->ref, &r->err, NULL, 0);
    if (e->seconds > 0) {
        r->seconds = e->seconds;
        r->efficiency = 1.0 / (r->err.mse * r->seconds);
        r->ttuv = r->seconds * r->err.rmse;
    }
    r->homogeneity = rd_cmp_homogeneity(&c->extra_img[i], &c->ref);
}

static void make_rows(rd_comparison *c)
{
    int n = 0;
    double min_mse = INFINITY;
    for (int i = 0; i < c->n_methods; i++) {
        if (!c->m[i].done) continue;
        rd_cmp_row *r = &c->rows[n];
        row_nan(r);
        row_method(c, &c->m[i], r);
        c->row_img[n++] = &c->m[i].img[0];
        min_mse = fmin(min_mse, r->err.mse);
    }
    for (int i = 0; i < c->opts.n_extras; i++) {
        rd_cmp_row *r = &c->rows[n];
        row_nan(r);
        row_extra(c, i, r);
        c->row_img[n++] = &c->extra_img[i];
    }
    c->sum.rows = c->rows;
    c->sum.n_rows = n;
    /* The reference's variance adds to every measured MSE: above a quarter of the best
     * method's MSE it hides the differences between methods (docs/compare.md). */
    c->sum.ref_too_noisy = isfinite(c->sum.ref_var) && n > 0 && c->sum.ref_var > 0.25 * min_mse;
}

/* ---- The comparison ------------------------------------------------------------------------ */

static rd_status check_opts(const rd_cmp_opts *o, char *err, size_t errlen)
{
    if (o->n_methods < 1 && o->n_extras < 1) return fail(err, errlen, RD_ERR_ARG, "%s: no methods to compare", "--methods");
    if (o->n_methods > RD_CMP_MAX_METHODS) return fail(err, errlen, RD_ERR_ARG, "%s: at most 8 methods", "--methods");
    if (o->n_extras > RD_CMP_MAX_METHODS) return fail(err, errlen, RD_ERR_ARG, "%s: at most 8 images", "--add");
    for (int i = 0; i < o->n_methods; i++) {
        int found = 0;
        for (int j = 0; j < rd_method_count(); j++) found |= !strcmp(o->methods[i], rd_method_name(j));
        if (!found) return fail(err, errlen, RD_ERR_ARG, "--methods: unknown method \"%s\"", o->methods[i]);
        for (int j = 0; j < i; j++)
            if (!strcmp(o->methods[i], o->methods[j])) return fail(err, errlen, RD_ERR_ARG, "--methods: \"%s\" given twice", o->methods[i]);
    }
    if (o->runs < 1 || o->runs > 64) return fail(err, errlen, RD_ERR_ARG, "%s: runs must be in [1, 64]", "--runs");
    if (!(o->budget > 0) || (o->equal_spp && (o->budget < 1 || o->budget > (1 << 24))))
        return fail(err, errlen, RD_ERR_ARG, "%s: must be > 0 (seconds), or in [1, 16777216] samples with --equal spp", "--budget");
    if (!o->reference && o->ref_spp < 1) return fail(err, errlen, RD_ERR_ARG, "%s: must be >= 1", "--ref-spp");
    for (int i = 0; i < o->n_extras; i++) {
        /* Labels name the report's files: they must differ from each other and the methods. */
        int clash = !strcmp(o->extras[i].label, "reference");
        for (int j = 0; j < o->n_methods; j++) clash |= !strcmp(o->extras[i].label, o->methods[j]);
        for (int j = 0; j < i; j++) clash |= !strcmp(o->extras[i].label, o->extras[j].label);
        if (clash) return fail(err, errlen, RD_ERR_ARG, "--add %s: the label is taken (a method, another image or \"reference\")", o->extras[i].label);
    }
    return RD_OK;
}

static rd_status alloc_methods(rd_comparison *c)
{
    int K = c->opts.runs, n = c->n_methods + c->opts.n_extras;
    c->m = calloc((size_t)c->n_methods + 1, sizeof *c->m);
    c->rows = calloc((size_t)n + 1, sizeof *c->rows);
    c->row_img = calloc((size_t)n + 1, sizeof *c->row_img);
    c->extra_img = calloc((size_t)c->opts.n_extras + 1, sizeof *c->extra_img);
    if (!c->m || !c->rows || !c->row_img || !c->extra_img) return RD_ERR_NOMEM;
    for (int i = 0; i < c->n_methods; i++) {
        cmp_method *m = &c->m[i];
        m->name = c->opts.methods[i];
        m->img = calloc(K, sizeof *m->img);
        m->se = calloc(K, sizeof *m->se);
        m->stats = calloc(K, sizeof *m->stats);
        m->curve = calloc(K, sizeof *m->curve);
        m->n_curve = calloc(K, sizeof *m->n_curve);
        if (!m->img || !m->se || !m->stats || !m->curve || !m->n_curve) return RD_ERR_NOMEM;
    }
    return RD_OK;
}

static rd_status load_extras(rd_comparison *c, char *err, size_t errlen)
{
    for (int i = 0; i < c->opts.n_extras; i++) {
        char what[80];
        snprintf(what, sizeof what, "--add %s", c->opts.extras[i].label);
        rd_status st = read_matching(c->opts.extras[i].path, what, c->w, c->h, &c->extra_img[i], err, errlen);
        if (st) return st;
    }
    return RD_OK;
}

static rd_status run_all(rd_comparison *c, const rd_scene *s, char *err, size_t errlen)
{
    for (int mi = 0; mi < c->n_methods && !c->sum.cancelled; mi++) {
        rd_status st = bake_for(c, s, mi, err, errlen);
        if (st) return st;
        for (int k = 0; k < c->opts.runs && !c->sum.cancelled; k++) {
            if (c->opts.cancel && *c->opts.cancel) { c->sum.cancelled = 1; break; }
            if ((st = run_one(c, s, mi, k, err, errlen)) != RD_OK) return st;
        }
    }
    return RD_OK;
}

rd_status rd_compare_run(const rd_scene *scene, const rd_cmp_opts *opts, rd_comparison **out,
                         char *err, size_t errlen)
{
    char dummy[8];
    if (!err) { err = dummy; errlen = sizeof dummy; }
    *out = NULL;
    rd_status st = check_opts(opts, err, errlen);
    if (st) return st;
    rd_comparison *c = calloc(1, sizeof *c);
    if (!c) return fail(err, errlen, RD_ERR_NOMEM, "%s: out of memory", "compare");
    c->opts = *opts;
    c->n_methods = opts->n_methods;
    c->w = rd_scene_width(scene);
    c->h = rd_scene_height(scene);
    c->exposure = rd_scene_exposure(scene);
    c->sum.ref_var = NAN;
    if ((st = alloc_methods(c)) != RD_OK) {
        fail(err, errlen, st, "%s: out of memory", "compare");
        goto bad;
    }
    /* Every input is checked before anything long runs. */
    if ((st = load_extras(c, err, errlen)) != RD_OK) goto bad;
    c->planned_seconds = opts->equal_spp ? 0.0 : opts->budget * opts->runs * opts->n_methods;
    if ((st = reference_get(c, scene, err, errlen)) != RD_OK) goto bad;
    if (!c->sum.cancelled) {
        if (c->ref_se.rgb) c->sum.ref_var = image_mean_sq(&c->ref_se);
        if ((st = run_all(c, scene, err, errlen)) != RD_OK) goto bad;
        make_rows(c);
    }
    *out = c;
    return RD_OK;
bad:
    rd_comparison_free(c);
    return st;
}

const rd_cmp_summary *rd_comparison_summary(const rd_comparison *c)
{
    return &c->sum;
}

void rd_comparison_free(rd_comparison *c)
{
    if (!c) return;
    for (int i = 0; c->m && i < c->n_methods; i++) {
        cmp_method *m = &c->m[i];
        for (int k = 0; k < m->done; k++) {
            rd_image_free_pixels(&m->img[k]);
            rd_image_free_pixels(&m->se[k]);
            free(m->curve[k]);
        }
        free(m->img), free(m->se), free(m->stats), free(m->curve), free(m->n_curve);
        if (m->owns_baked) rd_baked_free(m->baked);
    }
    for (int i = 0; c->extra_img && i < c->opts.n_extras; i++) rd_image_free_pixels(&c->extra_img[i]);
    rd_image_free_pixels(&c->ref);
    rd_image_free_pixels(&c->ref_se);
    free(c->m), free(c->rows), free(c->row_img), free(c->extra_img);
    free(c);
}

/* ==== The report folder (docs/compare.md) ================================================== */

/* sRGB 8-bit colour -> the linear value rd_image_write_png (exposure 0) turns back into it. */
static float srgb_to_linear(double c)
{
    return (float)(c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
}

/* The viridis colour map (van der Walt & Smith, matplotlib), 9 stops, t in [0, 1]. */
static void viridis(double t, float rgb[3])
{
    static const unsigned char stop[9][3] = {{68, 1, 84},    {71, 44, 122},  {59, 81, 139},
                                             {44, 113, 142}, {33, 144, 141}, {39, 173, 129},
                                             {92, 200, 99},  {170, 220, 50}, {253, 231, 37}};
    t = fmin(fmax(t, 0.0), 1.0) * 8.0;
    int i = (int)fmin(t, 7.0);
    double f = t - i;
    for (int c = 0; c < 3; c++)
        rgb[c] = srgb_to_linear(((1 - f) * stop[i][c] + f * stop[i + 1][c]) / 255.0);
}

/* Per-pixel relative error of luminance, the quantity of the error maps and of homogeneity. */
static double pixel_rel_error(const rd_image *x, const rd_image *r, size_t p)
{
    double lr = luminance(r->rgb + 3 * p);
    return fabs(luminance(x->rgb + 3 * p) - lr) / (lr + RD_CMP_EPS);
}

/* The error maps' common scale: the 99th percentile of the relative error over every row, so
 * the maps can be compared with each other and a few fireflies do not set the scale. */
static double error_scale(const rd_comparison *c)
{
    size_t np = (size_t)c->w * c->h, n = np * (size_t)c->sum.n_rows;
    double *e = malloc((n + 1) * sizeof *e);
    if (!e || !n) { free(e); return 1.0; }
    for (int i = 0; i < c->sum.n_rows; i++)
        for (size_t p = 0; p < np; p++) e[i * np + p] = pixel_rel_error(c->row_img[i], &c->ref, p);
    qsort(e, n, sizeof *e, cmp_double);
    double s = e[(size_t)(0.99 * (n - 1))];
    free(e);
    return s > 0 ? s : 1.0;
}

/* The worst region: the square window (a quarter of the shorter side, at least 8 px) with the
 * largest squared error summed over every row, found with a summed-area table. */
typedef struct { int x, y, s; } crop_box;
static crop_box worst_region(const rd_comparison *c)
{
    int w = c->w, h = c->h, shorter = w < h ? w : h, s = shorter / 4;
    if (s < 8) s = shorter < 8 ? shorter : 8;
    crop_box best = {0, 0, s};
    double *sat = calloc((size_t)(w + 1) * (h + 1), sizeof *sat);
    if (!sat) return best;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double e = 0.0;
            size_t p = (size_t)y * w + x;
            for (int i = 0; i < c->sum.n_rows; i++)
                for (int ch = 0; ch < 3; ch++) {
                    double d = c->row_img[i]->rgb[3 * p + ch] - c->ref.rgb[3 * p + ch];
                    e += d * d;
                }
            sat[(size_t)(y + 1) * (w + 1) + x + 1] = e + sat[(size_t)y * (w + 1) + x + 1] +
                                                      sat[(size_t)(y + 1) * (w + 1) + x] - sat[(size_t)y * (w + 1) + x];
        }
    double top = -1.0;
    for (int y = 0; y + s <= h; y++)
        for (int x = 0; x + s <= w; x++) {
            double v = sat[(size_t)(y + s) * (w + 1) + x + s] - sat[(size_t)y * (w + 1) + x + s] -
                       sat[(size_t)(y + s) * (w + 1) + x] + sat[(size_t)y * (w + 1) + x];
            if (v > top) top = v, best.x = x, best.y = y;
        }
    free(sat);
    return best;
}

static rd_status write_png_at(const char *dir, const char *name, const rd_image *im, double exposure,
                              char *err, size_t errlen)
{
    char path[1200];
    snprintf(path, sizeof path, "%.1000s/%s", dir, name);
    return rd_image_write_png(path, im, exposure, err, errlen);
}

static rd_status write_exr_at(const char *dir, const char *name, const rd_image *im, char *err,
                              size_t errlen)
{
    char path[1200];
    snprintf(path, sizeof path, "%.1000s/%s", dir, name);
    return rd_image_write_exr(path, im, err, errlen);
}

/* The false-colour error map of x: viridis(relative error / scale). */
static rd_status write_error_map(const rd_comparison *c, const rd_image *x, const char *dir,
                                 const char *name, double scale, char *err, size_t errlen)
{
    size_t np = (size_t)c->w * c->h;
    rd_image m = {c->w, c->h, malloc(np * 3 * sizeof(float)), 0};
    if (!m.rgb) return fail(err, errlen, RD_ERR_NOMEM, "%s: out of memory", name);
    for (size_t p = 0; p < np; p++) viridis(pixel_rel_error(x, &c->ref, p) / scale, m.rgb + 3 * p);
    rd_status st = write_png_at(dir, name, &m, 0.0, err, errlen);
    free(m.rgb);
    return st;
}

static rd_status write_colour_bar(const char *dir, char *err, size_t errlen)
{
    rd_image m = {256, 16, malloc(256 * 16 * 3 * sizeof(float)), 0};
    if (!m.rgb) return fail(err, errlen, RD_ERR_NOMEM, "%s: out of memory", "colorbar.png");
    for (int y = 0; y < 16; y++)
        for (int x = 0; x < 256; x++) viridis(x / 255.0, m.rgb + 3 * (y * 256 + x));
    rd_status st = write_png_at(dir, "colorbar.png", &m, 0.0, err, errlen);
    free(m.rgb);
    return st;
}

/* The crop box of x, enlarged by nearest neighbour to about 256 px. */
static rd_status write_crop(const rd_comparison *c, const rd_image *x, crop_box b, const char *dir,
                            const char *name, char *err, size_t errlen)
{
    int z = b.s >= 256 ? 1 : 256 / b.s, n = b.s * z;
    rd_image m = {n, n, malloc((size_t)n * n * 3 * sizeof(float)), 0};
    if (!m.rgb) return fail(err, errlen, RD_ERR_NOMEM, "%s: out of memory", name);
    for (int y = 0; y < n; y++)
        for (int xx = 0; xx < n; xx++) {
            size_t src = (size_t)(b.y + y / z) * c->w + b.x + xx / z;
            memcpy(m.rgb + 3 * ((size_t)y * n + xx), x->rgb + 3 * src, 3 * sizeof(float));
        }
    rd_status st = write_png_at(dir, name, &m, c->exposure, err, errlen);
    free(m.rgb);
    return st;
}

/* Every image of the report: per row LABEL.exr/.png, LABEL-error.png, LABEL-crop.png; the
 * reference's reference.exr/.png/-crop.png (and reference-stderr.exr), colorbar.png. */
static rd_status write_images(const rd_comparison *c, const char *dir, double scale, crop_box b,
                              char *err, size_t errlen)
{
    rd_status st;
    char name[128];
    if ((st = write_exr_at(dir, "reference.exr", &c->ref, err, errlen)) ||
        (st = write_png_at(dir, "reference.png", &c->ref, c->exposure, err, errlen)) ||
        (st = write_crop(c, &c->ref, b, dir, "reference-crop.png", err, errlen)) ||
        (st = write_colour_bar(dir, err, errlen)))
        return st;
    if (c->ref_se.rgb && (st = write_exr_at(dir, "reference-stderr.exr", &c->ref_se, err, errlen))) return st;
    for (int i = 0; i < c->sum.n_rows; i++) {
        const char *l = c->rows[i].label;
        const rd_image *x = c->row_img[i];
        snprintf(name, sizeof name, "%s.exr", l);
        if ((st = write_exr_at(dir, name, x, err, errlen))) return st;
        snprintf(name, sizeof name, "%s.png", l);
        if ((st = write_png_at(dir, name, x, c->exposure, err, errlen))) return st;
        snprintf(name, sizeof name, "%s-error.png", l);
        if ((st = write_error_map(c, x, dir, name, scale, err, errlen))) return st;
        snprintf(name, sizeof name, "%s-crop.png", l);
        if ((st = write_crop(c, x, b, dir, name, err, errlen))) return st;
    }
    return RD_OK;
}

/* ---- Convergence plot: gnuplot ------------------------------------------------------------ */

static rd_status write_text_at(const char *dir, const char *name, const char *text, char *err,
                               size_t errlen)
{
    char path[1200];
    snprintf(path, sizeof path, "%.1000s/%s", dir, name);
    return rd_write_atomic(path, text, strlen(text), err, errlen);
}

/* DIR/NAME from a text buffer (rd_text_write: atomic, frees the buffer). */
static rd_status write_buffer_at(const char *dir, const char *name, rd_text *b, char *err,
                                 size_t errlen)
{
    char path[1200];
    snprintf(path, sizeof path, "%.1000s/%s", dir, name);
    return rd_text_write(b, path, err, errlen);
}

/* curve-LABEL.dat: "seconds rmse" after every pass, one block per run (a blank line between
 * runs breaks the line in gnuplot); an added image with a time is one point. */
static rd_status write_curves(const rd_comparison *c, const char *dir, char *err, size_t errlen)
{
    for (int i = 0; i < c->sum.n_rows; i++) {
        const rd_cmp_row *r = &c->rows[i];
        rd_text b = {0};
        rd_text_printf(&b, "# seconds (bake included)  RMSE against the reference\n");
        if (r->is_extra) {
            if (r->seconds > 0) rd_text_printf(&b, "%.6g %.6g\n", r->seconds, r->err.rmse);
        } else {
            const cmp_method *m = NULL;
            for (int j = 0; j < c->n_methods; j++)
                if (!strcmp(c->m[j].name, r->label)) m = &c->m[j];
            for (int k = 0; m && k < m->done; k++) {
                for (int p = 0; p < m->n_curve[k]; p++)
                    if (m->curve[k][p].rmse > 0) rd_text_printf(&b, "%.6g %.6g\n", m->curve[k][p].seconds, m->curve[k][p].rmse);
                rd_text_printf(&b, "\n");
            }
        }
        char name[128];
        snprintf(name, sizeof name, "curve-%s.dat", r->label);
        rd_status st = write_buffer_at(dir, name, &b, err, errlen);
        if (st) return st;
    }
    return RD_OK;
}

/* Run gnuplot on convergence.gp in the report folder (no shell: fork, chdir, exec). */
static rd_status run_gnuplot(const char *dir, char *err, size_t errlen)
{
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) return fail(err, errlen, RD_ERR_OUTPUT, "%s/convergence.svg: cannot start gnuplot", dir);
    if (pid == 0) {
        int nul = open("/dev/null", O_WRONLY);
        if (nul >= 0) dup2(nul, 1);
        if (chdir(dir) == 0) execlp("gnuplot", "gnuplot", "convergence.gp", (char *)NULL);
        _exit(127);
    }
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {}
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
        return fail(err, errlen, RD_ERR_OUTPUT,
                    "%s/convergence.svg: gnuplot failed (exit 127: not installed; run scripts/install-deps.sh)", dir);
    return RD_OK;
}

static rd_status write_plot(const rd_comparison *c, const char *dir, char *err, size_t errlen)
{
    rd_status st = write_curves(c, dir, err, errlen);
    if (st) return st;
    rd_text b = {0};
    rd_text_printf(&b, "# RMSE against time, log-log (photonmarch compare; docs/compare.md)\n"
                  "set terminal svg size 720,440 dynamic font 'sans,12' background '#ffffff'\n"
                  "set output 'convergence.svg'\nset logscale xy\nset grid\nset key outside right\n"
                  "set xlabel 'time (s, bake included)'\nset ylabel 'RMSE'\n"
                  "set title 'RMSE against the reference after every pass (each run one line)'\nplot ");
    int plotted = 0;
    for (int i = 0; i < c->sum.n_rows; i++) {
        const rd_cmp_row *r = &c->rows[i];
        if (r->is_extra && !(r->seconds > 0)) continue;
        rd_text_printf(&b, "%s'curve-%s.dat' using 1:2 with %s lw 2 pt 7 title '%s'", plotted ? ", \\\n     " : "",
                  r->label, r->is_extra ? "points ps 1.5" : "linespoints", r->label);
        plotted++;
    }
    if (!plotted) rd_text_printf(&b, "NaN notitle");
    rd_text_printf(&b, "\n");
    st = write_buffer_at(dir, "convergence.gp", &b, err, errlen);
    return st ? st : run_gnuplot(dir, err, errlen);
}

/* ---- metrics.json (schema: docs/compare.md) ----------------------------------------------- */

/* A number, or null when it is NaN or infinite (JSON has no NaN). */
static void json_num(cJSON *o, const char *key, double v)
{
    if (isfinite(v)) cJSON_AddNumberToObject(o, key, v);
    else cJSON_AddNullToObject(o, key);
}

static const cmp_method *method_of(const rd_comparison *c, const char *label)
{
    for (int j = 0; j < c->n_methods; j++)
        if (!strcmp(c->m[j].name, label)) return &c->m[j];
    return NULL;
}

static cJSON *json_row(const rd_comparison *c, const rd_cmp_row *r)
{
    cJSON *o = cJSON_CreateObject();
    char name[128];
    cJSON_AddStringToObject(o, "label", r->label);
    cJSON_AddStringToObject(o, "kind", r->is_extra ? "added" : "method");
    cJSON_AddNumberToObject(o, "runs", r->runs);
    json_num(o, "seconds", r->seconds);
    json_num(o, "bake_seconds", r->bake_seconds);
    json_num(o, "spp", r->spp);
    json_num(o, "mse", r->err.mse);
    json_num(o, "rmse", r->err.rmse);
    json_num(o, "relmse", r->err.relmse);
    json_num(o, "mare", r->err.mare);
    json_num(o, "bias2", r->split.bias2);
    json_num(o, "bias2_se", r->split.bias2_se);
    json_num(o, "variance", r->split.variance);
    if (r->is_extra) cJSON_AddNullToObject(o, "variance_from");
    else cJSON_AddStringToObject(o, "variance_from", r->split_from_runs ? "runs" : "stderr image");
    json_num(o, "efficiency", r->efficiency);
    json_num(o, "ttuv", r->ttuv);
    cJSON *pp = cJSON_AddObjectToObject(o, "per_pixel");
    json_num(pp, "samples", r->spp);
    json_num(pp, "collisions", r->collisions_pp);
    json_num(pp, "lookups", r->lookups_pp);
    json_num(pp, "shadow_rays", r->shadow_rays_pp);
    json_num(o, "homogeneity", r->homogeneity);
    cJSON *im = cJSON_AddObjectToObject(o, "images");
    static const char *const kinds[][2] = {{"exr", "%s.exr"}, {"png", "%s.png"}, {"error", "%s-error.png"}, {"crop", "%s-crop.png"}};
    for (int k = 0; k < 4; k++) {
        snprintf(name, sizeof name, kinds[k][1], r->label);
        cJSON_AddStringToObject(im, kinds[k][0], name);
    }
    cJSON *curve = cJSON_AddArrayToObject(o, "curve");
    const cmp_method *m = r->is_extra ? NULL : method_of(c, r->label);
    for (int k = 0; m && k < m->done; k++) {
        cJSON *run = cJSON_CreateArray();
        for (int p = 0; p < m->n_curve[k]; p++) {
            const double v[3] = {m->curve[k][p].seconds, m->curve[k][p].spp_mean, m->curve[k][p].rmse};
            cJSON_AddItemToArray(run, cJSON_CreateDoubleArray(v, 3));
        }
        cJSON_AddItemToArray(curve, run);
    }
    return o;
}

static rd_status write_json(const rd_comparison *c, const rd_scene *s, const char *dir, double scale,
                            crop_box b, char *err, size_t errlen)
{
    const rd_cmp_opts *o = &c->opts;
    const rd_cmp_summary *S = &c->sum;
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "schema", "photonmarch-compare/1");
    cJSON_AddStringToObject(j, "scene", s->path);
    cJSON_AddNumberToObject(j, "width", c->w);
    cJSON_AddNumberToObject(j, "height", c->h);
    cJSON_AddStringToObject(j, "equal", o->equal_spp ? "spp" : "time");
    cJSON_AddNumberToObject(j, "budget", o->budget);
    cJSON_AddNumberToObject(j, "runs", o->runs);
    cJSON_AddNumberToObject(j, "seed", (double)o->seed);
    cJSON_AddBoolToObject(j, "cancelled", S->cancelled);
    cJSON *ref = cJSON_AddObjectToObject(j, "reference");
    cJSON_AddStringToObject(ref, "source", S->ref_source);
    cJSON_AddStringToObject(ref, "origin", S->ref_rendered == 1 ? "rendered" : S->ref_rendered == 2 ? "cache" : "given");
    json_num(ref, "spp", S->ref_rendered ? S->ref_spp : NAN);
    json_num(ref, "seconds", S->ref_rendered ? S->ref_seconds : NAN);
    json_num(ref, "variance", S->ref_var);
    cJSON_AddBoolToObject(ref, "too_noisy", S->ref_too_noisy);
    cJSON *em = cJSON_AddObjectToObject(j, "error_map");
    cJSON_AddStringToObject(em, "quantity", "|L(x) - L(r)| / (L(r) + 0.01), L = luminance");
    cJSON_AddNumberToObject(em, "scale_max", scale);
    cJSON *cr = cJSON_AddObjectToObject(j, "crop");
    cJSON_AddNumberToObject(cr, "x", b.x);
    cJSON_AddNumberToObject(cr, "y", b.y);
    cJSON_AddNumberToObject(cr, "size", b.s);
    cJSON *rows = cJSON_AddArrayToObject(j, "methods");
    for (int i = 0; i < S->n_rows; i++) cJSON_AddItemToArray(rows, json_row(c, &c->rows[i]));
    char *text = cJSON_Print(j);
    cJSON_Delete(j);
    if (!text) return fail(err, errlen, RD_ERR_NOMEM, "%s: out of memory", "metrics.json");
    rd_status st = write_text_at(dir, "metrics.json", text, err, errlen);
    cJSON_free(text);
    return st;
}

/* ---- index.html: one self-contained page (inline CSS and JS, images by relative path) ---- */

static void sb_escape(rd_text *b, const char *s)
{
    for (; *s; s++) {
        switch (*s) {
        case '&': rd_text_printf(b, "&amp;"); break;
        case '<': rd_text_printf(b, "&lt;"); break;
        case '>': rd_text_printf(b, "&gt;"); break;
        case '"': rd_text_printf(b, "&quot;"); break;
        default: rd_text_printf(b, "%c", *s);
        }
    }
}

/* A table cell with a number in %.3g, or "n/a". */
static void sb_cell(rd_text *b, double v)
{
    if (isfinite(v)) rd_text_printf(b, "<td>%.3g</td>", v);
    else rd_text_printf(b, "<td class=na>n/a</td>");
}

static const char *page_css =
    "body{font:14px/1.4 system-ui,sans-serif;margin:1.5em auto;max-width:1200px;padding:0 1em;color:#222}\n"
    "h1{font-size:1.4em}h2{font-size:1.1em;margin-top:1.6em;border-bottom:1px solid #ddd}\n"
    ".warn{background:#fff3cd;border:1px solid #e0c060;padding:.5em .8em}\n"
    ".grid{display:flex;flex-wrap:wrap;gap:12px}.grid figure{margin:0}\n"
    ".grid img{display:block;max-width:360px;image-rendering:pixelated;min-width:192px}\n"
    "figcaption{font-size:12px;color:#444}\n"
    "#view{display:block;width:min(100%,720px);image-rendering:pixelated;cursor:pointer;border:1px solid #888}\n"
    "#viewer button{margin:0 .3em .5em 0;padding:.3em .7em}#viewer button.on{background:#333;color:#fff}\n"
    "table{border-collapse:collapse;font-variant-numeric:tabular-nums}\n"
    "td,th{border:1px solid #ccc;padding:.25em .5em;text-align:right}th{background:#f4f4f4}\n"
    "td:first-child{text-align:left}.na{color:#999}.best{font-weight:bold;background:#e8f5e9}\n"
    ".bar{display:flex;align-items:center;gap:.5em}.bar img{width:256px;height:16px}\n";

/* The page's script: the A/B/reference toggle (click or Space cycles, keys 1..N pick,
 * R the reference) and #selftest, which checks every image and the toggle and writes the
 * result into #selftest for headless Chromium (tests/compare_page.sh). */
static const char *page_js =
    "const views = JSON.parse(document.getElementById('views').textContent);\n"
    "const view = document.getElementById('view'), caption = document.getElementById('viewcap');\n"
    "const errors = [];\n"
    "window.addEventListener('error', e => errors.push(String(e.message)));\n"
    "let cur = 0;\n"
    "function show(i) {\n"
    "  cur = (i + views.length) % views.length;\n"
    "  view.src = views[cur].src;\n"
    "  caption.textContent = views[cur].label + ' (' + (cur + 1) + ' of ' + views.length + ')';\n"
    "  document.querySelectorAll('#viewer button').forEach((b, j) => b.classList.toggle('on', j === cur));\n"
    "}\n"
    "document.querySelectorAll('#viewer button').forEach((b, j) => b.addEventListener('click', () => show(j)));\n"
    "view.addEventListener('click', () => show(cur + 1));\n"
    "document.addEventListener('keydown', e => {\n"
    "  if (e.key === ' ') { e.preventDefault(); show(cur + 1); }\n"
    "  else if (e.key === 'r' || e.key === 'R') show(views.length - 1);\n"
    "  else if (e.key >= '1' && e.key <= '9' && +e.key <= views.length) show(+e.key - 1);\n"
    "});\n"
    "function selftest() {\n"
    "  const out = document.getElementById('selftest'), lines = [];\n"
    "  let ok = errors.length === 0;\n"
    "  errors.forEach(m => lines.push('script error: ' + m));\n"
    "  for (const img of document.images) {\n"
    "    const good = img.complete && img.naturalWidth > 0;\n"
    "    ok = ok && good;\n"
    "    lines.push((good ? 'loaded ' : 'NOT LOADED ') + img.getAttribute('src') + ' ' + img.naturalWidth + 'x' + img.naturalHeight);\n"
    "  }\n"
    "  const before = view.getAttribute('src');\n"
    "  view.addEventListener('load', () => {\n"
    "    const after = view.getAttribute('src');\n"
    "    const switched = after !== before && view.naturalWidth > 0;\n"
    "    ok = ok && switched;\n"
    "    lines.push('toggle ' + before + ' -> ' + after + (switched ? ' ok' : ' FAILED'));\n"
    "    out.textContent = (ok ? 'SELFTEST PASS' : 'SELFTEST FAIL') + '\\n' + lines.join('\\n');\n"
    "    out.hidden = false;\n"
    "  }, {once: true});\n"
    "  view.click();\n"
    "}\n"
    "show(0);\n"
    "window.addEventListener('load', () => { if (location.hash === '#selftest') selftest(); });\n";

static void page_head(rd_text *b, const rd_comparison *c, const rd_scene *s)
{
    const rd_cmp_opts *o = &c->opts;
    const rd_cmp_summary *S = &c->sum;
    rd_text_printf(b, "<!doctype html>\n<html lang=en><head><meta charset=utf-8><title>photonmarch compare: ");
    sb_escape(b, s->path);
    rd_text_printf(b, "</title>\n<style>\n%s</style></head><body>\n<h1>photonmarch compare: ", page_css);
    sb_escape(b, s->path);
    rd_text_printf(b, "</h1>\n<p>%dx%d pixels; equal %s: %g %s per run; %d run%s per method (seeds %llu..%llu); "
                 "bake time charged to every run of a method that needs it.</p>\n",
              c->w, c->h, o->equal_spp ? "samples" : "time", o->budget, o->equal_spp ? "spp" : "s", o->runs,
              o->runs > 1 ? "s" : "", (unsigned long long)RUN_SEED(o->seed, 0), (unsigned long long)RUN_SEED(o->seed, o->runs - 1));
    rd_text_printf(b, "<p>Reference: ");
    sb_escape(b, S->ref_source);
    if (S->ref_rendered) rd_text_printf(b, " (delta, %.4g spp, %.1f s%s)", S->ref_spp, S->ref_seconds, S->ref_rendered == 2 ? ", from the cache" : "");
    if (isfinite(S->ref_var)) rd_text_printf(b, "; its own variance (mean stderr&sup2;) %.3g.</p>\n", S->ref_var);
    else rd_text_printf(b, "; its own standard error is unknown (no -stderr.exr beside it), so its noise is not accounted for.</p>\n");
    if (S->ref_too_noisy)
        rd_text_printf(b, "<p class=warn><b>The reference is too noisy to rank the methods:</b> its variance (%.3g) is more than a "
                     "quarter of the best method's MSE, so every MSE below is dominated by it. Render it longer "
                     "(--ref-spp) or pass a better one (--reference).</p>\n", S->ref_var);
    if (S->cancelled) rd_text_printf(b, "<p class=warn>Interrupted: this report holds the runs that finished.</p>\n");
}

static void page_viewer(rd_text *b, const rd_comparison *c)
{
    const rd_cmp_summary *S = &c->sum;
    rd_text_printf(b, "<h2>A / B / reference</h2>\n<section id=viewer>\n<div>");
    for (int i = 0; i < S->n_rows; i++) rd_text_printf(b, "<button>%d %s</button>", i + 1, c->rows[i].label);
    rd_text_printf(b, "<button>R reference</button></div>\n");
    rd_text_printf(b, "<img id=view src=\"%s.png\" alt=\"the image being compared\">\n", S->n_rows ? c->rows[0].label : "reference");
    rd_text_printf(b, "<p><b id=viewcap></b> &mdash; click the image or press Space to go to the next one at the same "
                 "place; keys 1&ndash;%d pick a method, R the reference.</p>\n</section>\n", S->n_rows > 9 ? 9 : S->n_rows);
    rd_text_printf(b, "<script type=\"application/json\" id=views>[");
    for (int i = 0; i < S->n_rows; i++) rd_text_printf(b, "{\"label\":\"%s\",\"src\":\"%s.png\"},", c->rows[i].label, c->rows[i].label);
    rd_text_printf(b, "{\"label\":\"reference\",\"src\":\"reference.png\"}]</script>\n");
}

static void page_images(rd_text *b, const rd_comparison *c, double scale, crop_box bx)
{
    const rd_cmp_summary *S = &c->sum;
    rd_text_printf(b, "<h2>Side by side</h2>\n<div class=grid>\n");
    for (int i = 0; i < S->n_rows; i++)
        rd_text_printf(b, "<figure><img src=\"%s.png\" alt=\"%s\"><figcaption>%s: RMSE %.3g</figcaption></figure>\n",
                  c->rows[i].label, c->rows[i].label, c->rows[i].label, c->rows[i].err.rmse);
    rd_text_printf(b, "<figure><img src=\"reference.png\" alt=reference><figcaption>reference</figcaption></figure>\n</div>\n");
    rd_text_printf(b, "<h2>Error maps</h2>\n<p>Per-pixel relative error of luminance |L(x) &minus; L(ref)| / (L(ref) + 0.01), "
                 "one colour scale for every map.</p>\n<div class=bar><span>0</span><img src=colorbar.png alt=\"colour bar\">"
                 "<span>&ge; %.3g</span></div>\n<div class=grid>\n", scale);
    for (int i = 0; i < S->n_rows; i++)
        rd_text_printf(b, "<figure><img src=\"%s-error.png\" alt=\"%s error\"><figcaption>%s</figcaption></figure>\n",
                  c->rows[i].label, c->rows[i].label, c->rows[i].label);
    rd_text_printf(b, "</div>\n<h2>Worst region</h2>\n<p>The %dx%d pixel window at (%d, %d) with the largest squared error "
                 "summed over the methods, enlarged.</p>\n<div class=grid>\n", bx.s, bx.s, bx.x, bx.y);
    for (int i = 0; i < S->n_rows; i++)
        rd_text_printf(b, "<figure><img src=\"%s-crop.png\" alt=\"%s crop\"><figcaption>%s</figcaption></figure>\n",
                  c->rows[i].label, c->rows[i].label, c->rows[i].label);
    rd_text_printf(b, "<figure><img src=\"reference-crop.png\" alt=\"reference crop\"><figcaption>reference</figcaption></figure>\n</div>\n");
}

/* The index of the row with the smallest (dir = 1) or largest (dir = -1) value, or -1. */
static int best_row(const rd_comparison *c, size_t off, int dir)
{
    int best = -1;
    for (int i = 0; i < c->sum.n_rows; i++) {
        double v = *(const double *)((const char *)&c->rows[i] + off);
        if (!isfinite(v)) continue;
        double bv = best < 0 ? 0 : *(const double *)((const char *)&c->rows[best] + off);
        if (best < 0 || dir * v < dir * bv) best = i;
    }
    return c->sum.n_rows > 1 ? best : -1;
}

static void page_table(rd_text *b, const rd_comparison *c)
{
    int be = best_row(c, offsetof(rd_cmp_row, efficiency), -1), br = best_row(c, offsetof(rd_cmp_row, err.rmse), 1);
    rd_text_printf(b, "<h2>Metrics</h2>\n<table><tr><th>method</th><th>runs</th><th>time s</th><th>bake s</th><th>spp</th>"
                 "<th>RMSE</th><th>relMSE</th><th>MARE</th><th>bias&sup2;</th><th>variance</th><th>efficiency<br>1/(MSE&middot;t)</th>"
                 "<th>TTUV<br>t&middot;RMSE</th><th>collisions /px</th><th>lookups /px</th><th>shadow rays /px</th><th>homogeneity</th></tr>\n");
    for (int i = 0; i < c->sum.n_rows; i++) {
        const rd_cmp_row *r = &c->rows[i];
        rd_text_printf(b, "<tr><td>%s%s</td><td>%d</td>", r->label, r->is_extra ? " (added)" : "", r->runs);
        sb_cell(b, r->seconds), sb_cell(b, r->bake_seconds), sb_cell(b, r->spp);
        rd_text_printf(b, i == br ? "<td class=best>%.3g</td>" : "<td>%.3g</td>", r->err.rmse);
        sb_cell(b, r->err.relmse), sb_cell(b, r->err.mare), sb_cell(b, r->split.bias2), sb_cell(b, r->split.variance);
        if (i == be) rd_text_printf(b, "<td class=best>%.3g</td>", r->efficiency);
        else sb_cell(b, r->efficiency);
        sb_cell(b, r->ttuv), sb_cell(b, r->collisions_pp), sb_cell(b, r->lookups_pp), sb_cell(b, r->shadow_rays_pp);
        sb_cell(b, r->homogeneity);
        rd_text_printf(b, "</tr>\n");
    }
    rd_text_printf(b, "</table>\n<p>Errors against the reference over every pixel and channel, the mean over the runs. "
                 "bias&sup2; and variance (of one run) from the %d runs%s. Efficiency: higher is better; TTUV (seed 002): lower "
                 "is better. Homogeneity: 90th / 50th percentile of the per-pixel relative error over lit pixels (1 = even). "
                 "Definitions: docs/compare.md; numbers: <a href=metrics.json>metrics.json</a>.</p>\n",
              c->opts.runs, c->opts.runs < 2 ? " (one run: variance from its standard-error image)" : "");
}

static rd_status write_page(const rd_comparison *c, const rd_scene *s, const char *dir, double scale,
                            crop_box bx, char *err, size_t errlen)
{
    rd_text b = {0};
    page_head(&b, c, s);
    page_table(&b, c);
    page_viewer(&b, c);
    page_images(&b, c, scale, bx);
    rd_text_printf(&b, "<h2>Convergence</h2>\n<p>RMSE against time during each run (log-log; drawn by gnuplot from "
                  "curve-*.dat).</p>\n<img src=convergence.svg alt=\"RMSE against time\" style=\"max-width:100%%\">\n");
    rd_text_printf(&b, "<pre id=selftest hidden></pre>\n<script>\n%s</script>\n</body></html>\n", page_js);
    return write_buffer_at(dir, "index.html", &b, err, errlen);
}

rd_status rd_compare_write_report(const rd_comparison *c, const rd_scene *scene, const char *dir,
                                  char *err, size_t errlen)
{
    char dummy[8], probe[1200];
    if (!err) { err = dummy; errlen = sizeof dummy; }
    if (!c->ref.rgb) return fail(err, errlen, RD_ERR_ARG, "%s: no reference, nothing to report", dir);
    snprintf(probe, sizeof probe, "%.1000s/index.html", dir);
    rd_status st = rd_make_parent_dirs(probe, err, errlen);
    if (st) return st;
    double scale = error_scale(c);
    crop_box bx = worst_region(c);
    if ((st = write_images(c, dir, scale, bx, err, errlen)) || (st = write_plot(c, dir, err, errlen)) ||
        (st = write_json(c, scene, dir, scale, bx, err, errlen)) || (st = write_page(c, scene, dir, scale, bx, err, errlen)))
        return st;
    return RD_OK;
}

/* ---- The summary table on stdout ----------------------------------------------------------- */

static void put_num(FILE *out, double v)
{
    if (isfinite(v)) fprintf(out, " %10.4g", v);
    else fprintf(out, " %10s", "n/a");
}

void rd_compare_print_table(const rd_comparison *c, FILE *out)
{
    fprintf(out, "%-16s %4s %10s %10s %10s %10s %10s %10s %10s %10s %10s\n", "method", "runs", "time_s", "spp", "RMSE",
            "relMSE", "MARE", "bias^2", "variance", "efficiency", "TTUV");
    for (int i = 0; i < c->sum.n_rows; i++) {
        const rd_cmp_row *r = &c->rows[i];
        fprintf(out, "%-16.16s %4d", r->label, r->runs);
        const double v[9] = {r->seconds, r->spp, r->err.rmse, r->err.relmse, r->err.mare, r->split.bias2,
                             r->split.variance, r->efficiency, r->ttuv};
        for (int k = 0; k < 9; k++) put_num(out, v[k]);
        fputc('\n', out);
    }
    const rd_cmp_summary *S = &c->sum;
    fprintf(out, "reference: %s", S->ref_source);
    if (isfinite(S->ref_var)) fprintf(out, " (variance %.3g)", S->ref_var);
    fprintf(out, "%s\n", S->ref_too_noisy ? "; TOO NOISY to rank the methods (see the report)" : "");
}
