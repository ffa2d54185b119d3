/* beams.c: photon balls crossed by a ray segment (rd_beams.h), on Embree's ray-facing disc
 * points.
 *
 * The balls are held in the map's own frame (positions relative to its origin, float), so a
 * query ray is moved into that frame in double first. Each ball is a disc of its radius that
 * faces the ray, through its centre: the ray meets the disc exactly when it crosses the ball,
 * once, at the centre's projection (a sphere point would be reported twice, at its entry and,
 * when a filter rejects that, at its exit). The filter here rejects every hit, so traversal
 * goes on through all of them, and records each ball's chord, computed in double. Each disc is
 * DISC_PAD wider than its ball, so that Embree's test in float drops no crossing that the
 * chord in double keeps (a grazing one). A ball that meets [t0, t1] has its centre's projection in
 * [t0 - r, t1 + r]; Embree ignores a disc whose centre projects less than twice its radius
 * past the ray's origin (its curve self-intersection avoidance, factor 2 in this build), so
 * the query ray runs from t0 - 3 r_max to t1 + r_max (r_max with the pad); the chord is then
 * clipped to [t0, t1] here. */
#include "integrators/rd_beams.h"

#include <embree3/rtcore.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>

#define DISC_PAD (1.0 + 1.0 / 256.0) /* a disc's radius over its ball's (the head comment) */

struct rd_beams {
    RTCDevice device;
    RTCScene scene; /* NULL: no balls */
    const pm_map *map;
    int *index;     /* Embree's primitive id -> the map's photon (balls with no radius are left out) */
    const float *ball; /* Embree's vertex buffer: (x, y, z, r) per primitive */
    double r_max;   /* the largest disc's radius (a ball's, DISC_PAD wider) */
};

/* The per-query state, Embree's context first (the filter casts the context back). */
typedef struct {
    struct RTCIntersectContext ctx;
    const float *ball;  /* Embree's vertex buffer: (x, y, z, r) per primitive */
    const int *index;
    double o[3], d[3];  /* the query ray as Embree has it (float origin, in double) */
    double s0;          /* its start on the caller's ray: t = s0 + s */
    double t0, t1;
    rd_beam_hit *hits;
    int cap, kept;
    long long seen;     /* balls crossed so far */
    pcg32 *rng;
} cross_ctx;

/* Embree's RTCRayN / RTCHitN are structures of arrays of N lanes: field k of lane i at k N + i
 * (rtcore_ray.h's accessors are C++ only). */
#define HITN_PRIM(hit, N, i) (((unsigned *)(hit))[5 * (N) + (i)])

static void record(cross_ctx *q, unsigned prim)
{
    const float *v = q->ball + 4 * (size_t)prim;
    double oc[3] = {v[0] - q->o[0], v[1] - q->o[1], v[2] - q->o[2]};
    double sc = oc[0] * q->d[0] + oc[1] * q->d[1] + oc[2] * q->d[2]; /* the ball's centre, projected */
    double r = v[3] / DISC_PAD, perp2 = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - sc * sc;
    double h2 = r * r - perp2;
    if (!(h2 > 0.0)) return;
    double h = sqrt(h2), ta = q->s0 + sc - h, tb = q->s0 + sc + h;
    if (ta < q->t0) ta = q->t0;
    if (tb > q->t1) tb = q->t1;
    if (!(tb > ta)) return;
    rd_beam_hit hit = {q->index[prim], (float)ta, (float)tb};
    if (!(hit.tb > hit.ta)) return;
    q->seen++;
    if (q->kept < q->cap) {
        q->hits[q->kept++] = hit;
        return;
    }
    /* Reservoir sampling (Vitter's algorithm R): the seen-th ball replaces a kept one with
     * probability cap / seen, so the kept set is a uniform sample of all seen. */
    long long j = (long long)(pcg32_uniform(q->rng) * (double)q->seen);
    if (j < q->cap) q->hits[j] = hit;
}

static void cross_filter(const struct RTCFilterFunctionNArguments *args)
{
    cross_ctx *q = (cross_ctx *)args->context;
    for (unsigned i = 0; i < args->N; i++) {
        if (args->valid[i] == 0) continue;
        record(q, HITN_PRIM(args->hit, args->N, i));
        args->valid[i] = 0; /* go on to the next ball */
    }
}

rd_status rd_beams_new(rd_beams **out, int threads, char *err, size_t errlen)
{
    *out = NULL;
    rd_beams *b = calloc(1, sizeof *b);
    if (!b) {
        snprintf(err, errlen, "out of memory for the photon balls");
        return RD_ERR_NOMEM;
    }
    char config[64];
    if (threads > 0) snprintf(config, sizeof config, "verbose=0,threads=%d", threads);
    else snprintf(config, sizeof config, "verbose=0");
    b->device = rtcNewDevice(config);
    if (!b->device) {
        snprintf(err, errlen, "Embree could not create a device for the photon balls (error %d)",
                 (int)rtcGetDeviceError(NULL));
        free(b);
        return RD_ERR_INTERNAL;
    }
    if (!rtcGetDeviceProperty(b->device, RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED) ||
        !rtcGetDeviceProperty(b->device, RTC_DEVICE_PROPERTY_POINT_GEOMETRY_SUPPORTED)) {
        snprintf(err, errlen, "this Embree was built without filter functions or point geometry");
        rd_beams_free(b);
        return RD_ERR_INTERNAL;
    }
    *out = b;
    return RD_OK;
}

