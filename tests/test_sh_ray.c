/* test_sh_ray.c: the guide ray iterator over uniform and adaptive grids (DESIGN.md convention
 * 7): segments tile the clipped ray exactly, and the cells they name are the cells a brute-force
 * point lookup finds. Deterministic; fixed seeds. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap.h"
#include "sh.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#include "support/test_rng.h"

/* Box [-1,2] x [0,1] x [0.5,1.5]: non-cubic, offset from the origin. */
static const double BLO[3] = {-1.0, 0.0, 0.5}, BHI[3] = {2.0, 1.0, 1.5};

static pm_map *blob_map(size_t n)
{
    rng r = rng_new(31);
    pm_photon *ph = malloc(n * sizeof *ph);
    for (size_t i = 0; i < n; i++) {
        double c = rng_u01(&r) < 0.7 ? 0.05 : 1.0; /* a dense blob plus background */
        for (int a = 0; a < 3; a++) {
            double mid = a == 0 ? 0.2 : 0.5 * (BLO[a] + BHI[a]);
            double x = mid + c * (BHI[a] - BLO[a]) * (rng_u01(&r) - 0.5);
            ph[i].pos[a] = (float)fmin(fmax(x, BLO[a]), BHI[a]);
            ph[i].dir[a] = a == 2 ? 1.0f : 0.0f;
            ph[i].power[a] = 1.0f;
        }
    }
    pm_map *m = pm_map_new();
    char err[256] = "";
    cr_assert_eq(pm_map_add_photons(m, ph, n, err, sizeof err), PM_OK, "%s", err);
    cr_assert_eq(pm_map_build(m, err, sizeof err), PM_OK, "%s", err);
    free(ph);
    return m;
}

static sh_guide *make_guide(sh_grid_kind kind)
{
    pm_map *m = blob_map(20000);
    sh_bake_params P;
    sh_bake_params_default(&P);
    for (int a = 0; a < 3; a++)
        P.lo[a] = BLO[a], P.hi[a] = BHI[a];
    P.kind = kind;
    P.bands = 1;
    P.k = 8;
    if (kind == SH_GRID_UNIFORM)
        P.res[0] = 7, P.res[1] = 5, P.res[2] = 3;
    sh_guide *g = NULL;
    char err[256] = "";
    cr_assert_eq(sh_guide_bake(&g, m, &P, err, sizeof err), SH_OK, "%s", err);
    pm_map_free(m);
    if (kind == SH_GRID_ADAPTIVE) {
        sh_guide_stats st;
        sh_guide_stats_get(g, &st);
        cr_assert_gt(st.depth_max, 4, "the adaptive test grid must be deep (got %d)",
                     st.depth_max);
    }
    return g;
}

/* Independent slab clip of the ray to the box. Returns 0 if it misses. */
static int clip(const double o[3], const double d[3], double tmin, double tmax, double *t0,
                double *t1)
{
    *t0 = tmin, *t1 = tmax;
    for (int a = 0; a < 3; a++) {
        if (d[a] == 0.0) {
            if (o[a] < BLO[a] || o[a] > BHI[a])
                return 0;
            continue;
        }
        double ta = (BLO[a] - o[a]) / d[a], tb = (BHI[a] - o[a]) / d[a];
        if (ta > tb) {
            double t = ta;
            ta = tb, tb = t;
        }
        *t0 = fmax(*t0, ta), *t1 = fmin(*t1, tb);
    }
    return *t0 < *t1;
}

#define MAXSEG 4096
typedef struct {
    int rays, segments, hit_rays;
} tally;

