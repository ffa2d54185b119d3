/* The path loops' beam connections (settings.beam_connect; transport/beam_connect.c):
 *  - the sampler of the connection's point: chi-square of its axial coordinate against the
 *    density rd_beam_connect_pdf integrated by Simpson's rule (not the sampler's inversion), and
 *    of its offset across the axis against the uniform disc; cells with an expected count < 5
 *    pooled, rejected at p = 1e-4 (z = 3.719), as tests/test_equiangular.c; the pdf integrates
 *    to 1 and the sampler returns the pdf of the point it draws; the test has teeth: the same
 *    samples judged against the pdf seen from another vertex fail;
 *  - unbiased (the sanitizer run keeps the homogeneous one and the surfaces, the release run has
 *    them all: Makefile ASAN_FILTER): `delta` with the connections gives `delta`'s image on a
 *    beam across fog, in a homogeneous medium and in a forward-scattering noise medium (z bounds
 *    of 5 for the image and 4.5 for the worst region, rt_expect_same; fixed seeds), also with a
 *    second light (a bright sphere in the beam) and max_depth 2, with a glass ball holding a
 *    denser medium and an opaque plate in the beam (a connection across a surface is blocked),
 *    and across two media along the beam (y takes its own medium); guided-unbiased's own paths,
 *    which connect too, give the same image;
 *  - max_depth 1 makes no connection (the image bit for bit); a sphere light blocks the
 *    connections that cross it;
 *  - "auto" (the default) is on for a narrow beam and off for a broad one (its breadth, load.c)
 *    and where `true` would be refused;
 *  - what `true` refuses, each with a one-line error naming the field. */
#include "support/rd_test.h"

#include <stdarg.h>

/* The camera of the image tests, and their beam (a directional light of radius 0.2), opening
 * the "lights" list. */
#define BC_CAMERA "{\"camera\":{\"position\":[0,0,3.2],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[32,24]},"
#define BC_BEAM \
    "\"lights\":[{\"type\":\"directional\",\"direction\":[1,-0.2,0.3],\"irradiance\":[5,5,5],\"radius\":0.2," \
    "\"center\":[0,0.1,0]}"
/* The scene-wide fog (its body a %s slot) opening the "media" list; and the end of a scene
 * with the beam alone, deep paths and settings.beam_connect left a %%s slot (for
 * expect_delta_s_image_of). */
#define BC_FOG_FILL \
    "\"medium\":\"fog\",\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-1,-0.8,-0.8],\"max\":[1,0.8,0.8]},%s},"
#define BC_TAIL BC_BEAM "],\"background\":0,\"settings\":{\"max_depth\":64,\"rr_depth\":3,\"beam_connect\":%%s}}"

/* A box of fog crossed by a beam; `medium` the medium's JSON body, `settings` extra settings. */
static const char *beam_fog_json(const char *medium, const char *settings)
{
    static char buf[2048];
    snprintf(buf, sizeof buf,
             BC_CAMERA
             "\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-1,-0.8,-0.8],\"max\":[1,0.8,0.8]},%s}],"
             BC_BEAM "],\"background\":0,"
             "\"settings\":{\"max_depth\":64,\"rr_depth\":3%s}}",
             medium, settings);
    return buf;
}

static const char *const homogeneous = "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1.5,\"albedo\":0.9,\"g\":0.6";

typedef struct {
    const rd_scene *s;
    vec3 x;
} pdf_ctx;

/* The density of the axial coordinate s: the point's density is the same across the disc. */
static double axial_pdf(double s, const void *ctx)
{
    const pdf_ctx *k = ctx;
    const rd_light *l = &k->s->lights[k->s->beam_connect.light];
    return rd_beam_connect_pdf(k->s, k->x, v3_madd(l->beam_center, l->dir, s)) * M_PI * l->radius * l->radius;
}

enum { NB = 64, NS = 200000 };

/* Samples from x: the axial coordinate binned over [s0, s1], the squared offset across the
 * axis over R^2 binned over [0, 1] (uniform for a uniform disc). */
