/* Photon tracing into the photon map (THEORY.md §3), checked against answers it did not
 * compute: the first-collision density of an isotropic point light in an infinite homogeneous
 * medium, the power balance, thread-count independence, and the k-NN radiance estimate against
 * an independent delta-tracking estimate of in-scattered radiance. Fixed seeds throughout. */
#include "support/rd_test.h"
#include "bake/rd_photons.h"

#include "photonmap.h"
#include "sh.h"

static pm_map *trace(const rd_scene *s, size_t n, int store_direct, int max_depth, uint64_t seed,
                     int threads, rd_photon_stats *st)
{
    pm_map *map = pm_map_new();
    char err[RD_ERRLEN];
    rd_photon_opts o = {.count = n, .store_direct = store_direct, .segments = 0, .max_depth = max_depth,
                        .seed = seed, .threads = threads};
    cr_assert(rd_trace_photons(s, &o, map, st, err, sizeof err) == RD_OK, "%s", err);
    return map;
}

Test(photons, first_collision_density_of_a_point_light, .timeout = 120)
{
    /* sigma_t = 1.5 in a box of side 100 around an isotropic point light of I = 2 W/sr
     * (Phi = 8 pi W), albedo 1, only first collisions stored (max_depth 1). The stored power
     * density is sigma_t Phi exp(-sigma_t r) / (4 pi r^2), so the power in the shell [r1, r2]
     * is Phi (exp(-sigma_t r1) - exp(-sigma_t r2)). Counts per shell are multinomial:
     * chi-square test at p = 1e-4, shells chosen so every expected count is large. */
    rd_scene *s = rt_scene("inf.json",
                           "{\"camera\":{\"position\":[0,0,90],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-50,-50,-50],\"max\":[50,50,50]},"
                           "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1.5,\"albedo\":1}],"
                           "\"lights\":[{\"type\":\"point\",\"position\":[0.3,-0.2,0.1],\"intensity\":2}]}");
    rd_photon_stats st;
    size_t n = 200000;
    pm_map *map = trace(s, n, 1, 1, 7, 2, &st);
    cr_assert(pm_map_photon_count(map) == n, "every photon collides once: %zu", pm_map_photon_count(map));
    const pm_photon *ph = pm_map_photons(map);
    double o[3]; /* stored positions are offsets from the map origin (the media centre) */
    pm_map_origin(map, o);
    const double phi = 8.0 * M_PI, sig = 1.5;
    enum { NS = 24 };
    double edges[NS + 1], obs[NS + 1] = {0};
    for (int i = 0; i <= NS; i++) edges[i] = 4.0 * i / NS; /* shells to r = 4, then the tail */
    double power_sum = 0;
    for (size_t i = 0; i < n; i++) {
        double dx = o[0] + ph[i].pos[0] - 0.3, dy = o[1] + ph[i].pos[1] + 0.2, dz = o[2] + ph[i].pos[2] - 0.1;
        double r = sqrt(dx * dx + dy * dy + dz * dz);
        int b = (int)(r / 4.0 * NS);
        obs[b < NS ? b : NS] += 1;
        power_sum += ph[i].power[1];
        cr_assert(fabs(ph[i].power[1] - phi / n) < 1e-6 * phi / n, "photon power is Phi/N");
    }
    cr_expect(fabs(power_sum - phi) < 1e-3 * phi);
    double chi2 = 0;
    for (int i = 0; i <= NS; i++) {
        double p = i < NS ? exp(-sig * edges[i]) - exp(-sig * edges[i + 1]) : exp(-sig * edges[NS]);
        double e = n * p;
        chi2 += (obs[i] - e) * (obs[i] - e) / e;
    }
    double crit = rt_chi2_quantile(NS, 3.719);
    cr_expect(chi2 < crit, "chi2 %.1f >= %.1f", chi2, crit);
    /* And the density itself at three radii, from the photons within a thin shell: 5 sigma
     * (Poisson count). */
    const double radii[] = {0.3, 1.0, 2.0};
    for (int k = 0; k < 3; k++) {
        double r1 = radii[k] - 0.05, r2 = radii[k] + 0.05, cnt = 0;
        for (size_t i = 0; i < n; i++) {
            double dx = o[0] + ph[i].pos[0] - 0.3, dy = o[1] + ph[i].pos[1] + 0.2, dz = o[2] + ph[i].pos[2] - 0.1;
            double r = sqrt(dx * dx + dy * dy + dz * dz);
            if (r >= r1 && r < r2) cnt++;
        }
        double vol = 4.0 / 3.0 * M_PI * (r2 * r2 * r2 - r1 * r1 * r1);
        double est = cnt * (phi / n) / vol;
        /* expected: the exact shell integral over the shell volume */
        double expect = phi * (exp(-sig * r1) - exp(-sig * r2)) / vol;
        double pointwise = sig * phi * exp(-sig * radii[k]) / (4 * M_PI * radii[k] * radii[k]);
        cr_expect(fabs(est - expect) < 5 * expect / sqrt(cnt), "r=%g: %.4f vs %.4f", radii[k], est, expect);
        cr_expect(fabs(expect - pointwise) < 0.01 * pointwise, "thin shell ~ point value at r=%g", radii[k]);
    }
    pm_map_free(map);
    rd_scene_free(s);
}

