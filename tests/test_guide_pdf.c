/* test_guide_pdf.c: the per-ray histogram PDF of guided marching (THEORY.md §6; seed 001 eq.
 * 16-17): normalisation by independent quadrature, the inverse CDF, chi-square tests of the
 * sampler with a negative control, positivity of the defensive mixture, unbiasedness of the
 * stratified importance-sampling estimator, the eq. 17 allocation and the build from a baked
 * guide grid. Fixed seeds; tolerances from standard errors and p = 1e-4 quantiles. */
#include "support/rd_test.h"

#include <float.h>

#include "integrators/rd_guide_pdf.h"
#include "sh.h"

#define MAXS 48

typedef struct {
    int n;
    double t[MAXS + 1], f[MAXS], s[MAXS];
    double tmin, tmax;
} segset;

enum { SET_RANDOM, SET_SINGLE, SET_ZERO_F, SET_ZERO_SIGMA, SET_HUGE_SIGMA, SET_OPAQUE_FRONT, SET_KINDS };

static double uni(pcg32 *r, double a, double b) { return a + (b - a) * pcg32_uniform(r); }

/* Random segment sets, including zero-f and zero-sigma segments, sigma up to 1e5 (sigma dt up
 * to ~1e6: T~ underflows to 0 behind such a segment), gaps between [tmin, tmax] and the
 * segments at either end. (Larger sigma would outrun the test quadrature, which can place its
 * nodes no closer than an ulp of t: relative error ~ sigma ulp(t).) */
static segset make_set(pcg32 *r, int kind)
{
    segset S;
    memset(&S, 0, sizeof S);
    S.tmin = uni(r, -2.0, 2.0);
    S.tmax = S.tmin + exp(uni(r, -3.0, 3.0));
    double L = S.tmax - S.tmin;
    S.n = kind == SET_SINGLE ? 1 : 1 + (int)(pcg32_uniform(r) * (MAXS - 1));
    double a = pcg32_uniform(r) < 0.5 ? S.tmin : S.tmin + 0.2 * L * pcg32_uniform(r);
    double b = pcg32_uniform(r) < 0.5 ? S.tmax : S.tmax - 0.2 * L * pcg32_uniform(r);
    /* sorted random interior bounds (insertion sort of n-1 uniforms) */
    S.t[0] = a;
    S.t[S.n] = b;
    for (int j = 1; j < S.n; j++) {
        double x = uni(r, a, b);
        int k = j;
        while (k > 1 && S.t[k - 1] > x) { S.t[k] = S.t[k - 1]; k--; }
        S.t[k] = x;
    }
    for (int j = 1; j <= S.n; j++) /* strictly increasing (ties are measure zero, but be sure) */
        if (!(S.t[j] > S.t[j - 1])) S.t[j] = nextafter(S.t[j - 1], INFINITY);
    for (int j = 0; j < S.n; j++) {
        double u = pcg32_uniform(r);
        S.f[j] = u < 0.2 ? 0.0 : exp(uni(r, -5.0, 5.0));
        u = pcg32_uniform(r);
        S.s[j] = u < 0.2 ? 0.0 : (u < 0.3 ? exp(uni(r, log(1e3), log(1e5))) : exp(uni(r, -4.0, 3.0)));
        if (kind == SET_ZERO_F) S.f[j] = 0.0;
        if (kind == SET_ZERO_SIGMA) S.s[j] = 0.0;
        if (kind == SET_HUGE_SIGMA) S.s[j] = exp(uni(r, log(1e4), log(1e5)));
        if (kind == SET_OPAQUE_FRONT) S.s[j] = j == 0 ? 1e5 : 1.0;
    }
    return S;
}

static void build_set(rd_guide_pdf *P, rd_gpdf_seg *store, const segset *S, double alpha)
{
    char err[256] = "";
    rd_guide_pdf_init(P, store, MAXS + 2);
    rd_status st = rd_guide_pdf_build(P, S->n, S->t, S->f, S->s, S->tmin, S->tmax, alpha, err,
                                      sizeof err);
    cr_assert_eq(st, RD_OK, "%s", err);
}

/* Integral of rd_guide_pdf_eval over [a, b] by 5-point Gauss-Legendre on panels, split at the
 * segment bounds; inside a segment the panels are at most 0.5/sigma wide over the first 60/sigma
 * (the exponential) and the rest is constant to e^-60. Independent of the closed forms. */
