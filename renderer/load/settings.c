/* settings.c: the scene's "settings" (method, sample counts, free-path engine), "photons",
 * "guide" and "march" sections, each with its defaults when the section or a field is absent.
 * settings.method is checked against the method table (integrators/rd_method.h). */
#include "bake/rd_photons.h"
#include "integrators/rd_method.h"
#include "load/rd_load.h"

#include <cJSON.h>
#include <stdio.h>
#include <string.h>

/* ---- settings ------------------------------------------------------------------------------ */

/* An equiangular mode at `key` of j (path.key in errors): true, false, "auto", "camera" where
 * `camera` allows it (settings.equiangular and guide.equiangular; march.equiangular has no
 * camera-only mode), and "tiles" where `tiles` does (settings.equiangular: `delta`'s choice
 * per tile). */
static rd_status parse_equiangular(ld_ctx *c, const cJSON *j, const char *path, int camera, int tiles,
                                   int *out)
{
    const cJSON *e = cJSON_GetObjectItemCaseSensitive(j, "equiangular");
    if (!e) return RD_OK;
    char field[64];
    snprintf(field, sizeof field, "%s.equiangular", path);
    const char *want = tiles    ? "true, false, \"camera\", \"auto\" or \"tiles\""
                       : camera ? "true, false, \"camera\" or \"auto\""
                                : "true, false or \"auto\"";
    if (cJSON_IsBool(e)) *out = cJSON_IsTrue(e) ? RD_EQ_ALL : RD_EQ_OFF;
    else if (camera && cJSON_IsString(e) && strcmp(e->valuestring, "camera") == 0) *out = RD_EQ_CAMERA;
    else if (tiles && cJSON_IsString(e) && strcmp(e->valuestring, "tiles") == 0) *out = RD_EQ_TILES;
    else if (cJSON_IsString(e) && strcmp(e->valuestring, "auto") == 0) *out = RD_EQ_AUTO;
    else if (cJSON_IsString(e)) return ld_fail(c, field, "expected %s, found \"%s\"", want, e->valuestring);
    else return ld_fail(c, field, "expected %s, found %s", want, ld_type_name(e));
    return RD_OK;
}

/* settings.adaptive: true, false, "auto" (RD_ADAPTIVE_AUTO), "pilot" (RD_ADAPTIVE_PILOT) or
 * "epochs" (RD_ADAPTIVE_EPOCHS); absent: *out unchanged. */
static rd_status parse_adaptive(ld_ctx *c, const cJSON *j, const char *path, int *out)
{
    const cJSON *e = cJSON_GetObjectItemCaseSensitive(j, "adaptive");
    if (!e) return RD_OK;
    char field[64];
    snprintf(field, sizeof field, "%s.adaptive", path);
    if (cJSON_IsBool(e)) *out = cJSON_IsTrue(e);
    else if (cJSON_IsString(e) && strcmp(e->valuestring, "auto") == 0) *out = RD_ADAPTIVE_AUTO;
    else if (cJSON_IsString(e) && strcmp(e->valuestring, "pilot") == 0) *out = RD_ADAPTIVE_PILOT;
    else if (cJSON_IsString(e) && strcmp(e->valuestring, "epochs") == 0) *out = RD_ADAPTIVE_EPOCHS;
    else if (cJSON_IsString(e))
        return ld_fail(c, field, "expected true, false, \"auto\", \"pilot\" or \"epochs\", found \"%.40s\"", e->valuestring);
    else return ld_fail(c, field, "expected true, false, \"auto\", \"pilot\" or \"epochs\", found %s", ld_type_name(e));
    return RD_OK;
}

/* settings.probes and march.probes (integrators/probes.c): "auto" (0) or a whole number of
 * camera chains per sample, 1 to 256; absent: *out unchanged. */
