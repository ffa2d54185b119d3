/* rd_select.h: the guided methods' choice, per tile of the image, between the method and
 * delta's path, and delta's path with equiangular sampling on every flight (where `guided`'s
 * marcher samples with it; for `guided-unbiased` always: rd_select_prepare) (settings.select =
 * "tiles"; select.c, the rule in select_rule.c); and `delta`'s own between its path without and
 * with it (settings.equiangular "tiles"; delta.c). Internal to integrators/ (and tests, bench). */
#ifndef RD_SELECT_H
#define RD_SELECT_H
#include "core/rd_core.h"
#include "integrators/rd_method.h"

#define RD_SELECT_TILE 8 /* the tile edge in pixels */

/* The kinds of estimator a tile can be given (rd_select.kind): delta's path with
 * settings.equiangular ("tiles" read as off), the method, delta's path with the strategy on every
 * flight, RD_EQ_ALL (with RD_SELECT_THIRD, settings.equiangular not RD_EQ_ALL, and a point or
 * spot light or a beam delta's path does not connect to), a second estimator of the method's own
 * (rd_select_more's `path`: `guided`'s holds guided-unbiased's paths), and the method's beams
 * (rd_select_more's `beams`: `guided`'s marcher with nee+beams, which consume the photon passes
 * in the method's stead). Estimators are numbered 0 .. n-1: delta's path 0, the method 1, then
 * the others it has in the order of their kinds. */
enum { RD_SEL_DELTA = 0, RD_SEL_METHOD = 1, RD_SEL_DELTA_EQ = 2, RD_SEL_PATH = 3, RD_SEL_BEAMS = 4, RD_SEL_MAX = 5 };

/* One estimator's samples in one half of one tile (rd_select.stats), from the pilot and the
 * image's epochs so far: the count, the count with any channel non-zero, per channel the sum
 * and the squared deviations from each pixel's own mean (dev2, with dof = samples - pixels
 * degrees of freedom), and the counted cost; and of those, the samples the image holds (the
 * epochs', not the pilot's, which draws on random numbers of its own) and their counted cost
 * (select_rule.c, "The samples the image holds"). */
typedef struct {
    double n, nonzero, dof, sum[3], dev2[3], cost;
    double image_n, image_cost;
    /* The beams' (0 for the others; select_rule.c, "The beams' bias"): the sum of their
     * samples' gaps at pass 1's radius (rd_thread.beam_gap, the mean over RGB, over the pass's
     * radius_scale); and over the pixels whose image samples so far (rd_select.gaps) hold passes
     * of all four classes mod 4, the product of their odd and even passes' mean gaps, each the
     * mean of its two classes' (a nearly unbiased estimate of the squared gap: the two sets share
     * no photons but pass 1's, which set the radii) times a weight w (select.c bias_fold) in
     * bias2, the weights in bias_n, and w times the same product with two signs turned (its
     * noise, of mean 0) in bias_split. Set anew at every epoch. */
    double gap, bias2, bias_n, bias_split;
} rd_select_stats;

/* The beams' squared bias over their squared gap (select_rule.c, "The beams' bias"): the gap is
 * the estimate less the same picks in balls of half the volume (radius r / sqrt 2), and where
 * the bias grows as r^p it is gap / (1 - 2^(-p/2)). A kernel's bias is first order in r (p = 1)
 * where the radiance has a corner within the ball (a lit face, a shadow's edge), second order
 * (p = 2) where it is smooth: the rule takes p = 1, (1 - 1/sqrt 2)^-2 = 11.66, which reads the
 * smooth parts' squared bias 2.9x high rather than the edges' 2.9x low. */
#define RD_SELECT_BIAS_PER_GAP2 11.656854249492380

/* How the render ends, seen at an epoch (select_rule.c, "The samples the image holds"): at its
 * deadline, `ahead` the time left over the time its image has taken so far (> 0), or at its
 * sample count, `left` the samples a pixel has left (> 0); the other 0. Both 0: no end known, or
 * nothing left (the rule weighs the samples to come alone). */
typedef struct {
    double ahead, left;
    double radius_scale; /* the photon pass's gather radius over pass 1's now (rd_render_ctx.radius_scale;
                            0 read as 1): the beams' bias is taken to scale as it */
} rd_select_end;

/* One pixel's samples since the last epoch (of one estimator: rd_select_uses is fixed within an
 * epoch), plain doubles so that ranks sum them as one array (rd_select_epoch): sum and sum2 in
 * float precision (they feed a choice, not the image), n and nonzero counts of the finite
 * samples, cost that of all drawn (the dropped too) in whole 1/RD_SELECT_COST_UNIT lookups. */
