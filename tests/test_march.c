/* Guided ray marching and its baselines (renderer/integrators/march.c) against independent
 * estimators of the same image:
 *  - with single scattering and direct light only (max_depth 1, march.ls = nee), guided,
 *    uniform, transmittance and delta agree (their estimators are all unbiased for it);
 *  - with multiple scattering from the photon map, guided and transmittance agree (they share
 *    the estimator of sigma_s L_s; only the placement of the samples differs);
 *  - alpha = 1 (the defensive sampler alone) and a guide that is wrong on purpose (baked with
 *    the light elsewhere) leave the expected image unchanged;
 *  - with the photon estimate alone, the gap to delta shrinks as the photon count grows (its
 *    k-NN blur is the marchers' only bias);
 *  - without march.samples each placement takes its own calibrated samples per ray.
 * Comparisons are z-scores of the image mean and of 8x8-pixel region means, with standard
 * errors from the films' per-pixel standard errors (pixels are independent). Under equal
 * expectations each z is standard normal; with at most 12 regions per comparison the region
 * bound 4.5 keeps the chance of a false alarm per test below 1e-4, the image bound is 5. */
#include "support/rd_test.h"

/* A heterogeneous, anisotropic medium lit by a spot (with falloff) and a directional beam. */
#define SCENE_BODY                                                                                  \
    "\"camera\":{\"position\":[0,0.3,4.2],\"look_at\":[0,0,0],\"fov\":34,\"resolution\":[32,24]},"  \
    "\"media\":[{\"bounds\":{\"min\":[-1.3,-1,-1],\"max\":[1.3,1,1]},"                              \
    "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":2,\"amplitude\":2,\"seed\":3,"       \
    "\"shape\":\"ellipsoid\",\"edge\":0.5},\"sigma_t\":2.5,\"albedo\":0.85,\"g\":0.6}],"

static const char *scene_json_photons(const char *extra, double spot_x, int photons)
{
    static char buf[2048];
    snprintf(buf, sizeof buf,
             "{" SCENE_BODY
             "\"lights\":[{\"type\":\"spot\",\"position\":[%g,2,1.5],\"look_at\":[-0.2,0,0],\"angle\":30,"
             "\"falloff\":8,\"intensity\":[20,16,12]},"
             "{\"type\":\"directional\",\"direction\":[1,-0.2,-0.3],\"irradiance\":[2,3,4],\"radius\":0.25,"
             "\"center\":[0.3,0.1,0]}],"
             "\"photons\":{\"count\":%d},\"guide\":{\"bands\":4},%s}",
             spot_x, photons, extra);
    return buf;
}

static const char *scene_json(const char *extra, double spot_x)
{
    return scene_json_photons(extra, spot_x, 40000);
}

Test(march, single_scattering_agrees_with_delta, .timeout = 300)
{
    rd_scene *s = rt_scene("ss_march.json", scene_json("\"settings\":{\"max_depth\":1},\"march\":{\"ls\":\"nee\",\"samples\":8}", -2.5));
    rd_render_result d = rt_render(s, "delta", 512, 11, NULL);
    const char *methods[] = {"guided", "uniform", "transmittance"};
    for (int i = 0; i < 3; i++) {
        rd_render_result m = rt_render(s, methods[i], 64, 20 + i, NULL);
        rt_expect_same(&d, &m, methods[i]);
        rd_render_result_free(&m);
    }
    rd_render_result_free(&d);
    rd_scene_free(s);
}

Test(march, sphere_and_environment_light_keep_their_full_direct_light, .timeout = 300)
{
    /* The marchers have no phase-sampled continuation, so their next-event estimate must carry
     * no MIS weight: a sphere light inside the medium's bounds and an environment light, single
     * scattering, against delta (whose MIS pair of NEE and phase sampling is unbiased). */
    rd_scene *s = rt_scene("sph_march.json",
        "{" SCENE_BODY
        "\"lights\":[{\"type\":\"sphere\",\"center\":[0.6,0.5,0.2],\"radius\":0.3,\"radiance\":[6,5,4]},"
        "{\"type\":\"environment\",\"radiance\":[0.3,0.4,0.5]}],"
        "\"photons\":{\"count\":20000},\"settings\":{\"max_depth\":1},\"march\":{\"ls\":\"nee\",\"samples\":8}}");
    rd_render_result d = rt_render(s, "delta", 512, 41, NULL);
    rd_render_result g = rt_render(s, "guided", 64, 42, NULL);
    rt_expect_same(&d, &g, "guided, sphere + environment light");
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    rd_scene_free(s);
}

