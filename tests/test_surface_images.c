/* The transport with surfaces (issue 14 step 2: transport/path.c, integrators/march.c,
 * integrators/guided_unbiased.c, bake/photons.c) judged on whole images against independent
 * estimators of the same image:
 *  1. an `interface` cube around a bound medium renders the box medium's image (delta, the
 *     guided marcher with ls = nee; and with a scene-wide medium outside it), and the photon
 *     tracer absorbs the same power;
 *  2. a dielectric of index 1 around a medium is invisible (delta);
 *  3. delta and guided-unbiased agree with a glass sphere of forward-scattering medium inside a
 *     scene-wide isotropic medium, without and with a diffuse floor;
 *  4. the marchers (ls = nee, single scattering) agree with delta when every camera path that
 *     reaches the medium went through a glass sphere (two Fresnel events, chosen per segment);
 *  W. a white furnace seen from inside a glass sphere: n^2 times the environment, exactly;
 *  5. a diffuse floor lit by a point light, in vacuum (exactly (rho/pi) I cos / d^2) and in a
 *     homogeneous scene-wide medium at max_depth 1 (single scattering along the camera ray plus
 *     the floor's attenuated direct light, integrated here by Simpson's rule), against delta.
 *
 * Statistics. Image comparisons are z-scores of the image mean and of 8x8-pixel region means of
 * luminance (rt_compare_images), each standard error from the films' per-pixel standard errors
 * of both images (pixels are independent; fixed seeds). Under equal expectations each z is
 * standard normal: the image bound 5 (false alarm 5.7e-7) and the region bound 4.5 (with at most
 * 12 regions, below 1e-4 per comparison). Photon powers: K independent seeds per scene, the
 * standard error from the spread of the K means, bound 5 on the z of the difference. Against
 * the quadrature (test 5) the standard error is the render's alone (the quadrature's error is
 * below 1e-6 relative, checked by halving its step).
 *
 * 4b. the same at max_depth 2, where neither may scatter behind the glass (the marchers once
 *     counted a segment's in-scattering as no event: z -122 before the fix). */
#include "support/rd_test.h"
#include "integrators/rd_probes.h"
#include "bake/rd_photons.h"

#include "photonmap.h"

/* ---- helpers ------------------------------------------------------------------------------- */

static const char *tmp_file(const char *name, const char *text)
{
    static char path[4][256];
    static int k = 0;
    k = (k + 1) % 4;
    snprintf(path[k], sizeof path[k], "%s/%s", rt_tmpdir(), name);
    rt_write_file(path[k], text, strlen(text));
    return path[k];
}

/* The unit cube [0,1]^3 as six quads wound counter-clockwise seen from outside (as in
 * test_geom.c), written as <tmp>/cube.obj. */
static void write_cube(void)
{
    tmp_file("cube.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                         "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n");
}

/* A floor quad at y = -1 over [-3,3]^2, front (counter-clockwise) facing +y: <tmp>/floor.obj. */
static void write_floor(void)
{
    tmp_file("floor.obj", "v -3 -1 -3\nv -3 -1 3\nv 3 -1 3\nv 3 -1 -3\nf 1 2 3 4\n");
}

/* Absolute path of the repository's icosphere (radius 1 at the origin; tests run from the
 * repository root, as test_geom.c's). */
static const char *icosphere(void)
{
    static char path[1024];
    char cwd[768];
    cr_assert(getcwd(cwd, sizeof cwd) != NULL);
    snprintf(path, sizeof path, "%s/scenes/data/icosphere-3.obj", cwd);
    cr_assert(access(path, R_OK) == 0, "%s is missing (scripts/make-meshes.sh)", path);
    return path;
}

/* The icosphere without its vertex normals (flat triangles: the dielectric's shading normal is
 * the geometric one), written as <tmp>/ico-flat.obj; its path relative to the scene folder. */
static const char *icosphere_flat(void)
{
    FILE *in = fopen(icosphere(), "r");
    cr_assert(in != NULL);
    char out[256], line[256];
    snprintf(out, sizeof out, "%s/ico-flat.obj", rt_tmpdir());
    FILE *o = fopen(out, "w");
    cr_assert(o != NULL);
    while (fgets(line, sizeof line, in)) {
        if (!strncmp(line, "vn", 2)) continue;
        if (line[0] == 'f') {
            unsigned a, b, c, na, nb, nc;
            cr_assert(sscanf(line, "f %u//%u %u//%u %u//%u", &a, &na, &b, &nb, &c, &nc) == 6, "%s", line);
            fprintf(o, "f %u %u %u\n", a, b, c);
        } else fputs(line, o);
    }
    fclose(in);
    fclose(o);
    return "ico-flat.obj";
}

static void release(rd_render_result *a, rd_render_result *b)
{
    rd_render_result_free(a);
    rd_render_result_free(b);
}

/* ---- 1. an interface around a bound medium is the box medium ------------------------------- */

/* A heterogeneous anisotropic medium in [-1,1]^3 lit by a spot, a point light and the
 * environment; `shapes` empty: a box medium; else the shapes (and the medium is bound). */
static const char *t1_json(const char *shapes, const char *extra)
{
    static char buf[4096];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[0,0.4,4.2],\"look_at\":[0,0,0],\"fov\":36,\"resolution\":[24,18]},"
             "\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
             "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":2,\"amplitude\":2,\"seed\":7},"
             "\"sigma_t\":2.5,\"albedo\":0.85,\"g\":0.5}],"
             "\"lights\":[{\"type\":\"spot\",\"position\":[-2.5,2,1.5],\"look_at\":[0,0,0],\"angle\":40,"
             "\"falloff\":6,\"intensity\":[20,16,12]},"
             "{\"type\":\"point\",\"position\":[1.8,1.4,1.6],\"intensity\":[2,3,4]},"
             "{\"type\":\"environment\",\"radiance\":[0.1,0.12,0.15]}],"
             "\"photons\":{\"count\":20000},\"guide\":{\"bands\":4},"
             "\"settings\":{\"max_depth\":16,\"rr_depth\":3}%s%s}",
             shapes, extra);
    return buf;
}

/* The cube scaled to [-1.1,1.1]^3: a margin of empty bound medium (density 0 outside its
 * bounds) between the medium and the surface. */
#define T1_INTERFACE ",\"shapes\":[{\"name\":\"box\",\"file\":\"cube.obj\"," \
    "\"transform\":{\"scale\":2.2,\"translate\":[-1.1,-1.1,-1.1]},"            \
    "\"material\":{\"type\":\"interface\"},\"inside\":\"fog\"}]"

