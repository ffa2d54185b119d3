/* march_beams.c: the beam radiance estimate of the marchers' source march.ls = nee+beams
 * (Jarosz, Zwicker & Jensen 2008, with a 3-D ball per photon): the indirect photons' balls, their
 * radii, and the estimate along a camera-ray segment (rd_march_beam_estimate). The balls
 * themselves are integrators/beams.c's; the samples of march.c add the direct light. */
#include "integrators/rd_march.h"
#include "scene/rd_geom.h"
#include "transport/rd_path.h"
#include "photonmap.h"

#include <stdlib.h>
#include <string.h>

/* ---- The radii: r_1 on cells of pass 1 --------------------------------------------------- */

/* A ball's radius is r_k = r_1(x_k) s_i: the pass's scale s_i (bake/passes.c) times pass 1's
 * bandwidth r_1 (rd_march_knn_bandwidth: the guide.k-NN distance in pass 1's indirect map, or
 * the fixed map's). A k-NN query per ball per pass cost more than tracing the pass (0.9 s a
 * pass for 200000 balls on one thread, smoke-vdb), so r_1 is read from cells instead: the
 * cells of edge h (the median r_1 over 4096 of pass 1's photons) that hold a photon of pass 1,
 * each with r_1 at its centre, found by binary search on the sorted cell keys. A ball whose
 * cell holds no photon of pass 1 gets its own query. r_1 stays a function of x fixed by pass 1
 * alone (piecewise constant on cells of the median kernel's size: coarser than the kernel where
 * photons are dense, finer where they are sparse), so every later pass is still a
 * fixed-kernel estimate and the passes' average converges. */
struct beam_field {
    double lo[3], h;      /* world corner of cell (0, 0, 0), cell edge; h = 0: no cells */
    size_t n;             /* cells held */
    uint64_t *key;        /* their keys, sorted: ix | iy << 21 | iz << 42 */
    float *r1;            /* r_1 at each one's centre (<= 0: none could be read; the ball queries) */
    const pm_map *first;
    int k;
};

#define CELL_BITS 21
#define CELL_MAX ((1u << CELL_BITS) - 1)

static int cell_key(const struct beam_field *f, vec3 x, uint64_t *key)
{
    double c[3] = {(x.x - f->lo[0]) / f->h, (x.y - f->lo[1]) / f->h, (x.z - f->lo[2]) / f->h};
    uint64_t k = 0;
    for (int a = 0; a < 3; a++) {
        if (!(c[a] >= 0.0 && c[a] < CELL_MAX)) return 0;
        k |= (uint64_t)c[a] << (CELL_BITS * a);
    }
    *key = k;
    return 1;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void field_free(struct beam_field *f)
{
    if (!f) return;
    free(f->key);
    free(f->r1);
    free(f);
}

/* r_1 at x: its cell's, or a query of its own (*queried set). */
static double field_r1(const struct beam_field *f, vec3 x, int *queried)
{
    *queried = 0;
    uint64_t key;
    if (f->h > 0.0 && cell_key(f, x, &key)) {
        size_t lo = 0, hi = f->n;
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (f->key[mid] < key) lo = mid + 1;
            else hi = mid;
        }
        if (lo < f->n && f->key[lo] == key && f->r1[lo] > 0.0f) return f->r1[lo];
    }
    *queried = 1;
    return rd_march_knn_bandwidth(f->first, f->k, x);
}

