/* guided_unbiased.c: `guided-unbiased`, the unbiased path tracer of `delta` (transport/path.c)
 * with its free flights guided by the photon-map SH guide (issue 10; docs/guided-unbiased.md).
 *
 * A flight from the path vertex o along d over [0, t_light] meets the media in [t0, t1] (the
 * media bounds, clipped before the nearest sphere light). The RTE along it (THEORY.md §1;
 * no emission in the media, T(0,t0) = 1 since nothing lies before t0):
 *
 *     L(o, -d) = integral_t0^t1 T(t0,t) sigma_s(t) L_s(x(t), -d) dt  +  T(t0,t1) L_behind      (1)
 *                \___________ scattered part S ______________/        \__ passed part B __/
 *
 * A flight is sampled by a one-sample mixture of two strategies, each of which either scatters
 * (at a distance t from its pdf) or passes through:
 *   guide     (weight 1 - w): scatters with probability P_g = S~ / (S~ + B~), the guide's own
 *             estimate of the scattered part S~ = I_ray (the integral of the histogram
 *             h(t) = T~(t0,t) f_j, f_j = sigma_s L_s toward -d of the cell: seed 001 eq. 16,
 *             integrators/guide_pdf.c) against the passed part B~ = T~(t0,t1) L_behind, held in
 *             [floor, 1 - floor] (guide.pass_floor); t from the defensive mixture
 *                 p_g(t) = (1 - alpha) h(t) / I_ray + alpha / (t1 - t0)    (guide.distance_alpha);
 *   majorant  (weight w = guide.majorant_weight): delta tracking's first tentative collision,
 *             P_m = 1 - T_maj(t0,t1), p_m(t) = sigma_maj(t) T_maj(t0,t) / P_m (the majorant
 *             walk of the free-path engine, media/freepath.c). sigma_maj >= sigma_t, so
 *             however wrong the guide, the joint density below stays >= w sigma_maj T_maj.
 * L_behind is known exactly (the light or environment beyond, MIS-weighted as the path loop
 * will weight it: rd_flight_behind); when it is 0 both strategies always scatter (passing can
 * only add 0). The flight therefore passes with probability, and scatters at t with density,
 *     P_pass = (1 - w)(1 - P_g) + w (1 - P_m)                                                (2)
 *     q(t)   = (1 - w) P_g p_g(t) + w P_m p_m(t)                                             (3)
 * and weights each outcome by the integrand of (1) over its probability (density):
 *     scatter at t:  T(t0,t) sigma_s(t) / q(t)     pass through:  T(t0,t1) / P_pass          (4)
 * The vertex weight is followed by the path loop's estimate of L_s(x(t), -d) (NEE plus the
 * phase-sampled continuation), the pass weight by L_behind. The expectation is
 *     integral q(t) T sigma_s E[L_s] / q(t) dt + P_pass T L_b / P_pass = (1)
 * for any guide: q > 0 wherever sigma_s can be (alpha > 0; and P_g >= floor), and P_pass > 0
 * wherever L_behind > 0 (floor), given unbiased T (the free-path engine's ratio / residual
 * ratio tracking or exact optical depth, settings.transmittance: rd_transmittance) and an
 * unbiased L_s estimate independent of t's choice. Delta tracking is q = sigma_t T, P_pass = T:
 * its weights reduce to the albedo and 1.
 *
 * A ray along which the guide sees no light at all (I_ray = 0) takes delta tracking's flight.
 *
 * Unlike delta tracking the vertex carries sigma_s(t) and T(t0,t) explicitly (delta's pdf
 * cancels both, leaving the albedo). NEE at the vertex estimates L_s = integral p L_direct,
 * which holds no sigma_s, so the vertex weight multiplies it as it is (rd_path_radiance). */
#include "integrators/rd_guide_pdf.h"
#include "scene/rd_geom.h"
#include "transport/rd_path.h"
#include "integrators/rd_method.h"
#include "integrators/rd_probes.h"
#include "integrators/rd_select.h"
#include "sh.h"

#include <stdlib.h>

/* A guide cell's incident-light lobe for one medium (cell_lobe): a vMF lobe of directions. */
typedef struct {
    vec3 mu;      /* its mean direction (unit) */
    double kappa; /* its concentration; 0: the cell has none */
} gu_lobe;
/* Most lobe table entries (cells x media) gu_prepare builds: 32 MiB */
#define GU_LOBES_MAX ((size_t)1 << 20)

typedef struct {
    int cap_g;   /* guide pdf segments a flight can need (guide cells crossed + 2 fillers) */
    int cap_m;   /* majorant pdf segments (majorant cells crossed in every medium + gaps) */
    rd_select sel; /* settings.select: the tiles the guided paths render (integrators/select.c) */
    sh_basis eval; /* the guide's first guide.eval_bands bands: what its flights and roulette
                      read (sh_eval_guide_bands) */
    /* Copies of ctx->guide and ctx->guide_indirect keeping only the bands read (eval_bands,
     * and band 1 for the direction lobe: sh_guide_truncate), NULL where nothing is cut. The
     * same floats in 48 bytes a cell at two bands: an 8-band guide's record puts them in
     * three blocks 256 bytes apart, and those cache misses were a fifth of the method's time
     * on hard-dense-block (perf; docs/guided-unbiased.md "A copy of the guide with only the
     * bands it reads"). */
    sh_guide *fast, *fast_indirect;
    rd_probes probes; /* guide.probes: more camera chains for the light at the camera chain's
                         end (integrators/probes.c) */
    /* With guide.roulette: each pixel's estimate I~ for the weight window (pixel_estimate), -1
     * until the first of its samples that reaches the guided path needs it; width x height,
     * a pixel's entry written only by the thread rendering that pixel. */
    double *I_pix;
    /* With guide.directions: the incident-light lobe of every cell of the guide the lobe is
     * read from (the indirect one when there is one) for every medium, [medium x lobe_cells +
     * cell] (cell_lobe; kappa 0: none), and each medium's phase lobe concentration kappa_g;
     * NULL where the table would pass GU_LOBES_MAX entries (the vertex finds its cell's). */
    gu_lobe *lobes;
    size_t lobe_cells;
    double *kappa_g;
} gu_state;

/* The guide the method reads (its truncated copy when there is one), and the indirect one. */
static const sh_guide *gu_guide(const rd_render_ctx *ctx)
{
    const gu_state *st = ctx->state;
    return st && st->fast ? st->fast : ctx->guide;
}

static const sh_guide *gu_guide_indirect(const rd_render_ctx *ctx)
{
    const gu_state *st = ctx->state;
    return st && st->fast_indirect ? st->fast_indirect : ctx->guide_indirect;
}

/* One thread's storage (scratch), laid out by scratch_layout. */
typedef struct {
    rd_gpdf_seg *seg_g, *seg_m;
    double *tb, *f, *sig;   /* cap_m + 1 entries each: the majorant histogram's arrays */
} gu_scratch;