Test(surface_images, interface_around_a_bound_medium_renders_the_box_medium, .timeout = 300)
{
    write_cube();
    rd_scene *box = rt_scene("t1_box.json", t1_json("", ""));
    rd_scene *itf = rt_scene("t1_itf.json", t1_json(T1_INTERFACE, ""));
    cr_assert(itf->n_shapes == 1 && itf->media[0].bound && !box->media[0].bound);
    rd_render_result a = rt_render(box, "delta", 96, 101, NULL);
    rd_render_result b = rt_render(itf, "delta", 96, 102, NULL);
    rt_expect_same(&a, &b, "delta: box medium vs interface cube");
    release(&a, &b);
    /* The guided marcher, single scattering by next-event estimation (its guide baked from
     * each scene's own photons). */
    rd_scene *boxm = rt_scene("t1_boxm.json", t1_json("", ",\"march\":{\"ls\":\"nee\",\"samples\":8}"));
    rd_scene *itfm = rt_scene("t1_itfm.json", t1_json(T1_INTERFACE, ",\"march\":{\"ls\":\"nee\",\"samples\":8}"));
    a = rt_render(boxm, "guided", 32, 103, NULL);
    b = rt_render(itfm, "guided", 32, 104, NULL);
    rt_expect_same(&a, &b, "guided (ls = nee): box medium vs interface cube");
    release(&a, &b);
    rd_scene_free(boxm);
    rd_scene_free(itfm);
    rd_scene_free(box);
    rd_scene_free(itf);
}

/* The same medium inside a scene-wide medium ("room"): as a box medium in the open region, and
 * bound inside an interface cube on its bounds with the room outside. A shadow ray from the
 * fog crosses the interface into the room (rd_shadow_transmittance: the region changes). */
static const char *t1b_json(int shapes)
{
    static char buf[4096];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[0,0.4,4.2],\"look_at\":[0,0,0],\"fov\":36,\"resolution\":[24,18]},"
             "\"medium\":\"room\","
             "\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
             "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":2,\"amplitude\":2,\"seed\":7},"
             "\"sigma_t\":2.5,\"albedo\":0.85,\"g\":0.5},"
             "{\"name\":\"room\",\"bounds\":{\"min\":[-3,-3,-3],\"max\":[3,3,3]},"
             "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":0.8,\"albedo\":0.5,\"g\":0}],"
             "\"lights\":[{\"type\":\"spot\",\"position\":[-2.5,2,1.5],\"look_at\":[0,0,0],\"angle\":40,"
             "\"falloff\":6,\"intensity\":[20,16,12]},"
             "{\"type\":\"point\",\"position\":[1.8,1.4,1.6],\"intensity\":[2,3,4]}],"
             "\"settings\":{\"max_depth\":16,\"rr_depth\":3}%s}",
             shapes ? ",\"shapes\":[{\"name\":\"box\",\"file\":\"cube.obj\","
                      "\"transform\":{\"scale\":2,\"translate\":[-1,-1,-1]},"
                      "\"material\":{\"type\":\"interface\"},\"inside\":\"fog\",\"outside\":\"room\"}]"
                    : "");
    return buf;
}

Test(surface_images, interface_between_a_bound_medium_and_the_scene_wide_medium, .timeout = 300)
{
    write_cube();
    rd_scene *box = rt_scene("t1b_box.json", t1b_json(0));
    rd_scene *itf = rt_scene("t1b_itf.json", t1b_json(1));
    cr_assert(itf->n_shapes == 1 && !box->media[0].bound && itf->media[0].bound);
    rd_render_result a = rt_render(box, "delta", 256, 111, NULL);
    rd_render_result b = rt_render(itf, "delta", 256, 112, NULL);
    rt_expect_same(&a, &b, "delta: box medium in a room vs interface cube with the room outside");
    release(&a, &b);
    rd_scene_free(box);
    rd_scene_free(itf);
}

Test(surface_images, interface_around_a_bound_medium_absorbs_the_box_mediums_photon_power, .timeout = 300)
{
    /* The photon tracer's power balance (rd_photon_stats): the power absorbed in the medium
     * and the power the max_depth cut carries, K = 8 seeds of 20000 photons per scene; z of the
     * difference of the means < 5. (Not the escaped power: the environment light's emitted
     * power grows with the scene radius, which the shapes' boxes enlarge.) */
    write_cube();
    rd_scene *sc[2] = {rt_scene("t1p_box.json", t1_json("", "")), rt_scene("t1p_itf.json", t1_json(T1_INTERFACE, ""))};
    enum { K = 8 };
    double m[2][2] = {{0}}, v[2][2] = {{0}}, x[2][2][K];
    for (int i = 0; i < 2; i++) {
        for (int k = 0; k < K; k++) {
            pm_map *map = pm_map_new();
            char err[RD_ERRLEN];
            rd_photon_opts o = {.count = 20000, .store_direct = 1, .max_depth = 4, .seed = 500 + 37 * i + k, .threads = 2};
            rd_photon_stats st;
            cr_assert(rd_trace_photons(sc[i], &o, map, &st, err, sizeof err) == RD_OK, "%s", err);
            x[i][0][k] = st.power_absorbed[0] + st.power_absorbed[1] + st.power_absorbed[2];
            x[i][1][k] = st.power_carried[0] + st.power_carried[1] + st.power_carried[2];
            cr_expect(st.power_absorbed_surfaces[0] == 0.0, "an interface absorbs nothing");
            pm_map_free(map);
        }
        for (int q = 0; q < 2; q++) {
            for (int k = 0; k < K; k++) m[i][q] += x[i][q][k] / K;
            for (int k = 0; k < K; k++) v[i][q] += (x[i][q][k] - m[i][q]) * (x[i][q][k] - m[i][q]) / (K - 1);
        }
    }
    const char *what[2] = {"absorbed", "carried past max_depth 4"};
    for (int q = 0; q < 2; q++) {
        double se = sqrt(v[0][q] / K + v[1][q] / K), z = (m[0][q] - m[1][q]) / se;
        cr_expect(se > 0.0, "%s: the estimates must be random", what[q]);
        /* the test's power: a change of 15% would stand 5 standard errors out */
        cr_expect(se < 0.03 * m[0][q], "%s: standard error %.3g too large for mean %.3g", what[q], se, m[0][q]);
        cr_expect(fabs(z) < 5.0, "%s power: box %.5g, interface %.5g (z = %.2f)", what[q], m[0][q], m[1][q], z);
        cr_log_info("%s power: box %.5g interface %.5g (se %.2g) z %.2f", what[q], m[0][q], m[1][q], se, z);
    }
    rd_scene_free(sc[0]);
    rd_scene_free(sc[1]);
}

