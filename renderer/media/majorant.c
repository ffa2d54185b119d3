/* majorant.c: majorant structures of the free-path engine (THEORY.md §2).
 *
 *  - Bound oracles: conservative [min, max] of the density over a box, for constant media, for
 *    trilinear voxel grids (every voxel whose interpolation support touches the box; a sparse
 *    grid answers from its bricks' own min and max) and for
 *    procedural fBm noise (seed 003 §4.2, eq. 15: each octave is bounded on the box from the
 *    noise definition, never by sampling a fine grid).
 *  - Super-voxel grid (seed 003 §3.1-3.3) with piecewise-constant or tri-linear upper bounds;
 *    its resolution, and whether to partition at all, chosen by the seed 000 cost model
 *    (eq. 14, uniform-grid form eq. 16 against no partition eq. 17).
 *  - Octree (seed 000 §5.2): split a node when eq. 18 < eq. 19 (here eq. 14 restricted to the
 *    node, which is eq. 18/19 for cubes and also holds for boxes), keep splitting through up to
 *    `fail_limit` failed tests, then merge bottom-up every parent whose children are all leaves
 *    created under a failed test.
 *  - The value-type iterator rd_majorant_next over walk/ (the 3D-DDA of Amanatides and Woo 1987
 *    for the grid; neighbour finding by descent from the root with plane snapping for the
 *    octree). */
#include "media/rd_freepath.h"
#include "walk.h"

#include <float.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- bound oracles ------------------------------------------------------------------------- */

/* Stored bounds are floats: round the max up and the min down (relative 1e-6, far above float
 * rounding and trilinear-interpolation rounding), so the stored values stay conservative. */
static float up_f(double v) { return v <= 0.0 ? 0.0f : (float)(v * (1.0 + 1e-6) + 1e-30); }
static float down_f(double v) { return v <= 0.0 ? 0.0f : (float)(v * (1.0 - 1e-6)); }

/* Min and max of the voxels i0..i1 (inclusive, inside the grid) of a sparse grid, from its
 * brick map (rd_medium.h rd_bricks): a constant table cell (tile or background) by its value,
 * a brick the range covers whole by its stored min and max, a brick the range cuts voxel by
 * voxel. The result equals the dense scan's, but empty space costs one read per 8^3 cell. */
static void bricks_range_bound(const rd_grid *g, const int i0[3], const int i1[3], float *mn, float *mx)
{
    const rd_bricks *b = g->bricks;
    const int n[3] = {g->nx, g->ny, g->nz};
    int c0[3], c1[3];
    for (int a = 0; a < 3; a++) {
        c0[a] = (i0[a] + b->off[a]) >> RD_BRICK_LOG2;
        c1[a] = (i1[a] + b->off[a]) >> RD_BRICK_LOG2;
    }
    for (int ck = c0[2]; ck <= c1[2]; ck++)
        for (int cj = c0[1]; cj <= c1[1]; cj++)
            for (int ci = c0[0]; ci <= c1[0]; ci++) {
                const int c[3] = {ci, cj, ck};
                size_t cell = ((size_t)ck * b->nb[1] + cj) * b->nb[0] + ci;
                int lo[3], hi[3], whole = 1;
                for (int a = 0; a < 3; a++) {
                    int first = c[a] * RD_BRICK - b->off[a]; /* the cell's voxels, clipped to the grid */
                    int cfirst = first > 0 ? first : 0, clast = first + RD_BRICK - 1 < n[a] ? first + RD_BRICK - 1 : n[a] - 1;
                    lo[a] = i0[a] > cfirst ? i0[a] : cfirst;
                    hi[a] = i1[a] < clast ? i1[a] : clast;
                    whole &= lo[a] == cfirst && hi[a] == clast;
                }
                if (whole || b->brick[cell] < 0) {
                    *mx = b->cmax[cell] > *mx ? b->cmax[cell] : *mx;
                    *mn = b->cmin[cell] < *mn ? b->cmin[cell] : *mn;
                    continue;
                }
                for (int k = lo[2]; k <= hi[2]; k++)
                    for (int j = lo[1]; j <= hi[1]; j++)
                        for (int i = lo[0]; i <= hi[0]; i++) {
                            float v = (float)rd_grid_voxel(g, i, j, k);
                            *mx = v > *mx ? v : *mx;
                            *mn = v < *mn ? v : *mn;
                        }
            }
}