static void sample_bins(const rd_scene *s, vec3 x, uint64_t seed, double *axial, double *radial)
{
    const rd_beam_connect *bc = &s->beam_connect;
    const rd_light *l = &s->lights[bc->light];
    pcg32 rng = pcg32_seed(seed, 7, 13);
    memset(axial, 0, NB * sizeof *axial);
    memset(radial, 0, NB * sizeof *radial);
    for (int i = 0; i < NS; i++) {
        double u[4] = {pcg32_uniform(&rng), pcg32_uniform(&rng), pcg32_uniform(&rng), pcg32_uniform(&rng)};
        vec3 y;
        double pdf;
        cr_assert(rd_beam_connect_sample(s, x, u[0], u[1], u[2], u[3], &y, &pdf));
        cr_assert(pdf == rd_beam_connect_pdf(s, x, y), "the sampler's pdf differs from rd_beam_connect_pdf");
        vec3 q = v3_sub(y, l->beam_center);
        double sy = v3_dot(q, l->dir);
        vec3 perp = v3_madd(q, l->dir, -sy);
        int a = (int)((sy - bc->s0) / (bc->s1 - bc->s0) * NB), r = (int)(v3_dot(perp, perp) / (l->radius * l->radius) * NB);
        axial[a < 0 ? 0 : a >= NB ? NB - 1 : a]++;
        radial[r < 0 ? 0 : r >= NB ? NB - 1 : r]++;
    }
}

static double axial_chi2(const rd_scene *s, vec3 x, const double *obs, int *dof)
{
    const rd_beam_connect *bc = &s->beam_connect;
    pdf_ctx k = {s, x};
    double frac[NB], h = (bc->s1 - bc->s0) / NB;
    /* 4000 intervals a bin: the sharpest feature, the equiangular peak of a vertex at the beam's
     * radius (0.2), spans several bins of 2.4/64 */
    for (int i = 0; i < NB; i++) frac[i] = rt_simpson(axial_pdf, &k, bc->s0 + i * h, bc->s0 + (i + 1) * h, 4000);
    return rt_chi2_pooled(obs, frac, NB, NS, dof);
}

Test(beam_connect, sampler_chi_square)
{
    rd_scene *s = rt_scene("bc.json", beam_fog_json(homogeneous, ",\"beam_connect\":true"));
    const rd_beam_connect *bc = &s->beam_connect;
    cr_assert(bc->light == 0 && bc->s1 > bc->s0);
    const vec3 xs[] = {
        {0.1, 0.5, 0.2},   /* beside the beam, upstream of its middle */
        {0.6, 0.0, 0.4},   /* near the beam, downstream */
        {-0.3, 0.16, -0.09}, /* inside the cylinder */
        {-0.9, -0.7, 0.7}, /* a far corner */
    };
    double z = 3.719; /* p = 1e-4 */
    for (size_t i = 0; i < sizeof xs / sizeof xs[0]; i++) {
        pdf_ctx k = {s, xs[i]};
        double total = rt_simpson(axial_pdf, &k, bc->s0, bc->s1, 64 * 4000);
        cr_expect(fabs(total - 1.0) < 1e-3, "vertex %zu: the axial pdf integrates to %.6f", i, total);
        double axial[NB], radial[NB], frac[NB];
        sample_bins(s, xs[i], 100 + i, axial, radial);
        int dof;
        double chi2 = axial_chi2(s, xs[i], axial, &dof);
        cr_expect(chi2 < rt_chi2_quantile(dof, z), "vertex %zu: axial chi2 %.1f, dof %d", i, chi2, dof);
        for (int b = 0; b < NB; b++) frac[b] = 1.0 / NB;
        chi2 = rt_chi2_pooled(radial, frac, NB, NS, &dof);
        cr_expect(chi2 < rt_chi2_quantile(dof, z), "vertex %zu: radial chi2 %.1f, dof %d", i, chi2, dof);
        cr_log_info("vertex %zu: pdf total %.6f", i, total);
    }
    rd_scene_free(s);
}

