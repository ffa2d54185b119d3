/* bench_guide.c: which photon-map bake gives the better SH guide grid, and where.
 *
 *   build/bench/bench_guide [--quick] [--json FILE] [--scene SUBSTRING]
 *
 * The guide grid (THEORY.md §5) stores per cell the SH coefficients of
 * f(x, w) = sigma_s(x) L_s(x, w) (THEORY.md §4), and the guided marcher (THEORY.md §6) uses f
 * toward the camera as its histogram height. A good guide is close to the true sigma_s L_s and,
 * above all, never 0 where light is (a zero cell is sampled only by the defensive mixture).
 *
 * Per scene (homogeneous, default with sigma_t 0.3, default, cloud):
 *  1. Points, w = normalise(camera position - x) (the w a camera ray through x evaluates):
 *     density-weighted points (pdf proportional to the density: where the scattering, hence the
 *     camera integrand, is), points uniform over the occupied volume (fringes and holes), and
 *     points of zero density inside the bounds. Reference at the occupied points, independent
 *     of the photon map, as in tests/test_photons.c: w' drawn from the HG phase around w,
 *     rd_delta_radiance (unbiased delta-tracking path tracing, THEORY.md §2) for the radiance
 *     arriving at x along w' (ray from x along -w'), plus the direct term p(w_l.w) Li T of every
 *     delta light (a traced ray never hits one) with T by rd_transmittance; both parts from the
 *     same sample, so the standard error covers both. Paths are added in batches until the
 *     relative standard error is below the target, 2.5% (or a cap of 2^18 paths). The same
 *     samples, re-weighted by p_L/p (and p_L in the direct term), give ref_L: the value for the
 *     phase truncated to the guide's bands (THEORY.md §4), the best a guide can reach. The
 *     scene background is set to 0 (it is not a light: photons never carry it) and the path
 *     depth to PHOTON_DEPTH - 1 scatterings, matching photon paths of PHOTON_DEPTH collisions.
 *  2. Photon maps (THEORY.md §3) of N = 1e5 and 1e6 emitted photons (--quick: 1e5),
 *     store_direct = 1 (the guide wants direct light too), segments stored; six bakes through
 *     rd_guide_bake with the scene's media (bands 4, k 64, lambda 1): {k-NN, track-length} x
 *     {uniform grid by the resolution rule, uniform grid of 32 cells on the longest axis,
 *     adaptive octree (max_depth 8)}. Guide value at a point: sh_guide_eval with each RGB
 *     channel clamped at 0, mean of R, G, B (= sh_eval_guide, what the PDF uses); reference:
 *     mean of R, G, B. Metrics: over the density-weighted points, rel = (guide - ref)/ref: RMS,
 *     median |rel|, mean (bias), RMS over "lit" points (delta-light direct term >= half the
 *     reference: spot beams, facing the light) and the others; the same for the bake-only
 *     error (guide - ref_L)/ref; over all occupied points the fraction where the guide is 0 and
 *     where it is below 0.1 ref; leak = mean guide at empty points / mean reference. Bake
 *     times: median of 3 runs at 1e5, one run at 1e6 (the track bakes there take seconds each).
 *  3. Resolution floor: both bakes from 4e6 photons (2e6 for the default variants, see SCENES;
 *     --quick: 3e5) on the same uniform grids.
 *     For the track-length bake this is mostly the cell-average-versus-point-value
 *     (discretisation) error, separated from photon noise; for k-NN, its kernel bias as well.
 *
 * Fixed seeds everywhere; the result does not depend on the thread count (one PCG32 stream per
 * (point, path) in the reference; photon tracing and bakes are deterministic). Prints markdown
 * tables (progress on stderr). Not a test. */
#include "bake/rd_photons.h"
#include "transport/rd_path.h"
#include "sh.h"

#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define PHOTON_DEPTH 64 /* collisions per photon path (the renderer's default) */
#define GUIDE_BANDS 4   /* SH bands L of every guide (the renderer's default, seed 001 §4) */
#define MAX_SCENES 4
#define MAX_BAKES 6
#define MAX_ROWS (2 * MAX_BAKES + 6) /* bakes at two counts + k-NN and track floors on 3 grids */

typedef struct {
    const char *label, *path;
    rd_override ov; /* at most one --set override */
    int nov;
    /* Photons of the resolution floor (full run). 4e6 where tracing and baking them is cheap;
     * 2e6 for the two default variants, whose track bakes cost ~10-20 s per 1e6 photons and whose
     * 1e6 track bakes were within 4% (relative) of a 4e6 floor's RMS rel (docs/guide-quality.md). */
    size_t floor_count;
} scene_spec;

