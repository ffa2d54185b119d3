/* guide_pdf.c: the per-ray histogram PDF of guided ray marching (THEORY.md §6; seed 001 §3.3
 * eq. 16 for the PDF, eq. 17 for the samples per ray). Contract in rd_guide_pdf.h. */
#include "integrators/rd_guide_pdf.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>

static rd_status fail(rd_guide_pdf *pdf, rd_status st, char *err, size_t errlen, const char *fmt,
                      ...)
{
    pdf->n = 0;
    pdf->last = 0;
    pdf->I = 0.0;
    pdf->alpha = 1.0;
    if (err && errlen) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err, errlen, fmt, ap);
        va_end(ap);
    }
    return st;
}

/* E(s, x) = integral_0^x exp(-s y) dy = (1 - exp(-s x)) / s, written -expm1(-s x) / s so that it
 * keeps full relative precision for small s x, with the limit x (1 - s x / 2) for s x < 1e-8
 * (error O((s x)^2) < 1e-16 relative) and exactly x for s = 0. */
static double seg_integral(double s, double x)
{
    double y = s * x;
    if (y < 1e-8) return x * (1.0 - 0.5 * y);
    return -expm1(-y) / s;
}

/* Inverse of E in x: E(s, x) = q  <=>  x = -log1p(-s q) / s, with the limit q (1 + s q / 2) for
 * s q < 1e-8. Returns +inf when s q >= 1 (q beyond the integral to infinity). */
static double seg_integral_inv(double s, double q)
{
    double z = s * q;
    if (z >= 1.0) return INFINITY;
    if (z < 1e-8) return q * (1.0 + 0.5 * z);
    return -log1p(-z) / s;
}

void rd_guide_pdf_init(rd_guide_pdf *pdf, rd_gpdf_seg *storage, int cap)
{
    pdf->seg = storage;
    pdf->cap = storage ? cap : 0;
    pdf->n = 0;
    pdf->needed = 0;
    pdf->last = 0;
    pdf->tmin = pdf->tmax = 0.0;
    pdf->alpha = 1.0;
    pdf->I = 0.0;
}

/* Given seg[0..n) with t0, t1, f, sigma filled in and tiling [tmin, tmax], compute the
 * optical depths of T~ (THEORY.md §6: piecewise exponential from the sigma_j), the prefix sums
 * H_j of the closed-form per-segment integrals of h = T~ f_j (seed 001 eq. 16), I_ray, the
 * defensive weight actually used, and the mixture CDF at every segment start. */
static int last_with_mass(const rd_guide_pdf *pdf);

static void finalize(rd_guide_pdf *pdf, double alpha)
{
    double tau = 0.0, H = 0.0;
    for (int j = 0; j < pdf->n; j++) {
        rd_gpdf_seg *s = &pdf->seg[j];
        double dt = s->t1 - s->t0;
        s->tau0 = tau;
        s->H0 = H;
        if (s->f > 0.0) H += s->f * exp(-tau) * seg_integral(s->sigma, dt);
        tau += s->sigma * dt;
    }
    pdf->I = H;
    /* Defensive mixture p = (1 - alpha) h / I + alpha p_def. p_def is uniform on the medium
     * interval [tmin, tmax], not the sigma-based p_T of THEORY.md §6: the sigma_j are cell
     * means of a coarse grid, and a cell whose mean is 0 (or whose f_j is 0) can still hold
     * medium at points its sampling missed, or light the photon map did not reach. A p_def
     * built from the sigma_j would be 0 over such a cell and leave it unsampled: a bias no sample
     * count removes. The uniform density is > 0 wherever the medium can be non-zero. With no
     * guide mass at all (I == 0, or an overflow to inf) p is p_def alone. */
    pdf->alpha = (H > 0.0 && isfinite(H)) ? alpha : 1.0;
    double L = pdf->tmax - pdf->tmin, a = pdf->alpha;
    for (int j = 0; j < pdf->n; j++) {
        rd_gpdf_seg *s = &pdf->seg[j];
        double cg = a < 1.0 ? (1.0 - a) * (s->H0 / H) : 0.0;
        s->C0 = cg + a * ((s->t0 - pdf->tmin) / L);
    }
    pdf->last = last_with_mass(pdf);
}

