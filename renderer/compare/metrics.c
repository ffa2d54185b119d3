/* metrics.c: the metrics of THEORY.md §7 on images, against a reference r (docs/compare.md):
 * RMSE, relMSE = mean (x - r)^2 / (r^2 + eps) and the mean absolute relative error of one
 * image; bias^2 and variance from K independent runs (bias^2 ~= mean over pixels of
 * (mean_k - r)^2 - var / K, less the reference's own variance); noise homogeneity, the ratio
 * of the 90th to the 50th percentile of the per-pixel relative error of luminance. Pure
 * functions of the images: runs.c applies them to every method's runs. */
#include "compare/rd_compare.h"

#include <math.h>
#include <stdlib.h>

rd_status rd_cmp_errors_of(const rd_image *x, const rd_image *r, rd_cmp_errors *out, char *err,
                           size_t errlen)
{
    if (x->w != r->w || x->h != r->h) return fail(err, errlen, RD_ERR_ARG, "%s: image sizes differ", "compare");
    size_t n = (size_t)x->w * x->h * 3;
    double se = 0.0, rel = 0.0, abs_rel = 0.0;
    for (size_t i = 0; i < n; i++) {
        double d = (double)x->rgb[i] - r->rgb[i], ri = r->rgb[i];
        se += d * d;                             /* MSE */
        rel += d * d / (ri * ri + RD_CMP_EPS);   /* relMSE = mean (x-r)^2 / (r^2 + eps) */
        abs_rel += fabs(d) / (fabs(ri) + RD_CMP_EPS);
    }
    out->mse = n ? se / n : 0.0;
    out->rmse = sqrt(out->mse);
    out->relmse = n ? rel / n : 0.0;
    out->mare = n ? abs_rel / n : 0.0;
    return RD_OK;
}

/* Mean and unbiased sample variance over k images of value i. */
static void moments(const rd_image *runs, int k, size_t i, double *mean, double *var)
{
    double s = 0.0, s2 = 0.0;
    for (int j = 0; j < k; j++) s += runs[j].rgb[i];
    double m = s / k;
    for (int j = 0; j < k; j++) s2 += (runs[j].rgb[i] - m) * (runs[j].rgb[i] - m);
    *mean = m;
    *var = s2 / (k - 1);
}

rd_status rd_cmp_split_of(const rd_image *runs, int k, const rd_image *r, const rd_image *r_stderr,
                          rd_cmp_split *out, char *err, size_t errlen)
{
    if (k < 2) return fail(err, errlen, RD_ERR_ARG, "%s: bias and variance need at least 2 runs", "compare");
    for (int j = 0; j < k; j++)
        if (runs[j].w != r->w || runs[j].h != r->h) return fail(err, errlen, RD_ERR_ARG, "%s: image sizes differ", "compare");
    size_t n = (size_t)r->w * r->h * 3;
    /* Per value: d = (m - r)^2 - s^2 / k - ref_var, an unbiased estimate of bias^2 there
     * (E[(m - r)^2] = bias^2 + var / k + ref_var for a reference independent of the runs). */
    double var_sum = 0.0, d_sum = 0.0, d_sum2 = 0.0;
    for (size_t i = 0; i < n; i++) {
        double m, v;
        moments(runs, k, i, &m, &v);
        double rv = r_stderr ? (double)r_stderr->rgb[i] * r_stderr->rgb[i] : 0.0;
        double d = (m - r->rgb[i]) * (m - r->rgb[i]) - v / k - rv;
        var_sum += v;
        d_sum += d;
        d_sum2 += d * d;
    }
    out->variance = var_sum / n;
    out->bias2 = d_sum / n;
    /* Standard error of that mean over the n values (treated as independent). */
    double sd2 = n > 1 ? (d_sum2 - d_sum * d_sum / n) / (n - 1) : 0.0;
    out->bias2_se = sqrt(fmax(0.0, sd2) / n);
    return RD_OK;
}

double rd_cmp_homogeneity(const rd_image *x, const rd_image *r)
{
    size_t np = (size_t)r->w * r->h, lit = 0;
    if (x->w != r->w || x->h != r->h || np == 0) return 0.0;
    double mean = 0.0;
    for (size_t p = 0; p < np; p++) mean += luminance(r->rgb + 3 * p);
    mean /= np;
    double *e = malloc(np * sizeof *e);
    if (!e) return 0.0;
    for (size_t p = 0; p < np; p++) {
        double lr = luminance(r->rgb + 3 * p);
        if (lr > 0.01 * mean && mean > 0) e[lit++] = fabs(luminance(x->rgb + 3 * p) - lr) / (lr + RD_CMP_EPS);
    }
    double h = 0.0;
    if (lit >= 10) {
        qsort(e, lit, sizeof *e, cmp_double);
        double p50 = e[lit / 2], p90 = e[(size_t)(0.9 * (lit - 1))];
        h = p50 > 0 ? p90 / p50 : 0.0;
    }
    free(e);
    return h;
}

/* The default reference's rule (renderer.h; docs/compare.md). With v(N) = ref_var spp / N the
 * reference's variance at N samples per pixel and m = best_mse - ref_var the best method's own
 * error, the rule v(N) <= share (m + v(N)) holds for v(N) <= share / (1 - share) m. */
double rd_cmp_ref_spp_needed(double spp, double ref_var, double best_mse)
{
    const double share = RD_CMP_REF_SHARE;
    if (!(ref_var > share * best_mse) || !(best_mse > 0)) return spp;
    /* When the reference's variance is nearly all of the best MSE, m is not measurable yet:
     * it is taken as at least a thousandth of best_mse, so the aim is far and the cap decides. */
    double m = fmax(best_mse - ref_var, 1e-3 * best_mse);
    double v = share / (1.0 - share) * m;
    return fmin(ceil(1.1 * spp * ref_var / v), (double)(1 << 24));
}
