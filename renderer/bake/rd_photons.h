/* rd_photons.h: photon tracing from the scene's lights into a photon map (THEORY.md §3).
 * Internal to renderer/ (and its tests). */
#ifndef RD_PHOTONS_H
#define RD_PHOTONS_H

#include "photonmap.h"
#include "scene/rd_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    size_t count;      /* photons emitted in total (over all lights) */
    int store_direct;  /* 1: store every collision; 0: skip first collisions straight from a
                          light (direct light then comes from next-event estimation) */
    int segments;      /* 1: also store path segments (clipped to the media bounds) */
    int max_depth;     /* collisions per photon path */
    int count_only;    /* 1: store nothing, only the statistics' power sums (rd_hidden_light) */
    int reachable;     /* 1: store only light that a path tracer's paths can reach: no photon
                          or segment on an L S+ path from a point, spot or directional light
                          (the light of power_hidden, below); the statistics count all */
    uint64_t seed;
    /* Thinning: 0 (or >= 1) stores every collision; in (0, 1) each collision is stored with
     * probability keep, its power divided by keep (unbiased given the kernel that reads it), the
     * choice a hash of (seed, photon, depth), so that it draws nothing from the photon's own
     * stream (its path is the same either way) and does not depend on threads or ranks. */
    double keep;
    int threads;       /* 0 = all */
    const volatile int *cancel; /* non-NULL: read before each block of 4096 photons; once it is
                                   non-zero the trace stops and returns RD_ERR_CANCELLED */
    /* Several ranks trace one map together (NULL or one rank: this process alone): rank r traces
     * the blocks [nblocks r / K, nblocks (r + 1) / K), then the ranks agree on the outcome (a
     * cancel or a failure on one rank fails all) and gather every rank's records and every
     * block's power sums in block order, so that the map and the statistics are one process's,
     * bit for bit, on every rank. Collective: every rank calls it with the same options. */
    const rd_comm *comm;
} rd_photon_opts;

typedef struct {
    double seconds;          /* tracing wall time */
    size_t emitted, stored, segments;
    uint64_t collisions, lookups;
    /* Power balance [W, RGB]: emitted = absorbed + absorbed_surfaces + escaped + carried (by
     * the max_depth cut) in expectation; absorbed is the expected absorption (1 - albedo) x
     * incident power at every collision in a medium, absorbed_surfaces the same at diffuse
     * surfaces, so the balance is a check of the Russian roulette. */
    double power_emitted[3], power_absorbed[3], power_escaped[3], power_carried[3];
    double power_absorbed_surfaces[3];
    /* Power scattered in the media (albedo x incident, at every collision, stored or not), and
     * the part of it on L S+ paths: photons whose first event was a specular surface (glass).
     * Next-event estimation cannot reach that light (a shadow ray stops at glass); a path finds
     * it only by hitting the light through the glass. power_hidden: the part from a point, spot
     * or directional light, which no path can hit, so that `delta` and `guided-unbiased` render
     * none of it, nor anything it lights further on; power_caustic: the part from any light,
     * sphere and environment lights too (rd_hidden_light). */
    double power_scattered[3], power_hidden[3], power_caustic[3];
    /* Several ranks: the gather's wall time (the counts' reduce, the agreement and the gathers)
     * and the bytes each rank received in it (every rank's records, its own included). */
    double gather_seconds;
    size_t gather_bytes;
} rd_photon_stats;

/* Photons aimed at the scene's glass (scene key photons.aim, docs/scene-format.md): a sphere
 * bounding every dielectric shape (about their bounding box's centre, through the farthest
 * vertex), and the share of each light's photons sent toward it. */
typedef struct {
    int on;          /* 0: no glass or photons.aim 0 */
    vec3 centre;
    double radius;
    double share;    /* photons.aim, in [0, 1) */
} rd_emission_aim;
rd_emission_aim rd_emission_aim_of(const rd_scene *s);
/* photons.aim when the scene does not set it (docs/scene-format.md). */
#define RD_PHOTON_AIM 0.0

/* Sample one photon leaving light l (THEORY.md §3): its ray r (origin, unit direction) and
 * power, RGB watts divided by the sample's pdf, so that the mean over photons is the light's
 * power. Draws from rng. The distributions, which tests/test_photons.c checks by chi-square:
 *   point        o = l->pos, d uniform on the sphere; power 4 pi I
 *   spot         o = l->pos, d uniform in the cone cos(theta) >= cos_outer; power weighted by
 *                rd_spot_falloff (so photon power is distributed like the falloff)
 *   directional  d = l->dir; o uniform on a disc across the beam (the beam's radius and centre,
 *                or the scene radius around the media centre) 2R upstream of the media centre
 *   sphere       o uniform on the sphere (just outside it), d cosine-weighted about the normal
 *   environment  d uniform on the sphere; o uniform on a disc of radius R across d, 2R upstream
 *                of the media centre (R = rd_scene_radius)
 * With an aim (non-NULL, on), a point, spot, sphere or directional light sends aim->share of its
 * photons uniformly over the directions from the emission point that meet the aim's sphere (a
 * directional light: uniformly over the disc of the sphere's radius around its centre,
 * projected into the beam's disc plane), as a one-sample mixture with its own distribution;
 * the power is then the emitted radiance (intensity, irradiance) over the mixture's density, so
 * that the mean power in any set of directions is the light's there. An aimed photon that the
 * light does not emit (outside a spot's cone or a beam's disc, into a sphere light) is none.
 * Not aimed, where aiming cannot gain: a spot whose cone misses the sphere's cone or lies inside
 * it, a beam whose disc misses the sphere's disc or lies inside it, a point of a sphere light
 * whose tangent plane hides the whole cone, a point light inside the sphere.
 * Returns 0 (no photon) for an unknown light kind and for such a photon. */
