/* guided.c: the method `guided`, seed 001's (§3.3-4, eq. 16-17; THEORY.md §6): ray marching
 * (integrators/march.c) with the samples placed by the histogram PDF of the camera ray through
 * the photon map's SH guide grid, mixed with a uniform defensive part (weight march.alpha), and
 * N_ray samples per ray by eq. 17 from a pilot pass over the image. */
#include "integrators/rd_march.h"
#include "sh.h"

#include <limits.h>
#include <stdlib.h>

/* The marcher with the guided placement at every pixel (the selection's `method`). */
static vec3 march_guided(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    return rd_march_radiance(ctx, th, r, smp, PLACE_GUIDED);
}

/* The marcher with the nee+beams source at every pixel its tile gives it (march.beams: the
 * selection's beams estimator, wants_beams). */
static vec3 march_beams(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    return rd_march_radiance_ls(ctx, th, r, smp, PLACE_GUIDED, RD_LS_NEE_BEAMS);
}

/* guided-unbiased's paths, an estimator of the selection (march.guided_paths): after delta's
 * path with the equiangular strategy where there is one, before the beams where they are. */
static vec3 paths_guided(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    const march_state *mst = ctx->state;
    uint64_t c0 = th->cells;
    vec3 L = rd_gu_paths_radiance(ctx, mst->gpaths, th, r, smp);
    th->path_cells += th->cells - c0; /* (the report's flight segments, not the marcher's) */
    return L;
}

/* Whether the selection may hold guided-unbiased's paths (march.guided_paths; the scene's guide
 * settings decide only what they guide): with an unbiased source that mixes with delta's path,
 * paths that differ from delta's (a guided part on), and a guide that holds no light they cannot
 * reach (a delta light's light through glass, rd_scene.hidden_share, would steer them to it). */
static int wants_paths(const rd_scene *s)
{
    const rd_guide_settings *g = &s->guide;
    return s->march.guided_paths && s->settings.select != RD_SELECT_OFF &&
           (s->march.ls == RD_LS_NEE_PATHS || s->march.ls == RD_LS_NEE_DELTA) &&
           (g->distances || g->directions || g->roulette) && !(s->hidden_share > RD_HIDDEN_SHARE);
}

/* Whether the selection holds the beams estimator (march.beams): beside an unbiased source that
 * mixes with delta's path, the marcher with the nee+beams source on progressive photon passes of
 * its own, paced by its samples (render.c; consistent: its kernel's bias shrinks with them),
 * not where light reaches the media through glass from a delta light (delta's tiles would lack
 * it: rd_scene.hidden_share, as for nee+beams's own tiles). */
static int wants_beams(const rd_scene *s)
{
    return s->march.beams && s->settings.select != RD_SELECT_OFF &&
           (s->march.ls == RD_LS_NEE_PATHS || s->march.ls == RD_LS_NEE_DELTA) && !(s->hidden_share > RD_HIDDEN_SHARE);
}

/* The maps a photon pass traces: the source's (with photons.progressive), or the beams
 * estimator's indirect map, in spatial order after pass 1 (RD_PASS_NO_INDEX; always progressive). */
static unsigned pass_maps_guided(const rd_scene *s)
{
    return wants_beams(s) ? RD_NEEDS_INDIRECT | RD_PASS_NO_INDEX | RD_PASS_THIN : rd_march_pass_maps(s);
}

/* The pilot pass of eq. 17: mean I_ray over a sparse grid of camera rays through pixel centres
 * (every 4th pixel each way) that enter the media. Costs a guide walk per ray, no tracking. */
