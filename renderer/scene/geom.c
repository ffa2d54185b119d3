/* geom.c: one Embree 3 scene (C API) for every shape's triangles and every sphere light, so
 * that "what does this ray hit first" has one answer (rd_geom.h).
 *
 * Precision: Embree intersects in single precision. The renderer works in double, so
 *  - triangle hits are re-intersected in double (Moller & Trumbore 1997) against the same
 *    float vertices, giving t, the hit point and the barycentrics to double precision;
 *  - sphere lights are a user geometry whose callback intersects the caller's double ray
 *    (carried in an extended RTCIntersectContext, the pattern Embree's tutorials use) with
 *    rd_light_hit, the function the light code itself uses;
 *  - a ray leaving a hit skips the triangle it leaves (an intersection filter) and starts a
 *    little off the surface (rd_hit_spawn), so float round-off never makes it re-hit the
 *    surface it leaves. */
#include "scene/rd_geom.h"

#include <embree3/rtcore.h>
#include <stdlib.h>
#include <string.h>

/* What an Embree geometry is: a shape or a sphere light. */
typedef struct {
    int shape, light;
} geom_id;

struct rd_geom {
    RTCDevice device;
    RTCScene scene;
    const rd_scene *s;
    geom_id *ids;       /* by Embree geomID */
    unsigned n_ids;
    size_t n_triangles;
};

/* The per-query context: Embree's context first, then the double ray and what to skip. */
typedef struct {
    struct RTCIntersectContext ctx;
    const rd_geom *g;
    ray3 r;
    unsigned skip_geom, skip_prim; /* RTC_INVALID_GEOMETRY_ID: nothing to skip */
} query_ctx;

/* Embree's RTCRayN / RTCHitN are structures of arrays of N lanes (rtcore_ray.h accessors,
 * which are C++ only): field k of lane i is at index k N + i. */
#define RAYN_F(ray, k, N, i) (((float *)(ray))[(k) * (N) + (i)])
#define RAYN_TNEAR 3
#define RAYN_TFAR 8
#define HITN_U(hit, k, N, i) (((unsigned *)(hit))[(k) * (N) + (i)])
#define HITN_PRIM 5
#define HITN_GEOM 6

/* Intersection/occlusion filter of the triangle geometries: reject the triangle the ray
 * leaves from (exact: a ray leaving a flat triangle cannot meet that triangle again). */
static void skip_filter(const struct RTCFilterFunctionNArguments *args)
{
    const query_ctx *q = (const query_ctx *)args->context;
    if (q->skip_geom == RTC_INVALID_GEOMETRY_ID) return;
    for (unsigned i = 0; i < args->N; i++) {
        if (args->valid[i] == 0) continue;
        if (HITN_U(args->hit, HITN_GEOM, args->N, i) == q->skip_geom &&
            HITN_U(args->hit, HITN_PRIM, args->N, i) == q->skip_prim)
            args->valid[i] = 0;
    }
}

/* ---- sphere lights as a user geometry ---------------------------------------------------- */
static void sphere_bounds(const struct RTCBoundsFunctionArguments *args)
{
    const rd_light *l = args->geometryUserPtr;
    /* Widened by a relative 1e-6 so the float box holds the double sphere. */
    double r = l->radius * (1.0 + 1e-6) + 1e-6 * v3_maxc(v3(fabs(l->pos.x), fabs(l->pos.y), fabs(l->pos.z)));
    struct RTCBounds *b = args->bounds_o;
    b->lower_x = (float)(l->pos.x - r), b->lower_y = (float)(l->pos.y - r), b->lower_z = (float)(l->pos.z - r);
    b->upper_x = (float)(l->pos.x + r), b->upper_y = (float)(l->pos.y + r), b->upper_z = (float)(l->pos.z + r);
    b->lower_x = nextafterf(b->lower_x, -INFINITY), b->lower_y = nextafterf(b->lower_y, -INFINITY);
    b->lower_z = nextafterf(b->lower_z, -INFINITY), b->upper_x = nextafterf(b->upper_x, INFINITY);
    b->upper_y = nextafterf(b->upper_y, INFINITY), b->upper_z = nextafterf(b->upper_z, INFINITY);
}

/* The double-precision distance from the query's ray to light l, if it lies in the lane's
 * current (tnear, tfar). */
static int sphere_t(const query_ctx *q, unsigned geom, const rd_light *l, float tnear, float tfar, double *t)
{
    if (q->skip_geom == geom) return 0;
    double th = rd_light_hit(l, q->r); /* INFINITY from inside or when missed */
    if (!(th < INFINITY) || !(th > tnear) || !((float)th < tfar)) return 0;
    *t = th;
    return 1;
}

