/* bench_sh.c: guide-grid bake time and memory (sh/; THEORY.md §5; seed 001 §3.1, §4).
 *
 *   bench_sh [--quick] [--json FILE] [--runs N]
 *
 * Synthetic clustered photons (Gaussian blobs plus a uniform background in the unit cube,
 * directions biased toward +x, one path segment per photon of exponential length) are stored
 * in a photon map; the map build is not timed. Each configuration is baked --runs times
 * (default 3, --quick 1) and the median wall time is reported, with the guide's memory.
 * Tables: photon count x threads; band count L = 1..8; quality lambda; k-NN vs track-length
 * for both grid kinds; and seed 001's reported 7.0-8.4 s for 1e5 photons, 16 coefficients on
 * a 2.8 GHz Pentium 4 against ours for the same work. Prints markdown. */
#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap.h"
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

int main(int argc, char **argv)
{
    int quick = 0, runs = 3;
    const char *json = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--quick"))
            quick = 1;
        else if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc)
            runs = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: %s [--quick] [--json FILE] [--runs N]\n", argv[0]);
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

    /* 5. Seed 001 §4: 1e5 photons, 16 coefficients, the rule's grid: 7.0 s / 8.4 s on a
     * 2.8 GHz Pentium 4 (their n and lambda are not given; ours: n = k = 50, lambda = 1, and
     * we bake RGB, 3 x 16 coefficients per cell). */
    printf("\n### Seed 001 comparison (1e5 photons, L = 4, grid by the rule, k-NN, 1 thread)\n\n");
    printf("| lambda | resolution | cells | ours median s | paper s | paper / ours |\n");
    printf("|---|---|---|---|---|---|\n");
    for (int i = 0; i < 2; i++) {
        result *r = &R[nr++];
        *r = (result){"seed001", sizes[0], 4, k, 1, i == 0 ? 1.0 : 16.0, SH_GRID_UNIFORM,
                      SH_BAKE_KNN, 0, 0, {0}};
        run(maps[0], r, runs);
        printf("| %.0f | %dx%dx%d | %zu | %.4f | 7.0-8.4 | %.0f-%.0f |\n", r->lambda, r->st.res[0],
               r->st.res[1], r->st.res[2], r->st.cells, r->median_s, 7.0 / r->median_s,
               8.4 / r->median_s);
    }
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
