/* march.c: the ray marcher, with importance-sampled sample positions: the method of seed 001
 * (§3.3-4; THEORY.md §6) and its two baselines share it, each a placement of the samples along
 * a camera ray (the method files guided.c, uniform.c and transmittance.c pick theirs):
 *
 *   guided         p(t) = the histogram PDF of the ray through the SH guide grid (eq. 16),
 *                  mixed with a uniform defensive component (weight guide.alpha), N_ray samples
 *                  by eq. 17 from a pilot pass;
 *   uniform        a fixed step with one random offset per ray (eq. 5): N evenly spaced samples;
 *   transmittance  p(t) proportional to sigma_t T(0,t) (eq. 11), from a piecewise-constant
 *                  extinction of 4N midpoint lookups, mixed with the same defensive component.
 *
 * All three draw stratified samples t_n = P^-1((n + u)/N) from one rd_guide_pdf (the uniform
 * placement is that PDF with alpha = 1), so they differ only in where the samples go. At each
 * sample the estimator (THEORY.md §6) is
 *
 *   L ~= T(0,t_end) L_behind + (1/N) sum_n T(0,t_n) S(x_n, -d) / p(t_n),
 *
 * with T from the free-path engine's unbiased estimator, swept once along the sorted samples
 * (T(0,t_n) = T(0,t_{n-1}) T(t_{n-1},t_n), independent pieces), plus, with march.equiangular,
 * one equiangular sample toward a point or spot light whose light the samples' next-event
 * estimates share with it by MIS (march_equiangular.c), and S = sigma_s L_s from the source
 * chosen by march.ls:
 *   nee+paths    (the default) delta's own vertex at x: sigma_s x (next-event estimation,
 *                rd_nee_split, + one phase-sampled path from x tracked by delta), so S is
 *                unbiased and every placement converges to delta's image;
 *   photons      the photon-map radiance estimate alone (the seed's original),
 *   nee+photons  sigma_s x next-event estimation of every light (direct light; rd_nee_all,
 *                no MIS with a path: none follows) + the photon map of photons
 *                stored without their first flight (multiple scattering),
 *   nee+guide    the same direct light + multiple scattering read from the guide baked from
 *                the indirect photons (a cell lookup instead of a k-NN query),
 *   nee+delta    sigma_s x next-event estimation (rd_nee_split) at the samples, and once per
 *                segment one path of delta's along the ray that leaves its first vertex's
 *                direct light to them (rd_delta_scattered): unbiased, and a path costs only
 *                where delta's would scatter;
 *   nee+beams    the same direct light at the samples + multiple scattering from the beam
 *                radiance estimate: the indirect photons' balls the segment crosses (a sample of
 *                them, unbiased), integrated with T along the whole segment
 *                (march_beams.c, rd_march_beam_estimate; no placement noise),
 *   nee          sigma_s x next-event estimation only (single scattering; for tests).
 * Given S, the estimate is unbiased for every placement (the defensive mixture keeps p > 0
 * wherever the integrand can be non-zero, and every ray gets at least one sample); what the
 * placements change is the variance. The photon estimates' own bias is shared; nee+paths has
 * none. */
#include "integrators/rd_march.h"
#include "scene/rd_geom.h"
#include "transport/rd_path.h"
#include "photonmap.h"
#include "sh.h"

#include <stdlib.h>
#include <string.h>

/* Samples per ray when the scene does not set march.samples: each placement's best on the
 * calibration scenes cloud.json and smoke-vdb.json (bench/bench_samples.sh, 4 spp, efficiency
 * 1/(variance x render time); docs/guided-marching.md), not on the benchmark scenes. A placement
 * that puts its samples where the light is needs fewer of them: most of a pixel's variance is
 * the film's and the shadow rays' (docs/guided-marching.md), which only more camera rays reduce. */
static int march_default_samples(placement p)
{
    static const int n[PLACE_COUNT] = {[PLACE_GUIDED] = 2, [PLACE_TRANSMITTANCE] = 4, [PLACE_UNIFORM] = 8};
    return n[p];
}

/* The chance that a sample continues its path (march.paths, nee+paths) when the scene does not
 * set it. Each of guided's N samples per ray ran a full path of delta's from it: N paths per
 * camera ray where delta runs one, for multiple scattering that is a small part of what guided
 * places its samples for. 0.5, one path per ray on average at guided's N_mean of 2, is guided's
 * best of 1, 0.5 and 0.25 (and of min(1, 1 / N) per ray) at equal time on the calibration
 * scenes, not on the benchmark's (bench/bench_calibrate.sh; docs/benchmarks.md "Session 15").
 * A probability learned per tile from the paths' second moment and cost (98e8645) tied with it
 * there and lost the lens caustic on the benchmark's check, and was reverted. The other
 * placements keep 1: not calibrated. */
