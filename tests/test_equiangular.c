/* Equiangular distance sampling (Kulla & Fajardo 2012; transport/equiangular.c) and the spot
 * cone's range along a ray (scene/lights.c, rd_light_lit_range):
 *  - chi-square of the sampler against its pdf, the expected count of each bin integrated from
 *    rd_equiangular_pdf by Simpson's rule (not from the sampler's own inversion), cells with an
 *    expected count < 5 pooled (pbrt-v4 bsdfs_test), rejected at p = 1e-4 (z = 3.719);
 *  - the test has teeth: the same samples judged against the pdf of a light 5% farther away fail;
 *  - the pdf integrates to 1 and the sampler returns the pdf of the distance it draws;
 *  - every point of a ray that a spot lights lies in the range rd_light_lit_range returns, and
 *    every point well inside the range is inside the cone;
 *  - a directional beam (radius > 0): the range is the chord inside its cylinder, point for
 *    point, and the sampler draws it uniformly (chi-square as above). */
#include "support/rd_test.h"

typedef struct {
    vec3 c;        /* the light */
    ray3 r;        /* r.d is normalised before use */
    double a, b;   /* the span */
} eq_case;

static rd_equiangular eq_of(const eq_case *k)
{
    rd_equiangular eq;
    ray3 r = {k->r.o, v3_norm(k->r.d)};
    cr_assert(rd_equiangular_init(&eq, k->c, r, k->a, k->b));
    return eq;
}

static const eq_case cases[] = {
    {{0.2, 0.45, -0.1}, {{-0.3, 0.1, 3.0}, {0.1, 0.05, -1.0}}, 1.9, 4.2},  /* light beside the span */
    {{0.0, 0.02, 0.0}, {{-2.0, 0.0, 0.0}, {1, 0, 0}}, 0.5, 3.5},                              /* 2 cm from the line */
    {{5.0, 1.0, 0.0}, {{0.0, 0.0, 0.0}, {1, 0, 0}}, 0.0, 2.0},                                /* beyond the span's end */
    {{-3.0, 4.0, 1.0}, {{0.0, 0.0, 0.0}, {0.6, 0.0, 0.8}}, 0.3, 6.0},                         /* behind the origin */
};

static double pdf_cb(double t, const void *ctx) { return rd_equiangular_pdf(ctx, t); }

/* Expected fraction of samples in each of nb equal bins of [a, b], by Simpson's rule on the
 * pdf (2000 intervals per bin: the sharpest peak here is 2 cm wide against bins of 5 cm). */
static void expected(const rd_equiangular *eq, int nb, double *e)
{
    double h = (eq->b - eq->a) / nb;
    for (int i = 0; i < nb; i++) e[i] = rt_simpson(pdf_cb, eq, eq->a + i * h, eq->a + (i + 1) * h, 2000);
}

enum { NB = 64 };

static void sample_bins(const rd_equiangular *eq, int n, uint64_t seed, double *obs)
{
    memset(obs, 0, NB * sizeof *obs);
    pcg32 rng = pcg32_seed(seed, 7, 11);
    for (int k = 0; k < n; k++) {
        double pdf, t = rd_equiangular_sample(eq, pcg32_uniform(&rng), &pdf);
        cr_assert(t >= eq->a && t <= eq->b, "t %g outside [%g, %g]", t, eq->a, eq->b);
        cr_assert(pdf == rd_equiangular_pdf(eq, t), "the sampler's pdf differs from rd_equiangular_pdf");
        int i = (int)((t - eq->a) / (eq->b - eq->a) * NB);
        obs[i >= NB ? NB - 1 : i] += 1;
    }
}

