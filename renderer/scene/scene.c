/* scene.c: JSON scene loading (cJSON) and validation of every field.
 *
 * Every error names the file and the JSON path and says what is wrong, e.g.
 *   fog.json: media[0].albedo: expected a number or 3 numbers in [0, 1]
 * Unknown keys are errors, so a typo is never silently ignored. The format is documented in
 * docs/scene-format.md. */
#include "scene/rd_geom.h"
#include "rd_internal.h"
#include "integrators/rd_method.h"

#include <cJSON.h>
#include <errno.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define MAX_SCENE_BYTES (64u << 20)
#define MAX_RESOLUTION 16384
#define MAX_MEDIA 64
#define MAX_LIGHTS 256
#define MAX_SHAPES 1024

/* Validation context: where we are and where errors go. */
typedef struct {
    const char *file; /* the scene path as the user gave it */
    char dir[1024];   /* its folder, for relative volume paths */
    char *err;
    size_t errlen;
} vctx;

static rd_status fail(vctx *c, const char *path, const char *fmt, ...)
{
    char msg[RD_ERRLEN];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (c->err && c->errlen) snprintf(c->err, c->errlen, "%s: %s: %s", c->file, path, msg);
    return RD_ERR_SCENE;
}

static void join(char *out, size_t n, const char *parent, const char *key)
{
    /* Keys are short; a key that does not fit is cut, never overflowed. */
    snprintf(out, n, "%.200s%s%.90s", parent, parent[0] ? "." : "", key);
}

static const char *type_name(const cJSON *j)
{
    if (cJSON_IsNumber(j)) return "a number";
    if (cJSON_IsString(j)) return "a string";
    if (cJSON_IsBool(j)) return "a boolean";
    if (cJSON_IsNull(j)) return "null";
    if (cJSON_IsArray(j)) return "an array";
    if (cJSON_IsObject(j)) return "an object";
    return "something else";
}

/* Reject keys not in `allowed` (NULL-terminated). */
static rd_status check_keys(vctx *c, const cJSON *obj, const char *path, const char *const *allowed)
{
    for (const cJSON *it = obj->child; it; it = it->next) {
        int ok = 0;
        for (const char *const *a = allowed; *a; a++)
            if (strcmp(it->string, *a) == 0) ok = 1;
        if (!ok) {
            char p[300], list[256] = "";
            join(p, sizeof p, path, it->string);
            for (const char *const *a = allowed; *a; a++) {
                strncat(list, *a, sizeof list - strlen(list) - 1);
                if (a[1]) strncat(list, ", ", sizeof list - strlen(list) - 1);
            }
            return fail(c, p, "unknown key (allowed: %s)", list);
        }
    }
    return RD_OK;
}

static rd_status need_object(vctx *c, const cJSON *j, const char *path)
{
    if (!cJSON_IsObject(j)) return fail(c, path, "expected an object, found %s", type_name(j));
    return RD_OK;
}

/* A finite number in [lo, hi] (open ends when lo_open / hi_open). Missing: default when
 * `required` is 0. */
static rd_status get_num(vctx *c, const cJSON *obj, const char *path, const char *key, int required,
                         double def, double lo, int lo_open, double hi, int hi_open, double *out)
{
    char p[300];
    join(p, sizeof p, path, key);
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!j) {
        if (required) return fail(c, p, "missing (required)");
        *out = def;
        return RD_OK;
    }
    if (!cJSON_IsNumber(j)) return fail(c, p, "expected a number, found %s", type_name(j));
    double v = j->valuedouble;
    if (!isfinite(v)) return fail(c, p, "must be finite");
    if ((lo_open ? v <= lo : v < lo) || (hi_open ? v >= hi : v > hi))
        return fail(c, p, "must be in %c%.10g, %.10g%c, found %.10g", lo_open ? '(' : '[', lo, hi,
                    hi_open ? ')' : ']', v);
    *out = v;
    return RD_OK;
}

static rd_status get_int(vctx *c, const cJSON *obj, const char *path, const char *key, int required,
                         long long def, long long lo, long long hi, long long *out)
{
    double v;
    rd_status st = get_num(c, obj, path, key, required, (double)def, (double)lo, 0, (double)hi, 0, &v);
    if (st) return st;
    if (v != floor(v)) {
        char p[300];
        join(p, sizeof p, path, key);
        return fail(c, p, "expected an integer, found %g", v);
    }
    *out = (long long)v;
    return RD_OK;
}

/* Three finite numbers (or, when `allow_scalar`, one number replicated), each in [lo, hi]. */
static rd_status get_vec3(vctx *c, const cJSON *obj, const char *path, const char *key, int required,
                          vec3 def, int allow_scalar, double lo, double hi, vec3 *out)
{
    char p[300];
    join(p, sizeof p, path, key);
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(obj, key);
    char range[64] = "";
    if (isfinite(lo) || isfinite(hi)) snprintf(range, sizeof range, " in [%g, %g]", lo, hi);
    const char *want = allow_scalar ? "a number or 3 numbers" : "3 numbers";
    if (!j) {
        if (required) return fail(c, p, "missing (required: %s)", want);
        *out = def;
        return RD_OK;
    }
    double v[3];
    if (allow_scalar && cJSON_IsNumber(j)) {
        v[0] = v[1] = v[2] = j->valuedouble;
    } else {
        if (!cJSON_IsArray(j) || cJSON_GetArraySize(j) != 3)
            return fail(c, p, "expected %s%s", want, range);
        for (int i = 0; i < 3; i++) {
            const cJSON *e = cJSON_GetArrayItem(j, i);
            if (!cJSON_IsNumber(e)) return fail(c, p, "expected %s%s", want, range);
            v[i] = e->valuedouble;
        }
    }
    for (int i = 0; i < 3; i++)
        if (!isfinite(v[i]) || v[i] < lo || v[i] > hi)
            return fail(c, p, "expected %s%s, found %g", want, range, v[i]);
    *out = v3(v[0], v[1], v[2]);
    return RD_OK;
}

static rd_status get_str(vctx *c, const cJSON *obj, const char *path, const char *key, int required,
                         const char *def, const char **out)
{
    char p[300];
    join(p, sizeof p, path, key);
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!j) {
        if (required) return fail(c, p, "missing (required)");
        *out = def;
        return RD_OK;
    }
    if (!cJSON_IsString(j) || !j->valuestring[0])
        return fail(c, p, "expected a non-empty string, found %s", type_name(j));
    *out = j->valuestring;
    return RD_OK;
}

static rd_status get_bool(vctx *c, const cJSON *obj, const char *path, const char *key, int def, int *out)
{
    char p[300];
    join(p, sizeof p, path, key);
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!j) { *out = def; return RD_OK; }
    if (!cJSON_IsBool(j)) return fail(c, p, "expected true or false, found %s", type_name(j));
    *out = cJSON_IsTrue(j);
    return RD_OK;
}

/* Map a string to one of `names` (NULL-terminated); the index goes to *out. */
static rd_status get_enum(vctx *c, const cJSON *obj, const char *path, const char *key, int required,
                          const char *const *names, int def, int *out)
{
    const char *s;
    rd_status st = get_str(c, obj, path, key, required, NULL, &s);
    if (st) return st;
    if (!s) { *out = def; return RD_OK; }
    for (int i = 0; names[i]; i++)
        if (strcmp(s, names[i]) == 0) { *out = i; return RD_OK; }
    char p[300], list[256] = "";
    join(p, sizeof p, path, key);
    for (int i = 0; names[i]; i++) {
        strncat(list, names[i], sizeof list - strlen(list) - 1);
        if (names[i + 1]) strncat(list, ", ", sizeof list - strlen(list) - 1);
    }
    return fail(c, p, "unknown value \"%s\" (expected one of: %s)", s, list);
}

#define TRY(x) do { rd_status st_ = (x); if (st_) return st_; } while (0)

/* ---- camera -------------------------------------------------------------------------------- */
static rd_status parse_camera(vctx *c, const cJSON *j, rd_camera *cam)
{
    const char *path = "camera";
    TRY(need_object(c, j, path));
    static const char *const kinds[] = {"perspective", "orthographic", NULL};
    int kind;
    TRY(get_enum(c, j, path, "type", 0, kinds, 0, &kind));
    cam->kind = kind == 0 ? RD_CAM_PERSPECTIVE : RD_CAM_ORTHOGRAPHIC;
    if (cam->kind == RD_CAM_PERSPECTIVE) {
        static const char *const keys[] = {"type", "position", "look_at", "up", "fov", "resolution", "exposure", "jitter", NULL};
        TRY(check_keys(c, j, path, keys));
    } else {
        static const char *const keys[] = {"type", "position", "direction", "up", "width", "resolution", "exposure", "jitter", NULL};
        TRY(check_keys(c, j, path, keys));
    }
    const cJSON *res = cJSON_GetObjectItemCaseSensitive(j, "resolution");
    if (!res) return fail(c, "camera.resolution", "missing (required: [width, height])");
    if (!cJSON_IsArray(res) || cJSON_GetArraySize(res) != 2 || !cJSON_IsNumber(res->child) ||
        !cJSON_IsNumber(res->child->next))
        return fail(c, "camera.resolution", "expected [width, height], two integers in [1, %d]", MAX_RESOLUTION);
    for (int i = 0; i < 2; i++) {
        double v = cJSON_GetArrayItem(res, i)->valuedouble;
        if (!isfinite(v) || v != floor(v) || v < 1 || v > MAX_RESOLUTION)
            return fail(c, "camera.resolution", "expected [width, height], two integers in [1, %d], found %g",
                        MAX_RESOLUTION, v);
    }
    cam->width = cJSON_GetArrayItem(res, 0)->valueint;
    cam->height = cJSON_GetArrayItem(res, 1)->valueint;
    TRY(get_vec3(c, j, path, "position", 1, v3(0, 0, 0), 0, -1e9, 1e9, &cam->pos));
    vec3 up;
    TRY(get_vec3(c, j, path, "up", 0, v3(0, 1, 0), 0, -1e9, 1e9, &up));
    TRY(get_num(c, j, path, "exposure", 0, 0.0, -30, 0, 30, 0, &cam->exposure));
    TRY(get_bool(c, j, path, "jitter", 1, &cam->jitter));
    vec3 fwd;
    if (cam->kind == RD_CAM_PERSPECTIVE) {
        vec3 at;
        TRY(get_vec3(c, j, path, "look_at", 1, v3(0, 0, 0), 0, -1e9, 1e9, &at));
        fwd = v3_sub(at, cam->pos);
        if (v3_len(fwd) < 1e-12) return fail(c, "camera.look_at", "must differ from camera.position");
        TRY(get_num(c, j, path, "fov", 0, 40.0, 0, 1, 180, 1, &cam->fov_deg));
    } else {
        TRY(get_vec3(c, j, path, "direction", 1, v3(0, 0, -1), 0, -1e9, 1e9, &fwd));
        if (v3_len(fwd) < 1e-12) return fail(c, "camera.direction", "must not be the zero vector");
        TRY(get_num(c, j, path, "width", 1, 1.0, 0, 1, INFINITY, 0, &cam->ortho_width));
    }
    fwd = v3_norm(fwd);
    vec3 right = v3_cross(fwd, up);
    if (v3_len(right) < 1e-9 * (v3_len(up) + 1e-300))
        return fail(c, "camera.up", "must not be parallel to the view direction");
    cam->forward = fwd;
    cam->right = v3_norm(right);
    cam->up = v3_cross(cam->right, fwd);
    return RD_OK;
}