static size_t scratch_layout(const gu_state *st, gu_scratch *sc, void *base)
{
    size_t off = 0;
    char *b = base;
#define TAKE(field, type, n)                                                                   \
    do {                                                                                       \
        if (b) sc->field = (type *)(b + off);                                                   \
        off += ((size_t)(n) * sizeof(type) + 15) / 16 * 16;                                     \
    } while (0)
    TAKE(seg_g, rd_gpdf_seg, st->cap_g);
    TAKE(seg_m, rd_gpdf_seg, st->cap_m + 2);
    TAKE(tb, double, st->cap_m + 1);
    TAKE(f, double, st->cap_m + 1);
    TAKE(sig, double, st->cap_m + 1);
#undef TAKE
    return off;
}

/* The distribution of one flight over the media interval [t0, t1] (header, eq. 2-3). */
typedef struct {
    double t0, t1;
    double w;          /* weight of the majorant strategy */
    double P_g, P_m;   /* scatter probability of each strategy */
    double B;          /* the guide's passed part B~ = T~(t0,t1) L_behind */
    double tau_m;      /* majorant optical depth over [t0, t1] */
    rd_guide_pdf g, m; /* distance pdf of each strategy */
} gu_dist;

static double mean3(vec3 v) { return (v.x + v.y + v.z) / 3.0; }

/* Append piece [a, b) of height f and extinction sig to the arrays, closing a gap before it
 * (between two media) with an empty piece. Returns 0 when the storage (cap pieces) is full. */
static int push_piece(const gu_scratch *sc, int cap, int *n, double a, double b, double f, double sig)
{
    if (*n == 0) {
        sc->tb[0] = a;
    } else if (a > sc->tb[*n]) {
        if (*n >= cap) return 0;
        sc->f[*n] = sc->sig[*n] = 0.0;
        sc->tb[++*n] = a;
    }
    if (!(b > sc->tb[*n])) return 1; /* empty, or swallowed by rounding */
    if (*n >= cap) return 0;
    sc->f[*n] = f;
    sc->sig[*n] = sig;
    sc->tb[++*n] = b;
    return 1;
}

/* The majorant strategy's pdf: the histogram of the majorant along r over [t0, t1], h(t) =
 * sigma_maj(t) T_maj(t0,t), piece by piece of the majorant walk (a constant bound per piece;
 * a tri-linear one by its mean over the piece). sigma_maj >= sigma_t, so p > 0 wherever the
 * medium can be. The storage running out gives the uniform pdf (still p > 0 everywhere). */
static void build_majorant_pdf(const gu_scratch *sc, int cap, const rd_scene *s, int region,
                               ray3 r, double t0, double t1, rd_guide_pdf *pdf)
{
    rd_interval iv[RD_MAX_INTERVALS];
    int n_iv = rd_media_intervals(s, region, r, t0, t1, iv), n = 0, ok = 1;
    for (int i = 0; i < n_iv && ok; i++) {
        const rd_medium *m = iv[i].m;
        double smin = fmin(m->density_min * m->sigma_t_scale, m->sigma_maj);
        rd_maj_iter it;
        rd_majorant_iter_begin(&it, m->majorant, r, iv[i].t0, iv[i].t1, m->sigma_maj, smin);
        rd_maj_seg g;
        while (ok && rd_majorant_next(&it, &g)) {
            if (!(g.t1 > g.t0)) continue;
            double sig = g.cubic ? rd_seg_tau(&g, 0.0, 1.0) / (g.t1 - g.t0) : g.c[0];
            ok = push_piece(sc, cap, &n, g.t0, g.t1, fmax(0.0, sig), fmax(0.0, sig));
        }
    }
    rd_guide_pdf_init(pdf, sc->seg_m, cap + 2);
    if (!ok || n == 0 || sc->tb[0] < t0 || sc->tb[n] > t1 ||
        rd_guide_pdf_build(pdf, n, sc->tb, sc->f, sc->sig, t0, t1, 0.0, NULL, 0) != RD_OK)
        rd_guide_pdf_build(pdf, 0, NULL, NULL, NULL, t0, t1, 1.0, NULL, 0);
}

/* The guide strategy's pdf: the guide's histogram toward -d with the defensive uniform part
 * (guide.distance_alpha); the uniform part alone if the ray needs more segments than the
 * storage holds. */
static void build_guide_pdf(const rd_render_ctx *ctx, const gu_scratch *sc, ray3 r, double t0,
                            double t1, rd_guide_pdf *pdf)
{
    const gu_state *st = ctx->state;
    const double o[3] = {r.o.x, r.o.y, r.o.z}, d[3] = {r.d.x, r.d.y, r.d.z};
    rd_guide_pdf_init(pdf, sc->seg_g, st->cap_g);
    if (rd_guide_pdf_build_guide_bands(pdf, gu_guide(ctx), &st->eval, o, d, t0, t1,
                                       ctx->scene->guide.distance_alpha, NULL, 0) != RD_OK)
        rd_guide_pdf_build(pdf, 0, NULL, NULL, NULL, t0, t1, 1.0, NULL, 0);
}

/* Both strategies of a flight over [t0, t1] whose light behind has channel mean L_behind.
 *   guide:    P_g = S~ / (S~ + B~), S~ = I_ray, B~ = T~(t0,t1) L_behind, held in
 *             [floor, 1 - floor] (guide.pass_floor);
 *   majorant: P_m = 1 - T_maj(t0,t1), the chance that delta tracking's first tentative
 *             collision falls inside [t0, t1] (exact: the histogram's T~ is T_maj).
 * Both are 1 when L_behind = 0 exactly: passing can only add 0 then. L_behind < 0 means a
 * surface ends the flight (behind_mean): the guide strategy then passes half the time. */
/* The majorant strategy's pdf, first: its optical depth decides whether the flight is guided
 * at all (guide.distance_tau_max), before the costlier guide walk. */
static void flight_majorant(const rd_render_ctx *ctx, const gu_scratch *sc, int region, ray3 r,
                            double t0, double t1, gu_dist *D)
{
    const gu_state *st = ctx->state;
    D->t0 = t0;
    D->t1 = t1;
    D->w = ctx->scene->guide.majorant_weight;
    build_majorant_pdf(sc, st->cap_m, ctx->scene, region, r, t0, t1, &D->m);
    D->tau_m = rd_guide_pdf_tau(&D->m);
}

