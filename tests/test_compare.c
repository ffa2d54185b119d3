/* `photonmarch compare` (issue 11; docs/compare.md): the metrics of THEORY.md §7 against
 * hand-computed values, the bias/variance split against synthetic images of known bias and
 * variance, a whole comparison in-process (two methods, two runs: the report folder is
 * complete, the reference is cached and reused, a changed scene misses the cache), the page in
 * headless Chromium (tests/compare_page.sh), and the command line's errors and Ctrl-C. */
#include "support/rd_test.h"
#include "support/compare_scene.h"
#include "support/test_rng.h"

#include <cJSON.h>
#include <signal.h>
#include <time.h>

/* ---- Metrics on tiny images -------------------------------------------------------------- */

Test(compare, errors_equal_hand_computed_values)
{
    /* Two pixels. Differences x - r: (1, 0, 0) and (0, 0, -0.5). With eps = 0.01:
     *   MSE    = (1 + 0.25) / 6                                   = 0.2083333...
     *   relMSE = (1 / (1 + 0.01) + 0.25 / (0.25 + 0.01)) / 6       = 0.3252729...
     *   MARE   = (1 / (1 + 0.01) + 0.5 / (0.5 + 0.01)) / 6         = 0.3284152... */
    float xr[6] = {2, 1, 1, 0.5f, 0.5f, 0}, rr[6] = {1, 1, 1, 0.5f, 0.5f, 0.5f};
    rd_image x = {2, 1, xr, 0}, r = {2, 1, rr, 0};
    rd_cmp_errors e;
    cr_assert(rd_cmp_errors_of(&x, &r, &e, NULL, 0) == RD_OK);
    cr_expect_float_eq(e.mse, 1.25 / 6, 1e-12);
    cr_expect_float_eq(e.rmse, sqrt(1.25 / 6), 1e-12);
    cr_expect_float_eq(e.relmse, (1 / 1.01 + 0.25 / 0.26) / 6, 1e-12);
    cr_expect_float_eq(e.mare, (1 / 1.01 + 0.5 / 0.51) / 6, 1e-12);
    rd_image small = {1, 1, rr, 0};
    char err[RD_ERRLEN];
    cr_expect(rd_cmp_errors_of(&x, &small, &e, err, sizeof err) == RD_ERR_ARG);
}

Test(compare, homogeneity_is_one_for_an_even_error_and_large_for_a_concentrated_one)
{
    enum { N = 100 };
    float r[3 * N], even[3 * N], spiky[3 * N];
    for (int i = 0; i < 3 * N; i++) {
        r[i] = 1.0f;
        even[i] = 1.1f;                     /* every pixel 10% off: p90 / p50 = 1 */
        spiky[i] = i / 3 < 80 ? 1.01f : 2.0f; /* 80 pixels 1% off, 20 pixels 100% off */
    }
    rd_image ri = {N, 1, r, 0}, ei = {N, 1, even, 0}, si = {N, 1, spiky, 0};
    cr_expect_float_eq(rd_cmp_homogeneity(&ei, &ri), 1.0, 1e-6);
    /* p50 = 0.01 / 1.01, p90 = 1 / 1.01: the ratio is 100 (to float rounding of 1.01f). */
    cr_expect_float_eq(rd_cmp_homogeneity(&si, &ri), 100.0, 1e-3);
}

/* Synthetic runs x_k = r + b + sigma z (z standard normal, fixed seed) over n values. */
static void synthetic_runs(rd_image *runs, int k, const rd_image *r, double b, double sigma, uint64_t seed)
{
    rng g = rng_new(seed);
    size_t n = (size_t)r->w * r->h * 3;
    for (int j = 0; j < k; j++) {
        runs[j] = (rd_image){r->w, r->h, malloc(n * sizeof(float)), 0};
        for (size_t i = 0; i < n; i++) runs[j].rgb[i] = (float)(r->rgb[i] + b + sigma * rng_normal(&g));
    }
}