/* ---- media --------------------------------------------------------------------------------- */
static void resolve_path(const vctx *c, const char *file, char *out, size_t n)
{
    if (file[0] == '/' || !c->dir[0]) snprintf(out, n, "%s", file);
    else snprintf(out, n, "%s/%s", c->dir, file);
}

static rd_status parse_bounds(vctx *c, const cJSON *m, const char *path, int required, rd_medium *med,
                              int *present)
{
    char p[300];
    join(p, sizeof p, path, "bounds");
    const cJSON *b = cJSON_GetObjectItemCaseSensitive(m, "bounds");
    *present = b != NULL;
    if (!b) {
        if (required) return fail(c, p, "missing (required: {\"min\": [x,y,z], \"max\": [x,y,z]})");
        return RD_OK;
    }
    TRY(need_object(c, b, p));
    static const char *const keys[] = {"min", "max", NULL};
    TRY(check_keys(c, b, p, keys));
    TRY(get_vec3(c, b, p, "min", 1, v3(0, 0, 0), 0, -1e9, 1e9, &med->bmin));
    TRY(get_vec3(c, b, p, "max", 1, v3(0, 0, 0), 0, -1e9, 1e9, &med->bmax));
    if (!(med->bmin.x < med->bmax.x && med->bmin.y < med->bmax.y && med->bmin.z < med->bmax.z))
        return fail(c, p, "min must be smaller than max on every axis");
    return RD_OK;
}

/* What to add to a density file's error (written into buf): a file that does not exist and that
 * the scene says a script makes ("made_by") is not committed, so name the script to run. */
static const char *missing_hint(const char *file, const char *made_by, char *buf, size_t n)
{
    buf[0] = '\0';
    struct stat sb;
    if (made_by && stat(file, &sb) != 0)
        snprintf(buf, n, " (not committed: made by %s; run it first)", made_by);
    return buf;
}

static rd_status parse_density(vctx *c, const cJSON *m, const char *mpath, rd_medium *med,
                               int has_bounds)
{
    char path[300];
    join(path, sizeof path, mpath, "density");
    const cJSON *d = cJSON_GetObjectItemCaseSensitive(m, "density");
    if (!d) return fail(c, path, "missing (required)");
    if (cJSON_IsNumber(d)) { /* shorthand: "density": 0.5 */
        if (!isfinite(d->valuedouble) || d->valuedouble < 0)
            return fail(c, path, "must be a finite number >= 0");
        med->kind = RD_DENSITY_CONSTANT;
        med->constant = d->valuedouble;
        if (!has_bounds) return fail(c, mpath[0] ? mpath : "media", "bounds: missing (required)");
        return RD_OK;
    }
    TRY(need_object(c, d, path));
    static const char *const kinds[] = {"constant", "vdb", "raw", "noise", NULL};
    int kind;
    TRY(get_enum(c, d, path, "type", 1, kinds, 0, &kind));
    if (kind != 1 && !has_bounds && kind != 3) {
        char p[300];
        join(p, sizeof p, mpath, "bounds");
        return fail(c, p, "missing (required for a %s density)", kinds[kind]);
    }
    char full[2048];
    if (kind == 0) {
        static const char *const keys[] = {"type", "value", NULL};
        TRY(check_keys(c, d, path, keys));
        med->kind = RD_DENSITY_CONSTANT;
        TRY(get_num(c, d, path, "value", 1, 0, 0, 0, 1e12, 0, &med->constant));
    } else if (kind == 1) {
        static const char *const keys[] = {"type", "file", "grid", "made_by", NULL};
        TRY(check_keys(c, d, path, keys));
        if (has_bounds) {
            char p[300];
            join(p, sizeof p, mpath, "bounds");
            return fail(c, p, "not allowed with a vdb density (the bounds come from the grid and its transform)");
        }
        const char *file, *grid, *made_by;
        TRY(get_str(c, d, path, "file", 1, NULL, &file));
        TRY(get_str(c, d, path, "grid", 0, "density", &grid));
        TRY(get_str(c, d, path, "made_by", 0, NULL, &made_by));
        resolve_path(c, file, full, sizeof full);
        med->kind = RD_DENSITY_GRID;
        char msg[RD_ERRLEN];
        rd_status st = rd_vdb_load(full, grid, &med->grid, &med->bmin, &med->bmax, msg, sizeof msg);
        if (st) {
            char p[300];
            join(p, sizeof p, path, "file");
            char hint[300];
            fail(c, p, "%s%s", msg, missing_hint(full, made_by, hint, sizeof hint));
            return st;
        }
    } else if (kind == 2) {
        static const char *const keys[] = {"type", "file", "dims", "made_by", NULL};
        TRY(check_keys(c, d, path, keys));
        const char *file, *made_by;
        TRY(get_str(c, d, path, "file", 1, NULL, &file));
        TRY(get_str(c, d, path, "made_by", 0, NULL, &made_by));
        char p[300];
        join(p, sizeof p, path, "dims");
        const cJSON *dims = cJSON_GetObjectItemCaseSensitive(d, "dims");
        if (!dims) return fail(c, p, "missing (required: [nx, ny, nz])");
        int n[3];
        if (!cJSON_IsArray(dims) || cJSON_GetArraySize(dims) != 3)
            return fail(c, p, "expected 3 integers in [1, 4096]");
        for (int i = 0; i < 3; i++) {
            const cJSON *e = cJSON_GetArrayItem(dims, i);
            if (!cJSON_IsNumber(e) || e->valuedouble != floor(e->valuedouble) || e->valuedouble < 1 ||
                e->valuedouble > 4096)
                return fail(c, p, "expected 3 integers in [1, 4096]");
            n[i] = e->valueint;
        }
        resolve_path(c, file, full, sizeof full);
        med->kind = RD_DENSITY_GRID;
        char msg[RD_ERRLEN];
        rd_status st = rd_raw_load(full, n[0], n[1], n[2], &med->grid, msg, sizeof msg);
        if (st) {
            join(p, sizeof p, path, "file");
            char hint[300];
            fail(c, p, "%s%s", msg, missing_hint(full, made_by, hint, sizeof hint));
            return st;
        }
        /* The voxels fill the medium bounds: u = n (x - bmin) / (bmax - bmin). */
        memset(med->grid.w2g, 0, sizeof med->grid.w2g);
        for (int a = 0; a < 3; a++) {
            double lo = v3_get(med->bmin, a), hi = v3_get(med->bmax, a);
            med->grid.w2g[a][a] = n[a] / (hi - lo);
            med->grid.w2g[a][3] = -lo * n[a] / (hi - lo);
        }
    } else {
        static const char *const keys[] = {"type", "octaves", "frequency", "gain", "lacunarity",
                                           "amplitude", "seed", "shape", "edge", NULL};
        TRY(check_keys(c, d, path, keys));
        rd_noise *nz = &med->noise;
        long long oct, seed;
        TRY(get_int(c, d, path, "octaves", 0, 5, 1, 16, &oct));
        TRY(get_num(c, d, path, "frequency", 0, 2.0, 0, 1, 1e6, 0, &nz->frequency));
        TRY(get_num(c, d, path, "gain", 0, 0.5, 0, 0, 1, 0, &nz->gain));
        TRY(get_num(c, d, path, "lacunarity", 0, 2.0, 1, 0, 8, 0, &nz->lacunarity));
        TRY(get_num(c, d, path, "amplitude", 0, 1.0, 0, 0, 100, 0, &nz->amplitude));
        TRY(get_int(c, d, path, "seed", 0, 1, 0, UINT32_MAX, &seed));
        TRY(get_num(c, d, path, "edge", 0, 0.4, 0, 1, 1, 0, &nz->edge));
        static const char *const shapes[] = {"none", "ellipsoid", NULL};
        int shape;
        TRY(get_enum(c, d, path, "shape", 0, shapes, 1, &shape));
        nz->octaves = (int)oct;
        nz->seed = (uint32_t)seed;
        /* The finest octave must stay a sane number of lattice cells per unit (its lattice
         * coordinates are converted to integers). */
        double finest = nz->frequency * pow(nz->lacunarity, nz->octaves - 1);
        if (!(finest <= 1e6))
            return fail(c, path, "the finest octave's frequency, frequency x lacunarity^(octaves-1) = %.3g, exceeds 1e6", finest);
        nz->shape = shape == 0 ? RD_SHAPE_NONE : RD_SHAPE_ELLIPSOID;
        if (!has_bounds) {
            char p[300];
            join(p, sizeof p, mpath, "bounds");
            return fail(c, p, "missing (required: the noise fills, and its ellipsoid is inscribed in, the bounds)");
        }
        nz->center = v3_scale(v3_add(med->bmin, med->bmax), 0.5);
        nz->radii = v3_scale(v3_sub(med->bmax, med->bmin), 0.5);
        rd_noise_init_perm(nz);
        med->kind = RD_DENSITY_NOISE;
    }
    return RD_OK;
}

