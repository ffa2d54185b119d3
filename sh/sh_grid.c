/* sh_grid.c: the guide object once it exists (THEORY.md §5; docs/guide-grid.md): the cell
 * boxes of both grid kinds, read access by cell id, point location and evaluation (the guide's
 * SH expansion at a point and direction, seed 001 §3.2), statistics and free. Making a guide is
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
