/* delta.c: the method `delta`, the unbiased reference: volumetric path tracing with delta
 * tracking's free flights (transport/path.c: next-event estimation with ratio tracking, phase
 * sampling, Russian roulette, MIS for the lights a path can hit). Every other method is checked
 * against it. (With its default "tiles" and the epochs' shares, unbiased at a sample count;
 * under a time limit but for the last sample's reach: select_share.c "Epoch shares".)
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
 * without the strategy, as "false". A beam that the path connects to (settings.beam_connect,
 * which "tiles" leaves on since session 72) counts as none: the strategy's chord sample is the
 * same light found the weaker way (select.c, "Beams that delta's path connects to"), and
 * beside the connections it made `delta` with "tiles" 0.13-0.82x plain `delta` on beam.json
 * (docs/free-path.md "Per tile: tiles").
 *
 * settings.probes: more camera chains for the light a sample's camera chain sees at its end
 * (integrators/probes.c), on `delta`'s own path (not on the tiles of "tiles", whose two
 * estimators are the selection's). */
#include "integrators/rd_method.h"
#include "integrators/rd_probes.h"
#include "integrators/rd_select.h"
#include "transport/rd_path.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>

/* What `delta` keeps for a render: the tile selection of settings.equiangular "tiles" (NULL:
 * none) and settings.probes. */
typedef struct {
    rd_select *sel;
    rd_probes probes;
} delta_state;

/* The method-table entry: the path's random numbers are one keyed stream (rd_sampler_stream). */
static vec3 delta_method_radiance(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    delta_state *ds = ctx->state;
    if (!ds) {
        pcg32 rng = rd_sampler_stream(smp);
        return rd_delta_radiance(ctx->scene, r, &rng, &th->counters);
    }
    /* settings.probes (probes.c; none: the plain path) */
    return rd_probes_delta(ctx, &ds->probes, th, r, smp, rd_eq_path_mode(ctx->scene->settings.equiangular));
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
    delta_state *ds = ctx->state;
    if (ds) {
        if (ds->sel) rd_select_free(ds->sel);
        free(ds->sel);
        rd_probes_free(&ds->probes);
    }
    free(ds);
    ctx->state = NULL;
}

static rd_status delta_prepare(rd_render_ctx *ctx, char *err, size_t errlen)
{
    const rd_scene *s = ctx->scene;
    int tiles = s->settings.equiangular == RD_EQ_TILES && rd_eq_tiles_have_lights(s);
    ctx->state = NULL;
    if (!tiles && s->settings.probes == 1) return RD_OK; /* plain delta: no state */
    delta_state *ds = calloc(1, sizeof *ds);
    if (!ds) {
        snprintf(err, errlen, "out of memory for delta's state");
        return RD_ERR_NOMEM;
    }
    ctx->state = ds;
    /* no PDF segments to count (cell cost 0); with "tiles", no probes (see the head) */
    rd_status st = rd_probes_init(&ds->probes, s, tiles ? 1 : s->settings.probes, 0.0, err, errlen);
    if (st == RD_OK && tiles) {
        ds->sel = calloc(1, sizeof *ds->sel);
        if (!ds->sel) {
            snprintf(err, errlen, "out of memory for the tile selection");
            st = RD_ERR_NOMEM;
        } else {
            /* two estimators: its "method" is the path with the strategy already, no third;
             * settings.adaptive "auto" is "epochs" (unbiased shares; docs/free-path.md "The default") */
            st = rd_select_prepare(ctx, delta_every_flight, NULL, 0.0, RD_SELECT_METHOD_IS_PATH | RD_SELECT_UNBIASED_SHARES_AUTO,
                                   ds->sel, err, errlen);
            ctx->weighted = st == RD_OK && (ds->sel->weight || ds->sel->blocks);
            ctx->blocks = st == RD_OK && ds->sel->blocks;
            ctx->shares = st == RD_OK && ds->sel->share;
        }
    }
    if (st != RD_OK) delta_release(ctx);
    return st;
}

static vec3 delta_radiance(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    const delta_state *ds = ctx->state;
    if (!ds || !ds->sel) return delta_method_radiance(ctx, th, r, smp);
    return rd_select_radiance(ctx, ds->sel, delta_every_flight, th, r, smp);
}

/* settings.adaptive on the tiles: the pixel's share of the samples and their weight
 * (select_share.c). */
static double delta_sample_share(const rd_render_ctx *ctx, int x, int y, double *weight)
{
    const delta_state *ds = ctx->state;
    return ds && ds->sel && ds->sel->choice ? rd_select_share(ds->sel, x, y, weight) : 1.0;
}

static void delta_pixel_done(const rd_render_ctx *ctx, rd_thread *th)
{
    const delta_state *ds = ctx->state;
    if (ds && ds->sel) rd_select_pixel_done(ds->sel, th);
}

/* The epochs: the selection's, or settings.probes "auto"'s (never both: see the head). */
static int delta_epoch_next(const rd_render_ctx *ctx, int sample)
{
    const delta_state *ds = ctx->state;
    if (!ds) return INT_MAX;
    return ds->sel ? rd_select_epoch_next(ds->sel, sample) : rd_probes_epoch_next(&ds->probes, sample);
}

static void delta_epoch(rd_render_ctx *ctx, int sample)
{
    delta_state *ds = ctx->state;
    (void)sample;
    if (!ds) return;
    /* (No end given: the rule as before session 61, measured for `guided` only; see
     * guided_unbiased.c's epoch.) */
    if (ds->sel) rd_select_epoch(ds->sel, ctx->comm, NULL);
    else rd_probes_epoch(ctx, &ds->probes);
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
    .pixel_done = delta_pixel_done,
    .sample_share = delta_sample_share,
};