static rd_status check_common(rd_guide_pdf *pdf, double tmin, double tmax, double alpha,
                              char *err, size_t errlen)
{
    if (!isfinite(tmin) || !isfinite(tmax))
        return fail(pdf, RD_ERR_ARG, err, errlen, "guide pdf: tmin %g / tmax %g not finite", tmin,
                    tmax);
    if (!(alpha >= 0.0 && alpha <= 1.0))
        return fail(pdf, RD_ERR_ARG, err, errlen, "guide pdf: alpha %g not in [0, 1]", alpha);
    return RD_OK;
}

/* Append a segment if there is room; count it either way (pdf->needed). */
static void push(rd_guide_pdf *pdf, double t0, double t1, double f, double sigma, long cell)
{
    if (pdf->n < pdf->cap) {
        rd_gpdf_seg *s = &pdf->seg[pdf->n++];
        s->t0 = t0;
        s->t1 = t1;
        s->f = f;
        s->sigma = sigma;
        s->cell = cell;
        s->tau0 = s->H0 = s->C0 = 0.0;
    }
    pdf->needed++;
}

rd_status rd_guide_pdf_build(rd_guide_pdf *pdf, int n, const double *t, const double *f,
                             const double *sigma, double tmin, double tmax, double alpha,
                             char *err, size_t errlen)
{
    if (!pdf) return RD_ERR_ARG;
    pdf->n = pdf->needed = 0;
    rd_status st = check_common(pdf, tmin, tmax, alpha, err, errlen);
    if (st != RD_OK) return st;
    if (n < 0 || (n > 0 && (!t || !f || !sigma)))
        return fail(pdf, RD_ERR_ARG, err, errlen, "guide pdf: bad segment arrays (n = %d)", n);
    for (int j = 0; j < n; j++) {
        if (!isfinite(f[j]) || f[j] < 0.0)
            return fail(pdf, RD_ERR_ARG, err, errlen, "guide pdf: f[%d] = %g", j, f[j]);
        if (!isfinite(sigma[j]) || sigma[j] < 0.0)
            return fail(pdf, RD_ERR_ARG, err, errlen, "guide pdf: sigma[%d] = %g", j, sigma[j]);
    }
    for (int j = 0; j <= n && n > 0; j++) {
        if (!isfinite(t[j]) || (j > 0 && !(t[j] > t[j - 1])))
            return fail(pdf, RD_ERR_ARG, err, errlen,
                        "guide pdf: t[%d] = %g not finite or not increasing", j, t[j]);
    }
    if (n > 0 && (t[0] < tmin || t[n] > tmax))
        return fail(pdf, RD_ERR_ARG, err, errlen,
                    "guide pdf: segments [%g, %g] outside [tmin, tmax] = [%g, %g]", t[0], t[n],
                    tmin, tmax);
    pdf->tmin = tmin;
    pdf->tmax = tmax;
    if (!(tmax > tmin)) { /* empty medium interval: empty pdf */
        pdf->I = 0.0;
        pdf->alpha = 1.0;
        return RD_OK;
    }
    if (n == 0 || t[0] > tmin) push(pdf, tmin, n ? t[0] : tmax, 0.0, 0.0, -1);
    for (int j = 0; j < n; j++) push(pdf, t[j], t[j + 1], f[j], sigma[j], -1);
    if (n > 0 && t[n] < tmax) push(pdf, t[n], tmax, 0.0, 0.0, -1);
    if (pdf->needed > pdf->cap)
        return fail(pdf, RD_ERR_NOMEM, err, errlen,
                    "guide pdf: %d segments needed, storage holds %d", pdf->needed, pdf->cap);
    finalize(pdf, alpha);
    return RD_OK;
}

rd_status rd_guide_pdf_build_guide(rd_guide_pdf *pdf, const sh_guide *g, const double o[3],
                                   const double d[3], double tmin, double tmax, double alpha,
                                   char *err, size_t errlen)
{
    return rd_guide_pdf_build_guide_bands(pdf, g, NULL, o, d, tmin, tmax, alpha, err, errlen);
}

