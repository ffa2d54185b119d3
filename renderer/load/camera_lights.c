/* camera_lights.c: the scene's "camera" and "lights" sections, read and checked field by field
 * into rd_camera and rd_light (docs/scene-format.md). */
#include "load/rd_load.h"

#include <cJSON.h>
#include <stdio.h>

#define MAX_RESOLUTION 16384

/* ---- camera -------------------------------------------------------------------------------- */
rd_status ld_parse_camera(ld_ctx *c, const cJSON *j, rd_camera *cam)
{
    const char *path = "camera";
    LD_TRY(ld_need_object(c, j, path));
    static const char *const kinds[] = {"perspective", "orthographic", NULL};
    int kind;
    LD_TRY(ld_get_enum(c, j, path, "type", 0, kinds, 0, &kind));
    cam->kind = kind == 0 ? RD_CAM_PERSPECTIVE : RD_CAM_ORTHOGRAPHIC;
    if (cam->kind == RD_CAM_PERSPECTIVE) {
        static const char *const keys[] = {"type", "position", "look_at", "up", "fov", "resolution", "exposure", "jitter", NULL};
        LD_TRY(ld_check_keys(c, j, path, keys));
    } else {
        static const char *const keys[] = {"type", "position", "direction", "up", "width", "resolution", "exposure", "jitter", NULL};
        LD_TRY(ld_check_keys(c, j, path, keys));
    }
    const cJSON *res = cJSON_GetObjectItemCaseSensitive(j, "resolution");
    if (!res) return ld_fail(c, "camera.resolution", "missing (required: [width, height])");
    if (!cJSON_IsArray(res) || cJSON_GetArraySize(res) != 2 || !cJSON_IsNumber(res->child) ||
        !cJSON_IsNumber(res->child->next))
        return ld_fail(c, "camera.resolution", "expected [width, height], two integers in [1, %d]", MAX_RESOLUTION);
    for (int i = 0; i < 2; i++) {
        double v = cJSON_GetArrayItem(res, i)->valuedouble;
        if (!isfinite(v) || v != floor(v) || v < 1 || v > MAX_RESOLUTION)
            return ld_fail(c, "camera.resolution", "expected [width, height], two integers in [1, %d], found %g",
                           MAX_RESOLUTION, v);
    }
    cam->width = cJSON_GetArrayItem(res, 0)->valueint;
    cam->height = cJSON_GetArrayItem(res, 1)->valueint;
    LD_TRY(ld_get_vec3(c, j, path, "position", 1, v3(0, 0, 0), 0, -1e9, 1e9, &cam->pos));
    vec3 up;
    LD_TRY(ld_get_vec3(c, j, path, "up", 0, v3(0, 1, 0), 0, -1e9, 1e9, &up));
    LD_TRY(ld_get_num(c, j, path, "exposure", 0, 0.0, -30, 0, 30, 0, &cam->exposure));
    LD_TRY(ld_get_bool(c, j, path, "jitter", 1, &cam->jitter));
    vec3 fwd;
    if (cam->kind == RD_CAM_PERSPECTIVE) {
        vec3 at;
        LD_TRY(ld_get_vec3(c, j, path, "look_at", 1, v3(0, 0, 0), 0, -1e9, 1e9, &at));
        fwd = v3_sub(at, cam->pos);
        if (v3_len(fwd) < 1e-12) return ld_fail(c, "camera.look_at", "must differ from camera.position");
        LD_TRY(ld_get_num(c, j, path, "fov", 0, 40.0, 0, 1, 180, 1, &cam->fov_deg));
        cam->tan_half_fov = tan(0.5 * cam->fov_deg * M_PI / 180.0);
    } else {
        LD_TRY(ld_get_vec3(c, j, path, "direction", 1, v3(0, 0, -1), 0, -1e9, 1e9, &fwd));
        if (v3_len(fwd) < 1e-12) return ld_fail(c, "camera.direction", "must not be the zero vector");
        LD_TRY(ld_get_num(c, j, path, "width", 1, 1.0, 0, 1, INFINITY, 0, &cam->ortho_width));
    }
    fwd = v3_norm(fwd);
    vec3 right = v3_cross(fwd, up);
    if (v3_len(right) < 1e-9 * (v3_len(up) + 1e-300))
        return ld_fail(c, "camera.up", "must not be parallel to the view direction");
    cam->forward = fwd;
    cam->right = v3_norm(right);
    cam->up = v3_cross(cam->right, fwd);
    return RD_OK;
}