static rd_status parse_medium(vctx *c, const cJSON *m, int idx, rd_medium *med)
{
    char path[64];
    snprintf(path, sizeof path, "media[%d]", idx);
    TRY(need_object(c, m, path));
    static const char *const keys[] = {"name", "bounds", "density", "sigma_t", "albedo", "g", "majorant", NULL};
    TRY(check_keys(c, m, path, keys));
    const char *name;
    char defname[32];
    snprintf(defname, sizeof defname, "medium%d", idx);
    TRY(get_str(c, m, path, "name", 0, defname, &name));
    snprintf(med->name, sizeof med->name, "%s", name);
    int has_bounds;
    TRY(parse_bounds(c, m, path, 0, med, &has_bounds));
    TRY(parse_density(c, m, path, med, has_bounds));
    TRY(get_num(c, m, path, "sigma_t", 1, 1.0, 0, 0, 1e9, 0, &med->sigma_t_scale));
    TRY(get_vec3(c, m, path, "albedo", 0, v3(1, 1, 1), 1, 0, 1, &med->albedo));
    TRY(get_num(c, m, path, "g", 0, 0.0, -1, 1, 1, 1, &med->g));
    switch (med->kind) {
    case RD_DENSITY_CONSTANT: med->density_max = med->constant; break;
    case RD_DENSITY_GRID: med->density_max = fmax(0.0, med->grid.vmax); break;
    case RD_DENSITY_NOISE: /* shape <= 1, so density <= 1 + amplitude * bound(|fbm|) */
        med->density_max = 1.0 + med->noise.amplitude * rd_noise_fbm_bound(&med->noise);
        break;
    }
    med->sigma_maj = med->density_max * med->sigma_t_scale;
    med->density_min = med->kind == RD_DENSITY_CONSTANT ? med->constant : 0.0;
    /* A medium so thick that one ray needs more than ~1e7 tentative collisions would make a
     * render that never finishes: refuse it (before building anything for it) rather than hang. */
    double tau = med->sigma_maj * v3_len(v3_sub(med->bmax, med->bmin));
    if (!(tau <= 1e7)) {
        char p[300];
        join(p, sizeof p, path, "sigma_t");
        return fail(c, p, "majorant optical depth across the bounds is %.3g, more than 1e7: the medium is too thick to render (lower sigma_t or the density)", tau);
    }

    /* Majorant structure (rd_freepath.h): {"type": "auto"|"none"|"grid"|"octree",
     * "resolution": N (grid), "bound": "constant"|"trilinear" (grid), "fail": F (octree)}. */
    rd_majorant_opts mo = {RD_MAJ_AUTO, 0, RD_BOUND_CONSTANT, 2, 0, 0.0};
    const cJSON *mj = cJSON_GetObjectItemCaseSensitive(m, "majorant");
    char mpath[300];
    join(mpath, sizeof mpath, path, "majorant");
    if (mj) {
        TRY(need_object(c, mj, mpath));
        static const char *const mkeys[] = {"type", "resolution", "bound", "fail", "max_level", "rewind_cost", NULL};
        TRY(check_keys(c, mj, mpath, mkeys));
        static const char *const mtypes[] = {"auto", "none", "grid", "octree", NULL};
        static const char *const bounds[] = {"constant", "trilinear", NULL};
        int type, bound;
        long long v;
        TRY(get_enum(c, mj, mpath, "type", 0, mtypes, 0, &type));
        mo.kind = (rd_maj_kind)type;
        TRY(get_enum(c, mj, mpath, "bound", 0, bounds, 0, &bound));
        mo.bound = (rd_bound_kind)bound;
        /* 256^3 super-voxels (16.7 M cells, 128 MiB of bounds) is past any gain (seed 003:
         * 16^3 is best for 512^3 data); larger grids would only cost memory and build time. */
        TRY(get_int(c, mj, mpath, "resolution", 0, 0, 1, 256, &v));
        mo.resolution = (int)v;
        TRY(get_int(c, mj, mpath, "fail", 0, 2, 0, 8, &v));
        mo.fail_limit = (int)v;
        TRY(get_int(c, mj, mpath, "max_level", 0, 0, 1, 8, &v));
        mo.max_level = (int)v;
        TRY(get_num(c, mj, mpath, "rewind_cost", 0, 0.0, 0, 1, 10, 0, &mo.rewind_cost));
        char p[300];
        if (cJSON_GetObjectItemCaseSensitive(mj, "resolution") && mo.kind != RD_MAJ_GRID) {
            join(p, sizeof p, mpath, "resolution");
            return fail(c, p, "only with \"type\": \"grid\"");
        }
        if (cJSON_GetObjectItemCaseSensitive(mj, "fail") && mo.kind != RD_MAJ_OCTREE) {
            join(p, sizeof p, mpath, "fail");
            return fail(c, p, "only with \"type\": \"octree\"");
        }
        if (mo.bound == RD_BOUND_TRILINEAR && mo.kind != RD_MAJ_GRID && mo.kind != RD_MAJ_AUTO) {
            join(p, sizeof p, mpath, "bound");
            return fail(c, p, "\"trilinear\" needs \"type\": \"grid\" or \"auto\"");
        }
    }
    /* Seed 000 eq. 15: a rewind (one DDA step) against an iteration, which costs a density
     * lookup: a trilinear fetch for grids, one Perlin evaluation per octave for noise. The
     * ratios 0.1 (grids) and 0.8 / octaves (noise) were calibrated by bench_freepath
     * --calibrate on media that are not in its benchmark (docs/benchmarks.md), so the
     * benchmark that judges them did not choose them. Fixed per density kind, so the structure,
     * and the image, never depend on timing. */
    if (mo.rewind_cost == 0.0)
        mo.rewind_cost = med->kind == RD_DENSITY_GRID ? 0.1 : med->kind == RD_DENSITY_NOISE ? 0.8 / med->noise.octaves : 1.0;
    /* A constant medium gains nothing from a partition (eq. 14 >= eq. 17): skip the levels. */
    if (mo.kind == RD_MAJ_AUTO && med->kind == RD_DENSITY_CONSTANT) mo.kind = RD_MAJ_NONE;
    if (mo.max_level == 0) {
        /* Finest level of the cost-model search: no finer than the voxels, at most 128 cells
         * per axis for grids and 64 for procedural noise (bounding cost grows with the cells). */
        int lim = med->kind == RD_DENSITY_NOISE ? 64 : 128;
        if (med->kind == RD_DENSITY_GRID) {
            int nmax = med->grid.nx > med->grid.ny ? med->grid.nx : med->grid.ny;
            if (med->grid.nz > nmax) nmax = med->grid.nz;
            if (nmax < lim) lim = nmax;
        }
        mo.max_level = 1;
        while ((2 << mo.max_level) <= lim && mo.max_level < 8) mo.max_level++;
    }
    char msg[RD_ERRLEN];
    med->majorant = rd_majorant_build(med->bmin, med->bmax, med->sigma_t_scale, med->sigma_maj,
                                      rd_medium_box_bound, med, &mo, msg, sizeof msg);
    if (!med->majorant) {
        fail(c, mpath, "%s", msg);
        return RD_ERR_NOMEM;
    }
    if (med->kind != RD_DENSITY_CONSTANT) med->density_min = med->majorant->dmin_root;
    /* The oracle's bound over the whole box can be tighter than the global formula (noise). */
    if (med->majorant->dmax_root < med->density_max && med->kind == RD_DENSITY_NOISE) {
        med->density_max = med->majorant->dmax_root * (1.0 + 1e-6);
        med->sigma_maj = med->density_max * med->sigma_t_scale;
    }
    return RD_OK;
}

