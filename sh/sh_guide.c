/* sh_guide.c: the guide grids of SH coefficients of in-scattered radiance (THEORY.md §5; seed
 * 001 §3.1, §3.2, §3.4): the uniform grid and the adaptive octree, their k-NN and track-length
 * bakes from a photon map, the ray iterator over both, point lookups, slice images and the
 * guide file. All of it lives in this one translation unit so that the guide's layout stays
 * private (sh.h is the module's only header). */
#include <float.h>
#include <limits.h>
#include <math.h>
#include <omp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sh.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define SH_MAX_DEPTH 20
#define SH_MAX_RES (1 << 20)

/* Octree node: child >= 0 is the index of the first of 2^popcount(mask) contiguous children,
 * child < 0 marks a leaf with cell id -(child + 1). mask bit a = axis a is halved. Children
 * are ordered by the bits of the split axes in axis order (lowest split axis = bit 0). */
typedef struct {
    int32_t child;
    uint32_t mask;
} sh_node;

struct sh_guide {
    sh_grid_kind kind;
    sh_bake_method method;
    int bands, ncoef; /* ncoef = 3 L^2 floats per cell */
    double lo[3], hi[3];
    /* uniform */
    int res[3];
    double h[3];
    /* adaptive */
    sh_node *nodes;
    size_t nnodes;
    double *leaf_lo, *leaf_hi; /* 3 per leaf */
    uint8_t *leaf_depth;
    int depth_max;
    /* cells */
    size_t ncells;
    float *coeffs;  /* ncells * ncoef */
    float *sigma_t; /* ncells */
    /* provenance */
    double bake_seconds;
    size_t photons;
    int k;
    double lambda;
    sh_basis basis;
};