static void grid_box_bound(const rd_grid *g, vec3 lo, vec3 hi, double *dmin, double *dmax)
{
    /* Image of the world box in grid coordinates (affine map: extremes at the corners, taken
     * per term), then v = u - 0.5: trilinear interpolation at v reads voxels floor(v) and
     * floor(v) + 1, so the box touches voxels floor(vlo) .. floor(vhi) + 1. */
    int i0[3], i1[3], border = 0;
    const int n[3] = {g->nx, g->ny, g->nz};
    for (int a = 0; a < 3; a++) {
        double ulo = g->w2g[a][3], uhi = g->w2g[a][3];
        for (int b = 0; b < 3; b++) {
            double p = g->w2g[a][b] * v3_get(lo, b), q = g->w2g[a][b] * v3_get(hi, b);
            ulo += fmin(p, q);
            uhi += fmax(p, q);
        }
        double vlo = ulo - 0.5, vhi = uhi - 0.5;
        double f0 = floor(vlo), f1 = floor(vhi) + 1.0;
        if (f0 < 0 || f1 > n[a] - 1) border = 1;
        f0 = fmax(0.0, fmin(f0, n[a] - 1.0));
        f1 = fmax(0.0, fmin(f1, n[a] - 1.0));
        i0[a] = (int)f0;
        i1[a] = (int)f1;
    }
    float mx = 0.0f, mn = INFINITY;
    if (g->data) {
        for (int k = i0[2]; k <= i1[2]; k++)
            for (int j = i0[1]; j <= i1[1]; j++) {
                const float *row = g->data + ((size_t)k * g->ny + j) * g->nx;
                for (int i = i0[0]; i <= i1[0]; i++) {
                    float v = row[i];
                    mx = v > mx ? v : mx;
                    mn = v < mn ? v : mn;
                }
            }
    } else {
        bricks_range_bound(g, i0, i1, &mn, &mx);
    }
    *dmax = mx;
    *dmin = border ? 0.0 : mn;
}

/* Bounds of one octave of Perlin noise over the lattice-coordinate box [qlo, qhi]. Inside a
 * lattice cell the noise is a convex combination (products of fade weights in [0, 1]) of the 8
 * corner terms g_c . (f - c), each linear in f: so it lies between the smallest and largest of
 * those linear terms over the box (seed 003 §4.2: gradient noise is bounded between the lattice
 * points by the signed distances of the corner planes). Boxes spanning more than 8 lattice cells
 * use the global bound (the scales "above k" of eq. 15); with 2 or more whole lattice cells per
 * axis the box bound is close to it anyway. */
static void octave_bound(const rd_noise *nz, vec3 qlo, vec3 qhi, double *nmin, double *nmax)
{
    double c0[3], c1[3];
    long long cells = 1;
    for (int a = 0; a < 3; a++) {
        c0[a] = floor(v3_get(qlo, a));
        c1[a] = floor(v3_get(qhi, a));
        cells *= (long long)(c1[a] - c0[a] + 1);
    }
    if (cells > 8) { *nmin = -RD_PERLIN_BOUND; *nmax = RD_PERLIN_BOUND; return; }
    double mx = -INFINITY, mn = INFINITY;
    const uint8_t *P = nz->perm;
    for (double Z = c0[2]; Z <= c1[2]; Z++)
        for (double Y = c0[1]; Y <= c1[1]; Y++)
            for (double X = c0[0]; X <= c1[0]; X++) {
                double cell[3] = {X, Y, Z}, flo[3], fhi[3];
                for (int a = 0; a < 3; a++) {
                    flo[a] = fmax(0.0, v3_get(qlo, a) - cell[a]);
                    fhi[a] = fmin(1.0, v3_get(qhi, a) - cell[a]);
                }
                int xi = (int)((long long)X & 255), yi = (int)((long long)Y & 255), zi = (int)((long long)Z & 255);
                double tmx[8], tmn[8];
                for (int c = 0; c < 8; c++) {
                    int cx = c & 1, cy = (c >> 1) & 1, cz = (c >> 2) & 1;
                    int h = P[P[P[xi + cx] + yi + cy] + zi + cz];
                    double g[3], tmax = 0.0, tmin = 0.0;
                    rd_perlin_grad_vec(h, g);
                    const double cc[3] = {cx, cy, cz};
                    for (int a = 0; a < 3; a++) {
                        double p = g[a] * (flo[a] - cc[a]), q = g[a] * (fhi[a] - cc[a]);
                        tmax += fmax(p, q);
                        tmin += fmin(p, q);
                    }
                    tmx[c] = tmax;
                    tmn[c] = tmin;
                }
                /* The weights are products of fade(f_a) (monotone on [0, 1]), so over the box
                 * they range over [fade(flo), fade(fhi)] per axis; with the terms replaced by
                 * their bounds the interpolation is multilinear in the fade values, extreme at
                 * a corner of that range. Tight for boxes much smaller than a lattice cell. */
                double W0[3], W1[3];
                for (int a = 0; a < 3; a++) { W0[a] = rd_perlin_fade(flo[a]); W1[a] = rd_perlin_fade(fhi[a]); }
                for (int q = 0; q < 8; q++) {
                    double u = (q & 1) ? W1[0] : W0[0], v = (q & 2) ? W1[1] : W0[1], w = (q & 4) ? W1[2] : W0[2];
                    double hi = 0.0, lo = 0.0;
                    for (int c = 0; c < 8; c++) {
                        double wc = ((c & 1) ? u : 1 - u) * ((c & 2) ? v : 1 - v) * ((c & 4) ? w : 1 - w);
                        hi += wc * tmx[c];
                        lo += wc * tmn[c];
                    }
                    mx = fmax(mx, hi);
                    mn = fmin(mn, lo);
                }
            }
    *nmax = fmin(mx, RD_PERLIN_BOUND);
    *nmin = fmax(mn, -RD_PERLIN_BOUND);
}

