/* rd_freepath.h: the free-path sampling engine (THEORY.md §2; seeds 000, 002, 003).
 *
 * Two parts:
 *  - majorant structures (majorant.c): a super-voxel grid (seed 003 §3.1-3.3) or an octree
 *    (seed 000 §5.2) over a medium's box, each cell holding a conservative maximum and minimum
 *    of the density, optionally a tri-linear upper bound (8 corner values). The grid resolution
 *    and the decision not to partition come from the seed-000 cost model (eq. 14-17). Walked by
 *    a value-type iterator: rd_majorant_next(&it, &seg) (DESIGN.md convention 7).
 *  - trackers and transmittance estimators (freepath.c) behind one interface, chosen by
 *    rd_fp_params (scene settings "tracker", "transmittance", "b", "m", "step").
 *
 * Internal to renderer/ (tests include it). */
#ifndef RD_FREEPATH_H
#define RD_FREEPATH_H

#include <stddef.h>
#include <stdint.h>

#include "media/rd_medium.h"
#include "walk.h"

/* Counters a tracker increments (per thread, summed by the caller). */
typedef struct {
    uint64_t collisions, lookups;
    uint64_t shadow_rays;  /* next-event transmittance estimates */
    uint64_t eq_flights;   /* flights that set up the equiangular strategy over media with a
                            * light of its set to choose (transport/equiangular.c), which
                            * the tile selection's counted cost charges (integrators/select.c) */
    uint64_t eq_samples;   /* equiangular samples evaluated (rd_eq_estimate); reported only: no
                            * weight for them held across scenes (bench_cost_fit.sh FIT=eqs) */
} rd_track_counters;

typedef struct {
    int hit;          /* 1 = real collision */
    double t;         /* distance along the ray */
    const rd_medium *medium;
    double weight;    /* path weight factor: 1 for analog trackers; weighted delta and
                         decomposition tracking (seed 002 Alg. 2-3) return their weight here,
                         for a collision and for an escape alike */
} rd_collision;

/* ---- Majorant structures ------------------------------------------------------------------ */
typedef enum { RD_MAJ_AUTO, RD_MAJ_NONE, RD_MAJ_GRID, RD_MAJ_OCTREE } rd_maj_kind;
typedef enum { RD_BOUND_CONSTANT, RD_BOUND_TRILINEAR } rd_bound_kind;

/* What the scene asks for (media[i].majorant). resolution 0 = chosen by the cost model. */
typedef struct {
    rd_maj_kind kind;
    int resolution;      /* grid cells along the longest axis (others in proportion); 0 = auto */
    rd_bound_kind bound;
    int fail_limit;      /* octree: levels that may fail the split test before stopping (§5.2) */
    int max_level;       /* finest level considered (2^level cells per axis); 0 = default */
    double rewind_cost;  /* t_rewind / t_iter of seed 000 eq. 15 for the grid choice; 0 = 1
                            (then eq. 15 is eq. 14, the iteration count) */
} rd_majorant_opts;

/* Conservative bounds of the density over an axis-aligned world box [lo, hi]:
 * *dmin <= density(x) <= *dmax for every x in the box. */
typedef void (*rd_box_bound_fn)(const void *ctx, vec3 lo, vec3 hi, double *dmin, double *dmax);

typedef struct {
    int child;           /* index of the first of 8 children (x fastest), -1 for a leaf */
    float dmax, dmin;    /* density bounds over the node */
} rd_octnode;

/* Opaque to the trackers except through the iterator; fields are open for tests and info. */
typedef struct rd_majorant {
    rd_maj_kind kind;     /* NONE, GRID or OCTREE (never AUTO once built) */
    rd_bound_kind bound;
    vec3 bmin, bmax;
    double sigma_t_scale;
    double dmin_root, dmax_root;   /* bounds over the whole box */
    /* grid */
    int n[3];
    vec3 cell, inv_cell;
    float *dmax, *dmin;  /* per cell, x fastest; owned */
    float *tri;          /* RD_BOUND_TRILINEAR: 8 corner values per cell (corner index x+2y+4z) */
    /* octree */
    rd_octnode *nodes;
    int n_nodes, n_leaves, depth;
    int fail_limit;
    /* seed 000 cost model (eq. 14): expected iterations per random ray */
    double N_chosen, N_nopart;
    double N_level[10];  /* eq. 14 for a uniform 2^l grid, l = 0..n_levels-1 */
    double T_level[10];  /* eq. 15 / t_iter (rewinds weighted by rewind_cost), same grids */
    double rewind_cost;
    int n_levels;
    double build_seconds;
} rd_majorant;

/* Build from a bound oracle over the box [bmin, bmax]. sigma_global is the majorant of the
 * "none" structure (Woodcock), used by eq. 17. Returns NULL with a message on failure. */