Test(march, guided_and_transmittance_share_the_multiple_scattering_estimate, .timeout = 300)
{
    /* nee+photons: direct light by NEE, multiple scattering from the indirect photon map;
     * nee+guide: the same from the guide baked from the indirect photons; nee+beams: the same
     * photons as balls along the whole segment. For each source both
     * renders use one bake: their expectations are equal. */
    const char *sources[] = {"nee+photons", "nee+guide", "nee+beams"};
    for (int k = 0; k < 3; k++) {
        char extra[128];
        snprintf(extra, sizeof extra, "\"march\":{\"samples\":8,\"ls\":\"%s\"}", sources[k]);
        rd_scene *s = rt_scene("ms_march.json", scene_json(extra, -2.5));
        char err[RD_ERRLEN];
        rd_baked *b = NULL;
        rd_bake_opts bo = {.seed = -1};
        rd_bake_opts_for(&bo, rd_method_needs_for("guided", s));
        cr_assert(rd_bake(s, &bo, &b, err, sizeof err) == RD_OK, "%s", err);
        rd_render_result g = rt_render(s, "guided", 64, 5, b);
        rd_render_result t = rt_render(s, "transmittance", 64, 6, b);
        char what[64];
        snprintf(what, sizeof what, "guided vs transmittance, %s", sources[k]);
        rt_expect_same(&g, &t, what);
        rd_render_result_free(&g);
        rd_render_result_free(&t);
        rd_baked_free(b);
        rd_scene_free(s);
    }
}

Test(march, defensive_only_and_wrong_guides_keep_the_expectation, .timeout = 300)
{
    rd_scene *s = rt_scene("w_march.json", scene_json("\"settings\":{\"max_depth\":1},\"march\":{\"ls\":\"nee\",\"samples\":8}", -2.5));
    rd_render_result u = rt_render(s, "uniform", 96, 31, NULL);
    /* alpha = 1: the guided method samples the defensive (uniform) component only. */
    rd_scene *s1 = rt_scene("w1_march.json", scene_json("\"settings\":{\"max_depth\":1},\"march\":{\"ls\":\"nee\",\"samples\":8,\"alpha\":1}", -2.5));
    rd_render_result a1 = rt_render(s1, "guided", 96, 32, NULL);
    rt_expect_same(&u, &a1, "alpha = 1");
    /* A guide baked with the spot on the other side of the medium: wrong on purpose. */
    rd_scene *sw = rt_scene("ww_march.json", scene_json("\"settings\":{\"max_depth\":1},\"march\":{\"ls\":\"nee\",\"samples\":8}", 2.5));
    char err[RD_ERRLEN];
    rd_baked *wrong = NULL;
    rd_bake_opts bo = {.seed = -1};
    cr_assert(rd_bake(sw, &bo, &wrong, err, sizeof err) == RD_OK, "%s", err);
    rd_render_result gw = rt_render(s, "guided", 96, 33, wrong);
    rt_expect_same(&u, &gw, "guide baked with the light elsewhere");
    rd_render_result_free(&u);
    rd_render_result_free(&a1);
    rd_render_result_free(&gw);
    rd_baked_free(wrong);
    rd_scene_free(s);
    rd_scene_free(s1);
    rd_scene_free(sw);
}

