/* renderer.h: the public API of photonmarch's renderer module.
 *
 * Loads and validates a JSON scene (docs/scene-format.md), renders it with one of the methods,
 * writes images, and describes the scene. The command line (renderer/cli/) is a thin layer over
 * this header.
 *
 * Errors: every fallible function returns rd_status and, when `err` is non-NULL, writes one
 * line naming the file and the JSON path ("fog.json: media[0].albedo: expected 3 numbers in
 * [0,1]") into the caller's buffer. Nothing here prints (except through the caller's progress
 * callback) and nothing exits.
 * Ownership: every _new/_load has a _free; _free(NULL) is safe.
 */
#ifndef PHOTONMARCH_RENDERER_H
#define PHOTONMARCH_RENDERER_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    RD_OK = 0,
    RD_ERR_ARG,    /* bad argument or option value */
    RD_ERR_NOMEM,  /* allocation failed */
    RD_ERR_IO,     /* file missing, unreadable or unwritable */
    RD_ERR_PARSE,  /* not valid JSON */
    RD_ERR_SCENE,  /* valid JSON, invalid scene (wrong type, range, unknown key, ...) */
    RD_ERR_FORMAT, /* a data file (volume, image) is corrupt or of the wrong kind */
    RD_ERR_INTERNAL,
    RD_ERR_OUTPUT, /* an output file or folder could not be written */
    RD_ERR_CANCELLED /* stopped by the caller's cancel flag (a signal); nothing was written */
} rd_status;

#define RD_ERRLEN 512

typedef struct rd_scene rd_scene; /* opaque; its fields: scene/rd_scene.h (internal) */
typedef struct rd_baked rd_baked; /* a photon map and its guide grid (rd_bake); opaque */

/* One `key=value` override applied to the JSON tree before validation (--set). The key is a
 * dotted JSON path with [i] indices ("settings.spp", "lights[0].intensity"); the value is
 * parsed as JSON, or taken as a string if it is not valid JSON. */
typedef struct { const char *key, *value; } rd_override;

/* Load, apply overrides, validate every field, load volume files (paths relative to the scene
 * file's folder), precompute majorants. A scene with glass, media and a point, spot or
 * directional light also gets a short photon trace on all cores (rd_hidden_light, 50000
 * photons, nothing stored): where it finds light only photons render, march.ls and
 * photons.progressive default to nee+beams and true (docs/scene-format.md). */
rd_status rd_scene_load(rd_scene **out, const char *path, const rd_override *ov, int nov,
                        char *err, size_t errlen);
void rd_scene_free(rd_scene *scene);

/* Human-readable description: media, bounds, density range, lights, memory. */
void rd_scene_info(const rd_scene *scene, FILE *out);
/* The share (luminance) of the light scattered in the media that only L S+ paths carry: light
 * that leaves a point, spot or directional light through glass first, which next-event
 * estimation cannot reach (a shadow ray stops at glass) and a path cannot hit (a delta light),
 * so that `delta`, `guided-unbiased` and `guided` with an unbiased march.ls render none of it
 * (bake/photons.c: a trace of `count` photons with a seed of its own, the power the photons
 * scatter in the media after such a first event over all they scatter there). 0 without a
 * trace when the scene has no glass shape, no point, spot or directional light, or no medium.
 * *caustic (NULL: not wanted; then the trace runs as said): the share on L S+ paths from any
 * light, sphere and environment lights too, which a path finds only by hitting the light
 * through the glass and next-event estimation never (`info` prints it; docs/guided-marching.md,
 * "Light through glass from a sphere light"); with it the trace runs for any light of positive
 * power. */
rd_status rd_hidden_light(const rd_scene *s, size_t count, int threads, double *share, double *caustic,
                          char *err, size_t errlen);
/* Light only photons find, as the loader measures it (RD_HIDDEN_PHOTONS photons) and acts on it
 * above RD_HIDDEN_SHARE of the media's light: march.ls defaults to nee+beams (load/load.c),
 * `compare` renders its reference with progressive photons, `info` and `render` say so
 * (docs/compare.md, "Light only photons find"). */
#define RD_HIDDEN_SHARE 0.001
#define RD_HIDDEN_PHOTONS 50000


/* Render settings as loaded (after overrides). */
int rd_scene_width(const rd_scene *scene);
int rd_scene_height(const rd_scene *scene);
int rd_scene_spp(const rd_scene *scene);
double rd_scene_time_limit(const rd_scene *scene);
uint64_t rd_scene_seed(const rd_scene *scene);
const char *rd_scene_method(const rd_scene *scene);
double rd_scene_exposure(const rd_scene *scene); /* camera.exposure, for the PNG preview */
int rd_scene_spp_given(const rd_scene *scene);    /* 1 when settings.spp is in the file */
/* 1 when march.ls takes in-scattered light from photons (photons, nee+photons, nee+guide,
 * nee+beams), so that the marchers find light that only photons find (rd_hidden_light). */
int rd_scene_march_uses_photons(const rd_scene *scene);
/* rd_hidden_light's share, measured when the scene was loaded (after its overrides). */
double rd_scene_hidden_light(const rd_scene *scene);

/* ---- Methods ----------------------------------------------------------------------------- *
 * The render methods form one table (renderer/integrators/methods.c); --help, settings.method,
 * the report and rd_render all read it. */
