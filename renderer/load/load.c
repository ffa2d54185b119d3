/* load.c: rd_scene_load: read scene.json (cJSON), apply the --set overrides, validate every
 * section (the parsers in this folder) and the scene as a whole (media do not overlap, the
 * scene's bounds), hash what a bake depends on (the bake key), build the shapes' Embree
 * scene, and measure the light that only photons find (a short photon trace when the scene
 * has glass and a point, spot or directional light: hidden_light_default).
 *
 * Every error names the file and the JSON path and says what is wrong, e.g.
 *   fog.json: media[0].albedo: expected a number or 3 numbers in [0, 1]
 * Unknown keys are errors, so a typo is never silently ignored. The format is documented in
 * docs/scene-format.md. */
#include "scene/rd_geom.h"
#include "load/rd_load.h"
#include "transport/rd_transport.h"

#include <cJSON.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_SCENE_BYTES (64u << 20)
#define MAX_MEDIA 64
#define MAX_LIGHTS 256

/* ---- --set overrides ----------------------------------------------------------------------- */
/* Walk a dotted path with [i] indices, creating missing object members, and replace the leaf. */
static rd_status apply_override(ld_ctx *c, cJSON *root, const rd_override *ov)
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

/* settings.beam_connect's "auto": on where the beam's breadth, the share of its media's
 * bounds that its cylinder fills times (1 - |g|)^2 (the solid angle of the phase function's
 * lobe, forward or backward, goes as (1 - |g|)^2 for |g| near 1; the connection's table samples
 * either), is below this: a heuristic. A path's own collisions find a wide beam in a broadly
 * scattering medium unaided, and there the connections cost 13-70% of a sample's time for
 * little (docs/free-path.md, "Where it runs"). Chosen on variants of the calibration scenes
 * beam-vdb and smoke-vdb (their radius and g varied, g >= 0): the connections paid 1.3-3.9x
 * where the breadth was 0.0046 or less, 1.02-1.10x at 0.041-0.051; 0.014 is about the
 * geometric mean of the two ends (0.0137). */
#define RD_BC_AUTO_BREADTH 0.014
#define RD_BC_STR_(x) #x
#define RD_BC_STR(x) RD_BC_STR_(x) /* the limit in the message below, as written above */

/* settings.beam_connect (transport/beam_connect.c): what it needs of the scene, then its
 * tables. It connects to one beam (the first directional light with a radius whose axis
 * crosses a medium), and not with settings.equiangular `true`, which samples the beam's chord
 * on every flight: the two would be the same strategy counted twice. With "tiles" it stays on
 * (since session 72): a connected beam is then no light for the tiles (rd_eq_tiles_have_lights),
 * so that beside it alone they are plain `delta`; where a point or spot light gives the tiles a
 * choice, the flights that take the strategy sample the beam's chord and drop the connections
 * (transport/path.c), the others connect. `true` where it
 * cannot run is an error; "auto", the default, is then off, and off too for a broad beam
 * (above). */
static rd_status beam_connect_setup(ld_ctx *c, rd_scene *s)
{
    rd_beam_connect *bc = &s->beam_connect;
    bc->light = -1;
    int mode = s->settings.beam_connect;
    if (mode == RD_BC_OFF) {
        bc->off = "settings.beam_connect false";
        return RD_OK;
    }
    const char *why = NULL; /* a literal: `photonmarch info` prints it too */
    if (s->settings.equiangular == RD_EQ_ALL)
        why = "not with settings.equiangular true, which samples the beam from the same flights";
    else if (!rd_beam_connect_setup(s)) why = "no directional light with a radius whose axis crosses a medium";
    if (!why && mode == RD_BC_AUTO && !(bc->breadth < RD_BC_AUTO_BREADTH)) {
        bc->light = -1;
        bc->off = "\"auto\": a broad beam, its breadth not below " RD_BC_STR(RD_BC_AUTO_BREADTH) ", which a path's own collisions find";
        return RD_OK;
    }
    bc->off = why;
    if (!why || mode != RD_BC_ON) return RD_OK;
    return ld_fail(c, "settings.beam_connect", "%s", why);
}

