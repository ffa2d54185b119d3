/* output.c: what a render leaves on disk (docs/cli.md): the mean image, its per-pixel standard
 * error, a preview, and the JSON report. Every file is written under a temporary name and
 * renamed (core/files.c, and core/images.c for the images), so a failed or interrupted run never
 * leaves a partial file where a good one was. */
#include "bake/rd_photons.h"
#include "core/rd_core.h"
#include "integrators/rd_method.h"
#include "transport/rd_transport.h"

#include <cJSON.h>
#include <stdlib.h>
#include <string.h>

/* OUT.exr -> OUT<ext> */
static void sibling(const char *exr, const char *ext, char *out, size_t n)
{
    size_t len = strlen(exr);
    snprintf(out, n, "%.*s%s", (int)(len > 4 ? len - 4 : len), exr, ext);
}

/* The report (docs/cli.md "The render report"), built with cJSON. */
static char *report_json(const rd_scene *s, const rd_render_opts *o, const rd_render_result *res)
{
    const rd_render_stats *st = &res->stats;
    double paths = st->paths > 0 ? (double)st->paths : 1.0;
    const rd_method *m = rd_method_find(o->method);
    cJSON *j = cJSON_CreateObject();
    if (!j) return NULL;
    cJSON_AddStringToObject(j, "scene", s->path);
    cJSON_AddStringToObject(j, "method", o->method);
    cJSON_AddStringToObject(j, "method_summary", m ? m->summary : "");
    cJSON_AddNumberToObject(j, "width", res->image.w);
    cJSON_AddNumberToObject(j, "height", res->image.h);
    cJSON_AddNumberToObject(j, "spp", st->spp);
    cJSON_AddNumberToObject(j, "spp_mean", st->spp_mean);
    cJSON_AddBoolToObject(j, "shares", st->shares);
    cJSON_AddNumberToObject(j, "seed", (double)o->seed);
    cJSON_AddNumberToObject(j, "threads", st->threads); /* used, not asked (0 = all) */
    cJSON_AddNumberToObject(j, "seconds", st->seconds);
    cJSON_AddNumberToObject(j, "bake_seconds", st->bake_seconds);
    cJSON_AddNumberToObject(j, "prepare_seconds", st->prepare_seconds);
    cJSON_AddNumberToObject(j, "render_seconds", st->seconds - st->bake_seconds - st->prepare_seconds);
    cJSON_AddNumberToObject(j, "time_limit", o->time_limit);
    cJSON_AddBoolToObject(j, "interrupted", st->cancelled);
    cJSON_AddBoolToObject(j, "timed_out", st->timed_out);
    cJSON_AddNumberToObject(j, "paths", (double)st->paths);
    cJSON_AddNumberToObject(j, "tentative_collisions", (double)st->collisions);
    cJSON_AddNumberToObject(j, "density_lookups", (double)st->lookups);
    cJSON_AddNumberToObject(j, "shadow_rays", (double)st->shadow_rays);
    cJSON_AddNumberToObject(j, "equiangular_flights", (double)st->eq_flights);
    cJSON_AddNumberToObject(j, "equiangular_samples", (double)st->eq_samples);
    cJSON_AddNumberToObject(j, "collisions_per_path", st->collisions / paths);
    cJSON_AddNumberToObject(j, "lookups_per_path", st->lookups / paths);
    cJSON_AddNumberToObject(j, "paths_per_second", st->seconds > 0 ? st->paths / st->seconds : 0.0);
    cJSON_AddNumberToObject(j, "invalid_samples", (double)st->invalid);
    if (st->probes) /* march.probes, settings.probes, guide.probes: probe chains a camera sample took */
        cJSON_AddNumberToObject(j, "probes_per_sample", (double)st->probes / (double)(st->paths ? st->paths : 1));
    if (st->photon_passes > 0) {
        /* Progressive photon passes (docs/guided-marching.md "Progressive photon passes"). */
        cJSON *pp = cJSON_AddObjectToObject(j, "photon_passes");
        if (pp) {
            cJSON_AddNumberToObject(pp, "passes", st->photon_passes);
            cJSON_AddNumberToObject(pp, "photons", (double)st->photons_traced);
            cJSON_AddNumberToObject(pp, "seconds", st->photon_seconds);
            cJSON_AddNumberToObject(pp, "radius_scale", st->radius_scale);
            /* the share of a pass's collisions stored (RD_PASS_THIN: the beams' passes after the
             * first, in a dense medium) */
            cJSON_AddNumberToObject(pp, "keep", st->photon_keep);
            cJSON_AddNumberToObject(pp, "stored", (double)st->photons_stored); /* by the last pass */
            cJSON_AddNumberToObject(pp, "alpha", s->photons.alpha);
            cJSON_AddNumberToObject(pp, "spp_per_pass", s->photons.pass_spp);
            /* the share aimed at the glass, where the scene has glass (rd_emission_aim) */
            cJSON_AddNumberToObject(pp, "aim", rd_emission_aim_of(s).on ? s->photons.aim : 0.0);
        }
    }
    /* settings.select: the share of camera samples the tile selection gave to delta's path, and
     * of those with equiangular sampling on every flight (integrators/select.c) */
    if (m && strcmp(m->name, "delta") == 0) {
        /* settings.equiangular "tiles": the share the tiles gave to the path with the strategy
         * on every flight (the selection's "method", integrators/delta.c; none without a point
         * or spot light or a directional beam that the path does not connect to, where there
         * is no choice) */
        if (s->settings.equiangular == RD_EQ_TILES)
            cJSON_AddNumberToObject(j, "equiangular_share",
                                    st->paths && rd_eq_tiles_have_lights(s) ? 1.0 - (double)st->delta_samples / (double)st->paths
                                                                     : 0.0);
    } else if (st->rays_marched || st->delta_samples || st->path_samples) {
        cJSON_AddNumberToObject(j, "delta_share", st->paths ? (double)st->delta_samples / (double)st->paths : 0.0);
        cJSON_AddNumberToObject(j, "delta_equiangular_share",
                                st->paths ? (double)st->delta_eq_samples / (double)st->paths : 0.0);
        if (m && strcmp(m->name, "guided") == 0) /* march.guided_paths: guided-unbiased's paths' */
            cJSON_AddNumberToObject(j, "guided_path_share",
                                    st->paths ? (double)st->path_samples / (double)st->paths : 0.0);
        if (m && strcmp(m->name, "guided") == 0 && s->march.beams) /* march.beams: the beams estimator's */
            cJSON_AddNumberToObject(j, "beams_share",
                                    st->paths ? (double)st->beams_samples / (double)st->paths : 0.0);
    }
    if (st->flight_segments || st->guide_vertices) { /* guided-unbiased's guide reads */
        cJSON *gp = cJSON_AddObjectToObject(j, "guided_paths");
        if (gp) {
            double n = st->paths ? (double)st->paths : 1.0;
            cJSON_AddNumberToObject(gp, "flight_segments_per_path", (double)st->flight_segments / n);
            cJSON_AddNumberToObject(gp, "guide_vertices_per_path", (double)st->guide_vertices / n);
        }
    }
    if (st->rays_marched) { /* the marching methods' per-ray statistics */
        cJSON *mr = cJSON_AddObjectToObject(j, "march");
        if (mr) {
            cJSON_AddNumberToObject(mr, "rays", (double)st->rays_marched);
            cJSON_AddNumberToObject(mr, "samples_per_ray", st->samples_per_ray);
            cJSON_AddNumberToObject(mr, "samples_min", st->samples_min);
            cJSON_AddNumberToObject(mr, "samples_max", st->samples_max);
            cJSON_AddNumberToObject(mr, "pdf_segments_per_ray", st->cells_per_ray);
            cJSON_AddNumberToObject(mr, "lookups_per_ray", st->rays_marched ? (double)st->lookups / (double)st->rays_marched : 0.0);
            if (st->beam_queries) { /* march.ls nee+beams */
                cJSON_AddNumberToObject(mr, "beam_queries", (double)st->beam_queries);
                cJSON_AddNumberToObject(mr, "balls_per_query", (double)st->beam_hits / (double)st->beam_queries);
            }

        }
    }
    /* Mean per-pixel standard error (luminance), a one-number noise level of the image. */
    size_t np = (size_t)res->image.w * res->image.h;
    double se = 0.0;
    for (size_t p = 0; p < np; p++)
        se += 0.2126 * res->stderr_img.rgb[3 * p] + 0.7152 * res->stderr_img.rgb[3 * p + 1] +
              0.0722 * res->stderr_img.rgb[3 * p + 2];
    cJSON_AddNumberToObject(j, "mean_pixel_stderr", np ? se / np : 0.0);
    /* Variance per sample: the mean over pixels and channels of stderr^2 x n, the sample
     * variance of one camera sample (n = spp_mean: a stopped pass leaves some pixels one sample
     * behind, a relative error under 1 / spp). With the render seconds per sample, the two
     * halves of an efficiency, reported apart. */
    double v = 0.0;
    for (size_t q = 0; q < 3 * np; q++) v += (double)res->stderr_img.rgb[q] * res->stderr_img.rgb[q];
    cJSON_AddNumberToObject(j, "variance_per_sample", np ? v / (3.0 * np) * st->spp_mean : 0.0);
    if (res->n_curve > 0) {
        cJSON *c = cJSON_AddArrayToObject(j, "convergence");
        for (int i = 0; c && i < res->n_curve; i++) {
            cJSON *pt = cJSON_CreateObject();
            if (!pt) break;
            cJSON_AddNumberToObject(pt, "seconds", res->curve[i].seconds);
            cJSON_AddNumberToObject(pt, "spp_mean", res->curve[i].spp_mean);
            cJSON_AddNumberToObject(pt, "rmse", res->curve[i].rmse);
            cJSON_AddItemToArray(c, pt);
        }
    }
    char *text = cJSON_Print(j);
    cJSON_Delete(j);
    return text;
}

rd_status rd_render_write(const rd_scene *s, const rd_render_opts *o, const rd_render_result *res,
                          const char *exr_path, char *err, size_t errlen)
{
    char png[2100], json[2100], se[2100];
    sibling(exr_path, ".png", png, sizeof png);
    sibling(exr_path, ".json", json, sizeof json);
    sibling(exr_path, "-stderr.exr", se, sizeof se);
    rd_status st = rd_make_parent_dirs(exr_path, err, errlen);
    if (st) return st;
    if (rd_image_write_exr(exr_path, &res->image, err, errlen) != RD_OK ||
        rd_image_write_exr(se, &res->stderr_img, err, errlen) != RD_OK ||
        rd_image_write_png(png, &res->image, s->camera.exposure, err, errlen) != RD_OK)
        return RD_ERR_OUTPUT;
    char *text = report_json(s, o, res);
    if (!text) {
        snprintf(err, errlen, "%s: out of memory for the report", json);
        return RD_ERR_NOMEM;
    }
    st = rd_write_atomic(json, text, strlen(text), err, errlen);
    cJSON_free(text);
    return st;
}