Test(beam_connect, chi_square_rejects_a_wrong_pdf)
{
    /* The samples drawn from one vertex, judged against the pdf seen from a vertex 0.1 away. */
    rd_scene *s = rt_scene("bc.json", beam_fog_json(homogeneous, ",\"beam_connect\":true"));
    vec3 x = {0.1, 0.5, 0.2}, x_moved = {0.1, 0.4, 0.2};
    double axial[NB], radial[NB];
    sample_bins(s, x, 100, axial, radial);
    int dof;
    double chi2 = axial_chi2(s, x_moved, axial, &dof);
    cr_expect(chi2 > rt_chi2_quantile(dof, 3.719), "a wrong pdf passed: chi2 %.1f, dof %d", chi2, dof);
    rd_scene_free(s);
}

/* `delta` with and without the connections, seeds apart. */
/* `delta` on scene a (the connections off) against `method` on scene b (on): the same image.
 * Frees both scenes. */
static void expect_same_image(rd_scene *a, rd_scene *b, const char *method, int spp_a, int spp_b, uint64_t seed_a,
                              uint64_t seed_b, const char *what)
{
    cr_assert(a->beam_connect.light == -1 && b->beam_connect.light == 0);
    rd_render_result ra = rt_render(a, "delta", spp_a, seed_a, NULL), rb = rt_render(b, method, spp_b, seed_b, NULL);
    rt_expect_same(&ra, &rb, what);
    cr_log_info("%s: variance per pixel %.3g without, %.3g with the connections", what, rt_mean_pixel_var(&ra),
                rt_mean_pixel_var(&rb));
    rd_render_result_free(&ra);
    rd_render_result_free(&rb);
    rd_scene_free(a);
    rd_scene_free(b);
}

static void expect_delta_s_image(const char *medium, int spp, const char *what)
{
    rd_scene *a = rt_scene("bc_off.json", beam_fog_json(medium, ",\"beam_connect\":false"));
    rd_scene *b = rt_scene("bc_on.json", beam_fog_json(medium, ",\"beam_connect\":true"));
    expect_same_image(a, b, "delta", spp, spp, 11, 12, what);
}

/* The same with a scene of the caller's: `fmt` is its JSON, its slots filled from the
 * arguments but the last, written %%s, the value of settings.beam_connect. */
static void expect_delta_s_image_of(int spp, uint64_t seed, const char *what, const char *fmt, ...)
{
    char tmpl[4096], a_json[4096], b_json[4096];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(tmpl, sizeof tmpl, fmt, ap);
    va_end(ap);
    snprintf(a_json, sizeof a_json, tmpl, "false");
    snprintf(b_json, sizeof b_json, tmpl, "true");
    rd_scene *a = rt_scene("bc_of_off.json", a_json), *b = rt_scene("bc_of_on.json", b_json);
    expect_same_image(a, b, "delta", spp, spp, seed, seed + 1, what);
}

Test(beam_connect, homogeneous_fog_gives_delta_s_image, .timeout = 120)
{
    expect_delta_s_image(homogeneous, 1024, "homogeneous, g 0.6");
}

/* A second light, so that the beam's share of next-event estimation is below 1 and the
 * collision's weight w_A must follow the light picked (applied to every pick it fails at z 10):
 * a bright sphere light inside the beam, two scattering events at most. */
Test(beam_connect, a_second_light_gives_delta_s_image, .timeout = 120)
{
    static const char *fmt =
        BC_CAMERA
        "\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-1,-0.8,-0.8],\"max\":[1,0.8,0.8]},%s}],"
        BC_BEAM ",{\"type\":\"sphere\",\"center\":[0.28,0.04,0.08],"
        "\"radius\":0.15,\"radiance\":[10,10,10]}],\"background\":0,"
        "\"settings\":{\"max_depth\":2,\"rr_depth\":3,\"beam_connect\":%%s}}";
    expect_delta_s_image_of(2048, 31, "a sphere light in the beam, max_depth 2", fmt, homogeneous);
}