static void noise_box_bound(const rd_noise *nz, vec3 lo, vec3 hi, double *dmin, double *dmax)
{
    double smin = 1.0, smax = 1.0;
    if (nz->shape == RD_SHAPE_ELLIPSOID) {
        /* Nearest and farthest points of the box in the normalised ellipsoid metric. */
        double rn = 0.0, rf = 0.0;
        for (int a = 0; a < 3; a++) {
            double c = v3_get(nz->center, a), R = v3_get(nz->radii, a);
            double l = (v3_get(lo, a) - c) / R, h = (v3_get(hi, a) - c) / R;
            double near = (l > 0) ? l : (h < 0 ? -h : 0.0);
            double far = fmax(fabs(l), fabs(h));
            rn += near * near;
            rf += far * far;
        }
        smax = rd_shape_of_r(nz->edge, sqrt(rn));
        smin = rd_shape_of_r(nz->edge, sqrt(rf));
    }
    if (smax <= 0.0) { *dmin = *dmax = 0.0; return; }
    /* fBm = sum_o gain^o noise(f_o (x - c)): bound every octave on the box (eq. 15). */
    double fmx = 0.0, fmn = 0.0, amp = 1.0, f = nz->frequency;
    vec3 qlo = v3_sub(lo, nz->center), qhi = v3_sub(hi, nz->center);
    for (int o = 0; o < nz->octaves; o++) {
        double a, b;
        octave_bound(nz, v3_scale(qlo, f), v3_scale(qhi, f), &a, &b);
        fmn += amp * a;
        fmx += amp * b;
        amp *= nz->gain;
        f *= nz->lacunarity;
    }
    *dmax = smax * fmax(0.0, 1.0 + nz->amplitude * fmx);
    *dmin = smin * fmax(0.0, 1.0 + nz->amplitude * fmn);
}

void rd_medium_box_bound(const void *medium, vec3 lo, vec3 hi, double *dmin, double *dmax)
{
    const rd_medium *m = medium;
    switch (m->kind) {
    case RD_DENSITY_CONSTANT: *dmin = *dmax = m->constant; return;
    case RD_DENSITY_GRID: grid_box_bound(&m->grid, lo, hi, dmin, dmax); return;
    case RD_DENSITY_NOISE: noise_box_bound(&m->noise, lo, hi, dmin, dmax); return;
    }
    *dmin = 0.0;
    *dmax = m->density_max;
}

/* ---- cost model (seed 000 eq. 14) ---------------------------------------------------------- */

double rd_cost_eq14(const double *k, const double *vol, int n, double plane_area, double S)
{
    double sum = 0.0;
    for (int j = 0; j < n; j++) sum += 4.0 * k[j] * vol[j];
    return (sum + 2.0 * plane_area) / S;
}

static double box_surface(vec3 e) { return 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x); }

/* ---- grid -------------------------------------------------------------------------------------- */

typedef struct {
    rd_box_bound_fn fn;
    const void *ctx;
    vec3 bmin, bmax, ext;
    double scale, S;
} build_ctx;

static vec3 cell_lo(const build_ctx *b, const int n[3], int i, int j, int k)
{
    return v3(b->bmin.x + b->ext.x * i / n[0], b->bmin.y + b->ext.y * j / n[1],
              b->bmin.z + b->ext.z * k / n[2]);
}
static vec3 cell_hi(const build_ctx *b, const int n[3], int i, int j, int k)
{
    /* The last cell ends exactly at bmax. */
    return v3(i + 1 == n[0] ? b->bmax.x : b->bmin.x + b->ext.x * (i + 1) / n[0],
              j + 1 == n[1] ? b->bmax.y : b->bmin.y + b->ext.y * (j + 1) / n[1],
              k + 1 == n[2] ? b->bmax.z : b->bmin.z + b->ext.z * (k + 1) / n[2]);
}

/* Cells per axis for `res` cells along the longest axis (others in proportion). */
static void grid_dims(vec3 ext, int res, int n[3])
{
    double emax = fmax(ext.x, fmax(ext.y, ext.z));
    for (int a = 0; a < 3; a++) {
        int v = (int)lround(res * v3_get(ext, a) / emax);
        n[a] = v < 1 ? 1 : v;
    }
}

/* Bounds of every cell of an n grid; eq. 14 for that grid. Returns 0 on out-of-memory.
 * The cells are bounded in parallel, but eq. 14's first sum is taken afterwards over the
 * per-cell terms in cell order: a floating-point sum in thread-schedule order (an OpenMP
 * reduction) would change its last bits with the thread count, and a near-tie between two
 * levels would then choose a different structure (and image) on another machine. */
