/* rd_light.h: the lights (scene key "lights") and their sampling: a sample of one light seen
 * from a point, its solid-angle pdf, a sphere light's hit, emitted power, and the choice of a
 * light in proportion to power (scene/lights.c). Next-event estimation, which uses these with a
 * shadow ray, is transport/nee.c. Internal to renderer/.
 *
 * Units: point/spot intensity in W/sr; sphere-light and environment radiance in W m^-2 sr^-1;
 * directional irradiance in W/m^2 (on a plane perpendicular to the beam). Colours are linear
 * RGB triplets. */
#ifndef RD_LIGHT_H
#define RD_LIGHT_H

#include "core/rd_math.h"
#include "renderer.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    RD_LIGHT_POINT,       /* pos, intensity I [W/sr] */
    RD_LIGHT_SPOT,        /* pos, dir, I [W/sr] on the axis, cone with smooth falloff */
    RD_LIGHT_DIRECTIONAL, /* dir (travel direction), irradiance E [W/m^2]; optional beam */
    RD_LIGHT_SPHERE,      /* centre, radius, uniform radiance L [W m^-2 sr^-1] */
    RD_LIGHT_ENVIRONMENT  /* uniform radiance L from every direction at infinity */
} rd_light_kind;

typedef struct {
    rd_light_kind kind;
    vec3 pos, dir;           /* dir: unit; spot axis or directional travel direction */
    vec3 value;              /* I, E or L as the kind says */
    double cos_outer;        /* spot: cos of half the cone angle */
    double cos_inner;        /* spot: cos where the smooth falloff starts */
    double radius;           /* sphere radius; directional beam radius (0 = unbounded) */
    vec3 beam_center;        /* directional beam: a point on the beam axis */
} rd_light;

/* A light sample seen from a point x, for next-event estimation. */
typedef struct {
    vec3 wi;        /* unit direction from x toward the light */
    double dist;    /* distance to the light (INFINITY for directional/environment) */
    vec3 contrib;   /* incident radiance times 1/pdf, i.e. the contribution before the phase
                       function and transmittance (delta lights: I/r^2 or E) */
    double pdf;     /* solid-angle pdf of wi; 0 for delta lights (no MIS) */
} rd_light_sample;

/* Sample light `l` from x with two uniforms; returns 0 when it contributes nothing. */
int rd_light_sample_li(const rd_light *l, vec3 x, double u1, double u2, rd_light_sample *s);
/* 1 for a light a sampled ray can hit (sphere, environment: pdf > 0 for some direction),
 * 0 for a delta light (point, spot, directional), which only next-event estimation finds. */
static inline int rd_light_hittable(const rd_light *l)
{
    return l->kind == RD_LIGHT_SPHERE || l->kind == RD_LIGHT_ENVIRONMENT;
}
/* Solid-angle pdf that rd_light_sample_li gives direction w from x (area lights only). */
double rd_light_pdf(const rd_light *l, vec3 x, vec3 w);
/* Spot light angular falloff in [0, 1] at cos_theta from its axis (smoothstep over the edge). */
double rd_spot_falloff(const rd_light *l, double cos_theta);
/* The part of [*t0, *t1] along r (r.d unit) that light l can light: a spot's
 * cone (cos from the axis > cos_outer, where the falloff is positive) cuts it to the one
 * interval where the line is inside the cone (a cone of half-angle <= 90 degrees is convex);
 * a directional beam (radius > 0) to the chord inside its cylinder; a point light, and any
 * other light, keeps it whole. Returns 0 when nothing is left. Used to restrict equiangular
 * sampling (transport/equiangular.c); a range a little too wide or narrow through round-off
 * costs efficiency there, never correctness (its MIS weights follow the range used). */
int rd_light_lit_range(const rd_light *l, ray3 r, double *t0, double *t1);
/* 1 for a point, spot or directional light: a delta in position or direction, which no sampled
 * direction can hit and a shadow ray reaches only in a straight line (rd_hidden_light). */
int rd_light_is_delta(const rd_light *l);
/* Distance along r to a sphere light's surface (INFINITY if missed or not a sphere light). */
double rd_light_hit(const rd_light *l, ray3 r);
/* Total emitted power [W] (luminance of the RGB), used to choose lights in proportion to power;
 * `scene_radius` bounds directional and environment lights. */
double rd_light_power(const rd_light *l, double scene_radius);

/* Lights chosen in proportion to power in O(1) (Walker's alias method; lights.c). pmf[i] is the
 * probability of light i (> 0 for every light of positive power). */
typedef struct {
    int n;
    double *pmf;   /* n probabilities, summing to 1 */
    double *prob;  /* alias table: keep column i with probability prob[i], else alias[i] */
    int *alias;
} rd_light_sampler;
rd_status rd_light_sampler_build(rd_light_sampler *ls, const rd_light *lights, int n,
                                 double scene_radius);
void rd_light_sampler_free(rd_light_sampler *ls);
/* The light for uniform u in [0, 1), and its probability; -1 when there are no lights. */
int rd_light_sampler_pick(const rd_light_sampler *ls, double u, double *pmf);

#ifdef __cplusplus
}
#endif
#endif /* RD_LIGHT_H */