rd_majorant *rd_majorant_build(vec3 bmin, vec3 bmax, double sigma_t_scale, double sigma_global,
                               rd_box_bound_fn fn, const void *ctx, const rd_majorant_opts *o,
                               char *err, size_t errlen);
void rd_majorant_free(rd_majorant *m); /* NULL is safe */

/* Bound oracles of the density kinds (majorant.c). ctx is the rd_medium. */
void rd_medium_box_bound(const void *medium, vec3 lo, vec3 hi, double *dmin, double *dmax);

/* One piece of the walk: on [t0, t1] the majorant is the cubic
 *   sigma_maj(t) = c[0] + c[1] s + c[2] s^2 + c[3] s^3,  s = (t - t0)/(t1 - t0)
 * (only c[0] for a constant bound), and sigma_min a constant minorant. 1/m units. */
typedef struct {
    double t0, t1;
    double c[4];
    double sigma_min;
    int cubic;           /* 1 when c[1..3] are used */
    int cell;            /* grid cell / octree node index, -1 for the global majorant */
} rd_maj_seg;

/* Value-type iterator (pbrt-v4 DDAMajorantIterator) over walk/'s grid DDA or octree walk. */
typedef struct {
    const rd_majorant *m;   /* NULL: one segment with the global majorant */
    ray3 r;
    double t, tmax;         /* the global-majorant segment */
    double sigma_global, sigma_global_min;
    int done;
    union {
        wk_dda grid;        /* RD_MAJ_GRID */
        wk_tree_walk tree;  /* RD_MAJ_OCTREE */
    } walk;
} rd_maj_iter;

/* Walk r over [t0, t1] (already clipped to the medium's box). m == NULL or kind NONE gives one
 * segment with sigma_global (and minorant sigma_min_global). */
void rd_majorant_iter_begin(rd_maj_iter *it, const rd_majorant *m, ray3 r, double t0, double t1,
                            double sigma_global, double sigma_min_global);
int rd_majorant_next(rd_maj_iter *it, rd_maj_seg *seg);

/* Optical depth of the majorant over the segment from normalised s0 to s1 (exact integral of
 * the cubic, seed 003 eq. 11). */
static inline double rd_seg_tau(const rd_maj_seg *g, double s0, double s1)
{
    double L = g->t1 - g->t0;
    if (!g->cubic) return g->c[0] * (s1 - s0) * L;
    double F1 = s1 * (g->c[0] + s1 * (g->c[1] / 2 + s1 * (g->c[2] / 3 + s1 * g->c[3] / 4)));
    double F0 = s0 * (g->c[0] + s0 * (g->c[1] / 2 + s0 * (g->c[2] / 3 + s0 * g->c[3] / 4)));
    return (F1 - F0) * L;
}
static inline double rd_seg_sigma(const rd_maj_seg *g, double s)
{
    return g->c[0] + s * (g->c[1] + s * (g->c[2] + s * g->c[3]));
}
/* Normalised s in [s0, 1] where the majorant optical depth from s0 reaches tau (< the segment's
 * remaining depth): closed form for a constant bound, Illinois regula falsi on the cubic's
 * integral otherwise (seed 003 §3.3.2, SolvePolyInt). */
double rd_seg_solve(const rd_maj_seg *g, double s0, double tau);

/* sigma(s) along a segment from local point E to O of a unit cell whose trilinear corner values
 * are v[8] (index x + 2y + 4z): c[0] + c[1] s + c[2] s^2 + c[3] s^3 (seed 003 PolyCoeff). */
void rd_trilinear_cubic(const double v[8], const double E[3], const double O[3], double c[4]);

/* Seed 000 eq. 14 for an explicit list of boxes with majorants k_j (1/m) and internal planes of
 * total area `plane_area`, in a box of surface S: N = (sum 4 k_j |E_j| + 2 plane_area) / S. */
double rd_cost_eq14(const double *k, const double *vol, int n, double plane_area, double S);

/* Russian roulette for a transmittance estimate T (Arvo and Kirk 1990; pbrt-v4's form): 1
 * while |T| >= 0.05; below, 0 with probability 0.75 and 4 otherwise. Multiplying an estimate
 * by it keeps its expectation and ends most walks whose light would count for little: ratio
 * tracking applies it at every tentative collision, the marchers to a camera ray's T. */
double rd_tr_roulette(double T, pcg32 *rng);

/* ---- The majorant walk (DESIGN.md convention 7; pbrt-v4 SampleT_maj) ---------------------- *
 * The one loop under every unbiased tracker and transmittance estimator (freepath.c): tentative
 * collisions are drawn along the majorant iterator with density mu(t) = b sigma_maj(t) - sigma_c,
 * and each is handed to a callback that decides what it means (accept a real collision, multiply
 * a ratio, weight a path, record a sample). The guided marcher and `explain` walk it too. */