/* What a method needs baked: a photon map, its guide grid, and the photon map of the photons
 * stored without their first flight (multiple scattering only, beside next-event estimation).
 * RD_NEEDS_FEW_PHOTONS: the guide only steers sampling decisions, so a share of the photons
 * serves (guide.photon_share of photons.count; guided-unbiased). RD_NEEDS_REACHABLE: the maps
 * (and so the guides) hold only light the method's paths can reach, without the light that a
 * point, spot or directional light sends through glass (rd_bake_opts.reachable;
 * guided-unbiased, whose guide steers paths that cannot find that light). RD_NEEDS_INDIRECT_LOBE:
 * the indirect map's guide read for its direction lobe alone, its first two bands (guided-unbiased's
 * paths): baked with those two only (rd_bake_opts.indirect_bands), unless RD_NEEDS_INDIRECT_GUIDE
 * asks for all of them. */
enum { RD_NEEDS_PHOTONS = 1, RD_NEEDS_GUIDE = 2, RD_NEEDS_INDIRECT = 4, RD_NEEDS_INDIRECT_GUIDE = 8,
       RD_NEEDS_FEW_PHOTONS = 16, RD_NEEDS_REACHABLE = 32, RD_NEEDS_INDIRECT_LOBE = 64 };
int rd_method_count(void);
/* Name, one-line summary and needs of method i (0 <= i < rd_method_count()). */
const char *rd_method_name(int i);
const char *rd_method_summary(int i);
unsigned rd_method_needs(int i);
/* The method names, comma-separated, into buf (truncated to n); returns the length needed. */
size_t rd_methods(char *buf, size_t n);
/* What `method` needs baked for this scene's settings (RD_NEEDS_*; 0 for an unknown method). */
unsigned rd_method_needs_for(const char *method, const rd_scene *scene);

/* ---- Rendering --------------------------------------------------------------------------- */

/* Linear RGB film: w*h pixels, 3 floats each, row-major from the top-left. */
typedef struct {
    int w, h;
    float *rgb;
    int channels; /* rd_image_read: the channels the file had (rgb holds RGB regardless); else 0 */
} rd_image;

void rd_image_free_pixels(rd_image *img);

/* A time source: seconds from any fixed origin, never decreasing, callable from several threads
 * at once. Renders and comparisons read every time they keep or report (time_limit, the bake's
 * charge, the seconds in the report and the convergence curve) on one such clock; NULL means
 * rd_clock_monotonic, wall time. Another clock gives a budget in CPU seconds, or a test its own
 * virtual time. (The bake's own statistics, rd_bake_stats.seconds, stay wall time.) */
typedef double (*rd_clock_fn)(void *user);
double rd_clock_monotonic(void *user); /* CLOCK_MONOTONIC in seconds; user is ignored */

/* For a program that renders several times in one process (compare's runs, the benchmarks):
 * every render's large blocks (1 MiB and up) from fresh pages, as in the process's first. glibc's
 * malloc raises its mmap threshold each time a large block is freed, after which a later
 * render's growing photon arrays are grown on the heap by copying: `guided`'s bake and pilot on
 * hard-dense-block took 1.36 s after a `guided-unbiased` render in the same process against
 * 1.24 s first (docs/benchmarks.md "Session 51"). Call once, before the first render; a no-op
 * where the C library has no such setting. */
void rd_steady_allocation(void);

/* Several processes on one job (MPI ranks, docs/cluster.md): the plain C hooks through which a
 * render shares its work. The library never calls MPI itself; the command line's renderer/dist/
 * implements these with MPI, and a test may implement them with threads. NULL, or size <= 1:
 * one process, and nothing below is called. */
typedef enum { RD_COMM_DOUBLE, RD_COMM_UINT32, RD_COMM_UINT64, RD_COMM_INT } rd_comm_type;
typedef enum { RD_COMM_SUM, RD_COMM_MIN, RD_COMM_MAX } rd_comm_op;
typedef struct rd_comm {
    int rank, size;   /* this process's rank in [0, size) and the number of ranks */
    void *user;       /* passed to the hooks */
    /* Element-wise reduce of buf[0, count) (elements of `type`) over every rank with `op`, in
     * place: root < 0 leaves the result in every rank's buf (an allreduce), root >= 0 in that
     * rank's only (the others' buf is then unspecified). Collective: every rank calls it with the
     * same count, type, op and root, in the same order. A failure ends the job (MPI's default
     * error handler), so it returns nothing. */
    void (*reduce)(void *user, void *buf, size_t count, rd_comm_type type, rd_comm_op op, int root);
    /* Gather onto every rank (an allgatherv): rank r contributes counts[r] elements of
     * elem_bytes bytes each from `send`; `recv` receives every rank's elements in rank order
     * (counts[0] + ... + counts[size-1] elements). counts and elem_bytes are the same on every
     * rank (a reduce of the counts gives them). `send` may be this rank's own place in recv (in
     * place). Collective, like reduce; a failure ends the job.
     * The bake gathers its photons through it (rd_bake_opts.comm). */
    void (*allgatherv)(void *user, const void *send, void *recv, const size_t *counts, size_t elem_bytes);
} rd_comm;
/* A collective step that failed on another rank (and not on this one) ends its message with
 * this, so that the caller can leave the saying to the rank that failed. */
#define RD_ON_ANOTHER_RANK "on another rank"


