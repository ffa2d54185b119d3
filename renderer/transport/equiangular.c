/* equiangular.c: `delta`'s equiangular strategy for single scattering from point and spot
 * lights and directional beams (Kulla & Fajardo 2012, "Importance Sampling Techniques for Path
 * Tracing in Participating Media"; THEORY.md §8), combined with the next-event estimation at delta
 * tracking's collisions by multiple importance sampling, as Cycles and Arnold combine it with
 * their distance sampling. settings.equiangular; docs/free-path.md has the same derivation.
 *
 * Directional beams (a directional light with a radius, session 29): the lit part of a flight
 * is the chord inside the beam's cylinder (rd_light_lit_range), and a light at infinity has no
 * 1 / r^2 along it, so e_j below is the uniform density 1 / (b - a) on the chord (the
 * equiangular family's limit as D grows). Everything else is the same. They are in the set of
 * `true` and "camera" (rd_eq_mode_beams), and so of the tiles that take `true` (the guided
 * methods' third estimator and `delta`'s "tiles", since session 30); "auto" leaves them to
 * delta tracking. A first build with beams in "auto" and in the third estimator together lost
 * 10% for guided-unbiased on the calibration scene beam-vdb and 4% on smoke-vdb; the third
 * estimator with beams alone tied there and won 1.6x on hard-window-beam (docs/free-path.md
 * "Directional beams"); "auto" with beams alone was not measured.
 *
 * The integrand. Along a flight x(t) = o + t d, t in [0, t_end] (one region, no surface in
 * between), the light of point or spot light j scattered once toward -d is
 *     I_j = integral T(0,t) sigma_s(t) L_j(t) dt,   L_j(t) = p(d . w_j) I_j f_j / r_j^2 T(x(t), j),
 * and the path loop's estimate of the flight's direct light is the sum over the lights.
 *
 * Strategy d (delta tracking, what `delta` always did): the collision t has density
 * sigma_t(t) T(0,t) (any tracker of rd_sample_free_path; weighted ones and thin bias carry a
 * weight W with E[W g(t)] = integral sigma_t T g for every g); next-event estimation there
 * chooses light j with probability P_j (rd_nee, by power) and returns L_j / P_j; the flight
 * weight holds the albedo sigma_s / sigma_t. So E[albedo W L_j / P_j w_d(t,j) 1{j chosen}] =
 * integral T sigma_s L_j w_d(t,j) dt.
 *
 * Strategy e (equiangular, added): choose one light j of the set (point and spot lights, and
 * beams: above) with probability Q_j = P_j / sum over the set of P_k, draw t from the
 * equiangular pdf e_j(t) over the media of the flight (the span from the first medium's entry
 * to the last one's exit, cut to the spot's cone or the beam's cylinder: rd_light_lit_range),
 * and return
 *     sigma_s(t) T^(0,t) L^_j(t) w_e(t,j) / (Q_j e_j(t)),
 * T^ an unbiased transmittance estimate (rd_transmittance: ratio or residual ratio tracking,
 * or the closed form) and L^_j next-event estimation toward j (unbiased shadow transmittance),
 * independent of each other given t. Its expectation is integral T sigma_s L_j w_e(t,j) dt.
 *
 * The sum of both is unbiased for every I_j whenever w_d(t,j) + w_e(t,j) = 1 at every t and j:
 * the weights need not be the balance or power heuristic of the true densities, only
 * deterministic functions of (flight, t, j) that sum to one (Veach 1997, §9.2.2). Delta
 * tracking's true density sigma_t(t) T(0,t) is not known in a heterogeneous medium, and putting
 * an estimate T^ into a weight would make the weight random and correlated with the estimate
 * it weights: biased (a ratio of unbiased estimates is not unbiased). So the weights use a
 * stand-in that is known exactly: the majorant's density
 *     m(t) = s_d sigma_maj(t) T_maj(0,t),
 * the density of delta tracking's first tentative collision, which is its collision density
 * where the majorant is tight (and exactly sigma_t T in a homogeneous medium). s_d = P'/P, the
 * thin-bias boost of the first tentative collision (rd_sample_free_path_thin), else 1. Then
 *     w_e(t,j) = (Q_j e_j(t))^2 / ((Q_j e_j(t))^2 + (P_j m(t))^2),   w_d = 1 - w_e
 * (the power heuristic, beta = 2). Both are > 0 only where their strategy can sample: e_j > 0
 * only on the cut span, and where e_j = 0, w_d = 1; m > 0 wherever sigma_t can be > 0. A
 * stand-in that is wrong costs variance, never bias. Lights that equiangular sampling never
 * chooses keep w_d = 1. A flight sampler that knows its own scattering density exactly (a
 * guided flight of guided-unbiased: q(t), eq. 3 of integrators/guided_unbiased.c) puts that
 * in m's place: rd_eq_flight.density for the equiangular sample, rd_flight.pdf for the weight
 * at its vertex (both the same function of (flight, t, j), so w_d + w_e = 1 still).
 *
 * "auto": which lights a flight samples. The weights above may be any deterministic functions
 * of the flight, so the set of lights strategy e samples may be too: a light outside the set
 * has Q_j = 0 and w_d = 1 on this flight, the set's Q_j are P_j over the set's sum. "auto" puts
 * light j in the set when delta tracking reaches j's lit span [a, b] (cut as above) but mostly
 * passes through it:
 *     T(0,a) >= 1/2   and   s_d (1 - T(a,b)) < EQ_AUTO_REACH = 1/3,
 * with each medium's global majorant for sigma_t in T (a constant per interval: the choice
 * costs no walk of the majorant grid) and s_d the thin bias's boost (T(0,a) is left unboosted:
 * a choice, like the rest, that changes variance only). Why: strategy d finds j's light only
 * from collisions in [a, b]; one that reaches a collides there with probability R = 1 - T(a,b),
 * so its estimate of what j gives the span is about I / R with probability R: a variance of
 * I^2 (1/R - 1). Strategy e's estimate has a variance of order I^2 (the transmittance and
 * sigma_s noise about a sample that always lies where j lights) and costs about as much as
 * delta's flight again (one transmittance estimate along the ray, one shadow ray), so it pays
 * when 1/R - 1 > 2: R < 1/3. The estimate is rough on purpose: delta's next-event estimate
 * also picks j with probability P_j only (a variance nearer I^2 (1/(R P_j) - 1) with several
 * lights), and a point light near the ray peaks inside its span (equiangular sampling's own
 * gain, which the rule does not count: it leaves a near point light in a thick span to delta
 * tracking, where `true` wins). A span hidden behind the medium (T(0,a) < 1/2) carries little
 * of the flight's light and its transmittance estimate costs most there: left to delta
 * tracking. Dense smoke lit by a spot (thick lit spans) keeps delta tracking, which finds the
 * light there; a thin fog crossed by a narrow cone gets strategy e. The global majorant
 * overstates sigma_t, so a light stays with delta tracking a little more often than it
 * should: variance, never bias. Lights with an index of 64 or more are always in the set (the
 * set is a 64-bit mask). */
