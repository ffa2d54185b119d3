/* queries.c: the questions the transport asks of a scene, in one place (rd_scene.h "Surfaces in
 * the transport"; docs/surfaces.md):
 *  - what does a ray meet first (rd_scene_intersect: Embree when there are shapes, else the
 *    sphere lights by rd_scene_hit_light);
 *  - which region is a point in (rd_scene_region_at: rays to the first shape, whose side says
 *    the medium), and where does a camera ray start (rd_scene_camera_region);
 *  - which medium is at a point of a region (rd_scene_medium_at).
 * A region is named by the medium on its side of the surfaces (pbrt-v4's MediumInterface). */
#include "scene/rd_geom.h"

#include <string.h>

/* ---- Surfaces: what a ray meets, which region a point is in, shadow rays across interfaces -- */

int rd_scene_intersect(const rd_scene *s, ray3 r, double tmax, const rd_hit *from, rd_hit *h)
{
    if (s->geom) return rd_geom_intersect(s->geom, r, 0.0, tmax, from, h);
    double t;
    int i = rd_scene_hit_light(s, r, tmax, -1, &t);
    if (i < 0) return 0;
    memset(h, 0, sizeof *h);
    h->t = t;
    h->p = ray_at(r, t);
    h->shape = -1;
    h->light = i;
    h->medium_from = h->medium_to = -1;
    return 1;
}

/* The region the first shape met along r says x is in (sphere lights do not bound regions:
 * the ray steps past them). */
static int region_along(const rd_scene *s, ray3 r)
{
    rd_hit h, prev;
    const rd_hit *from = NULL;
    for (int k = 0; k < 64; k++) {
        if (!rd_geom_intersect(s->geom, r, 0.0, INFINITY, from, &h)) return s->fill_medium;
        if (h.shape >= 0) return h.medium_from;
        prev = h;
        from = &prev;
        r = rd_hit_spawn(&prev, r.d);
    }
    return s->fill_medium;
}

int rd_scene_camera_region(const rd_scene *s, ray3 r)
{
    if (!s->geom) return s->fill_medium;
    const vec3 c = s->camera.pos;
    if (s->camera.kind == RD_CAM_PERSPECTIVE && r.o.x == c.x && r.o.y == c.y && r.o.z == c.z)
        return s->camera_region;
    return rd_scene_region_at(s, r.o);
}

int rd_scene_region_at(const rd_scene *s, vec3 x)
{
    if (!s->geom) return s->fill_medium;
    /* Directions off every axis and diagonal, so the rays do not run along the edges of
     * axis-aligned meshes. A ray through a crack between two triangles (Embree's float test is
     * not watertight) would miss a surface and name the wrong side: two rays that agree
     * decide; a third settles a disagreement. */
    int a = region_along(s, (ray3){x, v3_norm(v3(0.5316, 0.6124, 0.5851))});
    int b = region_along(s, (ray3){x, v3_norm(v3(-0.7213, 0.1877, -0.4409))});
    if (a == b) return a;
    int c = region_along(s, (ray3){x, v3_norm(v3(0.2219, -0.8377, 0.3583))});
    return c == b ? b : a;
}

static int in_box(const rd_medium *m, vec3 x)
{
    return x.x >= m->bmin.x && x.y >= m->bmin.y && x.z >= m->bmin.z && x.x <= m->bmax.x &&
           x.y <= m->bmax.y && x.z <= m->bmax.z;
}

const rd_medium *rd_scene_medium_at(const rd_scene *s, int region, vec3 x)
{
    /* rd_scene.h "Surfaces in the transport": a bound region holds its medium; the open
     * region the box media within their bounds and the scene-wide medium elsewhere. */
    if (region != s->fill_medium)
        return region >= 0 && region < s->n_media && in_box(&s->media[region], x) ? &s->media[region] : NULL;
    for (int i = 0; i < s->n_media; i++) {
        const rd_medium *m = &s->media[i];
        if (m->bound) continue;
        if (in_box(m, x)) return m;
    }
    if (s->fill_medium >= 0 && in_box(&s->media[s->fill_medium], x)) return &s->media[s->fill_medium];
    return NULL;
}

const rd_medium *rd_scene_medium_at_point(const rd_scene *s, vec3 x)
{
    return rd_scene_medium_at(s, rd_scene_region_at(s, x), x);
}
int rd_scene_hit_light(const rd_scene *s, ray3 r, double tmax, int skip, double *t_hit)
{
    int hit = -1;
    double best = tmax;
    for (int k = 0; k < s->n_sphere_lights; k++) {
        int i = s->sphere_lights[k];
        if (i == skip) continue;
        double t = rd_light_hit(&s->lights[i], r);
        if (t < best) { best = t; hit = i; }
    }
    if (t_hit) *t_hit = hit >= 0 ? best : tmax;
    return hit;
}


vec3 rd_scene_behind(const rd_scene *s, int hit_light)
{
    if (hit_light >= 0) return s->lights[hit_light].value;
    vec3 L = s->background;
    for (int i = 0; i < s->n_lights; i++)
        if (s->lights[i].kind == RD_LIGHT_ENVIRONMENT) L = v3_add(L, s->lights[i].value);
    return L;
}