static double gl5(const rd_guide_pdf *P, double (*fn)(const rd_guide_pdf *, double), double a,
                  double b)
{
    static const double x[5] = {0.0, -0.5384693101056831, 0.5384693101056831, -0.9061798459386640,
                                0.9061798459386640};
    static const double w[5] = {0.5688888888888889, 0.4786286704993665, 0.4786286704993665,
                                0.2369268850561891, 0.2369268850561891};
    double m = 0.5 * (a + b), h = 0.5 * (b - a), s = 0;
    for (int i = 0; i < 5; i++) s += w[i] * fn(P, m + h * x[i]);
    return s * h;
}
static double quad_piece(const rd_guide_pdf *P, double (*fn)(const rd_guide_pdf *, double),
                         double a, double b, double sigma)
{
    double len = b - a, s = 0;
    if (len <= 0) return 0;
    if (sigma * len <= 8.0) {
        for (int k = 0; k < 16; k++) s += gl5(P, fn, a + len * k / 16, a + len * (k + 1) / 16);
        return s;
    }
    double c = fmin(len, 60.0 / sigma);
    int np = (int)ceil(c * sigma / 0.5);
    for (int k = 0; k < np; k++) s += gl5(P, fn, a + c * k / np, a + c * (k + 1) / np);
    if (c < len)
        for (int k = 0; k < 4; k++) s += gl5(P, fn, a + c + (len - c) * k / 4, a + c + (len - c) * (k + 1) / 4);
    return s;
}
static double quad_fn(const rd_guide_pdf *P, double (*fn)(const rd_guide_pdf *, double),
                      double a, double b)
{
    double s = 0;
    for (int j = 0; j < P->n; j++) {
        double lo = fmax(a, P->seg[j].t0), hi = fmin(b, P->seg[j].t1);
        if (hi > lo) s += quad_piece(P, fn, lo, hi, P->seg[j].sigma);
    }
    return s;
}

/* Quadrature of the pdf itself. */
static double quad(const rd_guide_pdf *P, double a, double b)
{
    return quad_fn(P, rd_guide_pdf_eval, a, b);
}

static const double ALPHAS[] = {0.0, 0.1, 0.5, 1.0};
#define NALPHA (int)(sizeof ALPHAS / sizeof ALPHAS[0])

Test(guide_pdf, integrates_to_one_and_cdf_matches_quadrature)
{
    rd_gpdf_seg store[MAXS + 2];
    rd_guide_pdf P;
    pcg32 r = pcg32_seed(1, 2, 3);
    for (int k = 0; k < 240; k++) {
        int kind = k % SET_KINDS;
        segset S = make_set(&r, kind);
        for (int ai = 0; ai < NALPHA; ai++) {
            build_set(&P, store, &S, ALPHAS[ai]);
            if (kind == SET_ZERO_F) {
                cr_expect_eq(P.I, 0.0);
                cr_expect_eq(P.alpha, 1.0, "all-zero f must fall back to p_def");
            }
            double total = quad(&P, S.tmin, S.tmax);
            cr_expect(fabs(total - 1.0) < 1e-9, "set %d kind %d alpha %g: integral %.12f", k,
                      kind, ALPHAS[ai], total);
            cr_expect_eq(rd_guide_pdf_cdf(&P, S.tmax), 1.0);
            cr_expect_eq(rd_guide_pdf_cdf(&P, S.tmin), 0.0);
            /* The closed-form CDF at every segment end against the quadrature's prefix. */
            double acc = 0;
            for (int j = 0; j < P.n; j++) {
                acc += quad(&P, P.seg[j].t0, P.seg[j].t1);
                double c = rd_guide_pdf_cdf(&P, P.seg[j].t1);
                cr_expect(fabs(c - fmin(acc, 1.0)) < 1e-9, "set %d seg %d: cdf %.12f quad %.12f",
                          k, j, c, acc);
            }
            /* I_ray: the integral of h, closed form against quadrature of h. */
            double Ih = quad_fn(&P, rd_guide_pdf_h, S.tmin, S.tmax);
            cr_expect(fabs(Ih - P.I) <= 1e-9 * P.I, "I_ray %.12g vs quad %.12g", P.I, Ih);
        }
    }
}