/* ---- lights -------------------------------------------------------------------------------- */
rd_status ld_parse_light(ld_ctx *c, const cJSON *j, int idx, rd_light *l)
{
    char path[64];
    snprintf(path, sizeof path, "lights[%d]", idx);
    LD_TRY(ld_need_object(c, j, path));
    static const char *const kinds[] = {"point", "spot", "directional", "sphere", "environment", NULL};
    int kind;
    LD_TRY(ld_get_enum(c, j, path, "type", 1, kinds, 0, &kind));
    const double big = 1e12;
    switch (kind) {
    case 0: {
        static const char *const keys[] = {"type", "position", "intensity", NULL};
        LD_TRY(ld_check_keys(c, j, path, keys));
        l->kind = RD_LIGHT_POINT;
        LD_TRY(ld_get_vec3(c, j, path, "position", 1, v3(0, 0, 0), 0, -1e9, 1e9, &l->pos));
        LD_TRY(ld_get_vec3(c, j, path, "intensity", 1, v3(0, 0, 0), 1, 0, big, &l->value));
        break;
    }
    case 1: {
        static const char *const keys[] = {"type", "position", "direction", "look_at", "angle",
                                           "falloff", "intensity", NULL};
        LD_TRY(ld_check_keys(c, j, path, keys));
        l->kind = RD_LIGHT_SPOT;
        LD_TRY(ld_get_vec3(c, j, path, "position", 1, v3(0, 0, 0), 0, -1e9, 1e9, &l->pos));
        int has_dir = cJSON_GetObjectItemCaseSensitive(j, "direction") != NULL;
        int has_at = cJSON_GetObjectItemCaseSensitive(j, "look_at") != NULL;
        if (has_dir == has_at) return ld_fail(c, path, "give exactly one of direction, look_at");
        vec3 d;
        if (has_dir) LD_TRY(ld_get_vec3(c, j, path, "direction", 1, v3(0, 0, 0), 0, -1e9, 1e9, &d));
        else {
            vec3 at;
            LD_TRY(ld_get_vec3(c, j, path, "look_at", 1, v3(0, 0, 0), 0, -1e9, 1e9, &at));
            d = v3_sub(at, l->pos);
        }
        if (v3_len(d) < 1e-12) return ld_fail(c, path, "direction: must not be the zero vector");
        l->dir = v3_norm(d);
        double angle, falloff;
        LD_TRY(ld_get_num(c, j, path, "angle", 1, 30, 0, 1, 180, 0, &angle));
        LD_TRY(ld_get_num(c, j, path, "falloff", 0, 0.1 * angle, 0, 0, 180, 0, &falloff));
        if (falloff > 0.5 * angle) {
            char p[128];
            ld_join(p, sizeof p, path, "falloff");
            return ld_fail(c, p, "must be in [0, angle/2] = [0, %g], found %g", 0.5 * angle, falloff);
        }
        /* angle is the full cone angle (degrees); the intensity falls smoothly to zero over the
         * outer `falloff` degrees of the half-angle. */
        double half = 0.5 * angle * M_PI / 180.0;
        l->cos_outer = cos(half);
        l->cos_inner = cos(half - falloff * M_PI / 180.0);
        LD_TRY(ld_get_vec3(c, j, path, "intensity", 1, v3(0, 0, 0), 1, 0, big, &l->value));
        break;
    }
    case 2: {
        static const char *const keys[] = {"type", "direction", "irradiance", "radius", "center", NULL};
        LD_TRY(ld_check_keys(c, j, path, keys));
        l->kind = RD_LIGHT_DIRECTIONAL;
        vec3 d;
        LD_TRY(ld_get_vec3(c, j, path, "direction", 1, v3(0, 0, 0), 0, -1e9, 1e9, &d));
        if (v3_len(d) < 1e-12) return ld_fail(c, path, "direction: must not be the zero vector");
        l->dir = v3_norm(d);
        LD_TRY(ld_get_vec3(c, j, path, "irradiance", 1, v3(0, 0, 0), 1, 0, big, &l->value));
        LD_TRY(ld_get_num(c, j, path, "radius", 0, 0.0, 0, 0, 1e9, 0, &l->radius));
        LD_TRY(ld_get_vec3(c, j, path, "center", l->radius > 0, v3(0, 0, 0), 0, -1e9, 1e9, &l->beam_center));
        break;
    }
    case 3: {
        static const char *const keys[] = {"type", "center", "radius", "radiance", NULL};
        LD_TRY(ld_check_keys(c, j, path, keys));
        l->kind = RD_LIGHT_SPHERE;
        LD_TRY(ld_get_vec3(c, j, path, "center", 1, v3(0, 0, 0), 0, -1e9, 1e9, &l->pos));
        LD_TRY(ld_get_num(c, j, path, "radius", 1, 0, 0, 1, 1e9, 0, &l->radius));
        LD_TRY(ld_get_vec3(c, j, path, "radiance", 1, v3(0, 0, 0), 1, 0, big, &l->value));
        break;
    }
    default: {
        static const char *const keys[] = {"type", "radiance", NULL};
        LD_TRY(ld_check_keys(c, j, path, keys));
        l->kind = RD_LIGHT_ENVIRONMENT;
        LD_TRY(ld_get_vec3(c, j, path, "radiance", 1, v3(0, 0, 0), 1, 0, big, &l->value));
        break;
    }
    }
    return RD_OK;
}