/* With max_depth 1 a connection's vertex would be a second scattering event: none is made, no
 * random number drawn, so the image is `delta`'s without the connections bit for bit (plain
 * `delta`: without the connections its "tiles", the default, would sample the beam). */
Test(beam_connect, max_depth_1_makes_no_connection)
{
    rd_scene *a = rt_scene("bc_d1_off.json", beam_fog_json(homogeneous, ",\"beam_connect\":false,\"equiangular\":false"));
    rd_scene *b = rt_scene("bc_d1_on.json", beam_fog_json(homogeneous, ",\"beam_connect\":true,\"equiangular\":false"));
    a->settings.max_depth = b->settings.max_depth = 1;
    rd_render_result ra = rt_render(a, "delta", 16, 41, NULL), rb = rt_render(b, "delta", 16, 41, NULL);
    size_t n = (size_t)ra.image.w * ra.image.h * 3;
    cr_assert(memcmp(ra.image.rgb, rb.image.rgb, n * sizeof *ra.image.rgb) == 0, "max_depth 1: the images differ");
    rd_render_result_free(&ra);
    rd_render_result_free(&rb);
    rd_scene_free(a);
    rd_scene_free(b);
}

/* A sphere light ends every flight that meets it, so it blocks every connection that crosses
 * it: from a vertex beside a sphere light that hides part of the beam, each connection whose
 * point y (drawn again from a copy of the random numbers) lies behind the sphere is 0, and some
 * of the others are not. */
Test(beam_connect, a_sphere_light_blocks_the_connections_that_cross_it)
{
    static const char *fmt =
        "{\"camera\":{\"position\":[0,0,3.2],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
        "\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-1,-0.8,-0.8],\"max\":[1,0.8,0.8]},%s}],"
        BC_BEAM ",{\"type\":\"sphere\",\"center\":[0,-0.2,0.15],"
        "\"radius\":0.12,\"radiance\":1}],\"settings\":{\"beam_connect\":true}}";
    char json[2048];
    snprintf(json, sizeof json, fmt, homogeneous);
    rd_scene *s = rt_scene("bc_sph.json", json);
    cr_assert(s->beam_connect.light == 0);
    vec3 x = {0.0, -0.5, 0.3}, c = {0.0, -0.2, 0.15};
    double R = 0.12;
    pcg32 rng = pcg32_seed(51, 7, 13);
    rd_track_counters k = {0};
    int blocked = 0, blocked_lit = 0, open_lit = 0;
    for (int i = 0; i < 20000; i++) {
        pcg32 copy = rng; /* the connection's first four numbers draw its point */
        double u[4] = {pcg32_uniform(&copy), pcg32_uniform(&copy), pcg32_uniform(&copy), pcg32_uniform(&copy)};
        vec3 y;
        double pdf;
        int drawn = rd_beam_connect_sample(s, x, u[0], u[1], u[2], u[3], &y, &pdf);
        vec3 L = rd_beam_connect_estimate(s, rd_scene_region_at(s, x), x, v3(0, 0, -1), &s->media[0], NULL, &rng, &k);
        if (!drawn) continue;
        /* does the segment x -> y pass within R of the sphere's centre? */
        vec3 d = v3_sub(y, x), q = v3_sub(c, x);
        double t = fmin(fmax(v3_dot(q, d) / v3_dot(d, d), 0.0), 1.0);
        vec3 e = v3_sub(q, v3_scale(d, t));
        int crosses = v3_dot(e, e) < R * R;
        blocked += crosses;
        blocked_lit += crosses && v3_lum(L) != 0.0;
        open_lit += !crosses && v3_lum(L) != 0.0;
    }
    cr_expect(blocked > 200, "only %d connections cross the sphere: the test would prove little", blocked);
    cr_expect(blocked_lit == 0, "%d connections through the sphere light carried light", blocked_lit);
    cr_expect(open_lit > 100, "only %d open connections carried light", open_lit);
    cr_log_info("sphere: %d of 20000 connections cross it, %d open ones carry light", blocked, open_lit);
    rd_scene_free(s);
}

