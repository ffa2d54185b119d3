/* runs.c: the comparison itself, `photonmarch compare` without its report (issue 11;
 * THEORY.md §7; docs/compare.md).
 *
 * The steps: check the options, read the --add images and get the reference (reference.c),
 * one bake per kind of bake the methods need (its time charged to every run of those
 * methods), K runs of every method at equal time or equal samples, then one row per method
 * and per added image with the metrics of THEORY.md §7 (metrics.c): RMSE, relMSE, mean
 * absolute relative error, bias^2 and variance from the K runs, efficiency 1/(MSE x time),
 * seed 002's TTUV (time x RMSE), cost counters and noise homogeneity. The report (report.c)
 * is written from what this file keeps; nothing here calls it. */
#include "compare/rd_compare.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* At most this many methods, and this many --add images. */
#define RD_CMP_MAX_METHODS 8

/* The comparison's clock (rd_cmp_opts.clock). */
static double now_seconds(const rd_cmp_opts *o)
{
    return o->clock ? o->clock(o->clock_user) : rd_clock_monotonic(NULL);
}

/* Mean of stderr^2 over every value: the variance the reference adds to every measured MSE. */
static double image_mean_sq(const rd_image *im)
{
    size_t n = (size_t)im->w * im->h * 3;
    double s = 0.0;
    for (size_t i = 0; i < n; i++) s += (double)im->rgb[i] * im->rgb[i];
    return n ? s / n : 0.0;
}

/* ---- The runs ------------------------------------------------------------------------------ */

/* One bake per distinct set of needs, shared by the methods with those needs; its wall time
 * is charged to every run of each of them (docs/compare.md). */
static rd_status bake_for(rd_comparison *c, const rd_scene *s, int mi, char *err, size_t errlen)
{
    cmp_method *m = &c->m[mi];
    unsigned needs = rd_method_needs_for(m->name, s);
    if (!needs) return RD_OK;
    for (int j = 0; j < mi; j++)
        if (c->m[j].baked && c->m[j].needs == needs) {
            m->baked = c->m[j].baked;
            m->bake_seconds = c->m[j].bake_seconds;
            m->needs = needs;
            return RD_OK;
        }
    rd_bake_opts bo = {.seed = -1, .threads = c->opts.threads, .cancel = c->opts.cancel};
    rd_bake_opts_for(&bo, needs);
    double t0 = now_seconds(&c->opts);
    rd_status st = rd_bake(s, &bo, &m->baked, err, errlen);
    if (st) return st;
    m->bake_seconds = now_seconds(&c->opts) - t0;
    m->needs = needs;
    m->owns_baked = 1;
    return RD_OK;
}

typedef struct {
    rd_comparison *c;
    int mi, run;
    double started;
} run_ctx;

static void run_progress(void *user, int done, int total, double seconds)
{
    run_ctx *r = user;
    rd_comparison *c = r->c;
    const rd_cmp_opts *o = &c->opts;
    cmp_method *m = &c->m[r->mi];
    double left_run;
    if (!o->equal_spp) left_run = fmax(0.0, o->budget - seconds);
    else left_run = done > 0 ? (seconds - m->bake_seconds) * (total - done) / done : 0.0;
    rd_cmp_progress p = {m->name, r->run + 1, o->runs, done, seconds, o->budget, 0.0};
    p.left_seconds = left_run + c->planned_seconds;
    if (o->progress) o->progress(o->progress_user, &p);
}

/* Seconds the runs not yet started will take (equal time: exact; equal spp: the mean of the
 * runs finished so far, else unknown = 0). */
static double planned_after(const rd_comparison *c, int mi, int run)
{
    const rd_cmp_opts *o = &c->opts;
    int left = (c->n_methods - mi - 1) * o->runs + (o->runs - run - 1);
    if (!o->equal_spp) return left * o->budget;
    double sum = 0.0;
    int n = 0;
    for (int j = 0; j <= mi; j++)
        for (int k = 0; k < c->m[j].done; k++) sum += c->m[j].stats[k].seconds, n++;
    return n ? left * sum / n : 0.0;
}

