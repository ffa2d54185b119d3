/* bench_sh.c: guide-grid bake time and memory (sh/; THEORY.md §5; seed 001 §3.1, §4).
 *
 *   bench_sh [--quick] [--json FILE] [--runs N] [--only001]   (--only001: table 5 alone)
 *
 * Tables 1-4: synthetic clustered photons (Gaussian blobs plus a uniform background in the unit
 * cube, directions biased toward +x, one path segment per photon of exponential length) are
 * stored in a photon map; there the map build is timed apart (first table) and the bake times
 * are of the bake alone, without a medium (cell extinction 0). Each configuration is baked
 * --runs times (default 3, --quick 1) and the median wall time is reported, with the guide's
 * memory.
 *
 * Table 5, seed 001's reported 7.0-8.4 s for 1e5 photons and 16 coefficients on a 2.8 GHz
 * Pentium 4, against ours for the same work: 1e5 photons traced (untimed) in the default scene
 * (scenes/default.json); the timed part is everything from the photon list to the guide:
 * the FLANN kd-tree build, the k-NN bake and the cell-mean extinction of the scene's noise
 * medium (sigma_t lookups), one thread. Prints markdown. */
#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap.h"
#include "bake/rd_photons.h"
#include "sh.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

typedef struct {
    uint64_t s;
} rng;
static double u01(rng *r)
{
    r->s = r->s * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(r->s >> 11) * 0x1.0p-53;
}
static double normal(rng *r)
{
    double u = fmax(u01(r), 1e-300), v = u01(r);
    return sqrt(-2.0 * log(u)) * cos(2.0 * M_PI * v);
}

static pm_map *make_map(size_t n, uint64_t seed, double *build_s)
{
    rng r = {seed};
    const double blobs[4][4] = {{0.3, 0.3, 0.5, 0.05},
                                {0.7, 0.6, 0.4, 0.08},
                                {0.5, 0.8, 0.7, 0.02},
                                {0.2, 0.7, 0.2, 0.12}};
    pm_photon *ph = malloc(n * sizeof *ph);
    pm_segment *sg = malloc(n * sizeof *sg);
    if (!ph || !sg) {
        fprintf(stderr, "bench_sh: out of memory for %zu photons\n", n);
        exit(1);
    }
    for (size_t i = 0; i < n; i++) {
        double x[3], w[3];
        if (u01(&r) < 0.15) {
            for (int a = 0; a < 3; a++)
                x[a] = u01(&r);
        } else {
            const double *b = blobs[(int)(u01(&r) * 4) & 3];
            for (int a = 0; a < 3; a++) {
                do
                    x[a] = b[a] + b[3] * normal(&r);
                while (x[a] < 0.0 || x[a] > 1.0);
            }
        }
        double z = 1.0 - 2.0 * u01(&r), phi = 2.0 * M_PI * u01(&r), s = sqrt(1.0 - z * z);
        w[0] = s * cos(phi) + 0.7, w[1] = s * sin(phi), w[2] = z;
        double nn = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
        for (int a = 0; a < 3; a++) {
            ph[i].pos[a] = (float)x[a];
            ph[i].dir[a] = (float)(w[a] / nn);
            ph[i].power[a] = (float)(1e-3 * (0.5 + 0.5 * a));
            sg[i].org[a] = ph[i].pos[a];
            sg[i].dir[a] = ph[i].dir[a];
            sg[i].power[a] = ph[i].power[a];
        }
        sg[i].length = (float)(-0.05 * log(fmax(u01(&r), 1e-12)) + 1e-4);
    }
    pm_map *m = pm_map_new();
    char err[256] = "";
    if (pm_map_add_photons(m, ph, n, err, sizeof err) != PM_OK ||
        pm_map_add_segments(m, sg, n, err, sizeof err) != PM_OK) {
        fprintf(stderr, "bench_sh: %s\n", err);
        exit(1);
    }
    double t = omp_get_wtime();
    if (pm_map_build(m, err, sizeof err) != PM_OK) {
        fprintf(stderr, "bench_sh: %s\n", err);
        exit(1);
    }
    *build_s = omp_get_wtime() - t;
    free(ph);
    free(sg);
    return m;
}

