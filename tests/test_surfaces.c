/* test_surfaces.c: the transport with surfaces (issue 14 step 2; docs/surfaces.md), checked at
 * unit level against answers computed here, independently of the renderer's code:
 *   - shadow-ray transmittance across `interface` surfaces (and its blockers) and the media
 *     intervals of the open region: exp(-sum sigma_t x length), lengths clipped by a slab test
 *     written here;
 *   - the region of a point among nested shapes and sphere lights;
 *   - photon tracing: the power balance with surfaces, and the escaped fraction of a point light
 *     inside an absorbing glass cube against a quadrature over directions (own Fresnel);
 *   - the path loop (`delta`): a glass slab transmits (1 - R)/(1 + R), a white furnace through
 *     a glass sphere, a diffuse floor under a sphere light and a point light (next-event
 *     estimation and MIS at a surface).
 * Statistical checks use fixed seeds and a tolerance of 5 standard errors (two-sided false-alarm
 * probability 6e-7 per check), the standard error estimated from the samples themselves. Run from
 * the repository root (scenes/data/icosphere-3.obj). */
#include "support/rd_test.h"
#include "scene/rd_geom.h"
#include "bake/rd_photons.h"

#include "photonmap.h"

/* ---- helpers ------------------------------------------------------------------------------- */


/* The unit cube [0,1]^3 as six quads, wound counter-clockwise seen from outside, written as
 * <tmp>/cube.obj (scenes place it with a transform: scale s, translate t gives [t, t+s]). */
static void write_cube(void)
{
    const char *text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                       "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
    rt_write_file(rt_tmp_path("cube.obj"), text, strlen(text));
}

/* A shape entry for the box [lo, hi] made of the unit cube. */
static void box_shape(char *out, size_t n, const char *name, vec3 lo, vec3 hi, const char *material,
                      const char *inside, const char *outside)
{
    snprintf(out, n,
             "{\"name\":\"%s\",\"file\":\"cube.obj\",\"transform\":{\"scale\":[%.17g,%.17g,%.17g],"
             "\"translate\":[%.17g,%.17g,%.17g]},\"material\":%s,\"inside\":%s,\"outside\":%s}",
             name, hi.x - lo.x, hi.y - lo.y, hi.z - lo.z, lo.x, lo.y, lo.z, material, inside, outside);
}

/* The chord of segment a->b inside the box [lo, hi] (slab test, written here rather than taken
 * from the renderer's rd_box_intersect). */
static double chord(vec3 lo, vec3 hi, vec3 a, vec3 b)
{
    double t0 = 0.0, t1 = 1.0;
    double o[3] = {a.x, a.y, a.z}, d[3] = {b.x - a.x, b.y - a.y, b.z - a.z};
    double l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
    for (int k = 0; k < 3; k++) {
        if (d[k] == 0.0) {
            if (o[k] < l[k] || o[k] > h[k]) return 0.0;
            continue;
        }
        double u = (l[k] - o[k]) / d[k], v = (h[k] - o[k]) / d[k];
        if (u > v) { double w = u; u = v; v = w; }
        t0 = fmax(t0, u);
        t1 = fmin(t1, v);
    }
    return t1 > t0 ? (t1 - t0) * v3_len(v3_sub(b, a)) : 0.0;
}

/* Whether segment a->b meets the sphere (c, rad) (written here). */
static int seg_hits_sphere(vec3 a, vec3 b, vec3 c, double rad)
{
    vec3 d = v3_sub(b, a), oc = v3_sub(a, c);
    double A = v3_dot(d, d), B = 2 * v3_dot(oc, d), C = v3_dot(oc, oc) - rad * rad;
    if (C <= 0) return 1;
    double disc = B * B - 4 * A * C;
    if (disc < 0) return 0;
    double t = (-B - sqrt(disc)) / (2 * A);
    return t > 0 && t < 1;
}

/* Unpolarised Fresnel reflectance in the angle form (Born & Wolf §1.5.2, eqs. 21a-b and the
 * average of the two polarisations), written independently of rd_fresnel_dielectric's
 * amplitude form: cos_i the cosine of incidence, n = n_t / n_i. Total internal reflection: 1. */
static double fresnel_angle(double cos_i, double n)
{
    double sin_i = sqrt(fmax(0.0, 1 - cos_i * cos_i)), sin_t = sin_i / n;
    if (sin_t >= 1.0) return 1.0;
    if (sin_i < 1e-7) return ((n - 1) / (n + 1)) * ((n - 1) / (n + 1));
    double ti = asin(sin_i), tt = asin(sin_t);
    double rs = sin(ti - tt) / sin(ti + tt), rp = tan(ti - tt) / tan(ti + tt);
    return 0.5 * (rs * rs + rp * rp);
}

/* The same, per polarisation (for the comment on what the unpolarised model leaves out). */
static void fresnel_sp(double cos_i, double n, double *rs, double *rp)
{
    double ti = acos(cos_i), tt = asin(sin(ti) / n);
    *rs = pow(sin(ti - tt) / sin(ti + tt), 2);
    *rp = pow(tan(ti - tt) / tan(ti + tt), 2);
}

static const char *icosphere_path(void)
{
    static char p[1024];
    cr_assert(getcwd(p, sizeof p - 64) != NULL);
    strcat(p, "/scenes/data/icosphere-3.obj");
    cr_assert(access(p, R_OK) == 0, "%s missing (scripts/make-meshes.sh makes it)", p);
    return p;
}

/* The icosphere without its vertex normals, as <tmp>/ico-flat.obj: flat shading, so that a
 * dielectric event never meets a shading normal that sends its direction to the wrong side of
 * the surface (rd_material_sample then ends the path: an energy loss of the shading-normal
 * model, not of the transport, that an exact furnace check would otherwise see). */
static const char *icosphere_flat_path(void)
{
    FILE *in = fopen(icosphere_path(), "r");
    cr_assert(in != NULL);
    const char *p = rt_tmp_path("ico-flat.obj");
    FILE *out = fopen(p, "w");
    cr_assert(out != NULL);
    char line[512];
    while (fgets(line, sizeof line, in)) {
        unsigned a, b, c;
        if (line[0] == 'v' && line[1] == ' ') fputs(line, out);
        else if (sscanf(line, "f %u//%*u %u//%*u %u//%*u", &a, &b, &c) == 3) fprintf(out, "f %u %u %u\n", a, b, c);
    }
    fclose(in);
    fclose(out);
    return p;
}

/* ---- 1. Shadow rays across interfaces -------------------------------------------------------- */

/* The scene of tests 1: a scene-wide medium (room, sigma_t 0.1, within [-10,10]^3) or vacuum,
 * two interface boxes holding constant media whose bounds reach beyond the boxes (so only the
 * surfaces, not the bounds, can confine them), a glass box (vacuum inside), a diffuse wall, a
 * sphere light that shadow rays aim at and another one in the way. */
#define SIG_FOG 0.8
#define SIG_SMOKE 1.7
#define SIG_ROOM 0.1
static const vec3 BOX1_LO = {-1, -1, -1}, BOX1_HI = {1, 1, 1};
static const vec3 BOX2_LO = {2, -1, -1}, BOX2_HI = {3, 1, 1};
static const vec3 GLASS_LO = {-1, 3, -1}, GLASS_HI = {1, 4, 1};
static const vec3 WALL_LO = {-1, -4, -1}, WALL_HI = {1, -3, 1};
static const vec3 ROOM_LO = {-10, -10, -10}, ROOM_HI = {10, 10, 10};
static const vec3 TARGET_C = {0, 0, -6}, BLOCKER_C = {6, 0, 0};
#define LIGHT_R 0.5

