/* march_explain.c: `explain`, one camera ray laid open (renderer.h rd_explain): the dense
 * integrand T(0,t) S(t) along the ray's first straight segment, each placement's PDF, one draw
 * of its samples, and the variance of its stratified estimate against the dense integrand. */
#include "integrators/rd_march.h"

#include <stdlib.h>

/* Dense integrand value at t (piecewise constant on the dense cells). */
static double dense_f(const rd_explain_result *e, double t)
{
    double h = (e->t1 - e->t0) / e->n;
    long i = (long)floor((t - e->t0) / h);
    if (i < 0) i = 0;
    if (i >= e->n) i = e->n - 1;
    return e->f[i];
}

/* Variance (and the standard error of that variance, and the fourth central moment) of the
 * stratified estimate (1/N) sum f(t_n)/p(t_n) of I over R draws of u, against the dense f. */
static void placement_variance(const rd_explain_result *e, const rd_guide_pdf *pdf, int N,
                               double *t, double *p, uint64_t seed, double *var, double *se,
                               double *m4)
{
    enum { R = 4000 };
    double *est = malloc(sizeof(double) * R);
    if (!est) { *var = *se = *m4 = NAN; return; }
    pcg32 rng = pcg32_seed(seed, 0x6578706cU, 1);
    double mean = 0.0;
    for (int k = 0; k < R; k++) {
        rd_guide_pdf_sample_stratified(pdf, N, pcg32_uniform(&rng), t, p);
        double sum = 0.0;
        for (int n = 0; n < N; n++)
            if (p[n] > 0.0) sum += dense_f(e, t[n]) / p[n];
        est[k] = sum / N;
        mean += est[k];
    }
    mean /= R;
    double m2 = 0.0, q = 0.0;
    for (int k = 0; k < R; k++) {
        double d = est[k] - mean;
        m2 += d * d;
        q += d * d * d * d;
    }
    m2 /= R - 1;
    q /= R;
    *var = m2;
    *m4 = q;
    *se = sqrt(fmax(0.0, q - m2 * m2) / R); /* var of a sample variance ~ (m4 - s^4) / R */
    free(est);
}

rd_status rd_march_explain(const rd_render_ctx *ctx, ray3 r, int n, uint64_t seed,
                           rd_explain_result *e, char *err, size_t errlen)
{
    const rd_scene *s = ctx->scene;
    const march_state *st = ctx->state;
    e->origin[0] = r.o.x, e->origin[1] = r.o.y, e->origin[2] = r.o.z;
    e->dir[0] = r.d.x, e->dir[1] = r.d.y, e->dir[2] = r.d.z;
    int hit_light, region;
    /* The camera ray's first straight segment (up to the first surface or light). */
    if (!rd_march_first_segment(s, r, &region, &e->t0, &e->t1, &hit_light)) return RD_OK;
    e->hits_media = 1;
    e->n = n;
    int nmax = st->n_max;
    e->t = malloc(sizeof(double) * n);
    e->T = malloc(sizeof(double) * n);
    e->f = malloc(sizeof(double) * n);
    int ok = e->t && e->T && e->f;
    for (int k = 0; k < RD_EXPLAIN_PLACEMENTS; k++) {
        e->p[k] = malloc(sizeof(double) * n);
        e->samples[k] = malloc(sizeof(double) * nmax);
        ok = ok && e->p[k] && e->samples[k];
    }
    march_scratch ms;
    size_t bytes = rd_march_scratch_layout(st, &ms, NULL);
    void *buf = aligned_alloc(16, (bytes + 15) / 16 * 16);
    double *pbuf = malloc(sizeof(double) * nmax);
    if (!ok || !buf || !pbuf) {
        free(buf), free(pbuf);
        snprintf(err, errlen, "out of memory for explain (%d dense points)", n);
        return RD_ERR_NOMEM;
    }
    rd_march_scratch_layout(st, &ms, buf);

    /* The dense integrand: T by the midpoint rule on sigma_t, S averaged over 16 draws. */
    rd_track_counters c = {0};
    pcg32 rng = pcg32_seed(seed, 0x64656e73U, 2);
    double h = (e->t1 - e->t0) / n, tau = 0.0;
    e->I = 0.0;
    for (int i = 0; i < n; i++) {
        double t = e->t0 + (i + 0.5) * h;
        vec3 x = ray_at(r, t);
        const rd_medium *m = rd_scene_medium_at(s, region, x);
        double sig = m ? rd_medium_sigma_t(m, x) : 0.0;
        double T = exp(-(tau + 0.5 * sig * h));
        tau += sig * h;
        vec3 S = v3(0, 0, 0);
        if (m && sig > 0.0) {
            int draws = s->march.ls == RD_LS_PHOTONS ? 1 : 16;
            for (int k = 0; k < draws; k++)
                S = v3_add(S, rd_march_source(ctx, s->march.ls, m, region, x, r.d, sig, 1, 1.0, NULL, &rng, &c));
            S = v3_scale(S, 1.0 / draws);
        }
        e->t[i] = t;
        e->T[i] = T;
        e->f[i] = T * v3_lum(S);
        e->I += e->f[i] * h;
    }
    e->T_end = exp(-tau);

    /* Each placement's pdf, one draw of its samples, and its variance. */
    const placement places[RD_EXPLAIN_PLACEMENTS] = {PLACE_GUIDED, PLACE_TRANSMITTANCE, PLACE_UNIFORM};
    for (int k = 0; k < RD_EXPLAIN_PLACEMENTS; k++) {
        rd_guide_pdf pdf;
        int N = rd_march_build_pdf(ctx, places[k], &ms, region, r, e->t0, e->t1, &pdf, &c);
        if (k == RD_EXPLAIN_GUIDED) e->I_ray = pdf.I;
        for (int i = 0; i < n; i++) e->p[k][i] = rd_guide_pdf_eval(&pdf, e->t[i]);
        e->n_samples[k] = N;
        rd_guide_pdf_sample_stratified(&pdf, N, pcg32_uniform(&rng), e->samples[k], pbuf);
        placement_variance(e, &pdf, N, ms.t, ms.p, seed + (uint64_t)k, &e->var[k], &e->var_se[k], &e->m4[k]);
    }
    e->mean_I = st->mean_I;
    free(buf);
    free(pbuf);
    return RD_OK;
}
