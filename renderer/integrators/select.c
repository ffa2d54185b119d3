/* select.c: the guided methods' choice, per tile of the image, between the method (the
 * marcher of `guided`, the guided paths of `guided-unbiased`) and delta's path
 * (settings.select = "tiles"; docs/guided-marching.md "Where marching pays").
 *
 * Both are unbiased estimators of the radiance along a camera ray, so any choice made per pixel
 * before the image's samples are drawn keeps the image unbiased. The guided method wins where
 * the light along the ray is concentrated (a sample there costs several delta paths and has
 * far less variance); delta wins where it is broad (a camera ray that passes through thin
 * smoke costs delta almost nothing). A pilot, on random numbers of its own, measures both in
 * every tile of RD_SELECT_TILE x RD_SELECT_TILE pixels, on a quarter of its pixels (every other
 * pixel each way) with SEL_SPP samples each: the per-sample variance V (the pixels' variances,
 * pixel_variance(), summed over the tile's pixels as the image's squared error sums them) and
 * the cost C per sample, each then pooled over the tile's 3x3 neighbourhood (pool(), below).
 *
 * The rule. At equal time the image's MSE is (sum_k V_k)(sum_k C_k) / time for the choices
 * m_k of the tiles k, so the best choices minimise the product. Its stationary point is where
 * every tile takes the m minimising V_k,m + lambda C_k,m with lambda = sum V / sum C of the
 * choices themselves (d(VC) = C dV + V dC = 0): the fixed point is found by iterating from
 * each tile's own best V C, a few rounds; then single flips that lower the product itself are
 * made until none does (rd_select_choose).
 *
 * The cost. Time is not deterministic, and the choice must be (for one build, the same seed
 * gives the same image on any machine and thread count), so C is counted: density lookups, times the method's
 * lookup_cost for the method's, plus SEL_RAY_COST per camera sample. Lookups are what all of
 * them spend their time on: on 160x120 renders of cloud.json and smoke-vdb.json at 16 spp on
 * one thread, select off (the calibration scenes, not the benchmark's), time per lookup was
 * 0.38 / 0.39 / 0.62 us on cloud (delta / guided / guided-unbiased) and 0.24 / 0.18 / 0.38 us
 * on smoke-vdb: guided's lookup_cost 0.9, guided-unbiased's 1.6 (its guide walk per flight is
 * not a lookup). A per-sample term of 1.2 lookups fits smoke-vdb's guided/delta ratio and -0.2
 * cloud's, so SEL_RAY_COST is their midpoint, 0.5. */
#include "integrators/rd_select.h"
#include "transport/rd_path.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#define SEL_SPP 8           /* pilot samples per pixel and estimator */
#define SEL_RAY_COST 0.5    /* cost of a camera sample beyond its lookups (see above) */
#define SEL_ROUNDS 32       /* fixed-point rounds at most */
/* The pilot's random numbers: the image's keys (pixel, sample, seed) with the seed moved by a
 * constant, so no pilot sample is one of the image's. */
#define SEL_SEED_SHIFT 0x5E1EC7ULL

/* One pixel's pilot with one estimator: per channel the sum, the sum of squares and the count
 * of non-zero samples, and the cost summed over the samples. */
typedef struct {
    double sum[3], sum2[3], nonzero[3], cost;
} pilot_sums;

static pilot_sums pilot_pixel(const rd_render_ctx *ctx, rd_thread *th, int x, int y, int use_method,
                              rd_select_fn method, double lookup_cost)
{
    const rd_scene *s = ctx->scene;
    const rd_camera *cam = &s->camera;
    uint64_t pix = (uint64_t)y * cam->width + x;
    pilot_sums ps = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}, 0.0};
    uint64_t lookups0 = th->counters.lookups;
    for (int i = 0; i < SEL_SPP; i++) {
        rd_sampler smp = rd_sampler_start(pix, (uint64_t)i, ctx->seed + SEL_SEED_SHIFT);
        double jx = rd_sampler_1d(&smp), jy = rd_sampler_1d(&smp);
        if (!cam->jitter) jx = jy = 0.5;
        ray3 r = rd_camera_ray(cam, x + jx, y + jy);
        vec3 L;
        th->pixel = pix;
        if (use_method) {
            L = method(ctx, th, r, &smp);
        } else {
            pcg32 rng = rd_sampler_stream(&smp);
            L = rd_delta_radiance(s, r, &rng, &th->counters);
        }
        if (!v3_finite(L)) L = v3(0, 0, 0);
        double v[3] = {L.x, L.y, L.z};
        for (int k = 0; k < 3; k++) ps.sum[k] += v[k], ps.sum2[k] += v[k] * v[k], ps.nonzero[k] += v[k] != 0.0;
    }
    ps.cost = (double)(th->counters.lookups - lookups0) * (use_method ? lookup_cost : 1.0) + SEL_RAY_COST * SEL_SPP;
    return ps;
}