static rd_scene *shadow_scene(const char *name, int room, const char *estimator)
{
    write_cube();
    const char *out = room ? "\"room\"" : "null";
    char b1[512], b2[512], gl[512], wa[512], json[4096];
    /* the room exists only as the scene-wide medium (vacuum variant: no such medium at all) */
    char room_json[256] = "";
    if (room)
        snprintf(room_json, sizeof room_json,
                 ",{\"name\":\"room\",\"bounds\":{\"min\":[-10,-10,-10],\"max\":[10,10,10]},\"density\":1,\"sigma_t\":%g}",
                 SIG_ROOM);
    box_shape(b1, sizeof b1, "box1", BOX1_LO, BOX1_HI, "{\"type\":\"interface\"}", "\"fog\"", out);
    box_shape(b2, sizeof b2, "box2", BOX2_LO, BOX2_HI, "{\"type\":\"interface\"}", "\"smoke\"", out);
    box_shape(gl, sizeof gl, "glass", GLASS_LO, GLASS_HI, "{\"type\":\"dielectric\",\"ior\":1.5}", "null", out);
    box_shape(wa, sizeof wa, "wall", WALL_LO, WALL_HI, "{\"type\":\"diffuse\",\"albedo\":0.5}", "null", out);
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,9],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
             "\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-3,-3,-3],\"max\":[3,3,3]},\"density\":1,\"sigma_t\":%g},"
             "{\"name\":\"smoke\",\"bounds\":{\"min\":[0,-3,-3],\"max\":[5,3,3]},\"density\":1,\"sigma_t\":%g}%s],"
             "\"shapes\":[%s,%s,%s,%s]%s,"
             "\"lights\":[{\"type\":\"sphere\",\"center\":[0,0,-6],\"radius\":%g,\"radiance\":1},"
             "{\"type\":\"sphere\",\"center\":[6,0,0],\"radius\":%g,\"radiance\":1},"
             "{\"type\":\"point\",\"position\":[0,0,8],\"intensity\":1}],"
             "\"settings\":{\"transmittance\":\"%s\"}}",
             SIG_FOG, SIG_SMOKE, room_json, b1, b2, gl, wa, room ? ",\"medium\":\"room\"" : "", LIGHT_R, LIGHT_R,
             estimator);
    return rt_scene(name, json);
}

/* Optical depth of segment a->b in the shadow scene: the media confined by the boxes, the room
 * (when present) in the rest of its bounds. */
static double shadow_tau(int room, vec3 a, vec3 b)
{
    double c1 = chord(BOX1_LO, BOX1_HI, a, b), c2 = chord(BOX2_LO, BOX2_HI, a, b);
    double tau = SIG_FOG * c1 + SIG_SMOKE * c2;
    if (room) tau += SIG_ROOM * (chord(ROOM_LO, ROOM_HI, a, b) - c1 - c2);
    return tau;
}

/* Whether segment a->b is blocked: it meets the glass or the wall, or a sphere light other than
 * `light` (a sphere light that is the target blocks nothing up to it; the segments of the test
 * that aim at it end on or inside it). */
static int shadow_blocked(vec3 a, vec3 b, int light)
{
    if (chord(GLASS_LO, GLASS_HI, a, b) > 0 || chord(WALL_LO, WALL_HI, a, b) > 0) return 1;
    if (light != 0 && seg_hits_sphere(a, b, TARGET_C, LIGHT_R)) return 1;
    if (light != 1 && seg_hits_sphere(a, b, BLOCKER_C, LIGHT_R)) return 1;
    return 0;
}

static double shadow_T(const rd_scene *s, vec3 a, vec3 b, int light, pcg32 *rng)
{
    rd_track_counters c = {0};
    vec3 d = v3_sub(b, a);
    double dist = v3_len(d);
    ray3 r = {a, v3_scale(d, 1.0 / dist)};
    return rd_shadow_transmittance(s, rd_scene_region_at(s, a), r, dist, light, NULL, rng, &c);
}

/* Tolerance of the closed-form checks: not statistical. A ray leaving a surface starts eps =
 * 2^-16 max(1, |p|_inf, |o|_inf, t) off it (rd_hit_spawn; <= 3e-4 here, t < 20), along the
 * normal, so each crossing may shift the chords by a few eps: |d tau| <= 4 crossings x 2 eps x
 * sigma_max 1.7 ~ 4e-3 at grazing incidence, and far less at the angles drawn below. */
#define SPAWN_TOL 4e-3

