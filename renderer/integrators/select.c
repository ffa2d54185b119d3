/* select.c: the guided methods' choice, per tile of the image, between the method (the
 * marcher of `guided`, the guided paths of `guided-unbiased`) and delta's path
 * (settings.select "tiles", or "auto", the default; docs/guided-marching.md "Where marching
 * pays"), and a third estimator where there is one (below).
 *
 * Both are unbiased estimators of the radiance along a camera ray, so any choice made for a
 * pixel's sample before the sample is drawn keeps the image unbiased. The guided method wins
 * where the light along the ray is concentrated (a sample there costs several delta paths and
 * has far less variance); delta wins where it is broad (a camera ray that passes through thin
 * smoke costs delta almost nothing).
 *
 * What the choice is made from. Per tile of RD_SELECT_TILE x RD_SELECT_TILE pixels and per
 * estimator, the samples' statistics (rd_select_stats): their variance V per sample and their
 * cost C per sample. They come first from a pilot, on random numbers of its own: every other
 * pixel each way, SEL_SPP samples of each estimator (the beams fewer where they contend for
 * nothing: below, "The beams' pilot in two stages"). Then the image itself teaches: at samples
 * 4, 16, 64, ... of every pixel (the epochs) the samples the image took since the last epoch,
 * each pixel's of the estimator its tile gave it (rd_select_uses), are added to that
 * estimator's statistics and the choice is made again. A pilot of a few hundred samples a tile
 * misjudges heavy tails (the rare delta path that finds a narrow beam, the rare guided path
 * that carries a firefly); the image's thousands do not, and the estimator a tile uses is the one whose statistics grow. Each
 * epoch's choice depends only on samples drawn before it, so every sample is still an unbiased
 * estimate given the past, and so is each pixel's mean of a fixed number of them.
 *
 * The third estimator (session 24; its mode since session 25). The methods' own paths and
 * samples take `delta`'s equiangular strategy in their own mode (march.equiangular "auto" by
 * default; guide.equiangular "auto", and "false" where the selection runs since session 39),
 * while delta's path takes settings.equiangular ("tiles" read as off; off by default: "auto"
 * costs 4-38% of the time where it samples nothing, docs/free-path.md and docs/benchmarks.md
 * "Session 24"). On a narrow spot across thin fog `delta` with "auto" is 34x plain `delta`
 * and beat both methods (docs/benchmarks.md, session 23): what the methods gained there came
 * from the strategy, and their own estimators cost 3.5-11x a delta path for the same
 * variance. So where the method samples with the strategy (its mode not "false";
 * guided-unbiased always since session 39, whatever its own flights take: with the selection
 * they take none by default, where "auto" cost more than it gave on hard-dense-block, and the
 * third estimator carries the strategy's gains: docs/guided-unbiased.md "The equiangular
 * strategy"), the scene has a light the strategy samples (a point or spot light; a
 * directional beam too since session 30, below) and settings.equiangular is not "true", delta's path with
 * the strategy on every flight ("true") is a third estimator (RD_SEL_DELTA_EQ) with statistics
 * of its own, and every rule of select_rule.c runs over the three: each tile gets delta's path with or
 * without the strategy, or the method, whichever pays there. Why "true" and not the method's
 * "auto": "auto" is a choice for a whole image, which bounds the loss where the strategy has
 * nothing to win (the dense smoke of default) by giving up part of the gain where it has (a
 * point light over a thick span: homogeneous, `true` 1.39x plain `delta` against "auto"'s
 * 0.95x; the flights whose lit span lies behind the medium: the narrow spot, 75x against 39x;
 * docs/free-path.md). Per tile the selection bounds the loss itself, so it can take the
 * strategy at full strength where it pays. Measured at 10 s (docs/benchmarks.md, "Session
 * 25"): on cloud and hetero-forward the same as with "auto" within the runs' spread (neither
 * pays there), `guided-unbiased` on glass-fog 15% lower (9.3x -> 7.9x, the edge of the spread;
 * both against a plain `delta` reference as noisy as the runs: docs/benchmarks.md "Session 26");
 * on the narrow spot `guided` went from 25x to 65x plain `delta`, on homogeneous from 1.10x to
 * 1.53x (the same session's runs). The pilot samples it too (with "auto" as the third: prepare_seconds 0.12
 * against 0.09 for two estimators, default, 160x120, two threads, `render --spp 1`; 0.3% of a
 * 10-s render), and a trial between any two of them puts the higher-numbered one on the odd
 * squares (with two estimators: the method, as before). All three are unbiased for the same
 * image, so the mix is too (tests/test_select.c). Its cost counts one more kind of work: the
 * flights' equiangular set-up (rd_track_counters.eq_flights, weight 0.40 lookups, below); the
 * samples it then draws count as the lookups and shadow rays they are.
 *
 * A second estimator of the method's (session 50). `guided`'s selection holds guided-unbiased's
 * paths too (march.guided_paths; integrators/guided.c), after the third (rd_select.kind):
 * where light is broad and multiple scattering carries it (a dense, bright block; smoke lit by a
 * spot) they beat delta's path, and the marcher does not, so `guided` lost to `delta` there
 * (0.73-0.99x on five scenes at 10 s) while guided-unbiased won. Its PDF segments weigh its own
 * cell cost (rd_select_prepare_path), and every rule of select_rule.c runs over the four as over three.
 *
 * How a tile's estimator is chosen from the statistics (the variance a sample and its
 * Cauchy-Schwarz bound, a dim tile's prior, trials, the two halves, the image's prediction where
 * they disagree, unlit tiles, and the rule that weighs variance against cost): select_rule.c.
 * This file draws the samples (the pilot, the image's, the epochs), counts their cost, keeps the
 * statistics and calls it (rd_select_choose_tiles).
 *
 * Beams that delta's path connects to (session 38). Where settings.beam_connect is on, delta's
 * path (and the method's) connects every scattering vertex to the scene's directional beam
 * (transport/beam_connect.c), and a flight with the strategy on every flight (RD_EQ_ALL) drops
 * those connections for the strategy's own sample of the beam's chord (transport/path.c: the two
 * would sample the same light twice). The third estimator is then the same light found the
 * weaker way, not a new strategy: on beam.json `delta` with `true` made 0.40x plain `delta`
 * (whose connections are on), yet guided-unbiased's selection gave it tiles (a fifth of the
 * samples of a 64-spp render), its pilots misled by heavy tails, and the method made 0.78x
 * plain `delta` (docs/benchmarks.md "Session 38"; 1.30x without the third). So a beam makes
 * a third estimator only where delta's path does not connect to it (rd_eq_tiles_have_lights,
 * which compare's rendered reference asks too); a point or spot light still does (a scene with
 * both keeps the third, whose flights then drop the connections: not measured, no shipped
 * scene has both).
 *
 * The trace (session 44). `render --select-trace FILE` writes every choice with each tile's
 * figures (select_trace.c; docs/cli.md), which bench/bench_select_score scores against fixed
 * per-pixel variance tables: rules compared by their choices alone (docs/benchmarks.md "Session 44").
 *
 * A consistent method. The marcher with march.ls nee+beams is consistent, not unbiased: its
 * photon part carries the kernel's bias (shrinking with the progressive passes). It mixes with
 * delta's path only when settings.select names "tiles" or "pilot" (the default "auto" marches
 * every pixel with it). The choice compares that method's variance and cost only, so it does
 * not see that bias (the fifth estimator's it reads: below); a tile it gives to delta's path sheds the bias with the marcher, and where a beam tile
 * meets a delta tile a seam of the bias's size can show. Nor does it see the photon passes'
 * own noise: the samples of one pass share its photons, so what the photons add to the error
 * is common to them and absent from their variance about the pixel's mean (more so as a
 * marched pixel takes more samples per pass when tiles go to delta, render.c); the choice
 * leans toward the beams by that much. Tried and not kept: counting the bias,
 * estimated in the pilot from the two means' difference beyond three standard errors, against
 * the method at the next epoch's sample count: delta's pilot mean is low where its paths rarely
 * find the light (a tail its 128 samples a tile do not show, out of the Cauchy-Schwarz bound's
 * reach where the tile is lit otherwise too), so the gap read as bias where the beams were right
 * (beam.json: the beam's tiles went to delta, variance a sample 1.8e-4 against 8.5e-5, 32 spp).
 *
 * A fifth estimator: the beams (session 57). With march.beams `guided`'s selection holds, last,
 * the marcher with the nee+beams source (rd_select_more's `beams`, RD_SEL_BEAMS; guided.c), on
 * photon passes of its own: its samples, not the method's, consume them (rd_select.pass_kind:
 * they carry the passes' share and their pixels pace the passes, rd_select_pass_pixels). It is
 * consistent, as the nee+beams marcher is (below), and the rule weighs it as it weighs the others
 * (docs/guided-marching.md "The beams beside the marcher": where it loses, and a bias term tried),
 * and since session 64 its bias too, which each of its samples estimates (select_rule.c, "The
 * beams' bias": the sample's gap, estimate(), summed per pixel over the epochs in rd_select.gaps
 * and read by bias_fold).
 *
 * The beams' pilot in two stages (session 60). A beams sample marches the whole ray and queries
 * the photon balls along it: 50-75 us of one thread on sphere-in-fog, where the pilot's 38400 of
 * them (SEL_SPP a pilot pixel) took ~1 s of a 10-s render's 2 threads for tiles the beams then
 * won none of: `guided` with march.beams made 0.69-0.82x `guided` without there (docs/benchmarks.md
 * "Session 60"). So the beams draw SEL_SPP_BEAMS_FIRST samples of every pilot pixel first; the
 * rule runs on what the pilot has then (beams_contend), and the beams draw the rest of their
 * SEL_SPP only in the tiles it gives them or puts them on trial in, and those tiles' 3x3
 * neighbours (the reach of the figures' pooling; the image-wide parts, the non-zero prior and the
 * predicted variance where halves disagree, read every tile); then the rule chooses as always. A
 * tile whose beams pilot is whole has the statistics of a pilot of one stage, to the bit (the
 * records are kept in the image's pixel records until folded, in the same order); elsewhere the
 * beams enter the first choice with 16 samples a half tile instead of 64 (enough for the trial's
 * evidence ratio against the 64 of the tile's estimator: a move to them there is made at once,
 * as before, and at the epochs goes through a trial first, as before). Their samples count in the others'
 * dim-tile prior too (select_rule.c: the hits a tile's estimators saw against those expected), so
 * where the beams contend for no tile the others' choices can differ from a pilot of one stage
 * (hard-window-beam's pilot: 94 tiles to plain delta against 60, 200 to delta with the strategy
 * against 233).
 *
 * The photon passes (session 53). A pass is traced for every pass_spp x (all pixels) beam samples
 * (render.c), time no counter sees: each beam sample's cost carries its share of pass 1's work
 * (RD_SELECT_PASSES, sample_fixed_units; weights fitted on the calibration scenes, docs/benchmarks.md
 * "Session 53"; not counted: the beams' set-up a pass, ~14%, the one-thread kd-tree, R ranks' R x).
 * Since session 56 the beams' passes after the first build no kd-tree (RD_PASS_NO_INDEX, their
 * photons only put in spatial order), and their photons count RD_SELECT_COST_ORDERED
 * (RD_SELECT_PASSES_ORDERED; pass 1's counts stand for every pass's). Since session 62 those
 * passes are thinned as traced (RD_PASS_THIN), so the photons ordered a pass are counted as at
 * most the photons emitted (render.c photon_pass); the collisions, still all traced, are not.
 *
 * The cost. Time is not deterministic, and the choice must be (for one build, the same seed
 * gives the same image on any machine and thread count), so C is counted: the work a sample
 * did, weighted by what each kind of work costs. Per camera sample, in units of one density
 * lookup (c, below: the weights):
 *   C = lookups + c_S shadow rays + c_cell PDF segments + c_V guided vertices + c_0,
 * with the PDF segments the marcher's (guide cells and extinction steps per camera ray) or
 * guided-unbiased's (its flights' distance-pdf segments), whose weights differ (a marcher's
 * segment evaluates SH, a flight's is a lookup in a built table), and the guided vertices
 * guided-unbiased's (its vertex policy reads the guide and samples a lobe). The weights are a
 * least-squares fit of time per camera sample (weighted by its inverse: relative errors) on
 * six scenes that are not in the benchmark's tables, each rendered by delta, guided and
 * guided-unbiased with select off, 160x120, 16 spp, one thread: cloud, smoke-vdb, glass-fog,
 * sphere-in-fog, hetero-forward and noise-block. In microseconds: lookup 0.164, shadow ray
 * 0.322, marcher segment 0.249, flight segment 0.061, guided vertex 0.763, camera sample
 * 0.358. Checked, not fitted, on hard-dense-block and hard-lens-caustic: the method's time
 * over delta's per sample is 3.73 / 28.9 (guided / guided-unbiased) and 6.29 / 8.74 there,
 * the model says 4.10 / 24.1 and 6.67 / 8.13 (the model before said about half: the methods
 * got tiles at half their cost). When guided-unbiased came to read two SH bands instead of eight
 * (guide.eval_bands), its two weights were fitted again on the same six scenes, the other
 * weights held (the render report's guided_paths gives the counts): flight segment 0.37 ->
 * 0.41, guided vertex 4.65 -> 3.91 lookups. On the two checks: 19.96 / 7.30 measured, 19.3 /
 * 7.8 modelled (the old weights: 21.1 / 8.1). The beam estimate (march.ls nee+beams) adds
 * c_H per ball its segments' queries crossed, fitted with the other weights held
 * (bench/bench_cost_fit.sh FIT=beams; guided with nee+beams, one fixed map, on the same six
 * scenes): 0.098 us, 0.60 lookups; the model within 0.90-1.09 of each scene's time. The
 * equiangular set-up (the third estimator's extra work where it samples nothing) is fitted on
 * the paired difference of `delta` with settings.equiangular "auto" and "false", the other
 * weights held (bench/bench_cost_fit.sh FIT=eq; 32 spp, three rounds, on the calibration scenes
 * with a point or spot light, cloud, glass-fog and hetero-forward): 0.097 us, 0.59 lookups a
 * set-up, the model within 0.99-1.02 of the three; checked, not fitted: hard-dense-block 0.93
 * (its spot's cone cuts cost more than the mean), default 0.99, hard-narrow-spot 1.24. Fitted
 * again when the set-up stopped searching the flight's media a second time (session 25: the
 * path loop finds them once for the flight and the set-up): 0.065 us, 0.40 lookups, the model
 * within 0.99-1.02 of the three; checked, not fitted: default 0.74, hard-dense-block 1.79,
 * hard-narrow-spot 1.31 (differences of 0.07-0.11 us a sample between two noisy times). Since
 * session 43 a pixel's record holds its cost in whole units of 1/RD_SELECT_COST_UNIT lookup (the
 * weights rounded to them), from the counters' change over each run of a thread's samples of
 * the pixel (rd_select_run), the samples the film drops included: their time was spent. */
