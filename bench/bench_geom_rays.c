/* bench_geom_rays: Embree intersection throughput beside the media cost (issue 14's target,
 * docs/benchmarks.md "Surfaces (issue 14)"): where a camera sample's time goes in a scene with
 * shapes. For each scene, on fixed sets of N rays (one thread), the time per ray of:
 *
 *   isect-camera    rd_scene_intersect on camera rays (uniform random film positions), tmax = inf
 *   isect-random    rd_scene_intersect on random rays: origin uniform in the media bounds,
 *                   direction uniform on the sphere
 *   region-at       rd_scene_region_at at those random origins (the region query every camera
 *                   sample and every photon makes: two or three ray queries, scene/queries.c)
 *   flight-camera   rd_sample_free_path of a camera ray in the camera's region, clipped at its
 *                   first surface (the first flight of a delta path)
 *   tr-camera       rd_transmittance over the same interval (a shadow ray's medium part)
 *   flight-inside   rd_sample_free_path inside the shape a camera ray hits, from the entry
 *                   point straight on to the exit (refraction ignored: the cost of one flight
 *                   in the dense medium, not a transport estimate)
 *   delta-path      rd_delta_radiance of a camera ray: a whole `delta` sample (region query,
 *                   every flight, surface event and next-event estimate of the path)
 *
 * and, per operation, the tracker's counters per ray (tentative collisions, shadow rays). The
 * operations are timed interleaved (all of them once, K times over), so load from other users
 * of the machine falls on all alike; the median and min-max over the K repeats are printed,
 * and every cost also as a multiple of isect-camera's median in the same run.
 *
 * Usage: bench_geom_rays [--quick] [--rays N] [--repeats K] [--json FILE] [SCENE.json ...]
 * (default scenes: scenes/exp1-point.json scenes/exp2-directional.json scenes/glass-fog.json;
 * run from the repository root). */
#include "transport/rd_path.h"
#include "scene/rd_geom.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}
static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}
static double median(const double *v0, int n)
{
    double v[64];
    memcpy(v, v0, (size_t)n * sizeof *v);
    qsort(v, (size_t)n, sizeof *v, cmp_d);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}
static double vmin(const double *v, int n) { double m = v[0]; for (int i = 1; i < n; i++) m = v[i] < m ? v[i] : m; return m; }
static double vmax(const double *v, int n) { double m = v[0]; for (int i = 1; i < n; i++) m = v[i] > m ? v[i] : m; return m; }

enum { OP_ISECT_CAM, OP_ISECT_RND, OP_REGION, OP_FLIGHT_CAM, OP_TR_CAM, OP_FLIGHT_IN, OP_DELTA, N_OPS };
static const char *op_name[N_OPS] = {"isect-camera", "isect-random", "region-at", "flight-camera",
                                     "tr-camera", "flight-inside", "delta-path"};

typedef struct {
    const rd_scene *s;
    int n;                 /* rays per set */
    ray3 *cam, *rnd;       /* camera rays, random rays */
    double *cam_t;         /* camera ray: distance to its first surface, or to the media bounds' exit */
    int cam_region;        /* the camera's region (a pinhole: one for every camera ray) */
    ray3 *in;              /* rays inside a shape: from a camera ray's entry point, straight on */
    double *in_t;          /* ... to the exit */
    int *in_region;
    int n_in;
    volatile double sink;  /* keeps the results alive */
} bench_set;

