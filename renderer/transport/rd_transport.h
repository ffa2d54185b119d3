/* rd_transport.h: carrying light through the scene, the pieces every method shares: free
 * flights and transmittance across the scene's regions and surfaces (transport/tracking.c, with
 * thin-media probability biasing), next-event estimation with MIS (transport/nee.c), the
 * scattering-direction mixture (transport/directions.c) and equiangular sampling toward point
 * and spot lights (transport/equiangular.c). Internal to renderer/ (tests include it). */
#ifndef RD_TRANSPORT_H
#define RD_TRANSPORT_H

#include "media/rd_freepath.h"
#include "scene/rd_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The media of `region` r crosses within [tmin, tmax]: disjoint intervals sorted by entry
 * distance, each of one medium (media with sigma_maj = 0 left out; such a box medium is a
 * clear hole in the scene-wide medium, as rd_scene_medium_at has it). At most RD_MAX_INTERVALS
 * (64 box media and the scene-wide medium in the gaps between them). Returns their number. */
typedef struct { double t0, t1; const rd_medium *m; } rd_interval;
#define RD_MAX_INTERVALS 130
int rd_media_intervals(const rd_scene *s, int region, ray3 r, double tmin, double tmax,
                       rd_interval *out);

/* Free-path sampling along r through every medium of `region` it crosses, in order, from t = 0
 * up to tmax (the next surface: the caller clips to it), with the tracker of
 * s->settings.tracker (default: delta tracking over each medium's majorant structure;
 * "woodcock" uses the global majorant). The caller multiplies its path weight by the returned
 * weight (1 except for the weighted trackers). */
rd_collision rd_sample_free_path(const rd_scene *s, int region, ray3 r, double tmax, pcg32 *rng,
                                 rd_track_counters *c);
/* The same flight over intervals iv[0..n) that the caller already has: those rd_media_intervals
 * gives for (region, r, 0, tmax). The path loop computes them once per flight for both the
 * flight and the equiangular set-up (rd_eq_flight_choose). Same random numbers, same result. */
rd_collision rd_sample_free_path_iv(const rd_scene *s, const rd_interval *iv, int n, ray3 r,
                                    double tmax, pcg32 *rng, rd_track_counters *c);

/* Thin-media probability biasing of delta tracking (Villemin, Wrenninge & Fong 2018; derived in
 * transport/tracking.c and docs/free-path.md): the flight of rd_sample_free_path (analog delta
 * tracking over the media's majorants) with the probability that a tentative collision falls in
 * what is left of the flight raised to at least q (0 < q <= 1; 1 forces one), the outcomes
 * reweighted by true / biased probability in the returned weight. Unbiased for any q. */
rd_collision rd_sample_free_path_thin(const rd_scene *s, int region, ray3 r, double tmax, double q,
                                      pcg32 *rng, rd_track_counters *c);
/* The same over the caller's intervals (as rd_sample_free_path_iv). */
rd_collision rd_sample_free_path_thin_iv(const rd_scene *s, const rd_interval *iv, int n, ray3 r,
                                         double tmax, double q, pcg32 *rng, rd_track_counters *c);
/* Majorant optical depth along r from the first interval's start to t (t = INFINITY: all of
 * them) over the intervals iv[0..n) of rd_media_intervals, each medium's majorant structure
 * (`global`: its global majorant). *sigma (may be NULL) gets sigma_maj at t, 0 outside the
 * intervals. Deterministic: no random numbers. */
double rd_majorant_depth(const rd_interval *iv, int n, ray3 r, double t, int global, double *sigma);

/* Transmittance estimate along r over [t0, t1] within `region` (no surface in between: the
 * caller clips; rd_shadow_transmittance crosses surfaces) with the estimator of
 * s->settings.transmittance (THEORY.md §2, docs/free-path.md). */
double rd_transmittance(const rd_scene *s, int region, ray3 r, double t0, double t1, pcg32 *rng,
                        rd_track_counters *c);

/* Transmittance along a shadow ray from its origin in `region` to the point at distance
 * `dist` on light `light` (-1: a point, spot, directional or environment light): the product of
 * the transmittance estimates of every medium interval on the way, crossing `interface`
 * surfaces (the region changes), and 0 when a dielectric or diffuse surface or another sphere
 * light lies in between (a light behind glass is reached only by paths that refract: no
 * shadow ray connects through a dielectric). `from`: the surface the ray leaves (NULL for a
 * medium vertex). */
double rd_shadow_transmittance(const rd_scene *s, int region, ray3 r, double dist, int light,
                               const rd_hit *from, pcg32 *rng, rd_track_counters *c);