Test(compare, split_recovers_a_known_bias_and_variance)
{
    enum { W = 64, H = 64, K = 8 };
    const double b = 0.05, sigma = 0.2, n = W * H * 3;
    rd_image r = {W, H, malloc(sizeof(float) * W * H * 3), 0};
    for (int i = 0; i < W * H * 3; i++) r.rgb[i] = (float)(0.5 + 0.4 * sin(0.01 * i));
    rd_image runs[K];
    synthetic_runs(runs, K, &r, b, sigma, 20261123);
    rd_cmp_split s;
    cr_assert(rd_cmp_split_of(runs, K, &r, NULL, &s, NULL, 0) == RD_OK);
    /* Tolerances: 5 standard errors of the estimators, for n independent values.
     * variance: the mean of n sample variances, each with variance 2 sigma^4 / (K - 1).
     * bias^2: the mean of d = (m - r)^2 - s^2 / K, whose variance is
     *   2 (sigma^2/K)^2 + 4 b^2 sigma^2 / K + 2 sigma^4 / ((K - 1) K^2). */
    double se_var = sigma * sigma * sqrt(2.0 / ((K - 1) * n));
    double s2k = sigma * sigma / K;
    double se_b2 = sqrt((2 * s2k * s2k + 4 * b * b * s2k + 2 * pow(sigma, 4) / ((K - 1.0) * K * K)) / n);
    cr_expect(fabs(s.variance - sigma * sigma) < 5 * se_var, "variance %g, expected %g +- %g", s.variance, sigma * sigma, 5 * se_var);
    cr_expect(fabs(s.bias2 - b * b) < 5 * se_b2, "bias^2 %g, expected %g +- %g", s.bias2, b * b, 5 * se_b2);
    /* The standard error the split reports is that of the same estimator (within 10%). */
    cr_expect(fabs(s.bias2_se / se_b2 - 1) < 0.1, "bias2_se %g, analytic %g", s.bias2_se, se_b2);
    for (int j = 0; j < K; j++) rd_image_free_pixels(&runs[j]);

    /* No bias: bias^2 within 5 standard errors of 0 (not driven negative or positive). */
    synthetic_runs(runs, K, &r, 0.0, sigma, 7);
    cr_assert(rd_cmp_split_of(runs, K, &r, NULL, &s, NULL, 0) == RD_OK);
    double se0 = sqrt((2 * s2k * s2k + 2 * pow(sigma, 4) / ((K - 1.0) * K * K)) / n);
    cr_expect(fabs(s.bias2) < 5 * se0, "bias^2 %g with no bias (se %g)", s.bias2, se0);
    for (int j = 0; j < K; j++) rd_image_free_pixels(&runs[j]);

    cr_expect(rd_cmp_split_of(runs, 1, &r, NULL, &s, NULL, 0) == RD_ERR_ARG, "one run gives no split");
    rd_image_free_pixels(&r);
}

Test(compare, add_argument_is_parsed_or_refused)
{
    char buf[256], err[RD_ERRLEN];
    rd_cmp_extra e;
    cr_assert(rd_cmp_extra_parse("pbrt=out/pbrt.exr@12.5", buf, sizeof buf, &e, err, sizeof err) == RD_OK, "%s", err);
    cr_expect_str_eq(e.label, "pbrt");
    cr_expect_str_eq(e.path, "out/pbrt.exr");
    cr_expect_float_eq(e.seconds, 12.5, 1e-12);
    cr_assert(rd_cmp_extra_parse("old=a@b/old.exr", buf, sizeof buf, &e, err, sizeof err) == RD_ERR_ARG,
              "an @ not followed by a number is refused");
    cr_assert(rd_cmp_extra_parse("old=old.exr", buf, sizeof buf, &e, err, sizeof err) == RD_OK);
    cr_expect(e.seconds == 0.0, "no time given");
    static const char *bad[] = {"noequals.exr", "=x.exr", "a=", "a=x.exr@-1", "a=x.exr@", "a b=x.exr", NULL};
    for (int i = 0; bad[i]; i++) {
        cr_expect(rd_cmp_extra_parse(bad[i], buf, sizeof buf, &e, err, sizeof err) == RD_ERR_ARG, "accepted %s", bad[i]);
        cr_expect(strstr(err, "--add") != NULL && !strchr(err, '\n'), "%s", err);
    }
}

