/* bench_pixel_corr: are the pixels of one image independent? (issue 24)
 *
 *   bench_pixel_corr [--quick] [--json FILE]
 *
 * The statistic of tests/test_render.c's pixels_of_one_image_are_uncorrelated, with many more
 * seeds: over K renders (seeds 1..K) of an orthographic view into a slab lit by one directional
 * light, `delta`, R = (variance of the image mean over the renders) / (the variance the pixels'
 * standard errors predict, sum se^2 / P^2). With an average correlation rho between pixels,
 * E[R] = 1 + (P - 1) rho; without, R has standard error sqrt(2 / (K - 1)) (chi-square), so rho is
 * measured to +- sqrt(2 / (K - 1)) / (P - 1). Two designs: the issue's own (24 x 24 pixels,
 * 96 spp, where 40 seeds gave R = 1.63) and the test's (64 x 64, 16 spp), each with 1000 seeds. Also printed: R over consecutive windows of 40 seeds (the sample size), whose
 * spread shows how far one such window moves by chance, and the excess kurtosis of the image
 * means (0 for a normal law, which the chi-square assumes). --quick: a fifth of the seeds. */
#include "renderer.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *scene_fmt =
    "{\"camera\":{\"type\":\"orthographic\",\"position\":[0,0,5],\"direction\":[0,0,-1],\"up\":[0,1,0],"
    "\"width\":2,\"resolution\":[%d,%d]},"
    "\"media\":[{\"bounds\":{\"min\":[-1.5,-1.5,-0.5],\"max\":[1.5,1.5,0.5]},"
    "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1,\"albedo\":0.8,\"g\":0.3}],"
    "\"lights\":[{\"type\":\"directional\",\"direction\":[0.3,-1,-0.2],\"irradiance\":2}]}";

static int run(int n, int spp, int K, FILE *js, int first)
{
    char path[] = "/tmp/bench_pixel_corr.XXXXXX", err[RD_ERRLEN];
    int fd = mkstemp(path);
    if (fd < 0) { perror("mkstemp"); return 1; }
    FILE *f = fdopen(fd, "w");
    fprintf(f, scene_fmt, n, n);
    fclose(f);
    rd_scene *s = NULL;
    rd_status st = rd_scene_load(&s, path, NULL, 0, err, sizeof err);
    remove(path);
    if (st != RD_OK) { fprintf(stderr, "%s\n", err); return 1; }
    int P = n * n;
    double *m = calloc((size_t)K, sizeof *m), *v = calloc((size_t)K, sizeof *v);
    for (int k = 0; k < K; k++) {
        rd_render_opts o = {.method = "delta", .spp = spp, .seed = (uint64_t)(1 + k), .threads = 2};
        rd_render_result r;
        if (rd_render(s, &o, &r, err, sizeof err) != RD_OK) { fprintf(stderr, "%s\n", err); return 1; }
        double sum = 0, se2 = 0;
        for (int p = 0; p < P; p++) {
            double se = r.stderr_img.rgb[3 * p + 1];
            sum += r.image.rgb[3 * p + 1];
            se2 += se * se;
        }
        m[k] = sum / P;
        v[k] = se2 / ((double)P * P);
        rd_render_result_free(&r);
    }
    double mu = 0, s2 = 0, vbar = 0, m4 = 0;
    for (int k = 0; k < K; k++) mu += m[k] / K, vbar += v[k] / K;
    for (int k = 0; k < K; k++) {
        double d = m[k] - mu;
        s2 += d * d / (K - 1);
        m4 += d * d * d * d / K;
    }
    double R = s2 / vbar, se = sqrt(2.0 / (K - 1));
    printf("%dx%d pixels, %d spp, %d seeds: R = %.3f +- %.3f (z = %+.2f); average correlation %.2g +- %.2g; "
           "excess kurtosis of the image mean %.2f\n",
           n, n, spp, K, R, se, (R - 1) / se, (R - 1) / (P - 1), se / (P - 1), m4 / (s2 * s2) - 3);
    printf("  R over windows of 40 seeds:");
    for (int w = 0; w + 40 <= K; w += 40) {
        double a = 0, b = 0, c = 0;
        for (int k = w; k < w + 40; k++) a += m[k] / 40, c += v[k] / 40;
        for (int k = w; k < w + 40; k++) b += (m[k] - a) * (m[k] - a) / 39;
        printf(" %.2f", b / c);
    }
    printf("  (one window's standard error %.2f)\n", sqrt(2.0 / 39));
    fprintf(js, "%s  {\"pixels\": %d, \"spp\": %d, \"seeds\": %d, \"R\": %.6g, \"R_se\": %.6g, \"rho\": %.6g, \"rho_se\": %.6g}",
            first ? "" : ",\n", P, spp, K, R, se, (R - 1) / (P - 1), se / (P - 1));
    free(m);
    free(v);
    rd_scene_free(s);
    return 0;
}

int main(int argc, char **argv)
{
    int quick = 0;
    const char *json = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--quick")) quick = 1;
        else if (!strcmp(argv[i], "--json") && i + 1 < argc) json = argv[++i];
        else {
            fprintf(stderr, "usage: %s [--quick] [--json FILE]\n", argv[0]);
            return 1;
        }
    }
    FILE *js = json ? fopen(json, "w") : fopen("/dev/null", "w");
    if (!js) { perror(json); return 1; }
    printf("# pixel correlation of delta renders (slab, orthographic, directional light)%s\n",
           quick ? " (--quick: not the figures)" : "");
    fprintf(js, "[\n");
    int q = quick ? 5 : 1;
    if (run(24, 96, 1000 / q, js, 1) || run(64, 16, 1000 / q, js, 0)) return 1;
    fprintf(js, "\n]\n");
    fclose(js);
    return 0;
}