Test(beam_connect, forward_scattering_noise_gives_delta_s_image, .timeout = 120)
{
    expect_delta_s_image("\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":2,\"gain\":0.5,\"lacunarity\":2,"
                         "\"amplitude\":1.5,\"seed\":3},\"sigma_t\":1.2,\"albedo\":0.95,\"g\":0.85",
                         1024, "noise, g 0.85");
}

/* Surfaces: the beam crosses a glass ball holding a denser medium (a connection across its
 * surface is blocked: the path reaches the inside only by refraction, and its collision there
 * takes no weight w_A) and an opaque plate that shades part of it (a connection through the
 * plate would bring the lit side's light to the shaded side). */
Test(beam_connect, a_glass_ball_and_an_opaque_plate_give_delta_s_image, .timeout = 120)
{
    static const char *fmt =
        BC_CAMERA
        BC_FOG_FILL
        "{\"name\":\"dense\",\"bounds\":{\"min\":[-0.1,-0.1,-0.15],\"max\":[0.3,0.3,0.2]},"
        "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":4,\"albedo\":0.9,\"g\":0.3}],"
        "\"shapes\":[{\"name\":\"ball\",\"file\":\"%s/scenes/data/icosphere-3.obj\","
        "\"transform\":{\"scale\":0.15,\"translate\":[0.1,0.08,0.03]},"
        "\"material\":{\"type\":\"dielectric\",\"ior\":1.5},\"inside\":\"dense\",\"outside\":\"fog\"},"
        "{\"name\":\"plate\",\"file\":\"%s/scenes/data/box.obj\","
        "\"transform\":{\"scale\":[0.05,0.2,0.35],\"translate\":[-0.4,0.35,-0.1]},"
        "\"material\":{\"type\":\"diffuse\",\"albedo\":0.5},\"inside\":null,\"outside\":\"fog\"}],"
        BC_TAIL;
    char cwd[1024];
    cr_assert(getcwd(cwd, sizeof cwd) != NULL);
    expect_delta_s_image_of(2048, 61, "a glass ball and an opaque plate", fmt, homogeneous, cwd, cwd);
}

/* Two box media side by side along the beam: forward-scattering haze where it enters, fog
 * beyond. A connection from a vertex in one to a point in the other takes the point's medium
 * (its sigma_s, albedo and phase), not the vertex's. */
Test(beam_connect, two_media_along_the_beam_give_delta_s_image, .timeout = 120)
{
    static const char *fmt =
        BC_CAMERA
        "\"media\":[{\"name\":\"haze\",\"bounds\":{\"min\":[-1,-0.8,-0.8],\"max\":[-0.2,0.8,0.8]},"
        "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":2,\"albedo\":0.95,\"g\":0.85},"
        "{\"name\":\"fog\",\"bounds\":{\"min\":[-0.2,-0.8,-0.8],\"max\":[1,0.8,0.8]},%s}],"
        BC_TAIL;
    expect_delta_s_image_of(4096, 71, "two media along the beam", fmt, homogeneous);
}

/* An index-matched interface around a ball of a denser medium in the beam: the path crosses it
 * without an event, but its collision beyond takes no weight w_A (the flight met a surface), so
 * a connection across it must be blocked too, and one inside the ball takes the ball's medium. */
Test(beam_connect, an_interface_ball_gives_delta_s_image, .timeout = 120)
{
    static const char *fmt =
        BC_CAMERA
        BC_FOG_FILL
        "{\"name\":\"dense\",\"bounds\":{\"min\":[-0.45,-0.45,-0.45],\"max\":[0.45,0.45,0.45]},"
        "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":4,\"albedo\":0.9,\"g\":0.8}],"
        "\"shapes\":[{\"name\":\"ball\",\"file\":\"%s/scenes/data/icosphere-3.obj\","
        "\"transform\":{\"scale\":0.4,\"translate\":[0.0,0.05,0.0]},"
        "\"material\":{\"type\":\"interface\"},\"inside\":\"dense\",\"outside\":\"fog\"}],"
        BC_TAIL;
    char cwd[1024];
    cr_assert(getcwd(cwd, sizeof cwd) != NULL);
    expect_delta_s_image_of(2048, 91, "an interface ball", fmt, homogeneous, cwd);
}

