/* guided-unbiased (renderer/integrators/guided_unbiased.c): the path tracer of `delta` with
 * guided free flights, against answers it did not compute:
 *  - its images equal delta's in expectation on heterogeneous, anisotropic, multiple-scattering
 *    scenes (g = 0.9 and g = -0.5; spot, environment, sphere and directional lights), with the
 *    scene's own guide, with a guide baked with the light elsewhere, and with an empty guide
 *    (no photon reached the medium);
 *  - every part off (distances, directions, roulette, equiangular, probes) makes it `delta`, bit
 *    for bit;
 *  - the free flight as the tracer draws it (scatter or pass, then the distance) passes a
 *    chi-square test against P_s and the guide pdf;
 *  - a white furnace (albedo 1, environment of radiance 1) gives 1;
 *  - the path loop gives a split copy's vertex policy the path's throughput from the camera.
 * Image comparisons are z-scores of the image mean and of 8x8-pixel region means, with standard
 * errors from the films' per-pixel standard errors (pixels are independent, fixed seeds). Under
 * equal expectations each z is standard normal; with at most 12 regions per comparison the
 * region bound 4.5 keeps the chance of a false alarm per comparison below 1e-4, the image bound
 * is 5 (5.7e-7). */
#include "support/rd_test.h"

#include "integrators/rd_guide_pdf.h"
#include "bake/rd_photons.h"
#include "integrators/rd_method.h"

static rd_baked *bake(const rd_scene *s)
{
    char err[RD_ERRLEN];
    rd_baked *b = NULL;
    rd_bake_opts bo = {.seed = -1};
    rd_bake_opts_for(&bo, rd_method_needs_for("guided-unbiased", s));
    cr_assert(rd_bake(s, &bo, &b, err, sizeof err) == RD_OK, "%s", err);
    return b;
}

/* The tests guide every flight's distance, however thick and however deep in the path (the
 * default distances = false leaves them all to delta tracking, distance_tau_max the thick
 * ones, and secondary = false the ones after a scattering event, which would hide the guided
 * sampler from them); each rule has its own test. */
#define GUIDED_FLIGHTS ",\"distances\":true"
#define THICK_FLIGHTS ",\"distance_tau_max\":1e9"
#define DEEP_FLIGHTS ",\"secondary\":true"
#define ALL_FLIGHTS GUIDED_FLIGHTS THICK_FLIGHTS DEEP_FLIGHTS

/* A heterogeneous medium (noise in an ellipsoid) of asymmetry g, lit by a spot at x = spot_x
 * aimed at it, and `lights` more; `keys` are the guide's keys after "bands", as they are. */
static const char *scene_json_exact(double g, double spot_x, const char *lights, const char *keys)
{
    static char buf[4096];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[0,0.3,4.2],\"look_at\":[0,0,0],\"fov\":34,\"resolution\":[32,24]},"
             "\"media\":[{\"bounds\":{\"min\":[-1.3,-1,-1],\"max\":[1.3,1,1]},"
             "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":2,\"amplitude\":2,\"seed\":3,"
             "\"shape\":\"ellipsoid\",\"edge\":0.5},\"sigma_t\":2.5,\"albedo\":0.9,\"g\":%g}],"
             "\"lights\":[{\"type\":\"spot\",\"position\":[%g,2,1.5],\"look_at\":[-0.2,0,0],\"angle\":30,"
             "\"falloff\":8,\"intensity\":[20,16,12]}%s],"
             "\"photons\":{\"count\":40000},\"guide\":{\"bands\":4%s},"
             "\"settings\":{\"max_depth\":64,\"rr_depth\":3}}",
             g, spot_x, lights, keys);
    return buf;
}

/* The same with the guide keys in `extra` after ALL_FLIGHTS' three, each unless `extra` sets it
 * itself (cJSON reads the first of two equal keys). */
static const char *scene_json(double g, double spot_x, const char *lights, const char *extra)
{
    char keys[512];
    snprintf(keys, sizeof keys, "%s%s%s%s", strstr(extra, "\"distances\"") ? "" : GUIDED_FLIGHTS,
             strstr(extra, "distance_tau_max") ? "" : THICK_FLIGHTS, strstr(extra, "secondary") ? "" : DEEP_FLIGHTS,
             extra);
    return scene_json_exact(g, spot_x, lights, keys);
}

static const char ENV[] = ",{\"type\":\"environment\",\"radiance\":[0.2,0.25,0.3]}";
static const char ALL[] = ",{\"type\":\"environment\",\"radiance\":[0.1,0.12,0.15]},"
                          "{\"type\":\"sphere\",\"center\":[0.6,0.5,0.2],\"radius\":0.25,\"radiance\":[4,3,2]},"
                          "{\"type\":\"directional\",\"direction\":[1,-0.2,-0.3],\"irradiance\":[2,3,4],"
                          "\"radius\":0.25,\"center\":[0.3,0.1,0]}";

Test(guided_unbiased, equals_delta_forward_scattering_spot_and_environment, .timeout = 600)
{
    rd_scene *s = rt_scene("gu_fwd.json", scene_json(0.9, -2.5, ENV, ""));
    rd_render_result d = rt_render(s, "delta", 256, 11, NULL);
    rd_render_result g = rt_render(s, "guided-unbiased", 128, 12, NULL);
    rt_expect_same(&d, &g, "g = 0.9, spot + environment");
    /* The report's guide reads (guided_paths): counted for the guided paths, none for delta. */
    cr_expect(g.stats.flight_segments > 0 && g.stats.guide_vertices > 0, "guided-unbiased: %llu segments, %llu vertices",
              (unsigned long long)g.stats.flight_segments, (unsigned long long)g.stats.guide_vertices);
    cr_expect(d.stats.flight_segments == 0 && d.stats.guide_vertices == 0, "delta counted guide reads");
    /* The camera ray's flights guided, the secondary ones by delta tracking. */
    rd_scene *s1 = rt_scene("gu_fwd1.json", scene_json(0.9, -2.5, ENV, ",\"distance_tau_max\":1e9,\"secondary\":false"));
    rd_render_result g1 = rt_render(s1, "guided-unbiased", 128, 13, NULL);
    rt_expect_same(&d, &g1, "g = 0.9, spot + environment, camera flights only");
    /* The guide read through its band 0 alone (guide.eval_bands 1): other flights and
     * roulette, the same image. */
    rd_scene *s2 = rt_scene("gu_fwd2.json", scene_json(0.9, -2.5, ENV, ",\"eval_bands\":1"));
    rd_render_result g2 = rt_render(s2, "guided-unbiased", 128, 14, NULL);
    rt_expect_same(&d, &g2, "g = 0.9, spot + environment, guide band 0 only");
    rd_render_result_free(&g2);
    rd_scene_free(s2);
    rd_render_result_free(&g1);
    rd_scene_free(s1);
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    rd_scene_free(s);
}

/* A key's default against both its values: the scene with guide keys extra[0] (the key absent),
 * extra[1] (its default given) and extra[2] (the other value), each rendered by the method alone
 * (the selection off, so that every pixel is the method's; 16 samples, one seed) into r[k]; the
 * first two must be the same image bit for bit and the third another (`key` names it). */