Test(guide_pdf, closed_form_matches_a_hand_computed_case)
{
    /* Two segments, [0,1) f=2 sigma=1 and [1,3) f=1 sigma=0, medium [0, 4]:
     * I = 2 (1 - e^-1) + e^-1 * 2, h(0.5) = 2 e^-0.5, h(2) = e^-1, h(3.5) = 0. */
    double t[] = {0, 1, 3}, f[] = {2, 1}, s[] = {1, 0};
    rd_gpdf_seg store[8];
    rd_guide_pdf P;
    rd_guide_pdf_init(&P, store, 8);
    cr_assert_eq(rd_guide_pdf_build(&P, 2, t, f, s, 0.0, 4.0, 0.25, NULL, 0), RD_OK);
    double I = 2 * (1 - exp(-1)) + 2 * exp(-1);
    cr_expect(fabs(P.I - I) < 1e-15 * I);
    cr_expect_eq(P.n, 3, "trailing filler expected");
    cr_expect(fabs(rd_guide_pdf_h(&P, 0.5) - 2 * exp(-0.5)) < 1e-15);
    cr_expect(fabs(rd_guide_pdf_h(&P, 2.0) - exp(-1)) < 1e-15);
    cr_expect_eq(rd_guide_pdf_h(&P, 3.5), 0.0);
    cr_expect(fabs(rd_guide_pdf_eval(&P, 3.5) - 0.25 / 4) < 1e-15);
    cr_expect(fabs(rd_guide_pdf_eval(&P, 0.5) - (0.75 * 2 * exp(-0.5) / I + 0.0625)) < 1e-15);
    cr_expect_eq(rd_guide_pdf_eval(&P, -0.1), 0.0);
    cr_expect_eq(rd_guide_pdf_eval(&P, 4.1), 0.0);
    /* sigma -> 0 limit: a tiny sigma agrees with sigma = 0 to first order */
    double s2[] = {1e-12, 0};
    rd_guide_pdf Q;
    rd_gpdf_seg store2[8];
    rd_guide_pdf_init(&Q, store2, 8);
    cr_assert_eq(rd_guide_pdf_build(&Q, 2, t, f, s2, 0.0, 4.0, 0.0, NULL, 0), RD_OK);
    cr_expect(fabs(Q.I - 4.0) < 1e-11, "I %.17g", Q.I);
}

Test(guide_pdf, inverse_cdf_round_trip)
{
    rd_gpdf_seg store[MAXS + 2];
    rd_guide_pdf P;
    pcg32 r = pcg32_seed(4, 5, 6);
    double worst = 0;
    for (int k = 0; k < 240; k++) {
        segset S = make_set(&r, k % SET_KINDS);
        for (int ai = 0; ai < NALPHA; ai++) {
            build_set(&P, store, &S, ALPHAS[ai]);
            double tprev = -INFINITY;
            for (int i = 0; i <= 400; i++) {
                double u = i < 400 ? (i + pcg32_uniform(&r)) / 400.0 : 1.0;
                if (i == 0) u = 0.0;
                double p, t = rd_guide_pdf_sample(&P, u, &p);
                cr_assert(t >= S.tmin && t <= S.tmax, "t %g outside [%g, %g]", t, S.tmin, S.tmax);
                cr_expect(t >= tprev, "P^-1 not monotone at u = %g", u);
                tprev = t;
                /* 1e-10, or what double t can resolve: p(t) times a few ulp of t (a peak of
                 * sigma ~ 1e9 has p ~ 1e7, and t cannot be closer than an ulp to the root). */
                double pe = rd_guide_pdf_eval(&P, t), ulp = DBL_EPSILON * fmax(1.0, fabs(t));
                double e = fabs(rd_guide_pdf_cdf(&P, t) - u), tol = 1e-10 + 4.0 * pe * ulp;
                worst = fmax(worst, e / tol);
                cr_expect(e < tol, "set %d alpha %g u %.15f: cdf(P^-1(u)) = %.15f (p %g)", k,
                          ALPHAS[ai], u, rd_guide_pdf_cdf(&P, t), pe);
                cr_expect(p > 0.0, "sampled t = %g with p = 0 (u = %.17g)", t, u);
                /* the returned p is the pdf at the unrounded t0 + x of its segment */
                for (int j = 0; j < P.n; j++)
                    if (t > P.seg[j].t0 && t < P.seg[j].t1)
                        cr_expect(fabs(p - pe) <= pe * (1e-12 + 4.0 * P.seg[j].sigma * ulp),
                                  "p %.17g eval %.17g", p, pe);
            }
        }
    }
    cr_log_info("worst |cdf(P^-1(u)) - u| / tolerance = %.3g", worst);
}

/* Chi-square of iid samples (one u each) against bin probabilities from the quadrature of a
 * (possibly different) pdf `ref`. 64 equal bins over [tmin, tmax]; cells with expected count < 5
 * pooled; returns chi2 and its critical value at p = 1e-4. */
static void chi2_of(const rd_guide_pdf *sampler, const rd_guide_pdf *ref, int n, uint64_t seed,
                    double *chi2, double *crit, int *dof_out)
{
    enum { NB = 64 };
    double obs[NB] = {0}, L = ref->tmax - ref->tmin;
    pcg32 r = pcg32_seed(seed, 77, 1);
    for (int i = 0; i < n; i++) {
        double t = rd_guide_pdf_sample(sampler, pcg32_uniform(&r), NULL);
        int b = (int)((t - ref->tmin) / L * NB);
        obs[b < 0 ? 0 : (b >= NB ? NB - 1 : b)] += 1;
    }
    double c = 0, po = 0, pe = 0;
    int dof = -1;
    for (int b = 0; b < NB; b++) {
        double e = n * quad(ref, ref->tmin + L * b / NB, ref->tmin + L * (b + 1) / NB);
        if (e < 5) { po += obs[b]; pe += e; continue; }
        c += (obs[b] - e) * (obs[b] - e) / e;
        dof++;
    }
    if (pe >= 5) { c += (po - pe) * (po - pe) / pe; dof++; }
    else if (po > 0 && pe < 1e-300) c = INFINITY; /* samples where the pdf is 0 */
    *chi2 = c;
    *crit = rt_chi2_quantile(dof > 0 ? dof : 1, 3.719);
    *dof_out = dof;
}