static rd_status parse_probes(ld_ctx *c, const cJSON *j, const char *path, int *out)
{
    const cJSON *e = cJSON_GetObjectItemCaseSensitive(j, "probes");
    if (!e) return RD_OK;
    char field[64];
    snprintf(field, sizeof field, "%s.probes", path);
    if (cJSON_IsString(e) && strcmp(e->valuestring, "auto") == 0) {
        *out = 0;
        return RD_OK;
    }
    double v = cJSON_IsNumber(e) ? e->valuedouble : 0.0;
    if (!cJSON_IsNumber(e) || v != floor(v) || v < 1.0 || v > 256.0) {
        char found[64];
        if (cJSON_IsString(e)) snprintf(found, sizeof found, "\"%.40s\"", e->valuestring);
        else if (cJSON_IsNumber(e)) snprintf(found, sizeof found, "%g", v);
        else snprintf(found, sizeof found, "%s", ld_type_name(e));
        return ld_fail(c, field, "expected \"auto\" or an integer in [1, 256], found %s", found);
    }
    *out = (int)v;
    return RD_OK;
}

/* `delta`'s thin-media strategies (docs/free-path.md): settings.equiangular is true, false,
 * "camera", "auto" or "tiles"; settings.thin_bias is false or a number in (0, 1) (1 would never pass: biased wherever a
 * pass-through is worth something), and needs an analog delta tracker
 * (it replaces the tracker's flight: weighted trackers bring weights of their own);
 * settings.beam_connect is true, false or "auto" (what it needs of the scene: load.c). */