static void render_default_and_both(const char *key, const char *const extra[3], rd_render_result r[3])
{
    for (int k = 0; k < 3; k++) {
        char file[64];
        snprintf(file, sizeof file, "gu_%s%d.json", key, k);
        rd_scene *s = rt_scene(file, scene_json_exact(0.9, -2.5, ENV, extra[k]));
        s->settings.select = RD_SELECT_OFF;
        r[k] = rt_render(s, "guided-unbiased", 16, 5, NULL);
        rd_scene_free(s);
    }
    size_t bytes = sizeof(float) * 3 * r[0].image.w * r[0].image.h;
    cr_expect(memcmp(r[0].image.rgb, r[1].image.rgb, bytes) == 0, "the default is not %s's given default", key);
    cr_expect(memcmp(r[0].image.rgb, r[2].image.rgb, bytes) != 0, "%s's other value gives the default's image", key);
}

/* guide.secondary's default is false (docs/guided-unbiased.md, "Camera flights only"). */
Test(guided_unbiased, secondary_flights_are_delta_tracking_s_by_default, .timeout = 300)
{
    static const char *const extra[3] = {GUIDED_FLIGHTS THICK_FLIGHTS, GUIDED_FLIGHTS THICK_FLIGHTS ",\"secondary\":false",
                                         GUIDED_FLIGHTS THICK_FLIGHTS ",\"secondary\":true"};
    rd_render_result r[3];
    render_default_and_both("secondary", extra, r);
    cr_expect(r[0].stats.flight_segments < r[2].stats.flight_segments, "%llu segments by default, %llu with secondary",
              (unsigned long long)r[0].stats.flight_segments, (unsigned long long)r[2].stats.flight_segments);
    for (int k = 0; k < 3; k++) rd_render_result_free(&r[k]);
}

/* guide.distances' default is false (docs/guided-unbiased.md, "Guided distances off by
 * default"), thick flights guided too where it is true; and a scene with no "guide" object at
 * all has it false (the loader has two defaults: the value set before the object is read, and
 * the one for an absent key). */
Test(guided_unbiased, distances_are_delta_tracking_s_by_default, .timeout = 300)
{
    static const char *const extra[3] = {THICK_FLIGHTS, THICK_FLIGHTS ",\"distances\":false",
                                         THICK_FLIGHTS ",\"distances\":true"};
    rd_render_result r[3];
    render_default_and_both("distances", extra, r);
    for (int k = 0; k < 3; k++) rd_render_result_free(&r[k]);
    rd_scene *keyless = rt_scene("gu_distances_keyless.json", scene_json_exact(0.9, -2.5, ENV, ""));
    cr_expect_eq(keyless->guide.distances, 0, "key absent: guide.distances is %d", keyless->guide.distances);
    rd_scene_free(keyless);
    rd_scene *bare = rt_scene("gu_dist_bare.json", rt_spot_fog_json(8, 6, "{}"));
    cr_expect_eq(bare->guide.distances, 0, "no \"guide\" object: guide.distances is %d", bare->guide.distances);
    rd_scene_free(bare);
}

Test(guided_unbiased, equals_delta_backward_scattering_every_light_type, .timeout = 600)
{
    rd_scene *s = rt_scene("gu_back.json", scene_json(-0.5, -2.5, ALL, ""));
    rd_render_result d = rt_render(s, "delta", 256, 21, NULL);
    rd_render_result g = rt_render(s, "guided-unbiased", 128, 22, NULL);
    rt_expect_same(&d, &g, "g = -0.5, spot + environment + sphere + directional");
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    rd_scene_free(s);
}

/* Each part of the method switched on alone (guide.distances, guide.directions,
 * guide.roulette with splitting), against delta: forward scattering with a spot and the
 * environment, and backward scattering with every light type (sphere and environment lights
 * are where next-event estimation's MIS weight must use the direction mixture's pdf). */
/* `delta` on the scene of JSON jd against guided-unbiased on that of jg, each rendered with its
 * own spp and seed: equal in expectation (rt_expect_same). */
static void expect_delta_equals(const char *jd, int spp_d, uint64_t seed_d, const char *jg, int spp_g,
                                uint64_t seed_g, const char *what)
{
    rd_scene *sd = rt_scene("gu_eq_d.json", jd);
    rd_render_result d = rt_render(sd, "delta", spp_d, seed_d, NULL);
    rd_scene *sg = rt_scene("gu_eq_g.json", jg);
    rd_render_result g = rt_render(sg, "guided-unbiased", spp_g, seed_g, NULL);
    rt_expect_same(&d, &g, what);
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    rd_scene_free(sg);
    rd_scene_free(sd);
}

Test(guided_unbiased, each_part_alone_equals_delta, .timeout = 900)
{
    static const char *const parts[4][2] = {
        {",\"directions\":false,\"roulette\":false", "distances alone"},
        {",\"distances\":false,\"roulette\":false", "directions alone"},
        {",\"distances\":false,\"directions\":false", "roulette and splitting alone"},
        {",\"distance_tau_max\":0.5", "every part, distances on thin flights only"},
    };
    const struct { double g; const char *lights, *what; } sc[2] = {
        {0.9, ENV, "g = 0.9, spot + environment"},
        {-0.5, ALL, "g = -0.5, every light type"},
    };
    for (int k = 0; k < 2; k++) {
        rd_scene *s = rt_scene("gu_part_d.json", scene_json(sc[k].g, -2.5, sc[k].lights, ""));
        rd_render_result d = rt_render(s, "delta", 256, 61 + k, NULL);
        for (int i = 0; i < 4; i++) {
            rd_scene *sp = rt_scene("gu_part.json", scene_json(sc[k].g, -2.5, sc[k].lights, parts[i][0]));
            rd_render_result g = rt_render(sp, "guided-unbiased", 128, 70 + 3 * k + i, NULL);
            char what[160];
            snprintf(what, sizeof what, "%s, %s", sc[k].what, parts[i][1]);
            rt_expect_same(&d, &g, what);
            rd_render_result_free(&g);
            rd_scene_free(sp);
        }
        rd_render_result_free(&d);
        rd_scene_free(s);
    }
    /* A large sphere light beside a forward-scattering medium and nothing else: the guide's
     * lobe points at the light, so continuations hit it often (the MIS weights themselves are
     * checked exactly by nee_and_mixture_directions_share_a_sphere_light_by_mis; a wrong one
     * moves this image by less than its noise, since the single-scattered light at 90 degrees
     * is a small part of it). */
    const char *sph = "{\"camera\":{\"position\":[0,0.3,4.2],\"look_at\":[0,0,0],\"fov\":34,\"resolution\":[32,24]},"
        "\"media\":[{\"bounds\":{\"min\":[-1.3,-1,-1],\"max\":[1.3,1,1]},"
        "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":2,\"amplitude\":2,\"seed\":3,"
        "\"shape\":\"ellipsoid\",\"edge\":0.5},\"sigma_t\":2.5,\"albedo\":0.9,\"g\":0.8}],"
        "\"lights\":[{\"type\":\"sphere\",\"center\":[-2.8,0.4,0],\"radius\":1.4,\"radiance\":[1,1,1]}],"
        "\"photons\":{\"count\":40000},\"guide\":{\"bands\":4%s" ALL_FLIGHTS "},"
        "\"settings\":{\"max_depth\":64,\"rr_depth\":3}}";
    char jd[2048], jg[2048]; /* the part's keys first: cJSON reads the first of two equal keys */
    snprintf(jd, sizeof jd, sph, "");
    snprintf(jg, sizeof jg, sph, parts[1][0]);
    expect_delta_equals(jd, 256, 81, jg, 128, 82, "g = 0.8, sphere light alone, directions alone");
}

