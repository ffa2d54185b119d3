/* lights.c: the lights on their own (rd_light.h): a sample of one light seen from a point and
 * its solid-angle pdf (for next-event estimation and its MIS weights, transport/nee.c), a
 * sphere light's hit, emitted power, and the alias table that chooses lights in proportion to
 * power (for next-event estimation and photon emission). */
#include "scene/rd_light.h"

#include <stdlib.h>
#include <string.h>

/* Spot falloff: smoothstep from the cone edge (cos_outer) to cos_inner (pbrt-v4 SpotLight). */
double rd_spot_falloff(const rd_light *l, double cos_theta)
{
    if (cos_theta <= l->cos_outer) return 0.0;
    if (cos_theta >= l->cos_inner) return 1.0;
    double t = (cos_theta - l->cos_outer) / (l->cos_inner - l->cos_outer);
    return t * t * (3.0 - 2.0 * t);
}

/* Distance along unit w from x to the first intersection with a sphere (x outside it). The
 * discriminant is r^2 - |f|^2 with f the component of x - c perpendicular to w (pbrt-v4's
 * robust quadratic): b^2 - (|oc|^2 - r^2) cancels catastrophically for small, distant spheres. */
static double sphere_hit(vec3 c, double r, vec3 x, vec3 w)
{
    vec3 oc = v3_sub(x, c);
    double b = v3_dot(oc, w);
    vec3 f = v3_madd(oc, w, -b);
    double disc = r * r - v3_dot(f, f);
    if (disc < 0.0) return INFINITY;
    double t = -b - sqrt(disc);
    return t > 0.0 ? t : INFINITY;
}

/* The cone a sphere of radius r subtends from a point at distance dc > r from its centre:
 * sin^2 and 1 - cos of its half angle. 1 - cos_max is written sin^2 / (1 + cos_max), an exact
 * identity free of the cancellation of 1 - sqrt(1 - sin^2) for tiny or distant spheres (the
 * same concern as pbrt-v4's small-angle branch in Sphere::Sample). */
static double cone_one_minus_cos(double r2, double dc2, double *sin2_max)
{
    double s2 = r2 / dc2;
    *sin2_max = s2;
    return s2 / (1.0 + sqrt(fmax(0.0, 1.0 - s2)));
}