/* A box medium of density 0 inside the scene-wide fog, in the beam: a clear hole for delta
 * tracking (transport/tracking.c rd_media_intervals) as for the connection's point
 * (rd_scene_medium_at). */
Test(beam_connect, a_clear_box_in_the_fog_gives_delta_s_image, .timeout = 120)
{
    static const char *fmt =
        BC_CAMERA
        BC_FOG_FILL
        "{\"name\":\"hole\",\"bounds\":{\"min\":[-0.35,-0.5,-0.5],\"max\":[0.35,0.6,0.6]},"
        "\"density\":{\"type\":\"constant\",\"value\":0},\"sigma_t\":1}],"
        BC_TAIL;
    expect_delta_s_image_of(2048, 81, "a clear box in the fog", fmt, homogeneous);
}

/* guided-unbiased's own paths connect too (their guided directions and splitting: the
 * connection's weight against the direction mixture, a split vertex's one connection for all
 * its copies): the method alone (the selection off) gives `delta`'s image. */
Test(beam_connect, guided_unbiased_s_paths_connect_and_keep_delta_s_image, .timeout = 120)
{
    rd_scene *a = rt_scene("bc_off.json", beam_fog_json(homogeneous, ",\"beam_connect\":false"));
    rd_scene *b = rt_scene("bc_gu.json", beam_fog_json(homogeneous, ",\"beam_connect\":true"));
    expect_same_image(a, b, "guided-unbiased", 1024, 512, 15, 22, "guided-unbiased with the connections");
}

/* "auto", the default, is on where the connections can run and off, without an error, where
 * it would refuse. */
Test(beam_connect, auto_is_on_where_it_can_run)
{
    rd_scene *s = rt_scene("bc_auto.json", beam_fog_json(homogeneous, ""));
    cr_expect(s->settings.beam_connect == RD_BC_AUTO && s->beam_connect.light == 0, "the default is on for a narrow beam");
    /* the breadth (load.c): the cylinder fills 5.2% of the box; (1 - |g|)^2 is 0.16 for g 0.6
     * above and for g -0.6, 1 for g 0 */
    cr_expect(fabs(s->beam_connect.breadth - 0.0516 * 0.16) < 0.001, "breadth %g", s->beam_connect.breadth);
    rd_scene_free(s);
    s = rt_scene("bc_auto_back.json",
                 beam_fog_json("\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1.5,\"g\":-0.6", ""));
    cr_expect(s->beam_connect.light == 0 && fabs(s->beam_connect.breadth - 0.0516 * 0.16) < 0.001,
              "a backward lobe as narrow: breadth %g", s->beam_connect.breadth);
    rd_scene_free(s);
    s = rt_scene("bc_auto_broad.json",
                 beam_fog_json("\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1.5", ""));
    cr_expect(s->beam_connect.light == -1 && s->beam_connect.off && strstr(s->beam_connect.off, "broad") &&
                  strstr(s->beam_connect.off, "not below 0.014"),
              "auto connects to a broad beam (breadth %g): %s", s->beam_connect.breadth,
              s->beam_connect.off ? s->beam_connect.off : "(on)");
    rd_scene_free(s);
    s = rt_scene("bc_auto_broad_on.json",
                 beam_fog_json("\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1.5",
                               ",\"beam_connect\":true"));
    cr_expect(s->beam_connect.light == 0, "true connects to a broad beam");
    rd_scene_free(s);
    s = rt_scene("bc_auto_eq.json", beam_fog_json(homogeneous, ",\"equiangular\":true"));
    cr_expect(s->beam_connect.light == -1, "auto connects where `true` samples the chord");
    rd_scene_free(s);
    s = rt_scene("bc_auto_sun.json",
                 "{\"camera\":{\"position\":[0,0,3],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                 "\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                 "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1}],"
                 "\"lights\":[{\"type\":\"directional\",\"direction\":[1,0,0],\"irradiance\":1}]}");
    cr_expect(s->beam_connect.light == -1, "a sun without a radius is no beam");
    rd_scene_free(s);
}