/* ---- lights -------------------------------------------------------------------------------- */
static rd_status parse_light(vctx *c, const cJSON *j, int idx, rd_light *l)
{
    char path[64];
    snprintf(path, sizeof path, "lights[%d]", idx);
    TRY(need_object(c, j, path));
    static const char *const kinds[] = {"point", "spot", "directional", "sphere", "environment", NULL};
    int kind;
    TRY(get_enum(c, j, path, "type", 1, kinds, 0, &kind));
    const double big = 1e12;
    switch (kind) {
    case 0: {
        static const char *const keys[] = {"type", "position", "intensity", NULL};
        TRY(check_keys(c, j, path, keys));
        l->kind = RD_LIGHT_POINT;
        TRY(get_vec3(c, j, path, "position", 1, v3(0, 0, 0), 0, -1e9, 1e9, &l->pos));
        TRY(get_vec3(c, j, path, "intensity", 1, v3(0, 0, 0), 1, 0, big, &l->value));
        break;
    }
    case 1: {
        static const char *const keys[] = {"type", "position", "direction", "look_at", "angle",
                                           "falloff", "intensity", NULL};
        TRY(check_keys(c, j, path, keys));
        l->kind = RD_LIGHT_SPOT;
        TRY(get_vec3(c, j, path, "position", 1, v3(0, 0, 0), 0, -1e9, 1e9, &l->pos));
        int has_dir = cJSON_GetObjectItemCaseSensitive(j, "direction") != NULL;
        int has_at = cJSON_GetObjectItemCaseSensitive(j, "look_at") != NULL;
        if (has_dir == has_at) return fail(c, path, "give exactly one of direction, look_at");
        vec3 d;
        if (has_dir) TRY(get_vec3(c, j, path, "direction", 1, v3(0, 0, 0), 0, -1e9, 1e9, &d));
        else {
            vec3 at;
            TRY(get_vec3(c, j, path, "look_at", 1, v3(0, 0, 0), 0, -1e9, 1e9, &at));
            d = v3_sub(at, l->pos);
        }
        if (v3_len(d) < 1e-12) return fail(c, path, "direction: must not be the zero vector");
        l->dir = v3_norm(d);
        double angle, falloff;
        TRY(get_num(c, j, path, "angle", 1, 30, 0, 1, 180, 0, &angle));
        TRY(get_num(c, j, path, "falloff", 0, 0.1 * angle, 0, 0, 180, 0, &falloff));
        if (falloff > 0.5 * angle) {
            char p[128];
            join(p, sizeof p, path, "falloff");
            return fail(c, p, "must be in [0, angle/2] = [0, %g], found %g", 0.5 * angle, falloff);
        }
        /* angle is the full cone angle (degrees); the intensity falls smoothly to zero over the
         * outer `falloff` degrees of the half-angle. */
        double half = 0.5 * angle * M_PI / 180.0;
        l->cos_outer = cos(half);
        l->cos_inner = cos(half - falloff * M_PI / 180.0);
        TRY(get_vec3(c, j, path, "intensity", 1, v3(0, 0, 0), 1, 0, big, &l->value));
        break;
    }
    case 2: {
        static const char *const keys[] = {"type", "direction", "irradiance", "radius", "center", NULL};
        TRY(check_keys(c, j, path, keys));
        l->kind = RD_LIGHT_DIRECTIONAL;
        vec3 d;
        TRY(get_vec3(c, j, path, "direction", 1, v3(0, 0, 0), 0, -1e9, 1e9, &d));
        if (v3_len(d) < 1e-12) return fail(c, path, "direction: must not be the zero vector");
        l->dir = v3_norm(d);
        TRY(get_vec3(c, j, path, "irradiance", 1, v3(0, 0, 0), 1, 0, big, &l->value));
        TRY(get_num(c, j, path, "radius", 0, 0.0, 0, 0, 1e9, 0, &l->radius));
        TRY(get_vec3(c, j, path, "center", l->radius > 0, v3(0, 0, 0), 0, -1e9, 1e9, &l->beam_center));
        break;
    }
    case 3: {
        static const char *const keys[] = {"type", "center", "radius", "radiance", NULL};
        TRY(check_keys(c, j, path, keys));
        l->kind = RD_LIGHT_SPHERE;
        TRY(get_vec3(c, j, path, "center", 1, v3(0, 0, 0), 0, -1e9, 1e9, &l->pos));
        TRY(get_num(c, j, path, "radius", 1, 0, 0, 1, 1e9, 0, &l->radius));
        TRY(get_vec3(c, j, path, "radiance", 1, v3(0, 0, 0), 1, 0, big, &l->value));
        break;
    }
    default: {
        static const char *const keys[] = {"type", "radiance", NULL};
        TRY(check_keys(c, j, path, keys));
        l->kind = RD_LIGHT_ENVIRONMENT;
        TRY(get_vec3(c, j, path, "radiance", 1, v3(0, 0, 0), 1, 0, big, &l->value));
        break;
    }
    }
    return RD_OK;
}

/* ---- settings ------------------------------------------------------------------------------ */
static rd_status parse_settings(vctx *c, const cJSON *j, rd_settings *s)
{
    s->spp = 16;
    s->time_limit = 0;
    s->seed = 1;
    s->max_depth = 64;
    s->rr_depth = 3;
    snprintf(s->method, sizeof s->method, "delta");
    s->tracker = RD_FP_AUTO;
    s->transmittance = RD_TR_AUTO;
    s->track_b = 1.0;
    s->track_m = 1.0;
    s->track_step = 0.0;
    if (!j) return RD_OK;
    const char *path = "settings";
    TRY(need_object(c, j, path));
    static const char *const keys[] = {"spp", "time", "seed", "max_depth", "rr_depth", "method",
                                       "tracker", "transmittance", "b", "m", "step", NULL};
    TRY(check_keys(c, j, path, keys));
    long long v;
    TRY(get_int(c, j, path, "spp", 0, 16, 1, 1 << 24, &v));
    s->spp = (int)v;
    s->spp_given = cJSON_GetObjectItemCaseSensitive(j, "spp") != NULL;
    TRY(get_num(c, j, path, "time", 0, 0, 0, 0, 1e7, 0, &s->time_limit));
    TRY(get_int(c, j, path, "seed", 0, 1, 0, (1LL << 53), &v));
    s->seed = (uint64_t)v;
    TRY(get_int(c, j, path, "max_depth", 0, 64, 1, 100000, &v));
    s->max_depth = (int)v;
    TRY(get_int(c, j, path, "rr_depth", 0, 3, 0, 100000, &v));
    s->rr_depth = (int)v;
    const char *m;
    TRY(get_str(c, j, path, "method", 0, "delta", &m));
    if (!rd_method_find(m)) {
        char names[256];
        rd_methods(names, sizeof names);
        return fail(c, "settings.method", "unknown method \"%s\" (available: %s)", m, names);
    }
    snprintf(s->method, sizeof s->method, "%s", m);
    /* Free-path engine (rd_freepath.h): tracker, transmittance estimator and their parameters. */
    static const char *const trackers[] = {"auto", "woodcock", "supervoxel", "weighted", "decomposition", "raymarch", NULL};
    static const char *const trans[] = {"auto", "ratio-global", "ratio", "residual", "exact", "raymarch", NULL};
    TRY(get_enum(c, j, path, "tracker", 0, trackers, 0, &s->tracker));
    TRY(get_enum(c, j, path, "transmittance", 0, trans, 0, &s->transmittance));
    TRY(get_num(c, j, path, "b", 0, 1.0, 0, 1, 100, 0, &s->track_b));
    TRY(get_num(c, j, path, "m", 0, 1.0, 0, 0, 10, 0, &s->track_m));
    TRY(get_num(c, j, path, "step", 0, 0.0, 0, 1, 1e9, 0, &s->track_step));
    if (cJSON_GetObjectItemCaseSensitive(j, "b") && s->tracker != RD_FP_WEIGHTED &&
        s->tracker != RD_FP_DECOMPOSITION)
        return fail(c, "settings.b", "only with \"tracker\": \"weighted\" or \"decomposition\"");
    if (cJSON_GetObjectItemCaseSensitive(j, "m") && s->tracker != RD_FP_DECOMPOSITION)
        return fail(c, "settings.m", "only with \"tracker\": \"decomposition\"");
    if (cJSON_GetObjectItemCaseSensitive(j, "step") && s->tracker != RD_FP_RAYMARCH &&
        s->transmittance != RD_TR_RAYMARCH)
        return fail(c, "settings.step", "only with \"tracker\" or \"transmittance\": \"raymarch\"");
    return RD_OK;
}

/* ---- photons and guide (the photon map and its SH guide grid) ------------------------------- */
static rd_status parse_photons(vctx *c, const cJSON *j, rd_photon_settings *p)
{
    p->count = 200000;
    p->store_direct = 1;
    p->segments = 0;
    p->max_depth = 64;
    p->seed = 1;
    if (!j) return RD_OK;
    const char *path = "photons";
    TRY(need_object(c, j, path));
    static const char *const keys[] = {"count", "store_direct", "segments", "max_depth", "seed", NULL};
    TRY(check_keys(c, j, path, keys));
    long long v;
    TRY(get_int(c, j, path, "count", 0, 200000, 1, 1000000000LL, &v));
    p->count = (size_t)v;
    TRY(get_bool(c, j, path, "store_direct", 1, &p->store_direct));
    TRY(get_bool(c, j, path, "segments", 0, &p->segments));
    TRY(get_int(c, j, path, "max_depth", 0, 64, 1, 100000, &v));
    p->max_depth = (int)v;
    TRY(get_int(c, j, path, "seed", 0, 1, 0, (1LL << 53), &v));
    p->seed = (uint64_t)v;
    return RD_OK;
}

static rd_status parse_guide(vctx *c, const cJSON *j, rd_guide_settings *g)
{
    memset(g, 0, sizeof *g);
    g->bands = 8; /* calibrated on beam-vdb and cloud (docs/guided-marching.md) */
    g->k = 64;
    g->lambda = 1.0;
    g->max_depth = 8;
    g->window = 1;
    g->distances = 1;        /* guided-unbiased (docs/guided-unbiased.md) */
    g->distance_alpha = 0.2;
    g->pass_floor = 0.1;
    g->majorant_weight = 0.2;
    g->secondary = 1;
    g->distance_tau_max = 0.5; /* these three calibrated on hetero-forward and smoke-vdb */
    g->directions = 1;
    g->direction_weight = 0.25;
    g->roulette = 1;
    g->split_max = 2;
    if (!j) return RD_OK;
    const char *path = "guide";
    TRY(need_object(c, j, path));
    static const char *const keys[] = {"grid", "bake", "bands", "k", "lambda", "resolution", "min_cell", "max_depth", "window",
                                       "distances", "distance_alpha", "pass_floor", "majorant_weight", "secondary",
                                       "directions", "direction_weight", "roulette", "split_max", "distance_tau_max", NULL};
    TRY(check_keys(c, j, path, keys));
    static const char *const grids[] = {"uniform", "adaptive", NULL};
    static const char *const bakes[] = {"knn", "track", NULL};
    TRY(get_enum(c, j, path, "grid", 0, grids, 0, &g->adaptive));
    TRY(get_enum(c, j, path, "bake", 0, bakes, 0, &g->track));
    static const char *const windows[] = {"none", "hann", NULL};
    TRY(get_enum(c, j, path, "window", 0, windows, 1, &g->window));
    long long v;
    TRY(get_int(c, j, path, "bands", 0, 8, 1, 8, &v));
    g->bands = (int)v;
    TRY(get_int(c, j, path, "k", 0, 64, 1, 4096, &v));
    g->k = (int)v;
    TRY(get_num(c, j, path, "lambda", 0, 1.0, 0, 1, 1000, 0, &g->lambda));
    TRY(get_num(c, j, path, "min_cell", 0, 0.0, 0, 0, 1e9, 0, &g->min_cell));
    TRY(get_int(c, j, path, "max_depth", 0, 8, 1, 20, &v));
    g->max_depth = (int)v;
    /* guided-unbiased: p > 0 wherever the integrand can be needs alpha > 0; both outcomes of
     * the scatter-or-pass decision need a floor > 0 (and <= 0.5 so the two floors fit); the
     * majorant strategy's weight is in [0, 1) so the guide keeps a share. */
    TRY(get_bool(c, j, path, "distances", 1, &g->distances));
    TRY(get_num(c, j, path, "distance_alpha", 0, 0.2, 0, 1, 1, 0, &g->distance_alpha));
    TRY(get_num(c, j, path, "pass_floor", 0, 0.1, 0, 1, 0.5, 0, &g->pass_floor));
    TRY(get_num(c, j, path, "majorant_weight", 0, 0.2, 0, 0, 1, 1, &g->majorant_weight));
    TRY(get_bool(c, j, path, "secondary", 1, &g->secondary));
    /* The phase function keeps a share 1 - direction_weight > 0 of the continuations, so a
     * direction the guide's lobe misses is still drawn (p > 0 wherever the phase is). */
    TRY(get_num(c, j, path, "distance_tau_max", 0, 0.5, 0, 1, 1e300, 0, &g->distance_tau_max));
    TRY(get_bool(c, j, path, "directions", 1, &g->directions));
    TRY(get_num(c, j, path, "direction_weight", 0, 0.25, 0, 0, 1, 1, &g->direction_weight));
    TRY(get_bool(c, j, path, "roulette", 1, &g->roulette));
    TRY(get_int(c, j, path, "split_max", 0, 2, 1, 64, &v));
    g->split_max = (int)v;
    const cJSON *res = cJSON_GetObjectItemCaseSensitive(j, "resolution");
    if (res) {
        if (!cJSON_IsArray(res) || cJSON_GetArraySize(res) != 3)
            return fail(c, "guide.resolution", "expected 3 integers in [1, 1024]");
        for (int i = 0; i < 3; i++) {
            const cJSON *e = cJSON_GetArrayItem(res, i);
            if (!cJSON_IsNumber(e) || e->valuedouble != floor(e->valuedouble) || e->valuedouble < 1 ||
                e->valuedouble > 1024)
                return fail(c, "guide.resolution", "expected 3 integers in [1, 1024]");
            g->res[i] = e->valueint;
        }
        if (g->adaptive) return fail(c, "guide.resolution", "only for \"grid\": \"uniform\" (the adaptive grid refines by photon density)");
    }
    return RD_OK;
}