static void set_err(char *err, size_t errlen, const char *fmt, ...)
{
    if (!err || errlen == 0)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

void sh_guide_free(sh_guide *g)
{
    if (!g)
        return;
    free(g->nodes);
    free(g->leaf_lo);
    free(g->leaf_hi);
    free(g->leaf_depth);
    free(g->coeffs);
    free(g->sigma_t);
    free(g);
}

/* ---- Geometry helpers ---------------------------------------------------------------------- */

/* Plane i of axis a of the uniform grid; planes 0 and n are the box faces exactly, so the DDA
 * and the box clip agree to the bit. */
static inline double uplane(const sh_guide *g, int a, int i)
{
    if (i <= 0)
        return g->lo[a];
    if (i >= g->res[a])
        return g->hi[a];
    return g->lo[a] + g->h[a] * i;
}

/* Index of the uniform cell holding coordinate p on axis a: half-open [plane_i, plane_i+1),
 * clamped to the grid; decided by comparison with the planes themselves. */
static inline int ucell(const sh_guide *g, int a, double p)
{
    int n = g->res[a];
    double f = (p - g->lo[a]) / g->h[a];
    int i = f < 0.0 ? 0 : f >= n ? n - 1 : (int)f;
    if (i > 0 && p < uplane(g, a, i))
        i--;
    else if (i < n - 1 && p >= uplane(g, a, i + 1))
        i++;
    return i;
}

static inline int popcount3(uint32_t m)
{
    return (int)((m & 1u) + ((m >> 1) & 1u) + ((m >> 2) & 1u));
}

/* The split rule's axis choice: halve every axis whose edge exceeds half the longest edge, so
 * cells stay within aspect ratio 2 (docs/guide-grid.md, "split rule"). */
static uint32_t split_mask(const double lo[3], const double hi[3])
{
    double e[3], emax = 0.0;
    for (int a = 0; a < 3; a++) {
        e[a] = hi[a] - lo[a];
        emax = fmax(emax, e[a]);
    }
    uint32_t m = 0;
    for (int a = 0; a < 3; a++)
        if (e[a] > 0.5 * emax)
            m |= 1u << a;
    return m;
}

/* Child offset and bounds for point p moving along d: upper half if p > mid, or p == mid and
 * d >= 0 (so a point on a plane belongs to the cell the ray is about to enter; d = 0 gives
 * half-open cells [lo, hi)). Updates blo/bhi to the child's box. */
static inline int child_of(uint32_t mask, const double p[3], const double d[3], double blo[3],
                           double bhi[3])
{
    int off = 0, bit = 0;
    for (int a = 0; a < 3; a++) {
        if (!(mask & (1u << a)))
            continue;
        double mid = 0.5 * (blo[a] + bhi[a]);
        int up = p[a] > mid || (p[a] == mid && d[a] >= 0.0);
        if (up) {
            off |= 1 << bit;
            blo[a] = mid;
        } else {
            bhi[a] = mid;
        }
        bit++;
    }
    return off;
}

/* Descend from the root to the leaf holding p (direction-aware ties). */
static long descend(const sh_guide *g, const double p[3], const double d[3], double blo[3],
                    double bhi[3])
{
    for (int a = 0; a < 3; a++)
        blo[a] = g->lo[a], bhi[a] = g->hi[a];
    size_t n = 0;
    while (g->nodes[n].child >= 0) {
        int off = child_of(g->nodes[n].mask, p, d, blo, bhi);
        n = (size_t)g->nodes[n].child + (size_t)off;
    }
    return -(long)g->nodes[n].child - 1;
}

static void cell_bounds(const sh_guide *g, size_t cell, double lo[3], double hi[3])
{
    if (g->kind == SH_GRID_UNIFORM) {
        size_t nx = (size_t)g->res[0], ny = (size_t)g->res[1];
        int ijk[3] = {(int)(cell % nx), (int)((cell / nx) % ny), (int)(cell / (nx * ny))};
        for (int a = 0; a < 3; a++) {
            lo[a] = uplane(g, a, ijk[a]);
            hi[a] = uplane(g, a, ijk[a] + 1);
        }
    } else {
        for (int a = 0; a < 3; a++) {
            lo[a] = g->leaf_lo[3 * cell + a];
            hi[a] = g->leaf_hi[3 * cell + a];
        }
    }
}

/* ---- Read access ---------------------------------------------------------------------------- */

int sh_guide_bands(const sh_guide *g) { return g ? g->bands : 0; }
sh_grid_kind sh_guide_kind(const sh_guide *g) { return g ? g->kind : SH_GRID_UNIFORM; }
size_t sh_guide_cell_count(const sh_guide *g) { return g ? g->ncells : 0; }
const sh_basis *sh_guide_basis(const sh_guide *g) { return g ? &g->basis : NULL; }

void sh_guide_box(const sh_guide *g, double lo[3], double hi[3])
{
    for (int a = 0; a < 3; a++)
        lo[a] = g->lo[a], hi[a] = g->hi[a];
}

const float *sh_guide_cell_coeffs(const sh_guide *g, size_t cell)
{
    if (!g || cell >= g->ncells)
        return NULL;
    return g->coeffs + cell * (size_t)g->ncoef;
}

float sh_guide_cell_sigma_t(const sh_guide *g, size_t cell)
{
    if (!g || cell >= g->ncells)
        return 0.0f;
    return g->sigma_t[cell];
}

void sh_guide_cell_bounds(const sh_guide *g, size_t cell, double lo[3], double hi[3])
{
    if (!g || cell >= g->ncells) {
        for (int a = 0; a < 3; a++)
            lo[a] = hi[a] = 0.0;
        return;
    }
    cell_bounds(g, cell, lo, hi);
}

int sh_guide_cell_depth(const sh_guide *g, size_t cell)
{
    if (!g || g->kind != SH_GRID_ADAPTIVE || cell >= g->ncells)
        return 0;
    return g->leaf_depth[cell];
}

long sh_guide_locate(const sh_guide *g, const double x[3])
{
    if (!g)
        return -1;
    for (int a = 0; a < 3; a++)
        if (!(x[a] >= g->lo[a] && x[a] <= g->hi[a]))
            return -1;
    if (g->kind == SH_GRID_UNIFORM) {
        long i = ucell(g, 0, x[0]), j = ucell(g, 1, x[1]), k = ucell(g, 2, x[2]);
        return i + (long)g->res[0] * (j + (long)g->res[1] * k);
    }
    const double zero[3] = {0.0, 0.0, 0.0};
    double blo[3], bhi[3];
    return descend(g, x, zero, blo, bhi);
}

void sh_guide_eval(const sh_guide *g, const double x[3], const double w[3], float out[3])
{
    out[0] = out[1] = out[2] = 0.0f;
    long c = sh_guide_locate(g, x);
    if (c < 0)
        return;
    float y[SH_MAX_COEFFS];
    sh_basis_evalf(&g->basis, w, y);
    sh_eval_rgb(g->bands, g->coeffs + (size_t)c * (size_t)g->ncoef, y, out);
}

void sh_guide_stats_get(const sh_guide *g, sh_guide_stats *st)
{
    memset(st, 0, sizeof *st);
    if (!g)
        return;
    st->kind = g->kind;
    st->method = g->method;
    st->bands = g->bands;
    st->cells = g->ncells;
    st->nodes = g->nnodes;
    st->bake_seconds = g->bake_seconds;
    st->photons = g->photons;
    st->k = g->k;
    st->lambda = g->lambda;
    st->depth_max = g->kind == SH_GRID_ADAPTIVE ? g->depth_max : 0;
    st->memory_bytes = sizeof *g + g->ncells * (size_t)g->ncoef * sizeof(float) +
                       g->ncells * sizeof(float);
    if (g->kind == SH_GRID_UNIFORM) {
        for (int a = 0; a < 3; a++)
            st->res[a] = g->res[a];
        double e = 0.0;
        for (int a = 0; a < 3; a++)
            e = fmax(e, g->h[a]);
        st->cell_min = st->cell_max = e;
    } else {
        st->memory_bytes += g->nnodes * sizeof(sh_node) +
                            g->ncells * (6 * sizeof(double) + sizeof(uint8_t));
        double cmin = INFINITY, cmax = 0.0;
        for (size_t c = 0; c < g->ncells; c++) {
            double e = 0.0;
            for (int a = 0; a < 3; a++)
                e = fmax(e, g->leaf_hi[3 * c + a] - g->leaf_lo[3 * c + a]);
            cmin = fmin(cmin, e), cmax = fmax(cmax, e);
        }
        st->cell_min = g->ncells ? cmin : 0.0;
        st->cell_max = cmax;
        /* The finest level's equivalent resolution: box edge / smallest leaf edge per axis. */
        for (int a = 0; a < 3; a++) {
            double emin = INFINITY;
            for (size_t c = 0; c < g->ncells; c++)
                emin = fmin(emin, g->leaf_hi[3 * c + a] - g->leaf_lo[3 * c + a]);
            st->res[a] = g->ncells ? (int)lround((g->hi[a] - g->lo[a]) / emin) : 0;
        }
    }
}

/* ---- Ray iterator (DESIGN.md convention 7) ---------------------------------------------- */

void sh_guide_ray_begin(const sh_guide *g, const double o[3], const double d[3], double tmin,
                        double tmax, sh_guide_ray *it)
{
    memset(it, 0, sizeof *it);
    it->g = g;
    it->done = 1;
    if (!g || !(tmin <= tmax))
        return;
    /* Clip to the box by slabs. */
    double t0 = tmin, t1 = tmax;
    int enter_axis = -1;
    for (int a = 0; a < 3; a++) {
        it->o[a] = o[a];
        it->d[a] = d[a];
        if (!isfinite(o[a]) || !isfinite(d[a]))
            return;
        if (d[a] == 0.0) {
            it->inv[a] = INFINITY;
            if (o[a] < g->lo[a] || o[a] > g->hi[a])
                return;
            continue;
        }
        it->inv[a] = 1.0 / d[a];
        double ta = (g->lo[a] - o[a]) / d[a], tb = (g->hi[a] - o[a]) / d[a];
        if (ta > tb) {
            double s = ta;
            ta = tb, tb = s;
        }
        if (ta > t0)
            t0 = ta, enter_axis = a;
        if (tb < t1)
            t1 = tb;
    }
    if (!(t0 < t1))
        return;
    it->t = t0;
    it->tend = t1;
    it->done = 0;
    if (g->kind == SH_GRID_UNIFORM) {
        for (int a = 0; a < 3; a++) {
            it->step[a] = d[a] > 0.0 ? 1 : d[a] < 0.0 ? -1 : 0;
            if (a == enter_axis)
                it->ijk[a] = d[a] > 0.0 ? 0 : g->res[a] - 1;
            else
                it->ijk[a] = ucell(g, a, o[a] + t0 * d[a]);
        }
    } else if (enter_axis >= 0) {
        /* Entering through a face: snap that coordinate to the face exactly. */
        it->snap_mask = 1 << enter_axis;
        it->snap[enter_axis] = d[enter_axis] > 0.0 ? g->lo[enter_axis] : g->hi[enter_axis];
    }
}

static int ray_next_uniform(sh_guide_ray *it, sh_guide_seg *seg)
{
    const sh_guide *g = it->g;
    while (!it->done) {
        /* 3D-DDA (Amanatides & Woo 1987): the next plane crossing of each axis, recomputed
         * from the plane position (no incremental drift). */
        double tn = INFINITY;
        int axis = -1;
        for (int a = 0; a < 3; a++) {
            if (it->step[a] == 0)
                continue;
            int i = it->ijk[a] + (it->step[a] > 0 ? 1 : 0);
            double ta = (uplane(g, a, i) - it->o[a]) / it->d[a];
            if (ta < tn)
                tn = ta, axis = a;
        }
        double t1 = tn < it->tend ? tn : it->tend;
        if (t1 < it->t)
            t1 = it->t;
        long cell = it->ijk[0] + (long)g->res[0] * (it->ijk[1] + (long)g->res[1] * it->ijk[2]);
        double t0 = it->t;
        if (t1 >= it->tend) {
            it->done = 1;
        } else {
            int ni = it->ijk[axis] + it->step[axis];
            if (ni < 0 || ni >= g->res[axis]) {
                /* Left the grid before tend: only by rounding; the rest is this cell. */
                t1 = it->tend;
                it->done = 1;
            } else {
                it->ijk[axis] = ni;
            }
        }
        it->t = t1;
        if (t1 > t0) {
            seg->t0 = t0;
            seg->t1 = t1;
            seg->cell = cell;
            seg->coeffs = g->coeffs + (size_t)cell * (size_t)g->ncoef;
            seg->sigma_t = g->sigma_t[cell];
            return 1;
        }
    }
    return 0;
}

static int ray_next_adaptive(sh_guide_ray *it, sh_guide_seg *seg)
{
    const sh_guide *g = it->g;
    int zero_steps = 0;
    while (!it->done) {
        /* Neighbour stepping by descent from the root (THEORY.md §5): the point at t, with
         * the coordinates of the planes just crossed snapped exactly, picks the next leaf. */
        double p[3], blo[3], bhi[3];
        for (int a = 0; a < 3; a++)
            p[a] = (it->snap_mask & (1 << a)) ? it->snap[a] : it->o[a] + it->t * it->d[a];
        long cell = descend(g, p, it->d, blo, bhi);
        double t1 = it->tend;
        int exit_mask = 0, at_box = 0;
        double snapv[3] = {0, 0, 0};
        for (int a = 0; a < 3; a++) {
            if (it->d[a] == 0.0)
                continue;
            double plane = it->d[a] > 0.0 ? bhi[a] : blo[a];
            double ta = (plane - it->o[a]) / it->d[a];
            if (ta < t1) {
                t1 = ta;
                exit_mask = 1 << a;
            } else if (ta == t1) {
                exit_mask |= 1 << a;
            }
            snapv[a] = plane;
        }
        for (int a = 0; a < 3; a++)
            if ((exit_mask & (1 << a)) &&
                (it->d[a] > 0.0 ? bhi[a] >= g->hi[a] : blo[a] <= g->lo[a]))
                at_box = 1; /* leaving the box before tend: only by rounding */
        double t0 = it->t;
        if (t1 >= it->tend || at_box || ++zero_steps > 4 * SH_MAX_DEPTH + 16) {
            t1 = it->tend;
            it->done = 1;
        }
        if (t1 < t0)
            t1 = t0;
        if (!it->done) {
            if (t1 > t0)
                it->snap_mask = 0; /* moved on: earlier snaps no longer hold */
            it->snap_mask |= exit_mask;
            for (int a = 0; a < 3; a++)
                if (exit_mask & (1 << a))
                    it->snap[a] = snapv[a];
        }
        it->t = t1;
        if (t1 > t0) {
            seg->t0 = t0;
            seg->t1 = t1;
            seg->cell = cell;
            seg->coeffs = g->coeffs + (size_t)cell * (size_t)g->ncoef;
            seg->sigma_t = g->sigma_t[cell];
            return 1;
        }
    }
    return 0;
}

int sh_guide_ray_next(sh_guide_ray *it, sh_guide_seg *seg)
{
    if (!it || it->done || !it->g)
        return 0;
    return it->g->kind == SH_GRID_UNIFORM ? ray_next_uniform(it, seg) : ray_next_adaptive(it, seg);
}

/* ---- Bake ------------------------------------------------------------------------------------ */

void sh_bake_params_default(sh_bake_params *p)
{
    memset(p, 0, sizeof *p);
    p->kind = SH_GRID_UNIFORM;
    p->method = SH_BAKE_KNN;
    p->bands = 4;
    p->k = 50;
    p->lambda = 1.0;
    p->max_cells = (size_t)1 << 24;
    p->max_depth = 12;
    p->phase_b[0] = 1.0;
    p->sigma_t_samples = 2;
}

/* splitmix64: a fixed hash for the stratified sigma_t jitter (deterministic bake). */
static inline uint64_t mix64(uint64_t x)
{
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}
static inline double u01(uint64_t h) { return (double)(h >> 11) * 0x1.0p-53; }

/* Cell-mean extinction: mean of sigma_t at s^3 jittered strata of the cell. */
static double cell_mean_sigma_t(const sh_bake_params *P, size_t cell, const double lo[3],
                                const double hi[3])
{
    if (!P->sigma_t)
        return 0.0;
    int s = P->sigma_t_samples;
    double sum = 0.0;
    int n = 0;
    for (int k = 0; k < s; k++)
        for (int j = 0; j < s; j++)
            for (int i = 0; i < s; i++, n++) {
                uint64_t h = mix64(((uint64_t)cell << 10) ^ (uint64_t)n);
                int ijk[3] = {i, j, k};
                double x[3];
                for (int a = 0; a < 3; a++) {
                    double u = (ijk[a] + u01(mix64(h + (uint64_t)a))) / s;
                    x[a] = lo[a] + u * (hi[a] - lo[a]);
                }
                sum += P->sigma_t(x, P->sigma_t_user);
            }
    return sum / n;
}

static void cell_phase(const sh_bake_params *P, const double c[3], int bands, double *b)
{
    if (P->phase_at)
        P->phase_at(c, P->phase_user, b);
    else
        for (int l = 0; l < bands; l++)
            b[l] = P->phase_b[l];
}

static int nthreads(const sh_bake_params *P)
{
    return P->threads > 0 ? P->threads : omp_get_max_threads();
}

/* Validate params and fill the guide's box. */
static sh_status check_params(const pm_map *map, const sh_bake_params *P, double lo[3],
                              double hi[3], char *err, size_t errlen)
{
    if (!map || !P) {
        set_err(err, errlen, "sh_guide_bake: map and params must be non-NULL");
        return SH_ERR_ARG;
    }
    if (P->kind != SH_GRID_UNIFORM && P->kind != SH_GRID_ADAPTIVE) {
        set_err(err, errlen, "sh_guide_bake: params.kind = %d: unknown grid kind", (int)P->kind);
        return SH_ERR_ARG;
    }
    if (P->method != SH_BAKE_KNN && P->method != SH_BAKE_TRACK) {
        set_err(err, errlen, "sh_guide_bake: params.method = %d: unknown bake method",
                (int)P->method);
        return SH_ERR_ARG;
    }
    if (P->bands < 1 || P->bands > SH_MAX_BANDS) {
        set_err(err, errlen, "sh_guide_bake: params.bands = %d: must be 1..%d", P->bands,
                SH_MAX_BANDS);
        return SH_ERR_ARG;
    }
    if (P->k < 1) {
        set_err(err, errlen, "sh_guide_bake: params.k = %d: must be >= 1", P->k);
        return SH_ERR_ARG;
    }
    if (!(P->lambda > 0.0) || !isfinite(P->lambda)) {
        set_err(err, errlen, "sh_guide_bake: params.lambda = %g: must be finite and > 0",
                P->lambda);
        return SH_ERR_ARG;
    }
    int nres = 0;
    for (int a = 0; a < 3; a++) {
        if (P->res[a] < 0 || P->res[a] > SH_MAX_RES) {
            set_err(err, errlen, "sh_guide_bake: params.res[%d] = %d: must be 0..%d", a,
                    P->res[a], SH_MAX_RES);
            return SH_ERR_ARG;
        }
        nres += P->res[a] > 0;
    }
    if (nres != 0 && nres != 3) {
        set_err(err, errlen, "sh_guide_bake: params.res: give all three or none");
        return SH_ERR_ARG;
    }
    if (P->max_cells < 1) {
        set_err(err, errlen, "sh_guide_bake: params.max_cells = 0: must be >= 1");
        return SH_ERR_ARG;
    }
    if (P->max_depth < 0 || P->max_depth > SH_MAX_DEPTH) {
        set_err(err, errlen, "sh_guide_bake: params.max_depth = %d: must be 0..%d", P->max_depth,
                SH_MAX_DEPTH);
        return SH_ERR_ARG;
    }
    if (P->split_photons < 0) {
        set_err(err, errlen, "sh_guide_bake: params.split_photons = %d: must be >= 0",
                P->split_photons);
        return SH_ERR_ARG;
    }
    if (!(P->min_cell >= 0.0) || !isfinite(P->min_cell) || !(P->max_cell >= 0.0) ||
        !isfinite(P->max_cell)) {
        set_err(err, errlen, "sh_guide_bake: params.min_cell / max_cell must be finite and >= 0");
        return SH_ERR_ARG;
    }
    if (P->sigma_t_samples < 1 || P->sigma_t_samples > 8) {
        set_err(err, errlen, "sh_guide_bake: params.sigma_t_samples = %d: must be 1..8",
                P->sigma_t_samples);
        return SH_ERR_ARG;
    }
    for (int l = 0; l < P->bands; l++)
        if (!isfinite(P->phase_b[l])) {
            set_err(err, errlen, "sh_guide_bake: params.phase_b[%d] is not finite", l);
            return SH_ERR_ARG;
        }
    int zero = 1;
    for (int a = 0; a < 3; a++) {
        if (!isfinite(P->lo[a]) || !isfinite(P->hi[a])) {
            set_err(err, errlen, "sh_guide_bake: params.lo/hi[%d] is not finite", a);
            return SH_ERR_ARG;
        }
        zero &= P->lo[a] == 0.0 && P->hi[a] == 0.0;
    }
    if (!zero) {
        for (int a = 0; a < 3; a++) {
            if (!(P->lo[a] < P->hi[a])) {
                set_err(err, errlen, "sh_guide_bake: params.lo[%d] = %g >= params.hi[%d] = %g "
                        "(leave both all zero for the photon bounds)", a, P->lo[a], a, P->hi[a]);
                return SH_ERR_ARG;
            }
            lo[a] = P->lo[a], hi[a] = P->hi[a];
        }
        return SH_OK;
    }
    /* Default box: the photons' bounds (segment end points if there are no photons). */
    size_t np = pm_map_photon_count(map), ns = pm_map_segment_count(map);
    if (np > 0) {
        float flo[3], fhi[3];
        pm_map_bounds(map, flo, fhi);
        for (int a = 0; a < 3; a++)
            lo[a] = flo[a], hi[a] = fhi[a];
    } else if (ns > 0) {
        const pm_segment *s = pm_map_segments(map);
        for (int a = 0; a < 3; a++)
            lo[a] = INFINITY, hi[a] = -INFINITY;
        for (size_t i = 0; i < ns; i++)
            for (int a = 0; a < 3; a++) {
                double e = s[i].org[a] + (double)s[i].length * s[i].dir[a];
                lo[a] = fmin(lo[a], fmin(s[i].org[a], e));
                hi[a] = fmax(hi[a], fmax(s[i].org[a], e));
            }
    } else {
        set_err(err, errlen, "sh_guide_bake: no box given (params.lo/hi) and the photon map is "
                             "empty");
        return SH_ERR_ARG;
    }
    double ext = 0.0;
    for (int a = 0; a < 3; a++)
        ext = fmax(ext, hi[a] - lo[a]);
    double pad = fmax(1e-4 * ext, 1e-6);
    for (int a = 0; a < 3; a++)
        lo[a] -= pad, hi[a] += pad;
    return SH_OK;
}

/* Uniform resolution rule (THEORY.md §5; seed 001 §3.1, reconstructed):
 *   n_a = max(1, round(l_a (lambda N / (n l_x l_y l_z))^(1/3))). */
static void uniform_rule(const double lo[3], const double hi[3], double lambda, size_t N, int n,
                         int res[3])
{
    double l[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
    double s = cbrt(lambda * (double)N / ((double)n * l[0] * l[1] * l[2]));
    for (int a = 0; a < 3; a++) {
        double r = round(l[a] * s);
        res[a] = r < 1.0 ? 1 : r > SH_MAX_RES ? SH_MAX_RES : (int)r;
    }
}

/* ---- Adaptive octree build (seed 001 §3.4; docs/guide-grid.md "split rule") -------------- */

typedef struct {
    sh_guide *g;
    const float *pts; /* 3 per point */
    uint32_t *idx, *tmp; /* point ids; scatter buffer */
    uint8_t *off;         /* child offset of each point during a split */
    int split_count, max_depth;
    double min_cell, max_cell;
    size_t max_cells;
    size_t cap_nodes, cap_leaves;
    int failed; /* 1 nomem, 2 too many cells */
} build_ctx;

static int grow_nodes(build_ctx *B, size_t need)
{
    sh_guide *g = B->g;
    if (need <= B->cap_nodes)
        return 1;
    size_t cap = B->cap_nodes ? B->cap_nodes : 64;
    while (cap < need)
        cap *= 2;
    sh_node *n = realloc(g->nodes, cap * sizeof *n);
    if (!n)
        return 0;
    g->nodes = n;
    B->cap_nodes = cap;
    return 1;
}

static int add_leaf(build_ctx *B, size_t node, const double lo[3], const double hi[3], int depth)
{
    sh_guide *g = B->g;
    if (g->ncells >= B->max_cells) {
        B->failed = 2;
        return 0;
    }
    if (g->ncells == B->cap_leaves) {
        size_t cap = B->cap_leaves ? 2 * B->cap_leaves : 64;
        double *l = realloc(g->leaf_lo, 3 * cap * sizeof *l);
        if (l)
            g->leaf_lo = l;
        double *h = realloc(g->leaf_hi, 3 * cap * sizeof *h);
        if (h)
            g->leaf_hi = h;
        uint8_t *d = realloc(g->leaf_depth, cap);
        if (d)
            g->leaf_depth = d;
        if (!l || !h || !d) {
            B->failed = 1;
            return 0;
        }
        B->cap_leaves = cap;
    }
    size_t c = g->ncells++;
    for (int a = 0; a < 3; a++) {
        g->leaf_lo[3 * c + a] = lo[a];
        g->leaf_hi[3 * c + a] = hi[a];
    }
    g->leaf_depth[c] = (uint8_t)depth;
    g->nodes[node].child = -(int32_t)c - 1;
    g->nodes[node].mask = 0;
    if (depth > g->depth_max)
        g->depth_max = depth;
    return 1;
}

/* Split while count > split_count and the longest edge >= 2 min_cell, or while the longest
 * edge > max_cell; never below max_depth. Points [a, b) of idx lie in this node. Children are
 * allocated as one contiguous block and visited in order, so leaves are numbered depth-first. */
static void build_node(build_ctx *B, size_t node, const double lo[3], const double hi[3],
                       int depth, size_t a, size_t b)
{
    if (B->failed)
        return;
    double emax = 0.0;
    for (int ax = 0; ax < 3; ax++)
        emax = fmax(emax, hi[ax] - lo[ax]);
    size_t count = b - a;
    int split = depth < B->max_depth &&
                ((count > (size_t)B->split_count && emax >= 2.0 * B->min_cell) ||
                 emax > B->max_cell);
    if (!split) {
        add_leaf(B, node, lo, hi, depth);
        return;
    }
    uint32_t mask = split_mask(lo, hi);
    int nch = 1 << popcount3(mask);
    size_t first = B->g->nnodes;
    if (first + (size_t)nch > (size_t)INT32_MAX || !grow_nodes(B, first + (size_t)nch)) {
        B->failed = 1;
        return;
    }
    B->g->nnodes += (size_t)nch;
    B->g->nodes[node].child = (int32_t)first;
    B->g->nodes[node].mask = mask;
    /* Counting sort of the node's points into the children (same tie rule as locate). */
    size_t cnt[9] = {0};
    const double zero[3] = {0, 0, 0};
    for (size_t i = a; i < b; i++) {
        const float *q = B->pts + 3 * (size_t)B->idx[i];
        double p[3] = {q[0], q[1], q[2]}, cl[3] = {lo[0], lo[1], lo[2]},
               ch[3] = {hi[0], hi[1], hi[2]};
        int o = child_of(mask, p, zero, cl, ch);
        B->off[i] = (uint8_t)o;
        cnt[o + 1]++;
    }
    for (int c = 0; c < nch; c++)
        cnt[c + 1] += cnt[c];
    size_t start[9];
    memcpy(start, cnt, sizeof start);
    for (size_t i = a; i < b; i++)
        B->tmp[a + cnt[B->off[i]]++] = B->idx[i];
    memcpy(B->idx + a, B->tmp + a, count * sizeof *B->idx);
    for (int c = 0; c < nch; c++) {
        double cl[3] = {lo[0], lo[1], lo[2]}, chh[3] = {hi[0], hi[1], hi[2]};
        int bit = 0;
        for (int ax = 0; ax < 3; ax++) {
            if (!(mask & (1u << ax)))
                continue;
            double mid = 0.5 * (lo[ax] + hi[ax]);
            if (c & (1 << bit))
                cl[ax] = mid;
            else
                chh[ax] = mid;
            bit++;
        }
        build_node(B, first + (size_t)c, cl, chh, depth + 1, a + start[c], a + start[c + 1]);
        if (B->failed)
            return;
    }
}

static sh_status build_octree(sh_guide *g, const pm_map *map, const sh_bake_params *P,
                              char *err, size_t errlen)
{
    /* Points that drive the split: photon positions, or segment midpoints without photons. */
    size_t np = pm_map_photon_count(map), ns = pm_map_segment_count(map);
    size_t n = np > 0 ? np : ns;
    float *pts = malloc((n ? n : 1) * 3 * sizeof *pts);
    uint32_t *idx = malloc((n ? n : 1) * sizeof *idx);
    uint32_t *tmp = malloc((n ? n : 1) * sizeof *tmp);
    uint8_t *off = malloc(n ? n : 1);
    if (!pts || !idx || !tmp || !off || n > UINT32_MAX) {
        free(pts), free(idx), free(tmp), free(off);
        set_err(err, errlen, "sh_guide_bake: out of memory for the octree build (%zu points)", n);
        return SH_ERR_NOMEM;
    }
    size_t m = 0;
    if (np > 0) {
        const pm_photon *ph = pm_map_photons(map);
        for (size_t i = 0; i < np; i++)
            memcpy(pts + 3 * i, ph[i].pos, 3 * sizeof(float));
    } else {
        const pm_segment *s = pm_map_segments(map);
        for (size_t i = 0; i < ns; i++)
            for (int a = 0; a < 3; a++)
                pts[3 * i + a] = s[i].org[a] + 0.5f * s[i].length * s[i].dir[a];
    }
    for (size_t i = 0; i < n; i++) {
        const float *q = pts + 3 * i;
        int in = 1;
        for (int a = 0; a < 3; a++)
            in &= q[a] >= g->lo[a] && q[a] <= g->hi[a];
        if (in)
            idx[m++] = (uint32_t)i;
    }
    double emax = 0.0;
    for (int a = 0; a < 3; a++)
        emax = fmax(emax, g->hi[a] - g->lo[a]);
    build_ctx B;
    memset(&B, 0, sizeof B);
    B.g = g;
    B.pts = pts;
    B.idx = idx;
    B.tmp = tmp;
    B.off = off;
    B.max_depth = P->max_depth;
    B.split_count = P->split_photons > 0 ? P->split_photons : (int)ceil(P->k / P->lambda);
    B.min_cell = P->min_cell > 0.0 ? P->min_cell : emax / ldexp(1.0, P->max_depth);
    B.max_cell = P->max_cell > 0.0 ? P->max_cell : emax / 4.0;
    B.max_cells = P->max_cells;
    g->ncells = 0;
    g->nnodes = 0;
    g->depth_max = 0;
    if (!grow_nodes(&B, 1)) {
        B.failed = 1;
    } else {
        g->nnodes = 1;
        build_node(&B, 0, g->lo, g->hi, 0, 0, m);
    }
    free(pts), free(idx), free(tmp), free(off);
    if (B.failed == 2) {
        set_err(err, errlen, "sh_guide_bake: adaptive grid exceeds params.max_cells = %zu "
                             "(raise split_photons, min_cell or max_cells)", P->max_cells);
        return SH_ERR_NOMEM;
    }
    if (B.failed) {
        set_err(err, errlen, "sh_guide_bake: out of memory building the octree");
        return SH_ERR_NOMEM;
    }
    return SH_OK;
}

/* ---- k-NN bake (seed 001 §3.1-3.2, appendix A; THEORY.md §4-5) ------------------------- */

static sh_status bake_knn(sh_guide *g, const pm_map *map, const sh_bake_params *P, char *err,
                          size_t errlen)
{
    const int L = g->bands, nc = L * L, k = P->k;
    const pm_photon *ph = pm_map_photons(map);
    int failed = 0, nomem = 0;
    long long ncell = (long long)g->ncells;
#pragma omp parallel num_threads(nthreads(P))
    {
        int *idx = malloc((size_t)k * sizeof *idx);
        float *d2 = malloc((size_t)k * sizeof *d2);
        if (!idx || !d2) {
#pragma omp atomic write
            nomem = 1;
        }
#pragma omp for schedule(dynamic, 16)
        for (long long ci = 0; ci < ncell; ci++) {
            if (!idx || !d2)
                continue;
            size_t cell = (size_t)ci;
            double lo[3], hi[3], c[3];
            cell_bounds(g, cell, lo, hi);
            for (int a = 0; a < 3; a++)
                c[a] = 0.5 * (lo[a] + hi[a]);
            g->sigma_t[cell] = (float)cell_mean_sigma_t(P, cell, lo, hi);
            float *out = g->coeffs + cell * (size_t)g->ncoef;
            float xf[3] = {(float)c[0], (float)c[1], (float)c[2]};
            int n = pm_map_knn(map, xf, k, idx, d2);
            if (n < 0) {
#pragma omp atomic write
                failed = 1;
                continue;
            }
            double r2 = n > 0 ? (double)d2[n - 1] : 0.0;
            if (n == 0 || !(r2 > 0.0))
                continue; /* no photons (or all at the centre, r = 0): c = 0 */
            /* c_lm = (1/|V|) sum_k dPhi_k b_l Y_lm(w'_k), |V| = (4/3) pi r^3 (THEORY.md §4). */
            double acc[SH_CHANNELS * SH_MAX_COEFFS];
            memset(acc, 0, sizeof(double) * (size_t)(SH_CHANNELS * nc));
            double y[SH_MAX_COEFFS], b[SH_MAX_BANDS], one[SH_MAX_BANDS];
            for (int l = 0; l < L; l++)
                one[l] = 1.0; /* b_l is applied once per cell below */
            for (int j = 0; j < n; j++) {
                const pm_photon *q = &ph[idx[j]];
                double w[3] = {q->dir[0], q->dir[1], q->dir[2]};
                double pw[3] = {q->power[0], q->power[1], q->power[2]};
                sh_basis_eval(&g->basis, w, y);
                sh_project_add(L, one, y, pw, 1.0, acc);
            }
            cell_phase(P, c, L, b);
            double invV = 1.0 / (4.0 / 3.0 * M_PI * r2 * sqrt(r2));
            for (int ch = 0; ch < SH_CHANNELS; ch++)
                for (int l = 0; l < L; l++)
                    for (int m = -l; m <= l; m++) {
                        int i = ch * nc + SH_INDEX(l, m);
                        out[i] = (float)(acc[i] * b[l] * invV);
                    }
        }
        free(idx);
        free(d2);
    }
    if (nomem) {
        set_err(err, errlen, "sh_guide_bake: out of memory for k-NN buffers (k = %d)", k);
        return SH_ERR_NOMEM;
    }
    if (failed) {
        set_err(err, errlen, "sh_guide_bake: pm_map_knn failed (is the photon map built?)");
        return SH_ERR_PHOTONMAP;
    }
    return SH_OK;
}

/* ---- Track-length bake (THEORY.md §3, seed 004 taken to volumes) ----------------------- */

/* A fixed spatial partition of the cells: the work unit of the parallel track bake. Every
 * region sums its own cells' deposits over all segments in segment order, so the result does
 * not depend on the thread count. */
typedef struct {
    double lo[3], hi[3];
    int i0[3], i1[3];     /* uniform: cell index ranges [i0, i1) */
    size_t c0, c1;        /* adaptive: leaf range [c0, c1) (a depth-first subtree) */
} region;

static size_t collect_regions(const sh_guide *g, size_t node, const double lo[3],
                              const double hi[3], int depth, size_t *leaf_next, region *r,
                              size_t nr)
{
    /* Subtrees at depth 2 (or shallower leaves) are regions; count their leaves. */
    if (g->nodes[node].child < 0 || depth == 2) {
        size_t first = *leaf_next;
        /* count leaves of this subtree: walk it */
        size_t stack[64 * SH_MAX_DEPTH + 8], sp = 0, nleaves = 0;
        stack[sp++] = node;
        while (sp) {
            size_t n = stack[--sp];
            if (g->nodes[n].child < 0) {
                nleaves++;
                continue;
            }
            int nch = 1 << popcount3(g->nodes[n].mask);
            for (int c = 0; c < nch; c++)
                stack[sp++] = (size_t)g->nodes[n].child + (size_t)c;
        }
        if (r) {
            for (int a = 0; a < 3; a++)
                r[nr].lo[a] = lo[a], r[nr].hi[a] = hi[a];
            r[nr].c0 = first;
            r[nr].c1 = first + nleaves;
        }
        *leaf_next += nleaves;
        return nr + 1;
    }
    uint32_t mask = g->nodes[node].mask;
    int nch = 1 << popcount3(mask);
    for (int c = 0; c < nch; c++) {
        double cl[3] = {lo[0], lo[1], lo[2]}, chh[3] = {hi[0], hi[1], hi[2]};
        int bit = 0;
        for (int ax = 0; ax < 3; ax++) {
            if (!(mask & (1u << ax)))
                continue;
            double mid = 0.5 * (lo[ax] + hi[ax]);
            if (c & (1 << bit))
                cl[ax] = mid;
            else
                chh[ax] = mid;
            bit++;
        }
        nr = collect_regions(g, (size_t)g->nodes[node].child + (size_t)c, cl, chh, depth + 1,
                             leaf_next, r, nr);
    }
    return nr;
}

/* Conservative float bounding box of a segment, padded against rounding: the end point is
 * org + length dir for a unit dir, else it lies within the cube org +- length. */
static void segment_bbox(const pm_segment *S, double lo[3], double hi[3])
{
    float dd = S->dir[0] * S->dir[0] + S->dir[1] * S->dir[1] + S->dir[2] * S->dir[2];
    int unit = fabsf(dd - 1.0f) < 1e-3f;
    for (int a = 0; a < 3; a++) {
        float e = S->org[a] + S->length * S->dir[a];
        float l = unit ? fminf(S->org[a], e) : S->org[a] - S->length;
        float h = unit ? fmaxf(S->org[a], e) : S->org[a] + S->length;
        double pad = 1e-3 * S->length + 1e-6 * (fabs(S->org[a]) + 1.0);
        lo[a] = l - pad, hi[a] = h + pad;
    }
}

/* Lists of the segments whose bounding box meets each region: CSR (off[nr + 1], ids).
 * When the regions form a regular block grid (always for uniform grids, and for octrees split
 * at least to depth 2) the blocks a box meets are found per axis; otherwise every region is
 * tested. Returns 0, or -1 when out of memory. */
static int bin_segments(const region *R, size_t nr, const pm_segment *seg, size_t ns,
                        uint32_t **ids_out, size_t **off_out)
{
    /* Block boundaries per axis: the distinct region lo values, plus the largest hi. */
    double bnd[3][65];
    int nb[3] = {0, 0, 0}, regular = nr <= 64;
    for (int a = 0; a < 3 && regular; a++) {
        for (size_t r = 0; r < nr && regular; r++) {
            int found = 0;
            for (int j = 0; j < nb[a]; j++)
                found |= bnd[a][j] == R[r].lo[a];
            if (!found) {
                if (nb[a] >= 64)
                    regular = 0;
                else
                    bnd[a][nb[a]++] = R[r].lo[a];
            }
        }
        /* sort (tiny) */
        for (int i = 1; i < nb[a]; i++)
            for (int j = i; j > 0 && bnd[a][j - 1] > bnd[a][j]; j--) {
                double t = bnd[a][j];
                bnd[a][j] = bnd[a][j - 1], bnd[a][j - 1] = t;
            }
        double top = -INFINITY;
        for (size_t r = 0; r < nr; r++)
            top = fmax(top, R[r].hi[a]);
        bnd[a][nb[a]] = top;
    }
    int map[64];
    if (regular && (size_t)nb[0] * nb[1] * nb[2] == nr) {
        for (int i = 0; i < 64; i++)
            map[i] = -1;
        for (size_t r = 0; r < nr && regular; r++) {
            int jj[3];
            for (int a = 0; a < 3; a++) {
                jj[a] = -1;
                for (int j = 0; j < nb[a]; j++)
                    if (bnd[a][j] == R[r].lo[a] && bnd[a][j + 1] == R[r].hi[a])
                        jj[a] = j;
                if (jj[a] < 0)
                    regular = 0;
            }
            if (regular) {
                int q = jj[0] + nb[0] * (jj[1] + nb[1] * jj[2]);
                if (map[q] >= 0)
                    regular = 0;
                map[q] = (int)r;
            }
        }
    } else {
        regular = 0;
    }
    size_t *off = calloc(nr + 1, sizeof *off);
    if (!off)
        return -1;
    uint32_t *ids = NULL;
    for (int pass = 0; pass < 2; pass++) {
        size_t *fill = NULL;
        if (pass == 1) {
            for (size_t r = 0; r < nr; r++)
                off[r + 1] += off[r];
            ids = malloc((off[nr] ? off[nr] : 1) * sizeof *ids);
            fill = malloc((nr ? nr : 1) * sizeof *fill);
            if (!ids || !fill) {
                free(ids), free(fill), free(off);
                return -1;
            }
            memcpy(fill, off, nr * sizeof *fill);
        }
        for (size_t s = 0; s < ns; s++) {
            double lo[3], hi[3];
            segment_bbox(&seg[s], lo, hi);
            if (regular) {
                int j0[3], j1[3], empty = 0;
                for (int a = 0; a < 3; a++) {
                    j0[a] = nb[a], j1[a] = -1;
                    for (int j = 0; j < nb[a]; j++)
                        if (hi[a] >= bnd[a][j] && lo[a] <= bnd[a][j + 1]) {
                            if (j < j0[a])
                                j0[a] = j;
                            j1[a] = j;
                        }
                    empty |= j1[a] < 0;
                }
                if (empty)
                    continue;
                for (int z = j0[2]; z <= j1[2]; z++)
                    for (int y = j0[1]; y <= j1[1]; y++)
                        for (int x = j0[0]; x <= j1[0]; x++) {
                            int r = map[x + nb[0] * (y + nb[1] * z)];
                            if (pass == 0)
                                off[r + 1]++;
                            else
                                ids[fill[r]++] = (uint32_t)s;
                        }
            } else {
                for (size_t r = 0; r < nr; r++) {
                    int meet = 1;
                    for (int a = 0; a < 3; a++)
                        meet &= hi[a] >= R[r].lo[a] && lo[a] <= R[r].hi[a];
                    if (!meet)
                        continue;
                    if (pass == 0)
                        off[r + 1]++;
                    else
                        ids[fill[r]++] = (uint32_t)s;
                }
            }
        }
        free(fill);
    }
    *ids_out = ids;
    *off_out = off;
    return 0;
}

static sh_status bake_track(sh_guide *g, const pm_map *map, const sh_bake_params *P, char *err,
                            size_t errlen)
{
    const int L = g->bands, nc = L * L;
    const size_t ns = pm_map_segment_count(map);
    const pm_segment *seg = pm_map_segments(map);
    /* Regions: up to 4 blocks per axis (uniform) or the depth-2 subtrees (adaptive). */
    region *R = NULL;
    size_t nr = 0;
    if (g->kind == SH_GRID_UNIFORM) {
        int nb[3];
        for (int a = 0; a < 3; a++)
            nb[a] = g->res[a] < 4 ? g->res[a] : 4;
        nr = (size_t)nb[0] * nb[1] * nb[2];
        R = calloc(nr, sizeof *R);
        if (!R)
            goto nomem;
        size_t q = 0;
        for (int bz = 0; bz < nb[2]; bz++)
            for (int by = 0; by < nb[1]; by++)
                for (int bx = 0; bx < nb[0]; bx++, q++) {
                    int bb[3] = {bx, by, bz};
                    for (int a = 0; a < 3; a++) {
                        R[q].i0[a] = (int)((long)g->res[a] * bb[a] / nb[a]);
                        R[q].i1[a] = (int)((long)g->res[a] * (bb[a] + 1) / nb[a]);
                        R[q].lo[a] = uplane(g, a, R[q].i0[a]);
                        R[q].hi[a] = uplane(g, a, R[q].i1[a]);
                    }
                }
    } else {
        size_t leaf = 0;
        nr = collect_regions(g, 0, g->lo, g->hi, 0, &leaf, NULL, 0);
        R = calloc(nr, sizeof *R);
        if (!R)
            goto nomem;
        leaf = 0;
        collect_regions(g, 0, g->lo, g->hi, 0, &leaf, R, 0);
    }

    /* Bin the segments by region (ascending segment order within each region, so the sums
     * below run in a fixed order). */
    uint32_t *bin_seg = NULL;
    size_t *bin_off = NULL;
    if (ns > UINT32_MAX || bin_segments(R, nr, seg, ns, &bin_seg, &bin_off) != 0) {
        free(R);
        goto nomem;
    }
    int nomem_flag = 0;
    long long nreg = (long long)nr;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads(P))
    for (long long ri = 0; ri < nreg; ri++) {
        const region *r = &R[ri];
        size_t rc; /* cells in the region */
        int ni[3] = {0, 0, 0};
        if (g->kind == SH_GRID_UNIFORM) {
            for (int a = 0; a < 3; a++)
                ni[a] = r->i1[a] - r->i0[a];
            rc = (size_t)ni[0] * ni[1] * ni[2];
        } else {
            rc = r->c1 - r->c0;
        }
        double *acc = calloc(rc * (size_t)(SH_CHANNELS * nc) + 1, sizeof *acc);
        if (!acc) {
#pragma omp atomic write
            nomem_flag = 1;
            continue;
        }
        double y[SH_MAX_COEFFS];
        for (size_t q = bin_off[ri]; q < bin_off[ri + 1]; q++) {
            const pm_segment *S = &seg[bin_seg[q]];
            double o[3] = {S->org[0], S->org[1], S->org[2]};
            double d[3] = {S->dir[0], S->dir[1], S->dir[2]};
            double dn = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            double len = S->length;
            if (!(dn > 0.0) || !(len > 0.0) || !isfinite(len) || !isfinite(dn))
                continue;
            for (int a = 0; a < 3; a++)
                d[a] /= dn;
            /* Clip [0, len] to the region's box (slabs). */
            double t0 = 0.0, t1 = len;
            for (int a = 0; a < 3 && t0 < t1; a++) {
                if (d[a] == 0.0) {
                    if (o[a] < r->lo[a] || o[a] > r->hi[a])
                        t1 = -1.0;
                    continue;
                }
                double ta = (r->lo[a] - o[a]) / d[a], tb = (r->hi[a] - o[a]) / d[a];
                if (ta > tb) {
                    double t = ta;
                    ta = tb, tb = t;
                }
                t0 = fmax(t0, ta), t1 = fmin(t1, tb);
            }
            if (!(t0 < t1))
                continue;
            int have_y = 0;
            sh_guide_ray it;
            sh_guide_seg gs;
            sh_guide_ray_begin(g, o, d, t0, t1, &it);
            while (sh_guide_ray_next(&it, &gs)) {
                size_t local;
                size_t cell = (size_t)gs.cell;
                if (g->kind == SH_GRID_UNIFORM) {
                    size_t nx = (size_t)g->res[0], ny = (size_t)g->res[1];
                    int ijk[3] = {(int)(cell % nx), (int)((cell / nx) % ny),
                                  (int)(cell / (nx * ny))};
                    int in = 1;
                    for (int a = 0; a < 3; a++)
                        in &= ijk[a] >= r->i0[a] && ijk[a] < r->i1[a];
                    if (!in)
                        continue; /* a rounding sliver of a neighbouring region */
                    local = (size_t)(ijk[0] - r->i0[0]) +
                            (size_t)ni[0] * ((size_t)(ijk[1] - r->i0[1]) +
                                             (size_t)ni[1] * (size_t)(ijk[2] - r->i0[2]));
                } else {
                    if (cell < r->c0 || cell >= r->c1)
                        continue;
                    local = cell - r->c0;
                }
                if (!have_y) {
                    sh_basis_eval(&g->basis, d, y);
                    have_y = 1;
                }
                /* deposit sigma_s(x_mid) dPhi l Y_lm(w') (b_l / |V_cell| applied below) */
                double l = gs.t1 - gs.t0;
                double ss[3] = {1.0, 1.0, 1.0};
                if (P->sigma_s) {
                    double tm = 0.5 * (gs.t0 + gs.t1);
                    double xm[3] = {o[0] + tm * d[0], o[1] + tm * d[1], o[2] + tm * d[2]};
                    P->sigma_s(xm, P->sigma_s_user, ss);
                }
                double pw[3] = {S->power[0] * ss[0], S->power[1] * ss[1], S->power[2] * ss[2]};
                double *A = acc + local * (size_t)(SH_CHANNELS * nc);
                for (int ch = 0; ch < SH_CHANNELS; ch++) {
                    double v = pw[ch] * l;
                    for (int i = 0; i < nc; i++)
                        A[ch * nc + i] += v * y[i];
                }
            }
        }
        /* c_lm = b_l acc / |V_cell| */
        for (size_t local = 0; local < rc; local++) {
            size_t cell;
            if (g->kind == SH_GRID_UNIFORM) {
                size_t li = local % (size_t)ni[0], lj = (local / (size_t)ni[0]) % (size_t)ni[1],
                       lk = local / ((size_t)ni[0] * (size_t)ni[1]);
                cell = (size_t)(r->i0[0] + (int)li) +
                       (size_t)g->res[0] * ((size_t)(r->i0[1] + (int)lj) +
                                            (size_t)g->res[1] * (size_t)(r->i0[2] + (int)lk));
            } else {
                cell = r->c0 + local;
            }
            double lo[3], hi[3], c[3], b[SH_MAX_BANDS];
            cell_bounds(g, cell, lo, hi);
            double V = 1.0;
            for (int a = 0; a < 3; a++) {
                V *= hi[a] - lo[a];
                c[a] = 0.5 * (lo[a] + hi[a]);
            }
            cell_phase(P, c, L, b);
            g->sigma_t[cell] = (float)cell_mean_sigma_t(P, cell, lo, hi);
            const double *A = acc + local * (size_t)(SH_CHANNELS * nc);
            float *out = g->coeffs + cell * (size_t)g->ncoef;
            for (int ch = 0; ch < SH_CHANNELS; ch++)
                for (int l = 0; l < L; l++)
                    for (int m = -l; m <= l; m++) {
                        int i = ch * nc + SH_INDEX(l, m);
                        out[i] = (float)(A[i] * b[l] / V);
                    }
        }
        free(acc);
    }
    free(R);
    free(bin_seg);
    free(bin_off);
    if (nomem_flag)
        goto nomem;
    return SH_OK;
nomem:
    free(R);
    set_err(err, errlen, "sh_guide_bake: out of memory for the track-length accumulators");
    return SH_ERR_NOMEM;
}

sh_status sh_guide_bake(sh_guide **out, const pm_map *map, const sh_bake_params *P, char *err,
                        size_t errlen)
{
    if (!out) {
        set_err(err, errlen, "sh_guide_bake: out must be non-NULL");
        return SH_ERR_ARG;
    }
    *out = NULL;
    double lo[3], hi[3];
    sh_status st = check_params(map, P, lo, hi, err, errlen);
    if (st != SH_OK)
        return st;
    double t_start = omp_get_wtime();
    sh_guide *g = calloc(1, sizeof *g);
    if (!g) {
        set_err(err, errlen, "sh_guide_bake: out of memory");
        return SH_ERR_NOMEM;
    }
    g->kind = P->kind;
    g->method = P->method;
    g->bands = P->bands;
    g->ncoef = SH_CHANNELS * P->bands * P->bands;
    g->k = P->k;
    g->lambda = P->lambda;
    sh_basis_init(&g->basis, g->bands);
    for (int a = 0; a < 3; a++)
        g->lo[a] = lo[a], g->hi[a] = hi[a];
    size_t np = pm_map_photon_count(map), ns = pm_map_segment_count(map);
    g->photons = P->method == SH_BAKE_KNN ? np : ns;

    if (P->kind == SH_GRID_UNIFORM) {
        if (P->res[0] > 0) {
            for (int a = 0; a < 3; a++)
                g->res[a] = P->res[a];
        } else {
            uniform_rule(lo, hi, P->lambda, np > 0 ? np : ns, P->k, g->res);
        }
        double cells = (double)g->res[0] * g->res[1] * g->res[2];
        if (cells > (double)P->max_cells) {
            set_err(err, errlen, "sh_guide_bake: uniform grid %dx%dx%d exceeds params.max_cells "
                                 "= %zu", g->res[0], g->res[1], g->res[2], P->max_cells);
            sh_guide_free(g);
            return SH_ERR_NOMEM;
        }
        g->ncells = (size_t)cells;
        for (int a = 0; a < 3; a++)
            g->h[a] = (hi[a] - lo[a]) / g->res[a];
    } else {
        st = build_octree(g, map, P, err, errlen);
        if (st != SH_OK) {
            sh_guide_free(g);
            return st;
        }
    }
    g->coeffs = calloc(g->ncells * (size_t)g->ncoef, sizeof *g->coeffs);
    g->sigma_t = calloc(g->ncells, sizeof *g->sigma_t);
    if (!g->coeffs || !g->sigma_t) {
        set_err(err, errlen, "sh_guide_bake: out of memory for %zu cells x %d coefficients",
                g->ncells, g->ncoef);
        sh_guide_free(g);
        return SH_ERR_NOMEM;
    }
    st = P->method == SH_BAKE_KNN ? bake_knn(g, map, P, err, errlen)
                                  : bake_track(g, map, P, err, errlen);
    if (st != SH_OK) {
        sh_guide_free(g);
        return st;
    }
    g->bake_seconds = omp_get_wtime() - t_start;
    *out = g;
    return SH_OK;
}

/* ---- Slice images --------------------------------------------------------------------------- */

sh_status sh_guide_slice(const sh_guide *g, int axis, double coord, const double w[3],
                         sh_slice_what what, int width, int height, float *out, char *err,
                         size_t errlen)
{
    if (!g || !out || axis < 0 || axis > 2 || width < 1 || height < 1 || !isfinite(coord) ||
        (unsigned)what > SH_SLICE_DEPTH) {
        set_err(err, errlen, "sh_guide_slice: bad argument (axis %d, %dx%d, what %d)", axis,
                width, height, (int)what);
        return SH_ERR_ARG;
    }
    static const int UV[3][2] = {{1, 2}, {0, 2}, {0, 1}};
    int u = UV[axis][0], v = UV[axis][1];
    float y[SH_MAX_COEFFS];
    double wd[3] = {0.0, 0.0, 1.0};
    if (w)
        wd[0] = w[0], wd[1] = w[1], wd[2] = w[2];
    sh_basis_evalf(&g->basis, wd, y);
#pragma omp parallel for schedule(static)
    for (int j = 0; j < height; j++) {
        for (int i = 0; i < width; i++) {
            double x[3];
            x[axis] = coord;
            x[u] = g->lo[u] + (i + 0.5) / width * (g->hi[u] - g->lo[u]);
            x[v] = g->hi[v] - (j + 0.5) / height * (g->hi[v] - g->lo[v]); /* row 0 at the top */
            float *px = out + 3 * ((size_t)j * (size_t)width + (size_t)i);
            px[0] = px[1] = px[2] = 0.0f;
            long c = sh_guide_locate(g, x);
            if (c < 0)
                continue;
            const float *cf = g->coeffs + (size_t)c * (size_t)g->ncoef;
            switch (what) {
            case SH_SLICE_RADIANCE:
                sh_eval_rgb_clamped(g->bands, cf, y, px);
                break;
            case SH_SLICE_GUIDE:
                px[0] = px[1] = px[2] = sh_eval_guide(g->bands, cf, y);
                break;
            case SH_SLICE_SIGMA_T:
                px[0] = px[1] = px[2] = g->sigma_t[c];
                break;
            case SH_SLICE_DEPTH:
                px[0] = px[1] = px[2] = (float)sh_guide_cell_depth(g, (size_t)c);
                break;
            }
        }
    }
    return SH_OK;
}

/* ---- Files ----------------------------------------------------------------------------------
 * Layout (little-endian; docs/guide-grid.md "file format"):
 *   0   char[8]  magic "SHGUIDE\0"
 *   8   u32      version (1)
 *   12  u32      kind (0 uniform, 1 adaptive)
 *   16  u32      method (0 k-NN, 1 track)
 *   20  u32      bands L (1..16)
 *   24  f64[3]   box lo;  48  f64[3] box hi
 *   72  i32[3]   res (uniform; 0 for adaptive)
 *   84  u32      k
 *   88  u64      cells
 *   96  u64      nodes (adaptive; 0 for uniform)
 *   104 f64      lambda
 *   112 f64      bake seconds
 *   120 u64      photons (or segments) used
 *   128 nodes x {i32 child, u32 mask}
 *       cells x 3 L^2 f32 coefficients (channel-major per cell)
 *       cells x f32 sigma_t
 *       u64      FNV-1a 64 of every byte above
 */
#define SH_FILE_MAGIC "SHGUIDE"
#define SH_FILE_VERSION 1u
#define SH_HEADER_BYTES 128

typedef struct {
    FILE *f;
    uint64_t h;
    int bad;
} wstream;

static inline uint64_t fnv1a(uint64_t h, const unsigned char *p, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= 0x100000001b3ull;
    }
    return h;
}
#define FNV_OFFSET 0xcbf29ce484222325ull

