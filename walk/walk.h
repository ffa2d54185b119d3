/* walk.h: the one ray walk of photonmarch: box clip, uniform-grid 3D-DDA and octree walk.
 *
 * A leaf module (prefix wk_): plain double arrays, no allocation, no dependency on any other
 * module; sh/ (guide grids) and renderer/ (majorant grids and octrees) both walk through it.
 * The iterators are value types (DESIGN.md convention 7): begin fills one, next returns one
 * segment at a time; their fields are private.
 *
 * Ray x(t) = o + t d; d need not be unit (t is in units of |d|). Boxes are [lo, hi] with
 * lo < hi on every axis. */
#ifndef WALK_H
#define WALK_H

/* ---- Box clip (Kay & Kajiya 1986, slabs) ------------------------------------------------------
 * Clip [tmin, tmax] to the box [lo, hi]. Returns 1 and sets *t0 < *t1 when the ray crosses the
 * box with positive length; returns 0 (and leaves *t0, *t1 alone) otherwise. An axis-parallel
 * ray (d[a] == 0) outside the slab of axis a misses; any non-finite o, d, lo or hi misses; a
 * NaN tmin or tmax misses (tmax = +inf is fine). *enter_axis (may be NULL) receives the axis
 * whose slab set *t0 (the ray enters through that face at *t0), or -1 when *t0 = tmin, i.e.
 * the ray starts inside (or on the face of) the box; -1 also on a miss. */
int wk_box_clip(const double lo[3], const double hi[3], const double o[3], const double d[3],
                double tmin, double tmax, double *t0, double *t1, int *enter_axis);

/* ---- Uniform grid geometry --------------------------------------------------------------------
 * One axis of a grid of n >= 1 equal cells over [lo, hi], cell edge h = (hi - lo) / n.
 * Plane i (0..n) of that axis; planes 0 and n are the box faces exactly, so the box clip, the
 * DDA and a point lookup agree to the bit. */
static inline double wk_plane(double lo, double hi, double h, int n, int i)
{
    if (i <= 0)
        return lo;
    if (i >= n)
        return hi;
    return lo + h * i;
}

/* Cell holding coordinate p on that axis: half-open [plane_i, plane_i+1), clamped to 0..n-1
 * (NaN gives 0). The division is only a first guess; the comparison with the planes as
 * wk_plane computes them decides, so lookups and the DDA agree. */
static inline int wk_cell_of(double lo, double hi, double h, int n, double p)
{
    double f = (p - lo) / h;
    int i = !(f > 0.0) ? 0 : f >= n ? n - 1 : (int)f;
    if (i > 0 && p < wk_plane(lo, hi, h, n, i))
        i--;
    else if (i < n - 1 && p >= wk_plane(lo, hi, h, n, i + 1))
        i++;
    return i;
}

/* ---- Uniform-grid 3D-DDA (Amanatides & Woo 1987) ----------------------------------------------
 *
 *     wk_dda w;  wk_dda_seg s;
 *     wk_dda_begin(&w, lo, hi, res, o, d, t0, t1, enter_axis);
 *     while (wk_dda_next(&w, &s))  ... cell s.cell (s.ijk) on [s.ta, s.tb) ...
 *
 * [t0, t1] is the ray's interval already clipped to the box (wk_box_clip). enter_axis is the
 * axis the ray entered the box through at t0 (from wk_box_clip), or -1: on that axis the first
 * cell is taken from the direction (first or last slab) rather than from a rounded point
 * lookup; on the others, and for -1, the first cell is the one holding x(t0) (wk_cell_of).
 * The segments tile [t0, t1] exactly in increasing t (ta of one = tb of the previous, the first
 * ta = t0, the last tb = t1) and never have zero length (crossings through an edge or corner
 * are skipped). Each axis's exit parameter is computed from the plane index when the walk
 * steps on that axis (one multiplication by 1/d per step, not three), never accumulated, so
 * there is no drift. If rounding takes the walk out of the grid before t1, the rest of [t0, t1] goes to the
 * last cell. */
typedef struct {
    double ta, tb; /* the cell's piece of the ray, ta < tb */
    int ijk[3];    /* cell indices */
    long cell;     /* linear index, x fastest: i + nx (j + ny k) */
} wk_dda_seg;

typedef struct {
    /* private */
    double lo[3], hi[3], h[3];
    int res[3];
    double o[3], d[3], inv[3]; /* inv: 1/d (inf where d is 0 or 1/d overflows) */
    double t, tend;
    int ijk[3], step[3];
    double tx[3]; /* where the ray leaves the current cell's slab on each axis (inf: parallel) */
    int done;
} wk_dda;

void wk_dda_begin(wk_dda *w, const double lo[3], const double hi[3], const int res[3],
                  const double o[3], const double d[3], double t0, double t1, int enter_axis);
int wk_dda_next(wk_dda *w, wk_dda_seg *s);

/* ---- Octree / adaptive walk (neighbour finding by descent, after Revelles et al. 2000) --------
 *
 * The tree is reached only through locate: the leaf containing p, a coordinate on a splitting
 * plane going to the side d heads to (d[a] > 0 or, as the tree chooses, d[a] >= 0: the upper
 * side), with the leaf's box in lo, hi. It returns the leaf id (>= 0), or < 0 to end the walk.
 *
 * Each step descends at the point x(t) with the coordinates of the planes just crossed snapped
 * to the exact plane value, so rounding can never send the walk back into the leaf it left;
 * the walk leaves the leaf through its nearest face. Steps of zero length (the ray passes
 * exactly through an edge or corner shared by several leaves) return nothing; more than
 * 4 max_depth + 16 of them in a row end the walk with the rest of the ray as one segment (a
 * guard against an endless loop). Leaving the root box by rounding before t1 gives the rest to
 * the current leaf. Same tiling guarantees as the DDA. */
typedef long (*wk_locate_fn)(const void *tree, const double p[3], const double d[3],
                             double lo[3], double hi[3]);

typedef struct {
    double ta, tb;        /* the leaf's piece of the ray, ta < tb */
    long leaf;            /* what locate returned */
    double lo[3], hi[3];  /* the leaf's box */
} wk_tree_seg;

typedef struct {
    /* private */
    wk_locate_fn locate;
    const void *tree;
    double lo[3], hi[3]; /* root box */
    double o[3], d[3];
    double t, tend;
    int snap_mask;       /* axes whose coordinate is snapped to snap[] */
    double snap[3];
    int max_zero;        /* zero-length steps tolerated in a row */
    int done;
} wk_tree_walk;

/* [t0, t1] and enter_axis as for wk_dda_begin; max_depth: the deepest leaf level of the tree. */
void wk_tree_begin(wk_tree_walk *w, wk_locate_fn locate, const void *tree, const double lo[3],
                   const double hi[3], const double o[3], const double d[3], double t0, double t1,
                   int enter_axis, int max_depth);
int wk_tree_next(wk_tree_walk *w, wk_tree_seg *s);

#endif /* WALK_H */
