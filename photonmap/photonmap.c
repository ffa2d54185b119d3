/* photonmap.c: the volume photon map (THEORY.md §3) as a data structure: photon and segment
 * storage, the origin, the FLANN single kd-tree over photon positions, and read access. The
 * queries and the density and radiance estimates are in pm_query.c, the .pmap file in pm_file.c
 * (docs/photonmap-format.md); the map's layout is in pm_internal.h.
 *
 * Notes on FLANN (checked against libflann 1.9.2, the Debian 12 package, and its headers; the
 * notes on distances, ties and coordinates are at the top of pm_query.c):
 *
 *  - Data lifetime. flann_build_index_float() wraps our array without copying it; the
 *    KDTreeSingleIndex (reorder = true, its default) then copies the points into its own
 *    reordered array and searches only that copy, but NNIndex keeps pointers into our rows.
 *    We therefore keep the contiguous xyz array alive exactly as long as the index.
 *  - Build order. The rows handed to FLANN are the photons in a spatial (Morton) order, not in
 *    index order: the tree over the same points is built with far fewer cache misses. perm maps
 *    a row back to its photon, and pm_query.c does so for every row FLANN returns.
 *  - Thread safety. Every C-API call starts with init_flann_parameters(), which sets FLANN's
 *    process-wide log level (skipped when log_level < 0: flann::log_verbosity ignores negative
 *    levels) and calls srand() (only when random_seed > 0). Queries pass log_level = -1 and
 *    random_seed = 0, so a query writes no shared state; the search itself
 *    (KDTreeSingleIndex::findNeighbors) is const and keeps its result set and distance
 *    scratch on the calling thread. Each call gets its own FLANNParameters on the stack,
 *    because FLANN takes them by non-const pointer. Concurrent queries are therefore safe.
 *    The log level is set to NONE (so FLANN never prints) once, before the first build
 *    (pm_flann_build, under std::call_once), and every call passes -1 after it, so builds of
 *    different maps may run at once too (rd_bake builds its two maps' trees so). FLANN's
 *    distance type is a process global too; nothing in photonmarch may call
 *    flann_set_distance_type().
 */
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "pm_internal.h"

/* ---------------------------------------------------------------------------------------- */
/* Small helpers                                                                              */

void pmi_set_err(char *err, size_t errlen, const char *fmt, ...)
{
    if (err == NULL || errlen == 0)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---------------------------------------------------------------------------------------- */
/* Creation, filling, read access                                                             */

pm_map *pm_map_new(void)
{
    return calloc(1, sizeof(pm_map));
}

static void drop_index(pm_map *map)
{
    if (map->index != NULL) {
        struct FLANNParameters p = pmi_flann_params();
        flann_free_index_float(map->index, &p);
        map->index = NULL;
    }
    free(map->xyz);
    map->xyz = NULL;
    free(map->perm);
    map->perm = NULL;
    map->index_bytes = 0;
    map->built = 0;
    map->ordered = 0;
}

void pm_map_free(pm_map *map)
{
    if (map == NULL)
        return;
    drop_index(map);
    free(map->ph);
    free(map->seg);
    free(map);
}

/* Validation shared by add and load: writes a reason into why and returns 0 when a record
 * is unusable. Every field must be finite (a NaN would poison the tree or the estimates). */
int pmi_check_photon(const pm_photon *p, char *why, size_t whylen)
{
    if (!pmi_finite3(p->pos)) {
        snprintf(why, whylen, "position is not finite (%g, %g, %g)", p->pos[0], p->pos[1],
                 p->pos[2]);
        return 0;
    }
    if (!pmi_finite3(p->dir)) {
        snprintf(why, whylen, "direction is not finite");
        return 0;
    }
    if (!pmi_finite3(p->power)) {
        snprintf(why, whylen, "power is not finite");
        return 0;
    }
    return 1;
}

int pmi_check_segment(const pm_segment *s, char *why, size_t whylen)
{
    if (!pmi_finite3(s->org)) {
        snprintf(why, whylen, "origin is not finite");
        return 0;
    }
    if (!pmi_finite3(s->dir)) {
        snprintf(why, whylen, "direction is not finite");
        return 0;
    }
    if (!isfinite(s->length) || s->length < 0.0f) {
        snprintf(why, whylen, "length %g is not a finite value >= 0", s->length);
        return 0;
    }
    if (!pmi_finite3(s->power)) {
        snprintf(why, whylen, "power is not finite");
        return 0;
    }
    return 1;
}

/* Make room for `extra` more elements of size `elem` (doubling growth). */
static int reserve(void **buf, size_t *cap, size_t count, size_t extra, size_t elem)
{
    if (extra > SIZE_MAX / elem - count)
        return 0;
    size_t need = count + extra;
    if (need <= *cap)
        return 1;
    size_t ncap = *cap * 2 > need ? *cap * 2 : need;
    if (ncap > SIZE_MAX / elem)
        ncap = need;
    void *p = realloc(*buf, ncap * elem);
    if (p == NULL)
        return 0;
    *buf = p;
    *cap = ncap;
    return 1;
}

void pmi_grow_bounds(pm_map *map, const pm_photon *ph, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            float v = ph[i].pos[a];
            if (map->nph == 0 && i == 0) {
                map->lo[a] = map->hi[a] = v;
            } else {
                if (v < map->lo[a])
                    map->lo[a] = v;
                if (v > map->hi[a])
                    map->hi[a] = v;
            }
        }
    }
}

