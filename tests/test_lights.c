/* Single scattering (settings.max_depth 1) from each kind of light against a quadrature the
 * renderer did not compute:
 *  - a spot light, the camera ray crossing its smooth falloff band;
 *  - a directional light with a finite beam (the integrand jumps at the beam's edge);
 *  - a sphere light outside the medium and one inside it, for rays beside it and a ray that
 *    hits it (its answer includes the emitted radiance times the transmittance).
 * The single-scattering integral along a camera ray x(t) = o + t d (THEORY.md §1, eq. 1 of
 * seed 001 cut at one scattering event) is
 *   L = int T(o, x) sigma_s(x) int p(d . wi) Li(x, wi) T(x, light) dwi dt  (+ T L_e on a hit),
 * with rd_hg_eval's convention p(d . wi), wi pointing toward the light.
 * Every Monte Carlo estimate goes through rt_delta_mc (support/rd_test.h) with a fixed seed;
 * the tolerance is 5 standard errors of its mean (a false alarm per check has probability
 * 6e-7), and each test also checks the standard error is below 2% of the answer so that the
 * comparison has power. Each quadrature is computed at two resolutions: their difference
 * bounds its error (Simpson and Gauss rules converge faster than that difference shrinks) and
 * must be far below the standard error. */
#include "support/rd_test.h"

/* Homogeneous box [-1,1]^3 used by every test here. */
static const vec3 BOX_MIN = {-1, -1, -1}, BOX_MAX = {1, 1, 1};

/* Compare the three channels of a Monte Carlo estimate with exact[]: 5 standard errors, and
 * the standard error below 2% of the answer. */
static void expect_matches(const char *what, rt_mc mc, const double exact[3])
{
    for (int k = 0; k < 3; k++) {
        double m = v3_get(mc.mean, k), se = v3_get(mc.se, k);
        cr_expect(fabs(m - exact[k]) < 5.0 * se, "%s, channel %d: delta %.6f vs quadrature %.6f (se %.6f, %.1f se)",
                  what, k, m, exact[k], se, fabs(m - exact[k]) / se);
        cr_expect(se < 0.02 * exact[k], "%s, channel %d: se %.6f is not below 2%% of %.6f", what, k, se, exact[k]);
    }
}

/* The quadrature at resolutions n and 2n must agree far below the Monte Carlo noise. */
static void expect_converged(const char *what, double q_n, double q_2n, double se)
{
    cr_assert(fabs(q_2n - q_n) < 0.01 * se, "%s: quadrature not converged (%.3e vs %.3e, se %.3e)", what, q_n,
              q_2n, se);
}

/* ---- Point-like lights along the ray (spot and directional) ------------------------------ */

/* Everything the integrand along the camera ray needs. */
typedef struct {
    ray3 ray;
    double t0;         /* where the ray enters the box */
    double sigma_t, g;
    const rd_light *light;
    int falloff;       /* spot: apply the falloff (0 gives the answer without it) */
} line_ctx;

/* sigma_t T(t0, t) p(d . wi) Li T(x, light) for a spot light, per unit albedo and unit
 * intensity: Li = falloff(-wi . axis) / r^2 (pbrt-v4 SpotLight, renderer/scene/lights.c). */
static double spot_integrand(double t, const void *p)
{
    const line_ctx *c = p;
    vec3 x = ray_at(c->ray, t), tol = v3_sub(c->light->pos, x);
    double r2 = v3_dot(tol, tol);
    vec3 wi = v3_scale(tol, 1.0 / sqrt(r2));
    /* rd_spot_falloff is one smoothstep: written out here rather than called, so a defect in
     * it cannot cancel out of the comparison. */
    double f = 1.0, ct = -v3_dot(wi, c->light->dir);
    if (c->falloff) {
        double lo = c->light->cos_outer, hi = c->light->cos_inner;
        double s = fmin(1.0, fmax(0.0, (ct - lo) / (hi - lo)));
        f = s * s * (3.0 - 2.0 * s);
    }
    double tl = rt_inside_length(BOX_MIN, BOX_MAX, x, c->light->pos);
    return exp(-c->sigma_t * (t - c->t0)) * c->sigma_t * rd_hg_eval(c->g, v3_dot(c->ray.d, wi)) * f / r2 *
           exp(-c->sigma_t * tl);
}

