/* summary.c: what a comparison says in words (docs/compare.md, "The summary"): who won, by how
 * much, and whether bias or variance makes each method's error. One sentence per row relative
 * to the baseline (delta when it is compared, else the first method):
 *     guided: 1.4x delta's efficiency; 68% of its error is bias; per sample 3.1x the time and
 *     0.45x the variance
 * (the last part, why the ratio is what it is, when both rows have samples and a variance:
 * rd_cmp_time_per_sample, rd_cmp_variance_per_sample), and a verdict line naming the winner
 * (the highest efficiency 1/(MSE x time), THEORY.md §7), or why the methods are not ranked. Pure functions of the rows: report.c prints them under
 * the table and writes them to metrics.json, report_page.c puts them in the page's header. */
#include "compare/rd_compare.h"

#include <math.h>
#include <string.h>

int rd_cmp_baseline(const rd_cmp_summary *S)
{
    int first = -1;
    for (int i = 0; i < S->n_rows; i++) {
        if (S->rows[i].is_extra) continue;
        if (!strcmp(S->rows[i].label, "delta")) return i;
        if (first < 0) first = i;
    }
    return first >= 0 ? first : S->n_rows > 0 ? 0 : -1;
}

int rd_cmp_winner(const rd_cmp_summary *S)
{
    if (S->ref_too_noisy) return -1;
    int best = -1, n = 0;
    for (int i = 0; i < S->n_rows; i++) {
        double e = S->rows[i].efficiency;
        if (!(isfinite(e) && e > 0)) continue;
        n++;
        if (best < 0 || e > S->rows[best].efficiency) best = i;
    }
    return n >= 2 ? best : -1;
}

double rd_cmp_bias_share(const rd_cmp_row *r)
{
    double b = fmax(r->split.bias2, 0.0), v = r->split.variance;
    if (!isfinite(r->split.bias2) || !isfinite(v) || !(b + v > 0)) return NAN;
    return b / (b + v);
}

/* A ratio as people say it: 0.76x, 1.03x, 1.4x, 2.5x, 12x. */
static void ratio_text(double v, char *buf, size_t n)
{
    if (v < 0.995) snprintf(buf, n, "%.2gx", v);
    else if (v < 1.995) snprintf(buf, n, "%.3gx", v);
    else if (v < 9.95) snprintf(buf, n, "%.1fx", v);
    else snprintf(buf, n, "%.0fx", v);
}

static void bias_text(const rd_cmp_row *r, char *buf, size_t n)
{
    double share = rd_cmp_bias_share(r);
    if (isfinite(share)) snprintf(buf, n, "%.0f%% of its error is bias", 100.0 * share);
    else snprintf(buf, n, "bias and variance unknown (one image)");
}

double rd_cmp_time_per_sample(const rd_cmp_row *r)
{
    double bake = isfinite(r->bake_seconds) ? r->bake_seconds : 0.0;
    if (r->is_extra || !(r->spp > 0) || !isfinite(r->seconds)) return NAN;
    return (r->seconds - bake) / r->spp;
}

double rd_cmp_variance_per_sample(const rd_cmp_row *r)
{
    if (r->is_extra || !(r->spp > 0) || !isfinite(r->split.variance)) return NAN;
    return fmax(r->split.variance, 0.0) * r->spp;
}

/* "; per sample 3.1x the time and 0.45x the variance" of row r against the baseline's, or ""
 * when either is unknown. */
static void per_sample_text(const rd_cmp_row *r, const rd_cmp_row *base, char *buf, size_t n)
{
    double t = rd_cmp_time_per_sample(r) / rd_cmp_time_per_sample(base);
    double v = rd_cmp_variance_per_sample(r) / rd_cmp_variance_per_sample(base);
    char tr[32], vr[32];
    buf[0] = 0;
    if (!(isfinite(t) && t > 0 && isfinite(v) && v >= 0)) return;
    ratio_text(t, tr, sizeof tr);
    ratio_text(v, vr, sizeof vr);
    snprintf(buf, n, "; per sample %s the time and %s the variance", tr, vr);
}