Test(guided_unbiased, wrong_and_empty_guides_keep_the_expectation, .timeout = 600)
{
    rd_scene *s = rt_scene("gu_w.json", scene_json(0.9, -2.5, ENV, ""));
    rd_render_result d = rt_render(s, "delta", 256, 31, NULL);
    /* Wrong on purpose: the guide baked with the spot on the other side of the medium. */
    rd_scene *sw = rt_scene("gu_w2.json", scene_json(0.9, 2.5, ENV, ""));
    rd_baked *wrong = bake(sw);
    rd_render_result gw = rt_render(s, "guided-unbiased", 128, 32, wrong);
    rt_expect_same(&d, &gw, "guide baked with the spot elsewhere");
    /* Empty: baked from a spot aimed away from the medium, no other light: no photon is
     * stored, every f_j is 0, so every flight falls back to delta tracking's (I_ray = 0). */
    rd_scene *se = rt_scene("gu_e.json",
        "{\"camera\":{\"position\":[0,0.3,4.2],\"look_at\":[0,0,0],\"fov\":34,\"resolution\":[32,24]},"
        "\"media\":[{\"bounds\":{\"min\":[-1.3,-1,-1],\"max\":[1.3,1,1]},"
        "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":2,\"amplitude\":2,\"seed\":3,"
        "\"shape\":\"ellipsoid\",\"edge\":0.5},\"sigma_t\":2.5,\"albedo\":0.9,\"g\":0.9}],"
        "\"lights\":[{\"type\":\"spot\",\"position\":[-2.5,2,1.5],\"look_at\":[-5,4,3],\"angle\":10,"
        "\"intensity\":[20,16,12]}],\"photons\":{\"count\":1000},\"guide\":{\"bands\":4}}");
    rd_baked *empty = bake(se);
    rd_render_result ge = rt_render(s, "guided-unbiased", 128, 33, empty);
    rt_expect_same(&d, &ge, "empty guide");
    rd_render_result_free(&d);
    rd_render_result_free(&gw);
    rd_render_result_free(&ge);
    rd_baked_free(wrong);
    rd_baked_free(empty);
    rd_scene_free(s);
    rd_scene_free(sw);
    rd_scene_free(se);
}

Test(guided_unbiased, every_part_off_is_delta_bit_for_bit, .timeout = 120)
{
    rd_scene *s = rt_scene("gu_off.json", scene_json(0.9, -2.5, ENV,
                           ",\"distances\":false,\"directions\":false,\"roulette\":false,\"equiangular\":false,\"probes\":1"));
    cr_assert_eq(rd_method_needs_for("guided-unbiased", s), 0u, "nothing to bake with every part off");
    rd_render_result d = rt_render(s, "delta", 4, 41, NULL);
    rd_render_result g = rt_render(s, "guided-unbiased", 4, 41, NULL);
    size_t n = (size_t)d.image.w * d.image.h * 3;
    cr_expect(memcmp(d.image.rgb, g.image.rgb, n * sizeof(float)) == 0, "images differ");
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    /* The same with `delta`'s equiangular strategy in both (the spot's lit span is sampled
     * on some flights: the strategy's random numbers and weights must be the same too). */
    s->settings.equiangular = RD_EQ_ALL;
    s->guide.equiangular = RD_EQ_ALL;
    d = rt_render(s, "delta", 4, 41, NULL);
    g = rt_render(s, "guided-unbiased", 4, 41, NULL);
    cr_expect(memcmp(d.image.rgb, g.image.rgb, n * sizeof(float)) == 0, "images differ with equiangular sampling");
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    rd_scene_free(s);
}

/* A render context for guided-unbiased on scene s with bake b, prepared as a render would
 * prepare it, and one thread's scratch for it (free() it; m->release the context). */
static void *prepare_ctx(rd_scene *s, rd_baked *b, rd_render_ctx *ctx)
{
    const rd_method *m = rd_method_find("guided-unbiased");
    *ctx = (rd_render_ctx){.scene = s, .method = m, .guide = rd_baked_guide(b), .threads = 1};
    char err[RD_ERRLEN];
    cr_assert(m->prepare(ctx, err, sizeof err) == RD_OK, "%s", err);
    void *scratch = aligned_alloc(16, (m->scratch_bytes(ctx) + 15) / 16 * 16);
    cr_assert(scratch != NULL);
    return scratch;
}

/* Upper 1e-5 quantile of chi-square with df degrees of freedom (Wilson-Hilferty: accurate to
 * a few percent for df >= 10; z = 4.265 is the normal 1e-5 quantile). */
static double chi2_crit(int df)
{
    double a = 2.0 / (9.0 * df), z = 4.265;
    return df * pow(1.0 - a + z * sqrt(a), 3.0);
}

/* One scene, two rays: see the test below. */
static void chi_square_flights(const char *extra, uint64_t seed)
{
    char json[2048];
    snprintf(json, sizeof json,
        "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"resolution\":[8,8]},"
        "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
        "\"density\":{\"type\":\"noise\",\"octaves\":2,\"frequency\":1.5,\"amplitude\":2,\"seed\":5},"
        "\"sigma_t\":1.5,\"albedo\":0.8,\"g\":0.5}],"
        "\"lights\":[{\"type\":\"spot\",\"position\":[-3,0.2,0.3],\"look_at\":[0,0,0.3],\"angle\":12,\"intensity\":[40,40,40]},"
        "{\"type\":\"environment\",\"radiance\":[0.05,0.05,0.05]}],"
        "\"photons\":{\"count\":30000},\"guide\":{\"bands\":4" ALL_FLIGHTS "%s}}", extra);
    rd_scene *s = rt_scene("gu_chi.json", json);
    rd_baked *b = bake(s);
    const rd_method *m = rd_method_find("guided-unbiased");
    rd_render_ctx ctx;
    void *scratch = prepare_ctx(s, b, &ctx);
    const ray3 rays[2] = {{v3(0.1, 0.05, 4), v3_norm(v3(-0.05, 0.02, -1))},
                          {v3(-0.2, 0.1, 1.6), v3_norm(v3(0.3, -0.1, -1))}};
    const double phase_pdf[2] = {0.0, 0.3};
    enum { K = 64, N = 200000 };
    for (int k = 0; k < 2; k++) {
        rd_flight_in in = {.r = rays[k], .t_light = INFINITY, .hit_light = -1,
                           .hit_shape = -1, .region = -1, .camera_chain = k == 0,
                           .phase_pdf = phase_pdf[k], .depth = k};
        double t0, t1, P_pass;
        cr_assert(rd_box_intersect(s->bmin, s->bmax, in.r, 0.0, INFINITY, &t0, &t1));
        double expect[K + 1], prev = rd_gu_flight_cdf(&ctx, scratch, &in, t0, &P_pass);
        cr_assert(P_pass > 0.0 && P_pass < 1.0, "ray %d: P_pass %g", k, P_pass);
        cr_assert(fabs(prev) < 1e-15);
        for (int j = 0; j < K; j++) {
            double next = rd_gu_flight_cdf(&ctx, scratch, &in, t0 + (j + 1) * (t1 - t0) / K, NULL);
            expect[j] = N * (next - prev);
            prev = next;
        }
        expect[K] = N * P_pass;
        cr_assert(fabs(prev + P_pass - 1.0) < 1e-12, "ray %d: scatter %.15g + pass %.15g != 1", k, prev, P_pass);
        long count[K + 1] = {0};
        pcg32 rng = pcg32_seed(77, seed + (uint64_t)k, 3);
        rd_track_counters c = {0};
        for (int i = 0; i < N; i++) {
            double pp;
            rd_flight f = rd_gu_flight(&ctx, scratch, &in, &rng, &c, &pp);
            cr_assert(pp == P_pass, "P_pass must be a function of the ray");
            if (f.kind == RD_FLIGHT_PASS) { count[K]++; continue; }
            int bin = (int)floor((f.t - t0) / (t1 - t0) * K);
            cr_assert(bin >= 0 && bin <= K, "t %g outside [%g, %g]", f.t, t0, t1);
            count[bin < K ? bin : K - 1]++;
        }
        /* Pool neighbouring distance bins until each expects >= 5 (the pass cell alone). */
        double chi2 = 0.0, e_acc = 0.0;
        long o_acc = 0;
        int cells = 0;
        for (int j = 0; j <= K; j++) {
            e_acc += expect[j];
            o_acc += count[j];
            if (e_acc < 5.0 && j < K - 1) continue;
            chi2 += (o_acc - e_acc) * (o_acc - e_acc) / e_acc;
            cells++;
            e_acc = 0.0;
            o_acc = 0;
        }
        cr_assert(cells >= 20, "too few cells (%d)", cells);
        cr_expect(chi2 < chi2_crit(cells - 1), "%s ray %d: chi2 %.1f over %d cells (bound %.1f), P_pass %.3f",
                  extra, k, chi2, cells, chi2_crit(cells - 1), P_pass);
        cr_log_info("%s ray %d: chi2 %.1f, %d cells, bound %.1f, P_pass %.3f", extra, k, chi2, cells,
                    chi2_crit(cells - 1), P_pass);
    }
    free(scratch);
    m->release(&ctx);
    rd_baked_free(b);
    rd_scene_free(s);
}

