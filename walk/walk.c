/* walk.c: box clip (Kay & Kajiya 1986), uniform-grid 3D-DDA (Amanatides & Woo 1987) and the
 * octree walk by descent with plane snapping (neighbour finding as in Revelles et al. 2000,
 * made robust to rounding). The contracts are in walk.h. */
#include "walk.h"

#include <math.h>
#include <string.h>

/* ---- Box clip ------------------------------------------------------------------------------- */

int wk_box_clip(const double lo[3], const double hi[3], const double o[3], const double d[3],
                double tmin, double tmax, double *t0, double *t1, int *enter_axis)
{
    if (enter_axis)
        *enter_axis = -1;
    if (!(tmin <= tmax))
        return 0;
    double a0 = tmin, a1 = tmax;
    int axis = -1;
    for (int a = 0; a < 3; a++) {
        if (!isfinite(o[a]) || !isfinite(d[a]) || !isfinite(lo[a]) || !isfinite(hi[a]))
            return 0;
        if (d[a] == 0.0) { /* parallel to the slab: inside it or a miss */
            if (o[a] < lo[a] || o[a] > hi[a])
                return 0;
            continue;
        }
        /* Kay & Kajiya: the slab lo <= x_a <= hi is crossed on [ta, tb]. */
        double ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
        if (ta > tb) {
            double s = ta;
            ta = tb, tb = s;
        }
        if (ta > a0)
            a0 = ta, axis = a;
        if (tb < a1)
            a1 = tb;
    }
    if (!(a0 < a1))
        return 0;
    *t0 = a0;
    *t1 = a1;
    if (enter_axis)
        *enter_axis = axis;
    return 1;
}

/* ---- Uniform-grid 3D-DDA -------------------------------------------------------------------- */

/* Parameter at which the ray leaves the current cell's slab on axis a (+inf when the ray is
 * parallel to it): Amanatides & Woo's tMax, evaluated afresh from the plane index (no
 * incremental tDelta, so no drift). */
static double slab_exit(const wk_dda *w, int a)
{
    if (w->step[a] == 0)
        return INFINITY;
    int i = w->ijk[a] + (w->step[a] > 0 ? 1 : 0);
    double num = wk_plane(w->lo[a], w->hi[a], w->h[a], w->res[a], i) - w->o[a];
    /* times 1/d, found once a walk (a division costs several multiplications' time, and this
     * runs at every step of every walk); the division where 1/d overflows (|d| subnormal) */
    return isfinite(w->inv[a]) ? num * w->inv[a] : num / w->d[a];
}

/* The nearest of the three slab exits and its axis (-1 when the ray is parallel to every axis);
 * the first axis wins a tie. */
static double dda_exit(const wk_dda *w, int *axis)
{
    double tn = INFINITY;
    *axis = -1;
    for (int a = 0; a < 3; a++)
        if (w->step[a] != 0 && w->tx[a] < tn)
            tn = w->tx[a], *axis = a;
    return tn;
}

void wk_dda_begin(wk_dda *w, const double lo[3], const double hi[3], const int res[3],
                  const double o[3], const double d[3], double t0, double t1, int enter_axis)
{
    memset(w, 0, sizeof *w);
    w->done = 1;
    if (!(t0 < t1) || !isfinite(t0))
        return;
    for (int a = 0; a < 3; a++) {
        if (res[a] < 1 || !isfinite(o[a]) || !isfinite(d[a]))
            return;
        w->lo[a] = lo[a];
        w->hi[a] = hi[a];
        w->res[a] = res[a];
        w->h[a] = (hi[a] - lo[a]) / res[a];
        w->o[a] = o[a];
        w->d[a] = d[a];
        w->step[a] = d[a] > 0.0 ? 1 : d[a] < 0.0 ? -1 : 0;
        w->inv[a] = d[a] != 0.0 ? 1.0 / d[a] : INFINITY;
    }
    /* The first cell (Amanatides & Woo's initialisation): on the entry face's axis it is the
     * first or last slab by the direction alone; elsewhere the cell holding x(t0). */
    for (int a = 0; a < 3; a++) {
        if (a == enter_axis && d[a] != 0.0)
            w->ijk[a] = d[a] > 0.0 ? 0 : res[a] - 1;
        else
            w->ijk[a] = wk_cell_of(lo[a], hi[a], w->h[a], res[a], o[a] + t0 * d[a]);
    }
    for (int a = 0; a < 3; a++)
        w->tx[a] = slab_exit(w, a);
    w->t = t0;
    w->tend = t1;
    w->done = 0;
}

