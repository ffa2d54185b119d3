/* photonmap.h: the volume photon map as a data structure (THEORY.md §3).
 *
 * Stores photons (collision events) and, optionally, photon path segments; indexes the photon
 * positions in a FLANN single kd-tree; answers k-nearest and radius queries and the density and
 * radiance estimates built on them; saves and loads a documented binary file.
 *
 * It knows nothing of scenes. Positions, directions and powers arrive as plain arrays; the phase
 * function arrives as a callback p(cos) with cos = w'.w (w' = propagation direction of the
 * photon, w = direction the scattered light leaves in).
 *
 * Units and conventions (what the renderer stores, and what the estimates therefore mean):
 *   origin    a point in world coordinates (double, metres) held by the map, 0 by default.
 *             Stored positions (photon pos, segment org) are float offsets from it, so a scene
 *             far from the world origin keeps float precision relative to its own size (float
 *             spacing at 1e5 m is 0.008 m; at 1 m from the origin it is 1.2e-7 m). Set it to
 *             the middle of the scene before adding anything (pm_map_set_origin). Queries take
 *             world coordinates in double and subtract the origin in double.
 *   pos       metres (scene units), float, relative to the map origin
 *   dir       unit propagation direction w' of the photon *before* the event
 *   power     RGB watts *scattered* at the event: incident power times the medium's RGB albedo.
 *             With that convention the estimates below return sigma_s-weighted quantities
 *             directly (THEORY.md §3):
 *               density   sum_k dPhi_k / V            = sigma_s * fluence        [W m^-3]
 *               radiance  sum_k p(w'_k.w) dPhi_k / V  = sigma_s * L_s(x, w)      [W m^-3 sr^-1]
 *             with V = (4/3) pi r^3, r = distance to the k-th nearest photon.
 *   segments  origin, unit direction, length and the RGB power *flowing* along the segment
 *             (before any collision at its end). The track-length estimate of a segment over a
 *             region of volume |V| where it runs for length l is dPhi l / |V| (= fluence); a
 *             caller multiplies by its own sigma_s(x) and phase function.
 *
 * Threads: a build is single-threaded (FLANN), and builds of different maps may run at once;
 * every query function is safe to call from many threads at once on a built map. Results are
 * deterministic (exact kd-tree search, ties broken by index).
 *
 * Errors: functions return pm_status; when `err` is non-NULL a one-line message is written
 * into it (at most errlen bytes, always NUL-terminated). Nothing prints, nothing exits.
 * Ownership: every _new has a _free; _free(NULL) is safe.
 */
#ifndef PHOTONMAP_H
#define PHOTONMAP_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    PM_OK = 0,
    PM_ERR_ARG,    /* bad argument (NULL, k <= 0, NaN, not built, ...) */
    PM_ERR_NOMEM,  /* allocation failed */
    PM_ERR_IO,     /* open/read/write/rename failed */
    PM_ERR_FORMAT, /* file is not a photon map, wrong version, truncated or bad checksum */
    PM_ERR_INDEX   /* FLANN failed to build or query */
} pm_status;

/* One stored photon. Open value type. */
typedef struct {
    float pos[3];   /* m, relative to the map origin (world = origin + pos) */
    float dir[3];   /* unit propagation direction w' */
    float power[3]; /* W, RGB, scattered power (see above) */
} pm_photon;

/* One photon path segment (seed 004 idea taken to volumes). Open value type. */
typedef struct {
    float org[3];   /* m, relative to the map origin (world = origin + org) */
    float dir[3];   /* unit */
    float length;   /* m, > 0 */
    float power[3]; /* W, RGB, flowing along the segment */
} pm_segment;

/* Phase function callback: value of p at cos = w'.w [1/sr]. */
typedef double (*pm_phase_fn)(double cos_theta, void *user);

typedef struct pm_map pm_map; /* opaque */

/* Creation and filling. Photons and segments are copied. Every field must be finite and a
 * segment's length >= 0; otherwise PM_ERR_ARG names the first bad record and nothing is added.
 * At most INT_MAX photons (FLANN's row count). Adding photons unbuilds the map. */
pm_map *pm_map_new(void);
void pm_map_free(pm_map *map);
pm_status pm_map_add_photons(pm_map *map, const pm_photon *ph, size_t n, char *err, size_t errlen);
pm_status pm_map_add_segments(pm_map *map, const pm_segment *seg, size_t n, char *err,
                              size_t errlen);

/* The origin [m, world coordinates] that stored positions are relative to; default (0, 0, 0).
 * It can be set only while the map holds no photons and no segments (PM_ERR_ARG otherwise,
 * and for a non-finite value): records already stored would silently move. */
pm_status pm_map_set_origin(pm_map *map, const double origin[3], char *err, size_t errlen);
void pm_map_origin(const pm_map *map, double origin[3]); /* 0 for a NULL map */