Test(surfaces, shadow_transmittance_across_interfaces, .timeout = 60)
{
    for (int room = 0; room <= 1; room++) {
        rd_scene *s = shadow_scene(room ? "shadow_room.json" : "shadow_vac.json", room, "exact");
        pcg32 rng = pcg32_seed(11, 0, 1234);
        /* Hand-picked segments: from outside through box1; from inside box1 out; through both
         * boxes; from inside box1 through box2; a segment in the open region only. */
        const vec3 seg[][2] = {
            {{0.3, 0.2, 5}, {0.3, 0.2, -4}},    /* box1, straight through (chord 2) */
            {{0.3, 0.2, 0.5}, {0.9, 2.5, 4.1}}, /* starts in box1, leaves it */
            {{-4, 0.1, 0.2}, {5, 0.1, 0.2}},     /* box1 and box2 (chords 2 and 1) */
            {{0.3, 0.2, 0.5}, {5, -0.3, 0.1}},   /* starts in box1, crosses box2 */
            {{2.5, 0.3, -0.2}, {-3, -0.4, 0.6}}, /* starts in box2, crosses box1 */
            {{-5, 5, 5}, {5, 5, 3}},              /* open region only */
        };
        for (size_t k = 0; k < sizeof seg / sizeof seg[0]; k++) {
            vec3 a = seg[k][0], b = seg[k][1];
            cr_assert(!shadow_blocked(a, b, -1), "segment %zu should be free", k);
            double T = shadow_T(s, a, b, -1, &rng), e = exp(-shadow_tau(room, a, b));
            cr_expect(fabs(T - e) <= SPAWN_TOL * e, "room %d segment %zu: T %.9f, exp(-tau) %.9f", room, k, T, e);
        }
        cr_expect(fabs(shadow_T(s, seg[2][0], seg[2][1], -1, &rng) -
                       exp(-(SIG_FOG * 2 + SIG_SMOKE * 1 + (room ? SIG_ROOM * 6 : 0)))) < 1e-3,
                  "two boxes: exp(-(0.8 x 2 + 1.7 x 1 [+ 0.1 x 6]))");

        /* rd_transmittance within one region, which the caller clips to its surfaces: the bound
         * fog over its whole bounds [-3,3]^3 (the surfaces do not enter), the room (or vacuum)
         * over its bounds alone, the smoke over [0,5]x[-3,3]^2. */
        {
            const vec3 F_LO = {-3, -3, -3}, F_HI = {3, 3, 3}, S_LO = {0, -3, -3}, S_HI = {5, 3, 3};
            vec3 a = v3(-7, 0.4, -0.3), b = v3(8, -0.2, 0.5);
            double len = v3_len(v3_sub(b, a));
            ray3 r = {a, v3_scale(v3_sub(b, a), 1.0 / len)};
            rd_track_counters c = {0};
            double Tf = rd_transmittance(s, 0, r, 0.0, len, &rng, &c), Ts = rd_transmittance(s, 1, r, 0.0, len, &rng, &c);
            double To = rd_transmittance(s, s->fill_medium, r, 0.0, len, &rng, &c);
            double ef = exp(-SIG_FOG * chord(F_LO, F_HI, a, b)), es = exp(-SIG_SMOKE * chord(S_LO, S_HI, a, b));
            double eo = room ? exp(-SIG_ROOM * chord(ROOM_LO, ROOM_HI, a, b)) : 1.0;
            cr_expect(fabs(Tf - ef) < 1e-12 && fabs(Ts - es) < 1e-12 && fabs(To - eo) < 1e-12,
                      "room %d: per region fog %.12g vs %.12g, smoke %.12g vs %.12g, open %.12g vs %.12g", room, Tf, ef, Ts, es, To, eo);
            /* a sub-interval [t0, t1] */
            vec3 a2 = ray_at(r, 2.5), b2 = ray_at(r, 9.0);
            double Tf2 = rd_transmittance(s, 0, r, 2.5, 9.0, &rng, &c);
            cr_expect(fabs(Tf2 - exp(-SIG_FOG * chord(F_LO, F_HI, a2, b2))) < 1e-12, "room %d: fog over [2.5, 9]", room);
        }

        /* Random segments in [-8, 8]^3: blocked ones give exactly 0, the rest exp(-tau). */
        int free_n = 0, blocked_n = 0;
        double worst = 0; /* largest relative deviation seen (logged) */
        pcg32 pick = pcg32_seed(12, 0, 99);
        for (int i = 0; i < 3000; i++) {
            vec3 a = v3(16 * pcg32_uniform(&pick) - 8, 16 * pcg32_uniform(&pick) - 8, 16 * pcg32_uniform(&pick) - 8);
            vec3 b = v3(16 * pcg32_uniform(&pick) - 8, 16 * pcg32_uniform(&pick) - 8, 16 * pcg32_uniform(&pick) - 8);
            /* endpoints inside a sphere light are not shadow-ray ends */
            if (v3_len(v3_sub(a, TARGET_C)) < LIGHT_R || v3_len(v3_sub(b, TARGET_C)) < LIGHT_R ||
                v3_len(v3_sub(a, BLOCKER_C)) < LIGHT_R || v3_len(v3_sub(b, BLOCKER_C)) < LIGHT_R)
                continue;
            double T = shadow_T(s, a, b, -1, &rng);
            if (shadow_blocked(a, b, -1)) {
                blocked_n++;
                cr_expect(T == 0.0, "room %d: blocked segment %d gives T = %g", room, i, T);
            } else {
                free_n++;
                double e = exp(-shadow_tau(room, a, b));
                worst = fmax(worst, fabs(T - e) / e);
                cr_expect(fabs(T - e) <= SPAWN_TOL * e, "room %d: segment %d (%.3f %.3f %.3f)->(%.3f %.3f %.3f): T %.9f, exp(-tau) %.9f",
                          room, i, a.x, a.y, a.z, b.x, b.y, b.z, T, e);
            }
        }
        cr_expect(free_n > 500 && blocked_n > 100, "both kinds drawn: %d free, %d blocked", free_n, blocked_n);
        cr_log_info("room %d: %d free segments (worst relative deviation %.2e), %d blocked", room, free_n, worst, blocked_n);

        /* Sphere lights. Aiming at the target light's centre (past its surface): the target does
         * not block (T up to its surface), any other light index says it does. */
        vec3 a = v3(0.2, 0.1, 5);
        vec3 dir = v3_norm(v3_sub(TARGET_C, a));
        double t_surf = v3_len(v3_sub(TARGET_C, a)) - LIGHT_R; /* nearly: the ray is almost radial */
        {
            /* exact entry distance of the ray into the target sphere */
            vec3 oc = v3_sub(a, TARGET_C);
            double bq = v3_dot(oc, dir), cq = v3_dot(oc, oc) - LIGHT_R * LIGHT_R;
            t_surf = -bq - sqrt(bq * bq - cq);
        }
        vec3 surf = v3_add(a, v3_scale(dir, t_surf));
        double e = exp(-shadow_tau(room, a, surf));
        double T0 = shadow_T(s, a, TARGET_C, 0, &rng);
        cr_expect(fabs(T0 - e) <= SPAWN_TOL * e, "room %d: the target light does not block: %.9f vs %.9f", room, T0, e);
        cr_expect(shadow_T(s, a, surf, 0, &rng) > 0.5 * e, "room %d: to the target's surface", room);
        cr_expect(shadow_T(s, a, TARGET_C, -1, &rng) == 0.0, "room %d: a point light behind a sphere light is shadowed", room);
        cr_expect(shadow_T(s, a, TARGET_C, 1, &rng) == 0.0, "room %d: another light's shadow ray is blocked by it", room);
        /* The blocker in the way of the target: 0. Through the glass or the wall: 0. */
        cr_assert(shadow_blocked(v3(11, 0.02, 5.01), TARGET_C, 0), "the blocker lies on this segment");
        cr_expect(shadow_T(s, v3(11, 0.02, 5.01), TARGET_C, 0, &rng) == 0.0, "room %d: another sphere light blocks", room);
        cr_expect(shadow_T(s, v3(0.1, 6, 0.2), v3(0.1, 0, 0.2), -1, &rng) == 0.0, "room %d: glass blocks", room);
        cr_expect(shadow_T(s, v3(0.1, -6, 0.2), v3(0.1, 0, 0.2), -1, &rng) == 0.0, "room %d: the diffuse wall blocks", room);
        /* The same from inside box1 out through the glass (the region is fog at the start). */
        cr_expect(shadow_T(s, v3(0.1, 0.5, 0.2), v3(0.1, 7, 0.2), -1, &rng) == 0.0, "room %d: glass blocks from inside box1", room);
        rd_scene_free(s);
    }
}

/* The same segments with the stochastic ratio-tracking estimator: the mean of N estimates is
 * within 5 standard errors of exp(-tau) (se from the sample variance). */
Test(surfaces, shadow_transmittance_ratio_estimator_unbiased, .timeout = 60)
{
    rd_scene *s = shadow_scene("shadow_ratio.json", 1, "ratio");
    const vec3 seg[][2] = {{{0.3, 0.2, 5}, {0.3, 0.2, -4}}, {{0.3, 0.2, 0.5}, {5, -0.3, 0.1}}, {{-4, 0.1, 0.2}, {5, 0.1, 0.2}}};
    const int N = 20000;
    for (int k = 0; k < 3; k++) {
        double sum = 0, sum2 = 0;
        for (int i = 0; i < N; i++) {
            pcg32 rng = pcg32_seed(21 + k, (uint64_t)i, 1234);
            double T = shadow_T(s, seg[k][0], seg[k][1], -1, &rng);
            sum += T, sum2 += T * T;
        }
        double m = sum / N, se = sqrt(fmax(0.0, sum2 / N - m * m) / N);
        double e = exp(-shadow_tau(1, seg[k][0], seg[k][1]));
        cr_expect(se > 0, "segment %d: the ratio estimator should be random", k);
        cr_expect(fabs(m - e) < 5 * se + SPAWN_TOL * e, "segment %d: mean %.5f +- %.5f vs exp(-tau) %.5f", k, m, se, e);
    }
    rd_scene_free(s);
}

/* ---- 2. The open region: box media inside a scene-wide medium -------------------------------- */

/* The last box is clear (sigma_t 0): a hole in the scene-wide medium, not a part of it. */
#define N_BOXMED 4
static const vec3 BM_LO[N_BOXMED] = {{-2, -1, -1}, {0.5, -1, -1}, {3, 2, -1}, {-0.5, -1, -1}};
static const vec3 BM_HI[N_BOXMED] = {{-1, 1, 1}, {2, 1, 1}, {4, 3, 1}, {0.2, 1, 1}};
static const double BM_SIG[N_BOXMED] = {1.2, 0.5, 2.0, 0.0};
#define SIG_WIDE 0.3
static const vec3 WIDE_LO = {-6, -6, -6}, WIDE_HI = {6, 6, 6};

static rd_scene *open_scene(const char *name, const char *estimator)
{
    char json[4096];
    int n = snprintf(json, sizeof json, "{\"camera\":{\"position\":[0,0,9],\"look_at\":[0,0,0],\"resolution\":[4,4]},\"media\":[");
    for (int i = 0; i < N_BOXMED; i++)
        n += snprintf(json + n, sizeof json - n,
                      "{\"name\":\"b%d\",\"bounds\":{\"min\":[%g,%g,%g],\"max\":[%g,%g,%g]},\"density\":1,\"sigma_t\":%g},", i,
                      BM_LO[i].x, BM_LO[i].y, BM_LO[i].z, BM_HI[i].x, BM_HI[i].y, BM_HI[i].z, BM_SIG[i]);
    snprintf(json + n, sizeof json - n,
             "{\"name\":\"wide\",\"bounds\":{\"min\":[-6,-6,-6],\"max\":[6,6,6]},\"density\":1,\"sigma_t\":%g}],"
             "\"medium\":\"wide\",\"lights\":[{\"type\":\"point\",\"position\":[0,0,8],\"intensity\":1}],"
             "\"settings\":{\"transmittance\":\"%s\"}}",
             SIG_WIDE, estimator);
    return rt_scene(name, json);
}

