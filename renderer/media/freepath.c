/* freepath.c: trackers and transmittance estimators of the free-path engine (THEORY.md §2).
 *
 * Every unbiased tracker walks the same majorant iterator (rd_majorant_next): Woodcock tracking
 * is the walk with one global segment, super-voxel delta tracking the walk over the grid or
 * octree (seed 003 §3.3 SuperVoxelTraversal: draw tau* = -ln(1-u), accumulate the majorant's
 * optical depth segment by segment, solve inside the segment where it passes tau*). */
#include "media/rd_freepath.h"
#include "walk.h"

#include <string.h>

void rd_fp_params_default(rd_fp_params *p)
{
    p->tracker = RD_FP_AUTO;
    p->transmittance = RD_TR_AUTO;
    p->b = 1.0;
    p->m = 1.0;
    p->step = 0.0;
}

const char *rd_fp_tracker_name(rd_fp_kind k)
{
    static const char *const n[] = {"auto", "woodcock", "supervoxel", "weighted", "decomposition", "raymarch"};
    return (unsigned)k < 6 ? n[k] : "?";
}
const char *rd_tr_name(rd_tr_kind k)
{
    static const char *const n[] = {"auto", "ratio-global", "ratio", "residual", "exact", "raymarch"};
    return (unsigned)k < 6 ? n[k] : "?";
}

static double medium_density_cb(const void *ctx, vec3 x) { return rd_medium_density(ctx, x); }
static int medium_above_cb(const void *ctx, vec3 x, double scale, double thr)
{
    return rd_medium_sigma_above(ctx, x, scale, thr);
}

rd_fp_medium rd_fp_view(const rd_medium *m)
{
    /* Built per tracking call: every field named (the rest zero), no memset and no libm call;
     * this sits on the path of every free flight and shadow ray. */
    double smin = m->density_min * m->sigma_t_scale;
    return (rd_fp_medium){
        .density = medium_density_cb,
        .above = medium_above_cb,
        .ctx = m,
        .sigma_t_scale = m->sigma_t_scale,
        .sigma_global = m->sigma_maj,
        .sigma_global_min = smin < m->sigma_maj ? smin : m->sigma_maj,
        .maj = m->majorant,
        .grid = m->kind == RD_DENSITY_GRID ? &m->grid : NULL,
        .constant = m->kind == RD_DENSITY_CONSTANT ? m->constant : -1.0,
        .bmin = m->bmin,
        .bmax = m->bmax,
        .segments = NULL,
    };
}

static inline double sigma_at(const rd_fp_medium *fm, ray3 r, double t, rd_track_counters *c)
{
    c->lookups++;
    return fm->density(fm->ctx, ray_at(r, t)) * fm->sigma_t_scale;
}

/* thr < sigma_t at ray_at(r, t), decided by the medium's early-exit test when it has one (one
 * lookup either way). */
static inline int sigma_above(const rd_fp_medium *fm, ray3 r, double t, double thr, rd_track_counters *c)
{
    if (!fm->above) return thr < sigma_at(fm, r, t, c);
    c->lookups++;
    return fm->above(fm->ctx, ray_at(r, t), fm->sigma_t_scale, thr);
}

static double default_step(const rd_fp_params *p, const rd_fp_medium *fm)
{
    return p->step > 0.0 ? p->step : v3_len(v3_sub(fm->bmax, fm->bmin)) / 512.0;
}

/* The transmittance roulette: pbrt-v4's constants (VolPathIntegrator::SampleLd, threshold
 * 0.05, termination probability 0.75), not tuned here. */
#define TR_RR_T 0.05
#define TR_RR_Q 0.75

double rd_tr_roulette(double T, pcg32 *rng)
{
    if (!(fabs(T) < TR_RR_T) || T == 0.0) return 1.0;
    return pcg32_uniform(rng) < TR_RR_Q ? 0.0 : 1.0 / (1.0 - TR_RR_Q);
}

/* ---- The majorant walk ------------------------------------------------------------------ */