/* The rest, after flight_majorant. */
static void flight_dist(const rd_render_ctx *ctx, const gu_scratch *sc, ray3 r, double t0,
                        double t1, double L_behind, gu_dist *D)
{
    const rd_scene *s = ctx->scene;
    build_guide_pdf(ctx, sc, r, t0, t1, &D->g);
    D->B = 0.0;
    if (L_behind < 0.0) {
        /* A surface ends the flight: what lies behind it is the rest of the path, unknown
         * here. Any pass probability in (0, 1) keeps (4) unbiased; the guide strategy
         * passes half the time. */
        D->P_g = 0.5;
        D->P_m = -expm1(-rd_guide_pdf_tau(&D->m));
        return;
    }
    if (!(L_behind > 0.0)) {
        D->P_g = D->P_m = 1.0;
        return;
    }
    double S = D->g.I, B = exp(-rd_guide_pdf_tau(&D->g)) * L_behind, fl = s->guide.pass_floor;
    D->B = B;
    double P = (S + B > 0.0 && isfinite(S + B)) ? S / (S + B) : 0.5;
    D->P_g = fmin(1.0 - fl, fmax(fl, P));
    D->P_m = -expm1(-rd_guide_pdf_tau(&D->m));
}

/* Density of scattering at t (eq. 3) and probability of passing (eq. 2) of the mixture. */
static double dist_scatter_pdf(const gu_dist *D, double t)
{
    return (1.0 - D->w) * D->P_g * rd_guide_pdf_eval(&D->g, t) +
           D->w * D->P_m * rd_guide_pdf_eval(&D->m, t);
}
static double dist_pass(const gu_dist *D)
{
    return (1.0 - D->w) * (1.0 - D->P_g) + D->w * (1.0 - D->P_m);
}

/* The channel mean of what a pass-through receives (rd_flight_behind), or -1 when the flight
 * ends at a surface (the path goes on from there: unknown, and not 0). */
static double behind_mean(const rd_scene *s, const rd_flight_in *in)
{
    return in->hit_shape >= 0 ? -1.0 : mean3(rd_flight_behind(s, in));
}

/* The media interval of a flight, before the nearest light or surface; 0 when it meets no
 * medium. */
static int flight_interval(const rd_scene *s, const rd_flight_in *in, double *t0, double *t1)
{
    return s->n_media > 0 && rd_box_intersect(s->bmin, s->bmax, in->r, 0.0, in->t_light, t0, t1) &&
           *t1 > *t0;
}

/* What the flight sampler carries per path: the render context and this thread's scratch;
 * P_pass of the last flight for rd_gu_flight (-1 after a delta-tracking fallback: no guide,
 * no medium on the way, or no guide light along the ray). */
typedef struct {
    const rd_render_ctx *ctx;
    void *scratch;
    double P_pass;
    double I_cam;   /* the pixel estimate of the roulette's weight window: the guide's S~ + B~
                     * along four fixed rays through the pixel (pixel_estimate), or without
                     * I_pix along the camera sample's own first flight; 0: none (delta's
                     * roulette) */
    double *I_pix;  /* this pixel's entry of gu_state.I_pix; NULL: none (rd_gu_vertex's) */
    uint64_t segments; /* distance-pdf segments built (the selection's counted cost, select.c) */
    uint64_t vertices; /* vertices whose policy read the guide (likewise) */
    int guided;        /* the last flight was guided: D below is its mixture (its pdfs' segments
                        * in the scratch, until the next flight) */
    gu_dist D;
} gu_user;

/* Whether this flight's distance is the guide's (else delta tracking's). */
static int flight_guided(const rd_scene *s, const rd_render_ctx *ctx, const rd_flight_in *in)
{
    return ctx->guide && s->guide.distances && (in->depth == 0 || s->guide.secondary);
}

/* The pixel estimate I~ of the roulette's weight window (Vorba and Krivanek 2016, §4: the
 * pixel's value, estimated before its samples), for the pixel whose entry u->I_pix is: the mean
 * over four fixed points of the pixel (a 2x2 pattern, so that a pixel on a medium's silhouette
 * is not read by one ray) of the guide's estimate along the camera ray through each
 * (ray_estimate); 0 where none crosses a medium. A fixed function of the pixel, so the
 * roulette and splitting it steers keep every sample unbiased and the image is the same
 * however the passes, threads or ranks split the samples. It is found once a pixel, at its
 * first sample on the guided path (the selection's pilot's, for a pilot pixel), instead of
 * walking the guide along every camera ray that delta tracking's flight takes anyway (a thick
 * flight, guide.distance_tau_max): on hard-dense-block, where every camera flight is thick,
 * that walk was 9% of the method's time (docs/guided-unbiased.md, "The pixel estimate"). */
#define GU_PIXEL_CROSSINGS 64 /* interfaces followed (transport/path.c allows 4096) */
static double ray_estimate(const rd_render_ctx *ctx, const gu_scratch *sc, ray3 r, uint64_t *segments)
{
    /* The camera flight as the path loop starts it (transport/path.c, trace), and the flights
     * after each interface it crosses (a surface that only changes the medium: still the
     * camera flight, depth 0): I~ = sum_k T~_<k (S~_k + B~_k), T~_<k the guide's
     * transmittance of the flights before k; B~ only after the last (a flight that ends at a
     * surface has none: flight_dist). */
    const rd_scene *s = ctx->scene;
    int region = rd_scene_camera_region(s, r);
    rd_hit hit, prev;
    const rd_hit *from = NULL;
    double I = 0.0, T = 1.0;
    for (int k = 0; k <= GU_PIXEL_CROSSINGS; k++) {
        rd_flight_in in = {.r = r, .depth = 0, .region = region, .camera_chain = 1, .hit_light = -1,
                           .hit_shape = -1, .t_light = INFINITY};
        if (rd_scene_intersect(s, r, INFINITY, from, &hit)) {
            in.t_light = hit.t;
            in.hit_light = hit.light;
            in.hit_shape = hit.shape;
        }
        double t0, t1;
        if (flight_interval(s, &in, &t0, &t1)) {
            gu_dist D;
            flight_majorant(ctx, sc, in.region, r, t0, t1, &D);
            flight_dist(ctx, sc, r, t0, t1, behind_mean(s, &in), &D);
            *segments += (uint64_t)D.m.n + (uint64_t)D.g.n;
            I += T * (D.g.I + D.B);
            T *= exp(-rd_guide_pdf_tau(&D.g));
        }
        if (in.hit_shape < 0 || s->shapes[in.hit_shape].material.kind != RD_MAT_INTERFACE) break;
        prev = hit;
        from = &prev;
        region = prev.medium_to;
        r = rd_hit_spawn(&prev, r.d);
    }
    return I > 0.0 && isfinite(I) ? I : 0.0;
}

static double pixel_estimate(const rd_render_ctx *ctx, gu_user *u)
{
    const rd_scene *s = ctx->scene;
    const gu_state *st = ctx->state;
    size_t pix = (size_t)(u->I_pix - st->I_pix), w = (size_t)s->camera.width;
    gu_scratch sc;
    scratch_layout(st, &sc, u->scratch);
    double I = 0.0;
    for (int j = 0; j < 4; j++) {
        double px = (double)(pix % w) + 0.25 + 0.5 * (j & 1), py = (double)(pix / w) + 0.25 + 0.5 * (j >> 1);
        I += 0.25 * ray_estimate(ctx, &sc, rd_camera_ray(&s->camera, px, py), &u->segments);
    }
    return I;
}