typedef struct {
    const char *table;
    size_t photons;
    int bands, k, threads;
    double lambda;
    sh_grid_kind kind;
    sh_bake_method method;
    /* results */
    double median_s, min_s;
    sh_guide_stats st;
} result;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static void run(const pm_map *m, result *r, int runs)
{
    sh_bake_params P;
    sh_bake_params_default(&P);
    for (int a = 0; a < 3; a++)
        P.lo[a] = 0.0, P.hi[a] = 1.0;
    P.bands = r->bands;
    P.k = r->k;
    P.lambda = r->lambda;
    P.kind = r->kind;
    P.method = r->method;
    P.threads = r->threads;
    sh_phase_coeffs_hg(0.6, P.bands, P.phase_b);
    double t[16];
    for (int i = 0; i < runs; i++) {
        sh_guide *g = NULL;
        char err[256] = "";
        double t0 = omp_get_wtime();
        if (sh_guide_bake(&g, m, &P, err, sizeof err) != SH_OK) {
            fprintf(stderr, "bench_sh: %s\n", err);
            exit(1);
        }
        t[i] = omp_get_wtime() - t0;
        if (i == runs - 1)
            sh_guide_stats_get(g, &r->st);
        sh_guide_free(g);
    }
    qsort(t, (size_t)runs, sizeof t[0], cmp_double);
    r->median_s = runs % 2 ? t[runs / 2] : 0.5 * (t[runs / 2 - 1] + t[runs / 2]);
    r->min_s = t[0];
}

static const char *kind_name(sh_grid_kind k) { return k == SH_GRID_UNIFORM ? "uniform" : "adaptive"; }
static const char *method_name(sh_bake_method m) { return m == SH_BAKE_KNN ? "k-NN" : "track"; }

static void fmt_n(size_t n, char *buf, size_t len)
{
    int e = (int)floor(log10((double)n) + 1e-9);
    if (n == (size_t)llround(pow(10.0, e)))
        snprintf(buf, len, "1e%d", e);
    else
        snprintf(buf, len, "%zu", n);
}

static void print_row(const result *r)
{
    char nb[32], res[48];
    fmt_n(r->photons, nb, sizeof nb);
    if (r->kind == SH_GRID_UNIFORM)
        snprintf(res, sizeof res, "%dx%dx%d", r->st.res[0], r->st.res[1], r->st.res[2]);
    else
        snprintf(res, sizeof res, "depth %d", r->st.depth_max);
    printf("| %s | %d | %d | %.2g | %s | %s | %d | %s | %zu | %.4f | %.2f |\n", nb, r->bands,
           r->bands * r->bands, r->lambda, kind_name(r->kind), method_name(r->method),
           r->threads, res, r->st.cells, r->median_s, r->st.memory_bytes / 1048576.0);
}

static void print_header(const char *title)
{
    printf("\n### %s\n\n", title);
    printf("| photons | L | coeffs | lambda | grid | bake | threads | resolution | cells | "
           "median s | memory MiB |\n");
    printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
}

/* ---- Seed 001 comparison: photon list -> kd-tree -> guide with the medium's extinction ---- */

/* sigma_t of the scene's medium at x [1/m], as renderer/bake/bake.c gives it to the bake. */
static double scene_sigma_t(const double x[3], void *user)
{
    const rd_medium *m = rd_scene_medium_at_point(user, v3(x[0], x[1], x[2]));
    return m ? rd_medium_sigma_t(m, v3(x[0], x[1], x[2])) : 0.0;
}

/* Exactly n stored photons of the scene (first-flight collisions included), traced with a
 * fixed seed; tracing is not part of the bake and is not timed. */
static pm_photon *scene_photons(const rd_scene *s, size_t n)
{
    char err[RD_ERRLEN];
    for (size_t emit = n / 2;; emit *= 2) {
        pm_map *m = pm_map_new();
        rd_photon_opts o = {.count = emit, .store_direct = 1, .max_depth = 64, .seed = 1, .threads = 0};
        rd_photon_stats st;
        if (rd_trace_photons(s, &o, m, &st, err, sizeof err) != RD_OK) {
            fprintf(stderr, "bench_sh: %s\n", err);
            exit(1);
        }
        if (pm_map_photon_count(m) >= n) {
            pm_photon *ph = malloc(n * sizeof *ph);
            if (!ph) { fprintf(stderr, "bench_sh: out of memory\n"); exit(1); }
            memcpy(ph, pm_map_photons(m), n * sizeof *ph);
            pm_map_free(m);
            return ph;
        }
        pm_map_free(m);
    }
}

