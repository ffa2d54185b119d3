/* rd_internal.h: the renderer's internal types, shared by the files of renderer/ and by the
 * white-box tests. Not part of the public API (renderer.h is).
 *
 * Units: lengths in scene units (metres); extinction sigma_t in 1/m; point/spot intensity in
 * W/sr; sphere-light and environment radiance in W m^-2 sr^-1; directional irradiance in W/m^2
 * (on a plane perpendicular to the beam). Colours are linear RGB triplets. */
#ifndef RD_INTERNAL_H
#define RD_INTERNAL_H

#include "core/rd_math.h"
#include "renderer.h"

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- Camera -------------------------------------------------------------------------------- */
typedef enum { RD_CAM_PERSPECTIVE, RD_CAM_ORTHOGRAPHIC } rd_camera_kind;

typedef struct {
    rd_camera_kind kind;
    int width, height;
    vec3 pos;
    vec3 forward, right, up; /* orthonormal, right-handed: right = forward x up */
    double fov_deg;          /* perspective: vertical field of view */
    double ortho_width;      /* orthographic: width of the view in scene units */
    double exposure;         /* PNG preview: value * 2^exposure */
    int jitter;              /* 1 (default): a random position inside the pixel per sample;
                              * 0: every sample through the pixel centre (for measurements that
                              * must hold the camera ray fixed, docs/guided-marching.md) */
} rd_camera;

/* Primary ray through the film position (px, py) in pixels (0,0 = top-left corner). */
ray3 rd_camera_ray(const rd_camera *cam, double px, double py);
/* The inverse: film position (px, py) of the point p; 0 when p is behind a perspective camera. */
int rd_camera_project(const rd_camera *cam, vec3 p, double *px, double *py);

/* ---- Density fields ---------------------------------------------------------------------- */
typedef enum { RD_DENSITY_CONSTANT, RD_DENSITY_GRID, RD_DENSITY_NOISE } rd_density_kind;

/* Sparse storage of a voxel grid: a brick map (the layout of an OpenVDB tree's leaf level,
 * Museth 2013 §3). Bricks are 8^3 voxels; brick (a,b,c) of the table holds grid voxels
 * (8a - off[0] .. 8a - off[0] + 7, ...) so that each brick is one leaf node of the tree. A
 * table cell either holds a brick (brick[cell] >= 0: 512 floats at voxels + 512 brick[cell],
 * x fastest) or is constant (brick[cell] < 0: every voxel equals cmax[cell], a tile or the
 * background of the tree). cmin/cmax are the exact min and max of the cell's 512 voxels. */
#define RD_BRICK_LOG2 3
#define RD_BRICK (1 << RD_BRICK_LOG2)
typedef struct {
    int off[3];          /* grid voxel i lies in table cell (i + off) / 8, 0 <= off < 8 */
    int nb[3];           /* table cells per axis */
    int32_t *brick;      /* nb[0] nb[1] nb[2] entries, x fastest: brick index or -1; owned */
    float *cmin, *cmax;  /* per table cell; owned */
    float *voxels;       /* n_bricks * 512; owned */
    size_t n_bricks;
} rd_bricks;

/* Voxel grid with trilinear interpolation, stored dense (data) or sparse (bricks, data NULL).
 * Grid coordinates u are continuous with the centre of voxel (i,j,k) at (i+0.5, j+0.5, k+0.5);
 * outside the voxels the density is 0 beyond half a voxel (clamp-to-border). world -> grid is
 * an affine map. */
typedef struct {
    int nx, ny, nz;
    float *data;       /* dense: nx*ny*nz, x fastest; owned; NULL for a sparse grid */
    rd_bricks *bricks; /* sparse: the brick map; owned; read only when data is NULL */
    double w2g[3][4];  /* u = A x + b, rows of [A | b] */
    double vmin, vmax; /* min and max voxel value */
} rd_grid;