/* Ray marching of the guided methods (docs/scene-format.md "march"). */
static rd_status parse_march(vctx *c, const cJSON *j, rd_march_settings *m)
{
    m->samples = 0; /* per placement, calibrated on cloud and smoke-vdb (integrator_march.c) */
    m->min_samples = 1;
    m->max_samples = 64;
    m->alpha = 0.2;
    m->ls = RD_LS_NEE_PHOTONS;
    m->detail = 0; /* "cells": lookups mislead where the photon estimate dominates (cloud) */
    if (!j) return RD_OK;
    const char *path = "march";
    TRY(need_object(c, j, path));
    static const char *const keys[] = {"samples", "min_samples", "max_samples", "alpha", "ls", "detail", NULL};
    TRY(check_keys(c, j, path, keys));
    long long v;
    TRY(get_int(c, j, path, "samples", 0, 0, 1, 4096, &v));
    m->samples = (int)v;
    TRY(get_int(c, j, path, "min_samples", 0, 1, 1, 4096, &v));
    m->min_samples = (int)v;
    TRY(get_int(c, j, path, "max_samples", 0, 64, 1, 4096, &v));
    m->max_samples = (int)v;
    if (m->max_samples < m->min_samples)
        return fail(c, "march.max_samples", "must be >= march.min_samples (%d), found %d", m->min_samples, m->max_samples);
    TRY(get_num(c, j, path, "alpha", 0, 0.2, 0, 1, 1, 0, &m->alpha));
    static const char *const ls[] = {"nee+photons", "photons", "nee", "nee+guide", NULL};
    int k = 0;
    TRY(get_enum(c, j, path, "ls", 0, ls, 0, &k));
    m->ls = (rd_ls_kind)k;
    static const char *const detail[] = {"cells", "lookups", NULL};
    TRY(get_enum(c, j, path, "detail", 0, detail, 0, &m->detail));
    return RD_OK;
}

/* ---- shapes and the scene-wide medium (issue 14; rd_geom.h) ------------------------------- */

/* The index of the medium named by key `key` of obj (a string or null), or -1 for null or a
 * missing key. The name must match exactly one medium's name. */
static rd_status medium_ref(vctx *c, const cJSON *obj, const char *path, const char *key, const rd_scene *s, int *out)
{
    char p[300];
    join(p, sizeof p, path, key);
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(obj, key);
    *out = -1;
    if (!j || cJSON_IsNull(j)) return RD_OK;
    if (!cJSON_IsString(j) || !j->valuestring[0])
        return fail(c, p, "expected a medium's name or null, found %s", type_name(j));
    int found = -1, count = 0;
    for (int i = 0; i < s->n_media; i++)
        if (strcmp(s->media[i].name, j->valuestring) == 0) found = i, count++;
    if (count == 0) {
        char list[256] = "";
        for (int i = 0; i < s->n_media; i++) {
            strncat(list, s->media[i].name, sizeof list - strlen(list) - 1);
            if (i + 1 < s->n_media) strncat(list, ", ", sizeof list - strlen(list) - 1);
        }
        return fail(c, p, "no medium named \"%s\" (media: %s)", j->valuestring, s->n_media ? list : "none");
    }
    if (count > 1) return fail(c, p, "%d media are named \"%s\": give them distinct names", count, j->valuestring);
    *out = found;
    return RD_OK;
}

/* shapes[i].transform: {"scale": s or [sx, sy, sz] (> 0), "rotate": {"axis": [x, y, z],
 * "angle": degrees}, "translate": [x, y, z]}, applied in that order (rd_geom.h). */
static rd_status parse_transform(vctx *c, const cJSON *sh, const char *spath, rd_transform *xf)
{
    *xf = rd_transform_identity();
    char path[300];
    join(path, sizeof path, spath, "transform");
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(sh, "transform");
    if (!j) return RD_OK;
    TRY(need_object(c, j, path));
    static const char *const keys[] = {"scale", "rotate", "translate", NULL};
    TRY(check_keys(c, j, path, keys));
    TRY(get_vec3(c, j, path, "scale", 0, v3(1, 1, 1), 1, -1e9, 1e9, &xf->scale));
    if (!(xf->scale.x > 0 && xf->scale.y > 0 && xf->scale.z > 0)) {
        char p[300];
        join(p, sizeof p, path, "scale");
        return fail(c, p, "must be > 0 on every axis (a mirroring or flattening scale would turn the mesh inside out)");
    }
    TRY(get_vec3(c, j, path, "translate", 0, v3(0, 0, 0), 0, -1e9, 1e9, &xf->translate));
    const cJSON *rot = cJSON_GetObjectItemCaseSensitive(j, "rotate");
    if (rot) {
        char p[300];
        join(p, sizeof p, path, "rotate");
        TRY(need_object(c, rot, p));
        static const char *const rkeys[] = {"axis", "angle", NULL};
        TRY(check_keys(c, rot, p, rkeys));
        vec3 axis;
        TRY(get_vec3(c, rot, p, "axis", 1, v3(0, 0, 1), 0, -1e9, 1e9, &axis));
        if (!(v3_len(axis) > 1e-12)) {
            char q[300];
            join(q, sizeof q, p, "axis");
            return fail(c, q, "must not be the zero vector");
        }
        xf->axis = v3_norm(axis);
        TRY(get_num(c, rot, p, "angle", 1, 0, -360, 0, 360, 0, &xf->angle_deg));
    }
    return RD_OK;
}

static rd_status parse_material(vctx *c, const cJSON *sh, const char *spath, rd_material *m)
{
    char path[300];
    join(path, sizeof path, spath, "material");
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(sh, "material");
    if (!j) return fail(c, path, "missing (required: {\"type\": \"dielectric\" | \"interface\" | \"diffuse\", ...})");
    TRY(need_object(c, j, path));
    static const char *const kinds[] = {"interface", "dielectric", "diffuse", NULL};
    int kind;
    TRY(get_enum(c, j, path, "type", 1, kinds, 0, &kind));
    memset(m, 0, sizeof *m);
    m->ior = 1.0;
    m->albedo = v3(0, 0, 0);
    if (kind == 0) {
        static const char *const keys[] = {"type", NULL};
        TRY(check_keys(c, j, path, keys));
        m->kind = RD_MAT_INTERFACE;
    } else if (kind == 1) {
        static const char *const keys[] = {"type", "ior", NULL};
        TRY(check_keys(c, j, path, keys));
        m->kind = RD_MAT_DIELECTRIC;
        TRY(get_num(c, j, path, "ior", 0, 1.5, 1, 0, 4, 0, &m->ior));
    } else {
        static const char *const keys[] = {"type", "albedo", NULL};
        TRY(check_keys(c, j, path, keys));
        m->kind = RD_MAT_DIFFUSE;
        TRY(get_vec3(c, j, path, "albedo", 0, v3(0.5, 0.5, 0.5), 1, 0, 1, &m->albedo));
    }
    return RD_OK;
}

static rd_status parse_shape(vctx *c, const cJSON *j, int idx, rd_scene *s, rd_shape *sh)
{
    char path[64];
    snprintf(path, sizeof path, "shapes[%d]", idx);
    TRY(need_object(c, j, path));
    static const char *const keys[] = {"name", "file", "made_by", "transform", "material", "inside", "outside", NULL};
    TRY(check_keys(c, j, path, keys));
    const char *name, *file, *made_by;
    char defname[32];
    snprintf(defname, sizeof defname, "shape%d", idx);
    TRY(get_str(c, j, path, "name", 0, defname, &name));
    snprintf(sh->name, sizeof sh->name, "%s", name);
    TRY(get_str(c, j, path, "file", 1, NULL, &file));
    TRY(get_str(c, j, path, "made_by", 0, NULL, &made_by));
    rd_transform xf;
    TRY(parse_transform(c, j, path, &xf));
    TRY(parse_material(c, j, path, &sh->material));
    TRY(medium_ref(c, j, path, "inside", s, &sh->inside));
    TRY(medium_ref(c, j, path, "outside", s, &sh->outside));
    char p[300];
    if (sh->material.kind == RD_MAT_INTERFACE && sh->inside == sh->outside) {
        join(p, sizeof p, path, "material.type");
        return fail(c, p, "an interface between a medium and itself does nothing: give \"inside\" and \"outside\" different media");
    }
    resolve_path(c, file, sh->file, sizeof sh->file);
    join(p, sizeof p, path, "file");
    char msg[RD_ERRLEN];
    rd_status st = rd_mesh_load(sh->file, &xf, &sh->mesh, msg, sizeof msg);
    if (st) {
        char hint[300];
        fail(c, p, "%s%s", msg, missing_hint(sh->file, made_by, hint, sizeof hint));
        return st; /* RD_ERR_IO, RD_ERR_FORMAT or RD_ERR_NOMEM, as for volume files */
    }
    /* A boundary between two different media needs an inside: a closed, consistently
     * oriented mesh (rd_mesh.closed), or the path's medium would be wrong past a hole. */
    if (sh->inside != sh->outside && !sh->mesh.closed)
        return fail(c, p, "%s: not a closed mesh (%zu edges are not shared by exactly two consistently wound triangles): "
                          "a shape with different inside and outside media must be closed", sh->file, sh->mesh.open_edges);
    return RD_OK;
}