static void w_bytes(wstream *w, const void *p, size_t n)
{
    w->h = fnv1a(w->h, p, n);
    if (!w->bad && fwrite(p, 1, n, w->f) != n)
        w->bad = 1;
}
static void put_u32(unsigned char *b, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        b[i] = (unsigned char)(v >> (8 * i));
}
static void put_u64(unsigned char *b, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        b[i] = (unsigned char)(v >> (8 * i));
}
static void put_f64(unsigned char *b, double v)
{
    uint64_t u;
    memcpy(&u, &v, 8);
    put_u64(b, u);
}
static uint32_t get_u32(const unsigned char *b)
{
    uint32_t v = 0;
    for (int i = 0; i < 4; i++)
        v |= (uint32_t)b[i] << (8 * i);
    return v;
}
static uint64_t get_u64(const unsigned char *b)
{
    uint64_t v = 0;
    for (int i = 0; i < 8; i++)
        v |= (uint64_t)b[i] << (8 * i);
    return v;
}
static double get_f64(const unsigned char *b)
{
    uint64_t u = get_u64(b);
    double v;
    memcpy(&v, &u, 8);
    return v;
}

/* Write n floats little-endian through a chunk buffer. */
static void w_floats(wstream *w, const float *x, size_t n)
{
    unsigned char buf[4096];
    while (n) {
        size_t m = n < sizeof buf / 4 ? n : sizeof buf / 4;
        for (size_t i = 0; i < m; i++) {
            uint32_t u;
            memcpy(&u, &x[i], 4);
            put_u32(buf + 4 * i, u);
        }
        w_bytes(w, buf, 4 * m);
        x += m, n -= m;
    }
}

