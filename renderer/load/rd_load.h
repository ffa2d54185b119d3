/* rd_load.h: the scene loader's shared parts (internal to renderer/load/): the error context,
 * the typed-parameter helpers that read one JSON field each and check it (pbrt-v4's "typed
 * parameters"), and the parser of each section of scene.json. rd_scene_load (renderer.h) is
 * the loader's one entry point; nothing outside load/ uses this header (tests may).
 *
 * Errors: every function returns RD_OK or a status, and on a scene error writes one line to
 * the context's buffer naming the file and the JSON path, e.g.
 *   fog.json: media[0].albedo: expected a number or 3 numbers in [0, 1]
 * Unknown keys are errors, so a typo is never silently ignored (docs/scene-format.md). */
#ifndef RD_LOAD_H
#define RD_LOAD_H

#include "media/rd_freepath.h"
#include "scene/rd_scene.h"

#include <cJSON.h>
#include <stddef.h>

/* Validation context: where we are and where errors go. */
typedef struct {
    const char *file; /* the scene path as the user gave it */
    char dir[1024];   /* its folder, for relative volume paths */
    char *err;
    size_t errlen;
} ld_ctx;

/* Return the status of x when it is not RD_OK. */
#define LD_TRY(x) do { rd_status st_ = (x); if (st_) return st_; } while (0)

/* ---- the error context and typed parameters (json.c) -------------------------------------- */

/* Write "FILE: PATH: message" (printf-style) to c->err; returns RD_ERR_SCENE. */
rd_status ld_fail(ld_ctx *c, const char *path, const char *fmt, ...);
/* out = parent.key (or key when parent is ""); a key that does not fit is cut. */
void ld_join(char *out, size_t n, const char *parent, const char *key);
/* "a number", "a string", ... for messages. */
const char *ld_type_name(const cJSON *j);
/* Reject keys of obj not in `allowed` (NULL-terminated). */
rd_status ld_check_keys(ld_ctx *c, const cJSON *obj, const char *path, const char *const *allowed);
rd_status ld_need_object(ld_ctx *c, const cJSON *j, const char *path);
/* The typed parameters: field `key` of obj (path names obj). A missing field is an error when
 * `required`, else *out = def. */
/* A finite number in [lo, hi] (open ends when lo_open / hi_open). */
rd_status ld_get_num(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int required,
                     double def, double lo, int lo_open, double hi, int hi_open, double *out);
/* An integer in [lo, hi]. */
rd_status ld_get_int(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int required,
                     long long def, long long lo, long long hi, long long *out);
/* Three finite numbers (or, when `allow_scalar`, one number replicated), each in [lo, hi]. */
rd_status ld_get_vec3(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int required,
                      vec3 def, int allow_scalar, double lo, double hi, vec3 *out);
/* A non-empty string; *out points into obj (valid while the JSON tree lives). */
rd_status ld_get_str(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int required,
                     const char *def, const char **out);
/* true or false (never required). */
rd_status ld_get_bool(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int def, int *out);
/* A string that is one of `names` (NULL-terminated); its index goes to *out. */
rd_status ld_get_enum(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int required,
                      const char *const *names, int def, int *out);
/* A file named in the scene, relative to the scene's folder unless absolute. */
void ld_resolve_path(const ld_ctx *c, const char *file, char *out, size_t n);
/* What to add to a data file's error (written into buf and returned): " (not committed: made
 * by SCRIPT; run it first)" when the file does not exist and the scene names its "made_by". */
const char *ld_missing_hint(const char *file, const char *made_by, char *buf, size_t n);

/* ---- the sections (one call each from rd_scene_load's validation, load.c) ----------------- */

/* "camera" (camera_lights.c); j is the section (not NULL). */
rd_status ld_parse_camera(ld_ctx *c, const cJSON *j, rd_camera *cam);
/* lights[idx] (camera_lights.c). */
rd_status ld_parse_light(ld_ctx *c, const cJSON *j, int idx, rd_light *l);
/* media[idx] with its density and bounds (media.c), and in *mo the options of its majorant
 * structure. On an error the medium may hold a grid: rd_scene_free releases it. */
rd_status ld_parse_medium(ld_ctx *c, const cJSON *m, int idx, rd_medium *med, rd_majorant_opts *mo);
/* Build media[idx]'s majorant structure with the options ld_parse_medium gave (media.c); the
 * loader calls it once every key of the scene is read, so a mistake anywhere is reported
 * before this, the loader's longest step, runs. */
rd_status ld_build_majorant(ld_ctx *c, int idx, rd_medium *med, const rd_majorant_opts *mo);
/* "settings", "photons", "guide", "march" (settings.c): defaults first, then the section's
 * fields; j may be NULL (the section is absent: defaults only). */
rd_status ld_parse_settings(ld_ctx *c, const cJSON *j, rd_settings *s);
rd_status ld_parse_photons(ld_ctx *c, const cJSON *j, rd_photon_settings *p);
rd_status ld_parse_guide(ld_ctx *c, const cJSON *j, rd_guide_settings *g);
rd_status ld_parse_march(ld_ctx *c, const cJSON *j, rd_march_settings *m);
/* "shapes" (meshes loaded and placed) and the scene-wide "medium" (shapes.c); after the
 * media, which they name. */
rd_status ld_parse_surfaces(ld_ctx *c, const cJSON *root, rd_scene *s);
/* A box medium must lie clear of every shape that encloses a region other than the scene-wide
 * medium's (shapes.c). */
rd_status ld_check_boxes_clear_of_shapes(ld_ctx *c, const rd_scene *s);
/* Every shape's "outside" names the medium actually around it (the inside of the innermost
 * closed shape containing it, else the scene-wide medium): "shapes[1].outside: "fog" but the
 * shape lies in "room" (...)". */
rd_status ld_check_shape_outsides(ld_ctx *c, const rd_scene *s);

#endif