static rd_status parse_strategies(ld_ctx *c, const cJSON *j, rd_settings *s)
{
    LD_TRY(parse_equiangular(c, j, "settings", 1, 1, &s->equiangular));
    s->equiangular_given = cJSON_GetObjectItemCaseSensitive(j, "equiangular") != NULL;
    const cJSON *b = cJSON_GetObjectItemCaseSensitive(j, "thin_bias");
    if (b) {
        if (cJSON_IsFalse(b)) s->thin_bias = 0.0;
        else if (!cJSON_IsNumber(b)) return ld_fail(c, "settings.thin_bias", "expected false or a number in (0, 1), found %s", ld_type_name(b));
        else if (!(b->valuedouble > 0.0 && b->valuedouble < 1.0))
            return ld_fail(c, "settings.thin_bias", "expected false or a number in (0, 1), found %g", b->valuedouble);
        else s->thin_bias = b->valuedouble;
        if (s->thin_bias > 0.0 && s->tracker != RD_FP_AUTO && s->tracker != RD_FP_SUPERVOXEL && s->tracker != RD_FP_WOODCOCK)
            return ld_fail(c, "settings.thin_bias", "only with \"tracker\": \"auto\", \"supervoxel\" or \"woodcock\" (it replaces the tracker's flight)");
    }
    const cJSON *bc = cJSON_GetObjectItemCaseSensitive(j, "beam_connect");
    if (bc) {
        if (cJSON_IsBool(bc)) s->beam_connect = cJSON_IsTrue(bc) ? RD_BC_ON : RD_BC_OFF;
        else if (cJSON_IsString(bc) && strcmp(bc->valuestring, "auto") == 0) s->beam_connect = RD_BC_AUTO;
        else if (cJSON_IsString(bc)) return ld_fail(c, "settings.beam_connect", "expected true, false or \"auto\", found \"%s\"", bc->valuestring);
        else return ld_fail(c, "settings.beam_connect", "expected true, false or \"auto\", found %s", ld_type_name(bc));
    }
    return RD_OK;
}
rd_status ld_parse_settings(ld_ctx *c, const cJSON *j, rd_settings *s)
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
    s->equiangular = RD_EQ_TILES; /* with probes 1 (below); docs/free-path.md "The default" */
    s->thin_bias = 0.0;
    s->beam_connect = RD_BC_AUTO;
    s->select = RD_SELECT_AUTO; /* integrators/select.c */
    s->probes = 1; /* measured in docs/guided-marching.md "Probes" */
    s->adaptive = RD_ADAPTIVE_AUTO; /* docs/guided-marching.md "Samples where they pay" */
    if (!j) return RD_OK;
    const char *path = "settings";
    LD_TRY(ld_need_object(c, j, path));
    static const char *const keys[] = {"spp", "time", "seed", "max_depth", "rr_depth", "method",
                                       "tracker", "transmittance", "b", "m", "step", "equiangular", "thin_bias",
                                       "beam_connect", "select", "probes", "adaptive", NULL};
    LD_TRY(ld_check_keys(c, j, path, keys));
    long long v;
    LD_TRY(ld_get_int(c, j, path, "spp", 0, 16, 1, 1 << 24, &v));
    s->spp = (int)v;
    s->spp_given = cJSON_GetObjectItemCaseSensitive(j, "spp") != NULL;
    LD_TRY(ld_get_num(c, j, path, "time", 0, 0, 0, 0, 1e7, 0, &s->time_limit));
    LD_TRY(ld_get_int(c, j, path, "seed", 0, 1, 0, (1LL << 53), &v));
    s->seed = (uint64_t)v;
    LD_TRY(ld_get_int(c, j, path, "max_depth", 0, 64, 1, 100000, &v));
    s->max_depth = (int)v;
    LD_TRY(ld_get_int(c, j, path, "rr_depth", 0, 3, 0, 100000, &v));
    s->rr_depth = (int)v;
    const char *m;
    LD_TRY(ld_get_str(c, j, path, "method", 0, "delta", &m));
    if (!rd_method_find(m)) {
        char names[256];
        rd_methods(names, sizeof names);
        return ld_fail(c, "settings.method", "unknown method \"%s\" (available: %s)", m, names);
    }
    snprintf(s->method, sizeof s->method, "%s", m);
    /* Free-path engine (rd_freepath.h): tracker, transmittance estimator and their parameters. */
    static const char *const trackers[] = {"auto", "woodcock", "supervoxel", "weighted", "decomposition", "raymarch", NULL};
    static const char *const trans[] = {"auto", "ratio-global", "ratio", "residual", "exact", "raymarch", NULL};
    LD_TRY(ld_get_enum(c, j, path, "tracker", 0, trackers, 0, &s->tracker));
    LD_TRY(ld_get_enum(c, j, path, "transmittance", 0, trans, 0, &s->transmittance));
    LD_TRY(ld_get_num(c, j, path, "b", 0, 1.0, 0, 1, 100, 0, &s->track_b));
    LD_TRY(ld_get_num(c, j, path, "m", 0, 1.0, 0, 0, 10, 0, &s->track_m));
    LD_TRY(ld_get_num(c, j, path, "step", 0, 0.0, 0, 1, 1e9, 0, &s->track_step));
    if (cJSON_GetObjectItemCaseSensitive(j, "b") && s->tracker != RD_FP_WEIGHTED &&
        s->tracker != RD_FP_DECOMPOSITION)
        return ld_fail(c, "settings.b", "only with \"tracker\": \"weighted\" or \"decomposition\"");
    if (cJSON_GetObjectItemCaseSensitive(j, "m") && s->tracker != RD_FP_DECOMPOSITION)
        return ld_fail(c, "settings.m", "only with \"tracker\": \"decomposition\"");
    if (cJSON_GetObjectItemCaseSensitive(j, "step") && s->tracker != RD_FP_RAYMARCH &&
        s->transmittance != RD_TR_RAYMARCH)
        return ld_fail(c, "settings.step", "only with \"tracker\" or \"transmittance\": \"raymarch\"");
    LD_TRY(parse_strategies(c, j, s));
    static const char *const select[] = {"off", "tiles", "pilot", "auto", NULL}; /* RD_SELECT_* order */
    LD_TRY(ld_get_enum(c, j, path, "select", 0, select, RD_SELECT_AUTO, &s->select));
    LD_TRY(parse_probes(c, j, path, &s->probes));
    LD_TRY(parse_adaptive(c, j, path, &s->adaptive));
    /* settings.equiangular's default: "tiles" (with "auto"'s adaptive, the epochs' shares:
     * integrators/delta.c), since session 72 the strongest `delta` on both suites and the
     * calibration scenes; "false" where settings.probes asks for probes, which "tiles"' two
     * estimators do not take (docs/free-path.md "The default") */
    if (!s->equiangular_given) s->equiangular = s->probes == 1 ? RD_EQ_TILES : RD_EQ_OFF;
    /* The probes' transmittance estimate and the path's own pass or stop must be unbiased alike
     * (integrators/probes.c): not with a ray-marched one. */
    if (s->probes != 1 && (s->tracker == RD_FP_RAYMARCH || s->transmittance == RD_TR_RAYMARCH))
        return ld_fail(c, "settings.probes", "needs an unbiased tracker and transmittance, not \"raymarch\"");
    return RD_OK;
}