#include "integrators/rd_select.h"
#include "transport/rd_path.h"

#include <limits.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#define SEL_SPP 8           /* pilot samples per pixel and estimator */
#define SEL_SPP_BEAMS_FIRST 2 /* the beams' pilot samples per pixel in every tile (the head) */
/* The cost weights, in density lookups (see the head): */
#define SEL_COST_SHADOW 1.96   /* a shadow ray (its own lookups are counted as lookups) */
#define SEL_COST_SAMPLE RD_SELECT_COST_SAMPLE /* a camera sample: its rays, shapes and set-up */
#define SEL_COST_VERTEX 3.91   /* a guided-unbiased vertex that read the guide */
#define SEL_COST_BEAM_HIT 0.60 /* a ball a segment's query crossed (march.ls nee+beams) */
#define SEL_COST_EQ_FLIGHT 0.40 /* a flight's equiangular set-up (its choice of lights) */
#define SEL_EPOCH_FIRST 4   /* the first epoch ends at sample 4 of every pixel, */
#define SEL_EPOCH_GROWTH 4  /* and each is 4 times the last: 4, 16, 64, 256, ... */
/* The pilot's random numbers: the image's keys (pixel, sample, seed) with the seed moved by a
 * constant, so no pilot sample is one of the image's. */
#define SEL_SEED_SHIFT 0x5E1EC7ULL
/* A weight in whole units of 1/RD_SELECT_COST_UNIT lookups (a relative change under 2e-5). A
 * pixel's record keeps its cost in these units: the work counters' changes times the weights,
 * summed in integers, so the record is the same whichever runs of samples it is summed over,
 * and a run's cost is read from the counters once, at its end (rd_select_run). The unit is a
 * power of two: scaling a double by it is exact. */
