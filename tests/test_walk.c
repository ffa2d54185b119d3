/* walk/ (walk.h): the box clip, the uniform-grid 3D-DDA and the octree walk, against brute force.
 *  - clip: hits, misses, axis-parallel rays on and off a slab, non-finite input, entry axis;
 *  - DDA: on random boxes, resolutions and rays (fixed seeds), the segments tile the clipped
 *    interval exactly, never have zero length, every sampled point of a segment lies in the
 *    segment's cell (cell found by scanning the planes), and each cell's total length equals
 *    its slab overlap with the ray; rays along cell planes, through cell corners, axis-parallel
 *    rays, rays starting inside, and a walk asked past the box's exit;
 *  - octree walk: the same checks against a brute-force descent on small random trees.
 * The brute-force lengths are compared with an absolute 1e-9 on boxes of size ~1: the only
 * error is rounding of a few operations per plane (~1e-15), so this cannot hide a wrong cell
 * (a wrong cell is off by a whole piece of the ray). */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "support/test_rng.h"
#include "walk.h"

/* ---- brute force ------------------------------------------------------------------------------ */

/* Length of the ray's overlap with the closed box [lo, hi] within [t0, t1] (independent slab
 * arithmetic, not wk_box_clip). */
static double overlap(const double lo[3], const double hi[3], const double o[3], const double d[3],
                      double t0, double t1)
{
    for (int a = 0; a < 3; a++) {
        if (d[a] == 0.0) {
            if (o[a] < lo[a] || o[a] > hi[a])
                return 0.0;
            continue;
        }
        double x = (lo[a] - o[a]) / d[a], y = (hi[a] - o[a]) / d[a];
        t0 = fmax(t0, fmin(x, y));
        t1 = fmin(t1, fmax(x, y));
    }
    return t1 > t0 ? t1 - t0 : 0.0;
}

/* The grid's planes of one axis as the contract defines them: lo + h i, the ends exact. */
static double plane(double lo, double hi, int n, int i)
{
    return i == 0 ? lo : i == n ? hi : lo + (hi - lo) / n * i;
}

/* Cell of coordinate p by scanning the planes (half-open cells, clamped). */
static int scan_cell(double lo, double hi, int n, double p)
{
    for (int i = 0; i < n - 1; i++)
        if (p < plane(lo, hi, n, i + 1))
            return i;
    return n - 1;
}

static void random_ray(rng *r, const double lo[3], const double hi[3], double o[3], double d[3])
{
    for (int a = 0; a < 3; a++) {
        double c = 0.5 * (lo[a] + hi[a]), e = 0.75 * (hi[a] - lo[a]);
        o[a] = c + e * (2.0 * rng_u01(r) - 1.0);
    }
    rng_dir(r, d);
    if (rng_u01(r) < 0.15) { /* axis-parallel: the DDA's zero-step axes */
        int a = (int)(3 * rng_u01(r));
        d[0] = d[1] = d[2] = 0.0;
        d[a] = rng_u01(r) < 0.5 ? -1.0 : 1.0;
    } else if (rng_u01(r) < 0.15) { /* in a coordinate plane: one zero component */
        d[(int)(3 * rng_u01(r))] = 0.0;
    }
}

/* A small octree for the tests: node n is a leaf when child[n] < 0, else its 8 children are
 * child[n] + c, bit a of c = upper half of axis a; splits at the box midpoint. */
typedef struct {
    double lo[3], hi[3];
    int child[4096];
    int n;
    int depth;
} tree;

static void tree_split(tree *t, rng *r, int node, int level)
{
    t->child[node] = -1;
    if (level >= t->depth || rng_u01(r) < 0.35 || t->n + 8 > 4096)
        return;
    int first = t->n;
    t->n += 8;
    t->child[node] = first;
    for (int c = 0; c < 8; c++)
        tree_split(t, r, first + c, level + 1);
}

