/* transmittance.c: the method `transmittance`, seed 001's second baseline (eq. 11): ray
 * marching (integrators/march.c) with the samples placed by p(t) ~ sigma_t T(0,t), from a
 * piecewise-constant extinction of 4N midpoint lookups, mixed with the defensive uniform part. */
#include "integrators/rd_march.h"

static vec3 radiance_transmittance(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    return rd_march_radiance(ctx, th, r, smp, PLACE_TRANSMITTANCE);
}

const rd_method rd_method_transmittance = {
    .name = "transmittance",
    .summary = "seed 001 baseline: ray marching with samples placed by sigma_t T (eq. 11)",
    .needs = RD_NEEDS_PHOTONS | RD_NEEDS_INDIRECT | RD_NEEDS_INDIRECT_GUIDE,
    .needs_for = rd_march_source_needs,
    .pass_maps = rd_march_pass_maps,
    .photons_changed = rd_march_photons_changed,
    .scratch_bytes = rd_march_scratch_bytes,
    .prepare = rd_march_prepare,
    .epoch_next = rd_march_epoch_next,
    .epoch = rd_march_epoch,
    .release = rd_march_release,
    .radiance = radiance_transmittance,
};