static double march_default_paths(placement p)
{
    static const double q[PLACE_COUNT] = {[PLACE_GUIDED] = 0.5, [PLACE_TRANSMITTANCE] = 1.0, [PLACE_UNIFORM] = 1.0};
    return q[p];
}

size_t rd_march_scratch_layout(const march_state *st, march_scratch *ms, void *base)
{
    size_t off = 0;
    char *b = base;
#define TAKE(field, type, n)                                                                   \
    do {                                                                                       \
        if (b) ms->field = (type *)(b + off);                                                   \
        off += ((size_t)(n) * sizeof(type) + 15) / 16 * 16;                                     \
    } while (0)
    TAKE(seg, rd_gpdf_seg, st->seg_cap);
    TAKE(t, double, st->n_max);
    TAKE(p, double, st->n_max);
    TAKE(tb, double, st->piece_cap + 1);
    TAKE(f, double, st->piece_cap);
    TAKE(sig, double, st->piece_cap);
    TAKE(hits, rd_beam_hit, st->beam_cap);
    TAKE(cdf, double, st->beam_cap);
    TAKE(lw, double, st->n_lights);
#undef TAKE
    return off;
}

/* ---- Where the ray is, and what lies behind the media ------------------------------------- */


/* The part of the ray inside the scene bounds before t_end (the nearest light or surface):
 * [t0, t1]. */
static int medium_span(const rd_scene *s, ray3 r, double t_end, double *t0, double *t1)
{
    if (s->n_media == 0) return 0;
    return rd_box_intersect(s->bmin, s->bmax, r, 0.0, t_end, t0, t1) && *t1 > *t0;
}

/* The camera ray's first straight segment: its region and the part [t0, t1] inside the scene
 * bounds before the first light or surface; *hit_light gets that light, or -1. */
int rd_march_first_segment(const rd_scene *s, ray3 r, int *region, double *t0, double *t1,
                         int *hit_light)
{
    rd_hit h;
    int got = rd_scene_intersect(s, r, INFINITY, NULL, &h);
    *region = rd_scene_camera_region(s, r);
    *hit_light = got ? h.light : -1;
    return medium_span(s, r, got ? h.t : INFINITY, t0, t1);
}

/* ---- The three placements ------------------------------------------------------------------ */

/* Guided placement with detail (march.detail = "lookups"): the guide says how bright the
 * in-scattered light of each cell is, lookups say where inside the cell the medium is. Each
 * guide segment j is cut at the K-step lattice of the ray; piece i gets the extinction of a
 * lookup at its midpoint and the height f_j sigma_t(mid_i) / sigma_j, so h(t) follows
 * sigma_t(t) T~(0,t) L~_s(cell) instead of the cell mean (eq. 16 with sigma_s at the
 * lookup's resolution). Writes the pieces into ms->tb/f/sig and rebuilds pdf from them (the
 * guide segments are read before the rebuild overwrites their storage). */
static void refine_by_lookups(const rd_render_ctx *ctx, const march_scratch *ms, int region,
                              ray3 r, rd_guide_pdf *pdf, rd_track_counters *c)
{
    const rd_scene *s = ctx->scene;
    const march_state *st = ctx->state;
    double t0 = pdf->tmin, t1 = pdf->tmax, h = (t1 - t0) / (4 * st->n_mean[PLACE_GUIDED]);
    int n = 0;
    for (int j = 0; j < pdf->n && n < st->piece_cap; j++) {
        const rd_gpdf_seg sg = pdf->seg[j];
        double a = sg.t0;
        while (a < sg.t1 && n < st->piece_cap) {
            double lattice = t0 + (floor((a - t0) / h) + 1.0) * h; /* next lattice point > a */
            if (lattice <= a) lattice += h;                             /* rounding */
            double b = lattice < sg.t1 ? lattice : sg.t1;
            vec3 x = ray_at(r, 0.5 * (a + b));
            const rd_medium *m = sg.f > 0.0 ? rd_scene_medium_at(s, region, x) : NULL;
            double sig = m ? rd_medium_sigma_t(m, x) : 0.0;
            c->lookups += m != NULL;
            ms->tb[n] = a;
            ms->sig[n] = sg.f > 0.0 ? sig : sg.sigma; /* dark cells: T~ from the cell mean */
            ms->f[n] = sg.sigma > 0.0 ? sg.f * sig / sg.sigma : (sig > 0.0 ? sg.f : 0.0);
            n++;
            a = b;
        }
    }
    ms->tb[n] = n > 0 ? pdf->seg[pdf->n - 1].t1 : t1;
    double alpha = pdf->alpha;
    if (n == 0 || ms->tb[n] <= ms->tb[0] ||
        rd_guide_pdf_build(pdf, n, ms->tb, ms->f, ms->sig, t0, t1, alpha, NULL, 0) != RD_OK)
        rd_guide_pdf_build(pdf, 0, NULL, NULL, NULL, t0, t1, 1.0, NULL, 0); /* defensive only */
}

