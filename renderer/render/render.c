/* render.c: progressive rendering of any method in the table over tiles with OpenMP (camera
 * rays from scene/camera.c), into the film (film.c).
 *
 * Determinism (DESIGN.md convention 6): the random numbers of sample i of pixel p are keyed by
 * (p, i, dimension, seed) (rd_sampler); the first two dimensions place the sample in the pixel,
 * the method owns the rest. Each pixel is accumulated by one thread in sample order, so an
 * image rendered to a sample count is the same bit for bit whatever the thread count or the
 * pass sizes, and two methods see the same camera rays.
 *
 * The film keeps, per pixel, the sums of its samples: the image is their mean, and the render
 * reports each pixel's standard error (docs/cli.md). Where the method weighs its samples
 * (rd_method.sample_share's weight; with settings.adaptive, integrators/select_share.c
 * "Weights"; or each sample by the indices it stands for, "Epoch shares": rd_block_next), the
 * mean is weighted (rd_film.h, film.c). A time limit or Ctrl-C is checked before
 * every pixel, so a render stops within one pixel's work of the budget; pixels then differ in
 * count by at most one pass, which the per-pixel count accounts for.
 *
 * Several ranks (rd_render_opts.comm, docs/cluster.md): each renders the tiles it owns (tile
 * index modulo the rank count), the ranks agree before and after every pass (one small
 * allreduce: stop if any rank's time is up or its cancel flag is set; the smallest next pass),
 * so every collective call is matched on every rank, and the films are summed onto rank 0 at the
 * end. A pixel's samples depend only on its keys, and each pixel has one owner, whose sums the
 * others' zeros leave exact: rank 0's image is one process's, bit for bit. */
#include "bake/rd_photons.h"
#include "core/rd_core.h"
#include "integrators/rd_method.h"
#include "render/rd_film.h"

#include <limits.h>
#include <math.h>
#if defined(__GLIBC__) || defined(__linux__)
#include <malloc.h>
#endif
#include <omp.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define TILE 16

void rd_render_result_free(rd_render_result *res)
{
    if (!res) return;
    rd_image_free_pixels(&res->image);
    rd_image_free_pixels(&res->stderr_img);
    free(res->curve);
    res->curve = NULL;
    res->n_curve = 0;
}

