/* rd_probes.h: more camera chains for the light a camera sample sees at the end of its camera
 * chain: march.probes for the marchers, settings.probes for `delta` (integrators/probes.c says
 * how and why). Internal to integrators/ (tests include it). */
#ifndef RD_PROBES_H
#define RD_PROBES_H

#include "integrators/rd_method.h"
#include "integrators/rd_select.h"

/* One method's probes for one render. */
typedef struct {
    int M;                  /* 0: "auto" (px), else M >= 1 chains on every sample (1: none) */
    struct rd_probe_px *px; /* "auto": per pixel, what chooses M */
    double lambda;          /* "auto": the image's variance over its cost per sample at the last
                               epoch (0: none yet) */
    double cell_cost;       /* the method's PDF segment in the counted cost (rd_select.h) */
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
/* A sample's estimate of pixel th->pixel from its I and its own chain's E0 (probes.c's head),
 * with M - 1 probes averaged into E0; cost: the sample's counted cost (rd_probes_cost). Learns
 * from the sample under "auto" (p's per-pixel statistics). */
vec3 rd_probes_add(const rd_render_ctx *ctx, rd_probes *p, rd_thread *th, vec3 I, vec3 E0, double cost,
                   pcg32 *rng);
/* "auto"'s epochs, for the method's epoch hooks: the next after `sample` (INT_MAX: none), and
 * lambda from every pixel's samples so far (every rank's, through ctx->comm). */
int rd_probes_epoch_next(const rd_probes *p, int sample);
void rd_probes_epoch(const rd_render_ctx *ctx, rd_probes *p);

#endif /* RD_PROBES_H */