sh_status sh_guide_save(const sh_guide *g, const char *path, char *err, size_t errlen)
{
    if (!g || !path) {
        set_err(err, errlen, "sh_guide_save: guide and path must be non-NULL");
        return SH_ERR_ARG;
    }
    size_t plen = strlen(path);
    char *tmp = malloc(plen + 32);
    if (!tmp) {
        set_err(err, errlen, "%s: out of memory", path);
        return SH_ERR_NOMEM;
    }
    snprintf(tmp, plen + 32, "%s.tmp.%ld", path, (long)getpid());
    wstream w = {fopen(tmp, "wb"), FNV_OFFSET, 0};
    if (!w.f) {
        set_err(err, errlen, "%s: cannot create temporary file %s", path, tmp);
        free(tmp);
        return SH_ERR_IO;
    }
    unsigned char hd[SH_HEADER_BYTES];
    memset(hd, 0, sizeof hd);
    memcpy(hd, SH_FILE_MAGIC, 8);
    put_u32(hd + 8, SH_FILE_VERSION);
    put_u32(hd + 12, (uint32_t)g->kind);
    put_u32(hd + 16, (uint32_t)g->method);
    put_u32(hd + 20, (uint32_t)g->bands);
    for (int a = 0; a < 3; a++) {
        put_f64(hd + 24 + 8 * a, g->lo[a]);
        put_f64(hd + 48 + 8 * a, g->hi[a]);
        put_u32(hd + 72 + 4 * a, (uint32_t)(g->kind == SH_GRID_UNIFORM ? g->res[a] : 0));
    }
    put_u32(hd + 84, (uint32_t)g->k);
    put_u64(hd + 88, g->ncells);
    put_u64(hd + 96, g->kind == SH_GRID_ADAPTIVE ? g->nnodes : 0);
    put_f64(hd + 104, g->lambda);
    put_f64(hd + 112, g->bake_seconds);
    put_u64(hd + 120, g->photons);
    w_bytes(&w, hd, sizeof hd);
    if (g->kind == SH_GRID_ADAPTIVE) {
        unsigned char nb[8];
        for (size_t i = 0; i < g->nnodes; i++) {
            put_u32(nb, (uint32_t)g->nodes[i].child);
            put_u32(nb + 4, g->nodes[i].mask);
            w_bytes(&w, nb, 8);
        }
    }
    w_floats(&w, g->coeffs, g->ncells * (size_t)g->ncoef);
    w_floats(&w, g->sigma_t, g->ncells);
    unsigned char cs[8];
    put_u64(cs, w.h);
    if (!w.bad && fwrite(cs, 1, 8, w.f) != 8)
        w.bad = 1;
    if (fflush(w.f) != 0)
        w.bad = 1;
    if (fclose(w.f) != 0)
        w.bad = 1;
    if (w.bad) {
        remove(tmp);
        set_err(err, errlen, "%s: write failed (temporary file %s removed)", path, tmp);
        free(tmp);
        return SH_ERR_IO;
    }
    if (rename(tmp, path) != 0) {
        remove(tmp);
        set_err(err, errlen, "%s: cannot rename temporary file %s over it", path, tmp);
        free(tmp);
        return SH_ERR_IO;
    }
    free(tmp);
    return SH_OK;
}