static int grid_bounds(const build_ctx *b, const int n[3], float **pmax, float **pmin, double *N,
                       double *T, double rewind)
{
    size_t nc = (size_t)n[0] * n[1] * n[2];
    float *mx = malloc(nc * sizeof *mx), *mn = malloc(nc * sizeof *mn);
    double *term = malloc(nc * sizeof *term);
    if (!mx || !mn || !term) { free(mx); free(mn); free(term); return 0; }
#pragma omp parallel for schedule(dynamic, 1) if (nc > 4096)
    for (int k = 0; k < n[2]; k++)
        for (int j = 0; j < n[1]; j++)
            for (int i = 0; i < n[0]; i++) {
                double lo, hi;
                vec3 a = cell_lo(b, n, i, j, k), c = cell_hi(b, n, i, j, k);
                b->fn(b->ctx, a, c, &lo, &hi);
                size_t q = ((size_t)k * n[1] + j) * n[0] + i;
                mx[q] = up_f(hi);
                mn[q] = down_f(lo);
                vec3 e = v3_sub(c, a);
                term[q] = 4.0 * mx[q] * b->scale * e.x * e.y * e.z; /* eq. 14, first sum's term */
            }
    double sum = 0.0;
    for (size_t q = 0; q < nc; q++) sum += term[q]; /* fixed order: same bits on any thread count */
    free(term);
    /* Internal planes: (n_x - 1) planes of area ext_y ext_z, and so on (eq. 14, second sum). */
    double planes = (n[0] - 1) * b->ext.y * b->ext.z + (n[1] - 1) * b->ext.x * b->ext.z +
                    (n[2] - 1) * b->ext.x * b->ext.y;
    *N = (sum + 2.0 * planes) / b->S;
    *T = (sum + rewind * 2.0 * planes) / b->S; /* eq. 15 divided by t_iter */
    *pmax = mx;
    *pmin = mn;
    return 1;
}

/* Tri-linear upper bound per cell (seed 003 §3.3.2 and §4.1): fit the 8 corner values to the
 * constant bounds of the 4^3 sub-cells at the corners, then lift the whole function by the
 * largest deficit found at the corners of all sub-cells. A trilinear function attains its
 * minimum over a sub-box at one of the box's corners, so after the lift it is >= the sub-cell's
 * bound over every sub-cell, hence >= the density everywhere in the cell. */
static int grid_trilinear(const build_ctx *b, rd_majorant *m)
{
    enum { S = 4 };
    size_t nc = (size_t)m->n[0] * m->n[1] * m->n[2];
    m->tri = malloc(nc * 8 * sizeof *m->tri);
    if (!m->tri) return 0;
#pragma omp parallel for schedule(dynamic, 1) if (nc > 512)
    for (int k = 0; k < m->n[2]; k++)
        for (int j = 0; j < m->n[1]; j++)
            for (int i = 0; i < m->n[0]; i++) {
                vec3 lo = cell_lo(b, m->n, i, j, k), hi = cell_hi(b, m->n, i, j, k);
                vec3 e = v3_scale(v3_sub(hi, lo), 1.0 / S);
                double U[S][S][S];
                for (int z = 0; z < S; z++)
                    for (int y = 0; y < S; y++)
                        for (int x = 0; x < S; x++) {
                            vec3 a = v3(lo.x + e.x * x, lo.y + e.y * y, lo.z + e.z * z);
                            vec3 c = v3(x + 1 == S ? hi.x : a.x + e.x, y + 1 == S ? hi.y : a.y + e.y,
                                        z + 1 == S ? hi.z : a.z + e.z);
                            double dl, dh;
                            b->fn(b->ctx, a, c, &dl, &dh);
                            U[z][y][x] = dh;
                        }
                double cv[8];
                for (int c = 0; c < 8; c++)
                    cv[c] = U[(c >> 2) & 1 ? S - 1 : 0][(c >> 1) & 1 ? S - 1 : 0][c & 1 ? S - 1 : 0];
                double lift = 0.0;
                for (int z = 0; z < S; z++)
                    for (int y = 0; y < S; y++)
                        for (int x = 0; x < S; x++)
                            for (int c = 0; c < 8; c++) {
                                double X = (double)(x + (c & 1)) / S, Y = (double)(y + ((c >> 1) & 1)) / S,
                                       Z = (double)(z + ((c >> 2) & 1)) / S;
                                double g = 0.0;
                                for (int q = 0; q < 8; q++)
                                    g += cv[q] * ((q & 1) ? X : 1 - X) * ((q >> 1) & 1 ? Y : 1 - Y) *
                                         ((q >> 2) & 1 ? Z : 1 - Z);
                                lift = fmax(lift, U[z][y][x] - g);
                            }
                size_t cell = ((size_t)k * m->n[1] + j) * m->n[0] + i;
                double cmax = m->dmax[cell], mean = 0.0;
                for (int c = 0; c < 8; c++) mean += 0.125 * (cv[c] + lift);
                /* The integral of a trilinear function over the cell is the mean of its corners:
                 * keep the tri-linear bound only where it integrates below the constant one. */
                for (int c = 0; c < 8; c++)
                    m->tri[8 * cell + c] = mean < cmax ? up_f(cv[c] + lift) : (float)cmax;
            }
    return 1;
}

