/* rd_transport.h: carrying light through the scene, the pieces every method shares: free
 * flights and transmittance across the scene's regions and surfaces (transport/tracking.c),
 * next-event estimation with MIS (transport/nee.c) and the scattering-direction mixture
 * (transport/directions.c). Internal to renderer/ (tests include it). */
#ifndef RD_TRANSPORT_H
#define RD_TRANSPORT_H

#include "media/rd_freepath.h"
#include "scene/rd_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The media of `region` r crosses within [tmin, tmax]: disjoint intervals sorted by entry
 * distance, each of one medium (media with sigma_maj = 0 left out). At most RD_MAX_INTERVALS
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
 * which is rd_nee). */
vec3 rd_nee_mix(const rd_scene *s, int region, vec3 x, vec3 d, double g, const rd_dir_mix *mx,
                pcg32 *rng, rd_track_counters *c);
/* Next-event estimation at a diffuse surface hit h reached along d: one light by power, the
 * BSDF (rd_material_eval) times the cosine at the light's direction, the shadow ray from the
 * surface (rd_shadow_transmittance, in the region on d's side), MIS (power heuristic) against
 * BSDF sampling. Multiply by the path weight. */
vec3 rd_nee_surface(const rd_scene *s, const rd_hit *h, vec3 d, pcg32 *rng,
                    rd_track_counters *c);

/* Direct light at x with no path to share it with (the ray marchers): one sample of every
 * light, summed, no MIS weight (nothing else estimates the direct part, so a weight < 1 would
 * lose light from sphere and environment lights). A light that gives nothing at x (outside a
 * spot's cone, behind a finite beam) costs no shadow ray. */
vec3 rd_nee_all(const rd_scene *s, int region, vec3 x, vec3 d, double g, pcg32 *rng,
                rd_track_counters *c);

#ifdef __cplusplus
}
#endif
#endif /* RD_TRANSPORT_H */