typedef struct {
    const char *method;  /* a name from the method table */
    int spp;             /* samples per pixel to reach (>= 1) */
    double time_limit;   /* seconds; > 0 stops when the time is up (checked before every pixel:
                            no pixel starts at or after the deadline, so the budget is kept to
                            within a pixel's work and the film's resolve); spp still caps */
    rd_clock_fn clock;   /* the clock of time_limit, baked_seconds and the reported seconds; */
    void *clock_user;    /* NULL: rd_clock_monotonic. clock_user is passed to it */
    uint64_t seed;
    int threads;         /* 0 = OpenMP default */
    /* Polled between pixels: when it becomes non-zero the render stops and rd_render returns
     * RD_OK with the samples done so far (pixels may then differ by one pass in count). Also
     * passed to the bake rd_render makes when `baked` is NULL and to the tracing of the
     * progressive photon passes: set during the bake or the first pass, rd_render returns
     * RD_ERR_CANCELLED with nothing rendered (on every rank: they agree on the bake's outcome);
     * during a later photon pass, RD_OK with the samples so far. */
    const volatile int *cancel;
    /* Called after every pass (from the calling thread). May be NULL. */
    void (*progress)(void *user, int spp_done, int spp_total, double seconds);
    void *progress_user;
    /* Photon map and guide for the methods that need them (rd_method_needs); borrowed. NULL:
     * rd_render bakes them itself when the method needs them (time counted in the render). */
    const rd_baked *baked;
    double baked_seconds;  /* time the caller spent obtaining `baked` (a bake or a cache load):
                              counted in the render's seconds and against its time limit */
    /* Optional converged image of the same size: the RMSE of the running mean against it is
     * recorded after every pass (rd_render_result.curve). Borrowed. */
    const rd_image *reference;
    /* Index of every pixel's first sample (default 0): the render takes samples
     * [first_sample, first_sample + spp), so a render of N samples followed by one of M more
     * with first_sample = N and the same seed are together the render of N + M samples (the
     * random numbers are keyed by the sample index). compare extends its reference this way.
     * Not so for the guided methods with a tile selection (settings.select "auto", "tiles",
     * "pilot"), nor with march.probes or settings.probes "auto": each render runs its own pilot
     * and epochs, so the continuation is another render (unbiased, or consistent with
     * nee+beams), not the same one. */
    int first_sample;
    /* Several ranks render one image (NULL: this process alone; borrowed): rank r renders the
     * 16x16 tiles whose index is r modulo size, the ranks agree after every pass whether to stop
     * (the time limit or the cancel flag of any rank stops them all) and on the next pass's size
     * (the smallest), and the films are summed onto rank 0, whose result is the image of one
     * process, bit for bit (each pixel is rendered by one rank; the others add zeros). The
     * other ranks' results hold only their own pixels. Every rank calls rd_render with the
     * same scene and options. */
    const rd_comm *comm;
    /* Optional path: the guided methods' tile selection (settings.select; `delta`'s "tiles")
     * writes there, at its pilot and at every epoch, each 8x8 tile's choice and the figures it
     * was made from, one JSON line a choice (docs/cli.md, "The selection's trace"), the whole
     * file rewritten in place each time (rd_write_atomic). A render without a selection writes
     * nothing. Rank 0 alone writes. A write that fails does not stop the render: the result
     * says so (rd_render_stats.select_traced, rd_render_result.select_trace_err). NULL: none. */
    const char *select_trace;
} rd_render_opts;

typedef struct {
    double seconds;          /* time of the render on its clock (wall time), bake included */
    double bake_seconds;     /* of which baking the photon map and guide */
    int spp;                 /* samples per pixel completed by every pixel */
    double spp_mean;         /* samples per pixel on average (a stopped pass leaves some behind) */
    uint64_t paths;          /* camera samples taken */
    uint64_t collisions;     /* tentative collisions (real + null) of free-path sampling */
    uint64_t lookups;        /* density evaluations */
    uint64_t shadow_rays;    /* next-event transmittance estimates */
    uint64_t eq_flights;     /* flights that set up the equiangular strategy */
    uint64_t eq_samples;     /* equiangular samples evaluated */
    uint64_t invalid;        /* non-finite samples dropped (should be 0; reported if not) */
    int cancelled;           /* 1 when the cancel flag stopped the render early */
    int timed_out;           /* 1 when the time limit stopped it */
    int threads;             /* worker threads used */
    double prepare_seconds;  /* the method's set-up after the bake (e.g. a pilot pass) */
    /* Ray-marching methods: camera rays that entered the media, samples per such ray (mean,
     * min, max) and PDF segments built per ray (guide cells crossed; 0 for other methods). */
    uint64_t rays_marched;
    double samples_per_ray;
    int samples_min, samples_max;
    double cells_per_ray;
    /* the guided methods with a tile selection (settings.select): camera samples it gave to
     * delta's path instead of the method (integrators/select.c), and how many of those were
     * delta's path with equiangular sampling on every flight (RD_SEL_DELTA_EQ); `delta` with
     * settings.equiangular "tiles": the samples its tiles rendered without the strategy
     * (integrators/delta.c). */
    uint64_t delta_samples, delta_eq_samples;
    /* `guided` with march.guided_paths: the camera samples its selection gave to
     * guided-unbiased's paths (their guide reads are in flight_segments and guide_vertices). */
    uint64_t path_samples;
    /* `guided` with march.beams: the camera samples its selection gave to the marcher with the
     * nee+beams source (integrators/guided.c). */
    uint64_t beams_samples;
    /* guided-unbiased: distance-pdf segments its flights built (guide cells crossed) and path
     * vertices whose policy read the guide: with lookups and shadow rays, what a sample costs
     * (the selection's counted cost, integrators/select.c). 0 for the other methods. */
    uint64_t flight_segments, guide_vertices;
    /* march.ls nee+beams: camera-ray segments whose balls were gathered, and the balls they
     * crossed (what the beam estimate costs; the selection counts the balls). */
    uint64_t beam_queries, beam_hits;
    /* march.probes and settings.probes: the camera chains the samples added for the light at a
     * chain's end (integrators/probes.c). */
    uint64_t probes;
    /* Progressive photon passes (photons.progressive, or `guided`'s march.beams; 0 passes with
     * one fixed map): passes
     * traced, photons emitted over them, seconds spent tracing and indexing them (part of
     * `seconds`), the last pass's gather radius relative to the first pass's, the share of
     * its collisions the last pass stored (1, or RD_PASS_THIN's q: rd_method.h) and the photons
     * it stored. */
    int photon_passes;
    uint64_t photons_traced;
    double photon_seconds;
    double radius_scale;
    double photon_keep;
    size_t photons_stored;
    /* The tile selection (settings.select): the choices it made (its pilot's, one an epoch; 0:
     * the render had no selection) and, with rd_render_opts.select_trace, how many of them the
     * trace holds (on rank 0; the others write none). */
    int select_choices, select_traced;
    /* 1 where the selection gave its tiles shares of the samples (settings.adaptive true, each
     * sample weighing in its pixel's mean, "pilot", unweighted, or "epochs", each sample weighing
     * the indices it stands for; or "auto" for the guided methods); spp_mean then at most spp,
     * fewer where a tile's share fell below 1 (under "epochs" still one sample an epoch). */
    int shares;
} rd_render_stats;