/* Solid-angle pdf with which next-event estimation (rd_nee) produces direction w from x toward
 * light i, light choice included: for MIS of phase-sampled paths that hit the light. */
double rd_light_mis_pdf(const rd_scene *s, int i, vec3 x, vec3 w);
double rd_power_heuristic(double a, double b);

/* Next-event estimation at a scattering point x of a medium with HG asymmetry g, for a path
 * travelling along d: one light chosen by power (s->light_sampler), one sample of it, phase,
 * unbiased shadow transmittance, MIS against phase sampling. Multiply by the path weight. */
vec3 rd_nee(const rd_scene *s, int region, vec3 x, vec3 d, double g, pcg32 *rng,
            rd_track_counters *c);

/* How a path continues from a scattering vertex reached along d: with probability a a von
 * Mises-Fisher lobe (mean mu, concentration kappa: the guide's incident light), else the HG
 * phase function around d. a = 0 is phase sampling alone. The pdf of wo is
 *     pdf(wo) = a vmf(mu, kappa; wo) + (1 - a) hg(g; d.wo)                        (one-sample MIS,
 * the balance heuristic over the two strategies: Veach 1997 §9.2.4), the weight hg / pdf. */
typedef struct {
    double a;
    vec3 mu;
    double kappa;
} rd_dir_mix;
double rd_dir_mix_pdf(const rd_dir_mix *mx, double g, vec3 d, vec3 wo);
/* Draw wo from the mixture (three uniforms when a > 0, two when a = 0, so phase sampling alone
 * draws exactly what `delta` draws); *pdf gets rd_dir_mix_pdf. */
vec3 rd_dir_mix_sample(const rd_dir_mix *mx, double g, vec3 d, pcg32 *rng, double *pdf);
/* rd_nee with the MIS weight taken against the direction mixture mx (NULL: phase sampling,
 * which is rd_nee); *light (when not NULL) gets the light chosen (-1 for none), for a MIS
 * weight the caller applies. */
vec3 rd_nee_mix(const rd_scene *s, int region, vec3 x, vec3 d, double g, const rd_dir_mix *mx,
                pcg32 *rng, rd_track_counters *c, int *light);
/* Next-event estimation at a diffuse surface hit h reached along d: one light by power, the
 * BSDF (rd_material_eval) times the cosine at the light's direction, the shadow ray from the
 * surface (rd_shadow_transmittance, in the region on d's side), MIS (power heuristic) against
 * BSDF sampling. Multiply by the path weight. */
vec3 rd_nee_surface(const rd_scene *s, const rd_hit *h, vec3 d, pcg32 *rng,
                    rd_track_counters *c);

/* One sample of light i from medium point x (phase g toward it, unbiased shadow
 * transmittance), neither divided by a choice probability nor MIS-weighted: for a point or spot
 * light, the direct radiance p I f / r^2 T scattered toward -d; for a directional light,
 * p E T (0 outside a beam's cylinder). */
vec3 rd_nee_light(const rd_scene *s, int region, vec3 x, vec3 d, double g, int i, pcg32 *rng,
                  rd_track_counters *c);

/* ---- Equiangular sampling (Kulla & Fajardo 2012; transport/equiangular.c) ----------------- *
 * Distances t in [a, b] along r (r.d unit) toward a point c, with density proportional to
 * 1 / |x(t) - c|^2: with Delta = (c - o).d and D the distance from c to the line,
 * theta(t) = atan((t - Delta) / D) is uniform:
 *     t = Delta + D tan(theta_a + u (theta_b - theta_a)),
 *     pdf(t) = D / ((theta_b - theta_a) (D^2 + (t - Delta)^2)).                              */
/* A light at infinity (a directional beam) has no 1 / r^2 along the line: the same family's
 * limit D -> infinity, the uniform density 1 / (b - a), marked D = INFINITY. */
typedef struct {
    double a, b, delta, D, th_a, th_b;
} rd_equiangular;
/* Returns 0 when [a, b] is empty or not finite. D is held above a tiny floor (a light on the
 * line itself has an infinite integrand there anyway). */
int rd_equiangular_init(rd_equiangular *eq, vec3 c, ray3 r, double a, double b);
/* The lights the strategy samples (rd_eq_light): point and spot lights, and directional beams
 * (radius > 0: the lit part of a line is the chord inside the beam's cylinder). */
int rd_eq_light(const rd_light *l);
/* Light l's density over [a, b]: equiangular toward a point or spot light's position, uniform
 * for a directional beam. Returns 0 as rd_equiangular_init. */