Test(equiangular, sampler_chi_square)
{
    for (size_t ci = 0; ci < sizeof cases / sizeof cases[0]; ci++) {
        const eq_case *k = &cases[ci];
        rd_equiangular eq = eq_of(k);
        double frac[NB], obs[NB], total = 0;
        expected(&eq, NB, frac);
        for (int i = 0; i < NB; i++) total += frac[i];
        cr_expect(fabs(total - 1.0) < 1e-6, "case %zu: the pdf integrates to %.9f", ci, total);
        int n = 200000, dof;
        sample_bins(&eq, n, 100 + ci, obs);
        double chi2 = rt_chi2_pooled(obs, frac, NB, n, &dof), crit = rt_chi2_quantile(dof, 3.719);
        cr_expect(chi2 < crit, "case %zu: chi2 %.1f >= %.1f (dof %d)", ci, chi2, crit, dof);
    }
}

Test(equiangular, chi_square_rejects_a_wrong_pdf)
{
    /* Samples toward the light judged against the pdf toward a point 5% farther from the line. */
    const eq_case *k = &cases[0];
    rd_equiangular eq = eq_of(k), wrong = eq_of(k);
    wrong.D *= 1.05;
    wrong.th_a = atan((wrong.a - wrong.delta) / wrong.D);
    wrong.th_b = atan((wrong.b - wrong.delta) / wrong.D);
    double frac[NB], obs[NB];
    expected(&wrong, NB, frac);
    int n = 200000, dof;
    sample_bins(&eq, n, 5, obs);
    double chi2 = rt_chi2_pooled(obs, frac, NB, n, &dof);
    cr_expect(chi2 > rt_chi2_quantile(dof, 3.719), "chi2 %.1f did not detect D x 1.05", chi2);
}

Test(equiangular, empty_span_is_refused)
{
    rd_equiangular eq;
    ray3 r = {v3(0, 0, 0), v3(1, 0, 0)};
    cr_expect(!rd_equiangular_init(&eq, v3(0, 1, 0), r, 2.0, 2.0));
    cr_expect(!rd_equiangular_init(&eq, v3(0, 1, 0), r, 2.0, INFINITY));
    /* a light on the line: the floor on D keeps the pdf finite and normalised */
    cr_assert(rd_equiangular_init(&eq, v3(1, 0, 0), r, 0.0, 2.0));
    double pdf, t = rd_equiangular_sample(&eq, 0.3, &pdf);
    cr_expect(isfinite(pdf) && pdf > 0 && t >= 0 && t <= 2, "t %g pdf %g", t, pdf);
}

/* A random ray from a point uniform in the cube [-h, h]^3 in a uniform direction. */
static ray3 random_ray(pcg32 *rng, double h)
{
    vec3 o = v3(h * (2 * pcg32_uniform(rng) - 1), h * (2 * pcg32_uniform(rng) - 1), h * (2 * pcg32_uniform(rng) - 1));
    return (ray3){o, rd_sample_sphere(pcg32_uniform(rng), pcg32_uniform(rng))};
}

Test(equiangular, spot_range_holds_every_lit_point)
{
    rd_scene *s = rt_scene("spot.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},\"media\":[],"
                           "\"lights\":[{\"type\":\"spot\",\"position\":[0.3,2,0.1],\"look_at\":[0,0,0],\"angle\":20,\"intensity\":1},"
                           "{\"type\":\"spot\",\"position\":[0,0,0],\"direction\":[0,1,0],\"angle\":150,\"falloff\":10,\"intensity\":1},"
                           "{\"type\":\"spot\",\"position\":[1,1,1],\"direction\":[1,0,0],\"angle\":180,\"intensity\":1}]}");
    pcg32 rng = pcg32_seed(9, 9, 9);
    int lit_rays = 0;
    for (int li = 0; li < 3; li++) {
        const rd_light *l = &s->lights[li];
        for (int k = 0; k < 3000; k++) {
            ray3 r = random_ray(&rng, 2.0);
            double t0 = 0.0, t1 = 4.0;
            int any = rd_light_lit_range(l, r, &t0, &t1);
            int steps = 4000, lit = 0;
            for (int i = 0; i <= steps; i++) {
                double t = 4.0 * i / steps;
                vec3 x = v3_sub(ray_at(r, t), l->pos);
                double len = v3_len(x);
                if (!(len > 0)) continue;
                int inside = v3_dot(l->dir, x) / len > l->cos_outer;
                if (inside) {
                    lit = 1;
                    cr_assert(any && t >= t0 - 1e-9 && t <= t1 + 1e-9,
                              "light %d ray %d: lit point t = %g outside the range [%g, %g] (any %d)", li, k, t, t0, t1, any);
                } else if (any && t > t0 + 1e-6 && t < t1 - 1e-6) {
                    /* the cone is convex, so nothing unlit lies strictly between lit points */
                    double cs = v3_dot(l->dir, x) / len;
                    cr_assert(cs > l->cos_outer - 1e-9, "light %d ray %d: t = %g in [%g, %g] is outside the cone (cos %.9f < %.9f)",
                              li, k, t, t0, t1, cs, l->cos_outer);
                }
            }
            lit_rays += lit;
        }
    }
    cr_expect(lit_rays > 300, "too few rays met a cone (%d): the test would prove little", lit_rays);
    rd_scene_free(s);
}

