/* bake.c: from a scene to its photon map and SH guide grid (seed 001 §3, THEORY.md §3-5), and
 * the pictures that show them: a projection of the stored photons through the scene camera,
 * and slices of the guide evaluated toward a direction. */
#include "rd_photons.h"
#include "sh.h"

#include <stdlib.h>
#include <string.h>

/* ---- Scene fields as sh/ callbacks --------------------------------------------------------- */

static double cb_sigma_t(const double x[3], void *user)
{
    const rd_medium *m = rd_scene_medium_at(user, v3(x[0], x[1], x[2]));
    return m ? rd_medium_sigma_t(m, v3(x[0], x[1], x[2])) : 0.0;
}

static void cb_sigma_s(const double x[3], void *user, double out[3])
{
    const rd_medium *m = rd_scene_medium_at(user, v3(x[0], x[1], x[2]));
    double st = m ? rd_medium_sigma_t(m, v3(x[0], x[1], x[2])) : 0.0;
    out[0] = m ? st * m->albedo.x : 0.0;
    out[1] = m ? st * m->albedo.y : 0.0;
    out[2] = m ? st * m->albedo.z : 0.0;
}

/* HG Legendre coefficients b_l = g^l of the medium at x (seed 001 appendix). */
typedef struct { const rd_scene *s; int bands; } phase_ctx;
static void cb_phase_at(const double x[3], void *user, double *b)
{
    const phase_ctx *pc = user;
    const rd_medium *m = rd_scene_medium_at(pc->s, v3(x[0], x[1], x[2]));
    sh_phase_coeffs_hg(m ? m->g : 0.0, pc->bands, b);
}

rd_status rd_guide_bake(const rd_scene *s, const pm_map *map, int threads, sh_guide **out,
                        char *err, size_t errlen)
{
    const rd_guide_settings *gs = &s->guide;
    sh_bake_params p;
    sh_bake_params_default(&p);
    p.kind = gs->adaptive ? SH_GRID_ADAPTIVE : SH_GRID_UNIFORM;
    p.method = gs->track ? SH_BAKE_TRACK : SH_BAKE_KNN;
    p.bands = gs->bands;
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
    phase_ctx pc = {s, gs->bands};
    if (same_g) sh_phase_coeffs_hg(s->n_media ? s->media[0].g : 0.0, gs->bands, p.phase_b);
    else {
        p.phase_at = cb_phase_at;
        p.phase_user = &pc;
    }
    p.sigma_t = cb_sigma_t;
    p.sigma_t_user = (void *)s;
    p.sigma_s = cb_sigma_s;
    p.sigma_s_user = (void *)s;
    p.threads = threads;
    char msg[RD_ERRLEN];
    sh_status st = sh_guide_bake(out, map, &p, msg, sizeof msg);
    if (st != SH_OK) {
        snprintf(err, errlen, "%s: guide: %s", s->path, msg);
        return st == SH_ERR_NOMEM ? RD_ERR_NOMEM : RD_ERR_SCENE;
    }
    return RD_OK;
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
    double aspect = (double)w / h, th = tan(0.5 * cam->fov_deg * M_PI / 180.0);
    double half_h = 0.5 * cam->ortho_width / aspect;
    const pm_photon *ph = pm_map_photons(map);
    size_t n = pm_map_photon_count(map);
    double o[3]; /* stored positions are offsets from the map origin */
    pm_map_origin(map, o);
    for (size_t i = 0; i < n; i++) {
        vec3 x = v3(o[0] + ph[i].pos[0], o[1] + ph[i].pos[1], o[2] + ph[i].pos[2]);
        vec3 v = v3_sub(x, cam->pos);
        double z = v3_dot(v, cam->forward), sx, sy;
        if (cam->kind == RD_CAM_PERSPECTIVE) {
            if (z <= 0) continue;
            sx = v3_dot(v, cam->right) / (z * th * aspect);
            sy = v3_dot(v, cam->up) / (z * th);
        } else {
            sx = v3_dot(v, cam->right) / (half_h * aspect);
            sy = v3_dot(v, cam->up) / half_h;
        }
        int px = (int)floor((sx + 1.0) * 0.5 * w), py = (int)floor((1.0 - sy) * 0.5 * h);
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