/* The locate callback: ties on a midplane go up when d >= 0. */
static long tree_locate(const void *tp, const double p[3], const double d[3], double lo[3], double hi[3])
{
    const tree *t = tp;
    memcpy(lo, t->lo, sizeof t->lo);
    memcpy(hi, t->hi, sizeof t->hi);
    int n = 0;
    while (t->child[n] >= 0) {
        int c = 0;
        for (int a = 0; a < 3; a++) {
            double mid = 0.5 * (lo[a] + hi[a]);
            if (p[a] > mid || (p[a] == mid && d[a] >= 0.0))
                c |= 1 << a, lo[a] = mid;
            else
                hi[a] = mid;
        }
        n = t->child[n] + c;
    }
    return n;
}

/* ---- clip ------------------------------------------------------------------------------------- */

static const double U0[3] = {0, 0, 0}, U1[3] = {1, 1, 1};

Test(walk, clip_hits_misses_and_entry_axis)
{
    double t0, t1;
    int ax;
    /* Through the x faces from outside: enters through x at 1. */
    cr_assert(wk_box_clip(U0, U1, (double[]){-1, 0.5, 0.5}, (double[]){1, 0, 0}, 0, INFINITY, &t0, &t1, &ax));
    cr_expect(t0 == 1.0 && t1 == 2.0 && ax == 0, "t0 %g t1 %g axis %d", t0, t1, ax);
    /* From above, heading down: enters through the z = 1 face, axis 2. */
    cr_assert(wk_box_clip(U0, U1, (double[]){0.25, 0.5, 3}, (double[]){0, 0, -2}, 0, 10, &t0, &t1, &ax));
    cr_expect(t0 == 1.0 && t1 == 1.5 && ax == 2);
    /* Starting inside: t0 = tmin, axis -1. */
    cr_assert(wk_box_clip(U0, U1, (double[]){0.5, 0.5, 0.5}, (double[]){0.3, -0.2, 0.1}, 0, INFINITY, &t0, &t1, &ax));
    cr_expect(t0 == 0.0 && ax == -1 && fabs(t1 - 0.5 / 0.3) < 1e-15);
    /* tmax before the box: miss; tmin after it: miss. */
    cr_expect(!wk_box_clip(U0, U1, (double[]){-1, 0.5, 0.5}, (double[]){1, 0, 0}, 0, 0.5, &t0, &t1, &ax));
    cr_expect(!wk_box_clip(U0, U1, (double[]){-1, 0.5, 0.5}, (double[]){1, 0, 0}, 2.5, 3, &t0, &t1, &ax));
    /* Pointing away. */
    cr_expect(!wk_box_clip(U0, U1, (double[]){-1, 0.5, 0.5}, (double[]){-1, 0, 0}, 0, INFINITY, &t0, &t1, &ax));
    cr_expect(ax == -1);
}

Test(walk, clip_axis_parallel_rays_and_faces)
{
    double t0, t1;
    int ax;
    /* Parallel to x, outside the y slab: miss, whatever t range. */
    cr_expect(!wk_box_clip(U0, U1, (double[]){-1, 1.5, 0.5}, (double[]){1, 0, 0}, -INFINITY, INFINITY, &t0, &t1, &ax));
    cr_expect(!wk_box_clip(U0, U1, (double[]){-1, -1e-300, 0.5}, (double[]){1, 0, 0}, 0, INFINITY, &t0, &t1, &ax));
    /* Lying in the face y = 1 (closed slab): a hit of length 1. */
    cr_expect(wk_box_clip(U0, U1, (double[]){-1, 1, 0.5}, (double[]){1, 0, 0}, 0, INFINITY, &t0, &t1, &ax));
    cr_expect(t0 == 1.0 && t1 == 2.0 && ax == 0);
    /* Along an edge (y = 0, z = 1). */
    cr_expect(wk_box_clip(U0, U1, (double[]){2, 0, 1}, (double[]){-1, 0, 0}, 0, INFINITY, &t0, &t1, &ax));
    cr_expect(t0 == 1.0 && t1 == 2.0 && ax == 0);
    /* Touching the box at one corner only: zero length, a miss. */
    cr_expect(!wk_box_clip(U0, U1, (double[]){2, 0, 0.5}, (double[]){-1, 1, 0}, 0, INFINITY, &t0, &t1, &ax));
    /* An interval of zero length inside the box: a miss. */
    cr_expect(!wk_box_clip(U0, U1, (double[]){0.5, 0.5, 0.5}, (double[]){1, 0, 0}, 0.1, 0.1, &t0, &t1, &ax));
}