/* One point of the convergence curve: RMSE of the image so far against the reference. */
typedef struct {
    double seconds, spp_mean, rmse;
} rd_conv_point;

typedef struct {
    rd_image image;       /* the per-pixel mean */
    rd_image stderr_img;  /* per-pixel standard error of that mean, per channel:
                             sqrt(sample variance / n); 0 where a pixel has fewer than 2 samples */
    rd_render_stats stats;
    rd_conv_point *curve; /* one point per pass when opts.reference was given, else NULL */
    int n_curve;
    char select_trace_err[RD_ERRLEN]; /* the first failed write of the selection's trace, or "" */
} rd_render_result;

void rd_render_result_free(rd_render_result *res); /* frees the images and the curve */

rd_status rd_render(const rd_scene *scene, const rd_render_opts *opts, rd_render_result *res,
                    char *err, size_t errlen);

/* ---- Explain one pixel (docs/guided-marching.md "explain") ------------------------------- *
 * For the camera ray through the centre of pixel (px, py): the integrand of the marchers,
 * f(t) = T(0,t) sigma_s L_s(x(t), -d) (luminance), evaluated densely and deterministically
 * (T by a midpoint quadrature of sigma_t on the dense points, L_s from the scene's march.ls
 * source averaged over 16 draws of its next-event estimate), beside the PDF each placement
 * would sample (guided, transmittance, uniform), where one draw of each placement puts its
 * samples, and the variance each placement's stratified estimate of the integral I would have
 * (from 4000 simulated draws against the dense integrand). Uses the scene's march settings. */
enum { RD_EXPLAIN_GUIDED, RD_EXPLAIN_TRANSMITTANCE, RD_EXPLAIN_UNIFORM, RD_EXPLAIN_PLACEMENTS };

typedef struct {
    int px, py;
    const rd_baked *baked;  /* the guided method's bake (rd_bake / rd_bake_cached); NULL bakes */
    int n;                  /* dense points, >= 16 (0: 2000) */
    uint64_t seed;
    int threads;
} rd_explain_opts;

typedef struct {
    int px, py;
    double origin[3], dir[3];
    int hits_media;          /* 0: the ray misses the media; the arrays below are then NULL */
    double t0, t1;           /* the medium span along the ray [scene units] */
    int n;
    double *t, *T, *f;       /* dense midpoints, T(0,t), integrand f(t) */
    double *p[RD_EXPLAIN_PLACEMENTS];       /* each placement's pdf at t [1/unit] */
    int n_samples[RD_EXPLAIN_PLACEMENTS];   /* samples it takes on this ray */
    double *samples[RD_EXPLAIN_PLACEMENTS]; /* one draw of their positions */
    double I;                /* integral of f (midpoint rule over the dense points) */
    double T_end;            /* T(0, t1) */
    double I_ray, mean_I;    /* the guide's I_ray and the pilot's mean I (eq. 17) */
    double var[RD_EXPLAIN_PLACEMENTS];      /* variance of the estimate of I */
    double var_se[RD_EXPLAIN_PLACEMENTS];   /* standard error of that variance (from the draws) */
    double m4[RD_EXPLAIN_PLACEMENTS];       /* fourth central moment of the estimate */
} rd_explain_result;

const char *rd_explain_placement_name(int k); /* "guided", "transmittance", "uniform" */
rd_status rd_explain(const rd_scene *scene, const rd_explain_opts *opts, rd_explain_result *res,
                     char *err, size_t errlen);
void rd_explain_result_free(rd_explain_result *res);

/* Write PREFIX.json (scalars, variances, sample positions), and when the ray meets the media
 * PREFIX.csv (t, T, f, p_ideal = f/I, p_guided, p_transmittance, p_uniform) and PREFIX.gp (a
 * gnuplot script drawing PREFIX.png from the CSV), each through a temporary name. */
