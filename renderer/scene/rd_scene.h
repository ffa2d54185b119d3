/* rd_scene.h: the scene as the renderer holds it (struct rd_scene: camera, media, lights,
 * settings, shapes), and the questions asked of it: what a ray meets first, which region a
 * point lies in, which medium is where (scene/queries.c), its radius (scene/scene.c). The
 * loader that fills it from scene.json is load/. Internal to renderer/ (tests include it). */
#ifndef RD_SCENE_H
#define RD_SCENE_H

#include "media/rd_medium.h"
#include "scene/rd_camera.h"
#include "scene/rd_light.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int spp;
    int spp_given;       /* settings.spp was in the file (else --time/settings.time alone run
                            until the time is up) */
    double time_limit;
    uint64_t seed;
    int max_depth;       /* scattering events per path (1 = single scattering) */
    int rr_depth;        /* Russian roulette from this depth on */
    char method[32];
    /* Free-path engine (rd_freepath.h): rd_fp_kind / rd_tr_kind values and their parameters. */
    int tracker, transmittance;
    double track_b, track_m, track_step;
    /* `delta`'s strategies for thin media and small lights (docs/free-path.md "Equiangular
     * sampling" and "Thin-media probability biasing"): */
    int equiangular;     /* rd_equiangular_mode: an equiangular distance sample toward a point
                          * or spot light (or with `true` a directional beam) per flight, MIS
                          * with delta tracking's collision */
    int equiangular_given; /* settings.equiangular was in the file (else compare's rendered
                            * reference takes "tiles" where a point or spot light or a
                            * directional beam exists: compare/reference.c) */
    double thin_bias;    /* 0: off; in (0, 1): the least probability that a flight of `delta`
                          * has a tentative collision (flights whose pass-through is worth
                          * exactly 0 are forced: 1) */
    int beam_connect;    /* RD_BC_ON: every path loop (`delta`'s, guided-unbiased's, the marchers'
                          * continuations) connects each scattering vertex to a point of the
                          * scene's directional beam (transport/beam_connect.c); RD_BC_AUTO
                          * (default): on where the beam is narrow for its medium's phase
                          * (load.c); RD_BC_OFF: off */
    int select;          /* the guided methods (guided with an unbiased march.ls, and
                          * guided-unbiased): RD_SELECT_TILES lets a pilot give each 8x8 tile
                          * to the method or to delta's path, whichever pays, and the image's
                          * samples choose again at every epoch (integrators/select.c);
                          * RD_SELECT_PILOT: the pilot's choice only; RD_SELECT_OFF: the method
                          * everywhere; RD_SELECT_AUTO (default): RD_SELECT_TILES, except that
                          * guided with march.ls nee+beams marches every pixel (only an explicit
                          * "tiles" or "pilot" mixes the beams, which are consistent, not
                          * unbiased, with delta) */
    int probes;          /* `delta`: camera chains a sample takes for the light at the chain's
                          * end: M >= 1 (1, the default: the path's own only), or 0, "auto": M per
                          * pixel from its samples (integrators/probes.c) */
    int adaptive;        /* the methods with a tile selection (select with epochs, or delta's
                          * equiangular "tiles"): 1 gives each tile's pixels a share of the
                          * samples, sqrt(V / C) of their estimator's figures over the largest
                          * tile's, each weighing in its pixel's mean by its estimator's inverse
                          * variance (integrators/select_share.c); 0: every pixel draws every
                          * sample, each of weight 1; RD_ADAPTIVE_PILOT: shares set at the pilot's
                          * choice alone and kept, no weights (unbiased: select_share.c "Pilot
                          * shares"); RD_ADAPTIVE_EPOCHS: shares set at every choice, each sample
                          * weighing the indices it stands for (unbiased: "Epoch shares");
                          * RD_ADAPTIVE_AUTO (default): 1 for `guided`, RD_ADAPTIVE_EPOCHS for
                          * `guided-unbiased` and (since session 72) `delta`'s "tiles" */
} rd_settings;
enum { RD_SELECT_OFF, RD_SELECT_TILES, RD_SELECT_PILOT, RD_SELECT_AUTO };
/* settings.adaptive "auto" (the default): shares for `guided`, the epochs' for `guided-unbiased`
 * and `delta`'s "tiles";
 * "pilot": shares fixed from the pilot's figures, no weights; "epochs": shares set at every
 * choice, unbiased by the indices each sample stands for (rd_settings.adaptive). */