int rd_light_sample_li(const rd_light *l, vec3 x, double u1, double u2, rd_light_sample *s)
{
    switch (l->kind) {
    case RD_LIGHT_POINT:
    case RD_LIGHT_SPOT: {
        vec3 d = v3_sub(l->pos, x);
        double r2 = v3_dot(d, d);
        if (r2 <= 0.0) return 0;
        s->dist = sqrt(r2);
        s->wi = v3_scale(d, 1.0 / s->dist);
        double f = 1.0;
        if (l->kind == RD_LIGHT_SPOT) f = rd_spot_falloff(l, -v3_dot(s->wi, l->dir));
        if (f <= 0.0) return 0;
        s->contrib = v3_scale(l->value, f / r2); /* I / r^2 */
        s->pdf = 0.0;
        return 1;
    }
    case RD_LIGHT_DIRECTIONAL: {
        if (l->radius > 0.0) { /* beam: only points within `radius` of the axis are lit */
            vec3 q = v3_sub(x, l->beam_center);
            vec3 perp = v3_madd(q, l->dir, -v3_dot(q, l->dir));
            if (v3_dot(perp, perp) > l->radius * l->radius) return 0;
        }
        s->wi = v3_scale(l->dir, -1.0);
        s->dist = INFINITY;
        s->contrib = l->value; /* irradiance E */
        s->pdf = 0.0;
        return 1;
    }
    case RD_LIGHT_SPHERE: {
        /* Uniform sampling of the cone of directions the sphere subtends (pbrt-v4 Sphere),
         * in terms of 1 - cos so that tiny and distant spheres keep full precision. */
        vec3 d = v3_sub(l->pos, x);
        double dc2 = v3_dot(d, d), r2 = l->radius * l->radius;
        if (dc2 <= r2) return 0; /* inside the emitter: no contribution */
        double dc = sqrt(dc2), sin2_max;
        vec3 axis = v3_scale(d, 1.0 / dc);
        double omc_max = cone_one_minus_cos(r2, dc2, &sin2_max);
        double omc = u1 * omc_max;                 /* 1 - cos(theta), uniform in [0, omc_max] */
        double cos_t = 1.0 - omc, sin2_t = omc * (2.0 - omc);
        double sin_t = sqrt(fmax(0.0, sin2_t));
        double phi = 2.0 * M_PI * u2;
        vec3 a, b;
        v3_basis(axis, &a, &b);
        s->wi = v3_norm(v3_add(v3_scale(axis, cos_t), v3_add(v3_scale(a, sin_t * cos(phi)), v3_scale(b, sin_t * sin(phi)))));
        /* Distance to the near surface along wi: dc cos - sqrt(r^2 - dc^2 sin^2), with
         * dc^2 sin^2 <= r^2 by construction (clamped against round-off). */
        s->dist = fmax(0.0, dc * cos_t - sqrt(fmax(0.0, r2 - dc2 * sin2_t)));
        s->pdf = 1.0 / (2.0 * M_PI * omc_max);
        s->contrib = v3_scale(l->value, 1.0 / s->pdf);
        return 1;
    }
    case RD_LIGHT_ENVIRONMENT:
        s->wi = rd_sample_sphere(u1, u2);
        s->dist = INFINITY;
        s->pdf = RD_INV_4PI;
        s->contrib = v3_scale(l->value, 4.0 * M_PI);
        return 1;
    }
    return 0;
}

double rd_light_pdf(const rd_light *l, vec3 x, vec3 w)
{
    if (l->kind == RD_LIGHT_ENVIRONMENT) return RD_INV_4PI;
    if (l->kind != RD_LIGHT_SPHERE) return 0.0;
    vec3 d = v3_sub(l->pos, x);
    double dc2 = v3_dot(d, d), r2 = l->radius * l->radius, sin2_max;
    if (dc2 <= r2) return 0.0;
    /* w is inside the cone when it points at the centre's side and passes within r of it
     * (|w x d| <= r: no cancellation, unlike comparing cosines near 1). */
    vec3 cr = v3_cross(w, d);
    if (v3_dot(w, d) <= 0.0 || v3_dot(cr, cr) > r2) return 0.0;
    return 1.0 / (2.0 * M_PI * cone_one_minus_cos(r2, dc2, &sin2_max));
}

/* A directional beam's cylinder along a line: x(t) = o + t d is lit when its distance from the
 * axis (through c along a, |a| = 1) is at most the radius R. With the parts of d and q = o - c
 * across the axis, u = d - (d.a) a and w = q - (q.a) a, that is |w + t u|^2 <= R^2:
 *   (u.u) t^2 + 2 (u.w) t + (w.w - R^2) <= 0,
 * one interval between the roots (a line parallel to the axis is lit everywhere or nowhere). */
static int beam_chord(const rd_light *l, ray3 r, double *t0, double *t1)
{
    vec3 a = l->dir, q = v3_sub(r.o, l->beam_center);
    vec3 u = v3_madd(r.d, a, -v3_dot(r.d, a)), w = v3_madd(q, a, -v3_dot(q, a));
    double A = v3_dot(u, u), B = v3_dot(u, w), C = v3_dot(w, w) - l->radius * l->radius;
    if (!(A > 1e-12)) return C <= 0.0; /* parallel to the axis: inside or not */
    double disc = B * B - A * C;
    if (!(disc > 0.0)) return 0;
    /* the stable pair of roots (Numerical Recipes §5.6) of A t^2 + 2 B t + C */
    double k = -(B + (B >= 0.0 ? sqrt(disc) : -sqrt(disc)));
    double lo = k / A, hi = C / k; /* k != 0: disc > 0 */
    if (lo > hi) {
        double tmp = lo;
        lo = hi, hi = tmp;
    }
    lo = fmax(lo, *t0), hi = fmin(hi, *t1);
    if (!(hi > lo)) return 0;
    *t0 = lo;
    *t1 = hi;
    return 1;
}