pm_status pm_map_add_photons(pm_map *map, const pm_photon *ph, size_t n, char *err, size_t errlen)
{
    if (map == NULL || (ph == NULL && n > 0)) {
        pmi_set_err(err, errlen, "pm_map_add_photons: NULL argument");
        return PM_ERR_ARG;
    }
    if (n == 0)
        return PM_OK;
    /* FLANN counts rows in int, and indices are returned as int. */
    if (n > (size_t)INT_MAX - map->nph) {
        pmi_set_err(err, errlen, "pm_map_add_photons: %zu + %zu photons exceed the limit of %d",
                    map->nph, n, INT_MAX);
        return PM_ERR_ARG;
    }
    char why[128];
    for (size_t i = 0; i < n; i++) {
        if (!pmi_check_photon(&ph[i], why, sizeof why)) {
            pmi_set_err(err, errlen, "pm_map_add_photons: photon %zu: %s", i, why);
            return PM_ERR_ARG; /* nothing was added */
        }
    }
    if (!reserve((void **)&map->ph, &map->capph, map->nph, n, sizeof(pm_photon))) {
        pmi_set_err(err, errlen, "pm_map_add_photons: out of memory for %zu photons", map->nph + n);
        return PM_ERR_NOMEM;
    }
    drop_index(map); /* the tree no longer covers every photon */
    pmi_grow_bounds(map, ph, n);
    memcpy(map->ph + map->nph, ph, n * sizeof(pm_photon));
    map->nph += n;
    return PM_OK;
}

pm_status pm_map_add_segments(pm_map *map, const pm_segment *seg, size_t n, char *err,
                              size_t errlen)
{
    if (map == NULL || (seg == NULL && n > 0)) {
        pmi_set_err(err, errlen, "pm_map_add_segments: NULL argument");
        return PM_ERR_ARG;
    }
    if (n == 0)
        return PM_OK;
    char why[128];
    for (size_t i = 0; i < n; i++) {
        if (!pmi_check_segment(&seg[i], why, sizeof why)) {
            pmi_set_err(err, errlen, "pm_map_add_segments: segment %zu: %s", i, why);
            return PM_ERR_ARG;
        }
    }
    if (!reserve((void **)&map->seg, &map->capseg, map->nseg, n, sizeof(pm_segment))) {
        pmi_set_err(err, errlen, "pm_map_add_segments: out of memory for %zu segments",
                    map->nseg + n);
        return PM_ERR_NOMEM;
    }
    memcpy(map->seg + map->nseg, seg, n * sizeof(pm_segment));
    map->nseg += n; /* segments are not indexed: the build state is unchanged */
    return PM_OK;
}

