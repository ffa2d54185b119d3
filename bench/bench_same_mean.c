/* bench_same_mean: do two sets of renders have the same expected image?
 *
 *   build/bench/bench_same_mean A1.exr ... AK.exr -- B1.exr ... BK.exr
 *
 * Each set holds K independent renders (different seeds) of one scene by one build or method.
 * For the whole image and for every 16x16 region, the mean luminance of each render is taken;
 * across the K renders of a set that gives a mean and its standard error, and the two sets are
 * compared by t = (mean_A - mean_B) / sqrt(se_A^2 + se_B^2). Under the hypothesis of equal
 * expectations t follows Student's t with about K_A + K_B - 2 degrees of freedom (equal sizes,
 * similar variances): the tool prints the image t, the largest |t| over the regions, and how
 * many exceed 3 and 4 beside the counts that distribution expects.
 * Used for issue 8's check that the keyed sampler changed the bits of `delta`, not its mean. */
#include "renderer.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
#define R 16

/* P(|T| > x) for Student's t with nu degrees of freedom, by Simpson's rule on the density. */
static double t_tail(double x, double nu)
{
    double c = exp(lgamma((nu + 1) / 2) - lgamma(nu / 2)) / sqrt(nu * M_PI), s = 0.0, b = 1e4;
    int n = 200000;
    double hh = (b - x) / n;
    for (int i = 0; i <= n; i++) {
        double t = x + i * hh, f = c * pow(1.0 + t * t / nu, -(nu + 1) / 2);
        s += f * (i == 0 || i == n ? 1 : (i % 2 ? 4 : 2));
    }
    return 2.0 * s * hh / 3.0;
}

static double lum(const float *p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

int main(int argc, char **argv)
{
    int sep = -1;
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "--")) sep = i;
    if (sep < 0) { /* `make bench` runs every tool with --json: this one needs renders */
        printf("bench_same_mean: a tool for two sets of renders (see its header); nothing to run here\n");
        return 0;
    }
    int ka = sep - 1, kb = argc - sep - 1;
    if (sep < 0 || ka < 2 || kb < 2) {
        fprintf(stderr, "usage: bench_same_mean A1.exr ... AK.exr -- B1.exr ... BK.exr (K >= 2 each)\n");
        return 1;
    }
    int w = 0, h = 0, nrx = 0, nry = 0;
    double *sum[2] = {NULL, NULL}, *sum2[2] = {NULL, NULL};
    int k_of[2] = {ka, kb};
    for (int set = 0; set < 2; set++) {
        for (int k = 0; k < k_of[set]; k++) {
            const char *path = argv[set == 0 ? 1 + k : sep + 1 + k];
            rd_image img;
            char err[RD_ERRLEN];
            if (rd_image_read(path, &img, err, sizeof err) != RD_OK) {
                fprintf(stderr, "%s\n", err);
                return 2;
            }
            if (!w) {
                w = img.w;
                h = img.h;
                nrx = (w + R - 1) / R;
                nry = (h + R - 1) / R;
                for (int q = 0; q < 2; q++) {
                    sum[q] = calloc((size_t)nrx * nry + 1, sizeof(double));
                    sum2[q] = calloc((size_t)nrx * nry + 1, sizeof(double));
                }
            } else if (img.w != w || img.h != h) {
                fprintf(stderr, "%s: %dx%d, expected %dx%d\n", path, img.w, img.h, w, h);
                return 2;
            }
            /* Region means (index 0..nrx*nry-1) and the image mean (last index). */
            int nr = nrx * nry;
            double *reg = calloc((size_t)nr + 1, sizeof(double));
            int *cnt = calloc((size_t)nr + 1, sizeof(int));
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++) {
                    double l = lum(&img.rgb[3 * ((size_t)y * w + x)]);
                    int r = (y / R) * nrx + x / R;
                    reg[r] += l;
                    cnt[r]++;
                    reg[nr] += l;
                    cnt[nr]++;
                }
            for (int r = 0; r <= nr; r++) {
                double m = reg[r] / cnt[r];
                sum[set][r] += m;
                sum2[set][r] += m * m;
            }
            free(reg);
            free(cnt);
            rd_image_free_pixels(&img);
        }
    }
    int nr = nrx * nry, over3 = 0, over4 = 0, lit = 0;
    double zmax = 0.0, zimg = 0.0;
    for (int r = 0; r <= nr; r++) {
        double m[2], se2[2];
        for (int q = 0; q < 2; q++) {
            double K = k_of[q];
            m[q] = sum[q][r] / K;
            se2[q] = fmax(0.0, (sum2[q][r] - K * m[q] * m[q]) / (K - 1.0)) / K;
        }
        if (se2[0] + se2[1] <= 0.0) continue; /* a dark region: nothing to compare */
        double z = (m[0] - m[1]) / sqrt(se2[0] + se2[1]);
        if (r == nr) { zimg = z; continue; }
        lit++;
        if (fabs(z) > fabs(zmax)) zmax = z;
        over3 += fabs(z) > 3.0;
        over4 += fabs(z) > 4.0;
    }
    double nu = ka + kb - 2;
    printf("image mean luminance: A %.6g, B %.6g, t = %.2f\n", sum[0][nr] / ka, sum[1][nr] / kb, zimg);
    printf("regions (%dx%d px) with light: %d; largest |t| %.2f; |t| > 3: %d (expected %.1f); |t| > 4: %d (expected %.1f)\n",
           R, R, lit, fabs(zmax), over3, t_tail(3.0, nu) * lit, over4, t_tail(4.0, nu) * lit);
    return 0;
}