/* The spot's cone along a line: x(t) = o + t d is lit when f(t) = a.(x - p) > c |x - p|, a the
 * axis, p the apex, c = cos_outer >= 0. Squaring, f^2 - c^2 |x - p|^2 = A t^2 + B t + C with
 *   A = (a.d)^2 - c^2,  B = 2 ((a.d)(a.q) - c^2 (d.q)),  C = (a.q)^2 - c^2 q.q,  q = o - p,
 * whose roots and the root of f (the apex plane) split the line into pieces on which the
 * condition is constant: each piece is tested at its midpoint with the unsquared condition,
 * and the lit pieces (one interval: the cone is convex) are kept. */
int rd_light_lit_range(const rd_light *l, ray3 r, double *t0, double *t1)
{
    if (!(*t1 > *t0)) return 0;
    if (l->kind == RD_LIGHT_DIRECTIONAL && l->radius > 0.0) return beam_chord(l, r, t0, t1);
    if (l->kind != RD_LIGHT_SPOT) return 1;
    vec3 q = v3_sub(r.o, l->pos), a = l->dir;
    double c = fmax(0.0, l->cos_outer), ad = v3_dot(a, r.d), aq = v3_dot(a, q);
    double A = ad * ad - c * c, B = 2.0 * (ad * aq - c * c * v3_dot(r.d, q)), C = aq * aq - c * c * v3_dot(q, q);
    double cut[5];
    int n = 0;
    cut[n++] = *t0;
    double scale = fmax(fabs(A), fmax(fabs(B), fabs(C)));
    if (fabs(A) > 1e-12 * scale) {
        double disc = B * B - 4.0 * A * C;
        if (disc >= 0.0) {
            /* the stable pair of roots (Numerical Recipes §5.6) */
            double sq = sqrt(disc), k = -0.5 * (B + (B >= 0.0 ? sq : -sq));
            if (k != 0.0) cut[n++] = k / A, cut[n++] = C / k;
            else cut[n++] = 0.0;
        }
    } else if (B != 0.0) {
        cut[n++] = -C / B;
    }
    if (ad != 0.0) cut[n++] = -aq / ad;
    /* sort the cuts, keep those inside (t0, t1), close with t1 */
    for (int i = 1; i < n; i++)
        for (int k = i; k > 0 && cut[k - 1] > cut[k]; k--) {
            double tmp = cut[k];
            cut[k] = cut[k - 1];
            cut[k - 1] = tmp;
        }
    double lo = INFINITY, hi = -INFINITY, prev = *t0;
    for (int i = 0; i <= n; i++) {
        double next = i < n ? cut[i] : *t1;
        if (!(next > prev)) continue;
        if (next > *t1) next = *t1;
        double m = 0.5 * (prev + next);
        vec3 x = v3_add(q, v3_scale(r.d, m));
        if (v3_dot(a, x) > c * v3_len(x)) {
            lo = fmin(lo, prev);
            hi = fmax(hi, next);
        }
        prev = next;
        if (prev >= *t1) break;
    }
    if (!(hi > lo)) return 0;
    *t0 = lo;
    *t1 = hi;
    return 1;
}

int rd_light_is_delta(const rd_light *l)
{
    return l->kind == RD_LIGHT_POINT || l->kind == RD_LIGHT_SPOT || l->kind == RD_LIGHT_DIRECTIONAL;
}

/* Distance to the sphere light along a ray, for paths that hit it. */
double rd_light_hit(const rd_light *l, ray3 r)
{
    if (l->kind != RD_LIGHT_SPHERE) return INFINITY;
    vec3 d = v3_sub(l->pos, r.o);
    if (v3_dot(d, d) <= l->radius * l->radius) return INFINITY;
    return sphere_hit(l->pos, l->radius, r.o, r.d);
}