#define RD_SELECT_COST_UNIT 65536.0
typedef struct {
    double n, nonzero, sum[3], sum2[3], cost;
} rd_select_pixel;
#define RD_SELECT_PIXEL_DOUBLES 9
/* The beams' (apart: 72 bytes a pixel without them): their samples' gaps since the last epoch,
 * the sums (mean over RGB) and the counts on the photon passes of each class mod 4. */
typedef struct {
    double gap[4], gap_n[4];
} rd_select_gaps;

/* A method's own estimate of the radiance along camera ray r (what its radiance() does
 * where the selection gives it the pixel). */
typedef vec3 (*rd_select_fn)(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp);

/* delta's path along camera ray r with its flights in equiangular mode `equiangular`
 * (RD_EQ_*), as a method gives it to its delta tiles: with the method's probes (rd_probes.h),
 * so that a tile's choice weighs the method and delta with the same probes. */
typedef vec3 (*rd_select_delta_fn)(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp,
                                   int equiangular);

typedef struct {
    float *share;            /* settings.adaptive: [n k + e], tile k's share of the samples with e */
    double *weight;          /* and their weight (0: none yet; select_share.c); NULL with "pilot"'s
                                shares (fixed at the pilot) or "epochs"' (blocks, set at every choice);
                                both NULL: every pixel draws every sample, each of weight 1 */
    int blocks;              /* "epochs": each sample weighs the indices it stands for (render.c) */
    uint8_t *choice;         /* per tile, the estimator that renders it (0 .. n-1, of kind kind[e]);
                                NULL: the method everywhere (selection off, or not run) */
    uint8_t *trial;          /* per tile, 0, or 1 + the estimator on trial against the choice:
                                for one epoch the tile's pixels with x + y odd use the one of the
                                two with the higher index, the others the lower (rd_select_uses) */
    int n;                   /* estimators compared: 2 (delta, the method) to 5 */
    uint8_t kind[RD_SEL_MAX]; /* estimator e's kind (RD_SEL_*) */
    unsigned paths;          /* bit e set: estimator e is one of delta's paths (RD_SEL_DELTA,
                                RD_SEL_DELTA_EQ; in delta's own selection its "method" too) */
    int unlit;               /* the estimator of a tile no sample has lit yet, where the rule
                                gives it plain delta and there are two paths: the one the
                                pilot's samples prefer for the whole image (select_rule.c,
                                "Tiles no sample has lit"); -1 until the pilot's choice */
    int tiles_x, tiles_y, width, height;
    int epochs;              /* choose again at the epochs (settings.select "pilot": 0; every
                                other value 1: the guided methods select only with "tiles" or
                                "auto", delta's "tiles" whatever settings.select says) */
    double cell_cost;        /* the method's cost per PDF segment it counts in rd_thread.cells,
                                in density lookups (select.c) */
    rd_select_fn path;       /* the RD_SEL_PATH estimator (NULL: none), */
    double path_cell_cost;   /* and its cost per PDF segment */
    rd_select_fn beams;      /* the RD_SEL_BEAMS estimator (NULL: none; its PDF segments cost
                                cell_cost, the method's) */
    int pass_kind;           /* the kind whose samples consume the progressive photon passes:
                                RD_SEL_BEAMS where there is one, else RD_SEL_METHOD */
    double method_pass_cost; /* per camera sample of pass_kind (the method's, or the beams'), its
                                share of the progressive photon passes, which no thread's counters
                                see, in density lookups (RD_SELECT_PASSES); 0: none */
    rd_select_stats *stats;  /* per half h of the samples (select_rule.c, "Replication"), tile k
                                and estimator e, [n (tiles h + k) + e], tiles = tiles_x
                                tiles_y: a tile's samples are the sum of its two halves' */
    rd_select_pixel *pixels; /* per pixel, the current epoch's samples */
    rd_select_gaps *pixel_gaps; /* per pixel, the current epoch's beams' gaps; NULL without the beams */
    rd_select_gaps *gaps; /* per pixel, the beams' gaps of all its image samples so far
                             (select_rule.c, "The beams' bias"); NULL without the beams or the epochs */
    double bias_ratio, bias_se, bias_r2; /* the last choice's image-wide ratio of the beams' squared bias to
                                   their variance a sample, at the radius then, before the margin,
                                   and its standard error (select_rule.c bias_ratio; 0 without the
                                   beams' products), and the radius's square then over pass 1's,
                                   bias_r2 (1 without passes): traced */
    struct rd_select_run *runs; /* per worker thread (rd_thread.index), the samples of the pixel
                                   it renders now, written to `pixels` at rd_select_pixel_done
                                   (select.c); NULL before rd_select_prepare */
    int n_runs;
    rd_select_delta_fn delta; /* delta's path as the method gives it (with its probes), NULL:
                                 rd_delta_radiance_eq (rd_select_prepare) */
    int choices;              /* choices made so far: the pilot's, then one an epoch (traced_choice) */
    rd_select_report *report; /* rd_render_ctx.select_report (may be NULL) */
    const char *trace_path;   /* rd_render_ctx.select_trace on rank 0, else NULL */
    rd_text trace;            /* the trace's lines so far */
} rd_select;