/* ---- 2. a dielectric of index 1 is invisible ----------------------------------------------- */

Test(surface_images, dielectric_of_index_one_is_invisible, .timeout = 300)
{
    /* Noise in the ellipsoid inscribed in [-1,1]^3 (density 0 outside the unit sphere), inside
     * an icosphere of radius 1.05 of index 1. Lit by the environment and a sphere light:
     * lights a path reaches through the surface (next-event estimation stops at a dielectric,
     * so a point light would leave the medium dark: the estimator's limit, not the surface's). */
    const char *fmt =
        "{\"camera\":{\"position\":[0,0.4,4.2],\"look_at\":[0,0,0],\"fov\":34,\"resolution\":[24,18]},"
        "\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
        "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":2,\"amplitude\":2,\"seed\":3,"
        "\"shape\":\"ellipsoid\",\"edge\":0.4},\"sigma_t\":3,\"albedo\":0.9,\"g\":0.6}],"
        "\"lights\":[{\"type\":\"sphere\",\"center\":[-2.2,1.4,0.6],\"radius\":0.7,\"radiance\":[4,3.5,3]},"
        "{\"type\":\"environment\",\"radiance\":[0.15,0.2,0.3]}],"
        "\"settings\":{\"max_depth\":16,\"rr_depth\":3}%s}";
    char js[4096], shp[1536];
    snprintf(js, sizeof js, fmt, "");
    rd_scene *s0 = rt_scene("t2_none.json", js);
    snprintf(shp, sizeof shp,
             ",\"shapes\":[{\"name\":\"glass\",\"file\":\"%s\",\"transform\":{\"scale\":1.05},"
             "\"material\":{\"type\":\"dielectric\",\"ior\":1},\"inside\":\"fog\"}]",
             icosphere());
    snprintf(js, sizeof js, fmt, shp);
    rd_scene *s1 = rt_scene("t2_glass.json", js);
    rd_render_result a = rt_render(s0, "delta", 128, 201, NULL);
    rd_render_result b = rt_render(s1, "delta", 128, 202, NULL);
    rt_expect_same(&a, &b, "delta: no shape vs dielectric of index 1");
    release(&a, &b);
    rd_scene_free(s0);
    rd_scene_free(s1);
}

/* A white furnace seen from inside glass: the camera at the centre of a glass sphere (index
 * 1.5, radius 2, flat triangles) of albedo-1 medium, under a uniform environment of radiance 1.
 * Nothing is absorbed and every path ends by refracting out once more than in: a camera path
 * carries radiance, whose L / n^2 is invariant (Veach 1997 eq. 5.13), so every pixel sees
 * n^2 = 2.25. Every event's weight is 1 (albedo 1; Fresnel choice) but the last refraction's
 * 1/eta^2, so each sample is exactly 2.25 and the check is exact up to float round-off. Since
 * every light is outside the glass in the other tests, a camera path there crosses the surface
 * out as often as in and the (n_i/n_t)^2 factors cancel: this is the one test that sees them.
 * (With the icosphere's vertex normals as shading normals some paths die where the sampled
 * direction leaves on the wrong side of the geometric normal: the report measures that loss.) */
Test(surface_images, white_furnace_inside_a_glass_sphere_sees_n_squared, .timeout = 300)
{
    char js[2048];
    snprintf(js, sizeof js,
             "{\"camera\":{\"position\":[0,0,0],\"look_at\":[0,0,-1],\"fov\":60,\"resolution\":[8,6]},"
             "\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-2,-2,-2],\"max\":[2,2,2]},"
             "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1,\"albedo\":1,\"g\":0.5}],"
             "\"shapes\":[{\"name\":\"glass\",\"file\":\"%s\",\"transform\":{\"scale\":2},"
             "\"material\":{\"type\":\"dielectric\",\"ior\":1.5},\"inside\":\"fog\"}],"
             "\"lights\":[{\"type\":\"environment\",\"radiance\":1}],"
             "\"settings\":{\"max_depth\":100000,\"rr_depth\":3}}",
             icosphere_flat());
    rd_scene *s = rt_scene("t_furnace.json", js);
    rd_render_result r = rt_render(s, "delta", 64, 601, NULL);
    int n = r.image.w * r.image.h;
    double sum = 0.0;
    for (int i = 0; i < n; i++) {
        double v = r.image.rgb[3 * i + 1];
        cr_expect(fabs(v - 2.25) < 1e-5, "pixel %d: %.7f, expected 2.25", i, v);
        sum += v;
    }
    cr_log_info("furnace inside glass: mean %.7f (expected 2.25)", sum / n);
    rd_render_result_free(&r);
    rd_scene_free(s);
}

/* ---- 3. delta and guided-unbiased with a dielectric boundary ------------------------------- */

/* A glass icosphere (radius 0.8, index 1.5) of forward-scattering medium inside a scene-wide
 * isotropic medium, a spot and a point light; `floor`: a diffuse floor at y = -1 too. */
static const char *t3_json(int floor)
{
    static char buf[4096];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[0,0.6,4.2],\"look_at\":[0,-0.2,0],\"fov\":40,\"resolution\":[24,18]},"
             "\"medium\":\"room\","
             "\"media\":[{\"name\":\"room\",\"bounds\":{\"min\":[-3,-1,-3],\"max\":[3,3,5]},"
             "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":0.25,\"albedo\":0.9,\"g\":0},"
             "{\"name\":\"dense\",\"bounds\":{\"min\":[-0.8,-0.8,-0.8],\"max\":[0.8,0.8,0.8]},"
             "\"density\":{\"type\":\"noise\",\"octaves\":2,\"frequency\":2,\"amplitude\":1,\"seed\":5},"
             "\"sigma_t\":4,\"albedo\":0.95,\"g\":0.8}],"
             "\"shapes\":[{\"name\":\"glass\",\"file\":\"%s\",\"transform\":{\"scale\":0.8},"
             "\"material\":{\"type\":\"dielectric\",\"ior\":1.5},\"inside\":\"dense\",\"outside\":\"room\"}%s],"
             "\"lights\":[{\"type\":\"spot\",\"position\":[-1.5,2.5,1],\"look_at\":[0,0,0],\"angle\":30,"
             "\"falloff\":5,\"intensity\":[30,25,20]},"
             "{\"type\":\"point\",\"position\":[1.6,1.2,1.5],\"intensity\":[2,2,3]}],"
             "\"photons\":{\"count\":10000},\"guide\":{\"bands\":4,\"distances\":true,\"distance_tau_max\":1e9},"
             "\"settings\":{\"max_depth\":24,\"rr_depth\":3}}",
             icosphere(),
             floor ? ",{\"name\":\"floor\",\"file\":\"floor.obj\",\"material\":{\"type\":\"diffuse\",\"albedo\":0.6},"
                     "\"inside\":\"room\",\"outside\":\"room\"}"
                   : "");
    return buf;
}