rd_status rd_explain_write(const rd_scene *scene, const rd_explain_result *res, const char *prefix,
                           char *err, size_t errlen);
/* Run gnuplot on PREFIX.gp (in its folder). 1 on success; 0 with the reason in err. */
int rd_explain_plot(const char *prefix, char *err, size_t errlen);

/* Write a finished render: OUT.exr (mean, linear), OUT-stderr.exr (per-pixel standard error),
 * OUT.png (sRGB preview at camera.exposure) and OUT.json (the report: method, samples, times,
 * counters, convergence curve), each through a temporary name and a rename. `exr_path` ends in
 * .exr; its folder is created. Errors: RD_ERR_OUTPUT naming the file. */
rd_status rd_render_write(const rd_scene *scene, const rd_render_opts *opts,
                          const rd_render_result *res, const char *exr_path, char *err,
                          size_t errlen);

/* ---- Baking: photon map and guide grid (seed 001 §3; docs/guide-grid.md) --------------- */

typedef struct {
    size_t photons;            /* photons to emit; 0 = the scene's photons.count */
    long long seed;            /* photon seed; < 0 = the scene's photons.seed */
    int threads;               /* 0 = all; results do not depend on it */
    const char *load_photons;  /* reuse a saved .pmap instead of tracing (NULL: trace) */
    const char *load_indirect; /* reuse a saved indirect .pmap (with `indirect`) */
    const char *load_guide;    /* reuse a saved .guide instead of baking one (NULL: bake) */
    int no_guide;              /* 1: stop after the photon map */
    int indirect;              /* 1: also the map of photons stored without their first flight
                                  (same photons, same seed: the first collisions left out) */
    int indirect_guide;        /* 1 (with indirect): also a guide grid baked from that map, the
                                  multiple-scattering source of march.ls = nee+guide */
    const char *load_indirect_guide; /* reuse a saved indirect .guide (with indirect_guide) */
    int indirect_bands;        /* the indirect guide's SH bands: 0, guide.bands; else at most
                                  this many (RD_NEEDS_INDIRECT_LOBE: 2, all its reader needs) */
    int few_photons;           /* 1 (RD_NEEDS_FEW_PHOTONS): with photons 0, trace the scene's
                                  guide.photon_share of photons.count (at least 1) */
    int reachable;             /* 1 (RD_NEEDS_REACHABLE): the maps leave out the photons on
                                  L S+ paths from point, spot and directional lights, the light
                                  that reaches the media only through glass and that no
                                  camera path can find (rd_hidden_light's share) */
    const volatile int *cancel; /* non-NULL: polled while tracing (every 4096 photons), between
                                   the steps and while baking the guide; once non-zero the bake
                                   stops and returns RD_ERR_CANCELLED with no bake, and
                                   rd_bake_cached puts no further cache file in place */
    /* Several ranks bake together (NULL: this process alone; borrowed; renderer.h rd_comm):
     * rank r traces a contiguous range of the photon blocks (photon i's path depends on i
     * alone), and the photons, segments, indirect photons and the power sums are gathered on
     * every rank in photon order, so every rank holds one process's map, kd-tree and guide, bit
     * for bit. Every rank calls rd_bake (rd_bake_cached) with the same scene and options; both
     * return the same status on every rank (a failure or a cancel flag on one rank fails all;
     * a rank that did not fail says "another rank ..."). rd_bake_cached: the ranks use the cache
     * only when every rank can load it, else all bake, and rank 0 alone saves it. */
    const rd_comm *comm;
} rd_bake_opts;

/* Set the bake options that a method's needs (RD_NEEDS_*, from rd_method_needs_for) decide:
 * no_guide, indirect, indirect_guide, indirect_bands, few_photons, reachable. The rest of *opts
 * is left alone. */
void rd_bake_opts_for(rd_bake_opts *opts, unsigned needs);

typedef struct {
    /* photon map */
    int loaded;                /* 1 when read from load_photons */
    size_t emitted, stored, segments;
    size_t indexed;            /* photons in all the bake's maps (main and indirect), indexed */
    double trace_seconds, index_seconds;
    double collisions_per_photon;
    size_t map_bytes;          /* photons, segments and index */
    double power_emitted, power_absorbed, power_escaped, power_cut; /* luminance, W */
    double power_absorbed_surfaces; /* luminance, W: absorbed by diffuse surfaces */
    int ranks;                 /* ranks that traced the photons together (1: one process) */
    double gather_seconds;     /* several ranks: seconds of the photons' gather (in trace_seconds) */
    size_t gather_bytes;       /* bytes each rank received in it */
    /* guide grid (has_guide = 0 with no_guide) */
    int has_guide;
    int adaptive, track;       /* uniform/adaptive grid, k-NN/track-length bake */
    int bands;
    size_t cells;
    int res[3];                /* uniform */
    int depth_max;             /* adaptive */
    double cell_min, cell_max; /* adaptive cell edges, m */
    size_t guide_bytes;
    double guide_seconds;
    double seconds;            /* the whole bake */
} rd_bake_stats;

/* Trace (or load) the scene's photon map, build its FLANN index, bake the SH guide grid. */
rd_status rd_bake(const rd_scene *scene, const rd_bake_opts *opts, rd_baked **out, char *err,
                  size_t errlen);

/* rd_bake through a cache folder: the files are named by a hash of everything the bake depends
 * on (the scene without camera, march and render-only settings; grid voxel data; photon count,
 * seed, indirect map); when they are there and load cleanly they are used (*hit = 1), else the
 * bake runs and saves them (through temporary names; *hit = 0). A damaged cache file is
 * rebaked. If the files cannot be saved the bake is still returned, with *hit = -1 and the
 * reason in err. */
