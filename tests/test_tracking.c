/* Free-path sampling and transmittance (THEORY.md §2): delta tracking and ratio tracking
 * reproduce the exact transmittance of a homogeneous slab and of a trilinear voxel grid.
 * Tolerances: 5 standard errors of the estimate (binomial for delta tracking, the sample
 * standard deviation for ratio tracking), with fixed seeds. */
#include "support/rd_test.h"

static rd_scene *slab_scene(void)
{
    /* A slab 2 m thick along x, wide in y and z, sigma_t = 0.8 / m: T = exp(-1.6). */
    return rt_scene("slab.json",
                    "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                    "\"media\":[{\"bounds\":{\"min\":[-1,-50,-50],\"max\":[1,50,50]},"
                    "\"density\":{\"type\":\"constant\",\"value\":0.5},\"sigma_t\":1.6}]}");
}

/* Fraction of delta-tracked free paths that leave without a real collision, and the ratio
 * tracking mean with its standard error. */
static void estimate(const rd_scene *s, ray3 r, double tmax, int n, uint64_t seed, double *Td,
                     double *Tr, double *se_r)
{
    rd_track_counters c = {0};
    int escaped = 0;
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; i++) {
        pcg32 rng = pcg32_seed(seed, i, 77);
        if (!rd_sample_free_path(s, -1, r, tmax, &rng, &c).hit) escaped++;
        double T = rd_transmittance(s, -1, r, 0.0, tmax, &rng, &c);
        sum += T;
        sum2 += T * T;
    }
    *Td = (double)escaped / n;
    *Tr = sum / n;
    *se_r = sqrt(fmax(0.0, sum2 / n - (*Tr) * (*Tr)) / n);
}

Test(tracking, homogeneous_slab_transmittance)
{
    rd_scene *s = slab_scene();
    /* Loosen the majorant to 2.5 sigma_t so that null collisions are exercised too. */
    const double factors[] = {1.0, 2.5};
    const vec3 dirs[] = {v3(1, 0, 0), v3_norm(v3(1, 0.5, -0.3))};
    for (int f = 0; f < 2; f++)
        for (int d = 0; d < 2; d++) {
            s->media[0].sigma_maj = 0.8 * factors[f];
            ray3 r = {v3(-3, 0.1, 0.2), dirs[d]};
            double len = 2.0 / dirs[d].x; /* path length inside the slab */
            double exact = exp(-0.8 * len);
            int n = 200000;
            double Td, Tr, se_r;
            estimate(s, r, INFINITY, n, 10 * f + d, &Td, &Tr, &se_r);
            double se_d = sqrt(exact * (1 - exact) / n);
            cr_expect(fabs(Td - exact) < 5 * se_d, "delta: %.5f vs exact %.5f (se %.5f, maj x%g)", Td, exact, se_d, factors[f]);
            cr_expect(fabs(Tr - exact) < 5 * se_r + 1e-12, "ratio: %.5f vs exact %.5f (se %.5f)", Tr, exact, se_r);
        }
    rd_scene_free(s);
}

Test(tracking, homogeneous_transmittance_to_a_point_inside)
{
    rd_scene *s = slab_scene();
    s->media[0].sigma_maj = 1.3;
    ray3 r = {v3(-3, 0, 0), v3(1, 0, 0)};
    double exact = exp(-0.8 * 1.25); /* enters at t = 2, stops at t = 3.25 */
    double Td, Tr, se_r;
    int n = 200000;
    estimate(s, r, 3.25, n, 5, &Td, &Tr, &se_r);
    double se_d = sqrt(exact * (1 - exact) / n);
    cr_expect(fabs(Td - exact) < 5 * se_d, "delta: %.5f vs %.5f", Td, exact);
    cr_expect(fabs(Tr - exact) < 5 * se_r, "ratio: %.5f vs %.5f", Tr, exact);
    rd_scene_free(s);
}

Test(tracking, voxel_grid_transmittance)
{
    /* A 7x5x6 raw grid of random densities in [0, 2] in the box [-1, 1]^3, sigma_t scale 1.5.
     * The exact optical depth along each ray comes from a 400000-step midpoint rule of the
     * trilinear density (error far below the Monte Carlo tolerance). */
    enum { NX = 7, NY = 5, NZ = 6 };
    float vox[NX * NY * NZ];
    pcg32 g = pcg32_seed(3, 4, 5);
    for (int i = 0; i < NX * NY * NZ; i++) vox[i] = (float)(2.0 * pcg32_uniform(&g));
    char path[256];
    snprintf(path, sizeof path, "%s/grid.raw", rt_tmpdir());
    rt_write_file(path, vox, sizeof vox);
    rd_scene *s = rt_scene("grid.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":{\"type\":\"raw\",\"file\":\"grid.raw\",\"dims\":[7,5,6]},\"sigma_t\":1.5}]}");
    const rd_medium *m = &s->media[0];
    cr_assert(fabs(m->density_max - m->grid.vmax) < 1e-12);
    for (int k = 0; k < 4; k++) {
        vec3 o = v3(-2.0, -0.6 + 0.3 * k, 0.3 - 0.2 * k);
        vec3 d = v3_norm(v3(1.0, 0.1 * k, 0.1));
        ray3 r = {o, d};
        double t0, t1;
        cr_assert(rd_box_intersect(m->bmin, m->bmax, r, 0, INFINITY, &t0, &t1));
        int steps = 400000;
        double h = (t1 - t0) / steps, tau = 0;
        for (int i = 0; i < steps; i++) tau += rd_medium_sigma_t(m, ray_at(r, t0 + (i + 0.5) * h)) * h;
        double exact = exp(-tau);
        int n = 200000;
        double Td, Tr, se_r;
        estimate(s, r, INFINITY, n, 40 + k, &Td, &Tr, &se_r);
        double se_d = sqrt(exact * (1 - exact) / n);
        cr_expect(fabs(Td - exact) < 5 * se_d, "ray %d delta: %.5f vs %.5f (se %.5f)", k, Td, exact, se_d);
        cr_expect(fabs(Tr - exact) < 5 * se_r, "ray %d ratio: %.5f vs %.5f (se %.5f)", k, Tr, exact, se_r);
    }
    rd_scene_free(s);
}

Test(tracking, grid_lookup_is_trilinear)
{
    /* At voxel centres the lookup returns the voxel; halfway between two centres, their mean. */
    float vox[2 * 2 * 2] = {1, 2, 3, 4, 5, 6, 7, 8};
    char path[256];
    snprintf(path, sizeof path, "%s/tiny.raw", rt_tmpdir());
    rt_write_file(path, vox, sizeof vox);
    rd_scene *s = rt_scene("tiny.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[0,0,0],\"max\":[2,2,2]},"
                           "\"density\":{\"type\":\"raw\",\"file\":\"tiny.raw\",\"dims\":[2,2,2]},\"sigma_t\":1}]}");
    const rd_medium *m = &s->media[0];
    cr_expect(fabs(rd_medium_density(m, v3(0.5, 0.5, 0.5)) - 1.0) < 1e-12);
    cr_expect(fabs(rd_medium_density(m, v3(1.5, 1.5, 1.5)) - 8.0) < 1e-12);
    cr_expect(fabs(rd_medium_density(m, v3(1.0, 0.5, 0.5)) - 1.5) < 1e-12);
    cr_expect(fabs(rd_medium_density(m, v3(1.0, 1.0, 1.0)) - 4.5) < 1e-12);
    cr_expect(rd_medium_density(m, v3(2.5, 1.0, 1.0)) == 0.0, "outside the bounds the density is 0");
    rd_scene_free(s);
}