Test(photons, power_balance, .timeout = 120)
{
    /* emitted = absorbed + escaped + carried in expectation. Over 16 seeds of 20000 photons,
     * the mean of the relative imbalance must be within 5 standard errors of 0, and the
     * emitted power within 5 standard errors of the lights' total power. */
    rd_scene *s = rt_scene("balance.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":{\"type\":\"noise\",\"octaves\":3,\"seed\":5},\"sigma_t\":3,\"albedo\":[0.9,0.6,0.3],\"g\":0.4}],"
                           "\"lights\":[{\"type\":\"point\",\"position\":[0,1.5,0],\"intensity\":1},"
                           "{\"type\":\"spot\",\"position\":[2,2,0],\"look_at\":[0,0,0],\"angle\":40,\"falloff\":10,\"intensity\":[3,2,1]},"
                           "{\"type\":\"directional\",\"direction\":[0,-1,0],\"irradiance\":0.5,\"radius\":0.5,\"center\":[0,0,0]},"
                           "{\"type\":\"sphere\",\"center\":[0,-2,0],\"radius\":0.3,\"radiance\":2},"
                           "{\"type\":\"environment\",\"radiance\":0.05}]}");
    enum { K = 16 };
    double imb[K], emi[K];
    for (int k = 0; k < K; k++) {
        rd_photon_stats st;
        pm_map *map = trace(s, 20000, 1, 8, 100 + k, 2, &st);
        double e = st.power_emitted[0];
        imb[k] = (e - st.power_absorbed[0] - st.power_escaped[0] - st.power_carried[0]) / e;
        emi[k] = e;
        pm_map_free(map);
    }
    double m = 0, v = 0, me = 0, ve = 0;
    for (int k = 0; k < K; k++) { m += imb[k] / K; me += emi[k] / K; }
    for (int k = 0; k < K; k++) { v += (imb[k] - m) * (imb[k] - m) / (K - 1); ve += (emi[k] - me) * (emi[k] - me) / (K - 1); }
    double se = sqrt(v / K), see = sqrt(ve / K);
    cr_expect(fabs(m) < 5 * se + 1e-12, "imbalance %.2e (se %.2e)", m, se);
    cr_expect(se > 0, "the imbalance must be random, not identically 0 (else the test is empty)");
    /* Total power of the lights, red channel. */
    double R = rd_scene_radius(s), total = 0;
    const double spot_cos_o = cos(20 * M_PI / 180), spot_cos_i = cos(10 * M_PI / 180);
    /* spot: 2 pi I int f(cos) dcos, f = smoothstep over [cos_o, cos_i]: exact integral is
     * (cos_i - cos_o)/2 + (1 - cos_i) */
    total += 4 * M_PI * 1.0;
    total += 2 * M_PI * 3.0 * ((spot_cos_i - spot_cos_o) * 0.5 + (1 - spot_cos_i));
    total += 0.5 * M_PI * 0.25;
    total += 2.0 * M_PI * 4 * M_PI * 0.09;
    total += 0.05 * 4 * M_PI * M_PI * R * R;
    cr_expect(fabs(me - total) < 5 * see, "emitted %.5f vs lights %.5f (se %.5f)", me, total, see);
    rd_scene_free(s);
}

Test(photons, same_map_on_one_and_two_threads, .timeout = 60)
{
    rd_scene *s = rt_scene("det.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":{\"type\":\"noise\",\"octaves\":2},\"sigma_t\":2,\"albedo\":0.8,\"g\":0.5}],"
                           "\"lights\":[{\"type\":\"spot\",\"position\":[0,2,0],\"look_at\":[0,0,0],\"angle\":50,\"intensity\":4}]}");
    rd_photon_stats a, b;
    pm_map *m1 = trace(s, 30000, 0, 16, 3, 1, &a);
    pm_map *m2 = trace(s, 30000, 0, 16, 3, 2, &b);
    cr_assert(pm_map_photon_count(m1) == pm_map_photon_count(m2) && pm_map_photon_count(m1) > 1000);
    cr_expect(memcmp(pm_map_photons(m1), pm_map_photons(m2), pm_map_photon_count(m1) * sizeof(pm_photon)) == 0);
    pm_map_free(m1);
    pm_map_free(m2);
    rd_scene_free(s);
}

/* The guide's every coefficient, the same to the bit in both guides (either may be NULL: then
 * both must be). */
static void expect_same_guide(const sh_guide *a, const sh_guide *b, const char *which)
{
    cr_assert((a == NULL) == (b == NULL), "%s: one bake has it, the other not", which);
    if (!a) return;
    sh_guide_stats sa, sb;
    sh_guide_stats_get(a, &sa), sh_guide_stats_get(b, &sb);
    int L = sh_guide_bands(a);
    cr_assert(sa.cells == sb.cells && sa.cells > 0 && L == sh_guide_bands(b), "%s: cells %zu / %zu", which, sa.cells, sb.cells);
    size_t differ = 0;
    for (size_t k = 0; k < sa.cells; k++)
        differ += memcmp(sh_guide_cell_coeffs(a, k), sh_guide_cell_coeffs(b, k), 3 * (size_t)L * L * sizeof(float)) != 0;
    cr_expect(differ == 0, "%s: %zu of %zu cells differ", which, differ, sa.cells);
}

/* rd_bake builds the photon map's and the indirect map's kd-trees at once on two threads
 * (bake.c, build_maps): the maps, their k-NN answers and both guides baked from them are the same
 * to the bit as a bake on one thread, where the two builds run one after the other. */
Test(photons, the_bake_s_two_maps_and_guides_are_the_same_on_one_and_two_threads, .timeout = 120)
{
    rd_scene *s = rt_scene("bake_threads.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":{\"type\":\"noise\",\"octaves\":2},\"sigma_t\":2,\"albedo\":0.8,\"g\":0.5}],"
                           "\"lights\":[{\"type\":\"spot\",\"position\":[0,2,0],\"look_at\":[0,0,0],\"angle\":50,\"intensity\":4}],"
                           "\"photons\":{\"count\":20000},\"guide\":{\"resolution\":[8,8,8]}}");
    rd_baked *b[2];
    for (int i = 0; i < 2; i++) {
        char err[RD_ERRLEN];
        rd_bake_opts bo = {.seed = -1, .threads = i + 1};
        rd_bake_opts_for(&bo, RD_NEEDS_PHOTONS | RD_NEEDS_GUIDE | RD_NEEDS_INDIRECT_GUIDE);
        cr_assert(rd_bake(s, &bo, &b[i], err, sizeof err) == RD_OK, "%s", err);
    }
    const pm_map *maps[2][2] = {{rd_baked_map(b[0]), rd_baked_indirect_map(b[0])}, {rd_baked_map(b[1]), rd_baked_indirect_map(b[1])}};
    for (int m = 0; m < 2; m++) {
        const pm_map *x = maps[0][m], *y = maps[1][m];
        cr_assert(x && y && pm_map_photon_count(x) == pm_map_photon_count(y) && pm_map_photon_count(x) > 1000,
                  "map %d: %zu photons", m, x ? pm_map_photon_count(x) : 0);
        cr_expect(memcmp(pm_map_photons(x), pm_map_photons(y), pm_map_photon_count(x) * sizeof(pm_photon)) == 0, "map %d", m);
        for (int q = 0; q < 8; q++) { /* the trees answer alike */
            double at[3] = {-0.8 + 0.2 * q, 0.5 - 0.13 * q, 0.3 * (q % 3) - 0.3};
            int ix[16], iy[16];
            float dx[16], dy[16];
            int nx = pm_map_knn(x, at, 16, ix, dx), ny = pm_map_knn(y, at, 16, iy, dy);
            cr_expect(nx == 16 && ny == 16 && memcmp(ix, iy, sizeof ix) == 0 && memcmp(dx, dy, sizeof dx) == 0,
                      "map %d, query %d: %d and %d found, or other photons", m, q, nx, ny);
        }
    }
    expect_same_guide(rd_baked_guide(b[0]), rd_baked_guide(b[1]), "the guide");
    expect_same_guide(rd_baked_indirect_guide(b[0]), rd_baked_indirect_guide(b[1]), "the indirect guide");
    cr_expect(rd_baked_indirect_guide(b[0]) != NULL, "no indirect guide baked");
    rd_baked_free(b[0]), rd_baked_free(b[1]);
    rd_scene_free(s);
}

Test(photons, one_trace_gives_the_indirect_map_of_a_trace_of_its_own, .timeout = 60)
{
    /* rd_trace_photons_split fills the indirect map (photons without their first flight) in
     * the same trace as the main one: both must be, bit for bit, the maps of two traces of
     * their own (store_direct 1 with segments, and store_direct 0), on 2 threads. */
    rd_scene *s = rt_scene("split.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":{\"type\":\"noise\",\"octaves\":2},\"sigma_t\":2,\"albedo\":0.8,\"g\":0.5}],"
                           "\"lights\":[{\"type\":\"spot\",\"position\":[0,2,0],\"look_at\":[0,0,0],\"angle\":50,\"intensity\":4}]}");
    char err[RD_ERRLEN];
    rd_photon_stats st;
    rd_photon_opts o = {.count = 30000, .store_direct = 1, .segments = 1, .max_depth = 16, .seed = 9, .threads = 2};
    pm_map *all = pm_map_new(), *ind = pm_map_new(), *all1 = pm_map_new(), *ind1 = pm_map_new();
    cr_assert(rd_trace_photons_split(s, &o, all, ind, &st, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(rd_trace_photons(s, &o, all1, &st, err, sizeof err) == RD_OK, "%s", err);
    rd_photon_opts oi = o;
    oi.store_direct = 0;
    oi.segments = 0;
    cr_assert(rd_trace_photons(s, &oi, ind1, &st, err, sizeof err) == RD_OK, "%s", err);
    size_t n = pm_map_photon_count(ind);
    cr_assert(n > 1000 && n < pm_map_photon_count(all), "indirect %zu of %zu photons", n, pm_map_photon_count(all));
    cr_assert(n == pm_map_photon_count(ind1));
    cr_expect(memcmp(pm_map_photons(ind), pm_map_photons(ind1), n * sizeof(pm_photon)) == 0);
    cr_expect(pm_map_segment_count(ind) == 0);
    cr_assert(pm_map_photon_count(all) == pm_map_photon_count(all1) && pm_map_segment_count(all) == pm_map_segment_count(all1));
    cr_expect(memcmp(pm_map_photons(all), pm_map_photons(all1), pm_map_photon_count(all) * sizeof(pm_photon)) == 0);
    double o1[3], o2[3];
    pm_map_origin(ind, o1);
    pm_map_origin(ind1, o2);
    cr_expect(memcmp(o1, o2, sizeof o1) == 0);
    pm_map_free(all);
    pm_map_free(ind);
    pm_map_free(all1);
    pm_map_free(ind1);
    rd_scene_free(s);
}

Test(photons, knn_radiance_converges_to_delta_tracking, .timeout = 300)
{
    /* sigma_s L_s(x, w) at 48 fixed points and directions, from the photon map (all collisions
     * stored) at N = 1e4, 1e5, 1e6 photons with k = 30, 100, 300, against an independent
     * estimate: delta-tracked radiance arriving at x from directions sampled by the phase
     * function (150000 paths per point, relative standard error < 2%) plus the light's direct
     * term.
     * Expected rate: the k-NN relative error is a variance part ~ 1/sqrt(k - 2) (equal-power
     * photons) plus a bias ~ (k/N)^(2/3); with k ~ N^0.5 the RMS error falls like N^-0.25 (the
     * optimum, k ~ N^(4/7), gives N^-0.29). The RMS over 48 points has a relative uncertainty
     * of about 1/sqrt(96) = 10%, so the fitted log10 slope is known to about +-0.03: we require
     * a slope below -0.16 (3 of those sigma above -0.25), an RMS that falls at every step, and a
     * final RMS within twice the variance-only value 1/sqrt(k - 2) (the bias is not
     * dominant). */
    rd_scene *s = rt_scene("knn.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1.0,\"albedo\":0.8,\"g\":0.3}],"
                           "\"lights\":[{\"type\":\"point\",\"position\":[0,1.6,0],\"intensity\":1}]}");
    enum { NP = 48 };
    vec3 xs[NP], ws[NP];
    double ref[NP];
    pcg32 g = pcg32_seed(9, 9, 9);
    const rd_medium *m = &s->media[0];
    for (int i = 0; i < NP; i++) {
        /* points in the upper part of the box. The light is outside the medium (0.6 m above
         * it), so next-event estimates in the reference are bounded (a point light inside the
         * medium gives the reference infinite variance). */
        xs[i] = v3(1.6 * pcg32_uniform(&g) - 0.8, 0.2 + 0.7 * pcg32_uniform(&g), 1.6 * pcg32_uniform(&g) - 0.8);
        ws[i] = rd_sample_sphere(pcg32_uniform(&g), pcg32_uniform(&g));
        /* reference: sigma_s * E_{w' ~ p(.|w)} [L arriving at x travelling along w'] */
        int n = 150000;
        double sum = 0, sum2 = 0;
        rd_track_counters c = {0};
        for (int k = 0; k < n; k++) {
            pcg32 r = pcg32_seed(i, k, 555);
            /* w' with pdf p(w' . w): sample around -w... the phase is symmetric in
             * cos(w', w), so sample w' around w and trace backwards along -w'. */
            vec3 wp = rd_hg_sample(m->g, ws[i], pcg32_uniform(&r), pcg32_uniform(&r));
            ray3 back = {xs[i], v3_scale(wp, -1.0)};
            double L = rd_delta_radiance(s, back, &r, &c).y;
            sum += L;
            sum2 += L * L;
        }
        double mean = sum / n, se = sqrt((sum2 / n - mean * mean) / n);
        /* The light itself is a delta in direction that a traced ray never hits: add its
         * direct term p(w_l . w) I T / r^2 analytically (T through the homogeneous box). */
        vec3 tol = v3_sub(v3(0, 1.6, 0), xs[i]);
        double r = v3_len(tol), t0, t1;
        ray3 sr = {xs[i], v3_scale(tol, 1.0 / r)};
        double inside = rd_box_intersect(m->bmin, m->bmax, sr, 0, r, &t0, &t1) ? t1 - t0 : 0;
        double direct = rd_hg_eval(m->g, v3_dot(v3_scale(sr.d, -1.0), ws[i])) * 1.0 / (r * r) * exp(-1.0 * inside);
        ref[i] = 0.8 * 1.0 * (mean + direct); /* sigma_s = albedo sigma_t */
        cr_assert(se < 0.02 * mean, "reference too noisy at point %d: %.4f +- %.4f", i, mean, se);
    }
    const size_t ns[3] = {10000, 100000, 1000000};
    const int ks[3] = {30, 100, 300};
    double rms[3];
    double gg = m->g;
    for (int j = 0; j < 3; j++) {
        rd_photon_stats st;
        pm_map *map = trace(s, ns[j], 1, 64, 31 + j, 2, &st);
        char err[256];
        cr_assert(pm_map_build(map, err, sizeof err) == PM_OK, "%s", err);
        double e2 = 0;
        for (int i = 0; i < NP; i++) {
            double x[3] = {xs[i].x, xs[i].y, xs[i].z};
            float w[3] = {(float)ws[i].x, (float)ws[i].y, (float)ws[i].z};
            float out[3];
            cr_assert(pm_map_radiance(map, x, w, ks[j], rd_phase_hg_cb, &gg, out) == ks[j]);
            double rel = (out[1] - ref[i]) / ref[i];
            e2 += rel * rel / NP;
        }
        rms[j] = sqrt(e2);
        pm_map_free(map);
    }
    double slope = (log10(rms[2]) - log10(rms[0])) / 2.0;
    cr_expect(rms[1] < rms[0] && rms[2] < rms[1], "RMS relative error %.3f, %.3f, %.3f must fall", rms[0], rms[1], rms[2]);
    cr_expect(slope < -0.16, "log10 slope %.3f per decade (expected about -0.25)", slope);
    cr_expect(rms[2] < 2.0 / sqrt(ks[2] - 2.0), "RMS relative error at 1e6 photons %.3f", rms[2]);
    cr_log_info("k-NN RMS relative error: %.3f %.3f %.3f (slope %.3f)", rms[0], rms[1], rms[2], slope);
    rd_scene_free(s);
}

/* ---- Positions far from the world origin, errors ----------------------------------------- */

Test(photons, map_origin_is_the_media_centre_far_from_zero)
{
    /* A medium 1e5 m from the world origin: the map's origin is the centre of the media
     * bounds, and every stored photon (origin + offset, in double) lies inside the medium, to
     * the float precision of an offset (1 ulp at 1 m is 1.2e-7 m). */
    rd_scene *s = rt_scene("far.json",
                           "{\"camera\":{\"position\":[100000,100000,100010],\"look_at\":[100000,100000,100000],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[99999,99999.5,99999],\"max\":[100001,100000.5,100002]},"
                           "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":2,\"albedo\":0.9}],"
                           "\"lights\":[{\"type\":\"point\",\"position\":[100000,100000,100000.5],\"intensity\":1}]}");
    rd_photon_stats st;
    pm_map *map = trace(s, 20000, 1, 8, 3, 2, &st);
    double o[3];
    pm_map_origin(map, o);
    cr_assert(o[0] == 100000.0 && o[1] == 100000.0 && o[2] == 100000.5, "origin (%.17g, %.17g, %.17g)",
              o[0], o[1], o[2]);
    const pm_photon *ph = pm_map_photons(map);
    size_t n = pm_map_photon_count(map);
    cr_assert(n > 10000, "%zu photons", n);
    const double lo[3] = {99999, 99999.5, 99999}, hi[3] = {100001, 100000.5, 100002};
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            double x = o[a] + ph[i].pos[a];
            cr_assert(x >= lo[a] - 2e-7 && x <= hi[a] + 2e-7, "photon %zu axis %d at %.9f", i, a, x);
        }
    pm_map_free(map);
    rd_scene_free(s);
}

Test(photons, out_of_memory_writes_a_one_line_message)
{
    /* SIZE_MAX photons need SIZE_MAX / 4096 work blocks, far more bytes than an address space
     * holds: calloc fails deterministically. (This used to return RD_ERR_NOMEM with err left
     * empty, and the block count overflowed to 0.) */
    rd_scene *s = rt_scene("oom.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                           "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1,\"albedo\":0.5}],"
                           "\"lights\":[{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":1}]}");
    pm_map *map = pm_map_new();
    char err[RD_ERRLEN] = "";
    rd_photon_stats st;
    rd_photon_opts o = {.count = SIZE_MAX, .store_direct = 1, .max_depth = 4, .seed = 1, .threads = 1};
    rd_status rc = rd_trace_photons(s, &o, map, &st, err, sizeof err);
    cr_assert_eq(rc, RD_ERR_NOMEM, "status %d (%s)", rc, err);
    cr_assert(err[0] != 0, "no message");
    cr_assert_null(strchr(err, '\n'), "message is not one line: %s", err);
    cr_assert_not_null(strstr(err, "out of memory for"), "message does not say what: %s", err);
    cr_assert_not_null(strstr(err, "block"), "message does not name the allocation: %s", err);
    cr_assert_eq(pm_map_photon_count(map), 0);
    pm_map_free(map);
    rd_scene_free(s);
}

/* ---- Emission sampling: chi-square against the analytic distributions ---------------------- *
 * DESIGN.md convention 9: fixed seeds; cells whose expected count is < 5 are pooled into one;
 * the statistic is compared with the chi-square quantile at p = 1e-4 (z = 3.719), and each test
 * has a negative control: the same samples against a wrong distribution must fail. */

#define EM_N 200000

/* Pearson chi-square of counts obs[] against probabilities p[] (summing to 1) for N samples,
 * pooling cells with expected < 5; returns the statistic and its degrees of freedom. */
static double em_chi2(const double *obs, const double *p, int nb, double N, int *dof)
{
    double chi2 = 0.0, po = 0.0, pe = 0.0;
    int cells = 0;
    for (int i = 0; i < nb; i++) {
        double e = N * p[i];
        if (e < 5.0) {
            po += obs[i], pe += e;
            continue;
        }
        chi2 += (obs[i] - e) * (obs[i] - e) / e;
        cells++;
    }
    if (pe > 0.0) {
        chi2 += (po - pe) * (po - pe) / pe;
        cells++;
    }
    *dof = cells - 1;
    return chi2;
}

/* Pass against p, fail against the wrong distribution q (negative control). */
static void em_check(const char *what, const double *obs, const double *p, const double *q, int nb,
                     double N)
{
    int dof, dofq;
    double c = em_chi2(obs, p, nb, N, &dof), cq = em_chi2(obs, q, nb, N, &dofq);
    double crit = rt_chi2_quantile(dof, 3.719), critq = rt_chi2_quantile(dofq, 3.719);
    cr_expect(c < crit, "%s: chi2 %.1f >= %.1f (dof %d)", what, c, crit, dof);
    cr_expect(cq > critq, "%s: negative control passed: chi2 %.1f <= %.1f", what, cq, critq);
    cr_log_info("%s: chi2 %.1f (crit %.1f, dof %d); negative control %.1f", what, c, crit, dof, cq);
}

/* Bin of a unit vector w in (cos theta, phi) about the frame (a, b, n): nc x nphi cells with
 * cos theta in [cmin, 1] cut uniformly. */
static int em_bin(vec3 w, vec3 a, vec3 b, vec3 n, double cmin, int nc, int nphi)
{
    double c = v3_dot(w, n), phi = atan2(v3_dot(w, b), v3_dot(w, a)) + M_PI;
    int ic = (int)((c - cmin) / (1.0 - cmin) * nc), ip = (int)(phi / (2.0 * M_PI) * nphi);
    ic = ic < 0 ? 0 : (ic >= nc ? nc - 1 : ic);
    ip = ip < 0 ? 0 : (ip >= nphi ? nphi - 1 : ip);
    return ic * nphi + ip;
}

static rd_scene *em_scene(const char *light)
{
    char json[1024];
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,8],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
             "\"media\":[{\"bounds\":{\"min\":[-1,-2,-1],\"max\":[3,2,1]},"
             "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1,\"albedo\":0.5}],"
             "\"lights\":[%s]}", light);
    return rt_scene("emit.json", json);
}

enum { EM_NC = 12, EM_NP = 12, EM_NB = EM_NC * EM_NP };

/* Uniform-sphere cells and a tilted wrong distribution (1 + 0.15 cos theta) for controls. */
static void em_sphere_probs(double *p, double *q)
{
    for (int i = 0; i < EM_NB; i++) {
        double c0 = -1.0 + 2.0 * (i / EM_NP) / EM_NC, c1 = c0 + 2.0 / EM_NC;
        p[i] = 1.0 / EM_NB;
        q[i] = ((c1 - c0) + 0.075 * (c1 * c1 - c0 * c0)) / 2.0 / EM_NP;
    }
}

Test(photons, emission_point_light_is_uniform_on_the_sphere)
{
    rd_scene *s = em_scene("{\"type\":\"point\",\"position\":[0.5,0,0],\"intensity\":[1,2,3]}");
    const rd_light *l = &s->lights[0];
    vec3 n = v3(0.2, -0.5, 0.84), a, b;
    n = v3_norm(n);
    v3_basis(n, &a, &b);
    double obs[EM_NB] = {0}, p[EM_NB], q[EM_NB];
    pcg32 rng = pcg32_seed(11, 0, 1);
    for (int i = 0; i < EM_N; i++) {
        ray3 r;
        vec3 pw;
        cr_assert(rd_light_sample_emission(s, l, NULL, &rng, &r, &pw));
        cr_assert(r.o.x == 0.5 && r.o.y == 0 && r.o.z == 0, "photons leave the light's position");
        cr_assert(fabs(pw.y - 4.0 * M_PI * 2.0) < 1e-12, "power 4 pi I");
        obs[em_bin(r.d, a, b, n, -1.0, EM_NC, EM_NP)] += 1;
    }
    em_sphere_probs(p, q);
    em_check("point", obs, p, q, EM_NB, EM_N);
    rd_scene_free(s);
}

Test(photons, emission_environment_is_uniform_inward_over_a_disc)
{
    /* Directions uniform on the sphere; origins on a disc of radius R across d, 2R upstream of
     * the media centre: (o - centre).d = -2R, and the squared offset radius / R^2 uniform. */
    rd_scene *s = em_scene("{\"type\":\"environment\",\"radiance\":1}");
    const rd_light *l = &s->lights[0];
    vec3 c = v3_scale(v3_add(s->bmin, s->bmax), 0.5), n = v3(0, 0, 1), a, b;
    v3_basis(n, &a, &b);
    double R = rd_scene_radius(s);
    double obs[EM_NB] = {0}, p[EM_NB], q[EM_NB], rad[10] = {0}, pr[10], qr[10];
    pcg32 rng = pcg32_seed(12, 0, 1);
    for (int i = 0; i < EM_N; i++) {
        ray3 r;
        vec3 pw;
        cr_assert(rd_light_sample_emission(s, l, NULL, &rng, &r, &pw));
        obs[em_bin(r.d, a, b, n, -1.0, EM_NC, EM_NP)] += 1;
        vec3 off = v3_sub(r.o, c);
        double along = v3_dot(off, r.d);
        cr_assert(fabs(along + 2.0 * R) < 1e-9 * R, "disc 2R upstream: %g", along);
        double rho2 = (v3_dot(off, off) - along * along) / (R * R);
        int k = (int)(rho2 * 10);
        rad[k < 0 ? 0 : (k > 9 ? 9 : k)] += 1;
    }
    em_sphere_probs(p, q);
    em_check("environment directions", obs, p, q, EM_NB, EM_N);
    for (int k = 0; k < 10; k++) { /* control: radius uniform in [0, R] instead of area */
        pr[k] = 0.1;
        qr[k] = sqrt((k + 1) / 10.0) - sqrt(k / 10.0);
    }
    em_check("environment disc", rad, pr, qr, 10, EM_N);
    rd_scene_free(s);
}

Test(photons, emission_directional_is_one_direction_over_a_disc)
{
    /* Every photon travels along the light's direction; origins uniform over the beam disc
     * (its centre and radius), or over a disc of the scene radius around the media centre. */
    const char *lights[2] = {
        "{\"type\":\"directional\",\"direction\":[0.3,-1,0.2],\"irradiance\":2,\"radius\":0.4,\"center\":[1,0,0.2]}",
        "{\"type\":\"directional\",\"direction\":[0.3,-1,0.2],\"irradiance\":2}"};
    for (int t = 0; t < 2; t++) {
        rd_scene *s = em_scene(lights[t]);
        const rd_light *l = &s->lights[0];
        double R = rd_scene_radius(s), rad = t == 0 ? 0.4 : R;
        vec3 axis = t == 0 ? v3(1, 0, 0.2) : v3_scale(v3_add(s->bmin, s->bmax), 0.5), a, b;
        v3_basis(l->dir, &a, &b);
        double obs[EM_NB] = {0}, p[EM_NB], q[EM_NB];
        pcg32 rng = pcg32_seed(13 + t, 0, 1);
        for (int i = 0; i < EM_N; i++) {
            ray3 r;
            vec3 pw;
            cr_assert(rd_light_sample_emission(s, l, NULL, &rng, &r, &pw));
            cr_assert(r.d.x == l->dir.x && r.d.y == l->dir.y && r.d.z == l->dir.z, "one direction");
            cr_assert(fabs(pw.x - 2.0 * M_PI * rad * rad) < 1e-9 * pw.x, "power E pi r^2");
            /* offset from the beam axis, in the disc's plane */
            vec3 off = v3_sub(r.o, axis);
            double u = v3_dot(off, a) / rad, v = v3_dot(off, b) / rad, rho2 = u * u + v * v;
            cr_assert(rho2 <= 1.0 + 1e-9, "inside the disc: %g", rho2);
            double phi = atan2(v, u) + M_PI;
            int ir = (int)(rho2 * EM_NC), ip = (int)(phi / (2 * M_PI) * EM_NP);
            ir = ir >= EM_NC ? EM_NC - 1 : ir;
            ip = ip >= EM_NP ? EM_NP - 1 : ip;
            obs[ir * EM_NP + ip] += 1;
        }
        for (int i = 0; i < EM_NB; i++) { /* uniform in area; control: uniform in radius */
            int ir = i / EM_NP;
            p[i] = 1.0 / EM_NB;
            q[i] = (sqrt((ir + 1.0) / EM_NC) - sqrt((double)ir / EM_NC)) / EM_NP;
        }
        em_check(t == 0 ? "directional beam disc" : "directional scene disc", obs, p, q, EM_NB, EM_N);
        rd_scene_free(s);
    }
}

Test(photons, emission_sphere_light_is_cosine_weighted_from_a_uniform_surface)
{
    rd_scene *s = em_scene("{\"type\":\"sphere\",\"center\":[0.5,0.2,-0.1],\"radius\":0.3,\"radiance\":1}");
    const rd_light *l = &s->lights[0];
    vec3 ax = v3_norm(v3(0.6, 0.3, -0.74)), a, b;
    v3_basis(ax, &a, &b);
    double pos[EM_NB] = {0}, ps[EM_NB], qs[EM_NB], cosb[EM_NB] = {0}, pc[EM_NB], qc[EM_NB];
    pcg32 rng = pcg32_seed(15, 0, 1);
    for (int i = 0; i < EM_N; i++) {
        ray3 r;
        vec3 pw;
        cr_assert(rd_light_sample_emission(s, l, NULL, &rng, &r, &pw));
        vec3 off = v3_sub(r.o, l->pos);
        double d = v3_len(off);
        cr_assert(fabs(d - 0.3) < 1e-6, "on the surface: %g", d);
        vec3 nn = v3_scale(off, 1.0 / d);
        pos[em_bin(nn, a, b, ax, -1.0, EM_NC, EM_NP)] += 1;
        /* cosine-weighted about the normal: cos^2 theta uniform on [0, 1]; phi about the
         * normal uniform */
        vec3 na, nb;
        v3_basis(nn, &na, &nb);
        double c = v3_dot(r.d, nn);
        cr_assert(c >= 0.0, "outward");
        double phi = atan2(v3_dot(r.d, nb), v3_dot(r.d, na)) + M_PI;
        int ic = (int)(c * c * EM_NC), ip = (int)(phi / (2 * M_PI) * EM_NP);
        ic = ic >= EM_NC ? EM_NC - 1 : ic;
        ip = ip >= EM_NP ? EM_NP - 1 : ip;
        cosb[ic * EM_NP + ip] += 1;
    }
    em_sphere_probs(ps, qs);
    em_check("sphere light surface", pos, ps, qs, EM_NB, EM_N);
    for (int i = 0; i < EM_NB; i++) { /* control: uniform hemisphere, P(c^2 < x) = sqrt(x) */
        int ic = i / EM_NP;
        pc[i] = 1.0 / EM_NB;
        qc[i] = (sqrt((ic + 1.0) / EM_NC) - sqrt((double)ic / EM_NC)) / EM_NP;
    }
    em_check("sphere light directions", cosb, pc, qc, EM_NB, EM_N);
    rd_scene_free(s);
}

/* Integral of the spot falloff over cos theta in [c0, c1] (composite Simpson, 200 steps: the
 * smoothstep is a cubic in cos theta, so each piece is integrated exactly but for the kink at
 * cos_inner, whose error is < 1e-9 here). */
static double em_falloff_integral(const rd_light *l, double c0, double c1)
{
    const int m = 200;
    double h = (c1 - c0) / m, sum = rd_spot_falloff(l, c0) + rd_spot_falloff(l, c1);
    for (int i = 1; i < m; i++) sum += (i % 2 ? 4.0 : 2.0) * rd_spot_falloff(l, c0 + i * h);
    return sum * h / 3.0;
}

Test(photons, emission_spot_light_follows_its_falloff)
{
    /* Directions are drawn uniformly in the cone and weighted by the falloff; the emitted power
     * is then distributed like the falloff. Thinning each photon with probability
     * power / max power leaves directions distributed like falloff(cos theta) over the cone:
     * chi-square of those against the falloff's integral over each cell, the control being the
     * cone without falloff (uniform). */
    rd_scene *s = em_scene("{\"type\":\"spot\",\"position\":[0,0,0],\"direction\":[0.3,-0.2,1],"
                           "\"angle\":60,\"falloff\":15,\"intensity\":2}");
    const rd_light *l = &s->lights[0];
    vec3 a, b;
    v3_basis(l->dir, &a, &b);
    double pmax = 2.0 * 2.0 * M_PI * (1.0 - l->cos_outer);
    double obs[EM_NB] = {0}, p[EM_NB], q[EM_NB], kept = 0;
    pcg32 rng = pcg32_seed(16, 0, 1), thin = pcg32_seed(16, 1, 1);
    for (int i = 0; i < EM_N; i++) {
        ray3 r;
        vec3 pw;
        cr_assert(rd_light_sample_emission(s, l, NULL, &rng, &r, &pw));
        double c = v3_dot(r.d, l->dir);
        cr_assert(c >= l->cos_outer - 1e-12, "inside the cone");
        cr_assert(fabs(pw.x - pmax * rd_spot_falloff(l, c)) < 1e-9 * pmax, "power follows the falloff");
        if (pcg32_uniform(&thin) < pw.x / pmax) {
            obs[em_bin(r.d, a, b, l->dir, l->cos_outer, EM_NC, EM_NP)] += 1;
            kept++;
        }
    }
    double total = em_falloff_integral(l, l->cos_outer, 1.0);
    for (int i = 0; i < EM_NB; i++) {
        int ic = i / EM_NP;
        double c0 = l->cos_outer + (1.0 - l->cos_outer) * ic / EM_NC;
        double c1 = l->cos_outer + (1.0 - l->cos_outer) * (ic + 1) / EM_NC;
        p[i] = em_falloff_integral(l, c0, c1) / total / EM_NP;
        q[i] = 1.0 / EM_NB;
    }
    em_check("spot", obs, p, q, EM_NB, kept);
    rd_scene_free(s);
}

/* ---- Photons aimed at the glass (photons.aim, rd_emission_aim) ---------------------------- */

/* Per cell, the mean over EM_N photons of power x [photon in the cell] (x channel), and its
 * variance. Two sets of EM_NB cells: the photons whose ray meets the aim's sphere, by direction
 * within the sphere's cone (em_bin about the cone's axis from the cone's cos up), and the
 * others, by direction over the whole sphere about `axis`. For a directional light, by origin
 * instead: within the aim's disc (radius and angle about its centre) or in the beam's disc
 * (about `at`, scaled by `scale`). */
typedef struct { double sum[2 * EM_NB], sq[2 * EM_NB]; double inside; } em_flux;
#define EM_OWN (10 * EM_N)

static int em_ring(vec3 off, vec3 a, vec3 b, double scale, double rmax2)
{
    double u = v3_dot(off, a) / scale, v = v3_dot(off, b) / scale;
    int ir = (int)((u * u + v * v) / rmax2 * EM_NC), ip = (int)((atan2(v, u) + M_PI) / (2.0 * M_PI) * EM_NP);
    return (ir >= EM_NC ? EM_NC - 1 : ir) * EM_NP + (ip >= EM_NP ? EM_NP - 1 : ip);
}

static void em_flux_add(em_flux *f, const rd_light *l, ray3 r, vec3 pw, vec3 axis, vec3 at, double scale,
                        const rd_emission_aim *aim)
{
    vec3 a, b;
    int k;
    if (l->kind == RD_LIGHT_DIRECTIONAL) {
        v3_basis(l->dir, &a, &b);
        vec3 c = v3_madd(aim->centre, l->dir, v3_dot(v3_sub(r.o, aim->centre), l->dir));
        int in = v3_len(v3_sub(r.o, c)) <= aim->radius;
        k = in ? EM_NB + em_ring(v3_sub(r.o, c), a, b, aim->radius, 1.0) : em_ring(v3_sub(r.o, at), a, b, scale, 1.44);
        f->inside += in;
    } else {
        vec3 to = v3_sub(aim->centre, r.o);
        double d = v3_len(to), cmax = sqrt(1.0 - aim->radius * aim->radius / (d * d));
        vec3 w = v3_scale(to, 1.0 / d);
        int in = v3_dot(r.d, w) >= cmax;
        if (in) {
            v3_basis(w, &a, &b);
            k = EM_NB + em_bin(r.d, a, b, w, cmax, EM_NC, EM_NP);
        } else {
            v3_basis(axis, &a, &b);
            k = em_bin(r.d, a, b, axis, -1.0, EM_NC, EM_NP);
        }
        f->inside += in;
    }
    f->sum[k] += pw.x;
    f->sq[k] += pw.x * pw.x;
}

/* Sum over the cells of z^2, z the difference of the two means (of nx and ny photons) over its
 * standard error: about
 * chi-square with one degree of freedom a cell where both sides are unbiased for the same flux.
 * Cells no photon reached on either side are left out. */
static double em_flux_chi2(const em_flux *x, double nx, const em_flux *y, double ny, int *dof)
{
    double chi2 = 0.0;
    *dof = 0;
    for (int i = 0; i < 2 * EM_NB; i++) {
        double mx = x->sum[i] / nx, my = y->sum[i] / ny;
        double vx = (x->sq[i] / nx - mx * mx) / nx, vy = (y->sq[i] / ny - my * my) / ny;
        if (!(vx + vy > 0.0)) continue;
        chi2 += (mx - my) * (mx - my) / (vx + vy);
        (*dof)++;
    }
    return chi2;
}

Test(photons, aimed_emission_keeps_each_light_s_flux_per_direction_and_aims, .timeout = 120)
{
    /* With an aim, a light's photons are a mixture of its own distribution and a uniform one
     * toward a sphere (rd_light_sample_emission), each weighted by emitted radiance over the
     * mixture's density. So the power a photon carries into any set of directions (of disc
     * positions, for a directional light) has the same mean as without the aim: per cell
     * (em_flux: 144 in the sphere's cone, 144 over the rest), z^2 summed over the cells must stay under the chi-square quantile at
     * z = 3.719 (a one-sided 1e-4), EM_N aimed photons against EM_OWN = 10 EM_N of the
     * light's own (few of which meet the sphere: their noise bounds the test), fixed seeds. Each
     * mixture density planted 10% low in its aimed part fails (chi2 620, 260, 463 and 559
     * against bounds 386, 154, 386 and 268). Control: the aimed
     * photons weighted as if drawn from the light's own distribution (no mixture) must fail
     * it. And the aim must aim: more of the photons' rays meet the sphere (below). Each light kind with its own aim sphere, placed so
     * that part of it lies outside the spot's cone and the beam's disc. */
    const char *lights[4] = {
        "{\"type\":\"point\",\"position\":[0.5,0,0],\"intensity\":[1,2,3]}",
        "{\"type\":\"spot\",\"position\":[0,0,0],\"direction\":[0.3,-0.2,1],\"angle\":40,\"falloff\":10,\"intensity\":2}",
        "{\"type\":\"sphere\",\"center\":[0.5,0.2,-0.1],\"radius\":0.3,\"radiance\":1}",
        "{\"type\":\"directional\",\"direction\":[0.3,-1,0.2],\"irradiance\":2,\"radius\":0.6,\"center\":[1,0,0.2]}"};
    const vec3 centres[4] = {v3(0.5, 1.5, 0.4), v3(0.6, 0.2, 1.6), v3(0.5, -1.2, 0.5), v3(1.4, 0.0, 0.6)};
    const double radii[4] = {0.4, 0.5, 0.3, 0.35};
    for (int t = 0; t < 4; t++) {
        rd_scene *s = em_scene(lights[t]);
        const rd_light *l = &s->lights[0];
        rd_emission_aim aim = {1, centres[t], radii[t], 0.5};
        vec3 axis = v3_norm(v3_sub(aim.centre, l->pos)), at = l->beam_center;
        if (l->kind == RD_LIGHT_DIRECTIONAL) axis = l->dir;
        static em_flux own, aimed, wrong;
        memset(&own, 0, sizeof own), memset(&aimed, 0, sizeof aimed), memset(&wrong, 0, sizeof wrong);
        pcg32 r1 = pcg32_seed(21 + t, 0, 1), r2 = pcg32_seed(31 + t, 0, 1);
        for (int i = 0; i < EM_OWN; i++) {
            ray3 r;
            vec3 pw;
            if (rd_light_sample_emission(s, l, NULL, &r1, &r, &pw)) em_flux_add(&own, l, r, pw, axis, at, 0.6, &aim);
        }
        for (int i = 0; i < EM_N; i++) {
            ray3 r;
            vec3 pw;
            if (!rd_light_sample_emission(s, l, &aim, &r2, &r, &pw)) continue;
            em_flux_add(&aimed, l, r, pw, axis, at, 0.6, &aim);
            /* the control's weight: the light's own density alone */
            vec3 w = l->value;
            if (l->kind == RD_LIGHT_POINT) w = v3_scale(w, 4.0 * M_PI);
            else if (l->kind == RD_LIGHT_SPOT)
                w = v3_scale(w, rd_spot_falloff(l, v3_dot(r.d, l->dir)) * 2.0 * M_PI * (1.0 - l->cos_outer));
            else if (l->kind == RD_LIGHT_SPHERE) w = v3_scale(w, M_PI * 4.0 * M_PI * l->radius * l->radius);
            else w = v3_scale(w, M_PI * l->radius * l->radius);
            em_flux_add(&wrong, l, r, w, axis, at, 0.6, &aim);
        }
        int dof, dofw;
        double c = em_flux_chi2(&aimed, EM_N, &own, EM_OWN, &dof), cw = em_flux_chi2(&wrong, EM_N, &own, EM_OWN, &dofw);
        double crit = rt_chi2_quantile(dof, 3.719), critw = rt_chi2_quantile(dofw, 3.719);
        cr_expect(c < crit, "light %d: aimed flux per cell differs: chi2 %.1f >= %.1f (%d cells)", t, c, crit, dof);
        cr_expect(cw > critw, "light %d: control (no mixture weight) passed: %.1f <= %.1f", t, cw, critw);
        /* The point light keeps every aimed photon, so a share 0.5 + 0.5 f of them meets the
         * sphere, f the share without (binomial, 5 sigma); the others drop the aimed photons
         * they do not emit (outside the spot's cone or the beam's disc, into the sphere light),
         * so they only gain. */
        double fa = aimed.inside / EM_N, fo = own.inside / EM_OWN, want = 0.5 + 0.5 * fo;
        if (t == 0)
            cr_expect(fabs(fa - want) < 5.0 * sqrt(want * (1.0 - want) / EM_N), "point light: %.4f of the photons meet the sphere, expected %.4f", fa, want);
        else
            cr_expect(fa > fo + 0.05, "light %d: %.3f of the aimed photons meet the sphere (%.3f without)", t, fa, fo);
        cr_log_info("aimed light %d: chi2 %.1f (crit %.1f, %d cells), control %.1f; %.3f meet the sphere, %.3f without",
                    t, c, crit, dof, cw, fa, fo);
        rd_scene_free(s);
    }
}

Test(photons, aimed_map_keeps_the_power_below_the_lens_in_more_photons, .timeout = 120)
{
    /* The whole trace with the aim (rd_trace_photons, photons.aim): a glass ball in fog with a
     * small sphere light above it. The power stored in a box below the ball, where the ball
     * focuses the light, and in a box beside it, each the mean of K = 16 traces of 40000 photons
     * (fixed seeds) with photons.aim 0 and 0.5: the two means must agree within 5 standard
     * errors of their difference (from the traces' spread), and the aimed maps must hold more
     * photons below the ball (measured: 38189 against 7250). This checks the trace's use of the
     * sampler; the sampler's own weights are the test above's, which is the sharper: a mixture
     * density planted 10% low in its aimed part moves the power below the ball by 8% here, z
     * 4.6, under the bound. */
    rd_scene *s = rt_glass_ball_in_fog("aim_map.json", "{\"type\":\"sphere\",\"center\":[0,0.8,0],\"radius\":0.05,\"radiance\":400}", 4);
    const vec3 lo[2] = {v3(-0.15, -0.9, -0.15), v3(0.5, -0.9, -0.2)}, hi[2] = {v3(0.15, -0.35, 0.15), v3(0.9, -0.35, 0.2)};
    enum { K = 16 };
    double pw[2][2][K], n_below[2] = {0, 0};
    for (int a = 0; a < 2; a++) {
        s->photons.aim = a ? 0.5 : 0.0;
        for (int k = 0; k < K; k++) {
            rd_photon_stats st;
            pm_map *map = trace(s, 40000, 1, 64, 300 + k, 2, &st);
            double o[3];
            pm_map_origin(map, o);
            const pm_photon *ph = pm_map_photons(map);
            pw[a][0][k] = pw[a][1][k] = 0.0;
            for (size_t i = 0; i < pm_map_photon_count(map); i++) {
                vec3 x = v3(ph[i].pos[0] + o[0], ph[i].pos[1] + o[1], ph[i].pos[2] + o[2]);
                for (int b = 0; b < 2; b++)
                    if (x.x >= lo[b].x && x.x <= hi[b].x && x.y >= lo[b].y && x.y <= hi[b].y && x.z >= lo[b].z && x.z <= hi[b].z) {
                        pw[a][b][k] += ph[i].power[0];
                        if (b == 0) n_below[a] += 1;
                    }
            }
            pm_map_free(map);
        }
    }
    for (int b = 0; b < 2; b++) {
        double m[2], v[2];
        for (int a = 0; a < 2; a++) {
            m[a] = v[a] = 0.0;
            for (int k = 0; k < K; k++) m[a] += pw[a][b][k] / K;
            for (int k = 0; k < K; k++) v[a] += (pw[a][b][k] - m[a]) * (pw[a][b][k] - m[a]) / (K - 1);
        }
        double z = (m[1] - m[0]) / sqrt((v[0] + v[1]) / K);
        cr_expect(fabs(z) < 5.0, "%s the ball: power %.4g aimed, %.4g not (z %.2f)", b ? "beside" : "below", m[1], m[0], z);
        cr_log_info("%s the ball: power %.4g aimed, %.4g not (z %.2f)", b ? "beside" : "below", m[1], m[0], z);
    }
    cr_expect(n_below[1] > 2.0 * n_below[0], "photons below the ball: %.0f aimed, %.0f not", n_below[1], n_below[0]);
    cr_log_info("photons below the ball: %.0f aimed, %.0f not", n_below[1], n_below[0]);
    rd_scene_free(s);
}

/* ---- Light that only L S+ paths carry (rd_hidden_light; compare, issue 21 item 6) ---------- */

Test(photons, hidden_light_is_what_leaves_a_delta_light_through_glass_first, .timeout = 60)
{
    char err[RD_ERRLEN];
    double share;
    /* A point light inside the ball: every photon meets the glass before any fog, so all of the
     * light scattered in the fog is on L S+ paths: the share is 1 (to rounding). */
    rd_scene *s = rt_glass_ball_in_fog("hidden_inside.json", "{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":1}", 4);
    cr_assert(rd_hidden_light(s, 20000, 1, &share, NULL, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(fabs(share - 1.0) < 1e-9, "point light inside the glass ball: share %.12f, expected 1", share);
    rd_scene_free(s);
    /* A sphere light there instead: paths can hit it, so nothing is hidden, but all of its light
     * in the fog is on L S+ paths, as above: the caustic share is 1. Whether a trace runs is
     * told by a count of 0, which the trace refuses: without *caustic there is none (no delta
     * light), with it there is. */
    double caustic;
    s = rt_glass_ball_in_fog("hidden_sphere.json", "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":0.05,\"radiance\":1}", 4);
    cr_assert(rd_hidden_light(s, 20000, 1, &share, &caustic, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(share == 0.0, "sphere light inside the ball: share %g, expected 0", share);
    cr_expect(fabs(caustic - 1.0) < 1e-9, "sphere light inside the ball: caustic share %.12f, expected 1", caustic);
    cr_expect(rd_hidden_light(s, 0, 1, &share, NULL, err, sizeof err) == RD_OK && share == 0.0,
              "a sphere light, no caustic asked: no trace");
    cr_expect(rd_hidden_light(s, 0, 1, &share, &caustic, err, sizeof err) != RD_OK, "caustic asked: a trace");
    rd_scene_free(s);
    /* With *caustic too, no trace without power or without glass. */
    s = rt_glass_ball_in_fog("caustic_dark.json", "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":0.05,\"radiance\":0}", 4);
    cr_expect(rd_hidden_light(s, 0, 1, &share, &caustic, err, sizeof err) == RD_OK && caustic == 0.0,
              "a sphere light of no power: no trace (%s)", err);
    rd_scene_free(s);
    const rd_override no_glass[] = {{"shapes", "[]"}};
    char sphere_path[512];
    snprintf(sphere_path, sizeof sphere_path, "%s/hidden_sphere.json", rt_tmpdir());
    cr_assert(rd_scene_load(&s, sphere_path, no_glass, 1, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(rd_hidden_light(s, 0, 1, &share, &caustic, err, sizeof err) == RD_OK && caustic == 0.0,
              "no glass: no trace (%s)", err);
    rd_scene_free(s);
    /* A point light in the fog 0.7 m from the ball's centre: the photons aimed at the ball
     * (its solid angle, (1 - cos 25.4 deg) / 2 = 0.048 of them) reach the glass first with
     * the transmittance of the 0.4-0.6 m before it (about 0.6): about 0.029 of the photons are
     * hidden, and if a hidden photon scatters about as much power in the fog as any other, so
     * is the share. It is asserted within a factor of two of that (measured: 0.0296; a flag
     * set at any specular event, or never, gives 0.064 or 0). */
    s = rt_glass_ball_in_fog("hidden_beside.json", "{\"type\":\"point\",\"position\":[0.7,0,0],\"intensity\":1}", 4);
    cr_assert(rd_hidden_light(s, 20000, 1, &share, &caustic, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(share > 0.0145 && share < 0.045, "point light beside the ball: share %g, expected about 0.029", share);
    cr_expect(caustic == share, "a delta light alone: caustic share %g, hidden %g, expected the same", caustic, share);
    rd_scene_free(s);
    /* A small sphere light in its place (radius 0.005): nothing hidden, and its caustic share is
     * the point light's (the same photons but for where on the sphere they start; within the
     * same bounds: a flag set at any specular event would give about 0.064, as above). Its L S+
     * light reaches the marchers only from photons, but the loader's defaults stay nee+paths:
     * docs/guided-marching.md, "Light through glass from a sphere light". */
    s = rt_glass_ball_in_fog("caustic_beside.json", "{\"type\":\"sphere\",\"center\":[0.7,0,0],\"radius\":0.005,\"radiance\":1}", 4);
    cr_assert(rd_hidden_light(s, 20000, 1, &share, &caustic, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(share == 0.0 && caustic > 0.0145 && caustic < 0.045,
              "small sphere light beside the ball: hidden %g (expected 0), caustic %g (expected about 0.029)", share, caustic);
    cr_expect(s->march.ls == RD_LS_NEE_PATHS && s->photons.progressive == 0, "a sphere light: the default nee+paths");
    rd_scene_free(s);
    /* A sphere light inside the ball and that point light beside it: the sphere light's photons
     * all meet the glass first but are seen (paths hit it), so only the point light's hidden
     * part counts, over more scattered light than before: below the point light's own share
     * above, 0.0296 (the sphere light adds 1/6 of the power; the hidden count's own noise here,
     * about 500 photons, is 4%). Measured 0.0245; counting the sphere light's photons too
     * gives 0.156. */
    s = rt_glass_ball_in_fog("hidden_both.json",
                             "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":0.05,\"radiance\":20},"
                             "{\"type\":\"point\",\"position\":[0.7,0,0],\"intensity\":1}", 4);
    cr_assert(rd_hidden_light(s, 20000, 1, &share, &caustic, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(share > 0.0 && share < 0.0296, "sphere light inside, point light beside: share %g", share);
    /* The caustic share counts the sphere light's photons too: its power is 0.136 of the two
     * (1.97 W against the point light's 12.57), so about 0.136 + 0.864 x 0.0296 = 0.161 if
     * each watt scatters as much in the fog (measured 0.156); a count of the delta light's
     * alone gives the hidden share, 0.0245. */
    cr_expect(caustic > 0.12 && caustic < 0.20, "sphere light inside, point light beside: caustic share %g, expected "
              "about 0.161", caustic);
    rd_scene_free(s);
    /* The marchers' default source on such a scene (load/load.c): nee+beams with progressive
     * passes where more than 0.1% of the light is hidden, each unless the scene names it; the
     * unbiased nee+paths elsewhere. */
    s = rt_glass_ball_in_fog("hidden_default.json", "{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":1}", 4);
    double direct;
    cr_assert(rd_hidden_light(s, RD_HIDDEN_PHOTONS, 1, &direct, NULL, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(s->march.ls == RD_LS_NEE_BEAMS && s->photons.progressive == 1 && rd_scene_hidden_light(s) == direct,
              "hidden light: march.ls %d, progressive %d, share at load %g, measured again %g", (int)s->march.ls,
              s->photons.progressive, rd_scene_hidden_light(s), direct);
    char path[512];
    snprintf(path, sizeof path, "%s/hidden_default.json", rt_tmpdir());
    rd_scene_free(s);
    const rd_override named[] = {{"march.ls", "nee+paths"}};
    cr_assert(rd_scene_load(&s, path, named, 1, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(s->march.ls == RD_LS_NEE_PATHS && s->photons.progressive == 0, "march.ls named: kept");
    rd_scene_free(s);
    const rd_override fixed_map[] = {{"photons.progressive", "false"}};
    cr_assert(rd_scene_load(&s, path, fixed_map, 1, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(s->march.ls == RD_LS_NEE_BEAMS && s->photons.progressive == 0, "progressive named false: kept");
    rd_scene_free(s);
    /* There the beams never mix with delta's tiles, which lack that light, even when the scene
     * asks for tiles by name (integrators/guided.c): no sample is delta's. On scenes/glass-fog
     * at 16x12 the pilot would give every tile to delta (dark and cheap) without that rule. */
    const rd_override tiles[] = {{"settings.select", "tiles"}, {"camera.resolution", "[16,12]"}};
    cr_assert(rd_scene_load(&s, "scenes/glass-fog.json", tiles, 2, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(s->settings.select == RD_SELECT_TILES);
    rd_render_result res = rt_render(s, "guided", 1, 7, NULL);
    cr_expect(res.stats.paths > 0 && res.stats.delta_samples == 0, "tiles by name: %llu of %llu samples delta's",
              (unsigned long long)res.stats.delta_samples, (unsigned long long)res.stats.paths);
    rd_render_result_free(&res);
    rd_scene_free(s);
    const rd_override dark[] = {{"lights[0].intensity", "0"}}; /* the share after the overrides */
    cr_assert(rd_scene_load(&s, path, dark, 1, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(s->march.ls == RD_LS_NEE_PATHS && rd_scene_hidden_light(s) == 0.0, "no power: nothing hidden");
    rd_scene_free(s);
    s = rt_glass_ball_in_fog("seen_default.json", "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":0.05,\"radiance\":1}", 4);
    cr_expect(s->march.ls == RD_LS_NEE_PATHS && s->photons.progressive == 0, "nothing hidden: the default nee+paths");
    rd_scene_free(s);
    /* A point light that emits nothing: no light to hide, and no trace (which would refuse a
     * scene whose lights emit nothing). */
    s = rt_glass_ball_in_fog("hidden_dark.json", "{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":0}", 4);
    cr_assert(rd_hidden_light(s, 20000, 1, &share, NULL, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(share == 0.0, "a light of no power: share %g", share);
    rd_scene_free(s);
}

/* Whether the records of `sub` are those of `all` with some left out, in the same order. */
static int is_subsequence(const void *sub, size_t n_sub, const void *all, size_t n_all, size_t rec)
{
    size_t j = 0;
    for (size_t i = 0; i < n_all && j < n_sub; i++)
        if (memcmp((const char *)all + i * rec, (const char *)sub + j * rec, rec) == 0) j++;
    return j == n_sub;
}

/* The power of a map's photons, summed in double. */
static void map_power(const pm_map *m, double out[3])
{
    const pm_photon *p = pm_map_photons(m);
    out[0] = out[1] = out[2] = 0.0;
    for (size_t i = 0; i < pm_map_photon_count(m); i++)
        for (int c = 0; c < 3; c++) out[c] += p[i].power[c];
}

/* rd_photon_opts.reachable (guided-unbiased's bake, RD_NEEDS_REACHABLE) leaves out exactly the
 * hidden light: the photons and segments on L S+ paths from a delta light. On one thread a
 * photon's records come in photon order, so the reachable map must be the full map with
 * records left out; all of them where all the light is hidden, none where none is. And with
 * store_direct every collision is stored, so the power the reachable map lacks must be the
 * trace's power_hidden, in the main map and in the indirect one alike (a hidden photon's
 * collisions all follow its first event, the glass, so all are indirect). Tolerance: each
 * stored power is a float, within a relative 2^-24 (6e-8) of the double that power_hidden
 * sums, so the two sums agree within 6e-8 relative; asserted within 1e-6. */
Test(photons, a_reachable_map_leaves_out_the_hidden_light_and_nothing_else, .timeout = 60)
{
    char err[RD_ERRLEN];
    rd_photon_stats st, st_r;
    rd_photon_opts o = {.count = 20000, .store_direct = 1, .segments = 1, .max_depth = 16, .seed = 5, .threads = 1};
    rd_photon_opts o_r = o;
    o_r.reachable = 1;
    const char *lights[3] = {"{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":1}",        /* all hidden */
                             "{\"type\":\"point\",\"position\":[0.7,0,0],\"intensity\":1}",      /* ~3% hidden */
                             "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":0.05,\"radiance\":1}"}; /* none */
    for (int k = 0; k < 3; k++) {
        char name[64];
        snprintf(name, sizeof name, "reachable_%d.json", k);
        rd_scene *s = rt_glass_ball_in_fog(name, lights[k], 4);
        pm_map *all = pm_map_new(), *r = pm_map_new(), *ind = pm_map_new(), *ind_r = pm_map_new();
        cr_assert(rd_trace_photons_split(s, &o, all, ind, &st, err, sizeof err) == RD_OK, "%s", err);
        cr_assert(rd_trace_photons_split(s, &o_r, r, ind_r, &st_r, err, sizeof err) == RD_OK, "%s", err);
        size_t na = pm_map_photon_count(all), nr = pm_map_photon_count(r);
        size_t sa = pm_map_segment_count(all), sr = pm_map_segment_count(r);
        /* the statistics count every photon either way */
        cr_expect(memcmp(st.power_hidden, st_r.power_hidden, sizeof st.power_hidden) == 0 &&
                  memcmp(st.power_scattered, st_r.power_scattered, sizeof st.power_scattered) == 0,
                  "light %d: the statistics changed", k);
        cr_assert(na > 1000 && sa > 1000, "light %d: %zu photons, %zu segments", k, na, sa);
        /* the power left out is the hidden power, in both maps */
        const pm_map *full[2] = {all, ind}, *kept[2] = {r, ind_r};
        for (int m = 0; m < 2; m++) {
            double pf[3], pk[3];
            map_power(full[m], pf);
            map_power(kept[m], pk);
            for (int c = 0; c < 3; c++)
                cr_expect(fabs((pf[c] - pk[c]) - st.power_hidden[c]) <= 1e-6 * st.power_hidden[c],
                          "light %d, %s map, channel %d: %.9g left out, %.9g hidden", k, m ? "indirect" : "main", c,
                          pf[c] - pk[c], st.power_hidden[c]);
        }
        cr_expect(is_subsequence(pm_map_photons(ind_r), pm_map_photon_count(ind_r), pm_map_photons(ind),
                                 pm_map_photon_count(ind), sizeof(pm_photon)),
                  "light %d: the kept indirect photons are not the full indirect map's", k);
        if (k == 0) {
            cr_expect(st.power_hidden[0] > 0.99 * st.power_scattered[0], "light 0: all hidden");
            /* The first flights, from the light to the glass, come before the photon is on an
             * L S+ path (and cross only the ball's vacuum): those segments stay, no others. */
            size_t from_light = 0;
            const pm_segment *seg = pm_map_segments(r);
            for (size_t i = 0; i < sr; i++)
                from_light += fabsf(seg[i].org[0]) + fabsf(seg[i].org[1]) + fabsf(seg[i].org[2]) < 1e-6f;
            cr_expect(nr == 0 && pm_map_photon_count(ind_r) == 0 && sr > 0 && from_light == sr && sr < sa,
                      "light 0, all hidden: %zu photons, %zu segments kept (%zu from the light), of %zu", nr, sr, from_light, sa);
        } else if (k == 1) {
            cr_expect(st.power_hidden[0] > 0.0 && nr < na && sr < sa, "light 1: %zu of %zu photons, %zu of %zu segments",
                      nr, na, sr, sa);
            cr_expect(is_subsequence(pm_map_photons(r), nr, pm_map_photons(all), na, sizeof(pm_photon)),
                      "light 1: the kept photons are not the full map's");
            cr_expect(is_subsequence(pm_map_segments(r), sr, pm_map_segments(all), sa, sizeof(pm_segment)),
                      "light 1: the kept segments are not the full map's");
        } else {
            cr_expect(st.power_hidden[0] == 0.0 && st.power_caustic[0] > 0.0, "light 2: seen, not hidden");
            cr_expect(nr == na && sr == sa && memcmp(pm_map_photons(r), pm_map_photons(all), na * sizeof(pm_photon)) == 0 &&
                          memcmp(pm_map_segments(r), pm_map_segments(all), sa * sizeof(pm_segment)) == 0,
                      "light 2, nothing hidden: the map changed");
        }
        pm_map_free(all);
        pm_map_free(r);
        pm_map_free(ind);
        pm_map_free(ind_r);
        rd_scene_free(s);
    }
}

/* guided-unbiased asks for that bake, and the bake cache keeps it apart from a full one. */
Test(photons, guided_unbiased_bakes_the_reachable_light_alone)
{
    rd_scene *s = rt_glass_ball_in_fog("reachable_needs.json", "{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":1}", 4);
    unsigned gu = rd_method_needs_for("guided-unbiased", s), g = rd_method_needs_for("guided", s);
    cr_expect(gu & RD_NEEDS_REACHABLE, "guided-unbiased needs %#x", gu);
    cr_expect(!(g & RD_NEEDS_REACHABLE), "guided needs %#x: its photon estimates need the hidden light", g);
    rd_bake_opts bo = {.seed = -1, .threads = 1};
    rd_bake_opts_for(&bo, gu);
    cr_expect(bo.reachable == 1);
    char err[RD_ERRLEN], dir[300];
    snprintf(dir, sizeof dir, "%s/reachable-cache", rt_tmpdir());
    rd_baked *b = NULL;
    int hit = -1;
    cr_assert(rd_bake_cached(s, &bo, dir, &b, &hit, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(hit == 0 && pm_map_photon_count(rd_baked_map(b)) == 0, "all hidden: %zu photons", pm_map_photon_count(rd_baked_map(b)));
    rd_baked_free(b);
    bo.reachable = 0;
    cr_assert(rd_bake_cached(s, &bo, dir, &b, &hit, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(hit == 0 && pm_map_photon_count(rd_baked_map(b)) > 0, "full bake: hit %d, %zu photons", hit,
              pm_map_photon_count(rd_baked_map(b)));
    rd_baked_free(b);
    rd_scene_free(s);
}