static rd_status validate(ld_ctx *c, const cJSON *root, rd_scene *s)
{
    if (!cJSON_IsObject(root)) return ld_fail(c, "(top level)", "expected an object, found %s", ld_type_name(root));
    static const char *const keys[] = {"description", "camera", "media", "lights", "background", "settings", "photons", "guide", "march",
                                       "shapes", "medium", NULL};
    LD_TRY(ld_check_keys(c, root, "", keys));
    const char *desc;
    LD_TRY(ld_get_str(c, root, "", "description", 0, NULL, &desc));
    if (desc && !(s->description = strdup(desc))) return RD_ERR_NOMEM;
    const cJSON *cam = cJSON_GetObjectItemCaseSensitive(root, "camera");
    if (!cam) return ld_fail(c, "camera", "missing (required)");
    LD_TRY(ld_parse_camera(c, cam, &s->camera));

    const cJSON *media = cJSON_GetObjectItemCaseSensitive(root, "media");
    if (!media) return ld_fail(c, "media", "missing (required: an array of media)");
    if (!cJSON_IsArray(media)) return ld_fail(c, "media", "expected an array, found %s", ld_type_name(media));
    int nm = cJSON_GetArraySize(media);
    if (nm > MAX_MEDIA) return ld_fail(c, "media", "at most %d media", MAX_MEDIA);
    s->media = calloc(nm > 0 ? nm : 1, sizeof *s->media);
    if (!s->media) return RD_ERR_NOMEM;
    rd_majorant_opts mo[MAX_MEDIA];
    for (int i = 0; i < nm; i++) {
        rd_status st = ld_parse_medium(c, cJSON_GetArrayItem(media, i), i, &s->media[i], &mo[i]);
        s->n_media = i + 1; /* so rd_scene_free releases a partly loaded medium */
        if (st) return st;
    }
    LD_TRY(ld_parse_surfaces(c, root, s));
    for (int i = 0; i < nm; i++) s->media[i].bound = rd_scene_medium_bound(s, i);
    /* Media must not overlap: the trackers visit them one interval at a time. (Media bound to
     * shapes are exempt: the surfaces say where they are; box media stay clear of shapes.) */
    LD_TRY(ld_check_shape_outsides(c, s));
    LD_TRY(ld_check_boxes_clear_of_shapes(c, s));
    for (int i = 0; i < nm; i++)
        for (int k = i + 1; k < nm; k++) {
            if (rd_scene_medium_bound(s, i) || rd_scene_medium_bound(s, k)) continue;
            const rd_medium *a = &s->media[i], *b = &s->media[k];
            if (a->bmin.x < b->bmax.x && b->bmin.x < a->bmax.x && a->bmin.y < b->bmax.y &&
                b->bmin.y < a->bmax.y && a->bmin.z < b->bmax.z && b->bmin.z < a->bmax.z) {
                char p[64];
                snprintf(p, sizeof p, "media[%d].bounds", k);
                return ld_fail(c, p, "overlaps media[%d] (media must not overlap)", i);
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
        if (!cJSON_IsArray(lights)) return ld_fail(c, "lights", "expected an array, found %s", ld_type_name(lights));
        int nl = cJSON_GetArraySize(lights);
        if (nl > MAX_LIGHTS) return ld_fail(c, "lights", "at most %d lights", MAX_LIGHTS);
        s->lights = calloc(nl > 0 ? nl : 1, sizeof *s->lights);
        if (!s->lights) return RD_ERR_NOMEM;
        for (int i = 0; i < nl; i++) LD_TRY(ld_parse_light(c, cJSON_GetArrayItem(lights, i), i, &s->lights[i]));
        s->n_lights = nl;
    }
    LD_TRY(ld_get_vec3(c, root, "", "background", 0, v3(0, 0, 0), 1, 0, 1e12, &s->background));
    LD_TRY(ld_parse_settings(c, cJSON_GetObjectItemCaseSensitive(root, "settings"), &s->settings));
    /* A ray-marching step far below the scene's size would take forever. */
    if (s->settings.track_step > 0 && s->settings.track_step < 1e-6 * 2.0 * rd_scene_radius(s))
        return ld_fail(c, "settings.step", "%g is below 1e-6 of the scene's size (%g): the march would never finish",
                       s->settings.track_step, 2.0 * rd_scene_radius(s));
    LD_TRY(ld_parse_photons(c, cJSON_GetObjectItemCaseSensitive(root, "photons"), &s->photons));
    LD_TRY(ld_parse_guide(c, cJSON_GetObjectItemCaseSensitive(root, "guide"), &s->guide));
    /* guide.equiangular's default (session 39): false unless settings.select is off, since
     * guided-unbiased's tile selection has a third estimator (`delta` with the strategy on
     * every flight) that carries the strategy's gains; "auto" with the selection off (the method
     * alone, as calibrated in session 23); docs/guided-unbiased.md, "The equiangular strategy" */
    const cJSON *guide = cJSON_GetObjectItemCaseSensitive(root, "guide");
    if (!(cJSON_IsObject(guide) && cJSON_GetObjectItemCaseSensitive(guide, "equiangular")))
        s->guide.equiangular = s->settings.select == RD_SELECT_OFF ? RD_EQ_AUTO : RD_EQ_OFF;
    LD_TRY(ld_parse_march(c, cJSON_GetObjectItemCaseSensitive(root, "march"), &s->march));
    /* guide.probes as settings.probes: the probes' transmittance and guided-unbiased's own pass
     * or stop must be unbiased alike, so more than one chain needs an unbiased tracker and
     * transmittance; 1 and "auto" (0) take none there. */
    if (s->guide.probes > 1 && (s->settings.tracker == RD_FP_RAYMARCH || s->settings.transmittance == RD_TR_RAYMARCH))
        return ld_fail(c, "guide.probes", "needs an unbiased tracker and transmittance, not \"raymarch\"");
    if (s->guide.track && !s->photons.segments)
        s->photons.segments = 1; /* the track-length bake needs the segments */
    /* Every key is read: now the media's majorant structures (for a noise medium the loader's
     * longest step, which also tightens its majorant: nothing above reads it). */
    for (int i = 0; i < nm; i++) LD_TRY(ld_build_majorant(c, i, &s->media[i], &mo[i]));
    /* Lights by power for next-event estimation, and the lights a path can hit. */
    LD_TRY(rd_light_sampler_build(&s->light_sampler, s->lights, s->n_lights, rd_scene_radius(s)));
    s->sphere_lights = calloc(s->n_lights > 0 ? s->n_lights : 1, sizeof *s->sphere_lights);
    if (!s->sphere_lights) return RD_ERR_NOMEM;
    for (int i = 0; i < s->n_lights; i++)
        if (s->lights[i].kind == RD_LIGHT_SPHERE) s->sphere_lights[s->n_sphere_lights++] = i;
    return beam_connect_setup(c, s);
}

/* FNV-1a 64 over bytes, continuing from h. */
static uint64_t fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 0x100000001b3ULL;
    return h;
}