Test(guide_pdf, sampling_chi_square)
{
    rd_gpdf_seg store[MAXS + 2];
    rd_guide_pdf P;
    pcg32 r = pcg32_seed(8, 9, 10);
    const double alphas[] = {0.0, 0.05, 0.3, 1.0};
    for (int k = 0; k < 6; k++) {
        segset S = make_set(&r, k == 5 ? SET_RANDOM : k);
        for (int ai = 0; ai < 4; ai++) {
            build_set(&P, store, &S, alphas[ai]);
            double chi2, crit;
            int dof;
            chi2_of(&P, &P, 100000, 100 + 4 * k + ai, &chi2, &crit, &dof);
            cr_expect(chi2 < crit, "set %d alpha %g: chi2 %.1f >= %.1f (dof %d)", k, alphas[ai],
                      chi2, crit, dof);
        }
    }
}

Test(guide_pdf, chi_square_rejects_a_slightly_wrong_pdf)
{
    /* Samples of one pdf judged against the same segments with one f_j 10% higher, and against
     * the variant of THEORY.md §6 that holds T~ constant at each segment entry: both must fail,
     * so the test above has teeth. */
    double t[] = {0.0, 0.4, 0.9, 1.1, 1.7, 2.2, 2.6, 3.0}, f[] = {1, 3, 0.5, 2, 4, 1, 2},
           s[] = {0.5, 0.2, 0, 1.5, 0.8, 0.3, 1};
    rd_gpdf_seg sa[16], sb[16], sc[16];
    rd_guide_pdf A, B, C;
    rd_guide_pdf_init(&A, sa, 16);
    rd_guide_pdf_init(&B, sb, 16);
    rd_guide_pdf_init(&C, sc, 16);
    cr_assert_eq(rd_guide_pdf_build(&A, 7, t, f, s, 0.0, 3.0, 0.2, NULL, 0), RD_OK);
    double fw[7];
    memcpy(fw, f, sizeof f);
    fw[3] *= 1.1;
    cr_assert_eq(rd_guide_pdf_build(&B, 7, t, fw, s, 0.0, 3.0, 0.2, NULL, 0), RD_OK);
    /* entry-constant T~: f_j' = f_j T~(t_j) with sigma = 0 */
    double fc[7], s0[7] = {0}, tau = 0;
    for (int j = 0; j < 7; j++) {
        fc[j] = f[j] * exp(-tau);
        tau += s[j] * (t[j + 1] - t[j]);
    }
    cr_assert_eq(rd_guide_pdf_build(&C, 7, t, fc, s0, 0.0, 3.0, 0.2, NULL, 0), RD_OK);
    double chi2, crit;
    int dof;
    chi2_of(&A, &A, 100000, 5, &chi2, &crit, &dof);
    cr_expect(chi2 < crit, "right pdf rejected: chi2 %.1f >= %.1f", chi2, crit);
    chi2_of(&A, &B, 100000, 5, &chi2, &crit, &dof);
    cr_expect(chi2 > crit, "f_3 x 1.1 not detected: chi2 %.1f < %.1f", chi2, crit);
    chi2_of(&A, &C, 100000, 5, &chi2, &crit, &dof);
    cr_expect(chi2 > crit, "entry-constant T~ not detected: chi2 %.1f < %.1f", chi2, crit);
}