Test(guided_unbiased, flight_sampler_chi_square_against_its_pdf, .timeout = 900)
{
    /* A heterogeneous medium (noise: a grid majorant, and sigma_t = 0 in places, where a drawn
     * vertex ends the path but still reports its t) lit from the side by a spot, with an
     * environment behind (so the flight can pass): the outcome of rd_gu_flight (pass, or the
     * distance bin of t) against the probabilities P_pass and the mass of q over each bin
     * (rd_gu_flight_cdf, integrators/guided_unbiased.c eq. 2-3). Bins with an expected count
     * below 5 are pooled (DESIGN.md convention 9); the bound is the 1e-5 quantile. Two rays: a
     * camera ray, and a secondary one whose light behind is MIS-weighted; with the default
     * majorant weight and with the guide strategy alone. */
    chi_square_flights("", 77);
    chi_square_flights(",\"majorant_weight\":0", 78);
    /* The guide read through all its bands instead of the default first two (guide.eval_bands):
     * another pdf, which the cdf must follow too. */
    chi_square_flights(",\"eval_bands\":4", 79);
}

Test(guided_unbiased, white_furnace, .timeout = 300)
{
    /* Albedo 1, heterogeneous and anisotropic, in a uniform environment of radiance 1: every
     * pixel sees exactly 1. Guide baked from the environment's photons. 5 standard errors of
     * the image mean, and of each pixel (16 pixels: false alarm < 1e-5). */
    rd_scene *s = rt_scene("gu_furnace.json",
        "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"fov\":20,\"resolution\":[4,4]},"
        "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
        "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":2,\"seed\":4},"
        "\"sigma_t\":3,\"albedo\":1,\"g\":0.6}],"
        "\"lights\":[{\"type\":\"environment\",\"radiance\":1}],"
        "\"photons\":{\"count\":20000},\"guide\":{\"bands\":4" ALL_FLIGHTS "},"
        "\"settings\":{\"max_depth\":100000,\"rr_depth\":3}}");
    rd_render_result r = rt_render(s, "guided-unbiased", 8192, 51, NULL);
    double sum = 0.0, var = 0.0;
    for (int i = 0; i < 16; i++) {
        double v = r.image.rgb[3 * i + 1], se = r.stderr_img.rgb[3 * i + 1];
        cr_expect(fabs(v - 1.0) < 5.0 * se + 1e-9, "pixel %d: %.5f (se %.5f)", i, v, se);
        sum += v;
        var += se * se;
    }
    double mean = sum / 16, se = sqrt(var) / 16;
    cr_expect(fabs(mean - 1.0) < 5.0 * se, "image mean %.5f (se %.5f)", mean, se);
    cr_expect(se < 0.01, "the estimate must be precise enough to mean something (se %.5f)", se);
    cr_log_info("furnace: mean %.5f se %.5f", mean, se);
    rd_render_result_free(&r);
    rd_scene_free(s);
}

Test(guided_unbiased, bakes_its_share_of_the_photons, .timeout = 120)
{
    /* guided-unbiased's needs ask for few photons (guide.photon_share of photons.count, 0.25 by
     * default); guided's, and guided-unbiased's at share 1, for all of them. The count the
     * bake emitted is what the statistics say; the cache key follows it. */
    const struct {
        const char *method, *extra;
        size_t emitted;
    } cases[] = {{"guided-unbiased", "", 10000},
                 {"guided-unbiased", ",\"photon_share\":0.1", 4000},
                 {"guided-unbiased", ",\"photon_share\":1", 40000},
                 {"guided", "", 40000}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        rd_scene *s = rt_scene("gu_share.json", scene_json(0.5, -2.5, "", cases[i].extra));
        unsigned needs = rd_method_needs_for(cases[i].method, s);
        char err[RD_ERRLEN];
        rd_baked *b = NULL;
        rd_bake_opts bo = {.seed = -1, .threads = 2};
        rd_bake_opts_for(&bo, needs);
        cr_assert(rd_bake(s, &bo, &b, err, sizeof err) == RD_OK, "%s", err);
        cr_expect_eq(rd_baked_stats(b)->emitted, cases[i].emitted, "%s%s: %zu photons emitted, expected %zu",
                     cases[i].method, cases[i].extra, rd_baked_stats(b)->emitted, cases[i].emitted);
        rd_baked_free(b);
        rd_scene_free(s);
    }
}