/* ---- photons and guide (the photon map and its SH guide grid) ------------------------------- */
rd_status ld_parse_photons(ld_ctx *c, const cJSON *j, rd_photon_settings *p)
{
    p->count = 200000;
    p->store_direct = 1;
    p->segments = 0;
    p->max_depth = 64;
    p->seed = 1;
    p->progressive = 0;
    p->pass_count = 0;
    p->pass_spp = 1;
    p->alpha = RD_PPM_ALPHA;
    p->aim = RD_PHOTON_AIM;
    if (!j) return RD_OK;
    const char *path = "photons";
    LD_TRY(ld_need_object(c, j, path));
    static const char *const keys[] = {"count", "store_direct", "segments", "max_depth", "seed",
                                       "progressive", "pass_count", "pass_spp", "alpha", "aim", NULL};
    LD_TRY(ld_check_keys(c, j, path, keys));
    long long v;
    LD_TRY(ld_get_int(c, j, path, "count", 0, 200000, 1, 1000000000LL, &v));
    p->count = (size_t)v;
    LD_TRY(ld_get_bool(c, j, path, "store_direct", 1, &p->store_direct));
    LD_TRY(ld_get_bool(c, j, path, "segments", 0, &p->segments));
    LD_TRY(ld_get_int(c, j, path, "max_depth", 0, 64, 1, 100000, &v));
    p->max_depth = (int)v;
    LD_TRY(ld_get_int(c, j, path, "seed", 0, 1, 0, (1LL << 53), &v));
    p->seed = (uint64_t)v;
    LD_TRY(ld_get_bool(c, j, path, "progressive", 0, &p->progressive));
    LD_TRY(ld_get_int(c, j, path, "pass_count", 0, 0, 0, 1000000000LL, &v));
    p->pass_count = (size_t)v;
    LD_TRY(ld_get_int(c, j, path, "pass_spp", 0, 1, 1, 1 << 20, &v));
    p->pass_spp = (int)v;
    LD_TRY(ld_get_num(c, j, path, "alpha", 0, RD_PPM_ALPHA, 0, 1, 1, 1, &p->alpha));
    LD_TRY(ld_get_num(c, j, path, "aim", 0, RD_PHOTON_AIM, 0, 0, 1, 1, &p->aim));
    return RD_OK;
}

