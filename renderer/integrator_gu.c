/* integrator_gu.c: `guided-unbiased`, the unbiased path tracer of integrator_delta.c with its
 * free flights guided by the photon-map SH guide (issue 10; docs/guided-unbiased.md).
 *
 * A flight from the path vertex o along d over [0, t_light] meets the media in [t0, t1] (the
 * media bounds, clipped before the nearest sphere light). The RTE along it (THEORY.md §1;
 * no emission in the media, T(0,t0) = 1 since nothing lies before t0):
 *
 *     L(o, -d) = integral_t0^t1 T(t0,t) sigma_s(t) L_s(x(t), -d) dt  +  T(t0,t1) L_behind      (1)
 *                \___________ scattered part S ______________/        \__ passed part B __/
 *
 * The guide gives cheap estimates of both parts: S~ = I_ray, the integral of the histogram
 * h(t) = T~(t0,t) f_j with f_j = sigma_s L_s toward -d of the cell (seed 001 eq. 16,
 * renderer/guide_pdf.c), and B~ = T~(t0,t1) L_behind with L_behind known exactly (the light or
 * environment beyond, MIS-weighted as the path loop will weight it: rd_flight_behind). The
 * flight then
 *   1. scatters with probability P_s = S~ / (S~ + B~), held inside [floor, 1 - floor]
 *      (guide.pass_floor) so that each part keeps a positive probability whatever the guide
 *      says; P_s = 1 when L_behind = 0 exactly (then B = 0: passing can only add 0);
 *   2. if it scatters, draws t from the defensive mixture
 *          p(t) = (1 - alpha) h(t) / I_ray + alpha / (t1 - t0)        (guide.distance_alpha)
 *      which is > 0 on all of [t0, t1], wherever sigma_s can be;
 * and weights each outcome by the integrand of (1) over its probability density:
 *     scatter at t:  T(t0,t) sigma_s(t) / (P_s p(t))       (times the estimate of L_s at x(t)
 *                                                         that the path loop makes there: NEE
 *                                                         plus the phase-sampled continuation)
 *     pass through:  T(t0,t1) / (1 - P_s)                  (times L_behind)
 * Its expectation is P_s E[T sigma_s L_s / (P_s p)] + (1 - P_s) E[T L_b / (1 - P_s)] = (1):
 * unbiased for any guide, given unbiased T (the free-path engine's ratio / residual ratio
 * tracking or the exact optical depth, settings.transmittance: rd_transmittance) and an
 * unbiased, independent L_s estimate (the path loop's). Delta tracking is the special case
 * p(t) = sigma_t T / (1 - T(t0,t1)), P_s = 1 - T(t0,t1): its weights reduce to albedo and 1.
 *
 * Compared with delta tracking the vertex carries sigma_s(t) and T(t0,t) explicitly (delta's
 * pdf cancels both, leaving the albedo); NEE at the vertex estimates L_s = integral p L_direct,
 * which holds no sigma_s, so the vertex weight multiplies it as it is (rd_path_radiance). */
#include "rd_guide_pdf.h"
#include "rd_method.h"
#include "sh.h"

#include <stdlib.h>

typedef struct {
    int seg_cap; /* PDF segments a flight can need (guide cells crossed + 2 fillers) */
} gu_state;

/* The sampler's per-path data: the render context and this thread's segment storage. */
typedef struct {
    const rd_render_ctx *ctx;
    rd_gpdf_seg *seg;
    int cap;
    double P_s; /* of the last flight, for tests (rd_gu_flight) */
} gu_flight_user;

static double mean3(vec3 v) { return (v.x + v.y + v.z) / 3.0; }

/* The distance pdf of one flight over [t0, t1]: the guide's histogram toward -d with the
 * defensive mixture, or the defensive (uniform) part alone if the ray needs more segments
 * than the storage holds (still unbiased, only less guided). */
static void build_distance_pdf(const gu_flight_user *u, ray3 r, double t0, double t1,
                               rd_guide_pdf *pdf)
{
    const double o[3] = {r.o.x, r.o.y, r.o.z}, d[3] = {r.d.x, r.d.y, r.d.z};
    double alpha = u->ctx->scene->guide.distance_alpha;
    rd_guide_pdf_init(pdf, u->seg, u->cap);
    if (rd_guide_pdf_build_guide(pdf, u->ctx->guide, o, d, t0, t1, alpha, NULL, 0) != RD_OK)
        rd_guide_pdf_build(pdf, 0, NULL, NULL, NULL, t0, t1, 1.0, NULL, 0);
}

/* Step 1 of the header: P_s from the guide's scattered part S~ = I_ray against the passed
 * part B~ = T~(t0,t1) L_behind (channel means, as the guide's f_j are), held in
 * [floor, 1 - floor]; 1 when nothing lies behind. */
static double scatter_probability(const rd_guide_pdf *pdf, double L_behind, double floor)
{
    if (!(L_behind > 0.0)) return 1.0;
    double S = pdf->I, B = exp(-rd_guide_pdf_tau(pdf)) * L_behind;
    double P = (S + B > 0.0 && isfinite(S + B)) ? S / (S + B) : 0.5;
    return fmin(1.0 - floor, fmax(floor, P));
}