typedef struct {
    double build_s, bake_s, total_s;
    double bake_nosigma_s; /* the same bake without the medium (not part of total_s) */
    sh_guide_stats st;
} timed_bake;

/* The timed part: a new photon map from the photon list, its FLANN kd-tree, and the k-NN bake
 * over the scene's bounds with the cell-mean extinction of the scene's medium. One thread. */
static timed_bake bake_from_photons(const rd_scene *s, const pm_photon *ph, size_t n, int k, double lambda)
{
    timed_bake out;
    char err[256] = "";
    sh_bake_params P;
    sh_bake_params_default(&P);
    P.lo[0] = s->bmin.x, P.lo[1] = s->bmin.y, P.lo[2] = s->bmin.z;
    P.hi[0] = s->bmax.x, P.hi[1] = s->bmax.y, P.hi[2] = s->bmax.z;
    P.bands = 4;
    P.k = k;
    P.lambda = lambda;
    P.threads = 1;
    P.sigma_t = scene_sigma_t;
    P.sigma_t_user = (void *)s;
    sh_phase_coeffs_hg(s->media[0].g, P.bands, P.phase_b);
    double t0 = omp_get_wtime();
    pm_map *m = pm_map_new();
    if (pm_map_add_photons(m, ph, n, err, sizeof err) != PM_OK || pm_map_build(m, err, sizeof err) != PM_OK) {
        fprintf(stderr, "bench_sh: %s\n", err);
        exit(1);
    }
    double t1 = omp_get_wtime();
    sh_guide *g = NULL;
    if (sh_guide_bake(&g, m, &P, err, sizeof err) != SH_OK) {
        fprintf(stderr, "bench_sh: %s\n", err);
        exit(1);
    }
    double t2 = omp_get_wtime();
    sh_guide_stats_get(g, &out.st);
    sh_guide_free(g);
    /* What the old comparison timed: the bake alone from a built map, no sigma_t lookups. */
    P.sigma_t = NULL;
    double t3 = omp_get_wtime();
    if (sh_guide_bake(&g, m, &P, err, sizeof err) != SH_OK) {
        fprintf(stderr, "bench_sh: %s\n", err);
        exit(1);
    }
    out.bake_nosigma_s = omp_get_wtime() - t3;
    sh_guide_free(g);
    pm_map_free(m);
    out.build_s = t1 - t0;
    out.bake_s = t2 - t1;
    out.total_s = t2 - t0;
    return out;
}

static void min_med_max(double *v, int n, double *mn, double *md, double *mx)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    *mn = v[0];
    *mx = v[n - 1];
    *md = n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* s^3 stratified points per cell for the cell-mean extinction (sh.h, sigma_t_samples). */
static int lookups_per_cell(void)
{
    sh_bake_params P;
    sh_bake_params_default(&P);
    return P.sigma_t_samples * P.sigma_t_samples * P.sigma_t_samples;
}