rd_status ld_parse_guide(ld_ctx *c, const cJSON *j, rd_guide_settings *g)
{
    memset(g, 0, sizeof *g);
    g->bands = 8; /* calibrated on beam-vdb and cloud (docs/guided-marching.md) */
    g->k = 64;
    g->lambda = 1.0;
    g->max_depth = 8;
    g->window = 1;
    g->distances = 0; /* guided-unbiased: off since session 46, by the calibration scenes (docs/guided-unbiased.md) */
    g->distance_alpha = 0.2;
    g->pass_floor = 0.1;
    g->majorant_weight = 0.2;
    g->secondary = 0; /* docs/guided-unbiased.md, "Camera flights only" (session 12) */
    g->distance_tau_max = 0.5; /* these three calibrated on hetero-forward and smoke-vdb */
    g->directions = 1;
    g->direction_weight = 0.25;
    g->roulette = 1;
    g->split_max = 2;
    g->eval_bands = 2; /* calibrated on the six calibration scenes and beam-vdb (docs/guided-unbiased.md) */
    g->photon_share = 0.25; /* the same seven scenes (docs/guided-unbiased.md) */
    g->equiangular = RD_EQ_OFF; /* with settings.select off "auto": load.c, since session 39 */
    g->probes = 0; /* "auto": docs/guided-unbiased.md, "Probes" */
    if (!j) return RD_OK;
    const char *path = "guide";
    LD_TRY(ld_need_object(c, j, path));
    static const char *const keys[] = {"grid", "bake", "bands", "k", "lambda", "resolution", "min_cell", "max_depth", "window",
                                       "distances", "distance_alpha", "pass_floor", "majorant_weight", "secondary",
                                       "directions", "direction_weight", "roulette", "split_max", "distance_tau_max",
                                       "eval_bands", "photon_share", "equiangular", "probes", NULL};
    LD_TRY(ld_check_keys(c, j, path, keys));
    static const char *const grids[] = {"uniform", "adaptive", NULL};
    static const char *const bakes[] = {"knn", "track", NULL};
    LD_TRY(ld_get_enum(c, j, path, "grid", 0, grids, 0, &g->adaptive));
    LD_TRY(ld_get_enum(c, j, path, "bake", 0, bakes, 0, &g->track));
    static const char *const windows[] = {"none", "hann", NULL};
    LD_TRY(ld_get_enum(c, j, path, "window", 0, windows, 1, &g->window));
    long long v;
    LD_TRY(ld_get_int(c, j, path, "bands", 0, 8, 1, 8, &v));
    g->bands = (int)v;
    LD_TRY(ld_get_int(c, j, path, "k", 0, 64, 1, 4096, &v));
    g->k = (int)v;
    LD_TRY(ld_get_num(c, j, path, "lambda", 0, 1.0, 0, 1, 1000, 0, &g->lambda));
    LD_TRY(ld_get_num(c, j, path, "min_cell", 0, 0.0, 0, 0, 1e9, 0, &g->min_cell));
    LD_TRY(ld_get_int(c, j, path, "max_depth", 0, 8, 1, 20, &v));
    g->max_depth = (int)v;
    /* guided-unbiased: p > 0 wherever the integrand can be needs alpha > 0; both outcomes of
     * the scatter-or-pass decision need a floor > 0 (and <= 0.5 so the two floors fit); the
     * majorant strategy's weight is in [0, 1) so the guide keeps a share. */
    LD_TRY(ld_get_bool(c, j, path, "distances", 0, &g->distances));
    LD_TRY(ld_get_num(c, j, path, "distance_alpha", 0, 0.2, 0, 1, 1, 0, &g->distance_alpha));
    LD_TRY(ld_get_num(c, j, path, "pass_floor", 0, 0.1, 0, 1, 0.5, 0, &g->pass_floor));
    LD_TRY(ld_get_num(c, j, path, "majorant_weight", 0, 0.2, 0, 0, 1, 1, &g->majorant_weight));
    LD_TRY(ld_get_bool(c, j, path, "secondary", 0, &g->secondary));
    /* The phase function keeps a share 1 - direction_weight > 0 of the continuations, so a
     * direction the guide's lobe misses is still drawn (p > 0 wherever the phase is). */
    LD_TRY(ld_get_num(c, j, path, "distance_tau_max", 0, 0.5, 0, 1, 1e300, 0, &g->distance_tau_max));
    LD_TRY(ld_get_bool(c, j, path, "directions", 1, &g->directions));
    LD_TRY(ld_get_num(c, j, path, "direction_weight", 0, 0.25, 0, 0, 1, 1, &g->direction_weight));
    LD_TRY(ld_get_bool(c, j, path, "roulette", 1, &g->roulette));
    LD_TRY(ld_get_int(c, j, path, "split_max", 0, 2, 1, 64, &v));
    g->split_max = (int)v;
    LD_TRY(ld_get_int(c, j, path, "eval_bands", 0, 2, 1, 8, &v));
    g->eval_bands = (int)v;
    LD_TRY(ld_get_num(c, j, path, "photon_share", 0, 0.25, 0, 1, 1, 0, &g->photon_share));
    LD_TRY(parse_equiangular(c, j, path, 1, 0, &g->equiangular));
    LD_TRY(parse_probes(c, j, path, &g->probes));
    const cJSON *res = cJSON_GetObjectItemCaseSensitive(j, "resolution");
    if (res) {
        if (!cJSON_IsArray(res) || cJSON_GetArraySize(res) != 3)
            return ld_fail(c, "guide.resolution", "expected 3 integers in [1, 1024]");
        for (int i = 0; i < 3; i++) {
            const cJSON *e = cJSON_GetArrayItem(res, i);
            if (!cJSON_IsNumber(e) || e->valuedouble != floor(e->valuedouble) || e->valuedouble < 1 ||
                e->valuedouble > 1024)
                return ld_fail(c, "guide.resolution", "expected 3 integers in [1, 1024]");
            g->res[i] = e->valueint;
        }
        if (g->adaptive) return ld_fail(c, "guide.resolution", "only for \"grid\": \"uniform\" (the adaptive grid refines by photon density)");
    }
    return RD_OK;
}