/* Light only photons find (renderer.h rd_hidden_light; docs/compare.md): measured once, when
 * the scene is loaded. Where it is more than RD_HIDDEN_SHARE of the media's light, the
 * marchers' default source is nee+beams (unless the scene names march.ls), with progressive
 * photon passes (consistent; unless the scene names photons.progressive): the default nee+paths
 * is unbiased only for the light it can sample, and cannot render that light at all. nee+beams, not nee+photons: on glass-fog (a
 * calibration scene) 131x against 74x `delta`'s efficiency at 10 s (docs/benchmarks.md,
 * "Session 21"; docs/scene-format.md, march.ls). */
static rd_status hidden_light_default(const cJSON *root, rd_scene *s, char *err, size_t errlen)
{
    rd_status st = rd_hidden_light(s, RD_HIDDEN_PHOTONS, 0, &s->hidden_share, NULL, err, errlen);
    if (st || !(s->hidden_share > RD_HIDDEN_SHARE)) return st;
    const cJSON *march = cJSON_GetObjectItemCaseSensitive(root, "march");
    const cJSON *photons = cJSON_GetObjectItemCaseSensitive(root, "photons");
    if (cJSON_GetObjectItemCaseSensitive(march, "ls")) return RD_OK;
    s->march.ls = RD_LS_NEE_BEAMS;
    if (!cJSON_GetObjectItemCaseSensitive(photons, "progressive")) s->photons.progressive = 1;
    return RD_OK;
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
    static const char *const render_only[] = {"spp", "time", "seed", "method", "max_depth", "rr_depth",
                                              "equiangular", "thin_bias", "select", NULL};
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
    ld_ctx c = {.file = path, .err = err, .errlen = errlen};
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
    if (st == RD_OK) st = hidden_light_default(root, s, err, errlen);
    cJSON_Delete(root);
    if (st) {
        if (st == RD_ERR_NOMEM) snprintf(err, errlen, "%s: out of memory", path);
        rd_scene_free(s);
        return st;
    }
    *out = s;
    return RD_OK;
}