double rd_light_power(const rd_light *l, double scene_radius)
{
    double v = v3_lum(l->value);
    switch (l->kind) {
    case RD_LIGHT_POINT: return 4.0 * M_PI * v;
    case RD_LIGHT_SPOT: /* 2 pi I times the integral of the falloff over cos: mid-falloff cone */
        return 2.0 * M_PI * v * (1.0 - 0.5 * (l->cos_inner + l->cos_outer));
    case RD_LIGHT_DIRECTIONAL: {
        double r = l->radius > 0 ? fmin(l->radius, scene_radius) : scene_radius;
        return v * M_PI * r * r;
    }
    case RD_LIGHT_SPHERE: return v * M_PI * 4.0 * M_PI * l->radius * l->radius;
    case RD_LIGHT_ENVIRONMENT: return v * M_PI * 4.0 * M_PI * scene_radius * scene_radius;
    }
    return 0.0;
}

/* ---- Choosing a light: Walker's alias method over the lights' power ------------------------ */

/* Vose's construction of the alias table (Vose 1991): O(n) set-up, O(1) draws. Lights are
 * chosen in proportion to rd_light_power; all-zero powers fall back to uniform. */
rd_status rd_light_sampler_build(rd_light_sampler *ls, const rd_light *lights, int n,
                                 double scene_radius)
{
    memset(ls, 0, sizeof *ls);
    if (n <= 0) return RD_OK;
    ls->pmf = malloc((size_t)n * sizeof *ls->pmf);
    ls->prob = malloc((size_t)n * sizeof *ls->prob);
    ls->alias = malloc((size_t)n * sizeof *ls->alias);
    int *small = malloc((size_t)n * sizeof *small), *large = malloc((size_t)n * sizeof *large);
    if (!ls->pmf || !ls->prob || !ls->alias || !small || !large) {
        free(small);
        free(large);
        rd_light_sampler_free(ls);
        return RD_ERR_NOMEM;
    }
    ls->n = n;
    double total = 0.0;
    for (int i = 0; i < n; i++) {
        double p = rd_light_power(&lights[i], scene_radius);
        ls->pmf[i] = isfinite(p) && p > 0.0 ? p : 0.0;
        total += ls->pmf[i];
    }
    for (int i = 0; i < n; i++) ls->pmf[i] = total > 0.0 ? ls->pmf[i] / total : 1.0 / n;
    int ns = 0, nl = 0;
    for (int i = 0; i < n; i++) {
        ls->prob[i] = ls->pmf[i] * n;
        ls->alias[i] = i;
        if (ls->prob[i] < 1.0) small[ns++] = i;
        else large[nl++] = i;
    }
    while (ns > 0 && nl > 0) {
        int sm = small[--ns], lg = large[--nl];
        ls->alias[sm] = lg;
        ls->prob[lg] -= 1.0 - ls->prob[sm];
        if (ls->prob[lg] < 1.0) small[ns++] = lg;
        else large[nl++] = lg;
    }
    while (nl > 0) ls->prob[large[--nl]] = 1.0; /* round-off leftovers keep their own column */
    while (ns > 0) ls->prob[small[--ns]] = 1.0;
    free(small);
    free(large);
    return RD_OK;
}

void rd_light_sampler_free(rd_light_sampler *ls)
{
    if (!ls) return;
    free(ls->pmf);
    free(ls->prob);
    free(ls->alias);
    memset(ls, 0, sizeof *ls);
}

int rd_light_sampler_pick(const rd_light_sampler *ls, double u, double *pmf)
{
    if (ls->n <= 0) return -1;
    double x = u * ls->n;
    int i = (int)x;
    if (i >= ls->n) i = ls->n - 1;
    int k = (x - i) < ls->prob[i] ? i : ls->alias[i];
    if (pmf) *pmf = ls->pmf[k];
    return k;
}

