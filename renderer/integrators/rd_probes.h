/* rd_probes.h: more camera chains for the light a camera sample sees at the end of its camera
 * chain: march.probes for the marchers, settings.probes for `delta`, guide.probes for
 * `guided-unbiased` (integrators/probes.c says how and why). Internal to integrators/ (tests include it). */
#ifndef RD_PROBES_H
#define RD_PROBES_H

#include "integrators/rd_method.h"
#include "integrators/rd_select.h"

/* One method's probes for one render. */
typedef struct {
    int M;                  /* 0: "auto" (px), else M >= 1 chains on every sample (1: none) */
    struct rd_probe_px *px; /* "auto": per pixel, what chooses M, and the M chosen */
    double cell_cost;       /* the method's PDF segment in the counted cost (rd_select.h) */
    double bright;          /* the brightest light a chain can end on (the mean of its channels):
                               a sphere light, or the background with the environment lights */
} rd_probes;

/* Set up p from the setting (0 "auto", M >= 1) for scene s: no probes (M = 1) where no chain
 * can end on light (no sphere or environment light, a black background). */
rd_status rd_probes_init(rd_probes *p, const rd_scene *s, int setting, double cell_cost, char *err,
                         size_t errlen);
void rd_probes_free(rd_probes *p);
/* Whether a sample may take probes (else it is the method's own sample, bit for bit). */
static inline int rd_probes_on(const rd_probes *p) { return p->M != 1; }
/* The counted cost of a camera sample whose work began at w0 (rd_select_work_now), with p's
 * cell cost (rd_select.h). */
double rd_probes_cost(const rd_probes *p, const rd_select_work *w0, const rd_thread *th);
/* One probe: the light camera chain r sees at its end through the media's transmittance
 * (settings.transmittance's estimator) and the chain's glass; 0 where it ends on a diffuse
 * surface. */
vec3 rd_probes_chain(const rd_scene *s, ray3 r, pcg32 *rng, rd_track_counters *c);
/* A sample's estimate of pixel th->pixel (the probes aim at column th->x, row th->y) from
 * its I and its own chain's E0 (probes.c's head), with M - 1 probes averaged into E0; cost:
 * the sample's counted cost (rd_probes_cost). Learns from the sample under "auto" (p's
 * per-pixel statistics). */
vec3 rd_probes_add(const rd_render_ctx *ctx, rd_probes *p, rd_thread *th, vec3 I, vec3 E0, double cost,
                   pcg32 *rng);
/* One pixel's model under "auto" (probes.c's head): a sample with M - 1 probes,
 * I + (E_0 + E_1 + ... + E_{M-1}) / M, has the variance
 *   V(M) = vI + 2 cov / M + (v0 + (M - 1) vp) / M^2
 * (v0, vp: the variances of the sample's own E_0 and of a probe's E, equal for a marcher, and
 * for `delta` its pass-or-stop E_0 against the probes' transmittance estimate; cov the
 * covariance of I and E_0, the probes being independent of both) at the cost c + (M - 1) cp;
 * chains: the chains the pixel's samples and probes have taken. */
typedef struct {
    double vI, cov, v0, vp, c, cp, chains;
} rd_probes_model;
/* Chains a sample takes at most under "auto" (M <= RD_PROBES_MAX) */
#define RD_PROBES_MAX 32
/* The M in [1, RD_PROBES_MAX] that minimises V(M) + lambda C(M), the first if several do (1 when
 * lambda <= 0). Needs v0, vp >= 0 and cp >= 0, as every model from a pixel's samples has (its
 * search stops early on a bound that holds only then). */
int rd_probes_best_m(const rd_probes_model *m, double lambda);
/* The M a pixel takes under "auto" until the next epoch: rd_probes_best_m's; where the model
 * has no variance of E (v0 = vp = 0: its chains have seen no light, or the same light every
 * time), at least the M the search finds for the variance an unseen light of radiance `bright`
 * may still hide after the model's chains, but no more than the probes that cost an eighth of
 * the sample's own c (probes.c's head, "Where a pixel has seen no light"). cp > 0, as model_of
 * makes it. */
int rd_probes_choose_m(const rd_probes_model *m, double lambda, double bright);
/* delta's path along camera ray r, its flights in equiangular mode `equiangular`, with p's
 * probes (rd_probes_add; without probes rd_delta_radiance_eq's sample, bit for bit): `delta`'s
 * own sample under settings.probes, and the guided methods' delta tiles under theirs
 * (rd_select_delta_fn). */
vec3 rd_probes_delta(const rd_render_ctx *ctx, rd_probes *p, rd_thread *th, ray3 r, rd_sampler *smp,
                     int equiangular);
/* "auto"'s epochs, for the method's epoch hooks: the next after `sample` (INT_MAX: none), and
 * the epoch itself: lambda from every pixel's samples so far (every rank's, through ctx->comm),
 * then each pixel's M, which its samples take until the next epoch. */
int rd_probes_epoch_next(const rd_probes *p, int sample);
void rd_probes_epoch(const rd_render_ctx *ctx, rd_probes *p);

#endif /* RD_PROBES_H */