/* The guide's PDF of ray r over [t0, t1] (cells, or cells x lookups; defensive only when the
 * guide walk fails). */
void rd_march_build_guided(const rd_render_ctx *ctx, const march_scratch *ms, int region, ray3 r,
                         double t0, double t1, rd_guide_pdf *pdf, rd_track_counters *c)
{
    const rd_march_settings *m = &ctx->scene->march;
    double o[3] = {r.o.x, r.o.y, r.o.z}, d[3] = {r.d.x, r.d.y, r.d.z};
    if (rd_guide_pdf_build_guide(pdf, ctx->guide, o, d, t0, t1, m->alpha, NULL, 0) != RD_OK) {
        rd_guide_pdf_build(pdf, 0, NULL, NULL, NULL, t0, t1, 1.0, NULL, 0);
        return;
    }
    if (m->detail && pdf->I > 0.0) {
        pdf->alpha = m->alpha; /* the mixture weight asked for, not the I == 0 fallback */
        refine_by_lookups(ctx, ms, region, r, pdf, c);
    }
}

/* Build the PDF of `place` over [t0, t1] for ray r into pdf. Returns the samples to take. */
int rd_march_build_pdf(const rd_render_ctx *ctx, placement place, const march_scratch *ms,
                     int region, ray3 r, double t0, double t1, rd_guide_pdf *pdf,
                     rd_track_counters *c)
{
    const rd_scene *s = ctx->scene;
    const rd_march_settings *ms_set = &s->march;
    const march_state *st = ctx->state;
    rd_guide_pdf_init(pdf, ms->seg, st->seg_cap);
    int N = st->n_mean[place];
    if (place == PLACE_GUIDED) {
        rd_march_build_guided(ctx, ms, region, r, t0, t1, pdf, c);
        N = rd_guide_samples_per_ray(pdf->I, st->mean_I, N, ms_set->min_samples, ms_set->max_samples);
    } else if (place == PLACE_UNIFORM) {
        rd_guide_pdf_build(pdf, 0, NULL, NULL, NULL, t0, t1, 1.0, NULL, 0);
    } else {
        /* Piecewise-constant extinction from K midpoint lookups: p ~ sigma~ T~ (eq. 11) is the
         * histogram PDF with f_j = sigma_j, sampled exactly; the defensive mixture covers where
         * the midpoints saw no medium. */
        int K = 4 * st->n_mean[PLACE_TRANSMITTANCE];
        double h = (t1 - t0) / K;
        for (int j = 0; j < K; j++) {
            ms->tb[j] = t0 + j * h;
            vec3 x = ray_at(r, t0 + (j + 0.5) * h);
            const rd_medium *m = rd_scene_medium_at(s, region, x);
            ms->sig[j] = m ? rd_medium_sigma_t(m, x) : 0.0;
            ms->f[j] = ms->sig[j];
            c->lookups += m != NULL;
        }
        ms->tb[K] = t1;
        rd_guide_pdf_build(pdf, K, ms->tb, ms->f, ms->sig, t0, t1, ms_set->alpha, NULL, 0);
    }
    return N > st->n_max ? st->n_max : (N < 1 ? 1 : N);
}

/* ---- The in-scattered radiance source S = sigma_s L_s ------------------------------------- */

static double phase_cb(double cos_theta, void *user) { return rd_hg_eval(*(const double *)user, cos_theta); }

#define MAX_GATHER RD_MAX_GATHER

/* sigma_s L_s(x, w) from the photons around x (THEORY.md §3, pm_map_radiance):
 *     sum_k p(w'_k . w) dPhi_k / ((4/3) pi r^3),
 * over the k nearest photons with r the distance to the k-th (one fixed map), or over the
 * photons within the fixed radius r = r_fixed > 0 (a progressive pass, bake/passes.c: the radius
 * must not depend on the pass's own photons for the passes' average to converge).
 * With shapes, a photon is used only when no surface lies between x and it: photons stored
 * behind a surface belong to another region (the dense medium inside a glass, say), and
 * gathering them by position alone would carry that region's light across the surface (a halo
 * around the shape: tests/test_surface_photon_leak.c). The sphere of radius r keeps its full
 * volume, so a sample within r of a surface is underestimated by the share of the sphere
 * beyond it (the usual boundary bias of density estimation, now on the dark side). At the faces
 * of a constant-density box medium the same bias (or, at a face onto another medium, the
 * difference of the two densities) is divided out (rd_march_support_share, march_share.c). */
