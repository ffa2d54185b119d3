/* bake.c: from a scene to its photon map and SH guide grid (seed 001 §3, THEORY.md §3-5), and
 * the pictures that show them: a projection of the stored photons through the scene camera,
 * and slices of the guide evaluated toward a direction. */
#include "core/rd_core.h"
#include "integrators/rd_method.h"
#include "bake/rd_photons.h"
#include "sh.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- Scene fields as sh/ callbacks --------------------------------------------------------- */

static double cb_sigma_t(const double x[3], void *user)
{
    const rd_medium *m = rd_scene_medium_at_point(user, v3(x[0], x[1], x[2]));
    return m ? rd_medium_sigma_t(m, v3(x[0], x[1], x[2])) : 0.0;
}

static void cb_sigma_s(const double x[3], void *user, double out[3])
{
    const rd_medium *m = rd_scene_medium_at_point(user, v3(x[0], x[1], x[2]));
    double st = m ? rd_medium_sigma_t(m, v3(x[0], x[1], x[2])) : 0.0;
    out[0] = m ? st * m->albedo.x : 0.0;
    out[1] = m ? st * m->albedo.y : 0.0;
    out[2] = m ? st * m->albedo.z : 0.0;
}

/* The guide's phase coefficients: HG b_l = g^l (seed 001 appendix), times the Hann window
 * w_l when guide.window is on (sh_window_hann: truncated HG at g >= 0.7 rings below zero and
 * would call a forward-scattering beam seen from the side dark). */
static void guide_phase_coeffs(const rd_guide_settings *gs, double g, double *b)
{
    double w[SH_MAX_BANDS];
    sh_phase_coeffs_hg(g, gs->bands, b);
    if (gs->window && sh_window_hann(gs->bands, w) == SH_OK)
        for (int l = 0; l < gs->bands; l++) b[l] *= w[l];
}

/* Phase coefficients of the medium at x (media with different g). */
typedef struct { const rd_scene *s; } phase_ctx;
static void cb_phase_at(const double x[3], void *user, double *b)
{
    const phase_ctx *pc = user;
    const rd_medium *m = rd_scene_medium_at_point(pc->s, v3(x[0], x[1], x[2]));
    guide_phase_coeffs(&pc->s->guide, m ? m->g : 0.0, b);
}

/* rd_guide_bake with a cancel flag (rd_bake_opts.cancel; NULL: none). */
static rd_status guide_bake(const rd_scene *s, const pm_map *map, int bands, int threads, const volatile int *cancel,
                            sh_guide **out, char *err, size_t errlen)
{
    const rd_guide_settings *gs = &s->guide;
    sh_bake_params p;
    sh_bake_params_default(&p);
    p.kind = gs->adaptive ? SH_GRID_ADAPTIVE : SH_GRID_UNIFORM;
    p.method = gs->track ? SH_BAKE_TRACK : SH_BAKE_KNN;
    p.bands = bands > 0 && bands < gs->bands ? bands : gs->bands;
    p.k = gs->k;
    p.lambda = gs->lambda;
    memcpy(p.res, gs->res, sizeof p.res);
    p.min_cell = gs->min_cell;
    p.max_depth = gs->max_depth;
    /* The guide covers the media bounds. */
    p.lo[0] = s->bmin.x; p.lo[1] = s->bmin.y; p.lo[2] = s->bmin.z;
    p.hi[0] = s->bmax.x; p.hi[1] = s->bmax.y; p.hi[2] = s->bmax.z;
    /* One phase function for all media when they agree, else per cell. */
    int same_g = 1;
    for (int i = 1; i < s->n_media; i++) same_g &= s->media[i].g == s->media[0].g;
    /* (the phase coefficients of guide.bands, windowed for them, also where fewer bands are
     * baked: the bands kept are those of a full bake, and a reader's b_1 is guide.bands's) */
    phase_ctx pc = {s};
    if (same_g) guide_phase_coeffs(gs, s->n_media ? s->media[0].g : 0.0, p.phase_b);
    else {
        p.phase_at = cb_phase_at;
        p.phase_user = &pc;
    }
    p.sigma_t = cb_sigma_t;
    p.sigma_t_user = (void *)s;
    p.sigma_s = cb_sigma_s;
    p.sigma_s_user = (void *)s;
    p.threads = threads;
    p.cancel = cancel;
    char msg[RD_ERRLEN];
    sh_status st = sh_guide_bake(out, map, &p, msg, sizeof msg);
    if (st == SH_ERR_CANCELLED) {
        snprintf(err, errlen, "%s: guide bake interrupted", s->path);
        return RD_ERR_CANCELLED;
    }
    if (st != SH_OK) {
        snprintf(err, errlen, "%s: guide: %s", s->path, msg);
        return st == SH_ERR_NOMEM ? RD_ERR_NOMEM : RD_ERR_SCENE;
    }
    return RD_OK;
}