Test(surface_images, guided_unbiased_equals_delta_through_a_glass_sphere, .timeout = 600)
{
    write_floor();
    for (int floor = 0; floor < 2; floor++) {
        rd_scene *s = rt_scene("t3.json", t3_json(floor));
        rd_render_result d = rt_render(s, "delta", 96, 301 + 2 * floor, NULL);
        rd_render_result g = rt_render(s, "guided-unbiased", 64, 302 + 2 * floor, NULL);
        rt_expect_same(&d, &g, floor ? "delta vs guided-unbiased, glass sphere and floor" : "delta vs guided-unbiased, glass sphere");
        release(&d, &g);
        rd_scene_free(s);
    }
}

/* ---- 4. the marchers through a glass sphere -------------------------------------------------- */

/* The camera at z = 3 sees only a glass sphere (radius 1, index 1.5; vertical fov 14 degrees,
 * so every camera ray is within 11.6 degrees of the axis and hits it at incidence i below 37
 * degrees), and behind it a box of heterogeneous medium lit by a spot and the environment. A
 * camera path reaches the medium only after exactly 2 Fresnel events (in, out) or 4 or more
 * (two internal reflections): a reflection off the front turns the ray by 180 - 2i > 106
 * degrees, back toward +z; a path out after one internal reflection turns by 180 + 2i - 4r
 * (r the refraction angle; the rainbow's deviation) > 159 degrees, also toward +z, where
 * there is nothing. So at max_depth 3 delta's image behind the glass is single scattering
 * after the 2 events (in, out, scatter = 3 events; a second scattering would be a 4th), the
 * marchers march that segment with single scattering as their source, and both cut the
 * 4-event paths: their expectations are equal. (At max_depth 1, the "single
 * scattering", delta cannot scatter behind the glass at all; at 2 neither does: the test
 * after the next.) */
static const char *t4_json(int max_depth)
{
    static char buf[4096];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[0,0,3],\"look_at\":[0,0,0],\"fov\":14,\"resolution\":[24,18]},"
             "\"media\":[{\"bounds\":{\"min\":[-1.6,-1.2,-4.2],\"max\":[1.6,1.2,-1.6]},"
             "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":1.5,\"amplitude\":2,\"seed\":9},"
             "\"sigma_t\":2,\"albedo\":0.85,\"g\":0.5}],"
             "\"shapes\":[{\"name\":\"glass\",\"file\":\"%s\",\"material\":{\"type\":\"dielectric\",\"ior\":1.5}}],"
             "\"lights\":[{\"type\":\"spot\",\"position\":[2.5,2,-2.4],\"look_at\":[0,0,-2.9],\"angle\":50,"
             "\"falloff\":5,\"intensity\":[30,25,20]},"
             "{\"type\":\"environment\",\"radiance\":[0.05,0.06,0.08]}],"
             "\"photons\":{\"count\":10000},\"march\":{\"ls\":\"nee\",\"samples\":8},"
             "\"settings\":{\"max_depth\":%d}}",
             icosphere(), max_depth);
    return buf;
}

Test(surface_images, marchers_equal_delta_single_scattering_through_a_glass_sphere, .timeout = 300)
{
    rd_scene *s = rt_scene("t4.json", t4_json(3));
    rd_render_result d = rt_render(s, "delta", 256, 401, NULL);
    const char *methods[] = {"guided", "transmittance", "uniform"};
    for (int i = 0; i < 3; i++) {
        rd_render_result m = rt_render(s, methods[i], 32, 402 + i, NULL);
        char what[96];
        snprintf(what, sizeof what, "%s vs delta through a glass sphere", methods[i]);
        rt_expect_same(&d, &m, what);
        rd_render_result_free(&m);
    }
    rd_render_result_free(&d);
    rd_scene_free(s);
}

/* At max_depth 2 delta cannot scatter behind the glass (in, out, scatter would be event 3), so
 * its image there is the environment seen through the glass; the marchers must not march
 * in-scattering on that segment either (integrators/march.c rd_march_radiance: a segment behind
 * k surface events scatters as event k + 1). Before that rule the marchers added single
 * scattering there: z -122 / -57. */
Test(surface_images, marcher_max_depth_counts_in_scattering_like_delta, .timeout = 300)
{
    rd_scene *s = rt_scene("t4d.json", t4_json(2));
    rd_render_result d = rt_render(s, "delta", 128, 411, NULL);
    rd_render_result m = rt_render(s, "transmittance", 16, 412, NULL);
    rt_expect_same(&d, &m, "transmittance vs delta at max_depth 2 through a glass sphere");
    release(&d, &m);
    rd_scene_free(s);
}

/* ---- 5. a diffuse floor under a point light, against quadrature ---------------------------- */

typedef struct {
    ray3 r;
    vec3 light;
    double I, sigma_t, albedo, g;
} ss_ctx;

/* Henyey-Greenstein, written here: p(cos) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^1.5). */
static double hg(double g, double c)
{
    return (1.0 - g * g) / (4.0 * M_PI * pow(1.0 + g * g - 2.0 * g * c, 1.5));
}

/* Single-scattering integrand along the camera ray in a homogeneous medium filling a convex box
 * that holds the camera, the light and the path (RTE, THEORY.md §1):
 * T(0,t) sigma_s p(d . w_l) I T(x, l) / |l - x|^2, with T(a, b) = exp(-sigma_t |b - a|). */
static double ss_integrand(double t, const void *p)
{
    const ss_ctx *c = p;
    vec3 x = ray_at(c->r, t), wl = v3_sub(c->light, x);
    double dl = v3_len(wl);
    wl = v3_scale(wl, 1.0 / dl);
    return exp(-c->sigma_t * t) * c->sigma_t * c->albedo * hg(c->g, v3_dot(c->r.d, wl)) * c->I *
           exp(-c->sigma_t * dl) / (dl * dl);
}

/* The expected pixel value of delta at max_depth 1 for the pixel-centre ray r: single
 * scattering up to the floor (y = -1, |x|, |z| <= 3, albedo rho) or the medium's far side at
 * t_far, plus the floor's direct light (rho/pi) I cos(theta_l) / d^2 attenuated both ways. */
