/* sh_math.c: real spherical harmonics, Legendre polynomials, Gauss-Legendre quadrature and the
 * Legendre coefficients of phase functions (THEORY.md §4; seed 001 §3.2 and appendix A). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "sh.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static void set_err(char *err, size_t errlen, const char *fmt, ...)
{
    if (!err || errlen == 0)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

const char *sh_status_name(sh_status s)
{
    switch (s) {
    case SH_OK: return "ok";
    case SH_ERR_ARG: return "bad argument";
    case SH_ERR_NOMEM: return "out of memory";
    case SH_ERR_IO: return "i/o error";
    case SH_ERR_FORMAT: return "bad file format";
    case SH_ERR_PHOTONMAP: return "photon map query failed";
    case SH_ERR_CANCELLED: return "cancelled";
    }
    return "unknown status";
}

/* ---- Real SH by the normalised associated-Legendre recurrence ------------------------------
 *
 * With z = cos theta and Q_l^m = K_lm P_l^m(z) / sin^m(theta) (no Condon-Shortley phase):
 *   Q_0^0     = 1 / sqrt(4 pi)
 *   Q_m^m     = Q_{m-1}^{m-1} sqrt((2m+1) / (2m))                       (P_m^m = (2m-1)!! s^m)
 *   Q_{m+1}^m = z sqrt(2m+3) Q_m^m
 *   Q_l^m     = a_lm (z Q_{l-1}^m - b_lm Q_{l-2}^m),
 *               a_lm = sqrt((4l^2-1)/(l^2-m^2)), b_lm = sqrt(((l-1)^2-m^2)/(4(l-1)^2-1))
 * and sin^m(theta) (cos m phi + i sin m phi) = (x + i y)^m, advanced by one complex product per
 * m. Then Y_l0 = Q_l^0, Y_lm = sqrt2 Q_l^m Re(x+iy)^m, Y_l-m = sqrt2 Q_l^m Im(x+iy)^m.
 * The normalised form stays in range for any l (no factorials). */

sh_status sh_basis_init(sh_basis *basis, int bands)
{
    if (!basis || bands < 1 || bands > SH_MAX_BANDS)
        return SH_ERR_ARG;
    memset(basis, 0, sizeof *basis);
    basis->bands = bands;
    for (int m = 0; m < bands; m++) {
        basis->mm[m] = m == 0 ? 1.0 / sqrt(4.0 * M_PI) : sqrt((2.0 * m + 1.0) / (2.0 * m));
        if (m + 1 < bands)
            basis->a[SH_INDEX(m + 1, m)] = sqrt(2.0 * m + 3.0);
        for (int l = m + 2; l < bands; l++) {
            double l2 = (double)l * l, m2 = (double)m * m, lm1 = (double)(l - 1);
            basis->a[SH_INDEX(l, m)] = sqrt((4.0 * l2 - 1.0) / (l2 - m2));
            basis->b[SH_INDEX(l, m)] = sqrt((lm1 * lm1 - m2) / (4.0 * lm1 * lm1 - 1.0));
        }
    }
    return SH_OK;
}

static void basis_eval(const sh_basis *B, const double w[3], double *y)
{
    const int L = B->bands;
    double x = w[0], yy = w[1], z = w[2];
    double n2 = x * x + yy * yy + z * z;
    if (n2 > 0.0 && isfinite(n2)) {
        double inv = 1.0 / sqrt(n2);
        x *= inv, yy *= inv, z *= inv;
    } else {
        x = 0.0, yy = 0.0, z = 1.0;
    }
    const double s2 = sqrt(2.0);
    double qmm = 0.0;      /* Q_m^m */
    double cm = 1.0, sm = 0.0; /* (x + i y)^m */
    for (int m = 0; m < L; m++) {
        if (m == 0) {
            qmm = B->mm[0];
        } else {
            qmm *= B->mm[m];
            double c = cm * x - sm * yy, s = cm * yy + sm * x;
            cm = c, sm = s;
        }
        double fc = m == 0 ? 1.0 : s2 * cm, fs = s2 * sm;
        /* l = m */
        double q2 = 0.0, q1 = qmm;
        y[SH_INDEX(m, m)] = q1 * fc;
        if (m > 0)
            y[SH_INDEX(m, -m)] = q1 * fs;
        /* l = m + 1 */
        if (m + 1 < L) {
            double q = z * B->a[SH_INDEX(m + 1, m)] * q1;
            q2 = q1, q1 = q;
            y[SH_INDEX(m + 1, m)] = q * fc;
            if (m > 0)
                y[SH_INDEX(m + 1, -m)] = q * fs;
        }
        for (int l = m + 2; l < L; l++) {
            double q = B->a[SH_INDEX(l, m)] * (z * q1 - B->b[SH_INDEX(l, m)] * q2);
            q2 = q1, q1 = q;
            y[SH_INDEX(l, m)] = q * fc;
            if (m > 0)
                y[SH_INDEX(l, -m)] = q * fs;
        }
    }
}