rd_status rd_guide_pdf_build_guide_bands(rd_guide_pdf *pdf, const sh_guide *g,
                                         const sh_basis *basis, const double o[3],
                                         const double d[3], double tmin, double tmax,
                                         double alpha, char *err, size_t errlen)
{
    if (!pdf) return RD_ERR_ARG;
    pdf->n = pdf->needed = 0;
    if (!g || !o || !d) return fail(pdf, RD_ERR_ARG, err, errlen, "guide pdf: NULL guide or ray");
    rd_status st = check_common(pdf, tmin, tmax, alpha, err, errlen);
    if (st != RD_OK) return st;
    double dl = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!isfinite(o[0] + o[1] + o[2]) || !(fabs(dl - 1.0) <= 1e-6))
        return fail(pdf, RD_ERR_ARG, err, errlen,
                    "guide pdf: ray origin not finite or direction not unit (|d| = %g)", dl);
    pdf->tmin = tmin;
    pdf->tmax = tmax;
    if (!(tmax > tmin)) {
        pdf->I = 0.0;
        pdf->alpha = 1.0;
        return RD_OK;
    }
    /* Guide value toward w = -d: light travels toward the camera (sh.h, THEORY.md §6). One SH
     * evaluation per ray; per cell only the dot product of sh_eval_guide. */
    const int L = sh_guide_bands(g);
    if (!basis) basis = sh_guide_basis(g);
    if (basis->bands > L)
        return fail(pdf, RD_ERR_ARG, err, errlen, "guide pdf: %d bands asked of a %d-band guide",
                    basis->bands, L);
    const int use = basis->bands;
    const double w[3] = {-d[0], -d[1], -d[2]};
    float y[SH_MAX_COEFFS];
    sh_basis_evalf(basis, w, y);

    sh_guide_ray it;
    sh_guide_seg gs;
    sh_guide_ray_begin(g, o, d, tmin, tmax, &it);
    double tend = tmin;
    while (sh_guide_ray_next(&it, &gs)) {
        if (pdf->needed == 0 && gs.t0 > tmin) push(pdf, tmin, gs.t0, 0.0, 0.0, -1);
        double f = sh_eval_guide_bands(L, use, gs.coeffs, y);
        double s = gs.sigma_t;
        if (!(f >= 0.0) || !isfinite(f)) f = 0.0;   /* sh_eval_guide never gives < 0; NaN guard */
        if (!(s >= 0.0) || !isfinite(s)) s = 0.0;
        push(pdf, gs.t0, gs.t1, f, s, gs.cell);
        tend = gs.t1;
    }
    if (tend < tmax) push(pdf, tend, tmax, 0.0, 0.0, -1); /* also: ray missed the box */
    if (pdf->needed > pdf->cap)
        return fail(pdf, RD_ERR_NOMEM, err, errlen,
                    "guide pdf: ray crosses %d segments, storage holds %d", pdf->needed,
                    pdf->cap);
    finalize(pdf, alpha);
    return RD_OK;
}

/* Segment containing t (largest j with t0_j <= t), t in [tmin, tmax]. */
static int find_t(const rd_guide_pdf *pdf, double t)
{
    int lo = 0, hi = pdf->n;
    while (hi - lo > 1) {
        int mid = lo + (hi - lo) / 2;
        if (pdf->seg[mid].t0 <= t) lo = mid;
        else hi = mid;
    }
    return lo;
}

double rd_guide_pdf_h(const rd_guide_pdf *pdf, double t)
{
    if (pdf->n == 0 || !(t >= pdf->tmin && t <= pdf->tmax)) return 0.0;
    const rd_gpdf_seg *s = &pdf->seg[find_t(pdf, t)];
    if (s->f <= 0.0) return 0.0;
    return s->f * exp(-s->tau0 - s->sigma * (t - s->t0)); /* T~(0,t) f_j, eq. 16 */
}

/* Mixture density inside segment s at offset x: (1 - alpha) f T~ / I + alpha / (tmax - tmin). */
static double seg_pdf(const rd_guide_pdf *pdf, const rd_gpdf_seg *s, double x)
{
    double p = pdf->alpha / (pdf->tmax - pdf->tmin);
    if (pdf->alpha < 1.0 && s->f > 0.0)
        p += (1.0 - pdf->alpha) * s->f * exp(-s->tau0 - s->sigma * x) / pdf->I;
    return p;
}

