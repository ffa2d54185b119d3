/* rd_march.h: the ray marcher shared by `guided`, `uniform` and `transmittance` (seed 001
 * §3.3-4; THEORY.md §6), for the three method files and explain (integrators/march.c holds the
 * marcher; guided.c, uniform.c and transmittance.c the methods; march_explain.c explain).
 * Internal to integrators/. */
#ifndef RD_MARCH_H
#define RD_MARCH_H

#include "integrators/rd_beams.h"
#include "integrators/rd_guide_pdf.h"
#include "integrators/rd_method.h"
#include "integrators/rd_probes.h"
#include "integrators/rd_select.h"

/* Where the samples along a camera ray go (one method each). */
typedef enum { PLACE_GUIDED, PLACE_UNIFORM, PLACE_TRANSMITTANCE, PLACE_COUNT } placement;

/* What every thread reads: the pilot's mean I_ray (eq. 17) and the scratch layout. */
typedef struct {
    double mean_I;   /* mean over the pilot's rays of I_ray, 0 when unknown */
    int n_mean[PLACE_COUNT]; /* N_mean of each placement: march.samples, or its default */
    double q_path[PLACE_COUNT]; /* nee+paths: the chance that a sample continues its path:
                                   march.paths, or the placement's default */
    int seg_cap;     /* PDF segments per ray */
    int n_max;       /* samples per ray at most */
    int k_steps;     /* extinction lookups per ray at most: 4 N_mean (transmittance; guided
                      * detail lattice), over the placements */
    int piece_cap;   /* entries of the tb/f/sig tables: k_steps, or cells + k_steps (detail) */
    rd_select sel;   /* guided with settings.select: the tiles it marches (integrators/select.c) */
    /* march.ls = nee+beams, or guided's beams estimator (march.beams): beam_source 1, the
     * indirect photons as balls (rebuilt for every photon pass by rd_march_photons_changed),
     * their radii, and the balls a segment keeps at most. */
    int beam_source;
    rd_beams *beams;
    struct beam_field *beam_field; /* r_1 on cells of pass 1 (march_beams.c) */
    float *beam_radius;
    size_t beam_radius_cap;
    int beam_cap;
    int n_lights;    /* entries of the scratch's lw (march.equiangular) */
    double beam_weight; /* 1 / the share of the photons kept as balls */
    rd_probes probes; /* march.probes (probes.c) */
    rd_gu_paths *gpaths; /* guided with march.guided_paths: guided-unbiased's paths, one more
                            estimator of the selection (guided.c); else NULL */
    size_t beam_r1_queries; /* balls of the last build whose r_1 took a query of its own */
} march_state;

/* Scratch of one thread: PDF segments, sample positions and densities, extinction table. */
typedef struct {
    rd_gpdf_seg *seg;
    double *t, *p;
    double *tb, *f, *sig;
    double *lw;        /* march.equiangular: a weight per light (rd_march_source's light_w) */
    rd_beam_hit *hits; /* nee+beams: the balls one segment crosses, */
    double *cdf;       /* and the running sum of their picks' weights */
} march_scratch;

/* Lay the scratch out at base (NULL: only measure); returns its size in bytes. */
size_t rd_march_scratch_layout(const march_state *st, march_scratch *ms, void *base);
/* The camera ray's first straight segment: its region and the part [t0, t1] inside the scene
 * bounds before the first light or surface; *hit_light gets that light, or -1. 0: it misses. */
int rd_march_first_segment(const rd_scene *s, ray3 r, int *region, double *t0, double *t1,
                           int *hit_light);
/* The guide's PDF of ray r over [t0, t1] (cells, or cells x lookups; defensive only when the
 * guide walk fails). */
void rd_march_build_guided(const rd_render_ctx *ctx, const march_scratch *ms, int region, ray3 r,
                           double t0, double t1, rd_guide_pdf *pdf, rd_track_counters *c);