enum { RD_ADAPTIVE_AUTO = 2, RD_ADAPTIVE_PILOT = 3, RD_ADAPTIVE_EPOCHS = 4 };
enum { RD_BC_OFF, RD_BC_ON, RD_BC_AUTO }; /* settings.beam_connect */
/* settings.equiangular: off, every flight, the camera's flight only, or every flight for the
 * lights whose lit span delta tracking reaches but mostly crosses without colliding
 * (transport/equiangular.c, "auto"); and for settings.equiangular only, RD_EQ_TILES ("tiles"):
 * `delta` chooses per tile of the image between off and every flight (integrators/delta.c). A
 * path's flights never see RD_EQ_TILES: rd_eq_path_mode maps it. */
typedef enum { RD_EQ_OFF, RD_EQ_ALL, RD_EQ_CAMERA, RD_EQ_AUTO, RD_EQ_TILES } rd_equiangular_mode;
/* The mode a path's flights take for settings.equiangular `mode`: "tiles" is off where no tile
 * choice gives a path the strategy (the tile choice itself names RD_EQ_ALL). */
static inline int rd_eq_path_mode(int mode) { return mode == RD_EQ_TILES ? RD_EQ_OFF : mode; }

/* Photon tracing settings (scene key "photons", docs/scene-format.md). */
typedef struct {
    size_t count;        /* photons emitted */
    int store_direct;    /* store first collisions straight from lights (default 1: the guide
                            wants all in-scattered light) */
    int segments;        /* also store path segments (needed by the track-length bake) */
    int max_depth;
    uint64_t seed;
    /* Progressive photon mapping (Knaus & Zwicker 2011, for volumes; docs/guided-marching.md
     * "Progressive photon passes"): the marchers' photon estimate then gathers, for the samples
     * of pass i, a fresh batch of photons within a radius that shrinks as
     * r_{i+1}^3 = r_i^3 (i + alpha) / (i + 1), so the image converges to the right answer. */
    int progressive;     /* 0 (default): one fixed map (seed 001) */
    size_t pass_count;   /* photons emitted per pass (0: count) */
    int pass_spp;        /* samples per pixel rendered with each pass's photons, >= 1 (with a
                          * tile selection, pass_spp x all pixels samples of the estimate that
                          * reads them, the method's or guided's beams, so such a pixel takes
                          * more: rd_method.marched_pixels) */
    double alpha;        /* the schedule's alpha in (0, 1); 4/7 minimises the asymptotic MSE of
                          * a 3-D kernel (bake/passes.c derives it) */
    double aim;          /* the share of each light's photons sent toward the glass, in [0, 1)
                          * (rd_emission_aim; only where the scene has a dielectric shape) */
} rd_photon_settings;

/* Guide-grid settings (scene key "guide"). */
typedef struct {
    int adaptive;        /* 0 uniform grid, 1 adaptive octree */
    int track;           /* 0 k-NN bake, 1 track-length bake */
    int bands;           /* SH bands L */
    int k;               /* photons per estimate */
    double lambda;       /* grid quality */
    int res[3];          /* explicit uniform resolution, 0 = the rule */
    double min_cell;     /* adaptive: smallest cell edge [m], 0 = default */
    int max_depth;       /* adaptive: deepest level */
    int window;          /* 1 (default): Hann window on the phase's b_l (sh_window_hann), 0: none */
    /* guided-unbiased (docs/guided-unbiased.md): */
    int distances;       /* 1: free-flight distances and the scatter-or-pass decision from the
                          * guide; 0 (default): delta tracking's */
    double distance_alpha; /* defensive weight of the distance pdf's uniform part, in (0, 1] */
    double pass_floor;   /* the guide strategy's least probability of scatter and of pass, (0, 0.5] */
    double majorant_weight; /* weight of the majorant (delta-tracking) strategy, in [0, 1) */
    int secondary;       /* 0 (default): guide the camera ray's flights only; 1: the flights
                          * after a scattering event too */
    double distance_tau_max; /* guide a flight's distance only where its majorant optical depth
                              * is at most this (thicker flights: delta tracking's), > 0 */
    int directions;      /* 1 (default): continue from a vertex by a mixture of the guide's
                          * incident-light lobe and the phase function (MIS); 0: phase alone */
    double direction_weight; /* probability of the guide's lobe in that mixture, in [0, 1) */
    int roulette;        /* 1 (default): Russian roulette and splitting by the guide's estimate
                          * of the path's contribution (weight window, Vorba and Krivanek 2016);
                          * 0: the throughput roulette of `delta` */
    int split_max;       /* most copies one vertex splits into, in [1, 64] (1: roulette only) */
    int eval_bands;      /* guided-unbiased reads the guide's first min(eval_bands, bands)
                          * bands, in [1, 8] (sampling decisions only: unbiased for any) */
    double photon_share; /* guided-unbiased bakes this share of photons.count, in (0, 1] */
    int equiangular;     /* rd_equiangular_mode of guided-unbiased's flights (`delta`'s strategy,
                          * its MIS weights taken with a guided flight's own density;
                          * transport/equiangular.c) */
    int probes;          /* guide.probes: guided-unbiased's probes, 0 "auto" or M in [1, 256]
                          * (integrators/probes.c) */
} rd_guide_settings;

