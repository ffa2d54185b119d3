/* Extreme media (issue 13): every render method (the method table,
 * renderer/integrators/methods.c) on scenes at the edges of what the scene format accepts. Each
 * render must finish (the test's .timeout is the hang detector), give only finite pixels and
 * drop no non-finite sample (rd_render_stats.invalid == 0). Where the answer is known in closed
 * form the image is checked against it:
 *  - transmittance through a homogeneous absorbing box (albedo 0) in front of an environment
 *    light of radiance E, seen by an orthographic camera straight through it: every pixel is
 *    E exp(-sigma_t d) (Beer-Lambert, THEORY.md §1);
 *  - albedo 0 with a light beside the box: no scattered light, the same E exp(-sigma_t d);
 *  - the white furnace: albedo 1 inside a constant environment E: every pixel is E (the
 *    radiance field is E everywhere, in every direction; the collision-form RTE, THEORY.md §1).
 * Tolerance (expect_value): every pixel of these images has the same expected value, so the
 * image's mean is compared with the answer using the standard error of that mean, estimated
 * from the spread of the pixel values (sd / sqrt(pixels), 1024 pixels so sd is well known):
 * |mean - answer| <= 5 SE (a false alarm below 1e-6 per check for a normal mean) plus 1e-5 of
 * the answer, the float32 rounding of the film (about 100 ulp), for estimators that are exact
 * (closed-form transmittance gives every pixel the same value, SE = 0). Seeds are fixed.
 *
 * The suite `stress_big` (a 4096x4096 image at 1 spp, a 1x1 image at 1e6 spp) runs the command
 * line and measures its peak RSS (getrusage RUSAGE_CHILDREN after the child is reaped) against
 * a bound derived from the film's bytes per pixel (see big_rss_bound). */
#include "support/rd_test.h"

#include <sys/resource.h>

/* Built with AddressSanitizer (gcc and clang define __SANITIZE_ADDRESS__; clang also has the
 * feature test): its shadow memory and allocator make address-space limits and resident-memory
 * bounds meaningless, so the tests that measure them skip themselves there. */
#if defined(__SANITIZE_ADDRESS__)
#define UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define UNDER_ASAN 1
#endif
#endif
#ifndef UNDER_ASAN
#define UNDER_ASAN 0
#endif
static void skip_under_asan(void)
{
    if (UNDER_ASAN) cr_skip_test("built with AddressSanitizer: memory limits and RSS bounds do not apply");
}

static const char *const methods[] = {"delta", "guided", "uniform", "transmittance"};
enum { N_METHODS = sizeof methods / sizeof methods[0] };

/* Small photon maps and guides: these tests are about robustness, not about the quality of
 * the estimates; 32x32 pixels (1024 independent pixel values for the standard error). */
#define BAKE "\"photons\":{\"count\":4000},\"guide\":{\"bands\":2,\"k\":16,\"resolution\":[6,6,6]}"
#define ORTHO_Z "\"camera\":{\"type\":\"orthographic\",\"position\":[0,0,5],\"direction\":[0,0,-1],\"width\":0.8,\"resolution\":[32,32]}"
#define PERSP(res) "\"camera\":{\"position\":[0,0.5,4],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[" res "]}"

static rd_render_result render(const rd_scene *s, const char *method, int spp, uint64_t seed)
{
    rd_render_opts o = {.method = method, .spp = spp, .seed = seed, .threads = 2};
    rd_render_result r;
    char err[RD_ERRLEN];
    cr_assert(rd_render(s, &o, &r, err, sizeof err) == RD_OK, "%s: %s", method, err);
    size_t n = (size_t)r.image.w * r.image.h * 3;
    for (size_t i = 0; i < n; i++) {
        cr_assert(isfinite(r.image.rgb[i]), "%s: pixel value %zu is %g", method, i / 3, r.image.rgb[i]);
        cr_assert(isfinite(r.stderr_img.rgb[i]), "%s: stderr %zu is %g", method, i / 3, r.stderr_img.rgb[i]);
    }
    cr_assert(r.stats.invalid == 0, "%s: %llu non-finite samples were dropped", method,
              (unsigned long long)r.stats.invalid);
    return r;
}