/* Ray marching of the guided methods (docs/scene-format.md "march"). */
rd_status ld_parse_march(ld_ctx *c, const cJSON *j, rd_march_settings *m)
{
    m->samples = 0; /* per placement, calibrated on cloud and smoke-vdb (integrators/march.c) */
    m->min_samples = 1;
    m->max_samples = 64;
    m->alpha = 0.2;
    m->ls = RD_LS_NEE_PATHS; /* unbiased; the photon sources measured against it: docs/guided-marching.md */
    m->detail = 0; /* "cells": lookups mislead where the photon estimate dominates (cloud) */
    m->paths = 0.0; /* per placement (integrators/march.c, march_default_paths) */
    /* "auto": the lit spans the camera rays and the samples' paths cross but rarely collide in
     * (integrators/march_equiangular.c); measured in docs/guided-marching.md */
    m->equiangular = RD_EQ_AUTO;
    m->probes = 0; /* "auto": measured in docs/guided-marching.md "Probes" */
    m->guided_paths = 1; /* docs/guided-marching.md "A fourth estimator" */
    m->beams = 1; /* since session 61: docs/guided-marching.md "The beams beside the marcher" */
    if (!j) return RD_OK;
    const char *path = "march";
    LD_TRY(ld_need_object(c, j, path));
    static const char *const keys[] = {"samples", "min_samples", "max_samples", "alpha", "ls", "detail", "paths", "equiangular", "probes", "guided_paths", "beams", NULL};
    LD_TRY(ld_check_keys(c, j, path, keys));
    long long v;
    LD_TRY(ld_get_int(c, j, path, "samples", 0, 0, 1, 4096, &v));
    m->samples = (int)v;
    LD_TRY(ld_get_int(c, j, path, "min_samples", 0, 1, 1, 4096, &v));
    m->min_samples = (int)v;
    LD_TRY(ld_get_int(c, j, path, "max_samples", 0, 64, 1, 4096, &v));
    m->max_samples = (int)v;
    if (m->max_samples < m->min_samples)
        return ld_fail(c, "march.max_samples", "must be >= march.min_samples (%d), found %d", m->min_samples, m->max_samples);
    LD_TRY(ld_get_num(c, j, path, "alpha", 0, 0.2, 0, 1, 1, 0, &m->alpha));
    static const char *const ls[] = {"nee+photons", "photons", "nee", "nee+guide", "nee+paths", "nee+delta", "nee+beams", NULL};
    int k = RD_LS_NEE_PATHS;
    LD_TRY(ld_get_enum(c, j, path, "ls", 0, ls, RD_LS_NEE_PATHS, &k));
    m->ls = (rd_ls_kind)k;
    LD_TRY(ld_get_num(c, j, path, "paths", 0, 0.0, 0, 1, 1, 0, &m->paths));
    static const char *const detail[] = {"cells", "lookups", NULL};
    LD_TRY(ld_get_enum(c, j, path, "detail", 0, detail, 0, &m->detail));
    LD_TRY(parse_probes(c, j, path, &m->probes));
    LD_TRY(ld_get_bool(c, j, path, "guided_paths", 1, &m->guided_paths));
    LD_TRY(ld_get_bool(c, j, path, "beams", 1, &m->beams));
    return parse_equiangular(c, j, path, 0, 0, &m->equiangular);
}