/* Voxel (i, j, k) of either storage; 0 outside the grid (clamp-to-border). */
static inline double rd_grid_voxel(const rd_grid *g, int i, int j, int k)
{
    if (i < 0 || j < 0 || k < 0 || i >= g->nx || j >= g->ny || k >= g->nz) return 0.0;
    if (g->data) return g->data[((size_t)k * g->ny + j) * g->nx + i];
    const rd_bricks *b = g->bricks;
    int x = i + b->off[0], y = j + b->off[1], z = k + b->off[2];
    size_t cell = ((size_t)(z >> RD_BRICK_LOG2) * b->nb[1] + (y >> RD_BRICK_LOG2)) * b->nb[0] +
                  (x >> RD_BRICK_LOG2);
    int32_t q = b->brick[cell];
    if (q < 0) return b->cmax[cell];
    const int m = RD_BRICK - 1;
    return b->voxels[((size_t)q << (3 * RD_BRICK_LOG2)) +
                     (((z & m) << RD_BRICK_LOG2 | (y & m)) << RD_BRICK_LOG2 | (x & m))];
}
/* Free what a grid owns (either storage) and zero its pointers; safe on a zeroed grid. */
void rd_grid_free(rd_grid *g);
/* Bytes the grid's voxel storage takes (dense array, or table, bounds and bricks). */
size_t rd_grid_bytes(const rd_grid *g);

typedef enum { RD_SHAPE_NONE, RD_SHAPE_ELLIPSOID } rd_shape_kind;

/* Procedural fBm of Perlin gradient noise times a smooth shape (seed 003 §4.2):
 *   density(x) = shape(x) * max(0, 1 + amplitude * fbm(x)),
 *   fbm(x) = sum_{o<octaves} gain^o noise(frequency lacunarity^o (x - center)),
 *   shape(x) = smoothstep of the normalised ellipsoid radius (1 at the centre, 0 outside). */
typedef struct {
    int octaves;
    double frequency, gain, lacunarity, amplitude;
    uint32_t seed;
    rd_shape_kind shape;
    vec3 center, radii;
    double edge;         /* width of the shape's soft edge, as a fraction of the radius */
    uint8_t perm[512];   /* seeded permutation table */
} rd_noise;

typedef struct {
    char name[64];
    vec3 bmin, bmax;           /* axis-aligned bounds; density is 0 outside */
    rd_density_kind kind;
    double constant;           /* RD_DENSITY_CONSTANT */
    rd_grid grid;              /* RD_DENSITY_GRID */
    rd_noise noise;            /* RD_DENSITY_NOISE */
    double sigma_t_scale;      /* sigma_t(x) = density(x) * sigma_t_scale */
    vec3 albedo;               /* sigma_s = albedo * sigma_t, per channel */
    double g;                  /* Henyey-Greenstein asymmetry */
    double density_max;        /* conservative upper bound of density over the bounds */
    double sigma_maj;          /* global majorant = density_max * sigma_t_scale */
    double density_min;        /* conservative lower bound of density over the bounds */
    struct rd_majorant *majorant; /* super-voxel grid / octree (rd_freepath.h); owned, may be NULL */
    int bound;                 /* 1: named by a shape's inside/outside or the scene-wide "medium"
                                * (rd_scene_medium_bound): it exists where the surfaces say; 0: a
                                * box medium, filling its bounds in the open region */
} rd_medium;

/* Improved Perlin noise pieces (Perlin 2002), shared by the density (medium.c) and its bounds
 * (majorant.c) so that the two can never drift apart. */
#define RD_PERLIN_BOUND 1.04 /* |noise| <= 1.04 for any gradient table: medium.c derives it */
/* The quintic fade 6t^5 - 15t^4 + 10t^3. */
static inline double rd_perlin_fade(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }
/* The gradient of corner hash h (one of the 12 cube-edge directions) as a vector. */
static inline void rd_perlin_grad_vec(int h, double g[3])
{
    h &= 15;
    int ui = h < 8 ? 0 : 1;                                  /* u = h < 8 ? x : y */
    int vi = h < 4 ? 1 : (h == 12 || h == 14 ? 0 : 2);      /* v = h < 4 ? y : (12,14 ? x : z) */
    g[0] = g[1] = g[2] = 0.0;
    g[ui] += (h & 1) ? -1.0 : 1.0;
    g[vi] += (h & 2) ? -1.0 : 1.0;
}
/* The same gradient dotted with (x, y, z), written out for the hot path. */
static inline double rd_perlin_grad(int h, double x, double y, double z)
{
    h &= 15;
    double u = h < 8 ? x : y;
    double v = h < 4 ? y : (h == 12 || h == 14 ? x : z);
    return ((h & 1) ? -u : u) + ((h & 2) ? -v : v);
}
/* The ellipsoid shape as a function of the normalised radius r: 1 inside 1 - edge, smoothstep
 * down to 0 at r = 1 (non-increasing in r). */