static vec3 photon_estimate(const rd_scene *s, const pm_map *map, const rd_medium *m, int region, vec3 x,
                            vec3 w, int k, double r_fixed)
{
    double xd[3] = {x.x, x.y, x.z}, g = m->g;
    float wf[3] = {(float)w.x, (float)w.y, (float)w.z}, out[3];
    if (!map) return v3(0, 0, 0);
    /* FLANN's own estimate, but where the ball's share inside a box medium (divided out below,
     * rd_march_support_share) needs the radius. */
    int box_face = m->kind == RD_DENSITY_CONSTANT && !m->bound;
    if (!s->geom && r_fixed <= 0.0 && !box_face) {
        if (pm_map_radiance(map, xd, wf, k, phase_cb, &g, out) < 0) return v3(0, 0, 0);
        return v3(out[0], out[1], out[2]);
    }
    int idx[MAX_GATHER];
    float d2[MAX_GATHER];
    if (k > MAX_GATHER) k = MAX_GATHER;
    int n = r_fixed > 0.0 ? pm_map_radius(map, xd, (float)r_fixed, MAX_GATHER, idx, d2)
                          : pm_map_knn(map, xd, k, idx, d2);
    if (n <= 0 || (r_fixed <= 0.0 && !(d2[n - 1] > 0.0f))) return v3(0, 0, 0);
    const pm_photon *ph = pm_map_photons(map);
    double o[3];
    pm_map_origin(map, o);
    vec3 sum = v3(0, 0, 0);
    for (int i = 0; i < n; i++) {
        const pm_photon *p = &ph[idx[i]];
        if (s->geom) {
            vec3 q = v3(o[0] + p->pos[0], o[1] + p->pos[1], o[2] + p->pos[2]);
            vec3 dq = v3_sub(q, x);
            double len = v3_len(dq);
            if (len > 0.0) {
                ray3 r = {x, v3_scale(dq, 1.0 / len)};
                if (rd_geom_occluded(s->geom, r, 0.0, len, NULL)) continue;
            }
        }
        double cw = fmin(1.0, fmax(-1.0, p->dir[0] * w.x + p->dir[1] * w.y + p->dir[2] * w.z));
        sum = v3_madd(sum, v3(p->power[0], p->power[1], p->power[2]), rd_hg_eval(g, cw));
    }
    /* A fixed radius that held more than MAX_GATHER photons returned only the nearest of them:
     * the ball they fill is the one out to the farthest returned (the k-NN estimate with
     * k = MAX_GATHER), not the whole radius, whose volume would count the missing ones as none. */
    double r = r_fixed > 0.0 && n < MAX_GATHER ? r_fixed : sqrt((double)d2[n - 1]);
    if (!(r > 0.0)) return v3(0, 0, 0);
    return v3_scale(sum, 1.0 / (4.0 / 3.0 * M_PI * r * r * r * rd_march_support_share(s, region, m, x, r)));
}

/* The gather radius of the current progressive pass at x (bake/passes.c): r_1(x), pass 1's
 * k-NN bandwidth (bandwidth.c, rd_march_knn_bandwidth), times the pass's scale. r_1 depends on
 * pass 1's photons only, so every later pass's estimate is a fixed-kernel estimate, independent
 * of its own photons, and the passes' average converges. 0 with one fixed map (then the k-NN
 * estimate); -1 where pass 1 has no photon at all (nothing to gather). */
static double pass_radius(const rd_render_ctx *ctx, const pm_map *first, vec3 x)
{
    if (ctx->photon_pass < 1 || !first) return 0.0;
    double r = rd_march_knn_bandwidth(first, ctx->scene->guide.k, x);
    return r < 0.0 ? -1.0 : r * ctx->radius_scale;
}