/* "shapes" and the scene-wide "medium"; after the media (they name them). */
static rd_status parse_surfaces(vctx *c, const cJSON *root, rd_scene *s)
{
    s->fill_medium = -1;
    TRY(medium_ref(c, root, "", "medium", s, &s->fill_medium));
    const cJSON *shapes = cJSON_GetObjectItemCaseSensitive(root, "shapes");
    if (!shapes) return RD_OK;
    if (!cJSON_IsArray(shapes)) return fail(c, "shapes", "expected an array, found %s", type_name(shapes));
    int n = cJSON_GetArraySize(shapes);
    if (n > MAX_SHAPES) return fail(c, "shapes", "at most %d shapes", MAX_SHAPES);
    s->shapes = calloc(n > 0 ? n : 1, sizeof *s->shapes);
    if (!s->shapes) return RD_ERR_NOMEM;
    for (int i = 0; i < n; i++) {
        rd_status st = parse_shape(c, cJSON_GetArrayItem(shapes, i), i, s, &s->shapes[i]);
        s->n_shapes = i + 1; /* so rd_scene_free releases a partly loaded shape */
        if (st) return st;
    }
    return RD_OK;
}

int rd_scene_medium_bound(const rd_scene *s, int i)
{
    if (i == s->fill_medium) return 1;
    for (int k = 0; k < s->n_shapes; k++)
        if (s->shapes[k].inside == i || s->shapes[k].outside == i) return 1;
    return 0;
}

/* A box medium (not bound to surfaces) fills its bounds in the open region (the region of the
 * scene-wide medium: rd_internal.h "Surfaces in the transport"), so no shape that encloses
 * another region may reach into it: its bounds must not overlap the bounding box of a shape
 * whose inside is not the scene-wide medium. (A room whose walls enclose the scene-wide medium
 * may hold box media.) */
static rd_status check_boxes_clear_of_shapes(vctx *c, const rd_scene *s)
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
                return fail(c, p, "overlaps the bounding box of shapes[%d] (\"%s\"): a box medium must lie clear of every shape "
                                  "that encloses a region other than the scene-wide medium's; make it a shape's inside (an \"interface\" shape around it) instead", k, s->shapes[k].name);
            }
        }
    }
    return RD_OK;
}

/* ---- --set overrides ----------------------------------------------------------------------- */
/* Walk a dotted path with [i] indices, creating missing object members, and replace the leaf. */
static rd_status apply_override(vctx *c, cJSON *root, const rd_override *ov)
{
    char key[256];
    snprintf(key, sizeof key, "%s", ov->key);
    /* The whole value must be JSON (\"64x\" is the string "64x", which validation rejects). */
    cJSON *value = cJSON_ParseWithOpts(ov->value, NULL, 1);
    if (!value) value = cJSON_CreateString(ov->value);
    if (!value) return RD_ERR_NOMEM;
    cJSON *cur = root;
    char *p = key;
    while (*p) {
        char name[128];
        size_t n = strcspn(p, ".[");
        if (n == 0 && *p != '[') goto bad;
        if (n >= sizeof name) goto bad;
        memcpy(name, p, n);
        name[n] = 0;
        p += n;
        cJSON *parent = cur;
        int have_name = n > 0;
        if (have_name) {
            if (!cJSON_IsObject(parent)) goto bad;
            cJSON *child = cJSON_GetObjectItemCaseSensitive(parent, name);
            if (*p == 0) {
                if (child) cJSON_ReplaceItemInObjectCaseSensitive(parent, name, value);
                else cJSON_AddItemToObject(parent, name, value);
                return RD_OK;
            }
            if (!child) {
                if (*p == '[') goto bad;
                child = cJSON_AddObjectToObject(parent, name);
                if (!child) goto bad;
            }
            cur = child;
        }
        while (*p == '[') {
            char *end;
            long i = strtol(p + 1, &end, 10);
            if (*end != ']' || !cJSON_IsArray(cur) || i < 0 || i >= cJSON_GetArraySize(cur)) goto bad;
            p = end + 1;
            if (*p == 0) {
                cJSON_ReplaceItemInArray(cur, (int)i, value);
                return RD_OK;
            }
            cur = cJSON_GetArrayItem(cur, (int)i);
        }
        if (*p == '.') p++;
        else if (*p) goto bad;
    }
bad:
    cJSON_Delete(value);
    if (c->err) snprintf(c->err, c->errlen, "--set %s=%s: no such place in %s (use dotted keys and [i] for existing array items)",
                         ov->key, ov->value, c->file);
    return RD_ERR_ARG;
}

/* ---- load ---------------------------------------------------------------------------------- */
static char *read_file(const char *path, char *err, size_t errlen, rd_status *st)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errlen, "%s: %s", path, strerror(errno));
        *st = RD_ERR_IO;
        return NULL;
    }
    char *buf = malloc(MAX_SCENE_BYTES + 1);
    if (!buf) {
        fclose(f);
        *st = RD_ERR_NOMEM;
        snprintf(err, errlen, "%s: out of memory", path);
        return NULL;
    }
    size_t n = fread(buf, 1, MAX_SCENE_BYTES + 1, f);
    int bad = ferror(f);
    fclose(f);
    if (bad) {
        free(buf);
        snprintf(err, errlen, "%s: read error (is it a directory?)", path);
        *st = RD_ERR_IO;
        return NULL;
    }
    if (n > MAX_SCENE_BYTES) {
        free(buf);
        snprintf(err, errlen, "%s: larger than %u MiB; not a scene file", path, MAX_SCENE_BYTES >> 20);
        *st = RD_ERR_PARSE;
        return NULL;
    }
    buf[n] = 0;
    if (strlen(buf) != n) {
        free(buf);
        snprintf(err, errlen, "%s: contains a NUL byte; not a JSON text file", path);
        *st = RD_ERR_PARSE;
        return NULL;
    }
    return buf;
}

static void medium_release(rd_medium *m)
{
    rd_grid_free(&m->grid);
    rd_majorant_free(m->majorant);
}

void rd_scene_free(rd_scene *s)
{
    if (!s) return;
    for (int i = 0; i < s->n_media; i++) medium_release(&s->media[i]);
    free(s->media);
    free(s->lights);
    rd_light_sampler_free(&s->light_sampler);
    free(s->sphere_lights);
    free(s->description);
    rd_geom_free(s->geom);
    for (int i = 0; i < s->n_shapes; i++) rd_mesh_free(&s->shapes[i].mesh);
    free(s->shapes);
    free(s);
}