/* Build the FLANN kd-tree over photon positions. Must be called (again) after adding photons
 * and before any query. A map with zero photons builds and answers every query with 0 found. */
pm_status pm_map_build(pm_map *map, char *err, size_t errlen);

/* Read access. Pointers stay valid until the next add/free. */
size_t pm_map_photon_count(const pm_map *map);
const pm_photon *pm_map_photons(const pm_map *map);
size_t pm_map_segment_count(const pm_map *map);
const pm_segment *pm_map_segments(const pm_map *map);
/* Bounds of the photon positions in world coordinates (origin + pos), rounded outward to float
 * so that every photon lies inside; 0 if there are none. */
void pm_map_bounds(const pm_map *map, float lo[3], float hi[3]);
size_t pm_map_memory_bytes(const pm_map *map); /* photons + segments + index (approximate) */
double pm_map_build_seconds(const pm_map *map); /* wall time of the last pm_map_build or pm_map_order */
/* The spatial order alone (pm_map_spatial_order), without the kd-tree: for a caller that reads
 * the photons in that order and asks the map no query (they fail as on a map not built). A
 * fraction of pm_map_build's time: the tree's build is FLANN's, on one thread. */
pm_status pm_map_order(pm_map *map, char *err, size_t errlen);
/* The photon indices in a spatial order (Morton, over the photons' bounds: the kd-tree's rows),
 * pm_map_photon_count of them; NULL until the map is built or ordered (pm_map_order), or when it
 * is empty. Valid until the next pm_map_add_photons, pm_map_build, pm_map_order or pm_map_free. A
 * caller that lays photons out in memory in this order gets neighbours near each other. */
const int *pm_map_spatial_order(const pm_map *map);

/* Every query point x is in world coordinates [m], double; the map subtracts its origin in
 * double and searches with the float offset. Distances are in metres as float.
 *
 * k nearest photons to x, sorted by distance. Writes up to k indices and squared distances;
 * returns the number found (min(k, count)), or -1 on error (not built, k <= 0). */
int pm_map_knn(const pm_map *map, const double x[3], int k, int *idx, float *dist2);

/* Photons within radius r of x, sorted by distance, at most max of them; returns the number
 * written, or -1 on error. "Within" is inclusive (dist2 <= r*r); when more than max lie
 * within r, the max nearest are returned (ties by index). Errors: not built, max <= 0, r < 0
 * or NaN. */
int pm_map_radius(const pm_map *map, const double x[3], float r, int max, int *idx, float *dist2);

/* Batch k-NN for nq world query points (row-major nq x 3 doubles) with `threads` OpenMP threads (0 = all).
 * idx and dist2 are nq x k; rows with fewer than k photons are padded with -1 / INFINITY. */
pm_status pm_map_knn_batch(const pm_map *map, const double *queries, size_t nq, int k, int *idx,
                           float *dist2, int threads, char *err, size_t errlen);

/* Density estimate from the k nearest photons: out = sum dPhi / ((4/3) pi r^3), r = distance
 * to the k-th photon. Returns the number of photons used (0: out = 0), -1 on error.
 * A map with fewer than k photons uses all of them (r = distance to the farthest). If r = 0
 * (every photon used sits exactly at x) there is no volume: out = 0 and the return is 0.
 * The same two rules hold for pm_map_radiance. */
int pm_map_density(const pm_map *map, const double x[3], int k, float out[3]);

/* Radiance estimate sigma_s L_s(x, w) from the k nearest photons (THEORY.md §3):
 * out = sum p(w'_k . w) dPhi_k / ((4/3) pi r^3). w is the outgoing direction (unit).
 * Returns the number of photons used, -1 on error. */
int pm_map_radiance(const pm_map *map, const double x[3], const float w[3], int k,
                    pm_phase_fn phase, void *phase_user, float out[3]);

/* Photon map file (format in docs/photonmap-format.md): magic "PMAP", version, counts,
 * origin, photons, segments, FNV-1a 64 checksum. Version 1 files (no origin) load with origin 0.
 * pm_map_write writes the file to the stream f (opened for binary writing by the caller, who
 * closes it; the renderer writes through a temporary name and a rename) and flushes it; a
 * failed write is PM_ERR_IO naming `name` (the file's name for messages). Load
 * rejects wrong magic/version, truncation, absurd counts and checksum mismatches with
 * PM_ERR_FORMAT and a message naming the file. A loaded map is not built: call pm_map_build. */
pm_status pm_map_write(const pm_map *map, FILE *f, const char *name, char *err, size_t errlen);
pm_status pm_map_load(pm_map **out, const char *path, char *err, size_t errlen);

#ifdef __cplusplus
}
#endif
#endif /* PHOTONMAP_H */