static double floor_expected(ss_ctx c, double rho, double t_far)
{
    double t_end = t_far, floor_L = 0.0;
    if (c.r.d.y < 0.0) {
        double tf = (-1.0 - c.r.o.y) / c.r.d.y;
        vec3 p = ray_at(c.r, tf);
        /* The floor lies on the medium's lower bound: it is met whether or not t_far (the
         * exit through that same plane, up to round-off) comes first. */
        if (tf > 0.0 && fabs(p.x) <= 3.0 && fabs(p.z) <= 3.0) {
            t_end = fmin(tf, t_far);
            vec3 wl = v3_sub(c.light, p);
            double dl = v3_len(wl), cos_l = wl.y / dl;
            floor_L = exp(-c.sigma_t * tf) * rho / M_PI * c.I * cos_l / (dl * dl) * exp(-c.sigma_t * dl);
        }
    }
    if (!(c.sigma_t > 0.0)) return floor_L;
    double q = rt_simpson(ss_integrand, &c, 0.0, t_end, 4096);
    double q2 = rt_simpson(ss_integrand, &c, 0.0, t_end, 2048);
    cr_assert(fabs(q - q2) <= 1e-7 * fabs(q) + 1e-12, "quadrature not converged: %g vs %g", q, q2);
    return q + floor_L;
}

static const char *t5_json(double sigma_t)
{
    static char buf[2048];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[0,1.5,3],\"look_at\":[0,-1,-0.5],\"fov\":50,\"resolution\":[24,18],"
             "\"jitter\":false},"
             "\"medium\":\"air\","
             "\"media\":[{\"name\":\"air\",\"bounds\":{\"min\":[-4,-1,-4],\"max\":[4,4,4]},"
             "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":%g,\"albedo\":0.7,\"g\":0.3}],"
             "\"shapes\":[{\"name\":\"floor\",\"file\":\"floor.obj\",\"material\":{\"type\":\"diffuse\",\"albedo\":0.6},"
             "\"inside\":\"air\",\"outside\":\"air\"}],"
             "\"lights\":[{\"type\":\"point\",\"position\":[0.5,1.2,0.3],\"intensity\":[2,2,2]}],"
             "\"settings\":{\"max_depth\":1}}",
             sigma_t);
    return buf;
}

Test(surface_images, diffuse_floor_under_a_point_light_matches_quadrature, .timeout = 300)
{
    write_floor();
    const double rho = 0.6, I = 2.0;
    const vec3 light = v3(0.5, 1.2, 0.3);
    for (int k = 0; k < 2; k++) {
        double sigma_t = k ? 0.35 : 0.0;
        rd_scene *s = rt_scene("t5.json", t5_json(sigma_t));
        rd_render_result r = rt_render(s, "delta", k ? 128 : 2, 501 + k, NULL);
        int w = r.image.w, h = r.image.h, floor_px = 0, bad = 0;
        double img = 0, img_ref = 0, img_v = 0, zmax = 0, rel_max = 0;
        int regions = 0;
        for (int ry = 0; ry < h; ry += 8)
            for (int rx = 0; rx < w; rx += 8) {
                double m = 0, ref = 0, v = 0;
                for (int y = ry; y < ry + 8 && y < h; y++)
                    for (int x = rx; x < rx + 8 && x < w; x++) {
                        ss_ctx c = {rd_camera_ray(&s->camera, x + 0.5, y + 0.5), light, I, sigma_t, 0.7, 0.3};
                        double t0, t_far;
                        cr_assert(rd_box_intersect(v3(-4, -1, -4), v3(4, 4, 4), c.r, 0.0, INFINITY, &t0, &t_far));
                        double e = floor_expected(c, rho, t_far);
                        size_t i = 3 * ((size_t)y * w + x);
                        double px = r.image.rgb[i], se = r.stderr_img.rgb[i];
                        if (e > 0.0) floor_px++;
                        if (!k) {
                            /* Vacuum: one point light and the floor, deterministic (no medium,
                             * next-event estimation to a point): the film holds the value to
                             * float round-off. */
                            double rel = fabs(px - e) / fmax(e, 1e-12);
                            if (e > 0.0 && rel > rel_max) rel_max = rel;
                            if (!(fabs(px - e) <= 1e-5 * e + 1e-9) && bad++ == 0)
                                cr_log_error("vacuum: pixel (%d,%d) %g, expected %g", x, y, px, e);
                        }
                        m += px, ref += e, v += se * se;
                    }
                img += m, img_ref += ref, img_v += v;
                if (k && v > 0.0) {
                    double z = (m - ref) / sqrt(v);
                    if (fabs(z) > fabs(zmax)) zmax = z;
                    regions++;
                }
            }
        if (!k) {
            cr_expect(floor_px > w * h / 2, "the floor must fill most of the image (%d pixels)", floor_px);
            cr_expect(bad == 0, "vacuum: %d pixels differ from (rho/pi) I cos / d^2 (worst relative error %.3g)", bad, rel_max);
            cr_log_info("vacuum: worst relative error %.2e over %d floor pixels", rel_max, floor_px);
        } else {
            double z = (img - img_ref) / sqrt(img_v);
            cr_expect(regions >= 4, "too few regions (%d)", regions);
            cr_expect(fabs(z) < 5.0, "medium: image mean %g vs quadrature %g (z = %.2f)", img / (w * h), img_ref / (w * h), z);
            cr_expect(fabs(zmax) < 4.5, "medium: a region differs from the quadrature, z = %.2f (of %d)", zmax, regions);
            cr_log_info("medium: image %g quadrature %g z %.2f worst region %.2f of %d", img / (w * h), img_ref / (w * h), z, zmax, regions);
        }
        rd_render_result_free(&r);
        rd_scene_free(s);
    }
}

/* ---- 6. march.probes: the light at the end of the camera chain ------------------------------ */

/* A small sphere light (radius 0.04) seen through a glass ball (radius 0.5, index 1.5) in haze,
 * and directly past it: the pixels that see the light through the ball do so with a part of
 * their area only, so whether a jittered camera chain ends on the light is the noisiest part
 * of their samples (integrators/probes.c). With nee+paths the marcher is unbiased, so
 * each probe setting must equal delta. `probes` is the scene's march.probes, `delta_probes`
 * its settings.probes (delta's), `gu_probes` its guide.probes (guided-unbiased's). */