/* ---- octree ---------------------------------------------------------------------------------- */

typedef struct {
    rd_octnode *v;
    unsigned char *failed; /* node was split although eq. 18 >= eq. 19 */
    int n, cap;
} node_vec;

static int node_push(node_vec *nv, int count)
{
    if (nv->n + count > nv->cap) {
        int cap = nv->cap ? nv->cap * 2 : 256;
        while (cap < nv->n + count) cap *= 2;
        rd_octnode *v = realloc(nv->v, (size_t)cap * sizeof *v);
        if (!v) return -1;
        nv->v = v;
        unsigned char *f = realloc(nv->failed, (size_t)cap);
        if (!f) return -1;
        nv->failed = f;
        nv->cap = cap;
    }
    int first = nv->n;
    nv->n += count;
    return first;
}

static vec3 child_lo(vec3 lo, vec3 mid, int c)
{
    return v3(c & 1 ? mid.x : lo.x, c & 2 ? mid.y : lo.y, c & 4 ? mid.z : lo.z);
}
static vec3 child_hi(vec3 hi, vec3 mid, int c)
{
    return v3(c & 1 ? hi.x : mid.x, c & 2 ? hi.y : mid.y, c & 4 ? hi.z : mid.z);
}

/* Top-down split of node `idx` (box lo-hi, level l, fail count f); seed 000 §5.2. */
static int oct_split(const build_ctx *b, node_vec *nv, int idx, vec3 lo, vec3 hi, int l, int f,
                     int max_level, int fail_limit)
{
    nv->v[idx].child = -1;
    nv->failed[idx] = 0;
    if (l >= max_level) return 1;
    vec3 mid = v3_scale(v3_add(lo, hi), 0.5), e = v3_sub(hi, lo);
    double cmax[8], cmin[8], vol = e.x * e.y * e.z / 8.0;
    double part = 0.0;
    for (int c = 0; c < 8; c++) {
        b->fn(b->ctx, child_lo(lo, mid, c), child_hi(hi, mid, c), &cmin[c], &cmax[c]);
        part += 4.0 * up_f(cmax[c]) * b->scale * vol;
    }
    /* Eq. 18 and 19 (times 4^l S / common factors): the 3 splitting planes have the areas of the
     * node's faces. */
    part += 2.0 * (e.y * e.z + e.x * e.z + e.x * e.y);
    double nopart = 4.0 * nv->v[idx].dmax * b->scale * e.x * e.y * e.z;
    int fail = !(part < nopart);
    if (fail && f >= fail_limit) return 1;
    int first = node_push(nv, 8);
    if (first < 0) return 0;
    nv->v[idx].child = first;
    nv->failed[idx] = (unsigned char)fail;
    for (int c = 0; c < 8; c++) {
        nv->v[first + c].dmax = up_f(cmax[c]);
        nv->v[first + c].dmin = down_f(cmin[c]);
    }
    for (int c = 0; c < 8; c++)
        if (!oct_split(b, nv, first + c, child_lo(lo, mid, c), child_hi(hi, mid, c), l + 1,
                       f + fail, max_level, fail_limit))
            return 0;
    return 1;
}

/* Bottom-up merge: a parent split under a failed test whose children are all leaves becomes a
 * leaf (seed 000 §5.2, Figure 3). Recursive, so merges propagate upward. */
static void oct_merge(node_vec *nv, int idx)
{
    int c0 = nv->v[idx].child;
    if (c0 < 0) return;
    int all_leaves = 1;
    for (int c = 0; c < 8; c++) {
        oct_merge(nv, c0 + c);
        if (nv->v[c0 + c].child >= 0) all_leaves = 0;
    }
    if (all_leaves && nv->failed[idx]) nv->v[idx].child = -1;
}

/* Compact the reachable nodes (merged subtrees are dropped); eq. 14 over the leaves. */
static int oct_compact(const node_vec *nv, int idx, rd_octnode *out, int *n, int slot, vec3 lo,
                       vec3 hi, const build_ctx *b, double *sum, double *planes, int l, int *depth,
                       int *leaves)
{
    out[slot] = nv->v[idx];
    vec3 e = v3_sub(hi, lo);
    if (l > *depth) *depth = l;
    if (nv->v[idx].child < 0) {
        out[slot].child = -1;
        *sum += 4.0 * out[slot].dmax * b->scale * e.x * e.y * e.z;
        (*leaves)++;
        return 1;
    }
    *planes += e.y * e.z + e.x * e.z + e.x * e.y;
    int first = *n;
    *n += 8;
    out[slot].child = first;
    vec3 mid = v3_scale(v3_add(lo, hi), 0.5);
    for (int c = 0; c < 8; c++)
        oct_compact(nv, nv->v[idx].child + c, out, n, first + c, child_lo(lo, mid, c),
                    child_hi(hi, mid, c), b, sum, planes, l + 1, depth, leaves);
    return 1;
}