static void seed001_table(result *R, int *nr, int runs, int k)
{
    const char *path = "scenes/default.json";
    const size_t n = 100000;
    rd_scene *s = NULL;
    char err[RD_ERRLEN];
    if (rd_scene_load(&s, path, NULL, 0, err, sizeof err) != RD_OK) {
        fprintf(stderr, "bench_sh: %s\n", err);
        exit(1);
    }
    pm_photon *ph = scene_photons(s, n);
    const double lambdas[2] = {1.0, 16.0};
    double tb[2][16], tk[2][16], tt[2][16], tn[2][16];
    timed_bake last[2];
    /* Interleaved: lambda 1, lambda 16, lambda 1, ... so that other load falls on both. */
    for (int rep = 0; rep < runs; rep++)
        for (int i = 0; i < 2; i++) {
            last[i] = bake_from_photons(s, ph, n, k, lambdas[i]);
            tb[i][rep] = last[i].build_s;
            tk[i][rep] = last[i].bake_s;
            tt[i][rep] = last[i].total_s;
            tn[i][rep] = last[i].bake_nosigma_s;
        }
    printf("\n### Seed 001 comparison (1e5 photons of %s, L = 4, grid by the rule, k-NN, "
           "1 thread, median (min-max) of %d)\n\n", path, runs);
    printf("Timed: photon list -> FLANN kd-tree -> k-NN SH bake with the cell-mean extinction of "
           "the scene's noise medium (%d sigma_t lookups a cell). Not timed: photon tracing.\n\n",
           lookups_per_cell());
    printf("| lambda | resolution | cells | kd-tree build s | bake incl. sigma_t s | total s | paper s | "
           "paper / ours (total) | bake alone, no medium s (not like-for-like) |\n|---|---|---|---|---|---|---|---|---|\n");
    for (int i = 0; i < 2; i++) {
        double a0, a1, a2, b0, b1, b2, c0, c1, c2, d0, d1, d2;
        min_med_max(tn[i], runs, &d0, &d1, &d2);
        min_med_max(tb[i], runs, &a0, &a1, &a2);
        min_med_max(tk[i], runs, &b0, &b1, &b2);
        min_med_max(tt[i], runs, &c0, &c1, &c2);
        const sh_guide_stats *st = &last[i].st;
        printf("| %.0f | %dx%dx%d | %zu | %.4f (%.4f-%.4f) | %.4f (%.4f-%.4f) | %.4f (%.4f-%.4f) | 7.0-8.4 | %.0f-%.0f | %.4f (%.4f-%.4f) |\n",
               lambdas[i], st->res[0], st->res[1], st->res[2], st->cells, a1, a0, a2, b1, b0, b2, c1, c0, c2,
               7.0 / c1, 8.4 / c1, d1, d0, d2);
        result *r = &R[(*nr)++];
        *r = (result){"seed001", n, 4, k, 1, lambdas[i], SH_GRID_UNIFORM, SH_BAKE_KNN, c1, c0, *st};
    }
    free(ph);
    rd_scene_free(s);
}

