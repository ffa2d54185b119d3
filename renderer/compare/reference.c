/* reference.c: the images `photonmarch compare` reads from files, each checked to match the
 * scene (its size, RGB, finite): the reference the methods are measured against, and the
 * images from elsewhere given with --add (docs/compare.md).
 *
 * The reference is the file given with --reference (REF-stderr.exr beside it, when present, is
 * its standard error), else the cached one, else a long render with delta, the unbiased method
 * (THEORY.md §2), saved in the cache under a key hashed (FNV-1a) from everything the image
 * depends on. Its standard error gives the variance it adds to every measured MSE
 * (THEORY.md §7).
 *
 * Light delta cannot render (issue 21 item 6): light that leaves a point, spot or directional
 * light through glass first (L S+ paths) is reached neither by next-event estimation (a shadow
 * ray stops at glass) nor by a path (it cannot hit a delta light). Its share of the light
 * scattered in the media is measured when the scene is loaded (rd_hidden_light); above
 * RD_HIDDEN_SHARE the rendered reference is a consistent photon render instead
 * (reference_scene).
 *
 * `delta` with its equiangular choice per tile (session 26). A rendered reference must be less
 * noisy than the best method's error (the rule, rd_cmp_reference_extend), and a plain `delta`
 * reference reaches that only while the best method is under about 5x plain `delta`'s
 * efficiency (at 50x a run: its cap). Where a point or spot light lights thin fog the methods
 * are far past that: on hard-narrow-spot `delta` with settings.equiangular "tiles" is 71x plain
 * `delta` and `guided-unbiased` 59x (docs/benchmarks.md "Session 26"), so a plain reference
 * stops at its cap too noisy to rank them, and its noise, which compare counts in every
 * method's MSE, makes the best look worse than they are. So when the scene does not name
 * settings.equiangular and has a point or spot light, or a directional beam (since session
 * 30), the reference is `delta` with "tiles" (its own choice per tile between the strategy and
 * none: integrators/delta.c), unbiased for the same image, and the report names it. Where the
 * strategy does not pay it costs a little: "tiles" is 0.85-0.97x plain `delta` on default,
 * hard-dense-block, cloud and hetero-forward, 1.59x on homogeneous; with a beam 0.90x on
 * beam-vdb, 0.94x on smoke-vdb, 0.98x on beam and 1.53x on hard-window-beam
 * (docs/free-path.md "Directional beams"). (glass-fog's and exp2-directional's light comes
 * through glass: their reference is the photon render above.) */
#include "compare/rd_compare.h"
#include "transport/rd_transport.h"

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
 * camera and the path settings it left out, and what decides the reference's samples. A fixed
 * reference (--ref-spp and/or --ref-time) is keyed by its spp and time cap. The default one is
 * keyed by neither: it is the first N samples per pixel of one stream (delta, the reference's
 * seed, sample indices 0, 1, 2, ...), N recorded beside it, so a cached one of N samples is
 * extended by rendering samples N, N + 1, ... (rd_render_opts.first_sample) and saved again
 * under the same key: the same key always names a prefix of the same stream. (Not with
 * settings.equiangular "tiles": each part of the reference runs delta's own pilot and epochs
 * on its own samples, so an extended reference is a mean of parts whose tiles may differ;
 * unbiased all the same.) "v3" since session 72, when "tiles" began to keep the beam
 * connections (load/load.c): a reference cached before under the same settings is another
 * image's noise on beam scenes, and is not served. */