/* Every pixel channel has the same expectation `want`: compare the mean with it (see the
 * header for the tolerance). */
static void expect_value(const rd_render_result *r, double want, const char *what, const char *method)
{
    size_t n = (size_t)r->image.w * r->image.h * 3;
    double sum = 0, sum2 = 0;
    for (size_t i = 0; i < n; i++) {
        sum += r->image.rgb[i];
        sum2 += (double)r->image.rgb[i] * r->image.rgb[i];
    }
    double mean = sum / n, var = fmax(0.0, (sum2 - sum * mean) / (n - 1)), se = sqrt(var / n);
    double tol = 5.0 * se + 1e-5 * fabs(want);
    cr_log_info("%s, %s: mean %.7g, expected %.7g, SE %.3g", what, method, mean, want, se);
    cr_expect(fabs(mean - want) <= tol, "%s, %s: mean %.9g, expected %.9g (tolerance %.3g, SE %.3g)", what,
              method, mean, want, tol, se);
}

/* Load `json` and render it with every method; when `want` >= 0, check the answer. */
static void every_method(const char *name, const char *json, int spp, double want)
{
    rd_scene *s = rt_scene(name, json);
    for (int i = 0; i < N_METHODS; i++) {
        rd_render_result r = render(s, methods[i], spp, 7 + (uint64_t)i);
        if (want >= 0) expect_value(&r, want, name, methods[i]);
        rd_render_result_free(&r);
    }
    rd_scene_free(s);
}

/* ---- Cases with a closed-form answer ------------------------------------------------------ */

/* An absorbing box 1 m deep (z from -0.5 to 0.5), an environment of radiance E behind it. */
static const char *absorber(char *buf, size_t n, const char *sigma_t, const char *extra_lights)
{
    snprintf(buf, n,
             "{" ORTHO_Z ",\"media\":[{\"bounds\":{\"min\":[-0.5,-0.5,-0.5],\"max\":[0.5,0.5,0.5]},"
             "\"density\":1,\"sigma_t\":%s,\"albedo\":0}],"
             "\"lights\":[{\"type\":\"environment\",\"radiance\":0.75}%s]," BAKE "}",
             sigma_t, extra_lights);
    return buf;
}

Test(stress, transmittance_through_a_homogeneous_box, .timeout = 120)
{
    char buf[2048];
    every_method("absorb.json", absorber(buf, sizeof buf, "1.5", ""), 16, 0.75 * exp(-1.5));
}

/* sigma_t = 1e-9 /m: practically empty, T = exp(-1e-9). */
Test(stress, sigma_t_1e_minus_9, .timeout = 120)
{
    char buf[2048];
    every_method("thin.json", absorber(buf, sizeof buf, "1e-9", ""), 4, 0.75 * exp(-1e-9));
}

/* sigma_t = 1e6 /m over 1 m: T = exp(-1e6) = 0 in double. */
Test(stress, sigma_t_1e6, .timeout = 120)
{
    char buf[2048];
    every_method("dense.json", absorber(buf, sizeof buf, "1e6", ""), 4, 0.0);
}

/* Albedo exactly 0 with a point light and a spot beside the box: nothing scatters, so the
 * lights add nothing; only the attenuated environment is seen. */
Test(stress, albedo_0_shows_only_the_attenuated_background, .timeout = 120)
{
    char buf[2048];
    every_method("albedo0.json",
                 absorber(buf, sizeof buf, "2",
                          ",{\"type\":\"point\",\"position\":[0,1,0],\"intensity\":50},"
                          "{\"type\":\"spot\",\"position\":[1,0,0],\"look_at\":[0,0,0],\"angle\":40,\"intensity\":80}"),
                 16, 0.75 * exp(-2.0));
}