static rd_status run_one(rd_comparison *c, const rd_scene *s, int mi, int run, char *err, size_t errlen)
{
    const rd_cmp_opts *o = &c->opts;
    cmp_method *m = &c->m[mi];
    run_ctx rc = {c, mi, run, now_seconds(o)};
    rd_render_opts ro = {.method = m->name, .seed = RUN_SEED(o->seed, run), .threads = o->threads,
                         .cancel = o->cancel, .progress = run_progress, .progress_user = &rc,
                         .baked = m->baked, .baked_seconds = m->bake_seconds, .reference = &c->ref,
                         .clock = o->clock, .clock_user = o->clock_user};
    /* Equal time: the budget is the run's wall time, its share of the bake included; equal
     * spp: every method renders `budget` samples per pixel. */
    ro.spp = o->equal_spp ? (int)o->budget : 1 << 24;
    ro.time_limit = o->equal_spp ? 0.0 : o->budget;
    c->planned_seconds = planned_after(c, mi, run);
    run_progress(&rc, 0, ro.spp, m->bake_seconds);
    rd_render_result res;
    rd_status st = rd_render(s, &ro, &res, err, errlen);
    if (st) return st;
    if (res.stats.cancelled) {
        rd_render_result_free(&res); /* a run cut short is not one of the K: left out */
        c->sum.cancelled = 1;
        return RD_OK;
    }
    if (res.stats.spp < 1) {
        rd_render_result_free(&res);
        snprintf(err, errlen, "--budget %g: %s had no time to sample every pixel once (its bake took %.2f s; give it more)",
                 o->budget, m->name, m->bake_seconds);
        return RD_ERR_ARG;
    }
    int k = m->done++;
    m->img[k] = res.image;
    m->se[k] = res.stderr_img;
    m->stats[k] = res.stats;
    m->curve[k] = res.curve;
    m->n_curve[k] = res.n_curve;
    return RD_OK;
}

/* ---- Rows ------------------------------------------------------------------------------- */

static void row_nan(rd_cmp_row *r)
{
    double nan = NAN;
    r->seconds = r->bake_seconds = r->spp = nan;
    r->split.bias2 = r->split.variance = r->split.bias2_se = nan;
    r->efficiency = r->ttuv = nan;
    r->collisions_pp = r->lookups_pp = r->shadow_rays_pp = nan;
}

static void row_method(rd_comparison *c, const cmp_method *m, rd_cmp_row *r)
{
    size_t np = (size_t)c->w * c->h;
    snprintf(r->label, sizeof r->label, "%s", m->name);
    r->runs = m->done;
    rd_cmp_errors sum = {0};
    double secs = 0, spp = 0, col = 0, look = 0, shadow = 0;
    for (int k = 0; k < m->done; k++) {
        rd_cmp_errors e;
        rd_cmp_errors_of(&m->img[k], &c->ref, &e, NULL, 0);
        sum.mse += e.mse, sum.relmse += e.relmse, sum.mare += e.mare;
        const rd_render_stats *st = &m->stats[k];
        secs += st->seconds, spp += st->spp_mean;
        col += (double)st->collisions / np, look += (double)st->lookups / np, shadow += (double)st->shadow_rays / np;
    }
    double K = m->done;
    r->err = (rd_cmp_errors){sum.mse / K, sqrt(sum.mse / K), sum.relmse / K, sum.mare / K};
    r->seconds = secs / K, r->spp = spp / K, r->bake_seconds = m->bake_seconds;
    r->collisions_pp = col / K, r->lookups_pp = look / K, r->shadow_rays_pp = shadow / K;
    const rd_image *rse = c->ref_se.rgb ? &c->ref_se : NULL;
    if (m->done >= 2) {
        rd_cmp_split_of(m->img, m->done, &c->ref, rse, &r->split, NULL, 0);
        r->split_from_runs = 1;
    } else {
        /* One run: its variance from its own stderr image (stderr^2 = variance of the mean). */
        r->split.variance = image_mean_sq(&m->se[0]);
        r->split.bias2 = r->err.mse - r->split.variance - (rse ? c->sum.ref_var : 0.0);
        r->split.bias2_se = NAN;
    }
    r->efficiency = 1.0 / (r->err.mse * r->seconds); /* 1 / (MSE x time) */
    r->ttuv = r->seconds * r->err.rmse;              /* seed 002: TTUV = time x RMSE */
    r->homogeneity = rd_cmp_homogeneity(&m->img[0], &c->ref);
}

