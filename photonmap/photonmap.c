/* photonmap.c: the volume photon map (THEORY.md §3) as a data structure: photon and segment
 * storage, the FLANN single kd-tree over photon positions, exact k-NN and radius queries, the
 * density and radiance estimates, and the .pmap file (docs/photonmap-format.md).
 *
 * Notes on FLANN (checked against libflann 1.9.2, the Debian 12 package, and its headers):
 *
 *  - Data lifetime. flann_build_index_float() wraps our array without copying it; the
 *    KDTreeSingleIndex (reorder = true, its default) then copies the points into its own
 *    reordered array and searches only that copy, but NNIndex keeps pointers into our rows.
 *    We therefore keep the contiguous xyz array alive exactly as long as the index.
 *  - Thread safety. Every C-API call starts with init_flann_parameters(), which sets FLANN's
 *    process-wide log level (skipped when log_level < 0: flann::log_verbosity ignores negative
 *    levels) and calls srand() (only when random_seed > 0). Queries pass log_level = -1 and
 *    random_seed = 0, so a query writes no shared state; the search itself
 *    (KDTreeSingleIndex::findNeighbors) is const and keeps its result set and distance
 *    scratch on the calling thread. Each call gets its own FLANNParameters on the stack,
 *    because FLANN takes them by non-const pointer. Concurrent queries are therefore safe.
 *    The build sets the log level to NONE (so FLANN never prints): that one global int write
 *    is why building is documented as single-threaded. FLANN's distance type is a process
 *    global too; nothing in photonmarch may call flann_set_distance_type().
 *  - Distances are squared L2 in float, summed as ((dx*dx + dy*dy) + dz*dz).
 *  - Exactness and ties. KDTREE_SINGLE with eps = 0 is an exact search, except that its cell
 *    lower bounds are float sums, so a photon whose distance equals the current k-th distance
 *    to within a few float ulps may be missed or kept arbitrarily. We make every answer
 *    canonical: the k nearest in (dist2, index) order. FLANN is asked for k+1 neighbours; if
 *    the (k+1)-th is clearly farther than the k-th (by more than PM_TIE_REL relative), the k
 *    are the unique answer; otherwise every photon within the k-th distance is collected with
 *    a slightly enlarged radius search and sorted (first_within). With random positions this
 *    fallback runs for about 1.5 PM_TIE_REL k of the queries (0.8% at k = 256, measured);
 *    with duplicate photons it is what makes the answer independent of the tree.
 *  - Coordinates. FLANN indexes the stored float positions, which are offsets from the map's
 *    origin (double). A query point arrives in world coordinates as double; to_local()
 *    subtracts the origin in double and rounds once to float, so a scene 1e5 m from the world
 *    origin is searched with the precision of one near it.
 */
#include "photonmap.h"

#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "pm_flann_guard.h" /* FLANN's C API with its exceptions caught */
#include <omp.h>

#define PM_PI 3.14159265358979323846

/* kd-tree leaf size. bench/bench_photonmap.c at 1e6 clustered photons: 16 answered k = 16..256
 * 7-15% faster than 8 or 12 and as fast as 24, with 81 B/photon (12: 84, 8: 89). */
#ifndef PM_LEAF_MAX_SIZE
#define PM_LEAF_MAX_SIZE 16
#endif

/* Relative slack covering FLANN's float cell bounds (tree depth ~25, a few ulps per level,
 * so < 4e-6 relative); see the notes at the top. */
#define PM_TIE_REL 2e-5f

/* Queries with k+1 <= PM_STACK_K neighbours use stack scratch; larger ones malloc. */
#define PM_STACK_K 257

/* Batch queries are handed to FLANN in chunks of this many rows (amortises per-call cost). */
#define PM_BATCH_CHUNK 64

struct pm_map {
    double origin[3]; /* world position that stored positions are relative to */
    pm_photon *ph; /* nph photons, room for capph */
    size_t nph, capph;
    pm_segment *seg; /* nseg segments, room for capseg */
    size_t nseg, capseg;
    float lo[3], hi[3]; /* bounds of photon positions; zeros while nph == 0 */
    int built;          /* 1 after pm_map_build, back to 0 after any photon add */
    float *xyz;         /* nph x 3 positions handed to FLANN; lives as long as index */
    flann_index_t index; /* NULL when not built or when the map has no photons */
    size_t index_bytes;  /* approximate memory of index + xyz */
    double build_seconds;
};

/* ---------------------------------------------------------------------------------------- */
/* Small helpers                                                                              */