pm_status pm_map_set_origin(pm_map *map, const double origin[3], char *err, size_t errlen)
{
    if (map == NULL || origin == NULL) {
        pmi_set_err(err, errlen, "pm_map_set_origin: NULL argument");
        return PM_ERR_ARG;
    }
    if (!pmi_finite3d(origin)) {
        pmi_set_err(err, errlen, "pm_map_set_origin: origin (%g, %g, %g) is not finite", origin[0],
                    origin[1], origin[2]);
        return PM_ERR_ARG;
    }
    if (map->nph > 0 || map->nseg > 0) {
        pmi_set_err(err, errlen, "pm_map_set_origin: the map already holds %zu photons and %zu "
                             "segments (set the origin before adding any)", map->nph, map->nseg);
        return PM_ERR_ARG;
    }
    memcpy(map->origin, origin, sizeof map->origin);
    return PM_OK;
}

void pm_map_origin(const pm_map *map, double origin[3])
{
    for (int a = 0; a < 3; a++)
        origin[a] = map ? map->origin[a] : 0.0;
}

/* The cell of v on a 2^PM_ORDER_BITS grid over [lo, hi], clamped (a NaN cannot occur: every
 * stored position is finite). */
static unsigned order_cell(float v, float lo, float hi)
{
    const unsigned top = (1u << PM_ORDER_BITS) - 1u;
    double f = hi > lo ? ((double)v - lo) / ((double)hi - lo) * (top + 1.0) : 0.0;
    return f <= 0.0 ? 0u : (f >= top ? top : (unsigned)f);
}

/* Bits of a spread apart to every third position (Morton 1966's interleaving). */
static unsigned spread3(unsigned a)
{
    unsigned r = 0;
    for (int b = 0; b < PM_ORDER_BITS; b++)
        r |= ((a >> b) & 1u) << (3 * b);
    return r;
}

/* map->perm: the photons in Morton (Z-curve) order of their cell on a 2^PM_ORDER_BITS grid per
 * axis over their bounds, by one counting sort (stable, so a cell keeps index order; the order
 * is a function of the positions alone). FLANN's build partitions the points through an index
 * array; fed in this order its passes touch nearby memory (the build of default.json's 1.7e6
 * photons took 2.3x less CPU, sort included: docs/benchmarks.md, issue 21). Returns 0 when out
 * of memory. */
static int spatial_order(pm_map *map)
{
    size_t n = map->nph, cells = (size_t)1 << (3 * PM_ORDER_BITS);
    float lo[3], hi[3];
    for (int a = 0; a < 3; a++)
        lo[a] = hi[a] = map->ph[0].pos[a];
    for (size_t i = 1; i < n; i++)
        for (int a = 0; a < 3; a++) {
            float v = map->ph[i].pos[a];
            lo[a] = v < lo[a] ? v : lo[a];
            hi[a] = v > hi[a] ? v : hi[a];
        }
    unsigned *key = malloc(n * sizeof *key);
    size_t *start = calloc(cells + 1, sizeof *start);
    if (key == NULL || start == NULL) {
        free(key);
        free(start);
        return 0;
    }
    for (size_t i = 0; i < n; i++) {
        const float *x = map->ph[i].pos;
        key[i] = spread3(order_cell(x[0], lo[0], hi[0])) | spread3(order_cell(x[1], lo[1], hi[1])) << 1 |
                 spread3(order_cell(x[2], lo[2], hi[2])) << 2;
        start[key[i] + 1]++;
    }
    for (size_t c = 0; c < cells; c++)
        start[c + 1] += start[c];
    for (size_t i = 0; i < n; i++)
        map->perm[start[key[i]]++] = (int)i;
    free(key);
    free(start);
    return 1;
}

pm_status pm_map_order(pm_map *map, char *err, size_t errlen)
{
    if (map == NULL) {
        pmi_set_err(err, errlen, "pm_map_order: NULL map");
        return PM_ERR_ARG;
    }
    double t0 = now_seconds();
    drop_index(map);
    if (map->nph > 0) {
        map->perm = malloc(map->nph * sizeof(int));
        if (map->perm == NULL || !spatial_order(map)) {
            free(map->perm);
            map->perm = NULL;
            pmi_set_err(err, errlen, "pm_map_order: out of memory for the order of %zu photons", map->nph);
            return PM_ERR_NOMEM;
        }
    }
    map->ordered = 1;
    map->index_bytes = map->nph * sizeof(int); /* the order, for pm_map_memory_bytes */
    map->build_seconds = now_seconds() - t0;
    return PM_OK;
}