Test(guide_pdf, positive_everywhere_when_alpha_positive)
{
    rd_gpdf_seg store[MAXS + 2];
    rd_guide_pdf P;
    pcg32 r = pcg32_seed(11, 12, 13);
    for (int k = 0; k < 120; k++) {
        segset S = make_set(&r, k % SET_KINDS);
        for (int ai = 1; ai < NALPHA; ai++) {
            build_set(&P, store, &S, ALPHAS[ai]);
            double floor_p = ALPHAS[ai] / (S.tmax - S.tmin);
            for (int i = 0; i <= 1000; i++) {
                double t = fmin(S.tmax, S.tmin + (S.tmax - S.tmin) * i / 1000.0);
                cr_expect(rd_guide_pdf_eval(&P, t) >= floor_p * (1 - 1e-15), "p(%g) = %g", t,
                          rd_guide_pdf_eval(&P, t));
            }
            for (int j = 0; j < P.n; j++) { /* at every segment bound, both sides */
                cr_expect(rd_guide_pdf_eval(&P, P.seg[j].t0) > 0);
                cr_expect(rd_guide_pdf_eval(&P, nextafter(P.seg[j].t1, -INFINITY)) > 0);
            }
        }
    }
    /* alpha = 0 with zero-f stretches at both ends: no sample ever lands where p = 0, even at
     * u = 0, u = 1 and next to them. */
    double t[] = {1, 2, 3}, f[] = {0, 1}, s[] = {2, 2};
    rd_guide_pdf_init(&P, store, MAXS + 2);
    cr_assert_eq(rd_guide_pdf_build(&P, 2, t, f, s, 0.0, 5.0, 0.0, NULL, 0), RD_OK);
    const double us[] = {0.0, 1e-300, 1e-17, 0.5, 1 - 1e-16, 1.0};
    for (int i = 0; i < 6; i++) {
        double p, x = rd_guide_pdf_sample(&P, us[i], &p);
        cr_expect(p > 0 && x >= 2.0 && x <= 3.0, "u %.17g: t %.17g p %g", us[i], x, p);
    }
}

/* A smooth test integrand with a known integral over [a, b]: g(t) = 1 + t^2 / 4. */
static double gpoly(double t) { return 1.0 + 0.25 * t * t; }
static double gpoly_int(double a, double b) { return (b - a) + (b * b * b - a * a * a) / 12.0; }

Test(guide_pdf, stratified_estimate_is_unbiased)
{
    /* Over M independent u, the stratified estimate (1/N) sum g(t_n) / p(t_n) with t_n =
     * P^-1((n + u)/N) has mean = the integral within 5 standard errors (THEORY.md §6). Two
     * integrands: h(t)(1 + 0.5 sin 7t) (zero where h is, so alpha = 0 is allowed; its integral
     * by quadrature) and 1 + t^2/4 (needs alpha > 0; closed form). */
    rd_gpdf_seg store[MAXS + 2];
    rd_guide_pdf P;
    pcg32 r = pcg32_seed(21, 22, 23);
    enum { M = 400, N = 16 };
    double tn[N], pn[N];
    for (int k = 0; k < 12; k++) {
        segset S = make_set(&r, k % 2 ? SET_RANDOM : SET_ZERO_SIGMA);
        for (int ai = 0; ai < 3; ai++) {
            double alpha = ai == 0 ? 0.0 : (ai == 1 ? 0.1 : 0.5);
            build_set(&P, store, &S, alpha);
            if (P.I == 0) continue;
            for (int which = 0; which < 2; which++) {
                if (which == 1 && alpha == 0) continue;
                double truth;
                if (which == 0) {
                    /* closed form per segment: h = B e^{-s (t - a)} on [a, b), B = f T~(a);
                     * int e^{-s(t-a)} sin(wt) = [e^{-s(t-a)} (-s sin wt - w cos wt)/(s^2+w^2)] */
                    truth = 0;
                    const double w = 7.0;
                    for (int j = 0; j < P.n; j++) {
                        double a = P.seg[j].t0, b = P.seg[j].t1, sg = P.seg[j].sigma;
                        double B = P.seg[j].f * exp(-P.seg[j].tau0);
                        if (B == 0) continue;
                        double eb = exp(-sg * (b - a));
                        double e1 = sg > 0 ? -expm1(-sg * (b - a)) / sg : b - a;
                        double Fb = eb * (-sg * sin(w * b) - w * cos(w * b)) / (sg * sg + w * w);
                        double Fa = (-sg * sin(w * a) - w * cos(w * a)) / (sg * sg + w * w);
                        truth += B * (e1 + 0.5 * (Fb - Fa));
                    }
                } else {
                    truth = gpoly_int(S.tmin, S.tmax);
                }
                double sum = 0, sum2 = 0;
                for (int m = 0; m < M; m++) {
                    rd_guide_pdf_sample_stratified(&P, N, pcg32_uniform(&r), tn, pn);
                    double est = 0;
                    for (int n = 0; n < N; n++) {
                        cr_assert(pn[n] > 0, "stratified sample with p = 0");
                        if (n) cr_assert(tn[n] >= tn[n - 1]);
                        double g = which == 0 ? rd_guide_pdf_h(&P, tn[n]) * (1 + 0.5 * sin(7 * tn[n]))
                                              : gpoly(tn[n]);
                        est += g / pn[n];
                    }
                    est /= N;
                    sum += est;
                    sum2 += est * est;
                }
                double mean = sum / M, var = fmax(0.0, sum2 / M - mean * mean) * M / (M - 1);
                double se = sqrt(var / M);
                cr_expect(fabs(mean - truth) <= 5 * se + 1e-9 * fabs(truth),
                          "set %d alpha %g g%d: mean %.10g truth %.10g se %.3g", k, alpha, which,
                          mean, truth, se);
            }
            /* g = h with alpha = 0: every estimate is exactly I_ray (zero variance). */
            if (alpha == 0) {
                rd_guide_pdf_sample_stratified(&P, N, 0.37, tn, pn);
                double est = 0;
                for (int n = 0; n < N; n++) est += rd_guide_pdf_h(&P, tn[n]) / pn[n];
                est /= N;
                cr_expect(fabs(est - P.I) <= 1e-9 * P.I, "h/p not constant: %.15g vs %.15g", est, P.I);
            }
        }
    }
}