rd_status rd_bake_cached(const rd_scene *scene, const rd_bake_opts *opts, const char *cache_dir,
                         rd_baked **out, int *hit, char *err, size_t errlen);
void rd_baked_free(rd_baked *b);
const rd_bake_stats *rd_baked_stats(const rd_baked *b);

typedef struct {
    int write_map;          /* write PREFIX.pmap (skip it for a map that was loaded) */
    int nslices;            /* slices of the guide; 0 = one across z at the centre */
    char slice_axis[8];     /* 'x', 'y' or 'z' */
    int slice_has_at[8];
    double slice_at[8];     /* coordinate of the slice plane when slice_has_at */
    int has_toward;
    double toward[3];       /* unit direction the slice radiance leaves in (default: to the camera) */
} rd_bake_write_opts;

/* Write PREFIX.pmap, PREFIX-photons.exr/.png, PREFIX.guide, PREFIX-slice-A.exr/.png and
 * PREFIX-cells-A.png (docs/cli.md, bake). RD_ERR_ARG for a bad slice, RD_ERR_OUTPUT when a
 * file cannot be written (files already written stay). */
rd_status rd_baked_write(const rd_baked *b, const rd_scene *scene, const char *prefix,
                         const rd_bake_write_opts *o, char *err, size_t errlen);

/* ---- Voxelizing a medium ---------------------------------------------------------------- */

/* Sample medium `medium`'s density at voxel centres over its bounds, res voxels along the
 * longest axis, into OUT.vdb (OpenVDB float grid "density", cubic voxels, transform placing it
 * where the medium is) or OUT.raw (float32, x fastest, cells of the bounds' size / dims).
 * dims gets the voxel counts. */
rd_status rd_voxelize(const rd_scene *scene, int medium, int res, const char *out_path,
                      int dims[3], char *err, size_t errlen);

/* Create the folders above `path` (mkdir -p); RD_ERR_OUTPUT with a message on failure. */
rd_status rd_make_parent_dirs(const char *path, char *err, size_t errlen);

/* ---- Image files (OpenImageIO shim; never throws) ---------------------------------------- */

/* Linear float EXR; written to a temporary name in the same folder, then renamed. */
rd_status rd_image_write_exr(const char *path, const rd_image *img, char *err, size_t errlen);
/* sRGB 8-bit preview: value * 2^exposure, clamped, sRGB transfer. Temp name, then rename. */
rd_status rd_image_write_png(const char *path, const rd_image *img, double exposure, char *err,
                             size_t errlen);
/* Read any format OpenImageIO reads into linear RGB floats (first three channels; grey is
 * replicated). */
rd_status rd_image_read(const char *path, rd_image *out, char *err, size_t errlen);
/* The image calls above load OpenImageIO's module on their first use (core/image_plugin.h).
 * A command that will write images to `path` calls this first, so a missing module fails it
 * before its work, not after (RD_ERR_OUTPUT, the message naming path). */
rd_status rd_image_io_ready(const char *path, char *err, size_t errlen);

/* ==== Comparing methods: `photonmarch compare` (issue 11; THEORY.md §7; docs/compare.md) ==== *
 * This section is the compare module's, in renderer/compare/: metrics.c (rd_cmp_errors_of,
 * rd_cmp_split_of, rd_cmp_homogeneity), reference.c (the reference and the --add images;
 * rd_cmp_extra_parse), runs.c (rd_compare_run, rd_comparison_summary, rd_comparison_free),
 * report.c (rd_compare_write_report, rd_compare_print_table) with report_page.c (index.html).
 * Metrics are over every pixel and the three channels unless said otherwise. */

/* Error of one image x against a reference r (THEORY.md §7). eps = RD_CMP_EPS keeps the
 * relative errors finite where r = 0. */
#define RD_CMP_EPS 1e-2
typedef struct {
    double mse;    /* mean (x - r)^2 */
    double rmse;   /* sqrt(mse) */
    double relmse; /* mean (x - r)^2 / (r^2 + eps) */
    double mare;   /* mean |x - r| / (|r| + eps): mean absolute relative error */
} rd_cmp_errors;
/* RD_ERR_ARG when the sizes differ. */
rd_status rd_cmp_errors_of(const rd_image *x, const rd_image *r, rd_cmp_errors *out, char *err,
                           size_t errlen);

/* Bias and variance from k >= 2 independent images of the same method (THEORY.md §7):
 * per pixel-channel the mean m and unbiased sample variance s^2 over the k images;
 * variance = mean of s^2 (the variance of ONE run), bias2 = mean (m - r)^2 - variance / k
 * - ref_var (the reference's own variance, mean of its stderr^2; 0 when r_stderr is NULL).
 * bias2 may come out slightly negative from noise; it is reported as computed. */
typedef struct {
    double bias2, variance;
    double bias2_se; /* standard error of bias2 from the spread over pixels (docs/compare.md) */
} rd_cmp_split;
rd_status rd_cmp_split_of(const rd_image *runs, int k, const rd_image *r, const rd_image *r_stderr,
                          rd_cmp_split *out, char *err, size_t errlen);

/* Noise homogeneity: over the lit pixels (reference luminance > 1% of its mean), the ratio of
 * the 90th to the 50th percentile of the per-pixel relative error |x - r| / (r + eps)
 * (luminance). 1 = the error is spread evenly; large = concentrated in a few pixels. 0 when
 * fewer than 10 pixels are lit. */