static rd_status prepare_guided(rd_render_ctx *ctx, char *err, size_t errlen)
{
    /* The beams estimator reads the photon passes' maps: none where no pass was traced (explain
     * prepares without them; pass_maps_guided has render trace pass 1 whenever it is wanted). */
    const int beams = wants_beams(ctx->scene) && ctx->photon_pass >= 1;
    rd_status st = rd_march_prepare_beams(ctx, beams, err, errlen);
    if (st != RD_OK) return st;
    march_state *mst = ctx->state;
    const rd_scene *s = ctx->scene;
    march_scratch ms;
    size_t bytes = rd_march_scratch_layout(mst, &ms, NULL);
    void *buf = aligned_alloc(16, (bytes + 15) / 16 * 16);
    if (!buf) {
        snprintf(err, errlen, "out of memory for the pilot pass");
        rd_march_release(ctx);
        return RD_ERR_NOMEM;
    }
    rd_march_scratch_layout(mst, &ms, buf);
    double sum = 0.0;
    long n = 0;
    for (int y = 2; y < s->camera.height; y += 4)
        for (int x = 2; x < s->camera.width; x += 4) {
            ray3 r = rd_camera_ray(&s->camera, x + 0.5, y + 0.5);
            double t0, t1;
            int hit, region;
            if (!rd_march_first_segment(s, r, &region, &t0, &t1, &hit)) continue;
            rd_guide_pdf pdf;
            rd_guide_pdf_init(&pdf, ms.seg, mst->seg_cap);
            rd_track_counters c = {0};
            rd_march_build_guided(ctx, &ms, region, r, t0, t1, &pdf, &c);
            sum += pdf.I;
            n++;
        }
    free(buf);
    mst->mean_I = n > 0 ? sum / n : 0.0;
    /* The unbiased sources estimate what delta's path does, and the beams the same up to the
     * kernel's bias (select.c, "A consistent method"), so these mix with delta's path; the
     * beams only when settings.select asks for tiles or pilot by name (it lost on a narrow spot
     * in fog: docs/guided-marching.md). The point gather's cost is not counted (its k-NN
     * searches; nee+photons and photons), nee+guide's estimate is a guide cell's, a bias the
     * passes do not shrink, and nee alone estimates single scattering only: with those every
     * pixel is marched. */
    int sel = s->settings.select;
    /* (not the beams where light reaches the media by way of glass from a delta light, which
     * delta's tiles would lack: rd_scene.hidden_share, docs/compare.md) */
    int mixes = s->march.ls == RD_LS_NEE_PATHS || s->march.ls == RD_LS_NEE_DELTA ||
                (s->march.ls == RD_LS_NEE_BEAMS && (sel == RD_SELECT_TILES || sel == RD_SELECT_PILOT) &&
                 !(s->hidden_share > RD_HIDDEN_SHARE));
    if (sel != RD_SELECT_OFF && mixes) {
        /* guided-unbiased's paths as one more estimator (wants_paths) */
        if (wants_paths(s) && ctx->guide) {
            st = rd_gu_paths_new(ctx, &mst->gpaths, err, errlen);
            if (st != RD_OK) {
                rd_march_release(ctx);
                return st;
            }
        }
        /* (delta's tiles without the marcher's probes: with them, tried in session 36, `guided`
         * lost 0-10% against `delta` with probes on the calibration scenes; the marcher wins the
         * light's tiles without that: docs/guided-unbiased.md "Probes") */
        /* (the beams' samples consume the progressive photon passes: RD_SELECT_PASSES; the
         * beams estimator's where there is one; settings.adaptive "auto" gives `guided` shares:
         * docs/guided-marching.md "Samples where they pay") */
        int options = RD_SELECT_SHARES_AUTO | (s->march.equiangular != RD_EQ_OFF ? RD_SELECT_THIRD : 0) |
                      ((s->march.ls == RD_LS_NEE_BEAMS || beams) && ctx->pass_emitted > 0.0 ? RD_SELECT_PASSES : 0) |
                      (pass_maps_guided(s) & RD_PASS_NO_INDEX ? RD_SELECT_PASSES_ORDERED : 0);
        const rd_select_more more = {.path = mst->gpaths ? paths_guided : NULL, .path_cell_cost = RD_GU_CELL_COST,
                                     .beams = beams ? march_beams : NULL};
        st = rd_select_prepare_more(ctx, march_guided, NULL, RD_MARCH_CELL_COST, options, &more, &mst->sel, err, errlen);
        if (st != RD_OK) rd_march_release(ctx);
        else {
            ctx->weighted = mst->sel.weight || mst->sel.blocks, ctx->shares = mst->sel.share != NULL;
            ctx->blocks = mst->sel.blocks;
        }
    }
    return st;
}

