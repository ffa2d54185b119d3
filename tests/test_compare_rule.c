/* `photonmarch compare`'s first impression (issue 24; docs/compare.md): the default reference's
 * rule (rendered until its variance is at most a tenth of the best method's MSE; a cached one
 * too noisy for the runs is extended, to the very render of that many samples), --ref-time
 * alone deciding the reference, the summary in words (the bias share on constructed rows and on
 * synthetic runs of known bias and variance, the sentences in the table and the page), and the
 * --add labels that would overwrite the report's own files refused. */
#include "support/rd_test.h"
#include "support/compare_scene.h"
#include "support/test_rng.h"
#include "compare/rd_compare.h"

#include <cJSON.h>

/* small_scene_json: tests/support/compare_scene.h */

static const char *const only_delta[] = {"delta"};

/* small_scene_json with --set overrides KEY=VALUE (n of them; e.g. settings.equiangular=false:
 * its rendered reference is then plain `delta`, one stream whose extension is a prefix; without
 * the key, a scene with a point light gets a reference with "tiles", whose parts choose their
 * tiles apart: reference.c), loaded as rt_scene loads it. */
static rd_scene *small_scene_with(const char *name, int n, const char *const *kv)
{
    char path[256], err[RD_ERRLEN];
    snprintf(path, sizeof path, "%s/%s", rt_tmpdir(), name);
    rt_write_file(path, small_scene_json, strlen(small_scene_json));
    rd_override ov[4];
    cr_assert(n <= 4);
    for (int i = 0; i < n; i++) ov[i] = (rd_override){.key = kv[2 * i], .value = kv[2 * i + 1]};
    rd_scene *s = NULL;
    cr_assert(rd_scene_load(&s, path, ov, n, err, sizeof err) == RD_OK, "%s", err);
    s->settings.select = RD_SELECT_OFF; /* as rt_scene */
    return s;
}

static rd_cmp_opts delta_opts(const char *cache, double spp)
{
    rd_cmp_opts o = {.methods = only_delta, .n_methods = 1, .equal_spp = 1, .budget = spp, .runs = 2,
                     .seed = 5, .threads = 2, .cache_dir = cache, .ref_max_seconds = 600};
    return o;
}

/* ---- The rule ------------------------------------------------------------------------------ */

Test(compare_rule, a_reference_above_a_tenth_of_the_best_mse_needs_more_samples)
{
    /* At or below a tenth: enough as it is (and an unknown variance is not rendered further). */
    cr_expect(rd_cmp_ref_spp_needed(100, 0.9e-5, 1e-4) == 100);
    cr_expect(rd_cmp_ref_spp_needed(100, 1e-5, 1e-4) == 100);
    cr_expect(rd_cmp_ref_spp_needed(100, NAN, 1e-4) == 100);
    /* Half the best MSE: the method's own error is m = 5e-5; the rule v <= 0.1 (m + v) holds
     * from v = m / 9 = 5.56e-6, 9x below 5e-5, so 900 samples, and 990 with the 10% spared. */
    double n = rd_cmp_ref_spp_needed(100, 5e-5, 1e-4);
    cr_expect(n == 990, "needed %g", n);
    double v = 5e-5 * 100 / n, m = 1e-4 - 5e-5;
    cr_expect(v <= RD_CMP_REF_SHARE * (m + v), "at %g spp the rule fails: %g > 0.1 x %g", n, v, m + v);
    cr_expect(v > 0.8 * RD_CMP_REF_SHARE * (m + v), "but not by far more than asked: %g", v / (m + v));
}

/* A cached default reference of 10 spp (a comparison at 1 spp made it: 10x the budget), then a
 * comparison at 8 spp: its variance is (1/10) / (1/8 + 1/10) = 44% of delta's MSE, so it is
 * extended after the runs until it is at most 10%; the extension continues the same stream, so
 * the reference is the render of that many samples, and the cache holds it afterwards. */