/* A directional beam of radius R lights the points within R of its axis (scene/lights.c,
 * rd_light_sample): the range along a ray is exactly the chord inside that cylinder, and the
 * strategy's density over it is uniform (no 1 / r^2 from a light at infinity). */
Test(equiangular, beam_range_is_the_chord_inside_the_cylinder)
{
    rd_scene *s = rt_scene("beam.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},\"media\":[],"
                           "\"lights\":[{\"type\":\"directional\",\"direction\":[1,-0.1,0.45],\"irradiance\":1,"
                           "\"radius\":0.3,\"center\":[0.1,0.2,0]}]}");
    const rd_light *l = &s->lights[0];
    cr_assert(rd_eq_light(l), "a directional beam is one of the strategy's lights");
    pcg32 rng = pcg32_seed(19, 9, 9);
    int lit_rays = 0;
    for (int k = 0; k < 3000; k++) {
        ray3 r = random_ray(&rng, 1.0);
        double t0 = 0.0, t1 = 3.0;
        int any = rd_light_lit_range(l, r, &t0, &t1);
        int steps = 6000, lit = 0;
        for (int i = 0; i <= steps; i++) {
            double t = 3.0 * i / steps;
            vec3 q = v3_sub(ray_at(r, t), l->beam_center);
            vec3 perp = v3_madd(q, l->dir, -v3_dot(q, l->dir));
            double d2 = v3_dot(perp, perp), R2 = l->radius * l->radius;
            if (d2 < R2 * (1 - 1e-9)) {
                lit = 1;
                cr_assert(any && t >= t0 - 1e-9 && t <= t1 + 1e-9, "ray %d: lit point t = %g outside [%g, %g] (any %d)", k, t,
                          t0, t1, any);
            } else if (d2 > R2 * (1 + 1e-9)) {
                cr_assert(!any || t < t0 + 1e-9 || t > t1 - 1e-9, "ray %d: unlit point t = %g inside [%g, %g]", k, t, t0, t1);
            }
        }
        lit_rays += lit;
        if (any && lit) { /* the density over the chord is uniform: 1 / (t1 - t0) */
            rd_equiangular eq;
            cr_assert(rd_equiangular_init_light(&eq, l, r, t0, t1));
            double pdf, t = rd_equiangular_sample(&eq, 0.37, &pdf);
            cr_assert(fabs(t - (t0 + 0.37 * (t1 - t0))) < 1e-12 && fabs(pdf * (t1 - t0) - 1) < 1e-12, "ray %d: t %g pdf %g", k,
                      t, pdf);
        }
    }
    cr_expect(lit_rays > 300, "too few rays met the beam (%d): the test would prove little", lit_rays);
    /* a line along the axis: lit everywhere inside the cylinder, nowhere outside */
    double t0 = 0.0, t1 = 2.0;
    cr_expect(rd_light_lit_range(l, (ray3){l->beam_center, l->dir}, &t0, &t1) && t0 == 0.0 && t1 == 2.0);
    ray3 far = {v3_add(l->beam_center, v3(0, 0, 1)), l->dir};
    t0 = 0.0, t1 = 2.0;
    cr_expect(!rd_light_lit_range(l, far, &t0, &t1), "a line parallel to the axis, 0.91 m from it, is unlit");
    /* a directional light without a radius lights every line whole and is not the strategy's */
    rd_light sun = *l;
    sun.radius = 0.0;
    t0 = 0.0, t1 = 2.0;
    cr_expect(rd_light_lit_range(&sun, far, &t0, &t1) && t0 == 0.0 && t1 == 2.0);
    cr_expect(!rd_eq_light(&sun));
    rd_scene_free(s);
}

