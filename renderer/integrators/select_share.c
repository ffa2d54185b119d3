/* select_share.c: with settings.adaptive, how many of the samples each tile's pixels draw (the
 * shares) and what each weighs in its pixel's mean (the weights), set from the rule's figures at
 * every choice (select_rule.c calls rd_select_set_shares) and read by the render once a pixel a
 * pass (rd_select_share, select.c; rd_method.sample_share).
 *
 * Samples where they pay (session 67). With every pixel drawing every sample, a tile's cost
 * weighs against the whole image's variance (select_rule.c, "The rule"): an estimator nearly
 * noiseless at 70x a path's counted cost (the beams in the narrow spot's dim glow) wins no tile.
 * With shares, tile k's pixels draw n_k samples each; at a time R = sum C_k n_k the error sum
 * V_k / n_k is least at n_k ~ sqrt(V_k / C_k) (Lagrange's multiplier), where it is (sum
 * sqrt(V_k C_k))^2 / R: a sum over the tiles, so each takes the estimator of least V C, its own
 * (rd_select_choose_adaptive), and the shares are sqrt(V / C) over the largest tile's (from the
 * pooled figures of all the tile's samples). The beams' squared bias does not fall with a
 * pixel's samples: at a deadline the rule weighs (sum sqrt(V C))^2 / R + sum B, each tile the
 * least of (2 S / R) sqrt(V C) + B at the fixed point of S = sum sqrt(V C), then single moves.
 * Every pixel draws its first RD_SHARE_FIRST samples (the pilot's choice sets shares, read from
 * the first epoch on: below, "Pilot shares", where they are the only ones), a tile
 * whose estimator has no samples yet every sample, every other at least SEL_SHARE_MIN. render.c
 * draws sample i of a pixel of share s where (i + 1 - RD_SHARE_FIRST) s reaches a whole number
 * ("epochs": below), keyed by the index, so the image does not depend on the threads; the photon
 * passes are paced by the shares' sum over the beams' pixels (rd_select_pass_pixels; under
 * "epochs" a pixel's first sample of each epoch comes on top, which the pacing does not count).
 * Not read with shares that follow the choice: the samples the image holds (P, n0), a sample
 * count's end, and the bias's growth with a tile's own samples to come (bias_figures and past_of
 * take the image's pace); with "pilot"'s, fixed, they are (select_rule.c, "Fixed shares").
 *
 * Dark tiles (session 68). Where no sample of any estimator lit a tile or its 8 neighbours, V is
 * 0; at share 1 their cheap pixels set the pace of the sample index and took most of the time
 * (hard-dense-block's black background), and at the floor a rarely lit tile (select_rule.c,
 * "Tiles no sample has lit") would keep a few samples for good. Their V is Laplace's rule of
 * succession's, M / (N + 2) after N samples over the 3x3 tiles, all 0, M the image's mean square
 * of a lit sample: the share falls as 1 / sqrt(N) and never stops (with "pilot"'s shares it keeps
 * the pilot's).
 *
 * Weights (session 69). A pixel's plain mean weighs its samples alike, and with shares a tile
 * that moves to a quieter, costlier estimator draws few samples of it: those it drew before stay
 * in the mean at full weight. On smoke-vdb a tile the beams took at the epoch of 64 held 41
 * samples a pixel of delta's path (variance a sample 0.081) and then drew about 92 of the beams'
 * (0.0014): delta's made 96% of its pixels' variance, 1.9e-4 a pixel, where delta's 2500 samples
 * without shares made 3.2e-5. So each sample carries its tile's weight for its estimator in the
 * pixel's weighted mean (render.c's film), in inverse proportion to the estimator's variance a
 * sample: the combination of independent unbiased estimates of least variance. A tile's weight
 * for an estimator is fixed when the tile first uses it: 1 for the first (the pilot's choice),
 * and for a later one e, w_e = w_o V_o / V_e with o the tile's weighed estimator of the most
 * image samples and V the figures (pooled, with their bounds; a V of 0 the rule of
 * succession's above, so that an estimator reading 0 beside a lit one takes no infinite weight). A pixel's samples of one estimator so weigh alike: a weight that followed each
 * epoch's V would weigh the first epochs' samples by the noisiest figures, and since a tail
 * seen raises V it would weigh the samples after a tail less than the tail (hard-window-beam at
 * 30 s: 0.83x the plain mean; fixed weights 1.08x, docs/guided-marching.md "Weights"). What
 * changes is the ratio between estimators, read once, at the move. The image is consistent, not
 * unbiased (as the shares already make it): a weight is fixed before the samples it weighs are
 * drawn, from figures a pixel's samples enter among thousands, and every estimator is
 * consistent for the pixel's value.
 *
 * Pilot shares (session 70; settings.adaptive "pilot"). Shares that follow the epochs let a
 * pixel's count of samples depend on its own image samples (high early samples raise the
 * variance read and draw more samples to dilute them: a bias of order 1/n). Here the shares are
 * set once, at the pilot's choice (whose samples are on random numbers of their own and not in
 * the image), a tile's from the estimator the pilot gives it, and kept whatever estimator the
 * epochs give it later; there are no weights. Every pixel's count is then fixed before its image
 * samples are drawn, each of them is unbiased given the past (select.c's head), and so is their
 * plain mean. Past the pilot the rule weighs each tile's figures by its fixed share
 * (select_rule.c, "Fixed shares").
 *
 * Epoch shares (session 71; settings.adaptive "epochs"). The shares follow every choice, as with
 * true, and the image stays unbiased by what each sample weighs: in an epoch [a, b) a pixel of
 * share s draws index a and then every index where (v - a) s reaches a whole number
 * (rd_block_next), and a drawn index stands for itself and the indices up to the next drawn one
 * or b, its weight in the pixel's weighted mean (render.c). The blocks tile the epoch, so the
 * weights of a render of N samples a pixel sum to N whatever the shares were: the weighted mean
 * is sum_i w_i X_i / N with each w_i fixed (by the share, read at the epoch's start from samples
 * past) before X_i is drawn, and E[X_i | past] the pixel's value, so it is unbiased however the
 * shares follow the pixel's own samples (tests/test_select.c
 * block_weights_keep_a_pixel_s_mean_unbiased_whatever_its_shares_follow, where the plain mean
 * under the same shares is 183 standard errors off; and render.c checks the weights' sum after
 * every render that ran to its sample count, so any test that renders so fails on a wrong
 * epoch start: RD_ERR_INTERNAL). As an estimate of the indices' mean it has
 * the error the adaptive rule weighs (V / s an index, C s its time): the first epochs' noisy
 * samples weigh their few indices, not their share of the samples drawn (the plain mean's fault,
 * "Weights" above). Under a time limit the last block may run past the index where the clock
 * stops the render (up to 1/s indices): the image is unbiased at a sample count, and under a
 * deadline but for that block's reach, which its share sets. */
