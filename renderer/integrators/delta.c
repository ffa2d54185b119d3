/* delta.c: the method `delta`, the unbiased reference: volumetric path tracing with delta
 * tracking's free flights (transport/path.c: next-event estimation with ratio tracking, phase
 * sampling, Russian roulette, MIS for the lights a path can hit). Every other method is checked
 * against it. */
#include "integrators/rd_method.h"
#include "transport/rd_path.h"

/* The method-table entry: the path's random numbers are one keyed stream (rd_sampler_stream). */
static vec3 delta_method_radiance(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    pcg32 rng = rd_sampler_stream(smp);
    return rd_delta_radiance(ctx->scene, r, &rng, &th->counters);
}

const rd_method rd_method_delta = {
    .name = "delta",
    .summary = "unbiased reference: delta tracking, next-event estimation with ratio tracking, MIS",
    .needs = 0,
    .radiance = delta_method_radiance,
};