Test(walk, clip_non_finite_input_misses)
{
    double t0 = 7, t1 = 7;
    int ax = 5;
    const double o[3] = {-1, 0.5, 0.5}, d[3] = {1, 0, 0};
    cr_expect(!wk_box_clip(U0, U1, (double[]){NAN, 0.5, 0.5}, d, 0, INFINITY, &t0, &t1, &ax));
    cr_expect(t0 == 7 && t1 == 7 && ax == -1, "a miss leaves t0, t1 alone and sets axis -1");
    cr_expect(!wk_box_clip(U0, U1, (double[]){-INFINITY, 0.5, 0.5}, d, 0, INFINITY, &t0, &t1, &ax));
    cr_expect(!wk_box_clip(U0, U1, o, (double[]){1, NAN, 0}, 0, INFINITY, &t0, &t1, &ax));
    cr_expect(!wk_box_clip(U0, U1, o, (double[]){INFINITY, 0, 0}, 0, INFINITY, &t0, &t1, &ax));
    cr_expect(!wk_box_clip((double[]){NAN, 0, 0}, U1, o, d, 0, INFINITY, &t0, &t1, &ax));
    cr_expect(!wk_box_clip(U0, (double[]){1, INFINITY, 1}, o, d, 0, INFINITY, &t0, &t1, &ax));
    cr_expect(!wk_box_clip(U0, U1, o, d, NAN, INFINITY, &t0, &t1, &ax));
    cr_expect(!wk_box_clip(U0, U1, o, d, 0, NAN, &t0, &t1, &ax));
    cr_expect(!wk_box_clip(U0, U1, o, d, 3, 1, &t0, &t1, &ax), "tmin > tmax");
    cr_expect(wk_box_clip(U0, U1, o, d, 0, INFINITY, &t0, &t1, NULL), "enter_axis may be NULL");
}

/* ---- DDA -------------------------------------------------------------------------------------- */

/* Walk the clipped ray and check the DDA contract against brute force; returns segments. */
static int check_dda(const double lo[3], const double hi[3], const int res[3], const double o[3],
                     const double d[3], double t0, double t1, int enter, double *len)
{
    long nc = (long)res[0] * res[1] * res[2];
    for (long q = 0; q < nc; q++)
        len[q] = 0.0;
    wk_dda w;
    wk_dda_seg s;
    wk_dda_begin(&w, lo, hi, res, o, d, t0, t1, enter);
    double tprev = t0;
    int nseg = 0, prev[3] = {0, 0, 0};
    while (wk_dda_next(&w, &s)) {
        cr_assert(++nseg <= res[0] + res[1] + res[2] + 3, "more segments than planes");
        cr_assert(s.ta == tprev, "segment %d starts at %.17g, the previous ended at %.17g", nseg, s.ta, tprev);
        cr_assert(s.tb > s.ta, "zero-length segment at %.17g", s.ta);
        cr_assert(s.cell == s.ijk[0] + (long)res[0] * (s.ijk[1] + (long)res[1] * s.ijk[2]));
        for (int a = 0; a < 3; a++) {
            cr_assert(s.ijk[a] >= 0 && s.ijk[a] < res[a]);
            /* Cells only move the way the ray goes. */
            if (nseg > 1)
                cr_assert(d[a] > 0 ? s.ijk[a] >= prev[a] : d[a] < 0 ? s.ijk[a] <= prev[a] : s.ijk[a] == prev[a]);
        }
        memcpy(prev, s.ijk, sizeof prev);
        /* Points inside the segment (away from its ends by more than rounding) are in its cell. */
        if (s.tb - s.ta > 1e-9)
            for (int k = 1; k < 8; k++) {
                double t = s.ta + (s.tb - s.ta) * k / 8.0;
                for (int a = 0; a < 3; a++) {
                    int c = scan_cell(lo[a], hi[a], res[a], o[a] + t * d[a]);
                    cr_assert(c == s.ijk[a], "t %.17g axis %d: point in cell %d, segment's cell %d", t, a, c, s.ijk[a]);
                }
            }
        len[s.cell] += s.tb - s.ta;
        tprev = s.tb;
    }
    cr_assert(nseg > 0);
    cr_assert(tprev == t1, "the walk ends at %.17g, not at t1 = %.17g", tprev, t1);
    cr_assert(!wk_dda_next(&w, &s), "a finished walk stays finished");
    return nseg;
}