vec3 rd_march_source(const rd_render_ctx *ctx, rd_ls_kind ls, const rd_medium *m, int region, vec3 x,
                     vec3 d, double sigma_t, int event, double q_path, const double *light_w, pcg32 *rng,
                     rd_track_counters *c)
{
    const rd_scene *s = ctx->scene;
    vec3 S = v3(0, 0, 0);
    vec3 w = v3_scale(d, -1.0);
    switch (ls) {
    case RD_LS_PHOTONS: {
        double r = pass_radius(ctx, ctx->photons_first, x);
        return r < 0.0 ? v3(0, 0, 0) : photon_estimate(s, ctx->photons, m, region, x, w, s->guide.k, r);
    }
    case RD_LS_NEE_GUIDE: {
        /* Multiple scattering read from the guide of the indirect photons: one cell lookup
         * and one SH evaluation instead of a k-NN query (smoother, coarser: the cell's
         * average, band-limited). Negative lobes of the truncation are clamped per channel. */
        double xd[3] = {x.x, x.y, x.z}, wd[3] = {w.x, w.y, w.z};
        float out[3] = {0, 0, 0};
        if (ctx->guide_indirect) sh_guide_eval(ctx->guide_indirect, xd, wd, out);
        S = v3(fmax(0.0, out[0]), fmax(0.0, out[1]), fmax(0.0, out[2]));
        vec3 sigma_s = v3_scale(m->albedo, sigma_t);
        return v3_add(S, v3_mul(sigma_s, rd_nee_all(s, region, x, d, m->g, light_w, rng, c)));
    }
    case RD_LS_NEE_PATHS: {
        /* delta's own vertex at x: next-event estimation (rd_nee_split: every delta light,
         * MIS with the path for lights it can hit) plus one phase-sampled path from x on,
         * tracked by `delta` (its collisions' NEE and roulette), so S is unbiased and the
         * marcher converges to delta's image. The path is taken with probability q_path and
         * weighted 1/q_path (still unbiased); the HG weight p/pdf is 1. */
        vec3 sigma_s = v3_scale(m->albedo, sigma_t);
        vec3 Ls = rd_nee_split(s, region, x, d, m->g, light_w, rng, c);
        if (event + 1 <= s->settings.max_depth && q_path > 0.0 &&
            (q_path >= 1.0 || pcg32_uniform(rng) < q_path)) {
            vec3 wo = rd_hg_sample(m->g, d, pcg32_uniform(rng), pcg32_uniform(rng));
            ray3 next = {x, wo};
            vec3 Li = rd_delta_continue(s, next, region, rd_hg_eval(m->g, v3_dot(d, wo)), event, 0,
                                        s->march.equiangular, rng, c);
            Ls = v3_madd(Ls, Li, q_path >= 1.0 ? 1.0 : 1.0 / q_path);
        }
        return v3_mul(sigma_s, Ls);
    }
    case RD_LS_NEE_DELTA:
        /* The direct part of delta's vertex at x only: the rest of the in-scattering on this
         * segment is one path of delta's from the segment's start (march_segment). */
        return v3_mul(v3_scale(m->albedo, sigma_t), rd_nee_split(s, region, x, d, m->g, light_w, rng, c));
    case RD_LS_NEE_PHOTONS: {
        double r = pass_radius(ctx, ctx->photons_indirect_first, x);
        if (r >= 0.0) S = photon_estimate(s, ctx->photons_indirect, m, region, x, w, s->guide.k, r);
    }
        /* add the direct light: */
        /* fall through */
    case RD_LS_NEE:
    default: {
        vec3 sigma_s = v3_scale(m->albedo, sigma_t);
        return v3_add(S, v3_mul(sigma_s, rd_nee_all(s, region, x, d, m->g, light_w, rng, c)));
    }
    }
}

/* ---- The estimator -------------------------------------------------------------------------- */

/* One straight segment of the camera ray: r in `region` up to t_end (the next surface or light,
 * or INFINITY), marched over the part inside the scene bounds with N samples of `place`
 * stratified by the offset u. Returns the in-scattered estimate; *T_out gets the unbiased
 * transmittance estimate T(0, t_end), or 0 when `need_T` is 0 (what lies behind the segment
 * is black: the rest of T would multiply nothing, so it is not tracked). `event` is the
 * scattering event a sample here would be
 * (the surface events before the segment + 1); past settings.max_depth the segment gives the
 * transmittance alone, as `delta` scatters no more there either. *gap gets the beam estimate's
 * gap with nee+beams (rd_march_beam_estimate), else 0. */
