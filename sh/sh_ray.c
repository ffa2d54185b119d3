/* sh_ray.c: the ray iterator over both grid kinds (DESIGN.md convention 7; THEORY.md §5-6;
 * docs/guide-grid.md "The ray iterator"), a thin layer over walk/: sh_guide_ray_begin clips
 * the ray to the box (wk_box_clip, Kay & Kajiya 1986); each sh_guide_ray_next returns the next
 * cell crossed with its parameter interval [t0, t1), from the uniform-grid 3D-DDA (wk_dda,
 * Amanatides & Woo 1987) or the octree walk (wk_tree_walk). The segments tile the clipped
 * interval exactly (t0 of one = t1 of the previous), never have zero length, and agree with
 * sh_guide_locate about which cell a point is in (shi_ucell / shi_descend use the same plane
 * arithmetic). The track-length bake (sh_bake.c) uses the same iterator for its overlap lengths.
 *
 * sh_guide_ray (sh.h) keeps the walk's cursor in its own private fields; the functions below
 * copy it into a wk_ iterator for one step and back. The grid geometry (box, cell edge, res)
 * comes from the guide, so the copies are a few words. */
#include <math.h>
#include <string.h>

#include "sh_internal.h"
#include "walk.h"

/* The cursor of a uniform-grid walk, sh_guide_ray <-> wk_dda. */
static void dda_load(const sh_guide_ray *it, wk_dda *w)
{
    const sh_guide *g = it->g;
    for (int a = 0; a < 3; a++) {
        w->lo[a] = g->lo[a], w->hi[a] = g->hi[a], w->h[a] = g->h[a], w->res[a] = g->res[a];
        w->o[a] = it->o[a], w->d[a] = it->d[a];
        w->ijk[a] = it->ijk[a], w->step[a] = it->step[a];
        w->tx[a] = it->tx[a];
    }
    w->t = it->t, w->tend = it->tend, w->done = it->done;
}

static void dda_store(const wk_dda *w, sh_guide_ray *it)
{
    for (int a = 0; a < 3; a++)
        it->ijk[a] = w->ijk[a], it->step[a] = w->step[a], it->tx[a] = w->tx[a];
    it->t = w->t, it->tend = w->tend, it->done = w->done;
}

/* The locate callback of the octree walk: shi_descend (ties on a splitting plane go to the
 * side d heads to, d[a] >= 0 to the upper half). */
static long guide_locate(const void *tree, const double p[3], const double d[3], double lo[3],
                         double hi[3])
{
    return shi_descend(tree, p, d, lo, hi);
}

/* The cursor of an octree walk, sh_guide_ray <-> wk_tree_walk. */
static void tree_load(const sh_guide_ray *it, wk_tree_walk *w)
{
    const sh_guide *g = it->g;
    w->locate = guide_locate;
    w->tree = g;
    for (int a = 0; a < 3; a++) {
        w->lo[a] = g->lo[a], w->hi[a] = g->hi[a];
        w->o[a] = it->o[a], w->d[a] = it->d[a];
        w->snap[a] = it->snap[a];
    }
    w->t = it->t, w->tend = it->tend, w->done = it->done;
    w->snap_mask = it->snap_mask;
    w->max_zero = 4 * SH_MAX_DEPTH + 16;
}

static void tree_store(const wk_tree_walk *w, sh_guide_ray *it)
{
    for (int a = 0; a < 3; a++)
        it->snap[a] = w->snap[a];
    it->t = w->t, it->tend = w->tend, it->done = w->done;
    it->snap_mask = w->snap_mask;
}

/* Clip [tmin, tmax] to the box and set up the walk. A ray that misses leaves it->done = 1. The
 * first cell is fixed without any point lookup rounding at the entry face: uniform grids take
 * the entry axis's index from the direction (first or last slab), adaptive grids snap the
 * entry coordinate to the face exactly (both given the entry axis by wk_box_clip). */
void sh_guide_ray_begin(const sh_guide *g, const double o[3], const double d[3], double tmin,
                        double tmax, sh_guide_ray *it)
{
    memset(it, 0, sizeof *it);
    it->g = g;
    it->done = 1;
    if (!g)
        return;
    double t0, t1;
    int enter_axis;
    if (!wk_box_clip(g->lo, g->hi, o, d, tmin, tmax, &t0, &t1, &enter_axis))
        return;
    for (int a = 0; a < 3; a++) {
        it->o[a] = o[a];
        it->d[a] = d[a];
        it->inv[a] = d[a] != 0.0 ? 1.0 / d[a] : INFINITY;
    }
    if (g->kind == SH_GRID_UNIFORM) {
        wk_dda w;
        wk_dda_begin(&w, g->lo, g->hi, g->res, o, d, t0, t1, enter_axis);
        dda_store(&w, it);
    } else {
        wk_tree_walk w;
        wk_tree_begin(&w, guide_locate, g, g->lo, g->hi, o, d, t0, t1, enter_axis,
                      SH_MAX_DEPTH);
        tree_store(&w, it);
    }
}

/* Fill the guide's segment for cell `cell` on [t0, t1). */
static void emit_seg(const sh_guide *g, long cell, double t0, double t1, sh_guide_seg *seg)
{
    seg->t0 = t0;
    seg->t1 = t1;
    seg->cell = cell;
    seg->coeffs = g->coeffs + (size_t)cell * (size_t)g->ncoef;
    seg->sigma_t = g->sigma_t[cell];
}

int sh_guide_ray_next(sh_guide_ray *it, sh_guide_seg *seg)
{
    if (!it || it->done || !it->g)
        return 0;
    int got;
    if (it->g->kind == SH_GRID_UNIFORM) {
        wk_dda w;
        wk_dda_seg s;
        dda_load(it, &w);
        got = wk_dda_next(&w, &s);
        dda_store(&w, it);
        if (got)
            emit_seg(it->g, s.cell, s.ta, s.tb, seg);
    } else {
        wk_tree_walk w;
        wk_tree_seg s;
        tree_load(it, &w);
        got = wk_tree_next(&w, &s);
        tree_store(&w, it);
        if (got)
            emit_seg(it->g, s.leaf, s.ta, s.tb, seg);
    }
    return got;
}
