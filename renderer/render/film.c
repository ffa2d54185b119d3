/* film.c: the film's arrays and how the image and its standard error are resolved from them
 * (rd_film.h; docs/render-core.md, "The film").
 *
 * A pixel's mean is mu = sum w L / W, W = sum w over its n samples. Where every weight is 1 its
 * standard error is sqrt(s^2 / n), s^2 = (sum L^2 - sum L mu) / (n - 1), the unbiased sample
 * variance. Where the weights differ (settings.adaptive: integrators/select_share.c, "Weights")
 * it is the sandwich estimate, the weights taken as given: Var mu = sum w^2 V_i / W^2, each V_i
 * read from (L_i - mu)^2, so
 *     se^2 = (sum w^2 L^2 - 2 mu sum w^2 L + mu^2 sum w^2) / W^2 x n_e / (n_e - 1),
 * n_e = W^2 / sum w^2 the effective count: E[(L_i - mu)^2] = V_i - 2 w_i V_i / W + Var mu, and
 * with w_i proportional to 1 / V_i (what the weights are) the sum's expectation is Var mu
 * (1 - 1 / n_e), exactly; with every weight 1, n_e = n and the form is the one above. With
 * "epochs"' weights (the indices a sample stands for, not 1 / V_i) it is an approximation, and
 * reads low where one sample's weight dominates the pixel's (a share near the floor). */
#include "render/rd_film.h"
#include "integrators/rd_method.h"

#include <math.h>
#include <stdlib.h>

void rd_film_free(rd_film *f)
{
    free(f->sum), free(f->sum2), free(f->n);
    free(f->wl), free(f->wsum), free(f->wsum2);
    f->sum = f->sum2 = f->wl = f->wsum = f->wsum2 = NULL;
    f->n = NULL;
}

int rd_film_alloc(rd_film *f, int w, int h, int weighted)
{
    size_t np = (size_t)w * h;
    f->w = w, f->h = h;
    f->sum = rd_alloc_lines(np * 3 * sizeof *f->sum);
    f->sum2 = rd_alloc_lines(np * 3 * sizeof *f->sum2);
    f->n = rd_alloc_lines(np * sizeof *f->n);
    f->wl = f->wsum = f->wsum2 = NULL;
    if (weighted) {
        f->wl = rd_alloc_lines(np * 3 * sizeof *f->wl);
        f->wsum = rd_alloc_lines(np * sizeof *f->wsum);
        f->wsum2 = rd_alloc_lines(np * sizeof *f->wsum2);
    }
    if (f->sum && f->sum2 && f->n && (!weighted || (f->wl && f->wsum && f->wsum2))) return 1;
    rd_film_free(f);
    return 0;
}

/* Whether pixel p's samples weigh differently (else each weighs 1: sum w^2 = n exactly). */
static int weighed(const rd_film *f, size_t p)
{
    return f->wsum && f->wsum2[p] != (double)f->n[p];
}

void rd_film_sq_err(const rd_film *f, const rd_image *ref, double acc[3])
{
    size_t np = (size_t)f->w * f->h, m = 0;
    double se = 0.0;
    uint64_t total = 0;
    for (size_t p = 0; p < np; p++) {
        total += f->n[p];
        if (!f->n[p]) continue;
        const double W = weighed(f, p) ? f->wsum[p] : f->n[p];
        for (int c = 0; c < 3; c++) {
            double e = f->sum[3 * p + c] / W - ref->rgb[3 * p + c];
            se += e * e;
        }
        m += 3;
    }
    acc[0] += se;
    acc[1] += (double)m;
    acc[2] += (double)total;
}

void rd_film_resolve(const rd_film *f, float *mean, float *stderr_rgb)
{
    size_t np = (size_t)f->w * f->h;
    for (size_t p = 0; p < np; p++) {
        double n = f->n[p];
        for (int c = 0; c < 3; c++) {
            size_t i = 3 * p + c;
            double mu, var;
            if (weighed(f, p)) {
                const double W = f->wsum[p], ne = W * W / f->wsum2[p];
                mu = f->sum[i] / W;
                var = ne > 1.0 ? fmax(0.0, f->sum2[i] - 2.0 * mu * f->wl[i] + mu * mu * f->wsum2[p]) / (W * W) * ne / (ne - 1.0)
                               : 0.0;
            } else {
                mu = n > 0 ? f->sum[i] / n : 0.0;
                var = n > 1 ? fmax(0.0, (f->sum2[i] - f->sum[i] * mu) / (n - 1.0)) / n : 0.0;
            }
            mean[i] = (float)mu;
            stderr_rgb[i] = (float)sqrt(var);
        }
    }
}