/* Ray-marching settings of the guided methods (scene key "march", docs/scene-format.md). */
typedef enum { RD_LS_NEE_PHOTONS, RD_LS_PHOTONS, RD_LS_NEE, RD_LS_NEE_GUIDE, RD_LS_NEE_PATHS, RD_LS_NEE_DELTA,
               RD_LS_NEE_BEAMS } rd_ls_kind;
typedef struct {
    int samples;         /* N_mean: samples per ray (uniform and transmittance: every ray);
                          * 0 (key absent): each placement's own calibrated default
                          * (integrators/march.c, march_default_samples) */
    int min_samples;     /* guided: N_min >= 1 */
    int max_samples;     /* guided: N_max */
    double alpha;        /* defensive weight of the mixture, in (0, 1] */
    rd_ls_kind ls;       /* source of sigma_s L_s at a sample */
    double paths;        /* nee+paths: the probability, in (0, 1], that a sample continues
                          * its path (weight 1 / paths); 0 (key absent): each placement's
                          * own default (integrators/march.c, march_default_paths) */
    int detail;          /* guided: 1 scales each cell's f_j by sigma_t(t) / sigma_j from lookups
                          * along the ray; 0 (default) uses the cells alone (seed 001 eq. 16) */
    int equiangular;     /* rd_equiangular_mode OFF, ALL or AUTO: one equiangular sample per
                          * segment toward a point or spot light, MIS with the placement's
                          * samples for the direct part (integrators/march_equiangular.c) */
    int probes;          /* camera chains a sample takes for the light at the chain's end:
                          * M >= 1 (1: the sample's own only), or 0, "auto" (default): M per
                          * pixel from its samples (integrators/probes.c) */
    int guided_paths;    /* guided with a tile selection: 1 (default) lets the selection give
                          * tiles to guided-unbiased's paths too (integrators/guided.c) */
    int beams;           /* guided with a tile selection and march.ls nee+paths or nee+delta: 1
                          * (default) lets the selection give tiles to the marcher with the
                          * nee+beams source too, on progressive photon passes of its own (the
                          * beams estimator, integrators/guided.c); 0: not */
} rd_march_settings;

/* What settings.beam_connect's sampling needs, set once when the scene is loaded
 * (transport/beam_connect.c, rd_beam_connect_setup): the beam, its axis inside the media,
 * and a table over the angle at which a point on the axis is seen from a vertex. */
#define RD_BC_BINS 256
typedef struct {
    int light;            /* the beam (a directional light with a radius); -1: none, off */
    const char *off;      /* why it is off (a string literal, for `photonmarch info`), or NULL */
    double s0, s1;        /* its axis, beam_center + s dir, from where it enters the first
                             medium's bounds to where it leaves the last's */
    int medium;           /* the medium with the longest stretch of the axis: its g shapes
                             the table, its global majorant is sigma_bar */
    double share;         /* the cylinder's volume over [s0, s1] over the volume of the
                             bounds of the media its axis crosses */
    double breadth;       /* share (1 - |g|)^2, g that of `medium`: "auto"'s test (load.c) */
    double sigma_bar;     /* the MIS stand-in's extinction */
    double cdf[RD_BC_BINS + 1]; /* unnormalised CDF over theta in [-pi/2, pi/2] of HG(g, -sin theta) */
} rd_beam_connect;