typedef struct {
    FILE *f;
    uint64_t h;
} rstream;

static int r_bytes(rstream *r, void *p, size_t n)
{
    if (fread(p, 1, n, r->f) != n)
        return 0;
    r->h = fnv1a(r->h, p, n);
    return 1;
}

static int r_floats(rstream *r, float *x, size_t n)
{
    unsigned char buf[4096];
    while (n) {
        size_t m = n < sizeof buf / 4 ? n : sizeof buf / 4;
        if (!r_bytes(r, buf, 4 * m))
            return 0;
        for (size_t i = 0; i < m; i++) {
            uint32_t u = get_u32(buf + 4 * i);
            memcpy(&x[i], &u, 4);
        }
        x += m, n -= m;
    }
    return 1;
}

/* Walk the octree from the root: every node reached exactly once, children after their
 * parent, every leaf id used exactly once; fills the leaf bounds and depths. */
static int validate_octree(sh_guide *g, char *why, size_t whylen)
{
    uint8_t *seen = calloc(g->nnodes, 1);
    uint8_t *leaf_seen = calloc(g->ncells ? g->ncells : 1, 1);
    g->leaf_lo = malloc(3 * (g->ncells ? g->ncells : 1) * sizeof(double));
    g->leaf_hi = malloc(3 * (g->ncells ? g->ncells : 1) * sizeof(double));
    g->leaf_depth = malloc(g->ncells ? g->ncells : 1);
    typedef struct {
        size_t node;
        int depth;
        double lo[3], hi[3];
    } item;
    item *stack = malloc((size_t)(7 * (SH_MAX_DEPTH + 1) + 8) * sizeof *stack);
    int ok = seen && leaf_seen && g->leaf_lo && g->leaf_hi && g->leaf_depth && stack;
    if (!ok)
        snprintf(why, whylen, "out of memory");
    size_t sp = 0, visited = 0, leaves = 0;
    if (ok) {
        stack[sp].node = 0;
        stack[sp].depth = 0;
        for (int a = 0; a < 3; a++)
            stack[sp].lo[a] = g->lo[a], stack[sp].hi[a] = g->hi[a];
        sp++;
    }
    g->depth_max = 0;
    while (ok && sp) {
        item it = stack[--sp];
        if (seen[it.node]) {
            snprintf(why, whylen, "octree node %zu reached twice", it.node);
            ok = 0;
            break;
        }
        seen[it.node] = 1;
        visited++;
        const sh_node *n = &g->nodes[it.node];
        if (n->child < 0) {
            size_t c = (size_t)(-(int64_t)n->child - 1);
            if (c >= g->ncells || leaf_seen[c] || n->mask != 0) {
                snprintf(why, whylen, "octree node %zu: bad leaf id %zu", it.node, c);
                ok = 0;
                break;
            }
            leaf_seen[c] = 1;
            leaves++;
            for (int a = 0; a < 3; a++)
                g->leaf_lo[3 * c + a] = it.lo[a], g->leaf_hi[3 * c + a] = it.hi[a];
            g->leaf_depth[c] = (uint8_t)it.depth;
            if (it.depth > g->depth_max)
                g->depth_max = it.depth;
            continue;
        }
        int nch = 1 << popcount3(n->mask);
        if (n->mask == 0 || n->mask > 7 || it.depth >= SH_MAX_DEPTH ||
            (size_t)n->child <= it.node || (size_t)n->child + (size_t)nch > g->nnodes) {
            snprintf(why, whylen, "octree node %zu: bad children (first %d, mask %u, depth %d)",
                     it.node, (int)n->child, (unsigned)n->mask, it.depth);
            ok = 0;
            break;
        }
        /* push in reverse so that children are popped in order (depth-first ids) */
        for (int c = nch - 1; c >= 0; c--) {
            item ch;
            ch.node = (size_t)n->child + (size_t)c;
            ch.depth = it.depth + 1;
            int bit = 0;
            for (int a = 0; a < 3; a++) {
                ch.lo[a] = it.lo[a], ch.hi[a] = it.hi[a];
                if (!(n->mask & (1u << a)))
                    continue;
                double mid = 0.5 * (it.lo[a] + it.hi[a]);
                if (c & (1 << bit))
                    ch.lo[a] = mid;
                else
                    ch.hi[a] = mid;
                bit++;
            }
            stack[sp++] = ch;
        }
    }
    if (ok && (visited != g->nnodes || leaves != g->ncells)) {
        snprintf(why, whylen, "octree has %zu unreachable nodes / %zu unused leaves",
                 g->nnodes - visited, g->ncells - leaves);
        ok = 0;
    }
    free(seen);
    free(leaf_seen);
    free(stack);
    return ok;
}