/* The estimator (0 .. n-1) of pixel (x, y): its tile's choice, or its square of a trial's checkerboard. */
int rd_select_uses(const rd_select *sel, int x, int y);
/* Pixel (x, y)'s share of the samples past the first RD_SHARE_FIRST (rd_method.sample_share), its
 * tile's for the estimator it uses (1 before the first epoch), and in *weight (unless NULL) theirs. */
double rd_select_share(const rd_select *sel, int x, int y, double *weight);
/* Where the render asked for a trace (sel->trace_path), add the line of the choice just made,
 * which governs the samples from `from` on, and write the file again whole (select_trace.c): for every
 * tile, row by row, its estimator, its trial (0, or 1 + the estimator on trial) and, per
 * estimator, the samples the choice saw (both halves, the pilot's included), their mean and
 * their variance a sample (over RGB; squared deviations from each pixel's own mean over their
 * degrees of freedom) and their counted cost a sample in density lookups. Errors: RD_ERR_NOMEM,
 * or rd_write_atomic's naming the path. */
rd_status rd_select_trace(rd_select *sel, long from, char *err, size_t errlen);
/* How many pixels the selection gives to the estimator whose samples consume the photon passes
 * now (rd_select.pass_kind: the beams estimator where there is one, else the method; without a
 * selection the method has them all: `all`). */
uint64_t rd_select_pass_pixels(const rd_select *sel, uint64_t all);

/* The counted cost (select.c's head): a camera sample's own rays, shapes and set-up, in density
 * lookups; th's work counters now; and what the work since reading c0 cost, weighted (a PDF
 * segment weighs cell_cost), the camera sample's own left out. Counts are subtracted before
 * they are weighted, so the cost does not depend on what the thread did before. */
#define RD_SELECT_COST_SAMPLE 2.18
typedef struct {
    uint64_t lookups, shadow_rays, cells, vertices, beam_hits, eq_flights;
} rd_select_work;
rd_select_work rd_select_work_now(const rd_thread *th);
double rd_select_work_cost(const rd_select_work *c0, const rd_thread *th, double cell_cost);

/* An empty selection among `estimators` (2 to 5: delta's path, the method, then delta's path
 * with the strategy, the method's second estimator and the beams, in that order) for a width x height
 * image (no tile's statistics yet, every tile to delta). */
rd_status rd_select_init(rd_select *sel, int width, int height, double cell_cost, int estimators,
                         char *err, size_t errlen);
/* Run the pilot and make the first choice: on random numbers of its own, the variance and cost per
 * sample of `method` and of delta's path in every tile (and of delta's path with the equiangular
 * strategy on every flight, where the method asks for it, options with RD_SELECT_THIRD (`guided`:
 * where its marcher samples with the strategy, march.equiangular not off; `guided-unbiased`:
 * always since session 39; `delta`'s "tiles": never), settings.equiangular is not RD_EQ_ALL, and
 * the scene has a point or spot light, or a directional beam that delta's path does not connect
 * to, to sample); keeps the choices that give the image the least error at equal time. The cost
 * is counted work (select.c): `cell_cost` is what one of the method's PDF segments
 * (rd_thread.cells) costs, in density lookups, fitted on the calibration scenes. delta's path is
 * `delta` where the method gives one (its probes), else rd_delta_radiance_eq. Call at the end of
 * the method's prepare (ctx->state set: the pilot renders with the method's scratch). */
rd_status rd_select_prepare(const rd_render_ctx *ctx, rd_select_fn method, rd_select_delta_fn delta,
                            double cell_cost, int options, rd_select *sel, char *err, size_t errlen);