/* ---- A whole comparison, in-process --------------------------------------------------- */

/* small_scene_json: tests/support/compare_scene.h */

static const char *const two_methods[] = {"guided", "delta"};

static rd_cmp_opts small_opts(const char *cache)
{
    rd_cmp_opts o = {.methods = two_methods, .n_methods = 2, .equal_spp = 1, .budget = 4, .runs = 2,
                     .seed = 5, .threads = 2, .ref_spp = 16, .cache_dir = cache};
    return o;
}

static int exists(const char *dir, const char *name)
{
    char p[512];
    snprintf(p, sizeof p, "%s/%s", dir, name);
    struct stat st;
    return stat(p, &st) == 0 && st.st_size > 0;
}

static cJSON *read_json(const char *path)
{
    FILE *f = fopen(path, "r");
    cr_assert(f != NULL, "no %s", path);
    static char buf[1 << 18];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    buf[n] = 0;
    fclose(f);
    cJSON *j = cJSON_Parse(buf);
    cr_assert(j != NULL, "%s is not JSON", path);
    return j;
}

Test(compare, two_methods_two_runs_write_a_complete_report, .timeout = 120)
{
    rd_scene *s = rt_scene("cmp.json", small_scene_json);
    char cache[256], dir[256], err[RD_ERRLEN];
    snprintf(cache, sizeof cache, "%s/cache", rt_tmpdir());
    snprintf(dir, sizeof dir, "%s/report", rt_tmpdir());
    rd_cmp_opts o = small_opts(cache);
    rd_comparison *c = NULL;
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    const rd_cmp_summary *S = rd_comparison_summary(c);
    cr_assert(S->n_rows == 2);
    cr_expect(S->ref_rendered == 1, "the first comparison renders its reference");
    cr_expect(S->ref_spp == 16);
    cr_expect(isfinite(S->ref_var) && S->ref_var > 0, "the rendered reference's own variance is measured");
    for (int i = 0; i < 2; i++) {
        const rd_cmp_row *r = &S->rows[i];
        cr_expect_str_eq(r->label, two_methods[i]);
        cr_expect(r->runs == 2 && r->split_from_runs);
        cr_expect(r->spp == 4, "equal spp: %s rendered %g spp", r->label, r->spp);
        cr_expect(r->err.rmse > 0 && isfinite(r->err.relmse) && isfinite(r->err.mare));
        cr_expect(isfinite(r->split.bias2) && r->split.variance > 0);
        cr_expect(r->efficiency > 0 && r->ttuv > 0 && r->lookups_pp > 0);
        cr_expect(fabs(r->efficiency * r->err.mse * r->seconds - 1) < 1e-9, "efficiency = 1 / (MSE x time)");
        cr_expect(fabs(r->ttuv - r->seconds * r->err.rmse) < 1e-12, "TTUV = time x RMSE");
    }
    cr_expect(S->rows[0].bake_seconds > 0, "guided bakes, and its bake time is recorded");
    cr_expect(S->rows[0].seconds >= S->rows[0].bake_seconds, "and counted in its time");
    cr_expect(S->rows[1].bake_seconds == 0, "delta bakes nothing");
    cr_assert(rd_compare_write_report(c, s, dir, err, sizeof err) == RD_OK, "%s", err);
    static const char *files[] = {"index.html", "metrics.json", "convergence.svg", "convergence.gp", "colorbar.png",
                                  "reference.exr", "reference.png", "reference-stderr.exr", "reference-crop.png",
                                  "guided.exr", "guided.png", "guided-error.png", "guided-crop.png", "curve-guided.dat",
                                  "delta.exr", "delta.png", "delta-error.png", "delta-crop.png", "curve-delta.dat", NULL};
    for (int i = 0; files[i]; i++) cr_expect(exists(dir, files[i]), "report: no %s", files[i]);
    char path[512];
    snprintf(path, sizeof path, "%s/metrics.json", dir);
    cJSON *j = read_json(path);
    cJSON *rows = cJSON_GetObjectItemCaseSensitive(j, "methods");
    cr_expect(cJSON_GetArraySize(rows) == 2);
    cJSON *g = cJSON_GetArrayItem(rows, 0);
    cr_expect_float_eq(cJSON_GetObjectItemCaseSensitive(g, "rmse")->valuedouble, S->rows[0].err.rmse, 1e-9);
    cr_expect(cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(g, "curve")) == 2, "one curve per run");
    cJSON_Delete(j);
    /* The reference image in the report is the one the metrics used: guided's RMSE again. */
    rd_image ref, img;
    snprintf(path, sizeof path, "%s/reference.exr", dir);
    cr_assert(rd_image_read(path, &ref, err, sizeof err) == RD_OK, "%s", err);
    snprintf(path, sizeof path, "%s/guided.exr", dir);
    cr_assert(rd_image_read(path, &img, err, sizeof err) == RD_OK, "%s", err);
    rd_cmp_errors e;
    rd_cmp_errors_of(&img, &ref, &e, NULL, 0);
    cr_expect(e.rmse > 0);
    rd_image_free_pixels(&img);
    rd_comparison_free(c);

    /* Again: the reference comes from the cache, the same pixels. */
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(rd_comparison_summary(c)->ref_rendered == 2, "the cached reference was not reused");
    cr_assert(rd_compare_write_report(c, s, dir, err, sizeof err) == RD_OK, "%s", err);
    snprintf(path, sizeof path, "%s/reference.exr", dir);
    cr_assert(rd_image_read(path, &img, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(memcmp(img.rgb, ref.rgb, sizeof(float) * 24 * 16 * 3) == 0, "the cached reference differs");
    rd_image_free_pixels(&img);
    rd_image_free_pixels(&ref);
    rd_comparison_free(c);
    rd_scene_free(s);

    /* A changed scene (another albedo) misses the cache: never a stale reference. */
    char changed[1024];
    snprintf(changed, sizeof changed, "%s", small_scene_json);
    char *a = strstr(changed, "\"albedo\":0.9");
    cr_assert(a != NULL);
    a[strlen("\"albedo\":0.")] = '8';
    s = rt_scene("cmp2.json", changed);
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(rd_comparison_summary(c)->ref_rendered == 1, "a changed scene reused the old reference");
    rd_comparison_free(c);
    rd_scene_free(s);
}

/* Equal time: every run renders until its budget, its share of the bake included, and stops
 * at the first pixel past it. On a virtual clock (rt_ticks: each reading advances it by dt, so
 * the load cannot move it): the budget is 1024 readings, two passes and a part of the 384 pixels
 * (a reading costs a pixel whatever its samples, so a longer budget would let the passes, sized
 * by the time they took, grow without end); a render reads the clock once before each pixel,
 * and after its deadline only each thread's
 * stopping reading, the pass's end and the report's come (rd_render's own test counts them
 * exactly: render/time_limit_*, which also checks that the bake charged to a run counts against
 * its limit). The bake is timed on the same clock (two readings: one tick). */
Test(compare, equal_time_runs_use_the_budget_and_charge_the_bake, .timeout = 120)
{
    rd_scene *s = rt_scene("cmpt.json", small_scene_json);
    char err[RD_ERRLEN];
    rt_ticks clk = {.dt = 1.0 / 1024};
    rd_cmp_opts o = small_opts(NULL);
    o.equal_spp = 0;
    o.budget = 1.0;
    o.runs = 1;
    o.clock = rt_ticks_read;
    o.clock_user = &clk;
    rd_comparison *c = NULL;
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    const rd_cmp_summary *S = rd_comparison_summary(c);
    cr_assert(S->n_rows == 2);
    for (int i = 0; i < 2; i++) {
        const rd_cmp_row *r = &S->rows[i];
        cr_expect(r->seconds >= o.budget && r->seconds <= o.budget + (o.threads + 2) * clk.dt,
                  "%s: %.9g s for a budget of %g (the clock's step %g)", r->label, r->seconds, o.budget, clk.dt);
        cr_expect(r->spp > 1, "%s: %g spp", r->label, r->spp);
        cr_expect(!r->split_from_runs && r->split.variance > 0, "one run: variance from the stderr image");
    }
    cr_expect(S->rows[0].bake_seconds == clk.dt && S->rows[1].bake_seconds == 0, "guided's bake is timed on the "
              "comparison's clock: %g s", S->rows[0].bake_seconds);
    rd_comparison_free(c);
    rd_scene_free(s);
}

/* ---- The page in headless Chromium ------------------------------------------------------ */

Test(compare, page_loads_in_headless_chromium_and_toggles, .timeout = 180)
{
    rd_scene *s = rt_scene("page.json", small_scene_json);
    char dir[256], shot[300], err[RD_ERRLEN];
    snprintf(dir, sizeof dir, "%s/page", rt_tmpdir());
    snprintf(shot, sizeof shot, "%s/page/screenshot.png", rt_tmpdir());
    rd_cmp_opts o = small_opts(NULL);
    o.runs = 1;
    rd_comparison *c = NULL;
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(rd_compare_write_report(c, s, dir, err, sizeof err) == RD_OK, "%s", err);
    rd_comparison_free(c);
    rd_scene_free(s);
    static char out[1 << 16], errb[1 << 16];
    char *argv[] = {"/bin/bash", "tests/compare_page.sh", dir, shot, NULL};
    int code = rt_run(argv, out, sizeof out, errb, sizeof errb, NULL);
    cr_expect(code == 0, "tests/compare_page.sh exit %d:\n%s\n%s", code, out, errb);
    cr_expect(strstr(out, "SELFTEST PASS") != NULL, "%s", out);
    cr_expect(strstr(out, "toggle guided.png -&gt; delta.png ok") != NULL, "the toggle did not switch: %s", out);
    cr_expect(exists(dir, "screenshot.png"), "no screenshot");
}

/* ---- The command line ---------------------------------------------------------------------- */

static const char *bin_or_fail(void)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL, "PHOTONMARCH_BIN is not set (run through make test)");
    return bin;
}