Test(compare_rule, a_cached_reference_too_noisy_for_the_runs_is_extended, .timeout = 120)
{
    static const char *const plain_kv[] = {"settings.equiangular", "false"};
    rd_scene *s = small_scene_with("rule.json", 1, plain_kv);
    char cache[256], err[RD_ERRLEN];
    snprintf(cache, sizeof cache, "%s/cache", rt_tmpdir());
    rd_cmp_opts o = delta_opts(cache, 1);
    rd_comparison *c = NULL;
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    const rd_cmp_summary *S = rd_comparison_summary(c);
    /* 10x the budget, extended only if the estimates put it a little above a tenth of delta's
     * MSE (at 1/11 of it, the expected share; a fixed seed decides) */
    cr_expect(S->ref_auto && S->ref_rendered == 1 && S->ref_spp >= 10 && S->ref_spp <= 16, "first part: %g spp", S->ref_spp);
    cr_expect(!S->ref_too_noisy, "share %g", S->ref_share);
    rd_comparison_free(c);

    o = delta_opts(cache, 8);
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    S = rd_comparison_summary(c);
    cr_expect(S->ref_rendered == 2, "the cached reference is the start");
    cr_expect(S->ref_extended >= 1, "a reference at %g of the best MSE was not extended", S->ref_share);
    cr_expect(S->ref_spp >= 72, "extended to %g spp only", S->ref_spp);
    cr_expect(S->ref_var <= RD_CMP_REF_SHARE * S->rows[0].err.mse, "variance %g, best MSE %g", S->ref_var, S->rows[0].err.mse);
    cr_expect(!S->ref_too_noisy && !S->ref_capped);
    int spp = (int)S->ref_spp;
    cr_assert(spp == S->ref_spp, "a whole number of samples per pixel: %g", S->ref_spp);

    /* The same pixels as one render of spp samples of the reference's stream (to float
     * rounding of the merged parts). */
    cr_assert(rd_compare_write_report(c, s, rt_tmp_path("rule-report"), err, sizeof err) == RD_OK, "%s", err);
    rd_image ref, ref_se;
    char path[512];
    snprintf(path, sizeof path, "%s/reference.exr", rt_tmp_path("rule-report"));
    cr_assert(rd_image_read(path, &ref, err, sizeof err) == RD_OK, "%s", err);
    snprintf(path, sizeof path, "%s/reference-stderr.exr", rt_tmp_path("rule-report"));
    cr_assert(rd_image_read(path, &ref_se, err, sizeof err) == RD_OK, "%s", err);
    rd_render_opts ro = {.method = "delta", .spp = spp, .seed = REF_SEED(o.seed), .threads = 2};
    rd_render_result one;
    cr_assert(rd_render(s, &ro, &one, err, sizeof err) == RD_OK, "%s", err);
    double worst = 0, worst_se = 0;
    for (int i = 0; i < 24 * 16 * 3; i++) {
        worst = fmax(worst, fabs(ref.rgb[i] - one.image.rgb[i]) / (fabs(one.image.rgb[i]) + 1e-6));
        worst_se = fmax(worst_se, fabs(ref_se.rgb[i] - one.stderr_img.rgb[i]) / (one.stderr_img.rgb[i] + 1e-6));
    }
    cr_expect(worst < 1e-5, "the extended reference differs from one render by %g (relative)", worst);
    cr_expect(worst_se < 1e-3, "its standard error differs by %g (relative)", worst_se);
    rd_render_result_free(&one);
    rd_image_free_pixels(&ref);
    rd_image_free_pixels(&ref_se);
    rd_comparison_free(c);

    /* Again: the cache holds the extended reference, which is enough. */
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    S = rd_comparison_summary(c);
    cr_expect(S->ref_rendered == 2 && S->ref_spp == spp && S->ref_extended == 0,
              "cache: %d, %g spp, extended %d", S->ref_rendered, S->ref_spp, S->ref_extended);
    rd_comparison_free(c);

    /* A fixed reference (--ref-spp) is another key: it does not take the default one. */
    o.ref_spp = spp;
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(rd_comparison_summary(c)->ref_rendered == 1 && !rd_comparison_summary(c)->ref_auto);
    rd_comparison_free(c);
    rd_scene_free(s);
}

/* The rendered reference of a scene with a point light that does not name settings.equiangular
 * is `delta` with "tiles" (reference.c; the default reference and --ref-spp alike): the report
 * says so, and a --ref-spp one (one render) is the very render of that scene with "tiles" at
 * the reference's seed, whose tiles took the strategy (in thin fog, sigma_t 0.25, where the
 * strategy pays: 1.8x plain `delta`'s efficiency; 100% of the samples here. At sigma_t 0.5 it
 * halves the variance at twice the time, and the selection's halves left such a tie to the
 * cheaper plain path under session 27's rule; since session 40 the rest of the image's
 * prediction picks between the halves' two), so it is not plain `delta`'s image. It is unbiased: against an
 * independent plain `delta` render of many more samples, the pixels' summed difference over its
 * standard error (the two images' errors combined) is N(0, 1), checked to 5 sigma (fixed seeds;
 * 2.76 sigma here). The check can fail: the same reference 5% too bright fails it (12.0 sigma
 * here).
 * A scene that names the key gets its own `delta`. */