/* rd_select_prepare with one more estimator, the last: `path`, with `path_cell_cost` a PDF
 * segment it counts in rd_thread.cells (NULL: rd_select_prepare). Every estimator must be
 * unbiased for the same image (`guided`: guided-unbiased's paths, integrators/guided.c). */
rd_status rd_select_prepare_path(const rd_render_ctx *ctx, rd_select_fn method, rd_select_delta_fn delta,
                                 double cell_cost, int options, rd_select_fn path, double path_cell_cost,
                                 rd_select *sel, char *err, size_t errlen);
/* The method's further estimators (NULL: none): `path` (RD_SEL_PATH, its PDF segments at
 * path_cell_cost) and `beams` (RD_SEL_BEAMS, consistent: the same image up to the kernel's bias,
 * which shrinks with the passes; its PDF segments at the method's cell_cost; with RD_SELECT_PASSES
 * its samples, not the method's, carry the passes' share). */
typedef struct {
    rd_select_fn path;
    double path_cell_cost;
    rd_select_fn beams;
} rd_select_more;
rd_status rd_select_prepare_more(const rd_render_ctx *ctx, rd_select_fn method, rd_select_delta_fn delta,
                                 double cell_cost, int options, const rd_select_more *more, rd_select *sel,
                                 char *err, size_t errlen);
/* rd_select_prepare's options (bits): the third estimator wanted (above); the method is delta's own
 * path with the strategy on every flight (`delta`'s "tiles": one of delta's paths,
 * rd_select.paths); the samples of rd_select.pass_kind (the beams estimator where there is one,
 * else the method) consume the progressive photon passes (a pass serves photons.pass_spp x the
 * image's pixels of them): each adds its share of pass 1's work to its cost
 * (rd_select.method_pass_cost: ctx's pass_emitted, pass_collisions and pass_indexed, at the weights
 * below; select.c, "The photon passes"); with RD_SELECT_PASSES_ORDERED too, the passes after the
 * first put their photons in spatial order without a kd-tree (RD_PASS_NO_INDEX: nee+beams), and a
 * photon counts RD_SELECT_COST_ORDERED instead of RD_SELECT_COST_INDEXED (pass_indexed at most
 * pass_emitted where those passes are thinned: render.c, RD_PASS_THIN). A selection with epochs
 * takes shares (rd_select.share) where settings.adaptive is true, "pilot" or "epochs", or "auto"
 * and the method asks: RD_SELECT_SHARES_AUTO (`guided`: true), RD_SELECT_UNBIASED_SHARES_AUTO ("epochs"). */
enum { RD_SELECT_THIRD = 1, RD_SELECT_METHOD_IS_PATH = 2, RD_SELECT_PASSES = 4, RD_SELECT_PASSES_ORDERED = 8,
       RD_SELECT_SHARES_AUTO = 16, RD_SELECT_UNBIASED_SHARES_AUTO = 32 };
/* A progressive pass's work, in density lookups: a photon emitted, a tentative collision, a
 * photon indexed (stored and built into a kd-tree), a photon stored and put in order alone (the
 * indexed photon's weight less what the kd-tree cost on the calibration scenes: 0.152 us of
 * 0.450, docs/benchmarks.md "Session 56"). */
#define RD_SELECT_COST_EMITTED 0.87
#define RD_SELECT_COST_COLLISION 0.64
#define RD_SELECT_COST_INDEXED 2.75
#define RD_SELECT_COST_ORDERED 1.82
void rd_select_free(rd_select *sel);
/* The camera sample of `th->pixel` (column th->x, row th->y): the estimator the selection gives
 * the pixel: `method`, the method's second estimator or the beams (rd_select.path, .beams;
 * counted in th->path_samples, th->beams_samples), or delta's path in the estimator's equiangular
 * mode (th->delta_samples, and th->delta_eq_samples for RD_SEL_DELTA_EQ). Recorded for the next
 * epoch (rd_select_pixel_done): sel is written at th->pixel only, by one thread, in sample order. */
vec3 rd_select_radiance(const rd_render_ctx *ctx, rd_select *sel, rd_select_fn method,
                        rd_thread *th, ray3 r, rd_sampler *smp);
/* After th's samples of one pixel in a pass (rd_method.pixel_done): what rd_select_radiance
 * gathered over them, with their counted cost (th's work counters' change since the first of
 * them), goes into the pixel's record for the next epoch. Without it, the thread's next pixel or
 * the next epoch writes it, reading th's counters then: th must live, unreset, until then. */
