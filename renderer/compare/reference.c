/* reference.c: the images `photonmarch compare` reads from files, each checked to match the
 * scene (its size, RGB, finite): the reference the methods are measured against, and the
 * images from elsewhere given with --add (docs/compare.md).
 *
 * The reference is the file given with --reference (REF-stderr.exr beside it, when present, is
 * its standard error), else the cached one, else a long render with delta, the unbiased method
 * (THEORY.md §2), saved in the cache under a key hashed (FNV-1a) from everything the image
 * depends on. Its standard error gives the variance it adds to every measured MSE
 * (THEORY.md §7). */
#include "compare/rd_compare.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- Reading images that must match the scene --------------------------------------------- */

/* Read `path` (what: "reference", "--add image") and check it has the scene's size. */
static rd_status read_matching(const char *path, const char *what, int w, int h, rd_image *img,
                               char *err, size_t errlen)
{
    char msg[RD_ERRLEN];
    rd_status st = rd_image_read(path, img, msg, sizeof msg);
    if (st == RD_ERR_IO || st == RD_ERR_FORMAT || st == RD_ERR_INTERNAL) {
        /* OpenImageIO says "could not open" for missing and unreadable files alike. */
        snprintf(err, errlen, "%s: %s", what, msg);
        return st == RD_ERR_INTERNAL ? RD_ERR_FORMAT : st;
    }
    if (st) { snprintf(err, errlen, "%s", msg); return st; }
    if (img->channels != 3 && img->channels != 4) {
        snprintf(err, errlen, "%s: %s has %d channel%s, expected RGB or RGBA (a render of the scene)", what, path,
                 img->channels, img->channels == 1 ? "" : "s");
        rd_image_free_pixels(img);
        return RD_ERR_FORMAT;
    }
    if (img->w != w || img->h != h) {
        snprintf(err, errlen, "%s: %s is %dx%d, the scene renders %dx%d", what, path, img->w, img->h, w, h);
        rd_image_free_pixels(img);
        return RD_ERR_FORMAT;
    }
    for (size_t i = 0; i < (size_t)w * h * 3; i++)
        if (!isfinite(img->rgb[i])) {
            snprintf(err, errlen, "%s: %s has non-finite pixels (pixel %zu)", what, path, i / 3);
            rd_image_free_pixels(img);
            return RD_ERR_FORMAT;
        }
    return RD_OK;
}

/* ---- The reference: given, cached, or rendered --------------------------------------------- */

static uint64_t fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 0x100000001b3ULL;
    return h;
}
static uint64_t hash_d(uint64_t h, double v) { return fnv1a(h, &v, sizeof v); }
static uint64_t hash_v(uint64_t h, vec3 v) { return hash_d(hash_d(hash_d(h, v.x), v.y), v.z); }

/* The cache key of the rendered reference: the scene's bake key (its JSON after overrides
 * without camera and render-only settings, plus every grid's voxels: load/load.c bake_key), the
 * camera and the path settings it left out, and the reference's own settings. */
static uint64_t reference_key(const rd_scene *s, int spp, double time_cap, uint64_t seed)
{
    uint64_t h = fnv1a(0xcbf29ce484222325ULL, "photonmarch reference v1", 24);
    h = fnv1a(h, &s->bake_key, sizeof s->bake_key);
    const rd_camera *c = &s->camera;
    int ints[6] = {(int)c->kind, c->width, c->height, s->settings.max_depth, s->settings.rr_depth, spp};
    h = fnv1a(h, ints, sizeof ints);
    h = hash_v(hash_v(hash_v(hash_v(h, c->pos), c->forward), c->right), c->up);
    h = hash_d(hash_d(hash_d(h, c->fov_deg), c->ortho_width), time_cap);
    h = fnv1a(h, &seed, sizeof seed);
    h = fnv1a(h, &s->settings.tracker, sizeof s->settings.tracker);
    h = fnv1a(h, &s->settings.transmittance, sizeof s->settings.transmittance);
    h = hash_d(hash_d(hash_d(h, s->settings.track_b), s->settings.track_m), s->settings.track_step);
    /* delta's strategies change the reference's noise, not its expectation; keyed all the same */
    h = fnv1a(h, &s->settings.equiangular, sizeof s->settings.equiangular);
    h = hash_d(h, s->settings.thin_bias);
    return h;
}