static vec3 march_segment(const rd_render_ctx *ctx, rd_thread *th, ray3 r, int region,
                          double t_end, placement place, rd_ls_kind ls, double u, int event, int need_T,
                          pcg32 *rng, double *T_out, vec3 *gap)
{
    const rd_scene *s = ctx->scene;
    rd_track_counters *c = &th->counters;
    double t0, t1;
    *T_out = 1.0;
    *gap = v3(0, 0, 0);
    if (!medium_span(s, r, t_end, &t0, &t1)) return v3(0, 0, 0);
    if (event > s->settings.max_depth) {
        *T_out = need_T ? rd_transmittance(s, region, r, t0, t1, rng, c) : 0.0;
        return v3(0, 0, 0);
    }
    march_scratch ms;
    rd_march_scratch_layout(ctx->state, &ms, th->scratch);
    rd_guide_pdf pdf;
    int N = rd_march_build_pdf(ctx, place, &ms, region, r, t0, t1, &pdf, c);
    if (th->rays == 0 || (uint32_t)N < th->samples_min) th->samples_min = (uint32_t)N;
    if ((uint32_t)N > th->samples_max) th->samples_max = (uint32_t)N;
    th->rays++;
    th->ray_samples += (uint64_t)N;
    th->cells += (uint64_t)pdf.n;
    rd_guide_pdf_sample_stratified(&pdf, N, u, ms.t, ms.p);
    const march_state *st = ctx->state;
    double q_path = st->q_path[place]; /* nee+paths: the chance of a path from each sample */
    /* march.equiangular: the lights the segment's equiangular sample may choose, whose
     * next-event estimates at the placement's samples take the MIS weight w_p
     * (march_equiangular.c); ms.lw holds 1 for every other light. */
    rd_march_eq eq;
    int eq_n = rd_march_eq_begin(s, r, region, t_end, &pdf, N, &eq, c);
    const double *light_w = NULL;
    if (eq_n > 0) {
        for (int i = 0; i < st->n_lights; i++) ms.lw[i] = 1.0;
        light_w = ms.lw;
    }
    vec3 L = v3(0, 0, 0);
    double T = 1.0, tp = t0;
    for (int n = 0; n < N && T != 0.0; n++) {
        T *= rd_transmittance(s, region, r, tp, ms.t[n], rng, c); /* T(0, t_n), one sweep */
        /* Roulette on the ray's T (rd_tr_roulette): samples whose light reaches the camera at
         * under 5% are mostly skipped, the rest weighted up; killing it ends the ray, as the
         * samples beyond would be rouletted alike. */
        T *= rd_tr_roulette(T, rng);
        tp = ms.t[n];
        vec3 x = ray_at(r, ms.t[n]);
        const rd_medium *m = rd_scene_medium_at(s, region, x);
        if (!m || !(ms.p[n] > 0.0)) continue;
        double sigma_t = rd_medium_sigma_t(m, x);
        c->lookups++;
        if (sigma_t <= 0.0) continue;
        if (eq_n > 0) rd_march_eq_weights(&eq, ms.t[n], ms.lw);
        vec3 S = rd_march_source(ctx, ls, m, region, x, r.d, sigma_t, event, q_path, light_w, rng, c);
        L = v3_madd(L, S, T / (N * ms.p[n]));
    }
    if (eq_n > 0) L = v3_add(L, rd_march_eq_sample(s, &eq, t0, rng, c));
    /* nee+delta: the samples estimated the single scattering's next-event part; one path of
     * delta's along the segment adds everything else that scatters on it (rd_delta_scattered:
     * 0 when its flight passes, so it costs a delta path only where one would scatter). */
    if (ls == RD_LS_NEE_DELTA)
        L = v3_add(L, rd_delta_scattered(s, r, region, event - 1, s->march.equiangular, rng, c));
    /* nee+beams: the samples estimated the direct light; the photons' balls along the whole
     * segment give the rest (rd_march_beam_estimate). */
    if (ls == RD_LS_NEE_BEAMS) {
        int crossed;
        L = v3_add(L, rd_march_beam_estimate(ctx, &ms, r, region, t0, t1, rng, c, &crossed, th->want_gap ? gap : NULL));
        th->beam_queries++;
        th->beam_hits += (uint64_t)crossed;
    }
    if (T != 0.0 && need_T) T *= rd_transmittance(s, region, r, tp, t1, rng, c);
    *T_out = need_T ? T : 0.0;
    return L;
}

/* Surface crossings of one camera chain that are not events (index-matched interfaces). */
#define MAX_CROSSINGS 4096

/* One camera sample's chain: returns I, what the chain's media segments and a diffuse surface
 * at its end give, and *E, the light the chain sees at its end (probes.c). */
