/* uniform.c: the method `uniform`, seed 001's first baseline (eq. 5): ray marching
 * (integrators/march.c) with N evenly spaced samples per camera ray, one random offset each. */
#include "integrators/rd_march.h"

static vec3 radiance_uniform(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    return rd_march_radiance(ctx, th, r, smp, PLACE_UNIFORM);
}

const rd_method rd_method_uniform = {
    .name = "uniform",
    .summary = "seed 001 baseline: ray marching with a fixed step and one random offset (eq. 5)",
    .needs = RD_NEEDS_PHOTONS | RD_NEEDS_INDIRECT | RD_NEEDS_INDIRECT_GUIDE,
    .needs_for = rd_march_source_needs,
    .pass_maps = rd_march_pass_maps,
    .photons_changed = rd_march_photons_changed,
    .scratch_bytes = rd_march_scratch_bytes,
    .prepare = rd_march_prepare,
    .epoch_next = rd_march_epoch_next,
    .epoch = rd_march_epoch,
    .release = rd_march_release,
    .radiance = radiance_uniform,
};