static rd_flight guided_flight(const rd_flight_sampler *fs, const rd_scene *s,
                               const rd_flight_in *in, pcg32 *rng, rd_track_counters *c)
{
    gu_user *u = fs->user;
    const rd_render_ctx *ctx = u->ctx;
    ray3 r = in->r;
    double t0, t1;
    u->P_pass = -1.0;
    u->guided = 0;
    /* No guide, distances off, a secondary flight with guide.secondary off, or no medium on
     * the way: delta tracking's flight (it passes with weight 1 when the ray misses every
     * medium). Which sampler a flight uses depends on the flight alone: each stays unbiased.
     * The roulette's I~ is the pixel's (pixel_estimate); without a pixel (rd_gu_flight) the
     * camera flight walks the guide for it. */
    int guided = flight_guided(s, ctx, in);
    int want_I = ctx->guide && s->guide.roulette && in->depth == 0;
    if (want_I && u->I_pix) { /* the pixel's estimate: no histogram for it on this flight */
        if (*u->I_pix < 0.0) *u->I_pix = pixel_estimate(ctx, u);
        u->I_cam = *u->I_pix;
        want_I = 0;
    }
    if (!(guided || want_I) || !flight_interval(s, in, &t0, &t1))
        return rd_flight_delta(s, in, rng, c);
    gu_scratch sc;
    scratch_layout(ctx->state, &sc, u->scratch);
    gu_dist D;
    flight_majorant(ctx, &sc, in->region, r, t0, t1, &D);
    u->segments += (uint64_t)D.m.n;
    /* An optically thick flight (majorant depth above guide.distance_tau_max) is delta
     * tracking's: there T sigma_t, which delta tracking samples exactly, is most of the
     * integrand's shape, and the guide's cell-mean T~ and sigma can only add weight noise
     * (docs/guided-unbiased.md). Decided by the flight alone: unbiased either way. */
    if (D.tau_m > s->guide.distance_tau_max) guided = 0;
    if (!(guided || want_I)) return rd_flight_delta(s, in, rng, c);
    flight_dist(ctx, &sc, r, t0, t1, behind_mean(s, in), &D);
    u->segments += (uint64_t)D.g.n;
    if (in->depth == 0 && !u->I_pix) u->I_cam = D.g.I + D.B;
    /* A guide with no light along this ray (an empty or wrong guide, or a dark region) knows
     * nothing to guide by: delta tracking's flight. The choice depends on the ray alone, so
     * each flight's estimate stays unbiased. Without this the guide strategy would pass at
     * once, and its scattered paths carry weights up to 1/w per vertex, compounding with
     * depth (heavy tails: docs/guided-unbiased.md). */
    if (!guided || !(D.g.I > 0.0)) return rd_flight_delta(s, in, rng, c);
    double P_pass = dist_pass(&D);
    u->P_pass = P_pass;
    u->guided = 1;
    u->D = D;
    rd_flight f = {.kind = RD_FLIGHT_END, .t = t1, .medium = NULL, .weight = v3(0, 0, 0), .pdf = 0.0};
    /* One-sample mixture: pick a strategy, then scatter or pass with its probability. */
    int maj = pcg32_uniform(rng) < D.w;
    if (pcg32_uniform(rng) >= (maj ? D.P_m : D.P_g)) {
        if (!(P_pass > 0.0)) return f; /* rounding only: P_pass = 0 never gets here */
        double T = rd_transmittance(s, in->region, r, t0, t1, rng, c);
        f.kind = RD_FLIGHT_PASS;
        f.weight = v3_scale(v3(1, 1, 1), T / P_pass); /* eq. 4, pass */
        return f;
    }
    double t = rd_guide_pdf_sample(maj ? &D.m : &D.g, pcg32_uniform(rng), NULL);
    double q = dist_scatter_pdf(&D, t);
    vec3 x = ray_at(r, t);
    const rd_medium *m = rd_scene_medium_at(s, in->region, x);
    double sigma_t = m ? rd_medium_sigma_t(m, x) : 0.0;
    c->lookups += m != NULL;
    f.t = t;
    if (!(sigma_t > 0.0) || !(q > 0.0)) return f; /* zero integrand: the path adds no more */
    double T = rd_transmittance(s, in->region, r, t0, t, rng, c);
    f.kind = RD_FLIGHT_SCATTER;
    f.medium = m;
    f.weight = v3_scale(m->albedo, sigma_t * T / q); /* eq. 4, scatter: sigma_s = albedo sigma_t */
    f.pdf = q; /* the equiangular strategy's MIS weight at this vertex (transport/path.c) */
    return f;
}

/* The last flight's scattering density at t (eq. 3), for the equiangular strategy's MIS weight
 * (rd_flight_sampler.density); -1 when that flight was delta tracking's (the path loop then
 * takes the majorant stand-in, which is delta tracking's density where the majorant is
 * tight). */
static double guided_density(const rd_flight_sampler *fs, double t)
{
    const gu_user *u = fs->user;
    return u->guided ? dist_scatter_pdf(&u->D, t) : -1.0;
}

/* ---- The vertex policy: guided directions, roulette and splitting --------------------------- */

/* The weight window of the roulette (Vorba and Krivanek 2016, §4: s = 5): a path whose
 * expected contribution rho (in units of the pixel's) lies in [2/(1+s), 2s/(1+s)] goes on as
 * it is; below, Russian roulette lifts it to the window's lower edge; above, it splits. */
#define GU_WINDOW_S 5.0
/* Least survival probability the guide's roulette gives; below it (a guide calling a region
 * dark, rightly or not) the throughput roulette of `delta` decides (gu_vertex). */
#define GU_RR_FLOOR 0.05
/* The guide lobe needs the first-order coefficients divided by the phase's b_1; below this
 * |b_1| (near-isotropic media: the in-scattered radiance forgets the incident direction) the
 * cache holds no usable direction and the continuation is phase sampling alone. */
#define GU_B1_MIN 0.1

/* The band count whose window the lobe's guide was baked with (the window factor below is a
 * function of it): for the indirect guide the scene's guide.bands, also where the bake keeps
 * only the lobe's two bands (RD_NEEDS_INDIRECT_LOBE: bake.c windows them for guide.bands); for
 * the main guide its own, which may be a loaded file's. */
static int window_bands(const rd_render_ctx *ctx)
{
    return ctx->guide_indirect ? ctx->scene->guide.bands : sh_guide_bands(ctx->guide);
}