static double open_tau(vec3 a, vec3 b)
{
    double tau = 0, in_boxes = 0;
    for (int i = 0; i < N_BOXMED; i++) {
        double c = chord(BM_LO[i], BM_HI[i], a, b);
        tau += BM_SIG[i] * c;
        in_boxes += c;
    }
    return tau + SIG_WIDE * (chord(WIDE_LO, WIDE_HI, a, b) - in_boxes);
}

static int in_box3(vec3 lo, vec3 hi, vec3 x)
{
    return x.x >= lo.x && x.y >= lo.y && x.z >= lo.z && x.x <= hi.x && x.y <= hi.y && x.z <= hi.z;
}

Test(surfaces, open_region_intervals_and_exact_transmittance, .timeout = 60)
{
    rd_scene *s = open_scene("open_exact.json", "exact");
    cr_assert(s->fill_medium == N_BOXMED, "the scene-wide medium is media[%d]", N_BOXMED);
    cr_assert(rd_scene_region_at(s, v3(0, 0, 0)) == s->fill_medium);
    pcg32 pick = pcg32_seed(31, 0, 99), rng = pcg32_seed(32, 0, 1234);
    rd_track_counters c = {0};
    for (int i = 0; i < 2000; i++) {
        /* ends in [-8, 8]^3: some outside the scene-wide medium's bounds */
        vec3 a = v3(16 * pcg32_uniform(&pick) - 8, 16 * pcg32_uniform(&pick) - 8, 16 * pcg32_uniform(&pick) - 8);
        vec3 b = v3(16 * pcg32_uniform(&pick) - 8, 16 * pcg32_uniform(&pick) - 8, 16 * pcg32_uniform(&pick) - 8);
        if (i < 3) { /* and three through the boxes along the x axis */
            a = v3(-7, 0.1 * i, 0.05);
            b = v3(7, 0.1 * i + 2.5 * (i == 2), 0.05);
        }
        double len = v3_len(v3_sub(b, a));
        ray3 r = {a, v3_scale(v3_sub(b, a), 1.0 / len)};
        rd_interval iv[RD_MAX_INTERVALS];
        int n = rd_media_intervals(s, s->fill_medium, r, 0.0, len, iv);
        /* sorted, disjoint, within [0, len]; each interval's medium is the one at its midpoint */
        double per[N_BOXMED + 1] = {0}, last = 0.0;
        for (int k = 0; k < n; k++) {
            cr_assert(iv[k].t0 >= last - 1e-12 && iv[k].t1 > iv[k].t0 && iv[k].t1 <= len + 1e-12,
                      "ray %d interval %d [%g, %g] after %g", i, k, iv[k].t0, iv[k].t1, last);
            last = iv[k].t1;
            int mi = (int)(iv[k].m - s->media);
            cr_assert(mi >= 0 && mi <= N_BOXMED);
            per[mi] += iv[k].t1 - iv[k].t0;
            vec3 mid = ray_at(r, 0.5 * (iv[k].t0 + iv[k].t1));
            int expect = N_BOXMED;
            for (int j = 0; j < N_BOXMED; j++)
                if (in_box3(BM_LO[j], BM_HI[j], mid)) expect = j;
            cr_expect_eq(mi, expect, "ray %d interval %d: medium %d, expected %d", i, k, mi, expect);
            cr_expect(rd_scene_medium_at(s, s->fill_medium, mid) == &s->media[expect], "ray %d: medium at the midpoint", i);
        }
        /* lengths per medium against the chords computed here (none in the clear box) */
        double in_boxes = 0;
        for (int j = 0; j < N_BOXMED; j++) {
            double cj = chord(BM_LO[j], BM_HI[j], a, b), want = BM_SIG[j] > 0.0 ? cj : 0.0;
            in_boxes += cj;
            cr_expect(fabs(per[j] - want) < 1e-9, "ray %d: box %d length %.12f vs %.12f", i, j, per[j], want);
        }
        double cw = chord(WIDE_LO, WIDE_HI, a, b) - in_boxes;
        cr_expect(fabs(per[N_BOXMED] - cw) < 1e-9, "ray %d: scene-wide medium length %.12f vs %.12f", i, per[N_BOXMED], cw);
        /* the closed-form estimator: exactly exp(-tau) */
        double T = rd_transmittance(s, s->fill_medium, r, 0.0, len, &rng, &c), e = exp(-open_tau(a, b));
        cr_expect(fabs(T - e) <= 1e-9 * e + 1e-15, "ray %d: T %.12g vs %.12g", i, T, e);
    }
    /* outside the scene-wide medium's bounds and every box: no medium */
    cr_expect(rd_scene_medium_at(s, s->fill_medium, v3(7, 0, 0)) == NULL);
    cr_expect(rd_scene_medium_at_point(s, v3(1, 0, 0)) == &s->media[1]);
    cr_expect(rd_scene_medium_at_point(s, v3(0, 4, 0)) == &s->media[N_BOXMED]);
    cr_expect(rd_scene_medium_at_point(s, v3(-0.2, 0, 0)) == &s->media[N_BOXMED - 1], "the clear box is the medium there");
    rd_scene_free(s);
}

/* The stochastic estimators over the same open region: mean within 5 standard errors. (The
 * residual estimator's control is the constant density itself here, so it returns exp(-tau)
 * with no variance: se = 0 and the check is one of exactness, to 1e-12.) */
Test(surfaces, open_region_stochastic_estimators_unbiased, .timeout = 60)
{
    const char *est[] = {"ratio-global", "ratio", "residual"};
    vec3 a = v3(-7, 0.1, 0.05), b = v3(7, 2.6, 0.05);
    double len = v3_len(v3_sub(b, a)), e = exp(-open_tau(a, b));
    ray3 r = {a, v3_scale(v3_sub(b, a), 1.0 / len)};
    const int N = 20000;
    for (int k = 0; k < 3; k++) {
        char name[64];
        snprintf(name, sizeof name, "open_%s.json", est[k]);
        rd_scene *s = open_scene(name, est[k]);
        rd_track_counters c = {0};
        double sum = 0, sum2 = 0;
        for (int i = 0; i < N; i++) {
            pcg32 rng = pcg32_seed(41 + k, (uint64_t)i, 1234);
            double T = rd_transmittance(s, s->fill_medium, r, 0.0, len, &rng, &c);
            sum += T, sum2 += T * T;
        }
        double m = sum / N, se = sqrt(fmax(0.0, sum2 / N - m * m) / N);
        cr_expect(fabs(m - e) < 5 * se + 1e-12, "%s: mean %.6f +- %.6f vs exp(-tau) %.6f", est[k], m, se, e);
        cr_log_info("%s: %.6f +- %.6f vs %.6f", est[k], m, se, e);
        rd_scene_free(s);
    }
}

/* ---- 3. Regions of points -------------------------------------------------------------------- */

/* A flight sampler for shared_intervals_change_no_path: delta tracking, with thin bias where
 * the scene asks for it, over the media intervals the path loop hands it (in->iv), or, with
 * `fresh`, found again by the tracker as before the loop shared them. */
typedef struct {
    int fresh;
    long given; /* flights that came with the loop's intervals */
} shared_user;

static rd_flight shared_sample(const rd_flight_sampler *fs, const rd_scene *s, const rd_flight_in *in,
                               pcg32 *rng, rd_track_counters *c)
{
    shared_user *u = fs->user;
    rd_flight_in own = *in;
    u->given += in->iv != NULL;
    if (u->fresh) own.iv = NULL;
    double q = rd_thin_bias_q(s, &own);
    if (!(q > 0.0)) return rd_flight_delta(s, &own, rng, c);
    rd_collision col = own.iv ? rd_sample_free_path_thin_iv(s, own.iv, own.n_iv, own.r, own.t_light, q, rng, c)
                              : rd_sample_free_path_thin(s, own.region, own.r, own.t_light, q, rng, c);
    rd_flight f = {.kind = col.hit ? RD_FLIGHT_SCATTER : RD_FLIGHT_PASS, .t = col.t, .medium = col.medium, .pdf = 0.0};
    f.weight = col.hit ? v3_scale(col.medium->albedo, col.weight) : v3(col.weight, col.weight, col.weight);
    return f;
}