double rd_guide_pdf_eval(const rd_guide_pdf *pdf, double t)
{
    if (pdf->n == 0 || !(t >= pdf->tmin && t <= pdf->tmax)) return 0.0;
    const rd_gpdf_seg *s = &pdf->seg[find_t(pdf, t)];
    return seg_pdf(pdf, s, t - s->t0);
}

/* Coefficients of the mixture CDF inside a segment: P(t0 + x) = C0 + A E(sigma, x) + B x. */
static void seg_coeffs(const rd_guide_pdf *pdf, const rd_gpdf_seg *s, double *A, double *B)
{
    *B = pdf->alpha / (pdf->tmax - pdf->tmin);
    *A = (pdf->alpha < 1.0 && s->f > 0.0)
             ? (1.0 - pdf->alpha) * s->f * exp(-s->tau0) / pdf->I
             : 0.0;
}

double rd_guide_pdf_cdf(const rd_guide_pdf *pdf, double t)
{
    if (pdf->n == 0 || t <= pdf->tmin) return 0.0;
    if (t >= pdf->tmax) return 1.0;
    const rd_gpdf_seg *s = &pdf->seg[find_t(pdf, t)];
    double A, B, x = t - s->t0;
    seg_coeffs(pdf, s, &A, &B);
    double c = s->C0 + (A > 0.0 ? A * seg_integral(s->sigma, x) : 0.0) + B * x;
    return fmin(1.0, fmax(0.0, c));
}

/* Last segment with positive probability: trailing zero-mass segments (f = 0 filler with alpha
 * = 0) must never be chosen, or a sample with p = 0 could come out of rounding near u = 1. */
static int last_with_mass(const rd_guide_pdf *pdf)
{
    for (int j = pdf->n - 1; j > 0; j--) {
        double A, B;
        seg_coeffs(pdf, &pdf->seg[j], &A, &B);
        if (A > 0.0 || B > 0.0) return j;
    }
    return 0;
}

/* Solve P(t0 + x) = u inside segment j, i.e. F(x) = A E(sigma, x) + B x = r := u - C0, for x in
 * [0, dt]; return t and the density there. */
static double invert_in_segment(const rd_guide_pdf *pdf, int j, double u, double *p)
{
    const rd_gpdf_seg *s = &pdf->seg[j];
    double dt = s->t1 - s->t0, r = u - s->C0, A, B, x;
    seg_coeffs(pdf, s, &A, &B);
    /* The prefix sums C0 are rounded independently of the segment's own mass F(dt), so u can
     * fall a few ulp past it; hold r just inside, where the density is still > 0 even when
     * exp(-sigma dt) underflows (the CDF moves by < 1e-15). */
    double Fdt = (A > 0.0 ? A * seg_integral(s->sigma, dt) : 0.0) + B * dt;
    if (r > Fdt * (1.0 - 4.0 * DBL_EPSILON)) r = Fdt * (1.0 - 4.0 * DBL_EPSILON);
    if (r <= 0.0) {
        x = 0.0;
    } else if (A <= 0.0) {
        /* uniform part only (alpha = 1, or f_j = 0): linear */
        x = B > 0.0 ? r / B : 0.0;
    } else if (B <= 0.0) {
        /* guide only (alpha = 0): the exponential inverted in closed form,
         * x = -log1p(-sigma r / A) / sigma (seed 001 eq. 16 integrated) */
        x = seg_integral_inv(s->sigma, r / A);
    } else {
        /* Both: F is increasing and concave (F' = A exp(-sigma x) + B > 0, F'' <= 0), so
         * Newton from the left never overshoots the root; bracket it anyway and bisect if a
         * step leaves the bracket (rounding). Upper bounds of the root: each term alone. */
        double lo = 0.0, hi = fmin(dt, fmin(r / B, seg_integral_inv(s->sigma, r / A)));
        x = lo;
        for (int it = 0; it < 200; it++) {
            double F = A * seg_integral(s->sigma, x) + B * x - r;
            if (F < 0.0) lo = x;
            else if (F > 0.0) hi = x;
            else break;
            double dF = A * exp(-s->sigma * x) + B;
            double xn = x - F / dF;
            if (!(xn > lo && xn < hi)) xn = 0.5 * (lo + hi);
            double tol = 4.0 * DBL_EPSILON * (fabs(s->t0) + fabs(xn)) + DBL_MIN;
            int done = fabs(xn - x) <= tol || hi - lo <= tol;
            x = xn;
            if (done) break;
        }
    }
    if (!(x >= 0.0)) x = 0.0;
    if (x > dt) x = dt;
    if (p) *p = seg_pdf(pdf, s, x);
    double t = s->t0 + x;
    return fmin(t, s->t1);
}