sh_status sh_guide_load(sh_guide **out, const char *path, char *err, size_t errlen)
{
    if (!out || !path) {
        set_err(err, errlen, "sh_guide_load: out and path must be non-NULL");
        return SH_ERR_ARG;
    }
    *out = NULL;
    rstream r = {fopen(path, "rb"), FNV_OFFSET};
    if (!r.f) {
        set_err(err, errlen, "%s: cannot open", path);
        return SH_ERR_IO;
    }
    sh_status st = SH_ERR_FORMAT;
    sh_guide *g = NULL;
    char why[160] = "";
    /* File size, to reject truncation and trailing bytes before allocating anything. */
    long fsize = -1;
    if (fseek(r.f, 0, SEEK_END) == 0)
        fsize = ftell(r.f);
    if (fsize < 0 || fseek(r.f, 0, SEEK_SET) != 0) {
        set_err(err, errlen, "%s: cannot determine the file size", path);
        fclose(r.f);
        return SH_ERR_IO;
    }
    unsigned char hd[SH_HEADER_BYTES];
    if ((size_t)fsize < SH_HEADER_BYTES + 8 || !r_bytes(&r, hd, sizeof hd)) {
        snprintf(why, sizeof why, "truncated header (%ld bytes)", fsize);
        goto fail;
    }
    if (memcmp(hd, SH_FILE_MAGIC, 8) != 0) {
        snprintf(why, sizeof why, "not a guide file (bad magic)");
        goto fail;
    }
    uint32_t version = get_u32(hd + 8);
    if (version != SH_FILE_VERSION) {
        snprintf(why, sizeof why, "unsupported version %u (expected %u)", version,
                 SH_FILE_VERSION);
        goto fail;
    }
    g = calloc(1, sizeof *g);
    if (!g) {
        st = SH_ERR_NOMEM;
        snprintf(why, sizeof why, "out of memory");
        goto fail;
    }
    uint32_t kind = get_u32(hd + 12), method = get_u32(hd + 16), bands = get_u32(hd + 20);
    if (kind > 1 || method > 1) {
        snprintf(why, sizeof why, "bad kind %u or method %u", kind, method);
        goto fail;
    }
    if (bands < 1 || bands > SH_MAX_BANDS) {
        snprintf(why, sizeof why, "bands %u out of range 1..%d", bands, SH_MAX_BANDS);
        goto fail;
    }
    g->kind = (sh_grid_kind)kind;
    g->method = (sh_bake_method)method;
    g->bands = (int)bands;
    g->ncoef = SH_CHANNELS * g->bands * g->bands;
    for (int a = 0; a < 3; a++) {
        g->lo[a] = get_f64(hd + 24 + 8 * a);
        g->hi[a] = get_f64(hd + 48 + 8 * a);
        if (!isfinite(g->lo[a]) || !isfinite(g->hi[a]) || !(g->lo[a] < g->hi[a])) {
            snprintf(why, sizeof why, "box axis %d is empty or not finite", a);
            goto fail;
        }
        g->res[a] = (int)get_u32(hd + 72 + 4 * a);
    }
    g->k = (int)get_u32(hd + 84);
    uint64_t ncells = get_u64(hd + 88), nnodes = get_u64(hd + 96);
    g->lambda = get_f64(hd + 104);
    g->bake_seconds = get_f64(hd + 112);
    g->photons = (size_t)get_u64(hd + 120);
    /* Sizes: every count must be consistent with the file length (no absurd allocations). */
    uint64_t per_cell = (uint64_t)g->ncoef * 4 + 4;
    uint64_t avail = (uint64_t)fsize - SH_HEADER_BYTES - 8;
    if (ncells == 0 || ncells > avail / per_cell || nnodes > avail / 8 ||
        nnodes * 8 + ncells * per_cell != avail) {
        snprintf(why, sizeof why,
                 "size mismatch: %llu cells, %llu nodes do not fill %ld bytes (truncated or "
                 "trailing data)", (unsigned long long)ncells, (unsigned long long)nnodes,
                 fsize);
        goto fail;
    }
    g->ncells = (size_t)ncells;
    if (g->kind == SH_GRID_UNIFORM) {
        uint64_t prod = 1;
        for (int a = 0; a < 3; a++) {
            if (g->res[a] < 1 || g->res[a] > SH_MAX_RES) {
                snprintf(why, sizeof why, "res[%d] = %d out of range", a, g->res[a]);
                goto fail;
            }
            prod *= (uint64_t)g->res[a];
            g->h[a] = (g->hi[a] - g->lo[a]) / g->res[a];
        }
        if (prod != ncells || nnodes != 0) {
            snprintf(why, sizeof why, "res %dx%dx%d does not match %llu cells", g->res[0],
                     g->res[1], g->res[2], (unsigned long long)ncells);
            goto fail;
        }
    } else {
        if (nnodes < 1 || nnodes > (uint64_t)INT32_MAX || ncells > nnodes) {
            snprintf(why, sizeof why, "bad octree size (%llu nodes, %llu leaves)",
                     (unsigned long long)nnodes, (unsigned long long)ncells);
            goto fail;
        }
        g->nnodes = (size_t)nnodes;
        g->nodes = malloc(g->nnodes * sizeof *g->nodes);
        if (!g->nodes) {
            st = SH_ERR_NOMEM;
            snprintf(why, sizeof why, "out of memory for %zu nodes", g->nnodes);
            goto fail;
        }
        for (size_t i = 0; i < g->nnodes; i++) {
            unsigned char nb[8];
            if (!r_bytes(&r, nb, 8)) {
                snprintf(why, sizeof why, "truncated in the octree nodes");
                goto fail;
            }
            g->nodes[i].child = (int32_t)get_u32(nb);
            g->nodes[i].mask = get_u32(nb + 4);
        }
    }
    g->coeffs = malloc(g->ncells * (size_t)g->ncoef * sizeof(float));
    g->sigma_t = malloc(g->ncells * sizeof(float));
    if (!g->coeffs || !g->sigma_t) {
        st = SH_ERR_NOMEM;
        snprintf(why, sizeof why, "out of memory for %zu cells", g->ncells);
        goto fail;
    }
    if (!r_floats(&r, g->coeffs, g->ncells * (size_t)g->ncoef) ||
        !r_floats(&r, g->sigma_t, g->ncells)) {
        snprintf(why, sizeof why, "truncated in the cell data");
        goto fail;
    }
    uint64_t h = r.h;
    unsigned char cs[8];
    if (fread(cs, 1, 8, r.f) != 8) {
        snprintf(why, sizeof why, "truncated before the checksum");
        goto fail;
    }
    if (get_u64(cs) != h) {
        snprintf(why, sizeof why, "checksum mismatch (file corrupt)");
        goto fail;
    }
    if (g->kind == SH_GRID_ADAPTIVE && !validate_octree(g, why, sizeof why))
        goto fail;
    for (size_t i = 0; i < g->ncells * (size_t)g->ncoef; i++)
        if (!isfinite(g->coeffs[i])) {
            snprintf(why, sizeof why, "coefficient %zu of cell %zu is not finite",
                     i % (size_t)g->ncoef, i / (size_t)g->ncoef);
            goto fail;
        }
    for (size_t c = 0; c < g->ncells; c++)
        if (!isfinite(g->sigma_t[c]) || g->sigma_t[c] < 0.0f) {
            snprintf(why, sizeof why, "sigma_t of cell %zu is negative or not finite", c);
            goto fail;
        }
    if (!(g->lambda > 0.0) || !isfinite(g->lambda) || !isfinite(g->bake_seconds)) {
        snprintf(why, sizeof why, "bad lambda or bake time");
        goto fail;
    }
    sh_basis_init(&g->basis, g->bands);
    fclose(r.f);
    *out = g;
    return SH_OK;
fail:
    fclose(r.f);
    sh_guide_free(g);
    set_err(err, errlen, "%s: %s", path, why);
    return st;
}
