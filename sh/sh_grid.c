/* sh_grid.c: the guide object once it exists (THEORY.md §5; docs/guide-grid.md): the cell
 * boxes of both grid kinds, read access by cell id, point location and evaluation (the guide's
 * SH expansion at a point and direction, seed 001 §3.2), statistics, free, and a copy that
 * keeps fewer bands (sh_guide_truncate). Making a guide is
 * sh_layout.c (sh_guide_bake: the cell layout) and sh_bake.c (the cells' values); loading one
 * is sh_io.c. The guide's layout is in sh_internal.h. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sh_internal.h"

/* ---- Errors and lifetime -------------------------------------------------------------------- */

void shi_set_err(char *err, size_t errlen, const char *fmt, ...)
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

/* Copy n bytes of src into a fresh block at *dst (NULL for n = 0); 0 when out of memory. */
static int dup_bytes(void **dst, const void *src, size_t n)
{
    *dst = NULL;
    if (n == 0 || !src)
        return 1;
    if (!(*dst = malloc(n)))
        return 0;
    memcpy(*dst, src, n);
    return 1;
}

sh_status sh_guide_truncate(const sh_guide *g, int bands, sh_guide **out, char *err, size_t errlen)
{
    if (!out) {
        shi_set_err(err, errlen, "sh_guide_truncate: out must be non-NULL");
        return SH_ERR_ARG;
    }
    *out = NULL;
    if (!g || bands < 1 || bands > g->bands) {
        shi_set_err(err, errlen, "sh_guide_truncate: %d bands asked of a %d-band guide", bands,
                    g ? g->bands : 0);
        return SH_ERR_ARG;
    }
    sh_guide *t = malloc(sizeof *t);
    if (!t) {
        shi_set_err(err, errlen, "sh_guide_truncate: out of memory");
        return SH_ERR_NOMEM;
    }
    *t = *g;
    t->nodes = NULL, t->leaf_lo = t->leaf_hi = NULL, t->leaf_depth = NULL;
    t->coeffs = t->sigma_t = NULL;
    t->bands = bands;
    t->ncoef = SH_CHANNELS * bands * bands;
    int ok = dup_bytes((void **)&t->nodes, g->nodes, g->nnodes * sizeof *g->nodes) &&
             dup_bytes((void **)&t->leaf_lo, g->leaf_lo, g->leaf_lo ? 3 * g->ncells * sizeof(double) : 0) &&
             dup_bytes((void **)&t->leaf_hi, g->leaf_hi, g->leaf_hi ? 3 * g->ncells * sizeof(double) : 0) &&
             dup_bytes((void **)&t->leaf_depth, g->leaf_depth, g->leaf_depth ? g->ncells : 0) &&
             dup_bytes((void **)&t->sigma_t, g->sigma_t, g->ncells * sizeof(float)) &&
             (t->coeffs = malloc(g->ncells * (size_t)t->ncoef * sizeof(float) + 1)) != NULL;
    if (!ok || sh_basis_init(&t->basis, bands) != SH_OK) {
        sh_guide_free(t);
        shi_set_err(err, errlen, "sh_guide_truncate: out of memory");
        return SH_ERR_NOMEM;
    }
    /* Channel-major per cell (sh.h): channel c's band-l block is coefficients c L^2 + l^2 ... */
    const int n = bands * bands, L2 = g->bands * g->bands;
    for (size_t i = 0; i < g->ncells; i++)
        for (int c = 0; c < SH_CHANNELS; c++)
            memcpy(t->coeffs + i * (size_t)t->ncoef + (size_t)c * n,
                   g->coeffs + i * (size_t)g->ncoef + (size_t)c * L2, (size_t)n * sizeof(float));
    *out = t;
    return SH_OK;
}

/* ---- Cell geometry -------------------------------------------------------------------------- */

/* Uniform: cell id -> (i, j, k) -> planes; adaptive: the stored leaf box. */
void shi_cell_bounds(const sh_guide *g, size_t cell, double lo[3], double hi[3])
{
    if (g->kind == SH_GRID_UNIFORM) {
        size_t nx = (size_t)g->res[0], ny = (size_t)g->res[1];
        int ijk[3] = {(int)(cell % nx), (int)((cell / nx) % ny), (int)(cell / (nx * ny))};
        for (int a = 0; a < 3; a++) {
            lo[a] = shi_uplane(g, a, ijk[a]);
            hi[a] = shi_uplane(g, a, ijk[a] + 1);
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
    shi_cell_bounds(g, cell, lo, hi);
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
        long i = shi_ucell(g, 0, x[0]), j = shi_ucell(g, 1, x[1]), k = shi_ucell(g, 2, x[2]);
        return i + (long)g->res[0] * (j + (long)g->res[1] * k);
    }
    const double zero[3] = {0.0, 0.0, 0.0};
    double blo[3], bhi[3];
    return shi_descend(g, x, zero, blo, bhi);
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