Test(guide_pdf, stratified_equals_the_one_inverse_cdf)
{
    rd_gpdf_seg store[MAXS + 2];
    rd_guide_pdf P;
    pcg32 r = pcg32_seed(31, 32, 33);
    double tn[37], pn[37];
    for (int k = 0; k < 60; k++) {
        segset S = make_set(&r, k % SET_KINDS);
        build_set(&P, store, &S, ALPHAS[k % NALPHA]);
        double u = pcg32_uniform(&r);
        rd_guide_pdf_sample_stratified(&P, 37, u, tn, pn);
        for (int n = 0; n < 37; n++) {
            double p, t = rd_guide_pdf_sample(&P, (n + u) / 37, &p);
            cr_expect_eq(t, tn[n], "n %d: sweep %.17g vs search %.17g", n, tn[n], t);
            cr_expect_eq(p, pn[n]);
        }
    }
}

Test(guide_pdf, samples_per_ray_eq17)
{
    cr_expect_eq(rd_guide_samples_per_ray(2.0, 1.0, 8, 2, 64), 16);
    cr_expect_eq(rd_guide_samples_per_ray(0.5, 1.0, 8, 2, 64), 4);
    cr_expect_eq(rd_guide_samples_per_ray(0.0, 1.0, 8, 2, 64), 2);   /* clamp low */
    cr_expect_eq(rd_guide_samples_per_ray(100, 1.0, 8, 2, 64), 64);  /* clamp high */
    cr_expect_eq(rd_guide_samples_per_ray(1e300, 1e-300, 8, 2, 64), 64); /* inf */
    cr_expect_eq(rd_guide_samples_per_ray(1.0, 3.0, 8, 1, 64), 3);   /* round(2.67) */
    cr_expect_eq(rd_guide_samples_per_ray(1.0, 0.0, 8, 1, 64), 8);   /* no pilot */
    cr_expect_eq(rd_guide_samples_per_ray(NAN, 1.0, 8, 1, 64), 1);
    /* A dark ray with N_min = 0 still gets one sample (it used to get none: a bias wherever the
     * guide says 0 but the integrand is not). */
    cr_expect_eq(rd_guide_samples_per_ray(0.0, 1.0, 8, 0, 64), 1);
    cr_expect_eq(rd_guide_samples_per_ray(0.0, 1.0, 8, -3, 64), 1);
}

Test(guide_pdf, bad_arguments_and_capacity)
{
    rd_gpdf_seg store[4];
    rd_guide_pdf P;
    char err[256];
    rd_guide_pdf_init(&P, store, 4);
    double t[] = {0, 1, 2, 3, 4}, f[] = {1, 1, 1, 1}, s[] = {1, 1, 1, 1};
    cr_expect_eq(rd_guide_pdf_build(&P, 2, t, f, s, 0, 2, 1.5, err, sizeof err), RD_ERR_ARG);
    cr_expect(strstr(err, "alpha") != NULL, "%s", err);
    double fneg[] = {1, -1};
    cr_expect_eq(rd_guide_pdf_build(&P, 2, t, fneg, s, 0, 2, 0.5, err, sizeof err), RD_ERR_ARG);
    double tbad[] = {0, 1, 1};
    cr_expect_eq(rd_guide_pdf_build(&P, 2, tbad, f, s, 0, 2, 0.5, err, sizeof err), RD_ERR_ARG);
    cr_expect_eq(rd_guide_pdf_build(&P, 2, t, f, s, 0.5, 2, 0.5, err, sizeof err), RD_ERR_ARG);
    cr_expect_eq(P.n, 0);
    /* 4 segments plus a leading and a trailing filler need 6 entries */
    cr_expect_eq(rd_guide_pdf_build(&P, 4, t, f, s, -1, 5, 0.5, err, sizeof err), RD_ERR_NOMEM);
    cr_expect_eq(P.needed, 6, "needed %d", P.needed);
    cr_expect_eq(P.n, 0);
    /* empty medium interval: an empty pdf that samples tmin with p = 0 */
    cr_expect_eq(rd_guide_pdf_build(&P, 0, NULL, NULL, NULL, 1, 1, 0.5, err, sizeof err), RD_OK);
    double p = 1;
    cr_expect_eq(rd_guide_pdf_sample(&P, 0.5, &p), 1.0);
    cr_expect_eq(p, 0.0);
    /* no segments at all over a real interval: uniform */
    cr_expect_eq(rd_guide_pdf_build(&P, 0, NULL, NULL, NULL, 1, 3, 0.2, err, sizeof err), RD_OK);
    cr_expect_eq(P.alpha, 1.0);
    cr_expect(fabs(rd_guide_pdf_sample(&P, 0.25, &p) - 1.5) < 1e-15);
    cr_expect(fabs(p - 0.5) < 1e-15);
}