/* The guide's incident-light lobe in cell `coeffs` (3 channel-major bands^2 blocks; baked_bands
 * the L of the window the guide was baked with, window_bands) for a medium with
 * HG g, as a von Mises-Fisher lobe (mean mu, concentration kappa) of the directions a path
 * continuing from the cell would gather it along. 0 where there is none.
 *   The bake stores c_lm = (1/V) sum_k dPhi_k b_l Y_lm(w'_k) (sh.h; w'_k the photons' travel
 *   directions, b_l = g^l times the Hann window w_l when guide.window is on), so with
 *   (Y_1-1, Y_10, Y_11) = sqrt(3/(4 pi)) (y, z, x) and Y_00 = 1/(2 sqrt(pi)):
 *       m = sum_k dPhi_k w'_k / sum_k dPhi_k = (c_11, c_1-1, c_10) / (sqrt(3) b_1 c_00),
 *   the mean travel direction of the light arriving in the cell, |m| <= 1 its mean cosine.
 *   A path continuing along wo gathers light that travels along -wo: the lobe's mean is -m/|m|,
 *   its concentration the vMF's whose mean cosine is |m| (rd_vmf_kappa).
 * It depends on the cell and the medium alone, so gu_prepare finds it once for every cell of
 * the guide and every medium (gu_state.lobes); a vertex only takes its product with the phase
 * function (lobe_product). */
static int cell_lobe(const rd_scene *s, const float *coeffs, int bands, int baked_bands, double g, gu_lobe *out)
{
    if (bands < 2) return 0;
    double b1 = g * (s->guide.window ? 0.5 * (1.0 + cos(M_PI / baked_bands)) : 1.0);
    if (!(fabs(b1) >= GU_B1_MIN)) return 0;
    int L2 = bands * bands;
    double c00 = 0.0, c[3] = {0, 0, 0}; /* channel means of c_00 and of (c_11, c_1-1, c_10) */
    for (int ch = 0; ch < 3; ch++) {
        const float *k = coeffs + (size_t)ch * L2;
        c00 += k[SH_INDEX(0, 0)] / 3.0;
        c[0] += k[SH_INDEX(1, 1)] / 3.0;
        c[1] += k[SH_INDEX(1, -1)] / 3.0;
        c[2] += k[SH_INDEX(1, 0)] / 3.0;
    }
    if (!(c00 > 0.0)) return 0;
    vec3 m = v3_scale(v3(c[0], c[1], c[2]), 1.0 / (sqrt(3.0) * b1 * c00));
    double rbar = v3_len(m);
    if (!(rbar > 0.05) || !isfinite(rbar)) return 0; /* no preferred direction to speak of */
    out->mu = v3_scale(m, -1.0 / rbar);
    out->kappa = rd_vmf_kappa(fmin(rbar, 0.95));
    return 1;
}

/* The continuation wants p_HG(d.wo) L_i(wo), the product. With the phase function approximated
 * by the vMF of the same mean cosine about its axis (sign(g) d, kappa_g = rd_vmf_kappa(|g|)),
 * the product of two vMF lobes is a vMF lobe (up to a constant factor):
 *     kappa_g a_g . w + kappa_L mu_L . w = |v| (v/|v|) . w,  v = kappa_g a_g + kappa_L mu_L
 * (the product trick of Herholz et al. 2019, §5, for their vMF mixtures). 0 where the two
 * cancel. */
static int lobe_product(const rd_scene *s, const gu_lobe *L, double g, double kappa_g, vec3 d, rd_dir_mix *mx)
{
    vec3 v = v3_add(v3_scale(d, g < 0.0 ? -kappa_g : kappa_g), v3_scale(L->mu, L->kappa));
    double kv = v3_len(v);
    if (!(kv > 1e-9)) return 0; /* the two cancel: no preferred direction */
    mx->mu = v3_scale(v, 1.0 / kv);
    mx->kappa = kv;
    mx->a = s->guide.direction_weight;
    return 1;
}

static void gu_vertex(const rd_flight_sampler *fs, const rd_scene *s, const rd_vertex_in *v,
                      pcg32 *rng, rd_vertex_out *out)
{
    gu_user *u = fs->user;
    const sh_guide *guide = gu_guide(u->ctx);
    const rd_guide_settings *gs = &s->guide;
    u->vertices++;
    out->n = 1;
    out->rr_scale = 1.0;
    out->mix = (rd_dir_mix){.a = 0.0};
    double beta = fmax(fabs(v->beta.x), fmax(fabs(v->beta.y), fabs(v->beta.z)));
    const double xv[3] = {v->x.x, v->x.y, v->x.z};
    long cell = guide ? sh_guide_locate(guide, xv) : -1;
    const float *coeffs = cell >= 0 ? sh_guide_cell_coeffs(guide, (size_t)cell) : NULL;
    int bands = guide ? sh_guide_bands(guide) : 0;
    /* The lobe comes from the guide of the indirect photons when there is one: the direct
     * light is next-event estimation's, and a continuation aimed at a light source would
     * estimate again what NEE already has (THEORY.md §1: L_s = direct + indirect). */
    const sh_guide *lg = u->ctx->guide_indirect ? gu_guide_indirect(u->ctx) : guide;
    long lcell = lg == guide ? cell : sh_guide_locate(lg, xv);
    if (lcell >= 0 && gs->directions && gs->direction_weight > 0.0) {
        const gu_state *st = u->ctx->state;
        const double g = v->medium->g;
        ptrdiff_t mi = v->medium - s->media;
        if (st->lobes && mi >= 0 && mi < s->n_media && (size_t)lcell < st->lobe_cells) { /* found once (gu_prepare) */
            const gu_lobe *L = &st->lobes[(size_t)mi * st->lobe_cells + (size_t)lcell];
            if (L->kappa > 0.0) lobe_product(s, L, g, st->kappa_g[mi], v->d, &out->mix);
        } else {
            gu_lobe L;
            if (cell_lobe(s, sh_guide_cell_coeffs(lg, (size_t)lcell), sh_guide_bands(lg), window_bands(u->ctx), g, &L))
                lobe_product(s, &L, g, rd_vmf_kappa(fabs(g)), v->d, &out->mix);
        }
    }

    /* Roulette and splitting by the path's expected contribution against the pixel's
     * (adjoint-driven, Vorba and Krivanek 2016 eq. 7-8, with the guide as the adjoint):
     *   rho = |beta| L~_s(x, -d) / I~_cam,  L~_s = f(-d) / sigma_s of the cell,
     * f(-d) the guide's sigma_s L_s toward the way the path came (sh.h). */
    if (coeffs && gs->roulette && u->I_cam > 0.0) {
        const gu_state *st = u->ctx->state;
        float y[SH_MAX_COEFFS];
        const double w[3] = {-v->d.x, -v->d.y, -v->d.z};
        sh_basis_evalf(&st->eval, w, y);
        double f = sh_eval_guide_bands(bands, st->eval.bands, coeffs, y);
        double sig_s = sh_guide_cell_sigma_t(guide, (size_t)cell) * mean3(v->medium->albedo);
        double Ls = sig_s > 0.0 ? f / sig_s : 0.0;
        double rho = beta * Ls / u->I_cam;
        double lo = 2.0 / (1.0 + GU_WINDOW_S), hi = GU_WINDOW_S * lo;
        if (rho > hi && isfinite(rho)) {
            double n = ceil(rho / hi);
            out->n = n < gs->split_max ? (int)n : gs->split_max;
            return;
        }
        if (rho >= lo) return;
        double q = rho / lo;
        /* Survival lifts the weight to the window's edge, so a consistent estimate kills a
         * path once, not again at every vertex. Where the guide sees (next to) nothing the
         * lift would be huge and would repeat (rho stays below the window, weights of
         * 1/q^k after k vertices: the heavy tail of an empty or wrong guide), so below
         * GU_RR_FLOOR the guide's estimate is not trusted and the throughput roulette of
         * `delta` decides instead. */
        if (q >= GU_RR_FLOOR) {
            if (pcg32_uniform(rng) >= q) { out->n = 0; return; }
            out->rr_scale = 1.0 / q;
            return;
        }
    }
    /* No estimate: `delta`'s roulette on the throughput. */
    if (v->depth >= s->settings.rr_depth) {
        double q = fmin(1.0, beta);
        if (q <= 0.0 || pcg32_uniform(rng) >= q) { out->n = 0; return; }
        out->rr_scale = 1.0 / q;
    }
}

