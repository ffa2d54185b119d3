/* bench_photons: photon tracing rate on the example scenes (issue 4): photons emitted per
 * second with 1 and 2 threads, stored photons per emitted photon, FLANN index build time and
 * memory per photon. Medians of repeated runs taken in one process. Not a test.
 * First, the cost of the noise density that tracing in default.json spends most of its lookups
 * on (issue 21): one fBm evaluation with the gradient table (rd_noise_fbm) against Perlin's
 * 2002 branches on the hash (tests/support/perlin_2002.h), and the tracker's accept test with
 * the early exit (rd_medium_sigma_above) against the full density, interleaved, medians of 5.
 *
 *   build/bench/bench_photons [--quick] [--noise-only] [--json FILE]
 * bench/bench_bake.sh times the whole `photonmarch bake` (trace, index, guide) of one or more
 * builds against each other.
 */
#include "bake/rd_photons.h"
#include "../tests/support/perlin_2002.h"

#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static double fbm_2002(const rd_noise *n, vec3 x)
{
    double sum = 0.0, amp = 1.0, f = n->frequency;
    vec3 q = v3_sub(x, n->center);
    for (int o = 0; o < n->octaves; o++) {
        sum += amp * perlin_noise_2002(n, v3_scale(q, f));
        amp *= n->gain;
        f *= n->lacunarity;
    }
    return sum;
}

/* ns per call of four evaluations at the same NP points of the medium's bounds: fBm by the
 * table and by the 2002 formula; sigma_t compared with u sigma_maj (u uniform, the global
 * majorant) by the early exit and by the full density. Interleaved, median of 5. */
static void bench_noise(const rd_medium *m, int quick)
{
    enum { NP = 1 << 18 };
    const int reps = 5, calls = quick ? 2 : 8;
    vec3 *x = malloc(NP * sizeof *x);
    double *thr = malloc(NP * sizeof *thr), t[4][5], sink = 0.0;
    if (!x || !thr) { free(x); free(thr); return; }
    pcg32 g = pcg32_seed(21, 1, 0);
    for (int i = 0; i < NP; i++) {
        x[i] = v3(m->bmin.x + (m->bmax.x - m->bmin.x) * pcg32_uniform(&g),
                  m->bmin.y + (m->bmax.y - m->bmin.y) * pcg32_uniform(&g),
                  m->bmin.z + (m->bmax.z - m->bmin.z) * pcg32_uniform(&g));
        thr[i] = pcg32_uniform(&g) * m->sigma_maj;
    }
    for (int r = 0; r < reps; r++)
        for (int v = 0; v < 4; v++) {
            double t0 = now_s();
            for (int c = 0; c < calls; c++)
                for (int i = 0; i < NP; i++) {
                    if (v == 0) sink += rd_noise_fbm(&m->noise, x[i]);
                    else if (v == 1) sink += fbm_2002(&m->noise, x[i]);
                    else if (v == 2) sink += rd_medium_sigma_above(m, x[i], m->sigma_t_scale, thr[i]);
                    else sink += thr[i] < rd_medium_density(m, x[i]) * m->sigma_t_scale;
                }
            t[v][r] = (now_s() - t0) / ((double)calls * NP) * 1e9;
        }
    for (int v = 0; v < 4; v++) qsort(t[v], reps, sizeof t[v][0], cmp_d);
    printf("noise (scenes/default.json's medium, %d octaves; %d points x %d, median of %d, ns per call):\n",
           m->noise.octaves, NP, calls, reps);
    printf("| evaluation | ns/call | min-max |\n|---|---:|---|\n");
    const char *what[4] = {"fBm, gradient table (rd_noise_fbm)", "fBm, Perlin 2002 branches",
                           "accept test u sigma_maj < sigma_t, early exit (rd_medium_sigma_above)",
                           "accept test by the full density"};
    for (int v = 0; v < 4; v++) printf("| %s | %.1f | %.1f-%.1f |\n", what[v], t[v][reps / 2], t[v][0], t[v][reps - 1]);
    printf("(checksum %g)\n\n", sink);
    free(x);
    free(thr);
}