Test(compare_rule, a_point_lit_scene_s_rendered_reference_is_delta_with_tiles, .timeout = 120)
{
    char err[RD_ERRLEN];
    /* thin fog (sigma_t 0.25), where the tiles take the strategy on most samples */
    static const char *const thin[] = {"media[0].sigma_t", "0.25", "settings.equiangular", "\"tiles\""};
    static const char *const thin_plain[] = {"media[0].sigma_t", "0.25", "settings.equiangular", "false"};
    rd_scene *s = small_scene_with("strong.json", 1, thin);
    rd_cmp_opts o = delta_opts(NULL, 64);
    o.ref_spp = 640; /* one render, never extended (the default reference's first part is one too) */
    rd_comparison *c = NULL;
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    const rd_cmp_summary *S = rd_comparison_summary(c);
    cr_expect(strcmp(S->ref_method, "delta, settings.equiangular tiles") == 0, "reference by %s", S->ref_method);
    int spp = (int)S->ref_spp;
    cr_assert(spp == 640 && S->ref_extended == 0, "%d spp, extended %d", spp, S->ref_extended);
    cr_assert(rd_compare_write_report(c, s, rt_tmp_path("strong-report"), err, sizeof err) == RD_OK, "%s", err);
    rd_comparison_free(c);
    rd_image ref, ref_se;
    char path[512];
    snprintf(path, sizeof path, "%s/reference.exr", rt_tmp_path("strong-report"));
    cr_assert(rd_image_read(path, &ref, err, sizeof err) == RD_OK, "%s", err);
    snprintf(path, sizeof path, "%s/reference-stderr.exr", rt_tmp_path("strong-report"));
    cr_assert(rd_image_read(path, &ref_se, err, sizeof err) == RD_OK, "%s", err);
    const int nv = 24 * 16 * 3;

    { /* one render: that of the scene with "tiles", every sample drawn (the reference takes no
       * shares: reference.c; `delta`'s "auto" is the epochs' since session 72) */
        rd_scene *tiles = small_scene_with("strong-tiles.json", 2, thin);
        tiles->settings.adaptive = 0;
        rd_render_opts ro = {.method = "delta", .spp = spp, .seed = REF_SEED(o.seed), .threads = 2};
        rd_render_result t;
        cr_assert(rd_render(tiles, &ro, &t, err, sizeof err) == RD_OK, "%s", err);
        double worst = 0;
        for (int i = 0; i < nv; i++) worst = fmax(worst, fabs(ref.rgb[i] - t.image.rgb[i]) / (fabs(t.image.rgb[i]) + 1e-6));
        cr_expect(worst < 1e-5, "the reference differs from the render with tiles by %g (relative)", worst);
        uint64_t all = (uint64_t)24 * 16 * spp, without = t.stats.delta_samples;
        cr_log_info("tiles reference: %.1f%% of the samples with the strategy", 100.0 * (double)(all - without) / (double)all);
        cr_expect(without < all, "no tile took the strategy (%llu of %llu samples without it): plain delta's image",
                  (unsigned long long)without, (unsigned long long)all);
        rd_render_result_free(&t);
        rd_scene_free(tiles);
    }

    rd_scene *plain = small_scene_with("strong-plain.json", 2, thin_plain);
    rd_render_opts ro = {.method = "delta", .spp = 2048, .seed = 11, .threads = 2};
    rd_render_result one;
    cr_assert(rd_render(plain, &ro, &one, err, sizeof err) == RD_OK, "%s", err);
    double d = 0, d_bright = 0, v = 0;
    for (int i = 0; i < nv; i++) {
        d += ref.rgb[i] - one.image.rgb[i];
        d_bright += 1.05 * ref.rgb[i] - one.image.rgb[i];
        v += (double)ref_se.rgb[i] * ref_se.rgb[i] + (double)one.stderr_img.rgb[i] * one.stderr_img.rgb[i];
    }
    double z = d / sqrt(v), z_bright = d_bright / sqrt(v);
    cr_log_info("tiles reference: z %.2f, 5%% brighter %.2f", z, z_bright);
    cr_expect(fabs(z) < 5.0, "the tiles reference is %.2f sigma from plain delta", z);
    cr_expect(z_bright > 5.0, "5%% too bright is only %.2f sigma off: the check is too weak", z_bright);
    rd_render_result_free(&one);
    rd_image_free_pixels(&ref);
    rd_image_free_pixels(&ref_se);

    /* The scene names the key: its own `delta`. */
    cr_assert(rd_compare_run(plain, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    S = rd_comparison_summary(c);
    cr_expect(strcmp(S->ref_method, "delta") == 0, "reference by %s", S->ref_method);
    rd_comparison_free(c);
    rd_scene_free(plain);
    rd_scene_free(s);
}

/* A directional beam is a light the strategy samples (since session 30), so a scene lit by one
 * alone gets the reference with "tiles" too (reference.c) when its beam connections are off;
 * the mix's unbiasedness on a beam is tests/test_select.c's. Where the connections serve the
 * beam (settings.beam_connect, on by default since session 31) and without the beam's radius
 * (a plain sun), plain `delta`. */
Test(compare_rule, a_beam_lit_scene_s_rendered_reference_is_delta_with_tiles, .timeout = 60)
{
    static const char *fmt = "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"resolution\":[16,12]},"
                             "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                             "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":0.3,\"albedo\":0.8}],"
                             "\"lights\":[{\"type\":\"directional\",\"direction\":[1,-0.2,0.1],\"irradiance\":5%s}]%s}";
    /* a beam with its connections off; a sun without a radius; a beam that its connections
     * serve (settings.beam_connect "auto", the default: docs/free-path.md "Beam connections") */
    const char *beam = ",\"radius\":0.1,\"center\":[0,0,0]";
    const char *light[3] = {beam, "", beam};
    const char *settings[3] = {",\"settings\":{\"beam_connect\":false}", "", ""};
    const char *want[3] = {"delta, settings.equiangular tiles", "delta", "delta"};
    const char *name[3] = {"beamref.json", "sun.json", "beamconn.json"};
    for (int i = 0; i < 3; i++) {
        char json[1024], err[RD_ERRLEN];
        snprintf(json, sizeof json, fmt, light[i], settings[i]);
        rd_scene *s = rt_scene(name[i], json);
        rd_cmp_opts o = delta_opts(NULL, 4);
        o.ref_spp = 16;
        rd_comparison *c = NULL;
        cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
        const char *got = rd_comparison_summary(c)->ref_method;
        cr_expect(strcmp(got, want[i]) == 0, "%s: reference by %s", name[i], got);
        rd_comparison_free(c);
        rd_scene_free(s);
    }
}

/* The cap: a reference that would need more than ref_max_seconds stops there, and is then too
 * noisy to rank (said, not hidden). A cap below the first part stops it right after. */
Test(compare_rule, a_reference_at_its_cap_is_not_called_rankable, .timeout = 60)
{
    rd_scene *s = rt_scene("cap.json", small_scene_json);
    char err[RD_ERRLEN];
    rd_cmp_opts o = delta_opts(NULL, 64);
    o.ref_max_seconds = 1e-9;
    rd_comparison *c = NULL;
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    const rd_cmp_summary *S = rd_comparison_summary(c);
    cr_expect(S->ref_spp == 640, "the first part is 10x the budget: %g", S->ref_spp);
    cr_expect(S->ref_extended == 0);
    /* 640 spp against runs of 64: the rule holds (1/11 of delta's MSE) unless the noise of the
     * estimates says otherwise; either way the flag and the cap agree with the numbers. */
    cr_expect(S->ref_too_noisy == (S->ref_var > RD_CMP_REF_SHARE * S->rows[0].err.mse));
    cr_expect(!S->ref_too_noisy || S->ref_capped);
    rd_comparison_free(c);

    /* Runs far better than the reference: a cached reference of 10 spp (made by runs of 1 spp)
     * against runs of 64, which the cap does not let grow. */
    char cache[256];
    snprintf(cache, sizeof cache, "%s/capcache", rt_tmpdir());
    o = delta_opts(cache, 1);
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    rd_comparison_free(c);
    o = delta_opts(cache, 64);
    o.ref_max_seconds = 1e-9;
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    S = rd_comparison_summary(c);
    cr_expect(S->ref_spp <= 16 && S->ref_extended == 0, "the cap let it grow to %g spp", S->ref_spp);
    cr_expect(S->ref_too_noisy && S->ref_capped, "a 10-spp reference against 64-spp runs is too noisy (share %g)", S->ref_share);
    cr_expect(rd_cmp_winner(S) < 0, "and nothing is ranked");
    char line[512];
    rd_cmp_verdict(S, line, sizeof line);
    cr_expect(line[0] == 0, "one row: no verdict line (%s)", line);
    rd_comparison_free(c);
    rd_scene_free(s);
}

/* --ref-time alone: time decides (no samples-per-pixel cap); with --ref-spp the first limit
 * reached stops it. Checked against what the render reports, not the machine's speed. */
Test(compare_rule, ref_time_alone_decides_and_ref_spp_still_caps, .timeout = 60)
{
    rd_scene *s = rt_scene("rt.json", small_scene_json);
    char err[RD_ERRLEN];
    rd_cmp_opts o = delta_opts(NULL, 1);
    o.runs = 1;
    o.ref_time = 0.5;
    rd_comparison *c = NULL;
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    const rd_cmp_summary *S = rd_comparison_summary(c);
    cr_expect(!S->ref_auto && S->ref_extended == 0);
    cr_expect(S->ref_seconds >= 0.5, "the reference stopped at %g s, before its time (%g spp)", S->ref_seconds, S->ref_spp);
    rd_comparison_free(c);

    o.ref_spp = 8;
    o.ref_time = 100;
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    S = rd_comparison_summary(c);
    cr_expect(S->ref_spp == 8 && S->ref_seconds < 100, "%g spp, %g s", S->ref_spp, S->ref_seconds);
    rd_comparison_free(c);
    rd_scene_free(s);
}

/* ---- The summary in words ------------------------------------------------------------------ */

static rd_cmp_row row(const char *label, double eff, double bias2, double var)
{
    rd_cmp_row r = {0};
    snprintf(r.label, sizeof r.label, "%s", label);
    r.runs = 2;
    r.seconds = 10;
    r.efficiency = eff;
    r.split.bias2 = bias2;
    r.split.variance = var;
    r.err.mse = 1.0 / (eff * r.seconds);
    r.err.rmse = sqrt(r.err.mse);
    return r;
}

Test(compare_summary, sentences_on_constructed_rows)
{
    /* guided first, delta second: delta is the baseline all the same. */
    rd_cmp_row rows[4] = {row("guided", 140, 6.8e-5, 3.2e-5), row("delta", 100, 1e-6, 9e-6),
                          row("uniform", 20, -2e-6, 5e-5), row("pbrt", NAN, NAN, NAN)};
    rd_cmp_summary S = {.rows = rows, .n_rows = 3, .ref_var = 1e-7, .ref_share = 0.01};
    char line[512];
    cr_expect(rd_cmp_baseline(&S) == 1);
    cr_expect(rd_cmp_winner(&S) == 0);
    cr_expect_float_eq(rd_cmp_bias_share(&rows[0]), 0.68, 1e-12);
    rd_cmp_sentence(&S, 0, line, sizeof line);
    cr_expect_str_eq(line, "guided: 1.4x delta's efficiency; 68% of its error is bias");
    rd_cmp_sentence(&S, 1, line, sizeof line);
    cr_expect_str_eq(line, "delta: the baseline; 10% of its error is bias");
    /* A negative bias^2 (noise around none) is no bias. */
    rd_cmp_sentence(&S, 2, line, sizeof line);
    cr_expect_str_eq(line, "uniform: 0.2x delta's efficiency; 0% of its error is bias");
    rd_cmp_verdict(&S, line, sizeof line);
    cr_expect_str_eq(line, "winner: guided, 1.4x delta's efficiency");

    /* The baseline wins: by how much over the next best. */
    rows[0].efficiency = 50;
    rd_cmp_verdict(&S, line, sizeof line);
    cr_expect_str_eq(line, "winner: delta, 2.0x the efficiency of the next best (guided)");

    /* No delta: the first method is the baseline. An added image without its time has no
     * efficiency: its RMSE instead, and no bias share. */
    snprintf(rows[1].label, sizeof rows[1].label, "transmittance");
    rows[3].is_extra = 1;
    rows[3].err.rmse = 2 * rows[0].err.rmse;
    S.n_rows = 4;
    cr_expect(rd_cmp_baseline(&S) == 0);
    rd_cmp_sentence(&S, 1, line, sizeof line);
    cr_expect_str_eq(line, "transmittance: 2.0x guided's efficiency; 10% of its error is bias");
    rd_cmp_sentence(&S, 3, line, sizeof line);
    cr_expect_str_eq(line, "pbrt: no time given, so no efficiency; RMSE 2.0x guided's; bias and variance unknown (one image)");

    /* Too noisy: nothing is ranked, and the verdict says why. */
    S.ref_too_noisy = 1;
    S.ref_share = 0.3;
    cr_expect(rd_cmp_winner(&S) == -1);
    rd_cmp_verdict(&S, line, sizeof line);
    cr_expect(strstr(line, "not ranked: the reference is too noisy (its variance is 30% of the best MSE") == line, "%s", line);
}

/* The per-sample part of a sentence (docs/compare.md, "Per sample"): time per sample is the
 * render's time without the bake over its spp, variance per sample its variance times spp, both
 * as ratios to the baseline's; and for unbiased rows at equal time their product, with the
 * shares of the time left after the bakes, gives back the efficiency ratio. Rows written out by
 * hand: delta 10 s, 1000 spp, variance 2e-5 (2e-2 per sample, 10 ms per sample); guided 10 s of
 * which 1 s bake, 300 spp, variance 1e-5 (3e-3 per sample, 30 ms per sample). */
Test(compare_summary, per_sample_time_and_variance)
{
    rd_cmp_row d = row("delta", 0, 0, 2e-5), g = row("guided", 0, 0, 1e-5);
    d.spp = 1000, g.spp = 300, g.bake_seconds = 1.0;
    d.err.mse = d.split.variance, g.err.mse = g.split.variance;
    d.efficiency = 1.0 / (d.err.mse * d.seconds), g.efficiency = 1.0 / (g.err.mse * g.seconds);
    cr_expect_float_eq(rd_cmp_time_per_sample(&d), 0.010, 1e-15);
    cr_expect_float_eq(rd_cmp_time_per_sample(&g), 0.030, 1e-15);
    cr_expect_float_eq(rd_cmp_variance_per_sample(&d), 0.020, 1e-15);
    cr_expect_float_eq(rd_cmp_variance_per_sample(&g), 0.003, 1e-15);
    /* efficiency ratio = (T - bake)/T / (time ratio x variance ratio) = 0.9 / (3 x 0.15) = 2 */
    double t = rd_cmp_time_per_sample(&g) / rd_cmp_time_per_sample(&d);
    double v = rd_cmp_variance_per_sample(&g) / rd_cmp_variance_per_sample(&d);
    cr_expect_float_eq(g.efficiency / d.efficiency, (9.0 / 10.0) / (t * v), 1e-12);
    rd_cmp_row rows[2] = {g, d};
    rd_cmp_summary S = {.rows = rows, .n_rows = 2};
    char line[512];
    rd_cmp_sentence(&S, 0, line, sizeof line);
    cr_expect_str_eq(line, "guided: 2.0x delta's efficiency; 0% of its error is bias; per sample 3.0x the time and 0.15x the variance");
    /* The baseline's own line has no ratios; a row without samples has no per-sample part. */
    rd_cmp_sentence(&S, 1, line, sizeof line);
    cr_expect_str_eq(line, "delta: the baseline; 0% of its error is bias");
    rows[0].spp = 0;
    cr_expect(isnan(rd_cmp_time_per_sample(&rows[0])) && isnan(rd_cmp_variance_per_sample(&rows[0])));
    rd_cmp_sentence(&S, 0, line, sizeof line);
    cr_expect(strstr(line, "per sample") == NULL, "%s", line);
}

/* Synthetic runs x_k = r + b + sigma z: the split's bias share is b^2 / (b^2 + sigma^2) within
 * five standard errors (delta method on the split's two estimators, whose standard errors are
 * those of test_compare.c's split test), and the sentence prints that share. */
Test(compare_summary, bias_share_of_runs_with_a_known_bias)
{
    enum { W = 64, H = 64, K = 8 };
    const double b = 0.1, sigma = 0.2, n = W * H * 3;
    rd_image r = {W, H, malloc(sizeof(float) * W * H * 3), 0}, runs[K];
    for (int i = 0; i < W * H * 3; i++) r.rgb[i] = (float)(0.5 + 0.4 * sin(0.01 * i));
    rng g = rng_new(24);
    for (int j = 0; j < K; j++) {
        runs[j] = (rd_image){W, H, malloc(sizeof(float) * W * H * 3), 0};
        for (int i = 0; i < W * H * 3; i++) runs[j].rgb[i] = (float)(r.rgb[i] + b + sigma * rng_normal(&g));
    }
    rd_cmp_row rw[2] = {row("guided", 2, 0, 0), row("delta", 1, 0, 1)};
    cr_assert(rd_cmp_split_of(runs, K, &r, NULL, &rw[0].split, NULL, 0) == RD_OK);
    double B = b * b, V = sigma * sigma, s2k = V / K;
    double se_B = sqrt((2 * s2k * s2k + 4 * B * s2k + 2 * V * V / ((K - 1.0) * K * K)) / n);
    double se_V = V * sqrt(2.0 / ((K - 1) * n));
    double se_share = sqrt(V * V * se_B * se_B + B * B * se_V * se_V) / ((B + V) * (B + V));
    double share = rd_cmp_bias_share(&rw[0]);
    cr_expect(fabs(share - B / (B + V)) < 5 * se_share, "bias share %g, expected %g +- %g", share, B / (B + V), 5 * se_share);
    rd_cmp_summary S = {.rows = rw, .n_rows = 2};
    char line[256], want[64];
    rd_cmp_sentence(&S, 0, line, sizeof line);
    snprintf(want, sizeof want, "; %.0f%% of its error is bias", 100 * share);
    cr_expect(strstr(line, want) != NULL, "%s", line);
    for (int j = 0; j < K; j++) rd_image_free_pixels(&runs[j]);
    rd_image_free_pixels(&r);
}

/* The table on stdout and the page's header carry the same sentences. */
Test(compare_summary, table_and_page_say_it, .timeout = 120)
{
    rd_scene *s = rt_scene("say.json", small_scene_json);
    static const char *const two[] = {"guided", "delta"};
    rd_cmp_opts o = {.methods = two, .n_methods = 2, .equal_spp = 1, .budget = 4, .runs = 2, .seed = 5,
                     .threads = 2, .ref_spp = 64};
    char err[RD_ERRLEN];
    rd_comparison *c = NULL;
    cr_assert(rd_compare_run(s, &o, &c, err, sizeof err) == RD_OK, "%s", err);
    const char *dir = rt_tmp_path("say-report");
    cr_assert(rd_compare_write_report(c, s, dir, err, sizeof err) == RD_OK, "%s", err);
    static char table[1 << 14], page[1 << 18];
    FILE *f = fmemopen(table, sizeof table - 1, "w");
    rd_compare_print_table(c, f);
    fclose(f);
    char path[512];
    snprintf(path, sizeof path, "%s/index.html", dir);
    f = fopen(path, "r");
    cr_assert(f != NULL);
    page[fread(page, 1, sizeof page - 1, f)] = 0;
    fclose(f);
    const rd_cmp_summary *S = rd_comparison_summary(c);
    char line[512];
    for (int i = 0; i < S->n_rows; i++) {
        rd_cmp_sentence(S, i, line, sizeof line);
        cr_expect(strstr(table, line) != NULL, "not in the table: %s\n%s", line, table);
        cr_expect(strstr(page, line) != NULL, "not in the page: %s", line);
    }
    rd_cmp_sentence(S, 0, line, sizeof line);
    cr_expect(strstr(line, "guided: ") == line && strstr(line, "x delta's efficiency; ") && strstr(line, "% of its error is bias; per sample ") &&
                  strstr(line, "x the time and ") && strstr(line, "x the variance"),
              "%s", line);
    rd_cmp_verdict(S, line, sizeof line);
    cr_expect(line[0] && strstr(table, line) && strstr(page, line), "verdict: %s", line);
    snprintf(path, sizeof path, "%s/metrics.json", dir);
    f = fopen(path, "r");
    page[fread(page, 1, sizeof page - 1, f)] = 0;
    fclose(f);
    cJSON *j = cJSON_Parse(page);
    cJSON *sm = cJSON_GetObjectItemCaseSensitive(j, "summary");
    cr_expect_str_eq(cJSON_GetObjectItemCaseSensitive(sm, "baseline")->valuestring, "delta");
    cr_expect_str_eq(cJSON_GetObjectItemCaseSensitive(sm, "verdict")->valuestring, line);
    cJSON *ref = cJSON_GetObjectItemCaseSensitive(j, "reference");
    cr_expect_str_eq(cJSON_GetObjectItemCaseSensitive(ref, "decided_by")->valuestring, "spp");
    cr_expect(cJSON_IsBool(cJSON_GetObjectItemCaseSensitive(ref, "too_noisy")), "the old fields stay");
    cJSON_Delete(j);
    rd_comparison_free(c);
    rd_scene_free(s);
}

/* ---- --add labels ------------------------------------------------------------------------- */

Test(compare_rule, add_labels_that_would_overwrite_report_files_are_refused)
{
    rd_scene *s = rt_scene("add.json", small_scene_json);
    static const char *const two[] = {"guided", "delta"};
    /* label, and what the one-line error must name */
    static const char *const bad[][2] = {
        {"reference", "reference.exr"},          {"delta", "a method's name"},
        {"uniform", "a method's name"},          {"reference-stderr", "reference-stderr.exr"},
        {"reference-crop", "reference-crop.png"}, {"colorbar", "colorbar.png"},
        {"delta-error", "delta-error.png"},      {"guided-crop", "guided-crop.png"},
        {"other", "other.exr"}, /* the second of two "other"s */
        {"other-crop", "other-crop.png"},        {NULL, NULL}};
    char err[RD_ERRLEN], want[128];
    for (int i = 0; bad[i][0]; i++) {
        rd_cmp_extra ex[2] = {{"other", "x.exr", 0}, {bad[i][0], "x.exr", 0}};
        rd_cmp_opts o = {.methods = two, .n_methods = 2, .equal_spp = 1, .budget = 1, .runs = 1, .extras = ex,
                         .n_extras = 2, .ref_spp = 1};
        rd_comparison *c = NULL;
        cr_expect(rd_compare_run(s, &o, &c, err, sizeof err) == RD_ERR_ARG, "--add %s was accepted", bad[i][0]);
        snprintf(want, sizeof want, "--add %s: ", bad[i][0]);
        cr_expect(strstr(err, want) == err && strstr(err, bad[i][1]) && !strchr(err, '\n'), "%s", err);
        rd_comparison_free(c);
    }
    /* Labels that write files of their own are fine (checked up to the missing image). */
    static const char *const good[] = {"pbrt", "reference-old", "delta2", "index", "metrics", "curve", NULL};
    for (int i = 0; good[i]; i++) {
        char path[300];
        snprintf(path, sizeof path, "%s/missing.exr", rt_tmpdir());
        rd_cmp_extra ex = {good[i], path, 0};
        rd_cmp_opts o = {.methods = two, .n_methods = 2, .equal_spp = 1, .budget = 1, .runs = 1, .extras = &ex,
                         .n_extras = 1, .ref_spp = 1};
        rd_comparison *c = NULL;
        rd_status st = rd_compare_run(s, &o, &c, err, sizeof err);
        cr_expect(st == RD_ERR_IO || st == RD_ERR_FORMAT, "--add %s: %d, %s", good[i], st, err);
        cr_expect(strstr(err, "missing.exr") != NULL, "%s", err);
    }
    rd_scene_free(s);
}

/* ---- The command line ---------------------------------------------------------------------- */

static const char *bin_or_fail(void)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL, "PHOTONMARCH_BIN is not set (run through make test)");
    return bin;
}