void sh_basis_eval(const sh_basis *basis, const double w[3], double *y)
{
    basis_eval(basis, w, y);
}

void sh_basis_evalf(const sh_basis *basis, const double w[3], float *y)
{
    double tmp[SH_MAX_COEFFS];
    basis_eval(basis, w, tmp);
    int n = basis->bands * basis->bands;
    for (int i = 0; i < n; i++)
        y[i] = (float)tmp[i];
}

void sh_eval_basis(int bands, const double w[3], double *y)
{
    sh_basis B;
    if (sh_basis_init(&B, bands) != SH_OK)
        return;
    basis_eval(&B, w, y);
}

/* ---- Legendre polynomials and Gauss-Legendre quadrature ----------------------------------- */

double sh_legendre(int l, double x)
{
    if (l <= 0)
        return 1.0;
    double p0 = 1.0, p1 = x;
    /* Bonnet: (n+1) P_{n+1} = (2n+1) x P_n - n P_{n-1} */
    for (int n = 1; n < l; n++) {
        double p2 = ((2.0 * n + 1.0) * x * p1 - n * p0) / (n + 1.0);
        p0 = p1, p1 = p2;
    }
    return p1;
}

void sh_legendre_all(int n, double x, double *p)
{
    if (n <= 0)
        return;
    p[0] = 1.0;
    if (n > 1)
        p[1] = x;
    for (int l = 1; l + 1 < n; l++)
        p[l + 1] = ((2.0 * l + 1.0) * x * p[l] - l * p[l - 1]) / (l + 1.0);
}

/* Nodes are the roots of P_n, found by Newton from the Tricomi estimate
 * cos(pi (i + 3/4) / (n + 1/2)); w_i = 2 / ((1 - x_i^2) P_n'(x_i)^2). */
sh_status sh_gauss_legendre(int n, double *nodes, double *weights)
{
    if (n < 1 || n > 4096 || !nodes || !weights)
        return SH_ERR_ARG;
    for (int i = 0; i < (n + 1) / 2; i++) {
        double x = cos(M_PI * (i + 0.75) / (n + 0.5));
        double dp = 1.0;
        for (int it = 0; it < 100; it++) {
            double p0 = 1.0, p1 = x;
            for (int k = 1; k < n; k++) {
                double p2 = ((2.0 * k + 1.0) * x * p1 - k * p0) / (k + 1.0);
                p0 = p1, p1 = p2;
            }
            if (n == 1)
                p0 = 1.0, p1 = x;
            /* P_n' = n (x P_n - P_{n-1}) / (x^2 - 1) */
            dp = n * (x * p1 - p0) / (x * x - 1.0);
            double dx = p1 / dp;
            x -= dx;
            if (fabs(dx) < 1e-16)
                break;
        }
        {
            double p0 = 1.0, p1 = x;
            for (int k = 1; k < n; k++) {
                double p2 = ((2.0 * k + 1.0) * x * p1 - k * p0) / (k + 1.0);
                p0 = p1, p1 = p2;
            }
            if (n == 1)
                p0 = 1.0, p1 = x;
            dp = n * (x * p1 - p0) / (x * x - 1.0);
        }
        double w = 2.0 / ((1.0 - x * x) * dp * dp);
        nodes[i] = -x;
        nodes[n - 1 - i] = x;
        weights[i] = w;
        weights[n - 1 - i] = w;
    }
    if (n % 2 == 1)
        nodes[n / 2] = 0.0;
    return SH_OK;
}

