/* pm_flann_guard.h: photonmap/'s private bridge to FLANN's C API (photonmap/flann_guard.cpp).
 *
 * FLANN's C functions catch only std::runtime_error; any other exception (std::bad_alloc when
 * the index or a result set cannot get memory) would unwind through our C frames, which ends
 * the process in std::terminate. Each function here calls the FLANN function of the same
 * shape inside try/catch and, when it throws, returns FLANN's own failure value (NULL or -1)
 * with the reason in *fault. Not part of the module's public API (photonmap.h).
 */
#ifndef PM_FLANN_GUARD_H
#define PM_FLANN_GUARD_H

#include <stddef.h>

#include <flann/flann.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int nomem;      /* 1: std::bad_alloc (out of memory) */
    char what[160]; /* the exception's what(), or "" when nothing was thrown */
} pm_flann_fault;

/* flann_build_index_float; NULL when FLANN fails or throws. */
flann_index_t pm_flann_build(float *xyz, int rows, int cols, float *speedup,
                             struct FLANNParameters *p, pm_flann_fault *fault);
/* flann_find_nearest_neighbors_index_float; 0 on success, -1 when FLANN fails or throws. */
int pm_flann_knn(flann_index_t index, float *queries, int nq, int *idx, float *dist2, int k,
                 struct FLANNParameters *p, pm_flann_fault *fault);
/* flann_radius_search_float; the count found, -1 when FLANN fails or throws. */
int pm_flann_radius(flann_index_t index, float *query, int *idx, float *dist2, int max_nn,
                    float radius2, struct FLANNParameters *p, pm_flann_fault *fault);

#ifdef __cplusplus
}
#endif
#endif