static void row_extra(rd_comparison *c, int i, rd_cmp_row *r)
{
    const rd_cmp_extra *e = &c->opts.extras[i];
    snprintf(r->label, sizeof r->label, "%s", e->label);
    r->is_extra = 1;
    r->runs = 1;
    rd_cmp_errors_of(&c->extra_img[i], &c->ref, &r->err, NULL, 0);
    if (e->seconds > 0) {
        r->seconds = e->seconds;
        r->efficiency = 1.0 / (r->err.mse * r->seconds);
        r->ttuv = r->seconds * r->err.rmse;
    }
    r->homogeneity = rd_cmp_homogeneity(&c->extra_img[i], &c->ref);
}

static void make_rows(rd_comparison *c)
{
    int n = 0;
    double min_mse = INFINITY;
    for (int i = 0; i < c->n_methods; i++) {
        if (!c->m[i].done) continue;
        rd_cmp_row *r = &c->rows[n];
        row_nan(r);
        row_method(c, &c->m[i], r);
        c->row_img[n++] = &c->m[i].img[0];
        min_mse = fmin(min_mse, r->err.mse);
    }
    for (int i = 0; i < c->opts.n_extras; i++) {
        rd_cmp_row *r = &c->rows[n];
        row_nan(r);
        row_extra(c, i, r);
        c->row_img[n++] = &c->extra_img[i];
    }
    c->sum.rows = c->rows;
    c->sum.n_rows = n;
    /* The reference's variance adds to every measured MSE: above a tenth of the best method's
     * MSE it hides the differences between methods (docs/compare.md). */
    c->sum.ref_share = isfinite(c->sum.ref_var) && isfinite(min_mse) && min_mse > 0 ? c->sum.ref_var / min_mse : NAN;
    c->sum.ref_too_noisy = isfinite(c->sum.ref_var) && isfinite(min_mse) && c->sum.ref_var > RD_CMP_REF_SHARE * min_mse;
}

/* The smallest MSE of a method's row (NaN when none). */
static double best_method_mse(const rd_comparison *c)
{
    double best = NAN;
    for (int i = 0; i < c->sum.n_rows; i++)
        if (!c->rows[i].is_extra && !(c->rows[i].err.mse >= best)) best = c->rows[i].err.mse;
    return best;
}

/* The default reference's rule after the runs (rd_cmp_ref_spp_needed): while its variance is
 * above RD_CMP_REF_SHARE of the best method's MSE, render the samples the rule asks for (within
 * the cap: ref_max_seconds, else RD_CMP_REF_CAP x the longest mean run), merge them, and measure
 * the rows again. A few rounds at most: each aims 10% past the rule, so one is the rule. */
static rd_status reference_settle(rd_comparison *c, const rd_scene *s, char *err, size_t errlen)
{
    double longest = 0.0;
    for (int i = 0; i < c->sum.n_rows; i++)
        if (!c->rows[i].is_extra) longest = fmax(longest, c->rows[i].seconds);
    double cap = c->opts.ref_max_seconds > 0 ? c->opts.ref_max_seconds : RD_CMP_REF_CAP * longest;
    c->sum.ref_cap_seconds = cap;
    for (int round = 0; round < 4 && !c->sum.cancelled; round++) {
        double spp = c->sum.ref_spp;
        double need = rd_cmp_ref_spp_needed(spp, c->sum.ref_var, best_method_mse(c));
        if (!(need > spp)) return RD_OK;
        /* Seconds per sample per pixel so far: the cap in samples. */
        double rate = c->sum.ref_seconds / spp;
        double room = rate > 0 ? (cap - c->sum.ref_seconds) / rate : need - spp;
        double more = fmin(need - spp, fmin(floor(room), (double)(1 << 24) - spp));
        if (more < need - spp) c->sum.ref_capped = 1;
        if (more < 1) return RD_OK;
        rd_status st = rd_cmp_reference_extend(c, s, (int)more, err, errlen);
        if (st) return st;
        c->sum.ref_var = image_mean_sq(&c->ref_se);
        make_rows(c);
        if (c->sum.ref_capped) return RD_OK;
    }
    return RD_OK;
}