rd_status rd_guide_bake(const rd_scene *s, const pm_map *map, int threads, sh_guide **out,
                        char *err, size_t errlen)
{
    return guide_bake(s, map, 0, threads, NULL, out, err, errlen);
}

/* ---- Pictures ------------------------------------------------------------------------------ */

rd_status rd_photon_image(const rd_scene *s, const pm_map *map, rd_image *img, char *err,
                          size_t errlen)
{
    /* Splat each photon's power into the pixel it projects to through the scene camera: a
     * picture of where the light went (not a rendering: no transmittance to the camera). */
    const rd_camera *cam = &s->camera;
    int w = cam->width, h = cam->height;
    img->w = w;
    img->h = h;
    img->rgb = calloc((size_t)w * h * 3, sizeof(float));
    if (!img->rgb) {
        snprintf(err, errlen, "out of memory for the photon image");
        return RD_ERR_NOMEM;
    }
    const pm_photon *ph = pm_map_photons(map);
    size_t n = pm_map_photon_count(map);
    double o[3]; /* stored positions are offsets from the map origin */
    pm_map_origin(map, o);
    for (size_t i = 0; i < n; i++) {
        vec3 x = v3(o[0] + ph[i].pos[0], o[1] + ph[i].pos[1], o[2] + ph[i].pos[2]);
        double fx, fy;
        if (!rd_camera_project(cam, x, &fx, &fy)) continue;
        int px = (int)floor(fx), py = (int)floor(fy);
        if (px < 0 || py < 0 || px >= w || py >= h) continue;
        float *p = &img->rgb[3 * ((size_t)py * w + px)];
        p[0] += ph[i].power[0];
        p[1] += ph[i].power[1];
        p[2] += ph[i].power[2];
    }
    return RD_OK;
}

static int rd_cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Scale an image so that its 99.5th-percentile luminance maps to 1 (for PNG previews of
 * quantities with no natural exposure). */
void rd_image_normalise(rd_image *img)
{
    size_t n = (size_t)img->w * img->h;
    float *lum = malloc(n * sizeof *lum);
    if (!lum) return;
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        float l = 0.2126f * img->rgb[3 * i] + 0.7152f * img->rgb[3 * i + 1] + 0.0722f * img->rgb[3 * i + 2];
        if (l > 0) lum[m++] = l;
    }
    if (m > 0) {
        qsort(lum, m, sizeof *lum, rd_cmp_float);
        float ref = lum[(size_t)(0.995 * (m - 1))];
        if (ref > 0)
            for (size_t i = 0; i < 3 * n; i++) img->rgb[i] /= ref;
    }
    free(lum);
}


/* ---- The bake pipeline: scene in, photon map and guide out (seed 001 §3) ------------------ */

struct rd_baked {
    pm_map *map;
    pm_map *indirect;  /* NULL unless rd_bake_opts.indirect */
    sh_guide *guide;
    sh_guide *guide_indirect; /* NULL unless rd_bake_opts.indirect_guide */
    rd_bake_stats stats;
};

static double bake_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static double lum3(const double v[3]) { return 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]; }

void rd_baked_free(rd_baked *b)
{
    if (!b) return;
    sh_guide_free(b->guide);
    sh_guide_free(b->guide_indirect);
    pm_map_free(b->map);
    pm_map_free(b->indirect);
    free(b);
}

const rd_bake_stats *rd_baked_stats(const rd_baked *b) { return &b->stats; }
const pm_map *rd_baked_map(const rd_baked *b) { return b ? b->map : NULL; }
const pm_map *rd_baked_indirect_map(const rd_baked *b) { return b ? b->indirect : NULL; }
const sh_guide *rd_baked_guide(const rd_baked *b) { return b ? b->guide : NULL; }
const sh_guide *rd_baked_indirect_guide(const rd_baked *b) { return b ? b->guide_indirect : NULL; }