struct rd_scene {
    char path[1024];
    char *description;    /* the scene's "description" (what it shows, what to look at), or NULL */
    rd_camera camera;
    rd_medium *media;
    int n_media;
    rd_light *lights;
    int n_lights;
    vec3 background;      /* radiance seen by camera rays that leave the scene (not a light) */
    vec3 bmin, bmax;      /* bounds of all media */
    rd_settings settings;
    rd_photon_settings photons;
    rd_guide_settings guide;
    rd_march_settings march;
    rd_light_sampler light_sampler; /* lights by power, built by the loader */
    rd_beam_connect beam_connect;   /* settings.beam_connect's tables (light -1 when off) */
    uint64_t bake_key;    /* hash of what a bake depends on (load/ bake key), for the cache */
    double hidden_share;  /* the media's light on L S+ paths, measured at load (rd_hidden_light:
                             renderer.h; 0 for a scene without glass and a delta light) */
    int *sphere_lights;   /* indices of the sphere lights (the lights a path can hit) */
    int n_sphere_lights;
    /* Surfaces (issue 14; rd_geom.h, docs/scene-format.md "Shapes"): triangle meshes with a
     * material and the media on their two sides, and the scene-wide medium. */
    struct rd_shape *shapes;  /* n_shapes, owned (each owns its mesh) */
    int n_shapes;
    int fill_medium;      /* scene key "medium": index of the medium that fills everything
                           * outside every shape and box medium, or -1 (vacuum) */
    int camera_region;    /* the region of a perspective camera's position (rd_scene_region_at),
                           * found once by the loader: every camera ray starts there */
    struct rd_geom *geom; /* the Embree scene of shapes and sphere lights (rd_geom.h), built by
                           * the loader when there are shapes; NULL without (then sphere lights
                           * are hit by rd_scene_hit_light, as before shapes existed) */
};

/* ---- Surfaces in the transport (issue 14; docs/surfaces.md) --------------------------------- *
 * A ray travels in a REGION, named by the medium on its side of the surfaces: a medium index,
 * or -1 for vacuum (pbrt-v4's MediumInterface: each surface says which medium lies on each
 * side, and a path crossing it takes the other side's). The region s->fill_medium (the
 * scene-wide medium; -1 when the scene has none) is the OPEN region: there the box media (the
 * media no shape names) fill their bounds and the scene-wide medium fills the rest of its own
 * bounds. Any other region holds its one bound medium, whose density is 0 outside that medium's
 * bounds. A scene without shapes is one open region, so every call below with
 * region = s->fill_medium behaves as before shapes existed. */
typedef struct rd_hit rd_hit; /* rd_geom.h */
/* The region a camera ray starts in: s->camera_region for a ray from a perspective camera's
 * position, else rd_scene_region_at(s, r.o). */
int rd_scene_camera_region(const rd_scene *s, ray3 r);
/* The region containing point x: one ray query from x (the first shape it meets says which
 * medium lies on the side it arrives from); s->fill_medium when no shape is met. */
int rd_scene_region_at(const rd_scene *s, vec3 x);
/* The nearest surface or sphere light r meets with t in (0, tmax) (`from`: the hit r leaves
 * from, or NULL; rd_geom_intersect). Without shapes: the sphere lights by rd_scene_hit_light
 * (h->shape = -1, h->light, h->t, h->p; the rest zero). Returns 1 with *h filled, else 0. The
 * one answer to "what does this ray meet first". */
int rd_scene_intersect(const rd_scene *s, ray3 r, double tmax, const rd_hit *from, rd_hit *h);

/* The nearest sphere light that r hits before tmax (skipping light `skip`, -1 for none), or -1;
 * *t_hit (may be NULL) gets its distance. The one answer to "does this ray meet a light". */
int rd_scene_hit_light(const rd_scene *s, ray3 r, double tmax, int skip, double *t_hit);
/* What a camera chain sees at its end: the sphere light it hits (hit_light >= 0), or the
 * environment and the background (full weight: a camera chain has no MIS). */
vec3 rd_scene_behind(const rd_scene *s, int hit_light);

/* The medium of `region` at x (the bound medium, or in the open region the box medium whose
 * bounds contain x, else the scene-wide medium), or NULL where there is none. */
const rd_medium *rd_scene_medium_at(const rd_scene *s, int region, vec3 x);
/* The medium at x, wherever x is: rd_scene_medium_at(s, rd_scene_region_at(s, x), x). */
const rd_medium *rd_scene_medium_at_point(const rd_scene *s, vec3 x);

/* Scene radius: half the diagonal of the media bounds, at least 1e-3. */
double rd_scene_radius(const rd_scene *s);

#ifdef __cplusplus
}
#endif
#endif /* RD_SCENE_H */