/* The per-sample variance of one estimator at one pixel (mean over RGB), given the pixel's mean
 * mu from both estimators' pilot samples (both are unbiased for it). The sample variance alone
 * misleads exactly where delta is worst: a path that finds a narrow beam once in a thousand
 * samples gives eight zeros, variance 0. So it is bounded below by Cauchy-Schwarz: a
 * non-negative X with mean mu that is non-zero with probability p has E[X^2] >= mu^2 / p, so
 * Var X >= mu^2 (1/p - 1), with p estimated by Laplace's rule, (non-zero + 1) / (n + 2). */
static double pixel_variance(const pilot_sums *ps, const double mu[3])
{
    const double n = SEL_SPP;
    double v = 0.0;
    for (int k = 0; k < 3; k++) {
        double sv = fmax(0.0, (ps->sum2[k] - ps->sum[k] * ps->sum[k] / n) / (n - 1.0));
        double p = (ps->nonzero[k] + 1.0) / (n + 2.0);
        v += fmax(sv, mu[k] > 0.0 ? mu[k] * mu[k] * (1.0 / p - 1.0) : 0.0);
    }
    return v / 3.0;
}

void rd_select_choose(const double *var, const double *cost, int n, uint8_t *use_method)
{
    for (int k = 0; k < n; k++) /* start: each tile's own best V C */
        use_method[k] = var[2 * k + 1] * cost[2 * k + 1] < var[2 * k] * cost[2 * k];
    for (int round = 0; round < SEL_ROUNDS; round++) {
        double V = 0.0, C = 0.0;
        for (int k = 0; k < n; k++) V += var[2 * k + use_method[k]], C += cost[2 * k + use_method[k]];
        if (!(C > 0.0)) return;
        double lambda = V / C;
        int changed = 0;
        for (int k = 0; k < n; k++) {
            uint8_t u = var[2 * k + 1] + lambda * cost[2 * k + 1] < var[2 * k] + lambda * cost[2 * k];
            changed += u != use_method[k];
            use_method[k] = u;
        }
        if (!changed) break;
    }
    /* The fixed point is stationary for the linearised objective, but a tile whose flip trades
     * variance for cost can still lower the product itself (the cross term dV dC < 0): flip such
     * tiles, one at a time, until no single flip helps. */
    double V = 0.0, C = 0.0;
    for (int k = 0; k < n; k++) V += var[2 * k + use_method[k]], C += cost[2 * k + use_method[k]];
    for (int round = 0, changed = 1; changed && round < SEL_ROUNDS; round++) {
        changed = 0;
        for (int k = 0; k < n; k++) {
            int o = use_method[k], f = 1 - o;
            double V2 = V - var[2 * k + o] + var[2 * k + f], C2 = C - cost[2 * k + o] + cost[2 * k + f];
            if (V2 * C2 < V * C * (1.0 - 1e-12)) {
                use_method[k] = (uint8_t)f;
                V = V2, C = C2;
                changed = 1;
            }
        }
    }
}

/* Each tile's statistics replaced by the mean over its 3x3 neighbourhood (clipped at the image's
 * edge). A tile's own pilot has 16 pixels x SEL_SPP samples, and delta's variance is
 * heavy-tailed (a rare path that finds the light): alone, one tile's estimate swings the choice
 * from seed to seed; nine tiles' pooled steady it, at the price of a one-tile blur of the map. */
