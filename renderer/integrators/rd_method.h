/* rd_method.h: the render methods' table and the context they render in. Internal to
 * renderer/ (tests include it too).
 *
 * A method is one file that defines a `const rd_method` and one row in method_list.h. It
 * says what it needs baked (a photon map, a guide grid), may prepare shared state once per
 * render (a pilot pass, tables), and answers radiance queries for camera rays from worker
 * threads, each with its own rd_thread (counters, scratch memory). render/render.c owns the passes,
 * the film, the time budget and the random numbers; nothing in a method touches them. */
#ifndef RD_METHOD_H
#define RD_METHOD_H

#include "transport/rd_path.h"

#ifdef __cplusplus
extern "C" {
#endif

struct pm_map;
struct sh_guide;

/* What one worker thread owns during a render. Zeroed before the render; scratch is
 * method->scratch_bytes(ctx) bytes (aligned to a cache line) allocated once per thread, or NULL.
 * Each starts a cache line of its own (RD_CACHE_LINE; rd_threads_new): the counters are
 * written at every density lookup, and two threads' counters in one line would make each
 * write a miss on the other core (on hard-narrow-spot, with every tile forced to delta's path,
 * a camera sample of guided-unbiased took 7-48% longer than delta's own, from run to run as
 * the allocations fell; docs/benchmarks.md, "Session 14"). */
#define RD_CACHE_LINE 64
typedef struct rd_thread {
    _Alignas(RD_CACHE_LINE) int index;
    uint64_t pixel;         /* the pixel being rendered (y * width + x), set before radiance() */
    int x, y;               /* ... and its column and row (set with it) */
    int pilot;              /* 1 while the selection's pilot samples the pixel (select.c) */
    rd_track_counters counters;
    /* Per-ray statistics of the marching methods (zero for the others). */
    uint64_t rays;          /* camera rays that entered the media */
    uint64_t ray_samples;   /* samples placed along them */
    uint64_t cells;         /* PDF segments (guide cells, extinction steps) built; guided-unbiased:
                             * its flights' distance-pdf segments */
    uint64_t guide_vertices; /* guided-unbiased: path vertices whose policy read the guide */
    uint64_t beam_queries, beam_hits; /* march.ls nee+beams: segments queried, balls they crossed */
    int want_gap;           /* nee+beams: 1 while the selection draws an image's beams sample
                             * (not the pilot's, and with epochs to use it), whose beam_gap it
                             * reads (select.c); the gap is computed only then */
    vec3 beam_gap;          /* ... the sample's beam estimates less the same with balls of half
                             * the volume (rd_march_beam_estimate's gap; its bias, select_rule.c) */
    uint64_t probes;        /* march.probes, settings.probes: the probes' camera chains (probes.c) */
    uint32_t samples_min, samples_max;
    uint64_t delta_samples; /* settings.select: camera samples given to delta's path (for
                             * delta with settings.equiangular "tiles": to its path without
                             * the strategy) */
    uint64_t delta_eq_samples; /* ... of those, with equiangular sampling on every flight */
    uint64_t path_samples;  /* `guided`'s selection: camera samples given to guided-unbiased's
                             * paths (march.guided_paths), */
    uint64_t path_cells;    /* ... and their flights' pdf segments (counted in `cells` too) */
    uint64_t beams_samples; /* `guided`'s selection: camera samples given to its beams
                             * estimator (march.beams) */
    void *scratch;
    size_t scratch_bytes;
} rd_thread;

/* What a render shares across threads (read-only while the passes run). */
typedef struct rd_render_ctx {
    const rd_scene *scene;
    const struct rd_method *method;
    const struct pm_map *photons;   /* built photon map, when the method needs it */
    const struct pm_map *photons_indirect; /* photons stored without their first flight (with
                                              progressive passes: the pass's; only put in spatial
                                              order, no queries, after pass 1 where pass_maps has
                                              RD_PASS_NO_INDEX) */
    const struct sh_guide *guide;   /* guide grid, when the method needs it */
    const struct sh_guide *guide_indirect; /* guide of the indirect map (march.ls nee+guide) */
    void *state;                    /* the method's own, from prepare (freed by release) */
    /* Progressive photon passes (photons.progressive, rd_method.pass_maps): the pass whose
     * photons `photons` / `photons_indirect` hold now (>= 1), and its gather radius relative to
     * pass 1's (rd_ppm_radius_scale). 0 and 1 with one fixed map. The render changes both
     * between its passes, never while a pass runs. */
    int photon_pass;
    double radius_scale;
    const struct pm_map *photons_first;          /* pass 1's maps: r_1 from their nearest photons */
    const struct pm_map *photons_indirect_first;
    /* Pass 1's photon work (0 without passes): the photons emitted, their tentative collisions
     * and the photons its kd-trees index (rd_bake_stats.indexed), from which the selection
     * counts a sample's share of the passes (RD_SELECT_PASSES). Every pass emits as many. */
    double pass_emitted, pass_collisions, pass_indexed;
    uint64_t seed;
    int threads;
    /* Several ranks on one image (rd_render_opts.comm; NULL: one process): a method that learns
     * from the image's samples (epoch) sums what each rank saw through it first. */
    const rd_comm *comm;
    const char *select_trace; /* rd_render_opts.select_trace (integrators/select.c) */
    struct rd_select_report *select_report; /* where a tile selection counts its choices and
                                               its trace's writes (render.c's; may be NULL) */
    /* At an epoch (rd_method.epoch), how the render ends (integrators/select_rule.c, "The
     * samples the image holds"), whichever bound comes first: at its deadline, epoch_ahead the
     * time left over the time its image has taken so far (the same on every rank: the
     * largest), or at its sample count, epoch_left the samples a pixel has left; the other 0.
     * Both 0: no end known, or nothing left. */
    double epoch_ahead, epoch_left;
    /* Set by prepare where the method weighs its samples (rd_method.sample_share's weight: a tile
     * selection with settings.adaptive's shares, integrators/select_share.c; or blocks, below):
     * the film keeps the weighted sums (render/film.c). */
    int weighted;
    int shares; /* set by prepare where its selection gives the tiles shares of the samples (the report) */
    int blocks; /* and where each sample weighs the indices it stands for (rd_block_next; "epochs") */
} rd_render_ctx;

/* What a tile selection reports to the render (rd_render_stats.select_choices, select_traced,
 * rd_render_result.select_trace_err). */
typedef struct rd_select_report {
    int choices, traced;
    char err[RD_ERRLEN]; /* the trace's first failed write, or "" */
} rd_select_report;

/* Beside a progressive pass's maps (rd_method.pass_maps; a bit no RD_NEEDS_* flag of
 * renderer.h uses): the passes after the first are read photon by photon in spatial order and
 * asked no query, so they get that order without the kd-tree (pm_map_order; nee+beams, whose
 * k-NN radii come from pass 1's map, which is built whatever this says). */
enum { RD_PASS_NO_INDEX = 1u << 16 };
/* Beside a progressive pass's maps (the indirect map alone: render.c ignores it beside
 * RD_NEEDS_PHOTONS): the passes after the first are read as at most about as many
 * photons as the pass emitted (nee+beams keeps that many balls, march_beams.c), so they are
 * thinned as they are traced: each collision stored with probability
 * q = min(1, emitted / stored in pass 1), its power 1/q (rd_photon_opts.keep). In a dense medium,
 * where a photon stores a collision every mean free path, the pass then neither stores nor orders
 * the collisions the beams would drop (hard-dense-block: 1.85 million stored a pass, 0.2 million
 * kept). */
enum { RD_PASS_THIN = 1u << 17 };

typedef struct rd_method {
    const char *name;
    const char *summary;   /* one line, for --help and the report */
    unsigned needs;        /* the RD_NEEDS_* flags (renderer.h) the method can ask for, at most */
    /* Optional: what this scene's settings need (a subset of `needs`); NULL = `needs`. */
    unsigned (*needs_for)(const rd_scene *scene);
    /* Optional: the photon maps a progressive photon pass must trace anew for this scene
     * (RD_NEEDS_PHOTONS, RD_NEEDS_INDIRECT; 0 = none: no passes, the hook's to decide from the
     * scene, photons.progressive or `guided`'s march.beams), with RD_PASS_NO_INDEX where the passes after the
     * first are only read in spatial order, RD_PASS_THIN where they are thinned (above). NULL = none. */
    unsigned (*pass_maps)(const rd_scene *scene);
    /* Optional: called when a progressive photon pass has put new maps into ctx (between the
     * render's passes, after prepare; not for pass 1, whose maps prepare sees). */
    rd_status (*photons_changed)(rd_render_ctx *ctx, char *err, size_t errlen);
    /* Optional: how many of the image's pixels the estimate that reads the passes' photons
     * renders now (the method's own, or `guided`'s beams estimator; its tile selection gives the
     * rest to other estimators), at most all of them, constant between
     * epochs and the same on every rank (the photon passes are collective). Progressive photon
     * passes are paced by these pixels' samples: a pass per photons.pass_spp x (all pixels)
     * samples of the method, so that no pass is traced for samples that do not use it. NULL =
     * every pixel. */
    uint64_t (*marched_pixels)(const rd_render_ctx *ctx);
    /* Optional: per-thread scratch size for this render. */
    size_t (*scratch_bytes)(const rd_render_ctx *ctx);
    /* Optional: once per render, after the bake, before the passes (e.g. a pilot pass). */
    rd_status (*prepare)(rd_render_ctx *ctx, char *err, size_t errlen);
    /* Optional, both or neither: epochs, at which the method learns from the image's samples
     * so far (settings.select's tiles, integrators/select.c; the probes' lambda,
     * integrators/probes.c). epoch_next gives the first sample
     * index after `sample` at which an epoch ends (INT_MAX: none); the render cuts its passes
     * there and, when every pixel has rendered exactly that many samples, calls epoch() from
     * the calling thread, no pass running. */
    int (*epoch_next)(const rd_render_ctx *ctx, int sample);
    void (*epoch)(rd_render_ctx *ctx, int sample);
    /* Optional: frees ctx->state. */
    void (*release)(rd_render_ctx *ctx);
    /* Radiance arriving at the camera along r. The sampler is keyed by (pixel, sample) and
     * positioned after the film dimensions (RD_DIM_METHOD); the method draws from it only. */
    vec3 (*radiance)(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp);
    /* Optional: called by the thread that rendered them after each pixel's samples of a pass
     * (the tile selection writes back what it gathered over the pixel's samples: select.c). */
    void (*pixel_done)(const rd_render_ctx *ctx, rd_thread *th);
    /* Optional: the share in [0, 1] of the samples past the first RD_SHARE_FIRST that pixel
     * (x, y) draws (render.c draws sample i where floor((i + 1 - RD_SHARE_FIRST) share) passes
     * a whole number; with rd_render_ctx.blocks as rd_block_next says), and in *weight the
     * weight in the pixel's mean of every sample it draws in the pass (left as it is: 1); NULL: every sample, each weighing 1 (settings.adaptive:
     * select_share.c, "Samples where they pay" and "Weights"; the film keeps the weighted sums
     * where prepare set rd_render_ctx.weighted). Read once a pixel a pass. */
    double (*sample_share)(const rd_render_ctx *ctx, int x, int y, double *weight);
} rd_method;

/* The samples every pixel draws whatever its share (rd_method.sample_share): the first epoch's. */
#define RD_SHARE_FIRST 4

/* Does a pixel of share `share` (in [0, 1]; rd_method.sample_share) draw sample i? Every sample
 * below RD_SHARE_FIRST, and sample i past them where (i + 1 - RD_SHARE_FIRST) share reaches a
 * whole number. */
static inline int rd_share_draws(int i, double share)
{
    return share >= 1.0 || i < RD_SHARE_FIRST ||
           floor((i + 1 - RD_SHARE_FIRST) * share) != floor((i - RD_SHARE_FIRST) * share);
}

/* The first sample in [i, end) that a pixel of share `share` draws (rd_share_draws), else end:
 * found at once, not index by index (a share of 0.01 would test a hundred indices a sample).
 * With u = i - RD_SHARE_FIRST and g(v) = floor(v share), nondecreasing in v (a product by a
 * positive double is monotone), the next drawn index is the smallest v - 1 + RD_SHARE_FIRST
 * with g(v) >= g(u) + 1; ceil((g(u) + 1) / share) guesses v, and the steps after it make the
 * answer the predicate's own, rounding and all. */
static inline int rd_share_next(int i, int end, double share)
{
    if (i >= end || rd_share_draws(i, share)) return i;
    if (!(share > 0.0)) return end; /* (past the first samples a share of 0 draws none; below 0: as 0) */
    const double u = (double)(i - RD_SHARE_FIRST), j = floor(u * share) + 1.0;
    const double guess = ceil(j / share), last = (double)(end - RD_SHARE_FIRST); /* v of end - 1: last */
    if (!(guess <= last + 1.0)) return end;
    double v = guess > u + 1.0 ? guess : u + 1.0;
    while (v - 1.0 > u && floor((v - 1.0) * share) >= j) v -= 1.0;
    while (v <= last && floor(v * share) < j) v += 1.0;
    return v <= last ? (int)v - 1 + RD_SHARE_FIRST : end;
}

/* settings.adaptive "epochs" (select_share.c, "Epoch shares"): in an epoch that begins at index a
 * a pixel of share `share` draws a, then where (v - a) share reaches a whole number (rd_share_next's
 * pattern begun at a); the first such index in [i, end), else end. A drawn index v stands for
 * itself and the indices up to the next drawn one or the epoch's end, its weight in the mean.
 * For a >= RD_SHARE_FIRST (render.c's; an index below a counts as drawn). */
static inline int rd_block_next(int i, int a, int end, double share)
{
    const int off = a + 1 - RD_SHARE_FIRST; /* v is index v - off of rd_share_next's pattern */
    return rd_share_next(i - off, end - off, share) + off;
}

/* The table (methods.c). NULL for an unknown name. */
const rd_method *rd_method_find(const char *name);

/* The worker threads (threads.c). rd_threads_new: n zeroed per-thread contexts for ctx's
 * method (index set, scratch allocated, each scratch on cache lines of its own), or NULL when
 * out of memory; rd_threads_free frees them and their scratch. */
rd_thread *rd_threads_new(const rd_render_ctx *ctx, int n);
void rd_threads_free(rd_thread *th, int n);
/* `bytes` of zeroed memory starting a cache line (free with free()), or NULL: for per-pixel
 * arrays that two threads write at neighbouring pixels, so that a tile boundary is a line
 * boundary whenever a tile row's bytes are a whole number of lines. */
void *rd_alloc_lines(size_t bytes);

/* guided-unbiased (integrators/guided_unbiased.c), for the sampler's tests, on a context prepared for the
 * method (scratch: method->scratch_bytes(ctx) bytes). rd_gu_flight draws one free flight
 * exactly as its path tracer does; *P_pass (may be NULL) gets the flight's pass probability
 * (-1 when it fell back to delta tracking: no guide, guide.secondary off at depth > 0, no
 * medium on the way, or I_ray = 0).
 * rd_gu_flight_cdf gives the probability that that flight scatters before distance t, and
 * *P_pass; cdf(t1) + P_pass = 1 at the end t1 of the media interval. */
rd_flight rd_gu_flight(const rd_render_ctx *ctx, void *scratch, const rd_flight_in *in,
                       pcg32 *rng, rd_track_counters *c, double *P_pass);
double rd_gu_flight_cdf(const rd_render_ctx *ctx, void *scratch, const rd_flight_in *in,
                        double t, double *P_pass);
/* guided-unbiased's vertex policy (roulette/splitting and the direction mixture) at vertex v,
 * for a camera sample whose guide estimate is I_cam (0: none, the throughput roulette). The
 * direction lobes are the scene's and guide's as they were at prepare (a changed medium or
 * guide is prepared again). */
void rd_gu_vertex(const rd_render_ctx *ctx, const rd_vertex_in *v, double I_cam, pcg32 *rng,
                  rd_vertex_out *out);

/* guided-unbiased's path alone, as an estimator that another method's tile selection holds
 * (`guided`'s, march.guided_paths: integrators/guided.c): the method's flights, vertex policy,
 * roulette and probes (guide.probes) on ctx's guide (and its indirect guide for the direction
 * lobe, where ctx has one), without a selection of its own. rd_gu_paths_new validates the guide
 * settings as the method's prepare does (errors: RD_ERR_ARG naming the field, RD_ERR_NOMEM);
 * rd_gu_paths_radiance is one camera sample on ctx (its state the caller's) with th's scratch of
 * at least rd_gu_paths_scratch_bytes bytes; th->cells counts its flights' pdf segments, and
 * th->guide_vertices its guided vertices, as the method's. The probes' epochs (guide.probes
 * "auto": integrators/probes.c) are the caller's to run: rd_gu_paths_epoch_next gives the next
 * after `sample` (INT_MAX: none), rd_gu_paths_epoch runs one (no pass running). */
typedef struct rd_gu_paths rd_gu_paths;
rd_status rd_gu_paths_new(const rd_render_ctx *ctx, rd_gu_paths **out, char *err, size_t errlen);
size_t rd_gu_paths_scratch_bytes(const rd_gu_paths *p);
vec3 rd_gu_paths_radiance(const rd_render_ctx *ctx, const rd_gu_paths *p, rd_thread *th, ray3 r, rd_sampler *smp);
int rd_gu_paths_epoch_next(const rd_gu_paths *p, int sample);
void rd_gu_paths_epoch(const rd_render_ctx *ctx, rd_gu_paths *p);
void rd_gu_paths_free(rd_gu_paths *p);
/* What the paths need baked beside the guide (RD_NEEDS_*): the indirect photons' guide for the
 * direction lobe where guide.directions is on (RD_NEEDS_INDIRECT_LOBE). */
unsigned rd_gu_paths_needs(const rd_scene *s);
/* The counted cost of one of its flights' pdf segments, in density lookups (select.c, the fit). */
#define RD_GU_CELL_COST 0.41

/* explain (integrators/march_explain.c): fill res for ray r on a context prepared for `guided`. */
rd_status rd_march_explain(const rd_render_ctx *ctx, ray3 r, int n, uint64_t seed,
                           rd_explain_result *res, char *err, size_t errlen);

/* The methods, one `rd_method_<id>` per row of method_list.h. */
#define RD_METHOD(id) extern const rd_method rd_method_##id;
#include "integrators/method_list.h"
#undef RD_METHOD

#ifdef __cplusplus
}
#endif
#endif /* RD_METHOD_H */
