/* test_geom.c: meshes (assimp loading, transform, closedness, every error path), the shapes
 * keys of the scene loader, and the Embree ray queries (rd_geom.h) against exact answers
 * computed here in double precision. Run from the repository root (the icosphere is
 * scenes/data/icosphere-3.obj, made by scripts/make-meshes.sh). */
#include "support/rd_test.h"
#include "scene/rd_geom.h"

#include <omp.h>

/* ---- helpers ------------------------------------------------------------------------------- */

static const char *write_text(const char *name, const char *text)
{
    const char *p = rt_tmp_path(name);
    rt_write_file(p, text, strlen(text));
    return p;
}

/* The unit cube [0,1]^3 as six quads (assimp triangulates them), wound counter-clockwise seen
 * from outside; `skip_face` >= 0 leaves that face out, `flip_face` >= 0 reverses it. */
static const char *cube_obj(const char *name, int skip_face, int flip_face)
{
    static const int faces[6][4] = {{1, 4, 3, 2}, {5, 6, 7, 8}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 4, 8, 7}, {4, 1, 5, 8}};
    char text[1024];
    int n = snprintf(text, sizeof text,
                     "# unit cube\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n");
    for (int f = 0; f < 6; f++) {
        if (f == skip_face) continue;
        const int *q = faces[f];
        if (f == flip_face) n += snprintf(text + n, sizeof text - n, "f %d %d %d %d\n", q[3], q[2], q[1], q[0]);
        else n += snprintf(text + n, sizeof text - n, "f %d %d %d %d\n", q[0], q[1], q[2], q[3]);
    }
    return write_text(name, text);
}

/* Double-precision ray-triangle intersection written independently of geom.c: the plane
 * through the triangle, then the inside test by the signs of the three edge functions. */
static int exact_triangle(ray3 r, vec3 a, vec3 b, vec3 c, double *t)
{
    vec3 n = v3_cross(v3_sub(b, a), v3_sub(c, a));
    double dn = v3_dot(r.d, n);
    if (dn == 0.0) return 0;
    double tt = v3_dot(v3_sub(a, r.o), n) / dn;
    vec3 p = ray_at(r, tt);
    double e0 = v3_dot(v3_cross(v3_sub(b, a), v3_sub(p, a)), n);
    double e1 = v3_dot(v3_cross(v3_sub(c, b), v3_sub(p, b)), n);
    double e2 = v3_dot(v3_cross(v3_sub(a, c), v3_sub(p, c)), n);
    if (!((e0 >= 0 && e1 >= 0 && e2 >= 0) || (e0 <= 0 && e1 <= 0 && e2 <= 0))) return 0;
    *t = tt;
    return 1;
}

static vec3 mesh_v(const rd_mesh *m, uint32_t i)
{
    const float *p = m->positions + 3 * (size_t)i;
    return v3(p[0], p[1], p[2]);
}

/* Nearest triangle of m along r with t > tmin by brute force; its index or -1, and the gap
 * to the second nearest distinct t (to recognise ties at shared edges). */
static long brute_nearest(const rd_mesh *m, ray3 r, double tmin, double *t_best, double *gap)
{
    long best = -1;
    double b = INFINITY, second = INFINITY;
    for (size_t k = 0; k < m->n_triangles; k++) {
        const uint32_t *v = m->indices + 3 * k;
        double t;
        if (!exact_triangle(r, mesh_v(m, v[0]), mesh_v(m, v[1]), mesh_v(m, v[2]), &t) || !(t > tmin)) continue;
        if (t < b) {
            second = b;
            b = t;
            best = (long)k;
        } else if (t < second) second = t;
    }
    *t_best = b;
    *gap = second - b;
    return best;
}

/* A scene of the given shapes JSON (and optional media / lights / top-level extras). */
static char scene_buf[8192];
static const char *shape_scene(const char *name, const char *media, const char *shapes, const char *extra)
{
    snprintf(scene_buf, sizeof scene_buf,
             "{\"camera\":{\"position\":[0,0,6],\"look_at\":[0,0,0],\"resolution\":[8,8]},"
             "\"media\":[%s],\"shapes\":[%s]%s%s}",
             media, shapes, extra[0] ? "," : "", extra);
    return write_text(name, scene_buf);
}

static rd_status load(const char *path, rd_scene **s, char *err)
{
    *s = NULL;
    return rd_scene_load(s, path, NULL, 0, err, RD_ERRLEN);
}

/* Load must fail with a message containing every one of the given fragments. */
static void expect_scene_error(const char *path, const char *frag1, const char *frag2)
{
    rd_scene *s;
    char err[RD_ERRLEN] = "";
    rd_status st = load(path, &s, err);
    cr_expect(st != RD_OK, "%s loaded but should not", path);
    if (st == RD_OK) {
        rd_scene_free(s);
        return;
    }
    cr_expect(strstr(err, frag1) != NULL, "expected \"%s\" in: %s", frag1, err);
    if (frag2) cr_expect(strstr(err, frag2) != NULL, "expected \"%s\" in: %s", frag2, err);
    cr_expect(strchr(err, '\n') == NULL, "message is not one line: %s", err);
}