int main(int argc, char **argv)
{
    int quick = 0, noise_only = 0;
    const char *json = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--quick")) quick = 1;
        else if (!strcmp(argv[i], "--noise-only")) noise_only = 1;
        else if (!strcmp(argv[i], "--json") && i + 1 < argc) json = argv[++i];
        else { fprintf(stderr, "usage: bench_photons [--quick] [--noise-only] [--json FILE]\n"); return 1; }
    }
    {
        char err[RD_ERRLEN];
        rd_scene *s;
        if (rd_scene_load(&s, "scenes/default.json", NULL, 0, err, sizeof err) != RD_OK) {
            fprintf(stderr, "%s\n", err);
            return 1;
        }
        bench_noise(&s->media[0], quick);
        rd_scene_free(s);
        if (noise_only) return 0;
    }
    const char *scenes[] = {"scenes/default.json", "scenes/cloud.json", "scenes/homogeneous.json"};
    const size_t counts[] = {100000, 1000000};
    const int runs = quick ? 1 : 3;
    FILE *js = json ? fopen(json, "w") : NULL;
    if (js) fprintf(js, "{\n  \"runs\": %d,\n  \"results\": [\n", runs);
    printf("| scene | photons | threads | median s | photons/s | stored/emitted | index build s | bytes/photon |\n");
    printf("|---|---:|---:|---:|---:|---:|---:|---:|\n");
    int first = 1;
    for (int si = 0; si < 3; si++) {
        char err[RD_ERRLEN];
        rd_scene *s;
        if (rd_scene_load(&s, scenes[si], NULL, 0, err, sizeof err) != RD_OK) {
            fprintf(stderr, "%s\n", err);
            return 1;
        }
        for (int ci = 0; ci < (quick ? 1 : 2); ci++)
            for (int th = 1; th <= 2; th++) {
                double t[5], build = 0;
                size_t stored = 0, mem = 0;
                for (int r = 0; r < runs; r++) {
                    pm_map *map = pm_map_new();
                    rd_photon_opts o = {.count = counts[ci], .store_direct = 1, .max_depth = 64, .seed = 1 + r, .threads = th};
                    rd_photon_stats st;
                    if (rd_trace_photons(s, &o, map, &st, err, sizeof err) != RD_OK) { fprintf(stderr, "%s\n", err); return 1; }
                    t[r] = st.seconds;
                    stored = st.stored;
                    if (th == 1 && r == 0) {
                        char e2[256];
                        pm_map_build(map, e2, sizeof e2);
                        build = pm_map_build_seconds(map);
                        mem = pm_map_memory_bytes(map);
                    }
                    pm_map_free(map);
                }
                qsort(t, runs, sizeof t[0], cmp_d);
                double med = t[runs / 2];
                char extra[64] = "| |";
                if (th == 1) snprintf(extra, sizeof extra, "%.3f | %.1f |", build, stored ? (double)mem / stored : 0.0);
                printf("| %s | %zu | %d | %.3f | %.0f | %.2f | %s\n", scenes[si], counts[ci], th, med,
                       counts[ci] / med, (double)stored / counts[ci], extra);
                if (js) {
                    fprintf(js, "%s    {\"scene\": \"%s\", \"photons\": %zu, \"threads\": %d, \"median_s\": %.6f, \"photons_per_s\": %.1f, \"stored_per_emitted\": %.4f",
                            first ? "" : ",\n", scenes[si], counts[ci], th, med, counts[ci] / med, (double)stored / counts[ci]);
                    if (th == 1) fprintf(js, ", \"index_build_s\": %.6f, \"bytes_per_photon\": %.2f", build, stored ? (double)mem / stored : 0.0);
                    fprintf(js, "}");
                    first = 0;
                }
            }
        rd_scene_free(s);
    }
    if (js) { fprintf(js, "\n  ]\n}\n"); fclose(js); }
    return 0;
}
