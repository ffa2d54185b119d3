/* integrator_delta.c: the unbiased reference, method `delta`.
 *
 * Volumetric path tracing (THEORY.md §1-2): free paths by delta tracking, next-event estimation
 * to every light with ratio-tracking transmittance, Henyey-Greenstein phase sampling, Russian
 * roulette on the path throughput, and multiple importance sampling (power heuristic) between
 * light sampling and phase sampling for the lights a path can hit (sphere, environment). */
#include "rd_internal.h"

static double power_heuristic(double a, double b)
{
    double a2 = a * a, b2 = b * b;
    return a2 + b2 > 0.0 ? a2 / (a2 + b2) : 0.0;
}

/* Light reached by an escaping ray, or by a ray that hits a sphere light at distance t_light
 * (index hit_light). `phase_pdf` is the pdf with which the direction was sampled (0 for camera
 * rays: no MIS, full weight). */
static vec3 escaped_radiance(const rd_scene *s, ray3 r, int hit_light, double phase_pdf)
{
    vec3 L = v3(0, 0, 0);
    if (hit_light >= 0) {
        const rd_light *l = &s->lights[hit_light];
        double w = phase_pdf > 0.0 ? power_heuristic(phase_pdf, rd_light_pdf(l, r.o, r.d)) : 1.0;
        return v3_scale(l->value, w);
    }
    for (int i = 0; i < s->n_lights; i++) {
        const rd_light *l = &s->lights[i];
        if (l->kind != RD_LIGHT_ENVIRONMENT) continue;
        double w = phase_pdf > 0.0 ? power_heuristic(phase_pdf, RD_INV_4PI) : 1.0;
        L = v3_madd(L, l->value, w);
    }
    return L;
}

vec3 rd_delta_radiance(const rd_scene *s, ray3 r, pcg32 *rng, rd_track_counters *c,
                       uint64_t *shadow_rays)
{
    vec3 L = v3(0, 0, 0), beta = v3(1, 1, 1);
    double phase_pdf = 0.0; /* pdf of the current direction; 0 for the camera ray */
    for (int depth = 0;; depth++) {
        /* The nearest sphere light ends the free flight like a surface would. */
        double t_light = INFINITY;
        int hit_light = -1;
        for (int i = 0; i < s->n_lights; i++) {
            double t = rd_light_hit(&s->lights[i], r);
            if (t < t_light) { t_light = t; hit_light = i; }
        }
        rd_collision col = rd_sample_free_path(s, r, t_light, rng, c);
        /* Weighted trackers (seed 002 Alg. 2-3) return a path weight; 1 for delta tracking. */
        if (col.weight != 1.0) beta = v3_scale(beta, col.weight);
        if (!col.hit) {
            L = v3_add(L, v3_mul(beta, escaped_radiance(s, r, hit_light, phase_pdf)));
            if (depth == 0 && hit_light < 0) L = v3_add(L, v3_mul(beta, s->background));
            break;
        }
        if (depth + 1 > s->settings.max_depth) break; /* this would be scattering event depth+1 */
        const rd_medium *m = col.medium;
        vec3 x = ray_at(r, col.t);
        /* Real collision: sigma_s/sigma_t = albedo continues, the rest is absorbed (as weight). */
        beta = v3_mul(beta, m->albedo);

        /* Next-event estimation to every light: beta p(w_prop, wi) Li T. */
        for (int i = 0; i < s->n_lights; i++) {
            const rd_light *l = &s->lights[i];
            rd_light_sample ls;
            if (!rd_light_sample_li(l, x, pcg32_uniform(rng), pcg32_uniform(rng), &ls)) continue;
            double p = rd_hg_eval(m->g, v3_dot(r.d, ls.wi));
            double w = ls.pdf > 0.0 ? power_heuristic(ls.pdf, p) : 1.0;
            ray3 sr = {x, ls.wi};
            /* Other sphere lights may block the shadow ray. */
            double dist = ls.dist;
            for (int k = 0; k < s->n_lights; k++)
                if (k != i) dist = fmin(dist, rd_light_hit(&s->lights[k], sr));
            if (dist < ls.dist) continue;
            (*shadow_rays)++;
            double T = rd_transmittance(s, sr, ls.dist, rng, c);
            if (T > 0.0) L = v3_add(L, v3_scale(v3_mul(beta, ls.contrib), p * T * w));
        }

        /* Russian roulette on the throughput. Weighted trackers with non-bounding majorants
         * can make weights negative: survive with the largest magnitude, not the largest value. */
        if (depth + 1 >= s->settings.rr_depth) {
            double q = fmin(1.0, fmax(fabs(beta.x), fmax(fabs(beta.y), fabs(beta.z))));
            if (q <= 0.0 || pcg32_uniform(rng) >= q) break;
            beta = v3_scale(beta, 1.0 / q);
        }

        /* Phase sampling: the weight p/pdf is 1 for HG importance sampling. */
        vec3 wo = rd_hg_sample(m->g, r.d, pcg32_uniform(rng), pcg32_uniform(rng));
        phase_pdf = rd_hg_eval(m->g, v3_dot(r.d, wo));
        r.o = x;
        r.d = wo;
    }
    return L;
}