/* ---- Build from a real baked guide ---------------------------------------------------------- */

static double sigma_field(const double x[3], void *user)
{
    (void)user;
    return 0.5 + x[0] * x[0] + 2.0 * x[1] + 0.3 * x[2]; /* positive inside the box below */
}

Test(guide_pdf, build_from_baked_guide)
{
    const double lo[3] = {-1.0, 0.0, 0.5}, hi[3] = {2.0, 1.0, 1.5};
    enum { NPH = 3000 };
    static pm_photon ph[NPH];
    pcg32 r = pcg32_seed(41, 42, 43);
    for (int i = 0; i < NPH; i++) {
        vec3 w = rd_sample_sphere(pcg32_uniform(&r), pcg32_uniform(&r));
        double dir[3] = {w.x, w.y, w.z};
        for (int a = 0; a < 3; a++) {
            ph[i].pos[a] = (float)uni(&r, lo[a], hi[a]);
            ph[i].dir[a] = (float)dir[a];
            ph[i].power[a] = (float)(0.5 + a * 0.25 + (ph[i].pos[0] > 0.5 ? 1.0 : 0.0));
        }
    }
    char err[256] = "";
    pm_map *m = pm_map_new();
    cr_assert_eq(pm_map_add_photons(m, ph, NPH, err, sizeof err), PM_OK, "%s", err);
    cr_assert_eq(pm_map_build(m, err, sizeof err), PM_OK, "%s", err);
    sh_bake_params BP;
    sh_bake_params_default(&BP);
    for (int a = 0; a < 3; a++) BP.lo[a] = lo[a], BP.hi[a] = hi[a];
    BP.kind = SH_GRID_UNIFORM;
    BP.res[0] = 6, BP.res[1] = 4, BP.res[2] = 5;
    BP.bands = 3;
    BP.k = 20;
    sh_phase_coeffs_hg(0.6, BP.bands, BP.phase_b);
    BP.sigma_t = sigma_field;
    sh_guide *g = NULL;
    cr_assert_eq(sh_guide_bake(&g, m, &BP, err, sizeof err), SH_OK, "%s", err);
    pm_map_free(m);

    const int L = sh_guide_bands(g);
    enum { CAP = 6 + 4 + 5 + 2 };
    rd_gpdf_seg store[CAP];
    rd_guide_pdf P;
    int checked = 0, lit = 0, fillers = 0;
    for (int k = 0; k < 40; k++) {
        /* rays from outside the box through a random interior point; medium interval wider
         * than the box on both sides, so fillers appear */
        double target[3], o[3], d[3];
        for (int a = 0; a < 3; a++) target[a] = uni(&r, lo[a], hi[a]);
        vec3 dv = rd_sample_sphere(pcg32_uniform(&r), pcg32_uniform(&r));
        d[0] = dv.x, d[1] = dv.y, d[2] = dv.z;
        for (int a = 0; a < 3; a++) o[a] = target[a] - 5.0 * d[a];
        double tmin = k % 2 ? 0.0 : 4.6, tmax = k % 2 ? 10.0 : 5.7;
        rd_guide_pdf_init(&P, store, CAP);
        cr_assert_eq(rd_guide_pdf_build_guide(&P, g, o, d, tmin, tmax, 0.1, err, sizeof err),
                     RD_OK, "%s", err);
        cr_assert(P.n >= 1);
        cr_expect_eq(P.seg[0].t0, tmin);
        cr_expect_eq(P.seg[P.n - 1].t1, tmax);
        /* Reference: Y(-d) by the table-free evaluator; f_j at the cell centre. */
        double w[3] = {-d[0], -d[1], -d[2]}, yd[SH_MAX_COEFFS];
        float y[SH_MAX_COEFFS];
        sh_eval_basis(L, w, yd);
        for (int i = 0; i < L * L; i++) y[i] = (float)yd[i];
        /* the guide's own walk, for the exact bounds */
        sh_guide_ray it;
        sh_guide_seg gs;
        sh_guide_ray_begin(g, o, d, tmin, tmax, &it);
        for (int j = 0; j < P.n; j++) {
            const rd_gpdf_seg *s = &P.seg[j];
            cr_expect(s->t1 > s->t0);
            if (j > 0) cr_expect_eq(s->t0, P.seg[j - 1].t1, "gap/overlap at segment %d", j);
            if (s->cell < 0) {
                cr_expect_eq(s->f, 0.0);
                cr_expect_eq(s->sigma, 0.0);
                double mid[3];
                for (int a = 0; a < 3; a++) mid[a] = o[a] + 0.5 * (s->t0 + s->t1) * d[a];
                cr_expect_eq(sh_guide_locate(g, mid), -1, "filler inside the box");
                fillers++;
                continue;
            }
            cr_assert(sh_guide_ray_next(&it, &gs));
            cr_expect_eq(s->t0, gs.t0);
            cr_expect_eq(s->t1, gs.t1);
            cr_expect_eq(s->cell, gs.cell);
            double clo[3], chi[3], ctr[3], mid[3];
            sh_guide_cell_bounds(g, (size_t)s->cell, clo, chi);
            for (int a = 0; a < 3; a++) {
                ctr[a] = 0.5 * (clo[a] + chi[a]);
                mid[a] = o[a] + 0.5 * (s->t0 + s->t1) * d[a];
            }
            cr_expect_eq(sh_guide_locate(g, mid), s->cell, "segment midpoint not in its cell");
            long c = sh_guide_locate(g, ctr);
            cr_assert_eq(c, s->cell);
            float fref = sh_eval_guide(L, sh_guide_cell_coeffs(g, (size_t)c), y);
            cr_expect(fabs(s->f - fref) <= 1e-5 * fabs(fref) + 1e-6 * (fabs(fref) + 1e-30),
                      "cell %ld: f %.9g vs sh_eval_guide at centre %.9g", c, s->f, fref);
            cr_expect_eq(s->sigma, (double)sh_guide_cell_sigma_t(g, (size_t)c));
            cr_expect(s->sigma > 0);
            checked++;
            lit += s->f > 0;
        }
        cr_expect(!sh_guide_ray_next(&it, &gs), "pdf dropped guide segments");
        /* and it is a pdf: round trip and normalisation */
        cr_expect(fabs(quad(&P, tmin, tmax) - 1.0) < 1e-9);
        for (int i = 0; i < 50; i++) {
            double u = (i + 0.5) / 50, t = rd_guide_pdf_sample(&P, u, NULL);
            cr_expect(fabs(rd_guide_pdf_cdf(&P, t) - u) < 1e-10);
        }
    }
    cr_expect(checked > 100, "only %d guide segments checked", checked);
    cr_expect(fillers > 20, "only %d filler segments", fillers);
    cr_expect(lit > checked / 2, "only %d of %d segments have f > 0", lit, checked);
    /* too little storage: RD_ERR_NOMEM and the count this ray needs */
    double o[3] = {-2.0, 0.5, 1.0}, d[3] = {1.0, 0.0, 0.0};
    rd_guide_pdf_init(&P, store, 3);
    cr_expect_eq(rd_guide_pdf_build_guide(&P, g, o, d, 0.0, 10.0, 0.1, err, sizeof err),
                 RD_ERR_NOMEM);
    cr_expect_eq(P.needed, 6 + 2, "needed %d (6 cells + 2 fillers)", P.needed);
    double dn[3] = {2.0, 0.0, 0.0};
    cr_expect_eq(rd_guide_pdf_build_guide(&P, g, o, dn, 0.0, 10.0, 0.1, err, sizeof err),
                 RD_ERR_ARG, "non-unit d accepted");
    sh_guide_free(g);
}

/* Settings that would break an unbiased estimate are refused with a reason. */
Test(guide_pdf, unbiased_settings_are_checked)
{
    char err[256];
    cr_expect_eq(rd_guide_sampler_check(0.1, 1, 64, err, sizeof err), RD_OK);
    cr_expect_eq(rd_guide_sampler_check(1.0, 1, 1, err, sizeof err), RD_OK);
    cr_expect_eq(rd_guide_sampler_check(0.0, 1, 64, err, sizeof err), RD_ERR_ARG);
    cr_expect(strstr(err, "alpha") != NULL, "%s", err);
    cr_expect_eq(rd_guide_sampler_check(-0.5, 1, 64, err, sizeof err), RD_ERR_ARG);
    cr_expect_eq(rd_guide_sampler_check(NAN, 1, 64, err, sizeof err), RD_ERR_ARG);
    cr_expect_eq(rd_guide_sampler_check(0.1, 0, 64, err, sizeof err), RD_ERR_ARG);
    cr_expect(strstr(err, "N_min") != NULL, "%s", err);
    cr_expect_eq(rd_guide_sampler_check(0.1, 8, 4, err, sizeof err), RD_ERR_ARG);
}