/* Each cell's length against its slab overlap with the ray. */
static void check_lengths(const double lo[3], const double hi[3], const int res[3], const double o[3],
                          const double d[3], double t0, double t1, const double *len)
{
    for (int k = 0; k < res[2]; k++)
        for (int j = 0; j < res[1]; j++)
            for (int i = 0; i < res[0]; i++) {
                const int ijk[3] = {i, j, k};
                double clo[3], chi[3];
                for (int a = 0; a < 3; a++) {
                    clo[a] = plane(lo[a], hi[a], res[a], ijk[a]);
                    chi[a] = plane(lo[a], hi[a], res[a], ijk[a] + 1);
                }
                double l = overlap(clo, chi, o, d, t0, t1);
                long q = i + (long)res[0] * (j + (long)res[1] * k);
                cr_assert(fabs(l - len[q]) < 1e-9, "cell (%d,%d,%d): brute force %.12g, DDA %.12g", i, j, k, l, len[q]);
            }
}

Test(walk, dda_matches_brute_force_on_random_rays)
{
    rng r = rng_new(20261123);
    double *len = malloc(8 * 8 * 8 * sizeof *len);
    int walked = 0;
    for (int g = 0; g < 40; g++) {
        double lo[3], hi[3];
        int res[3];
        for (int a = 0; a < 3; a++) {
            lo[a] = 4.0 * rng_u01(&r) - 2.0;
            hi[a] = lo[a] + 0.3 + 2.0 * rng_u01(&r); /* not dyadic: planes round */
            res[a] = 1 + (int)(8 * rng_u01(&r));
        }
        for (int k = 0; k < 300; k++) {
            double o[3], d[3], t0, t1;
            int enter;
            random_ray(&r, lo, hi, o, d);
            if (!wk_box_clip(lo, hi, o, d, 0.0, INFINITY, &t0, &t1, &enter))
                continue;
            check_dda(lo, hi, res, o, d, t0, t1, enter, len);
            check_lengths(lo, hi, res, o, d, t0, t1, len);
            walked++;
        }
    }
    cr_expect(walked > 4000, "only %d rays crossed their box", walked); /* the test ran */
    free(len);
}

Test(walk, dda_rays_through_corners_and_along_planes)
{
    /* A 4^3 grid of unit cells: every plane is exact, so the expected walks are exact too. */
    const double lo[3] = {0, 0, 0}, hi[3] = {4, 4, 4};
    const int res[3] = {4, 4, 4};
    double len[64], t0, t1;
    int enter;
    struct {
        double o[3], d[3];
        int n;        /* segments expected */
        int first[3]; /* first cell expected */
    } cases[] = {
        {{-1, -1, -1}, {1, 1, 1}, 4, {0, 0, 0}},       /* through every cell corner (i, i, i) */
        {{5, 5, 5}, {-1, -1, -1}, 4, {3, 3, 3}},       /* the same, backwards */
        {{-1, -1, 0.5}, {1, 1, 0}, 4, {0, 0, 0}},      /* through the edges (i, i, z) */
        {{-1, 2, 0.5}, {1, 0, 0}, 4, {0, 2, 0}},       /* along the plane y = 2: the upper cell */
        {{5, 2, 3}, {-1, 0, 0}, 4, {3, 2, 3}},         /* along the edge y = 2, z = 3, backwards */
        {{0.5, 4, -1}, {0, 0, 1}, 4, {0, 3, 0}},       /* in the box face y = 4: the last cell */
        {{1, 1, -1}, {0, 0, 1}, 4, {1, 1, 0}},         /* along the edge x = 1, y = 1 */
        {{-2, 0.5, 0.5}, {1, 0.5, 0}, 4, {0, 1, 0}},   /* enters at (0, 1.5), corners (1, 2), (3, 3) */
        {{-1, 2.5, 0.5}, {1, 1e-310, 0}, 4, {0, 2, 0}}, /* a subnormal component (1/d overflows):
                                                          walked as a ray parallel to y's planes */
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        cr_assert(wk_box_clip(lo, hi, cases[c].o, cases[c].d, 0, INFINITY, &t0, &t1, &enter), "case %zu", c);
        int n = check_dda(lo, hi, res, cases[c].o, cases[c].d, t0, t1, enter, len);
        cr_expect(n == cases[c].n, "case %zu: %d segments, expected %d", c, n, cases[c].n);
        wk_dda w;
        wk_dda_seg s;
        wk_dda_begin(&w, lo, hi, res, cases[c].o, cases[c].d, t0, t1, enter);
        cr_assert(wk_dda_next(&w, &s));
        cr_expect(memcmp(s.ijk, cases[c].first, sizeof s.ijk) == 0, "case %zu: first cell (%d,%d,%d)", c,
                  s.ijk[0], s.ijk[1], s.ijk[2]);
    }
}