Test(lights, spot_falloff_single_scattering, .timeout = 60)
{
    /* Spot 2.5 m above the box centre, pointing down; full cone 60 degrees, falloff over the
     * outer 15 degrees of the 30-degree half-angle (cos_inner = cos 15, cos_outer = cos 30).
     * The ray at y = 0, z = 0.5 along x is 11 degrees off the axis at x = 0 and 24 degrees at
     * x = +-1: it runs from the full-intensity core into the falloff band on both sides. */
    rd_scene *s = rt_scene("spot.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":1,\"sigma_t\":1.1,\"albedo\":[0.9,0.7,0.5],\"g\":0.3}],"
                           "\"lights\":[{\"type\":\"spot\",\"position\":[0,2.5,0],\"look_at\":[0,0,0],"
                           "\"angle\":60,\"falloff\":15,\"intensity\":[4,5,6]}],"
                           "\"settings\":{\"max_depth\":1}}");
    const rd_light *l = &s->lights[0];
    cr_assert(fabs(l->cos_inner - cos(15 * M_PI / 180)) < 1e-12 && fabs(l->cos_outer - cos(30 * M_PI / 180)) < 1e-12);
    line_ctx c = {{v3(-3, 0, 0.5), v3(1, 0, 0)}, 2.0, 1.1, 0.3, l, 1};
    /* The smoothstep is C1 where the band starts (|x| = 0.39) and the integrand otherwise
     * smooth: Simpson converges, the doubling check below bounds the error. */
    double q = rt_simpson(spot_integrand, &c, 2.0, 4.0, 40000);
    double q_half = rt_simpson(spot_integrand, &c, 2.0, 4.0, 20000);
    c.falloff = 0;
    double q_nofalloff = rt_simpson(spot_integrand, &c, 2.0, 4.0, 40000);

    rt_mc mc = rt_delta_mc(s, c.ray, 200000, 501);
    const double albedo[3] = {0.9, 0.7, 0.5}, I[3] = {4, 5, 6};
    double exact[3];
    for (int k = 0; k < 3; k++) exact[k] = albedo[k] * I[k] * q;
    expect_converged("spot", q_half * albedo[1] * I[1], exact[1], mc.se.y);
    expect_matches("spot light, ray through the falloff band", mc, exact);
    /* Power: without the falloff the answer would be many standard errors away. */
    cr_expect(fabs(albedo[1] * I[1] * q_nofalloff - exact[1]) > 20 * mc.se.y,
              "the falloff changes the answer by too little for this test to see it");
    rd_scene_free(s);
}

/* Directional light: Li = E on the beam, the light's transmittance along -dir out of the box. */
static double beam_integrand(double t, const void *p)
{
    const line_ctx *c = p;
    vec3 x = ray_at(c->ray, t), wi = v3_scale(c->light->dir, -1.0);
    double tl = rt_inside_length(BOX_MIN, BOX_MAX, x, v3_madd(x, wi, 10.0));
    return exp(-c->sigma_t * (t - c->t0)) * c->sigma_t * rd_hg_eval(c->g, v3_dot(c->ray.d, wi)) *
           exp(-c->sigma_t * tl);
}

/* Where ray r is within `radius` of the line through `center` along unit `axis`: solve
 * |perp(o - c + t d)|^2 = R^2 with perp(v) = v - (v . a) a, a quadratic in t. */
static int cylinder_span(ray3 r, vec3 center, vec3 axis, double radius, double *ta, double *tb)
{
    vec3 q = v3_sub(r.o, center);
    vec3 pq = v3_madd(q, axis, -v3_dot(q, axis)), pd = v3_madd(r.d, axis, -v3_dot(r.d, axis));
    double a = v3_dot(pd, pd), b = 2.0 * v3_dot(pq, pd), cc = v3_dot(pq, pq) - radius * radius;
    double disc = b * b - 4.0 * a * cc;
    if (a <= 0.0 || disc <= 0.0) return 0;
    *ta = (-b - sqrt(disc)) / (2.0 * a);
    *tb = (-b + sqrt(disc)) / (2.0 * a);
    return 1;
}

