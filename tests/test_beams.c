/* The beam radiance estimate (march.ls = nee+beams; renderer/integrators/beams.c and
 * march_beams.c)
 * against brute force:
 *  - rd_beams_cross finds every ball a segment crosses exactly once, with its chord, for balls
 *    in a map whose origin is far from the world's, segments that start, end or lie wholly inside
 *    a ball, and balls left out (radius 0); checked against the chord of every ball in double;
 *  - when more balls are crossed than it keeps, the kept one is a uniform pick of them (a
 *    chi-square test on 12 balls) and the weight is their count;
 *  - the balls of a map: about the share q = emitted / stored of the photons kept (binomial,
 *    4.5 standard deviations), weighted 1/q, and every ball of the fixed map finds r_1 in the
 *    cells (no query of its own) in a medium off the world's centre;
 *  - the estimate along a segment equals the point gather with the same balls integrated
 *    exactly: sum_k p dPhi_k / V_k int_chord T dt, the chord integral of T = exp(-sigma_t t) in
 *    closed form, over every photon of the map (no Embree, no picks). The estimator's mean over
 *    independent draws must lie within 4.5 standard errors of it (a false alarm per ray well
 *    under 1e-4);
 *  - the default `guided`, beams and all, gives `delta`'s image on a dense box where the beams
 *    take a third of the samples (the comparison's resolution checked with a 10% brighter light). */
#include "support/rd_test.h"

#include "bake/rd_photons.h"
#include "integrators/rd_beams.h"
#include "integrators/rd_march.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const double ORIGIN[3] = {10.0, -3.0, 2.0};

/* n photons in the unit cube about ORIGIN, radii in [0.02, 0.15], every 10th left out. */
static pm_map *random_map(int n, float *rad, pcg32 *rng)
{
    pm_map *m = pm_map_new();
    char err[256];
    cr_assert(pm_map_set_origin(m, ORIGIN, err, sizeof err) == PM_OK, "%s", err);
    pm_photon *ph = calloc((size_t)n, sizeof *ph);
    for (int i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) ph[i].pos[a] = (float)(pcg32_uniform(rng) - 0.5);
        ph[i].dir[2] = 1.0f;
        ph[i].power[0] = ph[i].power[1] = ph[i].power[2] = 1.0f;
        rad[i] = i % 10 == 9 ? 0.0f : (float)(0.02 + 0.13 * pcg32_uniform(rng));
    }
    cr_assert(pm_map_add_photons(m, ph, (size_t)n, err, sizeof err) == PM_OK, "%s", err);
    free(ph);
    return m;
}

/* The chord of ball (c, rad) on ray r clipped to [t0, t1]; 0 when it misses. */
static int chord(ray3 r, vec3 c, double rad, double t0, double t1, double *ta, double *tb)
{
    vec3 oc = v3_sub(c, r.o);
    double tc = v3_dot(oc, r.d), h2 = rad * rad - (v3_dot(oc, oc) - tc * tc);
    if (!(h2 > 0.0)) return 0;
    *ta = fmax(t0, tc - sqrt(h2));
    *tb = fmin(t1, tc + sqrt(h2));
    return *tb > *ta;
}

/* Every ball a segment crosses, once, with its chord, against brute force; on a map not built
 * (the balls in photon order) and on a built one (in the map's spatial order, as the renders
 * have them: rd_beams_build). */
