/* nee.c: next-event estimation with multiple importance sampling (THEORY.md §1): at a medium
 * vertex or a diffuse surface, one light chosen in proportion to power (or every light, for the
 * ray marchers), one sample of it, the phase function or BSDF toward it, and an unbiased shadow
 * transmittance (transport/tracking.c); the power heuristic against the vertex's own direction
 * sampling (Veach 1997 §9.2) for the lights a sampled path can hit. */
#include "scene/rd_geom.h"
#include "transport/rd_transport.h"

/* ---- Paths meeting lights -------------------------------------------------------------- */

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

static vec3 nee_one(const rd_scene *s, const nee_site *v, pcg32 *rng, rd_track_counters *c,
                    int *light)
{
    double pmf;
    int i = rd_light_sampler_pick(&s->light_sampler, pcg32_uniform(rng), &pmf);
    if (i < 0 || !(pmf > 0.0)) {
        pcg32_uniform(rng), pcg32_uniform(rng); /* keep the stream's use fixed */
        if (light) *light = -1;
        return v3(0, 0, 0);
    }
    if (light) *light = i;
    return nee_light(s, i, pmf, v, rng, c);
}

vec3 rd_nee_light(const rd_scene *s, int region, vec3 x, vec3 d, double g, int i, pcg32 *rng,
                  rd_track_counters *c)
{
    nee_site v = {.x = x, .d = d, .region = region, .g = g, .mx = NULL, .surf = NULL};
    return nee_light(s, i, 0.0, &v, rng, c);
}

vec3 rd_nee(const rd_scene *s, int region, vec3 x, vec3 d, double g, pcg32 *rng,
            rd_track_counters *c)
{
    return rd_nee_mix(s, region, x, d, g, NULL, rng, c, NULL);
}

vec3 rd_nee_mix(const rd_scene *s, int region, vec3 x, vec3 d, double g, const rd_dir_mix *mx,
                pcg32 *rng, rd_track_counters *c, int *light)
{
    nee_site v = {.x = x, .d = d, .region = region, .g = g, .mx = mx, .surf = NULL};
    return nee_one(s, &v, rng, c, light);
}

vec3 rd_nee_surface(const rd_scene *s, const rd_hit *h, vec3 d, pcg32 *rng,
                    rd_track_counters *c)
{
    /* The light is looked for on the side d arrived from (a diffuse surface is opaque). */
    nee_site v = {.x = h->p, .d = d, .region = h->medium_from, .g = 0.0, .mx = NULL, .surf = h};
    return nee_one(s, &v, rng, c, NULL);
}

/* Light i's sample at v, times its weight light_w[i] (NULL: 1); a weight of 0 costs nothing. */
static vec3 nee_weighted(const rd_scene *s, int i, const double *light_w, const nee_site *v, pcg32 *rng,
                         rd_track_counters *c)
{
    double w = light_w ? light_w[i] : 1.0;
    if (!(w > 0.0)) return v3(0, 0, 0);
    vec3 L = nee_light(s, i, 0.0, v, rng, c);
    return w == 1.0 ? L : v3_scale(L, w);
}

vec3 rd_nee_split(const rd_scene *s, int region, vec3 x, vec3 d, double g, const double *light_w,
                  pcg32 *rng, rd_track_counters *c)
{
    nee_site v = {.x = x, .d = d, .region = region, .g = g, .mx = NULL, .surf = NULL};
    vec3 L = v3(0, 0, 0);
    for (int i = 0; i < s->n_lights; i++)
        if (!rd_light_hittable(&s->lights[i])) L = v3_add(L, nee_weighted(s, i, light_w, &v, rng, c));
    /* The lights a path can hit: delta's own pick (pmf_i), so that its power-heuristic weight
     * pairs with the one rd_flight_behind gives the path that hits light i. A pick of a delta
     * light adds nothing here (that light was summed above). */
    double pmf;
    int i = rd_light_sampler_pick(&s->light_sampler, pcg32_uniform(rng), &pmf);
    if (i >= 0 && pmf > 0.0 && rd_light_hittable(&s->lights[i]))
        L = v3_add(L, nee_light(s, i, pmf, &v, rng, c));
    return L;
}

vec3 rd_nee_all(const rd_scene *s, int region, vec3 x, vec3 d, double g, const double *light_w,
                pcg32 *rng, rd_track_counters *c)
{
    nee_site v = {.x = x, .d = d, .region = region, .g = g, .mx = NULL, .surf = NULL};
    vec3 L = v3(0, 0, 0);
    for (int i = 0; i < s->n_lights; i++) L = v3_add(L, nee_weighted(s, i, light_w, &v, rng, c));
    return L;
}