double rd_cmp_homogeneity(const rd_image *x, const rd_image *r);

/* An image from elsewhere (--add LABEL=IMAGE.exr[@SECONDS]). */
typedef struct {
    const char *label, *path;
    double seconds; /* its render time; <= 0 when not given (time-based metrics left out) */
} rd_cmp_extra;
/* Parse "LABEL=PATH[@SECONDS]" into e (pointers into buf, a copy the caller keeps alive).
 * RD_ERR_ARG with a one-line message when it does not have that shape. */
rd_status rd_cmp_extra_parse(const char *arg, char *buf, size_t bufn, rd_cmp_extra *e, char *err,
                             size_t errlen);

/* What the progress callback is told: before each run and after every pass of it. */
typedef struct {
    const char *label; /* method, or "reference" */
    int run, runs;     /* 1-based run of this method */
    int spp_done;
    double run_seconds, run_budget; /* budget: seconds (equal time) or spp (equal spp) */
    double left_seconds;            /* estimate for the whole comparison */
} rd_cmp_progress;

typedef struct {
    const char *const *methods; /* names from the method table */
    int n_methods;
    int equal_spp;       /* 0: equal time (default), 1: equal samples per pixel */
    double budget;       /* equal time: seconds per run (bake included); equal spp: spp */
    int runs;            /* K >= 1 independent runs per method, seeds seed+1 .. seed+K */
    uint64_t seed;
    int threads;         /* 0 = all */
    const char *reference; /* REF.exr (REF-stderr.exr beside it is read when present), or NULL:
                              rendered by delta (settings.equiangular "tiles" where a point or
                              spot light exists and the scene does not name the key) and cached */
    /* The rendered reference. Neither given (both <= 0): the default, rendered until its
     * variance is at most RD_CMP_REF_SHARE of the smallest method MSE (rd_cmp_ref_spp_needed:
     * RD_CMP_REF_FIRST x a run's budget before the runs, more after them if the rule asks),
     * within ref_max_seconds in all. Either given: one render of that many samples per pixel
     * and/or seconds (the first limit reached stops it), never extended. */
    int ref_spp;         /* samples per pixel (<= 0: not given) */
    double ref_time;     /* seconds (<= 0: not given) */
    double ref_max_seconds; /* the default reference's cap in seconds (<= 0: RD_CMP_REF_CAP
                               times the longest mean run of a method) */
    const char *cache_dir; /* where the rendered reference is cached; NULL: no cache */
    const rd_cmp_extra *extras;
    int n_extras;
    const volatile int *cancel; /* as rd_render_opts.cancel: stops the comparison; what
                                   finished is kept */
    void (*progress)(void *user, const rd_cmp_progress *p);
    void *progress_user;
    rd_clock_fn clock;   /* the clock of the budget, the bake's charge and every time reported */
    void *clock_user;    /* (rd_render_opts.clock); NULL: rd_clock_monotonic */
    /* Several ranks compare together (NULL: this process alone; borrowed; docs/compare.md,
     * "On several ranks"): run k of method i (the (i runs + k)-th run) is rendered whole by rank
     * (i runs + k) modulo size, with its own bake of the method's needs; the rendered reference
     * is one render by all ranks together (rd_render_opts.comm), shared with every rank; then
     * every run's images, counters and curve go to every rank, so every rank holds the same
     * comparison (rank 0 writes the report). Every rank calls rd_compare_run with the same
     * scene and options; it returns the same status on every rank. */
    const rd_comm *comm;
} rd_cmp_opts;

/* One row of the comparison: a method (its K runs) or an added image. Absent values are NaN. */
typedef struct {
    char label[64];
    int is_extra;
    int runs;              /* runs finished */
    double seconds;        /* mean wall time per run, the bake charged to it included */
    double bake_seconds;   /* of which the bake (the comparison's one bake of this method) */
    double spp;            /* mean samples per pixel per run */
    rd_cmp_errors err;     /* mean over the runs of each run's errors (rmse = sqrt(mean mse)) */
    rd_cmp_split split;    /* from the runs (K >= 2); from the stderr image when K = 1 */
    int split_from_runs;
    double efficiency;     /* 1 / (mse x seconds) */
    double ttuv;           /* seed 002's TTUV: seconds x rmse */
    double collisions_pp, lookups_pp, shadow_rays_pp; /* per pixel per run */
    double homogeneity;    /* rd_cmp_homogeneity of the first run */
} rd_cmp_row;

typedef struct {
    const rd_cmp_row *rows;
    int n_rows;
    char ref_source[1100];  /* the file given, or the cache file used/written */
    int ref_rendered;       /* 1 rendered now, 2 taken from the cache, 0 given */
    double ref_spp, ref_seconds;
    double ref_var;         /* mean of the reference's stderr^2; NaN when unknown */
    int ref_too_noisy;      /* ref_var > RD_CMP_REF_SHARE x the smallest method MSE: the
                               methods are not ranked (docs/compare.md) */
    int cancelled;          /* Ctrl-C: the rows hold what finished */
    int ref_auto;           /* 1: the default reference (rendered until the rule holds) */
    int ref_extended;       /* times the default reference was extended after the runs */
    int ref_capped;         /* 1: the default reference stopped at its cap, rule unmet */
    double ref_cap_seconds; /* that cap (NaN unless ref_auto) */
    double ref_share;       /* ref_var / the smallest method MSE (NaN when unknown) */
    int ranks;              /* processes that ran the comparison (1: one) */
    char hosts[512];        /* their host names, "a x2, b" (rank order of first appearance) */
    /* Light that delta cannot render (docs/compare.md, "Light only photons find"): the share
     * of the light scattered in the media that leaves a point, spot or directional light
     * through glass first (L S+ paths; 0 when the scene cannot have any). Above
     * RD_HIDDEN_SHARE the summary says so and a rendered reference is made by ref_method. */
    double hidden_share;
    char ref_method[96];    /* what rendered the reference ("delta", "delta, settings.equiangular
                             * tiles", the photon method, or "given") */
} rd_cmp_summary;

