/* rd_path.h: the unbiased volumetric path loop shared by `delta` and `guided-unbiased`, its
 * free-flight samplers and vertex policies, and the shared surface step (transport/path.c).
 * Internal to renderer/ (tests include it). */
#ifndef RD_PATH_H
#define RD_PATH_H

#include "transport/rd_transport.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Radiance arriving at the camera along r with the `delta` method: unbiased volumetric path
 * tracing (delta tracking, next-event estimation with ratio tracking, HG sampling, Russian
 * roulette, multiple importance sampling for area and environment lights), with the scene's
 * settings.equiangular (an equiangular sample toward a point or spot light per flight, MIS with
 * the collision's next-event estimate; "tiles" is off here: rd_eq_path_mode) and
 * settings.thin_bias (rd_sample_free_path_thin). */
vec3 rd_delta_radiance(const rd_scene *s, ray3 r, pcg32 *rng, rd_track_counters *c);
/* The same with the equiangular mode `equiangular` (RD_EQ_*, not RD_EQ_TILES) in place of
 * settings.equiangular (the tile selections' estimators: integrators/select.c, delta.c). */
vec3 rd_delta_radiance_eq(const rd_scene *s, ray3 r, int equiangular, pcg32 *rng, rd_track_counters *c);
/* rd_delta_radiance_eq's estimate split in two: returns all of it but *E, the light the camera's
 * chain (its first flight and the specular surfaces after it) meets at its end, a sphere
 * light, the environment or the background, when the flight passes through (the probes of
 * integrators/probes.c estimate that part again). The sum is rd_delta_radiance_eq's, on the
 * same random numbers. */
vec3 rd_delta_radiance_split(const rd_scene *s, ray3 r, int equiangular, pcg32 *rng, rd_track_counters *c,
                             vec3 *E);

/* ---- The unbiased path loop and its free-flight samplers (transport/path.c) ------------- *
 * One path tracer serves `delta` and `guided-unbiased`; they differ only in how a free flight
 * is sampled. A flight from the path vertex r.o along r.d over [0, t_light] either scatters at
 * some t inside a medium or passes through to what lies beyond (the sphere light it hits, the
 * environment, the background). By the RTE (THEORY.md §1)
 *     L(o, -d) = integral_0^t_end T(0,t) sigma_s(t) L_s(x(t), -d) dt + T(0,t_end) L_behind,
 * so a sampler that scatters with probability P_s at t with density p(t), and passes with
 * probability 1 - P_s, reports the weight T(0,t) sigma_s(t) / (P_s p(t)) for the vertex (the
 * loop then estimates L_s there) and T(0,t_end) / (1 - P_s) for a pass-through, each T an
 * unbiased estimate. Delta tracking's weights are the albedo and 1. */
typedef enum { RD_FLIGHT_PASS, RD_FLIGHT_SCATTER, RD_FLIGHT_END } rd_flight_kind;
typedef struct {
    rd_flight_kind kind;      /* END: the sampled vertex has a zero integrand; the path ends */
    double t;                 /* SCATTER (and END): distance of the vertex along the ray */
    const rd_medium *medium;  /* SCATTER: the medium there */
    vec3 weight;              /* multiplies the path throughput (see above) */
    double pdf;               /* SCATTER: the sampler's density of scattering at t when it is
                               * known exactly (guided-unbiased's q(t)), for the MIS weights
                               * against the equiangular strategy; 0 for delta tracking, whose
                               * weights take the majorant stand-in (transport/equiangular.c) */
} rd_flight;
typedef struct {
    ray3 r;                   /* the flight's ray (r.d unit) */
    double t_light;           /* distance to what the ray meets first (a sphere light or a
                               * surface: rd_scene_intersect), or INFINITY */
    int hit_light;            /* that sphere light, or -1 */
    int hit_shape;            /* that shape, or -1: a pass-through then reaches a surface and
                               * the path loop goes on from it (rd_flight_behind gives 0) */
    int region;               /* the region the flight travels in (rd_scene_region_at) */
    double phase_pdf;         /* pdf of r.d from phase or diffuse-BSDF sampling; 0 for the
                               * camera ray and after a specular surface event (no MIS) */
    int depth;                /* scattering events before this flight (0: the camera ray) */
    int camera_chain;         /* 1: the camera ray, or it followed by specular surface events
                               * only (an escape then sees the background) */
    const rd_interval *iv;    /* the media intervals of [0, t_light] (rd_media_intervals), when
                               * the loop has them for its equiangular set-up; NULL: the
                               * sampler finds them itself. They belong to this r, region and
                               * t_light: a sampler that hands on a changed copy of *in must
                               * set iv NULL in it */
    int n_iv;                 /* their number (with iv) */
} rd_flight_in;
/* A scattering vertex, as the path loop offers it to a vertex policy. */
typedef struct {
    vec3 x, d;                /* the vertex and the direction the path arrived along */
    const rd_medium *medium;
    int region;               /* the region of the vertex */
    int depth;                /* scattering events up to and including this one (>= 1) */
    vec3 beta;                /* path throughput from the camera up to here, flight weight
                               * included; in a copy that splitting made, the copy's share
                               * (rr_scale / n) and its direction weight included */
} rd_vertex_in;
/* What a vertex policy decides. The path continues as n copies (0: the path ends here), each
 * with throughput beta * rr_scale / n, each estimating L_s(x, -d) by next-event estimation and
 * a continuation drawn from `mix`. Unbiased for any choice made from what is known at the
 * vertex: Russian roulette survives with probability q and sets rr_scale = 1/q; splitting into
 * n copies averages n independent estimates. The loop may lower n (its split budget) and
 * divides by the n it keeps. */
typedef struct {
    int n;
    double rr_scale;
    rd_dir_mix mix;
} rd_vertex_out;
typedef struct rd_flight_sampler {
    rd_flight (*sample)(const struct rd_flight_sampler *fs, const rd_scene *s,
                        const rd_flight_in *in, pcg32 *rng, rd_track_counters *c);
    /* Optional (NULL for `delta`): the vertex policy, replacing the loop's throughput roulette
     * and plain phase sampling. */
    void (*vertex)(const struct rd_flight_sampler *fs, const rd_scene *s, const rd_vertex_in *v,
                   pcg32 *rng, rd_vertex_out *out);
    /* Optional (NULL for delta tracking): the density with which the flight just sampled would
     * have scattered at t, or a negative number when that flight was delta tracking's. The
     * loop calls it right after `sample`, for the equiangular strategy's MIS weight. */
    double (*density)(const struct rd_flight_sampler *fs, double t);
    void *user;               /* the sampler's own (per call of the path loop) */
    int equiangular;          /* rd_equiangular_mode of the loop's flights (RD_EQ_OFF: none).
                               * The MIS weights need only be deterministic (docs/free-path.md):
                               * a flight with `density` is weighted by its own density, delta
                               * tracking's by the majorant stand-in (with settings.thin_bias's
                               * boost for `delta`'s own flights, `density` NULL) */
} rd_flight_sampler;
/* Extra copies splitting may add to one camera sample's path tree (a bound on its cost). */
#define RD_SPLIT_BUDGET 32
/* The path loop: NEE at every scattering vertex, HG sampling with MIS, Russian roulette (or
 * the sampler's vertex policy, with splitting), and where settings.beam_connect is on a
 * connection to the scene's directional beam at every scattering vertex (beam_connect.c). */
vec3 rd_path_radiance(const rd_scene *s, ray3 r, const rd_flight_sampler *fs, pcg32 *rng,
                      rd_track_counters *c);
/* The same path less the light its camera chain sees at its end, which goes to *E (a sphere
 * light, the environment, the background through the chain's media and glass; 0 where there is
 * none): returns I, and I + *E is rd_path_radiance's estimate (integrators/probes.c). */
vec3 rd_path_radiance_split(const rd_scene *s, ray3 r, const rd_flight_sampler *fs, pcg32 *rng,
                            rd_track_counters *c, vec3 *E);
/* One scattering event at surface hit h (not an interface) of a path arriving along st->r.d
 * with throughput st->beta in region st->region, at scattering event `depth` (for the
 * roulette): next-event estimation at a diffuse surface (into st->L, throughput included),
 * Russian roulette, and the material's sampled continuation (RADIANCE mode, rd_geom.h). On
 * return 1, st holds the next ray (spawned off the surface), throughput, region, pdf (0 after
 * a specular event: no MIS) and camera_chain; 0: the path ends (st->L still counts). The path
 * loop and the marcher share it. */
typedef struct {
    ray3 r;
    vec3 beta, L;
    int region;
    double pdf;
    int camera_chain;
    double eta_scale;  /* product of (n_t/n_i)^2 over the refractions so far (pbrt-v4's
                        * etaScale): the roulette decides on beta x eta_scale, so the radiance
                        * factor (n_i/n_t)^2 of entering glass, which leaving undoes, kills no
                        * path. 1 for a path outside every glass */
} rd_surface_step;
int rd_surface_event(const rd_scene *s, const rd_hit *h, int depth, rd_surface_step *st,
                     pcg32 *rng, rd_track_counters *c);
/* `delta`'s path from a flight along r on (in `region`; r.d drawn with pdf `pdf`, 0 for none;
 * `depth` scattering events before it): the radiance estimate of L(r.o, -r.d). Its flights
 * take the equiangular strategy of mode `equiangular` (rd_equiangular_mode: `delta` itself
 * follows settings.equiangular, the marchers' paths march.equiangular). Its scattering vertices
 * connect to the beam where settings.beam_connect is on (beam_connect.c; not r.o's: the
 * caller's vertex did not connect, so r's first collision takes no weight against it). */
vec3 rd_delta_continue(const rd_scene *s, ray3 r, int region, double pdf, int depth,
                       int camera_chain, int equiangular, pcg32 *rng, rd_track_counters *c);
/* `delta`'s path along r (in `region`, `depth` scattering events before it) less two parts
 * that the caller estimates otherwise: what passes r's first flight (T L_behind, and all that
 * lies beyond the surface ending it: the estimate is 0 when the flight does not scatter) and
 * the next-event estimate of the first vertex (rd_nee_split's share of the direct light). What
 * is left is every path that scatters on r and goes on: the phase-sampled continuation from
 * the first vertex, with its MIS weight where it hits a light (rd_flight_behind), and all
 * later vertices as `delta` has them. The marchers' nee+delta source adds it to their own
 * estimate of the single scattering on r (integrators/march.c). Its flights after the first
 * take the equiangular strategy of mode `equiangular` (the marchers': march.equiangular), and
 * its scattering vertices, the first too, connect to the beam where settings.beam_connect is
 * on (beam_connect.c). */
vec3 rd_delta_scattered(const rd_scene *s, ray3 r, int region, int depth, int equiangular,
                        pcg32 *rng, rd_track_counters *c);
/* Delta tracking's flight (rd_sample_free_path with the scene's tracker). */
rd_flight rd_flight_delta(const rd_scene *s, const rd_flight_in *in, pcg32 *rng,
                          rd_track_counters *c);
/* The thin-media bias q of `delta`'s flight `in` (rd_sample_free_path_thin): 0 with
 * settings.thin_bias off; 1 (a forced collision) when a pass-through is worth exactly 0 (no
 * surface ends the flight and rd_flight_behind is 0: nothing is lost by never passing); else
 * settings.thin_bias. */
double rd_thin_bias_q(const rd_scene *s, const rd_flight_in *in);
/* Radiance a pass-through receives: the hit sphere light or the environment, MIS-weighted
 * against the light sampling of rd_nee when in->phase_pdf > 0, plus the background for a
 * camera chain that hits no light; 0 when the flight ends at a surface (in->hit_shape >= 0:
 * the loop continues from it). Deterministic (no random numbers). */
vec3 rd_flight_behind(const rd_scene *s, const rd_flight_in *in);

#ifdef __cplusplus
}
#endif
#endif /* RD_PATH_H */
