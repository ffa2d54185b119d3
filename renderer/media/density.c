/* density.c: density fields of the media (constant, voxel grid, procedural noise), ray-box
 * clipping, and the raw volume reader. */
#include "media/rd_medium.h"
#include "walk.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int rd_box_intersect(vec3 bmin, vec3 bmax, ray3 r, double tmin, double tmax, double *t0,
                     double *t1)
{
    /* Slab test (Kay and Kajiya 1986), walk/'s one clip: an axis-parallel ray outside a slab
     * misses, non-finite input misses, and the result agrees to the bit with the grid walks. */
    const double lo[3] = {bmin.x, bmin.y, bmin.z}, hi[3] = {bmax.x, bmax.y, bmax.z};
    const double o[3] = {r.o.x, r.o.y, r.o.z}, d[3] = {r.d.x, r.d.y, r.d.z};
    return wk_box_clip(lo, hi, o, d, tmin, tmax, t0, t1, NULL);
}

/* ---- Voxel grid ---------------------------------------------------------------------------- */

void rd_grid_free(rd_grid *g)
{
    free(g->data);
    g->data = NULL;
    if (g->bricks) {
        free(g->bricks->brick);
        free(g->bricks->cmin);
        free(g->bricks->cmax);
        free(g->bricks->voxels);
        free(g->bricks);
        g->bricks = NULL;
    }
}

size_t rd_grid_bytes(const rd_grid *g)
{
    if (g->data) return (size_t)g->nx * g->ny * g->nz * sizeof(float);
    if (!g->bricks) return 0;
    const rd_bricks *b = g->bricks;
    size_t cells = (size_t)b->nb[0] * b->nb[1] * b->nb[2];
    return sizeof *b + cells * (sizeof *b->brick + 2 * sizeof(float)) +
           b->n_bricks * RD_BRICK * RD_BRICK * RD_BRICK * sizeof(float);
}

/* The 8 voxels at the corners of the interpolation cell (i..i+1, j..j+1, k..k+1), index
 * x + 2y + 4z. A sparse grid's cell usually lies inside one brick (or one constant cell): then
 * the table is read once; otherwise, and for dense grids, voxel by voxel. */
static inline void cell_corners(const rd_grid *g, int i, int j, int k, double v[8])
{
    const rd_bricks *b = g->bricks;
    if (!g->data && i >= 0 && j >= 0 && k >= 0 && i + 1 < g->nx && j + 1 < g->ny && k + 1 < g->nz) {
        const int m = RD_BRICK - 1;
        int x = i + b->off[0], y = j + b->off[1], z = k + b->off[2];
        if ((x & m) != m && (y & m) != m && (z & m) != m) {
            size_t cell = ((size_t)(z >> RD_BRICK_LOG2) * b->nb[1] + (y >> RD_BRICK_LOG2)) * b->nb[0] +
                          (x >> RD_BRICK_LOG2);
            int32_t q = b->brick[cell];
            if (q < 0) {
                for (int c = 0; c < 8; c++) v[c] = b->cmax[cell];
                return;
            }
            const float *p = b->voxels + ((size_t)q << (3 * RD_BRICK_LOG2)) +
                             (((z & m) << RD_BRICK_LOG2 | (y & m)) << RD_BRICK_LOG2 | (x & m));
            for (int c = 0; c < 8; c++)
                v[c] = p[(c & 1) + ((c >> 1) & 1) * RD_BRICK + ((c >> 2) & 1) * RD_BRICK * RD_BRICK];
            return;
        }
    }
    for (int c = 0; c < 8; c++) v[c] = rd_grid_voxel(g, i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
}

double rd_grid_lookup(const rd_grid *g, vec3 x)
{
    /* u = A x + b; trilinear interpolation between voxel centres at integer + 0.5. */
    double u[3];
    for (int a = 0; a < 3; a++)
        u[a] = g->w2g[a][0] * x.x + g->w2g[a][1] * x.y + g->w2g[a][2] * x.z + g->w2g[a][3] - 0.5;
    if (u[0] < -1.0 || u[1] < -1.0 || u[2] < -1.0 || u[0] > g->nx || u[1] > g->ny || u[2] > g->nz)
        return 0.0;
    double fi = floor(u[0]), fj = floor(u[1]), fk = floor(u[2]);
    int i = (int)fi, j = (int)fj, k = (int)fk;
    double fx = u[0] - fi, fy = u[1] - fj, fz = u[2] - fk, v[8];
    cell_corners(g, i, j, k, v);
    double c00 = v[0] * (1 - fx) + v[1] * fx;
    double c10 = v[2] * (1 - fx) + v[3] * fx;
    double c01 = v[4] * (1 - fx) + v[5] * fx;
    double c11 = v[6] * (1 - fx) + v[7] * fx;
    double c0 = c00 * (1 - fy) + c10 * fy, c1 = c01 * (1 - fy) + c11 * fy;
    return c0 * (1 - fz) + c1 * fz;
}

/* Raw volume: nx*ny*nz little-endian float32, x fastest, no header (docs/scene-format.md). */
rd_status rd_raw_load(const char *path, int nx, int ny, int nz, rd_grid *g, char *err,
                      size_t errlen)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errlen, "%s: %s", path, strerror(errno));
        return RD_ERR_IO;
    }
    size_t n = (size_t)nx * ny * nz;
    if (fseek(f, 0, SEEK_END) != 0) {
        fclose(f);
        snprintf(err, errlen, "%s: cannot seek", path);
        return RD_ERR_IO;
    }
    long size = ftell(f);
    rewind(f);
    if (size < 0 || (size_t)size != n * sizeof(float)) {
        fclose(f);
        snprintf(err, errlen, "%s: size %ld bytes, expected %zu (%dx%dx%d float32)", path, size,
                 n * sizeof(float), nx, ny, nz);
        return RD_ERR_FORMAT;
    }
    float *data = malloc(n * sizeof(float));
    if (!data) {
        fclose(f);
        snprintf(err, errlen, "%s: out of memory for %zu voxels", path, n);
        return RD_ERR_NOMEM;
    }
    size_t got = fread(data, sizeof(float), n, f);
    fclose(f);
    if (got != n) {
        free(data);
        snprintf(err, errlen, "%s: short read", path);
        return RD_ERR_IO;
    }
    double vmin = INFINITY, vmax = -INFINITY;
    for (size_t q = 0; q < n; q++) {
        if (!isfinite(data[q]) || data[q] < 0.0f) {
            snprintf(err, errlen, "%s: voxel %zu: %s density %g", path, q,
                     isfinite(data[q]) ? "negative" : "non-finite", (double)data[q]);
            free(data);
            return RD_ERR_FORMAT;
        }
        if (data[q] < vmin) vmin = data[q];
        if (data[q] > vmax) vmax = data[q];
    }
    g->nx = nx;
    g->ny = ny;
    g->nz = nz;
    g->data = data;
    g->bricks = NULL;
    g->vmin = vmin;
    g->vmax = vmax;
    return RD_OK;
}