/* ---- The comparison ------------------------------------------------------------------------ */

static rd_status check_opts(const rd_cmp_opts *o, char *err, size_t errlen)
{
    if (o->n_methods < 1 && o->n_extras < 1) return fail(err, errlen, RD_ERR_ARG, "%s: no methods to compare", "--methods");
    if (o->n_methods > RD_CMP_MAX_METHODS) return fail(err, errlen, RD_ERR_ARG, "%s: at most 8 methods", "--methods");
    if (o->n_extras > RD_CMP_MAX_METHODS) return fail(err, errlen, RD_ERR_ARG, "%s: at most 8 images", "--add");
    for (int i = 0; i < o->n_methods; i++) {
        int found = 0;
        for (int j = 0; j < rd_method_count(); j++) found |= !strcmp(o->methods[i], rd_method_name(j));
        if (!found) return fail(err, errlen, RD_ERR_ARG, "--methods: unknown method \"%s\"", o->methods[i]);
        for (int j = 0; j < i; j++)
            if (!strcmp(o->methods[i], o->methods[j])) return fail(err, errlen, RD_ERR_ARG, "--methods: \"%s\" given twice", o->methods[i]);
    }
    if (o->runs < 1 || o->runs > 64) return fail(err, errlen, RD_ERR_ARG, "%s: runs must be in [1, 64]", "--runs");
    if (!(o->budget > 0) || (o->equal_spp && (o->budget < 1 || o->budget > (1 << 24))))
        return fail(err, errlen, RD_ERR_ARG, "%s: must be > 0 (seconds), or in [1, 16777216] samples with --equal spp", "--budget");
    /* Labels name the report's files and the summary's rows: a method's name is refused (the
     * summary's baseline is the row named delta), and so is a label whose files would overwrite
     * the reference's, the page's, a method's or an earlier image's. */
    const char *taken[2 * RD_CMP_MAX_METHODS];
    int nt = 0;
    for (int j = 0; j < o->n_methods; j++) taken[nt++] = o->methods[j];
    for (int i = 0; i < o->n_extras; i++) {
        const char *l = o->extras[i].label;
        char file[160];
        for (int j = 0; j < rd_method_count(); j++)
            if (!strcmp(l, rd_method_name(j))) {
                snprintf(err, errlen, "--add %s: the label is a method's name; give the image another", l);
                return RD_ERR_ARG;
            }
        if (rd_cmp_label_clash(l, taken, nt, file, sizeof file)) {
            snprintf(err, errlen, "--add %s: the label would overwrite the report's %s; give the image another", l, file);
            return RD_ERR_ARG;
        }
        taken[nt++] = l;
    }
    return RD_OK;
}

static rd_status alloc_methods(rd_comparison *c)
{
    int K = c->opts.runs, n = c->n_methods + c->opts.n_extras;
    c->m = calloc((size_t)c->n_methods + 1, sizeof *c->m);
    c->rows = calloc((size_t)n + 1, sizeof *c->rows);
    c->row_img = calloc((size_t)n + 1, sizeof *c->row_img);
    c->extra_img = calloc((size_t)c->opts.n_extras + 1, sizeof *c->extra_img);
    if (!c->m || !c->rows || !c->row_img || !c->extra_img) return RD_ERR_NOMEM;
    for (int i = 0; i < c->n_methods; i++) {
        cmp_method *m = &c->m[i];
        m->name = c->opts.methods[i];
        m->img = calloc(K, sizeof *m->img);
        m->se = calloc(K, sizeof *m->se);
        m->stats = calloc(K, sizeof *m->stats);
        m->curve = calloc(K, sizeof *m->curve);
        m->n_curve = calloc(K, sizeof *m->n_curve);
        if (!m->img || !m->se || !m->stats || !m->curve || !m->n_curve) return RD_ERR_NOMEM;
    }
    return RD_OK;
}