/* One pass of operation op over its rays; returns the rays done, adds the counters to *c. */
static int run_op(bench_set *b, int op, uint64_t pass, rd_track_counters *c)
{
    const rd_scene *s = b->s;
    double acc = 0;
    rd_hit h;
    int n = op == OP_FLIGHT_IN ? b->n_in : b->n;
    for (int i = 0; i < n; i++) {
        pcg32 rng = pcg32_seed((uint64_t)i, pass * N_OPS + (uint64_t)op, 12345);
        switch (op) {
        case OP_ISECT_CAM: acc += rd_scene_intersect(s, b->cam[i], INFINITY, NULL, &h) ? h.t : 0; break;
        case OP_ISECT_RND: acc += rd_scene_intersect(s, b->rnd[i], INFINITY, NULL, &h) ? h.t : 0; break;
        case OP_REGION: acc += rd_scene_region_at(s, b->rnd[i].o); break;
        case OP_FLIGHT_CAM: {
            rd_collision col = rd_sample_free_path(s, b->cam_region, b->cam[i], b->cam_t[i], &rng, c);
            acc += col.hit ? col.t : 0;
            break;
        }
        case OP_TR_CAM:
            c->shadow_rays++;
            acc += rd_transmittance(s, b->cam_region, b->cam[i], 0, b->cam_t[i], &rng, c);
            break;
        case OP_FLIGHT_IN: {
            rd_collision col = rd_sample_free_path(s, b->in_region[i], b->in[i], b->in_t[i], &rng, c);
            acc += col.hit ? col.t : 0;
            break;
        }
        case OP_DELTA: acc += rd_delta_radiance(s, b->cam[i], &rng, c).x; break;
        }
    }
    b->sink = acc;
    return n;
}

static int bench_scene(const char *path, int n, int K, FILE *json, int first)
{
    char err[1024];
    rd_scene *s = NULL;
    if (rd_scene_load(&s, path, NULL, 0, err, sizeof err) != RD_OK) {
        fprintf(stderr, "bench_geom_rays: %s\n", err);
        return 1;
    }
    bench_set b = {.s = s, .n = n};
    b.cam = malloc((size_t)n * sizeof *b.cam);
    b.rnd = malloc((size_t)n * sizeof *b.rnd);
    b.cam_t = malloc((size_t)n * sizeof *b.cam_t);
    b.in = malloc((size_t)n * sizeof *b.in);
    b.in_t = malloc((size_t)n * sizeof *b.in_t);
    b.in_region = malloc((size_t)n * sizeof *b.in_region);
    if (!b.cam || !b.rnd || !b.cam_t || !b.in || !b.in_t || !b.in_region) {
        fprintf(stderr, "bench_geom_rays: out of memory\n");
        return 1;
    }
    /* The ray sets (fixed seed, made before any timing). */
    pcg32 g = pcg32_seed(1, 2, 3);
    const rd_camera *cam = &s->camera;
    b.cam_region = rd_scene_region_at(s, rd_camera_ray(cam, 0.5 * cam->width, 0.5 * cam->height).o);
    long hits = 0;
    for (int i = 0; i < n; i++) {
        ray3 r = rd_camera_ray(cam, pcg32_uniform(&g) * cam->width, pcg32_uniform(&g) * cam->height);
        b.cam[i] = r;
        double t0 = 0, t1 = 0, tb = rd_box_intersect(s->bmin, s->bmax, r, 0, INFINITY, &t0, &t1) ? t1 : 0;
        rd_hit h, h2;
        if (rd_scene_intersect(s, r, INFINITY, NULL, &h)) {
            hits++;
            b.cam_t[i] = h.t < tb ? h.t : tb;
            if (h.shape >= 0 && h.front) {
                ray3 ri = {h.p, r.d};
                if (rd_scene_intersect(s, ri, INFINITY, &h, &h2) && h2.shape == h.shape) {
                    b.in[b.n_in] = ri;
                    b.in_t[b.n_in] = h2.t;
                    b.in_region[b.n_in] = h.medium_to;
                    b.n_in++;
                }
            }
        } else {
            b.cam_t[i] = tb;
        }
        vec3 o = {s->bmin.x + pcg32_uniform(&g) * (s->bmax.x - s->bmin.x),
                  s->bmin.y + pcg32_uniform(&g) * (s->bmax.y - s->bmin.y),
                  s->bmin.z + pcg32_uniform(&g) * (s->bmax.z - s->bmin.z)};
        ray3 rr = {o, rd_sample_sphere(pcg32_uniform(&g), pcg32_uniform(&g))};
        b.rnd[i] = rr;
    }
    /* Interleaved timing: every operation once per repeat. */
    double t[N_OPS][64];
    rd_track_counters cnt[N_OPS];
    memset(cnt, 0, sizeof cnt);
    int rays[N_OPS] = {0};
    for (int op = 0; op < N_OPS; op++) { /* warm-up (caches, page faults), not timed */
        rd_track_counters c0 = {0};
        run_op(&b, op, 1000, &c0);
    }
    for (int k = 0; k < K; k++)
        for (int op = 0; op < N_OPS; op++) {
            rd_track_counters c = {0};
            double t0 = now_s();
            int m = run_op(&b, op, (uint64_t)k, &c);
            t[op][k] = (now_s() - t0) / (m > 0 ? m : 1);
            rays[op] += m;
            cnt[op].collisions += c.collisions;
            cnt[op].lookups += c.lookups;
            cnt[op].shadow_rays += c.shadow_rays;
        }
    double base = median(t[OP_ISECT_CAM], K);
    printf("\n### %s\n\n", path);
    printf("%d rays per set (%ld camera rays hit a surface or light; %d enter a shape), one thread, "
           "%d repeats: median [min - max]\n\n", n, hits, b.n_in, K);
    printf("| operation | Mrays/s | us/ray | x isect-camera | collisions/ray | shadow rays/ray |\n");
    printf("|---|---|---|---|---|---|\n");
    if (json) fprintf(json, "%s{\"scene\": \"%s\", \"rays\": %d, \"repeats\": %d, \"ops\": [", first ? "" : ",\n", path, n, K);
    for (int op = 0; op < N_OPS; op++) {
        double md = median(t[op], K), lo = vmin(t[op], K), hi = vmax(t[op], K);
        double rn = rays[op] > 0 ? (double)rays[op] : 1;
        printf("| %s | %.3g [%.3g - %.3g] | %.3g | %.1f | %.2f | %.2f |\n", op_name[op], 1e-6 / md, 1e-6 / hi,
               1e-6 / lo, 1e6 * md, md / base, cnt[op].collisions / rn, cnt[op].shadow_rays / rn);
        if (json)
            fprintf(json, "%s{\"op\": \"%s\", \"s_per_ray_median\": %.6g, \"s_per_ray_min\": %.6g, "
                          "\"s_per_ray_max\": %.6g, \"collisions_per_ray\": %.6g, \"shadow_rays_per_ray\": %.6g}",
                    op ? ", " : "", op_name[op], md, lo, hi, cnt[op].collisions / rn, cnt[op].shadow_rays / rn);
    }
    if (json) fprintf(json, "]}");
    free(b.cam); free(b.rnd); free(b.cam_t); free(b.in); free(b.in_t); free(b.in_region);
    rd_scene_free(s);
    return 0;
}