Test(lights, directional_beam_single_scattering, .timeout = 60)
{
    /* A tilted beam of radius 0.4 through (0.1, 0, 0); the ray crosses it inside the box. */
    rd_scene *s = rt_scene("beam.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":1,\"sigma_t\":0.8,\"albedo\":[0.9,0.7,0.5],\"g\":0.4}],"
                           "\"lights\":[{\"type\":\"directional\",\"direction\":[0.3,-1,0.2],\"irradiance\":[2,3,4],"
                           "\"radius\":0.4,\"center\":[0.1,0,0]}],"
                           "\"settings\":{\"max_depth\":1}}");
    const rd_light *l = &s->lights[0];
    ray3 r = {v3(-3, 0.2, -0.1), v3_norm(v3(1, 0.05, 0.02))};
    double t0, t1, ta, tb;
    cr_assert(rd_box_intersect(BOX_MIN, BOX_MAX, r, 0, INFINITY, &t0, &t1));
    cr_assert(cylinder_span(r, l->beam_center, l->dir, l->radius, &ta, &tb));
    cr_assert(ta > t0 && tb < t1, "the beam must be crossed inside the box");
    /* The integrand is 0 outside [ta, tb] and smooth inside: integrate that piece only. */
    line_ctx c = {r, t0, 0.8, 0.4, l, 0};
    double q = rt_simpson(beam_integrand, &c, ta, tb, 2000);
    double q_half = rt_simpson(beam_integrand, &c, ta, tb, 1000);

    rt_mc mc = rt_delta_mc(s, r, 200000, 502);
    const double albedo[3] = {0.9, 0.7, 0.5}, E[3] = {2, 3, 4};
    double exact[3];
    for (int k = 0; k < 3; k++) exact[k] = albedo[k] * E[k] * q;
    expect_converged("beam", q_half * albedo[1] * E[1], exact[1], mc.se.y);
    expect_matches("directional beam", mc, exact);
    rd_scene_free(s);
}

/* ---- Sphere lights ----------------------------------------------------------------------- */

/* In-scattered radiance at x per unit sphere radiance and unit sigma_s, seen along d:
 *   S(x) = int_cone p(d . w) T(x, x + s(w) w) dw,
 * s(w) the distance to the sphere's near surface. Cone coordinates u = 1 - cos(theta) in
 * [0, u_max] and phi; with u = u_max (1 - v^2) the square-root edge of s (grazing lines) turns
 * smooth in v, so Gauss-Legendre in v and the trapezoid rule in phi (periodic) converge fast.
 * dw = du dphi = 2 u_max v dv dphi. */
typedef struct {
    ray3 ray;
    double t0, sigma_t, g;
    vec3 c;
    double radius;
    int nv, nphi;
} sphere_ctx;

/* Gauss-Legendre nodes and weights on [0, 1] by Newton on P_n (Numerical Recipes gauleg). */
static void gauss_legendre01(int n, double *x, double *w)
{
    for (int i = 0; i < n; i++) {
        double z = cos(M_PI * (i + 0.75) / (n + 0.5)), pp = 0;
        for (int it = 0; it < 100; it++) {
            double p1 = 1, p2 = 0;
            for (int j = 1; j <= n; j++) {
                double p3 = p2;
                p2 = p1;
                p1 = ((2.0 * j - 1.0) * z * p2 - (j - 1.0) * p3) / j;
            }
            pp = n * (z * p1 - p2) / (z * z - 1.0);
            double dz = p1 / pp;
            z -= dz;
            if (fabs(dz) < 1e-15) break;
        }
        x[i] = 0.5 * (1.0 - z);
        w[i] = 1.0 / ((1.0 - z * z) * pp * pp);
    }
}

static double sphere_inscatter(const sphere_ctx *c, vec3 x)
{
    double xs[128], ws[128];
    gauss_legendre01(c->nv, xs, ws);
    vec3 toc = v3_sub(c->c, x);
    double dc = v3_len(toc);
    vec3 axis = v3_scale(toc, 1.0 / dc), e1, e2;
    v3_basis(axis, &e1, &e2);
    double cos_max = sqrt(fmax(0.0, 1.0 - c->radius * c->radius / (dc * dc))), u_max = 1.0 - cos_max;
    double sum = 0.0;
    for (int i = 0; i < c->nv; i++) {
        double v = xs[i], u = u_max * (1.0 - v * v), ct = 1.0 - u, st = sqrt(fmax(0.0, 1.0 - ct * ct));
        /* distance to the near surface along a direction at angle theta from the axis */
        double s = dc * ct - sqrt(fmax(0.0, c->radius * c->radius - dc * dc * st * st));
        double ring = 0.0;
        for (int j = 0; j < c->nphi; j++) {
            double phi = 2.0 * M_PI * (j + 0.5) / c->nphi;
            vec3 w = v3_add(v3_scale(axis, ct), v3_add(v3_scale(e1, st * cos(phi)), v3_scale(e2, st * sin(phi))));
            double tl = rt_inside_length(BOX_MIN, BOX_MAX, x, v3_madd(x, w, s));
            ring += rd_hg_eval(c->g, v3_dot(c->ray.d, w)) * exp(-c->sigma_t * tl);
        }
        sum += ws[i] * 2.0 * u_max * v * ring * (2.0 * M_PI / c->nphi);
    }
    return sum;
}

/* sigma_t T(t0, t) S(x(t)) with t = t_end - len w^2 (see sphere_single_scatter). */
typedef struct {
    const sphere_ctx *c;
    double t_end, len;
} sphere_line;

