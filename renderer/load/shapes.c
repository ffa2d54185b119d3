/* shapes.c: the scene's "shapes" (a mesh file, its transform and material, the media inside
 * and outside) and the scene-wide "medium", which name media by name; the check that every
 * shape's outside is the medium actually around it; and the check that box media lie clear of
 * the shapes (issue 14; rd_geom.h). */
#include "scene/rd_geom.h"
#include "load/rd_load.h"

#include <cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_SHAPES 1024

/* ---- shapes and the scene-wide medium (issue 14; rd_geom.h) ------------------------------- */

/* The index of the medium named by key `key` of obj (a string or null), or -1 for null or a
 * missing key. The name must match exactly one medium's name. */
static rd_status medium_ref(ld_ctx *c, const cJSON *obj, const char *path, const char *key, const rd_scene *s, int *out)
{
    char p[300];
    ld_join(p, sizeof p, path, key);
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(obj, key);
    *out = -1;
    if (!j || cJSON_IsNull(j)) return RD_OK;
    if (!cJSON_IsString(j) || !j->valuestring[0])
        return ld_fail(c, p, "expected a medium's name or null, found %s", ld_type_name(j));
    int found = -1, count = 0;
    for (int i = 0; i < s->n_media; i++)
        if (strcmp(s->media[i].name, j->valuestring) == 0) found = i, count++;
    if (count == 0) {
        char list[256] = "";
        for (int i = 0; i < s->n_media; i++) {
            strncat(list, s->media[i].name, sizeof list - strlen(list) - 1);
            if (i + 1 < s->n_media) strncat(list, ", ", sizeof list - strlen(list) - 1);
        }
        return ld_fail(c, p, "no medium named \"%s\" (media: %s)", j->valuestring, s->n_media ? list : "none");
    }
    if (count > 1) return ld_fail(c, p, "%d media are named \"%s\": give them distinct names", count, j->valuestring);
    *out = found;
    return RD_OK;
}

/* shapes[i].transform: {"scale": s or [sx, sy, sz] (> 0), "rotate": {"axis": [x, y, z],
 * "angle": degrees}, "translate": [x, y, z]}, applied in that order (rd_geom.h). */
static rd_status parse_transform(ld_ctx *c, const cJSON *sh, const char *spath, rd_transform *xf)
{
    *xf = rd_transform_identity();
    char path[300];
    ld_join(path, sizeof path, spath, "transform");
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(sh, "transform");
    if (!j) return RD_OK;
    LD_TRY(ld_need_object(c, j, path));
    static const char *const keys[] = {"scale", "rotate", "translate", NULL};
    LD_TRY(ld_check_keys(c, j, path, keys));
    LD_TRY(ld_get_vec3(c, j, path, "scale", 0, v3(1, 1, 1), 1, -1e9, 1e9, &xf->scale));
    if (!(xf->scale.x > 0 && xf->scale.y > 0 && xf->scale.z > 0)) {
        char p[300];
        ld_join(p, sizeof p, path, "scale");
        return ld_fail(c, p, "must be > 0 on every axis (a mirroring or flattening scale would turn the mesh inside out)");
    }
    LD_TRY(ld_get_vec3(c, j, path, "translate", 0, v3(0, 0, 0), 0, -1e9, 1e9, &xf->translate));
    const cJSON *rot = cJSON_GetObjectItemCaseSensitive(j, "rotate");
    if (rot) {
        char p[300];
        ld_join(p, sizeof p, path, "rotate");
        LD_TRY(ld_need_object(c, rot, p));
        static const char *const rkeys[] = {"axis", "angle", NULL};
        LD_TRY(ld_check_keys(c, rot, p, rkeys));
        vec3 axis;
        LD_TRY(ld_get_vec3(c, rot, p, "axis", 1, v3(0, 0, 1), 0, -1e9, 1e9, &axis));
        if (!(v3_len(axis) > 1e-12)) {
            char q[300];
            ld_join(q, sizeof q, p, "axis");
            return ld_fail(c, q, "must not be the zero vector");
        }
        xf->axis = v3_norm(axis);
        LD_TRY(ld_get_num(c, rot, p, "angle", 1, 0, -360, 0, 360, 0, &xf->angle_deg));
    }
    return RD_OK;
}