double rd_clock_monotonic(void *user)
{
    (void)user;
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

void rd_steady_allocation(void)
{
#ifdef M_MMAP_THRESHOLD
    mallopt(M_MMAP_THRESHOLD, 1 << 20); /* fixed: setting it ends glibc's dynamic threshold */
#endif
}

/* The render's clock (rd_render_opts.clock): every time it keeps or reports is read here. */
typedef struct {
    rd_clock_fn fn;
    void *user;
} rclock;

static double now_seconds(const rclock *c)
{
    return c->fn(c->user);
}

/* ---- Passes -------------------------------------------------------------------------------- */

static int should_stop(double deadline, const volatile int *cancel, const rclock *clk)
{
    return (cancel && *cancel) || (deadline < INFINITY && now_seconds(clk) >= deadline);
}

/* The ranks sharing the render (1 and 0 alone). */
static int comm_size(const rd_comm *c) { return c && c->size > 1 ? c->size : 1; }
static int comm_rank(const rd_comm *c) { return comm_size(c) > 1 ? c->rank : 0; }

/* Render samples [s0, s1) of every pixel of this rank's tiles into the film; returns 1 when the
 * deadline or the cancel flag cut the pass short. Each thread reads the clock before each of its
 * pixels and stops at the first reading at or past the deadline. With ctx->blocks, [s0, s1) lies
 * in the epoch that begins at index a, and a drawn sample's block ends at lim at the latest (the
 * epoch's end or the render's last sample's, whichever comes first: rd_block_next). */
static int render_pass(const rd_render_ctx *ctx, rd_thread *th, rd_film *f, int s0, int s1, int a, int lim,
                       double deadline, const volatile int *cancel, const rclock *clk, uint64_t *invalid)
{
    const int ranks = comm_size(ctx->comm), rank = comm_rank(ctx->comm);
    const rd_camera *cam = &ctx->scene->camera;
    const rd_method *m = ctx->method;
    int tiles_x = (cam->width + TILE - 1) / TILE, tiles_y = (cam->height + TILE - 1) / TILE;
    uint64_t bad = 0;
    int stopped = 0;
#pragma omp parallel for num_threads(ctx->threads) schedule(dynamic, 1) reduction(+ : bad) reduction(| : stopped)
    for (int tile = 0; tile < tiles_x * tiles_y; tile++) {
        if (ranks > 1 && tile % ranks != rank) continue; /* another rank's tile */
        rd_thread *t = &th[omp_get_thread_num()];
        int x0 = (tile % tiles_x) * TILE, y0 = (tile / tiles_x) * TILE;
        for (int y = y0; y < y0 + TILE && y < cam->height; y++)
            for (int x = x0; x < x0 + TILE && x < cam->width; x++) {
                if (stopped || should_stop(deadline, cancel, clk)) { stopped = 1; continue; }
                uint64_t pix = (uint64_t)y * cam->width + x;
                /* The pixel's sums in registers for its samples, stored once after them. */
                rd_film_pixel acc;
                rd_film_load(f, pix, &acc);
                /* The pixel's share of the samples past the first few (rd_method.sample_share):
                 * sample i is drawn where (i + 1 - F) share reaches a whole number, so any run
                 * of k indices draws k share of them, give or take one; and their weight. */
                double w = 1.0;
                const double share = m->sample_share ? m->sample_share(ctx, x, y, &w) : 1.0;
                int drew = 0;
                /* With blocks ("epochs"), the epoch's first index is drawn and each drawn sample
                 * weighs the indices it stands for: a sum over the epoch's indices fixed before
                 * its samples are drawn (select_share.c, "Epoch shares") */
                const int blocks = ctx->blocks;
                for (int i = blocks ? rd_block_next(s0, a, s1, share) : rd_share_next(s0, s1, share), next; i < s1;
                     i = blocks ? (next < s1 ? next : s1) : rd_share_next(i + 1, s1, share)) {
                    drew = 1;
                    next = blocks ? rd_block_next(i + 1, a, lim, share) : 0; /* (lim >= s1) */
                    const double wi = blocks ? w * (double)(next - i) : w;
                    rd_sampler smp = rd_sampler_start(pix, (uint64_t)i, ctx->seed);
                    double jx = rd_sampler_1d(&smp), jy = rd_sampler_1d(&smp); /* RD_DIM_FILM */
                    if (!cam->jitter) jx = jy = 0.5; /* pixel centres (camera.jitter false) */
                    ray3 r = rd_camera_ray(cam, x + jx, y + jy);
                    t->pixel = pix, t->x = x, t->y = y;
                    vec3 L = m->radiance(ctx, t, r, &smp);
                    /* A non-finite sample would poison the pixel: drop and count it. */
                    if (!v3_finite(L)) { bad++; continue; }
                    rd_film_add(&acc, L, wi);
                }
                if (m->pixel_done && drew) m->pixel_done(ctx, t); /* (none drawn: nothing to write) */
                rd_film_store(f, pix, &acc);
            }
    }
    *invalid += bad;
    return stopped;
}

static int curve_push(rd_render_result *res, int *cap, double seconds, double spp_mean, double rmse)
{
    if (res->n_curve == *cap) {
        int nc = *cap ? 2 * *cap : 64;
        rd_conv_point *p = realloc(res->curve, (size_t)nc * sizeof *p);
        if (!p) return 0;
        res->curve = p;
        *cap = nc;
    }
    res->curve[res->n_curve++] = (rd_conv_point){seconds, spp_mean, rmse};
    return 1;
}

static rd_status fail(char *err, size_t errlen, rd_status st, const char *msg)
{
    snprintf(err, errlen, "%s", msg);
    return st;
}

/* Attach what ctx's method needs baked to ctx: `given`, or a bake made here (*own, which the
 * caller frees), by the ranks of ctx->comm together when there are several. */
static rd_status attach_bake(rd_render_ctx *ctx, const rd_baked *given, int threads, const volatile int *cancel,
                             rd_baked **own, char *err, size_t errlen)
{
    const rd_scene *s = ctx->scene;
    const rd_method *m = ctx->method;
    *own = NULL;
    unsigned needs = m->needs_for ? m->needs_for(s) : m->needs;
    if (!needs) return RD_OK;
    const rd_baked *b = given;
    if (!b) {
        rd_bake_opts bo = {0};
        bo.seed = -1;
        bo.threads = threads;
        bo.cancel = cancel; /* a cancel during the bake: RD_ERR_CANCELLED, nothing rendered */
        bo.comm = ctx->comm; /* (the same status on every rank) */
        rd_bake_opts_for(&bo, needs);
        rd_status st = rd_bake(s, &bo, own, err, errlen);
        if (st != RD_OK) return st;
        b = *own;
    }
    ctx->photons = rd_baked_map(b);
    ctx->photons_indirect = rd_baked_indirect_map(b);
    ctx->guide = rd_baked_guide(b);
    ctx->guide_indirect = rd_baked_indirect_guide(b);
    const char *missing = (needs & RD_NEEDS_GUIDE) && !ctx->guide ? "a guide grid"
                          : (needs & RD_NEEDS_INDIRECT) && !ctx->photons_indirect ? "an indirect photon map"
                          : (needs & (RD_NEEDS_INDIRECT_GUIDE | RD_NEEDS_INDIRECT_LOBE)) && !ctx->guide_indirect ? "a guide of the indirect photons"
                                                                                  : NULL;
    if (missing) {
        rd_baked_free(*own);
        *own = NULL;
        snprintf(err, errlen, "--method %s: needs %s, and the bake given has none", m->name, missing);
        return RD_ERR_ARG;
    }
    return RD_OK;
}

/* Progressive photon passes (bake/passes.c): trace pass `pass`'s photon maps and hand them to
 * ctx in place of the previous pass's (*cur, freed here unless it is pass 1's, which sets every
 * later pass's radius and lives until the render ends). The guide stays the first bake's. The
 * ranks of ctx->comm trace each pass together; a cancel flag stops the tracing
 * (RD_ERR_CANCELLED, on every rank). */
static rd_status photon_pass(rd_render_ctx *ctx, unsigned maps, int pass, rd_baked **cur, const rd_baked *first,
                             const volatile int *cancel, rd_render_stats *rs, char *err, size_t errlen)
{
    const rd_scene *s = ctx->scene;
    rd_baked *next = NULL;
    /* RD_PASS_THIN: the passes after the first store each collision with probability
     * q = min(1, emitted / stored) of pass 1 (rd_method.h), for maps of the indirect photons
     * alone, whose count is `indexed` and whose q the beams' radii read too (march_beams.c). */
    double keep = 1.0;
    if (pass > 1 && (maps & RD_PASS_THIN) && !(maps & RD_NEEDS_PHOTONS) && first) {
        const rd_bake_stats *b1 = rd_baked_stats(first);
        if ((double)b1->indexed > (double)b1->emitted) keep = (double)b1->emitted / (double)b1->indexed;
    }
    rd_status st = rd_bake_photon_pass(s, maps, pass, ctx->seed, keep, ctx->threads, cancel, ctx->comm, &next, err, errlen);
    if (st != RD_OK) return st;
    const rd_bake_stats *bs = rd_baked_stats(next);
    if (pass == 1) {
        ctx->photons_first = rd_baked_map(next);
        ctx->photons_indirect_first = rd_baked_indirect_map(next);
        ctx->pass_emitted = (double)bs->emitted;
        ctx->pass_collisions = (double)bs->emitted * bs->collisions_per_photon;
        ctx->pass_indexed = (double)bs->indexed;
        /* (the later passes, thinned, order about as many photons as were emitted: the share of
         * a pass the selection charges, select.c "The photon passes") */
        if ((maps & RD_PASS_THIN) && !(maps & RD_NEEDS_PHOTONS) && ctx->pass_indexed > ctx->pass_emitted)
            ctx->pass_indexed = ctx->pass_emitted;
    } else if (*cur != first) {
        rd_baked_free(*cur);
    }
    *cur = next;
    if (maps & RD_NEEDS_PHOTONS) ctx->photons = rd_baked_map(next);
    if (maps & RD_NEEDS_INDIRECT) ctx->photons_indirect = rd_baked_indirect_map(next);
    ctx->photon_pass = pass;
    ctx->radius_scale = rd_ppm_radius_scale(pass, s->photons.alpha);
    rs->photon_passes = pass;
    rs->photons_traced += bs->emitted;
    rs->photon_seconds += bs->seconds;
    rs->radius_scale = ctx->radius_scale;
    rs->photon_keep = keep;
    rs->photons_stored = bs->indexed;
    if (pass > 1 && ctx->method->photons_changed) return ctx->method->photons_changed(ctx, err, errlen);
    return RD_OK;
}

rd_status rd_render(const rd_scene *s, const rd_render_opts *o, rd_render_result *res,
                    char *err, size_t errlen)
{
    memset(res, 0, sizeof *res);
    const rd_method *m = rd_method_find(o->method);
    if (!m) {
        char names[256];
        rd_methods(names, sizeof names);
        snprintf(err, errlen, "--method %s: unknown method (available: %s)", o->method ? o->method : "(none)", names);
        return RD_ERR_ARG;
    }
    if (o->spp < 1) return fail(err, errlen, RD_ERR_ARG, "--spp: must be >= 1");
    if (o->first_sample < 0 || o->first_sample > INT_MAX - o->spp)
        return fail(err, errlen, RD_ERR_ARG, "first sample: must be >= 0, and first sample + spp within an int");
    const int s0 = o->first_sample; /* samples [s0, s0 + spp) of every pixel */
    int w = s->camera.width, h = s->camera.height;
    if (o->reference && (o->reference->w != w || o->reference->h != h || !o->reference->rgb)) {
        snprintf(err, errlen, "reference image: %dx%d, but the render is %dx%d", o->reference->w,
                 o->reference->h, w, h);
        return RD_ERR_ARG;
    }
    /* The caller's bake (o->baked_seconds) counts as if it had happened inside this call. */
    const rclock clk_ = {o->clock ? o->clock : rd_clock_monotonic, o->clock_user}, *clk = &clk_;
    double t_start = now_seconds(clk) - (o->baked ? fmax(0.0, o->baked_seconds) : 0.0);
    double deadline = o->time_limit > 0 ? t_start + o->time_limit : INFINITY; /* a clock may read 0 */
    rd_render_ctx ctx = {.scene = s, .method = m, .seed = o->seed,
                         .threads = o->threads > 0 ? o->threads : omp_get_max_threads(),
                         .comm = comm_size(o->comm) > 1 ? o->comm : NULL,
                         .select_trace = o->select_trace};
    rd_select_report select_report = {0};
    ctx.select_report = &select_report;
    const rd_comm *comm = ctx.comm;
    res->stats.threads = ctx.threads;

    /* What the method needs baked: given, or baked here (its time is part of the render). A
     * cancel stops the bake: RD_ERR_CANCELLED, on every rank (the ranks bake together and agree
     * on the bake's outcome). */
    rd_baked *own = NULL;
    rd_status st = attach_bake(&ctx, o->baked, o->threads, o->cancel, &own, err, errlen);
    if (st != RD_OK) return st;
    /* Progressive photon passes: pass 1's maps are traced here (the bake's own maps serve its
     * guide); the passes go on between render passes, pass i for the samples of the estimate
     * that reads them (the method's, or `guided`'s beams estimator: rd_method.marched_pixels)
     * [(i - 1), i) x photons.pass_spp x (all pixels) (below: with every pixel the method's,
     * samples [(i - 1) pass_spp, i pass_spp) of every pixel), so an image does not depend on
     * how the render's passes fall in time. */
    unsigned pass_maps = m->pass_maps ? m->pass_maps(s) : 0u; /* (0: one fixed map) */
    rd_baked *pass_bake = NULL, *first_bake = NULL;
    ctx.radius_scale = 1.0;
    if (pass_maps) {
        /* (pass 1 indexed whatever pass_maps says: its map answers the k-NN queries) */
        if ((st = photon_pass(&ctx, pass_maps & ~(unsigned)RD_PASS_NO_INDEX, 1, &pass_bake, NULL, o->cancel, &res->stats,
                              err, errlen)) != RD_OK) {
            rd_baked_free(own);
            return st;
        }
        first_bake = pass_bake;
    }
    res->stats.bake_seconds = now_seconds(clk) - t_start;
    if (m->prepare && (st = m->prepare(&ctx, err, errlen)) != RD_OK) {
        rd_baked_free(first_bake);
        rd_baked_free(own);
        return st;
    }
    res->stats.prepare_seconds = now_seconds(clk) - t_start - res->stats.bake_seconds;

    /* Per-thread contexts with the method's scratch, and the film. */
    rd_thread *th = rd_threads_new(&ctx, ctx.threads);
    rd_film f = {0};
    /* (the weights' sums where the method weighs its samples: rd_render_ctx.weighted) */
    int ok = th && rd_film_alloc(&f, w, h, ctx.weighted);
    size_t npix = (size_t)w * h;
    if (ok) {
        res->image.rgb = malloc(npix * 3 * sizeof(float));
        res->stderr_img.rgb = malloc(npix * 3 * sizeof(float));
        ok = res->image.rgb && res->stderr_img.rgb;
    }
    int others_ok = 1; /* several ranks: all go on, or all stop (the passes are collective) */
    if (comm) {
        int all = ok;
        comm->reduce(comm->user, &all, 1, RD_COMM_INT, RD_COMM_MIN, -1);
        others_ok = all || !ok;
    }
    if (!ok || !others_ok) {
        if (!ok) snprintf(err, errlen, "out of memory for a %dx%d film and %d threads' scratch", w, h, ctx.threads);
        else snprintf(err, errlen, "another rank ran out of memory for its %dx%d film", w, h);
        st = RD_ERR_NOMEM;
        goto done;
    }

    /* Progressive passes: start with one sample per pixel, then size passes to take about a
     * second (never past the time left), so progress, the convergence curve and Ctrl-C come
     * promptly. */
    uint64_t invalid = 0;
    const double t_image = now_seconds(clk); /* the image's first pass begins */
    int done = 0, pass = 1, curve_cap = 0;
    /* The photon passes' clock: samples of the estimate that reads the passes (the method's
     * own, or guided's beams: rd_method.marched_pixels), in pixel-samples (the samples before
     * s0 counted as if every pixel's were its). Pass i serves its samples [(i - 1), i) x photons.pass_spp x npix: with every pixel marched, pass i
     * is samples [(i - 1) pass_spp, i pass_spp) of every pixel, as before; with mp < npix a
     * pass ends at the first whole sample of every marched pixel past its share. */
    uint64_t marched = (uint64_t)s0 * npix, per_pass = (uint64_t)s->photons.pass_spp * npix;
    while (done < o->spp) {
        int stop[3] = {o->cancel && *o->cancel, deadline < INFINITY && now_seconds(clk) >= deadline, -pass};
        if (comm) { /* stop when any rank stops; the smallest pass */
            comm->reduce(comm->user, stop, 3, RD_COMM_INT, RD_COMM_MAX, -1);
            pass = -stop[2];
        }
        if (stop[0]) { res->stats.cancelled = 1; break; }
        if (stop[1]) { res->stats.timed_out = 1; break; }
        int n = pass < o->spp - done ? pass : o->spp - done;
        uint64_t mp = npix; /* the pixels whose samples read the passes, in this pass */
        if (pass_maps) {
            mp = m->marched_pixels ? m->marched_pixels(&ctx) : npix;
            if (mp > npix) mp = npix; /* (a pass per per_pass >= npix samples: none skipped) */
            /* Samples [done, done + n) stay within one photon pass. */
            int ip = (int)(marched / per_pass) + 1;
            /* (no pass while no pixel would read it: the selection gave those pixels away) */
            if (ip != ctx.photon_pass && mp > 0 &&
                (st = photon_pass(&ctx, pass_maps, ip, &pass_bake, first_bake, o->cancel, &res->stats, err, errlen)) != RD_OK) {
                /* A cancel while tracing a later pass ends the render with what it has. */
                if (st != RD_ERR_CANCELLED) goto done;
                st = RD_OK;
                res->stats.cancelled = 1;
                break;
            }
            if (mp > 0) { /* the samples until the pass's end, rounded up */
                uint64_t left = ((uint64_t)ip * per_pass - marched + mp - 1) / mp;
                if ((uint64_t)n > left) n = (int)left;
            }
            /* (Several ranks: the pass below finds the deadline at its first pixel, and they agree.) */
            if (!comm && deadline < INFINITY && now_seconds(clk) >= deadline) { res->stats.timed_out = 1; break; }
        }
        /* Samples [done, done + n) stay within one of the method's epochs. */
        int epoch_end = m->epoch_next ? m->epoch_next(&ctx, s0 + done) : INT_MAX;
        if (n > epoch_end - (s0 + done)) n = epoch_end - (s0 + done);
        /* the blocks' epoch, [a, epoch_end), and their last index (render_pass) */
        int a = RD_SHARE_FIRST;
        for (int b; m->epoch_next && (b = m->epoch_next(&ctx, a)) <= s0 + done;) a = b;
        const int lim = epoch_end - s0 < o->spp ? epoch_end : s0 + o->spp;
        double t0 = now_seconds(clk);
        int cut = render_pass(&ctx, th, &f, s0 + done, s0 + done + n, a, lim, deadline, o->cancel, clk, &invalid);
        int any_cancel = o->cancel && *o->cancel;
        if (comm) { /* a pass cut short on any rank is cut short on all */
            int v[2] = {cut, any_cancel};
            comm->reduce(comm->user, v, 2, RD_COMM_INT, RD_COMM_MAX, -1);
            cut = v[0], any_cancel = v[1];
        }
        if (!cut) done += n, marched += (uint64_t)n * mp;
        if (!cut && s0 + done == epoch_end) {
            /* How the render ends (rd_render_ctx.epoch_ahead, epoch_left): the bound that comes
             * first, each read as a multiple of the image's so far, its time by the deadline
             * (the largest over the ranks: one figure for all) or its samples. */
            double t = now_seconds(clk), by_samples = (double)(o->spp - done) / done, by_time = INFINITY;
            if (deadline < INFINITY && t > t_image) by_time = fmax(0.0, deadline - t) / (t - t_image);
            if (comm) comm->reduce(comm->user, &by_time, 1, RD_COMM_DOUBLE, RD_COMM_MAX, -1);
            ctx.epoch_ahead = by_time < by_samples ? by_time : 0.0;
            ctx.epoch_left = by_time < by_samples ? 0.0 : (double)(o->spp - done);
            m->epoch(&ctx, epoch_end);
        }
        double t1 = now_seconds(clk), elapsed = t1 - t_start;
        if (o->progress) o->progress(o->progress_user, done, o->spp, elapsed);
        if (o->reference) {
            double acc[3] = {0.0, 0.0, 0.0};
            rd_film_sq_err(&f, o->reference, acc);
            if (comm) comm->reduce(comm->user, acc, 3, RD_COMM_DOUBLE, RD_COMM_SUM, -1);
            /* (One process: after the loop, a failed push stops the render; several ranks go
             * on without the curve point, so that all keep calling the same collectives.) */
            if (!curve_push(res, &curve_cap, elapsed, acc[2] / npix, acc[1] > 0 ? sqrt(acc[0] / acc[1]) : 0.0) && !comm) {
                st = fail(err, errlen, RD_ERR_NOMEM, "out of memory for the convergence curve");
                goto done;
            }
        }
        if (cut) {
            if (any_cancel) res->stats.cancelled = 1;
            else res->stats.timed_out = 1;
            break;
        }
        double per = (t1 - t0) / n; /* seconds per sample per pixel */
        double budget = 1.0;
        if (deadline < INFINITY) budget = fmin(budget, deadline - t1);
        /* clamp in double before converting: budget/per can exceed INT_MAX */
        double next = per > 0 ? budget / per : 2.0 * pass;
        next = fmax(1.0, fmin(next, 4.0 * pass));
        pass = (int)next;
    }
    if (o->cancel && *o->cancel) res->stats.cancelled = 1;

    if (comm) { /* every pixel's sums onto rank 0: x + 0 = x, so the film of one process */
        comm->reduce(comm->user, f.sum, 3 * npix, RD_COMM_DOUBLE, RD_COMM_SUM, 0);
        comm->reduce(comm->user, f.sum2, 3 * npix, RD_COMM_DOUBLE, RD_COMM_SUM, 0);
        comm->reduce(comm->user, f.n, npix, RD_COMM_UINT32, RD_COMM_SUM, 0);
        if (f.wsum) {
            comm->reduce(comm->user, f.wl, 3 * npix, RD_COMM_DOUBLE, RD_COMM_SUM, 0);
            comm->reduce(comm->user, f.wsum, npix, RD_COMM_DOUBLE, RD_COMM_SUM, 0);
            comm->reduce(comm->user, f.wsum2, npix, RD_COMM_DOUBLE, RD_COMM_SUM, 0);
        }
    }
    /* "epochs" (ctx.blocks): a pixel's weights sum to the indices it rendered, whatever its
     * shares, which is what keeps its mean unbiased (integrators/select_share.c "Epoch shares");
     * checked where every pixel ran every pass and no sample was dropped (one process: another
     * rank's dropped samples are not counted here) */
    if (ctx.blocks && f.wsum && !comm && !res->stats.cancelled && !res->stats.timed_out && invalid == 0)
        for (size_t p = 0; p < npix; p++)
            if (f.wsum[p] != (double)done) {
                snprintf(err, errlen, "internal: pixel %zu's sample weights sum to %.17g, not its %d samples", p,
                         f.wsum[p], done);
                st = RD_ERR_INTERNAL;
                goto done;
            }
    rd_film_resolve(&f, res->image.rgb, res->stderr_img.rgb);
    res->image.w = res->stderr_img.w = w;
    res->image.h = res->stderr_img.h = h;
    uint64_t total = 0;
    for (size_t p = 0; p < npix; p++) total += f.n[p];
    rd_render_stats *rs = &res->stats;
    rs->spp = done; /* passes completed by every pixel (dropped samples aside) */
    rs->spp_mean = (double)total / (double)npix;
    rs->paths = total + invalid;
    rs->invalid = invalid;
    uint64_t samples = 0, cells = 0;
    rs->samples_min = 0;
    for (int i = 0; i < ctx.threads; i++) {
        rs->collisions += th[i].counters.collisions;
        rs->lookups += th[i].counters.lookups;
        rs->shadow_rays += th[i].counters.shadow_rays;
        rs->eq_flights += th[i].counters.eq_flights;
        rs->eq_samples += th[i].counters.eq_samples;
        rs->delta_samples += th[i].delta_samples;
        rs->delta_eq_samples += th[i].delta_eq_samples;
        rs->path_samples += th[i].path_samples;
        rs->beams_samples += th[i].beams_samples;
        rs->guide_vertices += th[i].guide_vertices;
        rs->beam_queries += th[i].beam_queries;
        rs->beam_hits += th[i].beam_hits;
        rs->probes += th[i].probes;
        if (th[i].rays == 0) { /* th->cells: a marcher's pdf segments, else guided flights' */
            rs->flight_segments += th[i].cells;
            continue;
        }
        rs->flight_segments += th[i].path_cells; /* (`guided`'s guided-unbiased paths) */
        if (rs->rays_marched == 0 || (int)th[i].samples_min < rs->samples_min) rs->samples_min = (int)th[i].samples_min;
        if ((int)th[i].samples_max > rs->samples_max) rs->samples_max = (int)th[i].samples_max;
        rs->rays_marched += th[i].rays;
        samples += th[i].ray_samples;
        cells += th[i].cells - th[i].path_cells;
    }
    if (comm) { /* the counters of every rank (rank 0's report), as for the film */
        uint64_t c[18] = {invalid, rs->collisions, rs->lookups, rs->shadow_rays, rs->delta_samples,
                          rs->rays_marched, samples, cells, rs->flight_segments, rs->guide_vertices,
                          rs->beam_queries, rs->beam_hits, rs->delta_eq_samples, rs->eq_flights,
                          rs->eq_samples, rs->probes, rs->path_samples, rs->beams_samples};
        int mm[2] = {rs->rays_marched ? -rs->samples_min : INT_MIN, rs->samples_max};
        comm->reduce(comm->user, c, 18, RD_COMM_UINT64, RD_COMM_SUM, 0);
        comm->reduce(comm->user, mm, 2, RD_COMM_INT, RD_COMM_MAX, 0);
        invalid = c[0], rs->collisions = c[1], rs->lookups = c[2], rs->shadow_rays = c[3];
        rs->delta_samples = c[4], rs->rays_marched = c[5], samples = c[6], cells = c[7];
        rs->flight_segments = c[8], rs->guide_vertices = c[9];
        rs->beam_queries = c[10], rs->beam_hits = c[11], rs->delta_eq_samples = c[12];
        rs->eq_flights = c[13], rs->eq_samples = c[14], rs->probes = c[15], rs->path_samples = c[16];
        rs->beams_samples = c[17];
        rs->samples_min = rs->rays_marched ? -mm[0] : 0, rs->samples_max = mm[1];
        rs->paths = total + invalid;
        rs->invalid = invalid;
    }
    if (rs->rays_marched) {
        rs->samples_per_ray = (double)samples / rs->rays_marched;
        rs->cells_per_ray = (double)cells / rs->rays_marched;
    }
    rs->seconds = now_seconds(clk) - t_start;
    rs->select_choices = select_report.choices, rs->select_traced = select_report.traced;
    rs->shares = ctx.shares;
    snprintf(res->select_trace_err, sizeof res->select_trace_err, "%s", select_report.err);
done:
    if (st != RD_OK) rd_render_result_free(res);
    rd_film_free(&f);
    rd_threads_free(th, ctx.threads);
    if (m->release) m->release(&ctx);
    if (pass_bake != first_bake) rd_baked_free(pass_bake);
    rd_baked_free(first_bake);
    rd_baked_free(own);
    return st;
}

/* ---- explain ------------------------------------------------------------------------------- */

const char *rd_explain_placement_name(int k)
{
    static const char *const names[RD_EXPLAIN_PLACEMENTS] = {"guided", "transmittance", "uniform"};
    return k >= 0 && k < RD_EXPLAIN_PLACEMENTS ? names[k] : "?";
}

void rd_explain_result_free(rd_explain_result *e)
{
    if (!e) return;
    free(e->t), free(e->T), free(e->f);
    for (int k = 0; k < RD_EXPLAIN_PLACEMENTS; k++) free(e->p[k]), free(e->samples[k]);
    memset(e, 0, sizeof *e);
}

rd_status rd_explain(const rd_scene *s, const rd_explain_opts *o, rd_explain_result *e,
                     char *err, size_t errlen)
{
    memset(e, 0, sizeof *e);
    const rd_camera *cam = &s->camera;
    if (o->px < 0 || o->py < 0 || o->px >= cam->width || o->py >= cam->height) {
        snprintf(err, errlen, "--pixel %d,%d: outside the %dx%d image", o->px, o->py, cam->width, cam->height);
        return RD_ERR_ARG;
    }
    int n = o->n > 0 ? o->n : 2000;
    if (n < 16 || n > 1000000) return fail(err, errlen, RD_ERR_ARG, "explain: dense points must be in [16, 1e6]");
    rd_render_ctx ctx = {.scene = s, .method = &rd_method_guided, .seed = o->seed,
                         .threads = o->threads > 0 ? o->threads : omp_get_max_threads()};
    rd_baked *own = NULL;
    rd_status st = attach_bake(&ctx, o->baked, o->threads, NULL, &own, err, errlen);
    if (st != RD_OK) return st;
    if ((st = ctx.method->prepare(&ctx, err, errlen)) == RD_OK) {
        e->px = o->px, e->py = o->py;
        ray3 r = rd_camera_ray(cam, o->px + 0.5, o->py + 0.5);
        st = rd_march_explain(&ctx, r, n, o->seed, e, err, errlen);
        ctx.method->release(&ctx);
    }
    rd_baked_free(own);
    if (st != RD_OK) rd_explain_result_free(e);
    return st;
}