#include "transport/rd_transport.h"

/* ---- The sampler ------------------------------------------------------------------------ */

int rd_equiangular_init(rd_equiangular *eq, vec3 c, ray3 r, double a, double b)
{
    if (!(b > a) || !isfinite(a) || !isfinite(b)) return 0;
    vec3 oc = v3_sub(c, r.o);
    double delta = v3_dot(oc, r.d);
    double D = v3_len(v3_madd(oc, r.d, -delta));
    /* A floor for a light on the line (or nearly): relative to the span and the distances */
    double floor = 1e-12 * (fabs(a) + fabs(b) + fabs(delta)) + 1e-300;
    if (!(D > floor)) D = floor;
    eq->a = a;
    eq->b = b;
    eq->delta = delta;
    eq->D = D;
    eq->th_a = atan((a - delta) / D);
    eq->th_b = atan((b - delta) / D);
    return eq->th_b > eq->th_a;
}

int rd_equiangular_init_light(rd_equiangular *eq, const rd_light *l, ray3 r, double a, double b)
{
    if (l->kind != RD_LIGHT_DIRECTIONAL) return rd_equiangular_init(eq, l->pos, r, a, b);
    if (!(b > a) || !isfinite(a) || !isfinite(b)) return 0;
    *eq = (rd_equiangular){.a = a, .b = b, .delta = 0.0, .D = INFINITY, .th_a = 0.0, .th_b = 1.0};
    return 1;
}