Test(guided_unbiased, scene_keys_are_validated)
{
    const char *bad[][2] = {
        {"\"distances\":1", "guide.distances"},
        {"\"distance_alpha\":0", "guide.distance_alpha"},
        {"\"distance_alpha\":1.5", "guide.distance_alpha"},
        {"\"pass_floor\":0", "guide.pass_floor"},
        {"\"pass_floor\":0.6", "guide.pass_floor"},
        {"\"majorant_weight\":1", "guide.majorant_weight"},
        {"\"majorant_weight\":-0.1", "guide.majorant_weight"},
        {"\"secondary\":0", "guide.secondary"},
        {"\"directions\":1", "guide.directions"},
        {"\"direction_weight\":1", "guide.direction_weight"},
        {"\"direction_weight\":-0.1", "guide.direction_weight"},
        {"\"roulette\":\"yes\"", "guide.roulette"},
        {"\"split_max\":0", "guide.split_max"},
        {"\"split_max\":65", "guide.split_max"},
        {"\"split_max\":2.5", "guide.split_max"},
        {"\"distance_tau_max\":0", "guide.distance_tau_max"},
        {"\"distance_tau_max\":-1", "guide.distance_tau_max"},
        {"\"eval_bands\":0", "guide.eval_bands"},
        {"\"eval_bands\":9", "guide.eval_bands"},
        {"\"eval_bands\":1.5", "guide.eval_bands"},
        {"\"photon_share\":0", "guide.photon_share"},
        {"\"photon_share\":1.5", "guide.photon_share"},
        {"\"equiangular\":\"sometimes\"", "guide.equiangular"},
        {"\"equiangular\":1", "guide.equiangular"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char path[256], extra[64], err[RD_ERRLEN] = "";
        snprintf(extra, sizeof extra, ",%s", bad[i][0]);
        snprintf(path, sizeof path, "%s/gu_bad.json", rt_tmpdir());
        const char *json = scene_json(0.9, -2.5, "", extra);
        rt_write_file(path, json, strlen(json));
        rd_scene *s = NULL;
        cr_expect(rd_scene_load(&s, path, NULL, 0, err, sizeof err) != RD_OK, "%s accepted", bad[i][0]);
        cr_expect(strstr(err, bad[i][1]) != NULL, "%s: message \"%s\" does not name %s", bad[i][0], err, bad[i][1]);
        cr_expect(strchr(err, '\n') == NULL, "one line: \"%s\"", err);
        rd_scene_free(s);
    }
}


/* guide.equiangular's default (session 39, renderer/load/load.c): false where the tile
 * selection runs (its third estimator carries the strategy), "auto" with settings.select off
 * (the method alone); a value in the file wins either way. A default that ignored the selection
 * fails the second case, one that ignored the file the third. */
Test(guided_unbiased, equiangular_default_follows_the_selection)
{
    const char *cases[][2] = {{"\"settings\":{}", ""},
                              {"\"settings\":{\"select\":\"off\"}", ""},
                              {"\"settings\":{\"select\":\"off\"}", ",\"guide\":{\"equiangular\":false}"},
                              {"\"settings\":{}", ",\"guide\":{\"equiangular\":true}"}};
    const int want[] = {RD_EQ_OFF, RD_EQ_AUTO, RD_EQ_OFF, RD_EQ_ALL};
    for (int i = 0; i < 4; i++) {
        char json[1024], name[32];
        snprintf(json, sizeof json,
                 "{\"camera\":{\"position\":[0,0,3],\"look_at\":[0,0,0],\"resolution\":[8,8]},"
                 "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                 "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1,\"albedo\":0.9}],"
                 "\"lights\":[{\"type\":\"point\",\"position\":[0,2,0],\"intensity\":[1,1,1]}],%s%s}",
                 cases[i][0], cases[i][1]);
        snprintf(name, sizeof name, "gu_eqdef%d.json", i);
        rd_scene *s = rt_scene(name, json);
        cr_expect(s->guide.equiangular == want[i], "case %d: guide.equiangular %d, expected %d", i, s->guide.equiangular,
                  want[i]);
        rd_scene_free(s);
    }
}

/* The guide's incident-light lobe (integrators/guided_unbiased.c cell_lobe, lobe_product) points where the
 * light comes from: a point light in a homogeneous forward-scattering medium sends the photons
 * radially, so the lobe's mean at points around it must point back at the light. The lobe is
 * the product with the phase function's lobe about the arrival direction d, so d is taken
 * toward the light too (both factors then agree; a sign mistake in the light's factor, kappa_L
 * about 20 against the phase's 5, would turn the product away). The bound: the mean direction
 * of single-scattered photons is exactly radial, and multiple scattering at albedo 0.5 and
 * optical radius 1 keeps it within a few degrees; 0.9 (26 degrees) catches a sign or axis
 * mistake (those give cosines near -1 or near 0). */
Test(guided_unbiased, guide_lobe_points_at_the_light, .timeout = 300)
{
    rd_scene *s = rt_scene("gu_lobe.json",
        "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[8,8]},"
        "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
        "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1,\"albedo\":0.5,\"g\":0.8}],"
        "\"lights\":[{\"type\":\"point\",\"position\":[0.1,-0.2,0.05],\"intensity\":10}],"
        "\"photons\":{\"count\":100000},\"guide\":{\"bands\":3,\"resolution\":[8,8,8]}}");
    rd_baked *b = bake(s);
    const rd_method *m = rd_method_find("guided-unbiased");
    rd_render_ctx ctx = {.scene = s, .method = m, .guide = rd_baked_guide(b), .threads = 1};
    char err[RD_ERRLEN];
    cr_assert(m->prepare(&ctx, err, sizeof err) == RD_OK, "%s", err);
    const vec3 light = v3(0.1, -0.2, 0.05);
    const vec3 pts[6] = {v3(0.8, 0, 0), v3(-0.7, 0.1, 0), v3(0, 0.75, 0.2),
                         v3(0.1, -0.8, -0.3), v3(0.2, 0.1, 0.8), v3(-0.5, -0.5, -0.7)};
    pcg32 rng = pcg32_seed(5, 6, 7);
    for (int i = 0; i < 6; i++) {
        rd_vertex_in v = {.x = pts[i], .d = v3_norm(v3_sub(light, pts[i])), .medium = &s->media[0], .region = -1,
                          .depth = 1, .beta = v3(1, 1, 1)};
        rd_vertex_out o;
        rd_gu_vertex(&ctx, &v, 0.0, &rng, &o);
        cr_assert(o.mix.a == s->guide.direction_weight, "point %d: no lobe (a = %g)", i, o.mix.a);
        double c = v3_dot(o.mix.mu, v3_norm(v3_sub(light, pts[i])));
        cr_expect(c > 0.9, "point %d: lobe mean . (light - x) = %.3f (kappa %.2f)", i, c, o.mix.kappa);
        cr_expect(o.mix.kappa > 0.0 && isfinite(o.mix.kappa));
        cr_log_info("lobe %d: cos to light %.4f, kappa %.2f", i, c, o.mix.kappa);
    }
    /* Switched off, or in a near-isotropic medium, there is no lobe. */
    rd_vertex_in v = {.x = pts[0], .d = v3(0, 0, -1), .medium = &s->media[0], .region = -1, .depth = 1, .beta = v3(1, 1, 1)};
    rd_vertex_out o;
    s->guide.directions = 0;
    rd_gu_vertex(&ctx, &v, 0.0, &rng, &o);
    cr_expect(o.mix.a == 0.0);
    s->guide.directions = 1;
    s->media[0].g = 0.05; /* (the lobes are found at prepare: a changed scene is prepared again) */
    m->release(&ctx);
    cr_assert(m->prepare(&ctx, err, sizeof err) == RD_OK, "%s", err);
    rd_gu_vertex(&ctx, &v, 0.0, &rng, &o);
    cr_expect(o.mix.a == 0.0, "g = 0.05 must give no lobe");
    m->release(&ctx);
    rd_baked_free(b);
    rd_scene_free(s);
}

/* The path loop hands a vertex policy the path's throughput from the camera (rd_vertex_in.beta),
 * in a copy that splitting made as in the path it came from: the policy's roulette and
 * splitting weigh the path's expected contribution against the pixel's, so a copy must carry
 * its share 1/n of the throughput and every weight before it. Here a policy splits every first
 * and second vertex into two, continues from them by a direction mixture with a vMF lobe (a
 * direction weight p/pdf != 1), and ends every third vertex. In a constant medium of albedo 1/2
 * delta tracking's flight weight is the albedo, so a vertex at depth k + 1 must see
 *     beta_{k+1} = beta_k x 1/2 x p(d_k . d_{k+1}) / pdf_mix(d_{k+1}) x 1/2,
 * beta_k and d_k its parent's throughput and arriving direction (the parent's the most recent
 * vertex one level up: the loop finishes a copy's subtree before its next copy). Checked to
 * 1e-12 relative (the loop multiplies the same factors in another order). The loop of before,
 * in which a copy that recursed started its own throughput at 1, fails at the first copy's
 * second vertex; dropping the direction weight or a copy's share fails too. */
#define BETA_G 0.3
typedef struct {
    rd_dir_mix mix;
    vec3 d[3];         /* the arriving direction of the latest vertex at each depth 1, 2 */
    double b[3];       /* and its throughput */
    int seen, ok;      /* vertices at depths 2 and 3, and those with the expected throughput */
} beta_record;

static rd_flight beta_test_flight(const rd_flight_sampler *fs, const rd_scene *s, const rd_flight_in *in,
                                  pcg32 *rng, rd_track_counters *c)
{
    (void)fs;
    return rd_flight_delta(s, in, rng, c);
}

static void beta_test_vertex(const rd_flight_sampler *fs, const rd_scene *s, const rd_vertex_in *v,
                             pcg32 *rng, rd_vertex_out *out)
{
    (void)s, (void)rng;
    beta_record *rec = fs->user;
    int k = v->depth;
    cr_assert(k >= 1 && k <= 3 && v->beta.x == v->beta.y && v->beta.y == v->beta.z);
    if (k > 1) {
        const vec3 d = rec->d[k - 1];
        double w = rd_hg_eval(BETA_G, v3_dot(d, v->d)) / rd_dir_mix_pdf(&rec->mix, BETA_G, d, v->d);
        double want = rec->b[k - 1] * 0.5 * w * 0.5;
        rec->seen++;
        rec->ok += fabs(v->beta.x - want) <= 1e-12 * want;
    }
    if (k < 3) rec->d[k] = v->d, rec->b[k] = v->beta.x;
    out->mix = rec->mix;
    out->rr_scale = 1.0;
    out->n = k < 3 ? 2 : 0;
}

Test(guided_unbiased, a_split_copy_gives_its_vertex_policy_the_path_s_throughput)
{
    char json[1024];
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
             "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
             "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":3,\"albedo\":0.5,\"g\":%g}],"
             "\"lights\":[{\"type\":\"point\",\"position\":[0,2,0],\"intensity\":1}]}", BETA_G);
    rd_scene *s = rt_scene("split.json", json);
    beta_record rec = {.mix = {.a = 0.5, .mu = v3(0, 1, 0), .kappa = 3.0}};
    const rd_flight_sampler fs = {.sample = beta_test_flight, .vertex = beta_test_vertex, .user = &rec,
                                  .equiangular = RD_EQ_OFF};
    pcg32 rng = pcg32_seed(3, 4, 5);
    rd_track_counters c = {0};
    for (int i = 0; i < 2000; i++) rd_path_radiance(s, (ray3){v3(0, 0, 5), v3(0, 0, -1)}, &fs, &rng, &c);
    /* sigma_t 3 over 2 m: most copies scatter again (at most 2 + 4 vertices below each first) */
    cr_assert(rec.seen > 6000, "only %d vertices at depths 2 and 3", rec.seen);
    cr_expect(rec.ok == rec.seen, "%d of %d vertices had the path's throughput", rec.ok, rec.seen);
    rd_scene_free(s);
}