Test(walk, dda_first_cell_from_the_entry_face)
{
    /* A ray entering through the upper x face of a grid whose planes round: the entry axis
     * gives the last x cell although x(t0) computed by o + t0 d may round either way. */
    const double lo[3] = {-0.3, 0.1, 0.7}, hi[3] = {1.1, 0.9, 1.3};
    const int res[3] = {7, 3, 5};
    rng r = rng_new(99);
    double len[105];
    for (int k = 0; k < 2000; k++) {
        double o[3] = {1.1 + 3 * rng_u01(&r), 0.1 + 0.8 * rng_u01(&r), 0.7 + 0.6 * rng_u01(&r)};
        double d[3] = {-1.0, 0.2 * (2 * rng_u01(&r) - 1), 0.2 * (2 * rng_u01(&r) - 1)};
        double t0, t1;
        int enter;
        if (!wk_box_clip(lo, hi, o, d, 0, INFINITY, &t0, &t1, &enter) || enter != 0)
            continue;
        wk_dda w;
        wk_dda_seg s;
        wk_dda_begin(&w, lo, hi, res, o, d, t0, t1, enter);
        cr_assert(wk_dda_next(&w, &s));
        cr_assert(s.ijk[0] == res[0] - 1 && s.ta == t0);
        check_dda(lo, hi, res, o, d, t0, t1, enter, len);
    }
}

Test(walk, dda_starting_inside_and_past_the_exit)
{
    const double lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
    const int res[3] = {5, 3, 4};
    double len[60];
    rng r = rng_new(7);
    for (int k = 0; k < 1000; k++) {
        double o[3], d[3], t0, t1;
        int enter;
        for (int a = 0; a < 3; a++)
            o[a] = 1.8 * rng_u01(&r) - 0.9;
        rng_dir(&r, d);
        cr_assert(wk_box_clip(lo, hi, o, d, 0, INFINITY, &t0, &t1, &enter));
        cr_assert(t0 == 0.0 && enter == -1, "inside: starts at tmin with no entry axis");
        check_dda(lo, hi, res, o, d, t0, t1, enter, len);
        check_lengths(lo, hi, res, o, d, t0, t1, len);
        /* Asked to go on past the exit, the walk gives the rest to the last cell and ends at
         * the asked t1 (the contract for leaving the grid by rounding). */
        wk_dda w;
        wk_dda_seg s, last = {0};
        wk_dda_begin(&w, lo, hi, res, o, d, t0, t1 + 1.0, enter);
        while (wk_dda_next(&w, &s))
            last = s;
        cr_assert(last.tb == t1 + 1.0);
    }
}

Test(walk, dda_degenerate_input_gives_nothing)
{
    const int res[3] = {2, 2, 2};
    wk_dda w;
    wk_dda_seg s;
    wk_dda_begin(&w, U0, U1, res, (double[]){0.5, 0.5, 0.5}, (double[]){1, 0, 0}, 0.2, 0.2, -1);
    cr_expect(!wk_dda_next(&w, &s), "empty interval");
    wk_dda_begin(&w, U0, U1, res, (double[]){NAN, 0.5, 0.5}, (double[]){1, 0, 0}, 0.0, 0.2, -1);
    cr_expect(!wk_dda_next(&w, &s), "non-finite origin");
    wk_dda_begin(&w, U0, U1, (const int[]){2, 0, 2}, (double[]){0.5, 0.5, 0.5}, (double[]){1, 0, 0}, 0.0, 0.2, -1);
    cr_expect(!wk_dda_next(&w, &s), "a zero resolution");
    /* d = 0: one segment, the cell of the point. */
    wk_dda_begin(&w, U0, U1, res, (double[]){0.75, 0.25, 0.5}, (double[]){0, 0, 0}, 0.0, 0.2, -1);
    cr_assert(wk_dda_next(&w, &s));
    cr_expect(s.cell == 1 + 2 * (0 + 2 * 1) && s.ta == 0.0 && s.tb == 0.2);
    cr_expect(!wk_dda_next(&w, &s));
}