Test(march, explain_agrees_with_the_renderer_on_one_ray, .timeout = 300)
{
    /* explain's dense integral I of one camera ray and its predicted per-ray variance of the
     * guided and uniform estimates, against what the renderer measures on that same ray
     * (camera.jitter false: every sample through the pixel centre). Deterministic source and T
     * (march.ls = photons from one bake, constant medium: exact T), a grey scene (the three
     * channels equal the luminance), background 0, so each render sample is exactly explain's
     * stratified estimate (1/N) sum f(t_n)/p(t_n) up to the dense table's resolution.
     * Tolerances: the mean within 5 standard errors of the render (plus 0.5% for the 20000-point
     * table); the variance within 5 standard errors of the difference of two sample variances,
     * each from explain's fourth moment: se^2 = (m4 - var^2) / spp + var_se^2. */
    rd_scene *s = rt_scene("explain_march.json",
        "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"fov\":30,\"resolution\":[5,5],\"jitter\":false},"
        "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1.2,\"albedo\":0.8,\"g\":0.5}],"
        "\"lights\":[{\"type\":\"spot\",\"position\":[-2.5,0.3,0],\"look_at\":[0,0,0],\"angle\":20,\"intensity\":[30,30,30]}],"
        "\"photons\":{\"count\":30000},\"march\":{\"ls\":\"photons\",\"samples\":8}}");
    char err[RD_ERRLEN];
    rd_baked *b = NULL;
    rd_bake_opts bo = {.seed = -1};
    cr_assert(rd_bake(s, &bo, &b, err, sizeof err) == RD_OK, "%s", err);
    const int px = 2, py = 2, spp = 800;
    rd_explain_opts eo = {.px = px, .py = py, .baked = b, .n = 20000, .seed = 9};
    rd_explain_result e;
    cr_assert(rd_explain(s, &eo, &e, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(e.hits_media && e.I > 0.0, "the centre ray must see lit medium");
    const char *methods[] = {"guided", "uniform"};
    const int which[] = {RD_EXPLAIN_GUIDED, RD_EXPLAIN_UNIFORM};
    for (int k = 0; k < 2; k++) {
        rd_render_result r = rt_render(s, methods[k], spp, 70 + k, b);
        size_t i = 3 * ((size_t)py * r.image.w + px);
        double mean = r.image.rgb[i], se = r.stderr_img.rgb[i];
        double var = se * se * spp; /* per-sample variance the film measured */
        int j = which[k];
        cr_expect(fabs(mean - e.I) < 5.0 * se + 0.005 * e.I, "%s: pixel %g vs explain's I %g (se %g)",
                  methods[k], mean, e.I, se);
        double var_tol = 5.0 * sqrt(fmax(0.0, e.m4[j] - e.var[j] * e.var[j]) / spp + e.var_se[j] * e.var_se[j]);
        cr_expect(fabs(var - e.var[j]) < var_tol, "%s: measured variance %g vs explain's %g (tolerance %g)",
                  methods[k], var, e.var[j], var_tol);
        cr_log_info("%s: mean %g I %g se %g; var %g predicted %g tol %g", methods[k], mean, e.I, se, var, e.var[j], var_tol);
        rd_render_result_free(&r);
    }
    rd_explain_result_free(&e);
    rd_baked_free(b);
    rd_scene_free(s);
}

/* explain prepares `guided` without photon passes: with march.beams (and nothing else asking the
 * bake for the indirect map: guided_paths off) it explains the scene's own source and does not
 * ask for the beams' balls, which only the passes' maps feed (guided.c). */
Test(march, explain_with_the_beams_estimator_needs_no_pass, .timeout = 120)
{
    rd_scene *s = rt_scene("explain_beams.json",
        "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"fov\":30,\"resolution\":[5,5]},"
        "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1.2,\"albedo\":0.8,\"g\":0.5}],"
        "\"lights\":[{\"type\":\"point\",\"position\":[0,1.6,0.5],\"intensity\":4}],"
        "\"photons\":{\"count\":20000},\"march\":{\"beams\":true,\"guided_paths\":false},\"settings\":{\"select\":\"tiles\"}}");
    char err[RD_ERRLEN];
    rd_baked *b = NULL; /* the bake `photonmarch explain` makes: what guided needs for the scene */
    rd_bake_opts bo = {.seed = -1};
    rd_bake_opts_for(&bo, rd_method_needs_for("guided", s));
    cr_assert(rd_bake(s, &bo, &b, err, sizeof err) == RD_OK, "%s", err);
    rd_explain_opts eo = {.px = 2, .py = 2, .baked = b, .n = 200, .seed = 9};
    rd_explain_result e;
    cr_assert(rd_explain(s, &eo, &e, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(e.hits_media && e.I > 0.0, "the centre ray must see lit medium");
    rd_explain_result_free(&e);
    rd_baked_free(b);
    rd_scene_free(s);
}

Test(march, each_placement_takes_its_own_default_samples_per_ray, .timeout = 120)
{
    /* Without march.samples each placement takes its calibrated N_mean (integrators/march.c,
     * march_default_samples: guided 2, transmittance 4, uniform 8). The render with the key
     * absent must equal, sample for sample, the render with that N given explicitly (same
     * seed, same image, same samples per ray); uniform and transmittance take exactly N per
     * ray. An explicit march.samples applies to every placement. */
    static const struct { const char *method; int n; } want[] = {{"guided", 2}, {"transmittance", 4}, {"uniform", 8}};
    char extra[128];
    rd_scene *dflt = rt_scene("dflt_n.json", scene_json("\"settings\":{\"max_depth\":1},\"march\":{\"ls\":\"nee\"}", -2.5));
    for (int i = 0; i < 3; i++) {
        snprintf(extra, sizeof extra, "\"settings\":{\"max_depth\":1},\"march\":{\"ls\":\"nee\",\"samples\":%d}", want[i].n);
        rd_scene *expl = rt_scene("expl_n.json", scene_json(extra, -2.5));
        rd_render_result a = rt_render(dflt, want[i].method, 1, 5, NULL);
        rd_render_result b = rt_render(expl, want[i].method, 1, 5, NULL);
        cr_assert(a.stats.rays_marched > 0, "%s: no ray marched", want[i].method);
        cr_expect(a.stats.samples_per_ray == b.stats.samples_per_ray, "%s: %g samples per ray by default, %g with samples = %d",
                  want[i].method, a.stats.samples_per_ray, b.stats.samples_per_ray, want[i].n);
        if (strcmp(want[i].method, "guided") != 0)
            cr_expect(a.stats.samples_per_ray == want[i].n, "%s: %g samples per ray, expected %d", want[i].method,
                      a.stats.samples_per_ray, want[i].n);
        size_t n = (size_t)a.image.w * a.image.h * 3;
        cr_expect(memcmp(a.image.rgb, b.image.rgb, n * sizeof(float)) == 0, "%s: the images differ", want[i].method);
        rd_render_result_free(&a);
        rd_render_result_free(&b);
        rd_scene_free(expl);
    }
    /* An explicit value is every placement's: uniform with samples = 3 takes 3 per ray. */
    rd_scene *three = rt_scene("three_n.json", scene_json("\"settings\":{\"max_depth\":1},\"march\":{\"ls\":\"nee\",\"samples\":3}", -2.5));
    rd_render_result u = rt_render(three, "uniform", 1, 5, NULL);
    cr_expect(u.stats.samples_per_ray == 3.0, "uniform: %g samples per ray with samples = 3", u.stats.samples_per_ray);
    rd_render_result_free(&u);
    rd_scene_free(three);
    rd_scene_free(dflt);
}

/* Squared gap between two renders over 4x4-pixel regions of luminance: the sum over regions of
 * (m_a - m_b)^2 minus its noise (v_a + v_b), an unbiased estimate of the sum of squared
 * differences of the expectations; *sd is its standard deviation (per region, for
 * x ~ N(b, s^2), var(x^2) = 2 s^4 + 4 b^2 s^2, with b^2 estimated by max(0, x^2 - s^2)). */
static double gap2(const rd_render_result *a, const rd_render_result *b, double *sd)
{
    int w = a->image.w, h = a->image.h;
    double sum = 0.0, var = 0.0;
    for (int ry = 0; ry < h; ry += 4)
        for (int rx = 0; rx < w; rx += 4) {
            double d = 0.0, v = 0.0;
            int n = 0;
            for (int y = ry; y < ry + 4 && y < h; y++)
                for (int x = rx; x < rx + 4 && x < w; x++, n++)
                    for (int k = 0; k < 2; k++) {
                        const rd_render_result *r = k ? b : a;
                        const float *p = &r->image.rgb[3 * ((size_t)y * w + x)];
                        const float *e = &r->stderr_img.rgb[3 * ((size_t)y * w + x)];
                        double se = v3_lum(v3(e[0], e[1], e[2]));
                        d += (k ? -1.0 : 1.0) * v3_lum(v3(p[0], p[1], p[2]));
                        v += se * se;
                    }
            d /= n, v /= (double)n * n;
            double b2 = fmax(0.0, d * d - v);
            sum += d * d - v;
            var += 2.0 * v * v + 4.0 * b2 * v;
        }
    *sd = sqrt(var);
    return sum;
}

Test(march, gap_to_delta_shrinks_as_photons_grow, .timeout = 300)
{
    /* Multiple scattering with the photon estimate alone (march.ls = photons, the seed's
     * original): its k-NN blur is the only bias, and it falls as the photon count grows. The
     * squared gap to a delta render (gap2) at 1e3, 1e4 and 1e5 photons must fall: the last is
     * below the first by more than 4.5 standard deviations of their difference, and the middle
     * is no more than 3 standard deviations above the first. */
    rd_scene *s = rt_scene("gap_delta.json", scene_json("\"march\":{\"ls\":\"photons\"}", -2.5));
    rd_render_result d = rt_render(s, "delta", 384, 71, NULL);
    static const int counts[] = {1000, 10000, 100000};
    double g[3], sd[3];
    for (int i = 0; i < 3; i++) {
        rd_scene *si = rt_scene("gap_photons.json", scene_json_photons("\"march\":{\"ls\":\"photons\"}", -2.5, counts[i]));
        rd_render_result r = rt_render(si, "guided", 48, 72 + i, NULL);
        g[i] = gap2(&r, &d, &sd[i]);
        cr_log_info("photons %d: squared gap to delta %.4g +- %.2g", counts[i], g[i], sd[i]);
        rd_render_result_free(&r);
        rd_scene_free(si);
    }
    cr_expect(g[0] - g[2] > 4.5 * sqrt(sd[0] * sd[0] + sd[2] * sd[2]),
              "the gap did not shrink from 1e3 to 1e5 photons: %.4g +- %.2g to %.4g +- %.2g", g[0], sd[0], g[2], sd[2]);
    cr_expect(g[1] < g[0] + 3.0 * sqrt(sd[0] * sd[0] + sd[1] * sd[1]),
              "the gap grew from 1e3 to 1e4 photons: %.4g +- %.2g to %.4g +- %.2g", g[0], sd[0], g[1], sd[1]);
    rd_render_result_free(&d);
    rd_scene_free(s);
}

Test(march, guided_continues_half_its_samples_paths_unless_told_otherwise, .timeout = 300)
{
    /* march.paths absent: guided takes its calibrated 0.5 (march_default_paths), the other
     * placements 1. Same seed, same random numbers: guided's image is that of march.paths 0.5 to
     * the bit and not that of 1 (which runs a path from every sample); uniform's is that of 1.
     * Whether 0.5 is unbiased is nee_paths_marchers_equal_delta_with_multiple_scattering's. */
    const char *sets[] = {"\"march\":{\"ls\":\"nee+paths\"}", "\"march\":{\"ls\":\"nee+paths\",\"paths\":0.5}",
                          "\"march\":{\"ls\":\"nee+paths\",\"paths\":1}"};
    const char *methods[] = {"guided", "uniform"};
    for (int m = 0; m < 2; m++) {
        rd_render_result r[3];
        for (int i = 0; i < 3; i++) {
            char name[64];
            snprintf(name, sizeof name, "qp%d_%d_march.json", m, i);
            rd_scene *s = rt_scene(name, scene_json(sets[i], -2.5));
            r[i] = rt_render(s, methods[m], 4, 91, NULL);
            rd_scene_free(s);
        }
        size_t n = (size_t)r[0].image.w * r[0].image.h * 3;
        int same_half = memcmp(r[0].image.rgb, r[1].image.rgb, n * sizeof(float)) == 0;
        int same_one = memcmp(r[0].image.rgb, r[2].image.rgb, n * sizeof(float)) == 0;
        if (m == 0)
            cr_expect(same_half && !same_one, "guided's default is not march.paths 0.5 (same as 0.5: %d, as 1: %d)",
                      same_half, same_one);
        else
            cr_expect(same_one && !same_half, "uniform's default is not march.paths 1 (same as 1: %d, as 0.5: %d)",
                      same_one, same_half);
        for (int i = 0; i < 3; i++) rd_render_result_free(&r[i]);
    }
}

Test(march, nee_paths_marchers_equal_delta_with_multiple_scattering, .timeout = 300)
{
    /* march.ls = nee+paths: delta's own vertex at every marching sample (next-event estimation
     * plus one phase-sampled path tracked by delta), so every placement is unbiased for the
     * whole image, multiple scattering included (max_depth 32). Each of guided (a path from
     * half its samples, its default march.paths, weighted 2), uniform and transmittance (a path
     * from every sample) against delta; guided also with march.paths 0.4. */
    rd_scene *s = rt_scene("np_march.json", scene_json("\"march\":{\"ls\":\"nee+paths\",\"samples\":4}", -2.5));
    rd_render_result d = rt_render(s, "delta", 512, 81, NULL);
    const char *methods[] = {"guided", "uniform", "transmittance"};
    for (int i = 0; i < 3; i++) {
        rd_render_result m = rt_render(s, methods[i], 96, 82 + i, NULL);
        rt_expect_same(&d, &m, methods[i]);
        rd_render_result_free(&m);
    }
    rd_scene *sq = rt_scene("npq_march.json", scene_json("\"march\":{\"ls\":\"nee+paths\",\"samples\":4,\"paths\":0.4}", -2.5));
    rd_render_result q = rt_render(sq, "guided", 96, 86, NULL);
    rt_expect_same(&d, &q, "guided, march.paths 0.4");
    rd_render_result_free(&q);
    /* nee+delta: the samples' next-event estimates plus one delta path along the ray that
     * leaves its first vertex's direct light to them (rd_delta_scattered); every pixel
     * marched. */
    rd_scene *sd = rt_scene("npd_march.json", scene_json("\"march\":{\"ls\":\"nee+delta\",\"samples\":4},\"settings\":{\"select\":\"off\"}", -2.5));
    rd_render_result nd = rt_render(sd, "guided", 96, 87, NULL);
    cr_assert(nd.stats.delta_samples == 0, "select off: every pixel is marched");
    rt_expect_same(&d, &nd, "guided, march.ls nee+delta");
    rd_render_result_free(&nd);
    rd_scene_free(sd);
    rd_render_result_free(&d);
    rd_scene_free(sq);
    rd_scene_free(s);
}

Test(march, nee_paths_counts_sphere_and_environment_light_once, .timeout = 300)
{
    /* With a path from each sample, light that the path can hit (a sphere light inside the
     * medium's bounds, an environment) is found twice, by next-event estimation and by the
     * path: rd_nee_split weights the two by the power heuristic as delta does, so the sum
     * counts it once. A double count (both at full weight) or a loss (NEE without the path's
     * share) moves the image by the direct light's share; against delta at full depth. */
    rd_scene *s = rt_scene("nps_march.json",
        "{" SCENE_BODY
        "\"lights\":[{\"type\":\"sphere\",\"center\":[0.6,0.5,0.2],\"radius\":0.3,\"radiance\":[6,5,4]},"
        "{\"type\":\"environment\",\"radiance\":[0.3,0.4,0.5]},"
        "{\"type\":\"spot\",\"position\":[-2.5,2,1.5],\"look_at\":[-0.2,0,0],\"angle\":30,\"falloff\":8,\"intensity\":[20,16,12]}],"
        "\"photons\":{\"count\":20000},\"march\":{\"ls\":\"nee+paths\",\"samples\":4}}");
    rd_render_result d = rt_render(s, "delta", 512, 91, NULL);
    rd_render_result g = rt_render(s, "guided", 96, 92, NULL);
    rt_expect_same(&d, &g, "guided nee+paths, sphere + environment + spot light");
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    rd_scene_free(s);
}

Test(march, equiangular_sample_keeps_the_expectation_and_finds_the_narrow_spot, .timeout = 300)
{
    /* march.equiangular (integrators/march_equiangular.c): one equiangular sample per segment
     * toward the spot, MIS (power heuristic) with the placement's samples, and the marcher's
     * paths' flights with `delta`'s equiangular strategy. On the small narrow-spot scene (a
     * 3-degree spot across thin fog, rt_spot_fog_json) every mode must keep the image of
     * `delta` with its own equiangular strategy (settings.equiangular, tested against
     * quadrature in test_integrator.c): single scattering with march.ls nee for each placement,
     * and the whole image (max_depth 8) with nee+paths. z bounds as in the head. The samples
     * must also find the spot: with the guide alone the cone's few centimetres lie inside one
     * or two guide cells, so the placement's samples land beside them; with the equiangular
     * sample the single-scattering image's variance (the mean over 3072 pixels of their
     * variances, each from 64 samples: fixed seeds, so the figure is the same every run) must
     * fall below a third of without (measured: 0.20 for guided, seed 93). Nine comparisons
     * of 6 lit regions each: a false alarm chance of about 4e-4 for the test under normal z.
     * A planted w_p of 1 - 0.7 w_e (weights summing to more than one) fails it at z = -7.6
     * to -12. */
    rd_scene *sd = rt_scene("eqm_delta.json", rt_spot_fog_json(64, 48, "{\"max_depth\":1,\"equiangular\":true}"));
    rd_render_result d = rt_render(sd, "delta", 2048, 91, NULL);
    const char *modes[] = {"false", "true", "\"auto\""};
    const char *methods[] = {"guided", "uniform", "transmittance"};
    double var_guided[3] = {0, 0, 0};
    for (int mo = 0; mo < 3; mo++)
        for (int i = 0; i < 3; i++) {
            if (mo == 0 && i > 0) continue; /* without the sample: guided alone, for its variance */
            char extra[256], what[96];
            snprintf(extra, sizeof extra, "\"photons\":{\"count\":40000},\"march\":{\"ls\":\"nee\",\"equiangular\":%s}", modes[mo]);
            rd_scene *s = rt_scene("eqm.json", rt_spot_fog_json_with(64, 48, "{\"max_depth\":1,\"select\":\"off\"}", extra));
            rd_render_result m = rt_render(s, methods[i], 64, 93 + i, NULL);
            snprintf(what, sizeof what, "%s, march.equiangular %s", methods[i], modes[mo]);
            rt_expect_same(&d, &m, what);
            if (i == 0) var_guided[mo] = rt_mean_pixel_var(&m);
            rd_render_result_free(&m);
            rd_scene_free(s);
        }
    cr_expect(var_guided[1] < var_guided[0] / 3.0, "guided's variance with the equiangular sample %.3g, without %.3g",
              var_guided[1], var_guided[0]);
    cr_log_info("guided's single-scattering variance: %.3g without, %.3g true, %.3g auto", var_guided[0], var_guided[1],
                var_guided[2]);
    rd_render_result_free(&d);
    rd_scene_free(sd);
    /* The whole image: the samples' paths go on with delta's equiangular strategy too. */
    rd_scene *sa = rt_scene("eqm_delta_all.json", rt_spot_fog_json(32, 24, "{\"max_depth\":8,\"equiangular\":true}"));
    rd_render_result da = rt_render(sa, "delta", 2048, 95, NULL);
    for (int mo = 1; mo < 3; mo++) {
        char extra[256], what[96];
        snprintf(extra, sizeof extra, "\"photons\":{\"count\":40000},\"march\":{\"ls\":\"nee+paths\",\"equiangular\":%s}", modes[mo]);
        rd_scene *s = rt_scene("eqm_all.json", rt_spot_fog_json_with(32, 24, "{\"max_depth\":8,\"select\":\"off\"}", extra));
        rd_render_result m = rt_render(s, "guided", 64, 96 + mo, NULL);
        snprintf(what, sizeof what, "guided nee+paths, march.equiangular %s", modes[mo]);
        rt_expect_same(&da, &m, what);
        rd_render_result_free(&m);
        rd_scene_free(s);
    }
    rd_render_result_free(&da);
    rd_scene_free(sa);
}

/* The strategy with a directional beam (transport/equiangular.c: a uniform sample on the chord
 * inside the beam's cylinder, settings.equiangular, march.equiangular and guide.equiangular
 * `true`): a beam of radius 0.08 across thin fog, the whole image (max_depth 8). `delta` with
 * the strategy, the marchers (nee+paths: the segment's sample and the paths' flights) and
 * guided-unbiased's flights must keep `delta`'s image without it; z bounds as in the head (four
 * comparisons of 12 lit regions; measured: worst |z| 1.8-2.6). A planted density of
 * 0.8 / (b - a) for the chord fails all four (z image -7.6 to -20), the quadrature test in
 * test_integrator.c and both of test_equiangular.c's beam tests. */
Test(march, a_directional_beam_s_equiangular_sample_keeps_every_method_s_image, .timeout = 300)
{
    static const char *fmt =
        "{\"camera\":{\"position\":[0,0.3,4.5],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[32,24]},"
        "\"media\":[{\"bounds\":{\"min\":[-2.2,-1,-1.2],\"max\":[1.0,1,1.2]},"
        "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":1.2,\"amplitude\":0.4,\"seed\":5,"
        "\"shape\":\"none\"},\"sigma_t\":0.3,\"albedo\":0.9,\"g\":0.5}],"
        "\"lights\":[{\"type\":\"directional\",\"direction\":[1,-0.15,0.2],\"irradiance\":[60,55,50],\"radius\":0.08,"
        "\"center\":[0,0.1,0]}],\"photons\":{\"count\":40000},%s,"
        "\"settings\":{\"max_depth\":8,\"select\":\"off\",\"equiangular\":%s}}";
    char json[2048];
    snprintf(json, sizeof json, fmt, "\"march\":{\"equiangular\":false}", "false");
    rd_scene *sd = rt_scene("beq_delta.json", json);
    rd_render_result d = rt_render(sd, "delta", 16384, 391, NULL);
    struct { const char *method, *extra, *settings_eq; int spp; } v[] = {
        {"delta", "\"march\":{\"equiangular\":false}", "true", 4096},
        {"guided", "\"march\":{\"ls\":\"nee+paths\",\"equiangular\":true}", "false", 512},
        {"uniform", "\"march\":{\"ls\":\"nee+paths\",\"equiangular\":true}", "false", 256},
        {"guided-unbiased", "\"guide\":{\"equiangular\":true,\"distances\":true}", "false", 2048},
    };
    for (size_t i = 0; i < sizeof v / sizeof v[0]; i++) {
        snprintf(json, sizeof json, fmt, v[i].extra, v[i].settings_eq);
        rd_scene *s = rt_scene("beq.json", json);
        rd_render_result m = rt_render(s, v[i].method, v[i].spp, 392 + (uint64_t)i, NULL);
        char what[96];
        snprintf(what, sizeof what, "%s with the beam's equiangular sample", v[i].method);
        rt_expect_same(&d, &m, what);
        rd_render_result_free(&m);
        rd_scene_free(s);
    }
    rd_render_result_free(&d);
    rd_scene_free(sd);
}

/* march.probes, settings.probes (delta's) and guide.probes (guided-unbiased's) are "auto" or a
 * whole number of camera chains in
 * [1, 256]; anything else is refused with one line naming the field (integrators/probes.c;
 * docs/scene-format.md). */
/* The scene of scene_json_photons with `key`.probes = value (guide's in its own section,
 * which that scene already has; its settings then `settings`, e.g. "{}"). */
static const char *probes_json_with(const char *key, const char *value, const char *settings)
{
    static char buf[2300];
    char extra[128];
    if (strcmp(key, "guide") != 0) {
        snprintf(extra, sizeof extra, "\"%s\":{\"probes\":%s}", key, value);
        return scene_json_photons(extra, -2.5, 1000);
    }
    char set[128];
    snprintf(set, sizeof set, "\"settings\":%s", settings);
    const char *base = scene_json_photons(set, -2.5, 1000), *at = strstr(base, "\"guide\":{");
    cr_assert(at != NULL, "the scene has no guide section");
    size_t head = (size_t)(at - base) + strlen("\"guide\":{");
    snprintf(buf, sizeof buf, "%.*s\"probes\":%s,%s", (int)head, base, value, base + head);
    return buf;
}

static const char *probes_json(const char *key, const char *value)
{
    return probes_json_with(key, value, "{}");
}

Test(march, probes_setting_is_checked)
{
    static const char *const where[] = {"march", "settings", "guide"};
    for (int w = 0; w < 3; w++) {
        static const char *const good[] = {"\"auto\"", "1", "256"};
        for (size_t i = 0; i < sizeof good / sizeof good[0]; i++) {
            rd_scene *s = rt_scene("probes_ok.json", probes_json(where[w], good[i]));
            int got = w == 2 ? s->guide.probes : w ? s->settings.probes : s->march.probes;
            cr_expect(got == (i == 0 ? 0 : atoi(good[i])), "%s.probes %s read as %d", where[w], good[i], got);
            rd_scene_free(s);
        }
        static const char *const bad[] = {"\"sometimes\"", "0", "257", "1.5", "true"};
        for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
            char path[256], err[RD_ERRLEN] = "", field[32];
            snprintf(field, sizeof field, "%s.probes", where[w]);
            snprintf(path, sizeof path, "%s/probes_bad.json", rt_tmpdir());
            const char *json = probes_json(where[w], bad[i]);
            rt_write_file(path, json, strlen(json));
            rd_scene *s = NULL;
            cr_expect(rd_scene_load(&s, path, NULL, 0, err, sizeof err) != RD_OK, "%s %s accepted", field, bad[i]);
            cr_expect(strstr(err, field) != NULL && strchr(err, '\n') == NULL, "%s %s: message \"%s\"", field, bad[i], err);
            rd_scene_free(s);
        }
    }
    /* With a "raymarch" transmittance or tracker more than one of guided-unbiased's probes is
     * refused, as settings.probes is (the probes and the path must be unbiased alike); 1 and
     * "auto" take none there and load. */
    static const char *const raymarch[] = {"{\"transmittance\":\"raymarch\"}", "{\"tracker\":\"raymarch\"}"};
    static const char *const gp[] = {"8", "2", "1", "\"auto\""};
    for (int r = 0; r < 2; r++)
        for (int i = 0; i < 4; i++) {
            char path[256], err[RD_ERRLEN] = "";
            const char *json = probes_json_with("guide", gp[i], raymarch[r]);
            snprintf(path, sizeof path, "%s/probes_rm.json", rt_tmpdir());
            rt_write_file(path, json, strlen(json));
            rd_scene *s = NULL;
            rd_status st = rd_scene_load(&s, path, NULL, 0, err, sizeof err);
            if (i < 2)
                cr_expect(st != RD_OK && strstr(err, "guide.probes") && strstr(err, "raymarch") && !strchr(err, '\n'),
                          "guide.probes %s with %s: status %d, \"%s\"", gp[i], raymarch[r], st, err);
            else
                cr_expect(st == RD_OK, "guide.probes %s with %s refused: %s", gp[i], raymarch[r], err);
            rd_scene_free(s);
        }
    /* the defaults: "auto" for the marchers and guided-unbiased, 1 (none) for delta */
    rd_scene *s = rt_scene("probes_default.json", scene_json_photons("\"settings\":{}", -2.5, 1000));
    cr_expect(s->march.probes == 0 && s->settings.probes == 1 && s->guide.probes == 0, "defaults %d, %d and %d",
              s->march.probes, s->settings.probes, s->guide.probes);
    rd_scene_free(s);
}

/* march.guided_paths (guided's selection may give tiles to guided-unbiased's paths): true by
 * default, a boolean, anything else refused with one line naming the field. */
Test(march, guided_paths_setting_is_checked)
{
    rd_scene *s = rt_scene("gp_default.json", scene_json_photons("\"settings\":{}", -2.5, 1000));
    cr_expect(s->march.guided_paths == 1, "default %d", s->march.guided_paths);
    rd_scene_free(s);
    s = rt_scene("gp_off.json", scene_json_photons("\"march\":{\"guided_paths\":false}", -2.5, 1000));
    cr_expect(s->march.guided_paths == 0, "false read as %d", s->march.guided_paths);
    rd_scene_free(s);
    static const char *const bad[] = {"1", "\"yes\"", "null"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char path[256], err[RD_ERRLEN] = "", extra[128];
        snprintf(extra, sizeof extra, "\"march\":{\"guided_paths\":%s}", bad[i]);
        snprintf(path, sizeof path, "%s/gp_bad.json", rt_tmpdir());
        const char *json = scene_json_photons(extra, -2.5, 1000);
        rt_write_file(path, json, strlen(json));
        rd_scene *b = NULL;
        cr_expect(rd_scene_load(&b, path, NULL, 0, err, sizeof err) != RD_OK, "march.guided_paths %s accepted", bad[i]);
        cr_expect(strstr(err, "march.guided_paths") != NULL && strchr(err, '\n') == NULL, "%s: message \"%s\"", bad[i], err);
        rd_scene_free(b);
    }
}
