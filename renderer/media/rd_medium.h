/* rd_medium.h: a participating medium by itself: its density field (constant, a voxel grid,
 * dense or in bricks, or procedural noise), its coefficients, and the loaders of its voxel files.
 * It knows nothing of scenes, lights or surfaces. Internal to renderer/ (tests include it).
 *
 * Units: lengths in scene units (metres); extinction sigma_t in 1/m. */
#ifndef RD_MEDIUM_H
#define RD_MEDIUM_H

#include "core/rd_math.h"
#include "renderer.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

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

/* Improved Perlin noise pieces (Perlin 2002), shared by the density (density.c) and its bounds
 * (majorant.c) so that the two can never drift apart. */
#define RD_PERLIN_BOUND 1.04 /* |noise| <= 1.04 for any gradient table: density.c derives it */
/* The quintic fade 6t^5 - 15t^4 + 10t^3. */
static inline double rd_perlin_fade(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }
/* The gradients of improved Perlin noise (Perlin 2002, its grad(): u = h < 8 ? x : y,
 * v = h < 4 ? y : (h == 12 || h == 14 ? x : z), result (h & 1 ? -u : u) + (h & 2 ? -v : v)):
 * the 12 cube-edge directions, 4 of them twice, as a table indexed by h & 15. */
static inline const double *rd_perlin_grad_row(int h)
{
    static const double G[16][3] = {
        {1, 1, 0}, {-1, 1, 0}, {1, -1, 0}, {-1, -1, 0},  /* h 0-3:  +-x +-y */
        {1, 0, 1}, {-1, 0, 1}, {1, 0, -1}, {-1, 0, -1},  /* h 4-7:  +-x +-z */
        {0, 1, 1}, {0, -1, 1}, {0, 1, -1}, {0, -1, -1},  /* h 8-11: +-y +-z */
        {1, 1, 0}, {0, -1, 1}, {-1, 1, 0}, {0, -1, -1}}; /* h 12-15: y+x, -y+z, y-x, -y-z */
    return G[h & 15];
}
/* The gradient of corner hash h as a vector. */
static inline void rd_perlin_grad_vec(int h, double g[3])
{
    const double *r = rd_perlin_grad_row(h);
    g[0] = r[0];
    g[1] = r[1];
    g[2] = r[2];
}
/* The same gradient dotted with (x, y, z), for the hot path. A table and two multiply-adds
 * instead of Perlin's branches on h, which the hash makes unpredictable (5x faster measured,
 * docs/benchmarks.md). The products are exact (factors +-1 and 0), so the sum equals Perlin's
 * u + v as a real number: the same double, except possibly the sign of an exact zero, which no
 * density sees (tests/test_volume.c checks it against Perlin's formula). */
static inline double rd_perlin_grad(int h, double x, double y, double z)
{
    const double *g = rd_perlin_grad_row(h);
    return g[0] * x + g[1] * y + g[2] * z;
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
/* Whether thr < rd_medium_density(m, x) * scale, with the same answer as evaluating that in
 * full, but for noise adding octaves only until their bound decides it (a tracker's accept test,
 * u sigma_maj < sigma_t(x), usually needs fewer than all octaves). */
int rd_medium_sigma_above(const rd_medium *m, vec3 x, double scale, double thr);
static inline double rd_medium_sigma_t(const rd_medium *m, vec3 x)
{
    return rd_medium_density(m, x) * m->sigma_t_scale;
}
/* Ray-box slab test; on a hit writes the overlap [t0, t1] clipped to [tmin, tmax]. */
int rd_box_intersect(vec3 bmin, vec3 bmax, ray3 r, double tmin, double tmax, double *t0,
                     double *t1);

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
#endif /* RD_MEDIUM_H */