/* The cells of pass 1's map `first` (see above). */
static rd_status field_build(const pm_map *first, int k, int threads, struct beam_field **out, char *err,
                             size_t errlen)
{
    struct beam_field *f = calloc(1, sizeof *f);
    size_t n = pm_map_photon_count(first);
    size_t m = n < 4096 ? n : 4096;
    double *sample = malloc((m ? m : 1) * sizeof *sample);
    if (f) f->key = malloc((n ? n : 1) * sizeof *f->key);
    if (!f || !sample || !f->key) {
        free(sample);
        field_free(f);
        snprintf(err, errlen, "out of memory for the photon balls' radius cells (%zu photons)", n);
        return RD_ERR_NOMEM;
    }
    f->first = first, f->k = k;
    const pm_photon *ph = pm_map_photons(first);
    double o[3];
    pm_map_origin(first, o);
    size_t got = 0;
    for (size_t i = 0; i < m; i++) {
        const pm_photon *p = &ph[i * n / m];
        double r = rd_march_knn_bandwidth(first, k, v3(o[0] + p->pos[0], o[1] + p->pos[1], o[2] + p->pos[2]));
        if (r > 0.0) sample[got++] = r;
    }
    if (got > 0) {
        qsort(sample, got, sizeof *sample, cmp_double);
        float lo[3], hi[3];
        pm_map_bounds(first, lo, hi);
        f->h = sample[got / 2];
        /* Never more cells along an axis than the keys hold (h grows for a scene whose photons
         * spread over a million median radii). pm_map_bounds is in world coordinates. */
        for (int a = 0; a < 3; a++) {
            double span = (double)hi[a] - lo[a] + f->h;
            if (span / f->h > 0.5 * CELL_MAX) f->h = span / (0.5 * CELL_MAX);
        }
        for (int a = 0; a < 3; a++) f->lo[a] = lo[a] - 0.5 * f->h;
    }
    free(sample);
    if (f->h > 0.0) {
        size_t nk = 0;
        for (size_t i = 0; i < n; i++) {
            uint64_t key;
            if (cell_key(f, v3(o[0] + ph[i].pos[0], o[1] + ph[i].pos[1], o[2] + ph[i].pos[2]), &key)) f->key[nk++] = key;
        }
        qsort(f->key, nk, sizeof *f->key, cmp_u64);
        size_t u = 0;
        for (size_t i = 0; i < nk; i++)
            if (u == 0 || f->key[i] != f->key[u - 1]) f->key[u++] = f->key[i];
        f->n = u;
        uint64_t *shrunk = realloc(f->key, (u ? u : 1) * sizeof *f->key);
        if (shrunk) f->key = shrunk;
        f->r1 = malloc((u ? u : 1) * sizeof *f->r1);
        if (!f->r1) {
            field_free(f);
            snprintf(err, errlen, "out of memory for %zu radius cells", u);
            return RD_ERR_NOMEM;
        }
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads)
        for (size_t i = 0; i < u; i++) {
            uint64_t key = f->key[i];
            vec3 c = v3(f->lo[0] + ((double)(key & CELL_MAX) + 0.5) * f->h,
                        f->lo[1] + ((double)((key >> CELL_BITS) & CELL_MAX) + 0.5) * f->h,
                        f->lo[2] + ((double)(key >> (2 * CELL_BITS)) + 0.5) * f->h);
            f->r1[i] = (float)rd_march_knn_bandwidth(first, k, c);
        }
    }
    *out = f;
    return RD_OK;
}

/* ---- The balls ----------------------------------------------------------------------------- */

void rd_march_beams_free(march_state *st)
{
    rd_beams_free(st->beams);
    free(st->beam_radius);
    field_free(st->beam_field);
    st->beams = NULL, st->beam_radius = NULL, st->beam_field = NULL;
}

/* The balls of the indirect photons ctx holds now: photon k with radius r_1(x_k) s_i (above).
 * This is the sample-point form of the kernel estimate (the radius belongs to the photon, not
 * to the point that gathers): the ball of photon k adds
 *     p(w'_k . w) dPhi_k / ((4/3) pi r_k^3)
 * at every point inside it. At most as many balls as photons emitted: a photon path in a dense
 * medium stores a collision every mean free path, and neighbouring collisions carry nearly the
 * same light; each photon is kept with probability q = emitted / stored and its power counted
 * 1/q (unbiased given the kernel), so a pass's balls cost in proportion to the photons emitted
 * however often they scatter. The choice hashes (pass, index), so it does not depend on the
 * threads. Keeping every photon tied on the calibration scenes (cloud, smoke-vdb,
 * sphere-in-fog: 0.87-1.08x) and lost 1.2x on a dense variant of hetero-forward (sigma_t 10,
 * albedo 0.99; docs/benchmarks.md "Session 19"). Since session 62 the passes after the first
 * are thinned as they are traced (RD_PASS_THIN, rd_method.h: q from pass 1's counts), so they
 * arrive with about `emitted` photons already carrying 1/q, and the thinning here only trims
 * the binomial excess (its 1/q then multiplies the tracer's: both unbiased).
 *
 * The kernel holds k of the balls read (session 62). r_1 is the radius of k neighbours in pass
 * 1's map, all its stored photons; of those, a share q_1 = min(1, emitted / stored in pass 1)
 * become balls (here, or in the tracer and here), so a ball of radius r_1 held k q_1 balls: on
 * hard-dense-block (q_1 0.11) about 7 where guide.k is 64, and the estimate had the variance of a
 * kernel of 7. The radii are scaled by q_1^(-1/3), which holds k again where the photons are
 * locally uniform (the k-NN bandwidth's own extrapolation, bandwidth.c: r ~ (k / n)^(1/3)): a
 * wider kernel (bias ~ r^2) of more balls (more crossed a query, ~ q_1^(-2/3)), the kernel's
 * definition the same whether a medium stores a collision per photon or ten. Where q_1 = 1 (no
 * pass stores more than it emits) nothing changes. */