static const char *t6_json_gu(const char *probes, int shapes, const char *delta_probes, const char *gu_probes)
{
    static char buf[4096];
    char shp[1200] = "";
    if (shapes)
        snprintf(shp, sizeof shp,
                 "\"shapes\":[{\"name\":\"ball\",\"file\":\"%s\",\"transform\":{\"scale\":0.5},"
                 "\"material\":{\"type\":\"dielectric\",\"ior\":1.5},\"inside\":null,\"outside\":\"haze\"}],",
                 icosphere());
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[0.1,0.05,3],\"look_at\":[0,0,0],\"fov\":24,\"resolution\":[24,18]},"
             "\"medium\":\"haze\","
             "\"media\":[{\"name\":\"haze\",\"bounds\":{\"min\":[-1.5,-1.2,-2.2],\"max\":[1.5,1.2,3.5]},"
             "\"density\":1,\"sigma_t\":0.25,\"albedo\":0.8,\"g\":0.3}],%s"
             "\"lights\":[{\"type\":\"sphere\",\"center\":[0.35,0.1,-1.5],\"radius\":0.1,\"radiance\":[100,90,80]}],"
             "\"photons\":{\"count\":10000},\"march\":{\"ls\":\"nee+paths\",\"probes\":%s},"
             "\"guide\":{\"probes\":%s},\"settings\":{\"max_depth\":8,\"select\":\"off\",\"probes\":%s}}",
             shp, probes, gu_probes, delta_probes);
    return buf;
}

static const char *t6_json(const char *probes, int shapes, const char *delta_probes)
{
    return t6_json_gu(probes, shapes, delta_probes, "1");
}

/* Plain `delta` (4096 spp, seed `seed`) against `method` (spp a render) with each probe
 * setting, 8 and "auto", on the scenes above without and with the ball: march.probes for
 * `guided`, settings.probes for `delta`, guide.probes for `guided-unbiased`. The bounds are
 * rt_expect_same's (5 and 4.5 standard errors). */
static void probes_against_plain_delta(const char *method, int spp, uint64_t seed)
{
    int on_delta = !strcmp(method, "delta"), on_gu = !strcmp(method, "guided-unbiased");
    const char *key = on_delta ? "settings" : on_gu ? "guide" : "march";
    for (int shapes = 0; shapes < 2; shapes++) {
        rd_scene *s = rt_scene("t6.json", t6_json("1", shapes, "1"));
        rd_render_result d = rt_render(s, "delta", 4096, seed + 10 * shapes, NULL);
        cr_expect(d.stats.probes == 0, "settings.probes 1 took probes");
        rd_scene_free(s);
        const char *settings[] = {"8", "\"auto\""};
        for (int i = 0; i < 2; i++) {
            s = rt_scene("t6p.json", t6_json_gu(on_delta || on_gu ? "1" : settings[i], shapes, on_delta ? settings[i] : "1",
                                                on_gu ? settings[i] : "1"));
            rd_render_result m = rt_render(s, method, spp, seed + 1 + 10 * shapes + i, NULL);
            char what[128];
            snprintf(what, sizeof what, "%s with %s.probes %s vs delta without, %s", method, key, settings[i],
                     shapes ? "through a glass ball" : "no shapes");
            rt_expect_same(&d, &m, what);
            cr_expect(m.stats.probes > 0, "%s: no probe was taken", what);
            rd_render_result_free(&m);
            rd_scene_free(s);
        }
        rd_render_result_free(&d);
    }
}

/* Unbiased for a fixed M and for "auto": each E_j has E_0's mean, and M is chosen before the
 * sample. A planted fault, the probes' sum weighted 1/(M-1) instead of 1/M, fails the fixed M's
 * comparisons (image z -7.5 without shapes, -6.3 through the ball; "auto", whose M is mostly 1
 * or 2 here, -1.3 and -1.4). */
Test(surface_images, probes_keep_the_marcher_equal_to_delta, .timeout = 600)
{
    probes_against_plain_delta("guided", 512, 601);
}

/* `method` on scene s with one thread (spp, seed) gives the image and the probe count `two`
 * got with two: the choice of M is counted, not timed. */