void rd_bake_opts_for(rd_bake_opts *o, unsigned needs)
{
    o->no_guide = !(needs & RD_NEEDS_GUIDE);
    o->indirect = (needs & (RD_NEEDS_INDIRECT | RD_NEEDS_INDIRECT_GUIDE | RD_NEEDS_INDIRECT_LOBE)) != 0;
    o->indirect_guide = (needs & (RD_NEEDS_INDIRECT_GUIDE | RD_NEEDS_INDIRECT_LOBE)) != 0;
    /* the lobe alone reads bands 0 and 1 (else every band, and 0 where there is no indirect guide) */
    o->indirect_bands = (needs & RD_NEEDS_INDIRECT_LOBE) && !(needs & RD_NEEDS_INDIRECT_GUIDE) ? 2 : 0;
    o->few_photons = (needs & RD_NEEDS_FEW_PHOTONS) != 0;
    o->reachable = (needs & RD_NEEDS_REACHABLE) != 0;
}

/* Photons to emit: the options' count, or the scene's (its guide.photon_share of it when the
 * method asked for few photons). */
static size_t photons_to_trace(const rd_scene *s, const rd_bake_opts *o)
{
    if (o->photons > 0) return o->photons;
    if (!o->few_photons) return s->photons.count;
    double n = floor((double)s->photons.count * s->guide.photon_share + 0.5);
    return n >= 1.0 ? (size_t)n : 1;
}

/* Trace the scene's photons into a new map (*map); store_direct and segments as asked. With
 * `indirect`, the same trace also fills a new *indirect with the photons without their first
 * flight (rd_trace_photons_split), which a second trace would otherwise repeat. Several ranks
 * (o->comm): collective, and a failure is every rank's. */
static rd_status trace_new_map(const rd_scene *s, const rd_bake_opts *o, int store_direct, int segments, double keep,
                               pm_map **map, pm_map **indirect, rd_photon_stats *ps, char *err,
                               size_t errlen)
{
    rd_photon_opts po = {.count = photons_to_trace(s, o),
                         .store_direct = store_direct,
                         .segments = segments,
                         .max_depth = s->photons.max_depth,
                         .reachable = o->reachable,
                         .keep = keep,
                         .seed = o->seed >= 0 ? (uint64_t)o->seed : s->photons.seed,
                         .threads = o->threads,
                         .cancel = o->cancel,
                         .comm = o->comm};
    memset(ps, 0, sizeof *ps);
    if (!(*map = pm_map_new()) || (indirect && !(*indirect = pm_map_new()))) {
        snprintf(err, errlen, "%s: out of memory for the photon map", s->path);
        return rd_comm_agree(o->comm, RD_ERR_NOMEM, "photon tracing", err, errlen); /* as the trace would */
    }
    return rd_trace_photons_split(s, &po, *map, indirect ? *indirect : NULL, ps, err, errlen);
}

/* Several ranks (rd_bake_opts.comm): the traces are collective, the loads, index builds and
 * guide bakes are each rank's own. So that a failure on one rank cannot leave the others waiting
 * in a trace, the ranks agree (rd_comm_agree) before each trace and at the end, and a rank that
 * fails agrees once, at its failure, which the others meet at their next agreement; an agreement
 * that reports a failure ends the bake on every rank. (The traces agree inside themselves, so a
 * failure there is already every rank's.) */
typedef struct {
    const rd_comm *comm;
    const char *path;
    int agreed; /* the failure being returned was agreed by every rank */
} bake_ranks;

/* A checkpoint: every rank's outcome so far (st), the worst of them returned. */
static rd_status bake_agree(bake_ranks *br, rd_status st, char *err, size_t errlen)
{
    char what[1100];
    snprintf(what, sizeof what, "%s: bake", br->path);
    st = rd_comm_agree(br->comm, st, what, err, errlen);
    br->agreed = st != RD_OK;
    return st;
}