Test(surfaces, shared_intervals_change_no_path, .timeout = 60)
{
    /* The path loop finds a flight's media intervals once, for the flight and the equiangular
     * set-up (transport/path.c). Paths through interfaces, glass, a diffuse wall and a
     * scene-wide medium, with the strategy on every flight and "auto", with and without thin
     * bias: the same random numbers give the same radiance and counters, to the bit, whether
     * the flight takes the loop's intervals or finds them itself. */
    rd_scene *s = shadow_scene("shared.json", 1, "ratio");
    int differ = 0;
    long given = 0;
    for (int v = 0; v < 4; v++) {
        s->settings.thin_bias = v & 1 ? 0.3 : 0.0;
        int mode = v & 2 ? RD_EQ_AUTO : RD_EQ_ALL;
        shared_user ua = {0, 0}, ub = {1, 0};
        rd_flight_sampler fa = {.sample = shared_sample, .user = &ua, .equiangular = mode};
        rd_flight_sampler fb = {.sample = shared_sample, .user = &ub, .equiangular = mode};
        for (int i = 0; i < 3000; i++) {
            pcg32 g = pcg32_seed(21, (uint64_t)i, (uint64_t)v);
            vec3 o = v3(0, 0, 9), at = v3(8.0 * pcg32_uniform(&g) - 4.0, 10.0 * pcg32_uniform(&g) - 5.0, 0);
            ray3 r = {o, v3_norm(v3_sub(at, o))};
            pcg32 a = pcg32_seed(23, (uint64_t)i, (uint64_t)v), b = a;
            rd_track_counters ca = {0}, cb = {0};
            vec3 La = rd_path_radiance(s, r, &fa, &a, &ca), Lb = rd_path_radiance(s, r, &fb, &b, &cb);
            differ += La.x != Lb.x || La.y != Lb.y || La.z != Lb.z || ca.lookups != cb.lookups ||
                      ca.shadow_rays != cb.shadow_rays || ca.eq_flights != cb.eq_flights ||
                      pcg32_uniform(&a) != pcg32_uniform(&b);
        }
        given += ua.given;
    }
    cr_log_info("%ld flights took the loop's intervals", given);
    cr_expect(given > 10000, "the loop must hand its intervals on: %ld flights", given);
    cr_expect(differ == 0, "%d paths differ", differ);
    rd_scene_free(s);
}

Test(surfaces, region_at_nested_shapes_and_behind_lights)
{
    /* outer: an interface box [-4,4]^3 holding "outer" in the scene-wide "wide"; inner: a glass
     * box [-1,1]^3 holding "inner" inside the outer one; a sphere light inside the outer box, and
     * one in the open region. Media indices: inner 0, outer 1, wide 2. */
    write_cube();
    char so[512], si[512], json[4096];
    box_shape(so, sizeof so, "outer", v3(-4, -4, -4), v3(4, 4, 4), "{\"type\":\"interface\"}", "\"outer\"", "\"wide\"");
    box_shape(si, sizeof si, "inner", v3(-1, -1, -1), v3(1, 1, 1), "{\"type\":\"dielectric\",\"ior\":1.4}", "\"inner\"", "\"outer\"");
    /* The region query casts its ray along a fixed direction (scene/queries.c); the lights sit
     * across several directions from the probe points so that some probe ray meets them whatever
     * the direction: probes are placed on both sides of each light along each axis and diagonal. */
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,9],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
             "\"media\":[{\"name\":\"inner\",\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":1,\"sigma_t\":3},"
             "{\"name\":\"outer\",\"bounds\":{\"min\":[-4,-4,-4],\"max\":[4,4,4]},\"density\":1,\"sigma_t\":1},"
             "{\"name\":\"wide\",\"bounds\":{\"min\":[-9,-9,-9],\"max\":[9,9,9]},\"density\":1,\"sigma_t\":0.2}],"
             "\"medium\":\"wide\",\"shapes\":[%s,%s],"
             "\"lights\":[{\"type\":\"sphere\",\"center\":[2.5,2.5,2.5],\"radius\":0.6,\"radiance\":1},"
             "{\"type\":\"sphere\",\"center\":[6,6,6],\"radius\":0.8,\"radiance\":1}]}",
             so, si);
    rd_scene *s = rt_scene("nested.json", json);
    cr_assert_eq(s->fill_medium, 2);
    const double e = 1e-4; /* well above the spawn offset (~6e-5 here), far below any feature */
    struct { vec3 x; int region; } probe[] = {
        {{0, 0, 0}, 0},        {{0.3, -0.2, 0.9}, 0},   {{1 - e, 0.2, 0.3}, 0},  {{1 + e, 0.2, 0.3}, 1},
        {{0.2, -1 + e, 0.1}, 0}, {{0.2, -1 - e, 0.1}, 1}, {{0.1, 0.2, 1 - e}, 0}, {{0.1, 0.2, 1 + e}, 1},
        {{2, 0, 0}, 1},        {{-3, 3, -3}, 1},        {{4 - e, 1, 2}, 1},      {{4 + e, 1, 2}, 2},
        {{-1, -4 + e, 3}, 1},  {{-1, -4 - e, 3}, 2},    {{0, 0, 8}, 2},          {{-7, 8.5, 0}, 2},
        {{12, 0, 0}, 2}, /* beyond every medium: still the open region */
    };
    for (size_t k = 0; k < sizeof probe / sizeof probe[0]; k++) {
        vec3 x = probe[k].x;
        cr_expect_eq(rd_scene_region_at(s, x), probe[k].region, "(%g, %g, %g): region %d, expected %d", x.x, x.y, x.z,
                     rd_scene_region_at(s, x), probe[k].region);
        const rd_medium *m = rd_scene_medium_at_point(s, x);
        const rd_medium *want = probe[k].region >= 0 && in_box3(s->media[probe[k].region].bmin, s->media[probe[k].region].bmax, x)
                                    ? &s->media[probe[k].region] : NULL;
        cr_expect(m == want, "(%g, %g, %g): medium %ld, expected %ld", x.x, x.y, x.z, m ? (long)(m - s->media) : -1L,
                  want ? (long)(want - s->media) : -1L);
    }
    /* Points behind a sphere light (the light lies between the point and every surface in many
     * directions): lights bound no region. Probe on a shell around each light, 2 radii out, in 26
     * directions: one of them has the light in the query ray's way whatever its direction is. */
    const vec3 lc[2] = {{2.5, 2.5, 2.5}, {6, 6, 6}};
    const double lr[2] = {0.6, 0.8};
    const int lreg[2] = {1, 2};
    for (int l = 0; l < 2; l++)
        for (int dx = -1; dx <= 1; dx++)
            for (int dy = -1; dy <= 1; dy++)
                for (int dz = -1; dz <= 1; dz++) {
                    if (!dx && !dy && !dz) continue;
                    vec3 x = v3_add(lc[l], v3_scale(v3_norm(v3(dx, dy, dz)), 2.0 * lr[l]));
                    cr_expect_eq(rd_scene_region_at(s, x), lreg[l], "light %d, offset (%d,%d,%d): region %d", l, dx, dy, dz,
                                 rd_scene_region_at(s, x));
                }
    /* And the point exactly behind a light along the query direction (scene/queries.c's ray). */
    vec3 qd = v3_norm(v3(0.5316, 0.6124, 0.5851));
    for (int l = 0; l < 2; l++) {
        vec3 x = v3_sub(lc[l], v3_scale(qd, 2.0 * lr[l]));
        cr_expect_eq(rd_scene_region_at(s, x), lreg[l], "behind light %d along the query ray", l);
    }
    rd_scene_free(s);
}

/* ---- 4. Photon power balance with surfaces --------------------------------------------------- */

static pm_map *trace(const rd_scene *s, size_t n, int max_depth, uint64_t seed, rd_photon_stats *st)
{
    pm_map *map = pm_map_new();
    char err[RD_ERRLEN];
    rd_photon_opts o = {.count = n, .store_direct = 1, .segments = 0, .max_depth = max_depth, .seed = seed, .threads = 2};
    cr_assert(rd_trace_photons(s, &o, map, st, err, sizeof err) == RD_OK, "%s", err);
    return map;
}

