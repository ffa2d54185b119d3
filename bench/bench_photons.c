/* bench_photons: photon tracing rate on the example scenes (issue 4): photons emitted per
 * second with 1 and 2 threads, stored photons per emitted photon, FLANN index build time and
 * memory per photon. Medians of repeated runs taken in one process. Not a test.
 *
 *   build/bench/bench_photons [--quick] [--json FILE]
 */
#include "bake/rd_photons.h"

#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    int quick = 0;
    const char *json = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--quick")) quick = 1;
        else if (!strcmp(argv[i], "--json") && i + 1 < argc) json = argv[++i];
        else { fprintf(stderr, "usage: bench_photons [--quick] [--json FILE]\n"); return 1; }
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
