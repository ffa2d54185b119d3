/* lights.c: light sampling for next-event estimation, pdfs for multiple importance sampling,
 * and light power (for choosing lights in proportion to power when tracing photons). */
#include "scene/rd_geom.h"

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

/* ---- Paths meeting lights -------------------------------------------------------------- */

int rd_scene_hit_light(const rd_scene *s, ray3 r, double tmax, int skip, double *t_hit)
{
    int hit = -1;
    double best = tmax;
    for (int k = 0; k < s->n_sphere_lights; k++) {
        int i = s->sphere_lights[k];
        if (i == skip) continue;
        double t = rd_light_hit(&s->lights[i], r);
        if (t < best) { best = t; hit = i; }
    }
    if (t_hit) *t_hit = hit >= 0 ? best : tmax;
    return hit;
}

double rd_light_mis_pdf(const rd_scene *s, int i, vec3 x, vec3 w)
{
    return s->light_sampler.pmf[i] * rd_light_pdf(&s->lights[i], x, w);
}

double rd_power_heuristic(double a, double b)
{
    double a2 = a * a, b2 = b * b;
    return a2 + b2 > 0.0 ? a2 / (a2 + b2) : 0.0;
}

/* Next-event estimation (THEORY.md §1): one light chosen in proportion to power, one sample of
 * it, the phase function toward it, and an unbiased estimate of the shadow transmittance.
 *   L_nee = p(d . wi) Li T(x, light) / (pmf_i pdf_i)  x  w_MIS
 * with the power heuristic against phase sampling for lights a phase-sampled path can hit
 * (sphere and environment: pdf_i > 0); delta lights take weight 1. */
/* Where next-event estimation starts: a medium vertex (phase function g, or guided-unbiased's
 * direction mixture as the competing strategy) or a diffuse surface hit (its BSDF). */
typedef struct {
    vec3 x, d;
    int region;
    double g;
    const rd_dir_mix *mx;
    const rd_hit *surf;       /* NULL at a medium vertex */
} nee_site;

/* One sample of light i seen from the site: scattering x Li x unbiased shadow transmittance /
 * pdf, with the MIS weight against the site's direction sampling when `pick_pmf` > 0 (the
 * probability that light i was the one chosen), none when it is 0 (no sampled path will find
 * the light). */
static vec3 nee_light(const rd_scene *s, int i, double pick_pmf, const nee_site *v, pcg32 *rng,
                      rd_track_counters *c)
{
    double u1 = pcg32_uniform(rng), u2 = pcg32_uniform(rng);
    const rd_light *l = &s->lights[i];
    rd_light_sample ls;
    if (!rd_light_sample_li(l, v->x, u1, u2, &ls)) return v3(0, 0, 0);
    vec3 f;
    double p = 1.0, p_dir;
    ray3 sr = {v->x, ls.wi};
    if (v->surf) {
        /* BSDF times the cosine at the surface (rd_material_eval: diffuse only; zero on the
         * far side), the shadow ray spawned off the surface to wi's side. */
        const rd_hit *h = v->surf;
        vec3 fb = rd_material_eval(&s->shapes[h->shape].material, v->d, ls.wi, h->ng, &p_dir);
        f = v3_scale(fb, fabs(v3_dot(ls.wi, h->ng)));
        if (!(v3_maxc(f) > 0.0)) return v3(0, 0, 0);
        sr = rd_hit_spawn(h, ls.wi);
    } else {
        p = rd_hg_eval(v->g, v3_dot(v->d, ls.wi));
        f = v3(1, 1, 1);
        /* The competing strategy is how the path continues: the phase function, or the
         * direction mixture of guided-unbiased (its pdf at wi, rd_dir_mix_pdf). */
        p_dir = v->mx && v->mx->a > 0.0 ? rd_dir_mix_pdf(v->mx, v->g, v->d, ls.wi) : p;
    }
    double w = pick_pmf > 0.0 && ls.pdf > 0.0 ? rd_power_heuristic(pick_pmf * ls.pdf, p_dir) : 1.0;
    double T;
    if (s->geom) {
        /* Through interface surfaces; glass, diffuse surfaces and other lights block it. */
        c->shadow_rays++;
        T = rd_shadow_transmittance(s, v->region, sr, ls.dist, l->kind == RD_LIGHT_SPHERE ? i : -1, v->surf, rng, c);
    } else {
        /* Another sphere light in front of this one blocks the shadow ray. */
        if (rd_scene_hit_light(s, sr, ls.dist, i, NULL) >= 0) return v3(0, 0, 0);
        c->shadow_rays++;
        T = rd_transmittance(s, v->region, sr, 0.0, ls.dist, rng, c);
    }
    if (!(T != 0.0)) return v3(0, 0, 0);
    /* f = 1 at a medium vertex (the phase value is in p, as the estimate was always written) */
    return v3_scale(v3_mul(ls.contrib, f), p * T * w / (pick_pmf > 0.0 ? pick_pmf : 1.0));
}

static vec3 nee_one(const rd_scene *s, const nee_site *v, pcg32 *rng, rd_track_counters *c)
{
    double pmf;
    int i = rd_light_sampler_pick(&s->light_sampler, pcg32_uniform(rng), &pmf);
    if (i < 0 || !(pmf > 0.0)) {
        pcg32_uniform(rng), pcg32_uniform(rng); /* keep the stream's use fixed */
        return v3(0, 0, 0);
    }
    return nee_light(s, i, pmf, v, rng, c);
}

vec3 rd_nee(const rd_scene *s, int region, vec3 x, vec3 d, double g, pcg32 *rng,
            rd_track_counters *c)
{
    return rd_nee_mix(s, region, x, d, g, NULL, rng, c);
}

vec3 rd_nee_mix(const rd_scene *s, int region, vec3 x, vec3 d, double g, const rd_dir_mix *mx,
                pcg32 *rng, rd_track_counters *c)
{
    nee_site v = {.x = x, .d = d, .region = region, .g = g, .mx = mx, .surf = NULL};
    return nee_one(s, &v, rng, c);
}

vec3 rd_nee_surface(const rd_scene *s, const rd_hit *h, vec3 d, pcg32 *rng,
                    rd_track_counters *c)
{
    /* The light is looked for on the side d arrived from (a diffuse surface is opaque). */
    nee_site v = {.x = h->p, .d = d, .region = h->medium_from, .g = 0.0, .mx = NULL, .surf = h};
    return nee_one(s, &v, rng, c);
}

vec3 rd_nee_all(const rd_scene *s, int region, vec3 x, vec3 d, double g, pcg32 *rng,
                rd_track_counters *c)
{
    nee_site v = {.x = x, .d = d, .region = region, .g = g, .mx = NULL, .surf = NULL};
    vec3 L = v3(0, 0, 0);
    for (int i = 0; i < s->n_lights; i++) L = v3_add(L, nee_light(s, i, 0.0, &v, rng, c));
    return L;
}