Test(surfaces, photon_power_balance_with_floor_and_glass, .timeout = 120)
{
    /* emitted = absorbed + absorbed_surfaces + escaped + carried in expectation (rd_photons.h).
     * A diffuse floor (albedo 0.6), a glass icosphere (ior 1.5) of scattering medium (albedo
     * 0.8, g 0.3), a point light and a sphere light. Over K = 16 seeds the mean relative
     * imbalance must lie within 5 standard errors of 0; every term must be present. */
    write_cube();
    char floor_[512], json[4096];
    box_shape(floor_, sizeof floor_, "floor", v3(-4, -1.3, -4), v3(4, -1.1, 4), "{\"type\":\"diffuse\",\"albedo\":[0.6,0.5,0.4]}", "null", "null");
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,6],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
             "\"media\":[{\"name\":\"smoke\",\"bounds\":{\"min\":[-1.01,-1.01,-1.01],\"max\":[1.01,1.01,1.01]},"
             "\"density\":1,\"sigma_t\":2,\"albedo\":[0.8,0.7,0.6],\"g\":0.3}],"
             "\"shapes\":[%s,{\"name\":\"glass\",\"file\":\"%s\",\"material\":{\"type\":\"dielectric\",\"ior\":1.5},"
             "\"inside\":\"smoke\",\"outside\":null}],"
             "\"lights\":[{\"type\":\"point\",\"position\":[0.3,2.2,0.1],\"intensity\":2},"
             "{\"type\":\"sphere\",\"center\":[-2,0.5,1],\"radius\":0.3,\"radiance\":1}]}",
             floor_, icosphere_path());
    rd_scene *s = rt_scene("balance.json", json);
    enum { K = 16 };
    double imb[K], surf = 0, esc = 0, abs_ = 0;
    for (int k = 0; k < K; k++) {
        rd_photon_stats st;
        pm_map *map = trace(s, 10000, 32, 200 + k, &st);
        double e = st.power_emitted[1];
        imb[k] = (e - st.power_absorbed[1] - st.power_absorbed_surfaces[1] - st.power_escaped[1] - st.power_carried[1]) / e;
        surf += st.power_absorbed_surfaces[1] / e / K;
        esc += st.power_escaped[1] / e / K;
        abs_ += st.power_absorbed[1] / e / K;
        pm_map_free(map);
    }
    double m = 0, v = 0;
    for (int k = 0; k < K; k++) m += imb[k] / K;
    for (int k = 0; k < K; k++) v += (imb[k] - m) * (imb[k] - m) / (K - 1);
    double se = sqrt(v / K);
    cr_expect(se > 0, "the imbalance must be random (Russian roulette), else the check is empty");
    cr_expect(fabs(m) < 5 * se, "imbalance %.3e (se %.3e)", m, se);
    cr_expect(surf > 0.02 && esc > 0.05 && abs_ > 0.02, "each sink takes a share: surfaces %.3f, escaped %.3f, medium %.3f", surf, esc, abs_);
    cr_log_info("balance: imbalance %.2e +- %.2e; floor %.3f, escaped %.3f, medium %.3f", m, se, surf, esc, abs_);
    rd_scene_free(s);
}

/* ---- 5. Photons escaping an absorbing glass cube ------------------------------------------- */

/* The expected escaped fraction of an isotropic point source at the centre of the cube
 * [-a, a]^3 of index n (vacuum outside) filled with a purely absorbing medium of sigma_t s.
 * A ray that reflects off a face of the cube only flips one component of its direction, so
 * unfolded by the mirror images of the cube it is a straight line from the centre along
 * (|dx|, |dy|, |dz|): it meets a face of normal axis k at t = (2j + 1) a / |d_k|, j >= 0, with
 * incidence cosine |d_k|. At each meeting the light leaves with probability 1 - F (Fresnel,
 * from the inside: n_t / n_i = 1 / n) after surviving absorption, exp(-s t):
 *     E(d) = sum_m prod_{i<m} F_i (1 - F_m) exp(-s t_m).
 * The escaped fraction is the mean of E over directions; by symmetry, the +z face's quarter
 * [0, a]^2 with dw = a dx dy / r^3 (r = |(x, y, a)|), times 24 / (4 pi). Midpoint rule on an
 * M x M grid. For a sphere E would be (1 - R) e^{-s a} / (1 - R e^{-2 s a}) in every direction. */
static double cube_escape_dir(double dx, double dy, double dz, double a, double n, double s)
{
    double len = sqrt(dx * dx + dy * dy + dz * dz);
    double d[3] = {fabs(dx) / len, fabs(dy) / len, fabs(dz) / len}, next[3], F[3];
    for (int k = 0; k < 3; k++) {
        next[k] = d[k] > 0 ? a / d[k] : INFINITY;
        F[k] = fresnel_angle(d[k], 1.0 / n);
    }
    double E = 0, keep = 1;
    for (;;) {
        int k = next[0] <= next[1] ? (next[0] <= next[2] ? 0 : 2) : (next[1] <= next[2] ? 1 : 2);
        double t = next[k], att = exp(-s * t);
        E += keep * (1 - F[k]) * att;
        keep *= F[k];
        if (keep * att < 1e-16) break;
        next[k] += 2 * a / d[k];
    }
    return E;
}

static double cube_escape_fraction(double a, double n, double s, int M)
{
    double sum = 0, h = a / M;
    for (int i = 0; i < M; i++)
        for (int j = 0; j < M; j++) {
            double x = (i + 0.5) * h, y = (j + 0.5) * h, r = sqrt(x * x + y * y + a * a);
            sum += cube_escape_dir(x, y, a, a, n, s) * a / (r * r * r);
        }
    return 24.0 / (4 * M_PI) * sum * h * h;
}

Test(surfaces, photons_escape_absorbing_glass_cube, .timeout = 120)
{
    const double a = 1.0, n = 1.5, s_t = 0.7;
    write_cube();
    char cube[512], json[4096];
    box_shape(cube, sizeof cube, "glass", v3(-a, -a, -a), v3(a, a, a), "{\"type\":\"dielectric\",\"ior\":1.5}", "\"ink\"", "null");
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,6],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
             "\"media\":[{\"name\":\"ink\",\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":1,\"sigma_t\":%g,\"albedo\":0}],"
             "\"shapes\":[%s],\"lights\":[{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":1}]}",
             s_t, cube);
    rd_scene *s = rt_scene("ink_cube.json", json);
    /* The quadrature, and its convergence: the M = 200 and M = 400 answers must agree far
     * below the photon estimate's standard error (E(d) is continuous: F -> 1 at the critical
     * angle, and two faces met at the same t give the same sum in either order). */
    double f1 = cube_escape_fraction(a, n, s_t, 200), f2 = cube_escape_fraction(a, n, s_t, 400);
    /* Sanity of the quadrature on its own: with s = 0 and no reflection (n = 1) every photon
     * leaves; with the sphere's formula as a rough neighbour (normal incidence everywhere). */
    double f_n1 = cube_escape_fraction(a, 1.0, 0.0, 200);
    cr_expect(fabs(f_n1 - 1.0) < 1e-3, "solid angle of the quadrature: %.6f", f_n1);
    const size_t N = 400000;
    rd_photon_stats st;
    pm_map *map = trace(s, N, 1000, 77, &st);
    double emitted = st.power_emitted[0], p = st.power_escaped[0] / emitted;
    /* Each photon carries 4 pi I / N and either escapes whole or not (albedo 0: absorbed at its
     * first collision; glass never rouletted): the escaped count is binomial. */
    double se = sqrt(f2 * (1 - f2) / N);
    cr_expect(fabs(emitted - 4 * M_PI) < 1e-9 * 4 * M_PI, "emitted %.12f", emitted);
    cr_expect(st.power_carried[0] < 1e-4 * emitted, "max_depth must not cut paths here: %.3g", st.power_carried[0] / emitted);
    cr_expect(fabs(f1 - f2) < 0.05 * se, "quadrature not converged: %.7f vs %.7f (se %.2g)", f1, f2, se);
    cr_expect(fabs(p - f2) < 5 * se, "escaped %.5f vs quadrature %.5f (se %.5f)", p, f2, se);
    double R = pow((n - 1) / (n + 1), 2), sphere = (1 - R) * exp(-s_t * a) / (1 - R * exp(-2 * s_t * a));
    cr_log_info("cube escape: photons %.5f +- %.5f, quadrature %.6f (sphere of radius a: %.5f)", p, se, f2, sphere);
    pm_map_free(map);
    rd_scene_free(s);
}