static rd_status parse_material(ld_ctx *c, const cJSON *sh, const char *spath, rd_material *m)
{
    char path[300];
    ld_join(path, sizeof path, spath, "material");
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(sh, "material");
    if (!j) return ld_fail(c, path, "missing (required: {\"type\": \"dielectric\" | \"interface\" | \"diffuse\", ...})");
    LD_TRY(ld_need_object(c, j, path));
    static const char *const kinds[] = {"interface", "dielectric", "diffuse", NULL};
    int kind;
    LD_TRY(ld_get_enum(c, j, path, "type", 1, kinds, 0, &kind));
    memset(m, 0, sizeof *m);
    m->ior = 1.0;
    m->albedo = v3(0, 0, 0);
    if (kind == 0) {
        static const char *const keys[] = {"type", NULL};
        LD_TRY(ld_check_keys(c, j, path, keys));
        m->kind = RD_MAT_INTERFACE;
    } else if (kind == 1) {
        static const char *const keys[] = {"type", "ior", NULL};
        LD_TRY(ld_check_keys(c, j, path, keys));
        m->kind = RD_MAT_DIELECTRIC;
        LD_TRY(ld_get_num(c, j, path, "ior", 0, 1.5, 0.25, 0, 4, 0, &m->ior));
    } else {
        static const char *const keys[] = {"type", "albedo", NULL};
        LD_TRY(ld_check_keys(c, j, path, keys));
        m->kind = RD_MAT_DIFFUSE;
        LD_TRY(ld_get_vec3(c, j, path, "albedo", 0, v3(0.5, 0.5, 0.5), 1, 0, 1, &m->albedo));
    }
    return RD_OK;
}

static rd_status parse_shape(ld_ctx *c, const cJSON *j, int idx, rd_scene *s, rd_shape *sh)
{
    char path[64];
    snprintf(path, sizeof path, "shapes[%d]", idx);
    LD_TRY(ld_need_object(c, j, path));
    static const char *const keys[] = {"name", "file", "made_by", "transform", "material", "inside", "outside", NULL};
    LD_TRY(ld_check_keys(c, j, path, keys));
    const char *name, *file, *made_by;
    char defname[32];
    snprintf(defname, sizeof defname, "shape%d", idx);
    LD_TRY(ld_get_str(c, j, path, "name", 0, defname, &name));
    snprintf(sh->name, sizeof sh->name, "%s", name);
    LD_TRY(ld_get_str(c, j, path, "file", 1, NULL, &file));
    LD_TRY(ld_get_str(c, j, path, "made_by", 0, NULL, &made_by));
    rd_transform xf;
    LD_TRY(parse_transform(c, j, path, &xf));
    LD_TRY(parse_material(c, j, path, &sh->material));
    LD_TRY(medium_ref(c, j, path, "inside", s, &sh->inside));
    LD_TRY(medium_ref(c, j, path, "outside", s, &sh->outside));
    char p[300];
    if (sh->material.kind == RD_MAT_INTERFACE && sh->inside == sh->outside) {
        ld_join(p, sizeof p, path, "material.type");
        return ld_fail(c, p, "an interface between a medium and itself does nothing: give \"inside\" and \"outside\" different media");
    }
    ld_resolve_path(c, file, sh->file, sizeof sh->file);
    ld_join(p, sizeof p, path, "file");
    char msg[RD_ERRLEN];
    rd_status st = rd_mesh_load(sh->file, &xf, &sh->mesh, msg, sizeof msg);
    if (st) {
        char hint[300];
        ld_fail(c, p, "%s%s", msg, ld_missing_hint(sh->file, made_by, hint, sizeof hint));
        return st; /* RD_ERR_IO, RD_ERR_FORMAT or RD_ERR_NOMEM, as for volume files */
    }
    /* A boundary between two different media needs an inside: a closed, consistently
     * oriented mesh (rd_mesh.closed), or the path's medium would be wrong past a hole. */
    if (sh->inside != sh->outside && !sh->mesh.closed)
        return ld_fail(c, p, "%s: not a closed mesh (%zu edges are not shared by exactly two consistently wound triangles): "
                             "a shape with different inside and outside media must be closed", sh->file, sh->mesh.open_edges);
    return RD_OK;
}

