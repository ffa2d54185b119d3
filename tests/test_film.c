/* test_film.c: the film's means and standard errors (render/film.c), with and without weights. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>

#include "render/rd_film.h"

/* Pixel 0: samples 1, 2, 3, 4 (x; y = 2x; z = 0) of weight 1: the mean 2.5 and sqrt(s^2 / n),
 * s^2 = 5/3, on a film with weights and on one without, to the bit. Pixel 1: 1 and 3 of
 * weight 1 and 2 of weight 10: the mean (1 + 3 + 20) / 12 = 2, and the sandwich error
 * sum w^2 (L - mu)^2 / W^2 x n_e / (n_e - 1) = 2 / 144 x (144 / 102) / (144 / 102 - 1) = 2 / 42. */
Test(film, weighted_mean_and_error_by_hand)
{
    rd_film f = {0}, g = {0};
    cr_assert(rd_film_alloc(&f, 2, 1, 1) && rd_film_alloc(&g, 2, 1, 0), "out of memory");
    rd_film_pixel a, b;
    rd_film_load(&f, 0, &a), rd_film_load(&g, 0, &b);
    for (int i = 1; i <= 4; i++) rd_film_add(&a, (vec3){i, 2.0 * i, 0.0}, 1.0), rd_film_add(&b, (vec3){i, 2.0 * i, 0.0}, 1.0);
    rd_film_store(&f, 0, &a), rd_film_store(&g, 0, &b);
    rd_film_load(&f, 1, &a);
    rd_film_add(&a, (vec3){1.0, 1.0, 1.0}, 1.0), rd_film_add(&a, (vec3){3.0, 3.0, 3.0}, 1.0);
    rd_film_add(&a, (vec3){2.0, 2.0, 2.0}, 10.0);
    rd_film_store(&f, 1, &a);
    float mf[6], sf[6], mg[6], sg[6];
    rd_film_resolve(&f, mf, sf), rd_film_resolve(&g, mg, sg);
    cr_assert(mf[0] == 2.5f && mf[1] == 5.0f && mf[2] == 0.0f, "pixel 0's mean (%g, %g, %g)", mf[0], mf[1], mf[2]);
    cr_assert(fabs(sf[0] - sqrt(5.0 / 12.0)) < 1e-6 && fabs(sf[1] - 2.0 * sqrt(5.0 / 12.0)) < 1e-6 && sf[2] == 0.0f,
              "pixel 0's standard error (%g, %g, %g)", sf[0], sf[1], sf[2]);
    cr_assert(mf[0] == mg[0] && mf[1] == mg[1] && sf[0] == sg[0] && sf[1] == sg[1],
              "weights of 1 changed the pixel: the film without weights gives (%g, %g)", mg[0], sg[0]);
    for (int c = 0; c < 3; c++) {
        cr_assert(fabs(mf[3 + c] - 2.0) < 1e-6, "pixel 1's weighted mean %g, not 2", mf[3 + c]);
        cr_assert(fabs(sf[3 + c] - sqrt(2.0 / 42.0)) < 1e-6, "pixel 1's standard error %g, not %g", sf[3 + c], sqrt(2.0 / 42.0));
    }
    rd_image ref = {.w = 2, .h = 1, .rgb = (float[6]){2.5f, 5.0f, 0.0f, 1.0f, 1.0f, 1.0f}};
    double acc[3] = {0.0, 0.0, 0.0};
    rd_film_sq_err(&f, &ref, acc);
    cr_assert(fabs(acc[0] - 3.0) < 1e-12 && acc[1] == 6.0 && acc[2] == 7.0, "squared error %g over %g channels, %g samples",
              acc[0], acc[1], acc[2]);
    rd_film_free(&f), rd_film_free(&g);
    rd_film_free(&f); /* (a second call is harmless) */
}

/* A standard normal (Box-Muller). */
static double normal(pcg32 *g)
{
    double u = fmax(pcg32_uniform(g), 1e-300), w = pcg32_uniform(g);
    return sqrt(-2.0 * log(u)) * cos(2.0 * M_PI * w);
}

/* The weighted standard error is honest: P pixels (independent, seeded), each with 40 samples of
 * mean 1 and variance 1 at weight 1 and 8 of variance 0.01 at weight 100 (inverse variances, as
 * the selection's weights are: integrators/select_share.c "Weights"; n_e = 8.8 of 48). Over the
 * pixels, R = sum (mean - 1)^2 / sum se^2 is 1; its standard error from the pixels' pairs (the
 * delta method; they are independent), tolerance 5 of them (about 0.05). The form with n / (n - 1)
 * for n_e / (n_e - 1) reads the variance 10% low: E[R] = 1.10, which the test tells apart
 * (asserted on the same samples). */
Test(film, weighted_standard_error_matches_the_spread)
{
    enum { P = 20000 };
    rd_film f = {0};
    cr_assert(rd_film_alloc(&f, P, 1, 1), "out of memory");
    pcg32 g = pcg32_seed(17, 23, 2026);
    for (int p = 0; p < P; p++) {
        rd_film_pixel a;
        rd_film_load(&f, p, &a);
        for (int i = 0; i < 48; i++) {
            const double sd = i < 40 ? 1.0 : 0.1, L = 1.0 + sd * normal(&g);
            rd_film_add(&a, (vec3){L, L, L}, 1.0 / (sd * sd));
        }
        rd_film_store(&f, p, &a);
    }
    float *mean = malloc(3 * P * sizeof *mean), *se = malloc(3 * P * sizeof *se);
    cr_assert(mean && se, "out of memory");
    rd_film_resolve(&f, mean, se);
    double A = 0.0, B = 0.0, Bn = 0.0;
    for (int p = 0; p < P; p++) {
        const double d = mean[3 * p] - 1.0, n = f.n[p], W = f.wsum[p], ne = W * W / f.wsum2[p];
        A += d * d, B += (double)se[3 * p] * se[3 * p];
        Bn += (double)se[3 * p] * se[3 * p] / (ne / (ne - 1.0)) * (n / (n - 1.0)); /* the wrong correction */
    }
    const double R = A / B, Rn = A / Bn;
    double v = 0.0;
    for (int p = 0; p < P; p++) {
        const double d = mean[3 * p] - 1.0, s2 = (double)se[3 * p] * se[3 * p];
        v += (d * d - R * s2) * (d * d - R * s2);
    }
    const double sigma = sqrt(v) / B;
    cr_log_info("weighted film: (mean - 1)^2 / se^2 = %.4f +- %.4f; with n / (n - 1): %.4f", R, sigma, Rn);
    cr_expect(fabs(R - 1.0) < 5.0 * sigma, "(mean - 1)^2 / se^2 = %.4f +- %.4f", R, sigma);
    cr_expect(fabs(Rn - 1.0) > 5.0 * sigma, "the test cannot tell n / (n - 1) from n_e / (n_e - 1): %.4f", Rn);
    free(mean), free(se);
    rd_film_free(&f);
}