static void pool(double *var, double *cost, int nx, int ny)
{
    size_t n = (size_t)nx * ny;
    double *tmp = malloc(4 * n * sizeof *tmp);
    if (!tmp) return; /* the tiles' own statistics, then */
    memcpy(tmp, var, 2 * n * sizeof *tmp);
    memcpy(tmp + 2 * n, cost, 2 * n * sizeof *tmp);
    for (int ty = 0; ty < ny; ty++)
        for (int tx = 0; tx < nx; tx++) {
            size_t k = (size_t)ty * nx + tx;
            double sv[2] = {0, 0}, sc[2] = {0, 0};
            int cnt = 0;
            for (int y = ty - 1; y <= ty + 1; y++)
                for (int x = tx - 1; x <= tx + 1; x++) {
                    if (x < 0 || y < 0 || x >= nx || y >= ny) continue;
                    size_t j = (size_t)y * nx + x;
                    for (int e = 0; e < 2; e++) sv[e] += tmp[2 * j + e], sc[e] += tmp[2 * n + 2 * j + e];
                    cnt++;
                }
            for (int e = 0; e < 2; e++) var[2 * k + e] = sv[e] / cnt, cost[2 * k + e] = sc[e] / cnt;
        }
    free(tmp);
}

rd_status rd_select_prepare(const rd_render_ctx *ctx, rd_select_fn method, double lookup_cost,
                            rd_select *sel, char *err, size_t errlen)
{
    const rd_camera *cam = &ctx->scene->camera;
    memset(sel, 0, sizeof *sel);
    sel->tiles_x = (cam->width + RD_SELECT_TILE - 1) / RD_SELECT_TILE;
    int tiles_y = (cam->height + RD_SELECT_TILE - 1) / RD_SELECT_TILE, n = sel->tiles_x * tiles_y;
    uint8_t *choice = calloc((size_t)n, 1);
    double *var = calloc(2 * (size_t)n, sizeof *var), *cost = calloc(2 * (size_t)n, sizeof *cost);
    int threads = ctx->threads > 0 ? ctx->threads : 1;
    rd_thread *th = calloc((size_t)threads, sizeof *th);
    size_t bytes = ctx->method->scratch_bytes ? ctx->method->scratch_bytes(ctx) : 0;
    int ok = choice && var && cost && th;
    for (int i = 0; ok && bytes && i < threads; i++) {
        th[i].index = i;
        th[i].scratch = aligned_alloc(16, (bytes + 15) / 16 * 16);
        th[i].scratch_bytes = bytes;
        ok = th[i].scratch != NULL;
    }
    if (ok) {
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1)
        for (int k = 0; k < n; k++) {
            rd_thread *t = &th[omp_get_thread_num()];
            int x0 = (k % sel->tiles_x) * RD_SELECT_TILE, y0 = (k / sel->tiles_x) * RD_SELECT_TILE;
            for (int y = y0; y < y0 + RD_SELECT_TILE && y < cam->height; y += 2)
                for (int x = x0; x < x0 + RD_SELECT_TILE && x < cam->width; x += 2) {
                    pilot_sums ps[2]; /* 0: delta, 1: the method */
                    for (int e = 0; e < 2; e++) ps[e] = pilot_pixel(ctx, t, x, y, e, method, lookup_cost);
                    double mu[3];
                    for (int c = 0; c < 3; c++) mu[c] = (ps[0].sum[c] + ps[1].sum[c]) / (2.0 * SEL_SPP);
                    for (int e = 0; e < 2; e++) {
                        var[2 * k + e] += pixel_variance(&ps[e], mu); /* the tile's sums (see the head) */
                        cost[2 * k + e] += ps[e].cost / SEL_SPP;
                    }
                }
        }
        pool(var, cost, sel->tiles_x, tiles_y);
        rd_select_choose(var, cost, n, choice);
        sel->guided = choice;
        choice = NULL;
    }
    for (int i = 0; th && i < threads; i++) free(th[i].scratch);
    free(th);
    free(var);
    free(cost);
    free(choice);
    if (!ok) {
        snprintf(err, errlen, "out of memory for the tile selection's pilot");
        return RD_ERR_NOMEM;
    }
    return RD_OK;
}

void rd_select_free(rd_select *sel)
{
    free(sel->guided);
    memset(sel, 0, sizeof *sel);
}

vec3 rd_select_radiance(const rd_render_ctx *ctx, const rd_select *sel, rd_select_fn method,
                        rd_thread *th, ray3 r, rd_sampler *smp)
{
    if (sel->guided) {
        int w = ctx->scene->camera.width;
        int x = (int)(th->pixel % (uint64_t)w), y = (int)(th->pixel / (uint64_t)w);
        if (!sel->guided[(y / RD_SELECT_TILE) * sel->tiles_x + x / RD_SELECT_TILE]) {
            th->delta_samples++;
            pcg32 rng = rd_sampler_stream(smp);
            return rd_delta_radiance(ctx->scene, r, &rng, &th->counters);
        }
    }
    return method(ctx, th, r, smp);
}
