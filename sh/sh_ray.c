/* sh_ray.c: the ray iterator over both grid kinds (DESIGN.md convention 7; THEORY.md §5-6;
 * docs/guide-grid.md "The ray iterator"), a thin layer over walk/: sh_guide_ray_begin clips
 * the ray to the box (wk_box_clip, Kay & Kajiya 1986); each sh_guide_ray_next returns the next
 * cell crossed with its parameter interval [t0, t1), from the uniform-grid 3D-DDA (wk_dda,
 * Amanatides & Woo 1987) or the octree walk (wk_tree_walk). The segments tile the clipped
 * interval exactly (t0 of one = t1 of the previous), never have zero length, and agree with
 * sh_guide_locate about which cell a point is in (shi_ucell / shi_descend use the same plane
 * arithmetic). The track-length bake (sh_bake.c) uses the same iterator for its overlap lengths.
 *
 * sh_guide_ray (sh.h) holds the wk_ iterator itself, stepped in place. */

#include "sh_internal.h"
#include "walk.h"

/* The locate callback of the octree walk: shi_descend (ties on a splitting plane go to the
 * side d heads to, d[a] >= 0 to the upper half). */
static long guide_locate(const void *tree, const double p[3], const double d[3], double lo[3],
                         double hi[3])
{
    return shi_descend(tree, p, d, lo, hi);
}

/* Clip [tmin, tmax] to the box and set up the walk. A ray that misses leaves it->done = 1. The
 * first cell is fixed without any point lookup rounding at the entry face: uniform grids take
 * the entry axis's index from the direction (first or last slab), adaptive grids snap the
 * entry coordinate to the face exactly (both given the entry axis by wk_box_clip). */
void sh_guide_ray_begin(const sh_guide *g, const double o[3], const double d[3], double tmin,
                        double tmax, sh_guide_ray *it)
{
    it->g = g; /* the walk's begin below sets (and clears) its own state */
    it->done = 1;
    if (!g)
        return;
    double t0, t1;
    int enter_axis;
    if (!wk_box_clip(g->lo, g->hi, o, d, tmin, tmax, &t0, &t1, &enter_axis))
        return;
    /* The walk's own state lives in the cursor and is stepped in place: copying it in and out
     * at every cell cost `guided` about 7% of its time on hard-narrow-spot with select off
     * (docs/benchmarks.md, "Session 16"). */
    it->done = 0;
    if (g->kind == SH_GRID_UNIFORM)
        wk_dda_begin(&it->w.grid, g->lo, g->hi, g->res, o, d, t0, t1, enter_axis);
    else
        wk_tree_begin(&it->w.tree, guide_locate, g, g->lo, g->hi, o, d, t0, t1, enter_axis,
                      SH_MAX_DEPTH);
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
    if (it->g->kind == SH_GRID_UNIFORM) {
        wk_dda_seg s;
        if (wk_dda_next(&it->w.grid, &s)) {
            emit_seg(it->g, s.cell, s.ta, s.tb, seg);
            return 1;
        }
    } else {
        wk_tree_seg s;
        if (wk_tree_next(&it->w.tree, &s)) {
            emit_seg(it->g, s.leaf, s.ta, s.tb, seg);
            return 1;
        }
    }
    it->done = 1;
    return 0;
}