/* ---- Phase functions ---------------------------------------------------------------------- */

double sh_phase_hg(double mu, double g)
{
    double den = 1.0 + g * g - 2.0 * g * mu;
    return (1.0 - g * g) / (4.0 * M_PI * den * sqrt(den));
}

sh_status sh_phase_coeffs_hg(double g, int bands, double *b)
{
    if (!b || bands < 1 || bands > SH_MAX_BANDS || !(g > -1.0 && g < 1.0))
        return SH_ERR_ARG;
    double gl = 1.0;
    for (int l = 0; l < bands; l++) { /* b_l = g^l (THEORY.md §4) */
        b[l] = gl;
        gl *= g;
    }
    return SH_OK;
}

double sh_phase_truncated(const double *b, int bands, double mu)
{
    double P[SH_MAX_BANDS];
    if (bands < 1 || bands > SH_MAX_BANDS)
        return 0.0;
    sh_legendre_all(bands, mu, P);
    double s = 0.0;
    for (int l = 0; l < bands; l++)
        s += (2.0 * l + 1.0) / (4.0 * M_PI) * b[l] * P[l];
    return s;
}

sh_status sh_window_hann(int bands, double *w)
{
    if (!w || bands < 1 || bands > SH_MAX_BANDS)
        return SH_ERR_ARG;
    for (int l = 0; l < bands; l++) /* w_l = (1 + cos(pi l / L)) / 2 */
        w[l] = 0.5 * (1.0 + cos(M_PI * l / bands));
    return SH_OK;
}

/* Adaptive composite Gauss-Legendre for the vector integrand p(mu) P_l(mu), l < bands. */
#define GL_PANEL 20
typedef struct {
    sh_phase_fn phase;
    void *user;
    int bands;
    double x[GL_PANEL], w[GL_PANEL];
    long evals;
    int bad;          /* non-finite value seen */
    double bad_mu;
    double tol;       /* absolute tolerance per unit of mu-length */
} quad_ctx;

static void panel(quad_ctx *q, double a, double b, double *out)
{
    double P[SH_MAX_BANDS];
    double h = 0.5 * (b - a), c = 0.5 * (a + b);
    for (int l = 0; l < q->bands; l++)
        out[l] = 0.0;
    for (int i = 0; i < GL_PANEL; i++) {
        double mu = c + h * q->x[i];
        double p = q->phase(mu, q->user);
        q->evals++;
        if (!isfinite(p)) {
            if (!q->bad)
                q->bad_mu = mu;
            q->bad = 1;
            p = 0.0;
        }
        sh_legendre_all(q->bands, mu, P);
        for (int l = 0; l < q->bands; l++)
            out[l] += h * q->w[i] * p * P[l];
    }
}

static void adapt(quad_ctx *q, double a, double b, const double *whole, int depth, double *acc)
{
    double left[SH_MAX_BANDS], right[SH_MAX_BANDS];
    double m = 0.5 * (a + b);
    panel(q, a, m, left);
    panel(q, m, b, right);
    double diff = 0.0;
    for (int l = 0; l < q->bands; l++)
        diff = fmax(diff, fabs(whole[l] - left[l] - right[l]));
    if (diff <= q->tol * (b - a) || depth >= 48 || q->evals > 4000000 || q->bad) {
        for (int l = 0; l < q->bands; l++)
            acc[l] += left[l] + right[l];
        return;
    }
    adapt(q, a, m, left, depth + 1, acc);
    adapt(q, m, b, right, depth + 1, acc);
}