#include "integrators/rd_select.h"

#include <math.h>
#include <string.h>

#define SEL_SHARE_MIN (1.0 / 4096.0) /* the least share: its samples grow with the render's */

double rd_select_tile_pixels(const rd_select *sel, int tx, int ty)
{
    int w = sel->width - tx * RD_SELECT_TILE, h = sel->height - ty * RD_SELECT_TILE;
    return (double)(w < RD_SELECT_TILE ? w : RD_SELECT_TILE) * (h < RD_SELECT_TILE ? h : RD_SELECT_TILE);
}

/* Tile k's weights (rd_select.weight, [m k + e]) for the estimators it uses next (its choice
 * and the one on trial), where it has none yet: 1 for the tile's first, else w_o v_o / v_e with
 * o its weighed estimator of the most image samples (statistics st) and v the figures, a 0 the
 * rule of succession's (the head, "Weights"); w_o where either v is 0 (nothing lit anywhere). */
static void set_weights(rd_select *sel, int k, const rd_select_stats *st, const double *v)
{
    const int m = sel->n;
    double *w = &sel->weight[(size_t)m * k];
    const int use[2] = {sel->choice[k], sel->trial[k] ? sel->trial[k] - 1 : sel->choice[k]};
    for (int i = 0; i < 2; i++) {
        int e = use[i], o = -1;
        if (w[e] > 0.0) continue;
        for (int j = 0; j < m; j++)
            if (w[j] > 0.0 && (o < 0 || st[(size_t)m * k + j].image_n > st[(size_t)m * k + o].image_n)) o = j;
        const double r = o >= 0 && v[o] > 0.0 && v[e] > 0.0 ? w[o] * (v[o] / v[e]) : 0.0;
        w[e] = o < 0 ? 1.0 : r > 0.0 && isfinite(r) ? r : w[o]; /* (a ratio out of range: w_o) */
    }
}