/* Seed 003 §3.3 SuperVoxelTraversal generalised (pbrt-v4 SampleT_maj): draw tau* = -ln(1-u),
 * accumulate the sampling majorant's optical depth segment by segment along the majorant
 * iterator, solve for t inside the segment where it passes tau* (closed form for a constant
 * bound, regula falsi on the cubic's integral for a tri-linear one), hand the point to the
 * caller, and draw the next tau* from there. The sampling density is mu(t) = b sigma_maj(t) -
 * sigma_c with sigma_c the segment's minorant for a residual walk (Novak et al. 2014), else 0.
 * static inline so that each tracker's callback below is inlined into its own copy. */
static inline int walk(const rd_fp_medium *fm, const rd_majorant *maj, ray3 r, double t0,
                       double t1, double b, int residual, pcg32 *rng, rd_track_counters *c,
                       rd_walk_fn fn, void *user, double *tau_c)
{
    rd_maj_iter it;
    rd_majorant_iter_begin(&it, maj, r, t0, t1, fm->sigma_global, fm->sigma_global_min);
    rd_maj_seg g;
    rd_walk_point pt;
    pt.seg = &g;
    double tau = -log(1.0 - pcg32_uniform(rng)); /* optical depth to the next tentative point */
    double tc = 0.0;
    int go_on = 1;
    while (go_on && rd_majorant_next(&it, &g)) {
        if (fm->segments) (*fm->segments)++;
        if (!(g.t1 > g.t0)) continue;
        if (b != 1.0) /* (multiplying by 1 changes nothing: skipped) */
            for (int d = 0; d < 4; d++) g.c[d] *= b;
        double sc = residual ? fmax(0.0, fmin(g.sigma_min, g.cubic ? INFINITY : g.c[0])) : 0.0;
        g.c[0] -= sc;
        pt.sigma_c = sc;
        double s0 = 0.0;
        for (;;) {
            double rest = rd_seg_tau(&g, s0, 1.0);
            if (!(rest > tau)) { tau -= rest; break; } /* passes this segment: next one */
            double s = rd_seg_solve(&g, s0, tau);
            pt.t = g.t0 + s * (g.t1 - g.t0);
            pt.mu = rd_seg_sigma(&g, s);
            pt.tau_c = tc + sc * (pt.t - g.t0);
            c->collisions++;
            if (!fn(user, &pt)) {
                tc += sc * (pt.t - g.t0);
                go_on = 0;
                break;
            }
            s0 = s;
            tau = -log(1.0 - pcg32_uniform(rng));
        }
        if (go_on) tc += sc * (g.t1 - g.t0);
    }
    if (tau_c) *tau_c = tc;
    return go_on;
}

int rd_fp_walk(const rd_fp_medium *fm, const rd_majorant *maj, ray3 r, double t0, double t1,
               double b, int residual, pcg32 *rng, rd_track_counters *c, rd_walk_fn fn,
               void *user, double *tau_c)
{
    return walk(fm, maj, r, t0, t1, b, residual, rng, c, fn, user, tau_c);
}

/* What the trackers' callbacks share: the medium, the ray, the counters, the event so far. */
typedef struct {
    const rd_fp_params *p;
    const rd_fp_medium *fm;
    ray3 r;
    pcg32 *rng;
    rd_track_counters *c;
    rd_fp_event ev;
    double T;     /* ratio tracking */
} track_state;

/* Analog delta tracking (seed 003 §3.1, seed 000 WT): real with probability sigma_t / sigma_maj. */
static int on_analog(void *user, const rd_walk_point *pt)
{
    track_state *ts = user;
    /* Only the comparison is needed, not sigma_t itself: noise media answer it from the first
     * octaves when those decide it (rd_medium_sigma_above), with the same answer. */
    if (sigma_above(ts->fm, ts->r, pt->t, pcg32_uniform(ts->rng) * pt->mu, ts->c)) {
        ts->ev.hit = 1;
        ts->ev.t = pt->t;
        return 0;
    }
    return 1;
}

/* Weighted delta tracking (seed 002 Alg. 2): majorant mu = b sigma_maj may be non-bounding
 * (sigma_n = mu - sigma_t < 0); real with P_r = |sigma_t| / (|sigma_t| + |sigma_n|), null
 * otherwise, weight *= sigma_x / (mu P_x). Alg. 2 splits "real" into absorption and scattering;
 * here the integrator applies the albedo as a weight, so they are merged. */