/* Check one ray: tiling, monotone, endpoints, and cells against point lookups. */
static void check_ray(const sh_guide *g, const double o[3], const double d[3], double tmin,
                      double tmax, tally *tl)
{
    static sh_guide_seg seg[MAXSEG];
    sh_guide_ray it;
    sh_guide_ray_begin(g, o, d, tmin, tmax, &it);
    int n = 0;
    while (n < MAXSEG && sh_guide_ray_next(&it, &seg[n]))
        n++;
    cr_assert_lt(n, MAXSEG);
    tl->rays++;
    tl->segments += n;
    double t0, t1;
    int hit = clip(o, d, tmin, tmax, &t0, &t1);
    double scale = fmax(1.0, fmax(fabs(t0), fabs(t1)));
    if (!hit) {
        cr_assert_eq(n, 0, "ray misses the box but got %d segments", n);
        return;
    }
    if (t1 - t0 < 1e-12 * scale)
        return; /* grazing: either answer is right */
    tl->hit_rays++;
    cr_assert_gt(n, 0, "ray hits the box [%g, %g] but got no segment", t0, t1);
    cr_assert_float_eq(seg[0].t0, t0, 1e-12 * scale);
    cr_assert_float_eq(seg[n - 1].t1, t1, 1e-12 * scale);
    for (int i = 0; i < n; i++) {
        cr_assert_gt(seg[i].t1, seg[i].t0, "segment %d empty", i);
        if (i > 0)
            cr_assert_eq(seg[i].t0, seg[i - 1].t1, "gap/overlap between segments %d and %d", i - 1,
                         i);
        cr_assert(seg[i].cell >= 0 && (size_t)seg[i].cell < sh_guide_cell_count(g));
        cr_assert_eq(seg[i].coeffs, sh_guide_cell_coeffs(g, (size_t)seg[i].cell));
        cr_assert_eq(seg[i].sigma_t, sh_guide_cell_sigma_t(g, (size_t)seg[i].cell));
        /* The segment's midpoint lies in its cell (segments longer than rounding). */
        if (seg[i].t1 - seg[i].t0 > 1e-9 * scale) {
            double tm = 0.5 * (seg[i].t0 + seg[i].t1), x[3];
            for (int a = 0; a < 3; a++)
                x[a] = o[a] + tm * d[a];
            cr_assert_eq(sh_guide_locate(g, x), seg[i].cell, "segment %d [%g, %g]: midpoint in "
                         "cell %ld, segment says %ld", i, seg[i].t0, seg[i].t1,
                         sh_guide_locate(g, x), seg[i].cell);
        }
    }
    /* Brute force: 1000 evenly spaced points along [t0, t1]; each lies in the cell of the
     * segment covering it (points within rounding of a boundary are skipped), and every
     * segment longer than two spacings contains a point, so the visited cell sets agree. */
    const int np = 1000;
    double dt = (t1 - t0) / np;
    int j = 0;
    static int seen[MAXSEG];
    memset(seen, 0, sizeof(int) * (size_t)n);
    for (int k = 0; k < np; k++) {
        double t = t0 + (k + 0.5) * dt;
        while (j < n - 1 && t >= seg[j].t1)
            j++;
        if (fabs(t - seg[j].t0) < 1e-9 * scale || fabs(t - seg[j].t1) < 1e-9 * scale)
            continue;
        double x[3];
        for (int a = 0; a < 3; a++)
            x[a] = o[a] + t * d[a];
        cr_assert_eq(sh_guide_locate(g, x), seg[j].cell, "point t=%g: lookup %ld, segment %ld",
                     t, sh_guide_locate(g, x), seg[j].cell);
        seen[j] = 1;
    }
    for (int i = 0; i < n; i++)
        if (seg[i].t1 - seg[i].t0 > 2.0 * dt)
            cr_assert(seen[i], "segment %d (cell %ld) not found by point sampling", i,
                      seg[i].cell);
}

static void random_rays(const sh_guide *g, uint64_t seed)
{
    rng r = rng_new(seed);
    tally tl = {0, 0, 0};
    for (int t = 0; t < 600; t++) {
        double o[3], d[3];
        for (int a = 0; a < 3; a++) /* origins inside and outside the box */
            o[a] = BLO[a] - 0.5 + (BHI[a] - BLO[a] + 1.0) * rng_u01(&r);
        rng_dir(&r, d);
        double s = 0.25 + 3.0 * rng_u01(&r); /* non-unit directions */
        for (int a = 0; a < 3; a++)
            d[a] *= s;
        double tmin = t % 3 == 0 ? -INFINITY : t % 3 == 1 ? 0.0 : 0.3 * rng_u01(&r);
        double tmax = t % 4 == 0 ? INFINITY : 0.2 + 2.0 * rng_u01(&r);
        check_ray(g, o, d, tmin, tmax, &tl);
    }
    cr_log_info("%d of %d random rays hit, %d segments", tl.hit_rays, tl.rays, tl.segments);
    cr_assert_gt(tl.hit_rays, 150);
    cr_assert_gt(tl.segments, 3 * tl.hit_rays);
}