/* Run compare with a bad input; expect exit 2 and one line on stderr containing `expect`. */
static void expect_input_error(char *const argv[], const char *expect)
{
    static char out[1 << 14], err[1 << 14];
    int code = rt_run(argv, out, sizeof out, err, sizeof err, NULL);
    cr_expect(code == 2, "exit %d (expected 2): %s", code, err);
    cr_expect(strstr(err, expect) != NULL, "expected \"%s\" in: %s", expect, err);
    const char *nl = strchr(err, '\n');
    cr_expect(nl && nl[1] == 0, "expected one line: %s", err);
}

Test(compare, bad_reference_and_bad_add_give_one_line_errors_naming_the_file, .timeout = 120)
{
    const char *bin = bin_or_fail();
    const char *t = rt_tmpdir();
    char scene[256], small[256], text[256], good[256], dir[256], add[300];
    snprintf(scene, sizeof scene, "%s/cli.json", t);
    rt_write_file(scene, small_scene_json, strlen(small_scene_json));
    snprintf(dir, sizeof dir, "%s/cli-report", t);
    /* A 4x4 EXR (the scene renders 24x16), a text file named .exr, a good 24x16 EXR. */
    float px[24 * 16 * 3] = {0};
    rd_image im = {4, 4, px, 0};
    char err[RD_ERRLEN];
    snprintf(small, sizeof small, "%s/small.exr", t);
    cr_assert(rd_image_write_exr(small, &im, err, sizeof err) == RD_OK, "%s", err);
    snprintf(text, sizeof text, "%s/text.exr", t);
    rt_write_file(text, "not an image\n", 13);
    snprintf(good, sizeof good, "%s/good.exr", t);
    im = (rd_image){24, 16, px, 0};
    cr_assert(rd_image_write_exr(good, &im, err, sizeof err) == RD_OK, "%s", err);
    char missing[256];
    snprintf(missing, sizeof missing, "%s/no-such.exr", t);
    /* A grey (one-channel) image of the right size: a PGM, which OpenImageIO reads. */
    char grey[256], pgm[24 * 16 * 2 + 32];
    snprintf(grey, sizeof grey, "%s/grey.pgm", t);
    int len = snprintf(pgm, sizeof pgm, "P2 24 16 255\n");
    for (int i = 0; i < 24 * 16; i++) pgm[len++] = '0', pgm[len++] = i % 24 == 23 ? '\n' : ' ';
    rt_write_file(grey, pgm, (size_t)len);

    char *a1[] = {(char *)bin, "compare", scene, "--methods", "delta", "-o", dir, "--reference", missing, NULL};
    expect_input_error(a1, missing);
    char *a2[] = {(char *)bin, "compare", scene, "--methods", "delta", "-o", dir, "--reference", small, NULL};
    expect_input_error(a2, "is 4x4, the scene renders 24x16");
    char *a3[] = {(char *)bin, "compare", scene, "--methods", "delta", "-o", dir, "--reference", text, NULL};
    expect_input_error(a3, text);
    char *a8[] = {(char *)bin, "compare", scene, "--methods", "delta", "-o", dir, "--reference", grey, NULL};
    expect_input_error(a8, "has 1 channel, expected RGB or RGBA");
    snprintf(add, sizeof add, "other=%s@3", small);
    char *a4[] = {(char *)bin, "compare", scene, "--methods", "delta", "-o", dir, "--reference", good, "--add", add, NULL};
    expect_input_error(a4, "--add other:");
    expect_input_error(a4, "is 4x4, the scene renders 24x16");
    snprintf(add, sizeof add, "other=%s", missing);
    char *a5[] = {(char *)bin, "compare", scene, "--methods", "delta", "-o", dir, "--reference", good, "--add", add, NULL};
    expect_input_error(a5, missing);
    /* A malformed --add or an unknown method is a usage error (exit 1). */
    static char out[4096], e2[4096];
    char *a6[] = {(char *)bin, "compare", scene, "--methods", "delta", "--add", "nolabel.exr", NULL};
    cr_expect(rt_run(a6, out, sizeof out, e2, sizeof e2, NULL) == 1, "%s", e2);
    cr_expect(strstr(e2, "--add nolabel.exr: expected LABEL=IMAGE.exr[@SECONDS]") != NULL, "%s", e2);
    char *a7[] = {(char *)bin, "compare", scene, "--methods", "delta,magic", "-o", dir, "--reference", good, NULL};
    cr_expect(rt_run(a7, out, sizeof out, e2, sizeof e2, NULL) == 1, "%s", e2);
    cr_expect(strstr(e2, "unknown method \"magic\"") != NULL, "%s", e2);
    struct stat st;
    cr_expect(stat(dir, &st) != 0, "a failed comparison wrote a report folder");
}