int main(int argc, char **argv)
{
    int n = 200000, K = 7;
    const char *json_path = NULL;
    const char *scenes[64];
    int ns = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--quick")) { n = 20000; K = 3; }
        else if (!strcmp(argv[i], "--rays") && i + 1 < argc) n = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--repeats") && i + 1 < argc) K = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--json") && i + 1 < argc) json_path = argv[++i];
        else if (argv[i][0] != '-' && ns < 64) scenes[ns++] = argv[i];
        else {
            fprintf(stderr, "usage: bench_geom_rays [--quick] [--rays N] [--repeats K] [--json FILE] [SCENE.json ...]\n");
            return 2;
        }
    }
    if (n < 1 || K < 1 || K > 64) {
        fprintf(stderr, "bench_geom_rays: --rays must be >= 1 and --repeats in [1, 64]\n");
        return 2;
    }
    if (!ns) {
        scenes[ns++] = "scenes/exp1-point.json";
        scenes[ns++] = "scenes/exp2-directional.json";
        scenes[ns++] = "scenes/glass-fog.json";
    }
    FILE *json = NULL;
    if (json_path && !(json = fopen(json_path, "w"))) {
        fprintf(stderr, "bench_geom_rays: %s: cannot write\n", json_path);
        return 1;
    }
    if (json) fprintf(json, "{\"bench\": \"geom_rays\", \"scenes\": [\n");
    int rc = 0;
    for (int i = 0; i < ns && !rc; i++) rc = bench_scene(scenes[i], n, K, json, i == 0);
    if (json) {
        fprintf(json, "\n]}\n");
        fclose(json);
    }
    return rc;
}
