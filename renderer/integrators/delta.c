/* delta.c: the method `delta`, the unbiased reference: volumetric path tracing with delta
 * tracking's free flights (transport/path.c: next-event estimation with ratio tracking, phase
 * sampling, Russian roulette, MIS for the lights a path can hit). Every other method is checked
 * against it.
 *
 * settings.equiangular "tiles": `delta` chooses per 8x8-pixel tile between its path without the
 * equiangular strategy and with it on every flight (`true`), by the guided methods' tile
 * selection (integrators/select.c: a pilot on random numbers of its own, then the image's own
 * samples at the epochs 4, 16, 64, ...; the choice that minimises the image's variance times
 * its counted cost). Both are unbiased for the same image and every choice comes before the
 * samples it governs, so the mix is unbiased. Why: the strategy wins where a small light's
 * light is concentrated in thin fog and loses where delta tracking's collisions already find
 * it (docs/free-path.md); one image often holds both, and "auto"'s per-flight rule, made for a
 * whole image, gives up part of the gain to bound the loss. The guided methods' selection had
 * this mix as two of its three estimators (session 25: on homogeneous it beat either mode
 * alone); here `delta` has it without a bake. Without a light the strategy samples (a point or
 * spot light, or a directional beam since session 30) there is nothing to choose: the path
 * without the strategy, as "false". */
#include "integrators/rd_method.h"
#include "integrators/rd_select.h"
#include "transport/rd_path.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>

/* The method-table entry: the path's random numbers are one keyed stream (rd_sampler_stream). */
static vec3 delta_method_radiance(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    pcg32 rng = rd_sampler_stream(smp);
    return rd_delta_radiance(ctx->scene, r, &rng, &th->counters);
}

/* ---- settings.equiangular "tiles" ------------------------------------------------------------ */

/* The selection's "method": delta's path with the strategy on every flight (`true`: point and
 * spot lights and directional beams). */
static vec3 delta_every_flight(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    pcg32 rng = rd_sampler_stream(smp);
    return rd_delta_radiance_eq(ctx->scene, r, RD_EQ_ALL, &rng, &th->counters);
}

static void delta_release(rd_render_ctx *ctx)
{
    if (ctx->state) rd_select_free(ctx->state);
    free(ctx->state);
    ctx->state = NULL;
}

static rd_status delta_prepare(rd_render_ctx *ctx, char *err, size_t errlen)
{
    const rd_scene *s = ctx->scene;
    ctx->state = NULL;
    if (s->settings.equiangular != RD_EQ_TILES || !rd_eq_has_lights(s, 1)) return RD_OK;
    rd_select *sel = calloc(1, sizeof *sel);
    if (!sel) {
        snprintf(err, errlen, "out of memory for the tile selection");
        return RD_ERR_NOMEM;
    }
    ctx->state = sel;
    /* two estimators: the method's own mode off means no third (rd_select_prepare); no PDF
     * segments to count (cell cost 0) */
    rd_status st = rd_select_prepare(ctx, delta_every_flight, 0.0, RD_EQ_OFF, sel, err, errlen);
    if (st != RD_OK) delta_release(ctx);
    return st;
}

static vec3 delta_radiance(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    rd_select *sel = ctx->state;
    if (!sel) return delta_method_radiance(ctx, th, r, smp);
    return rd_select_radiance(ctx, sel, delta_every_flight, th, r, smp);
}

static int delta_epoch_next(const rd_render_ctx *ctx, int sample)
{
    const rd_select *sel = ctx->state;
    return sel ? rd_select_epoch_next(sel, sample) : INT_MAX;
}

static void delta_epoch(rd_render_ctx *ctx, int sample)
{
    (void)sample;
    if (ctx->state) rd_select_epoch(ctx->state, ctx->comm);
}

const rd_method rd_method_delta = {
    .name = "delta",
    .summary = "unbiased reference: delta tracking, next-event estimation with ratio tracking, MIS",
    .needs = 0,
    .prepare = delta_prepare,
    .epoch_next = delta_epoch_next,
    .epoch = delta_epoch,
    .release = delta_release,
    .radiance = delta_radiance,
};
