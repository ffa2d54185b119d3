/* rd_select.h: the guided methods' choice, per tile of the image, between the method and
 * delta's path (settings.select = "tiles"; integrators/select.c). Internal to integrators/
 * (tests include it). */
#ifndef RD_SELECT_H
#define RD_SELECT_H

#include "integrators/rd_method.h"

/* The tile edge in pixels. */
#define RD_SELECT_TILE 8

/* Per tile, 1 where the method renders, 0 where delta's path does. `guided` NULL: the method
 * everywhere (selection off, or not run). */
typedef struct {
    uint8_t *guided;
    int tiles_x;
} rd_select;

/* A method's own estimate of the radiance along camera ray r (what its radiance() does
 * where the selection gives it the pixel). */
typedef vec3 (*rd_select_fn)(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp);

/* Run the pilot and make the choice: on random numbers of its own, the variance and cost per
 * sample of `method` and of delta's path in every tile; keeps the choices that give the image
 * the least error at equal time. `lookup_cost`: the method's time per density lookup relative
 * to delta's (its other work, guide walks and PDFs, rides on its lookups), calibrated by the
 * method on the calibration scenes. Call at the end of the method's prepare (ctx->state set: the
 * pilot renders with the method's scratch, ctx->method->scratch_bytes). */
rd_status rd_select_prepare(const rd_render_ctx *ctx, rd_select_fn method, double lookup_cost,
                            rd_select *sel, char *err, size_t errlen);
void rd_select_free(rd_select *sel);
/* The camera sample of `th->pixel`: `method` where the selection gives it the pixel's tile,
 * else delta's path (counted in th->delta_samples). */
vec3 rd_select_radiance(const rd_render_ctx *ctx, const rd_select *sel, rd_select_fn method,
                        rd_thread *th, ray3 r, rd_sampler *smp);
/* The rule: for n tiles with the per-sample variance and cost of delta (var[2k], cost[2k]) and
 * of the method (var[2k+1], cost[2k+1]), the choices that minimise (sum V)(sum C);
 * use_method[k] = 1 for the method. */
void rd_select_choose(const double *var, const double *cost, int n, uint8_t *use_method);

#endif /* RD_SELECT_H */
