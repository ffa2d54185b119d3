/* bench_photonmap.c: photon map build time, memory and k-NN throughput.
 *
 *   bench_photonmap [--quick] [--reps R] [--json FILE]
 *
 * For N = 1e5, 1e6, 1e7 photons (--quick: 1e5 and 1e6) drawn from a clustered distribution
 * (Gaussian blobs of different sizes plus a uniform background in the unit box, closer to a
 * real photon map than a uniform cloud), it measures:
 *   - the kd-tree build time (pm_map_build),
 *   - memory per photon (pm_map_memory_bytes / N: photons + index),
 *   - k-NN queries per second for k = 16, 64, 256 through pm_map_knn_batch with 1 and 2
 *     threads, on query points drawn from the same distribution.
 * Every timing is repeated R times (default 5) and the median is reported. The number of
 * queries per timing is calibrated to take about a quarter of a second on one thread.
 * Prints a markdown table; --json also writes the numbers to FILE.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "photonmap.h"

#define NBLOBS 32
#define MAX_REPS 50

typedef struct {
    uint64_t s;
} splitmix64;

/* SplitMix64 (Steele, Lea, Flood 2014). */
static uint64_t sm_next(splitmix64 *r)
{
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static double sm_uniform(splitmix64 *r) /* [0, 1) */
{
    return (double)(sm_next(r) >> 11) * (1.0 / 9007199254740992.0);
}

static double sm_normal(splitmix64 *r) /* Box-Muller */
{
    double u1 = sm_uniform(r), u2 = sm_uniform(r);
    return sqrt(-2.0 * log(1.0 - u1)) * cos(6.283185307179586 * u2);
}

typedef struct {
    double c[3], sigma, cdf;
} blob;

/* The mixture: NBLOBS Gaussian blobs (centres in [0.15, 0.85]^3, sigma log-uniform in
 * [0.01, 0.1], random weights) holding 80% of the photons, 20% uniform background. */
static void make_blobs(blob *b, uint64_t seed)
{
    splitmix64 r = {seed};
    double total = 0.0;
    for (int i = 0; i < NBLOBS; i++) {
        for (int a = 0; a < 3; a++)
            b[i].c[a] = 0.15 + 0.7 * sm_uniform(&r);
        b[i].sigma = 0.01 * pow(10.0, sm_uniform(&r));
        total += 0.2 + sm_uniform(&r);
        b[i].cdf = total;
    }
    for (int i = 0; i < NBLOBS; i++)
        b[i].cdf /= total;
}

static void sample_point(const blob *b, splitmix64 *r, float p[3])
{
    if (sm_uniform(r) < 0.2) {
        for (int a = 0; a < 3; a++)
            p[a] = (float)sm_uniform(r);
        return;
    }
    double u = sm_uniform(r);
    int i = 0;
    while (i < NBLOBS - 1 && b[i].cdf < u)
        i++;
    for (;;) { /* redraw until inside the unit box */
        int inside = 1;
        for (int a = 0; a < 3; a++) {
            double v = b[i].c[a] + b[i].sigma * sm_normal(r);
            inside = inside && v >= 0.0 && v < 1.0;
            p[a] = (float)v;
        }
        if (inside)
            return;
    }
}

static pm_photon *make_photons(const blob *b, size_t n, uint64_t seed)
{
    pm_photon *ph = malloc(n * sizeof *ph);
    if (ph == NULL)
        return NULL;
    splitmix64 r = {seed};
    for (size_t i = 0; i < n; i++) {
        sample_point(b, &r, ph[i].pos);
        double z = 2.0 * sm_uniform(&r) - 1.0, phi = 6.283185307179586 * sm_uniform(&r);
        double s = sqrt(1.0 - z * z);
        ph[i].dir[0] = (float)(s * cos(phi));
        ph[i].dir[1] = (float)(s * sin(phi));
        ph[i].dir[2] = (float)z;
        for (int a = 0; a < 3; a++)
            ph[i].power[a] = 1.0f / (float)n;
    }
    return ph;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static void die(const char *what, const char *err)
{
    fprintf(stderr, "bench_photonmap: %s: %s\n", what, err);
    exit(1);
}

/* Seconds for one batch k-NN run over nq queries. */
static double time_batch(const pm_map *m, const double *q, size_t nq, int k, int *idx,
                         float *d2, int threads)
{
    char err[256];
    double t0 = now();
    if (pm_map_knn_batch(m, q, nq, k, idx, d2, threads, err, sizeof err) != PM_OK)
        die("pm_map_knn_batch", err);
    return now() - t0;
}

typedef struct {
    int k;
    size_t nq;
    double qps1, qps2;
    int identical;
} knn_row;

typedef struct {
    size_t n;
    double build_s, bytes_per_photon;
    knn_row knn[3];
} size_row;

int main(int argc, char **argv)
{
    int quick = 0, reps = 5;
    const char *json = NULL;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--quick") == 0) {
            quick = 1;
        } else if (strcmp(argv[i], "--json") == 0 && i + 1 < argc) {
            json = argv[++i];
        } else if (strcmp(argv[i], "--reps") == 0 && i + 1 < argc) {
            reps = atoi(argv[++i]);
            if (reps < 1 || reps > MAX_REPS)
                die("--reps", "expected 1..50");
        } else {
            fprintf(stderr, "usage: %s [--quick] [--reps R] [--json FILE]\n", argv[0]);
            return 2;
        }
    }
    const size_t sizes[3] = {100000, 1000000, 10000000};
    const int ks[3] = {16, 64, 256};
    const int nsizes = quick ? 2 : 3;
    const size_t max_nq = 200000;
    size_row rows[3];
    blob blobs[NBLOBS];
    make_blobs(blobs, 12345);
    char err[256];
    /* Context for the numbers: other work on the machine competes for the cores. */
    char load_before[32] = "unknown";
    FILE *lf = fopen("/proc/loadavg", "r");
    if (lf != NULL) {
        if (fscanf(lf, "%31s", load_before) != 1)
            strcpy(load_before, "unknown");
        fclose(lf);
    }

    float *qf = malloc(max_nq * 3 * sizeof(float));
    double *q = malloc(max_nq * 3 * sizeof(double)); /* queries are world points in double */
    int *idx1 = malloc(max_nq * 256 * sizeof(int)), *idx2 = malloc(max_nq * 256 * sizeof(int));
    float *d1 = malloc(max_nq * 256 * sizeof(float)), *d2 = malloc(max_nq * 256 * sizeof(float));
    if (!qf || !q || !idx1 || !idx2 || !d1 || !d2)
        die("malloc", "out of memory");
    splitmix64 qr = {999};
    for (size_t j = 0; j < max_nq; j++) {
        sample_point(blobs, &qr, qf + 3 * j);
        for (int a = 0; a < 3; a++) q[3 * j + a] = qf[3 * j + a];
    }

    for (int s = 0; s < nsizes; s++) {
        size_t n = sizes[s];
        size_row *row = &rows[s];
        row->n = n;
        fprintf(stderr, "N = %zu: generating...\n", n);
        pm_photon *ph = make_photons(blobs, n, 1000 + (uint64_t)s);
        if (ph == NULL)
            die("malloc", "out of memory for photons");

        /* Build R times from scratch; keep the last map for the queries. */
        double tb[MAX_REPS];
        pm_map *m = NULL;
        for (int r = 0; r < reps; r++) {
            pm_map_free(m);
            m = pm_map_new();
            if (m == NULL || pm_map_add_photons(m, ph, n, err, sizeof err) != PM_OK)
                die("pm_map_add_photons", err);
            double t0 = now();
            if (pm_map_build(m, err, sizeof err) != PM_OK)
                die("pm_map_build", err);
            tb[r] = now() - t0;
        }
        row->build_s = median(tb, reps);
        row->bytes_per_photon = (double)pm_map_memory_bytes(m) / (double)n;
        free(ph);
        fprintf(stderr, "  build %.3f s, %.1f B/photon\n", row->build_s, row->bytes_per_photon);

        for (int t = 0; t < 3; t++) {
            int k = ks[t];
            knn_row *kr = &row->knn[t];
            kr->k = k;
            /* calibrate: about 0.25 s per timing on one thread */
            size_t probe = 1000;
            double tp = time_batch(m, q, probe, k, idx1, d1, 1);
            double want = 0.25 / (tp / (double)probe);
            kr->nq = want < 2000 ? 2000 : (want > (double)max_nq ? max_nq : (size_t)want);
            double t1[MAX_REPS], t2[MAX_REPS];
            for (int r = 0; r < reps; r++) {
                t1[r] = (double)kr->nq / time_batch(m, q, kr->nq, k, idx1, d1, 1);
                t2[r] = (double)kr->nq / time_batch(m, q, kr->nq, k, idx2, d2, 2);
            }
            kr->qps1 = median(t1, reps);
            kr->qps2 = median(t2, reps);
            kr->identical = memcmp(idx1, idx2, kr->nq * (size_t)k * sizeof(int)) == 0 &&
                            memcmp(d1, d2, kr->nq * (size_t)k * sizeof(float)) == 0;
            fprintf(stderr, "  k = %d: %.0f / %.0f queries/s\n", k, kr->qps1, kr->qps2);
        }
        pm_map_free(m);
    }

    printf("Photon map benchmark: clustered photons (%d Gaussian blobs + 20%% uniform) in the "
           "unit box; median of %d runs; 1-min load average before the run: %s.\n\n",
           NBLOBS, reps, load_before);
    printf("| photons | build (s) | bytes/photon | k | queries | k-NN/s 1 thread | k-NN/s 2 "
           "threads | speedup | same answers |\n");
    printf("|---:|---:|---:|---:|---:|---:|---:|---:|:---:|\n");
    for (int s = 0; s < nsizes; s++) {
        for (int t = 0; t < 3; t++) {
            const knn_row *kr = &rows[s].knn[t];
            if (t == 0)
                printf("| %.0e | %.3f | %.1f ", (double)rows[s].n, rows[s].build_s,
                       rows[s].bytes_per_photon);
            else
                printf("| | | ");
            printf("| %d | %zu | %.0f | %.0f | %.2f | %s |\n", kr->k, kr->nq, kr->qps1, kr->qps2,
                   kr->qps2 / kr->qps1, kr->identical ? "yes" : "NO");
        }
    }

    if (json != NULL) {
        FILE *f = fopen(json, "w");
        if (f == NULL)
            die(json, "cannot open for writing");
        fprintf(f, "{\n  \"distribution\": \"%d gaussian blobs + 20%% uniform, unit box\",\n",
                NBLOBS);
        fprintf(f, "  \"reps\": %d,\n  \"statistic\": \"median\",\n", reps);
        fprintf(f, "  \"loadavg_1min_before\": \"%s\",\n  \"sizes\": [\n", load_before);
        for (int s = 0; s < nsizes; s++) {
            fprintf(f,
                    "    {\"photons\": %zu, \"build_seconds\": %.6f, \"bytes_per_photon\": %.2f, "
                    "\"knn\": [\n",
                    rows[s].n, rows[s].build_s, rows[s].bytes_per_photon);
            for (int t = 0; t < 3; t++) {
                const knn_row *kr = &rows[s].knn[t];
                fprintf(f,
                        "      {\"k\": %d, \"queries\": %zu, \"qps_1thread\": %.1f, "
                        "\"qps_2threads\": %.1f, \"identical\": %s}%s\n",
                        kr->k, kr->nq, kr->qps1, kr->qps2, kr->identical ? "true" : "false",
                        t < 2 ? "," : "");
            }
            fprintf(f, "    ]}%s\n", s < nsizes - 1 ? "," : "");
        }
        fprintf(f, "  ]\n}\n");
        if (fclose(f) != 0)
            die(json, "write failed");
    }
    free(q);
    free(qf);
    free(idx1);
    free(idx2);
    free(d1);
    free(d2);
    return 0;
}