/* Build the kd-trees of maps a and b (either may be NULL): on two threads of `threads` (0: all)
 * where both are there and it allows two, else one after the other (FLANN's build is serial:
 * its divideTree; for hard-dense-block's 2.05 and 1.85 million photons 0.54 s one after the
 * other, 0.29 s at once: docs/benchmarks.md "Session 51"). Each tree is the same either way (a
 * build is its own, deterministic). On failure, why gets the first failed build's message. */
static rd_status build_maps(pm_map *a, pm_map *b, int threads, char *why, size_t whylen)
{
    pm_map *maps[2] = {a, b};
    pm_status ps[2] = {PM_OK, PM_OK};
    char m0[RD_ERRLEN], m1[RD_ERRLEN], *msg[2] = {m0, m1};
    int t = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for num_threads(a && b && t > 1 ? 2 : 1) schedule(static, 1)
    for (int i = 0; i < 2; i++)
        if (maps[i]) ps[i] = pm_map_build(maps[i], msg[i], RD_ERRLEN);
    for (int i = 0; i < 2; i++)
        if (ps[i] != PM_OK) {
            snprintf(why, whylen, "%s", msg[i]);
            return RD_ERR_INTERNAL;
        }
    return RD_OK;
}

rd_status rd_bake(const rd_scene *s, const rd_bake_opts *o, rd_baked **out, char *err,
                  size_t errlen)
{
    *out = NULL;
    bake_ranks br = {o->comm && o->comm->size > 1 ? o->comm : NULL, s->path, 0};
    double t_start = bake_now();
    rd_baked *b = calloc(1, sizeof *b);
    if (!b) {
        snprintf(err, errlen, "%s: out of memory for the bake", s->path);
        return RD_ERR_NOMEM;
    }
    rd_bake_stats *bs = &b->stats;
    char pmerr[RD_ERRLEN];
    rd_status st = RD_OK;
    /* 1. Photons: traced through the scene (THEORY.md §3), or a saved map. */
    if (!o->load_photons && (st = bake_agree(&br, RD_OK, err, errlen)) != RD_OK) goto fail;
    if (o->load_photons) {
        if (pm_map_load(&b->map, o->load_photons, pmerr, sizeof pmerr) != PM_OK) {
            snprintf(err, errlen, "%s", pmerr);
            st = RD_ERR_FORMAT;
            goto fail;
        }
        bs->loaded = 1;
    } else {
        rd_photon_stats ps;
        pm_map **ind = o->indirect && !o->load_indirect ? &b->indirect : NULL;
        if ((st = trace_new_map(s, o, s->photons.store_direct, s->photons.segments, 1.0, &b->map, ind, &ps, err, errlen)) != RD_OK) {
            br.agreed = 1; /* a failed trace failed on every rank */
            goto fail;
        }
        bs->emitted = ps.emitted;
        bs->trace_seconds = ps.seconds;
        bs->collisions_per_photon = ps.emitted ? (double)ps.collisions / ps.emitted : 0.0;
        bs->power_emitted = lum3(ps.power_emitted);
        bs->power_absorbed = lum3(ps.power_absorbed);
        bs->power_escaped = lum3(ps.power_escaped);
        bs->power_cut = lum3(ps.power_carried);
        bs->power_absorbed_surfaces = lum3(ps.power_absorbed_surfaces);
        bs->ranks = br.comm ? br.comm->size : 1;
        bs->gather_seconds = ps.gather_seconds;
        bs->gather_bytes = ps.gather_bytes;
    }
    /* 2. The same photons without their first flight, for multiple scattering beside
     * next-event estimation (photon i follows the same path: its stream is keyed by i). */
    if (o->indirect && o->load_indirect) {
        if (pm_map_load(&b->indirect, o->load_indirect, pmerr, sizeof pmerr) != PM_OK) {
            snprintf(err, errlen, "%s", pmerr);
            st = RD_ERR_FORMAT;
            goto fail;
        }
    } else if (o->indirect && !b->indirect) {
        /* (with a loaded main map: the indirect photons need a trace of their own) */
        rd_photon_stats ps;
        if ((st = bake_agree(&br, RD_OK, err, errlen)) != RD_OK) goto fail;
        if ((st = trace_new_map(s, o, 0, 0, 1.0, &b->indirect, NULL, &ps, err, errlen)) != RD_OK) {
            br.agreed = 1;
            goto fail;
        }
    }
    /* 2b. The FLANN kd-trees over the photons, the two maps' at once (build_maps). */
    if (build_maps(b->map, b->indirect, o->threads, pmerr, sizeof pmerr) != RD_OK) {
        snprintf(err, errlen, "photon map: %s", pmerr);
        st = RD_ERR_INTERNAL;
        goto fail;
    }
    bs->stored = pm_map_photon_count(b->map);
    bs->indexed = bs->stored + (b->indirect ? pm_map_photon_count(b->indirect) : 0);
    bs->segments = pm_map_segment_count(b->map);
    bs->map_bytes = pm_map_memory_bytes(b->map);
    bs->index_seconds = pm_map_build_seconds(b->map);
    /* (A signal during the index builds, which cannot stop part-way, is seen here.) */
    if (o->cancel && *o->cancel) {
        snprintf(err, errlen, "%s: bake interrupted", s->path);
        st = RD_ERR_CANCELLED;
        goto fail;
    }
    /* 3. The SH guide grid (THEORY.md §5). */
    if (!o->no_guide && o->load_guide) {
        if (sh_guide_load(&b->guide, o->load_guide, pmerr, sizeof pmerr) != SH_OK) {
            snprintf(err, errlen, "%s", pmerr);
            st = RD_ERR_FORMAT;
            goto fail;
        }
    } else if (!o->no_guide && (st = guide_bake(s, b->map, 0, o->threads, o->cancel, &b->guide, err, errlen)) != RD_OK) {
        goto fail;
    }
    /* 3b. The guide of the indirect map: multiple scattering for march.ls = nee+guide, or the
     * direction lobe of guided-unbiased's paths (its first two bands: o->indirect_bands). */
    if (b->indirect && o->indirect_guide && o->load_indirect_guide) {
        if (sh_guide_load(&b->guide_indirect, o->load_indirect_guide, pmerr, sizeof pmerr) != SH_OK) {
            snprintf(err, errlen, "%s", pmerr);
            st = RD_ERR_FORMAT;
            goto fail;
        }
    } else if (b->indirect && o->indirect_guide &&
               (st = guide_bake(s, b->indirect, o->indirect_bands, o->threads, o->cancel, &b->guide_indirect, err, errlen)) != RD_OK) {
        goto fail;
    }
    if (b->guide) {
        sh_guide_stats gst;
        sh_guide_stats_get(b->guide, &gst);
        bs->has_guide = 1;
        bs->adaptive = gst.kind == SH_GRID_ADAPTIVE;
        bs->track = gst.method == SH_BAKE_TRACK;
        bs->bands = gst.bands;
        bs->cells = gst.cells;
        memcpy(bs->res, gst.res, sizeof bs->res);
        bs->depth_max = gst.depth_max;
        bs->cell_min = gst.cell_min;
        bs->cell_max = gst.cell_max;
        bs->guide_bytes = gst.memory_bytes;
        bs->guide_seconds = gst.bake_seconds;
    }
    if ((st = bake_agree(&br, RD_OK, err, errlen)) != RD_OK) goto fail;
    bs->seconds = bake_now() - t_start;
    *out = b;
    return RD_OK;
fail:
    if (br.comm && !br.agreed) st = bake_agree(&br, st, err, errlen);
    rd_baked_free(b);
    return st;
}