/* The white furnace: albedo exactly 1, forward scattering, an environment of 0.5 and nothing
 * else. Optical depth 2 across the box, so paths of more than 64 events (max_depth) have a
 * negligible share. Every pixel is 0.5.
 * Every method is unbiased here: delta, guided-unbiased, and the marchers with their default
 * source (march.ls = nee+paths: delta's own vertex at every sample). With march.ls =
 * nee+photons the marchers were not held to 0.5: the k-NN estimate's bias is shared by every
 * pixel (one map for the image), so the spread of the pixels says nothing about it (measured
 * 0.4956 with 4000 photons and 0.5085 with 64000, uniform, 64 spp, pixel SE of the mean
 * 0.0003). */
Test(stress, white_furnace, .timeout = 300)
{
    rd_scene *s = rt_scene("furnace.json",
                           "{" ORTHO_Z ",\"media\":[{\"bounds\":{\"min\":[-0.5,-0.5,-0.5],\"max\":[0.5,0.5,0.5]},"
                           "\"density\":1,\"sigma_t\":2,\"albedo\":1,\"g\":0.5}],"
                           "\"lights\":[{\"type\":\"environment\",\"radiance\":0.5}]," BAKE "}");
    for (int i = 0; i < N_METHODS; i++) {
        rd_render_result r = render(s, methods[i], 16, 7 + (uint64_t)i);
        expect_value(&r, 0.5, "furnace.json", methods[i]);
        rd_render_result_free(&r);
    }
    rd_scene_free(s);
}

/* 64 absorbing media along the camera axis, each 0.01 m deep with sigma_t 1 + i/8 (gaps of
 * 0.005 m between them): T = exp(-sum_i 0.01 sigma_t,i). */
Test(stress, sixty_four_media_along_one_ray, .timeout = 120)
{
    static char buf[64 * 200 + 1024];
    size_t len = (size_t)snprintf(buf, sizeof buf, "{" ORTHO_Z ",\"media\":[");
    double tau = 0;
    for (int i = 0; i < 64; i++) {
        double z0 = -0.5 + 0.015 * i, st = 1.0 + i / 8.0;
        tau += 0.01 * st;
        len += (size_t)snprintf(buf + len, sizeof buf - len,
                                "%s{\"bounds\":{\"min\":[-0.5,-0.5,%.6f],\"max\":[0.5,0.5,%.6f]},"
                                "\"density\":1,\"sigma_t\":%.6f,\"albedo\":0}",
                                i ? "," : "", z0, z0 + 0.01, st);
    }
    snprintf(buf + len, sizeof buf - len, "],\"lights\":[{\"type\":\"environment\",\"radiance\":0.75}]," BAKE "}");
    every_method("media64.json", buf, 16, 0.75 * exp(-tau));
}

/* ---- Cases checked for finite output ------------------------------------------------------ */

/* A scattering box lit by a spot and a point light, seen in perspective, with phase g. */
static const char *lit_box(char *buf, size_t n, const char *g, const char *bounds, const char *sigma_t)
{
    snprintf(buf, n,
             "{" PERSP("16,12") ",\"media\":[{\"bounds\":%s,\"density\":1,\"sigma_t\":%s,\"albedo\":0.9,\"g\":%s}],"
             "\"lights\":[{\"type\":\"spot\",\"position\":[-2,2,1],\"look_at\":[0,0,0],\"angle\":30,\"intensity\":20},"
             "{\"type\":\"point\",\"position\":[1.5,1,1],\"intensity\":5}]," BAKE "}",
             bounds, sigma_t, g);
    return buf;
}
#define UNIT_BOX "{\"min\":[-0.6,-0.6,-0.6],\"max\":[0.6,0.6,0.6]}"

Test(stress, hg_g_plus_0_999, .timeout = 120)
{
    char buf[2048];
    every_method("gplus.json", lit_box(buf, sizeof buf, "0.999", UNIT_BOX, "2"), 8, -1);
}

