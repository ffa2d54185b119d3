/* lights.c: light sampling for next-event estimation, pdfs for multiple importance sampling,
 * and light power (for choosing lights in proportion to power when tracing photons). */
#include "rd_internal.h"

/* Spot falloff: smoothstep from the cone edge (cos_outer) to cos_inner (pbrt-v4 SpotLight). */
double rd_spot_falloff(const rd_light *l, double cos_theta)
{
    if (cos_theta <= l->cos_outer) return 0.0;
    if (cos_theta >= l->cos_inner) return 1.0;
    double t = (cos_theta - l->cos_outer) / (l->cos_inner - l->cos_outer);
    return t * t * (3.0 - 2.0 * t);
}

/* Distance along unit w from x to the first intersection with a sphere (x outside it). */
static double sphere_hit(vec3 c, double r, vec3 x, vec3 w)
{
    vec3 oc = v3_sub(x, c);
    double b = v3_dot(oc, w), q = v3_dot(oc, oc) - r * r;
    double disc = b * b - q;
    if (disc < 0.0) return INFINITY;
    double t = -b - sqrt(disc);
    return t > 0.0 ? t : INFINITY;
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
        /* Uniform sampling of the cone of directions the sphere subtends (pbrt-v4 Sphere). */
        vec3 d = v3_sub(l->pos, x);
        double dc2 = v3_dot(d, d), r2 = l->radius * l->radius;
        if (dc2 <= r2) return 0; /* inside the emitter: no contribution */
        double dc = sqrt(dc2);
        vec3 axis = v3_scale(d, 1.0 / dc);
        double cos_max = sqrt(fmax(0.0, 1.0 - r2 / dc2));
        double cos_t = 1.0 - u1 * (1.0 - cos_max);
        double sin_t = sqrt(fmax(0.0, 1.0 - cos_t * cos_t));
        double phi = 2.0 * M_PI * u2;
        vec3 a, b;
        v3_basis(axis, &a, &b);
        s->wi = v3_norm(v3_add(v3_scale(axis, cos_t), v3_add(v3_scale(a, sin_t * cos(phi)), v3_scale(b, sin_t * sin(phi)))));
        s->dist = sphere_hit(l->pos, l->radius, x, s->wi);
        if (!isfinite(s->dist)) s->dist = dc - l->radius; /* grazing round-off */
        s->pdf = 1.0 / (2.0 * M_PI * (1.0 - cos_max));
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
    double dc2 = v3_dot(d, d), r2 = l->radius * l->radius;
    if (dc2 <= r2 || !isfinite(sphere_hit(l->pos, l->radius, x, w))) return 0.0;
    double cos_max = sqrt(fmax(0.0, 1.0 - r2 / dc2));
    return 1.0 / (2.0 * M_PI * (1.0 - cos_max));
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