static uint64_t cost_units(double w)
{
    return (uint64_t)llround(w * RD_SELECT_COST_UNIT);
}
/* A sample of e beyond the counters: its rays and set-up, and for the kind whose samples consume
 * the photon passes (rd_select.pass_kind) its share of them. */
static uint64_t sample_fixed_units(const rd_select *sel, int e)
{
    return cost_units(SEL_COST_SAMPLE + (sel->kind[e] == sel->pass_kind ? sel->method_pass_cost : 0.0));
}

/* Add one finite sample L to a pixel's record (its cost is added apart: the work of the
 * samples the film drops counts too); a beams sample's gap on photon pass `pass` to its gaps g
 * (pass < 0: none, the other estimators; g is NULL only where no estimator has a pass). */
static void pixel_add(rd_select_pixel *px, rd_select_gaps *g, vec3 L, vec3 gap, int pass)
{
    const double v[3] = {L.x, L.y, L.z};
    for (int c = 0; c < 3; c++) { /* float sums, as they always were: the same choices */
        px->sum[c] = (float)px->sum[c] + (float)v[c];
        px->sum2[c] = (float)px->sum2[c] + (float)(v[c] * v[c]);
    }
    if (pass >= 0 && g) g->gap[pass & 3] += (gap.x + gap.y + gap.z) / 3.0, g->gap_n[pass & 3]++;
    px->nonzero += L.x != 0.0 || L.y != 0.0 || L.z != 0.0;
    px->n++;
}

/* Add one pixel's samples (all of one estimator) to that estimator's statistics in its tile,
 * with their gaps g (NULL: none). */
static void pixel_fold(rd_select_stats *st, const rd_select_pixel *px, const rd_select_gaps *g)
{
    st->cost += px->cost / RD_SELECT_COST_UNIT; /* (exact: a power of two; the dropped samples' too) */
    if (px->n == 0) return;
    double n = px->n;
    for (int c = 0; c < 3; c++) {
        double s = px->sum[c];
        st->sum[c] += s;
        st->dev2[c] += fmax(0.0, (double)px->sum2[c] - s * s / n);
    }
    if (g) st->gap += g->gap[0] + g->gap[1] + g->gap[2] + g->gap[3];
    st->n += n;
    st->dof += n - 1.0;
    st->nonzero += px->nonzero;
}

/* One thread's samples of the pixel it renders now (rd_select_radiance), since its first of
 * this pass: the pixel's record as it stood with these samples added (the sums in float, added
 * in pixel_add's order), how many samples it drew (the dropped ones too), the estimator the
 * pixel uses (its tile's choice, which changes only at an epoch), and the thread's work
 * counters at the run's first sample. Written back once (run_close), with the run's cost from
 * the counters' change over it (work_units): a sample reads neither the counters nor the tile
 * nor the record in memory. The cost is a whole number of units, so the record is the same to
 * the bit however the passes split the pixel's samples. On hard-narrow-spot, with every tile
 * forced to the strategy, `delta`'s "tiles" took 8% longer than `true` per sample when every
 * sample was recorded on its own, 6% when a sample read and weighed the counters
 * (docs/benchmarks.md "Session 42", "Session 43"). A thread that is not one of the render's
 * (rd_threads_new: its index picks its run) must call rd_select_pixel_done before another thread
 * renders the pixel, and stay alive until it does or until rd_select_epoch. */
typedef struct rd_select_run {
    _Alignas(RD_CACHE_LINE) float sum[3], sum2[3];
    double n, nonzero, gap[4], gap_n[4];
    uint64_t drawn;       /* the run's samples, finite or not */
    rd_select_work c;     /* the counters at the run's first sample */
    const rd_thread *th;  /* the thread whose counters c read; NULL: no run open */
    uint64_t pixel;
    int use;
} rd_select_run;

