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

double rd_dir_mix_pdf(const rd_dir_mix *mx, double g, vec3 d, vec3 wo)
{
    double p = rd_hg_eval(g, v3_dot(d, wo));
    if (!(mx->a > 0.0)) return p;
    return mx->a * rd_vmf_eval(mx->mu, mx->kappa, wo) + (1.0 - mx->a) * p;
}

vec3 rd_dir_mix_sample(const rd_dir_mix *mx, double g, vec3 d, pcg32 *rng, double *pdf)
{
    /* One-sample MIS (Veach 1997 §9.2.4): pick a strategy, draw from it, and weight by the
     * mixture's pdf, which any draw from either strategy shares. */
    int lobe = mx->a > 0.0 && pcg32_uniform(rng) < mx->a;
    double u1 = pcg32_uniform(rng), u2 = pcg32_uniform(rng);
    vec3 wo = lobe ? rd_vmf_sample(mx->mu, mx->kappa, u1, u2) : rd_hg_sample(g, d, u1, u2);
    *pdf = rd_dir_mix_pdf(mx, g, d, wo);
    return wo;
}

/* The loop from a free flight along r on, with unit throughput: returns the radiance estimate
 * of L(r.o, -r.d). `phase_pdf` is the pdf with which r.d was drawn (0 for the camera ray),
 * `depth` the scattering events before this flight, *budget the extra copies splitting may
 * still add to this camera sample. */
static vec3 trace(const rd_scene *s, ray3 r, double phase_pdf, int depth0,
                  const rd_flight_sampler *fs, pcg32 *rng, rd_track_counters *c, int *budget);

/* One copy of a continuation from vertex x (arrived along d) with the vertex policy's
 * direction mixture: next-event estimation plus the continued path, with unit throughput
 * (an estimate of L_s(x, -d)). */
static vec3 continue_from(const rd_scene *s, vec3 x, vec3 d, const rd_medium *m,
                          const rd_dir_mix *mx, int depth, const rd_flight_sampler *fs,
                          pcg32 *rng, rd_track_counters *c, int *budget)
{
    vec3 L = rd_nee_mix(s, x, d, m->g, mx, rng, c);
    double pdf;
    vec3 wo = rd_dir_mix_sample(mx, m->g, d, rng, &pdf);
    if (!(pdf > 0.0)) return L;
    /* Weight p / pdf: 1 for phase sampling alone, the mixture's ratio otherwise. */
    double w = rd_hg_eval(m->g, v3_dot(d, wo)) / pdf;
    ray3 next = {x, wo};
    return v3_add(L, v3_scale(trace(s, next, pdf, depth, fs, rng, c, budget), w));
}

static vec3 trace(const rd_scene *s, ray3 r, double phase_pdf, int depth0,
                  const rd_flight_sampler *fs, pcg32 *rng, rd_track_counters *c, int *budget)
{
    vec3 L = v3(0, 0, 0), beta = v3(1, 1, 1);
    for (int depth = depth0;; depth++) {
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
         * direct part, the sampled continuation for the rest. */
        if (fs->vertex) {
            /* The sampler's vertex policy: roulette or splitting, and the direction mixture.
             * Every copy but the last recurses; the last continues this loop. */
            rd_vertex_in vi = {.x = x, .d = r.d, .medium = m, .depth = depth + 1, .beta = beta};
            rd_vertex_out vo;
            fs->vertex(fs, s, &vi, rng, &vo);
            int n = vo.n;
            if (n <= 0) break;
            if (n - 1 > *budget) n = 1 + *budget;
            *budget -= n - 1;
            beta = v3_scale(beta, vo.rr_scale / n);
            for (int k = 1; k < n; k++)
                L = v3_add(L, v3_mul(beta, continue_from(s, x, r.d, m, &vo.mix, depth + 1, fs,
                                                         rng, c, budget)));
            L = v3_add(L, v3_mul(beta, rd_nee_mix(s, x, r.d, m->g, &vo.mix, rng, c)));
            double pdf;
            vec3 wo = rd_dir_mix_sample(&vo.mix, m->g, r.d, rng, &pdf);
            if (!(pdf > 0.0)) break;
            beta = v3_scale(beta, rd_hg_eval(m->g, v3_dot(r.d, wo)) / pdf);
            phase_pdf = pdf;
            r.o = x;
            r.d = wo;
            continue;
        }
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

vec3 rd_path_radiance(const rd_scene *s, ray3 r, const rd_flight_sampler *fs, pcg32 *rng,
                      rd_track_counters *c)
{
    int budget = RD_SPLIT_BUDGET;
    return trace(s, r, 0.0, 0, fs, rng, c, &budget);
}

vec3 rd_delta_radiance(const rd_scene *s, ray3 r, pcg32 *rng, rd_track_counters *c)
{
    const rd_flight_sampler fs = {.sample = delta_flight, .vertex = NULL, .user = NULL};
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