rd_status rd_march_photons_changed(rd_render_ctx *ctx, char *err, size_t errlen)
{
    march_state *st = ctx->state;
    if (!st || !st->beam_source) return RD_OK;
    const pm_map *map = ctx->photons_indirect;
    const pm_map *first = ctx->photon_pass >= 1 ? ctx->photons_indirect_first : map;
    double scale = ctx->photon_pass >= 1 ? ctx->radius_scale : 1.0;
    if (!map || !first) {
        snprintf(err, errlen, "the photon beams (march.ls nee+beams, march.beams): no indirect photon map");
        return RD_ERR_INTERNAL;
    }
    int k = ctx->scene->guide.k;
    rd_status s;
    if (!st->beam_field && (s = field_build(first, k, ctx->threads, &st->beam_field, err, errlen)) != RD_OK) return s;
    size_t n = pm_map_photon_count(map);
    if (n > st->beam_radius_cap) {
        float *r = realloc(st->beam_radius, (n ? n : 1) * sizeof *r);
        if (!r) {
            snprintf(err, errlen, "out of memory for %zu photon radii", n);
            return RD_ERR_NOMEM;
        }
        st->beam_radius = r, st->beam_radius_cap = n;
    }
    const pm_photon *ph = pm_map_photons(map);
    double o[3];
    pm_map_origin(map, o);
    float *rad = st->beam_radius;
    const rd_photon_settings *ps = &ctx->scene->photons;
    size_t emitted = ps->pass_count > 0 && ctx->photon_pass >= 1 ? ps->pass_count : ps->count;
    double q = n > emitted ? (double)emitted / n : 1.0;
    st->beam_weight = 1.0 / q;
    size_t n1 = pm_map_photon_count(first); /* (the kernel's k of the balls read: above) */
    if (n1 > emitted) scale *= cbrt((double)n1 / (double)emitted);
    uint64_t key = 0x9e3779b97f4a7c15ULL * (uint64_t)(ctx->photon_pass + 1);
    const struct beam_field *f = st->beam_field;
    size_t queries = 0;
#pragma omp parallel for schedule(dynamic, 1024) num_threads(ctx->threads) reduction(+ : queries)
    for (size_t i = 0; i < n; i++) {
        rad[i] = 0.0f;
        if (q < 1.0 && (double)(rd_mix64(key + i) >> 11) * 0x1.0p-53 >= q) continue;
        int queried;
        double r = field_r1(f, v3(o[0] + ph[i].pos[0], o[1] + ph[i].pos[1], o[2] + ph[i].pos[2]), &queried);
        queries += (size_t)queried;
        rad[i] = r > 0.0 ? (float)(r * scale) : 0.0f;
    }
    st->beam_r1_queries = queries;
    if (!st->beams && (s = rd_beams_new(&st->beams, ctx->threads, err, errlen)) != RD_OK) return s;
    return rd_beams_build(st->beams, map, rad, err, errlen);
}

/* ---- The estimate -------------------------------------------------------------------------- */

/* Points along a segment at which the beam estimate reads T (rd_march_beam_estimate). */
#define BEAM_PICKS 16

/* The beam radiance estimate of the indirect in-scattering along [t0, t1] of r (Jarosz,
 * Zwicker & Jensen 2008, with the 3-D ball of each photon): the integral of the sample-point
 * kernel estimate times the transmittance,
 *     int_t0^t1 T(t0, t) sum_k [|x(t) - x_k| < r_k] p(w'_k . w) dPhi_k / V_k dt
 *       = sum_k c_k (1 / L_k) int_{ta_k}^{tb_k} T(t0, t) dt,   c_k = p(w'_k . w) dPhi_k L_k / V_k,
 * over the balls the segment crosses ([ta_k, tb_k] its chord in ball k, L_k its length,
 * V_k = (4/3) pi r_k^3). A segment crosses hundreds of balls, and reading T at each costs a
 * tracking each; so the sum is estimated by BEAM_PICKS stratified picks k_j with probability
 * P_k = lum(c_k) / sum lum(c), each at u_j uniform on its chord:
 *     (1 / m) sum_j c_{k_j} T(t0, u_j) / P_{k_j},
 * with T from the free-path engine swept once over the sorted u_j (independent pieces, as the
 * samples' sweep in march_segment). Unbiased given the photons: the estimate equals the point
 * gather with the same balls marched with infinitely many samples (which skip empty voxels, as
 * the picks do: sigma_t = 0 there). The ball sampling (rd_beams_cross's reservoir, and the 1/q of
 * the balls kept) is unbiased too. Segments that cross at most
 * BEAM_PICKS balls take every ball once (P = 1). c_k's phase is that of the medium at the
 * chord's middle; the pick re-weights by the phase at x(u_j). With shapes, ball k counts at
 * u_j only when no surface lies between x(u_j) and the photon (the point gather's rule). Near a
 * face of a constant-density box medium, ball k's term at x(u_j) is divided by the share of the
 * ball of radius r_k about x(u_j) that holds photons, weighted by their density
 * (rd_march_support_share, march_share.c): the kernel's boundary bias, -2.6% of homogeneous's image
 * and -6.5% of the dense block's before, -0.4% and -1.2% after (docs/benchmarks.md
 * "Session 54"). */