static void expect_one_thread_as_two(rd_scene *s, const char *method, int spp, uint64_t seed,
                                     const rd_render_result *two)
{
    rd_render_opts o = {.method = method, .spp = spp, .seed = seed, .threads = 1};
    rd_render_result one;
    char err[RD_ERRLEN];
    cr_assert(rd_render(s, &o, &one, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(one.stats.probes == two->stats.probes &&
                  !memcmp(one.image.rgb, two->image.rgb, sizeof(float) * 3 * (size_t)two->image.w * two->image.h),
              "%s: one thread and two differ (%llu and %llu probes)", method, (unsigned long long)one.stats.probes,
              (unsigned long long)two->stats.probes);
    rd_render_result_free(&one);
}

/* "auto" probes where the chain's end is noisy: the pixels that see the light through the
 * ball take more than their first samples' probes (2 samples x 1 each), which is all that a
 * pixel whose chains never end on a light takes. A scene whose chains can see no light (a spot,
 * a black background) takes none. And the choice of M is counted, not timed: the same seed
 * gives the same image on one thread and on two, for `guided` and for `delta`. */
Test(surface_images, auto_probes_where_the_light_is_seen, .timeout = 300)
{
    rd_scene *s = rt_scene("t6a.json", t6_json("\"auto\"", 1, "1"));
    rd_render_result m = rt_render(s, "guided", 64, 621, NULL);
    uint64_t first = 2 * 1 * (uint64_t)(m.image.w * m.image.h);
    cr_expect(m.stats.probes > first + 1000, "auto took %llu probes: no more than the first samples' %llu",
              (unsigned long long)m.stats.probes, (unsigned long long)first);
    expect_one_thread_as_two(s, "guided", 64, 621, &m);
    rd_render_result_free(&m);
    rd_scene_free(s);
    /* delta's probes alike (settings.probes "auto") */
    s = rt_scene("t6ad.json", t6_json("1", 1, "\"auto\""));
    m = rt_render(s, "delta", 64, 623, NULL);
    cr_expect(m.stats.probes > first, "delta took %llu probes", (unsigned long long)m.stats.probes);
    expect_one_thread_as_two(s, "delta", 64, 623, &m);
    rd_render_result_free(&m);
    rd_scene_free(s);
    s = rt_scene("t6s.json",
                 "{\"camera\":{\"position\":[0,0,3],\"look_at\":[0,0,0],\"resolution\":[12,9]},"
                 "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":1,\"sigma_t\":1}],"
                 "\"lights\":[{\"type\":\"spot\",\"position\":[0,2,0],\"look_at\":[0,0,0],\"angle\":30,\"intensity\":5}],"
                 "\"photons\":{\"count\":2000},\"settings\":{\"select\":\"off\"}}");
    m = rt_render(s, "guided", 16, 622, NULL);
    cr_expect(m.stats.probes == 0, "%llu probes where no chain can end on a light", (unsigned long long)m.stats.probes);
    rd_render_result_free(&m);
    rd_scene_free(s);
}

/* `delta` with settings.probes: its path less the camera chain's end, and that end from M
 * chains (transport/path.c rd_delta_radiance_split, integrators/probes.c), against plain
 * `delta`. A planted fault, the chain's end left in the path as well (counted twice), fails
 * every comparison (image z -30 to -39). */
Test(surface_images, delta_probes_keep_delta_s_image, .timeout = 600)
{
    probes_against_plain_delta("delta", 2048, 701);
}

/* `guided-unbiased` with guide.probes: its path less the camera chain's end (transport/path.c
 * rd_path_radiance_split) and that end from M chains, against plain `delta`; and with the
 * selection on, its delta tiles take the method's probes (rd_probes_delta through the
 * selection's delta hook) and keep delta's image. */
Test(surface_images, guided_unbiased_probes_keep_delta_s_image, .timeout = 600)
{
    probes_against_plain_delta("guided-unbiased", 1024, 711);
    rd_scene *s = rt_scene("t10d.json", t6_json("1", 1, "1"));
    rd_render_result d = rt_render(s, "delta", 2048, 721, NULL);
    rd_scene_free(s);
    s = rt_scene("t10g.json", t6_json_gu("1", 1, "1", "\"auto\""));
    s->settings.select = RD_SELECT_TILES;
    rd_render_result g = rt_render(s, "guided-unbiased", 512, 722, NULL);
    rt_expect_same(&d, &g, "guided-unbiased with the selection and guide.probes \"auto\" vs delta, through a glass ball");
    /* more probes than the first two samples' (which take one each): "auto"'s epochs ran */
    uint64_t first = 2 * (uint64_t)(g.image.w * g.image.h);
    cr_expect(g.stats.probes > first + 1000 && g.stats.delta_samples > 0, "%llu probes (the first samples' %llu), %llu delta samples",
              (unsigned long long)g.stats.probes, (unsigned long long)first, (unsigned long long)g.stats.delta_samples);
    expect_one_thread_as_two(s, "guided-unbiased", 512, 722, &g);
    release(&d, &g);
    rd_scene_free(s);
}

/* The selection's pilot samples the method without probes under "auto" (it learns the method
 * as it comes; the per-pixel statistics learn from the image's samples only). Before this was
 * kept, M was "auto"'s 0 there and the pilot's samples came out as NaN (E / 0), which the
 * pilot drops: the method's tiles had no statistics. */
Test(surface_images, the_selection_s_pilot_takes_no_probes)
{
    rd_scene *s = rt_scene("t8.json", t6_json("\"auto\"", 0, "1"));
    rd_render_ctx ctx = {.scene = s};
    rd_probes p;
    char err[RD_ERRLEN];
    cr_assert(rd_probes_init(&p, s, 0, 0.0, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(rd_probes_on(&p), "a sphere light in view and no probes");
    rd_thread th = {0};
    th.pilot = 1;
    th.pixel = 5, th.x = 5, th.y = 0;
    pcg32 rng = pcg32_seed(8, 7, 13);
    vec3 L = rd_probes_add(&ctx, &p, &th, v3(1, 2, 3), v3(4, 5, 6), 10.0, &rng);
    cr_expect(L.x == 5.0 && L.y == 7.0 && L.z == 9.0 && th.probes == 0, "the pilot's sample is %g %g %g with %llu probes",
              L.x, L.y, L.z, (unsigned long long)th.probes);
    rd_probes_free(&p);
    rd_scene_free(s);
    /* and a guided render with the selection on keeps delta's image (whichever tiles it gives
     * the method: here it may give them all to delta) */
    s = rt_scene("t8d.json", t6_json("1", 1, "1"));
    rd_render_result d = rt_render(s, "delta", 2048, 801, NULL);
    rd_scene_free(s);
    s = rt_scene("t8g.json", t6_json("\"auto\"", 1, "1"));
    s->settings.select = RD_SELECT_TILES;
    rd_render_result g = rt_render(s, "guided", 256, 802, NULL);
    rt_expect_same(&d, &g, "guided with the selection and march.probes \"auto\" vs delta, through a glass ball");
    release(&d, &g);
    rd_scene_free(s);
}

/* "auto"'s per-pixel search (rd_probes_best_m) stops early, at the first M whose lower bound is
 * above the best so far; it must still return the full search's M: the first least of the
 * model's V(M) + lambda C(M) over M in [1, RD_PROBES_MAX]. Checked against this test's own full
 * search of the head's formula (the same expression, so the same rounding: exact equality) on
 * 200000 random models (fixed seed): covariances of either sign up to the Cauchy-Schwarz bound,
 * the probe's variance from 1e-4 to 1e4 times the sample's own, costs and lambda over eight
 * decades each; the draws must reach M = 1, the cap, and M > 1 with a negative covariance. Then
 * three models by hand: a pixel that never sees light, a covariance past the Cauchy-Schwarz
 * bound (a noisy estimate: V(1) < 0) and a probe far noisier than the sample's own chain. A
 * floor that leaves out the negative covariance (stopping where a later M is still better)
 * fails it (6848 of the 200000). */
static double t9_objective(const rd_probes_model *m, double lambda, int M)
{
    return m->vI + 2.0 * m->cov / M + (m->v0 + (M - 1) * m->vp) / ((double)M * M) +
           lambda * (m->c + (M - 1) * m->cp);
}

static int t9_full_search(const rd_probes_model *m, double lambda)
{
    if (!(lambda > 0.0)) return 1;
    int best = 1;
    for (int M = 2; M <= RD_PROBES_MAX; M++)
        if (t9_objective(m, lambda, M) < t9_objective(m, lambda, best)) best = M;
    return best;
}

Test(surface_images, auto_probes_search_finds_the_model_s_least)
{
    pcg32 rng = pcg32_seed(36, 1, 99);
    int wrong = 0, one = 0, cap = 0, negative = 0;
    for (int k = 0; k < 200000; k++) {
        double u[7];
        for (int i = 0; i < 7; i++) u[i] = pcg32_uniform(&rng);
        rd_probes_model m;
        m.vI = pow(10.0, -4.0 + 8.0 * u[0]);
        m.v0 = pow(10.0, -4.0 + 8.0 * u[1]);
        m.vp = m.v0 * pow(10.0, -4.0 + 8.0 * u[2]);
        m.cov = (2.0 * u[3] - 1.0) * sqrt(m.vI * m.v0); /* |cov| <= sqrt(vI v0) */
        m.c = pow(10.0, 4.0 * u[4]);
        m.cp = m.c * pow(10.0, -4.0 + 4.0 * u[5]);
        double lambda = pow(10.0, -6.0 + 8.0 * u[6]);
        int M = rd_probes_best_m(&m, lambda);
        wrong += M != t9_full_search(&m, lambda);
        one += M == 1;
        cap += M == RD_PROBES_MAX;
        negative += M > 1 && m.cov < 0.0;
    }
    cr_expect(wrong == 0, "%d of 200000 models: the search's M is not the full search's", wrong);
    cr_expect(one > 0 && cap > 0 && negative > 0, "regimes not reached: M = 1 %d, M = %d %d, M > 1 with cov < 0 %d",
              one, RD_PROBES_MAX, cap, negative);
    const rd_probes_model by_hand[] = {
        {0.5, 0.0, 0.0, 0.0, 10.0, 1.0, 0.0},      /* no light at the chain's end: M = 1 */
        {0.0, -3.0, 1.0, 0.01, 10.0, 0.001, 0.0},  /* cov past sqrt(vI v0): V(1) = -5 */
        {1.0, -0.2, 0.01, 100.0, 10.0, 0.01, 0.0}, /* a probe 1e4 x noisier than the own chain */
    };
    for (size_t i = 0; i < sizeof by_hand / sizeof by_hand[0]; i++)
        for (double lambda = 1e-6; lambda < 1e3; lambda *= 3.0) {
            int M = rd_probes_best_m(&by_hand[i], lambda), full = t9_full_search(&by_hand[i], lambda);
            cr_expect(M == full, "model %zu, lambda %g: M %d, the full search's %d", i, lambda, M, full);
        }
    rd_probes_model m = {1.0, -0.5, 1.0, 1.0, 1.0, 1.0, 0.0};
    cr_expect(rd_probes_best_m(&m, 0.0) == 1, "lambda 0: no probes");
}

/* "auto" where a pixel has seen no light (probes.c, "Where a pixel has seen no light"): a
 * pixel whose model has no variance of E takes the M the search finds for the variance that a
 * light as bright as the scene's brightest may still hide after its chains, p (1 - p) b^2 with
 * p = 1 / (chains + 2), but no more than the probes that cost an eighth of its sample,
 * 1 + floor(c / (8 cp)) chains; one that has seen light takes the search's M alone. Then a
 * render: a sphere light no camera chain can see (above the view), `guided`'s samples costing
 * more than eight chains that end on nothing, takes more than twice the probes of the first two
 * samples' one each (without the rule it takes exactly those; at 8 spp the samples after the
 * epoch at 4 take the rule's M, so most pixels must have M >= 2). */
Test(surface_images, auto_probes_look_for_a_light_no_chain_has_seen)
{
    const rd_probes_model unseen[] = {
        {0.5, 0.0, 0.0, 0.0, 40.0, 1.0, 8.0},   /* c = 40 cp: 1 + 5 chains */
        {0.5, 0.0, 0.0, 0.0, 7.9, 1.0, 8.0},    /* a sample under 8 probes: none */
        {0.5, 0.0, 0.0, 0.0, 1000.0, 1.0, 8.0}, /* the cap */
    };
    const int want[] = {6, 1, RD_PROBES_MAX};
    for (int i = 0; i < 3; i++)
        for (double lambda = 1e-4; lambda < 1e-1; lambda *= 10.0) {
            cr_expect(rd_probes_best_m(&unseen[i], lambda) == 1, "model %d: the search wants probes", i);
            /* a light 1000 bright: p (1 - p) b^2 = 9e4 asks for every chain the budget allows */
            int M = rd_probes_choose_m(&unseen[i], lambda, 1000.0);
            cr_expect(M == want[i], "model %d, lambda %g: M %d, the budget's %d", i, lambda, M, want[i]);
            /* a dim one (b = 0.01: 9e-6) asks for none; nothing to see, none */
            cr_expect(rd_probes_choose_m(&unseen[i], lambda, 0.01) == 1, "model %d, lambda %g: probes for a dim light", i,
                      lambda);
            cr_expect(rd_probes_choose_m(&unseen[i], lambda, 0.0) == 1, "model %d, lambda %g: probes for no light", i,
                      lambda);
        }
    /* between: b = 1 after 8 chains (p (1 - p) = 0.09) at lambda 0.01, cp 1: the search's
     * M for that variance (3 here), below the budget's 6 */
    rd_probes_model mid = unseen[0];
    mid.v0 = mid.vp = 0.09;
    int m_mid = rd_probes_best_m(&mid, 0.01);
    cr_expect(m_mid > 1 && m_mid < 6 && rd_probes_choose_m(&unseen[0], 0.01, 1.0) == m_mid,
              "b = 1: M %d, the search's for the unseen variance %d", rd_probes_choose_m(&unseen[0], 0.01, 1.0), m_mid);
    /* more chains that missed, less to look for: after 10^6 none */
    rd_probes_model many = unseen[0];
    many.chains = 1e6;
    cr_expect(rd_probes_choose_m(&many, 0.01, 1.0) == 1, "10^6 chains missed a light of 1: still probes");
    /* light seen (a variance of E): the search's M at every lambda (at lambda 1 it is below
     * the budget's 6, where a rule that ignored the light seen would differ) */
    rd_probes_model seen = {0.5, 0.0, 1e-4, 1e-4, 40.0, 1.0, 8.0};
    for (double lambda = 1e-6; lambda < 1e3; lambda *= 10.0)
        cr_expect(rd_probes_choose_m(&seen, lambda, 1000.0) == rd_probes_best_m(&seen, lambda),
                  "lambda %g: not the search's M", lambda);
    cr_expect(rd_probes_best_m(&seen, 1.0) < 6, "the seen model's search reaches the budget: no check");

    rd_scene *s = rt_scene("t11.json",
                           "{\"camera\":{\"position\":[0,0,3],\"look_at\":[0,0,0],\"fov\":24,\"resolution\":[12,9]},"
                           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":1,\"sigma_t\":1,"
                           "\"albedo\":0.8}],"
                           "\"lights\":[{\"type\":\"sphere\",\"center\":[0,4,0],\"radius\":0.2,\"radiance\":[50,50,50]}],"
                           "\"photons\":{\"count\":2000},\"march\":{\"ls\":\"nee+paths\",\"samples\":32,\"min_samples\":32,\"probes\":\"auto\"},"
                           "\"settings\":{\"select\":\"off\"}}");
    rd_render_result m = rt_render(s, "guided", 8, 631, NULL);
    uint64_t first = 2 * (uint64_t)(m.image.w * m.image.h);
    cr_expect(m.stats.probes > 2 * first, "%llu probes, the first two samples' %llu", (unsigned long long)m.stats.probes,
              (unsigned long long)first);
    rd_render_result_free(&m);
    rd_scene_free(s);
}