/* Next-event estimation and the direction mixture share the direct light of a sphere light by
 * MIS: at a vertex outside every medium (T = 1), looking straight at the light, the two
 * estimates together must give exactly
 *     integral over the light's cone of p_HG(d.w) L dw
 *       = L (1 - g^2)/(2 g) [1/(1 - g) - 1/sqrt(1 + g^2 - 2 g cos_max)]
 * (the HG integral over a cone about its axis). Each MIS weight must use the pdf of the
 * strategy that competes with it: the mixture's, not the phase function's (with the phase pdf
 * in rd_nee_mix the sum comes out 5% too large here, 0.821 against 0.783: about 100 standard
 * errors). 400000 samples, 5 standard errors. */
Test(guided_unbiased, nee_and_mixture_directions_share_a_sphere_light_by_mis)
{
    rd_scene *s = rt_scene("gu_mis.json",
        "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
        "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":1,\"sigma_t\":1}],"
        "\"lights\":[{\"type\":\"sphere\",\"center\":[5,0,0],\"radius\":1.5,\"radiance\":[2,2,2]}]}");
    const vec3 x = v3(2, 0, 0), d = v3(1, 0, 0); /* outside the medium, facing the light */
    const double g = 0.6, L = 2.0, cos_max = sqrt(1.0 - 1.5 * 1.5 / 9.0);
    const double exact = L * (1 - g * g) / (2 * g) * (1.0 / (1 - g) - 1.0 / sqrt(1 + g * g - 2 * g * cos_max));
    /* The lobe off the light's axis, so the two pdfs differ across the cone. */
    const rd_dir_mix mixes[2] = {{.a = 0.5, .mu = v3_norm(v3(1, 0.3, 0)), .kappa = 8.0},
                                 {.a = 0.0}};
    for (int k = 0; k < 2; k++) {
        pcg32 rng = pcg32_seed(3, 4, (uint64_t)k);
        rd_track_counters c = {0};
        double sum = 0.0, sum2 = 0.0;
        const int n = 400000;
        for (int i = 0; i < n; i++) {
            double v = rd_nee_mix(s, -1, x, d, g, &mixes[k], &rng, &c, NULL).y;
            double pdf;
            vec3 wo = rd_dir_mix_sample(&mixes[k], g, d, &rng, &pdf);
            rd_flight_in in = {.r = {x, wo}, .phase_pdf = pdf, .depth = 1, .hit_shape = -1, .region = -1};
            in.hit_light = rd_scene_hit_light(s, in.r, INFINITY, -1, &in.t_light);
            if (in.hit_light >= 0) v += rd_hg_eval(g, v3_dot(d, wo)) / pdf * rd_flight_behind(s, &in).y;
            sum += v;
            sum2 += v * v;
        }
        double mean = sum / n, se = sqrt(fmax(0.0, sum2 / n - mean * mean) / n);
        cr_expect(fabs(mean - exact) < 5 * se, "a = %g: %.6f against %.6f (se %.2g)", mixes[k].a, mean, exact, se);
        cr_expect(se < 0.01 * exact);
    }
    rd_scene_free(s);
}

/* guide.distance_tau_max: a flight whose majorant optical depth exceeds it is delta tracking's
 * (rd_gu_flight reports P_pass = -1), one below it is guided (P_pass >= 0). Unbiasedness with
 * the rule on is in each_part_alone_equals_delta. */
Test(guided_unbiased, thick_flights_are_delta_tracking, .timeout = 300)
{
    const double taus[2] = {1e-9, 1e9};
    for (int k = 0; k < 2; k++) {
        char extra[64];
        snprintf(extra, sizeof extra, ",\"distance_tau_max\":%g", taus[k]);
        rd_scene *s = rt_scene("gu_tau.json", scene_json(0.9, -2.5, ENV, extra));
        cr_assert_eq(s->guide.distance_tau_max, taus[k]);
        rd_baked *b = bake(s);
        const rd_method *m = rd_method_find("guided-unbiased");
        rd_render_ctx ctx;
        void *scratch = prepare_ctx(s, b, &ctx);
        rd_flight_in in = {.r = {v3(0, 0.1, 4.2), v3_norm(v3(0, -0.03, -1))}, .t_light = INFINITY,
                           .hit_light = -1, .hit_shape = -1, .region = -1, .camera_chain = 1, .depth = 0};
        pcg32 rng = pcg32_seed(1, 2, 3);
        rd_track_counters c = {0};
        double P_pass;
        rd_gu_flight(&ctx, scratch, &in, &rng, &c, &P_pass);
        if (k == 0) cr_expect(P_pass == -1.0, "tau_max 1e-9: the flight must be delta's (P_pass %g)", P_pass);
        else cr_expect(P_pass >= 0.0 && P_pass < 1.0, "tau_max 1e9: the flight must be guided (P_pass %g)", P_pass);
        free(scratch);
        m->release(&ctx);
        rd_baked_free(b);
        rd_scene_free(s);
    }
}