static void run_open(rd_select *sel, rd_select_run *u, const rd_thread *th)
{
    const rd_select_pixel *px = &sel->pixels[th->pixel];
    for (int c = 0; c < 3; c++) u->sum[c] = (float)px->sum[c], u->sum2[c] = (float)px->sum2[c]; /* exact */
    const rd_select_gaps *g = sel->pixel_gaps ? &sel->pixel_gaps[th->pixel] : NULL;
    for (int i = 0; i < 4; i++) u->gap[i] = g ? g->gap[i] : 0.0, u->gap_n[i] = g ? g->gap_n[i] : 0.0;
    u->n = px->n, u->nonzero = px->nonzero, u->drawn = 0;
    u->c = rd_select_work_now(th);
    u->th = th, u->pixel = th->pixel;
    u->use = rd_select_uses(sel, th->x, th->y);
}

static uint64_t work_units(const rd_select *sel, int e, const rd_select_work *c0, const rd_select_work *c1);

static void run_close(rd_select *sel, rd_select_run *u)
{
    if (!u->th) return;
    rd_select_pixel *px = &sel->pixels[u->pixel];
    for (int c = 0; c < 3; c++) px->sum[c] = u->sum[c], px->sum2[c] = u->sum2[c];
    if (sel->pixel_gaps)
        for (int i = 0; i < 4; i++) sel->pixel_gaps[u->pixel].gap[i] = u->gap[i], sel->pixel_gaps[u->pixel].gap_n[i] = u->gap_n[i];
    px->n = u->n, px->nonzero = u->nonzero;
    rd_select_work c1 = rd_select_work_now(u->th);
    px->cost += (double)(work_units(sel, u->use, &u->c, &c1) + u->drawn * sample_fixed_units(sel, u->use)); /* exact */
    u->th = NULL;
}

/* The statistics of the half pixel (x, y)'s samples count in, [n k + e] (select_rule.c,
 * "Replication"): 2x2 blocks of pixels in a checkerboard, so that a tile's pilot pixels (every
 * other pixel each way) and a trial's checkerboard of pixels fall evenly into both halves. */
static rd_select_stats *half_stats(rd_select *sel, int x, int y)
{
    int h = ((x >> 1) + (y >> 1)) & 1;
    return sel->stats + (size_t)h * sel->n * sel->tiles_x * sel->tiles_y;
}

rd_select_work rd_select_work_now(const rd_thread *th)
{
    return (rd_select_work){th->counters.lookups, th->counters.shadow_rays, th->cells, th->guide_vertices,
                            th->beam_hits, th->counters.eq_flights};
}

/* What one PDF segment (rd_thread.cells) of estimator e costs, in lookups: the method's
 * (cell_cost), or its second estimator's (path_cell_cost); delta's paths count none. */
static double cells_cost(const rd_select *sel, int e)
{
    return sel->kind[e] == RD_SEL_PATH ? sel->path_cell_cost : sel->cell_cost;
}

/* The weighted work between two readings of a thread's counters, c0 then c1. */
static double work_between(const rd_select_work *c0, const rd_select_work *c1, double cell_cost)
{
    return (double)(c1->lookups - c0->lookups) + SEL_COST_SHADOW * (double)(c1->shadow_rays - c0->shadow_rays) +
           cell_cost * (double)(c1->cells - c0->cells) + SEL_COST_VERTEX * (double)(c1->vertices - c0->vertices) +
           SEL_COST_BEAM_HIT * (double)(c1->beam_hits - c0->beam_hits) +
           SEL_COST_EQ_FLIGHT * (double)(c1->eq_flights - c0->eq_flights);
}

double rd_select_work_cost(const rd_select_work *c0, const rd_thread *th, double cell_cost)
{
    rd_select_work c1 = rd_select_work_now(th);
    return work_between(c0, &c1, cell_cost);
}

/* work_between in whole units of 1/RD_SELECT_COST_UNIT lookups (cost_units) for estimator e's
 * samples, the camera sample's own left out. */
static uint64_t work_units(const rd_select *sel, int e, const rd_select_work *c0, const rd_select_work *c1)
{
    return (c1->lookups - c0->lookups) * cost_units(1.0) + (c1->shadow_rays - c0->shadow_rays) * cost_units(SEL_COST_SHADOW) +
           (c1->cells - c0->cells) * cost_units(cells_cost(sel, e)) + (c1->vertices - c0->vertices) * cost_units(SEL_COST_VERTEX) +
           (c1->beam_hits - c0->beam_hits) * cost_units(SEL_COST_BEAM_HIT) +
           (c1->eq_flights - c0->eq_flights) * cost_units(SEL_COST_EQ_FLIGHT);
}

/* One sample of estimator e's counted cost in units, from th's counters before it (c0) and after. */
static uint64_t sample_units(const rd_select *sel, int e, const rd_thread *th, rd_select_work c0)
{
    rd_select_work c1 = rd_select_work_now(th);
    return work_units(sel, e, &c0, &c1) + sample_fixed_units(sel, e);
}

/* Camera sample `smp` of ray r with estimator e (0 .. sel->n - 1, of kind sel->kind[e]); for
 * the beams *gap their gap (rd_thread.beam_gap; select_rule.c, "The beams' bias") and *pass the
 * photon pass it read, for the others *pass -1. */
static vec3 estimate(const rd_render_ctx *ctx, const rd_select *sel, rd_thread *th, int e,
                     rd_select_fn method, ray3 r, rd_sampler *smp, vec3 *gap, int *pass)
{
    *gap = v3(0, 0, 0), *pass = -1;
    if (sel->kind[e] == RD_SEL_METHOD) return method(ctx, th, r, smp);
    if (sel->kind[e] == RD_SEL_PATH) return sel->path(ctx, th, r, smp);
    if (sel->kind[e] == RD_SEL_BEAMS) {
        th->want_gap = !th->pilot && sel->epochs; /* (the pilot's read pass 1 only: no product) */
        vec3 L = sel->beams(ctx, th, r, smp);
        th->want_gap = 0;
        /* the gap at pass 1's radius, taken to grow as the radius (select_rule.c, "The beams' bias") */
        const double s = ctx->radius_scale > 0.0 ? ctx->radius_scale : 1.0;
        if (v3_finite(th->beam_gap)) *gap = v3_scale(th->beam_gap, 1.0 / s), *pass = ctx->photon_pass;
        return L;
    }
    int mode = sel->kind[e] == RD_SEL_DELTA_EQ ? RD_EQ_ALL : rd_eq_path_mode(ctx->scene->settings.equiangular);
    if (sel->delta) return sel->delta(ctx, th, r, smp, mode); /* the method's (its probes) */
    pcg32 rng = rd_sampler_stream(smp);
    return rd_delta_radiance_eq(ctx->scene, r, mode, &rng, &th->counters);
}