/* The term of a pick at u on hit h's chord (ball of radius rk about q, medium m at the pick, with
 * sigma_t sigma_x there) read with the ball of half the volume, radius rk / sqrt 2, as a factor of
 * the pick's T and weight (rd_march.h, `gap`): u maps linearly onto the small ball's chord
 * (clipped to [t0, t1] as the big one is), so a u uniform on the big chord lands uniform on the
 * small one, and T there is the pick's times exp(-sigma (u' - u)), sigma the mean of sigma_t at
 * the two points (exact in a medium constant between them). The small term then follows the big
 * one pick for pick, and the gap is a smooth difference rather than an indicator's noise. 0
 * where the segment misses the small ball or u' lies outside the medium. One density lookup.
 * Approximate near a density edge or a surface: the small term is dropped with the big one where
 * the pick is empty or occluded (tested from x, not x'), and takes x's phase. */
static double half_ball_term(const rd_scene *s, int region, ray3 r, vec3 q, double rk, const rd_beam_hit *h,
                             double u, double t0, double t1, const rd_medium *m, double sigma_x, double cw,
                             rd_track_counters *c)
{
    const double rh = rk * 0.70710678118654752440; /* 1 / sqrt 2 */
    vec3 oq = v3_sub(q, r.o);
    double tc = v3_dot(oq, r.d), d2 = fmax(0.0, v3_dot(oq, oq) - tc * tc);
    if (!(d2 < rh * rh) || !(h->tb > h->ta)) return 0.0;
    double half = sqrt(rh * rh - d2), sa = fmax(tc - half, t0), sb = fmin(tc + half, t1);
    if (!(sb > sa)) return 0.0;
    double u2 = sa + (u - h->ta) / (h->tb - h->ta) * (sb - sa);
    vec3 x2 = ray_at(r, u2);
    const rd_medium *m2 = rd_scene_medium_at(s, region, x2);
    if (!m2) return 0.0;
    c->lookups++;
    double sigma2 = rd_medium_sigma_t(m2, x2);
    if (!(sigma2 > 0.0)) return 0.0;
    double f = rd_hg_eval(m->g, cw) * (sb - sa) / (4.0 / 3.0 * M_PI * rh * rh * rh);
    f /= rd_march_support_share(s, region, m2, x2, rh);
    return f * exp(-0.5 * (sigma_x + sigma2) * (u2 - u));
}

