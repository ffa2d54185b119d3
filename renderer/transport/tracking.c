/* tracking.c: free-path sampling and transmittance through the scene's media (THEORY.md §2;
 * seeds 000, 002, 003): the media the ray crosses, in order, each handed to the free-path
 * engine (freepath.c) with the tracker and estimator the scene settings choose. */
#include "scene/rd_geom.h"
#include "transport/rd_transport.h"

#include <stdlib.h>
#include <string.h>

typedef rd_interval interval;

#define MAX_IV RD_MAX_INTERVALS

/* Intervals in order of entry distance; among equal t0 (a zero-length interval at another's
 * entry) in the list's order, which is the order of their media in s->media. qsort: a ray along
 * a stack of box media meets them in the reverse of the list's order as often as not, and an
 * insertion sort made that O(n^2) copies (64 media: 2016 a call). */
static int by_entry(const void *a, const void *b)
{
    const interval *x = a, *y = b;
    if (x->t0 != y->t0) return x->t0 < y->t0 ? -1 : 1;
    return x->m < y->m ? -1 : x->m > y->m;
}

/* A bound region: its one medium, clipped to the medium's bounds. The open region: the box
 * media (they do not overlap: the loader checks), and the scene-wide medium in the gaps between
 * them, within its bounds. A box medium with a zero majorant is a clear hole in the scene-wide
 * medium (rd_scene_medium_at: box media fill their bounds): no interval of its own, and no
 * scene-wide medium there either. */
int rd_media_intervals(const rd_scene *s, int region, ray3 r, double tmin, double tmax,
                       rd_interval *out)
{
    int n = 0;
    double t0, t1;
    if (region != s->fill_medium) {
        if (region < 0 || region >= s->n_media) return 0;
        const rd_medium *m = &s->media[region];
        if (m->sigma_maj > 0.0 && rd_box_intersect(m->bmin, m->bmax, r, tmin, tmax, &t0, &t1))
            out[n++] = (interval){t0, t1, m};
        return n;
    }
    for (int i = 0; i < s->n_media && n < 64; i++) {
        const rd_medium *m = &s->media[i];
        if (m->bound) continue;
        if (!rd_box_intersect(m->bmin, m->bmax, r, tmin, tmax, &t0, &t1)) continue;
        out[n++] = (interval){t0, t1, m};
    }
    if (n > 1) qsort(out, (size_t)n, sizeof *out, by_entry);
    const rd_medium *f = s->fill_medium >= 0 ? &s->media[s->fill_medium] : NULL;
    if (f && f->sigma_maj > 0.0 && rd_box_intersect(f->bmin, f->bmax, r, tmin, tmax, &t0, &t1)) {
        /* The scene-wide medium over [t0, t1] minus the box intervals. */
        int nb = n;
        double a = t0;
        for (int k = 0; k <= nb; k++) {
            double b = k < nb ? fmin(out[k].t0, t1) : t1;
            if (b > a) out[n++] = (interval){a, b, f};
            if (k < nb) a = fmax(a, out[k].t1);
        }
        /* merge the gaps (made in order) into place among the boxes; on a tie the box first */
        if (n > nb && nb > 0) {
            interval merged[MAX_IV];
            int i = 0, j = nb, k = 0;
            while (i < nb || j < n)
                merged[k++] = j >= n || (i < nb && out[i].t0 <= out[j].t0) ? out[i++] : out[j++];
            memcpy(out, merged, (size_t)n * sizeof *out);
        }
    }
    /* the clear holes (above) only cut the gaps */
    int kept = 0;
    for (int i = 0; i < n; i++)
        if (out[i].m->sigma_maj > 0.0) out[kept++] = out[i];
    return kept;
}

static rd_fp_params params_of(const rd_scene *s)
{
    rd_fp_params p;
    p.tracker = (rd_fp_kind)s->settings.tracker;
    p.transmittance = (rd_tr_kind)s->settings.transmittance;
    p.b = s->settings.track_b;
    p.m = s->settings.track_m;
    p.step = s->settings.track_step;
    return p;
}

rd_collision rd_sample_free_path(const rd_scene *s, int region, ray3 r, double tmax, pcg32 *rng,
                                 rd_track_counters *c)
{
    interval iv[MAX_IV];
    int n = rd_media_intervals(s, region, r, 0.0, tmax, iv);
    return rd_sample_free_path_iv(s, iv, n, r, tmax, rng, c);
}