/* Pilot samples [i0, i1) of pixel (x, y) with estimator e, added to the record px and gaps g. */
static void pilot_samples(const rd_render_ctx *ctx, rd_thread *th, const rd_select *sel, int x, int y,
                          int e, rd_select_fn method, int i0, int i1, rd_select_pixel *px, rd_select_gaps *g)
{
    const rd_scene *s = ctx->scene;
    const rd_camera *cam = &s->camera;
    uint64_t pix = (uint64_t)y * cam->width + x;
    for (int i = i0; i < i1; i++) {
        rd_sampler smp = rd_sampler_start(pix, (uint64_t)i, ctx->seed + SEL_SEED_SHIFT);
        double jx = rd_sampler_1d(&smp), jy = rd_sampler_1d(&smp);
        if (!cam->jitter) jx = jy = 0.5;
        ray3 r = rd_camera_ray(cam, x + jx, y + jy);
        rd_select_work c0 = rd_select_work_now(th);
        th->pixel = pix, th->x = x, th->y = y;
        th->pilot = 1; /* (not an image sample: march.probes "auto" learns from those only) */
        vec3 gap;
        int pass;
        vec3 L = estimate(ctx, sel, th, e, method, r, &smp, &gap, &pass);
        th->pilot = 0;
        px->cost += (double)sample_units(sel, e, th, c0); /* (a dropped sample's work counts too) */
        if (v3_finite(L)) pixel_add(px, g, L, gap, pass);
    }
}

/* One pixel's pilot with estimator e: SEL_SPP samples, added to the tile's statistics. */
static void pilot_pixel(const rd_render_ctx *ctx, rd_thread *th, const rd_select *sel, int x, int y,
                        int e, rd_select_fn method, rd_select_stats *st)
{
    rd_select_pixel px = {0};
    rd_select_gaps g = {0};
    pilot_samples(ctx, th, sel, x, y, e, method, 0, SEL_SPP, &px, &g);
    pixel_fold(st, &px, &g);
}

/* The record in sel->pixels of pilot pixel (x, y), and its gaps (sel->pixel_gaps), which hold
 * the beams' pilot samples until beams_pilot_fold. */
static rd_select_pixel *pilot_record(rd_select *sel, int x, int y)
{
    return &sel->pixels[(size_t)y * sel->width + x];
}
static rd_select_gaps *pilot_gaps(rd_select *sel, int x, int y)
{
    return &sel->pixel_gaps[(size_t)y * sel->width + x]; /* (the beams': allocated with them) */
}

/* Tile k's pilot: every other pixel each way, SEL_SPP samples of each estimator into its
 * statistics; estimator b (the beams, -1: none) only its first SEL_SPP_BEAMS_FIRST, kept in the
 * pixels' records (see the head, "The beams' pilot in two stages"). */
static void pilot_tile(const rd_render_ctx *ctx, rd_thread *th, rd_select *sel, int k, rd_select_fn method, int b)
{
    int x0 = (k % sel->tiles_x) * RD_SELECT_TILE, y0 = (k / sel->tiles_x) * RD_SELECT_TILE;
    for (int y = y0; y < y0 + RD_SELECT_TILE && y < sel->height; y += 2)
        for (int x = x0; x < x0 + RD_SELECT_TILE && x < sel->width; x += 2)
            for (int e = 0; e < sel->n; e++) { /* (of kind sel->kind[e]) */
                if (e == b)
                    pilot_samples(ctx, th, sel, x, y, e, method, 0, SEL_SPP_BEAMS_FIRST, pilot_record(sel, x, y),
                                  pilot_gaps(sel, x, y));
                else pilot_pixel(ctx, th, sel, x, y, e, method, &half_stats(sel, x, y)[sel->n * k + e]);
            }
}

/* The rest of the beams' pilot samples, SEL_SPP_BEAMS_FIRST .. SEL_SPP, in tile k. */
static void pilot_tile_beams_rest(const rd_render_ctx *ctx, rd_thread *th, rd_select *sel, int k, rd_select_fn method, int b)
{
    int x0 = (k % sel->tiles_x) * RD_SELECT_TILE, y0 = (k / sel->tiles_x) * RD_SELECT_TILE;
    for (int y = y0; y < y0 + RD_SELECT_TILE && y < sel->height; y += 2)
        for (int x = x0; x < x0 + RD_SELECT_TILE && x < sel->width; x += 2)
            pilot_samples(ctx, th, sel, x, y, b, method, SEL_SPP_BEAMS_FIRST, SEL_SPP, pilot_record(sel, x, y),
                          pilot_gaps(sel, x, y));
}

/* The beams' pilot records (estimator b) folded into their tiles' statistics, in pilot_tile's
 * order (so the sums are those of a pilot of one stage, to the bit); with `clear` the records
 * emptied for the image. */
static void beams_pilot_fold(rd_select *sel, int b, int clear)
{
    for (int k = 0; k < sel->tiles_x * sel->tiles_y; k++) {
        int x0 = (k % sel->tiles_x) * RD_SELECT_TILE, y0 = (k / sel->tiles_x) * RD_SELECT_TILE;
        for (int y = y0; y < y0 + RD_SELECT_TILE && y < sel->height; y += 2)
            for (int x = x0; x < x0 + RD_SELECT_TILE && x < sel->width; x += 2) {
                rd_select_pixel *px = pilot_record(sel, x, y);
                rd_select_gaps *g = pilot_gaps(sel, x, y);
                pixel_fold(&half_stats(sel, x, y)[sel->n * k + b], px, g);
                if (clear) memset(px, 0, sizeof *px), memset(g, 0, sizeof *g);
            }
    }
}

/* Which tiles the beams (estimator b) contend for after their pilot's first stage: the rule on
 * the statistics so far gives them the tile or puts them on trial there, or in one of its 3x3
 * neighbours (the figures' pooling); contend[k] 1 for those. The selection's choices, trials,
 * statistics, unlit estimator and bias figures are as before the call, and no weight set (its
 * shares are the dry run's, which the pilot's own choice sets anew). Out of memory (here or in the rule,
 * which then leaves unlit unset): every tile contends. */
static void beams_contend(rd_select *sel, int b, uint8_t *contend)
{
    int nx = sel->tiles_x, ny = sel->tiles_y, n = nx * ny;
    size_t bytes = 2 * (size_t)sel->n * n * sizeof *sel->stats;
    rd_select_stats *keep = malloc(bytes);
    uint8_t *choice = malloc(2 * (size_t)n); /* the choices and the trials */
    if (!keep || !choice) {
        free(keep), free(choice);
        memset(contend, 1, (size_t)n);
        return;
    }
    memcpy(keep, sel->stats, bytes);
    memcpy(choice, sel->choice, (size_t)n), memcpy(choice + n, sel->trial, (size_t)n);
    const int unlit = sel->unlit;
    const double bias[3] = {sel->bias_ratio, sel->bias_se, sel->bias_r2};
    beams_pilot_fold(sel, b, 0);
    sel->unlit = -1; /* (the rule sets it where it runs) */
    rd_select_choose_tiles(sel, NULL);
    memset(contend, sel->unlit < 0, (size_t)n);
    for (int k = 0; k < n && sel->unlit >= 0; k++) {
        if (sel->choice[k] != b && sel->trial[k] != 1 + b) continue;
        int tx = k % nx, ty = k / nx;
        for (int y = ty - 1; y <= ty + 1; y++)
            for (int x = tx - 1; x <= tx + 1; x++)
                if (x >= 0 && y >= 0 && x < nx && y < ny) contend[y * nx + x] = 1;
    }
    memcpy(sel->stats, keep, bytes);
    memcpy(sel->choice, choice, (size_t)n), memcpy(sel->trial, choice + n, (size_t)n);
    if (sel->weight) memset(sel->weight, 0, (size_t)sel->n * n * sizeof *sel->weight); /* (the dry run's) */
    sel->unlit = unlit;
    sel->bias_ratio = bias[0], sel->bias_se = bias[1], sel->bias_r2 = bias[2];
    free(keep), free(choice);
}