typedef struct {
    double t;               /* distance of the tentative collision along the ray */
    double mu;              /* sampling density there: b sigma_maj(t) - sigma_c [1/m] */
    double sigma_c;         /* control extinction subtracted (residual walks), else 0 [1/m] */
    double tau_c;           /* control optical depth from the walk's start to t (residual
                             * walks), else 0 */
    const rd_maj_seg *seg;  /* the current segment; its c[] already scaled by b, minus sigma_c */
} rd_walk_point;
/* Return 1 to go on walking, 0 to stop. */
typedef int (*rd_walk_fn)(void *user, const rd_walk_point *pt);

/* ---- Trackers and transmittance estimators ------------------------------------------------ */
typedef enum {
    RD_FP_AUTO,          /* = supervoxel */
    RD_FP_WOODCOCK,      /* global majorant (seed 000's WT) */
    RD_FP_SUPERVOXEL,    /* delta tracking over the medium's majorant structure (seed 003 §3) */
    RD_FP_WEIGHTED,      /* weighted delta tracking, majorant b * structure (seed 002 Alg. 2) */
    RD_FP_DECOMPOSITION, /* weighted decomposition tracking, control m * minorant (Alg. 3) */
    RD_FP_RAYMARCH       /* biased fixed-step ray marching (comparison only) */
} rd_fp_kind;

typedef enum {
    RD_TR_AUTO,          /* by the render efficiency measured per density kind (docs/free-path.md):
                            exact for constant media, ratio-global for grids, residual for noise */
    RD_TR_RATIO_GLOBAL,  /* ratio tracking with the global majorant */
    RD_TR_RATIO,         /* ratio tracking over the majorant structure */
    RD_TR_RESIDUAL,      /* residual ratio tracking, control = per-cell minorant */
    RD_TR_EXACT,         /* exact optical depth (trilinear grids: one cubic per fine voxel) */
    RD_TR_RAYMARCH       /* biased fixed-step ray marching */
} rd_tr_kind;

typedef struct {
    rd_fp_kind tracker;
    rd_tr_kind transmittance;
    double b;            /* weighted trackers: majorant = b * structure majorant (b > 0) */
    double m;            /* decomposition: control = m * per-cell minorant (m >= 0) */
    double step;         /* ray marching step in scene units; 0 = box diagonal / 512 */
} rd_fp_params;

void rd_fp_params_default(rd_fp_params *p);
const char *rd_fp_tracker_name(rd_fp_kind k);
const char *rd_tr_name(rd_tr_kind k);

/* A medium as the trackers see it: density callback, scale, majorants. Built per call. */
typedef struct {
    double (*density)(const void *ctx, vec3 x); /* density (not yet scaled) */
    /* optional (NULL: compare with density): thr < density(x) * scale, the same answer as the
     * full evaluation, perhaps from less work (rd_medium_sigma_above) */
    int (*above)(const void *ctx, vec3 x, double scale, double thr);
    const void *ctx;
    double sigma_t_scale;
    double sigma_global;      /* global majorant (1/m), read at track time */
    double sigma_global_min;  /* global minorant (1/m) */
    const rd_majorant *maj;   /* may be NULL */
    const rd_grid *grid;      /* trilinear grid for the exact estimator, or NULL */
    double constant;          /* density when the medium is constant (grid == NULL), or < 0 */
    vec3 bmin, bmax;
    uint64_t *segments;       /* optional: majorant segments (seed 000 "rewinds") visited */
} rd_fp_medium;

rd_fp_medium rd_fp_view(const rd_medium *m);

typedef struct {
    int hit;
    double t;
    double weight;   /* path weight factor (1 for analog trackers) */
} rd_fp_event;

/* Free-path sampling over [t0, t1] of one medium. */
rd_fp_event rd_fp_sample(const rd_fp_params *p, const rd_fp_medium *fm, ray3 r, double t0,
                         double t1, pcg32 *rng, rd_track_counters *c);
/* Walk r over [t0, t1] of one medium (maj = NULL: the global majorant), calling fn at each
 * tentative collision in order; sigma_c = the segment's minorant when `residual`, else 0.
 * Returns 1 when the walk reached t1, 0 when fn stopped it. *tau_c (may be NULL) gets the
 * optical depth of the control over the part walked. */
int rd_fp_walk(const rd_fp_medium *fm, const rd_majorant *maj, ray3 r, double t0, double t1,
               double b, int residual, pcg32 *rng, rd_track_counters *c, rd_walk_fn fn,
               void *user, double *tau_c);

/* Transmittance estimate over [t0, t1] of one medium. */
double rd_fp_transmittance(const rd_fp_params *p, const rd_fp_medium *fm, ray3 r, double t0,
                           double t1, pcg32 *rng, rd_track_counters *c);
/* Exact optical depth of a trilinear grid along r over [t0, t1] (one cubic per fine voxel;
 * THEORY.md §2). Counts one lookup per fine voxel crossed. */
double rd_grid_optical_depth(const rd_grid *g, ray3 r, double t0, double t1,
                             rd_track_counters *c);

#endif /* RD_FREEPATH_H */