/* ---- Procedural noise ---------------------------------------------------------------------- */

void rd_noise_init_perm(rd_noise *n)
{
    /* Fisher-Yates shuffle of 0..255 driven by the noise seed; duplicated to 512 entries. */
    uint8_t p[256];
    for (int i = 0; i < 256; i++) p[i] = (uint8_t)i;
    pcg32 rng = pcg32_seed(0x9e11, 0, n->seed);
    for (int i = 255; i > 0; i--) {
        int j = (int)(pcg32_next(&rng) % (uint32_t)(i + 1));
        uint8_t t = p[i]; p[i] = p[j]; p[j] = t;
    }
    for (int i = 0; i < 512; i++) n->perm[i] = p[i & 255];
}

static inline double lerp(double t, double a, double b) { return a + t * (b - a); }

double rd_noise_eval(const rd_noise *n, vec3 p)
{
    double fx = floor(p.x), fy = floor(p.y), fz = floor(p.z);
    int X = (int)((long long)fx & 255), Y = (int)((long long)fy & 255), Z = (int)((long long)fz & 255);
    double x = p.x - fx, y = p.y - fy, z = p.z - fz;
    double u = rd_perlin_fade(x), v = rd_perlin_fade(y), w = rd_perlin_fade(z);
    const uint8_t *P = n->perm;
    int A = P[X] + Y, AA = P[A] + Z, AB = P[A + 1] + Z;
    int B = P[X + 1] + Y, BA = P[B] + Z, BB = P[B + 1] + Z;
    return lerp(w,
                lerp(v, lerp(u, rd_perlin_grad(P[AA], x, y, z), rd_perlin_grad(P[BA], x - 1, y, z)),
                     lerp(u, rd_perlin_grad(P[AB], x, y - 1, z), rd_perlin_grad(P[BB], x - 1, y - 1, z))),
                lerp(v, lerp(u, rd_perlin_grad(P[AA + 1], x, y, z - 1), rd_perlin_grad(P[BA + 1], x - 1, y, z - 1)),
                     lerp(u, rd_perlin_grad(P[AB + 1], x, y - 1, z - 1), rd_perlin_grad(P[BB + 1], x - 1, y - 1, z - 1))));
}

/* One octave of the fBm sum in the order rd_noise_fbm adds them: sum += amp noise(f q), then
 * the next amplitude and frequency. rd_medium_sigma_above repeats the same steps, so its final
 * sum is rd_noise_fbm's to the bit. */
static inline void fbm_step(const rd_noise *n, vec3 q, double *sum, double *amp, double *f)
{
    *sum += *amp * rd_noise_eval(n, v3_scale(q, *f));
    *amp *= n->gain;
    *f *= n->lacunarity;
}

double rd_noise_fbm(const rd_noise *n, vec3 x)
{
    double sum = 0.0, amp = 1.0, f = n->frequency;
    vec3 q = v3_sub(x, n->center);
    for (int o = 0; o < n->octaves; o++) fbm_step(n, q, &sum, &amp, &f);
    return sum;
}

