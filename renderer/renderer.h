/* renderer.h: the public API of photonmarch's renderer module.
 *
 * Loads and validates a JSON scene (docs/scene-format.md), renders it with one of the methods,
 * writes images, and describes the scene. The command line (renderer/main.c) is a thin layer
 * over this header.
 *
 * Errors: every fallible function returns rd_status and, when `err` is non-NULL, writes one
 * line naming the file and the JSON path ("fog.json: media[0].albedo: expected 3 numbers in
 * [0,1]") into the caller's buffer. Nothing here prints (except through the caller's progress
 * callback) and nothing exits.
 * Ownership: every _new/_load has a _free; _free(NULL) is safe.
 */
#ifndef PHOTONMARCH_RENDERER_H
#define PHOTONMARCH_RENDERER_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    RD_OK = 0,
    RD_ERR_ARG,    /* bad argument or option value */
    RD_ERR_NOMEM,  /* allocation failed */
    RD_ERR_IO,     /* file missing, unreadable or unwritable */
    RD_ERR_PARSE,  /* not valid JSON */
    RD_ERR_SCENE,  /* valid JSON, invalid scene (wrong type, range, unknown key, ...) */
    RD_ERR_FORMAT, /* a data file (volume, image) is corrupt or of the wrong kind */
    RD_ERR_INTERNAL
} rd_status;

#define RD_ERRLEN 512

typedef struct rd_scene rd_scene; /* opaque; see rd_internal.h */

/* One `key=value` override applied to the JSON tree before validation (--set). The key is a
 * dotted JSON path with [i] indices ("settings.spp", "lights[0].intensity"); the value is
 * parsed as JSON, or taken as a string if it is not valid JSON. */
typedef struct { const char *key, *value; } rd_override;

/* Load, apply overrides, validate every field, load volume files (paths relative to the scene
 * file's folder), precompute majorants. */
rd_status rd_scene_load(rd_scene **out, const char *path, const rd_override *ov, int nov,
                        char *err, size_t errlen);
void rd_scene_free(rd_scene *scene);

/* Human-readable description: media, bounds, density range, lights, memory. */
void rd_scene_info(const rd_scene *scene, FILE *out);

/* Render settings as loaded (after overrides). */
int rd_scene_width(const rd_scene *scene);
int rd_scene_height(const rd_scene *scene);
int rd_scene_spp(const rd_scene *scene);
double rd_scene_time_limit(const rd_scene *scene);
uint64_t rd_scene_seed(const rd_scene *scene);
const char *rd_scene_method(const rd_scene *scene);
double rd_scene_exposure(const rd_scene *scene); /* camera.exposure, for the PNG preview */

/* ---- Rendering --------------------------------------------------------------------------- */

typedef struct {
    const char *method;  /* "delta" (others arrive with their issues) */
    int spp;             /* samples per pixel to reach (>= 1) */
    double time_limit;   /* seconds; > 0 stops after the pass that crosses it (spp still caps) */
    uint64_t seed;
    int threads;         /* 0 = OpenMP default */
    /* Polled between passes: when it becomes non-zero the current pass finishes and rd_render
     * returns RD_OK with the samples done so far. May be NULL. */
    const volatile int *cancel;
    /* Called after every pass (from the calling thread). May be NULL. */
    void (*progress)(void *user, int spp_done, int spp_total, double seconds);
    void *progress_user;
} rd_render_opts;

typedef struct {
    double seconds;          /* wall time of the render */
    int spp;                 /* samples per pixel completed */
    uint64_t paths;          /* camera paths traced */
    uint64_t collisions;     /* tentative collisions (real + null) of free-path sampling */
    uint64_t lookups;        /* density evaluations */
    uint64_t shadow_rays;    /* next-event transmittance estimates */
    uint64_t invalid;        /* non-finite samples dropped (should be 0; reported if not) */
    int cancelled;           /* 1 when the cancel flag stopped the render early */
} rd_render_stats;

/* Linear RGB film: w*h pixels, 3 floats each, row-major from the top-left. */
typedef struct {
    int w, h;
    float *rgb;
} rd_image;

void rd_image_free_pixels(rd_image *img);

rd_status rd_render(const rd_scene *scene, const rd_render_opts *opts, rd_image *out,
                    rd_render_stats *stats, char *err, size_t errlen);

/* The methods rd_render knows, comma-separated (for --help and error messages). */
const char *rd_methods(void);

/* ---- Image files (OpenImageIO shim; never throws) ---------------------------------------- */

/* Linear float EXR; written to a temporary name in the same folder, then renamed. */
rd_status rd_image_write_exr(const char *path, const rd_image *img, char *err, size_t errlen);
/* sRGB 8-bit preview: value * 2^exposure, clamped, sRGB transfer. Temp name, then rename. */
rd_status rd_image_write_png(const char *path, const rd_image *img, double exposure, char *err,
                             size_t errlen);
/* Read any format OpenImageIO reads into linear RGB floats (first three channels; grey is
 * replicated). */
rd_status rd_image_read(const char *path, rd_image *out, char *err, size_t errlen);

#ifdef __cplusplus
}
#endif
#endif /* PHOTONMARCH_RENDERER_H */
