/* pm_internal.h: private to the photonmap/ module. The layout of the photon map (opaque in
 * photonmap.h) and the few helpers that more than one source file of the module needs. Only the
 * files in photonmap/ include it; nothing outside may (photonmap.h stays the module's one public
 * header).
 *
 * Where things live (THEORY.md §3; docs/photonmap-format.md):
 *   photonmap.c      storage: create and free, adding photons and segments (and their checks),
 *                    the origin, building the FLANN kd-tree, read access; the notes on FLANN's
 *                    data lifetime and thread safety.
 *   pm_query.c       exact k-NN, radius and batch queries, and the k-NN density and radiance
 *                    estimates; the notes on FLANN's distances, ties and coordinates.
 *   pm_file.c        the .pmap file: save and load.
 *   flann_guard.cpp  FLANN's C API with its exceptions caught (pm_flann_guard.h).
 * No cycle among the files: in the order pm_file.c, pm_query.c, photonmap.c, flann_guard.cpp
 * each file calls only files after it.
 *
 * Names: functions shared between these files start with pmi_ (photonmap internal); everything
 * else in a .c file is static. The helpers below are static inline because the queries call
 * them once per query. */
#ifndef PM_INTERNAL_H
#define PM_INTERNAL_H

#include <math.h>
#include <stddef.h>
#include <string.h>

#include "photonmap.h"
#include "pm_flann_guard.h" /* FLANN's C API with its exceptions caught */

/* kd-tree leaf size. bench/bench_photonmap.c at 1e6 clustered photons: 16 answered k = 16..256
 * 7-15% faster than 8 or 12 and as fast as 24, with 81 B/photon (12: 84, 8: 89). */
#ifndef PM_LEAF_MAX_SIZE
#define PM_LEAF_MAX_SIZE 16
#endif

/* Bits per axis of the grid whose Morton order the kd-tree build takes the photons in
 * (photonmap.c spatial_order): 64^3 cells. On the 1.7e6 photons of default.json (docs/
 * benchmarks.md, issue 21): 4 bits already gave most of the gain, 6 to 10 bits the least
 * sort + build time. */
#define PM_ORDER_BITS 6

/* ---- The photon map ------------------------------------------------------------------------ */

struct pm_map {
    double origin[3]; /* world position that stored positions are relative to */
    pm_photon *ph; /* nph photons, room for capph */
    size_t nph, capph;
    pm_segment *seg; /* nseg segments, room for capseg */
    size_t nseg, capseg;
    float lo[3], hi[3]; /* bounds of photon positions; zeros while nph == 0 */
    int built;          /* 1 after pm_map_build, back to 0 after any photon add */
    int ordered;        /* 1 after pm_map_order (perm only, no index), back to 0 as built */
    float *xyz;         /* nph x 3 positions handed to FLANN, row j = photon perm[j]; lives
                         * as long as index */
    int *perm;          /* nph: FLANN's row j is photon perm[j] (a spatial order, see
                         * pm_map_build); lives as long as index, or from pm_map_order to the
                         * next photon add or build */
    flann_index_t index; /* NULL when not built or when the map has no photons */
    size_t index_bytes;  /* approximate memory of index + xyz */
    double build_seconds;
};

/* ---- Shared functions (defined in photonmap.c) ---------------------------------------------- */

/* printf into err (at most errlen bytes, NUL-terminated); no-op for err = NULL. */
void pmi_set_err(char *err, size_t errlen, const char *fmt, ...)
#ifdef __GNUC__
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Validation shared by add and load: writes a reason into why and returns 0 when a record
 * is unusable. Every field must be finite (a NaN would poison the tree or the estimates). */
int pmi_check_photon(const pm_photon *p, char *why, size_t whylen);
int pmi_check_segment(const pm_segment *s, char *why, size_t whylen);

/* Widen map->lo/hi to cover the n photons ph (the first of them sets the bounds while
 * map->nph == 0). */
void pmi_grow_bounds(pm_map *map, const pm_photon *ph, size_t n);

/* ---- Small helpers -------------------------------------------------------------------------- */

/* FLANN's row numbers in fi[0..n) to photon indices, in place (-1, an empty slot, stays). */
static inline void pmi_rows_to_photons(const pm_map *map, int *fi, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (fi[i] >= 0)
            fi[i] = map->perm[fi[i]];
}

static inline int pmi_finite3(const float v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static inline int pmi_finite3d(const double v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

/* FLANN parameters for an exact single kd-tree, returned by value so that every call owns its
 * copy. log_level -1 makes init_flann_parameters() leave FLANN's global log level alone: it is
 * set once, to NONE, before the first build (pm_flann_build). */
static inline struct FLANNParameters pmi_flann_params(void)
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
    p.log_level = (enum flann_log_level_t)-1;
    p.random_seed = 0; /* no srand() */
    return p;
}

#endif /* PM_INTERNAL_H */