int main(int argc, char **argv)
{
    int quick = 0, runs = 3, only001 = 0;
    const char *json = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--quick"))
            quick = 1;
        else if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc)
            runs = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--only001"))
            only001 = 1;
        else {
            fprintf(stderr, "usage: %s [--quick] [--json FILE] [--runs N] [--only001]\n", argv[0]);
            return 2;
        }
    }
    if (quick)
        runs = 1;
    if (runs < 1 || runs > 15)
        runs = 3;
    const int k = 50;
    size_t sizes[3] = {100000, 1000000, 10000000};
    int nsizes = quick ? 2 : 3;
    static result R[512];
    int nr = 0;
    double t_all = omp_get_wtime();

    printf("# bench_sh: guide bake (k = %d photons per estimate, HG g = 0.6, unit cube, "
           "clustered photons; median of %d run%s)\n", k, runs, runs > 1 ? "s" : "");
    printf("\nmachine: %d OpenMP threads available", omp_get_max_threads());
    FILE *la = fopen("/proc/loadavg", "r");
    char lbuf[64];
    if (la && fgets(lbuf, sizeof lbuf, la)) {
        lbuf[strcspn(lbuf, "\n")] = 0;
        printf("; load average at start: %s (other work on the machine skews the 2-thread rows)",
               lbuf);
    }
    if (la)
        fclose(la);
    printf("\n");

    pm_map *maps[3] = {NULL, NULL, NULL};
    if (only001)
        nsizes = 0;
    else {
        printf("\n| photons | map build s | map MiB |\n|---|---|---|\n");
        for (int s = 0; s < nsizes; s++) {
            double bs;
            maps[s] = make_map(sizes[s], 1234 + (uint64_t)s, &bs);
            char nb[32];
            fmt_n(sizes[s], nb, sizeof nb);
            printf("| %s | %.2f | %.1f |\n", nb, bs, pm_map_memory_bytes(maps[s]) / 1048576.0);
        }

        /* 1. Photon count x threads (uniform, k-NN, L = 4, lambda = 1). */
        print_header("Photon count and threads (uniform grid by the rule, k-NN, L = 4)");
        for (int s = 0; s < nsizes; s++)
            for (int th = 1; th <= 2; th++) {
                result *r = &R[nr++];
                *r = (result){"photons", sizes[s], 4, k, th, 1.0, SH_GRID_UNIFORM, SH_BAKE_KNN, 0, 0,
                              {0}};
                run(maps[s], r, runs);
                print_row(r);
            }

        /* 2. Band count. */
        int sb = quick ? 0 : 1;
        char title[160], nb0[32];
        fmt_n(sizes[sb], nb0, sizeof nb0);
        snprintf(title, sizeof title, "Band count L (%s photons, uniform, k-NN, 2 threads)", nb0);
        print_header(title);
        for (int L = 1; L <= (quick ? 4 : 8); L++) {
            result *r = &R[nr++];
            *r = (result){"bands", sizes[sb], L, k, 2, 1.0, SH_GRID_UNIFORM, SH_BAKE_KNN, 0, 0, {0}};
            run(maps[sb], r, runs);
            print_row(r);
        }

        /* 3. Quality lambda. */
        snprintf(title, sizeof title, "Quality lambda (%s photons, uniform, k-NN, L = 4, 2 threads)",
                 nb0);
        print_header(title);
        const double lambdas[4] = {0.25, 1.0, 4.0, 16.0};
        for (int i = 0; i < (quick ? 3 : 4); i++) {
            result *r = &R[nr++];
            *r = (result){"lambda", sizes[sb], 4, k, 2, lambdas[i], SH_GRID_UNIFORM, SH_BAKE_KNN, 0,
                          0, {0}};
            run(maps[sb], r, runs);
            print_row(r);
        }

        /* 4. k-NN vs track-length, uniform vs adaptive. */
        print_header("k-NN vs track-length, uniform vs adaptive (L = 4, lambda = 1)");
        for (int s = 0; s < (quick ? 1 : 2); s++)
            for (int kind = 0; kind < 2; kind++)
                for (int method = 0; method < 2; method++)
                    for (int th = 1; th <= 2; th++) {
                        result *r = &R[nr++];
                        *r = (result){"method", sizes[s], 4, k, th, 1.0, (sh_grid_kind)kind,
                                      (sh_bake_method)method, 0, 0, {0}};
                        run(maps[s], r, runs);
                        print_row(r);
                    }
    }

    /* 5. Seed 001 §4, like-for-like (see the header). */
    seed001_table(R, &nr, runs, k);
    printf("\ntotal wall time %.1f s\n", omp_get_wtime() - t_all);

    if (json) {
        FILE *f = fopen(json, "w");
        if (!f) {
            fprintf(stderr, "bench_sh: cannot write %s\n", json);
            return 1;
        }
        fprintf(f, "{\n  \"bench\": \"sh\",\n  \"runs\": %d,\n  \"k\": %d,\n  \"results\": [\n",
                runs, k);
        for (int i = 0; i < nr; i++) {
            const result *r = &R[i];
            fprintf(f,
                    "    {\"table\": \"%s\", \"photons\": %zu, \"bands\": %d, \"lambda\": %g, "
                    "\"grid\": \"%s\", \"bake\": \"%s\", \"threads\": %d, \"res\": [%d, %d, %d], "
                    "\"depth_max\": %d, \"cells\": %zu, \"median_s\": %.6f, \"min_s\": %.6f, "
                    "\"memory_bytes\": %zu}%s\n",
                    r->table, r->photons, r->bands, r->lambda, kind_name(r->kind),
                    method_name(r->method), r->threads, r->st.res[0], r->st.res[1], r->st.res[2],
                    r->st.depth_max, r->st.cells, r->median_s, r->min_s, r->st.memory_bytes,
                    i + 1 < nr ? "," : "");
        }
        fprintf(f, "  ]\n}\n");
        fclose(f);
    }
    for (int s = 0; s < nsizes; s++)
        pm_map_free(maps[s]);
    return 0;
}