/* Build the PDF of `place` over [t0, t1] for ray r into pdf. Returns the samples to take. */
int rd_march_build_pdf(const rd_render_ctx *ctx, placement place, const march_scratch *ms,
                       int region, ray3 r, double t0, double t1, rd_guide_pdf *pdf,
                       rd_track_counters *c);
/* The in-scattered radiance source S = sigma_s L_s at x toward -d, from source `ls` (the scene's
 * march.ls, or the beams estimator's nee+beams: rd_march_radiance_ls); `event` is
 * the scattering event x would be (1 on the camera's first segment): nee+paths's path from x
 * counts its events on from there, as delta's does, and is taken with probability q_path.
 * light_w: each light's weight in the next-event part (NULL: 1; march_equiangular.c). */
vec3 rd_march_source(const rd_render_ctx *ctx, rd_ls_kind ls, const rd_medium *m, int region, vec3 x,
                     vec3 d, double sigma_t, int event, double q_path, const double *light_w, pcg32 *rng,
                     rd_track_counters *c);
/* The share of the kernel ball of radius r about x (in medium m of `region`) that holds photons,
 * weighted by their density relative to x's: within r of a constant-density box medium's face,
 * the part beyond it counts sigma_t there over sigma_t(x) (0 in empty space); 1 elsewhere. The
 * photon estimates divide by it (march_share.c says why). */
double rd_march_support_share(const rd_scene *s, int region, const rd_medium *m, vec3 x, double r);
/* march.ls = nee+beams: the beam radiance estimate of the indirect in-scattering along [t0, t1]
 * of r in `region` (the balls of the indirect photons, state's beams; march_beams.c says how), the
 * integral of T(t0, t) sigma_s L_s over the segment. */
vec3 rd_march_beam_estimate(const rd_render_ctx *ctx, const march_scratch *ms, ray3 r, int region,
                            double t0, double t1, pcg32 *rng, rd_track_counters *c, int *crossed, vec3 *gap);
/* (*crossed: the balls the segment crossed, those beyond the reservoir's cap included. *gap,
 * unless NULL: the estimate less the same picks read with every ball of half its volume, radius
 * r_k / sqrt 2 (each pick moved onto the small ball's chord, march_beams.c's half_ball_term).
 * Where the kernel's bias grows as r^2 (a smooth in-scattered field: a ball of radius r averages
 * it with a second moment r^2 / 5 a direction, so the bias is r^2 / 10 times its Laplacian), the
 * small balls carry half the bias, and 2 gap estimates the estimate's bias (Richardson's
 * extrapolation; select_rule.c "The beams' bias"). At an edge of the light the bias grows as r
 * instead and 2 gap reads 0.59 of it.) */
/* march.equiangular: one equiangular sample per segment toward a point or spot light (or a
 * directional beam), MIS with the placement's samples (march_equiangular.c says how). The
 * lights a segment samples: */
#define RD_MARCH_EQ_LIGHTS 8
typedef struct {
    int n;                              /* lights sampled on this segment (0: none) */
    int light[RD_MARCH_EQ_LIGHTS];      /* their indices */
    double Q[RD_MARCH_EQ_LIGHTS];       /* the probability of choosing each */
    rd_equiangular e[RD_MARCH_EQ_LIGHTS]; /* each one's pdf over its lit span */
    ray3 r;
    int region;
    const rd_guide_pdf *pdf;            /* the placement's pdf p of the segment, */
    int N;                              /* and its samples on it */
} rd_march_eq;
/* Set up the segment r in `region` up to t_end whose placement draws N samples of pdf; returns
 * the number of lights it samples (0: none, or march.equiangular off). A set-up over media with
 * a light of the set to choose counts in c->eq_flights (the selection's cost, select.c). */
int rd_march_eq_begin(const rd_scene *s, ray3 r, int region, double t_end, const rd_guide_pdf *pdf,
                      int N, rd_march_eq *eq, rd_track_counters *c);