int rd_light_sample_emission(const rd_scene *s, const rd_light *l, const rd_emission_aim *aim,
                             pcg32 *rng, ray3 *r, vec3 *power);

/* Trace o->count photons and add the stored photons (scattered power, THEORY §3) and, when
 * asked, the segments to `map` (not built: the caller calls pm_map_build). An empty map gets
 * its origin set to the centre of the media bounds (positions are stored relative to it); a
 * map that already holds records keeps its origin. Every error return writes a one-line
 * message into err (out of memory names what was being allocated). */
rd_status rd_trace_photons(const rd_scene *s, const rd_photon_opts *o, pm_map *map,
                           rd_photon_stats *st, char *err, size_t errlen);
/* The same trace, and also the photons without their first flight (depth > 1, no segments)
 * into `indirect` (new and empty; NULL: none): one trace gives both maps, each the same bit
 * for bit as a trace of its own (the indirect one with store_direct 0), since photon i's path
 * depends on i alone. The statistics are the main map's. */
rd_status rd_trace_photons_split(const rd_scene *s, const rd_photon_opts *o, pm_map *map,
                                 pm_map *indirect, rd_photon_stats *st, char *err, size_t errlen);

/* rd_hidden_light (renderer.h, bake/photons.c) reads power_hidden, power_caustic and
 * power_scattered. */
/* Bake the scene's SH guide grid (scene key "guide") from a built photon map over the media
 * bounds, with the media's extinction (cell means), scattering (track-length bake) and HG
 * phase coefficients. */
struct sh_guide;
rd_status rd_guide_bake(const rd_scene *s, const pm_map *map, int threads, struct sh_guide **out,
                        char *err, size_t errlen);

/* Where the light went: photon power splatted through the scene camera (img->rgb allocated). */
rd_status rd_photon_image(const rd_scene *s, const pm_map *map, rd_image *img, char *err,
                          size_t errlen);

/* Scale so the 99.5th-percentile luminance is 1 (previews of quantities with no exposure). */
void rd_image_normalise(rd_image *img);

/* What rd_bake made (bake/bake.c): the built photon map and the guide (NULL after no_guide). */
const struct pm_map *rd_baked_map(const rd_baked *b);
const struct pm_map *rd_baked_indirect_map(const rd_baked *b);
const struct sh_guide *rd_baked_guide(const rd_baked *b);
const struct sh_guide *rd_baked_indirect_guide(const rd_baked *b);

/* ---- Progressive photon passes (bake/passes.c; Knaus & Zwicker 2011 with a 3-D kernel) ---- */
/* The alpha of the radius schedule that minimises the asymptotic MSE of a 3-D kernel: 4/7
 * (derived in passes.c). */
#define RD_PPM_ALPHA (4.0 / 7.0)
/* r_pass / r_1 for the schedule r_{i+1}^3 = r_i^3 (i + alpha) / (i + 1); pass >= 1. */
double rd_ppm_radius_scale(int pass, double alpha);
/* The photon seed of pass `pass` (>= 1) of a render with seed `render_seed`: independent
 * streams for independent passes and for renders with different seeds. */
uint64_t rd_ppm_pass_seed(uint64_t photon_seed, uint64_t render_seed, int pass);
/* The photon maps of one progressive pass: `maps` (RD_NEEDS_PHOTONS: the map of every stored
 * collision; RD_NEEDS_INDIRECT: the map without first flights) traced with
 * photons.pass_count (else photons.count) photons and rd_ppm_pass_seed(photons.seed,
 * render_seed, pass), and indexed (with RD_PASS_NO_INDEX in maps only put in spatial order,
 * pm_map_order: no query may be asked of them), each collision stored with probability keep
 * (rd_photon_opts.keep; 0 or 1: every one); no guide. *out is freed with rd_baked_free; its stats say
 * the photons emitted and the seconds. cancel (NULL: none) is polled while tracing:
 * RD_ERR_CANCELLED. comm (NULL: alone): the ranks trace the pass together (rd_photon_opts.comm)
 * and return the same status on every rank. */
rd_status rd_bake_photon_pass(const rd_scene *s, unsigned maps, int pass, uint64_t render_seed, double keep,
                              int threads, const volatile int *cancel, const rd_comm *comm, rd_baked **out,
                              char *err, size_t errlen);

/* The phase-function callback for pm_map_radiance: Henyey-Greenstein with g = *(double *)user. */
double rd_phase_hg_cb(double cos_theta, void *user);

#ifdef __cplusplus
}
#endif
#endif