rd_status rd_select_init(rd_select *sel, int width, int height, double cell_cost, int estimators,
                         char *err, size_t errlen)
{
    memset(sel, 0, sizeof *sel);
    sel->width = width, sel->height = height, sel->cell_cost = cell_cost, sel->epochs = 1;
    sel->n = estimators < 2 ? 2 : estimators > RD_SEL_MAX ? RD_SEL_MAX : estimators;
    for (int e = 0; e < sel->n; e++) sel->kind[e] = (uint8_t)e; /* (rd_select_prepare_more renumbers) */
    sel->paths = 1u << RD_SEL_DELTA | (sel->n >= 3 ? 1u << RD_SEL_DELTA_EQ : 0u), sel->unlit = -1;
    sel->pass_kind = RD_SEL_METHOD;
    sel->tiles_x = (width + RD_SELECT_TILE - 1) / RD_SELECT_TILE;
    sel->tiles_y = (height + RD_SELECT_TILE - 1) / RD_SELECT_TILE;
    size_t n = (size_t)sel->tiles_x * sel->tiles_y;
    sel->choice = calloc(n, 1);
    sel->trial = calloc(n, 1);
    sel->stats = calloc(2 * (size_t)sel->n * n, sizeof *sel->stats); /* two halves */
    sel->pixels = rd_alloc_lines((size_t)width * height * sizeof *sel->pixels);
    if (sel->choice && sel->trial && sel->stats && sel->pixels) return RD_OK;
    rd_select_free(sel);
    snprintf(err, errlen, "out of memory for the tile selection (%dx%d pixels)", width, height);
    return RD_ERR_NOMEM;
}

/* Count the choice just made and trace it (rd_select_trace): the pilot's governs the render's
 * samples from its first, the epochs' from SEL_EPOCH_FIRST, then each SEL_EPOCH_GROWTH times the
 * last. A failed write does not stop the render: the report keeps its error and the tracing
 * stops, so the file holds the first select_traced lines, none missing between them. */
static void traced_choice(rd_select *sel)
{
    long from = 0;
    for (int i = 0; i < sel->choices; i++) from = i == 0 ? SEL_EPOCH_FIRST : from * SEL_EPOCH_GROWTH;
    sel->choices++;
    if (sel->report) sel->report->choices++;
    if (!sel->trace_path) return;
    char err[RD_ERRLEN];
    if (rd_select_trace(sel, from, err, sizeof err) == RD_OK) {
        if (sel->report) sel->report->traced++;
    } else {
        if (sel->report) snprintf(sel->report->err, sizeof sel->report->err, "%s", err);
        sel->trace_path = NULL;
    }
}

rd_status rd_select_prepare(const rd_render_ctx *ctx, rd_select_fn method, rd_select_delta_fn delta,
                            double cell_cost, int options, rd_select *sel, char *err, size_t errlen)
{
    return rd_select_prepare_path(ctx, method, delta, cell_cost, options, NULL, 0.0, sel, err, errlen);
}

rd_status rd_select_prepare_path(const rd_render_ctx *ctx, rd_select_fn method, rd_select_delta_fn delta,
                                 double cell_cost, int options, rd_select_fn path, double path_cell_cost,
                                 rd_select *sel, char *err, size_t errlen)
{
    const rd_select_more more = {.path = path, .path_cell_cost = path_cell_cost};
    return rd_select_prepare_more(ctx, method, delta, cell_cost, options, &more, sel, err, errlen);
}

rd_status rd_select_prepare_more(const rd_render_ctx *ctx, rd_select_fn method, rd_select_delta_fn delta,
                                 double cell_cost, int options, const rd_select_more *more, rd_select *sel,
                                 char *err, size_t errlen)
{
    const rd_scene *s = ctx->scene;
    rd_select_fn path = more ? more->path : NULL, beams = more ? more->beams : NULL;
    const rd_camera *cam = &s->camera;
    /* the third estimator: delta's path with the strategy on every flight (the head; a
     * directional beam counts only where delta's path does not connect to it, "Beams that
     * delta's path connects to") */
    int third = (options & RD_SELECT_THIRD) && s->settings.equiangular != RD_EQ_ALL && rd_eq_tiles_have_lights(s);
    rd_status st = rd_select_init(sel, cam->width, cam->height, cell_cost, 2 + third + (path != NULL) + (beams != NULL),
                                  err, errlen);
    if (st != RD_OK) return st;
    /* the estimators in the order of their kinds (rd_select.kind): delta's path, the method, then
     * those of the others there are */
    int next = 2;
    if (third) sel->kind[next++] = RD_SEL_DELTA_EQ;
    if (path) sel->kind[next++] = RD_SEL_PATH, sel->path = path, sel->path_cell_cost = more->path_cell_cost;
    if (beams) sel->kind[next++] = RD_SEL_BEAMS, sel->beams = beams, sel->pass_kind = RD_SEL_BEAMS;
    const size_t np = (size_t)cam->width * cam->height;
    if (beams && (!(sel->pixel_gaps = rd_alloc_lines(np * sizeof *sel->pixel_gaps)) ||
                  (s->settings.select != RD_SELECT_PILOT && /* (only the epochs read the beams' gaps) */
                   !(sel->gaps = calloc(np, sizeof *sel->gaps))))) {
        rd_select_free(sel);
        snprintf(err, errlen, "out of memory for the tile selection's beams gaps (%dx%d pixels)", cam->width, cam->height);
        return RD_ERR_NOMEM;
    }
    if (!third) sel->paths = 1u << RD_SEL_DELTA;
    /* settings.adaptive (true, "pilot" or "epochs", or "auto" where the method asks), where the
     * epochs choose again: every share 1 until the choices set them (read from the first epoch on;
     * "pilot": the pilot's choice alone, and no weights), no weight until they set them
     * (select_share.c) */
    int a = s->settings.adaptive;
    if (a == RD_ADAPTIVE_AUTO) /* the method's: `guided` shares, `guided-unbiased` the epochs' */
        a = options & RD_SELECT_SHARES_AUTO ? 1 : options & RD_SELECT_UNBIASED_SHARES_AUTO ? RD_ADAPTIVE_EPOCHS : 0;
    /* ("pilot": fixed shares, no weights; "epochs": blocks, no weights) */
    const int shares = a != 0, weights = a == 1;
    sel->blocks = shares && a == RD_ADAPTIVE_EPOCHS && s->settings.select != RD_SELECT_PILOT;
    if (shares && s->settings.select != RD_SELECT_PILOT) {
        size_t ns = (size_t)sel->n * sel->tiles_x * sel->tiles_y;
        if (!(sel->share = malloc(ns * sizeof *sel->share)) ||
            (weights && !(sel->weight = calloc(ns, sizeof *sel->weight)))) {
            rd_select_free(sel);
            snprintf(err, errlen, "out of memory for the tile selection's shares (%dx%d pixels)", cam->width, cam->height);
            return RD_ERR_NOMEM;
        }
        for (size_t i = 0; i < ns; i++) sel->share[i] = 1.0f;
    }
    if (options & RD_SELECT_METHOD_IS_PATH) sel->paths |= 1u << RD_SEL_METHOD;
    if (options & RD_SELECT_PASSES) /* the method's share of a pass's work, a sample (the head) */
        sel->method_pass_cost = (RD_SELECT_COST_EMITTED * ctx->pass_emitted + RD_SELECT_COST_COLLISION * ctx->pass_collisions +
                                 (options & RD_SELECT_PASSES_ORDERED ? RD_SELECT_COST_ORDERED : RD_SELECT_COST_INDEXED) *
                                     ctx->pass_indexed) /
                                ((double)s->photons.pass_spp * cam->width * cam->height);
    sel->delta = delta;
    sel->epochs = ctx->scene->settings.select != RD_SELECT_PILOT;
    sel->trace_path = ctx->select_trace && (!ctx->comm || ctx->comm->rank == 0) ? ctx->select_trace : NULL;
    sel->report = ctx->select_report;
    int n = sel->tiles_x * sel->tiles_y;
    int threads = ctx->threads > 0 ? ctx->threads : 1;
    sel->runs = rd_alloc_lines((size_t)threads * sizeof *sel->runs);
    sel->n_runs = sel->runs ? threads : 0;
    rd_thread *th = rd_threads_new(ctx, threads);
    int ok = th != NULL && sel->runs != NULL;
    if (ok) {
        /* One thread a tile: its statistics are summed in pixel order whatever the threads. */
        const int b = beams ? sel->n - 1 : -1; /* (the beams' pilot in two stages: the head) */
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1)
        for (int k = 0; k < n; k++) pilot_tile(ctx, &th[omp_get_thread_num()], sel, k, method, b);
        if (b >= 0) {
            uint8_t *contend = malloc((size_t)n);
            if (contend) beams_contend(sel, b, contend);
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1)
            for (int k = 0; k < n; k++)
                if (!contend || contend[k]) pilot_tile_beams_rest(ctx, &th[omp_get_thread_num()], sel, k, method, b);
            free(contend);
            beams_pilot_fold(sel, b, 1);
        }
        rd_select_choose_tiles(sel, NULL);
    }
    rd_threads_free(th, threads);
    if (!ok) {
        rd_select_free(sel);
        snprintf(err, errlen, "out of memory for the tile selection's pilot and its threads' records");
        return RD_ERR_NOMEM;
    }
    traced_choice(sel);
    return RD_OK;
}