static const scene_spec SCENES[MAX_SCENES] = {
    {"homogeneous (thin, constant)", "scenes/homogeneous.json", {NULL, NULL}, 0, 4000000},
    {"default thin (sigma_t 0.3)", "scenes/default.json", {"media[0].sigma_t", "0.3"}, 1, 2000000},
    {"default (noise, g 0.7, 2 spots)", "scenes/default.json", {NULL, NULL}, 0, 2000000},
    {"cloud (dense, 8 octaves)", "scenes/cloud.json", {NULL, NULL}, 0, 4000000},
};

typedef struct {
    const char *name;
    int track, adaptive, fixed;
} bake_cfg;

static const bake_cfg BAKES[MAX_BAKES] = {
    {"knn", 0, 0, 0}, {"track", 1, 0, 0}, {"knn", 0, 0, 1},
    {"track", 1, 0, 1}, {"knn", 0, 1, 0}, {"track", 1, 1, 0},
};

typedef struct {
    int quick;
    int n_dens, n_unif, n_empty; /* points per set (pick_points modes) */
    double target_rse;           /* stop adding reference paths below this relative SE */
    long min_paths, max_paths, batch;
    int n_counts;
    size_t counts[2];
    int runs[2];                 /* bake repeats for the median time, per photon count */
    size_t floor_count;          /* 0: each scene's own (full run) */
} bench_opts;

typedef struct {
    vec3 x, w;
    double ref;      /* mean over RGB of sigma_s L_s(x, w) [W m^-3 sr^-1] */
    double se;       /* its standard error */
    double direct;   /* the delta-light direct part of ref */
    double ref_L;    /* the same with the phase truncated to GUIDE_BANDS bands (p_L of THEORY.md
                        §4), each channel clamped at 0 like the guide value */
    double se_L;
    long paths;
} ref_point;

typedef struct {
    ref_point *p;
    int n;
} point_set;

typedef struct {
    char bake[16], grid[24];
    size_t photons, cells;
    int res[3];
    double bake_s;   /* median wall time; < 0: not timed */
    int runs;
    /* density-weighted points, against the reference and against the p_L reference */
    double rms, med, bias, rms_lit, rms_dark, rms_L, med_L, bias_L;
    /* all occupied points (density-weighted and uniform): coverage */
    double zero, starved;
    /* empty points */
    double leak;
} row;