Test(compare_cli, add_label_collision_is_a_usage_error, .timeout = 60)
{
    const char *bin = bin_or_fail();
    char scene[256], good[256], add[300], err[RD_ERRLEN];
    snprintf(scene, sizeof scene, "%s/cli.json", rt_tmpdir());
    rt_write_file(scene, small_scene_json, strlen(small_scene_json));
    static float px[24 * 16 * 3];
    rd_image im = {24, 16, px, 0};
    snprintf(good, sizeof good, "%s/good.exr", rt_tmpdir());
    cr_assert(rd_image_write_exr(good, &im, err, sizeof err) == RD_OK, "%s", err);
    static const char *const labels[] = {"reference", "delta", "delta-error", NULL};
    for (int i = 0; labels[i]; i++) {
        snprintf(add, sizeof add, "%s=%s@2", labels[i], good);
        char *argv[] = {(char *)bin, "compare", scene, "--methods", "delta", "--reference", good, "--add", add,
                        "-o", (char *)rt_tmp_path("cli-report"), "-q", NULL};
        static char out[4096], e[4096];
        int code = rt_run(argv, out, sizeof out, e, sizeof e, 0);
        char want[64];
        snprintf(want, sizeof want, "--add %s: ", labels[i]);
        cr_expect(code == 1, "--add %s: exit %d (expected 1, a usage error): %s", labels[i], code, e);
        cr_expect(strstr(e, want) != NULL && strchr(e, '\n') == e + strlen(e) - 1, "one line naming it: %s", e);
    }
    struct stat st;
    cr_expect(stat(rt_tmp_path("cli-report"), &st) != 0, "a refused comparison wrote a report folder");
}