Test(guided_unbiased, equiangular_strategy_keeps_the_expectation_and_finds_the_narrow_spot, .timeout = 600)
{
    /* guide.equiangular: `delta`'s equiangular strategy on guided-unbiased's flights, its MIS
     * weights taken with a guided flight's own density q(t) (eq. 3; rd_flight.pdf at the
     * vertex, rd_flight_sampler.density at the equiangular sample) and with the majorant
     * stand-in on delta tracking's flights (transport/equiangular.c). On the small narrow-spot
     * scene (a 3-degree spot across thin fog, rt_spot_fog_json) every mode must keep the image
     * of `delta` with its own equiangular strategy (tested against quadrature in
     * test_integrator.c), with the camera flights guided and with every flight guided
     * (guide.secondary, and thick flights too: THICK_FLIGHTS), roulette, splitting and guided directions on (the vertex policy's
     * branch of the path loop). z bounds as in the head: a false alarm chance below 1e-3 for
     * the test's six comparisons. The strategy must also find the spot: the guide's cells are
     * wider than the cone, so its distances land beside it, and the image's variance (the
     * mean over the pixels of their variances, each from 128 samples: fixed seeds, so the
     * figure is the same every run) must fall below a tenth of that without the strategy
     * (measured: 0.0068 of it with true, 0.0067 with auto). The narrow spot's light is almost all
     * the equiangular samples', so a wrong weight at the vertices hardly shows there: the last
     * comparison (a point light's glow, single scattering) is where the two strategies share
     * the light, every flight guided however thick. Planted there: the vertex's weight taken with
     * 0.7 q(t) (weights that no longer sum to one) fails at z = 101; the vertex's weight with the
     * stand-in while the equiangular sample's takes q(t) (the two not paired) at z = 72. */
    rd_scene *sd = rt_scene("gueq_delta.json", rt_spot_fog_json(32, 24, "{\"max_depth\":8,\"equiangular\":true}"));
    rd_render_result d = rt_render(sd, "delta", 2048, 111, NULL);
    const char *modes[] = {"false", "true", "\"auto\"", "\"camera\""};
    double var[4] = {0, 0, 0, 0};
    for (int mo = 0; mo < 4; mo++)
        for (int sec = 0; sec < 2; sec++) {
            if (sec && mo != 1) continue; /* every flight guided: with `true` */
            char extra[256], what[128];
            snprintf(extra, sizeof extra, "\"photons\":{\"count\":40000},\"guide\":{\"distances\":true,\"equiangular\":%s,\"secondary\":%s}",
                     modes[mo], sec ? "true" THICK_FLIGHTS : "false");
            rd_scene *s = rt_scene("gueq.json", rt_spot_fog_json_with(32, 24, "{\"max_depth\":8,\"select\":\"off\"}", extra));
            rd_render_result g = rt_render(s, "guided-unbiased", 128, 113 + 2 * mo + sec, NULL);
            snprintf(what, sizeof what, "guided-unbiased, guide.equiangular %s%s", modes[mo],
                     sec ? ", every flight guided" : "");
            rt_expect_same(&d, &g, what);
            if (!sec) var[mo] = rt_mean_pixel_var(&g);
            rd_render_result_free(&g);
            rd_scene_free(s);
        }
    cr_expect(var[1] < var[0] / 10.0, "variance with the strategy %.3g, without %.3g", var[1], var[0]);
    cr_expect(var[2] < var[0] / 10.0, "variance with auto %.3g, without %.3g", var[2], var[0]);
    cr_log_info("guided-unbiased's image variance: %.3g without, %.3g true, %.3g auto, %.3g camera", var[0], var[1],
                var[2], var[3]);
    rd_render_result_free(&d);
    rd_scene_free(sd);
    /* Where the two strategies overlap: the glow of a point light above a thin fog, single
     * scattering only, so that the guided vertices' next-event estimates and the equiangular
     * samples share most of the image and a weight that does not pair with the other shows. */
    static const char glow[] =
        "{\"camera\":{\"position\":[0,0.2,3.6],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[32,24]},"
        "\"media\":[{\"bounds\":{\"min\":[-1.5,-1,-1],\"max\":[1.5,1,1]},"
        "\"density\":{\"type\":\"noise\",\"octaves\":2,\"frequency\":1.5,\"amplitude\":0.5,\"seed\":4,"
        "\"shape\":\"none\"},\"sigma_t\":0.6,\"albedo\":0.9,\"g\":0.4}],"
        "\"lights\":[{\"type\":\"point\",\"position\":[0.3,2.6,0.2],\"intensity\":[12,10,9]}],"
        "\"photons\":{\"count\":40000},\"guide\":{\"equiangular\":%s" ALL_FLIGHTS "},"
        "\"settings\":{\"max_depth\":1,\"select\":\"off\",\"equiangular\":%s}}";
    char jd[2048], jg[2048];
    snprintf(jd, sizeof jd, glow, "false", "true");
    snprintf(jg, sizeof jg, glow, "true", "false");
    expect_delta_equals(jd, 1024, 121, jg, 256, 122, "guided-unbiased, guide.equiangular true, a point light's glow");
}

/* The weight window's pixel estimate (guided_unbiased.c, pixel_estimate) is the guide's along
 * four fixed rays through the pixel, a function of the pixel alone, so no camera sample
 * depends on the samples drawn before it, and rd_render_opts.first_sample's promise holds:
 * samples [0, 4) of every pixel are the mean of [0, 2) and [2, 4) rendered apart (roulette and
 * splitting on, the selection and guide.probes' epochs off, which by design learn from earlier
 * samples). An estimate taken from the camera ray of the pixel's first sample on the guided
 * path fails it (checked by mutation). The three means differ only by float rounding: 1e-5
 * relative. The window must act (the image without it differs), or the test would pass with
 * nothing to test. */