static vec3 gu_path(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    gu_state *st = ctx->state;
    gu_user u = {.ctx = ctx, .scratch = th->scratch, .I_pix = st->I_pix ? &st->I_pix[th->pixel] : NULL};
    /* With directions and roulette off the vertex is `delta`'s (the loop's own roulette and
     * phase sampling); with every part off (guide.equiangular too, or the same as `delta`'s
     * settings.equiangular, and guide.probes 1) the method is `delta`, bit for bit. */
    const rd_guide_settings *gs = &ctx->scene->guide;
    /* The flights take `delta`'s equiangular strategy in guide.equiangular's mode, weighted by
     * their own density where they are guided (guided_density). */
    const rd_flight_sampler fs = {.sample = guided_flight,
                                  .vertex = ctx->guide && (gs->directions || gs->roulette) ? gu_vertex : NULL,
                                  .density = guided_density,
                                  .user = &u,
                                  .equiangular = gs->equiangular};
    pcg32 rng = rd_sampler_stream(smp);
    if (!rd_probes_on(&st->probes)) {
        vec3 L = rd_path_radiance(ctx->scene, r, &fs, &rng, &th->counters);
        th->cells += u.segments;
        th->guide_vertices += u.vertices;
        return L;
    }
    /* guide.probes: the path less its camera chain's end, E, which the probes estimate again
     * (as `delta`'s settings.probes: integrators/delta.c) */
    rd_select_work w0 = rd_select_work_now(th);
    vec3 E, I = rd_path_radiance_split(ctx->scene, r, &fs, &rng, &th->counters, &E);
    th->cells += u.segments;
    th->guide_vertices += u.vertices;
    return rd_probes_add(ctx, &st->probes, th, I, E, rd_probes_cost(&st->probes, &w0, th), &rng);
}

/* delta's path on the selection's delta tiles, with the method's probes (guide.probes), so that
 * a tile's choice weighs the two with the same probes. */
static vec3 gu_delta(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp, int equiangular)
{
    gu_state *st = ctx->state;
    return rd_probes_delta(ctx, &st->probes, th, r, smp, equiangular);
}

/* The guided path, or delta's where settings.select gave the pixel's tile to it (select.c). */
static vec3 gu_radiance(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    gu_state *st = ctx->state;
    return rd_select_radiance(ctx, &st->sel, gu_path, th, r, smp);
}

/* settings.adaptive: the pixel's share of the samples and their weight (select_share.c). */
static double gu_sample_share(const rd_render_ctx *ctx, int x, int y, double *weight)
{
    const gu_state *st = ctx->state;
    return st && st->sel.choice ? rd_select_share(&st->sel, x, y, weight) : 1.0;
}

static void gu_pixel_done(const rd_render_ctx *ctx, rd_thread *th)
{
    gu_state *st = ctx->state;
    rd_select_pixel_done(&st->sel, th);
}

/* The epochs: the selection's (select.c: the tiles chosen again from the image's samples) and
 * guide.probes "auto"'s (probes.c), each on its own schedule. */
static int gu_epoch_next(const rd_render_ctx *ctx, int sample)
{
    const gu_state *st = ctx->state;
    int a = rd_select_epoch_next(&st->sel, sample), b = rd_probes_epoch_next(&st->probes, sample);
    return a < b ? a : b;
}

static void gu_epoch(rd_render_ctx *ctx, int sample)
{
    gu_state *st = ctx->state;
    /* (No end given: the rule weighs the samples to come alone, as before session 61. With the
     * image's samples weighed, hard-dense-block lost 30% of its efficiency in two rounds, fewer
     * tiles going on trial to the paths at the epoch at 64, for a reason not yet found:
     * integrators/select_rule.c, "The samples the image holds".) */
    if (rd_select_epoch_next(&st->sel, sample - 1) == sample) rd_select_epoch(&st->sel, ctx->comm, NULL);
    if (rd_probes_epoch_next(&st->probes, sample - 1) == sample) rd_probes_epoch(ctx, &st->probes);
}

rd_flight rd_gu_flight(const rd_render_ctx *ctx, void *scratch, const rd_flight_in *in,
                       pcg32 *rng, rd_track_counters *c, double *P_pass)
{
    gu_user u = {.ctx = ctx, .scratch = scratch};
    const rd_flight_sampler fs = {.sample = guided_flight, .user = &u};
    rd_flight f = guided_flight(&fs, ctx->scene, in, rng, c);
    if (P_pass) *P_pass = u.P_pass;
    return f;
}

void rd_gu_vertex(const rd_render_ctx *ctx, const rd_vertex_in *v, double I_cam, pcg32 *rng,
                  rd_vertex_out *out)
{
    gu_user u = {.ctx = ctx, .I_cam = I_cam};
    const rd_flight_sampler fs = {.sample = guided_flight, .vertex = gu_vertex, .user = &u};
    gu_vertex(&fs, ctx->scene, v, rng, out);
}