sh_status sh_phase_coeffs(sh_phase_fn phase, void *user, int bands, double *b, char *err,
                          size_t errlen)
{
    if (!phase || !b || bands < 1 || bands > SH_MAX_BANDS) {
        set_err(err, errlen, "sh_phase_coeffs: bands must be 1..%d and phase, b non-NULL",
                SH_MAX_BANDS);
        return SH_ERR_ARG;
    }
    quad_ctx q;
    memset(&q, 0, sizeof q);
    q.phase = phase, q.user = user, q.bands = bands;
    sh_gauss_legendre(GL_PANEL, q.x, q.w);
    /* Scale the tolerance by a coarse estimate of int |p| so that it is relative. */
    double acc[SH_MAX_BANDS] = {0};
    const int start = 16;
    double coarse = 0.0;
    double first[16][SH_MAX_BANDS];
    for (int i = 0; i < start; i++) {
        double a = -1.0 + 2.0 * i / start, c = -1.0 + 2.0 * (i + 1) / start;
        panel(&q, a, c, first[i]);
        coarse += fabs(first[i][0]);
    }
    q.tol = 1e-13 * fmax(coarse, 1e-300);
    for (int i = 0; i < start && !q.bad; i++) {
        double a = -1.0 + 2.0 * i / start, c = -1.0 + 2.0 * (i + 1) / start;
        adapt(&q, a, c, first[i], 0, acc);
    }
    if (q.bad) {
        set_err(err, errlen, "sh_phase_coeffs: phase function is not finite at mu = %.17g",
                q.bad_mu);
        return SH_ERR_ARG;
    }
    for (int l = 0; l < bands; l++)
        b[l] = 2.0 * M_PI * acc[l]; /* b_l = 2 pi int p P_l dmu (THEORY.md §4) */
    return SH_OK;
}

/* ---- Projection and evaluation (THEORY.md §4) --------------------------------------------- */

void sh_project_add(int bands, const double *b, const double *y, const double power[3],
                    double scale, double *coeffs)
{
    const int n = bands * bands;
    for (int l = 0; l < bands; l++) {
        for (int m = -l; m <= l; m++) {
            int i = SH_INDEX(l, m);
            double v = scale * b[l] * y[i]; /* c_lm += dPhi b_l Y_lm(w') / |V| */
            for (int c = 0; c < SH_CHANNELS; c++)
                coeffs[c * n + i] += power[c] * v;
        }
    }
}

/* f_c(w) over the first `use` bands of coefficients stored `bands` to a channel. */
static void eval_rgb(int bands, int use, const float *coeffs, const float *y, float out[3])
{
    /* Eight independent partial sums per channel: the serial sum is one dependency chain of
     * L^2 additions (IEEE order forbids the compiler to split it), the eight lanes are what
     * the vectoriser turns into two SIMD accumulators. The guided methods call this for every
     * guide cell a ray crosses (renderer/integrators/guide_pdf.c). */
    const int n = use * use, stride = bands * bands;
    for (int c = 0; c < SH_CHANNELS; c++) {
        const float *cc = coeffs + (size_t)c * stride;
        float s[8] = {0, 0, 0, 0, 0, 0, 0, 0}, t = 0.0f;
        int i = 0;
        for (; i + 8 <= n; i += 8)
            for (int k = 0; k < 8; k++)
                s[k] += cc[i + k] * y[i + k];
        for (; i < n; i++)
            t += cc[i] * y[i];
        out[c] = ((s[0] + s[4]) + (s[1] + s[5])) + ((s[2] + s[6]) + (s[3] + s[7])) + t;
    }
}

void sh_eval_rgb(int bands, const float *coeffs, const float *y, float out[3])
{
    eval_rgb(bands, bands, coeffs, y, out);
}

void sh_eval_rgb_clamped(int bands, const float *coeffs, const float *y, float out[3])
{
    sh_eval_rgb(bands, coeffs, y, out);
    for (int c = 0; c < SH_CHANNELS; c++)
        out[c] = out[c] > 0.0f ? out[c] : 0.0f; /* truncation rings (THEORY.md §4) */
}

float sh_eval_guide(int bands, const float *coeffs, const float *y)
{
    return sh_eval_guide_bands(bands, bands, coeffs, y);
}

float sh_eval_guide_bands(int bands, int use, const float *coeffs, const float *y)
{
    float f[3];
    eval_rgb(bands, use < bands ? use : bands, coeffs, y, f);
    for (int c = 0; c < SH_CHANNELS; c++)
        f[c] = f[c] > 0.0f ? f[c] : 0.0f; /* truncation rings (THEORY.md §4) */
    return (f[0] + f[1] + f[2]) * (1.0f / 3.0f);
}
