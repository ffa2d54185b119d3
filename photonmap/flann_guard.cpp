// flann_guard.cpp: FLANN's C API with every exception caught (pm_flann_guard.h says why).
// Each wrapper is the FLANN call inside try/catch: std::bad_alloc becomes fault->nomem = 1,
// any other exception its what(); the caller reports it as a status and a message.
#include "pm_flann_guard.h"

#include <cstdio>
#include <exception>
#include <mutex>
#include <new>

namespace {

void note(pm_flann_fault *fault, int nomem, const char *what)
{
    if (!fault) return;
    fault->nomem = nomem;
    std::snprintf(fault->what, sizeof fault->what, "%s", what);
}

void clear(pm_flann_fault *fault)
{
    if (fault) note(fault, 0, "");
}

// Run call() with every exception caught: its result, or on_fault after noting the fault.
template <class R, class F> R guarded(pm_flann_fault *fault, R on_fault, F &&call)
{
    clear(fault);
    try {
        return call();
    } catch (const std::bad_alloc &) {
        note(fault, 1, "out of memory");
    } catch (const std::exception &e) {
        note(fault, 0, e.what());
    } catch (...) {
        note(fault, 0, "unknown exception");
    }
    return on_fault;
}

} // namespace

extern "C" flann_index_t pm_flann_build(float *xyz, int rows, int cols, float *speedup,
                                        struct FLANNParameters *p, pm_flann_fault *fault)
{
    // FLANN's process-wide log level, set to NONE (it never prints) once before the first build;
    // every call's parameters then leave it alone (log_level -1), so two builds of different
    // maps may run at once (photonmap.c's head, "Thread safety").
    static std::once_flag quiet;
    return guarded<flann_index_t>(fault, nullptr, [&] {
        std::call_once(quiet, [] { flann_log_verbosity(FLANN_LOG_NONE); }); // (may throw: guarded)
        return flann_build_index_float(xyz, rows, cols, speedup, p);
    });
}

extern "C" int pm_flann_knn(flann_index_t index, float *queries, int nq, int *idx, float *dist2,
                            int k, struct FLANNParameters *p, pm_flann_fault *fault)
{
    return guarded(fault, -1, [&] { return flann_find_nearest_neighbors_index_float(index, queries, nq, idx, dist2, k, p); });
}

extern "C" int pm_flann_radius(flann_index_t index, float *query, int *idx, float *dist2,
                               int max_nn, float radius2, struct FLANNParameters *p,
                               pm_flann_fault *fault)
{
    return guarded(fault, -1, [&] { return flann_radius_search_float(index, query, idx, dist2, max_nn, radius2, p); });
}