#ifdef __GNUC__
__attribute__((format(printf, 3, 4)))
#endif
static void set_err(char *err, size_t errlen, const char *fmt, ...)
{
    if (err == NULL || errlen == 0)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

static int finite3(const float v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

/* World point (double) to the float offset from the origin that FLANN indexes: the difference
 * is taken in double, then rounded once. */
static void to_local(const pm_map *map, const double x[3], float q[3])
{
    for (int a = 0; a < 3; a++)
        q[a] = (float)(x[a] - map->origin[a]);
}

static int finite3d(const double v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* FLANN parameters for an exact single kd-tree, returned by value so that every call owns its
 * copy. log_level -1 makes init_flann_parameters() leave FLANN's global log level alone. */
static struct FLANNParameters flann_params(int for_build)
{
    struct FLANNParameters p;
    memset(&p, 0, sizeof p);
    p.algorithm = FLANN_INDEX_KDTREE_SINGLE;
    p.checks = FLANN_CHECKS_UNLIMITED;
    p.eps = 0.0f;
    p.sorted = 1;
    p.max_neighbors = -1;
    p.cores = 1;
    p.trees = 1;
    p.leaf_max_size = PM_LEAF_MAX_SIZE;
    p.log_level = for_build ? FLANN_LOG_NONE : (enum flann_log_level_t)-1;
    p.random_seed = 0; /* no srand() */
    return p;
}

/* Largest squared distance that may still tie with t after FLANN's rounding. */
static float tie_slack(float t)
{
    return t + t * PM_TIE_REL + 1e-30f;
}

/* Sort parallel arrays by (d2, idx), insertion sort: FLANN already returns them sorted by d2,
 * so only runs of equal distances move and this is linear in practice. */
static void sort_pairs(int *idx, float *d2, int n)
{
    for (int i = 1; i < n; i++) {
        int ki = idx[i];
        float kd = d2[i];
        int j = i - 1;
        while (j >= 0 && (d2[j] > kd || (d2[j] == kd && idx[j] > ki))) {
            idx[j + 1] = idx[j];
            d2[j + 1] = d2[j];
            j--;
        }
        idx[j + 1] = ki;
        d2[j + 1] = kd;
    }
}

typedef struct {
    float d2;
    int idx;
} pm_hit;

static int hit_cmp(const void *a, const void *b)
{
    const pm_hit *x = a, *y = b;
    if (x->d2 != y->d2)
        return x->d2 < y->d2 ? -1 : 1;
    return (x->idx > y->idx) - (x->idx < y->idx);
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
        struct FLANNParameters p = flann_params(0);
        flann_free_index_float(map->index, &p);
        map->index = NULL;
    }
    free(map->xyz);
    map->xyz = NULL;
    map->index_bytes = 0;
    map->built = 0;
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
static int check_photon(const pm_photon *p, char *why, size_t whylen)
{
    if (!finite3(p->pos)) {
        snprintf(why, whylen, "position is not finite (%g, %g, %g)", p->pos[0], p->pos[1],
                 p->pos[2]);
        return 0;
    }
    if (!finite3(p->dir)) {
        snprintf(why, whylen, "direction is not finite");
        return 0;
    }
    if (!finite3(p->power)) {
        snprintf(why, whylen, "power is not finite");
        return 0;
    }
    return 1;
}

static int check_segment(const pm_segment *s, char *why, size_t whylen)
{
    if (!finite3(s->org)) {
        snprintf(why, whylen, "origin is not finite");
        return 0;
    }
    if (!finite3(s->dir)) {
        snprintf(why, whylen, "direction is not finite");
        return 0;
    }
    if (!isfinite(s->length) || s->length < 0.0f) {
        snprintf(why, whylen, "length %g is not a finite value >= 0", s->length);
        return 0;
    }
    if (!finite3(s->power)) {
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

static void grow_bounds(pm_map *map, const pm_photon *ph, size_t n)
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
        set_err(err, errlen, "pm_map_add_photons: NULL argument");
        return PM_ERR_ARG;
    }
    if (n == 0)
        return PM_OK;
    /* FLANN counts rows in int, and indices are returned as int. */
    if (n > (size_t)INT_MAX - map->nph) {
        set_err(err, errlen, "pm_map_add_photons: %zu + %zu photons exceed the limit of %d",
                map->nph, n, INT_MAX);
        return PM_ERR_ARG;
    }
    char why[128];
    for (size_t i = 0; i < n; i++) {
        if (!check_photon(&ph[i], why, sizeof why)) {
            set_err(err, errlen, "pm_map_add_photons: photon %zu: %s", i, why);
            return PM_ERR_ARG; /* nothing was added */
        }
    }
    if (!reserve((void **)&map->ph, &map->capph, map->nph, n, sizeof(pm_photon))) {
        set_err(err, errlen, "pm_map_add_photons: out of memory for %zu photons", map->nph + n);
        return PM_ERR_NOMEM;
    }
    drop_index(map); /* the tree no longer covers every photon */
    grow_bounds(map, ph, n);
    memcpy(map->ph + map->nph, ph, n * sizeof(pm_photon));
    map->nph += n;
    return PM_OK;
}

pm_status pm_map_add_segments(pm_map *map, const pm_segment *seg, size_t n, char *err,
                              size_t errlen)
{
    if (map == NULL || (seg == NULL && n > 0)) {
        set_err(err, errlen, "pm_map_add_segments: NULL argument");
        return PM_ERR_ARG;
    }
    if (n == 0)
        return PM_OK;
    char why[128];
    for (size_t i = 0; i < n; i++) {
        if (!check_segment(&seg[i], why, sizeof why)) {
            set_err(err, errlen, "pm_map_add_segments: segment %zu: %s", i, why);
            return PM_ERR_ARG;
        }
    }
    if (!reserve((void **)&map->seg, &map->capseg, map->nseg, n, sizeof(pm_segment))) {
        set_err(err, errlen, "pm_map_add_segments: out of memory for %zu segments",
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
        set_err(err, errlen, "pm_map_set_origin: NULL argument");
        return PM_ERR_ARG;
    }
    if (!finite3d(origin)) {
        set_err(err, errlen, "pm_map_set_origin: origin (%g, %g, %g) is not finite", origin[0],
                origin[1], origin[2]);
        return PM_ERR_ARG;
    }
    if (map->nph > 0 || map->nseg > 0) {
        set_err(err, errlen, "pm_map_set_origin: the map already holds %zu photons and %zu "
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

pm_status pm_map_build(pm_map *map, char *err, size_t errlen)
{
    if (map == NULL) {
        set_err(err, errlen, "pm_map_build: NULL map");
        return PM_ERR_ARG;
    }
    double t0 = now_seconds();
    drop_index(map);
    if (map->nph == 0) { /* FLANN cannot build on 0 rows: an empty map answers 0 found */
        map->built = 1;
        map->build_seconds = now_seconds() - t0;
        return PM_OK;
    }
    map->xyz = malloc(map->nph * 3 * sizeof(float));
    if (map->xyz == NULL) {
        set_err(err, errlen, "pm_map_build: out of memory for %zu positions", map->nph);
        return PM_ERR_NOMEM;
    }
    for (size_t i = 0; i < map->nph; i++)
        memcpy(map->xyz + 3 * i, map->ph[i].pos, 3 * sizeof(float));

    struct FLANNParameters p = flann_params(1);
    float speedup = 0.0f;
    pm_flann_fault fault;
    map->index = pm_flann_build(map->xyz, (int)map->nph, 3, &speedup, &p, &fault);
    if (map->index == NULL) {
        free(map->xyz);
        map->xyz = NULL;
        if (fault.nomem) {
            set_err(err, errlen, "pm_map_build: out of memory for the FLANN kd-tree of %zu photons",
                    map->nph);
            return PM_ERR_NOMEM;
        }
        set_err(err, errlen, "pm_map_build: FLANN failed to build a kd-tree on %zu photons%s%s",
                map->nph, fault.what[0] ? ": " : "", fault.what);
        return PM_ERR_INDEX;
    }
    /* flann_used_memory counts tree nodes and the permutation; add FLANN's reordered copy
     * of the points (12 B), its row-pointer table (8 B) and our xyz array (12 B). */
    int used = flann_used_memory_float(map->index);
    map->index_bytes = (used > 0 ? (size_t)used : 0) +
                       map->nph * (3 * sizeof(float) + sizeof(float *) + 3 * sizeof(float));
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

/* ---------------------------------------------------------------------------------------- */
/* Queries                                                                                    */

/* Every photon with dist2 <= t, sorted by (dist2, idx): a FLANN radius search with the slack
 * radius (first counting, then fetching exactly that many), filtered exactly. Returns the
 * number found and a malloc'ed array in *out, or -1 on failure. */
static int collect_within(const pm_map *map, const float x[3], float t, pm_hit **out)
{
    struct FLANNParameters p = flann_params(0);
    float q[3] = {x[0], x[1], x[2]};
    float rs = tie_slack(t);
    int dummy_i;
    float dummy_d;
    /* max_nn = 0 makes FLANN only count the photons inside the radius. */
    int c = pm_flann_radius(map->index, q, &dummy_i, &dummy_d, 0, rs, &p, NULL);
    if (c < 0)
        return -1;
    size_t cn = c > 0 ? (size_t)c : 1;
    int *fi = malloc(cn * sizeof(int));
    float *fd = malloc(cn * sizeof(float));
    pm_hit *h = malloc(cn * sizeof(pm_hit));
    int n = -1;
    if (fi != NULL && fd != NULL && h != NULL) {
        int got = c > 0 ? pm_flann_radius(map->index, q, fi, fd, c, rs, &p, NULL) : 0;
        if (got >= 0) {
            if (got > c)
                got = c;
            n = 0;
            for (int i = 0; i < got; i++) {
                if (fi[i] >= 0 && fd[i] <= t) {
                    h[n].d2 = fd[i];
                    h[n].idx = fi[i];
                    n++;
                }
            }
            qsort(h, (size_t)n, sizeof(pm_hit), hit_cmp);
        }
    }
    free(fi);
    free(fd);
    if (n < 0) {
        free(h);
        return -1;
    }
    *out = h;
    return n;
}

/* The first min(n, want) photons of the canonical list of every photon with dist2 <= t
 * (collect_within). Returns how many were written, or -1. */
static int first_within(const pm_map *map, const float x[3], float t, int want, int *idx,
                        float *dist2)
{
    pm_hit *h = NULL;
    int n = collect_within(map, x, t, &h);
    if (n < 0)
        return -1;
    if (n > want)
        n = want;
    for (int j = 0; j < n; j++) {
        idx[j] = h[j].idx;
        dist2[j] = h[j].d2;
    }
    free(h);
    return n;
}

/* Second step of a k-NN query. fi/fd hold FLANN's kq nearest for point x (kq = want + 1 when
 * the map has more than `want` photons, else kq = want == count; unfilled slots are -1).
 * Writes the `want` nearest in (dist2, idx) order to idx/dist2. Returns want, or -1. */
static int finish_knn(const pm_map *map, const float x[3], int want, int *fi, float *fd,
                      int kq, int *idx, float *dist2)
{
    int n = 0;
    while (n < kq && fi[n] >= 0)
        n++;
    if (n < want) /* an exact search always fills kq <= count slots */
        return -1;
    sort_pairs(fi, fd, n);
    if (n > want) {
        float t = fd[want - 1];
        if (!(fd[want] > tie_slack(t))) { /* the (want+1)-th may tie with the want-th */
            /* At least `want` photons lie within t, so this writes `want` of them. */
            int got = first_within(map, x, t, want, idx, dist2);
            if (got == want || got < 0)
                return got;
            /* not reached if the slack analysis holds; FLANN's answer is still exact up to
             * the order of photons at distance t */
        }
    }
    memcpy(idx, fi, (size_t)want * sizeof(int));
    memcpy(dist2, fd, (size_t)want * sizeof(float));
    return want;
}

/* Scratch for one query of up to kq neighbours: on the stack when small. */
typedef struct {
    int si[PM_STACK_K];
    float sd[PM_STACK_K];
    int *fi;
    float *fd;
} pm_scratch;

static int scratch_get(pm_scratch *s, int kq)
{
    if (kq <= PM_STACK_K) {
        s->fi = s->si;
        s->fd = s->sd;
        return 1;
    }
    s->fi = malloc((size_t)kq * sizeof(int));
    s->fd = malloc((size_t)kq * sizeof(float));
    if (s->fi == NULL || s->fd == NULL) {
        free(s->fi);
        free(s->fd);
        return 0;
    }
    return 1;
}

static void scratch_put(pm_scratch *s)
{
    if (s->fi != s->si) {
        free(s->fi);
        free(s->fd);
    }
}

static void fill_empty(int *fi, float *fd, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        fi[i] = -1;
        fd[i] = INFINITY;
    }
}

/* k-NN for a point already in map-local float coordinates (see to_local). */
static int knn_local(const pm_map *map, const float x[3], int k, int *idx, float *dist2)
{
    if (idx == NULL || dist2 == NULL || k <= 0 || !map->built || !finite3(x))
        return -1;
    if (map->nph == 0)
        return 0;
    int count = (int)map->nph;
    int want = k < count ? k : count;
    int kq = want < count ? want + 1 : want; /* one extra to detect a tie at the k-th */

    pm_scratch s;
    if (!scratch_get(&s, kq))
        return -1;
    fill_empty(s.fi, s.fd, (size_t)kq);
    struct FLANNParameters p = flann_params(0);
    float q[3] = {x[0], x[1], x[2]};
    int r = -1;
    if (pm_flann_knn(map->index, q, 1, s.fi, s.fd, kq, &p, NULL) == 0)
        r = finish_knn(map, x, want, s.fi, s.fd, kq, idx, dist2);
    scratch_put(&s);
    return r;
}

int pm_map_knn(const pm_map *map, const double world[3], int k, int *idx, float *dist2)
{
    if (map == NULL || world == NULL || !finite3d(world))
        return -1;
    float x[3];
    to_local(map, world, x);
    return knn_local(map, x, k, idx, dist2);
}

int pm_map_radius(const pm_map *map, const double world[3], float r, int max, int *idx,
                  float *dist2)
{
    if (map == NULL || world == NULL || idx == NULL || dist2 == NULL || max <= 0 ||
        !map->built || !finite3d(world) || !(r >= 0.0f))
        return -1;
    float x[3];
    to_local(map, world, x);
    if (!finite3(x))
        return -1;
    if (map->nph == 0)
        return 0;
    int count = (int)map->nph;
    float r2 = r * r;
    int m = max < count ? max : count;
    int cap = m < count ? m + 1 : m; /* one extra to detect a tie at the max-th */

    pm_scratch s;
    if (!scratch_get(&s, cap))
        return -1;
    fill_empty(s.fi, s.fd, (size_t)cap);
    struct FLANNParameters p = flann_params(0);
    float q[3] = {x[0], x[1], x[2]};
    int out = -1;
    /* FLANN keeps the cap nearest photons strictly inside the slack radius. */
    int c = pm_flann_radius(map->index, q, s.fi, s.fd, cap, tie_slack(r2), &p, NULL);
    if (c >= 0) {
        int n = c < cap ? c : cap;
        sort_pairs(s.fi, s.fd, n);
        int within = 0; /* photons with dist2 <= r^2 (inclusive), a prefix after sorting */
        while (within < n && s.fd[within] <= r2)
            within++;
        if (within > m) {
            /* all cap = m+1 lie within r: the answer is the m nearest, as for k-NN */
            out = finish_knn(map, x, m, s.fi, s.fd, cap, idx, dist2);
        } else if (n == cap && cap > m) {
            /* Saturated, yet the (m+1)-th lies in the thin shell between r^2 and the slack
             * radius: FLANN may have pruned a photon at distance ~r; collect them all. */
            out = first_within(map, x, r2, m, idx, dist2);
        } else {
            /* FLANN returned every photon inside the slack radius. */
            memcpy(idx, s.fi, (size_t)within * sizeof(int));
            memcpy(dist2, s.fd, (size_t)within * sizeof(float));
            out = within;
        }
    }
    scratch_put(&s);
    return out;
}

pm_status pm_map_knn_batch(const pm_map *map, const double *queries, size_t nq, int k, int *idx,
                           float *dist2, int threads, char *err, size_t errlen)
{
    if (map == NULL || (nq > 0 && (queries == NULL || idx == NULL || dist2 == NULL))) {
        set_err(err, errlen, "pm_map_knn_batch: NULL argument");
        return PM_ERR_ARG;
    }
    if (k <= 0 || threads < 0) {
        set_err(err, errlen, "pm_map_knn_batch: bad k = %d or threads = %d", k, threads);
        return PM_ERR_ARG;
    }
    if (!map->built) {
        set_err(err, errlen, "pm_map_knn_batch: map is not built (call pm_map_build)");
        return PM_ERR_ARG;
    }
    if (nq > SIZE_MAX / (size_t)k / sizeof(float)) {
        set_err(err, errlen, "pm_map_knn_batch: %zu queries x k = %d overflows", nq, k);
        return PM_ERR_ARG;
    }
    for (size_t i = 0; i < nq; i++) {
        float q[3];
        if (finite3d(queries + 3 * i))
            to_local(map, queries + 3 * i, q);
        if (!finite3d(queries + 3 * i) || !finite3(q)) {
            set_err(err, errlen, "pm_map_knn_batch: query %zu is not finite", i);
            return PM_ERR_ARG;
        }
    }
    size_t ks = (size_t)k;
    if (map->nph == 0) {
        fill_empty(idx, dist2, nq * ks);
        return PM_OK;
    }
    int count = (int)map->nph;
    int want = k < count ? k : count;
    int kq = want < count ? want + 1 : want;
    int nt = threads > 0 ? threads : omp_get_max_threads();
    size_t nchunks = (nq + PM_BATCH_CHUNK - 1) / PM_BATCH_CHUNK;
    int failed = 0; /* 1: out of memory, 2: FLANN error */

    /* Each chunk of rows is independent, so the answer does not depend on the thread count. */
#pragma omp parallel num_threads(nt)
    {
        size_t cells = (size_t)PM_BATCH_CHUNK * (size_t)kq;
        int *fi = malloc(cells * sizeof(int));
        float *fd = malloc(cells * sizeof(float));
        float ql[3 * PM_BATCH_CHUNK]; /* the chunk's query rows in map-local float */
        if (fi == NULL || fd == NULL) {
#pragma omp atomic write
            failed = 1;
        }
        struct FLANNParameters p = flann_params(0);
#pragma omp for schedule(dynamic, 1)
        for (size_t c = 0; c < nchunks; c++) {
            int bad;
#pragma omp atomic read
            bad = failed;
            if (bad || fi == NULL || fd == NULL)
                continue;
            size_t q0 = c * PM_BATCH_CHUNK;
            size_t nb = nq - q0 < PM_BATCH_CHUNK ? nq - q0 : PM_BATCH_CHUNK;
            fill_empty(fi, fd, nb * (size_t)kq);
            for (size_t j = 0; j < nb; j++)
                to_local(map, queries + 3 * (q0 + j), ql + 3 * j);
            pm_flann_fault fault;
            if (pm_flann_knn(map->index, ql, (int)nb, fi, fd, kq, &p, &fault) != 0) {
                /* FLANN's bad_alloc is out of memory (1), like our scratch */
#pragma omp atomic write
                failed = fault.nomem ? 1 : 2;
                continue;
            }
            for (size_t j = 0; j < nb; j++) {
                size_t row = q0 + j;
                int *oi = idx + row * ks;
                float *od = dist2 + row * ks;
                if (finish_knn(map, ql + 3 * j, want, fi + j * (size_t)kq,
                               fd + j * (size_t)kq, kq, oi, od) < 0) {
#pragma omp atomic write
                    failed = 2;
                    break;
                }
                fill_empty(oi + want, od + want, ks - (size_t)want);
            }
        }
        free(fi);
        free(fd);
    }
    if (failed == 1) {
        set_err(err, errlen, "pm_map_knn_batch: out of memory for k = %d scratch or FLANN's search", k);
        return PM_ERR_NOMEM;
    }
    if (failed == 2) {
        set_err(err, errlen, "pm_map_knn_batch: FLANN query failed");
        return PM_ERR_INDEX;
    }
    return PM_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Estimates (THEORY.md §3)                                                                   */

/* Jensen & Christensen's k-NN estimate: out = sum_k w_k dPhi_k / ((4/3) pi r^3), r = distance
 * to the farthest of the photons used, with w_k = p(w'_k . w) for radiance or 1 for density. */
static int estimate(const pm_map *map, const double x[3], int k, const float w[3],
                    pm_phase_fn phase, void *user, float out[3])
{
    if (map == NULL || k <= 0)
        return -1;
    /* pm_map_knn writes at most min(k, count) results: size the scratch for that */
    int kk = (size_t)k < map->nph ? k : (map->nph > 0 ? (int)map->nph : 1);
    pm_scratch s;
    if (!scratch_get(&s, kk))
        return -1;
    int n = pm_map_knn(map, x, k, s.fi, s.fd);
    if (n > 0 && s.fd[n - 1] > 0.0f) {
        double sum[3] = {0.0, 0.0, 0.0};
        for (int j = 0; j < n; j++) {
            const pm_photon *ph = &map->ph[s.fi[j]];
            double wt = 1.0;
            if (phase != NULL) {
                double c = (double)ph->dir[0] * w[0] + (double)ph->dir[1] * w[1] +
                           (double)ph->dir[2] * w[2];
                c = c < -1.0 ? -1.0 : (c > 1.0 ? 1.0 : c);
                wt = phase(c, user);
            }
            for (int a = 0; a < 3; a++)
                sum[a] += wt * (double)ph->power[a];
        }
        double r2 = (double)s.fd[n - 1];
        double volume = (4.0 / 3.0) * PM_PI * r2 * sqrt(r2);
        for (int a = 0; a < 3; a++)
            out[a] = (float)(sum[a] / volume);
    } else if (n > 0) {
        n = 0; /* all photons used sit exactly at x: no volume, no estimate */
    }
    scratch_put(&s);
    return n;
}

int pm_map_density(const pm_map *map, const double x[3], int k, float out[3])
{
    if (out == NULL)
        return -1;
    out[0] = out[1] = out[2] = 0.0f;
    return estimate(map, x, k, NULL, NULL, NULL, out);
}

int pm_map_radiance(const pm_map *map, const double x[3], const float w[3], int k,
                    pm_phase_fn phase, void *phase_user, float out[3])
{
    if (out == NULL)
        return -1;
    out[0] = out[1] = out[2] = 0.0f;
    if (w == NULL || phase == NULL || !finite3(w))
        return -1;
    return estimate(map, x, k, w, phase, phase_user, out);
}

/* ---------------------------------------------------------------------------------------- */
/* File format (docs/photonmap-format.md)                                                    */

#define PM_FILE_VERSION 2u   /* 2 added the origin; 1 is still read, with origin 0 */
#define PM_HEADER_BYTES 24u  /* magic, version, photon count, segment count */
#define PM_ORIGIN_BYTES 24u  /* version 2: origin x, y, z as float64 */
#define PM_PHOTON_BYTES 36u  /* 9 float32 */
#define PM_SEGMENT_BYTES 40u /* 10 float32 */
#define PM_CHECKSUM_BYTES 8u /* FNV-1a 64 of everything before it */
#define FNV_OFFSET 0xcbf29ce484222325ULL
#define FNV_PRIME 0x100000001b3ULL

/* The records are written as their in-memory floats; that needs these exact layouts. */
_Static_assert(sizeof(float) == 4, "float must be IEEE-754 binary32");
_Static_assert(sizeof(double) == 8, "double must be IEEE-754 binary64");
_Static_assert(sizeof(pm_photon) == PM_PHOTON_BYTES, "pm_photon must be 9 packed floats");
_Static_assert(sizeof(pm_segment) == PM_SEGMENT_BYTES, "pm_segment must be 10 packed floats");

/* FNV-1a 64 (Fowler, Noll, Vo): h = (h XOR byte) * prime, per byte. */
static uint64_t fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= FNV_PRIME;
    }
    return h;
}

static int host_little_endian(void)
{
    const uint32_t one = 1;
    unsigned char b;
    memcpy(&b, &one, 1);
    return b == 1;
}

/* Reverse the bytes of each 4-byte word (float records on a big-endian host). */
static void swap_words(void *data, size_t nwords)
{
    unsigned char *p = data;
    for (size_t i = 0; i < nwords; i++, p += 4) {
        unsigned char t = p[0];
        p[0] = p[3];
        p[3] = t;
        t = p[1];
        p[1] = p[2];
        p[2] = t;
    }
}

static void put_le(unsigned char *p, uint64_t v, int nbytes)
{
    for (int i = 0; i < nbytes; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}

static uint64_t get_le(const unsigned char *p, int nbytes)
{
    uint64_t v = 0;
    for (int i = 0; i < nbytes; i++)
        v |= (uint64_t)p[i] << (8 * i);
    return v;
}

/* The origin as three little-endian IEEE-754 binary64 values. */
static void put_origin(unsigned char *p, const double origin[3])
{
    for (int a = 0; a < 3; a++) {
        uint64_t bits;
        memcpy(&bits, &origin[a], 8);
        put_le(p + 8 * a, bits, 8);
    }
}

static void get_origin(const unsigned char *p, double origin[3])
{
    for (int a = 0; a < 3; a++) {
        uint64_t bits = get_le(p + 8 * a, 8);
        memcpy(&origin[a], &bits, 8);
    }
}

/* Write n bytes of float records in little-endian order, updating the checksum. */
static int write_records(FILE *f, const void *data, size_t n, uint64_t *h)
{
    if (n == 0) /* data may be NULL then */
        return 1;
    if (host_little_endian()) {
        *h = fnv1a(*h, data, n);
        return fwrite(data, 1, n, f) == n;
    }
    unsigned char buf[4096];
    const unsigned char *p = data;
    while (n > 0) {
        size_t m = n < sizeof buf ? n : sizeof buf;
        memcpy(buf, p, m);
        swap_words(buf, m / 4);
        *h = fnv1a(*h, buf, m);
        if (fwrite(buf, 1, m, f) != m)
            return 0;
        p += m;
        n -= m;
    }
    return 1;
}

static void errno_text(int e, char *buf, size_t len)
{
    if (strerror_r(e, buf, len) != 0)
        snprintf(buf, len, "error %d", e);
}

/* The temporary name of `path` for this process: "dir/name.ext" -> "dir/.name.tmp<pid>.ext",
 * the scheme of the renderer's outputs (renderer/output.c): in the same folder, so the rename
 * is atomic, and hidden, so a bake killed mid-write leaves no visible file. `out` holds
 * strlen(path) + 32 bytes (a dot, ".tmp" and at most 20 digits are added). */
static void temp_name(const char *path, char *out, size_t n)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    if (!dot || dot == base) dot = base + strlen(base);
    snprintf(out, n, "%.*s.%.*s.tmp%ld%s", (int)(base - path), path, (int)(dot - base), base,
             (long)getpid(), dot);
}

pm_status pm_map_save(const pm_map *map, const char *path, char *err, size_t errlen)
{
    if (map == NULL || path == NULL) {
        set_err(err, errlen, "pm_map_save: NULL argument");
        return PM_ERR_ARG;
    }
    size_t tlen = strlen(path) + 32;
    char *tmp = malloc(tlen);
    if (tmp == NULL) {
        set_err(err, errlen, "%s: out of memory", path);
        return PM_ERR_NOMEM;
    }
    temp_name(path, tmp, tlen);
    char why[128];
    FILE *f = fopen(tmp, "wb");
    if (f == NULL) {
        errno_text(errno, why, sizeof why);
        set_err(err, errlen, "%s: cannot create %s: %s", path, tmp, why);
        free(tmp);
        return PM_ERR_IO;
    }
    unsigned char head[PM_HEADER_BYTES + PM_ORIGIN_BYTES];
    memcpy(head, "PMAP", 4);
    put_le(head + 4, PM_FILE_VERSION, 4);
    put_le(head + 8, (uint64_t)map->nph, 8);
    put_le(head + 16, (uint64_t)map->nseg, 8);
    put_origin(head + PM_HEADER_BYTES, map->origin);
    uint64_t h = fnv1a(FNV_OFFSET, head, sizeof head);
    int ok = fwrite(head, 1, sizeof head, f) == sizeof head;
    ok = ok && write_records(f, map->ph, map->nph * sizeof(pm_photon), &h);
    ok = ok && write_records(f, map->seg, map->nseg * sizeof(pm_segment), &h);
    unsigned char tail[PM_CHECKSUM_BYTES];
    put_le(tail, h, 8);
    ok = ok && fwrite(tail, 1, sizeof tail, f) == sizeof tail;
    ok = ok && fflush(f) == 0 && fsync(fileno(f)) == 0;
    int e = errno;
    if (fclose(f) != 0 && ok) {
        ok = 0;
        e = errno;
    }
    if (ok && rename(tmp, path) != 0) {
        ok = 0;
        e = errno;
    }
    if (!ok) {
        errno_text(e, why, sizeof why);
        set_err(err, errlen, "%s: write failed: %s", path, why);
        remove(tmp);
        free(tmp);
        return PM_ERR_IO;
    }
    free(tmp);
    return PM_OK;
}

/* Read n bytes of float records written little-endian, updating the checksum. */
static int read_records(FILE *f, void *data, size_t n, uint64_t *h)
{
    if (n == 0) /* data may be NULL then */
        return 1;
    if (fread(data, 1, n, f) != n)
        return 0;
    *h = fnv1a(*h, data, n);
    if (!host_little_endian())
        swap_words(data, n / 4);
    return 1;
}

pm_status pm_map_load(pm_map **out, const char *path, char *err, size_t errlen)
{
    if (out == NULL || path == NULL) {
        set_err(err, errlen, "pm_map_load: NULL argument");
        return PM_ERR_ARG;
    }
    *out = NULL;
    char why[128];
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        errno_text(errno, why, sizeof why);
        set_err(err, errlen, "%s: cannot open: %s", path, why);
        return PM_ERR_IO;
    }
    pm_map *map = NULL;
    pm_status code = PM_ERR_FORMAT;
    struct stat st;
    if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode)) {
        set_err(err, errlen, "%s: not a regular file", path);
        code = PM_ERR_IO;
        goto fail;
    }
    const uint64_t size = (uint64_t)st.st_size;

    /* 1. Header: magic, version, counts (and from version 2 the origin), all checked against
     *    the file size before any allocation, so a corrupt count can never make us allocate
     *    an absurd amount. */
    unsigned char head[PM_HEADER_BYTES + PM_ORIGIN_BYTES];
    size_t got = fread(head, 1, PM_HEADER_BYTES, f);
    if (size == 0) {
        set_err(err, errlen, "%s: empty file (not a photon map)", path);
        goto fail;
    }
    if (got >= 4 && memcmp(head, "PMAP", 4) != 0) {
        set_err(err, errlen, "%s: not a photon map (bad magic)", path);
        goto fail;
    }
    const uint64_t version = got >= 8 ? get_le(head + 4, 4) : PM_FILE_VERSION;
    if (version != 1 && version != PM_FILE_VERSION) {
        set_err(err, errlen, "%s: unsupported version %" PRIu64 " (expected 1 or %u)", path,
                version, PM_FILE_VERSION);
        goto fail;
    }
    const size_t headlen = PM_HEADER_BYTES + (version >= 2 ? PM_ORIGIN_BYTES : 0);
    const uint64_t minimum = headlen + PM_CHECKSUM_BYTES;
    if (got == PM_HEADER_BYTES && version >= 2)
        got += fread(head + PM_HEADER_BYTES, 1, PM_ORIGIN_BYTES, f);
    if (size < minimum || got < headlen) {
        set_err(err, errlen, "%s: truncated: expected at least %" PRIu64 " bytes, found %" PRIu64,
                path, minimum, size);
        goto fail;
    }
    const uint64_t nph = get_le(head + 8, 8), nseg = get_le(head + 16, 8);
    if (nph > (UINT64_MAX - minimum) / PM_PHOTON_BYTES ||
        nseg > (UINT64_MAX - minimum - nph * PM_PHOTON_BYTES) / PM_SEGMENT_BYTES) {
        set_err(err, errlen,
                "%s: impossible counts: %" PRIu64 " photons and %" PRIu64
                " segments, file has %" PRIu64 " bytes",
                path, nph, nseg, size);
        goto fail;
    }
    const uint64_t expected = minimum + nph * PM_PHOTON_BYTES + nseg * PM_SEGMENT_BYTES;
    if (expected != size) {
        set_err(err, errlen, "%s: %s: expected %" PRIu64 " bytes, found %" PRIu64, path,
                size < expected ? "truncated" : "trailing data", expected, size);
        goto fail;
    }
    if (nph > (uint64_t)INT_MAX) {
        set_err(err, errlen, "%s: %" PRIu64 " photons exceed the limit of %d", path, nph,
                INT_MAX);
        goto fail;
    }
    double origin[3] = {0.0, 0.0, 0.0}; /* version 1 files have none: origin 0 */
    if (version >= 2)
        get_origin(head + PM_HEADER_BYTES, origin);

    /* 2. Records, then the checksum over header and records. */
    map = pm_map_new();
    if (map != NULL) {
        map->ph = nph > 0 ? malloc((size_t)nph * sizeof(pm_photon)) : NULL;
        map->seg = nseg > 0 ? malloc((size_t)nseg * sizeof(pm_segment)) : NULL;
    }
    if (map == NULL || (nph > 0 && map->ph == NULL) || (nseg > 0 && map->seg == NULL)) {
        set_err(err, errlen, "%s: out of memory for %" PRIu64 " photons and %" PRIu64
                " segments", path, nph, nseg);
        code = PM_ERR_NOMEM;
        goto fail;
    }
    map->capph = (size_t)nph;
    map->capseg = (size_t)nseg;
    uint64_t h = fnv1a(FNV_OFFSET, head, headlen);
    unsigned char tail[PM_CHECKSUM_BYTES];
    if (!read_records(f, map->ph, (size_t)nph * sizeof(pm_photon), &h) ||
        !read_records(f, map->seg, (size_t)nseg * sizeof(pm_segment), &h) ||
        fread(tail, 1, sizeof tail, f) != sizeof tail) {
        set_err(err, errlen, "%s: read failed (file changed while reading?)", path);
        code = PM_ERR_IO;
        goto fail;
    }
    if (get_le(tail, 8) != h) {
        set_err(err, errlen, "%s: checksum mismatch: stored %016" PRIx64 ", computed %016" PRIx64,
                path, get_le(tail, 8), h);
        goto fail;
    }

    /* 3. Values: a finite origin, and the same rules as pm_map_add_photons / _add_segments. */
    if (!finite3d(origin)) {
        set_err(err, errlen, "%s: origin (%g, %g, %g) is not finite", path, origin[0], origin[1],
                origin[2]);
        goto fail;
    }
    memcpy(map->origin, origin, sizeof map->origin);
    for (size_t i = 0; i < (size_t)nph; i++) {
        if (!check_photon(&map->ph[i], why, sizeof why)) {
            set_err(err, errlen, "%s: photon %zu: %s", path, i, why);
            goto fail;
        }
    }
    for (size_t i = 0; i < (size_t)nseg; i++) {
        if (!check_segment(&map->seg[i], why, sizeof why)) {
            set_err(err, errlen, "%s: segment %zu: %s", path, i, why);
            goto fail;
        }
    }
    grow_bounds(map, map->ph, (size_t)nph); /* while map->nph is still 0 */
    map->nph = (size_t)nph;
    map->nseg = (size_t)nseg;
    fclose(f);
    *out = map;
    return PM_OK;

fail:
    pm_map_free(map);
    fclose(f);
    return code;
}