int rd_equiangular_init_light(rd_equiangular *eq, const rd_light *l, ray3 r, double a, double b);
double rd_equiangular_sample(const rd_equiangular *eq, double u, double *pdf);
double rd_equiangular_pdf(const rd_equiangular *eq, double t); /* 0 outside [a, b] */

/* `delta`'s equiangular strategy for one flight (settings.equiangular; march.equiangular and
 * guide.equiangular on the other methods' flights): the flight's media
 * intervals, the choice probabilities of the set's lights, and the scale of the
 * majorant density standing for delta tracking's collision density in the MIS weights (the
 * derivation is in transport/equiangular.c and docs/free-path.md). */
typedef struct {
    ray3 r;
    int region;
    rd_interval iv[RD_MAX_INTERVALS];
    int n;           /* intervals; 0 when the set-up stopped before them (no light of the set) */
    double ps_pmf;   /* sum of rd_nee's choice probabilities over the lights it samples */
    double dscale;   /* the tracking pdf's proxy is dscale sigma_maj(t) T_maj(0,t) */
    uint64_t left;   /* lights 0..63 left to delta tracking on this flight ("auto") */
    int beams;       /* directional beams are in the set (rd_eq_mode_beams) */
    /* The flight sampler's own scattering density at t when it knows it exactly (a guided
     * flight), else NULL or a negative return: the stand-in above. Set by the caller after
     * rd_eq_flight_init (which sets it NULL). */
    double (*density)(const void *user, double t);
    const void *density_user;
} rd_eq_flight;
/* Set up the flight along r in `region` over [0, t_light] whose delta tracking runs with thin
 * bias q (0: none; rd_sample_free_path_thin), in equiangular mode `mode` (rd_equiangular_mode,
 * not OFF or TILES). The set of lights: point and spot lights, and directional beams in the
 * modes of rd_eq_mode_beams (ALL, CAMERA); RD_EQ_AUTO keeps only the set's lights whose lit
 * span delta tracking reaches (global-majorant T(0,a) >= 1/2) but rarely collides in
 * (equiangular.c). Returns 0 when there is nothing to sample (no medium on the way, no light
 * of the set, or none left to sample). */
int rd_eq_flight_init(const rd_scene *s, ray3 r, int region, double t_light, double q, int mode,
                      rd_eq_flight *ef);
/* Does mode `mode` put directional beams in the set (RD_EQ_ALL, RD_EQ_CAMERA: `true` and
 * "camera"; not "auto")? */
int rd_eq_mode_beams(int mode);
/* rd_eq_flight_init in two steps, for a caller that needs the flight's media intervals itself
 * (the path loop: its flight and the set-up share one rd_media_intervals). First: does the
 * scene have a light of the set that next-event estimation chooses, rd_eq_has_lights(s,
 * rd_eq_mode_beams(mode)) (else the set-up stops before the intervals, n = 0)? Then, with
 * ef->iv[0..ef->n) filled by the caller from rd_media_intervals(s, region, r, 0, t_light)
 * (n = 0 allowed): the rest of the set-up, with the same result as rd_eq_flight_init.
 * rd_eq_has_lights with beams = 0: a point or spot light (what "auto" looks for); with
 * beams = 1, a directional beam also counts (the modes that sample beams; `delta`'s "tiles"
 * asks rd_eq_tiles_have_lights). */
int rd_eq_has_lights(const rd_scene *s, int beams);
/* Is there a light for tiles with the strategy on every flight beside delta's own path (the
 * guided methods' third estimator, `delta`'s "tiles", compare's rendered reference): a point
 * or spot light, or a directional beam that delta's path does not connect to
 * (settings.beam_connect: a flight with the strategy on every flight drops the connections and
 * samples the beam's chord instead, the same light found the weaker way;
 * integrators/select.c, "Beams that delta's path connects to")? */
int rd_eq_tiles_have_lights(const rd_scene *s);
int rd_eq_flight_choose(const rd_scene *s, ray3 r, int region, double q, int mode, rd_eq_flight *ef);
/* Does the strategy sample light i on this flight (in its set and not left to delta tracking)? */
int rd_eq_flight_samples(const rd_scene *s, const rd_eq_flight *ef, int i);
/* The equiangular strategy's MIS-weighted estimate of the single scattering from the set's
 * lights (point and spot lights; directional beams too in rd_eq_mode_beams' modes) along the
 * flight, for unit throughput. */