double rd_equiangular_pdf(const rd_equiangular *eq, double t)
{
    if (!(t >= eq->a && t <= eq->b)) return 0.0;
    if (eq->D == INFINITY) return 1.0 / (eq->b - eq->a);
    double x = t - eq->delta;
    return eq->D / ((eq->th_b - eq->th_a) * (eq->D * eq->D + x * x));
}

double rd_equiangular_sample(const rd_equiangular *eq, double u, double *pdf)
{
    double th = eq->th_a + u * (eq->th_b - eq->th_a);
    double t = eq->D == INFINITY ? eq->a + u * (eq->b - eq->a) : eq->delta + eq->D * tan(th);
    t = fmin(eq->b, fmax(eq->a, t)); /* round-off only */
    *pdf = rd_equiangular_pdf(eq, t);
    return t;
}

/* ---- The strategy along a flight --------------------------------------------------------- */

static int point_or_spot(const rd_light *l)
{
    return l->kind == RD_LIGHT_POINT || l->kind == RD_LIGHT_SPOT;
}

int rd_eq_light(const rd_light *l)
{
    return point_or_spot(l) || (l->kind == RD_LIGHT_DIRECTIONAL && l->radius > 0.0);
}

/* A light of the strategy's set on flights that take beams (ef->beams) or not. */
static int in_set(const rd_light *l, int beams)
{
    return beams ? rd_eq_light(l) : point_or_spot(l);
}

/* "auto" samples a light when delta tracking that reaches its lit span collides there with a
 * probability below this (the head: strategy e pays when 1/R - 1 > 2). */
#define EQ_AUTO_REACH (1.0 / 3.0)

/* Does strategy e sample light i on this flight? */
int rd_eq_flight_samples(const rd_scene *s, const rd_eq_flight *ef, int i)
{
    return in_set(&s->lights[i], ef->beams) && !(i < 64 && (ef->left >> i & 1u));
}

/* The span [*a, *b] of the flight's media that light l lights; 0 when empty. */
static int lit_span(const rd_eq_flight *ef, const rd_light *l, double *a, double *b)
{
    *a = ef->iv[0].t0, *b = ef->iv[ef->n - 1].t1;
    return rd_light_lit_range(l, ef->r, a, b);
}

/* Is light j's lit span [a, b] reached but thin (the head's "auto" rule)? T from the global
 * majorants; thin bias's boost s_d raises the collision probability as it does the proxy's. */
static int thin_and_reached(const rd_eq_flight *ef, double a, double b)
{
    double tau_a = 0.0, tau_b = 0.0;
    for (int k = 0; k < ef->n; k++) {
        const rd_interval *v = &ef->iv[k];
        tau_a += v->m->sigma_maj * fmax(0.0, fmin(a, v->t1) - v->t0);
        tau_b += v->m->sigma_maj * fmax(0.0, fmin(b, v->t1) - v->t0);
    }
    double Ta = exp(-tau_a), pass = exp(-(tau_b - tau_a));
    return Ta >= 0.5 && ef->dscale * (1.0 - pass) < EQ_AUTO_REACH;
}

/* Cheap necessary conditions of thin_and_reached for a spot, tried before the cone cut (which
 * cost most of "auto"'s choice: session 23). With t_half and t_third the distances at which the
 * flight's global-majorant depth reaches ln 2 and ln 3 (INFINITY if it never does):
 *  - T(0,a) >= 1/2 needs a <= t_half, and every point x(t), t <= t_half, lies within t_half of
 *    the flight's origin; so a spot whose cone is farther than t_half from the origin is out.
 *    The distance of a point p from the cone (half-angle theta about axis w) is at least
 *    r cos(theta) - h sin(theta), h = w.(p - apex) and r = |w x (p - apex)| (the distance to
 *    the nearest generator's whole line, a lower bound where the foot lies behind the apex);
 *  - T(0,a) >= 1/2 and R < 1/3 need T(0,b) = T(0,a) T(a,b) > 1/3 (R >= 1 - T(a,b), the thin
 *    bias's scale being >= 1), so b < t_third; a spot whose cone holds x(t_third), inside the
 *    media's span, has b >= t_third and is out (a flight deep in a lit dense medium).
 * Each rejects only what the rule rejects (in exact arithmetic; a depth of exactly ln 2 at an
 * interval's end is the measure-zero exception): the choice, and so the image, is the same
 * (checked bit for bit on four scenes: docs/free-path.md). Assumes r.d unit and the cone's
 * half-angle at most 90 degrees (spot angles are at most 180: load/camera_lights.c), where
 * c = max(0, cos_outer) = cos(theta). */
