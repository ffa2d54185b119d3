/* render.c: the camera, and progressive rendering over tiles with OpenMP.
 *
 * Determinism (DESIGN.md convention 6): sample i of pixel p draws from the PCG32 stream seeded by
 * (p, i, seed), and each pixel's sum is accumulated by one thread in sample order, so an image
 * is the same bit for bit whatever the thread count or the pass sizes. */
#include "rd_internal.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define TILE 16

ray3 rd_camera_ray(const rd_camera *cam, double px, double py)
{
    /* Film plane: x to the right, y down; sx, sy in [-1, 1] scaled by the aspect ratio. */
    double aspect = (double)cam->width / cam->height;
    double sx = (2.0 * px / cam->width - 1.0) * aspect;
    double sy = 1.0 - 2.0 * py / cam->height;
    ray3 r;
    if (cam->kind == RD_CAM_PERSPECTIVE) {
        double th = tan(0.5 * cam->fov_deg * M_PI / 180.0);
        r.o = cam->pos;
        r.d = v3_norm(v3_add(cam->forward, v3_add(v3_scale(cam->right, sx * th), v3_scale(cam->up, sy * th))));
    } else {
        double half = 0.5 * cam->ortho_width / aspect; /* half the view height */
        r.o = v3_add(cam->pos, v3_add(v3_scale(cam->right, sx * half), v3_scale(cam->up, sy * half)));
        r.d = cam->forward;
    }
    return r;
}

const char *rd_methods(void) { return "delta"; }

void rd_image_free_pixels(rd_image *img)
{
    if (!img) return;
    free(img->rgb);
    img->rgb = NULL;
}

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* Render samples [s0, s1) of every pixel into the running sums. */
static void render_pass(const rd_scene *s, uint64_t seed, int nthreads, int s0, int s1, double *sum,
                        rd_track_counters *tc, uint64_t *shadow, uint64_t *invalid)
{
    const rd_camera *cam = &s->camera;
    int tiles_x = (cam->width + TILE - 1) / TILE, tiles_y = (cam->height + TILE - 1) / TILE;
    uint64_t coll = 0, look = 0, shad = 0, bad = 0;
#pragma omp parallel for num_threads(nthreads) schedule(dynamic, 1) reduction(+ : coll, look, shad, bad)
    for (int tile = 0; tile < tiles_x * tiles_y; tile++) {
        int x0 = (tile % tiles_x) * TILE, y0 = (tile / tiles_x) * TILE;
        rd_track_counters c = {0, 0};
        uint64_t sh = 0;
        for (int y = y0; y < y0 + TILE && y < cam->height; y++)
            for (int x = x0; x < x0 + TILE && x < cam->width; x++) {
                uint64_t pix = (uint64_t)y * cam->width + x;
                double *acc = &sum[3 * pix];
                for (int i = s0; i < s1; i++) {
                    pcg32 rng = pcg32_seed(pix, (uint64_t)i, seed);
                    double jx = pcg32_uniform(&rng), jy = pcg32_uniform(&rng);
                    ray3 r = rd_camera_ray(cam, x + jx, y + jy);
                    vec3 L = rd_delta_radiance(s, r, &rng, &c, &sh);
                    /* A non-finite sample would poison the pixel: drop and count it. */
                    if (!v3_finite(L)) { bad++; continue; }
                    acc[0] += L.x;
                    acc[1] += L.y;
                    acc[2] += L.z;
                }
            }
        coll += c.collisions;
        look += c.lookups;
        shad += sh;
    }
    tc->collisions += coll;
    tc->lookups += look;
    *shadow += shad;
    *invalid += bad;
}

rd_status rd_render(const rd_scene *s, const rd_render_opts *o, rd_image *out,
                    rd_render_stats *st, char *err, size_t errlen)
{
    memset(st, 0, sizeof *st);
    out->rgb = NULL;
    if (strcmp(o->method, "delta") != 0) {
        snprintf(err, errlen, "--method %s: unknown method (available: %s)", o->method, rd_methods());
        return RD_ERR_ARG;
    }
    if (o->spp < 1) {
        snprintf(err, errlen, "--spp: must be >= 1");
        return RD_ERR_ARG;
    }
    int w = s->camera.width, h = s->camera.height;
    size_t npix = (size_t)w * h;
    double *sum = calloc(npix * 3, sizeof *sum);
    out->rgb = malloc(npix * 3 * sizeof *out->rgb);
    if (!sum || !out->rgb) {
        free(sum);
        free(out->rgb);
        out->rgb = NULL;
        snprintf(err, errlen, "out of memory for a %dx%d film", w, h);
        return RD_ERR_NOMEM;
    }
    out->w = w;
    out->h = h;
    int nthreads = o->threads > 0 ? o->threads : omp_get_max_threads();

    /* Progressive passes: start with one sample per pixel, then size passes to take about a
     * second, so Ctrl-C and --time are honoured promptly. */
    double t_start = now_seconds();
    rd_track_counters tc = {0, 0};
    uint64_t invalid = 0;
    int done = 0, pass = 1;
    while (done < o->spp) {
        if (o->cancel && *o->cancel) { st->cancelled = 1; break; }
        int n = pass < o->spp - done ? pass : o->spp - done;
        double t0 = now_seconds();
        render_pass(s, o->seed, nthreads, done, done + n, sum, &tc, &st->shadow_rays, &invalid);
        done += n;
        double dt = now_seconds() - t0, elapsed = now_seconds() - t_start;
        if (o->progress) o->progress(o->progress_user, done, o->spp, elapsed);
        if (o->time_limit > 0 && elapsed >= o->time_limit) break;
        double per = dt / n; /* seconds per sample per pixel */
        double budget = 1.0;
        if (o->time_limit > 0) budget = fmin(budget, o->time_limit - elapsed);
        /* clamp in double before converting: budget/per can exceed INT_MAX */
        double next = per > 0 ? budget / per : 2.0 * pass;
        next = fmax(1.0, fmin(next, 4.0 * pass));
        pass = (int)next;
    }
    if (o->cancel && *o->cancel) st->cancelled = 1;
    double inv = done > 0 ? 1.0 / done : 0.0;
    for (size_t i = 0; i < npix * 3; i++) out->rgb[i] = (float)(sum[i] * inv);
    free(sum);
    st->seconds = now_seconds() - t_start;
    st->spp = done;
    st->paths = (uint64_t)done * npix;
    st->collisions = tc.collisions;
    st->lookups = tc.lookups;
    st->invalid = invalid;
    return RD_OK;
}