/* The rank that renders run k of method mi: the runs in order, dealt round the ranks. */
static int run_owner(const rd_comparison *c, int mi, int k)
{
    const rd_comm *comm = cmp_ranks(c);
    return comm ? (mi * c->opts.runs + k) % comm->size : 0;
}

/* This rank's runs, each whole (its own bake of the method's needs, shared by its runs of the
 * methods with those needs). local[mi runs + k] gets the run's index in m->img (-1: not run
 * here, or cut short). */
static rd_status run_all(rd_comparison *c, const rd_scene *s, int *local, char *err, size_t errlen)
{
    const rd_comm *comm = cmp_ranks(c);
    for (int mi = 0; mi < c->n_methods && !c->sum.cancelled; mi++) {
        int mine = 0;
        for (int k = 0; k < c->opts.runs; k++) mine |= run_owner(c, mi, k) == (comm ? comm->rank : 0);
        if (!mine) continue;
        rd_status st = bake_for(c, s, mi, err, errlen);
        if (st == RD_ERR_CANCELLED) { /* Ctrl-C while baking: the rows hold what finished */
            c->sum.cancelled = 1;
            break;
        }
        if (st) return st;
        for (int k = 0; k < c->opts.runs && !c->sum.cancelled; k++) {
            if (run_owner(c, mi, k) != (comm ? comm->rank : 0)) continue;
            if (c->opts.cancel && *c->opts.cancel) { c->sum.cancelled = 1; break; }
            int before = c->m[mi].done;
            if ((st = run_one(c, s, mi, k, err, errlen)) != RD_OK) return st;
            if (c->m[mi].done > before) local[mi * c->opts.runs + k] = before;
        }
    }
    return RD_OK;
}

/* What the rank of a run tells the others before its images. */
typedef struct {
    int ok, n_curve;
    double bake_seconds;
    rd_render_stats stats;
} run_head;

/* Several ranks, after the runs: every run's images, statistics and curve from the rank that
 * rendered it to every rank, in run order (a run cut short is left out, as in one process), so
 * every rank holds the comparison one process would have made of the same images. A method's
 * bake time is the one measured by the rank of its first run. Collective. */