static rd_status validate(vctx *c, const cJSON *root, rd_scene *s)
{
    if (!cJSON_IsObject(root)) return fail(c, "(top level)", "expected an object, found %s", type_name(root));
    static const char *const keys[] = {"description", "camera", "media", "lights", "background", "settings", "photons", "guide", "march",
                                       "shapes", "medium", NULL};
    TRY(check_keys(c, root, "", keys));
    const char *desc;
    TRY(get_str(c, root, "", "description", 0, NULL, &desc));
    if (desc && !(s->description = strdup(desc))) return RD_ERR_NOMEM;
    const cJSON *cam = cJSON_GetObjectItemCaseSensitive(root, "camera");
    if (!cam) return fail(c, "camera", "missing (required)");
    TRY(parse_camera(c, cam, &s->camera));

    const cJSON *media = cJSON_GetObjectItemCaseSensitive(root, "media");
    if (!media) return fail(c, "media", "missing (required: an array of media)");
    if (!cJSON_IsArray(media)) return fail(c, "media", "expected an array, found %s", type_name(media));
    int nm = cJSON_GetArraySize(media);
    if (nm > MAX_MEDIA) return fail(c, "media", "at most %d media", MAX_MEDIA);
    s->media = calloc(nm > 0 ? nm : 1, sizeof *s->media);
    if (!s->media) return RD_ERR_NOMEM;
    for (int i = 0; i < nm; i++) {
        rd_status st = parse_medium(c, cJSON_GetArrayItem(media, i), i, &s->media[i]);
        s->n_media = i + 1; /* so rd_scene_free releases a partly loaded medium */
        if (st) return st;
    }
    TRY(parse_surfaces(c, root, s));
    for (int i = 0; i < nm; i++) s->media[i].bound = rd_scene_medium_bound(s, i);
    /* Media must not overlap: the trackers visit them one interval at a time. (Media bound to
     * shapes are exempt: the surfaces say where they are; box media stay clear of shapes.) */
    TRY(check_boxes_clear_of_shapes(c, s));
    for (int i = 0; i < nm; i++)
        for (int k = i + 1; k < nm; k++) {
            if (rd_scene_medium_bound(s, i) || rd_scene_medium_bound(s, k)) continue;
            const rd_medium *a = &s->media[i], *b = &s->media[k];
            if (a->bmin.x < b->bmax.x && b->bmin.x < a->bmax.x && a->bmin.y < b->bmax.y &&
                b->bmin.y < a->bmax.y && a->bmin.z < b->bmax.z && b->bmin.z < a->bmax.z) {
                char p[64];
                snprintf(p, sizeof p, "media[%d].bounds", k);
                return fail(c, p, "overlaps media[%d] (media must not overlap)", i);
            }
        }
    s->bmin = v3(INFINITY, INFINITY, INFINITY);
    s->bmax = v3(-INFINITY, -INFINITY, -INFINITY);
    for (int i = 0; i < nm; i++) {
        s->bmin = v3(fmin(s->bmin.x, s->media[i].bmin.x), fmin(s->bmin.y, s->media[i].bmin.y), fmin(s->bmin.z, s->media[i].bmin.z));
        s->bmax = v3(fmax(s->bmax.x, s->media[i].bmax.x), fmax(s->bmax.y, s->media[i].bmax.y), fmax(s->bmax.z, s->media[i].bmax.z));
    }
    if (nm == 0) s->bmin = s->bmax = v3(0, 0, 0);
    /* Shapes bound the scene too (a surface refracts light into the media): the photon emission
     * disc and a directional light's power cover them. */
    for (int k = 0; k < s->n_shapes; k++) {
        const rd_mesh *m = &s->shapes[k].mesh;
        if (nm == 0 && k == 0) s->bmin = m->bmin, s->bmax = m->bmax;
        s->bmin = v3(fmin(s->bmin.x, m->bmin.x), fmin(s->bmin.y, m->bmin.y), fmin(s->bmin.z, m->bmin.z));
        s->bmax = v3(fmax(s->bmax.x, m->bmax.x), fmax(s->bmax.y, m->bmax.y), fmax(s->bmax.z, m->bmax.z));
    }

    const cJSON *lights = cJSON_GetObjectItemCaseSensitive(root, "lights");
    if (lights) {
        if (!cJSON_IsArray(lights)) return fail(c, "lights", "expected an array, found %s", type_name(lights));
        int nl = cJSON_GetArraySize(lights);
        if (nl > MAX_LIGHTS) return fail(c, "lights", "at most %d lights", MAX_LIGHTS);
        s->lights = calloc(nl > 0 ? nl : 1, sizeof *s->lights);
        if (!s->lights) return RD_ERR_NOMEM;
        for (int i = 0; i < nl; i++) TRY(parse_light(c, cJSON_GetArrayItem(lights, i), i, &s->lights[i]));
        s->n_lights = nl;
    }
    TRY(get_vec3(c, root, "", "background", 0, v3(0, 0, 0), 1, 0, 1e12, &s->background));
    TRY(parse_settings(c, cJSON_GetObjectItemCaseSensitive(root, "settings"), &s->settings));
    /* A ray-marching step far below the scene's size would take forever. */
    if (s->settings.track_step > 0 && s->settings.track_step < 1e-6 * 2.0 * rd_scene_radius(s))
        return fail(c, "settings.step", "%g is below 1e-6 of the scene's size (%g): the march would never finish",
                    s->settings.track_step, 2.0 * rd_scene_radius(s));
    TRY(parse_photons(c, cJSON_GetObjectItemCaseSensitive(root, "photons"), &s->photons));
    TRY(parse_guide(c, cJSON_GetObjectItemCaseSensitive(root, "guide"), &s->guide));
    TRY(parse_march(c, cJSON_GetObjectItemCaseSensitive(root, "march"), &s->march));
    if (s->guide.track && !s->photons.segments)
        s->photons.segments = 1; /* the track-length bake needs the segments */
    /* Lights by power for next-event estimation, and the lights a path can hit. */
    TRY(rd_light_sampler_build(&s->light_sampler, s->lights, s->n_lights, rd_scene_radius(s)));
    s->sphere_lights = calloc(s->n_lights > 0 ? s->n_lights : 1, sizeof *s->sphere_lights);
    if (!s->sphere_lights) return RD_ERR_NOMEM;
    for (int i = 0; i < s->n_lights; i++)
        if (s->lights[i].kind == RD_LIGHT_SPHERE) s->sphere_lights[s->n_sphere_lights++] = i;
    return RD_OK;
}

/* FNV-1a 64 over bytes, continuing from h. */
static uint64_t fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 0x100000001b3ULL;
    return h;
}

/* The key of what a bake depends on: the scene's JSON after overrides without the parts that
 * cannot change photons or the guide (camera, march, and the render-only settings), printed
 * canonically by cJSON, and the voxel data of every grid medium (so a volume file replaced on
 * disk changes the key). */
static uint64_t bake_key(const cJSON *root, const rd_scene *s)
{
    /* Bump when a bake's result changes for the same scene text (2: Hann-windowed guide). */
    static const char version[] = "photonmarch bake 2";
    uint64_t h = fnv1a(0xcbf29ce484222325ULL, version, sizeof version);
    cJSON *copy = cJSON_Duplicate(root, 1);
    if (!copy) return 0;
    cJSON_DeleteItemFromObjectCaseSensitive(copy, "description");
    cJSON_DeleteItemFromObjectCaseSensitive(copy, "camera");
    cJSON_DeleteItemFromObjectCaseSensitive(copy, "march");
    /* guided-unbiased's sampling switches change no bake: */
    cJSON *gd = cJSON_GetObjectItemCaseSensitive(copy, "guide");
    static const char *const guide_render_only[] = {"distances", "distance_alpha", "pass_floor", "majorant_weight", "secondary",
                                                         "directions", "direction_weight", "roulette", "split_max", "distance_tau_max", NULL};
    for (int i = 0; cJSON_IsObject(gd) && guide_render_only[i]; i++)
        cJSON_DeleteItemFromObjectCaseSensitive(gd, guide_render_only[i]);
    cJSON *set = cJSON_GetObjectItemCaseSensitive(copy, "settings");
    static const char *const render_only[] = {"spp", "time", "seed", "method", "max_depth", "rr_depth", NULL};
    for (int i = 0; set && render_only[i]; i++) cJSON_DeleteItemFromObjectCaseSensitive(set, render_only[i]);
    char *text = cJSON_PrintUnformatted(copy);
    cJSON_Delete(copy);
    if (!text) return 0;
    h = fnv1a(h, text, strlen(text));
    cJSON_free(text);
    for (int i = 0; i < s->n_media; i++) {
        const rd_grid *g = &s->media[i].grid;
        if (s->media[i].kind == RD_DENSITY_GRID && g->data)
            h = fnv1a(h, g->data, (size_t)g->nx * g->ny * g->nz * sizeof *g->data);
        if (s->media[i].kind == RD_DENSITY_GRID && g->bricks) { /* sparse: table and bricks */
            const rd_bricks *b = g->bricks;
            size_t cells = (size_t)b->nb[0] * b->nb[1] * b->nb[2];
            h = fnv1a(h, b->brick, cells * sizeof *b->brick);
            h = fnv1a(h, b->cmax, cells * sizeof *b->cmax);
            h = fnv1a(h, b->voxels, b->n_bricks * RD_BRICK * RD_BRICK * RD_BRICK * sizeof *b->voxels);
        }
    }
    /* The meshes as loaded and placed (a mesh file replaced on disk changes the bake). */
    for (int k = 0; k < s->n_shapes; k++) {
        const rd_mesh *m = &s->shapes[k].mesh;
        h = fnv1a(h, m->positions, 3 * m->n_vertices * sizeof *m->positions);
        h = fnv1a(h, m->indices, 3 * m->n_triangles * sizeof *m->indices);
        if (m->normals) h = fnv1a(h, m->normals, 3 * m->n_vertices * sizeof *m->normals);
    }
    return h;
}

rd_status rd_scene_load(rd_scene **out, const char *path, const rd_override *ov, int nov, char *err,
                        size_t errlen)
{
    char dummy[8];
    if (!err) { err = dummy; errlen = sizeof dummy; }
    *out = NULL;
    vctx c = {.file = path, .err = err, .errlen = errlen};
    const char *slash = strrchr(path, '/');
    if (slash) snprintf(c.dir, sizeof c.dir, "%.*s", (int)(slash - path), path);
    if (slash == path) snprintf(c.dir, sizeof c.dir, "/");

    rd_status st = RD_OK;
    char *text = read_file(path, err, errlen, &st);
    if (!text) return st;
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithOpts(text, &end, 1);
    if (!root) {
        /* Report line and column of the first byte cJSON could not accept. */
        int line = 1, col = 1;
        const char *stop = end ? end : text;
        for (const char *p = text; p < stop && *p; p++) {
            if (*p == '\n') { line++; col = 1; } else col++;
        }
        snprintf(err, errlen, "%s: line %d, column %d: invalid JSON", path, line, col);
        free(text);
        return RD_ERR_PARSE;
    }
    free(text);
    for (int i = 0; i < nov; i++) {
        st = apply_override(&c, root, &ov[i]);
        if (st) { cJSON_Delete(root); return st; }
    }
    rd_scene *s = calloc(1, sizeof *s);
    if (!s) { cJSON_Delete(root); snprintf(err, errlen, "%s: out of memory", path); return RD_ERR_NOMEM; }
    snprintf(s->path, sizeof s->path, "%s", path);
    s->fill_medium = -1;
    st = validate(&c, root, s);
    if (st == RD_OK) s->bake_key = bake_key(root, s);
    if (st == RD_OK && s->n_shapes > 0) {
        /* One Embree scene for the shapes and the sphere lights (rd_scene_intersect). */
        char gerr[RD_ERRLEN];
        s->geom = rd_geom_build(s, gerr, sizeof gerr);
        if (!s->geom) {
            snprintf(err, errlen, "%s: shapes: %s", path, gerr);
            cJSON_Delete(root);
            rd_scene_free(s);
            return RD_ERR_INTERNAL;
        }
    }
    if (st == RD_OK) s->camera_region = rd_scene_region_at(s, s->camera.pos);
    cJSON_Delete(root);
    if (st) {
        if (st == RD_ERR_NOMEM) snprintf(err, errlen, "%s: out of memory", path);
        rd_scene_free(s);
        return st;
    }
    *out = s;
    return RD_OK;
}