Test(stress, hg_g_minus_0_999, .timeout = 120)
{
    char buf[2048];
    every_method("gminus.json", lit_box(buf, sizeof buf, "-0.999", UNIT_BOX, "2"), 8, -1);
}

/* A scattering medium with sigma_t 1e6 /m lit from outside: every path ends within micrometres
 * of the surface. */
Test(stress, lit_sigma_t_1e6, .timeout = 120)
{
    char buf[2048];
    every_method("litdense.json", lit_box(buf, sizeof buf, "0.3", UNIT_BOX, "1e6"), 4, -1);
}

/* A medium 1e5 m from the origin (camera and lights moved with it). */
Test(stress, medium_far_from_the_origin, .timeout = 120)
{
    every_method("far.json",
                 "{\"camera\":{\"position\":[100000,100000.5,100004],\"look_at\":[100000,100000,100000],"
                 "\"fov\":40,\"resolution\":[16,12]},"
                 "\"media\":[{\"bounds\":{\"min\":[99999.4,99999.4,99999.4],\"max\":[100000.6,100000.6,100000.6]},"
                 "\"density\":1,\"sigma_t\":2,\"albedo\":0.9,\"g\":0.5}],"
                 "\"lights\":[{\"type\":\"point\",\"position\":[100001.5,100001,100001],\"intensity\":5},"
                 "{\"type\":\"environment\",\"radiance\":0.1}]," BAKE "}",
                 8, -1);
}

/* A medium 1e-4 m across (optical depth 2 across), seen from 4e-4 m. */
Test(stress, medium_1e_minus_4_across, .timeout = 120)
{
    every_method("tiny.json",
                 "{\"camera\":{\"position\":[0,0,0.0004],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[16,12]},"
                 "\"media\":[{\"bounds\":{\"min\":[-5e-5,-5e-5,-5e-5],\"max\":[5e-5,5e-5,5e-5]},"
                 "\"density\":1,\"sigma_t\":20000,\"albedo\":0.9,\"g\":0.5}],"
                 "\"lights\":[{\"type\":\"point\",\"position\":[0.0002,0.0002,0.0002],\"intensity\":1e-6},"
                 "{\"type\":\"environment\",\"radiance\":0.1}]," BAKE "}",
                 8, -1);
}

/* A point light inside a dense scattering medium (optical radius 100 to the faces). */
Test(stress, light_inside_a_dense_medium, .timeout = 120)
{
    every_method("inside.json",
                 "{" PERSP("16,12") ",\"media\":[{\"bounds\":" UNIT_BOX ",\"density\":1,\"sigma_t\":166,"
                 "\"albedo\":0.95,\"g\":0.2}],"
                 "\"lights\":[{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":100}]," BAKE "}",
                 4, -1);
}

/* ---- Big images through the command line, with their peak memory (stress_big) ----------- */

/* The photonmarch binary under test (PHOTONMARCH_BIN, else build/photonmarch). */
static const char *bin(void)
{
    const char *b = getenv("PHOTONMARCH_BIN");
    return b && *b ? b : "build/photonmarch";
}

/* Upper bound of the peak resident memory of `render` for w x h pixels:
 *  - the film: sums and sums of squares in double (2 x 3 x 8 = 48 bytes) and a sample count
 *    (4 bytes) per pixel (renderer/render/render.c film_alloc);
 *  - the result: mean and standard-error images, 3 floats each (24 bytes);
 *  - writing: OpenImageIO may copy each float image once while encoding the EXR (12 bytes, at
 *    most one image at a time) and the PNG preview is 3 bytes per pixel;
 *  so 48 + 4 + 24 + 12 + 3 = 91 bytes per pixel, taken as 96; plus a fixed allowance of 256 MiB
 *  for the program, its libraries (OpenImageIO, OpenVDB, TBB), thread stacks and the bake. */
static long big_rss_bound_kib(long w, long h)
{
    return (w * h * 96) / 1024 + 256L * 1024;
}

/* Run `render` through the CLI and return its peak RSS in KiB (ru_maxrss of the reaped child:
 * this test process spawns no other child). */
