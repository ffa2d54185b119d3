/* rd_compare.h: what the files of `photonmarch compare` share (issue 11; THEORY.md §7;
 * docs/compare.md). Internal to renderer/compare/.
 *
 * The files, in the order the work flows (each uses only the ones before it):
 *   metrics.c      the metrics of THEORY.md §7 on images (public: rd_cmp_errors_of, ...)
 *   reference.c    the images read from files, checked to match the scene: the reference
 *                  (given, cached or rendered by delta) and the --add images
 *   runs.c         the comparison: the bakes, the K runs per method, the rows of metrics,
 *                  the default reference's rule (rd_compare_run, rd_comparison_summary,
 *                  rd_comparison_free)
 *   summary.c      the summary in words: baseline, winner, one sentence per row
 *   report_page.c  the text of the report's index.html
 *   report.c       the report folder (images, error maps, crops, convergence plot,
 *                  metrics.json, index.html) and the metrics table on stdout; it reads the
 *                  comparison, the comparison never calls it */
#ifndef RD_COMPARE_H
#define RD_COMPARE_H

#include "core/rd_core.h"
#include "scene/rd_scene.h"

#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Seeds: run k (0-based) of every method uses seed + 1 + k, so method A's run k and method
 * B's run k are as independent as any two renders; the reference uses a seed no run uses. */
#define RUN_SEED(seed, k) ((seed) + 1u + (uint64_t)(k))
#define REF_SEED(seed) ((seed) ^ 0x9e3779b97f4a7c15ULL)

/* One method's runs. */
typedef struct {
    const char *name;
    unsigned needs;       /* RD_NEEDS_* of its bake */
    rd_baked *baked;      /* shared with the methods of the same needs; owned when owns_baked */
    int owns_baked;
    double bake_seconds;  /* the bake's wall time, charged to each run */
    int done;             /* runs finished */
    rd_image *img, *se;   /* [runs]: mean and standard error images */
    rd_render_stats *stats;
    rd_conv_point **curve;
    int *n_curve;
} cmp_method;

struct rd_comparison {
    rd_cmp_opts opts;     /* a copy; the arrays it points to are the caller's */
    int n_methods, w, h;
    double exposure;      /* camera.exposure, for the PNGs */
    rd_image ref, ref_se; /* ref_se.rgb is NULL when the reference's error is unknown */
    cmp_method *m;
    rd_image *extra_img;  /* [n_extras] */
    rd_cmp_row *rows;
    const rd_image **row_img; /* [n_rows]: the image shown for each row (a method's first run) */
    rd_cmp_summary sum;
    double planned_seconds; /* seconds the runs not yet started will take (progress) */
    int photon_ref;       /* the reference is rendered by ref_scene's photons (RD_HIDDEN_SHARE) */
    int tiles_ref;        /* the reference is rendered by ref_scene's delta, equiangular "tiles" */
    rd_scene ref_scene;   /* the scene with the rendered reference's settings (a shallow copy) */
    uint64_t ref_key;     /* the rendered reference's cache key ... */
    char ref_base[1200];  /* ... and its cache path without extension ("": not cached) */
};

/* The comparison's ranks (opts.comm with several ranks; NULL alone). */
static inline const rd_comm *cmp_ranks(const rd_comparison *c)
{
    return c->opts.comm && c->opts.comm->size > 1 ? c->opts.comm : NULL;
}

/* The report's file names (report.c writes them; a --add label that would overwrite one is
 * refused, reference.c): per row, each pattern with the row's label; once, the fixed ones. */
enum { ROW_EXR, ROW_PNG, ROW_ERROR, ROW_CROP, ROW_CURVE, ROW_FILES };
extern const char *const rd_cmp_row_file[ROW_FILES];
extern const char *const rd_cmp_fixed_file[]; /* NULL-terminated */

/* The worst region of the report's crops: the square of side s at (x, y), in pixels. */
typedef struct { int x, y, s; } crop_box;

/* The one-line error: fmt with one %s, a. */
static inline rd_status fail(char *err, size_t errlen, rd_status st, const char *fmt, const char *a)
{
    if (err) snprintf(err, errlen, fmt, a);
    return st;
}

/* Rec. 709 luminance of a linear RGB value: the error maps and homogeneity are of it. */
static inline double luminance(const float *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

/* qsort order of doubles, ascending. */
static inline int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* ---- reference.c ---- */

/* The reference into c->ref (and c->ref_se when its error is known) and c->sum's ref_*:
 * opts.reference, else the cache (opts.cache_dir), else rendered and cached: by delta (with
 * settings.equiangular "tiles" where the scene has a point or spot light or a directional beam
 * and does not name the key), or by photons where delta cannot render part of the light (reference.c's head).
 * Cancelled while rendering: RD_OK with c->sum.cancelled = 1 and no reference. */
rd_status rd_cmp_reference_get(rd_comparison *c, const rd_scene *s, char *err, size_t errlen);
/* Several ranks (comm; NULL or one rank: nothing to do): rank root's w x h image into img on
 * every rank (allocated where img->rgb is NULL). Collective; the same status on every rank. */
rd_status rd_cmp_share_image(const rd_comm *comm, rd_image *img, int w, int h, int root, char *err, size_t errlen);
/* 1 when opts ask for the default reference (none given, neither --ref-spp nor --ref-time). */
int rd_cmp_reference_is_auto(const rd_cmp_opts *o);
/* Render `more` samples per pixel of the default reference's stream onto c->ref (the samples
 * after those it has, merged as one render would have them; with "tiles", a render whose
 * parts chose their tiles apart) and save it in the cache again.
 * Ctrl-C: the reference stays as it was, c->sum.cancelled = 1. */
rd_status rd_cmp_reference_extend(rd_comparison *c, const rd_scene *s, int more, char *err, size_t errlen);
/* Whether a --add label's files (LABEL.exr, ...) would be one of the report's other files:
 * those of the reference and the page, and those of the labels in names[0..n) (the methods
 * and the images before it). 0 when free, else 1 with the file named in file[0..filen). */
int rd_cmp_label_clash(const char *label, const char *const *names, int n, char *file, size_t filen);
/* The --add images into c->extra_img, each checked to have the scene's size. */
rd_status rd_cmp_extras_load(rd_comparison *c, char *err, size_t errlen);

/* ---- report_page.c ---- */

/* Append index.html for the comparison c of scene s to b: the error maps' scale and the
 * worst region bx are the ones its images were written with. */
void rd_cmp_page_text(rd_text *b, const rd_comparison *c, const rd_scene *s, double scale,
                      crop_box bx);

#ifdef __cplusplus
}
#endif

#endif