void rd_cmp_sentence(const rd_cmp_summary *S, int i, char *buf, size_t n)
{
    int b = rd_cmp_baseline(S);
    const rd_cmp_row *r = &S->rows[i], *base = &S->rows[b];
    char bias[64], ratio[32], per[128];
    bias_text(r, bias, sizeof bias);
    if (i == b) {
        snprintf(buf, n, "%s: the baseline; %s", r->label, bias);
        return;
    }
    double e = r->efficiency / base->efficiency;
    if (isfinite(e) && e > 0) {
        ratio_text(e, ratio, sizeof ratio);
        per_sample_text(r, base, per, sizeof per);
        snprintf(buf, n, "%s: %s %s's efficiency; %s%s", r->label, ratio, base->label, bias, per);
        return;
    }
    /* No efficiency (an added image without its time): its RMSE against the baseline's. */
    double q = r->err.rmse / base->err.rmse;
    if (isfinite(q) && q > 0) {
        ratio_text(q, ratio, sizeof ratio);
        snprintf(buf, n, "%s: no time given, so no efficiency; RMSE %s %s's; %s", r->label, ratio, base->label, bias);
    } else {
        snprintf(buf, n, "%s: not comparable with %s; %s", r->label, base->label, bias);
    }
}

void rd_cmp_verdict(const rd_cmp_summary *S, char *buf, size_t n)
{
    buf[0] = 0;
    if (S->n_rows < 2) return;
    if (S->ref_too_noisy) {
        snprintf(buf, n, "not ranked: the reference is too noisy (its variance is %.0f%% of the best MSE, more than %.0f%%)%s",
                 100.0 * S->ref_share, 100.0 * RD_CMP_REF_SHARE,
                 S->ref_capped ? "; it stopped at its time cap: give it more with --ref-time S" : "");
        return;
    }
    int w = rd_cmp_winner(S), b = rd_cmp_baseline(S);
    if (w < 0) {
        snprintf(buf, n, "not ranked: fewer than two rows have an efficiency");
        return;
    }
    const rd_cmp_row *win = &S->rows[w];
    char ratio[32];
    if (w != b) {
        ratio_text(win->efficiency / S->rows[b].efficiency, ratio, sizeof ratio);
        snprintf(buf, n, "winner: %s, %s %s's efficiency", win->label, ratio, S->rows[b].label);
        return;
    }
    /* The baseline won: by how much over the next best. */
    int next = -1;
    for (int i = 0; i < S->n_rows; i++) {
        double e = S->rows[i].efficiency;
        if (i != w && isfinite(e) && e > 0 && (next < 0 || e > S->rows[next].efficiency)) next = i;
    }
    ratio_text(win->efficiency / S->rows[next].efficiency, ratio, sizeof ratio);
    snprintf(buf, n, "winner: %s, %s the efficiency of the next best (%s)", win->label, ratio, S->rows[next].label);
}

void rd_cmp_hidden_note(const rd_cmp_summary *S, char *buf, size_t n)
{
    buf[0] = 0;
    if (!(S->hidden_share > RD_HIDDEN_SHARE)) return;
    const char *ref = !strcmp(S->ref_method, "given")
                          ? "check that the given reference holds it (a delta render does not)"
                      : !strcmp(S->ref_method, "delta")
                          ? "the reference, rendered by delta, lacks it"
                          : "the reference is a photon render (guided, march.ls photons, progressive passes): "
                            "its error is variance and a kernel bias that falls as it runs";
    snprintf(buf, n,
             "note: %.3g%% of the light scattered in the media leaves a point, spot or directional light "
             "by way of glass first (refracted or reflected: L S+ paths): delta, guided-unbiased and the marchers with an "
             "unbiased march.ls cannot render it, so their error includes its absence as bias; %s",
             100.0 * S->hidden_share, ref);
}