static int spot_out_of_reach(const rd_light *l, ray3 r, double t_half, double t_third, double t_end)
{
    double c = fmax(0.0, l->cos_outer), sn = sqrt(fmax(0.0, 1.0 - c * c));
    vec3 v = v3_sub(r.o, l->pos);
    double h = v3_dot(l->dir, v), rad = v3_len(v3_cross(l->dir, v));
    if (rad * c - h * sn > t_half) return 1;
    if (t_third < t_end) {
        vec3 x = v3_sub(ray_at(r, t_third), l->pos);
        if (v3_dot(l->dir, x) > c * v3_len(x)) return 1; /* rd_light_lit_range's test */
    }
    return 0;
}

/* The distances t_half and t_third of spot_out_of_reach over the flight's intervals. */
static void reach_marks(const rd_eq_flight *ef, double *t_half, double *t_third)
{
    const double lh = log(2.0), lt = log(3.0);
    double tau = 0.0;
    *t_half = *t_third = INFINITY;
    for (int k = 0; k < ef->n; k++) {
        const rd_interval *v = &ef->iv[k];
        double sig = v->m->sigma_maj, next = tau + sig * (v->t1 - v->t0);
        if (sig > 0.0 && *t_half == INFINITY && next >= lh) *t_half = v->t0 + (lh - tau) / sig;
        if (sig > 0.0 && next >= lt) {
            *t_third = v->t0 + (lt - tau) / sig;
            return;
        }
        tau = next;
    }
}

/* The sum of next-event estimation's choice probabilities over the set's lights: point and
 * spot lights, and directional beams where `beams`. */
static double set_pmf(const rd_scene *s, int beams)
{
    double sum = 0.0;
    for (int i = 0; i < s->n_lights; i++)
        if (in_set(&s->lights[i], beams)) sum += s->light_sampler.pmf[i];
    return sum;
}

int rd_eq_has_lights(const rd_scene *s, int beams) { return set_pmf(s, beams) > 0.0; }

int rd_eq_tiles_have_lights(const rd_scene *s) { return rd_eq_has_lights(s, s->beam_connect.light < 0); }

int rd_eq_mode_beams(int mode) { return mode == RD_EQ_ALL || mode == RD_EQ_CAMERA; }

int rd_eq_flight_init(const rd_scene *s, ray3 r, int region, double t_light, double q, int mode,
                      rd_eq_flight *ef)
{
    ef->n = 0;
    if (rd_eq_has_lights(s, rd_eq_mode_beams(mode))) ef->n = rd_media_intervals(s, region, r, 0.0, t_light, ef->iv);
    return rd_eq_flight_choose(s, r, region, q, mode, ef);
}

int rd_eq_flight_choose(const rd_scene *s, ray3 r, int region, double q, int mode, rd_eq_flight *ef)
{
    int automatic = mode == RD_EQ_AUTO;
    ef->left = 0;
    ef->beams = rd_eq_mode_beams(mode);
    ef->ps_pmf = set_pmf(s, ef->beams);
    ef->density = NULL;
    ef->density_user = NULL;
    if (!(ef->ps_pmf > 0.0)) {
        ef->n = 0;
        return 0;
    }
    if (ef->n == 0) return 0;
    ef->r = r;
    ef->region = region;
    ef->dscale = 1.0;
    if (q > 0.0) {
        double P = -expm1(-rd_majorant_depth(ef->iv, ef->n, r, INFINITY, 0, NULL));
        if (P > 0.0) ef->dscale = fmax(P, q) / P;
    }
    if (automatic) {
        /* leave to delta tracking the lights it reaches often, and those lighting nothing here */
        ef->ps_pmf = 0.0;
        double t_half, t_third;
        reach_marks(ef, &t_half, &t_third);
        for (int i = 0; i < s->n_lights; i++) {
            const rd_light *l = &s->lights[i];
            if (!point_or_spot(l) || !(s->light_sampler.pmf[i] > 0.0)) continue;
            double a, b;
            if (i < 64 && ((l->kind == RD_LIGHT_SPOT && spot_out_of_reach(l, r, t_half, t_third, ef->iv[ef->n - 1].t1)) ||
                           !lit_span(ef, l, &a, &b) || !thin_and_reached(ef, a, b)))
                ef->left |= (uint64_t)1 << i;
            else
                ef->ps_pmf += s->light_sampler.pmf[i];
        }
        if (!(ef->ps_pmf > 0.0)) return 0;
    }
    return 1;
}