/* "shapes" and the scene-wide "medium"; after the media (they name them). */
rd_status ld_parse_surfaces(ld_ctx *c, const cJSON *root, rd_scene *s)
{
    s->fill_medium = -1;
    LD_TRY(medium_ref(c, root, "", "medium", s, &s->fill_medium));
    const cJSON *shapes = cJSON_GetObjectItemCaseSensitive(root, "shapes");
    if (!shapes) return RD_OK;
    if (!cJSON_IsArray(shapes)) return ld_fail(c, "shapes", "expected an array, found %s", ld_type_name(shapes));
    int n = cJSON_GetArraySize(shapes);
    if (n > MAX_SHAPES) return ld_fail(c, "shapes", "at most %d shapes", MAX_SHAPES);
    s->shapes = calloc(n > 0 ? n : 1, sizeof *s->shapes);
    if (!s->shapes) return RD_ERR_NOMEM;
    for (int i = 0; i < n; i++) {
        rd_status st = parse_shape(c, cJSON_GetArrayItem(shapes, i), i, s, &s->shapes[i]);
        s->n_shapes = i + 1; /* so rd_scene_free releases a partly loaded shape */
        if (st) return st;
    }
    return RD_OK;
}


/* A box medium (not bound to surfaces) fills its bounds in the open region (the region of the
 * scene-wide medium: rd_scene.h "Surfaces in the transport"), so no shape that encloses
 * another region may reach into it: its bounds must not overlap the bounding box of a shape
 * whose inside is not the scene-wide medium. (A room whose walls enclose the scene-wide medium
 * may hold box media.) */
rd_status ld_check_boxes_clear_of_shapes(ld_ctx *c, const rd_scene *s)
{
    for (int i = 0; i < s->n_media; i++) {
        if (rd_scene_medium_bound(s, i)) continue;
        const rd_medium *a = &s->media[i];
        for (int k = 0; k < s->n_shapes; k++) {
            const rd_mesh *m = &s->shapes[k].mesh;
            if (s->shapes[k].inside == s->fill_medium) continue;
            if (a->bmin.x < m->bmax.x && m->bmin.x < a->bmax.x && a->bmin.y < m->bmax.y &&
                m->bmin.y < a->bmax.y && a->bmin.z < m->bmax.z && m->bmin.z < a->bmax.z) {
                char p[64];
                snprintf(p, sizeof p, "media[%d].bounds", i);
                return ld_fail(c, p, "overlaps the bounding box of shapes[%d] (\"%s\"): a box medium must lie clear of every shape "
                                     "that encloses a region other than the scene-wide medium's; make it a shape's inside (an \"interface\" shape around it) instead", k, s->shapes[k].name);
            }
        }
    }
    return RD_OK;
}

/* ---- a shape's outside against the medium around it (issue 24) ------------------------------ */

/* The distance along the ray (o, d) to triangle t of mesh m (Moller-Trumbore, in double), or
 * -1 when it misses; *back = 1 when the ray meets the triangle's back (d . n > 0, n by the
 * counter-clockwise winding: the outward normal of a closed mesh, rd_mesh). */