static inline double rd_shape_of_r(double edge, double r)
{
    if (r >= 1.0) return 0.0;
    double e0 = 1.0 - edge;
    if (r <= e0) return 1.0;
    double t = (r - e0) / edge;
    return 1.0 - t * t * (3.0 - 2.0 * t);
}

double rd_noise_eval(const rd_noise *n, vec3 x);     /* Perlin gradient noise in [-1, 1] */
double rd_noise_fbm(const rd_noise *n, vec3 x);
double rd_noise_fbm_bound(const rd_noise *n);         /* provable bound of |fbm| */
void rd_noise_init_perm(rd_noise *n);
double rd_grid_lookup(const rd_grid *g, vec3 x);      /* trilinear, world coordinates */
double rd_medium_density(const rd_medium *m, vec3 x); /* 0 outside bounds */
static inline double rd_medium_sigma_t(const rd_medium *m, vec3 x)
{
    return rd_medium_density(m, x) * m->sigma_t_scale;
}
/* Ray-box slab test; on a hit writes the overlap [t0, t1] clipped to [tmin, tmax]. */
int rd_box_intersect(vec3 bmin, vec3 bmax, ray3 r, double tmin, double tmax, double *t0,
                     double *t1);

/* ---- Lights -------------------------------------------------------------------------------- */
typedef enum {
    RD_LIGHT_POINT,       /* pos, intensity I [W/sr] */
    RD_LIGHT_SPOT,        /* pos, dir, I [W/sr] on the axis, cone with smooth falloff */
    RD_LIGHT_DIRECTIONAL, /* dir (travel direction), irradiance E [W/m^2]; optional beam */
    RD_LIGHT_SPHERE,      /* centre, radius, uniform radiance L [W m^-2 sr^-1] */
    RD_LIGHT_ENVIRONMENT  /* uniform radiance L from every direction at infinity */
} rd_light_kind;

typedef struct {
    rd_light_kind kind;
    vec3 pos, dir;           /* dir: unit; spot axis or directional travel direction */
    vec3 value;              /* I, E or L as the kind says */
    double cos_outer;        /* spot: cos of half the cone angle */
    double cos_inner;        /* spot: cos where the smooth falloff starts */
    double radius;           /* sphere radius; directional beam radius (0 = unbounded) */
    vec3 beam_center;        /* directional beam: a point on the beam axis */
} rd_light;

/* A light sample seen from a point x, for next-event estimation. */
typedef struct {
    vec3 wi;        /* unit direction from x toward the light */
    double dist;    /* distance to the light (INFINITY for directional/environment) */
    vec3 contrib;   /* incident radiance times 1/pdf, i.e. the contribution before the phase
                       function and transmittance (delta lights: I/r^2 or E) */
    double pdf;     /* solid-angle pdf of wi; 0 for delta lights (no MIS) */
} rd_light_sample;

/* Sample light `l` from x with two uniforms; returns 0 when it contributes nothing. */
int rd_light_sample_li(const rd_light *l, vec3 x, double u1, double u2, rd_light_sample *s);
/* Solid-angle pdf that rd_light_sample_li gives direction w from x (area lights only). */
double rd_light_pdf(const rd_light *l, vec3 x, vec3 w);
/* Spot light angular falloff in [0, 1] at cos_theta from its axis (smoothstep over the edge). */
double rd_spot_falloff(const rd_light *l, double cos_theta);
/* Distance along r to a sphere light's surface (INFINITY if missed or not a sphere light). */
double rd_light_hit(const rd_light *l, ray3 r);
/* Total emitted power [W] (luminance of the RGB), used to choose lights in proportion to power;
 * `scene_radius` bounds directional and environment lights. */
double rd_light_power(const rd_light *l, double scene_radius);

/* Lights chosen in proportion to power in O(1) (Walker's alias method; lights.c). pmf[i] is the
 * probability of light i (> 0 for every light of positive power). */
typedef struct {
    int n;
    double *pmf;   /* n probabilities, summing to 1 */
    double *prob;  /* alias table: keep column i with probability prob[i], else alias[i] */
    int *alias;
} rd_light_sampler;
rd_status rd_light_sampler_build(rd_light_sampler *ls, const rd_light *lights, int n,
                                 double scene_radius);
void rd_light_sampler_free(rd_light_sampler *ls);
/* The light for uniform u in [0, 1), and its probability; -1 when there are no lights. */
int rd_light_sampler_pick(const rd_light_sampler *ls, double u, double *pmf);