/* ---- 6. The path loop through a glass slab --------------------------------------------------- */

/* A slab 20 x 20 x 0.2 of index n (no medium), tilted by `tilt` degrees about y, in front of a
 * sphere light of radiance 2 (radius 900, centre 1000 behind), black background, no other
 * light: camera rays along -z. Reflected rays leave toward +z and meet nothing. */
static rd_scene *slab_scene(const char *name, double ior, double tilt)
{
    write_cube();
    char json[4096];
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,20],\"look_at\":[0,0,0],\"resolution\":[4,4]},\"media\":[],"
             "\"shapes\":[{\"name\":\"slab\",\"file\":\"cube.obj\",\"transform\":{\"scale\":[20,20,0.2],"
             "\"translate\":[-10,-10,-0.1]},\"material\":{\"type\":\"dielectric\",\"ior\":%.17g}}],"
             "\"lights\":[{\"type\":\"sphere\",\"center\":[0,0,-1000],\"radius\":900,\"radiance\":2}],"
             "\"settings\":{\"max_depth\":100000}}",
             ior);
    /* the tilt as a transform of the whole slab about the origin */
    if (tilt != 0.0) {
        char *p = strstr(json, "\"translate\":[-10,-10,-0.1]}");
        cr_assert(p);
        char tail[2048];
        snprintf(tail, sizeof tail, "%s", p + strlen("\"translate\":[-10,-10,-0.1]}"));
        /* rotate after translating the unit cube would rotate about a corner: instead rotate the
         * centred slab; p' = t + R (s p), so put the rotated centre offset in t. */
        double th = tilt * M_PI / 180;
        vec3 c0 = v3(-10, -10, -0.1); /* R(-10,-10,-0.1) about y */
        vec3 tr = v3(c0.x * cos(th) + c0.z * sin(th), c0.y, -c0.x * sin(th) + c0.z * cos(th));
        snprintf(p, sizeof json - (size_t)(p - json), "\"rotate\":{\"axis\":[0,1,0],\"angle\":%.17g},\"translate\":[%.17g,%.17g,%.17g]}%s",
                 tilt, tr.x, tr.y, tr.z, tail);
    }
    return rt_scene(name, json);
}

Test(surfaces, glass_slab_transmits_one_minus_r_over_one_plus_r, .timeout = 60)
{
    /* Multiple internal reflections between two parallel faces, each with the same Fresnel
     * reflectance R (Stokes; the inside angle gives the same R by reciprocity): transmitted
     * T = (1 - R)^2 sum_k R^{2k} = (1 - R)/(1 + R). The renderer's dielectric is unpolarised
     * at every event, so R is the unpolarised F; the physical slab's answer averages the two
     * polarisations separately (logged below: it differs by 0.2% at 40 degrees). */
    const double n = 1.5, L = 2.0;
    const int N = 40000;
    const double tilts[2] = {0.0, 40.0};
    for (int k = 0; k < 2; k++) {
        rd_scene *s = slab_scene(k ? "slab40.json" : "slab0.json", n, tilts[k]);
        ray3 r = {v3(0.13, 0.07, 20), v3(0, 0, -1)};
        rt_mc mc = rt_delta_mc(s, r, N, 60 + k);
        double F = fresnel_angle(cos(tilts[k] * M_PI / 180), n), e = L * (1 - F) / (1 + F);
        cr_expect(mc.se.y > 0, "tilt %g: random (Fresnel choices)", tilts[k]);
        cr_expect(fabs(mc.mean.y - e) < 5 * mc.se.y, "tilt %g: %.5f +- %.5f vs L (1-R)/(1+R) = %.5f", tilts[k], mc.mean.y, mc.se.y, e);
        if (k == 1) {
            double rs, rp;
            fresnel_sp(cos(tilts[k] * M_PI / 180), n, &rs, &rp);
            double pol = L * 0.5 * ((1 - rs) / (1 + rs) + (1 - rp) / (1 + rp));
            cr_log_info("slab at 40 deg: %.5f +- %.5f, unpolarised model %.5f, polarised physics %.5f", mc.mean.y, mc.se.y, e, pol);
        }
        rd_scene_free(s);
    }
    /* The same tilted slab under a uniform environment of radiance L in place of the sphere
     * light: what is not transmitted is reflected into the environment too, so the pixel is L
     * (no absorption anywhere). The roulette decides on the throughput without the radiance
     * factors of the refractions (eta_scale, as pbrt-v4), so inside the glass (beta = 1/n^2,
     * eta_scale = n^2) it keeps every path: every sample is exactly L. */
    {
        /* (the unit cube scaled and turned about its corner: the rays below still cross the
         * slab's two large faces, the only ones that matter here) */
        char json[4096];
        write_cube();
        snprintf(json, sizeof json,
                 "{\"camera\":{\"position\":[0,0,20],\"look_at\":[0,0,0],\"resolution\":[4,4]},\"media\":[],"
                 "\"shapes\":[{\"name\":\"slab\",\"file\":\"cube.obj\",\"transform\":{\"scale\":[20,20,0.2],"
                 "\"rotate\":{\"axis\":[0,1,0],\"angle\":40},\"translate\":[0,0,0]},"
                 "\"material\":{\"type\":\"dielectric\",\"ior\":1.5}}],"
                 "\"lights\":[{\"type\":\"environment\",\"radiance\":2}],\"settings\":{\"max_depth\":100000}}");
        rd_scene *s = rt_scene("slab_env.json", json);
        ray3 r = {v3(3.13, 4.07, 20), v3(0, 0, -1)};
        rt_mc mc = rt_delta_mc(s, r, N, 65);
        cr_expect(fabs(mc.mean.y - L) < 1e-9 && mc.se.y < 1e-9, "environment slab: %.12f +- %.3g vs L = %g", mc.mean.y, mc.se.y, L);
        rd_scene_free(s);
    }
    /* Index 1: invisible. Every sample is L exactly (no reflection, weight 1 both ways). */
    rd_scene *s = slab_scene("slab_n1.json", 1.0, 0.0);
    ray3 r = {v3(0.13, 0.07, 20), v3(0, 0, -1)};
    rt_mc mc = rt_delta_mc(s, r, 2000, 70);
    cr_expect(fabs(mc.mean.y - L) < 1e-12 && mc.se.y < 1e-12, "ior 1: %.15f +- %.3g", mc.mean.y, mc.se.y);
    rd_scene_free(s);
}

/* ---- 7. White furnace through glass --------------------------------------------------------- */

static rd_scene *furnace_scene(const char *name, double g, int rr_depth, int flat)
{
    char json[4096];
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,6],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
             "\"media\":[{\"name\":\"cloud\",\"bounds\":{\"min\":[-1.01,-1.01,-1.01],\"max\":[1.01,1.01,1.01]},"
             "\"density\":1,\"sigma_t\":3,\"albedo\":1,\"g\":%g}],"
             "\"shapes\":[{\"name\":\"glass\",\"file\":\"%s\",\"material\":{\"type\":\"dielectric\",\"ior\":1.33},"
             "\"inside\":\"cloud\",\"outside\":null}],"
             "\"lights\":[{\"type\":\"environment\",\"radiance\":1}],"
             "\"settings\":{\"max_depth\":100000,\"rr_depth\":%d}}",
             g, flat ? icosphere_flat_path() : icosphere_path(), rr_depth);
    return rt_scene(name, json);
}