Test(beam_connect, what_it_refuses)
{
    static const char *const bad[][2] = {
        {",\"beam_connect\":1", "expected true, false or \"auto\""},
        {",\"beam_connect\":\"sometimes\"", "expected true, false or \"auto\""},
        {",\"beam_connect\":true,\"equiangular\":true", "settings.equiangular"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char path[256], err[RD_ERRLEN] = "";
        snprintf(path, sizeof path, "%s/bc_bad.json", rt_tmpdir());
        const char *json = beam_fog_json(homogeneous, bad[i][0]);
        rt_write_file(path, json, strlen(json));
        rd_scene *s = NULL;
        cr_expect(rd_scene_load(&s, path, NULL, 0, err, sizeof err) != RD_OK, "%s accepted", bad[i][0]);
        cr_expect(strstr(err, "settings.beam_connect") && strstr(err, bad[i][1]), "%s: message \"%s\"", bad[i][0], err);
        cr_expect(strchr(err, '\n') == NULL, "one line: \"%s\"", err);
        rd_scene_free(s);
    }
    /* "tiles" leaves the connections on (since session 72: its tiles then sample no connected
     * beam, tests/test_select.c a_beam_that_delta_s_path_connects_to_makes_no_third_estimator) */
    {
        char path[256], err[RD_ERRLEN] = "";
        snprintf(path, sizeof path, "%s/bc_tiles.json", rt_tmpdir());
        const char *json = beam_fog_json(homogeneous, ",\"beam_connect\":true,\"equiangular\":\"tiles\"");
        rt_write_file(path, json, strlen(json));
        rd_scene *s = NULL;
        cr_expect(rd_scene_load(&s, path, NULL, 0, err, sizeof err) == RD_OK, "true with \"tiles\": %s", err);
        cr_expect(s && s->beam_connect.light >= 0, "true with \"tiles\" does not connect");
        rd_scene_free(s);
    }
    /* no beam: a sun without a radius; a beam that misses the media */
    const char *no_beam =
        "{\"camera\":{\"position\":[0,0,3],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
        "\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1}],"
        "\"lights\":[{\"type\":\"directional\",\"direction\":[1,0,0],\"irradiance\":1}],"
        "\"settings\":{\"beam_connect\":true}}";
    const char *missing =
        "{\"camera\":{\"position\":[0,0,3],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
        "\"media\":[{\"name\":\"a\",\"bounds\":{\"min\":[-1,-1,-1],\"max\":[0,1,1]},\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1},"
        "{\"name\":\"b\",\"bounds\":{\"min\":[0,-1,-1],\"max\":[1,1,1]},\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1}],"
        "\"lights\":[{\"type\":\"directional\",\"direction\":[1,0,0],\"irradiance\":1,\"radius\":0.2,\"center\":[0,3,0]}],"
        "\"settings\":{\"beam_connect\":true}}";
    const char *jsons[] = {no_beam, missing}, *want[] = {"directional light with a radius", "crosses a medium"};
    for (int i = 0; i < 2; i++) {
        char path[256], err[RD_ERRLEN] = "";
        snprintf(path, sizeof path, "%s/bc_bad2.json", rt_tmpdir());
        rt_write_file(path, jsons[i], strlen(jsons[i]));
        rd_scene *s = NULL;
        cr_expect(rd_scene_load(&s, path, NULL, 0, err, sizeof err) != RD_OK, "case %d accepted", i);
        cr_expect(strstr(err, "settings.beam_connect") && strstr(err, want[i]), "case %d: message \"%s\"", i, err);
        rd_scene_free(s);
    }
}