rd_status rd_bake_photon_pass(const rd_scene *s, unsigned maps, int pass, uint64_t render_seed, double keep,
                              int threads, const volatile int *cancel, const rd_comm *comm, rd_baked **out,
                              char *err, size_t errlen)
{
    *out = NULL;
    double t_start = bake_now();
    rd_baked *b = calloc(1, sizeof *b);
    if (!b) {
        snprintf(err, errlen, "%s: out of memory for photon pass %d", s->path, pass);
        return rd_comm_agree(comm, RD_ERR_NOMEM, "photon pass", err, errlen);
    }
    rd_bake_opts o = {0};
    o.photons = s->photons.pass_count > 0 ? s->photons.pass_count : s->photons.count;
    o.seed = (long long)rd_ppm_pass_seed(s->photons.seed, render_seed, pass);
    o.threads = threads;
    o.cancel = cancel;
    o.comm = comm;
    char pmerr[RD_ERRLEN];
    rd_status st = RD_OK;
    rd_photon_stats ps;
    /* The same two maps as rd_bake makes, from this pass's photons: one trace for both (a
     * collective one on several ranks, whose failure is every rank's). */
    pm_map **ind = maps & RD_NEEDS_INDIRECT ? &b->indirect : NULL;
    if (maps & RD_NEEDS_PHOTONS) st = trace_new_map(s, &o, s->photons.store_direct, 0, keep, &b->map, ind, &ps, err, errlen);
    else if (maps & RD_NEEDS_INDIRECT) st = trace_new_map(s, &o, 0, 0, keep, &b->indirect, NULL, &ps, err, errlen);
    if (st != RD_OK) {
        rd_baked_free(b);
        return st;
    }
    b->stats.emitted = ps.emitted;
    b->stats.collisions_per_photon = ps.emitted ? (double)ps.collisions / ps.emitted : 0.0;
    b->stats.stored = b->map ? pm_map_photon_count(b->map) : 0;
    /* (with RD_PASS_NO_INDEX: the photons put in order; only pass 1's count is read, and pass 1 is indexed) */
    b->stats.indexed = b->stats.stored + (b->indirect ? pm_map_photon_count(b->indirect) : 0);
    if (maps & RD_PASS_NO_INDEX) { /* the spatial order alone (rd_method.pass_maps) */
        pm_map *m[2] = {b->map, b->indirect};
        for (int i = 0; i < 2 && st == RD_OK; i++)
            if (m[i] && pm_map_order(m[i], pmerr, sizeof pmerr) != PM_OK) {
                snprintf(err, errlen, "photon map of pass %d: %s", pass, pmerr);
                st = RD_ERR_NOMEM;
            }
    } else if (build_maps(b->map, b->indirect, threads, pmerr, sizeof pmerr) != RD_OK) {
        snprintf(err, errlen, "photon map of pass %d: %s", pass, pmerr);
        st = RD_ERR_INTERNAL;
    }
    char what[64];
    snprintf(what, sizeof what, "photon pass %d", pass);
    if ((st = rd_comm_agree(comm, st, what, err, errlen)) != RD_OK) {
        rd_baked_free(b);
        return st;
    }
    b->stats.seconds = bake_now() - t_start;
    *out = b;
    return RD_OK;
}