static long render_rss(const char *scene, const char *method, const char *spp, const char *set, const char *out)
{
    char o[8192], e[8192];
    char *argv[] = {(char *)bin(), "render", (char *)scene, "--method", (char *)method, "--spp",
                    (char *)spp, "--threads", "2", "-q", "-o", (char *)out, "--set", (char *)set, NULL};
    int code = rt_run(argv, o, sizeof o, e, sizeof e, NULL);
    cr_assert(code == 0, "%s %s: exit %d: %s", scene, method, code, e);
    struct rusage ru;
    cr_assert(getrusage(RUSAGE_CHILDREN, &ru) == 0);
    return ru.ru_maxrss;
}

/* Every pixel of an EXR the CLI wrote is finite; the mean of channel 0 into *mean. */
static void expect_finite_file(const char *path, double *mean)
{
    rd_image img;
    char err[RD_ERRLEN];
    cr_assert(rd_image_read(path, &img, err, sizeof err) == RD_OK, "%s", err);
    size_t n = (size_t)img.w * img.h * 3;
    double sum = 0;
    for (size_t i = 0; i < n; i++) {
        cr_assert(isfinite(img.rgb[i]), "%s: pixel %zu is %g", path, i / 3, img.rgb[i]);
        sum += img.rgb[i];
    }
    *mean = sum / n;
    rd_image_free_pixels(&img);
}

static void write_scene(const char *path, const char *json)
{
    rt_write_file(path, json, strlen(json));
}

/* 4096 x 4096 pixels at 1 sample each: finite, and within the film's memory bound. Run for
 * plain `delta` (settings.equiangular false): the film's memory, the same for every method. A
 * tile selection (`delta`'s default "tiles" on this point light, the guided methods') adds its
 * pixel records, 72 bytes a pixel (rd_select_pixel), and the weighted film's 40: `delta` with
 * "tiles" peaked at 3.2 GiB here (session 72), outside this bound. */
Test(stress_big, image_4096_squared_at_1_spp, .timeout = 600)
{
    skip_under_asan();
    char scene[256], out[256];
    snprintf(scene, sizeof scene, "%s/big-scene.json", rt_tmpdir());
    snprintf(out, sizeof out, "%s/big.exr", rt_tmpdir());
    write_scene(scene, "{\"camera\":{\"position\":[0,0.5,4],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[4096,4096]},"
                       "\"media\":[{\"bounds\":{\"min\":[-0.6,-0.6,-0.6],\"max\":[0.6,0.6,0.6]},"
                       "\"density\":1,\"sigma_t\":2,\"albedo\":0.9,\"g\":0.5}],"
                       "\"lights\":[{\"type\":\"point\",\"position\":[1.5,1,1],\"intensity\":5}],"
                       "\"settings\":{\"max_depth\":4,\"equiangular\":false}}");
    long rss = render_rss(scene, "delta", "1", "settings.seed=3", out), bound = big_rss_bound_kib(4096, 4096);
    cr_log_info("4096^2 at 1 spp: peak RSS %ld MiB, bound %ld MiB", rss / 1024, bound / 1024);
    cr_expect(rss < bound, "peak RSS %ld KiB above the bound %ld KiB", rss, bound);
    double mean;
    expect_finite_file(out, &mean);
    cr_expect(mean > 0, "the image is black");
}

/* One pixel at 1e6 samples, every method, through the absorbing box of
 * stress::transmittance_through_a_homogeneous_box (albedo 0: a sample ends at its first
 * collision, so 1e6 of them are quick): the answer is 0.75 exp(-1.5), within 5 SE (from the
 * file's standard-error image) plus the float rounding; the memory bound holds for one pixel
 * (the fixed allowance). */