static rd_flight guided_flight(const rd_flight_sampler *fs, const rd_scene *s,
                               const rd_flight_in *in, pcg32 *rng, rd_track_counters *c)
{
    gu_flight_user *u = fs->user;
    ray3 r = in->r;
    double t0, t1;
    /* No guide or no medium on the way: delta tracking's flight (it passes with weight 1
     * when the ray misses every medium). */
    if (!u->ctx->guide || s->n_media == 0 ||
        !rd_box_intersect(s->bmin, s->bmax, r, 0.0, in->t_light, &t0, &t1) || !(t1 > t0)) {
        u->P_s = 0.0;
        return rd_flight_delta(s, in, rng, c);
    }
    rd_guide_pdf pdf;
    build_distance_pdf(u, r, t0, t1, &pdf);
    double P_s = scatter_probability(&pdf, mean3(rd_flight_behind(s, in)), s->guide.pass_floor);
    u->P_s = P_s;
    rd_flight f = {.kind = RD_FLIGHT_PASS, .t = t1, .medium = NULL};
    if (pcg32_uniform(rng) >= P_s) {
        /* Pass through: T(t0,t1) / (1 - P_s). */
        double T = rd_transmittance(s, r, t0, t1, rng, c);
        f.weight = v3_scale(v3(1, 1, 1), T / (1.0 - P_s));
        return f;
    }
    /* Scatter at t ~ p: T(t0,t) sigma_s(t) / (P_s p(t)). */
    double p;
    double t = rd_guide_pdf_sample(&pdf, pcg32_uniform(rng), &p);
    vec3 x = ray_at(r, t);
    const rd_medium *m = rd_scene_medium_at(s, x);
    double sigma_t = m ? rd_medium_sigma_t(m, x) : 0.0;
    c->lookups += m != NULL;
    if (!(sigma_t > 0.0) || !(p > 0.0)) {
        f.kind = RD_FLIGHT_END; /* zero integrand at the vertex: the path adds nothing more */
        f.weight = v3(0, 0, 0);
        return f;
    }
    double T = rd_transmittance(s, r, t0, t, rng, c);
    f.kind = RD_FLIGHT_SCATTER;
    f.t = t;
    f.medium = m;
    f.weight = v3_scale(m->albedo, sigma_t * T / (P_s * p)); /* sigma_s = albedo sigma_t */
    return f;
}

static vec3 gu_radiance(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    const gu_state *st = ctx->state;
    gu_flight_user u = {.ctx = ctx, .seg = th->scratch, .cap = st->seg_cap};
    const rd_flight_sampler fs = {.sample = guided_flight, .user = &u};
    pcg32 rng = rd_sampler_stream(smp);
    return rd_path_radiance(ctx->scene, r, &fs, &rng, &th->counters);
}

rd_flight rd_gu_flight(const rd_render_ctx *ctx, void *scratch, const rd_flight_in *in,
                       pcg32 *rng, rd_track_counters *c, double *P_s)
{
    const gu_state *st = ctx->state;
    gu_flight_user u = {.ctx = ctx, .seg = scratch, .cap = st->seg_cap};
    const rd_flight_sampler fs = {.sample = guided_flight, .user = &u};
    rd_flight f = guided_flight(&fs, ctx->scene, in, rng, c);
    if (P_s) *P_s = u.P_s;
    return f;
}

/* ---- Set-up --------------------------------------------------------------------------------- */

static rd_status gu_prepare(rd_render_ctx *ctx, char *err, size_t errlen)
{
    const rd_guide_settings *g = &ctx->scene->guide;
    /* Unbiasedness needs p > 0 wherever the integrand can be and both outcomes possible. */
    if (!(g->distance_alpha > 0.0 && g->distance_alpha <= 1.0)) {
        snprintf(err, errlen, "guide.distance_alpha: must be in (0, 1], found %g", g->distance_alpha);
        return RD_ERR_ARG;
    }
    if (!(g->pass_floor > 0.0 && g->pass_floor <= 0.5)) {
        snprintf(err, errlen, "guide.pass_floor: must be in (0, 0.5], found %g", g->pass_floor);
        return RD_ERR_ARG;
    }
    gu_state *st = calloc(1, sizeof *st);
    if (!st) {
        snprintf(err, errlen, "out of memory for guided-unbiased");
        return RD_ERR_NOMEM;
    }
    st->seg_cap = 2;
    if (ctx->guide) {
        /* As the marcher: a uniform grid is crossed in at most nx + ny + nz - 2 cells, an
         * adaptive one in at most 3 x 2^depth leaves; plus two fillers (rd_guide_pdf.h). */
        sh_guide_stats gs;
        sh_guide_stats_get(ctx->guide, &gs);
        st->seg_cap = gs.kind == SH_GRID_UNIFORM
                          ? gs.res[0] + gs.res[1] + gs.res[2] + 2
                          : 3 * (1 << (gs.depth_max < 12 ? gs.depth_max : 12)) + 2;
    }
    ctx->state = st;
    return RD_OK;
}

static void gu_release(rd_render_ctx *ctx)
{
    free(ctx->state);
    ctx->state = NULL;
}

static size_t gu_scratch_bytes(const rd_render_ctx *ctx)
{
    const gu_state *st = ctx->state;
    return (size_t)st->seg_cap * sizeof(rd_gpdf_seg);
}

/* The guide (and the photon map it is baked from) only when distances are guided; with
 * guide.distances false the method is delta tracking and needs no bake. */
static unsigned gu_needs(const rd_scene *s)
{
    return s->guide.distances ? RD_NEEDS_PHOTONS | RD_NEEDS_GUIDE : 0u;
}

const rd_method rd_method_guided_unbiased = {
    .name = "guided-unbiased",
    .summary = "unbiased path tracing with free-flight distances and scatter/pass guided by the SH guide",
    .needs = RD_NEEDS_PHOTONS | RD_NEEDS_GUIDE,
    .needs_for = gu_needs,
    .scratch_bytes = gu_scratch_bytes,
    .prepare = gu_prepare,
    .release = gu_release,
    .radiance = gu_radiance,
};
