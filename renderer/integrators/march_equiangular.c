/* march_equiangular.c: the marchers' equiangular sample (march.equiangular; issue 21 item 3):
 * one distance per camera-ray segment drawn toward a point or spot light, or with `true` a
 * directional beam (uniform on its chord; Kulla & Fajardo 2012; THEORY.md §8; the sampler of
 * transport/equiangular.c), combined by multiple importance sampling with the placement's own
 * samples for the direct light of those lights.
 *
 * Along a segment x(t) = o + t d over [t0, t1], the direct light of point or spot light j
 * scattered toward -d is
 *     I_j = integral T(t0,t) sigma_s(t) L_j(t) dt,   L_j(t) = p(d . w_j) I_j f_j / r_j^2 T(x(t), j),
 * and the marcher estimates it from its N samples t_n of the placement's pdf p (march.c: every
 * sample's next-event estimate sums every light, rd_nee_all or rd_nee_split). Its samples fall
 * at the density N p(t): the n-th stratified sample has density N p on its own stratum (p's
 * mass 1/N), so the sum of any g(t_n) over the N has expectation N integral p g.
 *
 * The equiangular strategy draws one light j with probability Q_j (rd_nee's power pick P_j over
 * the sum of P over the lights this segment samples: rd_march_eq_begin) and one t from j's
 * equiangular pdf e_j over the segment's media cut to j's cone or chord (rd_light_lit_range): the
 * density of its samples for light j is Q_j e_j(t). With the power heuristic (Veach 1997, §9.2,
 * beta = 2) over the two densities, both known exactly here (p is the placement's histogram,
 * not a collision density the way delta's is),
 *     w_e(t,j) = (Q_j e_j(t))^2 / ((Q_j e_j(t))^2 + (N p(t))^2),   w_p = 1 - w_e,
 * the placement's sample n counts light j with w_p(t_n, j) and the equiangular sample returns
 *     sigma_s(t) T^(t0,t) L^_j(t) w_e(t,j) / (Q_j e_j(t)),
 * T^ and L^ the unbiased transmittance and next-event estimates (rd_transmittance,
 * rd_nee_light). w_p + w_e = 1 at every t and j and each is > 0 only where its strategy can
 * sample (p > 0 on all of [t0, t1]: the defensive mixture), so the sum stays unbiased for I_j;
 * lights the strategy does not sample keep w_p = 1. N is fixed per ray by the guide before any
 * sample is drawn (eq. 17), so the weights are deterministic functions of (ray, t, j).
 *
 * Which lights: every point and spot light and directional beam (true), or "auto": the point
 * and spot lights whose lit span delta tracking reaches but rarely collides in
 * (rd_eq_flight_init's rule, `delta`'s, which looks at the majorants and the cone only, not at
 * the placement's pdf). At most RD_MARCH_EQ_LIGHTS lights per segment, the first by index; the rest keep w_p = 1 (a deterministic choice:
 * variance, never bias). */
#include "integrators/rd_march.h"

int rd_march_eq_begin(const rd_scene *s, ray3 r, int region, double t_end, const rd_guide_pdf *pdf,
                      int N, rd_march_eq *eq, rd_track_counters *c)
{
    eq->n = 0;
    if (s->march.equiangular == RD_EQ_OFF || s->march.ls == RD_LS_PHOTONS) return 0;
    rd_eq_flight ef;
    int ok = rd_eq_flight_init(s, r, region, t_end, 0.0, s->march.equiangular, &ef);
    c->eq_flights += ef.n > 0; /* as the path loop counts its flights' set-ups */
    if (!ok) return 0;
    double a_all = ef.iv[0].t0, b_all = ef.iv[ef.n - 1].t1, sum = 0.0;
    for (int i = 0; i < s->n_lights && eq->n < RD_MARCH_EQ_LIGHTS; i++) {
        const rd_light *l = &s->lights[i];
        double P = s->light_sampler.pmf[i], a = a_all, b = b_all;
        if (!(P > 0.0) || !rd_eq_flight_samples(s, &ef, i)) continue;
        if (!rd_light_lit_range(l, r, &a, &b)) continue;
        if (!rd_equiangular_init_light(&eq->e[eq->n], l, r, a, b)) continue;
        eq->light[eq->n] = i;
        eq->Q[eq->n] = P;
        sum += P;
        eq->n++;
    }
    if (!(sum > 0.0)) return eq->n = 0;
    for (int k = 0; k < eq->n; k++) eq->Q[k] /= sum;
    eq->r = r;
    eq->region = region;
    eq->pdf = pdf;
    eq->N = N;
    return eq->n;
}

/* The equiangular strategy's weight w_e at t for the k-th light of the segment. */
static double weight_e(const rd_march_eq *eq, int k, double t)
{
    double pe = eq->Q[k] * rd_equiangular_pdf(&eq->e[k], t);
    if (!(pe > 0.0)) return 0.0;
    return rd_power_heuristic(pe, eq->N * rd_guide_pdf_eval(eq->pdf, t));
}

void rd_march_eq_weights(const rd_march_eq *eq, double t, double *light_w)
{
    for (int k = 0; k < eq->n; k++) light_w[eq->light[k]] = 1.0 - weight_e(eq, k, t);
}

vec3 rd_march_eq_sample(const rd_scene *s, const rd_march_eq *eq, double t0, pcg32 *rng,
                        rd_track_counters *c)
{
    double u = pcg32_uniform(rng), acc = 0.0, ut = pcg32_uniform(rng);
    int k = eq->n - 1;
    for (int i = 0; i < eq->n; i++) {
        acc += eq->Q[i];
        if (u < acc) {
            k = i;
            break;
        }
    }
    double pdf;
    double t = rd_equiangular_sample(&eq->e[k], ut, &pdf);
    if (!(pdf > 0.0)) return v3(0, 0, 0);
    /* the medium at t (the lit span may hold gaps between media: nothing scatters there) */
    vec3 x = ray_at(eq->r, t);
    const rd_medium *m = rd_scene_medium_at(s, eq->region, x);
    if (!m) return v3(0, 0, 0);
    return rd_eq_estimate(s, eq->region, eq->r, t0, t, m, eq->light[k], weight_e(eq, k, t), eq->Q[k] * pdf,
                          rng, c);
}