typedef struct {
    const char *label;
    int n_dens, n_unif, n_empty, n_lit;
    double ref_seconds, rse_median, rse_max;
    long paths_median, paths_total;
    int rse_over3;
    double rseL_median, rseL_max;
    double trunc_mean, trunc_rms; /* (ref_L - ref)/ref over the density-weighted points */
    size_t floor_count;
    double trace_s[3];
    size_t stored[3], segments[3];
    int n_rows;
    row rows[MAX_ROWS];
} scene_result;

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int n)
{
    if (n <= 0) return 0.0;
    qsort(v, (size_t)n, sizeof *v, cmp_d);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static double density_at(const rd_scene *s, vec3 x)
{
    const rd_medium *m = rd_scene_medium_at_point(s, x);
    return m ? rd_medium_density(m, x) : 0.0;
}

/* Up to n points in the media bounds by rejection from a fixed stream (returns how many):
 *   PTS_DENSITY  pdf proportional to the density (accept with density/density_max): where
 *                scattering happens, i.e. where the camera integrand sigma_s L_s T has its mass
 *                (THEORY.md §1, §6);
 *   PTS_UNIFORM  uniform over the occupied volume (density > 0), fringes and holes included;
 *   PTS_EMPTY    uniform over the zero-density part of the bounds. */
enum { PTS_DENSITY = 0, PTS_UNIFORM = 1, PTS_EMPTY = 2 };
static int pick_points(const rd_scene *s, int n, int mode, uint64_t seed, vec3 *out)
{
    pcg32 r = pcg32_seed(seed, (uint64_t)mode, 0x706f696e7473ULL);
    vec3 lo = s->bmin, ext = v3_sub(s->bmax, s->bmin);
    double dmax = 0.0;
    for (int i = 0; i < s->n_media; i++) dmax = fmax(dmax, s->media[i].density_max);
    int found = 0;
    for (long tries = 0; found < n && tries < 4000000L; tries++) {
        vec3 x = v3(lo.x + ext.x * pcg32_uniform(&r), lo.y + ext.y * pcg32_uniform(&r),
                    lo.z + ext.z * pcg32_uniform(&r));
        double d = density_at(s, x), u = pcg32_uniform(&r);
        int ok = mode == PTS_EMPTY ? d == 0.0 : mode == PTS_UNIFORM ? d > 0.0 : d > 0.0 && u * dmax < d;
        if (ok) out[found++] = x;
    }
    return found;
}

/* Reference sigma_s L_s(x, w), mean of RGB (see the header; THEORY.md §1-2), and from the same
 * samples the reference for the phase truncated to L bands, p_L (THEORY.md §4): the path part
 * re-weighted by p_L/p (w' is drawn from p), the direct part with p_L. The guide can at best
 * reach the second (both bakes estimate sigma_s integral p_L L); the gap between the two is the
 * SH truncation error, which no bake removes. */
static void reference_point(const rd_scene *s, ref_point *p, uint64_t stream, const bench_opts *o)
{
    const rd_medium *m = rd_scene_medium_at_point(s, p->x);
    const double st = rd_medium_sigma_t(m, p->x);
    const vec3 ss = v3_scale(m->albedo, st);
    double b[GUIDE_BANDS];
    sh_phase_coeffs_hg(m->g, GUIDE_BANDS, b);
    double sum = 0, sum2 = 0, sumd = 0, sumL[3] = {0, 0, 0}, sumX = 0, sumX2 = 0;
    long n = 0;
    rd_track_counters c = {0};
    while (n < o->max_paths) {
        for (long k = n; k < n + o->batch; k++) {
            pcg32 r = pcg32_seed(stream, (uint64_t)k, 0x726566ULL);
            /* w' ~ p(w'.w): the phase is symmetric in w'.w, so sample around w. */
            vec3 wp = rd_hg_sample(m->g, p->w, pcg32_uniform(&r), pcg32_uniform(&r));
            double mu = v3_dot(wp, p->w);
            double wL = sh_phase_truncated(b, GUIDE_BANDS, mu) / rd_hg_eval(m->g, mu);
            ray3 back = {p->x, v3_scale(wp, -1.0)};
            vec3 L = rd_delta_radiance(s, back, &r, &c);
            /* Delta lights: p(w_l . w) Li T, w_l = -wi the direction the light travels. */
            vec3 D = v3(0, 0, 0), DL = v3(0, 0, 0);
            for (int i = 0; i < s->n_lights; i++) {
                rd_light_sample ls;
                double u1 = pcg32_uniform(&r), u2 = pcg32_uniform(&r);
                if (!rd_light_sample_li(&s->lights[i], p->x, u1, u2, &ls) || ls.pdf > 0.0) continue;
                ray3 sr = {p->x, ls.wi};
                double T = rd_transmittance(s, rd_scene_region_at(s, p->x), sr, 0.0, ls.dist, &r, &c);
                double mul = -v3_dot(ls.wi, p->w);
                D = v3_madd(D, ls.contrib, rd_hg_eval(m->g, mul) * T);
                DL = v3_madd(DL, ls.contrib, sh_phase_truncated(b, GUIDE_BANDS, mul) * T);
            }
            vec3 f = v3_mul(ss, v3_add(L, D)), fd = v3_mul(ss, D);
            vec3 fL = v3_mul(ss, v3_add(v3_scale(L, wL), DL));
            double X = (f.x + f.y + f.z) / 3.0, XL = (fL.x + fL.y + fL.z) / 3.0;
            sum += X;
            sum2 += X * X;
            sumd += (fd.x + fd.y + fd.z) / 3.0;
            sumL[0] += fL.x;
            sumL[1] += fL.y;
            sumL[2] += fL.z;
            sumX += XL;
            sumX2 += XL * XL;
        }
        n += o->batch;
        double mean = sum / n, var = fmax(0.0, sum2 / n - mean * mean) / (n - 1);
        if (n >= o->min_paths && sqrt(var) <= o->target_rse * mean) break;
    }
    p->ref = sum / n;
    p->se = sqrt(fmax(0.0, sum2 / n - p->ref * p->ref) / (n - 1));
    p->direct = sumd / n;
    p->ref_L = (fmax(0.0, sumL[0]) + fmax(0.0, sumL[1]) + fmax(0.0, sumL[2])) / (3.0 * n);
    p->se_L = sqrt(fmax(0.0, sumX2 / n - (sumX / n) * (sumX / n)) / (n - 1));
    p->paths = n;
}

/* Guide value the PDF uses: mean of R, G, B each clamped at 0 (sh.h, sh_eval_guide). */
static double guide_value(const sh_guide *g, vec3 x, vec3 w)
{
    const double xa[3] = {x.x, x.y, x.z}, wa[3] = {w.x, w.y, w.z};
    float f[3];
    sh_guide_eval(g, xa, wa, f);
    return (fmax(0.0, f[0]) + fmax(0.0, f[1]) + fmax(0.0, f[2])) / 3.0;
}

/* Relative error at each point of a set, |.| into abs_rel:
 *   trunc = 0: rel = (guide - ref) / ref, the error that matters for guiding;
 *   trunc = 1: (guide - ref_L) / ref, the part a bake adds on top of the SH truncation, in
 *              units of the true value, so that rel = this + (ref_L - ref)/ref exactly. */
static void rel_errors(const sh_guide *g, const point_set *ps, int trunc, double *rel, double *abs_rel)
{
    for (int i = 0; i < ps->n; i++) {
        double v = guide_value(g, ps->p[i].x, ps->p[i].w);
        rel[i] = (v - (trunc ? ps->p[i].ref_L : ps->p[i].ref)) / ps->p[i].ref;
        abs_rel[i] = fabs(rel[i]);
    }
}

static void metrics(const sh_guide *g, const point_set *dens, const point_set *unif,
                    const point_set *empty, row *r)
{
    int nmax = dens->n > unif->n ? dens->n : unif->n;
    double *rel = malloc((size_t)(nmax + 1) * sizeof *rel), *ab = malloc((size_t)(nmax + 1) * sizeof *ab);
    if (!rel || !ab) {
        fprintf(stderr, "bench_guide: out of memory\n");
        exit(1);
    }
    /* Density-weighted points: accuracy where the scattering is. A point is "lit" when the
     * delta lights' direct term is at least half its reference (spot beams, near the light). */
    rel_errors(g, dens, 0, rel, ab);
    double e2 = 0, bias = 0, e2l = 0, e2d = 0;
    int zero = 0, starved = 0, nl = 0, nd = 0;
    for (int i = 0; i < dens->n; i++) {
        e2 += rel[i] * rel[i];
        bias += rel[i];
        zero += rel[i] <= -1.0; /* guide == 0 */
        starved += rel[i] < -0.9;
        if (dens->p[i].direct >= 0.5 * dens->p[i].ref) { e2l += rel[i] * rel[i]; nl++; }
        else { e2d += rel[i] * rel[i]; nd++; }
    }
    r->rms = sqrt(e2 / dens->n);
    r->bias = bias / dens->n;
    r->rms_lit = nl ? sqrt(e2l / nl) : NAN;
    r->rms_dark = nd ? sqrt(e2d / nd) : NAN;
    r->med = median(ab, dens->n);
    /* The same against the truncated-phase reference: the error a bake adds. */
    rel_errors(g, dens, 1, rel, ab);
    e2 = bias = 0;
    for (int i = 0; i < dens->n; i++) {
        e2 += rel[i] * rel[i];
        bias += rel[i];
    }
    r->rms_L = sqrt(e2 / dens->n);
    r->bias_L = bias / dens->n;
    r->med_L = median(ab, dens->n);
    /* Coverage over all occupied points: a zero guide where light is starves the region. */
    rel_errors(g, unif, 0, rel, ab);
    for (int i = 0; i < unif->n; i++) {
        zero += rel[i] <= -1.0;
        starved += rel[i] < -0.9;
    }
    r->zero = (double)zero / (dens->n + unif->n);
    r->starved = (double)starved / (dens->n + unif->n);
    /* Empty points: guide mass where nothing scatters, relative to the mean reference of the
     * density-weighted points. */
    double leak = 0, refsum = 0;
    for (int i = 0; i < empty->n; i++) leak += guide_value(g, empty->p[i].x, empty->p[i].w);
    for (int i = 0; i < dens->n; i++) refsum += dens->p[i].ref;
    r->leak = empty->n ? (leak / empty->n) / (refsum / dens->n) : NAN;
    free(rel);
    free(ab);
}

static pm_map *trace(const rd_scene *s, size_t count, uint64_t seed, int build, double *secs,
                     size_t *stored, size_t *segments)
{
    pm_map *map = pm_map_new();
    char err[RD_ERRLEN];
    rd_photon_opts po = {.count = count, .store_direct = 1, .segments = 1,
                         .max_depth = PHOTON_DEPTH, .seed = seed, .threads = 0};
    rd_photon_stats st;
    double t0 = now();
    if (!map || rd_trace_photons(s, &po, map, &st, err, sizeof err) != RD_OK) {
        fprintf(stderr, "bench_guide: %s\n", err);
        exit(1);
    }
    if (build && pm_map_build(map, err, sizeof err) != PM_OK) {
        fprintf(stderr, "bench_guide: photon map: %s\n", err);
        exit(1);
    }
    *secs = now() - t0;
    *stored = st.stored;
    *segments = st.segments;
    return map;
}

/* Bake with the given settings (runs times, median wall time; runs 0 = once, not timed) and
 * fill a row. */
static void bake_row(rd_scene *s, const pm_map *map, size_t photons, const bake_cfg *c,
                     const int res[3], const char *name, const char *grid, int runs,
                     const point_set *dens, const point_set *unif, const point_set *empty, row *r)
{
    rd_guide_settings gs = {.adaptive = c->adaptive, .track = c->track, .bands = GUIDE_BANDS, .k = 64,
                            .lambda = 1.0, .res = {0, 0, 0}, .min_cell = 0.0, .max_depth = 8};
    if (res) memcpy(gs.res, res, sizeof gs.res);
    s->guide = gs;
    double t[8];
    sh_guide *g = NULL;
    int reps = runs > 0 ? runs : 1;
    for (int k = 0; k < reps; k++) {
        char err[RD_ERRLEN];
        sh_guide_free(g);
        g = NULL;
        double t0 = now();
        if (rd_guide_bake(s, map, 0, &g, err, sizeof err) != RD_OK) {
            fprintf(stderr, "bench_guide: %s\n", err);
            exit(1);
        }
        t[k] = now() - t0;
    }
    memset(r, 0, sizeof *r);
    snprintf(r->bake, sizeof r->bake, "%s", name);
    snprintf(r->grid, sizeof r->grid, "%s", grid);
    r->photons = photons;
    r->bake_s = runs > 0 ? median(t, runs) : -1.0;
    r->runs = runs;
    sh_guide_stats st;
    sh_guide_stats_get(g, &st);
    r->cells = st.cells;
    memcpy(r->res, st.res, sizeof r->res);
    metrics(g, dens, unif, empty, r);
    sh_guide_free(g);
}

static void print_num(double v, const char *fmt)
{
    if (isfinite(v)) printf(fmt, v);
    else printf("-");
    printf(" | ");
}

static void print_row(const row *r)
{
    char res[48], bs[32] = "-";
    snprintf(res, sizeof res, "%dx%dx%d", r->res[0], r->res[1], r->res[2]);
    if (r->bake_s >= 0) snprintf(bs, sizeof bs, r->runs > 1 ? "%.3f" : "%.3f (1 run)", r->bake_s);
    printf("| %s | %.0e | %s | %s | %zu | %s | ", r->bake, (double)r->photons, r->grid, res, r->cells, bs);
    print_num(r->rms, "%.3f");
    print_num(r->med, "%.3f");
    print_num(r->bias, "%+.3f");
    print_num(r->rms_L, "%.3f");
    print_num(r->med_L, "%.3f");
    print_num(r->bias_L, "%+.3f");
    print_num(r->rms_lit, "%.3f");
    print_num(r->rms_dark, "%.3f");
    print_num(r->zero, "%.3f");
    print_num(r->starved, "%.3f");
    print_num(r->leak, "%.4f");
    printf("\n");
}

static void json_num(FILE *f, const char *k, double v, int last)
{
    if (isfinite(v)) fprintf(f, "\"%s\": %.6g%s", k, v, last ? "" : ", ");
    else fprintf(f, "\"%s\": null%s", k, last ? "" : ", ");
}

static void write_json(const char *path, const bench_opts *o, const scene_result *sr, int ns)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "bench_guide: cannot write %s\n", path);
        return;
    }
    fprintf(f, "{\n  \"quick\": %d, \"threads\": %d, \"bands\": %d, \"guide_value\": \"mean of R, G, B each clamped at 0\",\n"
               "  \"floor_photons\": %zu, \"reference_target_rse\": %g, \"note\": \"floor_photons 0 = per scene, see floor_photons of each scene\",\n  \"scenes\": [\n",
            o->quick, omp_get_max_threads(), GUIDE_BANDS, o->floor_count, o->target_rse);
    for (int i = 0; i < ns; i++) {
        const scene_result *s = &sr[i];
        fprintf(f, "    {\"scene\": \"%s\", \"density_points\": %d, \"uniform_points\": %d, "
                   "\"empty_points\": %d, \"lit_points\": %d, ",
                s->label, s->n_dens, s->n_unif, s->n_empty, s->n_lit);
        fprintf(f, "\"floor_photons\": %zu, ", s->floor_count);
        json_num(f, "reference_s", s->ref_seconds, 0);
        json_num(f, "rse_median", s->rse_median, 0);
        json_num(f, "rse_max", s->rse_max, 0);
        json_num(f, "rse_truncated_median", s->rseL_median, 0);
        json_num(f, "rse_truncated_max", s->rseL_max, 0);
        json_num(f, "truncation_mean", s->trunc_mean, 0);
        json_num(f, "truncation_rms", s->trunc_rms, 0);
        fprintf(f, "\"paths_median\": %ld, \"paths_total\": %ld, \"rse_over_3pct\": %d,\n      \"rows\": [\n",
                s->paths_median, s->paths_total, s->rse_over3);
        for (int j = 0; j < s->n_rows; j++) {
            const row *r = &s->rows[j];
            fprintf(f, "        {\"bake\": \"%s\", \"grid\": \"%s\", \"photons\": %zu, \"cells\": %zu, "
                       "\"res\": [%d, %d, %d], ",
                    r->bake, r->grid, r->photons, r->cells, r->res[0], r->res[1], r->res[2]);
            json_num(f, "bake_s_median", r->bake_s >= 0 ? r->bake_s : NAN, 0);
            fprintf(f, "\"bake_runs\": %d, ", r->runs);
            json_num(f, "rms_rel", r->rms, 0);
            json_num(f, "median_abs_rel", r->med, 0);
            json_num(f, "mean_rel_bias", r->bias, 0);
            json_num(f, "bake_only_rms", r->rms_L, 0);
            json_num(f, "bake_only_median_abs", r->med_L, 0);
            json_num(f, "bake_only_bias", r->bias_L, 0);
            json_num(f, "rms_rel_lit", r->rms_lit, 0);
            json_num(f, "rms_rel_shadowed", r->rms_dark, 0);
            json_num(f, "zero_frac", r->zero, 0);
            json_num(f, "below_0.1_ref_frac", r->starved, 0);
            json_num(f, "leak", r->leak, 1);
            fprintf(f, "}%s\n", j + 1 < s->n_rows ? "," : "");
        }
        fprintf(f, "      ]}%s\n", i + 1 < ns ? "," : "");
    }
    fprintf(f, "  ]\n}\n");
    fclose(f);
}