/* u into [0, 1): u = 1 (which (N - 1 + u) / N can round to) would land on the very end of the
 * last segment with mass, where T~ may have underflowed and p would be 0. */
static double clamp_u(double u)
{
    return u >= 1.0 ? 1.0 - 0.5 * DBL_EPSILON : (u > 0.0 ? u : 0.0);
}

double rd_guide_pdf_sample(const rd_guide_pdf *pdf, double u, double *p)
{
    if (pdf->n == 0) {
        if (p) *p = 0.0;
        return pdf->tmin;
    }
    u = clamp_u(u);
    /* Binary search over the segment prefix CDFs: largest j <= last with C0_j <= u. Zero-mass
     * segments have C0_{j+1} = C0_j, so the largest such j is never one of them (but the last
     * few, excluded by `last`). */
    int lo = 0, hi = pdf->last + 1;
    while (hi - lo > 1) {
        int mid = lo + (hi - lo) / 2;
        if (pdf->seg[mid].C0 <= u) lo = mid;
        else hi = mid;
    }
    return invert_in_segment(pdf, lo, u, p);
}

double rd_guide_pdf_tau(const rd_guide_pdf *pdf)
{
    if (pdf->n == 0) return 0.0;
    const rd_gpdf_seg *s = &pdf->seg[pdf->n - 1];
    return s->tau0 + s->sigma * (s->t1 - s->t0); /* tau_j of eq. 16 past the last segment */
}

void rd_guide_pdf_sample_stratified(const rd_guide_pdf *pdf, int N, double u, double *t,
                                    double *p)
{
    if (N <= 0) return;
    if (pdf->n == 0) {
        for (int n = 0; n < N; n++) {
            t[n] = pdf->tmin;
            if (p) p[n] = 0.0;
        }
        return;
    }
    /* THEORY.md §6 estimator: u_n = (n + u) / N through the one inverse CDF. The u_n increase,
     * so the segment index only moves forward: the same j the binary search would find. */
    int last = pdf->last, j = 0;
    for (int n = 0; n < N; n++) {
        double un = clamp_u((n + u) / N);
        while (j < last && pdf->seg[j + 1].C0 <= un) j++;
        t[n] = invert_in_segment(pdf, j, un, p ? &p[n] : NULL);
    }
}

int rd_guide_samples_per_ray(double I_ray, double mean_I, double N_mean, int N_min, int N_max)
{
    /* seed 001 eq. 17 (reconstructed, THEORY.md §6): N_ray proportional to I_ray. A ray with no
     * sample would drop its whole integral (a bias wherever the guide says 0 but the integrand
     * is not), so every ray gets at least one: N_min < 1 acts as 1. */
    if (N_min < 1) N_min = 1;
    if (N_max < N_min) N_max = N_min;
    double v = (mean_I > 0.0 && isfinite(mean_I)) ? N_mean * I_ray / mean_I : N_mean;
    if (isnan(v)) return N_min;
    v = round(v);
    if (v <= (double)N_min) return N_min;
    if (v >= (double)N_max) return N_max;
    return (int)v;
}

rd_status rd_guide_sampler_check(double alpha, int N_min, int N_max, char *err, size_t errlen)
{
    const char *why = NULL;
    if (!(alpha > 0.0 && alpha <= 1.0))
        why = "the defensive weight alpha must be in (0, 1]: with alpha = 0 a region the guide "
              "calls dark is never sampled, and the estimate is biased there";
    else if (N_min < 1)
        why = "N_min must be >= 1: a ray given no sample drops its whole integral";
    else if (N_max < N_min)
        why = "N_max must be >= N_min";
    if (!why) return RD_OK;
    if (err && errlen) snprintf(err, errlen, "%s", why);
    return RD_ERR_ARG;
}