int wk_dda_next(wk_dda *w, wk_dda_seg *s)
{
    while (!w->done) {
        int axis;
        double tn = dda_exit(w, &axis);
        double t0 = w->t, t1 = tn < w->tend ? tn : w->tend;
        if (t1 < t0)
            t1 = t0;
        int ijk[3] = {w->ijk[0], w->ijk[1], w->ijk[2]};
        if (t1 >= w->tend) {
            w->done = 1;
        } else {
            /* Amanatides & Woo's step: to the neighbour across the nearest plane. */
            int ni = w->ijk[axis] + w->step[axis];
            if (ni < 0 || ni >= w->res[axis]) {
                t1 = w->tend; /* left the grid before tend: only by rounding; the rest is here */
                w->done = 1;
            } else {
                w->ijk[axis] = ni;
                w->tx[axis] = slab_exit(w, axis); /* only the crossed axis's exit moves */
            }
        }
        w->t = t1;
        if (t1 > t0) {
            s->ta = t0;
            s->tb = t1;
            for (int a = 0; a < 3; a++)
                s->ijk[a] = ijk[a];
            s->cell = ijk[0] + (long)w->res[0] * (ijk[1] + (long)w->res[1] * ijk[2]);
            return 1;
        }
    }
    return 0;
}

/* ---- Octree walk ---------------------------------------------------------------------------- */

void wk_tree_begin(wk_tree_walk *w, wk_locate_fn locate, const void *tree, const double lo[3],
                   const double hi[3], const double o[3], const double d[3], double t0, double t1,
                   int enter_axis, int max_depth)
{
    memset(w, 0, sizeof *w);
    w->done = 1;
    if (!locate || !(t0 < t1) || !isfinite(t0))
        return;
    for (int a = 0; a < 3; a++) {
        if (!isfinite(o[a]) || !isfinite(d[a]))
            return;
        w->lo[a] = lo[a];
        w->hi[a] = hi[a];
        w->o[a] = o[a];
        w->d[a] = d[a];
    }
    w->locate = locate;
    w->tree = tree;
    w->t = t0;
    w->tend = t1;
    w->max_zero = 4 * (max_depth > 0 ? max_depth : 0) + 16;
    if (enter_axis >= 0 && enter_axis < 3 && d[enter_axis] != 0.0) {
        /* Entering through a face: snap that coordinate to the face exactly. */
        w->snap_mask = 1 << enter_axis;
        w->snap[enter_axis] = d[enter_axis] > 0.0 ? lo[enter_axis] : hi[enter_axis];
    }
    w->done = 0;
}

/* The leaf's exit: the nearest of its faces ahead of the ray. Sets *exit_mask to the axes whose
 * face is crossed at that parameter (several at an edge or corner) and plane[a] to the face of
 * each axis; *at_box when one of the crossed faces is the root box's. */
static double tree_exit(const wk_tree_walk *w, const double blo[3], const double bhi[3],
                        int *exit_mask, double plane[3], int *at_box)
{
    double t1 = w->tend;
    *exit_mask = 0;
    *at_box = 0;
    for (int a = 0; a < 3; a++) {
        plane[a] = 0.0;
        if (w->d[a] == 0.0)
            continue;
        plane[a] = w->d[a] > 0.0 ? bhi[a] : blo[a];
        double ta = (plane[a] - w->o[a]) / w->d[a];
        if (ta < t1) {
            t1 = ta;
            *exit_mask = 1 << a;
        } else if (ta == t1) {
            *exit_mask |= 1 << a;
        }
    }
    for (int a = 0; a < 3; a++)
        if ((*exit_mask & (1 << a)) &&
            (w->d[a] > 0.0 ? bhi[a] >= w->hi[a] : blo[a] <= w->lo[a]))
            *at_box = 1;
    return t1;
}

int wk_tree_next(wk_tree_walk *w, wk_tree_seg *s)
{
    int zero_steps = 0;
    while (!w->done) {
        /* Neighbour stepping by descent from the root: the point at t, with the coordinates
         * of the planes just crossed snapped exactly, picks the next leaf. */
        double p[3], blo[3], bhi[3];
        for (int a = 0; a < 3; a++)
            p[a] = (w->snap_mask & (1 << a)) ? w->snap[a] : w->o[a] + w->t * w->d[a];
        long leaf = w->locate(w->tree, p, w->d, blo, bhi);
        if (leaf < 0) {
            w->done = 1;
            break;
        }
        int exit_mask, at_box;
        double plane[3];
        double t0 = w->t, t1 = tree_exit(w, blo, bhi, &exit_mask, plane, &at_box);
        /* Leaving the root box before tend happens only by rounding: the rest is this leaf. */
        if (t1 >= w->tend || at_box || ++zero_steps > w->max_zero) {
            t1 = w->tend;
            w->done = 1;
        }
        if (t1 < t0)
            t1 = t0;
        if (!w->done) {
            if (t1 > t0)
                w->snap_mask = 0; /* moved on: earlier snaps no longer hold */
            w->snap_mask |= exit_mask;
            for (int a = 0; a < 3; a++)
                if (exit_mask & (1 << a))
                    w->snap[a] = plane[a];
        }
        w->t = t1;
        if (t1 > t0) {
            s->ta = t0;
            s->tb = t1;
            s->leaf = leaf;
            for (int a = 0; a < 3; a++)
                s->lo[a] = blo[a], s->hi[a] = bhi[a];
            return 1;
        }
    }
    return 0;
}