double rd_gu_flight_cdf(const rd_render_ctx *ctx, void *scratch, const rd_flight_in *in,
                        double t, double *P_pass)
{
    double t0, t1;
    if (P_pass) *P_pass = -1.0;
    if (!flight_guided(ctx->scene, ctx, in) || !flight_interval(ctx->scene, in, &t0, &t1))
        return 0.0;
    gu_scratch sc;
    scratch_layout(ctx->state, &sc, scratch);
    gu_dist D;
    flight_majorant(ctx, &sc, in->region, in->r, t0, t1, &D);
    if (D.tau_m > ctx->scene->guide.distance_tau_max) return 0.0; /* delta's (guided_flight) */
    flight_dist(ctx, &sc, in->r, t0, t1, behind_mean(ctx->scene, in), &D);
    if (!(D.g.I > 0.0)) return 0.0; /* delta tracking's flight (guided_flight) */
    if (P_pass) *P_pass = dist_pass(&D);
    return (1.0 - D.w) * D.P_g * rd_guide_pdf_cdf(&D.g, t) + D.w * D.P_m * rd_guide_pdf_cdf(&D.m, t);
}

/* ---- Set-up --------------------------------------------------------------------------------- */

/* Majorant cells a ray can cross in medium m: a grid's nx + ny + nz, an octree's 3 x 2^depth
 * leaves, one global segment. */
static int majorant_crossings(const rd_medium *m)
{
    const rd_majorant *mj = m->majorant;
    if (!mj || mj->kind == RD_MAJ_NONE) return 1;
    if (mj->kind == RD_MAJ_GRID) return mj->n[0] + mj->n[1] + mj->n[2];
    return 3 * (1 << (mj->depth < 12 ? mj->depth : 12));
}

static void gu_state_free(gu_state *st);

/* gu_state.lobes and kappa_g (guide.directions): every cell's lobe for every medium, found as a
 * vertex would find it (cell_lobe, the same operations: the same bits). Left NULL where the
 * table would be too large, or its memory is not there: the vertex then finds its cell's lobe
 * itself (gu_vertex), the same lobe, only slower. ctx->state is st. */
static void build_lobes(const rd_render_ctx *ctx, gu_state *st)
{
    const rd_scene *s = ctx->scene;
    if (!ctx->guide || !s->guide.directions || !(s->guide.direction_weight > 0.0) || s->n_media < 1) return;
    const sh_guide *lg = ctx->guide_indirect ? gu_guide_indirect(ctx) : gu_guide(ctx);
    sh_guide_stats gs;
    sh_guide_stats_get(lg, &gs);
    if (gs.cells == 0 || gs.cells > GU_LOBES_MAX / (size_t)s->n_media) return;
    st->lobes = malloc(gs.cells * (size_t)s->n_media * sizeof *st->lobes);
    st->kappa_g = malloc((size_t)s->n_media * sizeof *st->kappa_g);
    if (!st->lobes || !st->kappa_g) {
        free(st->lobes), free(st->kappa_g);
        st->lobes = NULL, st->kappa_g = NULL;
        return;
    }
    st->lobe_cells = gs.cells;
    int bands = sh_guide_bands(lg), baked_bands = window_bands(ctx);
    for (int i = 0; i < s->n_media; i++) {
        double g = s->media[i].g;
        st->kappa_g[i] = rd_vmf_kappa(fabs(g));
        for (size_t c = 0; c < gs.cells; c++) {
            gu_lobe *L = &st->lobes[(size_t)i * gs.cells + c];
            if (!cell_lobe(s, sh_guide_cell_coeffs(lg, c), bands, baked_bands, g, L)) *L = (gu_lobe){.kappa = 0.0};
        }
    }
}

/* The counted cost of one of its flights' pdf segments (rd_method.h): the selection's and the
 * probes' */
#define GU_CELL_COST RD_GU_CELL_COST

/* The method's state for ctx's scene and bake, its probes set up, and no selection yet. */
static rd_status gu_state_new(const rd_render_ctx *ctx, gu_state **out, char *err, size_t errlen)
{
    const rd_scene *s = ctx->scene;
    const rd_guide_settings *g = &s->guide;
    *out = NULL;
    /* Unbiasedness needs p > 0 wherever the integrand can be and both outcomes possible. */
    if (!(g->distance_alpha > 0.0 && g->distance_alpha <= 1.0)) {
        snprintf(err, errlen, "guide.distance_alpha: must be in (0, 1], found %g", g->distance_alpha);
        return RD_ERR_ARG;
    }
    if (!(g->pass_floor > 0.0 && g->pass_floor <= 0.5)) {
        snprintf(err, errlen, "guide.pass_floor: must be in (0, 0.5], found %g", g->pass_floor);
        return RD_ERR_ARG;
    }
    if (!(g->majorant_weight >= 0.0 && g->majorant_weight < 1.0)) {
        snprintf(err, errlen, "guide.majorant_weight: must be in [0, 1), found %g", g->majorant_weight);
        return RD_ERR_ARG;
    }
    gu_state *st = calloc(1, sizeof *st);
    if (!st) {
        snprintf(err, errlen, "out of memory for guided-unbiased");
        return RD_ERR_NOMEM;
    }
    st->cap_g = 2;
    if (ctx->guide) {
        /* As the marcher: a uniform grid is crossed in at most nx + ny + nz - 2 cells, an
         * adaptive one in at most 3 x 2^depth leaves; plus two fillers (rd_guide_pdf.h). */
        sh_guide_stats gs;
        sh_guide_stats_get(ctx->guide, &gs);
        st->cap_g = gs.kind == SH_GRID_UNIFORM
                        ? gs.res[0] + gs.res[1] + gs.res[2] + 2
                        : 3 * (1 << (gs.depth_max < 12 ? gs.depth_max : 12)) + 2;
        int bands = sh_guide_bands(ctx->guide);
        sh_basis_init(&st->eval, g->eval_bands < bands ? g->eval_bands : bands);
        /* The copies that keep only what is read: eval_bands, and at least band 1 (the lobe) */
        int keep = g->eval_bands > 2 ? g->eval_bands : 2;
        sh_status ss = SH_OK;
        if (keep < bands) ss = sh_guide_truncate(ctx->guide, keep, &st->fast, err, errlen);
        if (ss == SH_OK && ctx->guide_indirect && keep < sh_guide_bands(ctx->guide_indirect))
            ss = sh_guide_truncate(ctx->guide_indirect, keep, &st->fast_indirect, err, errlen);
        if (ss != SH_OK) {
            gu_state_free(st);
            return RD_ERR_NOMEM;
        }
    }
    /* The scene-wide medium may come in pieces between box media: one more walk start and
     * gap each (rd_media_intervals). */
    st->cap_m = 1 + 2 * s->n_media;
    for (int i = 0; i < s->n_media; i++) st->cap_m += majorant_crossings(&s->media[i]) + 1;
    if (ctx->guide && g->roulette) {
        size_t np = (size_t)s->camera.width * (size_t)s->camera.height;
        st->I_pix = malloc(np * sizeof *st->I_pix);
        if (!st->I_pix) {
            snprintf(err, errlen, "out of memory for guided-unbiased's pixel estimates (%zu pixels)", np);
            gu_state_free(st);
            return RD_ERR_NOMEM;
        }
        for (size_t i = 0; i < np; i++) st->I_pix[i] = -1.0; /* not yet found */
    }
    rd_render_ctx own = *ctx; /* (build_lobes reads the guide copies through ctx->state) */
    own.state = st;
    build_lobes(&own, st);
    /* guide.probes, with the selection's cell cost; none with a ray-marched tracker or
     * transmittance (the probes' estimate and the path's own must be unbiased alike, as
     * settings.probes requires of `delta`): "auto" takes none there, and a number is refused
     * when the scene is loaded (load/load.c) */
    int raymarch = s->settings.tracker == RD_FP_RAYMARCH || s->settings.transmittance == RD_TR_RAYMARCH;
    rd_status ps = rd_probes_init(&st->probes, s, raymarch ? 1 : g->probes, GU_CELL_COST, err, errlen);
    if (ps != RD_OK) {
        gu_state_free(st);
        return ps;
    }
    *out = st;
    return RD_OK;
}