Test(equiangular, beam_sampler_chi_square)
{
    /* The uniform density of a beam's chord, checked as the point lights' are above. */
    rd_light beam = {.kind = RD_LIGHT_DIRECTIONAL, .dir = v3(0, 0, -1), .radius = 0.5};
    ray3 r = {v3(-2, 0.1, 0), v3(1, 0, 0)};
    double a = 0.0, b = 4.0;
    cr_assert(rd_light_lit_range(&beam, r, &a, &b));
    cr_expect(fabs(a - (2 - sqrt(0.24))) < 1e-12 && fabs(b - (2 + sqrt(0.24))) < 1e-12, "chord [%g, %g]", a, b);
    rd_equiangular eq;
    cr_assert(rd_equiangular_init_light(&eq, &beam, r, a, b));
    double frac[NB], obs[NB];
    expected(&eq, NB, frac);
    int n = 200000, dof;
    sample_bins(&eq, n, 41, obs);
    double chi2 = rt_chi2_pooled(obs, frac, NB, n, &dof), crit = rt_chi2_quantile(dof, 3.719);
    cr_expect(chi2 < crit, "chi2 %.1f >= %.1f (dof %d)", chi2, crit, dof);
}

/* Which modes put a beam in the strategy's set: `true` and "camera" (RD_EQ_ALL, RD_EQ_CAMERA,
 * and so the tiles that take `true`: the guided methods' third estimator, `delta`'s "tiles");
 * not "auto", which keeps the image it had before beams were sampled. A flight in thin fog
 * crossing both. */
Test(equiangular, only_true_and_camera_sample_a_beam_beside_a_spot)
{
    rd_scene *s = rt_scene("spot_beam.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-2,-1,-1],\"max\":[2,1,1]},"
                           "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":0.1,\"albedo\":0.9,\"g\":0}],"
                           "\"lights\":[{\"type\":\"spot\",\"position\":[-1,3,0],\"look_at\":[-1,0,0],\"angle\":4,\"intensity\":50},"
                           "{\"type\":\"directional\",\"direction\":[0,-1,0],\"irradiance\":5,\"radius\":0.1,"
                           "\"center\":[1,0,0]}]}");
    ray3 r = {v3(-3, 0, 0), v3(1, 0, 0)};
    int region = rd_scene_region_at(s, r.o);
    const struct { int mode, spot, beam; const char *name; } want[] = {
        {RD_EQ_ALL, 1, 1, "true"}, {RD_EQ_CAMERA, 1, 1, "camera"}, {RD_EQ_AUTO, 1, 0, "auto"}};
    for (size_t i = 0; i < sizeof want / sizeof want[0]; i++) {
        rd_eq_flight ef;
        cr_assert(rd_eq_flight_init(s, r, region, INFINITY, 0.0, want[i].mode, &ef), "%s samples nothing", want[i].name);
        cr_expect(rd_eq_flight_samples(s, &ef, 0) == want[i].spot && rd_eq_flight_samples(s, &ef, 1) == want[i].beam,
                  "%s: spot %d, beam %d", want[i].name, rd_eq_flight_samples(s, &ef, 0), rd_eq_flight_samples(s, &ef, 1));
    }
    cr_expect(rd_eq_has_lights(s, 0) && rd_eq_has_lights(s, 1));
    rd_scene_free(s);
}