static void special_rays(const sh_guide *g)
{
    tally tl = {0, 0, 0};
    rng r = rng_new(33);
    /* Axis-parallel rays, both directions, from outside and inside, including rays lying
     * exactly on internal planes (box mid-planes are octree planes; 0 and 0.5 are uniform
     * planes of the 7x5x3 grid only for some axes) and on the box faces. */
    const double special[3][5] = {{-1.0, 0.5, 0.2, 0.7142857142857143, 2.0},
                                  {0.0, 0.5, 0.4, 0.2, 1.0},
                                  {0.5, 1.0, 0.8333333333333334, 1.25, 1.5}};
    for (int a = 0; a < 3; a++)
        for (int s = -1; s <= 1; s += 2)
            for (int i = 0; i < 5; i++)
                for (int j = 0; j < 5; j++) {
                    int b = (a + 1) % 3, c = (a + 2) % 3;
                    double o[3], d[3] = {0, 0, 0};
                    o[a] = s > 0 ? BLO[a] - 1.0 : BHI[a] + 1.0;
                    o[b] = special[b][i];
                    o[c] = special[c][j];
                    d[a] = s;
                    check_ray(g, o, d, 0.0, INFINITY, &tl);
                    /* starting inside */
                    o[a] = BLO[a] + (BHI[a] - BLO[a]) * rng_u01(&r);
                    check_ray(g, o, d, 0.0, INFINITY, &tl);
                    check_ray(g, o, d, -INFINITY, 0.1, &tl);
                }
    /* Diagonals through cell corners. */
    double o[3] = {-1.0, 0.0, 0.5}, d[3] = {3.0, 1.0, 1.0};
    check_ray(g, o, d, -1.0, 2.0, &tl);
    double o2[3] = {2.0, 1.0, 1.5}, d2[3] = {-3.0, -1.0, -1.0};
    check_ray(g, o2, d2, 0.0, 1.0, &tl);
    cr_assert_gt(tl.hit_rays, 200);

    /* Misses: beside the box, parallel to a face outside it, pointing away, empty range. */
    sh_guide_ray it;
    sh_guide_seg sg;
    double om[3] = {-2.0, 2.0, 1.0}, dm[3] = {1.0, 0.0, 0.0};
    sh_guide_ray_begin(g, om, dm, 0.0, INFINITY, &it);
    cr_assert_not(sh_guide_ray_next(&it, &sg));
    double oa[3] = {0.5, 0.5, 1.0}, da[3] = {0.0, 0.0, 1.0};
    sh_guide_ray_begin(g, oa, da, 5.0, INFINITY, &it); /* starts beyond the box */
    cr_assert_not(sh_guide_ray_next(&it, &sg));
    sh_guide_ray_begin(g, oa, da, 0.3, 0.1, &it); /* tmin > tmax */
    cr_assert_not(sh_guide_ray_next(&it, &sg));
    sh_guide_ray_begin(g, oa, da, NAN, 1.0, &it);
    cr_assert_not(sh_guide_ray_next(&it, &sg));
    double on[3] = {NAN, 0.5, 1.0};
    sh_guide_ray_begin(g, on, da, 0.0, 1.0, &it);
    cr_assert_not(sh_guide_ray_next(&it, &sg));
    /* A zero direction inside the box: one segment over [tmin, tmax] in the cell of o. */
    double dz[3] = {0, 0, 0};
    sh_guide_ray_begin(g, oa, dz, 0.0, 1.0, &it);
    cr_assert(sh_guide_ray_next(&it, &sg));
    cr_assert_eq(sg.cell, sh_guide_locate(g, oa));
    cr_assert_eq(sg.t0, 0.0);
    cr_assert_eq(sg.t1, 1.0);
    cr_assert_not(sh_guide_ray_next(&it, &sg));
}

Test(sh, ray_iterator_uniform_random_rays)
{
    sh_guide *g = make_guide(SH_GRID_UNIFORM);
    cr_assert_eq(sh_guide_cell_count(g), 105);
    random_rays(g, 41);
    sh_guide_free(g);
}

Test(sh, ray_iterator_uniform_special_rays)
{
    sh_guide *g = make_guide(SH_GRID_UNIFORM);
    special_rays(g);
    sh_guide_free(g);
}

Test(sh, ray_iterator_adaptive_random_rays)
{
    sh_guide *g = make_guide(SH_GRID_ADAPTIVE);
    random_rays(g, 42);
    sh_guide_free(g);
}

Test(sh, ray_iterator_adaptive_special_rays)
{
    sh_guide *g = make_guide(SH_GRID_ADAPTIVE);
    special_rays(g);
    sh_guide_free(g);
}

Test(sh, ray_iterator_through_the_dense_blob)
{
    /* Rays through the blob of the adaptive grid cross many small leaves: the segment count
     * is far above what the coarse cells alone would give, and the tiling still holds. */
    sh_guide *g = make_guide(SH_GRID_ADAPTIVE);
    tally tl = {0, 0, 0};
    rng r = rng_new(43);
    for (int t = 0; t < 200; t++) {
        double o[3] = {0.2 + 0.05 * (rng_u01(&r) - 0.5), 0.5 + 0.05 * (rng_u01(&r) - 0.5),
                       1.0 + 0.05 * (rng_u01(&r) - 0.5)},
               d[3];
        rng_dir(&r, d);
        check_ray(g, o, d, -INFINITY, INFINITY, &tl);
    }
    cr_assert_gt(tl.segments, 20 * tl.rays, "%d segments over %d rays", tl.segments, tl.rays);
    sh_guide_free(g);
}