/* Try the cache: both images present, readable and of the right size, and the JSON beside
 * them naming the same key. Anything else is a miss (the reference is rendered again). */
static int reference_from_cache(rd_comparison *c, const char *base, uint64_t key)
{
    char path[1200], msg[RD_ERRLEN];
    snprintf(path, sizeof path, "%.1000s.json", base);
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    char text[512] = {0};
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = 0;
    char want[64];
    snprintf(want, sizeof want, "\"key\": \"%016llx\"", (unsigned long long)key);
    double spp = 0, secs = 0;
    const char *ps = strstr(text, "\"spp\": "), *pt = strstr(text, "\"seconds\": ");
    if (!strstr(text, want) || !ps || !pt) return 0;
    spp = atof(ps + 7);
    secs = atof(pt + 11);
    snprintf(path, sizeof path, "%.1000s.exr", base);
    if (read_matching(path, "cache", c->w, c->h, &c->ref, msg, sizeof msg)) return 0;
    snprintf(path, sizeof path, "%.1000s-stderr.exr", base);
    if (read_matching(path, "cache", c->w, c->h, &c->ref_se, msg, sizeof msg)) {
        rd_image_free_pixels(&c->ref);
        return 0;
    }
    c->sum.ref_spp = spp;
    c->sum.ref_seconds = secs;
    snprintf(c->sum.ref_source, sizeof c->sum.ref_source, "%.1000s.exr", base);
    return 1;
}

static void reference_progress(void *user, int done, int total, double seconds)
{
    rd_comparison *c = user;
    const rd_cmp_opts *o = &c->opts;
    rd_cmp_progress p = {"reference", 1, 1, done, seconds, o->ref_time > 0 ? o->ref_time : total, 0.0};
    double eta = done > 0 ? seconds * (total - done) / done : 0.0;
    if (o->ref_time > 0) eta = fmin(eta, fmax(0.0, o->ref_time - seconds));
    p.left_seconds = eta + c->planned_seconds;
    if (o->progress) o->progress(o->progress_user, &p);
}

/* Render the reference with delta (unbiased) and save it in the cache (a failed save is not an
 * error: the comparison goes on, and says so in ref_source). */
static rd_status reference_render(rd_comparison *c, const rd_scene *s, const char *base,
                                  uint64_t key, char *err, size_t errlen)
{
    const rd_cmp_opts *o = &c->opts;
    rd_render_opts ro = {.method = "delta", .spp = o->ref_spp, .time_limit = o->ref_time,
                         .seed = REF_SEED(o->seed), .threads = o->threads, .cancel = o->cancel,
                         .progress = reference_progress, .progress_user = c,
                         .clock = o->clock, .clock_user = o->clock_user};
    reference_progress(c, 0, o->ref_spp, 0.0);
    rd_render_result res;
    rd_status st = rd_render(s, &ro, &res, err, errlen);
    if (st) return st;
    if (res.stats.cancelled || res.stats.spp < 1) {
        rd_render_result_free(&res);
        c->sum.cancelled = 1;
        return RD_OK;
    }
    c->ref = res.image;
    c->ref_se = res.stderr_img;
    res.image.rgb = res.stderr_img.rgb = NULL;
    c->sum.ref_spp = res.stats.spp_mean;
    c->sum.ref_seconds = res.stats.seconds;
    c->sum.ref_rendered = 1;
    rd_render_result_free(&res);
    snprintf(c->sum.ref_source, sizeof c->sum.ref_source, "rendered now (not cached)");
    if (!base) return RD_OK;
    char path[1200], msg[RD_ERRLEN], meta[256];
    snprintf(path, sizeof path, "%.1000s.exr", base);
    int n = snprintf(meta, sizeof meta, "{\"key\": \"%016llx\", \"method\": \"delta\", \"spp\": %.6g, \"seconds\": %.6g}\n",
                     (unsigned long long)key, c->sum.ref_spp, c->sum.ref_seconds);
    if (rd_make_parent_dirs(path, msg, sizeof msg) == RD_OK && rd_image_write_exr(path, &c->ref, msg, sizeof msg) == RD_OK) {
        snprintf(path, sizeof path, "%.1000s-stderr.exr", base);
        if (rd_image_write_exr(path, &c->ref_se, msg, sizeof msg) == RD_OK) {
            snprintf(path, sizeof path, "%.1000s.json", base);
            if (rd_write_atomic(path, meta, (size_t)n, msg, sizeof msg) == RD_OK)
                snprintf(c->sum.ref_source, sizeof c->sum.ref_source, "%.1000s.exr", base);
        }
    }
    return RD_OK;
}