/* ---- Files: a photon map or a guide through core/files.c's temporary and rename ---------- */

typedef struct { const pm_map *map; const sh_guide *guide; const char *path; } save_job;

static rd_status write_map_or_guide(FILE *f, void *user, char *err, size_t errlen)
{
    const save_job *j = user;
    if (j->map) return pm_map_write(j->map, f, j->path, err, errlen) == PM_OK ? RD_OK : RD_ERR_OUTPUT;
    return sh_guide_write(j->guide, f, j->path, err, errlen) == SH_OK ? RD_OK : RD_ERR_OUTPUT;
}

/* Save a map (guide NULL) or a guide (map NULL) as path; with a raised cancel flag the file is
 * not put in place (RD_ERR_CANCELLED) and its temporary is removed. */
static rd_status save_file(const pm_map *map, const sh_guide *guide, const char *path,
                           const volatile int *cancel, char *err, size_t errlen)
{
    save_job j = {map, guide, path};
    return rd_write_file(path, write_map_or_guide, &j, cancel, err, errlen);
}

/* ---- The bake cache -------------------------------------------------------------------- */

rd_status rd_bake_cached(const rd_scene *s, const rd_bake_opts *o, const char *dir, rd_baked **out,
                         int *hit, char *err, size_t errlen)
{
    /* The key: the scene's bake key and the options that change what is baked. */
    uint64_t k = s->bake_key;
    uint64_t extra[7] = {photons_to_trace(s, o), (uint64_t)o->seed, (uint64_t)o->indirect,
                         (uint64_t)o->no_guide, (uint64_t)o->indirect_guide, (uint64_t)o->reachable,
                         (uint64_t)o->indirect_bands};
    for (size_t i = 0; i < sizeof extra; i++) k = (k ^ ((const unsigned char *)extra)[i]) * 0x100000001b3ULL;
    char pmap[1100], ind[1100], guide[1100], iguide[1100], msg[RD_ERRLEN];
    snprintf(pmap, sizeof pmap, "%s/%016llx.pmap", dir, (unsigned long long)k);
    snprintf(ind, sizeof ind, "%s/%016llx-indirect.pmap", dir, (unsigned long long)k);
    snprintf(guide, sizeof guide, "%s/%016llx.guide", dir, (unsigned long long)k);
    snprintf(iguide, sizeof iguide, "%s/%016llx-indirect.guide", dir, (unsigned long long)k);
    *hit = 0;
    FILE *f;
    int have = (f = fopen(pmap, "rb")) != NULL;
    if (f) fclose(f);
    if (have && o->indirect) { have = (f = fopen(ind, "rb")) != NULL; if (f) fclose(f); }
    if (have && !o->no_guide) { have = (f = fopen(guide, "rb")) != NULL; if (f) fclose(f); }
    if (have && o->indirect_guide) { have = (f = fopen(iguide, "rb")) != NULL; if (f) fclose(f); }
    /* Several ranks: the cache serves only when every rank loads it (a node's own folder may
     * lack it), else every rank bakes, together, and rank 0 alone saves. */
    const rd_comm *comm = o->comm && o->comm->size > 1 ? o->comm : NULL;
    rd_baked *loaded = NULL;
    if (have) {
        rd_bake_opts lo = *o;
        lo.load_photons = pmap;
        lo.load_indirect = o->indirect ? ind : NULL;
        lo.load_guide = o->no_guide ? NULL : guide;
        lo.load_indirect_guide = o->indirect_guide ? iguide : NULL;
        lo.comm = NULL; /* loads only: each rank its own */
        if (rd_bake(s, &lo, &loaded, msg, sizeof msg) != RD_OK) loaded = NULL;
        /* (a damaged or foreign cache file: bake anew and replace it) */
    }
    if (comm) {
        int all = loaded != NULL;
        comm->reduce(comm->user, &all, 1, RD_COMM_INT, RD_COMM_MIN, -1);
        if (!all) {
            rd_baked_free(loaded);
            loaded = NULL;
        }
    }
    if (loaded) {
        *out = loaded;
        *hit = 1;
        return RD_OK;
    }
    rd_status st = rd_bake(s, o, out, err, errlen);
    if (st != RD_OK) return st;
    const rd_baked *b = *out;
    const volatile int *c = o->cancel;
    if (!comm || comm->rank == 0) {
        if ((st = rd_make_parent_dirs(pmap, msg, sizeof msg)) != RD_OK ||
            (st = save_file(b->map, NULL, pmap, c, msg, sizeof msg)) != RD_OK ||
            (b->indirect && (st = save_file(b->indirect, NULL, ind, c, msg, sizeof msg)) != RD_OK) ||
            (b->guide && (st = save_file(NULL, b->guide, guide, c, msg, sizeof msg)) != RD_OK) ||
            (b->guide_indirect && (st = save_file(NULL, b->guide_indirect, iguide, c, msg, sizeof msg)) != RD_OK)) {
            if (st != RD_ERR_CANCELLED) {
                snprintf(err, errlen, "bake cache not saved: %s", msg); /* the bake itself is good */
                *hit = -1;
            }
        }
    }
    /* Interrupted while saving (on rank 0): no bake, no more files, on every rank. */
    int cancelled = st == RD_ERR_CANCELLED;
    if (comm) comm->reduce(comm->user, &cancelled, 1, RD_COMM_INT, RD_COMM_MAX, -1);
    if (cancelled) {
        rd_baked_free(*out);
        *out = NULL;
        if (st == RD_ERR_CANCELLED) snprintf(err, errlen, "%s: bake interrupted while saving the cache (%s)", s->path, msg);
        else snprintf(err, errlen, "%s: bake interrupted while rank 0 saved the cache", s->path);
        return RD_ERR_CANCELLED;
    }
    return RD_OK;
}