static double triangle_hit(const rd_mesh *m, size_t t, vec3 o, vec3 d, int *back)
{
    const float *P = m->positions;
    const uint32_t *ix = m->indices + 3 * t;
    vec3 a = v3(P[3 * ix[0]], P[3 * ix[0] + 1], P[3 * ix[0] + 2]);
    vec3 e1 = v3_sub(v3(P[3 * ix[1]], P[3 * ix[1] + 1], P[3 * ix[1] + 2]), a);
    vec3 e2 = v3_sub(v3(P[3 * ix[2]], P[3 * ix[2] + 1], P[3 * ix[2] + 2]), a);
    vec3 q = v3_cross(d, e2);
    double det = v3_dot(e1, q);
    if (det == 0.0) return -1.0;
    vec3 r = v3_sub(o, a);
    double u = v3_dot(r, q) / det;
    if (u < 0.0 || u > 1.0) return -1.0;
    vec3 w = v3_cross(r, e1);
    double v = v3_dot(d, w) / det;
    if (v < 0.0 || u + v > 1.0) return -1.0;
    double tt = v3_dot(e2, w) / det;
    if (!(tt > 0.0)) return -1.0;
    *back = v3_dot(d, v3_cross(e1, e2)) > 0.0;
    return tt;
}

/* Whether x lies inside the closed mesh m: the nearest triangle a ray from x meets is met from
 * its back (one nearest hit, not a parity count, so a ray through an edge does not matter
 * unless that edge is the nearest hit); *dist gets that hit's distance. */
static int inside_closed_mesh(const rd_mesh *m, vec3 x, vec3 d, double *dist)
{
    if (x.x < m->bmin.x || x.x > m->bmax.x || x.y < m->bmin.y || x.y > m->bmax.y || x.z < m->bmin.z ||
        x.z > m->bmax.z)
        return 0;
    double best = INFINITY;
    int best_back = 0;
    for (size_t t = 0; t < m->n_triangles; t++) {
        int back = 0;
        double h = triangle_hit(m, t, x, d, &back);
        if (h > 0.0 && h < best) best = h, best_back = back;
    }
    *dist = best;
    return isfinite(best) && best_back;
}

static const char *medium_label(const rd_scene *s, int i, char *buf, size_t n)
{
    if (i < 0) return "vacuum (null)";
    snprintf(buf, n, "\"%s\"", s->media[i].name);
    return buf;
}

/* Every shape's `outside` must be the medium around it: the `inside` of the innermost closed
 * shape that contains it (the first one a ray from the shape leaves through its back: nested
 * closed surfaces are left innermost first), or the scene-wide medium when no shape contains
 * it. A shape is located by the centroid of its first triangle. Otherwise a path crossing the
 * shape outward would take a medium that is not there. */
rd_status ld_check_shape_outsides(ld_ctx *c, const rd_scene *s)
{
    /* An arbitrary direction, off every axis and diagonal, so that a ray along it from a
     * face of an axis-aligned mesh does not run along another's edges. */
    const vec3 d = v3_norm(v3(0.3141592653, 0.5772156649, 0.7548776662));
    for (int k = 0; k < s->n_shapes; k++) {
        const rd_mesh *mk = &s->shapes[k].mesh;
        if (mk->n_triangles == 0) continue;
        const float *P = mk->positions;
        vec3 x = v3(0, 0, 0);
        for (int v = 0; v < 3; v++) {
            const float *q = P + 3 * mk->indices[v];
            x = v3_add(x, v3_scale(v3(q[0], q[1], q[2]), 1.0 / 3.0));
        }
        int around = s->fill_medium, container = -1;
        double nearest = INFINITY, dist;
        for (int j = 0; j < s->n_shapes; j++) {
            if (j == k || !s->shapes[j].mesh.closed) continue;
            if (inside_closed_mesh(&s->shapes[j].mesh, x, d, &dist) && dist < nearest) {
                nearest = dist;
                around = s->shapes[j].inside;
                container = j;
            }
        }
        if (s->shapes[k].outside == around) continue;
        char p[64], a[80], b[80], where[160];
        snprintf(p, sizeof p, "shapes[%d].outside", k);
        if (container >= 0)
            snprintf(where, sizeof where, "it is inside shapes[%d] (\"%s\")", container, s->shapes[container].name);
        else
            snprintf(where, sizeof where, "no shape contains it: the scene-wide \"medium\"");
        return ld_fail(c, p, "%s but the shape lies in %s (%s)", medium_label(s, s->shapes[k].outside, a, sizeof a),
                       medium_label(s, around, b, sizeof b), where);
    }
    return RD_OK;
}
