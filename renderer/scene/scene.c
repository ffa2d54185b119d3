/* scene.c: the scene as loaded (renderer/load/ builds it): its release (rd_scene_free), the
 * accessors of renderer.h, the scene-wide queries rd_scene_radius and rd_scene_medium_bound,
 * and rd_scene_info's summary. */
#include "scene/rd_geom.h"
#include "media/rd_freepath.h"

#include <stdio.h>
#include <stdlib.h>

static void medium_release(rd_medium *m)
{
    rd_grid_free(&m->grid);
    rd_majorant_free(m->majorant);
}

void rd_scene_free(rd_scene *s)
{
    if (!s) return;
    for (int i = 0; i < s->n_media; i++) medium_release(&s->media[i]);
    free(s->media);
    free(s->lights);
    rd_light_sampler_free(&s->light_sampler);
    free(s->sphere_lights);
    free(s->description);
    rd_geom_free(s->geom);
    for (int i = 0; i < s->n_shapes; i++) rd_mesh_free(&s->shapes[i].mesh);
    free(s->shapes);
    free(s);
}

/* ---- accessors and info -------------------------------------------------------------------- */
int rd_scene_width(const rd_scene *s) { return s->camera.width; }
int rd_scene_height(const rd_scene *s) { return s->camera.height; }
int rd_scene_spp(const rd_scene *s) { return s->settings.spp; }
double rd_scene_time_limit(const rd_scene *s) { return s->settings.time_limit; }
uint64_t rd_scene_seed(const rd_scene *s) { return s->settings.seed; }
const char *rd_scene_method(const rd_scene *s) { return s->settings.method; }
int rd_scene_spp_given(const rd_scene *s) { return s->settings.spp_given; }
double rd_scene_hidden_light(const rd_scene *s) { return s->hidden_share; }
int rd_scene_march_uses_photons(const rd_scene *s)
{
    rd_ls_kind k = s->march.ls;
    return k == RD_LS_PHOTONS || k == RD_LS_NEE_PHOTONS || k == RD_LS_NEE_GUIDE || k == RD_LS_NEE_BEAMS;
}
double rd_scene_exposure(const rd_scene *s) { return s->camera.exposure; }

double rd_scene_radius(const rd_scene *s)
{
    double r = 0.5 * v3_len(v3_sub(s->bmax, s->bmin));
    return r > 1e-3 ? r : 1e-3;
}