static vec3 march_chain(const rd_render_ctx *ctx, rd_thread *th, ray3 r, double u, pcg32 *rng,
                        placement place, rd_ls_kind ls, vec3 *E)
{
    const rd_scene *s = ctx->scene;
    rd_track_counters *c = &th->counters;
    double T;
    *E = v3(0, 0, 0);
    if (!s->geom) {
        /* No shapes: one segment, up to the nearest sphere light. */
        double t_light;
        int hit_light = rd_scene_hit_light(s, r, INFINITY, -1, &t_light);
        vec3 Lb = rd_scene_behind(s, hit_light);
        vec3 gap;
        vec3 L = march_segment(ctx, th, r, s->fill_medium, t_light, place, ls, u, 1, v3_maxc(Lb) > 0.0, rng, &T, &gap);
        th->beam_gap = v3_add(th->beam_gap, gap);
        *E = v3_scale(Lb, T);
        return L;
    }
    /* With shapes: each straight segment of the camera's specular chain is marched in its
     * region (docs/surfaces.md). At a dielectric one branch is followed, chosen with its
     * Fresnel probability (rd_surface_event: weight 1, (n_i/n_t)^2 on refraction); an
     * interface only changes the region; at a diffuse surface the marcher hands the path to
     * `delta` (next-event estimation there and the path tracer's continuation). */
    int region = rd_scene_camera_region(s, r), crossings = 0;
    double eta_scale = 1.0; /* rd_surface_step */
    vec3 L = v3(0, 0, 0), beta = v3(1, 1, 1);
    rd_hit h, prev;
    const rd_hit *from = NULL;
    for (int depth = 0;;) {
        int got = rd_scene_intersect(s, r, INFINITY, from, &h);
        /* In-scattering on a segment behind `depth` surface events is event depth + 1, as in
         * delta's path loop (settings.max_depth bounds both alike). */
        /* T of the segment matters when a surface follows it or something bright lies behind. */
        int need_T = (got && h.light < 0) || v3_maxc(rd_scene_behind(s, got ? h.light : -1)) > 0.0;
        vec3 gap;
        vec3 Ls = march_segment(ctx, th, r, region, got ? h.t : INFINITY, place, ls, u, depth + 1, need_T, rng, &T, &gap);
        L = v3_add(L, v3_mul(beta, Ls));
        th->beam_gap = v3_add(th->beam_gap, v3_mul(beta, gap));
        beta = v3_scale(beta, T);
        if (!got || h.light >= 0) {
            *E = v3_mul(beta, rd_scene_behind(s, got ? h.light : -1));
            break;
        }
        if (!(T != 0.0)) break;
        u = pcg32_uniform(rng); /* the next segment's stratification offset */
        prev = h;
        from = &prev;
        if (s->shapes[h.shape].material.kind == RD_MAT_INTERFACE) {
            if (++crossings > MAX_CROSSINGS) break;
            region = prev.medium_to;
            r = rd_hit_spawn(&prev, r.d);
            continue;
        }
        if (++depth > s->settings.max_depth) break;
        rd_surface_step st = {.r = r, .beta = beta, .region = region, .camera_chain = 1, .eta_scale = eta_scale};
        int go = rd_surface_event(s, &prev, depth, &st, rng, c);
        L = v3_add(L, st.L);
        if (!go) break;
        if (!st.camera_chain) {
            /* diffuse: the rest of the path is delta's */
            vec3 Lc = rd_delta_continue(s, st.r, st.region, st.pdf, depth, 0, s->march.equiangular, rng, c);
            L = v3_add(L, v3_mul(st.beta, Lc));
            break;
        }
        r = st.r, beta = st.beta, region = st.region, eta_scale = st.eta_scale;
    }
    return L;
}

vec3 rd_march_radiance(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp,
                       placement place)
{
    return rd_march_radiance_ls(ctx, th, r, smp, place, ctx->scene->march.ls);
}

vec3 rd_march_radiance_ls(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp,
                          placement place, rd_ls_kind ls)
{
    march_state *st = ctx->state;
    double u = rd_sampler_1d(smp);
    pcg32 rng = rd_sampler_stream(smp);
    vec3 E;
    th->beam_gap = v3(0, 0, 0);
    if (!rd_probes_on(&st->probes)) { /* no probes: the chain's own E */
        vec3 I = march_chain(ctx, th, r, u, &rng, place, ls, &E);
        return v3_add(I, E);
    }
    rd_select_work w0 = rd_select_work_now(th);
    vec3 I = march_chain(ctx, th, r, u, &rng, place, ls, &E);
    return rd_probes_add(ctx, &st->probes, th, I, E, rd_probes_cost(&st->probes, &w0, th), &rng);
}

int rd_march_epoch_next(const rd_render_ctx *ctx, int sample)
{
    const march_state *st = ctx->state;
    return rd_probes_epoch_next(&st->probes, sample);
}

void rd_march_epoch(rd_render_ctx *ctx, int sample)
{
    march_state *st = ctx->state;
    (void)sample;
    rd_probes_epoch(ctx, &st->probes);
}

/* ---- Set-up: scratch sizes and the pilot pass ---------------------------------------------- */

size_t rd_march_scratch_bytes(const rd_render_ctx *ctx)
{
    march_scratch ms;
    return rd_march_scratch_layout(ctx->state, &ms, NULL);
}

rd_status rd_march_prepare(rd_render_ctx *ctx, char *err, size_t errlen)
{
    return rd_march_prepare_beams(ctx, 0, err, errlen);
}