/* ---- octree ----------------------------------------------------------------------------------- */

/* Brute force: the leaf whose closed box holds p, by testing every leaf's box (boxes rebuilt
 * from the root by recursion, independent of the walk's descent). */
static void leaf_boxes(const tree *t, int node, const double lo[3], const double hi[3], double *blo, double *bhi)
{
    memcpy(blo + 3 * node, lo, 3 * sizeof *lo);
    memcpy(bhi + 3 * node, hi, 3 * sizeof *hi);
    if (t->child[node] < 0)
        return;
    for (int c = 0; c < 8; c++) {
        double clo[3], chi[3];
        for (int a = 0; a < 3; a++) {
            double mid = 0.5 * (lo[a] + hi[a]);
            clo[a] = (c >> a) & 1 ? mid : lo[a];
            chi[a] = (c >> a) & 1 ? hi[a] : mid;
        }
        leaf_boxes(t, t->child[node] + c, clo, chi, blo, bhi);
    }
}

static void check_tree_walk(const tree *t, const double *blo, const double *bhi, const double o[3],
                            const double d[3], double t0, double t1, int enter, double *len)
{
    for (int n = 0; n < t->n; n++)
        len[n] = 0.0;
    wk_tree_walk w;
    wk_tree_seg s;
    wk_tree_begin(&w, tree_locate, t, t->lo, t->hi, o, d, t0, t1, enter, t->depth);
    double tprev = t0;
    int nseg = 0;
    while (wk_tree_next(&w, &s)) {
        cr_assert(++nseg < 10000);
        cr_assert(s.ta == tprev && s.tb > s.ta, "tiling: %.17g after %.17g, ends %.17g", s.ta, tprev, s.tb);
        cr_assert(s.leaf >= 0 && s.leaf < t->n && t->child[s.leaf] < 0, "not a leaf: %ld", s.leaf);
        for (int a = 0; a < 3; a++)
            cr_assert(s.lo[a] == blo[3 * s.leaf + a] && s.hi[a] == bhi[3 * s.leaf + a], "the leaf's box");
        if (s.tb - s.ta > 1e-9)
            for (int k = 1; k < 8; k++) {
                double tt = s.ta + (s.tb - s.ta) * k / 8.0, p[3];
                for (int a = 0; a < 3; a++)
                    p[a] = o[a] + tt * d[a];
                for (int a = 0; a < 3; a++)
                    cr_assert(p[a] >= s.lo[a] && p[a] <= s.hi[a], "point outside the segment's leaf");
            }
        len[s.leaf] += s.tb - s.ta;
        tprev = s.tb;
    }
    cr_assert(tprev == t1, "the walk ends at %.17g, not %.17g", tprev, t1);
    for (int n = 0; n < t->n; n++)
        if (t->child[n] < 0) {
            double l = overlap(blo + 3 * n, bhi + 3 * n, o, d, t0, t1);
            cr_assert(fabs(l - len[n]) < 1e-9, "leaf %d: brute force %.12g, walk %.12g", n, l, len[n]);
        }
}