void rd_select_free(rd_select *sel)
{
    free(sel->choice);
    free(sel->share), free(sel->weight);
    free(sel->trial);
    free(sel->stats);
    free(sel->pixels), free(sel->pixel_gaps);
    free(sel->gaps);
    free(sel->runs);
    free(sel->trace.s);
    memset(sel, 0, sizeof *sel);
}

double rd_select_share(const rd_select *sel, int x, int y, double *weight)
{
    /* (the pilot's choice governs samples 0 .. RD_SHARE_FIRST - 1, which every pixel draws) */
    _Static_assert(RD_SHARE_FIRST == SEL_EPOCH_FIRST, "the shares begin at the first epoch");
    int k = (y / RD_SELECT_TILE) * sel->tiles_x + x / RD_SELECT_TILE;
    const size_t j = (size_t)sel->n * k + (sel->choice ? rd_select_uses(sel, x, y) : 0);
    if (weight) *weight = sel->weight && sel->choices > 0 && sel->weight[j] > 0.0 ? sel->weight[j] : 1.0;
    return sel->share && sel->choices >= 2 ? sel->share[j] : 1.0;
}

int rd_select_uses(const rd_select *sel, int x, int y)
{
    int k = (y / RD_SELECT_TILE) * sel->tiles_x + x / RD_SELECT_TILE;
    if (!sel->trial[k]) return sel->choice[k];
    int a = sel->choice[k], b = sel->trial[k] - 1; /* the two on trial: odd squares the higher */
    int hi = a > b ? a : b, lo = a > b ? b : a;
    return (x + y) & 1 ? hi : lo;
}

uint64_t rd_select_pass_pixels(const rd_select *sel, uint64_t all)
{
    if (!sel->choice) return all;
    /* (with shares, each pixel counts its share: the pass samples it draws an index) */
    double n = 0.0;
    for (int y = 0; y < sel->height; y++)
        for (int x = 0; x < sel->width; x++)
            if (sel->kind[rd_select_uses(sel, x, y)] == sel->pass_kind) n += rd_select_share(sel, x, y, NULL);
    return (uint64_t)ceil(n);
}

void rd_select_observe(rd_select *sel, uint64_t pixel, vec3 L, double cost)
{
    pixel_add(&sel->pixels[pixel], NULL, L, v3(0, 0, 0), -1);
    sel->pixels[pixel].cost += (double)cost_units(cost); /* (whole units, as every record's) */
}

int rd_select_epoch_next(const rd_select *sel, int sample)
{
    if (!sel->choice || !sel->epochs) return INT_MAX;
    int b = SEL_EPOCH_FIRST;
    while (b <= sample) {
        if (b > INT_MAX / SEL_EPOCH_GROWTH) return INT_MAX;
        b *= SEL_EPOCH_GROWTH;
    }
    return b;
}

/* The beams' squared gaps (rd_select_stats.bias2, bias_n, bias_split; select_rule.c, "The beams'
 * bias"), set anew from every pixel's image samples so far (rd_select.gaps), in the half and tile
 * of the pixel, of the beams estimator (the last), over the pixels with samples on passes of all
 * four classes mod 4. With m_j the mean gap of the pixel's samples on passes of class j, its
 * product is P = (m0 + m2)(m1 + m3) / 4, even passes' times odd passes' (pass 1, class 1, sets
 * the radii; the other passes are independent given it), weighed by w = n_e n_o / (n_e + n_o) for
 * n_e and n_o samples on each (bias2 the sum of w P, bias_n of w): a pixel with a few samples of
 * the beams (a trial's, a tile's that left them) weighs little. Its noise is read from
 * D = (m0 - m2)(m1 - m3) / 4 (bias_split the sum of w D): P and D are the same four cross
 * products m_i m_j, even x odd, with two signs turned, so where the gap is 0 they have the same
 * variance whatever each class's (its samples, and the photon noise its passes share), and D's
 * mean is 0 whatever the bias (the classes' gaps alike). The classes weigh equally, not by their
 * samples: a pass that served many samples would weigh its photons' noise into P more than into
 * D. All of a pixel's samples, not an epoch's: an epoch's product of two means of few samples is
 * noise squared, and the earlier epochs' records, each as noisy, would weigh as much as the
 * last's. */