void rd_select_set_shares(rd_select *sel, const rd_select_stats *st, const double *var, const double *cost)
{
    if (!sel->share || (!sel->weight && !sel->blocks && sel->choices > 0)) return; /* ("pilot": once, below) */
    const int nx = sel->tiles_x, ny = sel->tiles_y, n = nx * ny, m = sel->n;
    /* M per estimator (all of them in slot RD_SEL_MAX): the samples' squares (dev2 and the tile
     * mean's n mu^2, a lower bound of the pixels' means'), over the lit samples */
    double sq[RD_SEL_MAX + 1] = {0}, lit[RD_SEL_MAX + 1] = {0}, M[RD_SEL_MAX + 1];
    for (int k = 0; k < n; k++)
        for (int e = 0; e < m; e++) {
            const rd_select_stats *t = &st[m * k + e];
            if (!(t->nonzero > 0.0)) continue;
            double q = 0.0;
            for (int c = 0; c < 3; c++) q += (t->dev2[c] + t->sum[c] * t->sum[c] / t->n) / 3.0;
            sq[e] += q, lit[e] += t->nonzero, sq[RD_SEL_MAX] += q, lit[RD_SEL_MAX] += t->nonzero;
        }
    for (int e = 0; e <= RD_SEL_MAX; e++) M[e] = lit[e] > 0.0 ? sq[e] / lit[e] : 0.0;
    double top = 0.0; /* the largest sqrt(V / C) of the estimators the tiles use */
    for (int k = 0; k < n; k++)
        for (int i = 0; i < 2; i++) {
            size_t j = (size_t)m * k + (i && sel->trial[k] ? sel->trial[k] - 1 : sel->choice[k]);
            if (cost[j] > 0.0 && var[j] > 0.0) top = fmax(top, sqrt(var[j] / cost[j]));
        }
    for (int k = 0; k < n; k++) {
        int tx = k % nx, ty = k / nx;
        double around = 0.0, N[RD_SEL_MAX] = {0}; /* the 3x3 tiles' lit samples, and e's samples */
        for (int y = ty - 1; y <= ty + 1; y++)
            for (int x = tx - 1; x <= tx + 1; x++)
                for (int e = 0; x >= 0 && y >= 0 && x < nx && y < ny && e < m; e++)
                    around += st[m * (y * nx + x) + e].nonzero, N[e] += st[m * (y * nx + x) + e].n;
        double vw[RD_SEL_MAX]; /* the weights' V: a V of 0 the rule of succession's */
        for (int e = 0; e < m; e++) {
            size_t j = (size_t)m * k + e;
            double v = var[j], s = 1.0;
            const double dark = rd_select_tile_pixels(sel, tx, ty) * (M[e] > 0.0 ? M[e] : M[RD_SEL_MAX]) / (N[e] + 2.0);
            if (!(v > 0.0) && !(around > 0.0)) v = dark; /* a dark tile: the rule of succession */
            vw[e] = var[j] > 0.0 ? var[j] : dark;
            if (cost[j] > 0.0 && st[j].n > 0.0 && v > 0.0 && top > 0.0)
                s = fmin(1.0, fmax(SEL_SHARE_MIN, sqrt(v / cost[j]) / top));
            sel->share[j] = (float)s;
        }
        if (sel->weight) set_weights(sel, k, st, vw);
        else if (!sel->blocks) /* "pilot": the tile's share whatever estimator the epochs give it (the head) */
            for (int e = 0; e < m; e++) sel->share[(size_t)m * k + e] = sel->share[(size_t)m * k + sel->choice[k]];
    }
}