static uint64_t reference_key(const rd_scene *s, int auto_ref, int photons, int spp, double time_cap, uint64_t seed)
{
    uint64_t h = auto_ref ? fnv1a(0xcbf29ce484222325ULL, "photonmarch reference v3 stream", 31)
                          : fnv1a(0xcbf29ce484222325ULL, "photonmarch reference v3 fixed", 30);
    if (photons) { /* the photon reference: its method's settings too (reference_scene) */
        const rd_march_settings *m = &s->march;
        const rd_photon_settings *p = &s->photons;
        h = fnv1a(h, "photons", 7);
        int mi[7] = {(int)m->ls, m->samples, m->min_samples, m->max_samples, m->detail, p->pass_spp, m->equiangular};
        h = fnv1a(h, mi, sizeof mi);
        h = hash_d(hash_d(hash_d(hash_d(h, m->alpha), m->paths), p->alpha), p->aim);
        uint64_t pu[4] = {p->count, p->pass_count, (uint64_t)p->max_depth, p->seed};
        h = fnv1a(h, pu, sizeof pu);
    }
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
    /* (settings.probes alike; 1, the default, leaves the key as it was) */
    if (s->settings.probes != 1) h = fnv1a(h, &s->settings.probes, sizeof s->settings.probes);
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
    if (!(spp >= 1) || !(secs >= 0)) return 0;
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

/* Save the reference in the cache (c->ref_base); a failed save is not an error: the
 * comparison goes on, and ref_source says the reference was not cached. Several ranks: rank 0
 * alone saves. */
static void reference_save(rd_comparison *c)
{
    snprintf(c->sum.ref_source, sizeof c->sum.ref_source, "rendered now (not cached)");
    if (!c->ref_base[0] || (cmp_ranks(c) && cmp_ranks(c)->rank != 0)) return;
    const char *base = c->ref_base;
    char path[1200], msg[RD_ERRLEN], meta[256];
    snprintf(path, sizeof path, "%.1000s.exr", base);
    int n = snprintf(meta, sizeof meta, "{\"key\": \"%016llx\", \"method\": \"%s\", \"spp\": %.10g, \"seconds\": %.6g}\n",
                     (unsigned long long)c->ref_key, c->sum.ref_method, c->sum.ref_spp, c->sum.ref_seconds);
    if (rd_make_parent_dirs(path, msg, sizeof msg) == RD_OK && rd_image_write_exr(path, &c->ref, msg, sizeof msg) == RD_OK) {
        snprintf(path, sizeof path, "%.1000s-stderr.exr", base);
        if (rd_image_write_exr(path, &c->ref_se, msg, sizeof msg) == RD_OK) {
            snprintf(path, sizeof path, "%.1000s.json", base);
            if (rd_write_atomic(path, meta, (size_t)n, msg, sizeof msg) == RD_OK)
                snprintf(c->sum.ref_source, sizeof c->sum.ref_source, "%.1000s.exr", base);
        }
    }
}

rd_status rd_cmp_share_image(const rd_comm *comm, rd_image *img, int w, int h, int root, char *err, size_t errlen)
{
    if (!comm || comm->size <= 1) return RD_OK;
    rd_status st = RD_OK;
    if (!img->rgb) {
        img->w = w, img->h = h, img->channels = 0;
        if (!(img->rgb = malloc((size_t)w * h * 3 * sizeof(float)))) {
            snprintf(err, errlen, "compare: out of memory for a %dx%d image from another rank", w, h);
            st = RD_ERR_NOMEM;
        }
    }
    if ((st = rd_comm_agree(comm, st, "compare: sharing an image", err, errlen)) != RD_OK) return st;
    rd_comm_bcast(comm, img->rgb, (size_t)w * h * 3 * sizeof(float), root);
    return RD_OK;
}

/* Progress of the reference's render: samples done in all (earlier parts included), the
 * samples aimed at and, with a time aim, the seconds. */
typedef struct {
    rd_comparison *c;
    int spp_before;       /* samples per pixel the reference had before this render */
    int spp_aim;          /* samples per pixel it is to have in all */
    double secs_before, secs_aim; /* seconds it had; seconds it is to have (0: no time aim) */
} ref_progress_ctx;

static void reference_progress(void *user, int done, int total, double seconds)
{
    (void)total;
    ref_progress_ctx *r = user;
    rd_comparison *c = r->c;
    const rd_cmp_opts *o = &c->opts;
    int spp = r->spp_before + done;
    double secs = r->secs_before + seconds;
    rd_cmp_progress p = {"reference", 1, 1, spp, secs, r->secs_aim > 0 ? r->secs_aim : r->spp_aim, 0.0};
    double eta = done > 0 ? seconds * (r->spp_aim - spp) / done : 0.0;
    if (r->secs_aim > 0) eta = done > 0 ? fmax(0.0, r->secs_aim - secs) : r->secs_aim - secs;
    p.left_seconds = fmax(0.0, eta) + c->planned_seconds;
    if (o->progress) o->progress(o->progress_user, &p);
}

/* One render of the reference's stream: delta, samples [first, first + spp) of every pixel,
 * at most time_limit seconds (<= 0: none). *res is the caller's to free. A render cut short by
 * Ctrl-C is returned with res->stats.cancelled. */
static rd_status reference_part(rd_comparison *c, const rd_scene *s, int first, int spp, double time_limit,
                                ref_progress_ctx *pc, rd_render_result *res, char *err, size_t errlen)
{
    const rd_cmp_opts *o = &c->opts;
    s = &c->ref_scene; /* (the scene, or as reference_scene changed it) */
    rd_render_opts ro = {.method = c->photon_ref ? "guided" : "delta", .spp = spp, .time_limit = time_limit,
                         .seed = REF_SEED(o->seed),
                         .threads = o->threads, .cancel = o->cancel, .progress = reference_progress,
                         .progress_user = pc, .first_sample = first, .clock = o->clock,
                         .clock_user = o->clock_user, .comm = cmp_ranks(c)};
    reference_progress(pc, 0, spp, 0.0);
    rd_status st = rd_render(s, &ro, res, err, errlen);
    if (st || !ro.comm) return st; /* (several ranks: rd_render's status is every rank's) */
    /* Several ranks rendered it together and rank 0 holds the image: every rank takes rank 0's
     * images and statistics, so that every rank decides what comes next alike (the seconds
     * included) and measures its runs against the same reference. */
    rd_comm_bcast(ro.comm, &res->stats, sizeof res->stats, 0);
    if ((st = rd_cmp_share_image(ro.comm, &res->image, c->w, c->h, 0, err, errlen)) == RD_OK)
        st = rd_cmp_share_image(ro.comm, &res->stderr_img, c->w, c->h, 0, err, errlen);
    if (st) rd_render_result_free(res);
    return st;
}

/* Merge a render of n2 more samples per pixel (mean m2, standard error se2) into the reference
 * of n samples (c->ref, c->ref_se), per value as one film of all n + n2 samples would have
 * them: each part's sum of squared deviations M = s^2 (n - 1), s^2 = n se^2, and the pooled
 * M = M_a + M_b + (m_b - m_a)^2 n_a n_b / (n_a + n_b) (Chan, Golub & LeVeque 1979, the
 * pairwise update; no cancellation), mean (n_a m_a + n_b m_b) / (n_a + n_b), se = sqrt(M /
 * (N - 1) / N). The result is the render of n + n2 samples to float rounding
 * (rd_render_opts.first_sample; with delta's settings.equiangular "tiles", whose parts choose
 * their tiles apart, an unbiased render of as many). Pixels that dropped a non-finite sample
 * (rd_render_stats.invalid, normally 0) are counted as if they had not. */
static void reference_merge(rd_comparison *c, double n, const rd_image *m2, const rd_image *se2, double n2)
{
    size_t nv = (size_t)c->w * c->h * 3;
    double N = n + n2;
    for (size_t i = 0; i < nv; i++) {
        double a = c->ref.rgb[i], b = m2->rgb[i];
        double Ma = (double)c->ref_se.rgb[i] * c->ref_se.rgb[i] * n * (n - 1);
        double Mb = (double)se2->rgb[i] * se2->rgb[i] * n2 * (n2 - 1);
        double d = b - a;
        double M = Ma + Mb + d * d * n * n2 / N;
        c->ref.rgb[i] = (float)((n * a + n2 * b) / N);
        c->ref_se.rgb[i] = (float)(N > 1 ? sqrt(M / (N - 1) / N) : 0.0);
    }
}

/* Take a finished part into the reference: the first part becomes it, later ones (whole
 * passes) are merged. A fixed reference's one part may end within a pass (its time limit):
 * its spp is then the mean over pixels. */
static void reference_take(rd_comparison *c, rd_render_result *res)
{
    if (!c->ref.rgb) {
        c->ref = res->image;
        c->ref_se = res->stderr_img;
        res->image.rgb = res->stderr_img.rgb = NULL;
        c->sum.ref_spp = res->stats.timed_out ? res->stats.spp_mean : res->stats.spp;
    } else {
        reference_merge(c, c->sum.ref_spp, &res->image, &res->stderr_img, res->stats.spp);
        c->sum.ref_spp += res->stats.spp;
    }
    c->sum.ref_seconds += res->stats.seconds;
}

/* Render `more` samples per pixel of the default reference's stream onto the reference (none
 * yet: from sample 0), in parts of whole passes so every pixel has the same count (the render
 * of a part is never cut by a time limit). With secs_aim > 0 the parts are sized to end near
 * that many seconds in all instead, from the rate measured so far: the first part 1 spp, each
 * next at most 3x the samples so far and, while more than 2 s are left, half of what is left
 * (so a change of speed under load overshoots the aim by a part of a second or two, not by a
 * third). Ctrl-C: the part cut short is dropped, c->sum.cancelled. */
static rd_status reference_grow(rd_comparison *c, const rd_scene *s, int more, double secs_aim, char *err,
                                size_t errlen)
{
    int have = c->ref.rgb ? (int)c->sum.ref_spp : 0;
    double secs0 = c->sum.ref_seconds;
    ref_progress_ctx pc = {c, have, have + more, secs0, secs_aim};
    int left = more;
    while (!c->sum.cancelled) {
        int spp_now = c->ref.rgb ? (int)c->sum.ref_spp : 0;
        int n;
        if (secs_aim > 0) {
            double rate = spp_now > have ? (c->sum.ref_seconds - secs0) / (spp_now - have) : 0.0;
            if (spp_now > have && rate > 0) {
                double want = (secs_aim - c->sum.ref_seconds) / rate;
                if (want < 0.5) break;
                if (want * rate > 2.0) want = 0.5 * want;
                n = (int)fmax(1.0, fmin(want + 0.5, fmin(3.0 * (spp_now - have + 1), (1 << 24) - spp_now)));
            } else n = 1;
            pc.spp_aim = spp_now + n;
        } else {
            if (left <= 0) break;
            n = left;
        }
        pc.spp_before = spp_now;
        pc.secs_before = c->sum.ref_seconds;
        rd_render_result res;
        rd_status st = reference_part(c, s, spp_now, n, 0.0, &pc, &res, err, errlen);
        if (st) return st;
        if (res.stats.cancelled || res.stats.spp < n) {
            rd_render_result_free(&res);
            c->sum.cancelled = 1;
            break;
        }
        reference_take(c, &res);
        rd_render_result_free(&res);
        left -= n;
    }
    return RD_OK;
}

/* A fixed reference: delta (or the photon reference) with `spp` samples per pixel (<= 0: no
 * cap) and `secs` seconds at most (<= 0: no limit); one render, never extended. */
static rd_status reference_fixed(rd_comparison *c, const rd_scene *s, int spp, double secs, char *err,
                                 size_t errlen)
{
    if (spp <= 0) spp = 1 << 24;
    ref_progress_ctx pc = {c, 0, spp, 0.0, secs > 0 ? secs : 0.0};
    rd_render_result res;
    rd_status st = reference_part(c, s, 0, spp, secs, &pc, &res, err, errlen);
    if (st == RD_ERR_CANCELLED) { /* Ctrl-C in the photon reference's bake or photon pass */
        c->sum.cancelled = 1;
        return RD_OK;
    }
    if (st) return st;
    if (res.stats.cancelled || res.stats.spp < 1) {
        rd_render_result_free(&res);
        c->sum.cancelled = 1;
        return RD_OK;
    }
    reference_take(c, &res);
    rd_render_result_free(&res);
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

int rd_cmp_reference_is_auto(const rd_cmp_opts *o)
{
    return !o->reference && o->ref_spp <= 0 && o->ref_time <= 0;
}

/* The rendered reference's scene and the report's name for its method (the head). Light delta
 * cannot render: its share (measured when the scene was loaded, with a fixed seed: the same on
 * every rank), and the photon reference's scene when a rendered reference must hold it:
 * `guided` with the photon map as its whole source, fresh photons every pass with a shrinking
 * radius (consistent), and no tile selection (its `delta` tiles would lack that light again).
 * Else `delta`, with settings.equiangular "tiles" (and settings.select at its default) where
 * the scene leaves that key to its default and has a point or spot light or a directional
 * beam that its beam connections (settings.beam_connect) do not serve. */
static void reference_scene(rd_comparison *c, const rd_scene *s)
{
    /* The reference draws every sample of every pixel (its parts are pooled by their sample
     * counts): never settings.adaptive's shares. */
    c->ref_scene = *s;
    c->ref_scene.settings.adaptive = 0;
    double share = rd_scene_hidden_light(s); /* measured at load (load/load.c) */
    c->sum.hidden_share = share;
    c->photon_ref = share > RD_HIDDEN_SHARE && !c->opts.reference;
    /* a beam that settings.beam_connect serves (on since session 31) needs no chord sample:
     * `delta` with its connections makes 2.8x plain `delta` on beam.json against the chord
     * sample's 1.2x (a 200-s reference), and 1.9-2.1x on beam-vdb against its 0.91x
     * (docs/benchmarks.md "Session 31", docs/free-path.md "Directional beams"), so only point
     * and spot lights, and beams "auto" leaves unconnected, call for "tiles" there */
    c->tiles_ref = !c->opts.reference && !c->photon_ref && !s->settings.equiangular_given && rd_eq_tiles_have_lights(s);
    snprintf(c->sum.ref_method, sizeof c->sum.ref_method, "%s",
             c->opts.reference ? "given"
             : c->photon_ref  ? "guided, march.ls photons, progressive passes"
             : c->tiles_ref   ? "delta, settings.equiangular tiles"
                              : "delta");
    if (c->tiles_ref) {
        c->ref_scene.settings.equiangular = RD_EQ_TILES;
        /* delta's tiles read settings.select ("pilot": no epochs), which is not in the key:
         * the reference takes the default whatever the scene asks of the guided methods */
        c->ref_scene.settings.select = RD_SELECT_AUTO;
    }
    if (c->photon_ref) {
        c->ref_scene.march.ls = RD_LS_PHOTONS;
        c->ref_scene.photons.store_direct = 1; /* no NEE: every collision's photon, first ones too */
        c->ref_scene.photons.progressive = 1;
        c->ref_scene.photons.pass_spp = 1; /* a pixel's samples on independent passes: its stderr holds */
        c->ref_scene.settings.select = RD_SELECT_OFF;
    }
}

/* The reference: given, else cached, else rendered (rd_compare.h). */
rd_status rd_cmp_reference_get(rd_comparison *c, const rd_scene *s, char *err, size_t errlen)
{
    const rd_cmp_opts *o = &c->opts;
    const rd_comm *comm = cmp_ranks(c);
    reference_scene(c, s);
    if (o->reference) /* several ranks: each reads the file, as it loads the scene */
        return rd_comm_agree(comm, reference_given(c, err, errlen), "compare: the reference", err, errlen);
    /* The photon reference is one render (its passes restart in every render, so parts would
     * not pool into a longer one): RD_CMP_REF_FIRST x a run's budget unless --ref-spp or
     * --ref-time say otherwise, never extended. */
    int auto_ref = rd_cmp_reference_is_auto(o) && !c->photon_ref;
    int ref_spp = o->ref_spp;
    double ref_time = o->ref_time;
    if (c->photon_ref && rd_cmp_reference_is_auto(o)) { /* its limits come from the budget */
        ref_spp = o->equal_spp ? (int)fmin(RD_CMP_REF_FIRST * o->budget, 1 << 24) : 0;
        ref_time = o->equal_spp ? 0.0 : RD_CMP_REF_FIRST * o->budget;
    }
    c->ref_key = reference_key(&c->ref_scene, auto_ref, c->photon_ref, auto_ref ? 0 : ref_spp,
                               auto_ref ? 0.0 : ref_time, REF_SEED(o->seed));
    c->ref_base[0] = 0;
    if (o->cache_dir) {
        snprintf(c->ref_base, sizeof c->ref_base, "%.900s/reference-%016llx", o->cache_dir, (unsigned long long)c->ref_key);
        /* Several ranks: rank 0 looks in the cache (it alone saves there) and gives the others
         * what it found. */
        int hit = !comm || comm->rank == 0 ? reference_from_cache(c, c->ref_base, c->ref_key) : 0;
        rd_comm_bcast(comm, &hit, sizeof hit, 0);
        if (hit && comm) {
            double v[2] = {c->sum.ref_spp, c->sum.ref_seconds};
            rd_comm_bcast(comm, v, sizeof v, 0);
            c->sum.ref_spp = v[0], c->sum.ref_seconds = v[1];
            rd_comm_bcast(comm, c->sum.ref_source, sizeof c->sum.ref_source, 0);
            rd_status st = rd_cmp_share_image(comm, &c->ref, c->w, c->h, 0, err, errlen);
            if (st == RD_OK) st = rd_cmp_share_image(comm, &c->ref_se, c->w, c->h, 0, err, errlen);
            if (st) return st;
        }
        if (hit) {
            c->sum.ref_rendered = 2;
            return RD_OK;
        }
    }
    rd_status st;
    if (auto_ref) {
        /* The first part, before the runs: RD_CMP_REF_FIRST times one run's budget (seconds,
         * or samples per pixel at equal spp), what the rule needs when delta is among the
         * methods; the rest, if the rule asks for it, after the runs (rd_cmp_reference_extend). */
        if (o->equal_spp) st = reference_grow(c, s, (int)fmin(RD_CMP_REF_FIRST * o->budget, 1 << 24), 0.0, err, errlen);
        else st = reference_grow(c, s, 0, RD_CMP_REF_FIRST * o->budget, err, errlen);
    } else {
        st = reference_fixed(c, s, ref_spp, ref_time, err, errlen);
    }
    if (st) return st;
    if (c->sum.cancelled || !c->ref.rgb) {
        /* Ctrl-C while rendering it: no comparison, nothing cached. */
        c->sum.cancelled = 1;
        rd_image_free_pixels(&c->ref);
        rd_image_free_pixels(&c->ref_se);
        return RD_OK;
    }
    c->sum.ref_rendered = 1;
    reference_save(c);
    return RD_OK;
}

/* More samples on the default reference after the runs, then saved again (rd_compare.h). */
rd_status rd_cmp_reference_extend(rd_comparison *c, const rd_scene *s, int more, char *err, size_t errlen)
{
    if (more < 1 || !c->ref.rgb) return RD_OK;
    double had = c->sum.ref_spp;
    rd_status st = reference_grow(c, s, more, 0.0, err, errlen);
    if (st || c->sum.ref_spp == had) return st; /* Ctrl-C: the reference as it was */
    c->sum.ref_extended++;
    reference_save(c);
    return RD_OK;
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

/* The report's files (rd_compare.h): report.c names its files with these, and a label whose
 * files would be one of them is refused before anything runs. */
const char *const rd_cmp_row_file[ROW_FILES] = {"%s.exr", "%s.png", "%s-error.png", "%s-crop.png", "curve-%s.dat"};
const char *const rd_cmp_fixed_file[] = {"index.html", "metrics.json", "convergence.svg", "convergence.gp",
                                         "colorbar.png", "reference.exr", "reference.png", "reference-crop.png",
                                         "reference-stderr.exr", NULL};

int rd_cmp_label_clash(const char *label, const char *const *names, int n, char *file, size_t filen)
{
    char mine[ROW_FILES][128], other[128];
    for (int k = 0; k < ROW_FILES; k++) snprintf(mine[k], sizeof mine[k], rd_cmp_row_file[k], label);
    for (int k = 0; k < ROW_FILES; k++) {
        for (int f = 0; rd_cmp_fixed_file[f]; f++)
            if (!strcmp(mine[k], rd_cmp_fixed_file[f])) return snprintf(file, filen, "%s", mine[k]), 1;
        for (int i = 0; i < n; i++)
            for (int j = 0; j < ROW_FILES; j++) {
                snprintf(other, sizeof other, rd_cmp_row_file[j], names[i]);
                if (!strcmp(mine[k], other)) return snprintf(file, filen, "%s", mine[k]), 1;
            }
    }
    return 0;
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