static rd_status gather_runs(rd_comparison *c, const int *local, char *err, size_t errlen)
{
    const rd_comm *comm = cmp_ranks(c);
    int K = c->opts.runs;
    rd_status st = RD_OK;
    for (int mi = 0; mi < c->n_methods && st == RD_OK; mi++) {
        cmp_method *m = &c->m[mi];
        /* the gathered runs go to new arrays, in run order; this rank's own are moved there */
        rd_image *img = calloc((size_t)K, sizeof *img), *se = calloc((size_t)K, sizeof *se);
        rd_render_stats *stats = calloc((size_t)K, sizeof *stats);
        rd_conv_point **curve = calloc((size_t)K, sizeof *curve);
        int *n_curve = calloc((size_t)K, sizeof *n_curve), done = 0, have_bake = 0;
        st = img && se && stats && curve && n_curve ? RD_OK : RD_ERR_NOMEM;
        if (st) snprintf(err, errlen, "compare: out of memory gathering the runs");
        st = rd_comm_agree(comm, st, "compare: gathering the runs", err, errlen);
        for (int k = 0; k < K && st == RD_OK; k++) {
            int owner = run_owner(c, mi, k), li = comm->rank == owner ? local[mi * K + k] : -1;
            run_head h = {0};
            if (li >= 0) h = (run_head){1, m->n_curve[li], m->bake_seconds, m->stats[li]};
            rd_comm_bcast(comm, &h, sizeof h, owner);
            if (!h.ok) continue;
            if (li >= 0) { /* this rank's run: moved */
                img[done] = m->img[li], se[done] = m->se[li], curve[done] = m->curve[li];
                m->img[li].rgb = m->se[li].rgb = NULL;
                m->curve[li] = NULL;
            } else if (h.n_curve > 0 && !(curve[done] = malloc((size_t)h.n_curve * sizeof **curve))) {
                st = RD_ERR_NOMEM;
                snprintf(err, errlen, "compare: out of memory gathering the runs");
            }
            if ((st = rd_comm_agree(comm, st, "compare: gathering the runs", err, errlen)) != RD_OK) break;
            if (h.n_curve > 0) rd_comm_bcast(comm, curve[done], (size_t)h.n_curve * sizeof **curve, owner);
            if ((st = rd_cmp_share_image(comm, &img[done], c->w, c->h, owner, err, errlen)) != RD_OK ||
                (st = rd_cmp_share_image(comm, &se[done], c->w, c->h, owner, err, errlen)) != RD_OK) {
                done++; /* (freed below with the others) */
                break;
            }
            stats[done] = h.stats;
            n_curve[done] = h.n_curve;
            if (!have_bake) m->bake_seconds = h.bake_seconds, have_bake = 1;
            done++;
        }
        /* the old arrays (what is left in them: nothing but runs not moved) and the new */
        for (int k = 0; k < m->done; k++) {
            rd_image_free_pixels(&m->img[k]);
            rd_image_free_pixels(&m->se[k]);
            free(m->curve[k]);
        }
        free(m->img), free(m->se), free(m->stats), free(m->curve), free(m->n_curve);
        m->img = img, m->se = se, m->stats = stats, m->curve = curve, m->n_curve = n_curve;
        m->done = done;
        if (st != RD_OK && (!img || !se || !stats || !curve || !n_curve)) m->done = 0;
    }
    return st;
}

/* Several ranks: their host names into c->sum.hosts ("a x2, b": each name once, in rank order
 * of first appearance, with its rank count; past 32 names, "..."), one broadcast a rank.
 * Collective. */
static void gather_hosts(rd_comparison *c)
{
    const rd_comm *comm = cmp_ranks(c);
    enum { HOST = 64, NAMES = 32 };
    char names[NAMES][HOST];
    int times[NAMES], n = 0, more = 0;
    c->sum.ranks = comm ? comm->size : 1;
    for (int k = 0; k < c->sum.ranks; k++) {
        char h[HOST] = {0};
        if ((!comm || comm->rank == k) && gethostname(h, HOST - 1) != 0) snprintf(h, HOST, "?");
        rd_comm_bcast(comm, h, HOST, k);
        int j = 0;
        while (j < n && strcmp(names[j], h)) j++;
        if (j < n) times[j]++;
        else if (n < NAMES) memcpy(names[n], h, HOST), times[n++] = 1;
        else more = 1;
    }
    size_t at = 0;
    c->sum.hosts[0] = 0;
    for (int j = 0; j < n && at < sizeof c->sum.hosts; j++) {
        int w = times[j] > 1 ? snprintf(c->sum.hosts + at, sizeof c->sum.hosts - at, "%s%s x%d", j ? ", " : "", names[j], times[j])
                             : snprintf(c->sum.hosts + at, sizeof c->sum.hosts - at, "%s%s", j ? ", " : "", names[j]);
        at += w > 0 ? (size_t)w : 0;
    }
    if (more && at < sizeof c->sum.hosts) snprintf(c->sum.hosts + at, sizeof c->sum.hosts - at, ", ...");
}