static void sphere_intersect(const struct RTCIntersectFunctionNArguments *args)
{
    const query_ctx *q = (const query_ctx *)args->context;
    const rd_light *l = args->geometryUserPtr;
    unsigned N = args->N;
    float *ray = (float *)args->rayhit;       /* RTCRayHitN: the ray's 12 fields of N lanes, */
    float *hit = (float *)args->rayhit + 12 * N; /* then the hit's */
    for (unsigned i = 0; i < N; i++) {
        if (args->valid[i] == 0) continue;
        double t;
        if (!sphere_t(q, args->geomID, l, RAYN_F(ray, RAYN_TNEAR, N, i), RAYN_F(ray, RAYN_TFAR, N, i), &t)) continue;
        RAYN_F(ray, RAYN_TFAR, N, i) = (float)t;
        vec3 n = v3_scale(v3_sub(ray_at(q->r, t), l->pos), 1.0 / l->radius);
        ((float *)hit)[0 * N + i] = (float)n.x; /* Ng */
        ((float *)hit)[1 * N + i] = (float)n.y;
        ((float *)hit)[2 * N + i] = (float)n.z;
        ((float *)hit)[3 * N + i] = 0.0f; /* u, v */
        ((float *)hit)[4 * N + i] = 0.0f;
        HITN_U(hit, HITN_PRIM, N, i) = args->primID;
        HITN_U(hit, HITN_GEOM, N, i) = args->geomID;
        HITN_U(hit, 7, N, i) = args->context->instID[0];
    }
}

static void sphere_occluded(const struct RTCOccludedFunctionNArguments *args)
{
    const query_ctx *q = (const query_ctx *)args->context;
    const rd_light *l = args->geometryUserPtr;
    unsigned N = args->N;
    for (unsigned i = 0; i < N; i++) {
        if (args->valid[i] == 0) continue;
        double t;
        if (sphere_t(q, args->geomID, l, RAYN_F(args->ray, RAYN_TNEAR, N, i), RAYN_F(args->ray, RAYN_TFAR, N, i), &t))
            RAYN_F(args->ray, RAYN_TFAR, N, i) = -INFINITY; /* Embree's "occluded" mark */
    }
}

/* ---- build --------------------------------------------------------------------------------- */
typedef struct { char *err; size_t n; } err_sink;
static void device_error(void *user, enum RTCError code, const char *str)
{
    err_sink *e = user;
    if (e->err && e->n && !e->err[0]) snprintf(e->err, e->n, "Embree error %d: %s", (int)code, str ? str : "");
}