static int on_weighted(void *user, const rd_walk_point *pt)
{
    track_state *ts = user;
    double st = sigma_at(ts->fm, ts->r, pt->t, ts->c), sn = pt->mu - st;
    double Pr = fabs(st) / (fabs(st) + fabs(sn));
    if (pcg32_uniform(ts->rng) < Pr) {
        ts->ev.hit = 1;
        ts->ev.t = pt->t;
        ts->ev.weight *= st / (pt->mu * Pr);
        return 0;
    }
    ts->ev.weight *= sn / (pt->mu * (1.0 - Pr));
    return 1;
}

/* Weighted decomposition tracking (seed 002 Alg. 3): control mu_c = m x the segment's minorant; a
 * control collision with P_c = mu_c / mu needs no density lookup; otherwise residual
 * (sigma_t - mu_c) or null (mu - sigma_t) in proportion to their magnitudes, weighted.
 * P_c = mu_c / mu as in Alg. 3 while mu_c <= 0.95 mu. Residual + null always sum to mu - mu_c
 * (known before the lookup); when the control is non-bounding (mu_c > mu) or nearly so,
 * P_c = mu_c / (mu_c + D) with D = max(|mu - mu_c|, 0.05 mu) keeps a positive probability for
 * the residual/null branch, which is needed for unbiasedness unless the cell is exactly
 * homogeneous (bounds equal, m = b = 1: then residual = null = 0 and P_c = 1). */
static int on_decomposition(void *user, const rd_walk_point *pt)
{
    track_state *ts = user;
    const rd_maj_seg *g = pt->seg;
    double mu = pt->mu, bfac = ts->p->b;
    double mu_c = ts->p->m * g->sigma_min, Pc;
    int homogeneous = !g->cubic && ts->p->m == 1.0 && bfac == 1.0 && g->sigma_min >= g->c[0];
    if (mu_c <= 0.0) Pc = 0.0;
    else if (homogeneous) Pc = 1.0;
    else Pc = mu_c / (mu_c + fmax(fabs(mu - mu_c), 0.05 * mu));
    if (pcg32_uniform(ts->rng) < Pc) { /* control collision: analytic, no lookup */
        ts->ev.hit = 1;
        ts->ev.t = pt->t;
        ts->ev.weight *= mu_c / (mu * Pc);
        return 0;
    }
    double st = sigma_at(ts->fm, ts->r, pt->t, ts->c), res = st - mu_c, nul = mu - st;
    double a = fabs(res), bb = fabs(nul);
    if (a + bb == 0.0) { /* both coefficients vanish: this branch carries no weight */
        ts->ev.hit = 1;
        ts->ev.t = pt->t;
        ts->ev.weight = 0.0;
        return 0;
    }
    double Pr = a / (a + bb);
    if (pcg32_uniform(ts->rng) < Pr) {
        ts->ev.hit = 1;
        ts->ev.t = pt->t;
        ts->ev.weight *= res / (mu * (1.0 - Pc) * Pr);
        return 0;
    }
    ts->ev.weight *= nul / (mu * (1.0 - Pc) * (1.0 - Pr));
    return 1;
}

/* Biased fixed-step ray marching: one random offset per ray, midpoint-like Riemann sum of tau,
 * the collision placed by linear interpolation inside the step where tau passes tau*. */
static rd_fp_event march(const rd_fp_params *p, const rd_fp_medium *fm, ray3 r, double t0,
                         double t1, pcg32 *rng, rd_track_counters *c)
{
    rd_fp_event ev = {0, t1, 1.0};
    double h = default_step(p, fm), target = -log(1.0 - pcg32_uniform(rng));
    double u = pcg32_uniform(rng), acc = 0.0;
    /* An integer step count: a step below the float spacing of t could never advance a. */
    long n = (long)ceil((t1 - t0) / h);
    for (long i = 0; i < n; i++) {
        double a = t0 + i * h;
        double b = fmin(a + h, t1), x = fmin(a + u * h, b);
        double st = sigma_at(fm, r, x, c);
        double d = st * (b - a);
        if (acc + d >= target && st > 0.0) {
            ev.hit = 1;
            ev.t = a + (target - acc) / st;
            return ev;
        }
        acc += d;
    }
    return ev;
}