rd_collision rd_sample_free_path_iv(const rd_scene *s, const rd_interval *iv, int n, ray3 r,
                                    double tmax, pcg32 *rng, rd_track_counters *c)
{
    rd_collision col = {0, tmax, NULL, 1.0};
    rd_fp_params p = params_of(s);
    for (int i = 0; i < n; i++) {
        /* One medium at a time, with the engine's tracker (freepath.c). */
        rd_fp_medium fm = rd_fp_view(iv[i].m);
        rd_fp_event ev = rd_fp_sample(&p, &fm, r, iv[i].t0, iv[i].t1, rng, c);
        col.weight *= ev.weight;
        if (ev.hit) {
            col.hit = 1;
            col.t = ev.t;
            col.medium = iv[i].m;
            return col;
        }
    }
    return col;
}

double rd_transmittance(const rd_scene *s, int region, ray3 r, double t0, double t1, pcg32 *rng,
                        rd_track_counters *c)
{
    interval iv[MAX_IV];
    if (!(t1 > t0)) return 1.0;
    int n = rd_media_intervals(s, region, r, t0, t1, iv);
    double T = 1.0;
    rd_fp_params p = params_of(s);
    for (int i = 0; i < n && T != 0.0; i++) {
        rd_fp_medium fm = rd_fp_view(iv[i].m);
        T *= rd_fp_transmittance(&p, &fm, r, iv[i].t0, iv[i].t1, rng, c);
    }
    return T;
}

double rd_shadow_transmittance(const rd_scene *s, int region, ray3 r, double dist, int light,
                               const rd_hit *from, pcg32 *rng, rd_track_counters *c)
{
    double T = 1.0, t0 = 0.0;
    rd_hit h, prev;
    /* Each leg runs from the current origin to the next surface; an interface hands the ray
     * to the medium on its other side (rd_geom.h: medium_to) and the estimate goes on. */
    for (int legs = 0; legs < 256 && T != 0.0; legs++) {
        double left = dist - t0;
        if (!rd_scene_intersect(s, r, left, from, &h)) return T * rd_transmittance(s, region, r, 0.0, left, rng, c);
        if (h.light >= 0) /* the light itself ends the ray; another one shadows it */
            return h.light == light ? T * rd_transmittance(s, region, r, 0.0, h.t, rng, c) : 0.0;
        if (s->shapes[h.shape].material.kind != RD_MAT_INTERFACE) return 0.0;
        T *= rd_transmittance(s, region, r, 0.0, h.t, rng, c);
        region = h.medium_to;
        t0 += h.t;
        prev = h;
        from = &prev;
        r = rd_hit_spawn(&prev, r.d);
    }
    return T;
}

/* ---- The majorant along a flight, across its media ------------------------------------------- */

/* Iterator over the majorant segments of every interval of a flight, in order (each medium's
 * structure, or its global majorant when `global`). */
typedef struct {
    const rd_interval *iv;
    int n, i, started, global;
    ray3 r;
    rd_maj_iter it;
} flight_iter;

static int flight_next(flight_iter *k, rd_maj_seg *g)
{
    while (k->i < k->n) {
        if (!k->started) {
            const rd_medium *m = k->iv[k->i].m;
            double smin = fmin(m->density_min * m->sigma_t_scale, m->sigma_maj);
            rd_majorant_iter_begin(&k->it, k->global ? NULL : m->majorant, k->r, k->iv[k->i].t0,
                                   k->iv[k->i].t1, m->sigma_maj, smin);
            k->started = 1;
        }
        while (rd_majorant_next(&k->it, g))
            if (g->t1 > g->t0) return 1;
        k->i++;
        k->started = 0;
    }
    return 0;
}

double rd_majorant_depth(const rd_interval *iv, int n, ray3 r, double t, int global, double *sigma)
{
    flight_iter k = {iv, n, 0, 0, global, r, {0}};
    rd_maj_seg g;
    double tau = 0.0;
    if (sigma) *sigma = 0.0;
    while (flight_next(&k, &g)) {
        if (g.t0 >= t) break;
        if (t <= g.t1) {
            double s = (t - g.t0) / (g.t1 - g.t0);
            tau += rd_seg_tau(&g, 0.0, s);
            if (sigma) *sigma = fmax(0.0, rd_seg_sigma(&g, s));
            break;
        }
        tau += rd_seg_tau(&g, 0.0, 1.0);
    }
    return tau;
}

