/* Regression test (issue 14): the photon estimate of the ray-marching methods must not gather
 * photons across surfaces. Before main's 71c148a ("march: with shapes the photon estimate uses
 * only the photons no surface hides from the sample") it did, and this test FAILS on any commit
 * before that one (it was written on branch h-s, based on 7eb0778, to show the defect; on main
 * at 9d5ccc8 with this file added it passes).
 *
 * The defect: integrator_march.c (now integrators/march.c) photon_estimate() took the k nearest
 * photons of the map by position alone (pm_map_radiance), whatever region (medium behind the
 * surfaces) they were stored in. Beside a shape holding a dense medium, a marching sample in
 * the thin medium outside gathered the dense medium's photons from inside (stored at its
 * collision density, 100 times the outside's here), and the image showed a bright halo around
 * the shape. Found by bench/bench_fig5.sh (docs/benchmarks.md, "Surfaces (issue 14)": the
 * marchers' error maps on exp1-point.json have a crescent outside the blob's silhouette).
 *
 * The scene makes every method see the same light: an `interface` sphere (no refraction, so
 * shadow rays cross it and `delta` is unbiased for everything), dense medium inside, thin
 * medium outside, a point light above. Over an annulus of pixels whose camera rays pass just
 * outside the sphere (they never enter it), `uniform`'s mean must agree with `delta`'s within
 * 5 standard errors (both images' own per-pixel errors; the photon estimate's blur inside the
 * homogeneous thin fog is far below that, as the control annulus farther out shows). Measured
 * before a fix through the CLI at 64 spp: delta 0.068, uniform 0.111 in the near annulus (62%
 * too bright, ~50 standard errors); 0.072 against 0.074 in the far one. The test takes 16 spp
 * (before the fix the gap was then still ~23 standard errors). */
#include "support/rd_test.h"

#include <math.h>
#include <unistd.h>

/* Mean of channel 0 over pixels whose centre lies at distance [r0, r1) from (cx, cy), and the
 * standard error of that mean from the per-pixel standard errors (pixels independent). */
static void ring_mean(const rd_render_result *r, double cx, double cy, double r0, double r1,
                      double *mean, double *se)
{
    double sum = 0, var = 0;
    int n = 0;
    for (int y = 0; y < r->image.h; y++)
        for (int x = 0; x < r->image.w; x++) {
            double d = hypot(x + 0.5 - cx, y + 0.5 - cy);
            if (d < r0 || d >= r1) continue;
            size_t q = 3 * ((size_t)y * r->image.w + x);
            sum += r->image.rgb[q];
            var += (double)r->stderr_img.rgb[q] * r->stderr_img.rgb[q];
            n++;
        }
    cr_assert(n > 0);
    *mean = sum / n;
    *se = sqrt(var) / n;
}

Test(surface_photon_leak, marchers_do_not_gather_photons_across_surfaces, .timeout = 300)
{
    char cwd[512], json[2048];
    cr_assert(getcwd(cwd, sizeof cwd) != NULL);
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,3],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[64,48]},"
             "\"medium\":\"thin\","
             "\"media\":[{\"name\":\"thin\",\"bounds\":{\"min\":[-2,-2,-2],\"max\":[2,2,4]},\"density\":1,"
             "\"sigma_t\":0.3,\"albedo\":0.9},"
             "{\"name\":\"dense\",\"bounds\":{\"min\":[-0.6,-0.6,-0.6],\"max\":[0.6,0.6,0.6]},\"density\":1,"
             "\"sigma_t\":30,\"albedo\":0.95}],"
             "\"shapes\":[{\"file\":\"%s/scenes/data/icosphere-3.obj\",\"transform\":{\"scale\":0.5},"
             "\"material\":{\"type\":\"interface\"},\"inside\":\"dense\",\"outside\":\"thin\"}],"
             "\"lights\":[{\"type\":\"point\",\"position\":[0,2.5,0],\"intensity\":10}],"
             "\"photons\":{\"count\":100000},\"settings\":{\"max_depth\":64}}",
             cwd);
    rd_scene *s = rt_scene("leak.json", json);
    rd_render_result rd, ru;
    char err[RD_ERRLEN];
    rd_render_opts od = {.method = "delta", .spp = 16, .seed = 1, .threads = 2};
    rd_render_opts ou = {.method = "uniform", .spp = 16, .seed = 2, .threads = 2};
    cr_assert(rd_render(s, &od, &rd, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(rd_render(s, &ou, &ru, err, sizeof err) == RD_OK, "%s", err);
    /* The sphere (radius 0.5 at distance 3) spans asin(0.5/3) = 9.6 degrees: 11.1 pixels of
     * radius at fov 40 over 48 rows (24 / tan 20deg * tan 9.6deg). Near annulus: 12.5-15 px
     * (rays pass outside the sphere); far annulus: 18-22 px (the control). */
    const double cx = 32, cy = 24;
    double md, sd, mu, su;
    ring_mean(&rd, cx, cy, 18, 22, &md, &sd);
    ring_mean(&ru, cx, cy, 18, 22, &mu, &su);
    cr_expect(fabs(mu - md) < 5 * hypot(sd, su), "far annulus: uniform %.4f, delta %.4f +- %.4f", mu, md,
              hypot(sd, su));
    ring_mean(&rd, cx, cy, 12.5, 15, &md, &sd);
    ring_mean(&ru, cx, cy, 12.5, 15, &mu, &su);
    cr_expect(fabs(mu - md) < 5 * hypot(sd, su),
              "photons gathered across the surface (issue 14; fixed by 71c148a): near annulus, uniform %.4f, "
              "delta %.4f +- %.4f",
              mu, md, hypot(sd, su));
    rd_render_result_free(&rd);
    rd_render_result_free(&ru);
    rd_scene_free(s);
}