static rd_fp_event track(const rd_fp_params *p, const rd_fp_medium *fm, const rd_majorant *maj,
                         rd_walk_fn on_point, double b, ray3 r, double t0, double t1, pcg32 *rng,
                         rd_track_counters *c)
{
    track_state ts = {p, fm, r, rng, c, {0, t1, 1.0}, 1.0};
    walk(fm, maj, r, t0, t1, b, 0, rng, c, on_point, &ts, NULL);
    return ts.ev;
}

rd_fp_event rd_fp_sample(const rd_fp_params *p, const rd_fp_medium *fm, ray3 r, double t0,
                         double t1, pcg32 *rng, rd_track_counters *c)
{
    switch (p->tracker) {
    case RD_FP_WOODCOCK: return track(p, fm, NULL, on_analog, 1.0, r, t0, t1, rng, c);
    case RD_FP_WEIGHTED: return track(p, fm, fm->maj, on_weighted, p->b, r, t0, t1, rng, c);
    case RD_FP_DECOMPOSITION: return track(p, fm, fm->maj, on_decomposition, p->b, r, t0, t1, rng, c);
    case RD_FP_RAYMARCH: return march(p, fm, r, t0, t1, rng, c);
    case RD_FP_AUTO:
    case RD_FP_SUPERVOXEL:
    default: return track(p, fm, fm->maj, on_analog, 1.0, r, t0, t1, rng, c);
    }
}

/* Ratio tracking (residual when `residual`): T = exp(-int sigma_c) prod (1 - (sigma_t(x_i) -
 * sigma_c) / mu_r(x_i)) over tentative collisions drawn with the residual majorant
 * mu_r = sigma_maj - sigma_c; sigma_c = the segment's minorant (Novak et al. 2014, seed 003
 * §3.4's decomposition of eq. 13 estimated by tracking instead of quadrature). With sigma_c a
 * true minorant every factor lies in [0, 1]. */
static int on_ratio(void *user, const rd_walk_point *pt)
{
    track_state *ts = user;
    ts->T *= 1.0 - (sigma_at(ts->fm, ts->r, pt->t, ts->c) - pt->sigma_c) / pt->mu;
    /* The roulette (rd_tr_roulette) on the estimate so far, ratio product x exp(-control
     * depth): a ray deep in a dense medium stops early, the expectation unchanged. */
    ts->T *= rd_tr_roulette(pt->tau_c > 0.0 ? ts->T * exp(-pt->tau_c) : ts->T, ts->rng);
    return ts->T != 0.0;
}

static double ratio(const rd_fp_medium *fm, const rd_majorant *maj, int residual, ray3 r,
                    double t0, double t1, pcg32 *rng, rd_track_counters *c)
{
    track_state ts = {NULL, fm, r, rng, c, {0, t1, 1.0}, 1.0};
    double tau_c = 0.0;
    walk(fm, maj, r, t0, t1, 1.0, residual, rng, c, on_ratio, &ts, &tau_c);
    return ts.T == 0.0 ? 0.0 : ts.T * exp(-tau_c);
}