/* Light j's equiangular pdf over the flight's span cut to what it lights; 0 when empty. */
static int light_span(const rd_eq_flight *ef, const rd_light *l, rd_equiangular *eq)
{
    double a, b;
    if (!lit_span(ef, l, &a, &b)) return 0;
    return rd_equiangular_init_light(eq, l, ef->r, a, b);
}

/* The stand-in for delta tracking's collision density at t (header comment). */
static double tracking_proxy(const rd_eq_flight *ef, double t)
{
    double sigma;
    double tau = rd_majorant_depth(ef->iv, ef->n, ef->r, t, 0, &sigma);
    return ef->dscale * sigma * exp(-tau);
}

vec3 rd_eq_nee(const rd_scene *s, const rd_eq_flight *ef, pcg32 *rng, rd_track_counters *c)
{
    /* Light j with probability Q_j = P_j / sum over the set's lights of P_k */
    double u = pcg32_uniform(rng) * ef->ps_pmf, acc = 0.0;
    int j = -1;
    for (int i = 0; i < s->n_lights; i++) {
        if (!rd_eq_flight_samples(s, ef, i) || !(s->light_sampler.pmf[i] > 0.0)) continue;
        j = i;
        acc += s->light_sampler.pmf[i];
        if (u < acc) break;
    }
    double ut = pcg32_uniform(rng);
    rd_equiangular eq;
    if (j < 0 || !light_span(ef, &s->lights[j], &eq)) return v3(0, 0, 0);
    double Pj = s->light_sampler.pmf[j], Qj = Pj / ef->ps_pmf, pdf;
    double t = rd_equiangular_sample(&eq, ut, &pdf);
    if (!(pdf > 0.0)) return v3(0, 0, 0);
    /* the medium at t (the span may hold gaps between media: nothing scatters there) */
    const rd_medium *m = NULL;
    for (int k = 0; k < ef->n && !m; k++)
        if (t >= ef->iv[k].t0 && t <= ef->iv[k].t1) m = ef->iv[k].m;
    if (!m) return v3(0, 0, 0);
    /* The competing density: the flight's own when it knows it (guided-unbiased's q(t), asked
     * now, while the flight it describes is the last one sampled), else the stand-in. */
    double pc = ef->density ? ef->density(ef->density_user, t) : -1.0;
    if (!(pc >= 0.0)) pc = tracking_proxy(ef, t);
    double pe = Qj * pdf;
    return rd_eq_estimate(s, ef->region, ef->r, 0.0, t, m, j, rd_power_heuristic(pe, Pj * pc), pe, rng, c);
}

vec3 rd_eq_estimate(const rd_scene *s, int region, ray3 r, double t_from, double t, const rd_medium *m,
                    int light, double w, double pe, pcg32 *rng, rd_track_counters *c)
{
    vec3 x = ray_at(r, t);
    c->lookups++;
    c->eq_samples++; /* the report's equiangular_samples */
    double sigma_t = rd_medium_sigma_t(m, x);
    if (!(sigma_t > 0.0) || !(w > 0.0)) return v3(0, 0, 0);
    vec3 Lj = rd_nee_light(s, region, x, r.d, m->g, light, rng, c);
    if (!(v3_maxc(Lj) > 0.0)) return v3(0, 0, 0);
    double T = rd_transmittance(s, region, r, t_from, t, rng, c);
    if (T == 0.0) return v3(0, 0, 0);
    return v3_scale(v3_mul(m->albedo, Lj), sigma_t * T * w / pe);
}

double rd_eq_weight(const rd_scene *s, const rd_eq_flight *ef, double t, int light, double density)
{
    if (light < 0 || !rd_eq_flight_samples(s, ef, light)) return 1.0;
    rd_equiangular eq;
    if (!light_span(ef, &s->lights[light], &eq)) return 1.0;
    double pdf = rd_equiangular_pdf(&eq, t);
    if (!(pdf > 0.0)) return 1.0;
    double Pj = s->light_sampler.pmf[light], Qj = Pj / ef->ps_pmf;
    double pc = density > 0.0 ? density : tracking_proxy(ef, t);
    return rd_power_heuristic(Pj * pc, Qj * pdf);
}