Test(compare, ctrl_c_writes_the_report_of_the_runs_that_finished, .timeout = 120)
{
    const char *bin = bin_or_fail();
    const char *t = rt_tmpdir();
    char scene[256], dir[256], ref[256], err[RD_ERRLEN];
    snprintf(scene, sizeof scene, "%s/int.json", t);
    rt_write_file(scene, small_scene_json, strlen(small_scene_json));
    snprintf(dir, sizeof dir, "%s/int-report", t);
    /* A reference file, so the comparison starts with the runs. */
    snprintf(ref, sizeof ref, "%s/int-ref.exr", t);
    float px[24 * 16 * 3];
    for (int i = 0; i < 24 * 16 * 3; i++) px[i] = 0.05f;
    rd_image im = {24, 16, px, 0};
    cr_assert(rd_image_write_exr(ref, &im, err, sizeof err) == RD_OK, "%s", err);
    /* Two runs of delta at 2000 spp each (seconds per run): SIGINT when run 2 starts (its
     * progress line on a non-terminal stderr), so run 1 has finished and run 2 is cut. */
    char *argv[] = {(char *)bin, "compare", scene, "--methods", "delta", "--runs", "2", "--budget", "2000",
                    "--equal", "spp", "--reference", ref, "-o", dir, "--threads", "1", NULL};
    static char out[1 << 14], errb[1 << 14];
    int code = run_signal_on(argv, "delta run 2/2", SIGINT, errb, sizeof errb, out, sizeof out);
    cr_expect(code == 130, "exit %d (expected 130): %s", code, errb);
    cr_expect(exists(dir, "index.html") && exists(dir, "metrics.json") && exists(dir, "delta.png"), "no report: %s", errb);
    char path[512];
    snprintf(path, sizeof path, "%s/metrics.json", dir);
    cJSON *j = read_json(path);
    cr_expect(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(j, "cancelled")));
    cJSON *row = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(j, "methods"), 0);
    cr_expect(row && cJSON_GetObjectItemCaseSensitive(row, "runs")->valuedouble == 1, "the finished run only");
    cJSON_Delete(j);
    cr_expect(strstr(out, "report ") != NULL, "the table and the report's path on stdout: %s", out);
}