/* ---- accessors and info -------------------------------------------------------------------- */
int rd_scene_width(const rd_scene *s) { return s->camera.width; }
int rd_scene_height(const rd_scene *s) { return s->camera.height; }
int rd_scene_spp(const rd_scene *s) { return s->settings.spp; }
double rd_scene_time_limit(const rd_scene *s) { return s->settings.time_limit; }
uint64_t rd_scene_seed(const rd_scene *s) { return s->settings.seed; }
const char *rd_scene_method(const rd_scene *s) { return s->settings.method; }
int rd_scene_spp_given(const rd_scene *s) { return s->settings.spp_given; }
double rd_scene_exposure(const rd_scene *s) { return s->camera.exposure; }

double rd_scene_radius(const rd_scene *s)
{
    double r = 0.5 * v3_len(v3_sub(s->bmax, s->bmin));
    return r > 1e-3 ? r : 1e-3;
}

void rd_scene_info(const rd_scene *s, FILE *out)
{
    static const char *const dkind[] = {"constant", "voxel grid", "procedural noise"};
    static const char *const lkind[] = {"point", "spot", "directional", "sphere", "environment"};
    const rd_camera *cam = &s->camera;
    fprintf(out, "scene      %s\n", s->path);
    if (s->description) fprintf(out, "about      %s\n", s->description);
    fprintf(out, "camera     %s, %dx%d, position (%g, %g, %g), forward (%.3f, %.3f, %.3f)",
            cam->kind == RD_CAM_PERSPECTIVE ? "perspective" : "orthographic", cam->width, cam->height,
            cam->pos.x, cam->pos.y, cam->pos.z, cam->forward.x, cam->forward.y, cam->forward.z);
    if (cam->kind == RD_CAM_PERSPECTIVE) fprintf(out, ", fov %g deg\n", cam->fov_deg);
    else fprintf(out, ", width %g\n", cam->ortho_width);
    size_t mem = sizeof *s + (size_t)s->n_media * sizeof(rd_medium) + (size_t)s->n_lights * sizeof(rd_light);
    fprintf(out, "media      %d\n", s->n_media);
    for (int i = 0; i < s->n_media; i++) {
        const rd_medium *m = &s->media[i];
        fprintf(out, "  [%d] %-12s %s", i, m->name, dkind[m->kind]);
        double dmin = 0, dmax = 0;
        if (m->kind == RD_DENSITY_CONSTANT) {
            dmin = dmax = m->constant;
        } else if (m->kind == RD_DENSITY_GRID) {
            size_t n = (size_t)m->grid.nx * m->grid.ny * m->grid.nz, bytes = rd_grid_bytes(&m->grid);
            mem += bytes;
            fprintf(out, " %dx%dx%d", m->grid.nx, m->grid.ny, m->grid.nz);
            if (m->grid.bricks)
                fprintf(out, " sparse, %zu bricks of 8^3 (%.1f MiB; dense would be %.1f MiB)", m->grid.bricks->n_bricks,
                        bytes / 1048576.0, n * 4.0 / 1048576.0);
            else
                fprintf(out, " (%.1f MiB)", bytes / 1048576.0);
            dmin = m->grid.vmin;
            dmax = m->grid.vmax;
        } else {
            const rd_noise *n = &m->noise;
            fprintf(out, " %d octaves, frequency %g, gain %g, seed %u", n->octaves, n->frequency, n->gain, n->seed);
            /* Sampled range on a 48^3 lattice (the majorant below is the provable bound). */
            dmin = INFINITY;
            dmax = 0;
            for (int k = 0; k < 48; k++)
                for (int j = 0; j < 48; j++)
                    for (int q = 0; q < 48; q++) {
                        vec3 x = v3(m->bmin.x + (q + 0.5) / 48 * (m->bmax.x - m->bmin.x),
                                    m->bmin.y + (j + 0.5) / 48 * (m->bmax.y - m->bmin.y),
                                    m->bmin.z + (k + 0.5) / 48 * (m->bmax.z - m->bmin.z));
                        double d = rd_medium_density(m, x);
                        dmin = fmin(dmin, d);
                        dmax = fmax(dmax, d);
                    }
            fprintf(out, " (range sampled on 48^3)");
        }
        fprintf(out, "\n       bounds (%g, %g, %g) - (%g, %g, %g)\n", m->bmin.x, m->bmin.y, m->bmin.z,
                m->bmax.x, m->bmax.y, m->bmax.z);
        fprintf(out, "       density [%g, %g], sigma_t scale %g, albedo (%g, %g, %g), g %g\n", dmin, dmax,
                m->sigma_t_scale, m->albedo.x, m->albedo.y, m->albedo.z, m->g);
        const rd_majorant *mj = m->majorant;
        if (!mj || mj->kind == RD_MAJ_NONE) {
            fprintf(out, "       majorant: global, sigma_maj %g 1/m", m->sigma_maj);
            if (mj && mj->n_levels > 1) {
                double best = INFINITY;
                for (int l = 1; l < mj->n_levels; l++) best = fmin(best, mj->N_level[l]);
                fprintf(out, " (no partition: seed 000 eq. 17 N = %.3f <= best grid eq. 16 N = %.3f)",
                        mj->N_nopart, best);
            }
            fprintf(out, "\n");
        } else if (mj->kind == RD_MAJ_GRID) {
            fprintf(out, "       majorant: super-voxel grid %dx%dx%d, %s bound, global sigma_maj %g 1/m\n",
                    mj->n[0], mj->n[1], mj->n[2], mj->bound == RD_BOUND_TRILINEAR ? "tri-linear" : "constant",
                    m->sigma_maj);
            fprintf(out, "       cost model (seed 000 eq. 14): %.3f iterations/ray vs %.3f unpartitioned (x%.2f)",
                    mj->N_chosen, mj->N_nopart, mj->N_nopart / fmax(mj->N_chosen, 1e-300));
            if (mj->n_levels > 1) {
                fprintf(out, "; per 2^l grid:");
                for (int l = 1; l < mj->n_levels; l++) fprintf(out, " %d:%.3g", 1 << l, mj->N_level[l]);
            }
            fprintf(out, "; chosen by eq. 15 with t_rewind/t_iter %.3g; built in %.3f s\n", mj->rewind_cost,
                    mj->build_seconds);
        } else {
            fprintf(out, "       majorant: octree, %d nodes, %d leaves, depth %d, fail limit %d, global sigma_maj %g 1/m\n",
                    mj->n_nodes, mj->n_leaves, mj->depth, mj->fail_limit, m->sigma_maj);
            fprintf(out, "       cost model (seed 000 eq. 14): %.3f iterations/ray vs %.3f unpartitioned (x%.2f); built in %.3f s\n",
                    mj->N_chosen, mj->N_nopart, mj->N_nopart / fmax(mj->N_chosen, 1e-300), mj->build_seconds);
        }
    }
    fprintf(out, "lights     %d\n", s->n_lights);
    for (int i = 0; i < s->n_lights; i++) {
        const rd_light *l = &s->lights[i];
        fprintf(out, "  [%d] %-11s", i, lkind[l->kind]);
        switch (l->kind) {
        case RD_LIGHT_POINT:
            fprintf(out, " at (%g, %g, %g), intensity (%g, %g, %g) W/sr", l->pos.x, l->pos.y, l->pos.z,
                    l->value.x, l->value.y, l->value.z);
            break;
        case RD_LIGHT_SPOT:
            fprintf(out, " at (%g, %g, %g), axis (%.3f, %.3f, %.3f), cone %g deg, intensity (%g, %g, %g) W/sr",
                    l->pos.x, l->pos.y, l->pos.z, l->dir.x, l->dir.y, l->dir.z,
                    2.0 * acos(l->cos_outer) * 180.0 / M_PI, l->value.x, l->value.y, l->value.z);
            break;
        case RD_LIGHT_DIRECTIONAL:
            fprintf(out, " toward (%.3f, %.3f, %.3f), irradiance (%g, %g, %g) W/m^2", l->dir.x, l->dir.y,
                    l->dir.z, l->value.x, l->value.y, l->value.z);
            if (l->radius > 0) fprintf(out, ", beam radius %g", l->radius);
            break;
        case RD_LIGHT_SPHERE:
            fprintf(out, " at (%g, %g, %g), radius %g, radiance (%g, %g, %g)", l->pos.x, l->pos.y, l->pos.z,
                    l->radius, l->value.x, l->value.y, l->value.z);
            break;
        case RD_LIGHT_ENVIRONMENT:
            fprintf(out, " radiance (%g, %g, %g)", l->value.x, l->value.y, l->value.z);
            break;
        }
        fprintf(out, ", power %.4g W\n", rd_light_power(l, rd_scene_radius(s)));
    }
    if (s->n_shapes || s->fill_medium >= 0) {
        static const char *const mkind[] = {"interface", "dielectric", "diffuse"};
        fprintf(out, "shapes     %d", s->n_shapes);
        if (s->fill_medium >= 0) fprintf(out, ", scene-wide medium %s", s->media[s->fill_medium].name);
        fprintf(out, "\n");
        for (int i = 0; i < s->n_shapes; i++) {
            const rd_shape *sh = &s->shapes[i];
            fprintf(out, "  [%d] %-12s %s, %zu triangles, %s", i, sh->name, sh->file, sh->mesh.n_triangles,
                    sh->mesh.closed ? "closed" : "open");
            fprintf(out, ", %s", mkind[sh->material.kind]);
            if (sh->material.kind == RD_MAT_DIELECTRIC) fprintf(out, " ior %g", sh->material.ior);
            fprintf(out, ", inside %s, outside %s\n", sh->inside >= 0 ? s->media[sh->inside].name : "(none)",
                    sh->outside >= 0 ? s->media[sh->outside].name : "(none)");
        }
    }
    fprintf(out, "background (%g, %g, %g)\n", s->background.x, s->background.y, s->background.z);
    fprintf(out, "settings   method %s, spp %d, time %g s, seed %llu, max_depth %d, rr_depth %d\n",
            s->settings.method, s->settings.spp, s->settings.time_limit,
            (unsigned long long)s->settings.seed, s->settings.max_depth, s->settings.rr_depth);
    fprintf(out, "memory     %.2f MiB (scene and volumes; film %.2f MiB)\n", mem / 1048576.0,
            (double)cam->width * cam->height * 3 * (sizeof(float) + sizeof(double)) / 1048576.0);
}