Test(walk, octree_walk_matches_brute_force)
{
    static tree t;
    static double blo[3 * 4096], bhi[3 * 4096], len[4096];
    rng r = rng_new(4242);
    int walked = 0;
    for (int g = 0; g < 20; g++) {
        for (int a = 0; a < 3; a++) {
            t.lo[a] = 2.0 * rng_u01(&r) - 1.0;
            t.hi[a] = t.lo[a] + 0.5 + rng_u01(&r);
        }
        t.n = 1;
        t.depth = 4;
        tree_split(&t, &r, 0, 0);
        leaf_boxes(&t, 0, t.lo, t.hi, blo, bhi);
        for (int k = 0; k < 150; k++) {
            double o[3], d[3], t0, t1;
            int enter;
            random_ray(&r, t.lo, t.hi, o, d);
            if (rng_u01(&r) < 0.2) /* through the root's centre, where all midplanes meet */
                for (int a = 0; a < 3; a++)
                    d[a] = 0.5 * (t.lo[a] + t.hi[a]) - o[a];
            if (!wk_box_clip(t.lo, t.hi, o, d, 0.0, INFINITY, &t0, &t1, &enter))
                continue;
            check_tree_walk(&t, blo, bhi, o, d, t0, t1, enter, len);
            walked++;
        }
    }
    cr_expect(walked > 1500, "only %d rays crossed their tree", walked);
}

Test(walk, octree_rays_through_corners_and_along_planes)
{
    /* A full depth-2 tree over [0, 4]^3 (unit leaves, every plane exact). */
    static tree t;
    static double blo[3 * 4096], bhi[3 * 4096], len[4096];
    for (int a = 0; a < 3; a++)
        t.lo[a] = 0.0, t.hi[a] = 4.0;
    t.n = 1;
    t.child[0] = 1;
    t.n = 9;
    for (int c = 0; c < 8; c++) {
        t.child[1 + c] = t.n;
        for (int q = 0; q < 8; q++)
            t.child[t.n + q] = -1;
        t.n += 8;
    }
    t.depth = 2;
    leaf_boxes(&t, 0, t.lo, t.hi, blo, bhi);
    const double rays[][6] = {
        {-1, -1, -1, 1, 1, 1},   /* through the corners (i, i, i), the root's centre among them */
        {5, 5, 5, -1, -1, -1},
        {-1, -1, 0.5, 1, 1, 0},  /* through edges */
        {-1, 2, 0.5, 1, 0, 0},   /* along the root's midplane y = 2 */
        {5, 2, 2, -1, 0, 0},     /* along the midplane edge y = z = 2, backwards */
        {1, 1, -1, 0, 0, 1},     /* along an edge between four leaves */
        {0.5, 4, -1, 0, 0, 1},   /* in the root's face y = 4 */
    };
    const int expect[] = {4, 4, 4, 4, 4, 4, 4};
    for (size_t c = 0; c < sizeof rays / sizeof rays[0]; c++) {
        double t0, t1;
        int enter;
        cr_assert(wk_box_clip(t.lo, t.hi, rays[c], rays[c] + 3, 0, INFINITY, &t0, &t1, &enter));
        wk_tree_walk w;
        wk_tree_seg s;
        wk_tree_begin(&w, tree_locate, &t, t.lo, t.hi, rays[c], rays[c] + 3, t0, t1, enter, t.depth);
        int n = 0;
        double tprev = t0;
        while (wk_tree_next(&w, &s)) {
            cr_assert(s.ta == tprev && s.tb > s.ta);
            cr_expect(s.tb - s.ta == 1.0, "ray %zu: unit leaves give unit segments, got %.17g", c, s.tb - s.ta);
            tprev = s.tb;
            n++;
        }
        cr_expect(n == expect[c], "ray %zu: %d segments", c, n);
        cr_expect(tprev == t1);
    }
    (void)len;
}

static long locate_nothing(const void *tp, const double p[3], const double d[3], double lo[3], double hi[3])
{
    (void)tp, (void)p, (void)d, (void)lo, (void)hi;
    return -1;
}

Test(walk, octree_locate_failure_ends_the_walk)
{
    /* A locate that finds nothing (returns < 0) ends the walk without a segment; so does a
     * missing locate. */
    const double o[3] = {0.5, 0.5, 0.5}, d[3] = {1, 0, 0};
    wk_tree_walk w;
    wk_tree_seg s;
    wk_tree_begin(&w, locate_nothing, NULL, U0, U1, o, d, 0.0, 0.5, -1, 0);
    cr_expect(!wk_tree_next(&w, &s));
    cr_expect(!wk_tree_next(&w, &s), "and stays ended");
    wk_tree_begin(&w, NULL, NULL, U0, U1, o, d, 0.0, 0.5, -1, 0);
    cr_expect(!wk_tree_next(&w, &s));
}