/* Write img as PREFIX<suffix>.exr (unless png_only) and, normalised, .png. */
static rd_status write_pair(const char *prefix, const char *suffix, rd_image *img, int png_only,
                            char *err, size_t errlen)
{
    char path[1200];
    if (!png_only) {
        snprintf(path, sizeof path, "%s%s.exr", prefix, suffix);
        if (rd_image_write_exr(path, img, err, errlen) != RD_OK) return RD_ERR_OUTPUT;
    }
    rd_image_normalise(img);
    snprintf(path, sizeof path, "%s%s.png", prefix, suffix);
    return rd_image_write_png(path, img, 0.0, err, errlen) == RD_OK ? RD_OK : RD_ERR_OUTPUT;
}

/* One slice of the guide across `axis` at coordinate c, toward w: the radiance picture and the
 * cells picture (extinction for a uniform grid, depth for an adaptive one). */
static rd_status write_slice(const sh_guide *g, const char *prefix, char axis_name, int axis,
                             double c, const double w[3], char *err, size_t errlen)
{
    double lo[3], hi[3];
    sh_guide_box(g, lo, hi);
    int u = axis == 0 ? 1 : 0, v = axis == 2 ? 1 : 2;
    double ext_u = hi[u] - lo[u], ext_v = hi[v] - lo[v];
    rd_image img;
    img.w = 512;
    img.h = (int)fmax(1.0, fmin(2048.0, round(512.0 * ext_v / ext_u)));
    img.rgb = malloc((size_t)img.w * img.h * 3 * sizeof(float));
    if (!img.rgb) {
        snprintf(err, errlen, "out of memory for a guide slice");
        return RD_ERR_NOMEM;
    }
    sh_guide_stats gst;
    sh_guide_stats_get(g, &gst);
    sh_slice_what what[2] = {SH_SLICE_RADIANCE, gst.kind == SH_GRID_UNIFORM ? SH_SLICE_SIGMA_T : SH_SLICE_DEPTH};
    rd_status st = RD_OK;
    for (int q = 0; q < 2 && st == RD_OK; q++) {
        char msg[RD_ERRLEN], suffix[32];
        if (sh_guide_slice(g, axis, c, w, what[q], img.w, img.h, img.rgb, msg, sizeof msg) != SH_OK) {
            snprintf(err, errlen, "--slice %c: %s", axis_name, msg);
            st = RD_ERR_ARG;
            break;
        }
        snprintf(suffix, sizeof suffix, q == 0 ? "-slice-%c" : "-cells-%c", axis_name);
        st = write_pair(prefix, suffix, &img, q == 1, err, errlen);
    }
    rd_image_free_pixels(&img);
    return st;
}