static void cross_finds_every_ball_once_on(int built)
{
    enum { N = 3000, RAYS = 300, CAP = 4096 };
    pcg32 rng = pcg32_seed(1, 2, 3);
    static float rad[N];
    pm_map *m = random_map(N, rad, &rng);
    rd_beams *b;
    char err[256];
    if (built) {
        cr_assert(pm_map_build(m, err, sizeof err) == PM_OK, "%s", err);
        cr_assert(pm_map_spatial_order(m) != NULL);
    }
    cr_assert(rd_beams_new(&b, 2, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(rd_beams_build(b, m, rad, err, sizeof err) == RD_OK, "%s", err);
    const pm_photon *ph = pm_map_photons(m);
    static rd_beam_hit hits[CAP];
    static int seen[N];
    int total = 0;
    for (int k = 0; k < RAYS; k++) {
        /* From a random point of the box widened by 0.3 toward a random direction; every third
         * segment short (0.01-0.1 m), often inside one ball. */
        vec3 o = v3(ORIGIN[0] + 1.6 * (pcg32_uniform(&rng) - 0.5), ORIGIN[1] + 1.6 * (pcg32_uniform(&rng) - 0.5),
                    ORIGIN[2] + 1.6 * (pcg32_uniform(&rng) - 0.5));
        double z = 2.0 * pcg32_uniform(&rng) - 1.0, phi = 2.0 * M_PI * pcg32_uniform(&rng);
        vec3 d = v3(sqrt(1.0 - z * z) * cos(phi), sqrt(1.0 - z * z) * sin(phi), z);
        ray3 r = {o, d};
        double t0 = 0.5 * pcg32_uniform(&rng);
        double t1 = t0 + (k % 3 == 0 ? 0.01 + 0.09 * pcg32_uniform(&rng) : 2.0 * pcg32_uniform(&rng));
        double w;
        int n = rd_beams_cross(b, r, t0, t1, hits, CAP, &rng, &w);
        cr_assert(n < CAP && w == 1.0, "ray %d: %d hits, weight %g", k, n, w);
        memset(seen, 0, sizeof seen);
        for (int i = 0; i < n; i++) {
            int id = hits[i].idx;
            cr_assert(id >= 0 && id < N && rad[id] > 0.0f, "ray %d: hit of ball %d, which was left out", k, id);
            cr_assert(seen[id]++ == 0, "ray %d: ball %d reported twice", k, id);
        }
        for (int id = 0; id < N; id++) {
            vec3 c = v3(ORIGIN[0] + ph[id].pos[0], ORIGIN[1] + ph[id].pos[1], ORIGIN[2] + ph[id].pos[2]);
            double ta, tb;
            int want = rad[id] > 0.0f && chord(r, c, rad[id], t0, t1, &ta, &tb);
            /* Grazing chords (under 1e-4 m) may go either way in float. */
            if (want && tb - ta < 1e-4) continue;
            if (!want) {
                if (seen[id]) {
                    for (int i = 0; i < n; i++)
                        if (hits[i].idx == id)
                            cr_assert(hits[i].tb - hits[i].ta < 1e-4, "ray %d: ball %d reported, chord %g, but the segment misses it",
                                      k, id, hits[i].tb - hits[i].ta);
                }
                continue;
            }
            cr_assert(seen[id], "ray %d: ball %d (chord %g m) missed", k, id, tb - ta);
            for (int i = 0; i < n; i++)
                if (hits[i].idx == id)
                    cr_assert(fabs(hits[i].ta - ta) < 1e-4 && fabs(hits[i].tb - tb) < 1e-4,
                              "ray %d: ball %d chord [%g, %g], brute force [%g, %g]", k, id, hits[i].ta, hits[i].tb, ta, tb);
            total++;
        }
    }
    cr_assert(total > 2 * RAYS, "too few crossings to test: %d", total);
    rd_beams_free(b);
    pm_map_free(m);
}

Test(beams, cross_finds_every_ball_once)
{
    cross_finds_every_ball_once_on(0);
    cross_finds_every_ball_once_on(1);
}

/* Twelve balls on the x axis; a segment through all of them keeps one: each with probability
 * 1/12. Pearson's chi-square with 11 degrees of freedom against its 1 - 1e-5 quantile. */
Test(beams, reservoir_keeps_a_uniform_pick)
{
    enum { M = 12, DRAWS = 60000 };
    pm_map *m = pm_map_new();
    char err[256];
    pm_photon ph[M] = {0};
    float rad[M];
    for (int i = 0; i < M; i++) {
        ph[i].pos[0] = (float)(0.1 * i);
        ph[i].dir[2] = 1.0f;
        rad[i] = 0.04f;
    }
    cr_assert(pm_map_add_photons(m, ph, M, err, sizeof err) == PM_OK, "%s", err);
    rd_beams *b;
    cr_assert(rd_beams_new(&b, 2, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(rd_beams_build(b, m, rad, err, sizeof err) == RD_OK, "%s", err);
    ray3 r = {v3(-1, 0.01, 0), v3(1, 0, 0)};
    long count[M] = {0};
    pcg32 rng = pcg32_seed(7, 8, 9);
    for (int k = 0; k < DRAWS; k++) {
        rd_beam_hit h;
        double w;
        int n = rd_beams_cross(b, r, 0.0, 3.0, &h, 1, &rng, &w);
        cr_assert(n == 1 && w == M, "kept %d of %d, weight %g", n, M, w);
        count[h.idx]++;
    }
    double chi2 = 0.0, e = (double)DRAWS / M;
    for (int i = 0; i < M; i++) chi2 += (count[i] - e) * (count[i] - e) / e;
    double q = rt_chi2_quantile(M - 1, 4.265); /* z of 1 - 1e-5 */
    cr_assert(chi2 < q, "chi-square %g >= %g: the kept ball is not a uniform pick", chi2, q);
    rd_beams_free(b);
    pm_map_free(m);
}

#define SIGMA_T 1.5
/* The medium's box is centred at (3, -2, 1), off the world's origin (the map's origin is its
 * centre); every point below is given relative to that centre. */
static const double C[3] = {3.0, -2.0, 1.0};
static const char *scene_json(void)
{
    return "{\"camera\":{\"position\":[3,-2,5],\"look_at\":[3,-2,1],\"fov\":30,\"resolution\":[8,8]},"
           "\"media\":[{\"bounds\":{\"min\":[2,-3,0],\"max\":[4,-1,2]},"
           "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1.5,\"albedo\":0.9,\"g\":0.4}],"
           "\"lights\":[{\"type\":\"point\",\"position\":[3.3,-1.8,1.1],\"intensity\":[3,2,1]}],"
           "\"photons\":{\"count\":3000,\"seed\":5},\"guide\":{\"k\":16},"
           "\"march\":{\"ls\":\"nee+beams\"},\"settings\":{\"method\":\"uniform\"}}";
}

/* scene_json's medium made dense (sigma_t 6, albedo 0.97): a photon stores several collisions,
 * the indirect map about 12 for each photon emitted. */
static const char *dense_json(void)
{
    return "{\"camera\":{\"position\":[3,-2,5],\"look_at\":[3,-2,1],\"fov\":30,\"resolution\":[8,8]},"
           "\"media\":[{\"bounds\":{\"min\":[2,-3,0],\"max\":[4,-1,2]},"
           "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":6,\"albedo\":0.97,\"g\":0.4}],"
           "\"lights\":[{\"type\":\"point\",\"position\":[3.3,-1.8,1.1],\"intensity\":[3,2,1]}],"
           "\"photons\":{\"count\":3000,\"seed\":5},\"guide\":{\"k\":16},"
           "\"march\":{\"ls\":\"nee+beams\"},\"settings\":{\"method\":\"uniform\"}}";
}

/* The share of the ball of radius r about x that lies inside the box [lo, hi] (empty space all
 * round), computed here on its own: per axis the unit ball's volume between the faces,
 * G(s) = 1/2 + 3 s / 4 - s^3 / 4 at the clamped distances, the axes multiplied (the form
 * rd_march_support_share documents; the test of that form against the ball's volume is below). */
static double box_share(const double x[3], double r, const double lo[3], const double hi[3])
{
    double share = 1.0;
    for (int a = 0; a < 3; a++) {
        double b = fmin(1.0, (hi[a] - x[a]) / r), c = fmin(1.0, (x[a] - lo[a]) / r);
        share *= (0.75 * b - 0.25 * b * b * b) + (0.75 * c - 0.25 * c * c * c);
    }
    return share;
}

/* Scene s's fixed photon maps baked (*bk) and `uniform` prepared on them (*ctx): the beams'
 * balls built, their radii in the march state. */
static void prepare_uniform(rd_scene *s, rd_baked **bk, rd_render_ctx *ctx)
{
    rd_bake_opts bo = {0};
    bo.seed = -1;
    bo.threads = 2;
    rd_bake_opts_for(&bo, RD_NEEDS_PHOTONS | RD_NEEDS_INDIRECT);
    char err[RD_ERRLEN];
    cr_assert(rd_bake(s, &bo, bk, err, sizeof err) == RD_OK, "%s", err);
    *ctx = (rd_render_ctx){.scene = s, .method = rd_method_find("uniform"), .threads = 2, .radius_scale = 1.0};
    ctx->photons = rd_baked_map(*bk);
    ctx->photons_indirect = rd_baked_indirect_map(*bk);
    cr_assert(rd_march_prepare(ctx, err, sizeof err) == RD_OK, "%s", err);
}

Test(beams, estimate_equals_the_exact_point_gather, .timeout = 300)
{
    rd_scene *s = rt_scene("beams.json", scene_json());
    rd_baked *bk;
    rd_render_ctx ctx;
    prepare_uniform(s, &bk, &ctx);
    const march_state *st = ctx.state;
    const pm_map *map = ctx.photons_indirect;
    size_t np = pm_map_photon_count(map);
    cr_assert(np > 1000, "too few indirect photons: %zu", np);
    march_scratch ms;
    void *buf = aligned_alloc(16, (rd_march_scratch_layout(st, &ms, NULL) + 15) / 16 * 16);
    rd_march_scratch_layout(st, &ms, buf);
    const pm_photon *ph = pm_map_photons(map);
    double org[3];
    pm_map_origin(map, org);
    /* The balls: a share q = 3000 emitted / stored of the photons, each weighted 1/q; and in
     * the fixed map every ball is a photon of the map that sets r_1, so each finds its cell. */
    size_t kept = 0;
    for (size_t i = 0; i < np; i++) kept += st->beam_radius[i] > 0.0f;
    double q = np > 3000 ? 3000.0 / np : 1.0;
    cr_expect(fabs(st->beam_weight - 1.0 / q) < 1e-12, "balls weighted %g, not 1/q = %g", st->beam_weight, 1.0 / q);
    cr_expect(fabs(kept - q * np) <= 4.5 * sqrt(np * q * (1.0 - q)) + 0.5,
              "%zu balls kept of %zu photons, expected %.1f", kept, np, q * np);
    cr_expect(st->beam_r1_queries == 0, "%zu balls of the fixed map missed their cells", st->beam_r1_queries);
    const vec3 from[3] = {v3(0, 0, 4), v3(0.2, -0.3, 4), v3(3, 1, -2)};
    const vec3 to[3] = {v3(0, 0, 0), v3(0.3, 0.2, 0.1), v3(-0.5, 0, 0.4)};
    vec3 cw_ = v3(C[0], C[1], C[2]);
    for (int k = 0; k < 3; k++) {
        ray3 r = {v3_add(from[k], cw_), v3_norm(v3_sub(to[k], from[k]))};
        double t0, t1;
        cr_assert(rd_box_intersect(s->bmin, s->bmax, r, 0.0, INFINITY, &t0, &t1) && t1 > t0);
        /* The exact gather: every ball, its chord's integral of exp(-sigma_t (t - t0)); and the
         * same with every ball of half the volume, radius r_k / sqrt 2, which the estimate
         * less its gap must equal (rd_march_beam_estimate's gap). */
        double want = 0.0, want_half = 0.0;
        vec3 w = v3_scale(r.d, -1.0);
        for (int hv = 0; hv < 2; hv++) {
            for (size_t i = 0; i < np; i++) {
                double rk = st->beam_radius[i] * (hv ? sqrt(0.5) : 1.0), ta, tb;
                vec3 c = v3(org[0] + ph[i].pos[0], org[1] + ph[i].pos[1], org[2] + ph[i].pos[2]);
                if (!(rk > 0.0) || !chord(r, c, rk, t0, t1, &ta, &tb)) continue;
                double cw = ph[i].dir[0] * w.x + ph[i].dir[1] * w.y + ph[i].dir[2] * w.z;
                /* The chord's integral of exp(-sigma_t (t - t0)) / share(x(t)): near the box's
                 * faces the estimate divides by the ball's share inside (march_share.c), so the
                 * integral is taken by the midpoint rule, 256 points a chord. */
                double Tint = 0.0;
                const double lo[3] = {C[0] - 1, C[1] - 1, C[2] - 1}, hi[3] = {C[0] + 1, C[1] + 1, C[2] + 1};
                for (int qi = 0; qi < 256; qi++) {
                    double t = ta + (qi + 0.5) / 256.0 * (tb - ta);
                    vec3 xt = ray_at(r, t);
                    const double xa[3] = {xt.x, xt.y, xt.z};
                    Tint += exp(-SIGMA_T * (t - t0)) / box_share(xa, rk, lo, hi) * (tb - ta) / 256.0;
                }
                double add = ph[i].power[0] * rd_hg_eval(0.4, cw) / (4.0 / 3.0 * M_PI * rk * rk * rk) * Tint;
                if (hv) want_half += add;
                else want += add;
            }
        }
        want *= st->beam_weight, want_half *= st->beam_weight;
        cr_assert(want > 0.0 && want_half > 0.0, "ray %d crosses no ball", k);
        enum { DRAWS = 20000 };
        double sum = 0.0, sum2 = 0.0, hsum = 0.0, hsum2 = 0.0;
        rd_track_counters c = {0};
        int crossed;
        for (int j = 0; j < DRAWS; j++) {
            pcg32 rng = pcg32_seed(11, (uint64_t)j, (uint64_t)k);
            vec3 gap;
            double v = rd_march_beam_estimate(&ctx, &ms, r, s->fill_medium, t0, t1, &rng, &c, &crossed, &gap).x;
            sum += v, sum2 += v * v;
            hsum += v - gap.x, hsum2 += (v - gap.x) * (v - gap.x);
        }
        /* Both within 4.5 standard errors of their draws' means (fixed seeds). */
        double mean = sum / DRAWS, se = sqrt(fmax(0.0, sum2 / DRAWS - mean * mean) / DRAWS);
        double hmean = hsum / DRAWS, hse = sqrt(fmax(0.0, hsum2 / DRAWS - hmean * hmean) / DRAWS);
        cr_log_info("beams: ray %d: estimate %.6g +- %.2g, exact gather %.6g; half-volume balls %.6g +- %.2g, exact %.6g",
                    k, mean, se, want, hmean, hse, want_half);
        cr_expect(fabs(mean - want) < 4.5 * se + 1e-9 * want,
                  "ray %d: the beam estimate %.6g +- %.2g is not the exact gather %.6g", k, mean, se, want);
        cr_expect(fabs(hmean - want_half) < 4.5 * hse + 1e-9 * want_half,
                  "ray %d: the estimate less its gap %.6g +- %.2g is not the exact gather of the half-volume balls %.6g",
                  k, hmean, hse, want_half);
    }
    free(buf);
    rd_march_release(&ctx);
    rd_baked_free(bk);
    rd_scene_free(s);
}

/* rd_march_support_share against the ball's volume inside the box, counted by Monte Carlo:
 * M points uniform in the unit ball (fixed seed), the share inside p with standard error
 * sqrt(p (1 - p) / M); where the ball is cut on one axis only, or x lies on every face that
 * cuts it (a face, an edge, a corner), the product of the axes' shares is exact and must agree
 * within 4.5 standard errors. Cut on two axes off the edge, or on three off the corner, the
 * product is an approximation that reads the share high, never low: by up to 1.4% near an edge
 * and 4.4% near a corner (both at 0.4 r from each face; numerical integration, 8e6 points), so
 * those points are held to 1.5% and 4.5% above the count. A face that opens onto another
 * medium counts its density. */
Test(beams, support_share_is_the_ball_s_volume_inside_the_box)
{
    rd_scene *s = rt_scene("beams.json", scene_json());
    const rd_medium *m = &s->media[0];
    enum { M = 400000 };
    double (*u)[3] = malloc(sizeof(double[M][3]));
    cr_assert(u != NULL);
    pcg32 rng = pcg32_seed(3, 4, 5);
    for (int i = 0; i < M; i++) {
        do {
            for (int a = 0; a < 3; a++) u[i][a] = 2.0 * pcg32_uniform(&rng) - 1.0;
        } while (u[i][0] * u[i][0] + u[i][1] * u[i][1] + u[i][2] * u[i][2] > 1.0);
    }
    const double r = 0.2;
    /* x relative to the box's centre C (half-width 1): at depth h below the +z face, on the
     * +x/+z edge, at the corner, off the edge by 0.4 r and r/5 each way, off the corner by
     * 0.4 r, and deep inside. exact: 1, or the bound above the count (1.5%, 4.5%). */
    const struct { double x[3]; double exact; } at[] = {
        {{0.0, 0.0, 1.0}, 1},          {{0.0, 0.0, 1.0 - 0.3 * r}, 1}, {{0.3, -0.2, 1.0 - 0.7 * r}, 1},
        {{1.0, 0.0, 1.0}, 1},          {{1.0, -1.0, 1.0}, 1},          {{1.0 - 0.4 * r, 0.0, 1.0 - 0.4 * r}, 1.015},
        {{1.0 - 0.2 * r, 0.1, 1.0 - 0.2 * r}, 1.015}, {{1.0 - 0.4 * r, -1.0 + 0.4 * r, 1.0 - 0.4 * r}, 1.045},
        {{0.0, 0.0, 0.0}, 1},
    };
    for (size_t k = 0; k < sizeof at / sizeof at[0]; k++) {
        vec3 x = v3(C[0] + at[k].x[0], C[1] + at[k].x[1], C[2] + at[k].x[2]);
        long in = 0;
        for (int i = 0; i < M; i++) {
            vec3 y = v3(x.x + r * u[i][0], x.y + r * u[i][1], x.z + r * u[i][2]);
            in += y.x >= m->bmin.x && y.x <= m->bmax.x && y.y >= m->bmin.y && y.y <= m->bmax.y &&
                  y.z >= m->bmin.z && y.z <= m->bmax.z;
        }
        double p = (double)in / M, se = sqrt(p * (1.0 - p) / M) + 1e-12;
        double got = rd_march_support_share(s, s->fill_medium, m, x, r);
        cr_log_info("support share at point %zu: %.5f, the ball's volume inside %.5f +- %.5f", k, got, p, se);
        if (at[k].exact == 1)
            cr_expect(fabs(got - p) < 4.5 * se, "point %zu: share %.5f, the ball's volume inside %.5f +- %.5f", k, got, p, se);
        else
            cr_expect(got > p - 4.5 * se && got < at[k].exact * p + 4.5 * se,
                      "point %zu (off an edge or corner): share %.5f, the ball's volume inside %.5f +- %.5f", k, got, p, se);
    }
    free(u);
    rd_scene_free(s);
    /* Two boxes sharing the face z = 0, sigma_t 1 below and 4 above: the part of the ball past
     * that face counts the density there relative to x's (the photons there are 4x or 1/4x as
     * dense), G(h / r) + w (1 - G(h / r)) at h = r / 4 from it, w = 4 below and 1/4 above; the
     * outer face z = 1 of the upper box opens onto empty space (w = 0). */
    s = rt_scene("two-boxes.json",
                 "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"fov\":30,\"resolution\":[8,8]},"
                 "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,0]},\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1},"
                 "{\"bounds\":{\"min\":[-1,-1,0],\"max\":[1,1,1]},\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":4}],"
                 "\"lights\":[{\"type\":\"point\",\"position\":[0,0,3],\"intensity\":1}]}");
    const double G = 0.5 + 0.75 * 0.25 - 0.25 * 0.25 * 0.25 * 0.25; /* G(1/4) */
    const struct { vec3 x; double want; } face[] = {
        {{0, 0, -0.05}, G + 4.0 * (1.0 - G)}, {{0, 0, 0.05}, G + 0.25 * (1.0 - G)}, {{0, 0, 0.95}, G}};
    for (int k = 0; k < 3; k++) {
        const rd_medium *mk = rd_scene_medium_at(s, s->fill_medium, face[k].x);
        cr_assert(mk != NULL);
        double got = rd_march_support_share(s, s->fill_medium, mk, face[k].x, r);
        cr_expect(fabs(got - face[k].want) < 1e-12, "two boxes, point %d: share %.6f, want %.6f", k, got, face[k].want);
    }
    rd_scene_free(s);
}

/* The beams' passes after the first (rd_march_pass_maps: RD_PASS_NO_INDEX): rd_bake_photon_pass
 * puts the pass's indirect photons in spatial order and builds no kd-tree, so the map answers no
 * k-NN query and gives the order the built map of the same pass gives (the same photons: the
 * pass's seed). Pass 1 is built whatever the flag says (render.c strips it): its map serves the
 * radii's k-NN, which a render whose pass 1 were only ordered would find nothing in. */
Test(beams, later_passes_are_ordered_not_indexed)
{
    rd_scene *s = rt_scene("beams.json", scene_json());
    cr_assert(rd_march_pass_maps(s) == 0u, "one fixed map (photons.progressive false): no pass");
    s->photons.progressive = 1;
    cr_assert(rd_march_pass_maps(s) == (RD_NEEDS_INDIRECT | RD_PASS_NO_INDEX | RD_PASS_THIN));
    char err[RD_ERRLEN];
    rd_baked *ordered = NULL, *built = NULL;
    cr_assert(rd_bake_photon_pass(s, rd_march_pass_maps(s), 2, 7, 1.0, 1, NULL, NULL, &ordered, err, sizeof err) == RD_OK,
              "%s", err);
    cr_assert(rd_bake_photon_pass(s, RD_NEEDS_INDIRECT, 2, 7, 1.0, 1, NULL, NULL, &built, err, sizeof err) == RD_OK, "%s", err);
    const pm_map *a = rd_baked_indirect_map(ordered), *b = rd_baked_indirect_map(built);
    size_t n = pm_map_photon_count(a);
    cr_assert(n > 100 && n == pm_map_photon_count(b), "%zu and %zu photons", n, pm_map_photon_count(b));
    const int *oa = pm_map_spatial_order(a), *ob = pm_map_spatial_order(b);
    cr_assert(oa != NULL && ob != NULL);
    cr_expect(memcmp(oa, ob, n * sizeof *oa) == 0, "the ordered pass's order differs from the built one's");
    const double x[3] = {3.0, -2.0, 1.0};
    int idx[4];
    float d2[4];
    cr_expect(pm_map_knn(a, x, 4, idx, d2) == -1, "the ordered pass answered a k-NN query");
    cr_expect(pm_map_knn(b, x, 4, idx, d2) == 4);
    rd_baked_free(ordered);
    rd_baked_free(built);
    rd_scene_free(s);
}

/* A thinned pass (RD_PASS_THIN; rd_photon_opts.keep): the same photons' paths, each collision
 * stored with probability q and its power divided by q. So the thinned map is a subsequence of
 * the pass's whole map (the same seed: positions and directions to the bit, power x 1/q), it
 * holds about q of its collisions, and its total power estimates the whole map's without bias.
 * The count is binomial, sd sqrt(n q (1 - q)); the power's difference has variance
 * sum p_i^2 (1 - q) / q over the whole map's photons: both within 5 sigma (fixed seeds). */
Test(beams, a_thinned_pass_keeps_a_share_of_the_same_collisions)
{
    rd_scene *s = rt_scene("beams.json", scene_json());
    s->photons.count = 20000;
    char err[RD_ERRLEN];
    const double q = 0.3;
    rd_baked *whole = NULL, *thin = NULL;
    cr_assert(rd_bake_photon_pass(s, RD_NEEDS_INDIRECT, 2, 7, 1.0, 1, NULL, NULL, &whole, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(rd_bake_photon_pass(s, RD_NEEDS_INDIRECT | RD_PASS_NO_INDEX, 2, 7, q, 2, NULL, NULL, &thin, err, sizeof err) == RD_OK,
              "%s", err);
    const pm_map *a = rd_baked_indirect_map(whole), *b = rd_baked_indirect_map(thin);
    size_t na = pm_map_photon_count(a), nb = pm_map_photon_count(b);
    cr_assert(na > 20000, "the scene stores %zu indirect collisions for 20000 photons", na);
    const pm_photon *pa = pm_map_photons(a), *pb = pm_map_photons(b);
    size_t j = 0, unmatched = 0;
    double sum_a = 0.0, sum_b = 0.0, var = 0.0;
    for (size_t i = 0; i < na; i++) {
        double p = pa[i].power[0] + pa[i].power[1] + pa[i].power[2];
        sum_a += p;
        var += p * p * (1.0 - q) / q;
    }
    for (size_t i = 0; i < nb; i++) {
        while (j < na && memcmp(pa[j].pos, pb[i].pos, sizeof pa[j].pos) != 0) j++;
        if (j == na || memcmp(pa[j].dir, pb[i].dir, sizeof pa[j].dir) != 0) {
            unmatched++;
            j = 0;
            continue;
        }
        for (int c = 0; c < 3; c++)
            cr_expect(fabs(pb[i].power[c] - pa[j].power[c] / q) <= 1e-6 * fabs(pa[j].power[c] / q) + 1e-30,
                      "photon %zu, channel %d: power %g, want %g / %g", i, c, pb[i].power[c], pa[j].power[c], q);
        sum_b += pb[i].power[0] + pb[i].power[1] + pb[i].power[2];
        j++;
    }
    cr_expect(unmatched == 0, "%zu of the thinned pass's %zu photons are not in the whole pass, in order", unmatched, nb);
    double sd_n = sqrt(na * q * (1.0 - q));
    cr_expect(fabs(nb - q * na) < 5.0 * sd_n, "kept %zu of %zu, want %.0f +- 5 x %.1f", nb, na, q * na, sd_n);
    cr_expect(fabs(sum_b - sum_a) < 5.0 * sqrt(var), "power %.6g thinned, %.6g whole (5 sd %.3g)", sum_b, sum_a,
              5.0 * sqrt(var));
    rd_baked_free(whole);
    rd_baked_free(thin);
    rd_scene_free(s);
}

/* A render whose beams read progressive passes (march.ls nee+beams, photons.progressive) thins
 * the passes after the first by pass 1's own counts: the report's keep is pass 1's emitted over
 * its stored indirect photons (the same pass baked here, the render's seed), the last pass
 * stored a small share of what pass 1 stored, and the image is finite. (That the thinning keeps the estimate unbiased is the test above.) */
Test(beams, a_render_thins_its_later_passes_by_pass_one_s_counts, .timeout = 300)
{
    rd_scene *s = rt_scene("beams-dense.json", dense_json());
    s->photons.progressive = 1;
    char err[RD_ERRLEN];
    rd_baked *first = NULL;
    cr_assert(rd_bake_photon_pass(s, RD_NEEDS_INDIRECT, 1, 3, 1.0, 2, NULL, NULL, &first, err, sizeof err) == RD_OK, "%s", err);
    const rd_bake_stats *b1 = rd_baked_stats(first);
    cr_assert(b1->indexed > b1->emitted, "pass 1 stores %zu for %zu emitted: nothing to thin", b1->indexed, b1->emitted);
    double want = (double)b1->emitted / (double)b1->indexed;
    rd_render_opts o = {.method = "uniform", .spp = 3, .seed = 3, .threads = 2};
    rd_render_result r;
    cr_assert(rd_render(s, &o, &r, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(r.stats.photon_passes == 3, "%d passes", r.stats.photon_passes);
    cr_expect(r.stats.photon_keep == want, "keep %.17g, want %.17g", r.stats.photon_keep, want);
    /* The tracer thinned (not only the report): the last pass stored about `emitted` photons
     * where pass 1 stored about 12 x as many (keep about 0.08); half of pass 1's is far past both. */
    cr_expect(r.stats.photons_stored < b1->indexed / 2, "the last pass stored %zu photons, pass 1 %zu",
              r.stats.photons_stored, b1->indexed);
    for (int i = 0; i < 3 * r.image.w * r.image.h; i++)
        cr_assert(isfinite(r.image.rgb[i]), "pixel value %d not finite", i);
    rd_render_result_free(&r);
    rd_baked_free(first);
    rd_scene_free(s);
}

/* The kernel holds k of the balls read (march_beams.c, rd_march_photons_changed): where the balls
 * are a share q_1 < 1 of pass 1's stored photons, the radii are r_1 q_1^(-1/3), so a ball holds
 * about k = guide.k other balls' centres, not k q_1. Counted here, over the balls whose ball lies inside
 * the medium (the photons' density falls off from the light, so the count is the k-NN bandwidth's
 * local-uniformity approximation, not an exact figure): the mean count within 25% of k, where
 * the radii unscaled would hold k q_1 (q_1 below 0.6 here). */
Test(beams, a_ball_holds_k_of_the_balls_read, .timeout = 300)
{
    rd_scene *s = rt_scene("beams-dense.json", dense_json());
    rd_baked *bk;
    rd_render_ctx ctx;
    prepare_uniform(s, &bk, &ctx);
    const march_state *st = ctx.state;
    const pm_map *map = ctx.photons_indirect;
    size_t np = pm_map_photon_count(map);
    double q1 = 3000.0 / (double)np;
    cr_assert(q1 < 0.6, "the scene must store more indirect photons than it emits: %zu for 3000", np);
    const pm_photon *ph = pm_map_photons(map);
    const int k = s->guide.k;
    double sum = 0.0;
    int balls = 0;
    for (size_t i = 0; i < np && balls < 400; i++) {
        double r = st->beam_radius[i];
        if (!(r > 0.0)) continue;
        int inside = 1; /* the box is [-1, 1]^3 about the map's origin, its centre */
        for (int a = 0; a < 3; a++) inside &= fabs(ph[i].pos[a]) + r < 1.0;
        if (!inside) continue;
        int count = 0;
        for (size_t j = 0; j < np; j++) {
            if (j == i || !(st->beam_radius[j] > 0.0f)) continue; /* (the others' centres) */
            double d2 = 0.0;
            for (int a = 0; a < 3; a++) d2 += (ph[j].pos[a] - ph[i].pos[a]) * (ph[j].pos[a] - ph[i].pos[a]);
            count += d2 < r * r;
        }
        sum += count;
        balls++;
    }
    cr_assert(balls >= 100, "only %d balls lie inside the medium", balls);
    double mean = sum / balls;
    cr_expect(fabs(mean / k - 1.0) < 0.25, "a ball holds %.2f other balls on average, want about k = %d (q_1 %.3f: unscaled %.2f)",
              mean, k, q1, q1 * k);
    rd_march_release(&ctx);
    rd_baked_free(bk);
    rd_scene_free(s);
}

/* `guided` as a user's render runs it but for a smaller kernel (march.beams on, the tile selection
 * named, as rt_scene would turn it off, the shares of settings.adaptive "auto", the beams'
 * progressive passes as the defaults have them; guide.k 8, below) against `delta` on a dense box
 * lit from above, where the beams take a good share of the samples and hold lit regions (checked
 * from the selection's trace): a guard against a wrong weight or scale of the beams, their shares or
 * their passes, not a measure of the kernel's blur (which estimate_equals_the_exact_point_gather
 * and the rule's own bias reading cover). The beams are consistent, not unbiased, so the kernel's
 * bias at this budget must lie below what the comparison resolves, and it is kept there by design:
 *  - guide.k 8, not 64: with 64, over 32 seeds (100-131), the image's light was 1.9 +- 0.5% over
 *    `delta`'s (a blur of the light's convex fall from the top), and a region's z was past 4.5 in
 *    13 of 32 renders; with 8 (r^2 1/4 as large) in none of the regions compared below;
 *  - regions compared only where `delta`'s light is at least a quarter of an even share: the blur
 *    lifts the dark bottom (under 0.5% of the light a region) to twice its light, where the
 *    beams' few samples vary little. Those regions' z measures the blur, not the weights; with
 *    them, 5 of 32 renders at guide.k 8 went past 4.5 (the image's z: none past 5).
 * The bounds are rt_expect_same's: 5 standard errors of the image mean and 4.5 of each region's,
 * from the two renders' own standard errors. The beams' pixels of one pass share its photons, so
 * those, taken as independent, understate the regions' noise: the z-scores err toward a false
 * alarm, not toward a pass. What the comparison resolves is checked too: the same render with the
 * light 20% brighter must be told apart from `delta`'s (at 32 seeds, every one was: the image's z
 * at least 7.2; 10% brighter, 30 of 32). Checked by hand, the beams' samples scaled in select.c:
 * by 0.8 the image's z is -18.5; by 1.2 the rule leaves the beams (8% of the samples: the share
 * check fails); by 1.1 it passes (the image's z 3.9): the guard is for errors of 20%, not 10%. */
static const char *dense_box_json(double intensity)
{
    static char buf[1024];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[32,24]},"
             "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":{\"type\":\"constant\",\"value\":1},"
             "\"sigma_t\":10,\"albedo\":0.99,\"g\":0.3}],"
             "\"lights\":[{\"type\":\"point\",\"position\":[0,1.6,0.5],\"intensity\":%g}],"
             "\"photons\":{\"count\":20000},\"guide\":{\"k\":8},"
             "\"settings\":{\"select\":\"auto\"}}",
             intensity);
    return buf;
}

/* The quarter of an even share of the light a region must hold to be compared (above). */
#define DENSE_BOX_LIT 0.25

/* How many of the regions rt_compare_lit compares (delta's image d) the beams hold under the
 * trace's last choice for samples below spp. */
static int dense_box_lit_beams(const char *trace, const rd_render_result *d, int spp)
{
    static char line[1 << 16];
    FILE *f = fopen(trace, "r");
    cr_assert(f, "no trace at %s", trace);
    cJSON *last = NULL;
    while (fgets(line, sizeof line, f)) {
        cJSON *j = cJSON_Parse(line);
        cr_assert(j, "the trace's line is not JSON");
        if (cJSON_GetObjectItem(j, "from_sample")->valuedouble >= spp) { /* (a choice for no sample) */
            cJSON_Delete(j);
            continue;
        }
        cJSON_Delete(last);
        last = j;
    }
    fclose(f);
    cr_assert(last, "the trace holds no choice");
    const cJSON *est = cJSON_GetObjectItem(last, "estimators"), *tiles = cJSON_GetObjectItem(last, "tiles");
    int b = -1;
    for (int e = 0; e < cJSON_GetArraySize(est); e++)
        if (strcmp(cJSON_GetArrayItem(est, e)->valuestring, "beams") == 0) b = e;
    cr_assert(b >= 0, "no beams estimator in the trace");
    const int w = d->image.w, h = d->image.h, tx = (w + 7) / 8, ty = (h + 7) / 8;
    const double even = rt_image_light(d) / (double)(tx * ty);
    int n = 0;
    for (int k = 0; k < tx * ty; k++) {
        double m = 0.0;
        for (int y = (k / tx) * 8; y < (k / tx) * 8 + 8 && y < h; y++)
            for (int x = (k % tx) * 8; x < (k % tx) * 8 + 8 && x < w; x++) {
                const float *p = &d->image.rgb[3 * ((size_t)y * w + x)];
                m += v3_lum(v3(p[0], p[1], p[2]));
            }
        n += m >= DENSE_BOX_LIT * even && cJSON_GetObjectItem(cJSON_GetArrayItem(tiles, k), "choice")->valueint == b;
    }
    cJSON_Delete(last);
    return n;
}

Test(beams, the_default_guided_gives_delta_s_image_where_the_beams_take_the_tiles, .timeout = 600)
{
    rd_scene *s = rt_scene("beams-box.json", dense_box_json(4.0));
    cr_assert(s->settings.adaptive == RD_ADAPTIVE_AUTO, "the shares are not the default");
    rd_render_result d = rt_render(s, "delta", 1024, 71, NULL);
    const char *trace = rt_tmp_path("beams-box.jsonl");
    rd_render_opts o = {.method = "guided", .spp = 64, .seed = 72, .threads = 2, .select_trace = trace};
    rd_render_result g;
    char err[RD_ERRLEN];
    cr_assert(rd_render(s, &o, &g, err, sizeof err) == RD_OK, "%s", err);
    double share = (double)g.stats.beams_samples / (double)g.stats.paths;
    cr_log_info("the beams' share %.2f, %d passes", share, g.stats.photon_passes);
    cr_assert(share > 0.25 && g.stats.photon_passes >= 4, "the beams' share %.2f, %d passes", share,
              g.stats.photon_passes);
    cr_assert(g.stats.spp_mean < 0.9 * 64.0, "no shares: %.1f samples a pixel of 64", g.stats.spp_mean);
    rt_cmp c = rt_compare_lit(&g, &d, DENSE_BOX_LIT);
    cr_log_info("the default guided, beams on the dense box: z image %.2f, worst of %d lit regions %.2f", c.z_image,
                c.regions, c.z_max);
    cr_assert(c.regions >= 4, "too few lit regions (%d)", c.regions);
    /* The beams hold lit regions (an 8x8 region is a tile) under the choice that governed most
     * samples, the last before the end: else a wrong weight of theirs would hide in the dark. */
    const int lit_beams = dense_box_lit_beams(trace, &d, o.spp);
    cr_log_info("the beams hold %d of the lit regions", lit_beams);
    cr_assert(lit_beams >= 2, "the beams hold %d of the lit regions", lit_beams);
    cr_expect(fabs(c.z_image) < 5.0, "image means differ, z = %.2f", c.z_image);
    cr_expect(fabs(c.z_max) < 4.5, "a lit region differs, z = %.2f (of %d)", c.z_max, c.regions);
    rd_scene *b = rt_scene("beams-box-bright.json", dense_box_json(4.8));
    rd_render_result gb = rt_render(b, "guided", 64, 72, NULL);
    rt_cmp cb = rt_compare_lit(&gb, &d, DENSE_BOX_LIT);
    cr_log_info("the light 20%% brighter: z image %.2f, worst region %.2f", cb.z_image, cb.z_max);
    cr_expect(fabs(cb.z_image) >= 5.0 || fabs(cb.z_max) >= 4.5,
              "the comparison does not resolve a 20%% brighter light (z image %.2f, worst region %.2f)", cb.z_image,
              cb.z_max);
    rd_render_result_free(&gb);
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    rd_scene_free(b);
    rd_scene_free(s);
}