/* ---- Scene --------------------------------------------------------------------------------- */
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
} rd_settings;

/* Photon tracing settings (scene key "photons", docs/scene-format.md). */
typedef struct {
    size_t count;        /* photons emitted */
    int store_direct;    /* store first collisions straight from lights (default 1: the guide
                            wants all in-scattered light) */
    int segments;        /* also store path segments (needed by the track-length bake) */
    int max_depth;
    uint64_t seed;
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
    int distances;       /* 1 (default): free-flight distances and the scatter-or-pass decision
                          * from the guide; 0: delta tracking's */
    double distance_alpha; /* defensive weight of the distance pdf's uniform part, in (0, 1] */
    double pass_floor;   /* the guide strategy's least probability of scatter and of pass, (0, 0.5] */
    double majorant_weight; /* weight of the majorant (delta-tracking) strategy, in [0, 1) */
    int secondary;       /* 1 (default): guide secondary flights too; 0: the camera ray's only */
    double distance_tau_max; /* guide a flight's distance only where its majorant optical depth
                              * is at most this (thicker flights: delta tracking's), > 0 */
    int directions;      /* 1 (default): continue from a vertex by a mixture of the guide's
                          * incident-light lobe and the phase function (MIS); 0: phase alone */
    double direction_weight; /* probability of the guide's lobe in that mixture, in [0, 1) */
    int roulette;        /* 1 (default): Russian roulette and splitting by the guide's estimate
                          * of the path's contribution (weight window, Vorba and Krivanek 2016);
                          * 0: the throughput roulette of `delta` */
    int split_max;       /* most copies one vertex splits into, in [1, 64] (1: roulette only) */
} rd_guide_settings;

/* Ray-marching settings of the guided methods (scene key "march", docs/scene-format.md). */
typedef enum { RD_LS_NEE_PHOTONS, RD_LS_PHOTONS, RD_LS_NEE, RD_LS_NEE_GUIDE } rd_ls_kind;
typedef struct {
    int samples;         /* N_mean: samples per ray (uniform and transmittance: every ray);
                          * 0 (key absent): each placement's own calibrated default
                          * (integrator_march.c, march_default_samples) */
    int min_samples;     /* guided: N_min >= 1 */
    int max_samples;     /* guided: N_max */
    double alpha;        /* defensive weight of the mixture, in (0, 1] */
    rd_ls_kind ls;       /* source of sigma_s L_s at a sample */
    int detail;          /* guided: 1 scales each cell's f_j by sigma_t(t) / sigma_j from lookups
                          * along the ray; 0 (default) uses the cells alone (seed 001 eq. 16) */
} rd_march_settings;

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
    uint64_t bake_key;    /* hash of what a bake depends on (scene.c bake_key), for the cache */
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
/* Solid-angle pdf with which next-event estimation (rd_nee) produces direction w from x toward
 * light i, light choice included: for MIS of phase-sampled paths that hit the light. */
double rd_light_mis_pdf(const rd_scene *s, int i, vec3 x, vec3 w);
double rd_power_heuristic(double a, double b);

/* ---- Free-path sampling and transmittance (THEORY.md §2) ---------------------------------- */

/* Counters a tracker increments (per thread, summed by the caller). */
typedef struct {
    uint64_t collisions, lookups;
    uint64_t shadow_rays;  /* next-event transmittance estimates */
} rd_track_counters;

typedef struct {
    int hit;          /* 1 = real collision */
    double t;         /* distance along the ray */
    const rd_medium *medium;
    double weight;    /* path weight factor: 1 for analog trackers; weighted delta and
                         decomposition tracking (seed 002 Alg. 2-3) return their weight here,
                         for a collision and for an escape alike */
} rd_collision;

#include "media/rd_freepath.h"


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
/* The medium of `region` at x (the bound medium, or in the open region the box medium whose
 * bounds contain x, else the scene-wide medium), or NULL where there is none. */
const rd_medium *rd_scene_medium_at(const rd_scene *s, int region, vec3 x);
/* The medium at x, wherever x is: rd_scene_medium_at(s, rd_scene_region_at(s, x), x). */
const rd_medium *rd_scene_medium_at_point(const rd_scene *s, vec3 x);

/* Scene radius: half the diagonal of the media bounds, at least 1e-3. */
double rd_scene_radius(const rd_scene *s);

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