Test(guided_unbiased, a_camera_sample_does_not_depend_on_the_samples_before_it, .timeout = 300)
{
    rd_scene *s = rt_scene("gu_first.json", scene_json_exact(0.6, -2.5, ENV, ",\"probes\":1"));
    s->settings.select = RD_SELECT_OFF;
    cr_assert(s->guide.roulette, "the test needs the weight window");
    rd_baked *b = bake(s);
    const int first[3] = {0, 0, 2}, spp[3] = {4, 2, 2};
    rd_render_result r[3];
    for (int i = 0; i < 3; i++) {
        rd_render_opts o = {.method = "guided-unbiased", .spp = spp[i], .first_sample = first[i], .seed = 5,
                            .threads = 2, .baked = b};
        char err[RD_ERRLEN];
        cr_assert(rd_render(s, &o, &r[i], err, sizeof err) == RD_OK, "%s", err);
    }
    size_t n = (size_t)r[0].image.w * r[0].image.h * 3, bad = 0, lit = 0;
    for (size_t i = 0; i < n; i++) {
        double a = r[0].image.rgb[i], m = 0.5 * ((double)r[1].image.rgb[i] + r[2].image.rgb[i]);
        lit += a > 0.0;
        bad += !(fabs(a - m) <= 1e-5 * fabs(a) + 1e-12);
    }
    cr_expect(lit > n / 2, "only %zu of %zu values lit", lit, n);
    cr_expect(bad == 0, "%zu of %zu values differ from the mean of the two halves", bad, n);
    /* and the window acted: without it the same samples differ */
    s->guide.roulette = 0;
    rd_render_result off;
    rd_render_opts o = {.method = "guided-unbiased", .spp = 4, .seed = 5, .threads = 2, .baked = b};
    char err[RD_ERRLEN];
    cr_assert(rd_render(s, &o, &off, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(memcmp(off.image.rgb, r[0].image.rgb, n * sizeof(float)) != 0, "the weight window changed nothing");
    rd_render_result_free(&off);
    for (int i = 0; i < 3; i++) rd_render_result_free(&r[i]);
    rd_baked_free(b);
    rd_scene_free(s);
}

/* rd_gu_paths, the method's paths as an estimator of `guided`'s selection (march.guided_paths),
 * on the method's own bake gives the method's camera samples bit for bit (its selection off,
 * one probe: its radiance is then its path alone), with the same counted work, whatever the
 * context's state and method (guided's, which hold none of this method's). */
Test(guided_unbiased, its_paths_alone_are_its_camera_samples, .timeout = 300)
{
    rd_scene *s = rt_scene("gu_paths.json", scene_json_exact(0.6, -2.5, ENV, ",\"probes\":1"));
    s->settings.select = RD_SELECT_OFF;
    cr_assert(s->guide.roulette && s->guide.directions, "the test needs the vertex policy");
    rd_baked *b = bake(s);
    const rd_method *m = rd_method_find("guided-unbiased");
    rd_render_ctx ctx = {.scene = s, .method = m, .guide = rd_baked_guide(b),
                         .guide_indirect = rd_baked_indirect_guide(b), .threads = 1};
    char err[RD_ERRLEN];
    cr_assert(ctx.guide_indirect != NULL, "the bake has no indirect guide");
    cr_assert(m->prepare(&ctx, err, sizeof err) == RD_OK, "%s", err);
    rd_render_ctx other = ctx;
    other.method = rd_method_find("guided"), other.state = NULL;
    rd_gu_paths *p = NULL;
    cr_assert(rd_gu_paths_new(&other, &p, err, sizeof err) == RD_OK, "%s", err);
    size_t bytes = m->scratch_bytes(&ctx);
    cr_expect(rd_gu_paths_scratch_bytes(p) == bytes, "scratch %zu, the method's %zu", rd_gu_paths_scratch_bytes(p), bytes);
    rd_thread ta = {.scratch = aligned_alloc(64, (bytes + 63) / 64 * 64)};
    rd_thread tb = {.scratch = aligned_alloc(64, (bytes + 63) / 64 * 64)};
    cr_assert(ta.scratch && tb.scratch);
    const rd_camera *cam = &s->camera;
    long n = 0, same = 0, lit = 0;
    for (int y = 0; y < cam->height; y++)
        for (int x = 0; x < cam->width; x++)
            for (int i = 0; i < 4; i++) {
                uint64_t pix = (uint64_t)y * cam->width + x;
                ta.pixel = tb.pixel = pix, ta.x = tb.x = x, ta.y = tb.y = y;
                rd_sampler sa = rd_sampler_start(pix, (uint64_t)i, 9), sb = sa;
                ray3 r = rd_camera_ray(cam, x + 0.5, y + 0.5);
                vec3 A = m->radiance(&ctx, &ta, r, &sa), B = rd_gu_paths_radiance(&other, p, &tb, r, &sb);
                same += memcmp(&A, &B, sizeof A) == 0;
                lit += A.x != 0.0;
                n++;
            }
    cr_expect(same == n, "%ld of %ld samples differ", n - same, n);
    cr_expect(lit > n / 4, "only %ld of %ld samples lit", lit, n);
    cr_expect(ta.counters.lookups == tb.counters.lookups && ta.cells == tb.cells &&
                  ta.guide_vertices == tb.guide_vertices && ta.guide_vertices > 0,
              "work: lookups %llu / %llu, segments %llu / %llu, guided vertices %llu / %llu",
              (unsigned long long)ta.counters.lookups, (unsigned long long)tb.counters.lookups,
              (unsigned long long)ta.cells, (unsigned long long)tb.cells, (unsigned long long)ta.guide_vertices,
              (unsigned long long)tb.guide_vertices);
    free(ta.scratch);
    free(tb.scratch);
    rd_gu_paths_free(p);
    m->release(&ctx);
    rd_baked_free(b);
    rd_scene_free(s);
}

/* The bake for a reader of the indirect guide's direction lobe alone (RD_NEEDS_INDIRECT_LOBE:
 * guided-unbiased, and `guided`'s paths) keeps the lobe's two SH bands, each cell's the same
 * numbers as the first two bands of the full indirect guide (RD_NEEDS_INDIRECT_GUIDE: march.ls
 * nee+guide), windowed for guide.bands as those are, so every lobe and image is the full
 * guide's (bake.c; guided_unbiased.c window_bands). */
Test(guided_unbiased, the_lobe_s_indirect_guide_is_the_full_one_s_first_two_bands, .timeout = 300)
{
    rd_scene *s = rt_scene("gu_lobe_bands.json", scene_json_exact(0.6, -2.5, ENV, ""));
    cr_assert(s->guide.bands > 2, "the scene's guide has %d bands", s->guide.bands);
    rd_baked *b[2];
    const unsigned needs[2] = {RD_NEEDS_PHOTONS | RD_NEEDS_INDIRECT_LOBE, RD_NEEDS_PHOTONS | RD_NEEDS_INDIRECT_GUIDE};
    for (int i = 0; i < 2; i++) {
        char err[RD_ERRLEN];
        rd_bake_opts bo = {.seed = -1, .threads = 2};
        rd_bake_opts_for(&bo, needs[i]);
        cr_assert(rd_bake(s, &bo, &b[i], err, sizeof err) == RD_OK, "%s", err);
    }
    const sh_guide *lobe = rd_baked_indirect_guide(b[0]), *full = rd_baked_indirect_guide(b[1]);
    cr_assert(lobe && full, "an indirect guide is missing");
    cr_expect(sh_guide_bands(lobe) == 2 && sh_guide_bands(full) == s->guide.bands, "bands %d and %d",
              sh_guide_bands(lobe), sh_guide_bands(full));
    sh_guide_stats a, c;
    sh_guide_stats_get(lobe, &a), sh_guide_stats_get(full, &c);
    cr_assert(a.cells == c.cells && a.cells > 0, "cells %zu and %zu", a.cells, c.cells);
    int L = sh_guide_bands(full);
    size_t differ = 0, nonzero = 0;
    for (size_t k = 0; k < a.cells; k++) {
        const float *x = sh_guide_cell_coeffs(lobe, k), *y = sh_guide_cell_coeffs(full, k);
        for (int ch = 0; ch < 3; ch++)
            for (int j = 0; j < 4; j++) { /* (l, m) = (0, 0), (1, -1), (1, 0), (1, 1) */
                float u = x[ch * 4 + j], v = y[ch * L * L + j];
                differ += !(fabsf(u - v) <= 1e-6f * fabsf(v));
                nonzero += v != 0.0f;
            }
    }
    cr_expect(differ == 0, "%zu of %zu coefficients differ", differ, a.cells * 12);
    cr_expect(nonzero > a.cells, "only %zu non-zero coefficients", nonzero);
    rd_baked_free(b[0]), rd_baked_free(b[1]);
    rd_scene_free(s);
}