rd_status rd_march_prepare_beams(rd_render_ctx *ctx, int beams, char *err, size_t errlen)
{
    const rd_march_settings *m = &ctx->scene->march;
    rd_status st = rd_guide_sampler_check(m->alpha, m->min_samples, m->max_samples, err, errlen);
    if (st != RD_OK) return st;
    march_state *ms = calloc(1, sizeof *ms);
    if (!ms) {
        snprintf(err, errlen, "out of memory for the marcher");
        return RD_ERR_NOMEM;
    }
    ms->n_max = m->max_samples;
    ms->k_steps = 0;
    for (int p = 0; p < PLACE_COUNT; p++) {
        ms->n_mean[p] = m->samples > 0 ? m->samples : march_default_samples((placement)p);
        ms->q_path[p] = m->paths > 0.0 ? m->paths : march_default_paths((placement)p);
        if (ms->n_mean[p] > ms->n_max) ms->n_max = ms->n_mean[p];
        if (4 * ms->n_mean[p] > ms->k_steps) ms->k_steps = 4 * ms->n_mean[p];
    }
    ms->seg_cap = ms->k_steps + 2;
    if (ctx->guide) {
        /* A uniform grid is crossed in at most nx + ny + nz - 2 cells; an adaptive one in at
         * most 3 x 2^depth leaves. Plus two fillers (rd_guide_pdf.h). A ray that needs more
         * falls back to the defensive PDF alone (still unbiased). */
        sh_guide_stats gs;
        sh_guide_stats_get(ctx->guide, &gs);
        int need = gs.kind == SH_GRID_UNIFORM ? gs.res[0] + gs.res[1] + gs.res[2] + 2
                                              : 3 * (1 << (gs.depth_max < 12 ? gs.depth_max : 12)) + 2;
        if (need > ms->seg_cap) ms->seg_cap = need;
    }
    /* Detail pieces: every guide segment cut at most once per lattice step, so at most
     * (segments) + k_steps pieces; the rebuilt PDF needs as many entries plus the fillers. */
    ms->piece_cap = ms->k_steps;
    if (ctx->guide && m->detail) {
        ms->piece_cap = ms->seg_cap + ms->k_steps;
        ms->seg_cap = ms->piece_cap + 2;
    }
    ms->beam_source = ctx->scene->march.ls == RD_LS_NEE_BEAMS || beams;
    ms->beam_cap = ms->beam_source ? RD_BEAM_CAP : 0;
    ms->n_lights = ctx->scene->march.equiangular != RD_EQ_OFF ? ctx->scene->n_lights : 0;
    ctx->state = ms;
    rd_status bs = rd_probes_init(&ms->probes, ctx->scene, m->probes, RD_MARCH_CELL_COST, err, errlen);
    if (bs == RD_OK) bs = rd_march_photons_changed(ctx, err, errlen);
    if (bs != RD_OK) rd_march_release(ctx);
    return bs;
}

void rd_march_release(rd_render_ctx *ctx)
{
    march_state *ms = ctx->state;
    if (ms) {
        rd_select_free(&ms->sel);
        rd_march_beams_free(ms);
        rd_probes_free(&ms->probes);
        rd_gu_paths_free(ms->gpaths);
    }
    free(ctx->state);
    ctx->state = NULL;
}

unsigned rd_march_pass_maps(const rd_scene *s)
{
    if (!s->photons.progressive) return 0u; /* one fixed map */
    switch (s->march.ls) {
    case RD_LS_PHOTONS: return RD_NEEDS_PHOTONS;
    case RD_LS_NEE_PHOTONS: return RD_NEEDS_INDIRECT;
    /* the beams read a pass's photons in spatial order and ask it no query (march_beams.c: the
     * radii from pass 1's map), and keep about as many balls as photons emitted */
    case RD_LS_NEE_BEAMS: return RD_NEEDS_INDIRECT | RD_PASS_NO_INDEX | RD_PASS_THIN;
    default: return 0u;
    }
}


/* What the scene's source needs baked: the photon map (photons) or its indirect part
 * (nee+photons); the guided placement needs the guide (and so a photon map) in any case. */
unsigned rd_march_source_needs(const rd_scene *s)
{
    switch (s->march.ls) {
    case RD_LS_PHOTONS: return RD_NEEDS_PHOTONS;
    case RD_LS_NEE_PHOTONS:
    case RD_LS_NEE_BEAMS: return RD_NEEDS_PHOTONS | RD_NEEDS_INDIRECT;
    case RD_LS_NEE_GUIDE: return RD_NEEDS_PHOTONS | RD_NEEDS_INDIRECT | RD_NEEDS_INDIRECT_GUIDE;
    default: return 0u;
    }
}