/* Radiance arriving at the camera along r with the `delta` method: unbiased volumetric path
 * tracing (delta tracking, next-event estimation with ratio tracking, HG sampling, Russian
 * roulette, multiple importance sampling for area and environment lights). */
vec3 rd_delta_radiance(const rd_scene *s, ray3 r, pcg32 *rng, rd_track_counters *c);

/* ---- The unbiased path loop and its free-flight samplers (integrator_delta.c) ------------- *
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
} rd_flight_in;
/* A scattering vertex, as the path loop offers it to a vertex policy. */
typedef struct {
    vec3 x, d;                /* the vertex and the direction the path arrived along */
    const rd_medium *medium;
    int region;               /* the region of the vertex */
    int depth;                /* scattering events up to and including this one (>= 1) */
    vec3 beta;                /* path throughput up to here, flight weight included */
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
    void *user;               /* the sampler's own (per call of the path loop) */
} rd_flight_sampler;
/* Extra copies splitting may add to one camera sample's path tree (a bound on its cost). */
#define RD_SPLIT_BUDGET 32
/* The path loop: NEE at every scattering vertex, HG sampling with MIS, Russian roulette (or
 * the sampler's vertex policy, with splitting). */
vec3 rd_path_radiance(const rd_scene *s, ray3 r, const rd_flight_sampler *fs, pcg32 *rng,
                      rd_track_counters *c);
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
 * `depth` scattering events before it): the radiance estimate of L(r.o, -r.d). */
vec3 rd_delta_continue(const rd_scene *s, ray3 r, int region, double pdf, int depth,
                       int camera_chain, pcg32 *rng, rd_track_counters *c);
/* Delta tracking's flight (rd_sample_free_path with the scene's tracker). */
rd_flight rd_flight_delta(const rd_scene *s, const rd_flight_in *in, pcg32 *rng,
                          rd_track_counters *c);
/* Radiance a pass-through receives: the hit sphere light or the environment, MIS-weighted
 * against the light sampling of rd_nee when in->phase_pdf > 0, plus the background for a
 * camera chain that hits no light; 0 when the flight ends at a surface (in->hit_shape >= 0:
 * the loop continues from it). Deterministic (no random numbers). */
vec3 rd_flight_behind(const rd_scene *s, const rd_flight_in *in);

/* A growing text buffer (text.c): rd_text_printf appends; on a failed allocation it sets oom
 * and ignores later calls, so a writer checks oom once at the end. Start with {0}; free(s). */
typedef struct { char *s; size_t n, cap; int oom; } rd_text;
void rd_text_printf(rd_text *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Write the buffer to path atomically (rd_write_atomic) and free it; a buffer that ran out of
 * memory writes nothing and fails with RD_ERR_NOMEM, "PATH: out of memory". */
rd_status rd_text_write(rd_text *b, const char *path, char *err, size_t errlen);

/* Write n bytes to path through a temporary name in its folder and a rename (output.c), so a
 * failed write never leaves a partial file; RD_ERR_OUTPUT naming the path. */
rd_status rd_write_atomic(const char *path, const void *data, size_t n, char *err, size_t errlen);

/* Volume loading shims (C++ behind a C API; never throw). Both fill the grid's storage, dims,
 * w2g, vmin/vmax and return the world-space bounds of the voxels. rd_vdb_load reads the float
 * grid `grid_name` over its active bounding box, sparsely (g->bricks: the tree's leaves become
 * bricks, its tiles and background constants) unless the dense box would take at most twice
 * the bytes of the bricks (then g->data); rd_raw_load fills g->data. */
rd_status rd_vdb_load(const char *path, const char *grid_name, rd_grid *g, vec3 *bmin,
                      vec3 *bmax, char *err, size_t errlen);
/* Write a dense float grid as a .vdb: voxel (i,j,k) centred at origin + voxel_size (i,j,k).
 * Zero voxels are left inactive (the background), so the grid's active box is the non-zero
 * region; the file is zip-compressed. */
rd_status rd_vdb_save_dense(const char *path, const char *grid_name, const float *data, int nx,
                            int ny, int nz, double voxel_size, const double origin[3], char *err,
                            size_t errlen);
rd_status rd_raw_load(const char *path, int nx, int ny, int nz, rd_grid *g, char *err,
                      size_t errlen);

#ifdef __cplusplus
}
#endif
#endif /* RD_INTERNAL_H */