pm_status pm_map_build(pm_map *map, char *err, size_t errlen)
{
    if (map == NULL) {
        pmi_set_err(err, errlen, "pm_map_build: NULL map");
        return PM_ERR_ARG;
    }
    double t0 = now_seconds();
    drop_index(map);
    if (map->nph == 0) { /* FLANN cannot build on 0 rows: an empty map answers 0 found */
        map->built = 1;
        map->build_seconds = now_seconds() - t0;
        return PM_OK;
    }
    /* The order first: its scratch is freed before the positions' copy is made. */
    map->perm = malloc(map->nph * sizeof(int));
    if (map->perm != NULL && spatial_order(map))
        map->xyz = malloc(map->nph * 3 * sizeof(float));
    if (map->xyz == NULL) {
        free(map->xyz);
        free(map->perm);
        map->xyz = NULL;
        map->perm = NULL;
        pmi_set_err(err, errlen, "pm_map_build: out of memory for %zu positions", map->nph);
        return PM_ERR_NOMEM;
    }
    for (size_t j = 0; j < map->nph; j++)
        memcpy(map->xyz + 3 * j, map->ph[map->perm[j]].pos, 3 * sizeof(float));

    struct FLANNParameters p = pmi_flann_params();
    float speedup = 0.0f;
    pm_flann_fault fault;
    map->index = pm_flann_build(map->xyz, (int)map->nph, 3, &speedup, &p, &fault);
    if (map->index == NULL) {
        free(map->xyz);
        map->xyz = NULL;
        free(map->perm);
        map->perm = NULL;
        if (fault.nomem) {
            pmi_set_err(err, errlen,
                        "pm_map_build: out of memory for the FLANN kd-tree of %zu photons",
                        map->nph);
            return PM_ERR_NOMEM;
        }
        pmi_set_err(err, errlen, "pm_map_build: FLANN failed to build a kd-tree on %zu photons%s%s",
                    map->nph, fault.what[0] ? ": " : "", fault.what);
        return PM_ERR_INDEX;
    }
    /* flann_used_memory counts tree nodes and the permutation; add FLANN's reordered copy
     * of the points (12 B), its row-pointer table (8 B), our xyz array (12 B) and our row to
     * photon table (4 B). */
    int used = flann_used_memory_float(map->index);
    map->index_bytes = (used > 0 ? (size_t)used : 0) +
                       map->nph * (3 * sizeof(float) + sizeof(float *) + 3 * sizeof(float) + sizeof(int));
    map->built = 1;
    map->build_seconds = now_seconds() - t0;
    return PM_OK;
}

size_t pm_map_photon_count(const pm_map *map)
{
    return map ? map->nph : 0;
}

const pm_photon *pm_map_photons(const pm_map *map)
{
    return map ? map->ph : NULL;
}

size_t pm_map_segment_count(const pm_map *map)
{
    return map ? map->nseg : 0;
}

const pm_segment *pm_map_segments(const pm_map *map)
{
    return map ? map->seg : NULL;
}

void pm_map_bounds(const pm_map *map, float lo[3], float hi[3])
{
    for (int a = 0; a < 3; a++) {
        lo[a] = hi[a] = 0.0f;
        if (map == NULL || map->nph == 0)
            continue;
        /* world = origin + offset in double, then rounded outward to float */
        double l = map->origin[a] + (double)map->lo[a], h = map->origin[a] + (double)map->hi[a];
        lo[a] = (float)l;
        hi[a] = (float)h;
        if ((double)lo[a] > l)
            lo[a] = nextafterf(lo[a], -INFINITY);
        if ((double)hi[a] < h)
            hi[a] = nextafterf(hi[a], INFINITY);
    }
}

size_t pm_map_memory_bytes(const pm_map *map)
{
    if (map == NULL)
        return 0;
    return sizeof(pm_map) + map->capph * sizeof(pm_photon) + map->capseg * sizeof(pm_segment) +
           map->index_bytes;
}

double pm_map_build_seconds(const pm_map *map)
{
    return map ? map->build_seconds : 0.0;
}

const int *pm_map_spatial_order(const pm_map *map)
{
    return map && (map->built || map->ordered) ? map->perm : NULL;
}