/* The reference given with --reference: REF.exr, and REF-stderr.exr beside it if present. */
static rd_status reference_given(rd_comparison *c, char *err, size_t errlen)
{
    const char *path = c->opts.reference;
    rd_status st = read_matching(path, "reference", c->w, c->h, &c->ref, err, errlen);
    if (st) return st;
    snprintf(c->sum.ref_source, sizeof c->sum.ref_source, "%.1000s", path);
    size_t n = strlen(path);
    if (n > 4 && !strcmp(path + n - 4, ".exr")) {
        char se[1200], msg[RD_ERRLEN];
        snprintf(se, sizeof se, "%.*s-stderr.exr", (int)(n - 4), path);
        FILE *f = fopen(se, "rb");
        if (f) {
            fclose(f);
            st = read_matching(se, "reference standard error", c->w, c->h, &c->ref_se, msg, sizeof msg);
            if (st) { snprintf(err, errlen, "%s", msg); return st; }
        }
    }
    return RD_OK;
}

/* The reference: given, else cached, else rendered (rd_compare.h). */
rd_status rd_cmp_reference_get(rd_comparison *c, const rd_scene *s, char *err, size_t errlen)
{
    const rd_cmp_opts *o = &c->opts;
    if (o->reference) return reference_given(c, err, errlen);
    uint64_t key = reference_key(s, o->ref_spp, o->ref_time, REF_SEED(o->seed));
    char base[1200];
    if (o->cache_dir) {
        snprintf(base, sizeof base, "%.900s/reference-%016llx", o->cache_dir, (unsigned long long)key);
        if (reference_from_cache(c, base, key)) {
            c->sum.ref_rendered = 2;
            return RD_OK;
        }
    }
    return reference_render(c, s, o->cache_dir ? base : NULL, key, err, errlen);
}

/* ---- Images from elsewhere: --add LABEL=IMAGE.exr[@SECONDS] --------------------------------- */

rd_status rd_cmp_extra_parse(const char *arg, char *buf, size_t bufn, rd_cmp_extra *e, char *err,
                             size_t errlen)
{
    if (strlen(arg) >= bufn) return fail(err, errlen, RD_ERR_ARG, "--add %s: too long", arg);
    snprintf(buf, bufn, "%s", arg);
    char *eq = strchr(buf, '=');
    if (!eq || eq == buf || !eq[1] || eq - buf >= 48)
        return fail(err, errlen, RD_ERR_ARG, "--add %s: expected LABEL=IMAGE.exr[@SECONDS] (a label of 1 to 47 characters)", arg);
    *eq = 0;
    e->label = buf;
    e->path = eq + 1;
    e->seconds = 0.0;
    char *at = strrchr(eq + 1, '@');
    if (at) {
        char *end;
        double s = strtod(at + 1, &end);
        if (end == at + 1 || *end || !(s > 0 && s < 1e9))
            return fail(err, errlen, RD_ERR_ARG, "--add %s: the time after @ must be a number of seconds > 0", arg);
        *at = 0;
        e->seconds = s;
    }
    if (!e->path[0]) return fail(err, errlen, RD_ERR_ARG, "--add %s: no image path", arg);
    for (const char *c = e->label; *c; c++)
        if (!(isalnum((unsigned char)*c) || *c == '-' || *c == '_' || *c == '.'))
            return fail(err, errlen, RD_ERR_ARG, "--add %s: the label may have letters, digits, '-', '_' and '.' only", arg);
    return RD_OK;
}

/* The --add images, read and checked before anything long runs. */
rd_status rd_cmp_extras_load(rd_comparison *c, char *err, size_t errlen)
{
    for (int i = 0; i < c->opts.n_extras; i++) {
        char what[80];
        snprintf(what, sizeof what, "--add %s", c->opts.extras[i].label);
        rd_status st = read_matching(c->opts.extras[i].path, what, c->w, c->h, &c->extra_img[i], err, errlen);
        if (st) return st;
    }
    return RD_OK;
}