vec3 rd_eq_nee(const rd_scene *s, const rd_eq_flight *ef, pcg32 *rng, rd_track_counters *c);
/* One equiangular sample's estimate at t along r (r.d unit) in medium m, for light `light`
 * drawn with density pe (its choice probability times the equiangular pdf) and MIS weight w:
 *     sigma_s(t) T^(t_from, t) L^_light(t) w / pe
 * (T^ and L^ unbiased, rd_transmittance and rd_nee_light), 0 where sigma_t or w is. Shared by
 * rd_eq_nee and the marchers' sample (integrators/march_equiangular.c). */
vec3 rd_eq_estimate(const rd_scene *s, int region, ray3 r, double t_from, double t, const rd_medium *m,
                    int light, double w, double pe, pcg32 *rng, rd_track_counters *c);
/* The MIS weight of next-event estimation toward light `light` at the flight's scattering
 * vertex at distance t (1 for a light that equiangular sampling never chooses). `density` is
 * the flight's scattering density at t when known exactly (rd_flight.pdf > 0), else 0: delta
 * tracking's, the stand-in. (rd_eq_nee takes a density of 0 from ef->density as it is, while
 * here 0 means the stand-in: a flight with q(t) = 0 never puts its vertex at t, so only the
 * sample's side needs it; keep the two tests as they are.) */
double rd_eq_weight(const rd_scene *s, const rd_eq_flight *ef, double t, int light, double density);

/* Direct light at x where a phase-sampled path from x goes on (the marchers' nee+paths source):
 * every light a path cannot hit (point, spot, directional) once with weight 1, and delta's
 * own pick among all lights (pmf_i) kept when it is a light a path can hit (sphere,
 * environment), with the power heuristic against phase sampling. The path from x then
 * counts the light it hits with the matching weight (rd_flight_behind), so the two sum to
 * the direct light exactly once (Veach 1997 §9.2). light_w (NULL: every weight 1) scales each
 * light that is not hittable by a weight of the caller's (the marchers' MIS weight against
 * their equiangular sample, march_equiangular.c); a weight of 0 casts no shadow ray. */
vec3 rd_nee_split(const rd_scene *s, int region, vec3 x, vec3 d, double g, const double *light_w,
                  pcg32 *rng, rd_track_counters *c);

/* Direct light at x with no path to share it with (the ray marchers' photon sources): one
 * sample of every light, summed, with no MIS weight against a path (none follows, so a weight
 * < 1 would lose light from sphere and environment lights). A light that gives nothing at x
 * (outside a spot's cone, behind a finite beam) costs no shadow ray. light_w as for
 * rd_nee_split, for every light: the marchers' weights against their equiangular sample. */
vec3 rd_nee_all(const rd_scene *s, int region, vec3 x, vec3 d, double g, const double *light_w,
                pcg32 *rng, rd_track_counters *c);

/* ---- settings.beam_connect: the path loops' beam connections (transport/beam_connect.c) ----- */
/* Fill s->beam_connect for the scene's first directional beam whose axis crosses a medium's
 * bounds (light -1 and 0 when there is none). The loader calls it, once. */
int rd_beam_connect_setup(rd_scene *s);
/* The connection's point y seen from vertex x, from four uniforms, and its density per unit
 * volume *pdf (rd_beam_connect_pdf); 0 when there is none. */
int rd_beam_connect_sample(const rd_scene *s, vec3 x, double u_mix, double u_th, double u1, double u2,
                           vec3 *y, double *pdf);
/* The density per unit volume with which rd_beam_connect_sample draws y from x (0 outside the
 * beam's cylinder over the axis' span [s0, s1] within the media). */
double rd_beam_connect_pdf(const rd_scene *s, vec3 x, vec3 y);
/* The MIS stand-in for the path's own way to y: direction density dir_pdf at x, then delta
 * tracking's collision density over `dist` with the beam's medium's global majorant (sigma_bar),
 * per unit volume. */
double rd_beam_connect_path_pdf(const rd_scene *s, double dir_pdf, double dist);
/* One connection from scattering vertex x (in medium m, arrived along d) to the beam, with its
 * MIS weight against the path's own continuation (direction mixture mx, NULL: phase sampling)
 * and its roulette: an estimate of the part of L_s(x, -d) that the beam's light scattered at a
 * point of its cylinder gives, per unit throughput at x. */
vec3 rd_beam_connect_estimate(const rd_scene *s, int region, vec3 x, vec3 d, const rd_medium *m,
                              const rd_dir_mix *mx, pcg32 *rng, rd_track_counters *c);

#ifdef __cplusplus
}
#endif
#endif /* RD_TRANSPORT_H */