/* The case: --ref-time alone was capped by the default --ref-spp (1024 spp in 17 s of
 * the 240 asked). Now the render runs for the time (it reports at least that many seconds). */
Test(compare_cli, ref_time_alone_is_not_capped, .timeout = 60)
{
    const char *bin = bin_or_fail();
    char scene[256];
    snprintf(scene, sizeof scene, "%s/rt.json", rt_tmpdir());
    rt_write_file(scene, small_scene_json, strlen(small_scene_json));
    const char *dir = rt_tmp_path("rt-report");
    char *argv[] = {(char *)bin, "compare", scene, "--methods", "delta", "--equal", "spp", "--budget", "1", "--runs", "1",
                    "--ref-time", "2", "--no-cache", "-o", (char *)dir, "-q", NULL};
    static char out[1 << 14], e[1 << 14];
    int code = rt_run(argv, out, sizeof out, e, sizeof e, 0);
    cr_assert(code == 0, "exit %d: %s", code, e);
    char path[512];
    snprintf(path, sizeof path, "%s/metrics.json", dir);
    FILE *f = fopen(path, "r");
    cr_assert(f != NULL);
    static char buf[1 << 18];
    buf[fread(buf, 1, sizeof buf - 1, f)] = 0;
    fclose(f);
    cJSON *j = cJSON_Parse(buf);
    cJSON *ref = cJSON_GetObjectItemCaseSensitive(j, "reference");
    double secs = cJSON_GetObjectItemCaseSensitive(ref, "seconds")->valuedouble;
    double spp = cJSON_GetObjectItemCaseSensitive(ref, "spp")->valuedouble;
    cr_expect(secs >= 2.0, "--ref-time 2 stopped at %g s (%g spp)", secs, spp);
    cr_expect_str_eq(cJSON_GetObjectItemCaseSensitive(ref, "decided_by")->valuestring, "time");
    cJSON_Delete(j);
    cr_expect(strstr(out, "delta: the baseline; ") != NULL, "the summary on stdout: %s", out);
}