void rd_beams_free(rd_beams *b)
{
    if (!b) return;
    if (b->scene) rtcReleaseScene(b->scene);
    if (b->device) rtcReleaseDevice(b->device);
    free(b->index);
    free(b);
}

const pm_map *rd_beams_map(const rd_beams *b) { return b ? b->map : NULL; }

rd_status rd_beams_build(rd_beams *b, const pm_map *map, const float *radius, char *err, size_t errlen)
{
    if (b->scene) rtcReleaseScene(b->scene);
    b->scene = NULL;
    free(b->index);
    b->index = NULL;
    b->ball = NULL;
    b->map = map;
    b->r_max = 0.0;
    size_t n = pm_map_photon_count(map), used = 0;
    const pm_photon *ph = pm_map_photons(map);
    for (size_t k = 0; k < n; k++) used += radius[k] > 0.0f && isfinite(radius[k]);
    if (used == 0) return RD_OK;
    if (used > INT_MAX) {
        snprintf(err, errlen, "%zu photon balls: more than Embree's primitive ids hold", used);
        return RD_ERR_ARG;
    }
    b->index = malloc(used * sizeof *b->index);
    RTCScene scene = b->index ? rtcNewScene(b->device) : NULL;
    RTCGeometry geo = scene ? rtcNewGeometry(b->device, RTC_GEOMETRY_TYPE_DISC_POINT) : NULL;
    float *v = geo ? rtcSetNewGeometryBuffer(geo, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4,
                                             4 * sizeof(float), used)
                   : NULL;
    if (!v) {
        if (geo) rtcReleaseGeometry(geo);
        if (scene) rtcReleaseScene(scene);
        snprintf(err, errlen, "out of memory for %zu photon balls (Embree error %d)", used,
                 (int)rtcGetDeviceError(b->device));
        return RD_ERR_NOMEM;
    }
    /* The balls in the map's spatial order (pm_map_spatial_order), so that the balls one query
     * crosses lie near each other in Embree's buffer and in b->index (in photon order they were
     * scattered over it): renders on glass-fog 3-8% faster, the gain in Embree's traversal
     * (docs/benchmarks.md "Session 51"). The order Embree reports a query's balls in may
     * change with the layout, and with it the reservoir's picks and the estimate's: the images
     * are the same in distribution, not to the bit. */
    const int *order = pm_map_spatial_order(map);
    size_t j = 0;
    for (size_t i = 0; i < n; i++) {
        size_t k = order ? (size_t)order[i] : i;
        if (!(radius[k] > 0.0f && isfinite(radius[k]))) continue;
        v[4 * j + 0] = ph[k].pos[0];
        v[4 * j + 1] = ph[k].pos[1];
        v[4 * j + 2] = ph[k].pos[2];
        v[4 * j + 3] = (float)(radius[k] * DISC_PAD);
        if (v[4 * j + 3] > b->r_max) b->r_max = v[4 * j + 3];
        b->index[j++] = (int)k;
    }
    rtcSetGeometryIntersectFilterFunction(geo, cross_filter);
    rtcCommitGeometry(geo);
    rtcAttachGeometry(scene, geo);
    rtcReleaseGeometry(geo);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_MEDIUM);
    rtcCommitScene(scene);
    if (rtcGetDeviceError(b->device) != RTC_ERROR_NONE) {
        rtcReleaseScene(scene);
        snprintf(err, errlen, "Embree could not build the BVH of %zu photon balls", used);
        return RD_ERR_INTERNAL;
    }
    b->scene = scene;
    b->ball = v;
    return RD_OK;
}

int rd_beams_cross(const rd_beams *b, ray3 r, double t0, double t1, rd_beam_hit *hits, int cap,
                   pcg32 *rng, double *weight)
{
    *weight = 1.0;
    if (!b || !b->scene || !(t1 > t0) || cap < 1) return 0;
    cross_ctx q;
    rtcInitIntersectContext(&q.ctx);
    q.ball = b->ball;
    q.index = b->index;
    q.t0 = t0, q.t1 = t1;
    q.hits = hits, q.cap = cap, q.kept = 0, q.seen = 0, q.rng = rng;
    /* The ray in the map's frame, from 3 r_max before t0 to r_max past t1 (the head comment). */
    double org[3];
    pm_map_origin(b->map, org);
    q.s0 = t0 - 3.0 * b->r_max;
    vec3 o = ray_at(r, q.s0);
    struct RTCRayHit rh;
    rh.ray.org_x = (float)(o.x - org[0]), rh.ray.org_y = (float)(o.y - org[1]), rh.ray.org_z = (float)(o.z - org[2]);
    rh.ray.dir_x = (float)r.d.x, rh.ray.dir_y = (float)r.d.y, rh.ray.dir_z = (float)r.d.z;
    q.o[0] = rh.ray.org_x, q.o[1] = rh.ray.org_y, q.o[2] = rh.ray.org_z;
    q.d[0] = r.d.x, q.d[1] = r.d.y, q.d[2] = r.d.z;
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = (float)(t1 + b->r_max - q.s0);
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xffffffffu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(b->scene, &q.ctx, &rh);
    if (q.seen > q.kept) *weight = (double)q.seen / q.kept;
    return q.kept;
}