/* The marcher, or delta's path where settings.select gave the pixel's tile to it (select.c). */
static vec3 radiance_guided(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    march_state *mst = ctx->state;
    return rd_select_radiance(ctx, &mst->sel, march_guided, th, r, smp);
}

static void pixel_done_guided(const rd_render_ctx *ctx, rd_thread *th)
{
    march_state *mst = ctx->state;
    rd_select_pixel_done(&mst->sel, th);
}

/* settings.adaptive: the pixel's share of the samples and their weight (select_share.c). */
static double sample_share_guided(const rd_render_ctx *ctx, int x, int y, double *weight)
{
    const march_state *mst = ctx->state;
    return mst->sel.choice ? rd_select_share(&mst->sel, x, y, weight) : 1.0;
}

/* The epochs: the selection's (select.c: the tiles chosen again from the image's samples),
 * march.probes "auto"'s (probes.c: its lambda) and the guided paths' guide.probes "auto"'s, each
 * on its own schedule. */
static int epoch_next_guided(const rd_render_ctx *ctx, int sample)
{
    const march_state *mst = ctx->state;
    int a = rd_select_epoch_next(&mst->sel, sample), b = rd_probes_epoch_next(&mst->probes, sample);
    int c = mst->gpaths ? rd_gu_paths_epoch_next(mst->gpaths, sample) : INT_MAX;
    return a < b ? (a < c ? a : c) : (b < c ? b : c);
}

static void epoch_guided(rd_render_ctx *ctx, int sample)
{
    march_state *mst = ctx->state;
    if (rd_select_epoch_next(&mst->sel, sample - 1) == sample)
        rd_select_epoch(&mst->sel, ctx->comm, &(rd_select_end){ctx->epoch_ahead, ctx->epoch_left, ctx->radius_scale});
    if (rd_probes_epoch_next(&mst->probes, sample - 1) == sample) rd_probes_epoch(ctx, &mst->probes);
    if (mst->gpaths && rd_gu_paths_epoch_next(mst->gpaths, sample - 1) == sample) rd_gu_paths_epoch(ctx, mst->gpaths);
}

/* The pixels whose samples consume the photon passes (the marcher's, or the beams estimator's
 * where there is one): they pace the passes. */
static uint64_t marched_pixels_guided(const rd_render_ctx *ctx)
{
    const march_state *mst = ctx->state;
    const rd_camera *cam = &ctx->scene->camera;
    return rd_select_pass_pixels(&mst->sel, (uint64_t)cam->width * (uint64_t)cam->height);
}

/* The guided placement needs the guide (and so a photon map) whatever the source needs, and the
 * paths what they need beside it. */
static unsigned needs_guided(const rd_scene *s)
{
    unsigned paths = wants_paths(s) ? rd_gu_paths_needs(s) : 0u;
    /* (the beams read pass 1's indirect map, traced by render.c, not the bake's) */
    return rd_march_source_needs(s) | RD_NEEDS_PHOTONS | RD_NEEDS_GUIDE | paths;
}

/* The marcher's scratch, or the paths' where they need more (a sample uses one of the two). */
static size_t scratch_bytes_guided(const rd_render_ctx *ctx)
{
    const march_state *mst = ctx->state;
    size_t a = rd_march_scratch_bytes(ctx), b = mst && mst->gpaths ? rd_gu_paths_scratch_bytes(mst->gpaths) : 0;
    return a > b ? a : b;
}

const rd_method rd_method_guided = {
    .name = "guided",
    .summary = "seed 001: ray marching with samples placed by the photon-map SH guide (eq. 16-17)",
    .needs = RD_MARCH_NEEDS,
    .needs_for = needs_guided,
    .pass_maps = pass_maps_guided,
    .photons_changed = rd_march_photons_changed,
    .marched_pixels = marched_pixels_guided,
    .scratch_bytes = scratch_bytes_guided,
    .prepare = prepare_guided,
    .epoch_next = epoch_next_guided,
    .epoch = epoch_guided,
    .release = rd_march_release,
    .radiance = radiance_guided,
    .pixel_done = pixel_done_guided,
    .sample_share = sample_share_guided,
};