/* ---- build ------------------------------------------------------------------------------------ */

void rd_majorant_free(rd_majorant *m)
{
    if (!m) return;
    free(m->dmax);
    free(m->dmin);
    free(m->tri);
    free(m->nodes);
    free(m);
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

rd_majorant *rd_majorant_build(vec3 bmin, vec3 bmax, double sigma_t_scale, double sigma_global,
                               rd_box_bound_fn fn, const void *ctx, const rd_majorant_opts *o,
                               char *err, size_t errlen)
{
    double t_start = now_s();
    rd_majorant *m = calloc(1, sizeof *m);
    if (!m) goto oom;
    build_ctx b = {fn, ctx, bmin, bmax, v3_sub(bmax, bmin), sigma_t_scale, 0.0};
    b.S = box_surface(b.ext);
    m->bmin = bmin;
    m->bmax = bmax;
    m->sigma_t_scale = sigma_t_scale;
    m->bound = o->bound;
    m->fail_limit = o->fail_limit;
    fn(ctx, bmin, bmax, &m->dmin_root, &m->dmax_root);
    /* Eq. 14 with a single cell and no planes (eq. 17 for a cube): Woodcock's expected count. */
    m->N_nopart = 4.0 * sigma_global * b.ext.x * b.ext.y * b.ext.z / b.S;
    m->N_chosen = m->N_nopart;
    m->kind = RD_MAJ_NONE;
    int max_level = o->max_level > 0 ? o->max_level : 6;
    double rw = o->rewind_cost > 0 ? o->rewind_cost : 1.0;
    m->rewind_cost = rw;
    if (max_level > 9) max_level = 9;
    if (o->kind == RD_MAJ_NONE) goto done;

    if (o->kind == RD_MAJ_OCTREE) {
        node_vec nv = {0};
        if (node_push(&nv, 1) < 0) { free(nv.v); free(nv.failed); goto oom; }
        nv.v[0].dmax = up_f(m->dmax_root);
        nv.v[0].dmin = down_f(m->dmin_root);
        if (!oct_split(&b, &nv, 0, bmin, bmax, 0, 0, max_level, o->fail_limit)) {
            free(nv.v);
            free(nv.failed);
            goto oom;
        }
        oct_merge(&nv, 0);
        m->nodes = malloc((size_t)nv.n * sizeof *m->nodes);
        if (!m->nodes) { free(nv.v); free(nv.failed); goto oom; }
        double sum = 0.0, planes = 0.0;
        int n = 1;
        oct_compact(&nv, 0, m->nodes, &n, 0, bmin, bmax, &b, &sum, &planes, 0, &m->depth,
                    &m->n_leaves);
        m->n_nodes = n;
        free(nv.v);
        free(nv.failed);
        m->N_chosen = (sum + 2.0 * planes) / b.S; /* eq. 14 over the leaves */
        m->kind = RD_MAJ_OCTREE;
        goto done;
    }

    if (o->kind == RD_MAJ_GRID && o->resolution > 0) {
        grid_dims(b.ext, o->resolution, m->n);
        double Tn;
        if (!grid_bounds(&b, m->n, &m->dmax, &m->dmin, &m->N_chosen, &Tn, rw)) goto oom;
    } else {
        /* Seed 000 §5.1: eq. 14 (eq. 16 for a cube) for m = 2^l, l = 1..max_level; the best m is
         * used only if it beats no partition (eq. 17). The choice minimises the time form eq. 15
         * (t_rewind / t_iter = rewind_cost; 1 gives eq. 14 exactly, as in the paper). */
        double best = INFINITY;
        int best_l = 0;
        m->N_level[0] = m->T_level[0] = m->N_nopart;
        m->n_levels = max_level + 1;
        for (int l = 1; l <= max_level; l++) {
            int n[3];
            float *mx, *mn;
            grid_dims(b.ext, 1 << l, n);
            if (!grid_bounds(&b, n, &mx, &mn, &m->N_level[l], &m->T_level[l], rw)) goto oom;
            if (m->T_level[l] < best) {
                best = m->T_level[l];
                best_l = l;
                free(m->dmax);
                free(m->dmin);
                m->dmax = mx; /* keep the best level's bounds */
                m->dmin = mn;
            } else {
                free(mx);
                free(mn);
            }
        }
        if (o->kind == RD_MAJ_AUTO && !(best < m->N_nopart)) { /* do not partition */
            free(m->dmax);
            free(m->dmin);
            m->dmax = m->dmin = NULL;
            goto done;
        }
        grid_dims(b.ext, 1 << best_l, m->n);
        m->N_chosen = m->N_level[best_l];
    }
    m->cell = v3(b.ext.x / m->n[0], b.ext.y / m->n[1], b.ext.z / m->n[2]);
    m->inv_cell = v3(1.0 / m->cell.x, 1.0 / m->cell.y, 1.0 / m->cell.z);
    m->kind = RD_MAJ_GRID;
    if (o->bound == RD_BOUND_TRILINEAR && !grid_trilinear(&b, m)) goto oom;
done:
    if (m->kind != RD_MAJ_GRID) m->bound = RD_BOUND_CONSTANT;
    m->build_seconds = now_s() - t_start;
    return m;
oom:
    rd_majorant_free(m);
    if (err && errlen) snprintf(err, errlen, "out of memory building the majorant structure");
    return NULL;
}

/* ---- iterator --------------------------------------------------------------------------------- */

/* The octree's locate callback for walk/ (wk_locate_fn): descend from the root to the leaf
 * holding p; a coordinate on a splitting plane goes to the side the ray heads to (d > 0: the
 * upper half). Children are numbered with bit a = upper half of axis a. Returns the node. */
static long oct_locate(const void *tree, const double p[3], const double d[3], double lo[3],
                       double hi[3])
{
    const rd_majorant *m = tree;
    for (int a = 0; a < 3; a++) {
        lo[a] = v3_get(m->bmin, a);
        hi[a] = v3_get(m->bmax, a);
    }
    int node = 0;
    while (m->nodes[node].child >= 0) {
        int c = 0;
        for (int a = 0; a < 3; a++) {
            double mid = 0.5 * (lo[a] + hi[a]);
            int right = p[a] > mid || (p[a] == mid && d[a] > 0);
            if (right) { c |= 1 << a; lo[a] = mid; } else hi[a] = mid;
        }
        node = m->nodes[node].child + c;
    }
    return node;
}

/* The axis through whose face the ray enters the box exactly at t0, or -1 (t0 inside the box, or
 * not the entry parameter wk_box_clip computes). Lets the walks take the first cell from the
 * direction instead of a rounded point lookup, as the guide's iterator does. */
static int entry_axis(const rd_majorant *m, const double o[3], const double d[3], double t0,
                      double t1)
{
    const double lo[3] = {m->bmin.x, m->bmin.y, m->bmin.z}, hi[3] = {m->bmax.x, m->bmax.y, m->bmax.z};
    double c0, c1;
    int axis;
    if (!wk_box_clip(lo, hi, o, d, t0, t1, &c0, &c1, &axis) || c0 != t0) return -1;
    return axis;
}

void rd_majorant_iter_begin(rd_maj_iter *it, const rd_majorant *m, ray3 r, double t0, double t1,
                            double sigma_global, double sigma_min_global)
{
    /* Set in place, field by field: the iterator is large (the walk's state), and building it
     * on the stack to return by value copied all of it on every free flight and shadow ray.
     * The walk's state is set by its begin, when there is a walk. */
    it->m = (m && m->kind != RD_MAJ_NONE) ? m : NULL;
    it->r = r;
    it->t = t0;
    it->tmax = t1;
    it->sigma_global = sigma_global;
    it->sigma_global_min = sigma_min_global;
    it->done = !(t0 < t1);
    if (!it->m || it->done) return;
    const double lo[3] = {m->bmin.x, m->bmin.y, m->bmin.z}, hi[3] = {m->bmax.x, m->bmax.y, m->bmax.z};
    const double o[3] = {r.o.x, r.o.y, r.o.z}, d[3] = {r.d.x, r.d.y, r.d.z};
    int enter = entry_axis(m, o, d, t0, t1);
    if (m->kind == RD_MAJ_GRID) /* 3D-DDA (Amanatides and Woo 1987) over the super-voxels */
        wk_dda_begin(&it->walk.grid, lo, hi, m->n, o, d, t0, t1, enter);
    else /* octree: neighbour finding by descent from the root (walk/) */
        wk_tree_begin(&it->walk.tree, oct_locate, m, lo, hi, o, d, t0, t1, enter, m->depth);
}

/* Coefficients of the trilinear function with corner values v[8] (index x + 2y + 4z) along the
 * segment from local point E to O: a cubic in s (seed 003 PolyCoeff, by polynomial products). */
void rd_trilinear_cubic(const double v[8], const double E[3], const double O[3], double c[4])
{
    c[0] = c[1] = c[2] = c[3] = 0.0;
    for (int q = 0; q < 8; q++) {
        if (v[q] == 0.0) continue;
        /* product over axes of (X or 1 - X), X(s) = E + s (O - E) */
        double p[4] = {v[q], 0, 0, 0};
        for (int a = 0; a < 3; a++) {
            double a0 = E[a], a1 = O[a] - E[a];
            if (!((q >> a) & 1)) { a0 = 1.0 - a0; a1 = -a1; }
            double n3 = p[3] * a0 + p[2] * a1, n2 = p[2] * a0 + p[1] * a1, n1 = p[1] * a0 + p[0] * a1,
                   n0 = p[0] * a0;
            p[0] = n0; p[1] = n1; p[2] = n2; p[3] = n3;
        }
        for (int d = 0; d < 4; d++) c[d] += p[d];
    }
}

static double clamp01(double x) { return x < 0 ? 0 : (x > 1 ? 1 : x); }

/* The global majorant over the whole interval (no structure, Woodcock). */
static int next_global(rd_maj_iter *it, rd_maj_seg *seg)
{
    seg->t0 = it->t;
    seg->t1 = it->tmax;
    seg->c[0] = it->sigma_global;
    seg->c[1] = seg->c[2] = seg->c[3] = 0.0;
    seg->cubic = 0;
    seg->sigma_min = it->sigma_global_min;
    seg->cell = -1;
    it->done = 1;
    return 1;
}

/* The majorant of super-voxel s.cell on [s.ta, s.tb): the constant bound, or the tri-linear
 * bound as a cubic along the segment (seed 003 §3.3.2). */
static void grid_seg(const rd_majorant *m, ray3 r, const wk_dda_seg *s, rd_maj_seg *seg)
{
    double sc = m->sigma_t_scale;
    size_t cell = (size_t)s->cell;
    seg->t0 = s->ta;
    seg->t1 = s->tb;
    seg->cell = (int)cell;
    seg->sigma_min = m->dmin[cell] * sc;
    if (m->bound == RD_BOUND_TRILINEAR) {
        double E[3], O[3];
        vec3 pe = ray_at(r, seg->t0), po = ray_at(r, seg->t1);
        for (int a = 0; a < 3; a++) {
            double lo = wk_plane(v3_get(m->bmin, a), v3_get(m->bmax, a), v3_get(m->cell, a),
                                 m->n[a], s->ijk[a]);
            E[a] = clamp01((v3_get(pe, a) - lo) * v3_get(m->inv_cell, a));
            O[a] = clamp01((v3_get(po, a) - lo) * v3_get(m->inv_cell, a));
        }
        double v[8];
        for (int q = 0; q < 8; q++) v[q] = m->tri[8 * cell + q];
        rd_trilinear_cubic(v, E, O, seg->c);
        for (int d = 0; d < 4; d++) seg->c[d] *= sc;
        seg->cubic = 1;
    } else {
        seg->c[0] = m->dmax[cell] * sc;
        seg->c[1] = seg->c[2] = seg->c[3] = 0.0;
        seg->cubic = 0;
    }
}

int rd_majorant_next(rd_maj_iter *it, rd_maj_seg *seg)
{
    if (it->done) return 0;
    const rd_majorant *m = it->m;
    if (!m) return next_global(it, seg);
    if (m->kind == RD_MAJ_GRID) {
        wk_dda_seg s;
        if (!wk_dda_next(&it->walk.grid, &s)) { it->done = 1; return 0; }
        grid_seg(m, it->r, &s, seg);
        return 1;
    }
    wk_tree_seg s;
    if (!wk_tree_next(&it->walk.tree, &s)) { it->done = 1; return 0; }
    const rd_octnode *leaf = &m->nodes[s.leaf];
    seg->t0 = s.ta;
    seg->t1 = s.tb;
    seg->c[0] = leaf->dmax * m->sigma_t_scale;
    seg->c[1] = seg->c[2] = seg->c[3] = 0.0;
    seg->cubic = 0;
    seg->sigma_min = leaf->dmin * m->sigma_t_scale;
    seg->cell = (int)s.leaf;
    return 1;
}

/* Seed 003 §3.3.2 SolvePolyInt by regula falsi, Illinois variant (halve the weight of the end
 * that stays, so convergence is superlinear instead of one-sided). */
double rd_seg_solve(const rd_maj_seg *g, double s0, double tau)
{
    double L = g->t1 - g->t0;
    if (!g->cubic) return s0 + tau / (g->c[0] * L);
    double lo = s0, hi = 1.0, flo = -tau, fhi = rd_seg_tau(g, s0, 1.0) - tau;
    if (fhi <= 0.0) return 1.0;
    int side = 0;
    double s = lo;
    for (int i = 0; i < 200 && hi - lo > 1e-14; i++) {
        s = (lo * fhi - hi * flo) / (fhi - flo);
        if (!(s > lo && s < hi)) s = 0.5 * (lo + hi);
        double f = rd_seg_tau(g, s0, s) - tau;
        if (f == 0.0) return s;
        if (f < 0.0) {
            lo = s; flo = f;
            if (side == -1) fhi *= 0.5;
            side = -1;
        } else {
            hi = s; fhi = f;
            if (side == 1) flo *= 0.5;
            side = 1;
        }
    }
    return s;
}