Test(surfaces, white_furnace_through_glass_sphere, .timeout = 120)
{
    /* A closed lossless system (dielectric sphere, albedo-1 medium) under a uniform environment
     * of radiance 1: every camera ray sees radiance 1 outside (Kirchhoff: nothing absorbs, so
     * nothing can differ from the surroundings), and n^2 inside the glass (radiance / n^2 is
     * invariant, Veach eq. 5.13; the RADIANCE weight (n_i/n_t)^2 = n^2 of the way out). Paths
     * end only by escaping (max_depth 100000 is never reached) or by roulette:
     *   - rr_depth 3 (default): inside the glass beta = 1/n^2, but the roulette decides on
     *     beta x eta_scale = 1 (eta_scale: the product of (n_t/n_i)^2 over the refractions,
     *     pbrt-v4's etaScale), so it keeps every path, and each sample from outside is exactly
     *     1. (Before eta_scale the roulette killed a path entering the glass with probability
     *     1 - 1/n^2 and the samples were 0, 1 or n^2: 12x the variance on a glass ball.) A
     *     path that starts inside keeps beta = 1 until it leaves: every sample is exactly n^2.
     *   - rr_depth 100000 (no roulette): each sample from outside is exactly 1 and each from
     *     inside exactly n^2 (next-event estimation gives 0 inside: the glass blocks shadow
     *     rays), so the mean must equal them to round-off.
     * Rays: from outside toward the sphere (they hit it), and from inside it. */
    const double n2 = 1.33 * 1.33;
    const double gs[2] = {0.7, 0.0};
    const int N = 20000;
    ray3 outside = {v3(0.2, 0.1, 6), v3_norm(v3(-0.05, 0.02, -1))};
    ray3 inside = {v3(0.1, 0.2, 0.3), v3_norm(v3(0.3, -0.5, 0.8))};
    for (int k = 0; k < 2; k++) {
        char name[64];
        snprintf(name, sizeof name, "furnace_rr_%d.json", k);
        rd_scene *s = furnace_scene(name, gs[k], 3, 1);
        rt_mc mo = rt_delta_mc(s, outside, N, 80 + k), mi = rt_delta_mc(s, inside, N / 10, 90 + k);
        cr_expect(fabs(mo.mean.y - 1.0) < 1e-9 && mo.se.y < 1e-9, "g %g, outside: %.12f +- %.3g vs 1 (roulette must not act)", gs[k], mo.mean.y, mo.se.y);
        cr_expect(fabs(mi.mean.y - n2) < 1e-9 && mi.se.y < 1e-9, "g %g, inside: %.12f +- %.3g vs n^2 = %.4f", gs[k], mi.mean.y, mi.se.y, n2);
        cr_log_info("furnace g %g (roulette): outside %.4f +- %.4f, inside %.4f +- %.4f", gs[k], mo.mean.y, mo.se.y, mi.mean.y, mi.se.y);
        rd_scene_free(s);
        snprintf(name, sizeof name, "furnace_norr_%d.json", k);
        s = furnace_scene(name, gs[k], 100000, 1);
        mo = rt_delta_mc(s, outside, N / 10, 100 + k);
        mi = rt_delta_mc(s, inside, N / 10, 110 + k);
        cr_expect(fabs(mo.mean.y - 1.0) < 1e-9 && mo.se.y < 1e-9, "g %g, outside, no roulette: %.12f +- %.3g", gs[k], mo.mean.y, mo.se.y);
        cr_expect(fabs(mi.mean.y - n2) < 1e-9 && mi.se.y < 1e-9, "g %g, inside, no roulette: %.12f +- %.3g", gs[k], mi.mean.y, mi.se.y);
        rd_scene_free(s);
    }
}

/* ---- 8. A diffuse surface's next-event estimation and MIS ----------------------------------- */

Test(surfaces, diffuse_floor_under_sphere_and_point_lights, .timeout = 60)
{
    /* A Lambertian floor (albedo rho; the top face of a thin box at y = 0) with nothing else in
     * view but one light above the point p = 0 of it. Nothing reaches p but direct light (the
     * floor is flat, the lights do not reflect), so the radiance leaving p is
     *   sphere light (radiance L, centre h above p, radius a): rho/pi x integral over the cap of
     *     L cos(theta) dw = rho/pi x L pi sin^2(alpha) = rho L (a/h)^2    (cap about the normal);
     *   point light (intensity I, h above p): rho/pi x I / h^2.
     * The sphere light is reached both by next-event estimation and by the cosine-sampled
     * bounce (MIS, power heuristic: rd_nee_surface): within 5 standard errors. The point light
     * only by next-event estimation, with no randomness left here: to round-off. */
    write_cube();
    char floor_[512], json[4096];
    const double rho = 0.5, L = 3.0, h = 2.0, a = 0.5, I = 1.5;
    box_shape(floor_, sizeof floor_, "floor", v3(-10, -0.2, -10), v3(10, 0, 10), "{\"type\":\"diffuse\",\"albedo\":0.5}", "null", "null");
    ray3 cam = {v3(0, 3, 5), v3_norm(v3(0, -3, -5))}; /* passes 1.7 from the light's centre */
    for (int k = 0; k < 2; k++) {
        snprintf(json, sizeof json,
                 "{\"camera\":{\"position\":[0,3,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},\"media\":[],\"shapes\":[%s],"
                 "\"lights\":[%s]}",
                 floor_,
                 k ? "{\"type\":\"point\",\"position\":[0,2,0],\"intensity\":1.5}"
                   : "{\"type\":\"sphere\",\"center\":[0,2,0],\"radius\":0.5,\"radiance\":3}");
        rd_scene *s = rt_scene(k ? "floor_point.json" : "floor_sphere.json", json);
        rt_mc mc = rt_delta_mc(s, cam, k ? 200 : 40000, 120 + k);
        if (k == 0) {
            double e = rho * L * (a / h) * (a / h);
            cr_expect(mc.se.y > 0, "sphere light: random");
            cr_expect(fabs(mc.mean.y - e) < 5 * mc.se.y, "sphere light: %.5f +- %.5f vs rho L (a/h)^2 = %.5f", mc.mean.y, mc.se.y, e);
            cr_log_info("floor under a sphere light: %.5f +- %.5f vs %.5f", mc.mean.y, mc.se.y, e);
        } else {
            double e = rho / M_PI * I / (h * h);
            cr_expect(fabs(mc.mean.y - e) < 1e-9 * e, "point light: %.12f vs rho I / (pi h^2) = %.12f", mc.mean.y, e);
        }
        rd_scene_free(s);
    }
    /* The point light again, with the floor in a scene-wide, purely absorbing medium (sigma_t
     * 0.3, albedo 0): the shadow ray from the floor leaves in the floor's outside region and the
     * camera ray crosses the same medium, so the radiance is
     *   exp(-sigma |c - p|) rho/pi I/h^2 exp(-sigma h).
     * The camera flight (delta tracking: a collision ends the path, albedo 0) makes it random
     * (a Bernoulli factor); the shadow ray's transmittance is the closed form: 5 standard errors. */
    box_shape(floor_, sizeof floor_, "floor", v3(-10, -0.2, -10), v3(10, 0, 10), "{\"type\":\"diffuse\",\"albedo\":0.5}", "null", "\"air\"");
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,3,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
             "\"media\":[{\"name\":\"air\",\"bounds\":{\"min\":[-12,-12,-12],\"max\":[12,12,12]},\"density\":1,\"sigma_t\":0.3,\"albedo\":0}],"
             "\"medium\":\"air\",\"shapes\":[%s],\"lights\":[{\"type\":\"point\",\"position\":[0,2,0],\"intensity\":1.5}]}",
             floor_);
    rd_scene *s = rt_scene("floor_air.json", json);
    cr_assert_eq(rd_scene_region_at(s, cam.o), 0, "the camera is in the air");
    rt_mc mc = rt_delta_mc(s, cam, 20000, 130);
    double e = exp(-0.3 * sqrt(34.0)) * rho / M_PI * I / (h * h) * exp(-0.3 * h);
    cr_expect(mc.se.y > 0, "absorbing air: random");
    cr_expect(fabs(mc.mean.y - e) < 5 * mc.se.y, "absorbing air: %.6f +- %.6f vs %.6f", mc.mean.y, mc.se.y, e);
    rd_scene_free(s);
}