/* Thin-media probability biasing (Villemin, Wrenninge & Fong, JCGT 7(3) 2018, "probability
 * biasing", in the form derived here for delta tracking over majorant segments).
 *
 * Delta tracking is a Markov chain over tentative collisions: from distance t_k with majorant
 * optical depth tau_k left in the flight, the next tentative collision falls inside the flight
 * with probability P_k = 1 - exp(-tau_k), at majorant depth tau* from t_k with the truncated
 * exponential density exp(-tau*) / P_k on [0, tau_k]; otherwise the flight passes. A tentative
 * collision at t is real with probability sigma_t(t) / sigma_maj(t) (the path scatters), else
 * null (the chain goes on from t).
 *
 * The biased chain changes only the first of these choices: inside with P'_k = max(P_k, q),
 * passing with 1 - P'_k, the conditional density of tau* and the real/null choice unchanged.
 * Every sampled history keeps its probability under the true chain up to the factors changed,
 * so the importance weight of a history is the product of true over biased probability of the
 * choices it made:
 *     inside: P_k / P'_k (<= 1),        pass: (1 - P_k) / (1 - P'_k) = T_maj(t_k, end) / (1 - P'_k),
 * and E'[W F] = E[F] for any quantity F the path computes from the history: unbiased for any
 * q in (0, 1] wherever P'_k < 1 or the pass is worth nothing (q = 1 forces a collision: the
 * caller gives 1 only when a pass-through contributes exactly 0). When P_k >= q (a thick
 * flight) the step is delta tracking's own, weight 1. Every weight is <= 1 but the pass's,
 * which is <= 1 / (1 - q): the thin flight's light gets q / P_k times as many samples as delta
 * tracking gives it, and what lies behind pays at most 1 / (1 - q) in weight. Biasing the
 * rest of the flight again after each null collision keeps the boost when the majorant is
 * loose (a null first collision would otherwise fall back to delta tracking's odds), while the
 * chain's weight is at least THIN_BOOST_W. */
rd_collision rd_sample_free_path_thin(const rd_scene *s, int region, ray3 r, double tmax, double q,
                                      pcg32 *rng, rd_track_counters *c)
{
    interval iv[MAX_IV];
    int n = rd_media_intervals(s, region, r, 0.0, tmax, iv);
    return rd_sample_free_path_thin_iv(s, iv, n, r, tmax, q, rng, c);
}

/* Below this chain weight the thin bias stops boosting (rd_sample_free_path_thin_iv): the rest
 * of the flight then carries at most 1% of the path's weight. A bound on the cost, not a tuned
 * figure. */
#define THIN_BOOST_W 0.01

rd_collision rd_sample_free_path_thin_iv(const rd_scene *s, const rd_interval *iv, int n, ray3 r,
                                         double tmax, double q, pcg32 *rng, rd_track_counters *c)
{
    rd_collision col = {0, tmax, NULL, 1.0};
    if (n == 0) return col;
    int global = s->settings.tracker == RD_FP_WOODCOCK;
    double tau_left = rd_majorant_depth(iv, n, r, INFINITY, global, NULL);
    flight_iter k = {iv, n, 0, 0, global, r, {0}};
    rd_maj_seg g;
    int have = 0;
    double s0 = 0.0;
    for (;;) {
        double P = -expm1(-tau_left);
        if (!(P > 0.0)) return col; /* nothing left to collide with: pass, weight unchanged */
        /* Boost only while the chain's weight is at least THIN_BOOST_W (then delta tracking's
         * own odds): with q = 1 and a loose majorant over empty space the boost would force a
         * tentative collision into ever shorter remainders of the flight until T_maj
         * underflows, a density lookup a step, for weights falling geometrically (beam-vdb, no
         * background: 191 lookups a path against delta tracking's 1.7). Any rule that reads
         * only the chain so far keeps the weights' expectation (each step's weight is its own
         * true / chosen probability). */
        double Pb = col.weight >= THIN_BOOST_W ? fmax(P, q) : P;
        if (pcg32_uniform(rng) >= Pb) { /* pass (never when Pb = 1) */
            col.weight *= exp(-tau_left) / (1.0 - Pb);
            return col;
        }
        col.weight *= P / Pb;
        /* tau* from exp(-tau) / P on [0, tau_left] by inversion: 1 - exp(-tau*) = u P */
        double tau = -log1p(-pcg32_uniform(rng) * P);
        tau_left -= tau;
        /* walk the majorant segments forward to depth tau* */
        for (;;) {
            if (!have) {
                if (!flight_next(&k, &g)) return col; /* round-off at the very end: pass */
                have = 1;
                s0 = 0.0;
            }
            double rest = rd_seg_tau(&g, s0, 1.0);
            if (rest > tau) break;
            tau -= rest;
            have = 0;
        }
        double sn = rd_seg_solve(&g, s0, tau);
        s0 = sn;
        double t = g.t0 + sn * (g.t1 - g.t0), smaj = rd_seg_sigma(&g, sn);
        const rd_medium *m = iv[k.i].m;
        c->collisions++;
        c->lookups++;
        if (pcg32_uniform(rng) * smaj < rd_medium_sigma_t(m, ray_at(r, t))) {
            col.hit = 1;
            col.t = t;
            col.medium = m;
            return col;
        }
    }
}
