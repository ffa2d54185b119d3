/* bench_bias: how far one render's mean lies from a reference, and where.
 *
 *   build/bench/bench_bias REF.exr IMG.exr
 *
 * Both files come with their per-pixel standard errors beside them (REF-stderr.exr,
 * IMG-stderr.exr, as `photonmarch render` writes them). Over the lit pixels (luminance of the
 * reference above 5% of its largest), on the luminance:
 *   - the relative bias of the image's sum, sum (x - r) / sum r, with its standard error from
 *     both files' (independent renders: the variances add);
 *   - the per-pixel squared bias, the mean of (x - r)^2 less both variances (the part of the
 *     error no number of samples of the same estimator removes), and the image's own variance;
 *   - the relative bias in six bands of rows, and in the edge band (lit pixels within 3 pixels
 *     of an unlit one or of the image's border) against the rest.
 * A consistent estimator's kernel bias shows here as a mean offset or as an edge band apart from
 * the inside (docs/benchmarks.md "Session 54": the photon estimates at a box medium's faces).
 * Without arguments (as `make bench` runs every tool) it says so and exits 0. */
#include "renderer.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define EDGE 3
#define BANDS 6

static double lum(const float *p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

/* X.exr and X-stderr.exr; 0 on success, the error printed otherwise. */
static int read_pair(const char *path, rd_image *img, rd_image *se)
{
    char err[RD_ERRLEN], sp[4096];
    size_t n = strlen(path);
    if (n < 5 || strcmp(path + n - 4, ".exr") || n + 8 >= sizeof sp) {
        fprintf(stderr, "bench_bias: %s: not an .exr path\n", path);
        return -1;
    }
    snprintf(sp, sizeof sp, "%.*s-stderr.exr", (int)(n - 4), path);
    if (rd_image_read(path, img, err, sizeof err) != RD_OK || rd_image_read(sp, se, err, sizeof err) != RD_OK) {
        fprintf(stderr, "bench_bias: %s\n", err);
        return -1;
    }
    if (img->w != se->w || img->h != se->h) {
        fprintf(stderr, "bench_bias: %s: its standard errors are %dx%d, the image %dx%d\n", sp, se->w, se->h, img->w,
                img->h);
        return -1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 1 || argv[1][0] == '-') { /* `make bench` runs every tool with [--quick] --json FILE */
        printf("bench_bias: a tool for a render against a reference (see its header); nothing to run here\n");
        return 0;
    }
    if (argc != 3) {
        fprintf(stderr, "usage: bench_bias REF.exr IMG.exr (each with its -stderr.exr beside it)\n");
        return 1;
    }
    rd_image ref, rse, img, ise;
    if (read_pair(argv[1], &ref, &rse) || read_pair(argv[2], &img, &ise)) return 2;
    if (img.w != ref.w || img.h != ref.h) {
        fprintf(stderr, "bench_bias: %s is %dx%d, the reference %dx%d\n", argv[2], img.w, img.h, ref.w, ref.h);
        return 2;
    }
    int w = ref.w, h = ref.h;
    size_t n = (size_t)w * h;
    double top = 0.0;
    for (size_t i = 0; i < n; i++) top = fmax(top, lum(ref.rgb + 3 * i));
    unsigned char *lit = calloc(n, 1), *inner = calloc(n, 1);
    if (!lit || !inner) {
        fprintf(stderr, "bench_bias: out of memory\n");
        return 2;
    }
    for (size_t i = 0; i < n; i++) lit[i] = lum(ref.rgb + 3 * i) > 0.05 * top;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int in = lit[(size_t)y * w + x];
            for (int dy = -EDGE; in && dy <= EDGE; dy++)
                for (int dx = -EDGE; in && dx <= EDGE; dx++) {
                    int u = x + dx, v = y + dy;
                    in = u >= 0 && v >= 0 && u < w && v < h && lit[(size_t)v * w + u];
                }
            inner[(size_t)y * w + x] = (unsigned char)in;
        }
    /* sums of (x - r), r, the variance of the difference, (x - r)^2, the image's variance: over
     * every lit pixel, per band of rows, and the edge band / the inner part */
    double d = 0, r = 0, var = 0, d2 = 0, ivar = 0, bd[BANDS] = {0}, br[BANDS] = {0}, ed[2] = {0}, er[2] = {0};
    long count = 0, bc[BANDS] = {0}, ec[2] = {0};
    for (size_t i = 0; i < n; i++) {
        if (!lit[i]) continue;
        double xi = lum(img.rgb + 3 * i), ri = lum(ref.rgb + 3 * i);
        double si = lum(ise.rgb + 3 * i), sr = lum(rse.rgb + 3 * i);
        int b = (int)(i / (size_t)w) * BANDS / h, e = inner[i];
        d += xi - ri, r += ri, var += si * si + sr * sr, d2 += (xi - ri) * (xi - ri), ivar += si * si;
        bd[b] += xi - ri, br[b] += ri, bc[b]++;
        ed[e] += xi - ri, er[e] += ri, ec[e]++;
        count++;
    }
    if (count == 0 || !(r > 0.0)) {
        fprintf(stderr, "bench_bias: %s: no lit pixel\n", argv[1]);
        return 2;
    }
    printf("lit pixels %ld of %zu: relative bias %+.2f%% +- %.2f%%\n", count, n, 100.0 * d / r, 100.0 * sqrt(var) / r);
    printf("per-pixel squared bias %.3g (mean squared difference %.3g less both variances), the image's variance %.3g\n",
           (d2 - var) / count, d2 / count, ivar / count);
    for (int b = 0; b < BANDS; b++)
        if (bc[b]) printf("  rows %3d-%3d: %+.2f%% (%ld pixels)\n", b * h / BANDS, (b + 1) * h / BANDS, 100.0 * bd[b] / br[b], bc[b]);
    for (int e = 0; e < 2; e++)
        if (ec[e] && er[e] > 0.0)
            printf("  %s: %+.2f%% (%ld pixels)\n", e ? "inside" : "edge band (3 px)", 100.0 * ed[e] / er[e], ec[e]);
    free(lit);
    free(inner);
    rd_image_free_pixels(&ref);
    rd_image_free_pixels(&rse);
    rd_image_free_pixels(&img);
    rd_image_free_pixels(&ise);
    return 0;
}