/* Points of one set with their reference values (OpenMP over points). */
static point_set make_set(const rd_scene *s, int n, int mode, int si, const bench_opts *o)
{
    point_set ps = {calloc((size_t)(n > 0 ? n : 1), sizeof(ref_point)), 0};
    vec3 *xs = calloc((size_t)(n > 0 ? n : 1), sizeof *xs);
    if (!ps.p || !xs) {
        fprintf(stderr, "bench_guide: out of memory\n");
        exit(1);
    }
    ps.n = pick_points(s, n, mode, 11 + (uint64_t)si, xs);
    for (int i = 0; i < ps.n; i++) {
        ps.p[i].x = xs[i];
        ps.p[i].w = v3_norm(v3_sub(s->camera.pos, xs[i])); /* toward the camera */
    }
    free(xs);
    if (mode != PTS_EMPTY) {
#pragma omp parallel for schedule(dynamic, 1)
        for (int i = 0; i < ps.n; i++)
            reference_point(s, &ps.p[i], ((uint64_t)si << 32) | ((uint64_t)mode << 16) | (uint64_t)i, o);
    }
    return ps;
}

int main(int argc, char **argv)
{
    bench_opts o = {.quick = 0, .n_dens = 96, .n_unif = 64, .n_empty = 32, .target_rse = 0.025,
                    .min_paths = 4096, .max_paths = 1L << 18, .batch = 2048, .n_counts = 2,
                    .counts = {100000, 1000000}, .runs = {3, 1}, .floor_count = 0};
    const char *json = NULL, *only = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--quick")) o.quick = 1;
        else if (!strcmp(argv[i], "--json") && i + 1 < argc) json = argv[++i];
        else if (!strcmp(argv[i], "--scene") && i + 1 < argc) only = argv[++i];
        else {
            fprintf(stderr, "usage: bench_guide [--quick] [--json FILE] [--scene SUBSTRING]\n");
            return 1;
        }
    }
    if (o.quick) {
        o.n_dens = 16;
        o.n_unif = 8;
        o.n_empty = 8;
        o.target_rse = 0.05;
        o.min_paths = 512;
        o.max_paths = 4096;
        o.batch = 512;
        o.n_counts = 1;
        o.runs[0] = 1;
        o.floor_count = 300000;
    }
    scene_result *results = calloc(MAX_SCENES, sizeof *results);
    if (!results) {
        fprintf(stderr, "bench_guide: out of memory\n");
        return 1;
    }
    double load0[3] = {0, 0, 0};
    FILE *la = fopen("/proc/loadavg", "r");
    if (la) {
        if (fscanf(la, "%lf %lf %lf", &load0[0], &load0[1], &load0[2]) != 3) load0[0] = NAN;
        fclose(la);
    }
    const double t_start = now();
    printf("%s run, %d thread(s), load average at start %.2f. Guide value = mean over R, G, B of max(0, f_c(w)) (sh_eval_guide);\n"
           "reference = mean over R, G, B of sigma_s L_s(x, w); rel = guide/ref - 1; w = toward the camera.\n\n",
           o.quick ? "Quick" : "Full", omp_get_max_threads(), load0[0]);
    int ns = 0;
    for (int si = 0; si < MAX_SCENES; si++) {
        const scene_spec *sp = &SCENES[si];
        if (only && !strstr(sp->label, only)) continue;
        scene_result *res = &results[ns++];
        res->label = sp->label;
        const size_t floor_count = o.floor_count ? o.floor_count : sp->floor_count;
        res->floor_count = floor_count;
        char err[RD_ERRLEN];
        rd_scene *s;
        if (rd_scene_load(&s, sp->path, sp->nov ? &sp->ov : NULL, sp->nov, err, sizeof err) != RD_OK) {
            fprintf(stderr, "bench_guide: %s\n", err);
            return 1;
        }
        s->background = v3(0, 0, 0);             /* not a light: photons never carry it */
        s->settings.max_depth = PHOTON_DEPTH - 1; /* same path depth as the photons */

        /* 1. Points and reference. */
        double t0 = now();
        point_set dens = make_set(s, o.n_dens, PTS_DENSITY, si, &o);
        point_set unif = make_set(s, o.n_unif, PTS_UNIFORM, si, &o);
        point_set empty = make_set(s, o.n_empty, PTS_EMPTY, si, &o);
        res->ref_seconds = now() - t0;
        fprintf(stderr, "[%s] reference %.1f s\n", sp->label, res->ref_seconds);
        int nall = dens.n + unif.n;
        double *rse = malloc((size_t)(nall + 1) * sizeof *rse), *np = malloc((size_t)(nall + 1) * sizeof *np);
        double *rseL = malloc((size_t)(nall + 1) * sizeof *rseL);
        for (int i = 0; i < nall; i++) {
            const ref_point *p = i < dens.n ? &dens.p[i] : &unif.p[i - dens.n];
            if (!(p->ref > 0)) {
                fprintf(stderr, "bench_guide: %s: a point has a zero reference\n", sp->label);
                return 1;
            }
            rse[i] = p->se / p->ref;
            rseL[i] = p->se_L / p->ref; /* in units of the true value, like the p_L metrics */
            res->rseL_max = fmax(res->rseL_max, rseL[i]);
            np[i] = (double)p->paths;
            res->rse_max = fmax(res->rse_max, rse[i]);
            res->rse_over3 += rse[i] > 0.03;
            res->paths_total += p->paths;
        }
        for (int i = 0; i < dens.n; i++) {
            double t = dens.p[i].ref_L / dens.p[i].ref - 1.0;
            res->n_lit += dens.p[i].direct >= 0.5 * dens.p[i].ref;
            res->trunc_mean += t / dens.n;
            res->trunc_rms += t * t / dens.n;
        }
        res->trunc_rms = sqrt(res->trunc_rms);
        res->rse_median = median(rse, nall);
        res->rseL_median = median(rseL, nall);
        free(rseL);
        res->paths_median = (long)median(np, nall);
        free(rse);
        free(np);
        res->n_dens = dens.n;
        res->n_unif = unif.n;
        res->n_empty = empty.n;

        /* Fixed resolution: 32 cells on the longest axis, roughly cubic cells. */
        vec3 ext = v3_sub(s->bmax, s->bmin);
        double lmax = v3_maxc(ext);
        int fixed[3] = {(int)fmax(1, round(32 * ext.x / lmax)), (int)fmax(1, round(32 * ext.y / lmax)),
                        (int)fmax(1, round(32 * ext.z / lmax))};

        /* 2. Bakes at each photon count; remember the rule resolutions for the floor. */
        int rule_res[2][3];
        for (int ci = 0; ci < o.n_counts; ci++) {
            pm_map *map = trace(s, o.counts[ci], 101 + ci, 1, &res->trace_s[ci], &res->stored[ci],
                                &res->segments[ci]);
            for (int b = 0; b < MAX_BAKES; b++) {
                const bake_cfg *c = &BAKES[b];
                const char *grid = c->adaptive ? "adaptive" : c->fixed ? "uniform fixed" : "uniform rule";
                row *r = &res->rows[res->n_rows++];
                bake_row(s, map, o.counts[ci], c, c->fixed ? fixed : NULL, c->name, grid, o.runs[ci],
                         &dens, &unif, &empty, r);
                if (!c->adaptive && !c->fixed && !c->track) memcpy(rule_res[ci], r->res, sizeof r->res);
            }
            pm_map_free(map);
            fprintf(stderr, "[%s] N=%.0e traced %.1f s, bakes done at %.1f s\n", sp->label,
                    (double)o.counts[ci], res->trace_s[ci], now() - t0);
        }
        /* 3. Resolution floor: both bakes from many photons on the same uniform grids (not
         * timed). The track-length floor is the cell-average-versus-point error of the grid. */
        {
            pm_map *map = trace(s, floor_count, 201, 1, &res->trace_s[2], &res->stored[2],
                                &res->segments[2]);
            for (int b = 0; b < 2; b++)
                for (int ci = 0; ci <= o.n_counts; ci++) {
                    const int *rr = ci < o.n_counts ? rule_res[ci] : fixed;
                    char grid[24], name[16];
                    if (ci < o.n_counts) snprintf(grid, sizeof grid, "rule of %.0e", (double)o.counts[ci]);
                    else snprintf(grid, sizeof grid, "uniform fixed");
                    snprintf(name, sizeof name, "floor %s", BAKES[b].name);
                    bake_row(s, map, floor_count, &BAKES[b], rr, name, grid, 0, &dens, &unif, &empty,
                             &res->rows[res->n_rows++]);
                }
            pm_map_free(map);
            fprintf(stderr, "[%s] floor traced %.1f s, done at %.1f s\n", sp->label, res->trace_s[2],
                    now() - t0);
        }

        /* This scene's table. */
        printf("### %s\n\n`%s`%s%s%s\n\n", sp->label, sp->path, sp->nov ? " with " : "",
               sp->nov ? sp->ov.key : "", sp->nov ? "=0.3" : "");
        printf("Reference: %d density-weighted points (%d lit: direct >= half the reference), %d uniform "
               "occupied points, %d empty points; paths/point median %ld (total %ld); relative SE median "
               "%.3f, max %.3f, %d point(s) above 0.03 (p_L reference: median %.3f, max %.3f); %.1f s.\n"
               "SH truncation alone, (ref_L - ref)/ref over the density-weighted points: mean %+.3f, RMS %.3f.\n",
               dens.n, res->n_lit, unif.n, empty.n, res->paths_median, res->paths_total, res->rse_median,
               res->rse_max, res->rse_over3, res->rseL_median, res->rseL_max, res->ref_seconds,
               res->trunc_mean, res->trunc_rms);
        printf("Photons: ");
        for (int ci = 0; ci <= o.n_counts; ci++) {
            int k = ci < o.n_counts ? ci : 2;
            size_t cnt = ci < o.n_counts ? o.counts[ci] : floor_count;
            printf("%s%.0e emitted -> %zu stored, %zu segments (%.1f s trace + index)", ci ? "; " : "",
                   (double)cnt, res->stored[k], res->segments[k], res->trace_s[k]);
        }
        printf(".\n\n");
        printf("| bake | N | grid | res | cells | bake s | RMS rel | median abs rel | bias | bake-only RMS "
               "| bake-only median abs | bake-only bias | RMS lit | RMS shadowed | zero | < 0.1 ref | leak |\n");
        printf("|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
        for (int j = 0; j < res->n_rows; j++) print_row(&res->rows[j]);
        printf("\n");
        fflush(stdout);
        free(dens.p);
        free(unif.p);
        free(empty.p);
        rd_scene_free(s);
    }
    double load1[3] = {0, 0, 0};
    la = fopen("/proc/loadavg", "r");
    if (la) {
        if (fscanf(la, "%lf %lf %lf", &load1[0], &load1[1], &load1[2]) != 3) load1[0] = NAN;
        fclose(la);
    }
    printf("Columns: bake s = median wall time of %d bake(s) at %.0e photons%s (floor rows not timed). "
           "RMS rel, median abs rel, bias (mean rel), RMS lit / shadowed (points whose delta-light direct term is "
           ">= / < half the reference) are over the density-weighted points, rel = (guide - ref)/ref; bake-only: "
           "the same for (guide - ref_L)/ref, ref_L = reference with the phase truncated to %d SH bands (what a guide "
           "of %d bands can reach at best), so rel = bake-only + SH truncation. "
           "zero / < 0.1 ref = fraction of all occupied points (density-weighted and uniform) where the guide is 0 / "
           "below a tenth of the reference; leak = mean guide at zero-density points / mean reference of the "
           "density-weighted points. Floor rows: the bake from the N shown on the named uniform grid. Reference target "
           "relative SE %.3f.\n",
           o.runs[0], (double)o.counts[0], o.n_counts > 1 ? ", a single run at 1e+06" : "", GUIDE_BANDS,
           GUIDE_BANDS, o.target_rse);
    printf("Total %.0f s; load average at end %.2f (1 min), %.2f (5 min).\n", now() - t_start, load1[0], load1[1]);
    if (json) write_json(json, &o, results, ns);
    free(results);
    return 0;
}