void rd_select_pixel_done(rd_select *sel, const rd_thread *th);
/* Record one sample L of `pixel`, with its counted cost (in lookups; kept in whole units of
 * 1/RD_SELECT_COST_UNIT), for the next epoch. */
void rd_select_observe(rd_select *sel, uint64_t pixel, vec3 L, double cost);
/* The image's epochs: the choice is made again at samples 4, 16, 64, ... (x4) of every pixel
 * from everything seen so far. rd_select_epoch_next: the first epoch boundary after `sample`
 * (INT_MAX: none); rd_select_epoch: fold the pixels' samples into their tiles' statistics and
 * choose again (no-op when the selection is off), for a render that ends as `end` says
 * (rd_render_ctx.epoch_ahead and epoch_left; NULL or both 0: no end known, and the rule weighs
 * the samples to come alone: select_rule.c). */
int rd_select_epoch_next(const rd_select *sel, int sample);
/* With comm (several ranks, each with the samples of the pixels it renders and zeros elsewhere),
 * the pixels' samples are first summed over the ranks (exactly: one rank holds each pixel's), so
 * every rank makes the same choice as one process: collective, at the same epoch on every rank. */
void rd_select_epoch(rd_select *sel, const rd_comm *comm, const rd_select_end *end);
/* The trial (select_rule.c, "Evidence of unequal size"): a tile moves to another estimator at
 * once only when that one's samples in the tile are at least 1 / RD_SELECT_TRIAL_RATIO of the
 * current one's and the tile's halves agree on it, or when it leaves the beams while the image
 * reads their bias ("Off the biased beams at once"); else it goes on trial for one epoch first. */
#define RD_SELECT_TRIAL_RATIO 4

/* The image's samples so far, for the rule (select_rule.c, "The samples the image holds"): P,
 * the sum over the pixels of their samples' variances (the squared error of their means times
 * n0^2), n0 the samples a pixel, T0 their counted cost; and the render's end: with left > 0 it
 * ends left samples a pixel from now, else R (in the units of the rule's costs) from now, and
 * then w weighs a consistent estimator's squared bias: the squared share of the mean at the end
 * that the samples to come make at the image's pace so far ("The beams' bias"; 0: none). */
typedef struct {
    double P, n0, T0, R, left, w;
} rd_select_past;

/* The rule: for n tiles with the per-sample variance and cost of each of the m estimators
 * (var[m k + e], cost[m k + e], e = 0 .. m-1, as sums over each tile's pixels), the choices
 * that minimise (sum V)(sum C), or with `past` (may be NULL) the image's squared error at the
 * end of the time left, (P + a sum V) / (n0 + a)^2 + w sum B with a = R / sum C and w =
 * past->w, or where the render ends at a sample count (past->left > 0) that error times the
 * render's time, (P + left sum V + left^2 sum B)(T0 + left sum C); B the squared bias a
 * consistent estimator's samples add (bias[m k + e], a sum over the tile's pixels; NULL: none),
 * which only a known end weighs; choice[k] the estimator of tile k. */
void rd_select_choose(const double *var, const double *cost, const double *bias, int n, int m, const rd_select_past *past,
                      uint8_t *choice);
/* With shares of the samples (settings.adaptive; select_share.c, "Samples where they pay"): the
 * choices that minimise (sum sqrt(V C))^2, at a deadline (past->R > 0, no left) (sum sqrt(V
 * C))^2 / R + sum B; the arguments as rd_select_choose's (not its P, n0, T0, left or w). */
void rd_select_choose_adaptive(const double *var, const double *cost, const double *bias, int n, int m,
                               const rd_select_past *past, uint8_t *choice);
/* After a choice (neither weights nor blocks, "pilot": the pilot's alone), the shares and weights
 * from st (all tiles' samples) and the rule's pooled figures; none without shares. Tile: <= 64 px. */
void rd_select_set_shares(rd_select *sel, const rd_select_stats *st, const double *var, const double *cost);
double rd_select_tile_pixels(const rd_select *sel, int tx, int ty);

/* Every tile's estimator (sel->choice, sel->trial, and sel->unlit at the first call) from the
 * statistics of its two halves so far, sel->stats (select_rule.c): at the pilot's end (end
 * NULL) and at each epoch, for a render that ends as `end` says (NULL: no end known), and with
 * rd_select.share the shares. Out of memory: the choices stay as they are. */
void rd_select_choose_tiles(rd_select *sel, const rd_select_end *end);

#endif /* RD_SELECT_H */