static double sphere_integrand(double w, const void *p)
{
    const sphere_line *sl = p;
    double t = sl->t_end - sl->len * w * w;
    vec3 x = ray_at(sl->c->ray, t);
    return sl->c->sigma_t * exp(-sl->c->sigma_t * (t - sl->c->t0)) * sphere_inscatter(sl->c, x) * 2.0 * sl->len * w;
}

/* Single scattering per unit albedo and radiance from t0 to t_end. Where the ray ends on the
 * sphere, S grows like sqrt(t_end - t) toward it: t = t_end - len w^2 makes that smooth. */
static double sphere_single_scatter(const sphere_ctx *c, double t_end, int n)
{
    sphere_line sl = {c, t_end, t_end - c->t0};
    return rt_simpson(sphere_integrand, &sl, 0.0, 1.0, n);
}

/* One sphere-light case: quadrature at two resolutions, Monte Carlo, comparison. */
static void check_sphere_ray(rd_scene *s, ray3 r, int expect_hit, const char *what, uint64_t seed)
{
    const rd_light *l = &s->lights[0];
    const rd_medium *m = &s->media[0];
    double t0, t1;
    cr_assert(rd_box_intersect(m->bmin, m->bmax, r, 0, INFINITY, &t0, &t1));
    double t_hit = rd_light_hit(l, r);
    cr_assert(expect_hit == isfinite(t_hit), "%s: the ray should %s the sphere", what, expect_hit ? "hit" : "miss");
    double t_end = fmin(t1, t_hit);
    sphere_ctx c = {r, t0, m->sigma_t_scale, m->g, l->pos, l->radius, 24, 32};
    double q_n = sphere_single_scatter(&c, t_end, 100);
    c.nv *= 2;
    c.nphi *= 2;
    double q = sphere_single_scatter(&c, t_end, 200);
    /* A ray that hits the sphere also carries L_e T(o, hit). */
    double T_hit = expect_hit ? exp(-c.sigma_t * rt_inside_length(m->bmin, m->bmax, r.o, ray_at(r, t_hit))) : 0.0;

    rt_mc mc = rt_delta_mc(s, r, 150000, seed);
    double exact[3];
    for (int k = 0; k < 3; k++) exact[k] = v3_get(l->value, k) * (v3_get(m->albedo, k) * q + T_hit);
    expect_converged(what, q_n * m->albedo.y * l->value.y, q * m->albedo.y * l->value.y, mc.se.y);
    expect_matches(what, mc, exact);
}

Test(lights, sphere_light_outside_the_medium, .timeout = 60)
{
    /* The sphere sits above the box: every line from the box to it leaves through the top
     * face (|x|, |z| <= 0.6 on the sphere, the box is [-1,1]^3), so the light's transmittance
     * is smooth over the cone and Gauss-Legendre converges. */
    rd_scene *s = rt_scene("sphere_out.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":1,\"sigma_t\":0.9,\"albedo\":[0.9,0.7,0.5],\"g\":0.5}],"
                           "\"lights\":[{\"type\":\"sphere\",\"center\":[0,2.2,0],\"radius\":0.6,\"radiance\":[1.5,2,2.5]}],"
                           "\"settings\":{\"max_depth\":1}}");
    check_sphere_ray(s, (ray3){v3(-3, 0.3, 0.2), v3_norm(v3(1, 0.1, -0.05))}, 0, "outside, ray beside", 503);
    check_sphere_ray(s, (ray3){v3(0.2, -3, 0.1), v3_norm(v3(-0.02, 1, 0.01))}, 1, "outside, ray hits it", 504);
    rd_scene_free(s);
}

Test(lights, sphere_light_inside_the_medium, .timeout = 60)
{
    /* The sphere inside the box: the rays beside it pass 0.15 m and 0.5 m from its surface;
     * the one that hits it ends there, with the medium in front of it. */
    rd_scene *s = rt_scene("sphere_in.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":1,\"sigma_t\":1.3,\"albedo\":[0.9,0.7,0.5],\"g\":-0.2}],"
                           "\"lights\":[{\"type\":\"sphere\",\"center\":[0.1,0,0],\"radius\":0.3,\"radiance\":[1.5,2,2.5]}],"
                           "\"settings\":{\"max_depth\":1}}");
    check_sphere_ray(s, (ray3){v3(-3, 0.45, 0), v3(1, 0, 0)}, 0, "inside, ray 0.15 beside", 505);
    check_sphere_ray(s, (ray3){v3(-3, 0.1, 0.8), v3(1, 0, 0)}, 0, "inside, ray 0.5 beside", 506);
    check_sphere_ray(s, (ray3){v3(-3, 0.1, 0.05), v3(1, 0, 0)}, 1, "inside, ray hits it", 507);
    rd_scene_free(s);
}