/* The placement sample at t: light_w[j] = w_p(t, j) for the segment's lights (the others are
 * left as they are). */
void rd_march_eq_weights(const rd_march_eq *eq, double t, double *light_w);
/* The equiangular sample's MIS-weighted estimate of the direct light (unit throughput at t0,
 * the segment's start in the scene bounds). */
vec3 rd_march_eq_sample(const rd_scene *s, const rd_march_eq *eq, double t0, pcg32 *rng,
                        rd_track_counters *c);
/* The time of one of the marcher's PDF segments, in density lookups (select.c, the fit): the
 * selection's cell_cost for a marcher. */
#define RD_MARCH_CELL_COST 1.52
/* The method table's epoch hooks for a marcher without a selection (uniform, transmittance). */
int rd_march_epoch_next(const rd_render_ctx *ctx, int sample);
void rd_march_epoch(rd_render_ctx *ctx, int sample);
/* Radiance along camera ray r with the samples of `place` (the estimator of THEORY.md §6), the
 * source march.ls; rd_march_radiance_ls: with source `ls` instead (nee+beams needs the balls:
 * march_state.beam_source). */
vec3 rd_march_radiance(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp,
                       placement place);
vec3 rd_march_radiance_ls(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp,
                          placement place, rd_ls_kind ls);
/* The method table's hooks, shared by the three methods: scratch size, the common prepare
 * (march_state from the scene's march settings; guided adds its pilot pass), release. */
size_t rd_march_scratch_bytes(const rd_render_ctx *ctx);
rd_status rd_march_prepare(rd_render_ctx *ctx, char *err, size_t errlen);
/* rd_march_prepare, with the photon balls built (and rebuilt at every pass) also where `beams`
 * says so though march.ls is not nee+beams: `guided`'s beams estimator (march.beams, guided.c). */
rd_status rd_march_prepare_beams(rd_render_ctx *ctx, int beams, char *err, size_t errlen);
void rd_march_release(rd_render_ctx *ctx);
/* Balls a segment keeps at most (rd_beams_cross samples them beyond). */
#define RD_BEAM_CAP 4096
/* Largest k the scene allows (guide.k, load/settings.c): the photons one estimate gathers. */
#define RD_MAX_GATHER 4096
/* r_1(x), the k-NN bandwidth of seed 001's fixed map at x in `first` (pass 1's map, or the fixed
 * map), read from a nearer neighbour (bandwidth.c says how); -1 where `first` holds no photon. */
double rd_march_knn_bandwidth(const pm_map *first, int k, vec3 x);
/* Free the beam source's parts of st (march_beams.c). */
void rd_march_beams_free(march_state *st);
/* The method table's photons_changed hook: with the balls on (march_state.beam_source), the balls
 * of the indirect photons ctx holds now, with their radii (a no-op otherwise). */
rd_status rd_march_photons_changed(rd_render_ctx *ctx, char *err, size_t errlen);
/* What the scene's source needs baked: the photon map (photons) or its indirect part
 * (nee+photons), and the indirect guide (nee+guide). */
unsigned rd_march_source_needs(const rd_scene *s);
/* The photon map a progressive pass must trace anew for the scene's source (rd_method.pass_maps;
 * none without photons.progressive):
 * the map for march.ls = photons, the indirect map for nee+photons, the indirect map for nee+beams
 * with RD_PASS_NO_INDEX (after pass 1 its photons are read in order, never queried), none for
 * nee, nee+paths, nee+delta and nee+guide. */
unsigned rd_march_pass_maps(const rd_scene *s);
/* Every bake a marcher may need (the methods' `needs`). */
#define RD_MARCH_NEEDS (RD_NEEDS_PHOTONS | RD_NEEDS_GUIDE | RD_NEEDS_INDIRECT | RD_NEEDS_INDIRECT_GUIDE | RD_NEEDS_INDIRECT_LOBE)

#endif /* RD_MARCH_H */