/* ---- meshes -------------------------------------------------------------------------------- */
Test(geom, cube_obj_loads_transformed_and_closed)
{
    const char *p = cube_obj("cube.obj", -1, -1);
    rd_transform xf = {v3(2, 3, 4), v3(0, 0, 1), 90.0, v3(1, 2, 3)};
    rd_mesh m;
    char err[RD_ERRLEN];
    cr_assert(rd_mesh_load(p, &xf, &m, err, sizeof err) == RD_OK, "%s", err);
    cr_expect_eq(m.n_triangles, 12);
    cr_expect_eq(m.n_vertices, 8);
    cr_expect(m.closed && m.open_edges == 0 && !m.flipped);
    /* scale (2,3,4): volume 24; rotation about z by 90 deg maps (x, y) to (-y, x). */
    cr_expect(fabs(m.volume - 24.0) < 1e-5, "volume %g", m.volume);
    /* Every corner of the unit cube must appear at translate + R(scale * corner). */
    for (int c = 0; c < 8; c++) {
        vec3 q = v3(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        vec3 w = v3(1 - 3 * q.y, 2 + 2 * q.x, 3 + 4 * q.z); /* R_z(90) (2x, 3y, 4z) + (1,2,3) */
        vec3 t = rd_transform_point(&xf, q);
        cr_expect(v3_len(v3_sub(t, w)) < 1e-12, "transform of corner %d", c);
        int found = 0;
        for (size_t i = 0; i < m.n_vertices; i++) found |= v3_len(v3_sub(mesh_v(&m, (uint32_t)i), w)) < 1e-6;
        cr_expect(found, "corner %d (%g, %g, %g) missing", c, w.x, w.y, w.z);
    }
    cr_expect(fabs(m.bmin.x - -2) < 1e-6 && fabs(m.bmax.x - 1) < 1e-6 && fabs(m.bmin.y - 2) < 1e-6 &&
              fabs(m.bmax.y - 4) < 1e-6 && fabs(m.bmin.z - 3) < 1e-6 && fabs(m.bmax.z - 7) < 1e-6);
    /* Outward winding: each triangle's normal points away from the centre. */
    vec3 centre = v3_scale(v3_add(m.bmin, m.bmax), 0.5);
    for (size_t k = 0; k < m.n_triangles; k++) {
        const uint32_t *v = m.indices + 3 * k;
        vec3 a = mesh_v(&m, v[0]), b = mesh_v(&m, v[1]), c = mesh_v(&m, v[2]);
        vec3 n = v3_cross(v3_sub(b, a), v3_sub(c, a));
        cr_expect(v3_dot(n, v3_sub(a, centre)) > 0, "triangle %zu wound inward", k);
    }
    rd_mesh_free(&m);
    rd_mesh_free(&m); /* safe on a freed (zeroed) mesh */
}

Test(geom, ply_inward_tetrahedron_is_flipped)
{
    /* A binary-free ASCII PLY tetrahedron whose faces are all wound inward. */
    const char *p = write_text("tet.ply",
                               "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                               "element face 4\nproperty list uchar int vertex_indices\nend_header\n"
                               "0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                               "3 0 1 2\n3 0 3 1\n3 0 2 3\n3 1 3 2\n");
    rd_mesh m;
    char err[RD_ERRLEN];
    cr_assert(rd_mesh_load(p, NULL, &m, err, sizeof err) == RD_OK, "%s", err);
    cr_expect_eq(m.n_triangles, 4);
    cr_expect(m.closed, "open edges %zu", m.open_edges);
    cr_expect(m.flipped, "an inward tetrahedron must be reversed");
    cr_expect(fabs(m.volume - 1.0 / 6.0) < 1e-7, "volume %g", m.volume);
    rd_mesh_free(&m);
}

Test(geom, open_and_inconsistent_meshes_are_not_closed)
{
    rd_mesh m;
    char err[RD_ERRLEN];
    cr_assert(rd_mesh_load(cube_obj("open.obj", 2, -1), NULL, &m, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(!m.closed);
    cr_expect_eq(m.open_edges, 4, "a missing quad leaves its 4 edges open, found %zu", m.open_edges);
    rd_mesh_free(&m);
    cr_assert(rd_mesh_load(cube_obj("flip.obj", -1, 3), NULL, &m, err, sizeof err) == RD_OK, "%s", err);
    cr_expect(!m.closed, "a face wound the wrong way breaks the orientation");
    cr_expect_eq(m.open_edges, 4, "found %zu", m.open_edges);
    rd_mesh_free(&m);
}

Test(geom, seams_split_by_normals_are_welded)
{
    /* The cube with one normal per face: assimp keeps 24 vertices (position + normal), yet
     * the surface is closed (closedness welds by position). */
    const char *p = write_text("seams.obj",
                               "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                               "vn 0 0 -1\nvn 0 0 1\nvn 0 -1 0\nvn 1 0 0\nvn 0 1 0\nvn -1 0 0\n"
                               "f 1//1 4//1 3//1 2//1\nf 5//2 6//2 7//2 8//2\nf 1//3 2//3 6//3 5//3\n"
                               "f 2//4 3//4 7//4 6//4\nf 3//5 4//5 8//5 7//5\nf 4//6 1//6 5//6 8//6\n");
    rd_mesh m;
    char err[RD_ERRLEN];
    cr_assert(rd_mesh_load(p, NULL, &m, err, sizeof err) == RD_OK, "%s", err);
    cr_expect_eq(m.n_vertices, 24);
    cr_expect(m.normals != NULL);
    cr_expect(m.closed, "open edges %zu", m.open_edges);
    rd_mesh_free(&m);
}

Test(geom, mesh_error_paths)
{
    rd_mesh m;
    char err[RD_ERRLEN];
    cr_expect(rd_mesh_load(rt_tmp_path("nothere.obj"), NULL, &m, err, sizeof err) == RD_ERR_IO);
    cr_expect(strstr(err, "nothere.obj: no such file") != NULL, "%s", err);
    cr_expect(m.positions == NULL && m.n_triangles == 0);
    cr_expect(rd_mesh_load(rt_tmpdir(), NULL, &m, err, sizeof err) == RD_ERR_IO);
    cr_expect(strstr(err, "not a regular file") != NULL, "%s", err);
    cr_expect(rd_mesh_load(write_text("junk.ply", "ply\nthis is not a mesh\n"), NULL, &m, err, sizeof err) == RD_ERR_FORMAT);
    cr_expect(strstr(err, "junk.ply: not a mesh assimp can read") != NULL, "%s", err);
    cr_expect(rd_mesh_load(write_text("lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nl 2 3\n"), NULL, &m, err, sizeof err) ==
              RD_ERR_FORMAT);
    cr_expect(strstr(err, "lines.obj: no triangles") != NULL || strstr(err, "lines.obj: not a mesh") != NULL, "%s", err);
    /* Only a degenerate triangle (two equal corners): nothing left. */
    cr_expect(rd_mesh_load(write_text("degen.obj", "v 0 0 0\nv 1 0 0\nv 1 0 0\nf 1 2 3\n"), NULL, &m, err, sizeof err) ==
              RD_ERR_FORMAT);
    cr_expect(strstr(err, "degen.obj: no triangles") != NULL, "%s", err);
    float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint32_t bad[3] = {0, 1, 3};
    cr_expect(rd_mesh_from_arrays(pos, 3, NULL, bad, 1, &m, err, sizeof err) == RD_ERR_FORMAT);
    cr_expect(strstr(err, "out of range") != NULL, "%s", err);
    float nanpos[9] = {0, 0, 0, 1, 0, 0, 0, NAN, 0};
    uint32_t ok[3] = {0, 1, 2};
    cr_expect(rd_mesh_from_arrays(nanpos, 3, NULL, ok, 1, &m, err, sizeof err) == RD_ERR_FORMAT);
    cr_expect(strstr(err, "non-finite") != NULL, "%s", err);
}

Test(geom, generated_meshes_are_closed)
{
    static const char *const files[] = {"scenes/data/icosphere-3.obj", "scenes/data/blob-4.obj", "scenes/data/knot.obj"};
    static const size_t tris[] = {1280, 5120, 4608};
    for (int i = 0; i < 3; i++) {
        rd_mesh m;
        char err[RD_ERRLEN];
        cr_assert(rd_mesh_load(files[i], NULL, &m, err, sizeof err) == RD_OK, "%s (run from the repository root)", err);
        cr_expect_eq(m.n_triangles, tris[i], "%s: %zu triangles", files[i], m.n_triangles);
        cr_expect(m.closed, "%s: %zu open edges", files[i], m.open_edges);
        cr_expect(!m.flipped, "%s: written inward", files[i]);
        cr_expect(m.normals != NULL, "%s: no normals", files[i]);
        if (i == 0) /* inscribed polyhedron: a little under 4 pi / 3 */
            cr_expect(m.volume < 4.0 * M_PI / 3.0 && m.volume > 0.97 * 4.0 * M_PI / 3.0, "icosphere volume %g", m.volume);
        rd_mesh_free(&m);
    }
}

/* The flat meshes (no vertex normals): a cube and a wall with a window, a closed genus-1 slab. */
Test(geom, generated_flat_meshes_are_closed)
{
    static const char *const files[] = {"scenes/data/box.obj", "scenes/data/window-wall.obj"};
    static const size_t tris[] = {12, 32};
    /* [-1,1]^3, and the same slab less the hole 0.5 x 0.4 x 2 */
    static const double volume[] = {8.0, 8.0 - 0.5 * 0.4 * 2.0};
    for (int i = 0; i < 2; i++) {
        rd_mesh m;
        char err[RD_ERRLEN];
        cr_assert(rd_mesh_load(files[i], NULL, &m, err, sizeof err) == RD_OK, "%s (run from the repository root)", err);
        cr_expect_eq(m.n_triangles, tris[i], "%s: %zu triangles", files[i], m.n_triangles);
        cr_expect(m.closed, "%s: %zu open edges", files[i], m.open_edges);
        cr_expect(!m.flipped, "%s: written inward", files[i]);
        cr_expect(m.normals == NULL, "%s: vertex normals on a flat mesh", files[i]);
        cr_expect(fabs(m.volume - volume[i]) < 1e-5, "%s: volume %g, expected %g", files[i], m.volume, volume[i]);
        rd_mesh_free(&m);
    }
}

/* ---- scene keys ---------------------------------------------------------------------------- */
#define FOG "{\"name\":\"fog\",\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":1,\"sigma_t\":2}"
#define ROOM "{\"name\":\"room\",\"bounds\":{\"min\":[-5,-5,-5],\"max\":[5,5,5]},\"density\":1,\"sigma_t\":0.1}"

Test(geom, scene_with_shapes_loads)
{
    const char *cube = cube_obj("c.obj", -1, -1);
    (void)cube;
    const char *p = shape_scene("ok.json", FOG "," ROOM,
                                "{\"name\":\"glass\",\"file\":\"c.obj\",\"transform\":{\"scale\":2.2,\"translate\":[-1.1,-1.1,-1.1]},"
                                "\"material\":{\"type\":\"dielectric\",\"ior\":1.33},\"inside\":\"fog\",\"outside\":\"room\"},"
                                "{\"file\":\"c.obj\",\"transform\":{\"scale\":[4,0.1,4],\"rotate\":{\"axis\":[0,1,0],\"angle\":45},"
                                "\"translate\":[0,-2,0]},\"material\":{\"type\":\"diffuse\",\"albedo\":[0.2,0.4,0.6]},"
                                "\"inside\":null,\"outside\":\"room\"}",
                                "\"medium\":\"room\"");
    rd_scene *s;
    char err[RD_ERRLEN];
    cr_assert(load(p, &s, err) == RD_OK, "%s", err);
    cr_expect_eq(s->n_shapes, 2);
    cr_expect_eq(s->fill_medium, 1);
    cr_expect(strcmp(s->shapes[0].name, "glass") == 0 && strcmp(s->shapes[1].name, "shape1") == 0);
    cr_expect(s->shapes[0].material.kind == RD_MAT_DIELECTRIC && s->shapes[0].material.ior == 1.33);
    cr_expect(s->shapes[1].material.kind == RD_MAT_DIFFUSE && s->shapes[1].material.albedo.z == 0.6);
    cr_expect(s->shapes[0].inside == 0 && s->shapes[0].outside == 1 && s->shapes[1].inside == -1);
    cr_expect(rd_scene_medium_bound(s, 0) && rd_scene_medium_bound(s, 1));
    cr_expect(fabs(s->shapes[0].mesh.volume - 2.2 * 2.2 * 2.2) < 1e-4);
    /* The loader built the scene's Embree geometry; the regions follow the shapes. */
    cr_expect(s->geom != NULL);
    cr_expect_eq(rd_scene_region_at(s, v3(0, 0, 0)), 0, "inside the glass cube: fog");
    cr_expect_eq(rd_scene_region_at(s, v3(0, 3, 0)), 1, "outside: the room");
    cr_expect(rd_scene_medium_at_point(s, v3(0, 3, 0)) == &s->media[1]);
    cr_expect(rd_scene_medium_at_point(s, v3(0.5, 0.5, 0.5)) == &s->media[0]);
    /* the fog's bounds end at 1: its region holds nothing beyond them */
    cr_expect(rd_scene_medium_at(s, 0, v3(1.05, 0, 0)) == NULL);
    rd_scene_free(s);
    /* A scene without shapes is unchanged: no fill medium, renderable. */
    s = rt_scene("plain.json", "{\"camera\":{\"position\":[0,0,6],\"look_at\":[0,0,0],\"resolution\":[8,8]},\"media\":[" FOG "]}");
    cr_expect_eq(s->n_shapes, 0);
    cr_expect_eq(s->fill_medium, -1);
    cr_expect(!rd_scene_medium_bound(s, 0));
    cr_expect(s->geom == NULL && rd_scene_region_at(s, v3(0, 0, 0)) == -1);
    rd_scene_free(s);
}

Test(geom, scene_shape_errors)
{
    cube_obj("c.obj", -1, -1);
    cube_obj("open.obj", 0, -1);
    const char *mat = "\"material\":{\"type\":\"dielectric\",\"ior\":1.5}";
    char sh[1024];
    snprintf(sh, sizeof sh, "{\"file\":\"c.obj\",%s,\"inside\":\"smoke\"}", mat);
    expect_scene_error(shape_scene("e1.json", FOG, sh, ""), "e1.json: shapes[0].inside: no medium named \"smoke\"", "fog");
    expect_scene_error(shape_scene("e2.json", FOG, "{\"file\":\"c.obj\",\"material\":{\"type\":\"dielectric\",\"ior\":0.2}}", ""),
                       "e2.json: shapes[0].material.ior: must be in [0.25, 4]", NULL);
    expect_scene_error(shape_scene("e3.json", FOG, "{\"file\":\"c.obj\",\"material\":{\"type\":\"dielectric\",\"ior\":5}}", ""),
                       "shapes[0].material.ior: must be in [0.25, 4]", NULL);
    snprintf(sh, sizeof sh, "{\"file\":\"meshes/knot.obj\",%s}", mat);
    expect_scene_error(shape_scene("e4.json", FOG, sh, ""), "e4.json: shapes[0].file:", "meshes/knot.obj: no such file");
    snprintf(sh, sizeof sh, "{\"file\":\"open.obj\",%s,\"inside\":\"fog\"}", mat);
    expect_scene_error(shape_scene("e5.json", FOG, sh, ""), "e5.json: shapes[0].file:", "not a closed mesh (4 edges");
    expect_scene_error(shape_scene("e6.json", FOG, "{\"file\":\"c.obj\",\"material\":{\"type\":\"interface\"},\"inside\":\"fog\",\"outside\":\"fog\"}", ""),
                       "shapes[0].material.type: an interface between a medium and itself", NULL);
    expect_scene_error(shape_scene("e7.json", FOG, "{\"file\":\"c.obj\",\"material\":{\"type\":\"glass\"}}", ""),
                       "shapes[0].material.type: unknown value \"glass\"", NULL);
    snprintf(sh, sizeof sh, "{\"file\":\"c.obj\",%s,\"colour\":1}", mat);
    expect_scene_error(shape_scene("e8.json", FOG, sh, ""), "shapes[0].colour: unknown key", NULL);
    snprintf(sh, sizeof sh, "{\"file\":\"c.obj\",%s,\"transform\":{\"scale\":[1,-1,1]}}", mat);
    expect_scene_error(shape_scene("e9.json", FOG, sh, ""), "shapes[0].transform.scale: must be > 0", NULL);
    snprintf(sh, sizeof sh, "{\"file\":\"c.obj\",%s,\"transform\":{\"rotate\":{\"axis\":[0,0,0],\"angle\":3}}}", mat);
    expect_scene_error(shape_scene("e10.json", FOG, sh, ""), "shapes[0].transform.rotate.axis: must not be the zero vector", NULL);
    /* A box medium that a shape enclosing another region reaches into. */
    snprintf(sh, sizeof sh, "{\"file\":\"c.obj\",%s,\"inside\":\"room\"}", mat);
    expect_scene_error(shape_scene("e11.json", FOG "," ROOM, sh, ""), "e11.json: media[0].bounds: overlaps the bounding box of shapes[0]", NULL);
    /* ... but a shape whose inside is the open region (here vacuum, no scene-wide medium) may
     * overlap box media: they fill their bounds there too. */
    snprintf(sh, sizeof sh, "{\"file\":\"c.obj\",%s}", mat);
    rd_scene *ok;
    char okerr[RD_ERRLEN];
    cr_expect(load(shape_scene("e11b.json", FOG, sh, ""), &ok, okerr) == RD_OK, "%s", okerr);
    rd_scene_free(ok);
    expect_scene_error(shape_scene("e12.json", FOG, "{\"file\":\"c.obj\"}", ""), "shapes[0].material: missing", NULL);
    expect_scene_error(shape_scene("e13.json", FOG, "", "\"medium\":\"air\""), "e13.json: medium: no medium named \"air\"", NULL);
    expect_scene_error(shape_scene("e14.json", FOG "," FOG, "", "\"medium\":\"fog\""), "medium: 2 media are named \"fog\"", NULL);
    expect_scene_error(shape_scene("e15.json", FOG, "{\"file\":\"gone.obj\",\"made_by\":\"scripts/make-meshes.sh\",\"material\":{\"type\":\"interface\"},\"inside\":\"fog\"}", ""),
                       "gone.obj: no such file (not committed: made by scripts/make-meshes.sh", NULL);
    expect_scene_error(shape_scene("e16.json", FOG, "{\"file\":\"c.obj\",\"material\":{\"type\":\"diffuse\",\"albedo\":2}}", ""),
                       "shapes[0].material.albedo: expected a number or 3 numbers in [0, 1]", NULL);
}

Test(geom, cli_renders_shapes, .timeout = 300)
{
    cube_obj("c.obj", -1, -1);
    const char *p = shape_scene("cli.json", ROOM, "{\"file\":\"c.obj\",\"material\":{\"type\":\"diffuse\"},\"outside\":\"room\",\"inside\":\"room\"}",
                                "\"medium\":\"room\",\"lights\":[{\"type\":\"point\",\"position\":[0,3,3],\"intensity\":5}],"
                                "\"settings\":{\"spp\":2},\"photons\":{\"count\":2000},\"guide\":{\"resolution\":[4,4,4]}");
    const char *bin = getenv("PHOTONMARCH_BIN");
    if (!bin) bin = "build/photonmarch";
    cr_assert(access(bin, X_OK) == 0, "%s: not built", bin);
    /* Every command takes a scene with shapes (and a scene-wide medium). */
    const char *cmds[] = {"render", "bake", "compare"};
    for (int i = 0; i < 3; i++) {
        char out[4096], err[4096], dst[300];
        snprintf(dst, sizeof dst, "%s/%s", rt_tmpdir(), i == 2 ? "cli-compare" : "cli-out.exr");
        char *argv_r[] = {(char *)bin, (char *)cmds[i], (char *)p, "-o", dst, NULL};
        /* compare at equal samples: at equal time a loaded machine could leave a run no time for
         * a pass (equal time is compare's own test, on a virtual clock). */
        char *argv_c[] = {(char *)bin, (char *)cmds[i], (char *)p, "--methods", "delta,guided", "--equal", "spp",
                          "--budget", "2", "--ref-spp", "16", "--runs", "2", "-o", dst, NULL};
        int code = rt_run(i == 2 ? argv_c : argv_r, out, sizeof out, err, sizeof err, NULL);
        cr_expect(code == 0, "%s: exit %d, stderr %s", cmds[i], code, err);
    }
    char out[8192], err[4096];
    char *argv_i[] = {(char *)bin, "info", (char *)p, NULL};
    cr_expect(rt_run(argv_i, out, sizeof out, err, sizeof err, NULL) == 0, "info: %s", err);
    cr_expect(strstr(out, "shapes     1") != NULL, "%s", out);
}

/* ---- ray queries --------------------------------------------------------------------------- */
/* A scene holding the icosphere (radius 1 at the origin, as written) and, when `lights`, two
 * sphere lights: one at (3, 0, 0) radius 0.5, one at (0, 3, 0) radius 0.25. */
static rd_scene *ico_scene(int lights)
{
    char json[2048];
    char cwd[1024];
    cr_assert(getcwd(cwd, sizeof cwd) != NULL);
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,6],\"look_at\":[0,0,0],\"resolution\":[8,8]},\"media\":[],"
             "\"shapes\":[{\"name\":\"ico\",\"file\":\"%s/scenes/data/icosphere-3.obj\",\"material\":{\"type\":\"dielectric\"}}]%s}",
             cwd,
             lights ? ",\"lights\":[{\"type\":\"sphere\",\"center\":[3,0,0],\"radius\":0.5,\"radiance\":1},"
                      "{\"type\":\"sphere\",\"center\":[0,3,0],\"radius\":0.25,\"radiance\":1}]"
                    : "");
    return rt_scene("ico.json", json);
}

static rd_geom *build(const rd_scene *s)
{
    char err[RD_ERRLEN];
    rd_geom *g = rd_geom_build(s, err, sizeof err);
    cr_assert(g != NULL, "%s", err);
    return g;
}

static ray3 random_ray_at_sphere(pcg32 *rng, double R, double spread)
{
    vec3 o = v3_scale(rd_sample_sphere(pcg32_uniform(rng), pcg32_uniform(rng)), R);
    vec3 target = v3_scale(rd_sample_sphere(pcg32_uniform(rng), pcg32_uniform(rng)), spread * pcg32_uniform(rng));
    ray3 r = {o, v3_norm(v3_sub(target, o))};
    return r;
}

Test(geom, icosphere_hits_match_exact_triangles, .timeout = 120)
{
    rd_scene *s = ico_scene(0);
    rd_geom *g = build(s);
    cr_expect_eq(rd_geom_triangles(g), 1280);
    const rd_mesh *m = &s->shapes[0].mesh;
    pcg32 rng = pcg32_seed(14, 1, 2);
    int hits = 0, misses = 0;
    for (int i = 0; i < 4000; i++) {
        /* From outside at distance 3, aimed within radius 1.3 of the centre: some miss. */
        ray3 r = random_ray_at_sphere(&rng, 3.0, 1.3);
        double tb, gap;
        long k = brute_nearest(m, r, 0.0, &tb, &gap);
        rd_hit h;
        int got = rd_geom_intersect(g, r, 0.0, INFINITY, NULL, &h);
        if (k < 0) {
            /* A ray grazing an edge may legitimately be found by one test and not the other;
             * with random rays that needs the exact edge: not expected at all here. */
            cr_expect(!got, "ray %d: Embree hit triangle %u at %g, the exact test nothing", i, h.prim, h.t);
            misses++;
            continue;
        }
        cr_assert(got, "ray %d: exact hit of triangle %ld at %.9g, Embree nothing", i, k, tb);
        hits++;
        /* The double refinement is exact up to round-off of the double solve. */
        cr_expect(fabs(h.t - tb) < 1e-12 * (1 + tb), "ray %d: t %.15g vs exact %.15g", i, h.t, tb);
        if ((long)h.prim != k)
            cr_expect(gap < 1e-6, "ray %d: triangle %u, exact nearest %ld (gap %g)", i, h.prim, k, gap);
        cr_expect_eq(h.shape, 0);
        cr_expect_eq(h.light, -1);
        cr_expect(h.front, "ray %d from outside must hit the front", i);
        cr_expect(h.medium_from == -1 && h.medium_to == -1);
        cr_expect(v3_dot(h.ng, h.p) > 0, "geometric normal points outward");
        cr_expect(fabs(v3_len(h.ns) - 1) < 1e-9 && v3_dot(h.ns, h.ng) > 0.9, "shading normal near ng");
        cr_expect(v3_len(v3_sub(h.p, ray_at(r, tb))) < 1e-12 * (1 + tb));
    }
    cr_expect(hits > 1000 && misses > 100, "hits %d, misses %d", hits, misses);
    rd_geom_free(g);
    rd_scene_free(s);
}

Test(geom, spawned_rays_leave_without_self_hits, .timeout = 120)
{
    rd_scene *s = ico_scene(0);
    rd_geom *g = build(s);
    const rd_mesh *m = &s->shapes[0].mesh;
    pcg32 rng = pcg32_seed(14, 2, 2);
    int n = 0;
    for (int i = 0; i < 4000; i++) {
        ray3 r = random_ray_at_sphere(&rng, 3.0, 0.9);
        rd_hit h1, h2, h3;
        if (!rd_geom_intersect(g, r, 0.0, INFINITY, NULL, &h1)) continue;
        n++;
        /* Straight through (an interface): the next hit is the exit on the far side. */
        ray3 r2 = rd_hit_spawn(&h1, r.d);
        cr_assert(rd_geom_intersect(g, r2, 0.0, INFINITY, &h1, &h2), "ray %d: no exit", i);
        cr_expect(!h2.front, "ray %d: the exit must be a back-side hit", i);
        double tb, gap;
        brute_nearest(m, r2, 1e-9, &tb, &gap);
        cr_expect(fabs(h2.t - tb) < 1e-9 * (1 + tb), "ray %d: exit at %.12g, exact %.12g", i, h2.t, tb);
        cr_expect(h2.t > 10 * h1.eps, "ray %d: exit at %g is a self-hit", i, h2.t);
        /* The skip alone (no offset: from the hit point itself) never meets the same triangle. */
        ray3 raw = {h1.p, r.d};
        rd_hit hr;
        if (rd_geom_intersect(g, raw, 0.0, INFINITY, &h1, &hr))
            cr_expect(hr.prim != h1.prim, "ray %d: re-hit its own triangle at %g", i, hr.t);
        /* Reflected back outside at the entry: nothing more to hit. */
        ray3 r3 = rd_hit_spawn(&h1, rd_reflect(r.d, h1.ng));
        cr_expect(!rd_geom_intersect(g, r3, 0.0, INFINITY, &h1, &h3), "ray %d: reflection re-hit at %g", i, h3.t);
        cr_expect(!rd_geom_occluded(g, r3, 0.0, INFINITY, &h1), "ray %d: reflection occluded", i);
        /* Reflected inside at the exit: the next hit is again from the inside. */
        ray3 r4 = rd_hit_spawn(&h2, rd_reflect(r2.d, h2.ng));
        cr_assert(rd_geom_intersect(g, r4, 0.0, INFINITY, &h2, &h3), "ray %d: internal reflection escaped", i);
        cr_expect(!h3.front && h3.t > 10 * h2.eps, "ray %d: internal reflection self-hit", i);
    }
    cr_expect(n > 2000, "%d rays hit", n);
    rd_geom_free(g);
    rd_scene_free(s);
}

Test(geom, sphere_lights_and_nearest_of_several)
{
    rd_scene *s = ico_scene(1);
    rd_geom *g = build(s);
    /* Along +x from (-5, 0, 0): icosphere front at x = -1, its back at +1, the light at 2.5. */
    ray3 r = {v3(-5, 0, 0), v3(1, 0, 0)};
    rd_hit h;
    cr_assert(rd_geom_intersect(g, r, 0, INFINITY, NULL, &h));
    cr_expect(h.shape == 0 && h.front && h.t > 3.9 && h.t <= 4.0, "first: shape %d t %g", h.shape, h.t);
    rd_hit h2;
    cr_assert(rd_geom_intersect(g, rd_hit_spawn(&h, r.d), 0, INFINITY, &h, &h2));
    cr_expect(h2.shape == 0 && !h2.front);
    rd_hit h3;
    ray3 r3 = rd_hit_spawn(&h2, r.d);
    cr_assert(rd_geom_intersect(g, r3, 0, INFINITY, &h2, &h3));
    cr_expect(h3.light == 0 && h3.shape == -1, "third: light %d shape %d", h3.light, h3.shape);
    cr_expect_eq(h3.t, rd_light_hit(&s->lights[0], r3), "the light's distance is rd_light_hit's, exactly");
    /* On the sphere (the spawned origin is off the x axis by the icosphere's facet normal). */
    vec3 c = s->lights[0].pos;
    cr_expect(fabs(v3_len(v3_sub(h3.p, c)) - 0.5) < 1e-12 && fabs(h3.p.x - 2.5) < 1e-9, "light hit at (%.17g, %g, %g)", h3.p.x,
              h3.p.y, h3.p.z);
    cr_expect(v3_len(v3_sub(h3.ng, v3_scale(v3_sub(h3.p, c), 2.0))) < 1e-12 && h3.front);
    /* The same answer as rd_scene_hit_light for rays that meet only lights. */
    pcg32 rng = pcg32_seed(14, 3, 2);
    int lit = 0;
    for (int i = 0; i < 2000; i++) {
        ray3 q = {v3(1.2 + 2 * pcg32_uniform(&rng), 1.2 + 2 * pcg32_uniform(&rng), pcg32_uniform(&rng) - 0.5),
                  rd_sample_sphere(pcg32_uniform(&rng), pcg32_uniform(&rng))};
        double tl;
        int li = rd_scene_hit_light(s, q, INFINITY, -1, &tl);
        rd_hit hq;
        int got = rd_geom_intersect(g, q, 0, INFINITY, NULL, &hq);
        if (got && hq.shape >= 0) continue; /* the icosphere in front */
        cr_expect_eq(got ? hq.light : -1, li, "ray %d", i);
        if (li >= 0 && got) {
            cr_expect_eq(hq.t, tl);
            lit++;
        }
    }
    cr_expect(lit > 20, "%d rays reached a light", lit);
    /* tmax cuts: the icosphere front at 4 is beyond tmax 3.5; occlusion agrees. */
    cr_expect(!rd_geom_intersect(g, r, 0, 3.5, NULL, &h));
    cr_expect(!rd_geom_occluded(g, r, 0, 3.5, NULL));
    cr_expect(rd_geom_occluded(g, r, 0, 4.5, NULL));
    /* tmin cuts: starting past the icosphere, the light is first. */
    cr_assert(rd_geom_intersect(g, r, 6.5, INFINITY, NULL, &h));
    cr_expect(h.light == 0 && fabs(h.t - 7.5) < 1e-12);
    /* From inside a light: it is not hit (rd_light_hit's rule). */
    ray3 inl = {v3(3, 0, 0), v3(1, 0, 0)};
    cr_expect(!rd_geom_intersect(g, inl, 0, INFINITY, NULL, &h));
    rd_geom_free(g);
    rd_scene_free(s);
}

Test(geom, media_on_each_side)
{
    cube_obj("c.obj", -1, -1);
    const char *p = shape_scene("sides.json", FOG "," ROOM,
                                "{\"file\":\"c.obj\",\"transform\":{\"scale\":2,\"translate\":[-1,-1,-1]},"
                                "\"material\":{\"type\":\"interface\"},\"inside\":\"fog\",\"outside\":\"room\"}",
                                "\"medium\":\"room\"");
    rd_scene *s;
    char err[RD_ERRLEN];
    cr_assert(load(p, &s, err) == RD_OK, "%s", err);
    rd_geom *g = build(s);
    ray3 r = {v3(-4, 0.3, 0.2), v3(1, 0, 0)};
    rd_hit h, h2;
    cr_assert(rd_geom_intersect(g, r, 0, INFINITY, NULL, &h));
    cr_expect(h.front && h.medium_from == 1 && h.medium_to == 0, "entering: from %d to %d", h.medium_from, h.medium_to);
    cr_expect(fabs(h.t - 3.0) < 1e-12);
    cr_assert(rd_geom_intersect(g, rd_hit_spawn(&h, r.d), 0, INFINITY, &h, &h2));
    cr_expect(!h2.front && h2.medium_from == 0 && h2.medium_to == 1, "leaving: from %d to %d", h2.medium_from, h2.medium_to);
    cr_expect(fabs(h2.p.x - 1.0) < 1e-12, "exit at x = %.17g", h2.p.x);
    rd_geom_free(g);
    rd_scene_free(s);
}

Test(geom, parallel_queries_agree_with_serial, .timeout = 120)
{
    rd_scene *s = ico_scene(1);
    rd_geom *g = build(s);
    enum { N = 20000 };
    static ray3 rays[N];
    static rd_hit serial[N], par[N];
    static int got_s[N], got_p[N], occ_s[N], occ_p[N];
    pcg32 rng = pcg32_seed(14, 4, 2);
    for (int i = 0; i < N; i++) rays[i] = random_ray_at_sphere(&rng, 4.0, 3.5);
    for (int i = 0; i < N; i++) {
        got_s[i] = rd_geom_intersect(g, rays[i], 0, INFINITY, NULL, &serial[i]);
        occ_s[i] = rd_geom_occluded(g, rays[i], 0, 5.0, NULL);
    }
    int threads = 0;
#pragma omp parallel num_threads(4)
    {
#pragma omp single
        threads = omp_get_num_threads();
#pragma omp for schedule(dynamic, 64)
        for (int i = 0; i < N; i++) {
            got_p[i] = rd_geom_intersect(g, rays[i], 0, INFINITY, NULL, &par[i]);
            occ_p[i] = rd_geom_occluded(g, rays[i], 0, 5.0, NULL);
        }
    }
    cr_expect(threads > 1, "ran on %d thread(s)", threads);
    int diff = 0, hits = 0;
    for (int i = 0; i < N; i++) {
        hits += got_s[i];
        if (got_s[i] != got_p[i] || occ_s[i] != occ_p[i]) diff++;
        else if (got_s[i] && (serial[i].t != par[i].t || serial[i].shape != par[i].shape || serial[i].light != par[i].light ||
                              serial[i].prim != par[i].prim))
            diff++;
    }
    cr_expect_eq(diff, 0, "%d of %d queries differ", diff, N);
    cr_expect(hits > N / 4, "%d hits", hits);
    rd_geom_free(g);
    rd_scene_free(s);
}

/* The glass slab again (test_material.c follows it analytically), now through the Embree scene:
 * a 20 x 20 x 1 box of relative index 1.5 entered from above at 40 degrees; each path is
 * followed by rd_geom_intersect, rd_material_sample (IMPORTANCE) and rd_hit_spawn until it
 * meets nothing more. The fraction leaving downward is (1 - F)/(1 + F) (F the unpolarised
 * reflectance at 40 degrees, the same at every face by reciprocity), within 5 standard errors
 * of the binomial. A self-hit or a lost side would change the count. */
Test(geom, glass_slab_through_embree, .timeout = 120)
{
    cube_obj("c.obj", -1, -1);
    const char *p = shape_scene("slab.json", "",
                                "{\"file\":\"c.obj\",\"transform\":{\"scale\":[20,20,1],\"translate\":[-10,-10,-0.5]},"
                                "\"material\":{\"type\":\"dielectric\",\"ior\":1.5}}",
                                "");
    rd_scene *s;
    char err[RD_ERRLEN];
    cr_assert(load(p, &s, err) == RD_OK, "%s", err);
    rd_geom *g = build(s);
    const rd_material *m = &s->shapes[0].material;
    const int N = 100000;
    double th = 40 * M_PI / 180, F = rd_fresnel_dielectric(cos(th), 1.5);
    long down = 0, stuck = 0;
    for (int i = 0; i < N; i++) {
        pcg32 rng = pcg32_seed(14, (uint64_t)i, 5);
        ray3 r = {v3(-3 * sin(th), 0.1, 3 * cos(th)), v3(sin(th), 0, -cos(th))};
        rd_hit h, prev;
        int have_prev = 0, n = 0;
        while (rd_geom_intersect(g, r, 0, INFINITY, have_prev ? &prev : NULL, &h)) {
            rd_surface_sample ss;
            if (++n > 1000 || !rd_material_sample(m, r.d, h.ng, h.ng, RD_TRANSPORT_IMPORTANCE, pcg32_uniform(&rng), 0, 0, &ss)) {
                stuck++;
                break;
            }
            r = rd_hit_spawn(&h, ss.d);
            prev = h;
            have_prev = 1;
        }
        if (r.d.z < 0) down++;
    }
    double expect = (1 - F) / (1 + F), got = (double)down / N, sd = sqrt(expect * (1 - expect) / N);
    cr_expect_eq(stuck, 0, "%ld paths stuck", stuck);
    cr_expect(fabs(got - expect) < 5 * sd, "transmitted %.5f, (1-F)/(1+F) = %.5f +- %.5f", got, expect, sd);
    rd_geom_free(g);
    rd_scene_free(s);
}

/* A shape's "outside" must be the medium around it (the inside of the innermost closed shape
 * that contains it, else the scene-wide medium): one line naming the file and the field, and the
 * medium that is there. A bubble (a shape inside another, of lower index: ior < 1) loads when
 * written right, in either order of the shapes, and its regions are the ones written. */
#define GLASS_CUBE "{\"name\":\"glass\",\"file\":\"c.obj\",\"transform\":{\"scale\":2.2,\"translate\":[-1.1,-1.1,-1.1]}," \
                   "\"material\":{\"type\":\"dielectric\",\"ior\":1.5},\"inside\":\"fog\",\"outside\":\"room\"}"
#define BUBBLE(outside) "{\"name\":\"bubble\",\"file\":\"c.obj\",\"transform\":{\"scale\":0.5,\"translate\":[-0.25,-0.25,-0.25]}," \
                        "\"material\":{\"type\":\"dielectric\",\"ior\":0.6667},\"inside\":null,\"outside\":" outside "}"
Test(geom, shape_outside_must_be_the_medium_around_it)
{
    cube_obj("c.obj", -1, -1);
    /* Nested: the bubble lies in the glass's fog, not in the room. */
    expect_scene_error(shape_scene("o1.json", FOG "," ROOM, GLASS_CUBE "," BUBBLE("\"room\""), "\"medium\":\"room\""),
                       "o1.json: shapes[1].outside: \"room\" but the shape lies in \"fog\"", "inside shapes[0] (\"glass\")");
    /* Top level: around it is the scene-wide medium, or vacuum when there is none. */
    expect_scene_error(shape_scene("o2.json", FOG "," ROOM, BUBBLE("\"fog\""), "\"medium\":\"room\""),
                       "o2.json: shapes[0].outside: \"fog\" but the shape lies in \"room\"", "scene-wide");
    expect_scene_error(shape_scene("o3.json", FOG "," ROOM, GLASS_CUBE, ""),
                       "o3.json: shapes[0].outside: \"room\" but the shape lies in vacuum (null)", NULL);
    /* The bubble written right, before or after the glass. */
    const char *orders[2] = {GLASS_CUBE "," BUBBLE("\"fog\""), BUBBLE("\"fog\"") "," GLASS_CUBE};
    for (int i = 0; i < 2; i++) {
        rd_scene *s;
        char err[RD_ERRLEN];
        cr_assert(load(shape_scene("bubble.json", FOG "," ROOM, orders[i], "\"medium\":\"room\""), &s, err) == RD_OK,
                  "order %d: %s", i, err);
        cr_expect_eq(rd_scene_region_at(s, v3(0, 0, 0)), -1, "order %d: inside the bubble: vacuum", i);
        cr_expect_eq(rd_scene_region_at(s, v3(0.6, 0.5, 0.4)), 0, "order %d: in the glass, outside the bubble: fog", i);
        cr_expect_eq(rd_scene_region_at(s, v3(0, 3, 0)), 1, "order %d: outside the glass: the room", i);
        rd_scene_free(s);
    }
}