rd_status rd_compare_run(const rd_scene *scene, const rd_cmp_opts *opts, rd_comparison **out,
                         char *err, size_t errlen)
{
    char dummy[8];
    if (!err) { err = dummy; errlen = sizeof dummy; }
    *out = NULL;
    rd_status st = check_opts(opts, err, errlen);
    if (st) return st;
    rd_comparison *c = calloc(1, sizeof *c);
    if (!c) fail(err, errlen, RD_ERR_NOMEM, "%s: out of memory", "compare");
    const rd_comm *comm = opts->comm && opts->comm->size > 1 ? opts->comm : NULL;
    if ((st = rd_comm_agree(comm, c ? RD_OK : RD_ERR_NOMEM, "compare", err, errlen)) != RD_OK) {
        free(c);
        return st;
    }
    c->opts = *opts;
    c->n_methods = opts->n_methods;
    c->w = rd_scene_width(scene);
    c->h = rd_scene_height(scene);
    c->exposure = rd_scene_exposure(scene);
    c->sum.ref_var = NAN;
    c->sum.ref_share = NAN;
    c->sum.ref_cap_seconds = NAN;
    gather_hosts(c);
    if ((st = alloc_methods(c)) != RD_OK) fail(err, errlen, st, "%s: out of memory", "compare");
    /* (several ranks: every step that can fail on one rank alone ends in an agreement) */
    if ((st = rd_comm_agree(comm, st, "compare", err, errlen)) != RD_OK) goto bad;
    /* Every input is checked before anything long runs. */
    st = rd_cmp_extras_load(c, err, errlen);
    if ((st = rd_comm_agree(comm, st, "compare: --add", err, errlen)) != RD_OK) goto bad;
    c->planned_seconds = opts->equal_spp ? 0.0 : opts->budget * opts->runs * opts->n_methods;
    if ((st = rd_cmp_reference_get(c, scene, err, errlen)) != RD_OK) goto bad;
    if (!c->sum.cancelled) {
        if (c->ref_se.rgb) c->sum.ref_var = image_mean_sq(&c->ref_se);
        int *local = calloc((size_t)c->n_methods * opts->runs + 1, sizeof *local);
        if (!local) st = fail(err, errlen, RD_ERR_NOMEM, "%s: out of memory", "compare");
        for (int i = 0; local && i < c->n_methods * opts->runs; i++) local[i] = -1;
        if (st == RD_OK) st = run_all(c, scene, local, err, errlen);
        if (comm) {
            if ((st = rd_comm_agree(comm, st, "compare: a run", err, errlen)) == RD_OK) st = gather_runs(c, local, err, errlen);
            int cancelled = c->sum.cancelled; /* a run cut short anywhere: the comparison was cut */
            comm->reduce(comm->user, &cancelled, 1, RD_COMM_INT, RD_COMM_MAX, -1);
            c->sum.cancelled = cancelled;
        }
        free(local);
        if (st != RD_OK) goto bad;
        make_rows(c);
        c->sum.ref_auto = rd_cmp_reference_is_auto(opts) && !c->photon_ref; /* (reference.c) */
        c->planned_seconds = 0.0;
        if (c->sum.ref_auto && c->sum.n_rows && (st = reference_settle(c, scene, err, errlen)) != RD_OK) goto bad;
    }
    *out = c;
    return RD_OK;
bad:
    rd_comparison_free(c);
    return st;
}

const rd_cmp_summary *rd_comparison_summary(const rd_comparison *c)
{
    return &c->sum;
}

void rd_comparison_free(rd_comparison *c)
{
    if (!c) return;
    for (int i = 0; c->m && i < c->n_methods; i++) {
        cmp_method *m = &c->m[i];
        for (int k = 0; k < m->done; k++) {
            rd_image_free_pixels(&m->img[k]);
            rd_image_free_pixels(&m->se[k]);
            free(m->curve[k]);
        }
        free(m->img), free(m->se), free(m->stats), free(m->curve), free(m->n_curve);
        if (m->owns_baked) rd_baked_free(m->baked);
    }
    for (int i = 0; c->extra_img && i < c->opts.n_extras; i++) rd_image_free_pixels(&c->extra_img[i]);
    rd_image_free_pixels(&c->ref);
    rd_image_free_pixels(&c->ref_se);
    free(c->m), free(c->rows), free(c->row_img), free(c->extra_img);
    free(c);
}