Test(stress_big, one_pixel_at_1e6_spp, .timeout = 600)
{
    skip_under_asan();
    char scene[256], out[256], sd[256], json[2048];
    snprintf(scene, sizeof scene, "%s/pixel-scene.json", rt_tmpdir());
    write_scene(scene, absorber(json, sizeof json, "1.5", ""));
    const double want = 0.75 * exp(-1.5);
    for (int i = 0; i < N_METHODS; i++) {
        snprintf(out, sizeof out, "%s/pixel-%s.exr", rt_tmpdir(), methods[i]);
        snprintf(sd, sizeof sd, "%s/pixel-%s-stderr.exr", rt_tmpdir(), methods[i]);
        long rss = render_rss(scene, methods[i], "1000000", "camera.resolution=[1,1]", out), bound = big_rss_bound_kib(1, 1);
        cr_log_info("1x1 at 1e6 spp, %s: peak RSS so far %ld MiB, bound %ld MiB", methods[i], rss / 1024,
                    bound / 1024);
        cr_expect(rss < bound, "%s: peak RSS %ld KiB above the bound %ld KiB", methods[i], rss, bound);
        double mean, se;
        expect_finite_file(out, &mean);
        expect_finite_file(sd, &se);
        cr_log_info("1x1 at 1e6 spp, %s: %.7f, expected %.7f (SE %.3g)", methods[i], mean, want, se);
        cr_expect(fabs(mean - want) <= 5 * se + 1e-5 * want, "%s: %.7f, expected %.7f (SE %.3g)", methods[i],
                  mean, want, se);
    }
}

/* ---- Memory limits (suite memory) ---------------------------------------------------------- *
 * A render or bake that cannot get memory says so in one line naming what it was allocating
 * and exits with a status (never a signal). The CLI runs under `ulimit -v` (1 GiB of address
 * space: enough to start, which takes about 0.6 GiB with its libraries and threads, far too
 * little for what the scene asks for). */

/* Run `args` (a shell word list after the binary) under `ulimit -v kib`; the exit status (or
 * 1000 + signal) and the last line of stderr. */
static int run_limited(long kib, const char *args, char *err, size_t errlen)
{
    char cmd[2048], o[4096];
    snprintf(cmd, sizeof cmd, "ulimit -v %ld; exec '%s' %s", kib, bin(), args);
    char *argv[] = {"/bin/bash", "-c", cmd, NULL};
    return rt_run(argv, o, sizeof o, err, errlen, NULL);
}

/* One line (a single newline, at the end). */
static void expect_one_line(const char *err)
{
    const char *nl = strchr(err, '\n');
    cr_expect(nl != NULL && nl[1] == 0, "not one line: %s", err);
}

/* A 8192x8192 film (4.8 GB: 76 bytes per pixel) under 1 GiB: exit 4 (internal error: out of
 * memory) with the film named. Found a double free: film_alloc freed the partial film and
 * rd_render freed it again (SIGSEGV). */
Test(memory, render_without_memory_for_its_film_says_so, .timeout = 120)
{
    char scene[256], args[1024], err[4096];
    snprintf(scene, sizeof scene, "%s/nomem-scene.json", rt_tmpdir());
    write_scene(scene, "{\"camera\":{\"position\":[0,0.5,4],\"look_at\":[0,0,0],\"resolution\":[8192,8192]},"
                       "\"media\":[{\"bounds\":{\"min\":[-0.6,-0.6,-0.6],\"max\":[0.6,0.6,0.6]},"
                       "\"density\":1,\"sigma_t\":2,\"albedo\":0.9}],"
                       "\"lights\":[{\"type\":\"point\",\"position\":[1.5,1,1],\"intensity\":5}],"
                       "\"settings\":{\"equiangular\":false}}"); /* (the film alone: no tile selection) */
    snprintf(args, sizeof args, "render '%s' --spp 1 --threads 2 -q -o '%s/nomem.exr'", scene, rt_tmpdir());
    int code = run_limited(1L << 20, args, err, sizeof err);
    cr_expect(code > 0 && code < 128, "exit %d (expected a failure status, not a signal): %s", code, err);
    cr_expect(strstr(err, "out of memory") && strstr(err, "8192x8192 film"), "%s", err);
    expect_one_line(err);
}