static void bias_fold(rd_select *sel)
{
    if (!sel->gaps || sel->kind[sel->n - 1] != RD_SEL_BEAMS) return;
    const int b = sel->n - 1;
    for (int h = 0; h < 2; h++)
        for (int k = 0; k < sel->tiles_x * sel->tiles_y; k++) {
            rd_select_stats *st = &sel->stats[((size_t)h * sel->tiles_x * sel->tiles_y + k) * sel->n + b];
            st->bias2 = st->bias_n = st->bias_split = 0.0;
        }
    for (int y = 0; y < sel->height; y++)
        for (int x = 0; x < sel->width; x++) {
            const double *s = sel->gaps[(size_t)y * sel->width + x].gap, *c = sel->gaps[(size_t)y * sel->width + x].gap_n;
            if (!(c[0] > 0.0 && c[1] > 0.0 && c[2] > 0.0 && c[3] > 0.0)) continue;
            int k = (y / RD_SELECT_TILE) * sel->tiles_x + x / RD_SELECT_TILE;
            rd_select_stats *st = &half_stats(sel, x, y)[sel->n * k + b];
            const double ne = c[0] + c[2], no = c[1] + c[3], w = ne * no / (ne + no);
            const double m0 = s[0] / c[0], m1 = s[1] / c[1], m2 = s[2] / c[2], m3 = s[3] / c[3];
            st->bias2 += w * (m0 + m2) * (m1 + m3) / 4.0, st->bias_n += w;
            st->bias_split += w * (m0 - m2) * (m1 - m3) / 4.0;
        }
}

void rd_select_epoch(rd_select *sel, const rd_comm *comm, const rd_select_end *end)
{
    if (!sel->choice) return;
    _Static_assert(sizeof(rd_select_pixel) == RD_SELECT_PIXEL_DOUBLES * sizeof(double),
                   "rd_select_pixel is an array of doubles");
    _Static_assert(sizeof(rd_select_gaps) == 8 * sizeof(double), "rd_select_gaps is an array of doubles");
    for (int i = 0; i < sel->n_runs; i++) run_close(sel, &sel->runs[i]); /* (no pass runs) */
    /* Several ranks: each holds the samples of the pixels it rendered and zeros elsewhere, so
     * the sum over the ranks is every pixel's samples, exactly (x + 0 = x). */
    if (comm && comm->size > 1) {
        comm->reduce(comm->user, sel->pixels, (size_t)sel->width * sel->height * RD_SELECT_PIXEL_DOUBLES,
                     RD_COMM_DOUBLE, RD_COMM_SUM, -1);
        if (sel->pixel_gaps)
            comm->reduce(comm->user, sel->pixel_gaps, (size_t)sel->width * sel->height * 8, RD_COMM_DOUBLE, RD_COMM_SUM, -1);
    }
    for (int y = 0; y < sel->height; y++)
        for (int x = 0; x < sel->width; x++) {
            int k = (y / RD_SELECT_TILE) * sel->tiles_x + x / RD_SELECT_TILE;
            rd_select_pixel *px = &sel->pixels[(size_t)y * sel->width + x];
            rd_select_gaps *pg = sel->pixel_gaps ? &sel->pixel_gaps[(size_t)y * sel->width + x] : NULL;
            rd_select_stats *st = &half_stats(sel, x, y)[sel->n * k + rd_select_uses(sel, x, y)];
            pixel_fold(st, px, pg);
            st->image_n += px->n, st->image_cost += px->cost / RD_SELECT_COST_UNIT; /* (the image's) */
            if (sel->gaps && pg) {
                rd_select_gaps *g = &sel->gaps[(size_t)y * sel->width + x];
                for (int i = 0; i < 4; i++) g->gap[i] += pg->gap[i], g->gap_n[i] += pg->gap_n[i];
            }
            memset(px, 0, sizeof *px);
            if (pg) memset(pg, 0, sizeof *pg);
        }
    bias_fold(sel);
    rd_select_choose_tiles(sel, end);
    traced_choice(sel);
}

vec3 rd_select_radiance(const rd_render_ctx *ctx, rd_select *sel, rd_select_fn method,
                        rd_thread *th, ray3 r, rd_sampler *smp)
{
    if (!sel->choice) return method(ctx, th, r, smp);
    if (th->index < 0 || th->index >= sel->n_runs) { /* (no run for this thread: one sample's record) */
        int use = rd_select_uses(sel, th->x, th->y);
        rd_select_work c0 = rd_select_work_now(th);
        th->delta_samples += sel->kind[use] == RD_SEL_DELTA || sel->kind[use] == RD_SEL_DELTA_EQ;
        th->delta_eq_samples += sel->kind[use] == RD_SEL_DELTA_EQ;
        th->path_samples += sel->kind[use] == RD_SEL_PATH;
        th->beams_samples += sel->kind[use] == RD_SEL_BEAMS;
        vec3 gap;
        int pass;
        vec3 L = estimate(ctx, sel, th, use, method, r, smp, &gap, &pass);
        sel->pixels[th->pixel].cost += (double)sample_units(sel, use, th, c0); /* (a dropped sample's too) */
        if (v3_finite(L))
            pixel_add(&sel->pixels[th->pixel], sel->pixel_gaps ? &sel->pixel_gaps[th->pixel] : NULL, L, gap, pass);
        return L;
    }
    rd_select_run *u = &sel->runs[th->index];
    if (u->th != th || u->pixel != th->pixel) { /* a new pixel: the last one's run written back */
        run_close(sel, u);
        run_open(sel, u, th);
    }
    th->delta_samples += sel->kind[u->use] == RD_SEL_DELTA || sel->kind[u->use] == RD_SEL_DELTA_EQ;
    th->delta_eq_samples += sel->kind[u->use] == RD_SEL_DELTA_EQ;
    th->path_samples += sel->kind[u->use] == RD_SEL_PATH;
    th->beams_samples += sel->kind[u->use] == RD_SEL_BEAMS;
    vec3 gap;
    int pass;
    vec3 L = estimate(ctx, sel, th, u->use, method, r, smp, &gap, &pass);
    u->drawn++; /* (its work is read from the counters at the run's end: run_close) */
    if (v3_finite(L)) { /* pixel_add's sums, in the same order: the same to the bit */
        const float v[3] = {(float)L.x, (float)L.y, (float)L.z}, v2[3] = {(float)(L.x * L.x), (float)(L.y * L.y), (float)(L.z * L.z)};
        for (int c = 0; c < 3; c++) u->sum[c] += v[c], u->sum2[c] += v2[c];
        if (pass >= 0) u->gap[pass & 3] += (gap.x + gap.y + gap.z) / 3.0, u->gap_n[pass & 3]++;
        u->nonzero += L.x != 0.0 || L.y != 0.0 || L.z != 0.0;
        u->n += 1.0;
    }
    return L;
}

void rd_select_pixel_done(rd_select *sel, const rd_thread *th)
{
    if (th->index >= 0 && th->index < sel->n_runs) run_close(sel, &sel->runs[th->index]);
}