static void gu_state_free(gu_state *st)
{
    if (!st) return;
    rd_select_free(&st->sel);
    rd_probes_free(&st->probes);
    sh_guide_free(st->fast);
    sh_guide_free(st->fast_indirect);
    free(st->I_pix);
    free(st->lobes);
    free(st->kappa_g);
    free(st);
}

static void gu_release(rd_render_ctx *ctx)
{
    gu_state_free(ctx->state);
    ctx->state = NULL;
}

static rd_status gu_prepare(rd_render_ctx *ctx, char *err, size_t errlen)
{
    const rd_scene *s = ctx->scene;
    gu_state *st;
    rd_status ps = gu_state_new(ctx, &st, err, errlen);
    if (ps != RD_OK) return ps;
    ctx->state = st;
    /* With a guide (else the method is delta's path already), the tiles where it pays. The
     * selection has `delta`'s path with the strategy on every flight as a third estimator
     * whatever the method's own flights take (guide.equiangular): since session 39 they take
     * none by default where the selection runs (load.c), and the third estimator is where the
     * strategy pays (select.c's head). */
    if (s->settings.select != RD_SELECT_OFF && ctx->guide) {
        /* Without probes (M = 1 for the whole render: guide.probes 1, a ray-marched tracker or
         * transmittance, or a scene where no chain can end on light: rd_probes_init) the selection calls
         * delta's path itself, the same sample without the two calls between (a `delta` tile's
         * sample on hard-narrow-spot costs about 0.3 us, each call a few ns). */
        rd_select_delta_fn dfn = rd_probes_on(&st->probes) ? gu_delta : NULL;
        /* (settings.adaptive "auto": the epochs' shares, which keep the image unbiased:
         * docs/guided-unbiased.md "Shares that follow the epochs, unbiased") */
        const int options = RD_SELECT_THIRD | RD_SELECT_UNBIASED_SHARES_AUTO;
        rd_status rs = rd_select_prepare(ctx, gu_path, dfn, GU_CELL_COST, options, &st->sel, err, errlen);
        if (rs != RD_OK) {
            gu_release(ctx);
            return rs;
        }
        ctx->weighted = st->sel.weight || st->sel.blocks, ctx->shares = st->sel.share != NULL;
        ctx->blocks = st->sel.blocks;
    }
    return RD_OK;
}

/* ---- The paths alone, for another method's selection (rd_method.h) ---------------------- */

struct rd_gu_paths {
    gu_state *st;
};

rd_status rd_gu_paths_new(const rd_render_ctx *ctx, rd_gu_paths **out, char *err, size_t errlen)
{
    *out = NULL;
    rd_gu_paths *p = calloc(1, sizeof *p);
    if (!p) {
        snprintf(err, errlen, "out of memory for guided-unbiased's paths");
        return RD_ERR_NOMEM;
    }
    rd_status st = gu_state_new(ctx, &p->st, err, errlen); /* (its probes as the method's) */
    if (st != RD_OK) {
        free(p);
        return st;
    }
    *out = p;
    return RD_OK;
}

size_t rd_gu_paths_scratch_bytes(const rd_gu_paths *p)
{
    gu_scratch sc;
    return scratch_layout(p->st, &sc, NULL);
}

vec3 rd_gu_paths_radiance(const rd_render_ctx *ctx, const rd_gu_paths *p, rd_thread *th, ray3 r, rd_sampler *smp)
{
    rd_render_ctx own = *ctx; /* (the method's functions read their state through ctx) */
    own.state = p->st;
    return gu_path(&own, th, r, smp);
}

int rd_gu_paths_epoch_next(const rd_gu_paths *p, int sample)
{
    return rd_probes_epoch_next(&p->st->probes, sample);
}

void rd_gu_paths_epoch(const rd_render_ctx *ctx, rd_gu_paths *p)
{
    rd_render_ctx own = *ctx;
    own.state = p->st;
    rd_probes_epoch(&own, &p->st->probes);
}

unsigned rd_gu_paths_needs(const rd_scene *s)
{
    return s->guide.directions ? RD_NEEDS_INDIRECT | RD_NEEDS_INDIRECT_LOBE : 0u; /* (the lobe alone) */
}

void rd_gu_paths_free(rd_gu_paths *p)
{
    if (!p) return;
    gu_state_free(p->st);
    free(p);
}

static size_t gu_scratch_bytes(const rd_render_ctx *ctx)
{
    gu_scratch sc;
    return scratch_layout(ctx->state, &sc, NULL);
}

/* The guide (and the photon map it is baked from) only when distances are guided; with
 * guide.distances false the method is delta tracking and needs no bake. */
static unsigned gu_needs(const rd_scene *s)
{
    if (!s->guide.distances && !s->guide.directions && !s->guide.roulette) return 0u;
    unsigned n = RD_NEEDS_PHOTONS | RD_NEEDS_GUIDE;
    n |= rd_gu_paths_needs(s);
    if (s->guide.photon_share < 1.0) n |= RD_NEEDS_FEW_PHOTONS; /* its guide steers, never sums */
    /* Its paths cannot find the light a delta light sends through glass (docs/surfaces.md): a
     * guide that held it would split and steer paths toward light they never reach. */
    return n | RD_NEEDS_REACHABLE;
}

const rd_method rd_method_guided_unbiased = {
    .name = "guided-unbiased",
    .summary = "unbiased path tracing with continuation directions and roulette/splitting guided by the SH guide",
    .needs = RD_NEEDS_PHOTONS | RD_NEEDS_GUIDE | RD_NEEDS_INDIRECT | RD_NEEDS_INDIRECT_LOBE | RD_NEEDS_REACHABLE,
    .needs_for = gu_needs,
    .scratch_bytes = gu_scratch_bytes,
    .prepare = gu_prepare,
    .epoch_next = gu_epoch_next,
    .epoch = gu_epoch,
    .release = gu_release,
    .radiance = gu_radiance,
    .pixel_done = gu_pixel_done,
    .sample_share = gu_sample_share,
};