typedef struct rd_comparison rd_comparison; /* the runs' images, curves and rows; opaque */

/* The default reference's rule (docs/compare.md, "The reference"): it is good enough to rank
 * the methods when its variance (mean stderr^2) is at most RD_CMP_REF_SHARE of the smallest
 * MSE of a method (the MSEs as measured: each includes the reference's variance). Its first
 * part, before the runs, is RD_CMP_REF_FIRST times one run's budget (seconds, or samples per
 * pixel at equal spp: what the rule asks when delta is one of the methods); it is extended
 * after the runs up to RD_CMP_REF_CAP times the longest run. The same share decides
 * ref_too_noisy for every reference, given or rendered. */
#define RD_CMP_REF_SHARE 0.1
#define RD_CMP_REF_FIRST 10.0
#define RD_CMP_REF_CAP 50.0
/* Samples per pixel a reference of `spp` samples and variance ref_var needs for the rule
 * against the smallest method MSE best_mse: spp when it holds (or ref_var is unknown), else
 * spp x ref_var / v, v the variance that meets it once the best method's own error
 * best_mse - ref_var stays and the variance falls as 1/spp, with 10% to spare. */
double rd_cmp_ref_spp_needed(double spp, double ref_var, double best_mse);

/* The summary in words (docs/compare.md, "The summary"). The baseline is `delta` when it is
 * one of the rows, else the first method's row (-1: no rows). The winner is the row of the
 * highest efficiency (methods, and added images with a time), -1 when fewer than two rows have
 * one or the reference is too noisy to rank them. */
int rd_cmp_baseline(const rd_cmp_summary *S);
int rd_cmp_winner(const rd_cmp_summary *S);
/* Why a row's efficiency is what it is (docs/compare.md, "Per sample"): per sample per pixel,
 * its render time, the bake left out ((seconds - bake_seconds) / spp; the pilot and the method's
 * other set-up stay in), and the variance of one sample (variance x spp). For an unbiased row
 * at equal time T, 1 / efficiency = MSE T = (variance per sample x time per sample) x T / (T -
 * bake), so its efficiency over another's is the inverse of the product of these two ratios,
 * times the ratio of the shares of T left after the bake. NaN when unknown (no samples, an
 * added image, no variance). */
double rd_cmp_time_per_sample(const rd_cmp_row *r);
double rd_cmp_variance_per_sample(const rd_cmp_row *r);
/* Share of one run's own error that is bias: max(bias2, 0) / (max(bias2, 0) + variance), in
 * [0, 1]; NaN when unknown (an added image). */
double rd_cmp_bias_share(const rd_cmp_row *r);
/* Row i's sentence, relative to the baseline, e.g. "guided: 1.4x delta's efficiency; 68% of
 * its error is bias"; the baseline's own: "delta: the baseline; 3% of its error is bias". */
void rd_cmp_sentence(const rd_cmp_summary *S, int i, char *buf, size_t n);
/* Who won and by how much, e.g. "winner: guided, 1.4x delta's efficiency", or why none: "not
 * ranked: the reference is too noisy ...". Empty with fewer than two rows. */
void rd_cmp_verdict(const rd_cmp_summary *S, char *buf, size_t n);
/* When the scene has light delta cannot render (hidden_share > RD_HIDDEN_SHARE), what it
 * means, e.g. "note: 31% of the light scattered in the media leaves a point, spot or
 * directional light through glass first ..."; empty otherwise. */
void rd_cmp_hidden_note(const rd_cmp_summary *S, char *buf, size_t n);

/* Check the options and load or render the reference (errors name the file: a reference of
 * the wrong size is RD_ERR_FORMAT, a missing one RD_ERR_IO; an --add image likewise), then run
 * every method K times and compute the rows. Cancelled: RD_OK with summary.cancelled = 1. */
rd_status rd_compare_run(const rd_scene *scene, const rd_cmp_opts *opts, rd_comparison **out,
                         char *err, size_t errlen);
const rd_cmp_summary *rd_comparison_summary(const rd_comparison *c);
/* The report folder (docs/compare.md): index.html, metrics.json, convergence.svg (gnuplot),
 * the EXR and PNG images, error maps and crops. Created if missing; RD_ERR_OUTPUT naming the
 * file that could not be written. */
rd_status rd_compare_write_report(const rd_comparison *c, const rd_scene *scene, const char *dir,
                                  char *err, size_t errlen);
/* The metrics table as fixed-width text (the CLI prints it on stdout). */
void rd_compare_print_table(const rd_comparison *c, FILE *out);
void rd_comparison_free(rd_comparison *c);
/* ==== end of the compare section ===================================================== */

#ifdef __cplusplus
}
#endif
#endif /* PHOTONMARCH_RENDERER_H */
