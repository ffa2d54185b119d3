/* pm_query.c: questions to a built photon map (THEORY.md §3): exact k-NN, radius and batch k-NN
 * queries through the FLANN kd-tree, and the k-NN density and radiance estimates of Jensen &
 * Christensen 1998 (docs/photonmap-format.md "Estimates").
 *
 * Notes on FLANN's search (libflann 1.9.2; data lifetime and thread safety are at the top of
 * photonmap.c):
 *
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
 *  - Row numbers. FLANN's rows are the photons in a spatial order (pm_map_build); every row
 *    number FLANN returns is turned into the photon's index (pmi_rows_to_photons) before any
 *    sorting or tie test, so the answers are in photon indices as before.
 *  - Coordinates. FLANN indexes the stored float positions, which are offsets from the map's
 *    origin (double). A query point arrives in world coordinates as double; to_local()
 *    subtracts the origin in double and rounds once to float, so a scene 1e5 m from the world
 *    origin is searched with the precision of one near it.
 */
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "pm_internal.h"

#define PM_PI 3.14159265358979323846

/* Relative slack covering FLANN's float cell bounds (tree depth ~25, a few ulps per level,
 * so < 4e-6 relative); see the notes at the top. */
#define PM_TIE_REL 2e-5f

/* Queries with k+1 <= PM_STACK_K neighbours use stack scratch; larger ones malloc. */
#define PM_STACK_K 257

/* Batch queries are handed to FLANN in chunks of this many rows (amortises per-call cost). */
#define PM_BATCH_CHUNK 64

/* ---------------------------------------------------------------------------------------- */
/* Small helpers                                                                              */

/* World point (double) to the float offset from the origin that FLANN indexes: the difference
 * is taken in double, then rounded once. */
static void to_local(const pm_map *map, const double x[3], float q[3])
{
    for (int a = 0; a < 3; a++)
        q[a] = (float)(x[a] - map->origin[a]);
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
/* Queries                                                                                    */

/* Every photon with dist2 <= t, sorted by (dist2, idx): a FLANN radius search with the slack
 * radius (first counting, then fetching exactly that many), filtered exactly. Returns the
 * number found and a malloc'ed array in *out, or -1 on failure. */
static int collect_within(const pm_map *map, const float x[3], float t, pm_hit **out)
{
    struct FLANNParameters p = pmi_flann_params();
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
            pmi_rows_to_photons(map, fi, (size_t)got);
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
    if (idx == NULL || dist2 == NULL || k <= 0 || !map->built || !pmi_finite3(x))
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
    struct FLANNParameters p = pmi_flann_params();
    float q[3] = {x[0], x[1], x[2]};
    int r = -1;
    if (pm_flann_knn(map->index, q, 1, s.fi, s.fd, kq, &p, NULL) == 0) {
        pmi_rows_to_photons(map, s.fi, (size_t)kq);
        r = finish_knn(map, x, want, s.fi, s.fd, kq, idx, dist2);
    }
    scratch_put(&s);
    return r;
}

int pm_map_knn(const pm_map *map, const double world[3], int k, int *idx, float *dist2)
{
    if (map == NULL || world == NULL || !pmi_finite3d(world))
        return -1;
    float x[3];
    to_local(map, world, x);
    return knn_local(map, x, k, idx, dist2);
}

int pm_map_radius(const pm_map *map, const double world[3], float r, int max, int *idx,
                  float *dist2)
{
    if (map == NULL || world == NULL || idx == NULL || dist2 == NULL || max <= 0 ||
        !map->built || !pmi_finite3d(world) || !(r >= 0.0f))
        return -1;
    float x[3];
    to_local(map, world, x);
    if (!pmi_finite3(x))
        return -1;
    if (map->nph == 0)
        return 0;
    int count = (int)map->nph;
    float r2 = r * r;
    int m = max < count ? max : count;
    int cap = m < count ? m + 1 : m; /* one extra to detect a tie at the max-th */

    pm_scratch s;
    struct FLANNParameters p = pmi_flann_params();
    float q[3] = {x[0], x[1], x[2]};
    int out = -1, c = -1;
    /* FLANN keeps the cap nearest photons strictly inside the slack radius, and its result set
     * reserves room for cap of them on every query (64 KB at the renderer's cap of 4097, most of
     * a gather's time). A gather usually holds far fewer: ask for the stack's PM_STACK_K first;
     * unless that fills, FLANN has returned every photon inside the slack radius, the same set
     * the full cap finds, and only a full first try asks again with the whole cap. */
    if (cap > PM_STACK_K) {
        scratch_get(&s, PM_STACK_K);
        c = pm_flann_radius(map->index, q, s.fi, s.fd, PM_STACK_K, tie_slack(r2), &p, NULL);
        if (c >= PM_STACK_K)
            c = -1; /* filled: ask again below */
    }
    if (c < 0) {
        if (!scratch_get(&s, cap))
            return -1;
        c = pm_flann_radius(map->index, q, s.fi, s.fd, cap, tie_slack(r2), &p, NULL);
    }
    if (c >= 0) {
        int n = c < cap ? c : cap;
        pmi_rows_to_photons(map, s.fi, (size_t)n);
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
        pmi_set_err(err, errlen, "pm_map_knn_batch: NULL argument");
        return PM_ERR_ARG;
    }
    if (k <= 0 || threads < 0) {
        pmi_set_err(err, errlen, "pm_map_knn_batch: bad k = %d or threads = %d", k, threads);
        return PM_ERR_ARG;
    }
    if (!map->built) {
        pmi_set_err(err, errlen, "pm_map_knn_batch: map is not built (call pm_map_build)");
        return PM_ERR_ARG;
    }
    if (nq > SIZE_MAX / (size_t)k / sizeof(float)) {
        pmi_set_err(err, errlen, "pm_map_knn_batch: %zu queries x k = %d overflows", nq, k);
        return PM_ERR_ARG;
    }
    for (size_t i = 0; i < nq; i++) {
        float q[3];
        if (pmi_finite3d(queries + 3 * i))
            to_local(map, queries + 3 * i, q);
        if (!pmi_finite3d(queries + 3 * i) || !pmi_finite3(q)) {
            pmi_set_err(err, errlen, "pm_map_knn_batch: query %zu is not finite", i);
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
        struct FLANNParameters p = pmi_flann_params();
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
            pmi_rows_to_photons(map, fi, nb * (size_t)kq);
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
        pmi_set_err(err, errlen, "pm_map_knn_batch: out of memory for k = %d scratch or FLANN's search", k);
        return PM_ERR_NOMEM;
    }
    if (failed == 2) {
        pmi_set_err(err, errlen, "pm_map_knn_batch: FLANN query failed");
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
    if (w == NULL || phase == NULL || !pmi_finite3(w))
        return -1;
    return estimate(map, x, k, w, phase, phase_user, out);
}