/* Upper bound of |noise| for improved Perlin noise with any gradient table. At a point with
 * fractional coordinates f the noise is a convex combination (the fade weights w_c) of corner
 * terms g_c.(f - c), where g_c has two non-zero components of magnitude 1, so
 *   |noise(f)| <= E(f) = sum_c w_c(f) (largest two of |f - c|).
 * E depends on f only; its maximum over the unit cube, found by a 61^3 grid search refined by a
 * local random search, is 1.03635 at f = (0.355, 0.481, 0.5) and its mirror images. We use 1.04
 * (tests/test_volume.c checks E on random points and the noise against the bound). The
 * constant RD_PERLIN_BOUND lives in rd_medium.h. */

double rd_noise_fbm_bound(const rd_noise *n)
{
    double sum = 0.0, amp = 1.0;
    for (int o = 0; o < n->octaves; o++) {
        sum += RD_PERLIN_BOUND * amp;
        amp *= n->gain;
    }
    return sum;
}

static double shape_eval(const rd_noise *n, vec3 x)
{
    if (n->shape == RD_SHAPE_NONE) return 1.0;
    vec3 q = v3_sub(x, n->center);
    double r = sqrt((q.x * q.x) / (n->radii.x * n->radii.x) + (q.y * q.y) / (n->radii.y * n->radii.y) +
                    (q.z * q.z) / (n->radii.z * n->radii.z));
    return rd_shape_of_r(n->edge, r);
}

static inline int outside_bounds(const rd_medium *m, vec3 x)
{
    return x.x < m->bmin.x || x.y < m->bmin.y || x.z < m->bmin.z || x.x > m->bmax.x ||
           x.y > m->bmax.y || x.z > m->bmax.z;
}

/* The noise density from the shape value s > 0 and an fBm value (seed 003 §4.2, rd_medium.h). */
static inline double noise_density(const rd_noise *n, double s, double fbm)
{
    double d = 1.0 + n->amplitude * fbm;
    return d > 0.0 ? s * d : 0.0;
}

double rd_medium_density(const rd_medium *m, vec3 x)
{
    if (outside_bounds(m, x)) return 0.0;
    switch (m->kind) {
    case RD_DENSITY_CONSTANT: return m->constant;
    case RD_DENSITY_GRID: return rd_grid_lookup(&m->grid, x);
    case RD_DENSITY_NOISE: {
        double s = shape_eval(&m->noise, x);
        if (s <= 0.0) return 0.0;
        return noise_density(&m->noise, s, rd_noise_fbm(&m->noise, x));
    }
    }
    return 0.0;
}

/* Octave by octave with an early exit: after octave o the octaves not yet added sum to at most
 * R_o = sum_{o' > o} |amp_o'| RD_PERLIN_BOUND in magnitude (the bound rd_noise_fbm_bound uses,
 * derived above), so the final fBm lies in [sum - R_o, sum + R_o], and, the density being
 * monotone in the fBm (non-decreasing for amplitude >= 0, and rounding is monotone), sigma lies
 * between the densities of those two ends times scale. When thr is below the low end or not
 * below the high end, the answer is known; otherwise the next octave is added. R_o is widened
 * by 1e-9 of the whole bound, many orders above the rounding of the partial sums (about 16
 * ulps of the bound), so the early answer is always the full evaluation's. The final
 * comparison uses the same sum, in the same order, as rd_medium_density. */
static int noise_sigma_above(const rd_medium *m, vec3 x, double scale, double thr)
{
    const rd_noise *n = &m->noise;
    double s = shape_eval(n, x);
    if (s <= 0.0) return thr < 0.0 * scale;
    double rest = 0.0, a = 1.0;
    for (int o = 0; o < n->octaves; o++) {
        rest += fabs(a) * RD_PERLIN_BOUND;
        a *= n->gain;
    }
    const double slack = 1e-9 * rest;
    double sum = 0.0, amp = 1.0, f = n->frequency;
    vec3 q = v3_sub(x, n->center);
    for (int o = 0; o + 1 < n->octaves; o++) {
        rest -= fabs(amp) * RD_PERLIN_BOUND; /* the octaves after o */
        fbm_step(n, q, &sum, &amp, &f);
        double r = (rest > 0.0 ? rest : 0.0) + slack;
        double d0 = noise_density(n, s, sum - r) * scale, d1 = noise_density(n, s, sum + r) * scale;
        if (thr < (d0 < d1 ? d0 : d1)) return 1;   /* (no NaN here: noise_density gives 0 for one) */
        if (!(thr < (d0 < d1 ? d1 : d0))) return 0;
    }
    if (n->octaves > 0) fbm_step(n, q, &sum, &amp, &f);
    return thr < noise_density(n, s, sum) * scale;
}

int rd_medium_sigma_above(const rd_medium *m, vec3 x, double scale, double thr)
{
    if (m->kind == RD_DENSITY_NOISE && !outside_bounds(m, x)) return noise_sigma_above(m, x, scale, thr);
    return thr < rd_medium_density(m, x) * scale;
}
