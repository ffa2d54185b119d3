/* integrator_delta.c: the unbiased path loop, and with delta tracking as its free-flight
 * sampler the reference method `delta`.
 *
 * Volumetric path tracing (THEORY.md §1-2): free flights from a pluggable sampler
 * (rd_flight_sampler: delta tracking over the free-path engine here, guided distances in
 * integrator_gu.c), next-event estimation (rd_nee: one light chosen by power, unbiased shadow
 * transmittance), Henyey-Greenstein phase sampling, Russian roulette on the path weight, and
 * multiple importance sampling (power heuristic) between light sampling and phase sampling for
 * the lights a path can hit (sphere, environment). */
#include "rd_method.h"

/* Light reached by an escaping ray, or by a ray that hits sphere light `hit_light`. `phase_pdf`
 * is the pdf with which the direction was sampled (0 for camera rays: no MIS, full weight);
 * the light's pdf in the MIS weight includes its probability of being chosen by rd_nee. */
static vec3 escaped_radiance(const rd_scene *s, ray3 r, int hit_light, double phase_pdf)
{
    if (hit_light >= 0) {
        double w = phase_pdf > 0.0 ? rd_power_heuristic(phase_pdf, rd_light_mis_pdf(s, hit_light, r.o, r.d)) : 1.0;
        return v3_scale(s->lights[hit_light].value, w);
    }
    vec3 L = v3(0, 0, 0);
    for (int i = 0; i < s->n_lights; i++) {
        const rd_light *l = &s->lights[i];
        if (l->kind != RD_LIGHT_ENVIRONMENT) continue;
        double w = phase_pdf > 0.0 ? rd_power_heuristic(phase_pdf, rd_light_mis_pdf(s, i, r.o, r.d)) : 1.0;
        L = v3_madd(L, l->value, w);
    }
    return L;
}

vec3 rd_flight_behind(const rd_scene *s, const rd_flight_in *in)
{
    vec3 L = escaped_radiance(s, in->r, in->hit_light, in->phase_pdf);
    if (in->depth == 0 && in->hit_light < 0) L = v3_add(L, s->background);
    return L;
}

rd_flight rd_flight_delta(const rd_scene *s, const rd_flight_in *in, pcg32 *rng,
                          rd_track_counters *c)
{
    rd_collision col = rd_sample_free_path(s, in->r, in->t_light, rng, c);
    rd_flight f;
    f.kind = col.hit ? RD_FLIGHT_SCATTER : RD_FLIGHT_PASS;
    f.t = col.t;
    f.medium = col.medium;
    /* Delta tracking draws t with density sigma_t(t) T(0,t) and passes with probability
     * T(0,t_end), so the vertex weight T sigma_s / (sigma_t T) is the albedo and the pass
     * weight T / T is 1 (rd_flight); weighted trackers (seed 002 Alg. 2-3) add their own
     * factor, 1 for delta tracking. */
    f.weight = col.hit ? v3_scale(col.medium->albedo, col.weight) : v3(col.weight, col.weight, col.weight);
    return f;
}

static rd_flight delta_flight(const rd_flight_sampler *fs, const rd_scene *s,
                              const rd_flight_in *in, pcg32 *rng, rd_track_counters *c)
{
    (void)fs;
    return rd_flight_delta(s, in, rng, c);
}

vec3 rd_path_radiance(const rd_scene *s, ray3 r, const rd_flight_sampler *fs, pcg32 *rng,
                      rd_track_counters *c)
{
    vec3 L = v3(0, 0, 0), beta = v3(1, 1, 1);
    double phase_pdf = 0.0; /* pdf of the current direction; 0 for the camera ray */
    for (int depth = 0;; depth++) {
        /* The nearest sphere light ends the free flight like a surface would. */
        rd_flight_in in = {.r = r, .depth = depth, .phase_pdf = phase_pdf};
        in.hit_light = rd_scene_hit_light(s, r, INFINITY, -1, &in.t_light);
        rd_flight f = fs->sample(fs, s, &in, rng, c);
        if (f.kind == RD_FLIGHT_END) break;
        beta = v3_mul(beta, f.weight);
        if (f.kind == RD_FLIGHT_PASS) {
            L = v3_add(L, v3_mul(beta, rd_flight_behind(s, &in)));
            break;
        }
        if (depth + 1 > s->settings.max_depth) break; /* this would be scattering event depth+1 */
        const rd_medium *m = f.medium;
        vec3 x = ray_at(r, f.t);
        /* Scattering vertex: beta now carries T sigma_s / pdf (rd_flight), so what follows
         * estimates L_s(x, -d) = integral of p L (THEORY.md §1): next-event estimation for the
         * direct part, the phase-sampled continuation for the rest. */
        L = v3_add(L, v3_mul(beta, rd_nee(s, x, r.d, m->g, rng, c)));

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

vec3 rd_delta_radiance(const rd_scene *s, ray3 r, pcg32 *rng, rd_track_counters *c)
{
    const rd_flight_sampler fs = {.sample = delta_flight, .user = NULL};
    return rd_path_radiance(s, r, &fs, rng, c);
}

/* The method-table entry: the path's random numbers are one keyed stream (rd_sampler_stream). */
static vec3 delta_method_radiance(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    pcg32 rng = rd_sampler_stream(smp);
    return rd_delta_radiance(ctx->scene, r, &rng, &th->counters);
}

const rd_method rd_method_delta = {
    .name = "delta",
    .summary = "unbiased reference: delta tracking, next-event estimation with ratio tracking, MIS",
    .needs = 0,
    .radiance = delta_method_radiance,
};
