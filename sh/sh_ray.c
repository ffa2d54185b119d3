/* sh_ray.c: the ray iterator over both grid kinds (DESIGN.md convention 7; THEORY.md §5-6;
 * docs/guide-grid.md "The ray iterator"). sh_guide_ray_begin clips the ray to the box;
 * each sh_guide_ray_next returns the next cell crossed with its parameter interval
 * [t0, t1). The segments tile the clipped interval exactly (t0 of one = t1 of the previous),
 * never have zero length, and agree with sh_guide_locate about which cell a point is in.
 * The track-length bake (sh_bake.c) uses the same iterator for its overlap lengths. */
#include <math.h>
#include <string.h>

#include "sh_internal.h"

/* Clip [tmin, tmax] to the box and set up the walk. A ray that misses leaves it->done = 1. The
 * first cell is fixed here without any point lookup rounding at the entry face: uniform grids
 * take the entry axis's index from the direction (first or last slab), adaptive grids snap the
 * entry coordinate to the face exactly. */
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
                it->ijk[a] = shi_ucell(g, a, o[a] + t0 * d[a]);
        }
    } else if (enter_axis >= 0) {
        /* Entering through a face: snap that coordinate to the face exactly. */
        it->snap_mask = 1 << enter_axis;
        it->snap[enter_axis] = d[enter_axis] > 0.0 ? g->lo[enter_axis] : g->hi[enter_axis];
    }
}

/* Uniform grid: it->ijk is the current cell; step to the neighbour across the nearest plane. */
/* Fill the segment [t0, t1) of cell `cell` (both walks end a step this way). */
static void emit_seg(const sh_guide *g, long cell, double t0, double t1, sh_guide_seg *seg)
{
    seg->t0 = t0;
    seg->t1 = t1;
    seg->cell = cell;
    seg->coeffs = g->coeffs + (size_t)cell * (size_t)g->ncoef;
    seg->sigma_t = g->sigma_t[cell];
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
            double ta = (shi_uplane(g, a, i) - it->o[a]) / it->d[a];
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
            emit_seg(g, cell, t0, t1, seg);
            return 1;
        }
    }
    return 0;
}

/* Octree: find the current leaf by descent from the root at the point x(t), then leave it
 * through the nearest of its faces. A step may have zero length (the ray passes exactly
 * through an edge or corner shared by several leaves); such steps return nothing, and
 * zero_steps bounds how many in a row are tolerated before the walk gives up and returns the
 * rest of the ray as one segment (a guard against an endless loop). */
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
        long cell = shi_descend(g, p, it->d, blo, bhi);
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
            emit_seg(g, cell, t0, t1, seg);
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