rd_geom *rd_geom_build(const rd_scene *s, char *err, size_t errlen)
{
    char dummy[8];
    if (!err) err = dummy, errlen = sizeof dummy;
    err[0] = 0;
    rd_geom *g = calloc(1, sizeof *g);
    unsigned n = (unsigned)(s->n_shapes + s->n_sphere_lights);
    if (!g || !(g->ids = calloc(n ? n : 1, sizeof *g->ids))) {
        free(g);
        snprintf(err, errlen, "%s: out of memory building the ray-query scene", s->path);
        return NULL;
    }
    g->s = s;
    err_sink sink = {err, errlen};
    g->device = rtcNewDevice("verbose=0");
    if (!g->device) {
        snprintf(err, errlen, "%s: Embree could not create a device (error %d)", s->path, (int)rtcGetDeviceError(NULL));
        rd_geom_free(g);
        return NULL;
    }
    rtcSetDeviceErrorFunction(g->device, device_error, &sink);
    /* The skip of the triangle a ray leaves is an intersection filter (Debian builds Embree
     * with them; refuse a build without rather than risk self-hits). */
    if (!rtcGetDeviceProperty(g->device, RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED)) {
        snprintf(err, errlen, "this Embree was built without filter functions (EMBREE_FILTER_FUNCTION)");
        goto fail;
    }
    g->scene = rtcNewScene(g->device);
    if (!g->scene) goto fail;
    rtcSetSceneFlags(g->scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(g->scene, RTC_BUILD_QUALITY_HIGH);
    for (int i = 0; i < s->n_shapes; i++) {
        const rd_mesh *m = &s->shapes[i].mesh;
        RTCGeometry geo = rtcNewGeometry(g->device, RTC_GEOMETRY_TYPE_TRIANGLE);
        if (!geo) goto fail;
        float *vb = rtcSetNewGeometryBuffer(geo, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m->n_vertices);
        unsigned *ib = rtcSetNewGeometryBuffer(geo, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m->n_triangles);
        if (!vb || !ib) {
            rtcReleaseGeometry(geo);
            goto fail;
        }
        memcpy(vb, m->positions, 3 * m->n_vertices * sizeof(float));
        memcpy(ib, m->indices, 3 * m->n_triangles * sizeof(unsigned));
        rtcSetGeometryIntersectFilterFunction(geo, skip_filter);
        rtcSetGeometryOccludedFilterFunction(geo, skip_filter);
        rtcCommitGeometry(geo);
        unsigned id = rtcAttachGeometry(g->scene, geo);
        rtcReleaseGeometry(geo);
        if (id >= n) goto fail;
        g->ids[id].shape = i, g->ids[id].light = -1;
        g->n_triangles += m->n_triangles;
    }
    for (int k = 0; k < s->n_sphere_lights; k++) {
        int li = s->sphere_lights[k];
        RTCGeometry geo = rtcNewGeometry(g->device, RTC_GEOMETRY_TYPE_USER);
        if (!geo) goto fail;
        rtcSetGeometryUserPrimitiveCount(geo, 1);
        rtcSetGeometryUserData(geo, (void *)&s->lights[li]);
        rtcSetGeometryBoundsFunction(geo, sphere_bounds, (void *)&s->lights[li]);
        rtcSetGeometryIntersectFunction(geo, sphere_intersect);
        rtcSetGeometryOccludedFunction(geo, sphere_occluded);
        rtcCommitGeometry(geo);
        unsigned id = rtcAttachGeometry(g->scene, geo);
        rtcReleaseGeometry(geo);
        if (id >= n) goto fail;
        g->ids[id].shape = -1, g->ids[id].light = li;
    }
    g->n_ids = n;
    rtcCommitScene(g->scene);
    if (rtcGetDeviceError(g->device) != RTC_ERROR_NONE || err[0]) goto fail;
    rtcSetDeviceErrorFunction(g->device, NULL, NULL); /* the sink lives on this stack */
    return g;
fail: {
    char msg[RD_ERRLEN];
    snprintf(msg, sizeof msg, "%s", err[0] ? err : "Embree failed");
    snprintf(err, errlen, "%s: building the ray-query scene: %s", s->path, msg);
    rtcSetDeviceErrorFunction(g->device, NULL, NULL);
    rd_geom_free(g);
    return NULL;
}
}

void rd_geom_free(rd_geom *g)
{
    if (!g) return;
    if (g->scene) rtcReleaseScene(g->scene);
    if (g->device) rtcReleaseDevice(g->device);
    free(g->ids);
    free(g);
}

size_t rd_geom_triangles(const rd_geom *g) { return g ? g->n_triangles : 0; }

/* ---- queries ------------------------------------------------------------------------------- */
static void init_query(query_ctx *q, const rd_geom *g, ray3 r, const rd_hit *from)
{
    rtcInitIntersectContext(&q->ctx);
    q->g = g;
    q->r = r;
    q->skip_geom = q->skip_prim = RTC_INVALID_GEOMETRY_ID;
    if (!from) return;
    /* Find the Embree id of the shape or light the ray leaves (ids are few: shapes, then
     * sphere lights, in attach order). */
    for (unsigned id = 0; id < g->n_ids; id++)
        if ((from->shape >= 0 && g->ids[id].shape == from->shape) ||
            (from->light >= 0 && g->ids[id].light == from->light)) {
            q->skip_geom = id;
            q->skip_prim = from->shape >= 0 ? from->prim : 0;
            break;
        }
}

static void fill_ray(struct RTCRay *ray, ray3 r, double tmin, double tmax)
{
    ray->org_x = (float)r.o.x, ray->org_y = (float)r.o.y, ray->org_z = (float)r.o.z;
    ray->dir_x = (float)r.d.x, ray->dir_y = (float)r.d.y, ray->dir_z = (float)r.d.z;
    ray->tnear = (float)fmax(tmin, 0.0);
    ray->tfar = tmax >= 3.0e38 ? INFINITY : (float)tmax;
    ray->time = 0.0f;
    ray->mask = 0xffffffffu;
    ray->id = 0;
    ray->flags = 0;
}

/* Moller-Trumbore ray-triangle intersection in double (Moller & Trumbore 1997, JGT 2(1)):
 * t and the barycentrics (b1, b2) of the hit, without a range test on t; 0 when the ray is
 * parallel to the triangle's plane. */
static int triangle_double(ray3 r, vec3 p0, vec3 p1, vec3 p2, double *t, double *b1, double *b2)
{
    vec3 e1 = v3_sub(p1, p0), e2 = v3_sub(p2, p0);
    vec3 pv = v3_cross(r.d, e2);
    double det = v3_dot(e1, pv);
    if (det == 0.0) return 0;
    double inv = 1.0 / det;
    vec3 tv = v3_sub(r.o, p0);
    vec3 qv = v3_cross(tv, e1);
    *b1 = v3_dot(tv, pv) * inv;
    *b2 = v3_dot(r.d, qv) * inv;
    *t = v3_dot(e2, qv) * inv;
    return 1;
}

static vec3 vtx(const float *a, uint32_t i) { return v3(a[3 * (size_t)i], a[3 * (size_t)i + 1], a[3 * (size_t)i + 2]); }

int rd_geom_intersect(const rd_geom *g, ray3 r, double tmin, double tmax, const rd_hit *from,
                      rd_hit *h)
{
    if (!g || !(tmax > tmin)) return 0;
    query_ctx q;
    init_query(&q, g, r, from);
    struct RTCRayHit rh;
    fill_ray(&rh.ray, r, tmin, tmax);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(g->scene, &q.ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID || rh.hit.geomID >= g->n_ids) return 0;
    const geom_id *id = &g->ids[rh.hit.geomID];
    const rd_scene *s = g->s;
    h->shape = id->shape;
    h->light = id->light;
    h->prim = rh.hit.primID;
    h->t = rh.ray.tfar;
    if (id->light >= 0) {
        const rd_light *l = &s->lights[id->light];
        h->t = rd_light_hit(l, r); /* the double value the callback found */
        h->p = ray_at(r, h->t);
        h->ng = h->ns = v3_norm(v3_sub(h->p, l->pos));
        h->b1 = h->b2 = 0.0;
        h->medium_from = h->medium_to = -1; /* the path knows its own medium */
    } else {
        const rd_shape *sh = &s->shapes[id->shape];
        const rd_mesh *m = &sh->mesh;
        const uint32_t *v = m->indices + 3 * (size_t)h->prim;
        vec3 p0 = vtx(m->positions, v[0]), p1 = vtx(m->positions, v[1]), p2 = vtx(m->positions, v[2]);
        double t, b1, b2;
        /* Refine Embree's float t in double on the same float triangle; keep Embree's value in
         * the rare grazing case where the double solve disagrees about the range. */
        if (triangle_double(r, p0, p1, p2, &t, &b1, &b2) && t > tmin && t <= tmax) {
            h->t = t;
            h->b1 = b1, h->b2 = b2;
        } else {
            h->b1 = rh.hit.u, h->b2 = rh.hit.v;
        }
        h->p = ray_at(r, h->t);
        h->ng = v3_norm(v3_cross(v3_sub(p1, p0), v3_sub(p2, p0))); /* counter-clockwise front */
        h->ns = h->ng;
        if (m->normals) {
            double b0 = 1.0 - h->b1 - h->b2;
            vec3 n = v3_add(v3_scale(vtx(m->normals, v[0]), b0),
                            v3_add(v3_scale(vtx(m->normals, v[1]), h->b1), v3_scale(vtx(m->normals, v[2]), h->b2)));
            if (v3_len(n) > 1e-12) {
                n = v3_norm(n);
                h->ns = v3_dot(n, h->ng) < 0.0 ? v3_scale(n, -1.0) : n;
            }
        }
    }
    h->front = v3_dot(r.d, h->ng) < 0.0;
    if (h->shape >= 0) {
        const rd_shape *sh = &s->shapes[h->shape];
        h->medium_from = h->front ? sh->outside : sh->inside;
        h->medium_to = h->front ? sh->inside : sh->outside;
    }
    double pinf = fmax(fabs(h->p.x), fmax(fabs(h->p.y), fabs(h->p.z)));
    double oinf = fmax(fabs(r.o.x), fmax(fabs(r.o.y), fabs(r.o.z)));
    h->eps = 0x1p-16 * fmax(fmax(pinf, oinf), fmax(h->t, 0x1p-20));
    return 1;
}

int rd_geom_occluded(const rd_geom *g, ray3 r, double tmin, double tmax, const rd_hit *from)
{
    if (!g || !(tmax > tmin)) return 0;
    query_ctx q;
    init_query(&q, g, r, from);
    struct RTCRay ray;
    fill_ray(&ray, r, tmin, tmax);
    rtcOccluded1(g->scene, &q.ctx, &ray);
    return ray.tfar == -INFINITY;
}

ray3 rd_hit_spawn(const rd_hit *h, vec3 d)
{
    double side = v3_dot(d, h->ng) >= 0.0 ? 1.0 : -1.0;
    ray3 r = {v3_madd(h->p, h->ng, side * h->eps), d};
    return r;
}