/* ---- Light delta cannot render (issue 21 item 6; docs/compare.md, "Light only photons find") */

Test(compare, light_only_photons_find_gets_a_photon_reference_and_a_note, .timeout = 180)
{
    /* rt_glass_ball_in_fog at 16x16 with a point light inside the glass ball: all of the fog's
     * light leaves it through glass
     * first, so delta renders black and a delta reference would be black too; the comparison
     * must measure the share (1), render the reference with photons (it is lit), find delta's
     * error all bias (its runs are identical: zero variance) and say so. */
    static const char *const only_delta[] = {"delta"};
    rd_scene *s = rt_glass_ball_in_fog("hidden_cmp.json", "{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":2}", 16);
    rd_cmp_opts o = {.methods = only_delta, .n_methods = 1, .equal_spp = 1, .budget = 2, .runs = 2,
                     .seed = 5, .threads = 2, .ref_spp = 8};
    rd_comparison *c = NULL;
    char err[RD_ERRLEN], note[1024];
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    const rd_cmp_summary *S = rd_comparison_summary(c);
    cr_expect(fabs(S->hidden_share - 1.0) < 1e-9, "share %.12f", S->hidden_share);
    cr_expect(strstr(S->ref_method, "photons") != NULL, "reference by %s", S->ref_method);
    cr_assert(S->n_rows == 1);
    cr_expect(S->rows[0].split.variance == 0.0 && S->rows[0].split.bias2 > 0.0,
              "delta: variance %g (black runs), bias^2 %g (the reference is lit)", S->rows[0].split.variance,
              S->rows[0].split.bias2);
    rd_cmp_hidden_note(S, note, sizeof note);
    cr_expect(strstr(note, "100% of the light") != NULL && strstr(note, "L S+") != NULL, "%s", note);
    rd_comparison_free(c);

    /* The default photon reference: 10x the budget (equal spp: 10 and 20 spp), cached under a
     * key of its limits, so a comparison with another budget renders its own and one with the
     * same budget reads it back. */
    char cache[256];
    snprintf(cache, sizeof cache, "%s/hidden-cache", rt_tmpdir());
    const int budgets[3] = {1, 2, 2}, rendered[3] = {1, 1, 2};
    for (int k = 0; k < 3; k++) {
        rd_cmp_opts d = {.methods = only_delta, .n_methods = 1, .equal_spp = 1, .budget = budgets[k], .runs = 1,
                         .seed = 5, .threads = 2, .cache_dir = cache};
        cr_assert(rd_compare_run(s, &d, &c, err, sizeof err) == RD_OK, "%s", err);
        S = rd_comparison_summary(c);
        cr_expect(S->ref_rendered == rendered[k] && S->ref_spp == 10 * budgets[k],
                  "budget %d: reference %s (1 rendered, 2 cache), %g spp", budgets[k],
                  S->ref_rendered == 1 ? "rendered" : "from the cache", S->ref_spp);
        rd_comparison_free(c);
    }
    rd_scene_free(s);

    /* A sphere light there instead: paths reach it, nothing is hidden, delta renders the
     * reference and the note is empty. */
    s = rt_glass_ball_in_fog("seen_cmp.json", "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":0.05,\"radiance\":20}", 16);
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    S = rd_comparison_summary(c);
    cr_expect(S->hidden_share == 0.0 && strcmp(S->ref_method, "delta") == 0, "share %g, reference by %s",
              S->hidden_share, S->ref_method);
    rd_cmp_hidden_note(S, note, sizeof note);
    cr_expect(note[0] == 0, "%s", note);
    rd_comparison_free(c);
    rd_scene_free(s);
}