int rd_scene_medium_bound(const rd_scene *s, int i)
{
    if (i == s->fill_medium) return 1;
    for (int k = 0; k < s->n_shapes; k++)
        if (s->shapes[k].inside == i || s->shapes[k].outside == i) return 1;
    return 0;
}
void rd_scene_info(const rd_scene *s, FILE *out)
{
    static const char *const dkind[] = {"constant", "voxel grid", "procedural noise"};
    static const char *const lkind[] = {"point", "spot", "directional", "sphere", "environment"};
    const rd_camera *cam = &s->camera;
    fprintf(out, "scene      %s\n", s->path);
    if (s->description) fprintf(out, "about      %s\n", s->description);
    fprintf(out, "camera     %s, %dx%d, position (%g, %g, %g), forward (%.3f, %.3f, %.3f)",
            cam->kind == RD_CAM_PERSPECTIVE ? "perspective" : "orthographic", cam->width, cam->height,
            cam->pos.x, cam->pos.y, cam->pos.z, cam->forward.x, cam->forward.y, cam->forward.z);
    if (cam->kind == RD_CAM_PERSPECTIVE) fprintf(out, ", fov %g deg\n", cam->fov_deg);
    else fprintf(out, ", width %g\n", cam->ortho_width);
    size_t mem = sizeof *s + (size_t)s->n_media * sizeof(rd_medium) + (size_t)s->n_lights * sizeof(rd_light);
    fprintf(out, "media      %d\n", s->n_media);
    for (int i = 0; i < s->n_media; i++) {
        const rd_medium *m = &s->media[i];
        fprintf(out, "  [%d] %-12s %s", i, m->name, dkind[m->kind]);
        double dmin = 0, dmax = 0;
        if (m->kind == RD_DENSITY_CONSTANT) {
            dmin = dmax = m->constant;
        } else if (m->kind == RD_DENSITY_GRID) {
            size_t n = (size_t)m->grid.nx * m->grid.ny * m->grid.nz, bytes = rd_grid_bytes(&m->grid);
            mem += bytes;
            fprintf(out, " %dx%dx%d", m->grid.nx, m->grid.ny, m->grid.nz);
            if (m->grid.bricks)
                fprintf(out, " sparse, %zu bricks of 8^3 (%.1f MiB; dense would be %.1f MiB)", m->grid.bricks->n_bricks,
                        bytes / 1048576.0, n * 4.0 / 1048576.0);
            else
                fprintf(out, " (%.1f MiB)", bytes / 1048576.0);
            dmin = m->grid.vmin;
            dmax = m->grid.vmax;
        } else {
            const rd_noise *n = &m->noise;
            fprintf(out, " %d octaves, frequency %g, gain %g, seed %u", n->octaves, n->frequency, n->gain, n->seed);
            /* Sampled range on a 48^3 lattice (the majorant below is the provable bound). */
            dmin = INFINITY;
            dmax = 0;
            for (int k = 0; k < 48; k++)
                for (int j = 0; j < 48; j++)
                    for (int q = 0; q < 48; q++) {
                        vec3 x = v3(m->bmin.x + (q + 0.5) / 48 * (m->bmax.x - m->bmin.x),
                                    m->bmin.y + (j + 0.5) / 48 * (m->bmax.y - m->bmin.y),
                                    m->bmin.z + (k + 0.5) / 48 * (m->bmax.z - m->bmin.z));
                        double d = rd_medium_density(m, x);
                        dmin = fmin(dmin, d);
                        dmax = fmax(dmax, d);
                    }
            fprintf(out, " (range sampled on 48^3)");
        }
        fprintf(out, "\n       bounds (%g, %g, %g) - (%g, %g, %g)\n", m->bmin.x, m->bmin.y, m->bmin.z,
                m->bmax.x, m->bmax.y, m->bmax.z);
        fprintf(out, "       density [%g, %g], sigma_t scale %g, albedo (%g, %g, %g), g %g\n", dmin, dmax,
                m->sigma_t_scale, m->albedo.x, m->albedo.y, m->albedo.z, m->g);
        const rd_majorant *mj = m->majorant;
        if (!mj || mj->kind == RD_MAJ_NONE) {
            fprintf(out, "       majorant: global, sigma_maj %g 1/m", m->sigma_maj);
            if (mj && mj->n_levels > 1) {
                double best = INFINITY;
                for (int l = 1; l < mj->n_levels; l++) best = fmin(best, mj->N_level[l]);
                fprintf(out, " (no partition: seed 000 eq. 17 N = %.3f <= best grid eq. 16 N = %.3f)",
                        mj->N_nopart, best);
            }
            fprintf(out, "\n");
        } else if (mj->kind == RD_MAJ_GRID) {
            fprintf(out, "       majorant: super-voxel grid %dx%dx%d, %s bound, global sigma_maj %g 1/m\n",
                    mj->n[0], mj->n[1], mj->n[2], mj->bound == RD_BOUND_TRILINEAR ? "tri-linear" : "constant",
                    m->sigma_maj);
            fprintf(out, "       cost model (seed 000 eq. 14): %.3f iterations/ray vs %.3f unpartitioned (x%.2f)",
                    mj->N_chosen, mj->N_nopart, mj->N_nopart / fmax(mj->N_chosen, 1e-300));
            if (mj->n_levels > 1) {
                fprintf(out, "; per 2^l grid:");
                for (int l = 1; l < mj->n_levels; l++) fprintf(out, " %d:%.3g", 1 << l, mj->N_level[l]);
            }
            fprintf(out, "; chosen by eq. 15 with t_rewind/t_iter %.3g; built in %.3f s\n", mj->rewind_cost,
                    mj->build_seconds);
        } else {
            fprintf(out, "       majorant: octree, %d nodes, %d leaves, depth %d, fail limit %d, global sigma_maj %g 1/m\n",
                    mj->n_nodes, mj->n_leaves, mj->depth, mj->fail_limit, m->sigma_maj);
            fprintf(out, "       cost model (seed 000 eq. 14): %.3f iterations/ray vs %.3f unpartitioned (x%.2f); built in %.3f s\n",
                    mj->N_chosen, mj->N_nopart, mj->N_nopart / fmax(mj->N_chosen, 1e-300), mj->build_seconds);
        }
    }
    fprintf(out, "lights     %d\n", s->n_lights);
    for (int i = 0; i < s->n_lights; i++) {
        const rd_light *l = &s->lights[i];
        fprintf(out, "  [%d] %-11s", i, lkind[l->kind]);
        switch (l->kind) {
        case RD_LIGHT_POINT:
            fprintf(out, " at (%g, %g, %g), intensity (%g, %g, %g) W/sr", l->pos.x, l->pos.y, l->pos.z,
                    l->value.x, l->value.y, l->value.z);
            break;
        case RD_LIGHT_SPOT:
            fprintf(out, " at (%g, %g, %g), axis (%.3f, %.3f, %.3f), cone %g deg, intensity (%g, %g, %g) W/sr",
                    l->pos.x, l->pos.y, l->pos.z, l->dir.x, l->dir.y, l->dir.z,
                    2.0 * acos(l->cos_outer) * 180.0 / M_PI, l->value.x, l->value.y, l->value.z);
            break;
        case RD_LIGHT_DIRECTIONAL:
            fprintf(out, " toward (%.3f, %.3f, %.3f), irradiance (%g, %g, %g) W/m^2", l->dir.x, l->dir.y,
                    l->dir.z, l->value.x, l->value.y, l->value.z);
            if (l->radius > 0) fprintf(out, ", beam radius %g", l->radius);
            break;
        case RD_LIGHT_SPHERE:
            fprintf(out, " at (%g, %g, %g), radius %g, radiance (%g, %g, %g)", l->pos.x, l->pos.y, l->pos.z,
                    l->radius, l->value.x, l->value.y, l->value.z);
            break;
        case RD_LIGHT_ENVIRONMENT:
            fprintf(out, " radiance (%g, %g, %g)", l->value.x, l->value.y, l->value.z);
            break;
        }
        fprintf(out, ", power %.4g W\n", rd_light_power(l, rd_scene_radius(s)));
    }
    if (s->n_shapes || s->fill_medium >= 0) {
        static const char *const mkind[] = {"interface", "dielectric", "diffuse"};
        fprintf(out, "shapes     %d", s->n_shapes);
        if (s->fill_medium >= 0) fprintf(out, ", scene-wide medium %s", s->media[s->fill_medium].name);
        fprintf(out, "\n");
        for (int i = 0; i < s->n_shapes; i++) {
            const rd_shape *sh = &s->shapes[i];
            fprintf(out, "  [%d] %-12s %s, %zu triangles, %s", i, sh->name, sh->file, sh->mesh.n_triangles,
                    sh->mesh.closed ? "closed" : "open");
            fprintf(out, ", %s", mkind[sh->material.kind]);
            if (sh->material.kind == RD_MAT_DIELECTRIC) fprintf(out, " ior %g", sh->material.ior);
            fprintf(out, ", inside %s, outside %s\n", sh->inside >= 0 ? s->media[sh->inside].name : "(none)",
                    sh->outside >= 0 ? s->media[sh->outside].name : "(none)");
        }
    }
    fprintf(out, "background (%g, %g, %g)\n", s->background.x, s->background.y, s->background.z);
    fprintf(out, "settings   method %s, spp %d, time %g s, seed %llu, max_depth %d, rr_depth %d\n",
            s->settings.method, s->settings.spp, s->settings.time_limit,
            (unsigned long long)s->settings.seed, s->settings.max_depth, s->settings.rr_depth);
    static const char *const eq_names[] = {"off", "every flight", "camera ray", "auto (lit spans crossed)",
                                           "tiles (off or every flight, chosen per tile)"};
    char thin[32] = "off";
    if (s->settings.thin_bias > 0.0) snprintf(thin, sizeof thin, "%g", s->settings.thin_bias);
    fprintf(out, "delta      equiangular %s, thin_bias %s\n", eq_names[s->settings.equiangular], thin);
    static const char *const bc_names[] = {"false", "true", "auto"};
    const rd_beam_connect *bc = &s->beam_connect;
    /* the breadth (load.c, "auto"'s test): the share of its media's bounds that the beam's
     * cylinder fills x (1 - |g|)^2; 0 where no beam was set up */
    char breadth[64] = "";
    if (bc->breadth > 0.0) snprintf(breadth, sizeof breadth, ", breadth %.2g", bc->breadth);
    if (bc->light >= 0)
        fprintf(out, "beams      beam_connect %s: on, to light %d in medium \"%s\"%s (every path loop but the flights that sample its chord)\n",
                bc_names[s->settings.beam_connect], bc->light, s->media[bc->medium].name, breadth);
    else
        fprintf(out, "beams      beam_connect %s: off%s%s%s%s\n", bc_names[s->settings.beam_connect], bc->off ? " (" : "",
                bc->off ? bc->off : "", bc->off ? ")" : "", breadth);
    static const char *const march_eq[] = {"off", "every segment and path flight", "", "auto (lit spans crossed)"};
    fprintf(out, "marchers   equiangular %s\n", march_eq[s->march.equiangular]);
    fprintf(out, "guided-unb equiangular %s\n", eq_names[s->guide.equiangular]);
    fprintf(out, "memory     %.2f MiB (scene and volumes; film %.2f MiB)\n", mem / 1048576.0,
            (double)cam->width * cam->height * 3 * (sizeof(float) + sizeof(double)) / 1048576.0);
}