vec3 rd_march_beam_estimate(const rd_render_ctx *ctx, const march_scratch *ms, ray3 r, int region,
                             double t0, double t1, pcg32 *rng, rd_track_counters *c, int *crossed, vec3 *gap)
{
    const rd_scene *s = ctx->scene;
    const march_state *st = ctx->state;
    double wgt;
    if (gap) *gap = v3(0, 0, 0);
    int n = rd_beams_cross(st->beams, r, t0, t1, ms->hits, st->beam_cap, rng, &wgt);
    *crossed = n < st->beam_cap ? n : (int)lround(wgt * n); /* every ball crossed, kept or not */
    if (n == 0) return v3(0, 0, 0);
    const pm_map *map = rd_beams_map(st->beams);
    const pm_photon *ph = pm_map_photons(map);
    vec3 w = v3_scale(r.d, -1.0);
    /* The hits' photons and radii, scattered over their arrays: their loads issued together,
     * not one a hit behind the last hit's arithmetic. */
    for (int i = 0; i < n; i++) {
        __builtin_prefetch(&ph[ms->hits[i].idx]);
        __builtin_prefetch(&st->beam_radius[ms->hits[i].idx]);
    }
    /* The picks' weights: cdf[i] = sum of lum(c_k) over the first i + 1 hits, each divided by
     * the ball's share inside the box at its chord's middle, as its term is at the pick. */
    double total = 0.0;
    for (int i = 0; i < n; i++) {
        const rd_beam_hit *h = &ms->hits[i];
        const pm_photon *p = &ph[h->idx];
        vec3 mid = ray_at(r, 0.5 * (h->ta + h->tb));
        const rd_medium *m = rd_scene_medium_at(s, region, mid);
        double rk = st->beam_radius[h->idx];
        double cw = fmin(1.0, fmax(-1.0, p->dir[0] * w.x + p->dir[1] * w.y + p->dir[2] * w.z));
        double lum = 0.2126 * p->power[0] + 0.7152 * p->power[1] + 0.0722 * p->power[2];
        double sh = m ? rd_march_support_share(s, region, m, mid, rk) : 1.0; /* (below) */
        total += fmax(lum, 0.0) * rd_hg_eval(m ? m->g : 0.0, cw) * (h->tb - h->ta) / (rk * rk * rk * sh);
        ms->cdf[i] = total;
    }
    if (!(total > 0.0)) return v3(0, 0, 0);
    /* The picks (hit, u, 1 / (m P)), stratified over the cdf; sorted by u. */
    int npick = n <= BEAM_PICKS ? n : BEAM_PICKS;
    int pk[BEAM_PICKS];
    double pu[BEAM_PICKS], pw[BEAM_PICKS];
    for (int j = 0, i = 0; j < npick; j++) {
        int k = j;
        double inv_mp = 1.0;
        if (n > BEAM_PICKS) {
            /* x < total, so the hit it lands on has cdf[k - 1] <= x < cdf[k]: ck > 0. */
            double x = fmin((j + pcg32_uniform(rng)) / BEAM_PICKS * total, nextafter(total, 0.0));
            while (i < n - 1 && ms->cdf[i] <= x) i++;
            k = i;
            double ck = ms->cdf[k] - (k > 0 ? ms->cdf[k - 1] : 0.0);
            inv_mp = total / (ck * BEAM_PICKS);
        }
        const rd_beam_hit *h = &ms->hits[k];
        double u = h->ta + pcg32_uniform(rng) * (h->tb - h->ta);
        int at = j; /* insertion by u */
        while (at > 0 && pu[at - 1] > u) {
            pk[at] = pk[at - 1], pu[at] = pu[at - 1], pw[at] = pw[at - 1];
            at--;
        }
        pk[at] = k, pu[at] = u, pw[at] = inv_mp;
    }
    double o[3];
    pm_map_origin(map, o);
    vec3 sum = v3(0, 0, 0), half = v3(0, 0, 0);
    double T = 1.0, tp = t0;
    for (int j = 0; j < npick && T != 0.0; j++) {
        double u = pu[j];
        T *= rd_transmittance(s, region, r, tp, u, rng, c);
        T *= rd_tr_roulette(T, rng);
        tp = u;
        if (T == 0.0) break;
        const rd_beam_hit *h = &ms->hits[pk[j]];
        const pm_photon *p = &ph[h->idx];
        vec3 x = ray_at(r, u);
        const rd_medium *m = rd_scene_medium_at(s, region, x);
        /* No scattering where the medium is empty (the samples skip sigma_t = 0 alike): a ball
         * reaching into an empty voxel adds nothing there. */
        if (!m) continue;
        c->lookups++;
        const double sigma_x = rd_medium_sigma_t(m, x);
        if (!(sigma_x > 0.0)) continue;
        vec3 q = v3(o[0] + p->pos[0], o[1] + p->pos[1], o[2] + p->pos[2]);
        vec3 dq = v3_sub(q, x);
        if (s->geom) {
            double len = v3_len(dq);
            if (len > 0.0 && rd_geom_occluded(s->geom, (ray3){x, v3_scale(dq, 1.0 / len)}, 0.0, len, NULL)) continue;
        }
        double rk = st->beam_radius[h->idx];
        double cw = fmin(1.0, fmax(-1.0, p->dir[0] * w.x + p->dir[1] * w.y + p->dir[2] * w.z));
        double f = rd_hg_eval(m->g, cw) * (h->tb - h->ta) / (4.0 / 3.0 * M_PI * rk * rk * rk);
        f /= rd_march_support_share(s, region, m, x, rk);
        vec3 power = v3(p->power[0], p->power[1], p->power[2]);
        sum = v3_madd(sum, power, f * T * pw[j]);
        if (gap) half = v3_madd(half, power, half_ball_term(s, region, r, q, rk, h, u, t0, t1, m, sigma_x, cw, c) * T * pw[j]);
    }
    double scale = wgt * st->beam_weight;
    if (gap) *gap = v3_scale(v3_sub(sum, half), scale);
    return v3_scale(sum, scale);
}