double rd_grid_optical_depth(const rd_grid *gr, ray3 r, double t0, double t1, rd_track_counters *c)
{
    /* Interpolation cells: in v = u - 0.5 (u = A x + b) the density is trilinear on every unit
     * cell [i, i+1]^3 with voxel values at the corners (zero outside the grid), i = -1..n-1.
     * Along the ray v(t) = v0 + t dv; in each cell the density is a cubic in t (seed 003
     * PolyCoeff), integrated exactly. The cells are walked by walk/'s DDA over the lattice box
     * [-1, n]^3 with n + 1 unit cells per axis (its planes are the integers exactly). */
    double v0[3], dv[3];
    const int n[3] = {gr->nx, gr->ny, gr->nz};
    for (int a = 0; a < 3; a++) {
        v0[a] = gr->w2g[a][0] * r.o.x + gr->w2g[a][1] * r.o.y + gr->w2g[a][2] * r.o.z + gr->w2g[a][3] - 0.5;
        dv[a] = gr->w2g[a][0] * r.d.x + gr->w2g[a][1] * r.d.y + gr->w2g[a][2] * r.d.z;
    }
    const double lo[3] = {-1.0, -1.0, -1.0}, hi[3] = {n[0], n[1], n[2]};
    const int res[3] = {n[0] + 1, n[1] + 1, n[2] + 1};
    double ta, tb;
    int enter;
    if (!wk_box_clip(lo, hi, v0, dv, t0, t1, &ta, &tb, &enter)) return 0.0;
    wk_dda w;
    wk_dda_seg sg;
    wk_dda_begin(&w, lo, hi, res, v0, dv, ta, tb, enter);
    double tau = 0.0;
    while (wk_dda_next(&w, &sg)) {
        int idx[3] = {sg.ijk[0] - 1, sg.ijk[1] - 1, sg.ijk[2] - 1}; /* lattice cell [i, i+1] */
        double val[8];
        int any = 0;
        for (int q = 0; q < 8; q++) {
            int i = idx[0] + (q & 1), j = idx[1] + ((q >> 1) & 1), k = idx[2] + ((q >> 2) & 1);
            val[q] = rd_grid_voxel(gr, i, j, k); /* dense or sparse; 0 outside */
            any |= val[q] != 0.0;
        }
        c->lookups++;
        if (!any) continue;
        double E[3], O[3], cc[4];
        for (int a = 0; a < 3; a++) {
            E[a] = v0[a] + sg.ta * dv[a] - idx[a];
            O[a] = v0[a] + sg.tb * dv[a] - idx[a];
        }
        rd_trilinear_cubic(val, E, O, cc);
        tau += (sg.tb - sg.ta) * (cc[0] + cc[1] / 2 + cc[2] / 3 + cc[3] / 4);
    }
    return tau;
}

double rd_fp_transmittance(const rd_fp_params *p, const rd_fp_medium *fm, ray3 r, double t0,
                           double t1, pcg32 *rng, rd_track_counters *c)
{
    switch (p->transmittance) {
    case RD_TR_RATIO_GLOBAL: return ratio(fm, NULL, 0, r, t0, t1, rng, c);
    case RD_TR_RATIO: return ratio(fm, fm->maj, 0, r, t0, t1, rng, c);
    case RD_TR_EXACT:
        if (fm->constant >= 0.0) return exp(-fm->constant * fm->sigma_t_scale * (t1 - t0));
        if (fm->grid) return exp(-fm->sigma_t_scale * rd_grid_optical_depth(fm->grid, r, t0, t1, c));
        return ratio(fm, fm->maj, 1, r, t0, t1, rng, c); /* no closed form: residual ratio */
    case RD_TR_RAYMARCH: {
        double h = default_step(p, fm), u = pcg32_uniform(rng), tau = 0.0;
        long n = (long)ceil((t1 - t0) / h);
        for (long i = 0; i < n; i++) {
            double a = t0 + i * h;
            double b = fmin(a + h, t1);
            tau += sigma_at(fm, r, fmin(a + u * h, b), c) * (b - a);
        }
        return exp(-tau);
    }
    case RD_TR_AUTO:
        /* Chosen per density kind by render efficiency, 1 / (pixel variance x time), measured
         * by bench_render_tr (docs/free-path.md): the closed form for constant media, ratio
         * tracking with the global majorant for grids (exact costs 2.4x the render time for
         * the same variance there), residual ratio tracking for noise (1.4x ratio-global). */
        if (fm->constant >= 0.0) return exp(-fm->constant * fm->sigma_t_scale * (t1 - t0));
        if (fm->grid) return ratio(fm, NULL, 0, r, t0, t1, rng, c);
        return ratio(fm, fm->maj, 1, r, t0, t1, rng, c);
    case RD_TR_RESIDUAL:
    default: return ratio(fm, fm->maj, 1, r, t0, t1, rng, c);
    }
}