/* A bake whose photons do not fit (a point light inside a dense, white medium: every photon is
 * stored at up to 64 collisions, 1e6 photons would store about 6e7 = 2 GB) under 1 GiB. */
Test(memory, bake_without_memory_for_its_photons_says_so, .timeout = 180)
{
    char scene[256], args[1024], err[4096];
    snprintf(scene, sizeof scene, "%s/nomem-bake.json", rt_tmpdir());
    write_scene(scene, "{\"camera\":{\"position\":[0,0.5,4],\"look_at\":[0,0,0],\"resolution\":[16,16]},"
                       "\"media\":[{\"bounds\":{\"min\":[-0.6,-0.6,-0.6],\"max\":[0.6,0.6,0.6]},"
                       "\"density\":1,\"sigma_t\":100,\"albedo\":1}],"
                       "\"lights\":[{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":5}],"
                       "\"photons\":{\"max_depth\":64}}");
    snprintf(args, sizeof args, "bake '%s' --photons 1000000 --threads 2 -q -o '%s/nomem/b'", scene, rt_tmpdir());
    int code = run_limited(1L << 20, args, err, sizeof err);
    cr_expect(code > 0 && code < 128, "exit %d (expected a failure status, not a signal): %s", code, err);
    cr_expect(strstr(err, "out of memory") && strstr(err, "photons"), "%s", err);
    expect_one_line(err);
}

/* FLANN's C API lets std::bad_alloc through (it catches only std::runtime_error), which ended
 * the process in std::terminate (SIGABRT). pm_map_build under an address-space limit that
 * leaves room for our copy of the positions but not for FLANN's: PM_ERR_NOMEM and a message;
 * with the limit lifted the same map builds. */
#include "photonmap.h"

static long vm_size_kib(void)
{
    FILE *f = fopen("/proc/self/status", "r");
    cr_assert(f != NULL);
    char line[256];
    long kib = -1;
    while (fgets(line, sizeof line, f))
        if (sscanf(line, "VmSize: %ld", &kib) == 1) break;
    fclose(f);
    return kib;
}

Test(memory, flann_index_without_memory_is_an_error)
{
    skip_under_asan();
    enum { N = 2000000 };
    pm_photon *ph = calloc(N, sizeof *ph);
    cr_assert(ph != NULL);
    pcg32 rng = pcg32_seed(5, 6, 7);
    for (int i = 0; i < N; i++)
        for (int a = 0; a < 3; a++) {
            ph[i].pos[a] = (float)pcg32_uniform(&rng);
            ph[i].dir[a] = a == 2 ? 1.0f : 0.0f;
            ph[i].power[a] = 1e-6f;
        }
    pm_map *map = pm_map_new();
    char err[256];
    cr_assert(pm_map_add_photons(map, ph, N, err, sizeof err) == PM_OK, "%s", err);
    free(ph);
    /* Room for pm_map_build's own copy of the positions and its row-to-photon table (12 + 4
     * bytes each; the scratch of its spatial order is freed before the copy is made) and 8 MiB
     * more; FLANN's reordered copy of the points alone needs another 12 bytes each (24 MB). */
    struct rlimit old, lim;
    cr_assert(getrlimit(RLIMIT_AS, &old) == 0);
    lim = old;
    lim.rlim_cur = (rlim_t)(vm_size_kib() + (16L * N) / 1024 + 8 * 1024) * 1024;
    cr_assert(setrlimit(RLIMIT_AS, &lim) == 0);
    pm_status st = pm_map_build(map, err, sizeof err);
    cr_assert(setrlimit(RLIMIT_AS, &old) == 0);
    cr_expect(st == PM_ERR_NOMEM, "status %d: %s", st, err);
    cr_expect(strstr(err, "out of memory") && strstr(err, "kd-tree"), "%s", err);
    cr_expect(pm_map_build(map, err, sizeof err) == PM_OK, "without the limit: %s", err);
    pm_map_free(map);
}