rd_status rd_baked_write(const rd_baked *b, const rd_scene *s, const char *prefix,
                         const rd_bake_write_opts *o, char *err, size_t errlen)
{
    char path[1200];
    rd_status st = rd_make_parent_dirs(prefix, err, errlen);
    if (st) return st;
    if (o->write_map) {
        snprintf(path, sizeof path, "%s.pmap", prefix);
        if ((st = save_file(b->map, NULL, path, NULL, err, errlen)) != RD_OK) return st;
    }
    rd_image img = {0, 0, NULL, 0};
    if ((st = rd_photon_image(s, b->map, &img, err, errlen)) == RD_OK)
        st = write_pair(prefix, "-photons", &img, 0, err, errlen);
    rd_image_free_pixels(&img);
    if (st || !b->guide) return st;
    snprintf(path, sizeof path, "%s.guide", prefix);
    if ((st = save_file(NULL, b->guide, path, NULL, err, errlen)) != RD_OK) return st;
    /* Slices toward the camera unless told otherwise; one across z at the centre by default. */
    double w[3] = {-s->camera.forward.x, -s->camera.forward.y, -s->camera.forward.z};
    if (o->has_toward) memcpy(w, o->toward, sizeof w);
    double lo[3], hi[3];
    sh_guide_box(b->guide, lo, hi);
    int n = o->nslices > 0 ? (o->nslices < 8 ? o->nslices : 8) : 1;
    for (int k = 0; k < n && st == RD_OK; k++) {
        char name = o->nslices > 0 ? o->slice_axis[k] : 'z';
        if (name < 'x' || name > 'z') {
            snprintf(err, errlen, "--slice %c: expected x, y or z", name);
            return RD_ERR_ARG;
        }
        int axis = name - 'x';
        double c = o->nslices > 0 && o->slice_has_at[k] ? o->slice_at[k] : 0.5 * (lo[axis] + hi[axis]);
        st = write_slice(b->guide, prefix, name, axis, c, w, err, errlen);
    }
    return st;
}
