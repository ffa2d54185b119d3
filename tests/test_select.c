/* The guided methods' tile selection (settings.select = "tiles", renderer/integrators/select.c and
 * select_rule.c):
 * a pilot gives each 8x8 tile to the method (guided's marcher, guided-unbiased's paths) or to
 * delta's path, whichever the rule says pays.
 *  - the rule: dominance (a tile where one estimator has both less variance and less cost gets
 *    it) and a local minimum of (sum V)(sum C) (no single tile's flip lowers it), on random
 *    instances;
 *  - the image: with tiles of both kinds, guided equals delta region by region (8x8 regions,
 *    the tiles themselves; z-scores as in test_march.c: each standard normal under equal
 *    expectations, bounds 4.5 per region and 5 for the image);
 *  - the choice is deterministic: one thread and two give the same image bit for bit;
 *  - replication: a tile's samples (the pilot's, a trial's) fall 50/50 into two halves of 2x2
 *    blocks in a checkerboard, and a costlier estimator takes the tile only when the rule on
 *    each half alone wants it (a tile in one half only: that half's choice);
 *  - where a tile's halves disagree, the rule on the image's predicted variances (its pooled
 *    relative variance times the tile's mean squared) picks between their two;
 *  - with shares of the samples (settings.adaptive), each tile's own least V C, shares
 *    sqrt(V / C), a dark tile's by the rule of succession, and delta's image still. */
#include "support/rd_test.h"
#include "integrators/rd_select.h"

#include <cjson/cJSON.h>
#include <limits.h>
#include <math.h>
#include <string.h>
#include <unistd.h>

/* ---- The rule ---------------------------------------------------------------------------- */

Test(select, rule_keeps_dominance_and_no_flip_lowers_the_product)
{
    pcg32 rng = pcg32_seed(2026, 11, 7);
    enum { N = 200 };
    double var[2 * N], cost[2 * N];
    uint8_t m[N];
    for (int inst = 0; inst < 50; inst++) {
        /* Variances over four decades, costs over one and a half: both kinds of tile. */
        for (int i = 0; i < 2 * N; i++) {
            var[i] = pow(10.0, -6.0 + 4.0 * pcg32_uniform(&rng));
            cost[i] = pow(10.0, 1.5 * pcg32_uniform(&rng));
        }
        rd_select_choose(var, cost, NULL, N, 2, NULL, m);
        double V = 0.0, C = 0.0;
        for (int k = 0; k < N; k++) V += var[2 * k + m[k]], C += cost[2 * k + m[k]];
        for (int k = 0; k < N; k++) {
            const double *v = &var[2 * k], *c = &cost[2 * k];
            if (v[1] < v[0] && c[1] < c[0]) cr_assert(m[k] == 1, "instance %d tile %d: the marcher dominates", inst, k);
            if (v[0] < v[1] && c[0] < c[1]) cr_assert(m[k] == 0, "instance %d tile %d: delta dominates", inst, k);
        }
        /* Every single change from the choice makes (sum V)(sum C) larger or keeps it. */
        for (int k = 0; k < N; k++) {
            int o = m[k], f = 1 - o;
            double V2 = V - var[2 * k + o] + var[2 * k + f], C2 = C - cost[2 * k + o] + cost[2 * k + f];
            cr_assert(V2 * C2 >= V * C * (1.0 - 1e-12), "instance %d tile %d: flipping it lowers the product", inst, k);
        }
    }
}

Test(select, three_estimators_keep_dominance_and_no_move_lowers_the_product)
{
    /* The same rule over three estimators (delta, the method, delta with the method's
     * equiangular mode: RD_SEL_*): a tile where one estimator has both the least variance and
     * the least cost gets it, and no single move of one tile to either other estimator lowers
     * (sum V)(sum C). */
    pcg32 rng = pcg32_seed(2026, 11, 27);
    enum { N = 200, M = 3 };
    double var[M * N], cost[M * N];
    uint8_t m[N];
    int seen[M] = {0, 0, 0};
    for (int inst = 0; inst < 50; inst++) {
        for (int i = 0; i < M * N; i++) {
            var[i] = pow(10.0, -6.0 + 4.0 * pcg32_uniform(&rng));
            cost[i] = pow(10.0, 1.5 * pcg32_uniform(&rng));
        }
        rd_select_choose(var, cost, NULL, N, M, NULL, m);
        double V = 0.0, C = 0.0;
        for (int k = 0; k < N; k++) V += var[M * k + m[k]], C += cost[M * k + m[k]];
        for (int k = 0; k < N; k++) {
            cr_assert(m[k] < M, "instance %d tile %d: estimator %d", inst, k, m[k]);
            seen[m[k]]++;
            const double *v = &var[M * k], *c = &cost[M * k];
            for (int e = 0; e < M; e++) {
                int dom = 1;
                for (int f = 0; f < M; f++)
                    if (f != e && !(v[e] < v[f] && c[e] < c[f])) dom = 0;
                if (dom) cr_assert(m[k] == e, "instance %d tile %d: estimator %d dominates, %d chosen", inst, k, e, m[k]);
            }
            for (int e = 0; e < M; e++) {
                if (e == m[k]) continue;
                double V2 = V - var[M * k + m[k]] + var[M * k + e], C2 = C - cost[M * k + m[k]] + cost[M * k + e];
                cr_assert(V2 * C2 >= V * C * (1.0 - 1e-12), "instance %d tile %d: moving it to %d lowers the product",
                          inst, k, e);
            }
        }
    }
    for (int e = 0; e < M; e++) cr_assert(seen[e] > 0, "estimator %d never chosen: the test shows nothing of it", e);
}

Test(select, a_tie_goes_to_delta)
{
    /* Tiles that see no medium: variance 0 for both, and the same cost per sample summed over
     * different numbers of samples, so equal up to rounding either way; the last tile sees
     * the medium (lambda = sum V / sum C > 0, so the costs decide the others). */
    enum { N = 7 };
    double var[2 * N] = {0}, cost[2 * N];
    uint8_t m[N];
    var[2 * (N - 1)] = 1.0, var[2 * (N - 1) + 1] = 3.0, cost[2 * (N - 1)] = cost[2 * (N - 1) + 1] = 2.0;
    for (int k = 0; k < N - 1; k++) {
        double c = 0.0;
        for (int i = 0; i < 3 + k; i++) c += 2.18;
        cost[2 * k] = c / (3 + k), cost[2 * k + 1] = nextafter(cost[2 * k], (k & 1) ? 0.0 : 1e9);
    }
    rd_select_choose(var, cost, NULL, N, 2, NULL, m);
    for (int k = 0; k < N; k++) cr_assert(m[k] == 0, "tile %d: a tie (costs %.17g, %.17g) went to the method", k, cost[2 * k], cost[2 * k + 1]);
}

/* The rule's objective with the image's samples so far (P, n0, their cost T0), written out here
 * apart from the rule's: at a deadline R from now, the image's squared error (times the pixels)
 * then; at a sample count, left samples a pixel from now, that error times the render's time
 * (the error's (n0 + left)^2 left out: a constant). */
static double error_at_end(double V, double C, const rd_select_past *p)
{
    if (p->left > 0.0) return (p->P + p->left * V) * (p->T0 + p->left * C);
    double a = p->R / C; /* the samples a pixel draws in the time left */
    return (p->P + a * V) / ((p->n0 + a) * (p->n0 + a));
}

/* Whether some single move of one tile of choice ch lowers error_at_end. */
static int a_move_lowers(const double *var, const double *cost, int n, int m, const uint8_t *ch, const rd_select_past *p)
{
    double V = 0.0, C = 0.0;
    for (int k = 0; k < n; k++) V += var[m * k + ch[k]], C += cost[m * k + ch[k]];
    const double F = error_at_end(V, C, p);
    for (int k = 0; k < n; k++)
        for (int e = 0; e < m; e++) {
            if (e == ch[k]) continue;
            double V2 = V - var[m * k + ch[k]] + var[m * k + e], C2 = C - cost[m * k + ch[k]] + cost[m * k + e];
            if (error_at_end(V2, C2, p) < F * (1.0 - 1e-12)) return 1;
        }
    return 0;
}

Test(select, with_the_image_s_samples_no_move_lowers_its_error_at_the_end)
{
    /* select_rule.c, "The samples the image holds": with the image's samples so far (P, n0, T0),
     * the rule minimises the image's error at the render's end (at a deadline) or that error
     * times the render's time (at a sample count), not (sum V)(sum C). Random instances over
     * three estimators, half ending at a deadline and half at a sample count, the past's
     * variance 0.01-100x what the product's choices would add over the time left: no single move
     * lowers that objective, while the product's own choices are lowered by one in some
     * instances (so the check sees the difference); and with no past (P = n0 = T0 = 0) the
     * choices are the product's. */
    pcg32 rng = pcg32_seed(2026, 12, 6);
    enum { N = 100, M = 3 };
    double var[M * N], cost[M * N];
    uint8_t m[N], plain[N], none[N];
    int differ = 0, plain_lowered = 0;
    for (int inst = 0; inst < 80; inst++) {
        for (int i = 0; i < M * N; i++) {
            var[i] = pow(10.0, -6.0 + 4.0 * pcg32_uniform(&rng));
            cost[i] = pow(10.0, 1.5 * pcg32_uniform(&rng));
        }
        rd_select_choose(var, cost, NULL, N, M, NULL, plain);
        double V0 = 0.0, C0 = 0.0;
        for (int k = 0; k < N; k++) V0 += var[M * k + plain[k]], C0 += cost[M * k + plain[k]];
        const double n0 = 4.0 * pow(4.0, (double)(inst % 5)); /* an epoch: 4 .. 1024 */
        const double ahead = pow(10.0, -1.0 + 3.0 * pcg32_uniform(&rng)); /* time left 0.1 .. 100x */
        const double weight = pow(10.0, -2.0 + 4.0 * pcg32_uniform(&rng));
        const int by_samples = inst & 1;
        rd_select_past past = {V0 * ahead * n0 * weight, n0, n0 * C0, by_samples ? 0.0 : ahead * n0 * C0,
                               by_samples ? ahead * n0 : 0.0, 0.0};
        rd_select_choose(var, cost, NULL, N, M, &past, m);
        for (int k = 0; k < N; k++) differ += m[k] != plain[k];
        cr_assert(!a_move_lowers(var, cost, N, M, m, &past), "instance %d (%s): a single move lowers the objective", inst,
                  by_samples ? "sample count" : "deadline");
        plain_lowered += a_move_lowers(var, cost, N, M, plain, &past);
        const rd_select_past nothing = {0.0, 0.0, 0.0, past.R, past.left, 0.0};
        rd_select_choose(var, cost, NULL, N, M, &nothing, none);
        for (int k = 0; k < N; k++)
            cr_assert(none[k] == plain[k], "instance %d tile %d: with no past, %d where the product takes %d", inst, k,
                      none[k], plain[k]);
    }
    cr_assert(differ > 0 && plain_lowered > 0, "the past changed %d choices, lowered the product's in %d instances: "
              "the test shows nothing", differ, plain_lowered);
}

/* The image's squared error at the end with a consistent estimator's squared bias B (sum over
 * the chosen figures), as select_rule.c's head ("The beams' bias") states it: a deadline's
 * (P + a V) / (n0 + a)^2 + w B, w the past's; a sample count's (P + left V + left^2 B)(T0 + left C). */
static double error_with_bias(double V, double C, double B, const rd_select_past *p)
{
    if (p->left > 0.0) return (p->P + p->left * V + p->left * p->left * B) * (p->T0 + p->left * C);
    double a = p->R / C;
    return (p->P + a * V) / ((p->n0 + a) * (p->n0 + a)) + p->w * B;
}

static double sum_of(const double *f, int n, int m, const uint8_t *ch, int k0)
{
    double t = 0.0;
    for (int k = k0; k < n; k++) t += f[m * k + ch[k]];
    return t;
}

Test(select, a_bias_is_weighed_by_the_samples_still_to_come)
{
    /* Two estimators of equal cost in every tile: delta's path (V 1) and a consistent one (V 0.1,
     * squared bias b a pixel). With a samples a pixel still to come of n0 + a the error at the
     * end is (P + a V) / (n0 + a)^2 + (a / (n0 + a))^2 B, so the consistent one pays while a V
     * saved exceeds a^2 b: b < 0.9 / a. Either side of that line by 10%, at a deadline and at a sample count; and with
     * no end known (the pilot) the bias is not weighed. */
    enum { N = 12 };
    double var[2 * N], cost[2 * N], bias[2 * N];
    uint8_t ch[N];
    static const double ahead[2] = {16.0, 1000.0};
    for (const double *a = ahead; a < ahead + 2; a++)
        for (int by_samples = 0; by_samples < 2; by_samples++)
            for (int side = 0; side < 2; side++) {
                const double b = 0.9 / *a * (side ? 1.1 : 0.9);
                for (int k = 0; k < N; k++) {
                    var[2 * k] = 1.0, var[2 * k + 1] = 0.1, cost[2 * k] = cost[2 * k + 1] = 1.0;
                    bias[2 * k] = 0.0, bias[2 * k + 1] = b;
                }
                /* C = N whatever the choice: a deadline's R = a N leaves a samples a pixel */
                const double w = by_samples ? 0.0 : (*a / (4.0 + *a)) * (*a / (4.0 + *a));
                rd_select_past past = {0.5 * N, 4.0, 4.0 * N, by_samples ? 0.0 : *a * N, by_samples ? *a : 0.0, w};
                rd_select_choose(var, cost, bias, N, 2, &past, ch);
                for (int k = 0; k < N; k++)
                    cr_assert(ch[k] == (side ? 0 : 1), "a = %g (%s), b = %g: tile %d took %d", *a,
                              by_samples ? "sample count" : "deadline", b, k, ch[k]);
                rd_select_choose(var, cost, bias, N, 2, NULL, ch);
                for (int k = 0; k < N; k++) cr_assert(ch[k] == 1, "no end known: the bias was weighed (tile %d)", k);
            }
}

/* Random figures for the rule's tests: variances over four decades and costs over one and a
 * half, count of each. */
static void draw_figures(pcg32 *rng, double *var, double *cost, int count)
{
    for (int i = 0; i < count; i++) {
        var[i] = pow(10.0, -6.0 + 4.0 * pcg32_uniform(rng));
        cost[i] = pow(10.0, 1.5 * pcg32_uniform(rng));
    }
}

Test(select, with_a_bias_no_move_lowers_the_error_at_the_end)
{
    /* Random instances over three estimators, the last with a squared bias (0.01-100x its
     * variance a sample times 1 / (the samples to come)), at a deadline or a sample count: no
     * single move lowers the error at the end with the bias counted, while the choices made
     * without the bias are lowered by one in some instances (so the check sees the bias). */
    pcg32 rng = pcg32_seed(2026, 12, 7);
    enum { N = 100, M = 3 };
    double var[M * N], cost[M * N], bias[M * N];
    uint8_t m[N], blind[N];
    int blind_lowered = 0;
    for (int inst = 0; inst < 80; inst++) {
        const double n0 = 4.0 * pow(4.0, (double)(inst % 5)), ahead = pow(10.0, -1.0 + 3.0 * pcg32_uniform(&rng));
        const int by_samples = inst & 1;
        draw_figures(&rng, var, cost, M * N);
        for (int i = 0; i < M * N; i++)
            bias[i] = i % M == M - 1 ? var[i] / (ahead * n0) * pow(10.0, -2.0 + 4.0 * pcg32_uniform(&rng)) : 0.0;
        uint8_t plain[N];
        rd_select_choose(var, cost, NULL, N, M, NULL, plain);
        double V0 = sum_of(var, N, M, plain, 0), C0 = sum_of(cost, N, M, plain, 0);
        const double share = ahead / (1.0 + ahead); /* (the samples to come at the pace so far: past_of) */
        rd_select_past past = {V0 * ahead * n0, n0, n0 * C0, by_samples ? 0.0 : ahead * n0 * C0, by_samples ? ahead * n0 : 0.0,
                               by_samples ? 0.0 : share * share};
        rd_select_choose(var, cost, bias, N, M, &past, m);
        rd_select_choose(var, cost, NULL, N, M, &past, blind);
        for (int pass = 0; pass < 2; pass++) {
            const uint8_t *ch = pass ? blind : m;
            const double F = error_with_bias(sum_of(var, N, M, ch, 0), sum_of(cost, N, M, ch, 0), sum_of(bias, N, M, ch, 0), &past);
            int lowers = 0;
            for (int k = 0; k < N && !lowers; k++)
                for (int e = 0; e < M; e++) {
                    if (e == ch[k]) continue;
                    uint8_t c2[N];
                    memcpy(c2, ch, sizeof c2);
                    c2[k] = (uint8_t)e;
                    if (error_with_bias(sum_of(var, N, M, c2, 0), sum_of(cost, N, M, c2, 0), sum_of(bias, N, M, c2, 0), &past) <
                        F * (1.0 - 1e-12)) {
                        lowers = 1;
                        break;
                    }
                }
            if (pass) blind_lowered += lowers;
            else cr_assert(!lowers, "instance %d (%s): a single move lowers the error with the bias", inst,
                           by_samples ? "sample count" : "deadline");
        }
    }
    cr_assert(blind_lowered > 0, "the choices blind to the bias were never lowered: the test shows nothing");
}

/* With shares of the samples (settings.adaptive), tile k drawing n_k samples a pixel, the image's
 * error at a time R is sum V_k / n_k + sum B_k, least at n_k ~ sqrt(V_k / C_k), where it is
 * (sum sqrt(V_k C_k))^2 / R + sum B (select_share.c, "Samples where they pay"), written out here
 * apart from the rule's (which reads past->w not at all: the test draws it at random). */
static double error_with_shares(const double *var, const double *cost, const double *bias, int n, int m, const uint8_t *ch,
                                double R)
{
    double S = 0.0, B = 0.0;
    for (int k = 0; k < n; k++) S += sqrt(var[m * k + ch[k]] * cost[m * k + ch[k]]), B += bias ? bias[m * k + ch[k]] : 0.0;
    return S * S / R + B;
}

Test(select, with_shares_each_tile_takes_its_own_least_v_c_and_no_move_lowers_the_error)
{
    /* Random instances over three estimators: with no end known each tile takes the estimator
     * of least V C, its own (the objective (sum sqrt(V C))^2 is a sum over tiles); at a
     * deadline, the last estimator with a squared bias, no single move lowers
     * (sum sqrt(V C))^2 / R + sum B, while the choices blind to the bias are lowered by one in
     * some instance (so the check sees the bias). And a dim tile where the costly estimator has
     * the least V C takes it with shares, where the rule without them keeps the cheap one (its
     * cost weighs against the whole image's variance): the two rules differ where it looks. */
    pcg32 rng = pcg32_seed(2026, 12, 67);
    enum { N = 100, M = 3 };
    double var[M * N], cost[M * N], bias[M * N];
    uint8_t m[N], blind[N];
    int blind_lowered = 0;
    for (int inst = 0; inst < 60; inst++) {
        const double R = pow(10.0, 1.0 + 3.0 * pcg32_uniform(&rng)), w = pcg32_uniform(&rng); /* (not read) */
        draw_figures(&rng, var, cost, M * N);
        for (int i = 0; i < M * N; i++) bias[i] = i % M == M - 1 ? var[i] * pow(10.0, -3.0 + 4.0 * pcg32_uniform(&rng)) : 0.0;
        rd_select_choose_adaptive(var, cost, NULL, N, M, NULL, m);
        for (int k = 0; k < N; k++)
            for (int e = 0; e < M; e++)
                cr_assert(var[M * k + m[k]] * cost[M * k + m[k]] <= var[M * k + e] * cost[M * k + e] * (1.0 + 1e-9),
                          "instance %d tile %d: %d chosen, %d has the lesser V C", inst, k, m[k], e);
        rd_select_past past = {0.0, 4.0, 0.0, R, 0.0, w};
        rd_select_choose_adaptive(var, cost, NULL, N, M, &past, blind);
        const double Fb = error_with_shares(var, cost, bias, N, M, blind, R);
        for (int k = 0, low = 0; k < N && !low; k++)
            for (int e = 0; e < M && !low; e++) {
                uint8_t c2[N];
                memcpy(c2, blind, sizeof c2);
                c2[k] = (uint8_t)e;
                if (error_with_shares(var, cost, bias, N, M, c2, R) < Fb * (1.0 - 1e-12)) low = 1, blind_lowered++;
            }
        rd_select_choose_adaptive(var, cost, bias, N, M, &past, m);
        const double F = error_with_shares(var, cost, bias, N, M, m, R);
        for (int k = 0; k < N; k++)
            for (int e = 0; e < M; e++) {
                if (e == m[k]) continue;
                uint8_t c2[N];
                memcpy(c2, m, sizeof c2);
                c2[k] = (uint8_t)e;
                cr_assert(error_with_shares(var, cost, bias, N, M, c2, R) >= F * (1.0 - 1e-12),
                          "instance %d tile %d: moving it to %d lowers the error", inst, k, e);
            }
    }
    /* Nine bright tiles (V 1 at cost 1 on both estimators) and a dim one: V 1e-4 at cost 1, or
     * 1e-7 at cost 100 (V C 1e-4 against 1e-5). */
    double v2[20], c2[20];
    for (int k = 0; k < 10; k++) v2[2 * k] = v2[2 * k + 1] = 1.0, c2[2 * k] = c2[2 * k + 1] = 1.0;
    v2[18] = 1e-4, v2[19] = 1e-7, c2[19] = 100.0;
    uint8_t with[10], without[10];
    rd_select_choose_adaptive(v2, c2, NULL, 10, 2, NULL, with);
    rd_select_choose(v2, c2, NULL, 10, 2, NULL, without);
    cr_assert(with[9] == 1 && without[9] == 0, "the dim tile: %d with shares, %d without", with[9], without[9]);
    cr_assert(blind_lowered > 0, "the choices blind to the bias were never lowered: the test shows nothing");
}

/* ---- The epochs: the image's samples correct the pilot -------------------------------------- */

/* Statistics i = n k + e (tile k, estimator e) of half h of the samples (select_rule.c,
 * "Replication"): what `pixels` pixels x `spp` samples each would have shown, with per-sample
 * variance v, mean mu, non-zero rate p and cost c, added to what the half holds. */
static void add_half(rd_select *sel, int h, int i, double pixels, double spp, double mu, double v, double p,
                     double c)
{
    rd_select_stats *st = &sel->stats[(size_t)h * sel->n * sel->tiles_x * sel->tiles_y + i];
    double n = pixels * spp, dof = pixels * (spp - 1.0);
    st->n += n, st->dof += dof, st->nonzero += p * n, st->cost += c * n;
    for (int k = 0; k < 3; k++) st->sum[k] += mu * n, st->dev2[k] += v * dof;
}

/* Statistics i = n k + e as a pilot of 16 pixels x 8 samples would have shown them (v, mu, p, c
 * as add_half's), 8 pixels in each half: the halves agree. */
static void fake_pilot(rd_select *sel, int i, double mu, double v, double p, double c)
{
    for (int h = 0; h < 2; h++) {
        memset(&sel->stats[(size_t)h * sel->n * sel->tiles_x * sel->tiles_y + i], 0, sizeof *sel->stats);
        add_half(sel, h, i, 8, 8, mu, v, p, c);
    }
}

/* Statistics i = n k + e of all of a tile's samples: its two halves' (select_rule.c). */
static rd_select_stats tile_stats(const rd_select *sel, int i)
{
    const rd_select_stats *a = &sel->stats[i], *b = &sel->stats[(size_t)sel->n * sel->tiles_x * sel->tiles_y + i];
    rd_select_stats t = {a->n + b->n, a->nonzero + b->nonzero, a->dof + b->dof, {0, 0, 0}, {0, 0, 0}, a->cost + b->cost,
                       a->image_n + b->image_n, a->image_cost + b->image_cost, 0, 0, 0, 0};
    for (int c = 0; c < 3; c++) t.sum[c] = a->sum[c] + b->sum[c], t.dev2[c] = a->dev2[c] + b->dev2[c];
    return t;
}

/* The variance per sample (channel 0) over all of tile statistics i's samples. */
static double tile_var(const rd_select *sel, int i)
{
    rd_select_stats t = tile_stats(sel, i);
    return t.dev2[0] / t.dof;
}

/* n samples of every pixel of the tile drawn from X = mu / q with probability q, else 0 (mean
 * mu, variance mu^2 (1/q - 1)), each costing c: what the estimator in use shows the image. */
static void observe_rare(rd_select *sel, int n, double mu, double q, double c, uint64_t seed)
{
    pcg32 rng = pcg32_seed(seed, 3, 1);
    for (int p = 0; p < 64; p++)
        for (int i = 0; i < n; i++) {
            double x = pcg32_uniform(&rng) < q ? mu / q : 0.0;
            rd_select_observe(sel, (uint64_t)p, v3(x, x, x), c);
        }
}

/* An epoch of a one-tile selection (8x8 pixels) on trial: n samples of every pixel, those with
 * x + y odd the method's (X = mu / q_m with probability q_m, else 0, at cost c_m), the others
 * delta's (q_d, c_d). */
static void observe_trial(rd_select *sel, int n, double mu, double q_d, double c_d, double q_m, double c_m,
                          uint64_t seed)
{
    pcg32 rng = pcg32_seed(seed, 3, 1);
    for (int p = 0; p < 64; p++) {
        int m = rd_select_uses(sel, p % 8, p / 8);
        cr_assert(m == ((p % 8 + p / 8) & 1), "pixel %d on trial: a checkerboard", p);
        double q = m ? q_m : q_d, c = m ? c_m : c_d;
        for (int i = 0; i < n; i++) {
            double x = pcg32_uniform(&rng) < q ? mu / q : 0.0;
            rd_select_observe(sel, (uint64_t)p, v3(x, x, x), c);
        }
    }
}

Test(select, an_epoch_drops_the_method_when_the_image_shows_its_heavy_tail)
{
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(&sel, 8, 8, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    /* The pilot: delta variance 1 at cost 1, the method variance 0.1 at cost 2 (V C 0.2 < 1). */
    fake_pilot(&sel, 0, 1.0, 1.0, 1.0, 1.0);
    fake_pilot(&sel, 1, 1.0, 0.1, 1.0, 2.0);
    rd_select_epoch(&sel, NULL, NULL); /* no samples yet: the pilot's choice */
    cr_assert(sel.choice[0] == 1, "the pilot's statistics favour the method");
    /* The image: the method's samples are mostly zero with a rare firefly, variance
     * 1 / 0.002 - 1 = 499 per sample over 64 x 256 samples. */
    observe_rare(&sel, 256, 1.0, 0.002, 2.0, 11);
    rd_select_epoch(&sel, NULL, NULL);
    cr_assert(tile_stats(&sel, 1).n == 128 + 64 * 256 && tile_stats(&sel, 0).n == 128,
              "the samples go to the estimator that drew them: %g and %g", tile_stats(&sel, 0).n, tile_stats(&sel, 1).n);
    /* delta's 128 samples against the method's 16512: delta goes on trial, not in at once. */
    cr_assert(sel.choice[0] == RD_SEL_METHOD && sel.trial[0] == 1 + RD_SEL_DELTA, "delta on trial (method %d, trial %d)", sel.choice[0],
              sel.trial[0]);
    /* The trial: delta's half shows variance 1 at cost 1, the method's half its heavy tail. */
    observe_trial(&sel, 256, 1.0, 0.5, 1.0, 0.002, 2.0, 13);
    rd_select_epoch(&sel, NULL, NULL);
    cr_assert(sel.choice[0] == 0 && sel.trial[0] == 0, "after the trial, delta (method's variance %g over %g samples)",
              tile_var(&sel, 1), tile_stats(&sel, 1).n);
    cr_assert(tile_stats(&sel, 0).n == 128 + 32 * 256 && tile_stats(&sel, 1).n == 128 + 64 * 256 + 32 * 256,
              "the trial's samples go to the estimator of their pixel: %g and %g", tile_stats(&sel, 0).n,
              tile_stats(&sel, 1).n);
    rd_select_free(&sel);
}

/* A one-tile selection whose pilot favours delta (delta saw the light in half its samples,
 * variance 1 at cost 1; the method variance 0.2 at cost 8: V C 1.6 > 1), then an epoch in which
 * delta's paths find the light once in 200 (variance 199 per sample). The method has 128
 * samples against delta's 16512: the tile goes on trial, not to the method at once. */
static void rare_light_tile_on_trial(rd_select *sel)
{
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(sel, 8, 8, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    fake_pilot(sel, 0, 1.0, 1.0, 0.5, 1.0);
    fake_pilot(sel, 1, 1.0, 0.2, 1.0, 8.0);
    rd_select_epoch(sel, NULL, NULL);
    cr_assert(sel->choice[0] == 0, "the pilot's statistics favour delta");
    observe_rare(sel, 256, 1.0, 0.005, 1.0, 12);
    rd_select_epoch(sel, NULL, NULL);
    cr_assert(sel->choice[0] == RD_SEL_DELTA && sel->trial[0] == 1 + RD_SEL_METHOD, "the method on trial (method %d, trial %d; delta's variance %g)",
              sel->choice[0], sel->trial[0], tile_var(sel, 0));
}

Test(select, an_epoch_takes_the_method_when_delta_s_paths_rarely_find_the_light)
{
    rd_select sel;
    rare_light_tile_on_trial(&sel);
    /* The trial: the method's half keeps its variance 0.2 (X = 1.2 with probability 1 / 1.2),
     * delta's half its rare hits. */
    observe_trial(&sel, 256, 1.0, 0.005, 1.0, 1.0 / 1.2, 8.0, 14);
    rd_select_epoch(&sel, NULL, NULL);
    cr_assert(sel.choice[0] == 1 && sel.trial[0] == 0, "after the trial, the method (its variance %g over %g samples)",
              tile_var(&sel, 1), tile_stats(&sel, 1).n);
    rd_select_free(&sel);
}

Test(select, a_trial_lasts_one_epoch)
{
    /* Even an epoch that brings no samples ends the trial: the rule then decides alone (here
     * for the method: delta's rare hits, variance 199 at cost 1, against 0.2 at cost 8). A
     * trial that the counts could keep open would leave the tile half and half for good. */
    rd_select sel;
    rare_light_tile_on_trial(&sel);
    rd_select_epoch(&sel, NULL, NULL);
    cr_assert(sel.trial[0] == 0 && sel.choice[0] == 1, "the trial ended (method %d, trial %d)", sel.choice[0],
              sel.trial[0]);
    rd_select_free(&sel);
}

Test(select, a_move_that_pays_only_after_the_render_ends_is_not_made)
{
    /* The rare-light tile at the epoch at 256 (delta's 256 samples a pixel in the image,
     * variance 199 a sample at cost 1; the method 0.2 at cost 8). With as much time left as the
     * image has taken (ahead 1) the method's samples would not outweigh delta's 256 by the end:
     * the error there, (P + a V) / (n0 + a)^2 per pixel, is (256 + 256) 199 / 512^2 = 0.39 with
     * delta and (256 x 199 + 32 x 0.2) / 288^2 = 0.61 with the method, so the tile stays with
     * delta, no trial. With 100x the time left: 0.0077 against 0.0043, and the method goes on
     * trial, as with no end known. At a sample count the same: with 256 samples a pixel left,
     * error times time (P + 256 V)(T0 + 256 C) is 101888 x 512 = 5.2e7 with delta against
     * 50995 x 2304 = 1.2e8 with the method; with 25600 left, 1.3e11 against 1.1e10. */
    const rd_select_end ends[5] = {{1.0, 0.0, 1.0}, {100.0, 0.0, 1.0}, {0.0, 256.0, 1.0}, {0.0, 25600.0, 1.0}, {0.0, 0.0, 1.0}};
    const int trial[5] = {0, 1 + RD_SEL_METHOD, 0, 1 + RD_SEL_METHOD, 1 + RD_SEL_METHOD};
    for (int i = 0; i < 5; i++) {
        rd_select sel;
        char err[RD_ERRLEN];
        cr_assert(rd_select_init(&sel, 8, 8, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
        fake_pilot(&sel, 0, 1.0, 1.0, 0.5, 1.0);
        fake_pilot(&sel, 1, 1.0, 0.2, 1.0, 8.0);
        rd_select_epoch(&sel, NULL, &ends[i]);
        cr_assert(sel.choice[0] == RD_SEL_DELTA, "the pilot's statistics favour delta");
        observe_rare(&sel, 256, 1.0, 0.005, 1.0, 12);
        rd_select_epoch(&sel, NULL, &ends[i]);
        cr_assert(sel.choice[0] == RD_SEL_DELTA && sel.trial[0] == trial[i],
                  "end (ahead %g, left %g): choice %d, trial %d (want %d)", ends[i].ahead, ends[i].left, sel.choice[0],
                  sel.trial[0], trial[i]);
        rd_select_free(&sel);
    }
}

Test(select, a_trial_keeps_delta_where_the_method_s_tail_is_delta_s)
{
    /* The lens caustic (docs/benchmarks.md, "Session 13"): both estimators carry the same rare
     * firefly, the method at 8x the cost. delta's 16512 samples show it, the method's pilot of
     * 128 does not; without the trial the tile went to the method. On trial the method's half
     * shows the same tail, and the tile stays with delta. */
    rd_select sel;
    rare_light_tile_on_trial(&sel);
    observe_trial(&sel, 256, 1.0, 0.005, 1.0, 0.005, 8.0, 15);
    rd_select_epoch(&sel, NULL, NULL);
    cr_assert(sel.choice[0] == 0 && sel.trial[0] == 0, "after the trial, delta (the method's variance %g)",
              tile_var(&sel, 1));
    rd_select_free(&sel);
}

Test(select, a_trial_between_delta_and_delta_with_equiangular_sampling_is_a_checkerboard)
{
    /* Three estimators, one tile: delta (variance 1, cost 1, the pilot's 128 samples and 4096
     * of the image's), the method (variance 1, cost 10) and delta with equiangular sampling
     * (variance 0.1, cost 1.2, the pilot's 128 only). The third wins the rule
     * on evidence 33x thinner than delta's, so the tile goes on trial: odd squares the
     * higher-numbered estimator (RD_SEL_DELTA_EQ), even ones delta; the method none. The next
     * epoch, with the trial's samples showing the same figures, moves the tile to it. */
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(&sel, 8, 8, 1.0, 3, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(sel.n == 3);
    fake_pilot(&sel, RD_SEL_DELTA, 1.0, 1.0, 1.0, 1.0);
    for (int h = 0; h < 2; h++) add_half(&sel, h, RD_SEL_DELTA, 32, 64, 1.0, 1.0, 1.0, 1.0);
    fake_pilot(&sel, RD_SEL_METHOD, 1.0, 1.0, 1.0, 10.0);
    fake_pilot(&sel, RD_SEL_DELTA_EQ, 1.0, 0.1, 1.0, 1.2);
    rd_select_epoch(&sel, NULL, NULL);
    cr_assert(sel.choice[0] == RD_SEL_DELTA && sel.trial[0] == 1 + RD_SEL_DELTA_EQ,
              "choice %d, trial %d: lopsided evidence must go on trial first", sel.choice[0], sel.trial[0]);
    for (int p = 0; p < 64; p++) {
        int x = p % 8, y = p / 8, u = rd_select_uses(&sel, x, y);
        cr_assert(u == ((x + y) & 1 ? RD_SEL_DELTA_EQ : RD_SEL_DELTA), "pixel %d on trial uses %d", p, u);
        /* each pixel's 64 samples from its estimator: mean 1, variance 1 (delta) or 0.1 */
        double sd = u == RD_SEL_DELTA_EQ ? sqrt(0.1) : 1.0, c = u == RD_SEL_DELTA_EQ ? 1.2 : 1.0;
        for (int i = 0; i < 64; i++) {
            double xv = 1.0 + sd * (i & 1 ? 1.0 : -1.0);
            rd_select_observe(&sel, (uint64_t)p, v3(xv, xv, xv), c);
        }
    }
    rd_select_epoch(&sel, NULL, NULL);
    cr_assert(sel.choice[0] == RD_SEL_DELTA_EQ && sel.trial[0] == 0, "after the trial: choice %d, trial %d",
              sel.choice[0], sel.trial[0]);
    rd_select_free(&sel);
    /* A trial of the method against delta ends with the rule wanting the third estimator, which
     * was not on trial and has its pilot's samples alone: it goes on trial in turn, it does not
     * take the tile at once (the build before this check gave it the tile). */
    cr_assert(rd_select_init(&sel, 8, 8, 1.0, 3, err, sizeof err) == RD_OK, "%s", err);
    fake_pilot(&sel, RD_SEL_DELTA, 1.0, 1.0, 1.0, 1.0);
    fake_pilot(&sel, RD_SEL_METHOD, 1.0, 1.0, 1.0, 10.0);
    fake_pilot(&sel, RD_SEL_DELTA_EQ, 1.0, 0.1, 1.0, 1.2);
    for (int h = 0; h < 2; h++) { /* delta's and the method's samples after the trial: 4224 and 2176 */
        add_half(&sel, h, RD_SEL_DELTA, 16, 128, 1.0, 1.0, 1.0, 1.0);
        add_half(&sel, h, RD_SEL_METHOD, 16, 64, 1.0, 1.0, 1.0, 10.0);
    }
    sel.choice[0] = RD_SEL_DELTA, sel.trial[0] = 1 + RD_SEL_METHOD;
    rd_select_epoch(&sel, NULL, NULL);
    cr_assert(sel.choice[0] == RD_SEL_DELTA && sel.trial[0] == 1 + RD_SEL_DELTA_EQ,
              "after the method's trial: choice %d, trial %d (the third must go on trial)", sel.choice[0], sel.trial[0]);
    rd_select_free(&sel);
}

/* ---- Replication: a costlier estimator needs both halves of the samples --------------------- */

/* A one-tile selection whose halves show delta (cost 1) with variance v0 and v1 and the method
 * (cost 2) with variance 1, each half a pilot's 8 pixels x 8 samples. */
static void halves_tile(rd_select *sel, double v0, double v1)
{
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(sel, 8, 8, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    for (int h = 0; h < 2; h++) {
        add_half(sel, h, RD_SEL_DELTA, 8, 8, 1.0, h ? v1 : v0, 1.0, 1.0);
        add_half(sel, h, RD_SEL_METHOD, 8, 8, 1.0, 1.0, 1.0, 2.0);
    }
    rd_select_epoch(sel, NULL, NULL); /* no samples: the choice from these statistics */
}

Test(select, a_costlier_estimator_takes_a_tile_only_when_both_halves_want_it)
{
    /* One half's delta samples carry a firefly (variance 4), the other's not (1): over all the
     * samples delta's variance is 2.5, and the rule on them gives the method (V C 2 < 2.5),
     * which its own half does not support (2 > 1). The halves differ, so the cheaper of their
     * two choices, delta, takes the tile: a variance gain at twice the cost is taken only where
     * it shows twice. */
    rd_select sel;
    halves_tile(&sel, 4.0, 1.0);
    cr_assert(sel.choice[0] == RD_SEL_DELTA && sel.trial[0] == 0, "one half's firefly gave the method the tile");
    rd_select_free(&sel);
    /* the same with the halves swapped */
    halves_tile(&sel, 1.0, 4.0);
    cr_assert(sel.choice[0] == RD_SEL_DELTA, "the other half's firefly gave the method the tile");
    rd_select_free(&sel);
    /* Both halves show it (delta's variance 4 and 3): the method. */
    halves_tile(&sel, 4.0, 3.0);
    cr_assert(sel.choice[0] == RD_SEL_METHOD, "a gain both halves show went to delta");
    rd_select_free(&sel);
}

/* ---- Where the halves disagree, the image decides ---------------------------------------------- */

/* A row of eight tiles (64x8 pixels) whose halves show delta (cost 1) with variance v0[k] and
 * v1[k] and the method (cost 4) with variance 1, each half a pilot's 8 pixels x 8 samples, mean 1,
 * every sample non-zero (no Cauchy-Schwarz bound). */
static void noisy_row(rd_select *sel, const double *v0, const double *v1)
{
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(sel, 64, 8, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    for (int k = 0; k < 8; k++)
        for (int h = 0; h < 2; h++) {
            add_half(sel, h, 2 * k + RD_SEL_DELTA, 8, 8, 1.0, h ? v1[k] : v0[k], 1.0, 1.0);
            add_half(sel, h, 2 * k + RD_SEL_METHOD, 8, 8, 1.0, 1.0, 1.0, 4.0);
        }
    rd_select_epoch(sel, NULL, NULL); /* no samples: the choice from these statistics */
}

Test(select, where_the_halves_disagree_the_image_s_pooled_variance_decides)
{
    /* In every tile one half reads delta's variance as 0.01 (it drew no tail) and the other as
     * 10: the first half gives every tile to delta (less variance and less cost), the second to
     * the method ((sum V)(sum C) 8 x 32 = 256 against 80 x 8 = 640 all to delta), so the halves
     * disagree everywhere. Over the image delta's relative variance is 5.005: predicted, every
     * tile to delta makes 40 x 8 = 320 > 256, so the image wants the method, and every tile
     * goes on trial toward it (a move the halves do not agree on always does). The rule before
     * session 40, the cheaper of the two, keeps delta with no trial (the planted fault fails
     * here). */
    double lo[8], hi[8];
    for (int k = 0; k < 8; k++) lo[k] = 0.01, hi[k] = 10.0;
    rd_select sel;
    noisy_row(&sel, lo, hi);
    for (int k = 0; k < 8; k++)
        cr_assert(sel.choice[k] == RD_SEL_DELTA && sel.trial[k] == 1 + RD_SEL_METHOD,
                  "tile %d: estimator %d, trial %d: not delta with the method on trial", k, sel.choice[k], sel.trial[k]);
    rd_select_free(&sel);
    /* The second half reads 6 instead (its own rule still wants the method: 48 x 8 = 384 >
     * 256): the image's relative variance is 3.005, every tile to delta predicts 24 x 8 = 192
     * < 256, the image wants delta, and the tiles keep it with no trial (a rule that took the
     * costlier on a split fails here). */
    for (int k = 0; k < 8; k++) hi[k] = 6.0;
    noisy_row(&sel, lo, hi);
    for (int k = 0; k < 8; k++)
        cr_assert(sel.choice[k] == RD_SEL_DELTA && sel.trial[k] == 0, "tile %d: estimator %d, trial %d", k, sel.choice[k],
                  sel.trial[k]);
    rd_select_free(&sel);
}

/* The half (0 or 1) that one sample of pixel (x, y) of a 16x16 selection lands in. */
static int half_of_pixel(int x, int y)
{
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(&sel, 16, 16, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    rd_select_observe(&sel, (uint64_t)(16 * y + x), v3(1, 1, 1), 1.0);
    rd_select_epoch(&sel, NULL, NULL);
    size_t mn = (size_t)sel.n * sel.tiles_x * sel.tiles_y;
    double n0 = 0.0, n1 = 0.0;
    for (size_t i = 0; i < mn; i++) n0 += sel.stats[i].n, n1 += sel.stats[mn + i].n;
    rd_select_free(&sel);
    cr_assert(n0 + n1 == 1.0, "pixel (%d, %d): one sample, %g in the halves", x, y, n0 + n1);
    return n1 > 0.0;
}

Test(select, the_halves_are_a_checkerboard_of_2x2_blocks_that_splits_a_trial_evenly)
{
    /* 2x2 blocks of pixels, each half's blocks a checkerboard: the blocks beside and below a
     * block are in the other half (so a stripe of blocks, which also splits evenly, fails). */
    for (int by = 0; by < 4; by++)
        for (int bx = 0; bx < 4; bx++) {
            int h = half_of_pixel(2 * bx, 2 * by);
            cr_assert(half_of_pixel(2 * bx + 1, 2 * by + 1) == h, "block (%d, %d) is split", bx, by);
            cr_assert(half_of_pixel(2 * bx + 1, 2 * by) == h && half_of_pixel(2 * bx, 2 * by + 1) == h,
                      "block (%d, %d) is split", bx, by);
            if (bx < 3) cr_assert(half_of_pixel(2 * bx + 2, 2 * by) != h, "blocks (%d, %d) and the next in x", bx, by);
            if (by < 3) cr_assert(half_of_pixel(2 * bx, 2 * by + 2) != h, "blocks (%d, %d) and the next in y", bx, by);
        }
    /* A trial's squares (x + y odd) fall 16 and 16 into each half of every 8x8 tile. */
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(&sel, 16, 16, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    size_t mn = (size_t)sel.n * sel.tiles_x * sel.tiles_y;
    for (int k = 0; k < 4; k++) sel.choice[k] = RD_SEL_DELTA, sel.trial[k] = 1 + RD_SEL_METHOD; /* all on trial */
    for (int p = 0; p < 256; p++) rd_select_observe(&sel, (uint64_t)p, v3(1, 1, 1), 1.0);
    rd_select_epoch(&sel, NULL, NULL);
    for (int k = 0; k < 4; k++)
        for (int e = 0; e < 2; e++)
            cr_assert(sel.stats[2 * k + e].n == 16 && sel.stats[mn + 2 * k + e].n == 16,
                      "tile %d, estimator %d on trial: %g and %g samples in the halves (16 each)", k, e,
                      sel.stats[2 * k + e].n, sel.stats[mn + 2 * k + e].n);
    rd_select_free(&sel);
}

Test(select, a_move_the_halves_do_not_agree_on_goes_on_trial_first)
{
    /* The tile is on the method (cost 2) and the halves differ: one half's delta samples carry
     * a firefly (variance 4: the method), the other's not (1: delta, the cheaper). The evidence
     * is of equal size, which would move the tile at once; but one half's word is weak evidence
     * (a firefly of the method's own in one half sent a thin-fog tile to delta for good, where
     * the strategy was 1.8x delta's efficiency), so delta goes on trial for an epoch. */
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(&sel, 8, 8, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    for (int h = 0; h < 2; h++) {
        add_half(&sel, h, RD_SEL_DELTA, 8, 8, 1.0, h ? 1.0 : 4.0, 1.0, 1.0);
        add_half(&sel, h, RD_SEL_METHOD, 8, 8, 1.0, 1.0, 1.0, 2.0);
    }
    sel.choice[0] = RD_SEL_METHOD;
    rd_select_epoch(&sel, NULL, NULL);
    cr_assert(sel.choice[0] == RD_SEL_METHOD && sel.trial[0] == 1 + RD_SEL_DELTA, "choice %d, trial %d: delta must go on trial",
              sel.choice[0], sel.trial[0]);
    /* after the trial (no new samples here), the halves still differ: the cheaper, delta */
    rd_select_epoch(&sel, NULL, NULL);
    cr_assert(sel.choice[0] == RD_SEL_DELTA && sel.trial[0] == 0, "after the trial: choice %d, trial %d", sel.choice[0],
              sel.trial[0]);
    rd_select_free(&sel);
}

/* ---- Tiles no sample has lit ----------------------------------------------------------------- */

/* A row of eight tiles (64x8 pixels), each estimator's pilot as fake_pilot's: tiles 0-3 lit
 * (mean 1, every sample non-zero) with delta's path at variance v_delta, cost 1, the third
 * estimator (delta's path with the strategy) at variance v_eq, cost 1.2, and the method at
 * variance 1, cost 10; tiles 4-7 unlit (every sample zero, the same costs). */
static void half_lit_row(rd_select *sel, int estimators, double v_delta, double v_eq)
{
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(sel, 64, 8, 1.0, estimators, err, sizeof err) == RD_OK, "%s", err);
    int m = sel->n;
    for (int k = 0; k < 8; k++) {
        double lit = k < 4 ? 1.0 : 0.0;
        fake_pilot(sel, m * k + RD_SEL_DELTA, lit, lit * v_delta, lit, 1.0);
        fake_pilot(sel, m * k + RD_SEL_METHOD, lit, lit * 1.0, lit, m == 3 ? 10.0 : 1.2);
        if (m == 3) fake_pilot(sel, m * k + RD_SEL_DELTA_EQ, lit, lit * v_eq, lit, 1.2);
    }
    rd_select_epoch(sel, NULL, NULL); /* no samples: the pilot's choice */
}

Test(select, a_tile_no_sample_has_lit_takes_the_path_the_image_prefers)
{
    /* The lit tiles show the strategy's path far better (variance 0.1 against 10, at 1.2x the
     * cost): the unlit tiles take it too, at once, where the rule's figures (all zero) would
     * give them plain delta, the cheapest (the build before session 42 fails here: tiles 5-7,
     * whose 3x3 neighbourhoods are dark too). */
    rd_select sel;
    half_lit_row(&sel, 3, 10.0, 0.1);
    for (int k = 4; k < 8; k++)
        cr_assert(sel.choice[k] == RD_SEL_DELTA_EQ && sel.trial[k] == 0, "unlit tile %d: estimator %d, trial %d", k,
                  sel.choice[k], sel.trial[k]);
    rd_select_free(&sel);
    /* The lit tiles show plain delta better (0.1 against 0.1 at 1.2x the cost): unlit tiles
     * keep it. */
    half_lit_row(&sel, 3, 0.1, 0.1);
    for (int k = 4; k < 8; k++)
        cr_assert(sel.choice[k] == RD_SEL_DELTA && sel.trial[k] == 0, "unlit tile %d: estimator %d, trial %d", k,
                  sel.choice[k], sel.trial[k]);
    rd_select_free(&sel);
    /* A guided method without the third estimator: one path, and an unlit tile takes what the
     * rule gives it, the cheapest, as before. */
    half_lit_row(&sel, 2, 10.0, 0.1);
    cr_assert(sel.choice[7] == RD_SEL_DELTA, "one path: unlit tile 7 on estimator %d", sel.choice[7]);
    rd_select_free(&sel);
    /* `delta`'s own "tiles": its "method" is the strategy's path, one of delta's paths. */
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(&sel, 64, 8, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    sel.paths |= 1u << RD_SEL_METHOD; /* as rd_select_prepare sets it for RD_SELECT_METHOD_IS_PATH */
    for (int k = 0; k < 8; k++) {
        double lit = k < 4 ? 1.0 : 0.0;
        fake_pilot(&sel, 2 * k + RD_SEL_DELTA, lit, lit * 10.0, lit, 1.0);
        fake_pilot(&sel, 2 * k + RD_SEL_METHOD, lit, lit * 0.1, lit, 1.2);
    }
    rd_select_epoch(&sel, NULL, NULL);
    for (int k = 4; k < 8; k++)
        cr_assert(sel.choice[k] == RD_SEL_METHOD && sel.trial[k] == 0, "delta's tiles, unlit tile %d: estimator %d, trial %d",
                  k, sel.choice[k], sel.trial[k]);
    rd_select_free(&sel);
}

static const char *select_scene(const char *settings); /* below, with the image tests */

/* A camera sample of a stand-in method: always 1. */
static vec3 unit_method(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    (void)ctx, (void)th, (void)r, (void)smp;
    return v3(1, 1, 1);
}

Test(select, the_pilot_puts_half_of_each_tile_s_pixels_in_each_half)
{
    /* rd_select_prepare's pilot on a 32x24 scene (4x3 tiles): every other pixel each way, 16 a
     * tile, SEL_SPP = 8 samples each per estimator; 8 of the pixels, 64 samples, in each half. */
    rd_scene *s = rt_scene("selpilot.json", select_scene("{\"select\":\"tiles\"}"));
    rd_render_ctx ctx = {.scene = s, .method = rd_method_find("delta"), .threads = 2};
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_prepare(&ctx, unit_method, NULL, 1.0, 0, &sel, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(sel.n == 2 && sel.tiles_x == 4 && sel.tiles_y == 3);
    size_t mn = (size_t)sel.n * sel.tiles_x * sel.tiles_y;
    for (size_t i = 0; i < mn; i++)
        cr_assert(sel.stats[i].n == 64 && sel.stats[mn + i].n == 64, "statistics %zu: %g and %g pilot samples (64 each)", i,
                  sel.stats[i].n, sel.stats[mn + i].n);
    rd_select_free(&sel);
    rd_scene_free(s);
}

/* rd_select_prepare with RD_SELECT_PASSES: the method's share of a pass a sample is pass 1's
 * work (photons emitted, their tentative collisions, the photons indexed, from the render
 * context, at rd_select.h's weights) over the samples a pass serves, photons.pass_spp x the
 * image's 32 x 24 pixels; nothing without the option; with RD_SELECT_PASSES_ORDERED the photons
 * at RD_SELECT_COST_ORDERED's weight instead of RD_SELECT_COST_INDEXED's. Each field alone, then
 * all three; and the share is in the method's recorded cost, pilot and image (which a rule that
 * left the passes out, or added them to delta's samples, fails). */
Test(select, a_pass_s_work_is_shared_by_the_samples_it_serves)
{
    rd_scene *s = rt_scene("selpass.json", select_scene("{\"select\":\"tiles\"}"));
    rd_render_ctx ctx = {.scene = s, .method = rd_method_find("delta"), .threads = 1};
    char err[RD_ERRLEN];
    const double w[3] = {RD_SELECT_COST_EMITTED, RD_SELECT_COST_COLLISION, RD_SELECT_COST_INDEXED};
    const double work[5][3] = {{1000, 0, 0}, {0, 9000, 0}, {0, 0, 4000}, {1000, 9000, 4000}, {1000, 9000, 4000}};
    for (int i = 0; i < 7; i++) { /* 5: no option; 6: the passes ordered, not indexed */
        const double *f = work[i < 5 ? i : i == 5 ? 4 : 3];
        ctx.pass_emitted = f[0], ctx.pass_collisions = f[1], ctx.pass_indexed = f[2];
        s->photons.pass_spp = i == 4 ? 4 : 1;
        rd_select sel;
        int options = i == 5 ? 0 : i == 6 ? RD_SELECT_PASSES | RD_SELECT_PASSES_ORDERED : RD_SELECT_PASSES;
        cr_assert(rd_select_prepare(&ctx, unit_method, NULL, 1.0, options, &sel, err, sizeof err) == RD_OK, "%s", err);
        double w2 = i == 6 ? RD_SELECT_COST_ORDERED : w[2];
        double want = i == 5 ? 0.0 : (w[0] * f[0] + w[1] * f[1] + w2 * f[2]) / (s->photons.pass_spp * 32.0 * 24.0);
        cr_assert(fabs(sel.method_pass_cost - want) <= 1e-12 * want, "case %d: a sample's share %.17g, not %.17g", i,
                  sel.method_pass_cost, want);
        /* It is in every recorded sample of the method (the stand-in does no counted work): the
         * pilot's, 2.18 + the share a sample within the records' unit, and the image's (a tile
         * given to the method, one sample of each of its pixels), where the rule reads it. */
        int tiles = sel.tiles_x * sel.tiles_y;
        size_t mn = (size_t)sel.n * tiles;
        for (int k = 0; k < tiles; k++)
            for (int h = 0; h < 2; h++) {
                const rd_select_stats *st = &sel.stats[h * mn + (size_t)sel.n * k + RD_SEL_METHOD];
                cr_assert(fabs(st->cost / st->n - (RD_SELECT_COST_SAMPLE + want)) < 2.0 / RD_SELECT_COST_UNIT,
                          "case %d, tile %d, half %d: the pilot's cost %g a sample, not %g", i, k, h, st->cost / st->n,
                          RD_SELECT_COST_SAMPLE + want);
            }
        sel.choice[0] = RD_SEL_METHOD, sel.trial[0] = 0;
        rd_thread th = {0};
        for (int y = 0; y < 8; y++)
            for (int x = 0; x < 8; x++) {
                th.pixel = (uint64_t)y * 32 + x, th.x = x, th.y = y;
                rd_sampler smp = rd_sampler_start(th.pixel, 0, 7);
                rd_select_radiance(&ctx, &sel, unit_method, &th, (ray3){v3(0, 0, 3), v3(0, 0, -1)}, &smp);
                rd_select_pixel_done(&sel, &th);
                double c = sel.pixels[th.pixel].cost / RD_SELECT_COST_UNIT;
                cr_assert(fabs(c - (RD_SELECT_COST_SAMPLE + want)) < 2.0 / RD_SELECT_COST_UNIT,
                          "case %d, pixel (%d, %d): the image's sample cost %g, not %g", i, x, y, c, RD_SELECT_COST_SAMPLE + want);
            }
        rd_select_free(&sel);
    }
    rd_scene_free(s);
}

/* A stand-in second estimator of the method's (rd_select_prepare_path): always 2, with 10 PDF
 * segments counted a sample. */
static vec3 path_stand_in(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    (void)ctx, (void)r, (void)smp;
    th->cells += 10;
    return v3(2, 2, 2);
}

/* One sample of every pixel of a 32x24 selection scene through rd_select_radiance (with
 * unit_method as the method), each recorded (rd_select_pixel_done); Lx[y 32 + x] gets its red. */
static void sample_every_pixel(const rd_render_ctx *ctx, rd_select *sel, rd_thread *th, double *Lx)
{
    for (int y = 0; y < 24; y++)
        for (int x = 0; x < 32; x++) {
            th->pixel = (uint64_t)y * 32 + x, th->x = x, th->y = y;
            rd_sampler smp = rd_sampler_start(th->pixel, 0, 7);
            Lx[th->pixel] = rd_select_radiance(ctx, sel, unit_method, th, (ray3){v3(0, 0, 3), v3(0, 0, -1)}, &smp).x;
            rd_select_pixel_done(sel, th);
        }
}

/* The method's second estimator (`guided`'s guided-unbiased paths) is the selection's last: the
 * fourth with the third, else the third, and not one of delta's paths (the unlit tiles' choice).
 * The pilot samples it as the others (64 samples in each half of each tile), its cost counts its
 * PDF segments at its own weight (0.5 here; the method's 7 would make 72.18 a sample, not 7.18),
 * and a tile given to it renders it and counts the sample in th->path_samples. */
Test(select, the_method_s_second_estimator_is_sampled_and_costed_with_its_own_weight)
{
    rd_scene *s = rt_scene("selpath.json", select_scene("{\"select\":\"tiles\"}"));
    rd_render_ctx ctx = {.scene = s, .method = rd_method_find("delta"), .threads = 1};
    char err[RD_ERRLEN];
    for (int third = 0; third < 2; third++) {
        rd_select sel;
        cr_assert(rd_select_prepare_path(&ctx, unit_method, NULL, 7.0, third ? RD_SELECT_THIRD : 0, path_stand_in, 0.5,
                                         &sel, err, sizeof err) == RD_OK,
                  "%s", err);
        int e = sel.n - 1, tiles = sel.tiles_x * sel.tiles_y;
        cr_assert(sel.n == 3 + third && sel.kind[e] == RD_SEL_PATH, "third %d: %d estimators, the last of kind %d", third,
                  sel.n, sel.kind[e]);
        cr_expect(!third || sel.kind[RD_SEL_DELTA_EQ] == RD_SEL_DELTA_EQ, "the third is delta's path with the strategy");
        cr_expect(sel.paths == (1u << RD_SEL_DELTA | (third ? 1u << RD_SEL_DELTA_EQ : 0u)), "third %d: delta's paths 0x%x",
                  third, sel.paths);
        size_t mn = (size_t)sel.n * tiles;
        for (int k = 0; k < tiles; k++)
            for (int h = 0; h < 2; h++) {
                const rd_select_stats *st = &sel.stats[h * mn + (size_t)sel.n * k + e];
                cr_expect(st->n == 64 && st->sum[0] == 128.0 && fabs(st->cost / st->n - (RD_SELECT_COST_SAMPLE + 5.0)) < 1e-4,
                          "third %d, tile %d, half %d: %g samples, sum %g, cost %g a sample (64, 128, 7.18)", third, k, h,
                          st->n, st->sum[0], st->cost / st->n);
            }
        /* every tile given to it: every pixel's sample is its */
        for (int k = 0; k < tiles; k++) sel.choice[k] = (uint8_t)e, sel.trial[k] = 0;
        rd_thread th = {0};
        double Lx[32 * 24];
        sample_every_pixel(&ctx, &sel, &th, Lx);
        for (int i = 0; i < 32 * 24; i++)
            cr_expect(Lx[i] == 2.0, "pixel (%d, %d): %g, not the second estimator's 2", i % 32, i / 32, Lx[i]);
        cr_expect(th.path_samples == 32 * 24 && th.delta_samples == 0, "%llu path samples, %llu delta samples",
                  (unsigned long long)th.path_samples, (unsigned long long)th.delta_samples);
        cr_expect(rd_select_pass_pixels(&sel, 32 * 24) == 0, "the method renders no pixel");
        rd_select_free(&sel);
    }
    rd_scene_free(s);
}

/* What a delta hook saw (through ctx->state): calls per equiangular mode, pilot or not. */
typedef struct {
    long calls[2][RD_EQ_TILES + 1]; /* [th->pilot][mode] */
} hook_log;

/* A method's delta hook that records its call and returns 3 (the stand-in method returns 1). */
static vec3 recording_hook(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp, int equiangular)
{
    (void)r, (void)smp;
    hook_log *log = ctx->state;
    if (equiangular >= 0 && equiangular <= RD_EQ_TILES) log->calls[th->pilot ? 1 : 0][equiangular]++;
    return v3(3, 3, 3);
}

/* rd_select_prepare's delta hook (a method's own delta path, with its probes: guided-unbiased's
 * guide.probes) renders both delta estimators, in the pilot and in the image: plain delta in
 * its path mode (settings.equiangular false: RD_EQ_OFF) and the third, delta with the strategy
 * on every flight, in RD_EQ_ALL; and never the method's own tiles. A selection without the
 * hook never calls it. One thread: the log is not shared. */
Test(select, the_delta_hook_renders_both_delta_estimators)
{
    rd_scene *s = rt_scene("selhook.json", select_scene("{\"select\":\"tiles\"}"));
    hook_log log = {0};
    rd_render_ctx ctx = {.scene = s, .method = rd_method_find("delta"), .threads = 1, .state = &log};
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_prepare(&ctx, unit_method, recording_hook, 1.0, 1, &sel, err, sizeof err) == RD_OK, "%s",
              err);
    cr_assert(sel.n == 3, "a spot light and the method's own mode on: three estimators, got %d", sel.n);
    /* the pilot: 16 pixels a tile x 8 samples, each delta estimator, 12 tiles */
    cr_expect(log.calls[1][RD_EQ_OFF] == 12 * 16 * 8 && log.calls[1][RD_EQ_ALL] == 12 * 16 * 8,
              "pilot: %ld plain and %ld every-flight calls (1536 each)", log.calls[1][RD_EQ_OFF], log.calls[1][RD_EQ_ALL]);
    /* the image: every pixel once; the hook where a delta estimator has it, its value returned */
    rd_thread th = {0};
    long delta_px = 0, eq_px = 0;
    for (int y = 0; y < 24; y++)
        for (int x = 0; x < 32; x++) {
            th.pixel = (uint64_t)y * 32 + x, th.x = x, th.y = y;
            rd_sampler smp = rd_sampler_start(th.pixel, 0, 7);
            vec3 L = rd_select_radiance(&ctx, &sel, unit_method, &th, (ray3){v3(0, 0, 3), v3(0, 0, -1)}, &smp);
            int use = rd_select_uses(&sel, x, y);
            delta_px += use == RD_SEL_DELTA, eq_px += use == RD_SEL_DELTA_EQ;
            cr_expect(L.x == (use == RD_SEL_METHOD ? 1.0 : 3.0), "pixel (%d, %d), estimator %d: %g", x, y, use, L.x);
        }
    cr_expect(log.calls[0][RD_EQ_OFF] == delta_px && log.calls[0][RD_EQ_ALL] == eq_px,
              "image: %ld and %ld calls for %ld and %ld pixels", log.calls[0][RD_EQ_OFF], log.calls[0][RD_EQ_ALL],
              delta_px, eq_px);
    rd_select_free(&sel);
    /* without the hook: never called */
    hook_log none = {0};
    ctx.state = &none;
    cr_assert(rd_select_prepare(&ctx, unit_method, NULL, 1.0, 1, &sel, err, sizeof err) == RD_OK, "%s", err);
    long total = 0;
    for (int p = 0; p < 2; p++)
        for (int m = 0; m <= RD_EQ_TILES; m++) total += none.calls[p][m];
    cr_expect(total == 0, "a selection without the hook called it %ld times", total);
    rd_select_free(&sel);
    rd_scene_free(s);
}

/* A stand-in method whose samples vary: a value from the sampler (now and then 0, now and then
 * not finite), and some counted work (density lookups) that depends on it: floor(7 u), and 5
 * more where the sample is not finite. */
static vec3 varying_method(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    (void)ctx, (void)r;
    double u = rd_sampler_1d(smp);
    th->counters.lookups += (uint64_t)(u * 7.0);
    if (u < 0.05) return th->counters.lookups += 5, v3(NAN, 0, 0);
    if (u < 0.3) return v3(0, 0, 0);
    return v3(u * 3.1, u * u, 1.0 / u);
}

/* The samples of two passes (samples 0-2 of every pixel, then 3-6), pixel after pixel, through
 * rd_select_radiance on a thread whose index is `index`, each pixel closed by
 * rd_select_pixel_done; the selection prepared with varying_method, and with `all_method` every
 * tile then given to it. Returns how many samples were not finite. */
static int two_passes(rd_render_ctx *ctx, rd_select *sel, int index, int all_method)
{
    char err[RD_ERRLEN];
    cr_assert(rd_select_prepare(ctx, varying_method, NULL, 1.0, 0, sel, err, sizeof err) == RD_OK, "%s", err);
    if (all_method) {
        size_t tiles = (size_t)sel->tiles_x * sel->tiles_y;
        memset(sel->choice, RD_SEL_METHOD, tiles), memset(sel->trial, 0, tiles);
    }
    int dropped = 0;
    rd_thread th = {0};
    th.index = index;
    for (int pass = 0; pass < 2; pass++)
        for (int y = 0; y < 24; y++)
            for (int x = 0; x < 32; x++) {
                th.pixel = (uint64_t)y * 32 + x, th.x = x, th.y = y;
                for (int i = pass ? 3 : 0; i < (pass ? 7 : 3); i++) {
                    rd_sampler smp = rd_sampler_start(th.pixel, (uint64_t)i, 9);
                    vec3 L = rd_select_radiance(ctx, sel, varying_method, &th, (ray3){v3(0, 0, 3), v3(0, 0, -1)}, &smp);
                    dropped += !v3_finite(L);
                }
                rd_select_pixel_done(sel, &th);
            }
    return dropped;
}

/* A thread's record of a pixel (select.c, rd_select_run) is the record a sample at a time
 * gives, to the bit: the sums, the counts and the counted cost (a dropped non-finite sample's
 * work counted too), over samples that two passes split. The one-sample path runs for a thread
 * with no record of its own (index -1). */
Test(select, a_thread_s_record_of_a_pixel_equals_one_sample_at_a_time)
{
    rd_scene *s = rt_scene("selrun.json", select_scene("{\"select\":\"tiles\"}"));
    rd_render_ctx ctx = {.scene = s, .method = rd_method_find("delta"), .threads = 1};
    rd_select a, b;
    two_passes(&ctx, &a, 0, 0);
    two_passes(&ctx, &b, -1, 0);
    size_t n = (size_t)a.width * a.height;
    double samples = 0.0, costs = 0.0;
    for (size_t p = 0; p < n; p++) samples += a.pixels[p].n, costs += a.pixels[p].cost / RD_SELECT_COST_UNIT;
    cr_assert(samples > 0.5 * 7 * n && samples < 7.0 * n, "%g finite samples of %zu", samples, 7 * n);
    cr_assert(memcmp(a.pixels, b.pixels, n * sizeof *a.pixels) == 0, "the thread's records differ from one sample's at a time");
    cr_assert(costs > 2.18 * samples, "the counted cost %g of %g samples has no work in it", costs, samples);
    rd_select_epoch(&a, NULL, NULL);
    rd_select_epoch(&b, NULL, NULL);
    size_t mn = 2 * (size_t)a.n * a.tiles_x * a.tiles_y;
    cr_assert(memcmp(a.stats, b.stats, mn * sizeof *a.stats) == 0 && memcmp(a.choice, b.choice, (size_t)a.tiles_x * a.tiles_y) == 0,
              "the epoch's statistics or choices differ");
    rd_select_free(&a);
    rd_select_free(&b);
    rd_scene_free(s);
}

/* A pixel's counted cost is that of every sample it drew, the film's dropped ones too: with
 * every tile on varying_method, whose sample u costs floor(7 u) lookups (5 more where it is not
 * finite, u < 0.05) and the camera sample's RD_SELECT_COST_SAMPLE, each pixel's record is the
 * sum over its seven samples, the dropped ones included, up to the weights' rounding to whole
 * units (at most 7 x 0.48 units in a pixel's cost of 15 lookups or more: a relative 3.4e-6;
 * allowed 1e-5). A record that leaves the dropped samples' work out (7.18 lookups each: 10% or
 * more of a pixel's cost), or that counts a run's work twice, fails. */
Test(select, a_pixel_s_counted_cost_is_every_drawn_sample_s)
{
    rd_scene *s = rt_scene("selcost.json", select_scene("{\"select\":\"tiles\"}"));
    rd_render_ctx ctx = {.scene = s, .method = rd_method_find("delta"), .threads = 1};
    rd_select sel;
    int dropped = two_passes(&ctx, &sel, 0, 1);
    cr_assert(dropped > 0, "no sample was dropped: the test tests nothing");
    for (int p = 0; p < 24 * 32; p++) {
        double want = 0.0;
        for (int i = 0; i < 7; i++) {
            rd_sampler smp = rd_sampler_start((uint64_t)p, (uint64_t)i, 9);
            double u = rd_sampler_1d(&smp);
            want += floor(u * 7.0) + (u < 0.05 ? 5.0 : 0.0) + RD_SELECT_COST_SAMPLE;
        }
        double got = sel.pixels[p].cost / RD_SELECT_COST_UNIT;
        cr_assert(fabs(got - want) <= 1e-5 * want, "pixel %d: counted cost %.9g, its samples' %.9g", p, got, want);
    }
    rd_select_free(&sel);
    rd_scene_free(s);
}

Test(select, a_tile_of_2x2_pixels_at_the_edge_takes_the_choice_of_its_one_half)
{
    /* 26x26 pixels: the last row and column of tiles are 2 pixels wide, and the corner tile
     * (15: pixels 24-25 each way) is one 2x2 block, in half 0 alone. Every tile shows delta
     * (variance 1, cost 1) better than the method (1, cost 2) in both halves, but the corner,
     * whose 4 pixels' delta variance is 1000: half 0 wants the method there (and, pooled, in
     * its neighbours), half 1, which has no samples of the corner, delta. The corner takes its
     * one half's method; its neighbours' halves differ, and the image beyond their 3x3 tiles
     * (which leaves the corner out: select_rule.c, "Where the halves disagree") predicts delta's
     * variance 1 there, so they keep delta with no trial. A prediction that kept the corner in
     * (delta's pooled relative variance about 7.5) would put tile 10 on trial toward the
     * method. */
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(&sel, 26, 26, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(sel.tiles_x == 4 && sel.tiles_y == 4);
    for (int k = 0; k < 16; k++)
        for (int h = 0; h < 2; h++) {
            if (k == 15 && h == 1) continue;
            double px = k == 15 ? 4 : (k % 4 == 3 || k / 4 == 3) ? 8 : 32;
            add_half(&sel, h, 2 * k + RD_SEL_DELTA, px, 8, 1.0, k == 15 ? 1000.0 : 1.0, 1.0, 1.0);
            add_half(&sel, h, 2 * k + RD_SEL_METHOD, px, 8, 1.0, 1.0, 1.0, 2.0);
        }
    rd_select_epoch(&sel, NULL, NULL);
    cr_assert(sel.choice[15] == RD_SEL_METHOD, "the corner tile: %d", sel.choice[15]);
    cr_assert(sel.choice[10] == RD_SEL_DELTA && sel.trial[10] == 0, "its neighbour: %d, trial %d", sel.choice[10],
              sel.trial[10]);
    rd_select_free(&sel);
}

/* ---- Pooling: a tile's neighbours steady its estimate ---------------------------------------- */

/* A 5x5-tile selection (40x40 pixels) whose every tile has the pilot statistics of fake_pilot:
 * delta variance 1 at cost 1, the method variance 0.67 at cost 2.75 (V C 1.84 > 1: delta; the
 * lens caustic's per-sample figures, docs/benchmarks.md "Session 13"), except where delta_v
 * gives delta's variance in a tile. */
static void pool_scene(rd_select *sel, const double *delta_v)
{
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(sel, 40, 40, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(sel->tiles_x == 5 && sel->tiles_y == 5);
    for (int k = 0; k < 25; k++) {
        fake_pilot(sel, 2 * k, 1.0, delta_v[k], 1.0, 1.0);
        fake_pilot(sel, 2 * k + 1, 1.0, 0.67, 1.0, 2.75);
    }
    rd_select_epoch(sel, NULL, NULL); /* no samples: the choice from these statistics */
}

Test(select, a_beam_across_the_tiles_still_goes_to_the_method)
{
    /* delta's variance 50x along the middle row of tiles (a thin beam its paths rarely find):
     * every row tile's window holds two or three beam tiles of its six or nine, a pooled
     * variance of 17 > 1.84, so the row goes to the method. A pooling robust to one tile's
     * outlier must not lose this: a median of the window would drop the beam (three of nine). */
    double v[25];
    for (int k = 0; k < 25; k++) v[k] = k / 5 == 2 ? 50.0 : 1.0;
    rd_select sel;
    pool_scene(&sel, v);
    for (int x = 0; x < 5; x++)
        cr_assert(sel.choice[2 * 5 + x] == 1, "beam tile %d stayed with delta", x);
    rd_select_free(&sel);
}

/* ---- The non-zero probability's prior (session 22) ------------------------------------------ */

/* A 5x5-tile selection whose method (every tile: mean 1, variance 0.5, never zero, cost c_m)
 * meets a delta (cost 1) that is zero in all 128 pilot samples of every tile but those where
 * lit[k]: there its samples are mu / q with probability q = hits / 128 (mean 1, variance
 * 1/q - 1). In an all-zero tile delta's variance is the Cauchy-Schwarz bound mu^2 (1/p - 1),
 * mu = 1/2 (the two means' mean), with p from the tile's count and delta's non-zero fraction
 * over the lit tiles (select_rule.c's head); the choice pools each figure over 3x3 windows. */
static void prior_scene(rd_select *sel, const int *lit, int hits, double c_m)
{
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(sel, 40, 40, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    for (int k = 0; k < 25; k++) {
        double q = hits / 128.0;
        if (lit[k]) fake_pilot(sel, 2 * k, 1.0, 1.0 / q - 1.0, q, 1.0);
        else fake_pilot(sel, 2 * k, 0.0, 0.0, 0.0, 1.0);
        fake_pilot(sel, 2 * k + 1, 1.0, 0.5, 1.0, c_m);
    }
    rd_select_epoch(sel, NULL, NULL); /* no samples: the choice from these statistics */
}

Test(select, a_tile_of_zeros_goes_by_how_often_delta_sees_light_elsewhere)
{
    /* Rare: delta found the light once, in the centre tile (1 of the 3200 samples: hard-narrow-
     * spot's pilot had 39 of 38400), the method at 70x delta's cost (V C 35). delta's non-zero
     * fraction pbar = 2/3202, so a tile of 128 zeros has p = 2 pbar / 130 = 9.6e-6 and a
     * variance bound of 2.6e4: every tile goes to the method. With Laplace's rule (p = 1/130,
     * bound 32) all 25 stayed with delta. */
    int lit[25] = {0};
    lit[12] = 1;
    rd_select sel;
    prior_scene(&sel, lit, 1, 70.0);
    for (int k = 0; k < 25; k++) cr_assert(sel.choice[k] == 1, "rare light: tile %d stayed with delta", k);
    rd_select_free(&sel);
    /* Common: delta's samples are non-zero in half the samples of each of the other 24 tiles
     * (variance 1), pbar = 0.48, so the one tile of zeros in the centre has p = 1/135, about
     * Laplace's, a bound of 34, a pooled variance of 4.6 < 35: delta keeps it (the rare case's
     * p would give it away: a pooled 2900). */
    for (int k = 0; k < 25; k++) lit[k] = k != 12;
    prior_scene(&sel, lit, 64, 70.0);
    cr_assert(sel.choice[12] == 0, "common light, half: the tile of zeros went to the method");
    rd_select_free(&sel);
    /* Most: delta's samples non-zero in 115 of 128 (variance 0.11) around the tile of zeros, the
     * method at 6x the cost (V C 3): pbar = 0.86, p = 0.013, a bound of 19, pooled 2.2 < 3:
     * delta keeps it. Laplace's p (bound 32, pooled 3.7) gives it away; so does any prior that
     * does not follow the image: a fixed centre p0 must be above 0.6 here and below 0.46 in the
     * rare case. */
    prior_scene(&sel, lit, 115, 6.0);
    cr_assert(sel.choice[12] == 0, "common light, most: the tile of zeros went to the method");
    rd_select_free(&sel);
}

/* A 5x5-tile selection, columns 0-1 dim and 2-4 bright (session 48, select_rule.c's head "A dim
 * tile's prior"). In the bright tiles delta (cost 1) finds the light in 8 of 128 pilot samples
 * (mean 1, variance 15), the method (cost 3) in every one (variance 0.5). In the dim tiles the
 * method finds it once in 128 (mean mu_d, variance mu_d^2 x 127) and delta never: its variance
 * there is the Cauchy-Schwarz bound, mu^2 (1/p - 1) with mu = mu_d / 2 and p from its prior. */
static void dim_scene(rd_select *sel, double mu_d, int delta_hits_dim)
{
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(sel, 40, 40, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    for (int k = 0; k < 25; k++) {
        if (k % 5 >= 2) {
            fake_pilot(sel, 2 * k, 1.0, 15.0, 8.0 / 128.0, 1.0);
            fake_pilot(sel, 2 * k + 1, 1.0, 0.5, 1.0, 3.0);
        } else {
            double q = delta_hits_dim / 128.0;
            if (q > 0.0) fake_pilot(sel, 2 * k, mu_d, mu_d * mu_d * (1.0 / q - 1.0), q, 1.0);
            else fake_pilot(sel, 2 * k, 0.0, 0.0, 0.0, 1.0);
            fake_pilot(sel, 2 * k + 1, mu_d, mu_d * mu_d * 127.0, 1.0 / 128.0, 3.0);
        }
    }
    rd_select_epoch(sel, NULL, NULL); /* no samples: the choice from these statistics */
}

Test(select, a_dim_tile_s_zeros_weigh_by_how_dim_it_is)
{
    /* Delta's non-zero fraction over the lit tiles, pbar = 121/3202 = 0.038 (the bright tiles'
     * 8 in 128 over the dim tiles' zeros), put its bound in a dim tile's half (64 samples) at
     * mu^2 (66 / (2 pbar) - 1) = 0.022 for mu_d = 0.01, 1.7x the method's 0.0127 there, and
     * the image's lambda (its variance over its cost: the bright tiles' 0.5 a sample at cost 3)
     * judged that worth a third of the cost: the dim tiles went to delta, the narrow spot's
     * firefly. The method's half hit there, where its image fraction (0.60) expects 38.6, scales
     * delta's prior centre by 1.5/39.6 and its bound about 26x: the dim tiles go to the method.
     * (It fails without the scale.) */
    rd_select sel;
    dim_scene(&sel, 0.01, 0);
    for (int y = 0; y < 5; y++) {
        cr_assert(sel.choice[5 * y] == 1, "dim tile (0, %d) went to delta on its zeros", y);
        cr_assert(sel.choice[5 * y + 4] == 1, "bright tile (4, %d) went to delta", y);
    }
    rd_select_free(&sel);
    /* Where delta does find the dim tiles' light, once in 128 as the method does, its own
     * samples say what it is worth: variance mu_d^2 x 127 at a third of the cost, and the dim
     * tiles keep delta (a check that the scale does not overshoot: its bound there, 0.013, is
     * about its sample variance). */
    dim_scene(&sel, 0.01, 1);
    for (int y = 0; y < 5; y++) cr_assert(sel.choice[5 * y] == 0, "dim tile (0, %d) lost delta, which finds its light", y);
    rd_select_free(&sel);
    /* A tile bright to the others is not dim: session 22's "most" case (delta non-zero in 115
     * of 128 samples around a tile where it saw none and the method lit every sample), with the
     * method at 3x delta's cost, keeps delta, as it did before the scale. A scale that counted
     * delta's own zeros (dimness 129/239 there, its bound 1.85x) gives the tile to the method. */
    int lit[25];
    for (int k = 0; k < 25; k++) lit[k] = k != 12;
    prior_scene(&sel, lit, 115, 3.0);
    cr_assert(sel.choice[12] == 0, "a tile bright to the method went to it on delta's zeros");
    rd_select_free(&sel);
}

Test(select, epochs_end_at_4_16_64_and_only_with_epochs_on)
{
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(&sel, 8, 8, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(rd_select_epoch_next(&sel, 0) == 4 && rd_select_epoch_next(&sel, 3) == 4);
    cr_assert(rd_select_epoch_next(&sel, 4) == 16 && rd_select_epoch_next(&sel, 63) == 64);
    cr_assert(rd_select_epoch_next(&sel, INT_MAX - 1) == INT_MAX);
    sel.epochs = 0; /* settings.select "pilot" */
    cr_assert(rd_select_epoch_next(&sel, 0) == INT_MAX, "the pilot's choice only: no epochs");
    rd_select_free(&sel);
    cr_assert(rd_select_epoch_next(&sel, 0) == INT_MAX, "no selection, no epochs");
}

/* ---- The image --------------------------------------------------------------------------- */

/* rt_spot_fog_json at 32x24, 12 tiles: the right half of the image sees no fog (delta's tiles
 * there, where both estimators are exact and delta's costs no more). Which of the lit tiles
 * march depends on the pilot's samples: with this seed, some. */
static const char *select_scene(const char *settings)
{
    return rt_spot_fog_json(32, 24, settings);
}

Test(select, tiles_of_both_kinds_give_delta_s_image, .timeout = 300)
{
    /* guided's marcher against delta's path. guided-unbiased mixes through the same
     * rd_select_radiance; on this scene it wins no tile robustly (its paths cost 9x delta's
     * there, for 8x less variance, when measured with guided flights before session 46), and
     * a precondition that holds for one compiler's rounding and not another's tests nothing,
     * so it is not asserted for it. The marcher's
     * equiangular sample is off, as delta's is: two estimators (with it on, the third,
     * delta's path with equiangular sampling, takes every lit tile here; the next test). */
    rd_scene *s = rt_scene("sel.json", rt_spot_fog_json_with(32, 24, "{\"select\":\"tiles\"}",
                                                             "\"photons\":{\"count\":40000},\"march\":{\"equiangular\":false}"));
    rd_render_result d = rt_render(s, "delta", 512, 31, NULL);
    rd_render_result g = rt_render(s, "guided", 128, 32, NULL);
    /* The test means something only if both estimators render some tiles. */
    double share = (double)g.stats.delta_samples / (double)g.stats.paths;
    int mixed = share > 0.0 && share < 1.0;
    if (mixed) {
        cr_log_info("guided: delta renders %.0f%% of the samples", 100.0 * share);
        rt_expect_same(&d, &g, "guided with settings.select tiles");
    }
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    rd_scene_free(s);
    cr_assert(mixed, "delta's share of the samples is %g: one kind of tile only", share);
}

/* settings.adaptive: the tiles' pixels draw shares of the samples (select_share.c, "Samples where
 * they pay") and weigh them ("Weights"), and the image is still delta's (rt_expect_same's z
 * bounds: 5 for the image, 4.5 for each 8x8 region; the beams off: the unbiased estimators only). The fog spans the whole
 * image (rt_spot_fog_json_with's cut at x = 0 moved past the frame), so that every tile reads
 * light and none draws the dark tiles' least share: a mean below 0.9 x 256 samples a pixel
 * means lit tiles were thinned. */
/* The spot in fog (rt_spot_fog_json_with) at 32x24 with shares (settings.adaptive), the beams
 * and the marcher's equiangular sample off, `photons` photons, the fog over the whole frame;
 * settings.equiangular false, so that `delta`, the reference, is its plain path (its default
 * "tiles" would take these shares too, consistent, not unbiased; the guided methods read
 * "tiles" as false). */
static rd_scene *shares_fog_scene(const char *name, int photons)
{
    char json[2048], members[160];
    snprintf(members, sizeof members, "\"photons\":{\"count\":%d},\"march\":{\"equiangular\":false,\"beams\":false}",
             photons);
    snprintf(json, sizeof json, "%s",
             rt_spot_fog_json_with(32, 24, "{\"select\":\"tiles\",\"adaptive\":true,\"equiangular\":false}", members));
    char *cut = strstr(json, "\"max\":[0.0,");
    cr_assert(cut != NULL, "the fog's cut at x = 0 is not in the scene");
    memcpy(cut + 7, "2.2", 3); /* [0.0, ...] -> [2.2, ...]: the fog to the frame's right edge */
    return rt_scene(name, json);
}

Test(select, shares_of_the_samples_keep_delta_s_image, .timeout = 300)
{
    rd_scene *s = shares_fog_scene("selad.json", 40000);
    rd_render_result d = rt_render(s, "delta", 512, 31, NULL);
    rd_render_result g = rt_render(s, "guided", 256, 33, NULL);
    const double spp = g.stats.spp_mean;
    cr_log_info("guided with shares: %.1f samples a pixel of 256", spp);
    cr_assert(spp < 0.9 * 256.0 && spp >= RD_SHARE_FIRST, "the shares drew %g samples a pixel of 256", spp);
    rt_expect_same(&d, &g, "guided with settings.adaptive");
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    rd_scene_free(s);
}

/* settings.adaptive "auto", the default: shares for `guided`'s selection, the epochs' for
 * guided-unbiased's (which keep it unbiased: docs/guided-unbiased.md "Shares of the samples")
 * and, since session 72, for `delta`'s "tiles" (its default); true and false force them either way. Read from the
 * render (rd_render_stats.shares, the JSON's "shares") and from its samples: a render with shares
 * draws fewer than spp a pixel past the first four, one without draws every one. */
Test(select, auto_gives_shares_to_the_guided_methods, .timeout = 300)
{
    static const struct {
        const char *method, *adaptive;
        int shares;
    } cases[] = {{"guided", NULL, 1},          {"guided", "false", 0}, {"guided-unbiased", NULL, 1},
                 {"guided-unbiased", "false", 0}, {"delta", NULL, 1},     {"delta", "false", 0}};
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        char settings[160], name[64];
        /* (delta's selection: its equiangular "tiles", the default, named since rt_scene turns
         * an unnamed one off; the spot's) */
        const char *eq = strcmp(cases[i].method, "delta") == 0 ? ",\"equiangular\":\"tiles\"" : "";
        if (cases[i].adaptive)
            snprintf(settings, sizeof settings, "{\"select\":\"tiles\"%s,\"adaptive\":%s}", eq, cases[i].adaptive);
        else snprintf(settings, sizeof settings, "{\"select\":\"tiles\"%s}", eq);
        snprintf(name, sizeof name, "selauto%zu.json", i);
        rd_scene *s = rt_scene(name, rt_spot_fog_json_with(32, 24, settings, "\"photons\":{\"count\":20000}"));
        cr_assert(cases[i].adaptive || s->settings.adaptive == RD_ADAPTIVE_AUTO);
        rd_render_result r = rt_render(s, cases[i].method, 32, 41, NULL);
        const char *named = cases[i].adaptive ? cases[i].adaptive : "(default)";
        cr_log_info("%s, adaptive %s: shares %d, %.1f samples a pixel of 32", cases[i].method, named, r.stats.shares,
                    r.stats.spp_mean);
        cr_expect(r.stats.shares == cases[i].shares, "%s, adaptive %s: shares %d", cases[i].method, named,
                  r.stats.shares);
        if (cases[i].shares) cr_expect(r.stats.spp_mean < 32.0, "shares, yet every sample drawn");
        else cr_expect(r.stats.spp_mean == 32.0, "no shares, yet %.2f samples a pixel of 32", r.stats.spp_mean);
        rd_render_result_free(&r);
        rd_scene_free(s);
    }
    /* and guided-unbiased's "auto" is "epochs" (loaded from the scene), neither "pilot" nor true:
     * the same image to the bit as "epochs", another than theirs; `delta`'s too (with "tiles",
     * its default, named: rt_scene turns an unnamed one off) */
    static const char *const methods[2] = {"guided-unbiased", "delta"};
    for (int k = 0; k < 2; k++) {
        rd_render_result g[4];
        const char *modes[4] = {NULL, "\"epochs\"", "\"pilot\"", "true"};
        for (int i = 0; i < 4; i++) {
            char settings[160], name[64];
            const char *eq = k ? ",\"equiangular\":\"tiles\"" : "";
            if (modes[i]) snprintf(settings, sizeof settings, "{\"select\":\"tiles\"%s,\"adaptive\":%s}", eq, modes[i]);
            else snprintf(settings, sizeof settings, "{\"select\":\"tiles\"%s}", eq);
            snprintf(name, sizeof name, "selautogu%d%d.json", k, i);
            rd_scene *s = rt_scene(name, rt_spot_fog_json_with(32, 24, settings, "\"photons\":{\"count\":20000}"));
            cr_assert(i != 1 || s->settings.adaptive == RD_ADAPTIVE_EPOCHS, "\"epochs\" not loaded");
            g[i] = rt_render(s, methods[k], 32, 41, NULL);
            rd_scene_free(s);
        }
        const size_t bytes = (size_t)g[0].image.w * g[0].image.h * 3 * sizeof(float);
        cr_expect(memcmp(g[0].image.rgb, g[1].image.rgb, bytes) == 0, "%s's \"auto\" is not \"epochs\"", methods[k]);
        cr_expect(memcmp(g[0].image.rgb, g[2].image.rgb, bytes) != 0, "%s's \"auto\" renders as \"pilot\"", methods[k]);
        cr_expect(memcmp(g[0].image.rgb, g[3].image.rgb, bytes) != 0, "%s's \"auto\" renders as true", methods[k]);
        for (int i = 0; i < 4; i++) rd_render_result_free(&g[i]);
    }
}

/* settings.equiangular's default (since session 72, docs/free-path.md "The default"): "tiles",
 * but `false` where settings.probes is not 1, since the tiles' estimators take no probes and
 * would drop them unsaid; a value named in the scene stands whatever the probes. Planted: the
 * default "tiles" whatever the probes fails the second and third cases. */
Test(select, delta_s_default_is_the_tiles_but_beside_probes)
{
    static const struct {
        const char *settings;
        int want;
    } cases[] = {{"{}", RD_EQ_TILES},
                 {"{\"probes\":4}", RD_EQ_OFF},
                 {"{\"probes\":\"auto\"}", RD_EQ_OFF},
                 {"{\"equiangular\":false}", RD_EQ_OFF},
                 {"{\"equiangular\":\"tiles\",\"probes\":4}", RD_EQ_TILES},
                 {"{\"equiangular\":true,\"probes\":4}", RD_EQ_ALL}};
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        char name[64];
        snprintf(name, sizeof name, "seldefault%zu.json", i);
        /* (loaded as the CLI loads it: rt_scene turns an unnamed "tiles" off) */
        const char *json = rt_spot_fog_json_with(16, 12, cases[i].settings, "\"photons\":{\"count\":2000}");
        char err[RD_ERRLEN];
        rt_write_file(rt_tmp_path(name), json, strlen(json));
        rd_scene *s = NULL;
        cr_assert(rd_scene_load(&s, rt_tmp_path(name), NULL, 0, err, sizeof err) == RD_OK, "%s", err);
        cr_expect(s->settings.equiangular == cases[i].want, "settings %s: equiangular %d, not %d", cases[i].settings,
                  s->settings.equiangular, cases[i].want);
        rd_scene_free(s);
    }
}

/* guided-unbiased's unbiased shares, the pilot's and the epochs' (settings.adaptive "pilot" and
 * "epochs"; select_share.c "Pilot shares", "Epoch shares"), keep `delta`'s image: the spot in fog
 * over the whole frame as above, the selection named (rt_scene turns it off), rt_expect_same's
 * bounds (5 for the image, 4.5 for each 8x8 region; `delta` at 2048 samples a pixel, so that its
 * own noise adds little). A mean below 0.9 x 256 samples a pixel means the shares thinned lit
 * tiles. A guard against a wrong count or weight, not a proof: a bias of order 1/n lies far
 * below what it resolves (the test above is the proof of the epochs' weights). */
Test(select, the_unbiased_shares_keep_delta_s_image_with_guided_unbiased, .timeout = 300)
{
    rd_render_result d;
    for (int epochs = 0; epochs < 2; epochs++) {
        char json[2048];
        /* (settings.equiangular false: `delta` is its plain path, not its default "tiles" with
         * these shares; the guided methods read "tiles" as false) */
        const char *set = epochs ? "{\"select\":\"tiles\",\"adaptive\":\"epochs\",\"equiangular\":false}"
                                 : "{\"select\":\"tiles\",\"adaptive\":\"pilot\",\"equiangular\":false}";
        snprintf(json, sizeof json, "%s", rt_spot_fog_json_with(32, 24, set, "\"photons\":{\"count\":40000}"));
        char *cut = strstr(json, "\"max\":[0.0,");
        cr_assert(cut != NULL, "the fog's cut at x = 0 is not in the scene");
        memcpy(cut + 7, "2.2", 3); /* the fog to the frame's right edge */
        rd_scene *s = rt_scene("selpilot.json", json);
        if (!epochs) d = rt_render(s, "delta", 2048, 31, NULL); /* (delta: no selection, the same image) */
        rd_render_result g = rt_render(s, "guided-unbiased", 256, 35, NULL);
        const char *what = epochs ? "guided-unbiased with the epochs' shares" : "guided-unbiased with the pilot's shares";
        cr_log_info("%s: %.1f samples a pixel of 256", what, g.stats.spp_mean);
        cr_assert(g.stats.shares && g.stats.spp_mean < 0.9 * 256.0, "%s: shares %d, %.1f samples a pixel of 256", what,
                  g.stats.shares, g.stats.spp_mean);
        rt_expect_same(&d, &g, what);
        rd_render_result_free(&g);
        rd_scene_free(s);
    }
    rd_render_result_free(&d);
}

/* Pixel (x, y)'s estimator under a trace line's tile (rd_select_uses from the trace). */
static int traced_use(const cJSON *tile, int x, int y)
{
    int c = cJSON_GetObjectItem(tile, "choice")->valueint, trial = cJSON_GetObjectItem(tile, "trial")->valueint;
    int hi = trial && trial - 1 > c ? trial - 1 : c, lo = trial && trial - 1 < c ? trial - 1 : c;
    return trial ? ((x + y) & 1 ? hi : lo) : c;
}

/* With shares the film weighs each sample by its tile's weight for its estimator (select_share.c,
 * "Weights"; render.c), and reports the sandwich estimate of the weighted mean's standard
 * error. Over K renders (seeds) of the spot in fog of the test above (32x24 pixels, 64 spp, the
 * beams off: every estimator unbiased), the pixels whose samples came from two estimators (of
 * different weights; read from each render's trace) are compared with a long `delta` render:
 * R = sum (mean - ref)^2 / sum (se^2 + se_ref^2) over those pixels should be 1, as over the
 * pixels of one estimator. Tolerance 5 standard errors of R, the jackknife's over the K renders
 * (a render's pixels share its photons and its choices, and the errors are heavy-tailed: the
 * chi-square's sqrt(2 / pixels) is several times too small); at least 200 such pixels. */
Test(select, weighted_samples_report_an_honest_standard_error, .timeout = 300)
{
    rd_scene *s = shares_fog_scene("selw.json", 20000);
    enum { K = 24, W = 32, H = 24 };
    rd_render_result ref = rt_render(s, "delta", 8192, 699, NULL);
    const char *path = rt_tmp_path("selw.jsonl");
    double a[2][K] = {{0}}, b[2][K] = {{0}}; /* per render: sum (mean - ref)^2 and sum se^2 */
    int n[2] = {0, 0};
    char err[RD_ERRLEN];
    static char line[1 << 16];
    for (int k = 0; k < K; k++) {
        rd_render_opts o = {.method = "guided", .spp = 64, .seed = 700 + k, .threads = 2, .select_trace = path};
        rd_render_result r;
        cr_assert(rd_render(s, &o, &r, err, sizeof err) == RD_OK, "%s", err);
        int used[W * H] = {0}; /* a bit per estimator a pixel drew from */
        FILE *f = fopen(path, "r");
        cr_assert(f, "no trace at %s", path);
        while (fgets(line, sizeof line, f)) {
            cJSON *j = cJSON_Parse(line);
            cr_assert(j, "the trace's line is not JSON");
            const cJSON *tiles = cJSON_GetObjectItem(j, "tiles");
            if (cJSON_GetObjectItem(j, "from_sample")->valuedouble >= o.spp) { /* (a choice for samples not drawn) */
                cJSON_Delete(j);
                continue;
            }
            for (int y = 0; y < H; y++)
                for (int x = 0; x < W; x++) used[y * W + x] |= 1 << traced_use(cJSON_GetArrayItem(tiles, (y / 8) * 4 + x / 8), x, y);
            cJSON_Delete(j);
        }
        fclose(f);
        for (int p = 0; p < W * H; p++) {
            const int two = (used[p] & (used[p] - 1)) != 0;
            const double d = r.image.rgb[3 * p + 1] - ref.image.rgb[3 * p + 1];
            const double se2 = (double)r.stderr_img.rgb[3 * p + 1] * r.stderr_img.rgb[3 * p + 1] +
                               (double)ref.stderr_img.rgb[3 * p + 1] * ref.stderr_img.rgb[3 * p + 1];
            if (!(se2 > 0.0)) continue;
            a[two][k] += d * d, b[two][k] += se2, n[two]++;
        }
        rd_render_result_free(&r);
    }
    double R[2], se[2];
    for (int i = 0; i < 2; i++) { /* the ratio of sums, and its jackknife standard error over the renders */
        double A = 0.0, B = 0.0, r[K], rbar = 0.0, v = 0.0;
        for (int k = 0; k < K; k++) A += a[i][k], B += b[i][k];
        R[i] = A / B;
        for (int k = 0; k < K; k++) r[k] = (A - a[i][k]) / (B - b[i][k]), rbar += r[k] / K;
        for (int k = 0; k < K; k++) v += (r[k] - rbar) * (r[k] - rbar);
        se[i] = sqrt((K - 1.0) / K * v);
    }
    cr_log_info("weighted samples: (mean - ref)^2 / se^2 = %.3f +- %.3f over %d pixels of two estimators, %.3f +- %.3f over %d of one",
                R[1], se[1], n[1], R[0], se[0], n[0]);
    cr_assert(n[1] >= 200, "only %d pixels drew from two estimators: the test shows little", n[1]);
    cr_expect(fabs(R[1] - 1.0) < 5.0 * se[1] && fabs(R[0] - 1.0) < 5.0 * se[0], "(mean - ref)^2 / se^2 = %.3f +- %.3f and %.3f +- %.3f",
              R[1], se[1], R[0], se[0]);
    rd_render_result_free(&ref);
    rd_scene_free(s);
}

/* A small dense, bright block lit on one side by a spot and seen from the other
 * (scenes/hard-dense-block.json made small and seen closer), 32x24 pixels, settings
 * `settings`, `guided`'s beams off (march.beams: consistent, not unbiased; the test below is of
 * the unbiased estimators' mix, and since session 62 the beams take every tile the paths had). */
static const char *dense_block_scene(const char *settings)
{
    static char buf[2048];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[2.1,0.6,2.0],\"look_at\":[0,-0.05,0],\"fov\":20,\"resolution\":[32,24]},"
             "\"media\":[{\"bounds\":{\"min\":[-0.5,-0.4,-0.4],\"max\":[0.5,0.4,0.4]},"
             "\"density\":{\"type\":\"constant\",\"value\":1.0},\"sigma_t\":12,\"albedo\":0.995,\"g\":0.8}],"
             "\"lights\":[{\"type\":\"spot\",\"position\":[-2,0.2,0],\"look_at\":[0,0,0],\"angle\":14,\"falloff\":2,"
             "\"intensity\":[40,38,34]}],\"photons\":{\"count\":40000},\"march\":{\"beams\":false},\"settings\":%s}",
             settings);
    return buf;
}

/* `guided` with march.guided_paths (the default): its selection holds guided-unbiased's paths
 * as a fourth estimator beside the marcher, delta's path and delta's path with the strategy.
 * All four are unbiased, so any mix gives delta's image (z bounds of rt_expect_same: 5 for the
 * image, 4.5 for each 8x8 region). On this dense block the paths take part of the tiles (38%
 * of the samples, delta's paths 48%, the marcher 13%, in the release build, session 62); the test needs
 * them to (asserted last, with the shares logged). The paths' estimate scaled by 1.2 fails it
 * (image z = -7.0), by 1.1 not: it sees a bias of the paths' of about 15% and more. Not in the
 * sanitizer suite (Makefile ASAN_FILTER): a minute there, and clang's photons differ, and with
 * them the selection's choices. */
Test(select, guided_unbiased_paths_in_guided_s_tiles_give_delta_s_image, .timeout = 300)
{
    rd_scene *s = rt_scene("selgp.json", dense_block_scene("{\"select\":\"tiles\",\"max_depth\":256}"));
    rd_render_result d = rt_render(s, "delta", 4096, 41, NULL);
    rd_render_result g = rt_render(s, "guided", 1024, 42, NULL);
    double n = (double)g.stats.paths, paths = (double)g.stats.path_samples / n, delta = (double)g.stats.delta_samples / n;
    cr_log_info("guided: guided-unbiased's paths %.0f%%, delta's %.0f%%, the marcher %.0f%% of the samples",
                100.0 * paths, 100.0 * delta, 100.0 * (1.0 - paths - delta));
    int mixed = paths > 0.0 && paths < 1.0;
    if (mixed) rt_expect_same(&d, &g, "guided with guided-unbiased's paths");
    cr_expect(g.stats.guide_vertices > 0, "the paths read the guide at no vertex");
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    rd_scene_free(s);
    cr_assert(mixed, "guided-unbiased's paths took %g of the samples: none, or all", paths);
}

/* `method` on scene s at spp samples and seed, on one thread and on two: r[0] and r[1]. */
static void render_on_1_and_2_threads(const rd_scene *s, const char *method, int spp, uint64_t seed,
                                      rd_render_result r[2])
{
    for (int i = 0; i < 2; i++) {
        rd_render_opts o = {.method = method, .spp = spp, .seed = seed, .threads = i + 1};
        char err[RD_ERRLEN];
        cr_assert(rd_render(s, &o, &r[i], err, sizeof err) == RD_OK, "%s", err);
    }
}

/* The two renders of render_on_1_and_2_threads gave the same tiles (the samples of each kind,
 * the balls gathered) and the same image bit for bit; frees them. */
static void expect_one_and_two_threads_alike(rd_render_result r[2])
{
    const rd_render_stats *a = &r[0].stats, *b = &r[1].stats;
    cr_assert(a->delta_samples == b->delta_samples && a->beams_samples == b->beams_samples && a->beam_hits == b->beam_hits,
              "the tiles differ with the threads");
    cr_assert(memcmp(r[0].image.rgb, r[1].image.rgb, sizeof(float) * 3 * r[0].image.w * r[0].image.h) == 0,
              "one thread and two give different images");
    for (int i = 0; i < 2; i++) rd_render_result_free(&r[i]);
}

/* The selection scene with the fog filling the whole view (hard-narrow-spot made small), the
 * settings object `settings`. */
static const char *full_fog_scene(const char *settings)
{
    static char buf[2048];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[0,0.3,4.5],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[32,24]},"
             "\"media\":[{\"bounds\":{\"min\":[-2.2,-1,-1.2],\"max\":[2.2,1,1.2]},"
             "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":1.2,\"amplitude\":0.4,\"seed\":5,"
             "\"shape\":\"none\"},\"sigma_t\":0.15,\"albedo\":0.9,\"g\":0.3}],"
             "\"lights\":[{\"type\":\"spot\",\"position\":[-3.2,0.9,-0.4],\"look_at\":[2.2,-0.5,0.3],\"angle\":3,"
             "\"falloff\":0.3,\"intensity\":[1600,1500,1300]}],\"photons\":{\"count\":40000},\"settings\":%s}",
             settings);
    return buf;
}

/* guided-unbiased on s (1024 samples, seed + 1) against `delta` on ref (4096, seed), where the
 * tiles mix delta's path, the third estimator (delta with `true`) and the method: are both
 * kinds of delta tile there (the shares logged)? If so the images must agree (z bounds of
 * rt_expect_same). *eq_samples (unless NULL): guided-unbiased's equiangular samples. */
static int third_kind_keeps_delta_s_image(const rd_scene *ref, const rd_scene *s, uint64_t seed, const char *what,
                                          uint64_t *eq_samples)
{
    rd_render_result d = rt_render(ref, "delta", 4096, seed, NULL);
    rd_render_result g = rt_render(s, "guided-unbiased", 1024, seed + 1, NULL);
    double paths = (double)g.stats.paths, eq = (double)g.stats.delta_eq_samples / paths,
           plain = (double)(g.stats.delta_samples - g.stats.delta_eq_samples) / paths;
    int mixed = eq > 0.0 && plain > 0.0;
    cr_log_info("%s: delta %.0f%%, delta with true %.0f%%, the method %.0f%% of the samples", what, 100.0 * plain,
                100.0 * eq, 100.0 * (1.0 - eq - plain));
    if (mixed) rt_expect_same(&d, &g, what);
    if (eq_samples) *eq_samples = g.stats.eq_samples;
    rd_render_result_free(&g);
    rd_render_result_free(&d);
    return mixed;
}

Test(select, delta_with_equiangular_sampling_on_every_flight_is_a_third_kind_of_tile, .timeout = 300)
{
    /* guided-unbiased (guide.equiangular its default: "auto" until session 39, false since)
     * where delta's own equiangular strategy is "auto": three estimators, the method, delta's
     * path ("auto"), and delta's path with the strategy on every flight ("true",
     * RD_SEL_DELTA_EQ). All are unbiased, so any mix
     * of them gives delta's image (z bounds of rt_expect_same; the reference is delta with
     * `true`). The test needs both kinds of delta tile. (With delta's "camera" its own tiles
     * would not do: on this scene `camera`'s 256 and even 2048 samples differ from `true`'s in
     * one region at z = 8.1 and 5.6, the heavy tail of the spot's light that only the secondary
     * flights find, which the pixels' sample variances under-read.) With this seed and gcc's
     * rounding 79% of the samples are delta's with "auto", 21% with "true" (session 30; the
     * same at session 29's commit; session 27 recorded 20% / 80%): z = -1.46 over the image
     * and -2.20 in the worst of 12 regions (session 27's seed 33: 58% / 42%, z = 0.44 and 1.46). Planted: the third kind's samples scaled
     * by 1.15 (in the pilot too) fail at z = -4.94 over the image and -7.12 in the worst region.
     * (Those figures are of guide.equiangular "auto", before session 39; not re-recorded.)
     * And no third kind when delta's own mode is "true"; since session 39 a third kind whatever
     * the method's own mode (guide.equiangular "false", its default now). */
    rd_scene *s = rt_scene("sel3.json", full_fog_scene("{\"select\":\"tiles\",\"equiangular\":\"auto\"}"));
    rd_scene *ref = rt_scene("sel3r.json", full_fog_scene("{\"select\":\"tiles\",\"equiangular\":true}"));
    int mixed = third_kind_keeps_delta_s_image(ref, s, 31, "guided-unbiased with delta's tiles of both modes", NULL);
    rd_scene_free(s);
    cr_assert(mixed, "not both kinds of delta tile");
    /* No third estimator where delta's own mode is "true" (nothing for a third to add). Where
     * the method's own flights take no strategy (guide.equiangular false) the third is there
     * all the same (session 39: it carries the strategy's gains; docs/guided-unbiased.md "The
     * equiangular strategy"): with this seed it takes 10752 of the 12288 samples, and the
     * coupling of before (no third with the method's mode off) gives it none. */
    rd_scene *s3 = rt_scene("sel3o.json", full_fog_scene("{\"select\":\"tiles\"},\"guide\":{\"equiangular\":false}"));
    const rd_scene *two[2] = {ref, s3};
    for (int k = 0; k < 2; k++) {
        rd_render_result g2 = rt_render(two[k], "guided-unbiased", 16, 32, NULL);
        cr_assert(k ? g2.stats.delta_eq_samples > 0 : g2.stats.delta_eq_samples == 0 && g2.stats.delta_samples > 0,
                  "%s (%llu of its samples on the third)",
                  k ? "the method's mode is off: the third estimator all the same" : "delta's mode is true: no third",
                  (unsigned long long)g2.stats.delta_eq_samples);
        rd_render_result_free(&g2);
    }
    rd_scene_free(ref);
    rd_scene_free(s3);
}

/* A beam across fog (test_march.c's beam scene at sigma_t 0.3, radius 0.08), the settings
 * object `settings`. */
static const char *beam_fog_scene(double sigma_t, double radius, const char *settings)
{
    static char buf[2048];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[0,0.3,4.5],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[32,24]},"
             "\"media\":[{\"bounds\":{\"min\":[-2.2,-1,-1.2],\"max\":[1.0,1,1.2]},"
             "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":1.2,\"amplitude\":0.4,\"seed\":5,"
             "\"shape\":\"none\"},\"sigma_t\":%g,\"albedo\":0.9,\"g\":0.5}],"
             "\"lights\":[{\"type\":\"directional\",\"direction\":[1,-0.15,0.2],\"irradiance\":[60,55,50],"
             "\"radius\":%g,\"center\":[0,0.1,0]}],\"photons\":{\"count\":40000},"
             "\"settings\":{\"max_depth\":8,%s}}",
             sigma_t, radius, settings);
    return buf;
}

Test(select, a_directional_beam_is_sampled_by_the_tiles_that_take_the_strategy, .timeout = 300)
{
    /* Since session 30 the tiles that take the equiangular strategy on every flight sample
     * directional beams too (RD_EQ_ALL): on a scene whose only light is a beam,
     * guided-unbiased's selection (whatever guide.equiangular says) has its third estimator, and
     * `delta` with "tiles" has a choice. All are unbiased, so the mixes give the image of
     * `delta` with `true` (z bounds of rt_expect_same). The first check needs both kinds of
     * delta tile. With these seeds and gcc's rounding: guided-unbiased gives delta's path 63% of
     * the samples, delta with `true` 37% (z = -0.81 over the image, 2.05 in the worst of 12
     * regions; seeds 43-45 of the CLI: 30-63% to the third); `delta` with "tiles" 100% with the
     * strategy (z = -0.36, 2.10). Planted: the third kind's samples scaled by 1.15 (in the
     * pilot too) fail at z = -17.5 and -14.2; the samples of `delta`'s tiles with the strategy
     * scaled by 0.9 or 1.1 fail at z = 9.8 and -9.0 over the image; the third kind in "auto"'s
     * mode, which leaves the beam out, fails the check on its equiangular samples. */
    rd_scene *ref = rt_scene("selBr.json", beam_fog_scene(1.0, 0.4, "\"equiangular\":true"));
    rd_scene *s = rt_scene("selB.json", beam_fog_scene(1.0, 0.4, "\"select\":\"tiles\""));
    uint64_t eq_samples = 0;
    int mixed = third_kind_keeps_delta_s_image(ref, s, 41, "guided-unbiased with a beam's third kind of tile", &eq_samples);
    cr_expect(mixed, "not both kinds of delta tile");
    /* and the tiles with the strategy sample the beam (the light is a beam alone, which the
     * method's own "auto" leaves out: every equiangular sample here is a tile's) */
    cr_expect(eq_samples > 0, "guided-unbiased's third kind of tile drew no equiangular sample");
    /* `delta`'s own tiles on a beam: at sigma_t 1 and radius 0.4 its two modes nearly tie (gcc's
     * rounding gave 44% of the samples the strategy, the sanitizer build's 0%), so the check
     * takes test_march.c's thinner fog and narrower beam, where the strategy pays on nearly
     * every tile (its mix of modes is delta_s_own_tiles_mix_its_two_modes_and_give_delta_s_image's,
     * on a point light): the tiles must take it there, draw beam samples, and give `true`'s image.
     * The beam connections off: beside them the tiles sample no beam (the next test) */
    rd_scene *tref = rt_scene("selBtr.json", beam_fog_scene(0.3, 0.08, "\"equiangular\":true"));
    rd_scene *st = rt_scene("selBt.json", beam_fog_scene(0.3, 0.08, "\"equiangular\":\"tiles\",\"beam_connect\":false"));
    rd_render_result dt = rt_render(tref, "delta", 4096, 44, NULL);
    rd_render_result t = rt_render(st, "delta", 1024, 43, NULL);
    double with = 1.0 - (double)t.stats.delta_samples / (double)t.stats.paths;
    cr_log_info("delta with tiles on a beam: %.0f%% of the samples with the strategy", 100.0 * with);
    rt_expect_same(&dt, &t, "delta with its own tiles on a beam");
    cr_expect(with > 0.5, "%g of the samples with the strategy, where it pays on nearly every tile", with);
    cr_expect(t.stats.eq_samples > 0, "delta's tiles with the strategy drew no equiangular sample");
    rd_render_result_free(&t);
    rd_render_result_free(&dt);
    rd_scene_free(st);
    rd_scene_free(tref);
    rd_scene_free(s);
    rd_scene_free(ref);
}

Test(select, a_beam_that_delta_s_path_connects_to_makes_no_third_estimator, .timeout = 60)
{
    /* Where settings.beam_connect is on (its "auto" on this narrow beam: breadth about 0.001),
     * delta's path connects every vertex to the beam, and delta with the strategy on every
     * flight drops those connections for its own sample of the beam (transport/path.c): the
     * same light found the weaker way, so the selection has no third estimator there (select.c,
     * "Beams that delta's path connects to"). With the connections off the same scene has one,
     * and its tiles take it (the strategy pays on nearly every tile here: the test above). Both
     * methods, 16 samples a pixel. Planted: the rule dropped (any beam makes a third) puts every
     * sample of both methods (12288 of 12288) on the third with the connections on.
     * `delta` with "tiles" (since session 72 it leaves the connections on): with them, no choice,
     * so plain `delta`'s image bit for bit, shares and all; without them, its tiles take the
     * strategy. Planted: delta.c's test for a light the tiles sample back at any beam
     * (rd_eq_has_lights(s, 1)) fails the first. */
    rd_scene *on = rt_scene("selBc1.json", beam_fog_scene(0.3, 0.08, "\"select\":\"tiles\""));
    rd_scene *off = rt_scene("selBc0.json", beam_fog_scene(0.3, 0.08, "\"select\":\"tiles\",\"beam_connect\":false"));
    cr_assert(on->beam_connect.light >= 0 && off->beam_connect.light < 0, "beam_connect: on %d, off %d",
              on->beam_connect.light, off->beam_connect.light);
    static const char *const methods[2] = {"guided-unbiased", "guided"};
    for (int k = 0; k < 2; k++) {
        rd_render_result a = rt_render(on, methods[k], 16, 51, NULL);
        rd_render_result b = rt_render(off, methods[k], 16, 51, NULL);
        cr_log_info("%s on a beam: delta with the strategy %llu of %llu samples with the connections, %llu of %llu "
                    "without", methods[k], (unsigned long long)a.stats.delta_eq_samples,
                    (unsigned long long)a.stats.paths, (unsigned long long)b.stats.delta_eq_samples,
                    (unsigned long long)b.stats.paths);
        cr_expect(a.stats.delta_eq_samples == 0, "%s: %llu samples on a third estimator beside the beam's connections",
                  methods[k], (unsigned long long)a.stats.delta_eq_samples);
        cr_expect(b.stats.delta_eq_samples > 0, "%s: no sample on the third estimator without the connections",
                  methods[k]);
        rd_render_result_free(&a);
        rd_render_result_free(&b);
    }
    rd_scene *ton = rt_scene("selBc1t.json", beam_fog_scene(0.3, 0.08, "\"equiangular\":\"tiles\",\"adaptive\":\"epochs\""));
    rd_scene *toff = rt_scene("selBc0t.json", beam_fog_scene(0.3, 0.08, "\"equiangular\":\"tiles\",\"beam_connect\":false"));
    rd_scene *plain = rt_scene("selBc1p.json", beam_fog_scene(0.3, 0.08, "\"equiangular\":false"));
    cr_assert(ton->beam_connect.light >= 0 && toff->beam_connect.light < 0 && plain->beam_connect.light >= 0,
              "\"tiles\" turned the connections off");
    rd_render_result t1 = rt_render(ton, "delta", 16, 51, NULL);
    rd_render_result t0 = rt_render(toff, "delta", 16, 51, NULL);
    rd_render_result p = rt_render(plain, "delta", 16, 51, NULL);
    cr_expect(t1.stats.eq_samples == 0 && t1.stats.delta_samples == 0, "delta's tiles beside the connections: %llu "
              "equiangular samples, %llu counted by a selection", (unsigned long long)t1.stats.eq_samples,
              (unsigned long long)t1.stats.delta_samples);
    cr_expect(memcmp(t1.image.rgb, p.image.rgb, sizeof(float) * 3 * p.image.w * p.image.h) == 0,
              "delta's tiles beside the connections are not plain delta's image");
    cr_expect(t0.stats.eq_samples > 0, "delta's tiles without the connections drew no equiangular sample");
    rd_render_result_free(&t1);
    rd_render_result_free(&t0);
    rd_render_result_free(&p);
    rd_scene_free(ton);
    rd_scene_free(toff);
    rd_scene_free(plain);
    rd_scene_free(on);
    rd_scene_free(off);
}

Test(select, delta_s_own_tiles_mix_its_two_modes_and_give_delta_s_image, .timeout = 300)
{
    /* `delta` with settings.equiangular "tiles" (integrators/delta.c): per tile its path without
     * the equiangular strategy or with it on every flight, by the selection. Both are unbiased,
     * so the mix gives the image of `delta` with `true` (z bounds of rt_expect_same) on a fog
     * cube under a point light (scenes/homogeneous.json made small), where the test needs both
     * kinds of tile (on the fog-filled narrow spot every tile takes the strategy); one thread
     * and two give the same image bit for bit (the choice is counted work, not time); and
     * without a point or spot light or a directional beam there is nothing to choose: the
     * image of `false`, bit for bit. With this seed and gcc's rounding a third of the samples are without the strategy:
     * z = -0.64 over the image, -1.93 in the worst of 12 regions; the strategy's samples planted
     * 1.1x fail at z = -51.6 and -33.0. */
    const char *cube = "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[32,24]},"
                       "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                       "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1,\"albedo\":0.8,\"g\":0.3}],"
                       "\"lights\":[{\"type\":\"point\",\"position\":[0,1.6,0.5],\"intensity\":4}],"
                       "\"settings\":{\"equiangular\":%s}}";
    char js[1024];
    snprintf(js, sizeof js, cube, "true");
    rd_scene *ref = rt_scene("selDr.json", js);
    snprintf(js, sizeof js, cube, "\"tiles\"");
    rd_scene *s = rt_scene("selD.json", js);
    rd_render_result d = rt_render(ref, "delta", 4096, 31, NULL);
    rd_render_result t[2];
    render_on_1_and_2_threads(s, "delta", 1024, 32, t);
    double plain = (double)t[0].stats.delta_samples / (double)t[0].stats.paths;
    int mixed = plain > 0.0 && plain < 1.0;
    cr_log_info("delta with tiles: %.0f%% of the samples without the strategy", 100.0 * plain);
    if (mixed) rt_expect_same(&d, &t[0], "delta with its own tiles of both modes");
    cr_expect(t[0].stats.delta_samples == t[1].stats.delta_samples &&
                  memcmp(t[0].image.rgb, t[1].image.rgb, sizeof(float) * 3 * t[0].image.w * t[0].image.h) == 0,
              "one thread and two give different images");
    /* The two kinds are what they say: the tiles without the strategy draw no equiangular
     * sample (a "tiles" that reached the flights as "every flight" would), so the mix draws
     * fewer a path than `true` does, by about the share without it (the two images' pixels
     * differ in how many flights they make, hence the margin of a tenth). Planted: "tiles"
     * passed to the flights unmapped fails both checks (1.307 samples a path against true's
     * 1.305). */
    double z_true = (double)d.stats.eq_samples / (double)d.stats.paths,
           z_tiles = (double)t[0].stats.eq_samples / (double)t[0].stats.paths;
    cr_log_info("equiangular samples a path: %.3f with true, %.3f with tiles", z_true, z_tiles);
    cr_expect(z_tiles > 0.0 && z_tiles < (1.0 - plain + 0.1) * z_true,
              "tiles draws %g equiangular samples a path against true's %g, %.0f%% of its samples without the strategy",
              z_tiles, z_true, 100.0 * plain);
    /* and a path of "tiles" outside the selection is the path of "false", to the bit */
    snprintf(js, sizeof js, cube, "false");
    rd_scene *off = rt_scene("selDo.json", js);
    int same = 1;
    for (int i = 0; i < 200; i++) {
        ray3 r = rd_camera_ray(&s->camera, 4.0 + 0.12 * i, 12.0);
        pcg32 a = pcg32_seed(3, (uint64_t)i, 9), b = a;
        rd_track_counters ca = {0}, cb = {0};
        vec3 La = rd_delta_radiance(s, r, &a, &ca), Lb = rd_delta_radiance(off, r, &b, &cb);
        same &= La.x == Lb.x && La.y == Lb.y && La.z == Lb.z && ca.eq_flights == 0 && cb.lookups == ca.lookups;
    }
    cr_expect(same, "delta's path with settings.equiangular \"tiles\" must be the path of \"false\"");
    rd_scene_free(off);
    for (int i = 0; i < 2; i++) rd_render_result_free(&t[i]);
    rd_render_result_free(&d);
    rd_scene_free(s);
    rd_scene_free(ref);
    cr_assert(mixed, "%g of the samples without the strategy: not both kinds of tile", plain);
    /* no point or spot light nor directional beam: "tiles" is "false" */
    const char *sky = "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"resolution\":[16,12]},"
                      "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
                      "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1,\"albedo\":0.8}],"
                      "\"lights\":[{\"type\":\"environment\",\"radiance\":[1,1,1]}],\"settings\":{\"equiangular\":%s}}";
    char buf[1024];
    rd_render_result e[2];
    for (int i = 0; i < 2; i++) {
        snprintf(buf, sizeof buf, sky, i ? "\"tiles\"" : "false");
        rd_scene *se = rt_scene(i ? "selDe1.json" : "selDe0.json", buf);
        e[i] = rt_render(se, "delta", 16, 5, NULL);
        rd_scene_free(se);
    }
    cr_expect(e[1].stats.delta_samples == 0 &&
                  memcmp(e[0].image.rgb, e[1].image.rgb, sizeof(float) * 3 * e[0].image.w * e[0].image.h) == 0,
              "without a light the strategy samples \"tiles\" must be \"false\"");
    for (int i = 0; i < 2; i++) rd_render_result_free(&e[i]);
}

Test(select, the_choice_does_not_depend_on_the_threads, .timeout = 300)
{
    rd_scene *s = rt_scene("selt.json", select_scene("{\"select\":\"tiles\"}"));
    rd_render_result r[2];
    /* 20 samples: past the epochs at 4 and 16, which choose again */
    render_on_1_and_2_threads(s, "guided", 20, 5, r);
    cr_assert(r[0].stats.delta_samples == r[1].stats.delta_samples, "the tiles differ: %llu against %llu delta samples",
              (unsigned long long)r[0].stats.delta_samples, (unsigned long long)r[1].stats.delta_samples);
    cr_assert(memcmp(r[0].image.rgb, r[1].image.rgb, sizeof(float) * 3 * r[0].image.w * r[0].image.h) == 0,
              "one thread and two give different images");
    for (int i = 0; i < 2; i++) rd_render_result_free(&r[i]);
    rd_scene_free(s);
}

Test(select, the_trace_says_which_estimator_drew_every_sample, .timeout = 300)
{
    /* rd_render_opts.select_trace: one JSON line a choice (the pilot's, the epochs' at 4 and
     * 16 of 20 samples). Counted from the trace alone (each tile's choice, or its trial's
     * checkerboard, over the samples from its line's from_sample to the next's), the samples
     * given to delta's paths, and of those to delta's path with the strategy, must be the
     * render's own counts, to the sample; and writing the trace must not change the image.
     * hard-dense-block at 32x24, seed 1: its tiles go on trial at the pilot and move at both
     * epochs (checked below), so a trace written before the choice, or of the wrong one, fails.
     * Without shares (settings.adaptive false; "auto" gives this method the epochs'): with them a
     * pixel draws only its share of the indices a line governs, which the trace does not hold. */
    const rd_override res[] = {{"camera.resolution", "[32,24]"}, {"settings.adaptive", "false"}};
    rd_scene *s = NULL;
    char err[RD_ERRLEN];
    cr_assert(rd_scene_load(&s, "scenes/hard-dense-block.json", res, 2, err, sizeof err) == RD_OK, "%s", err);
    const char *path = rt_tmp_path("trace.jsonl");
    rd_render_result r[2];
    for (int i = 0; i < 2; i++) {
        rd_render_opts o = {.method = "guided-unbiased", .spp = 20, .seed = 1, .threads = 2, .select_trace = i ? path : NULL};
        cr_assert(rd_render(s, &o, &r[i], err, sizeof err) == RD_OK, "%s", err);
    }
    cr_assert(memcmp(r[0].image.rgb, r[1].image.rgb, sizeof(float) * 3 * r[0].image.w * r[0].image.h) == 0,
              "the trace changed the image");
    cr_assert(r[0].stats.select_choices == 3 && r[0].stats.select_traced == 0 && r[1].stats.select_choices == 3 &&
                  r[1].stats.select_traced == 3 && !r[1].select_trace_err[0],
              "choices %d and %d, traced %d and %d (%s)", r[0].stats.select_choices, r[1].stats.select_choices,
              r[0].stats.select_traced, r[1].stats.select_traced, r[1].select_trace_err);
    FILE *f = fopen(path, "r");
    cr_assert(f, "no trace at %s", path);
    static char line[1 << 16];
    const long from_expected[3] = {0, 4, 16};
    uint64_t delta_samples = 0, eq_samples = 0;
    int lines = 0, moves = 0, w = r[1].image.w, h = r[1].image.h;
    static int last[64 * 64];
    /* each tile's samples of each estimator before the line: the pilot's (16 pixels x 8), then
     * what the lines gave it (every sample of this scene is finite, so the trace counts them all) */
    double drawn[12][3];
    for (int k = 0; k < 12; k++)
        for (int e = 0; e < 3; e++) drawn[k][e] = 128.0;
    while (fgets(line, sizeof line, f)) {
        cr_assert(lines < 3, "more than three choices for 20 samples");
        cJSON *j = cJSON_Parse(line);
        cr_assert(j, "line %d is not JSON", lines + 1);
        long from = (long)cJSON_GetObjectItem(j, "from_sample")->valuedouble;
        int tx = cJSON_GetObjectItem(j, "tiles_x")->valueint, ty = cJSON_GetObjectItem(j, "tiles_y")->valueint;
        int m = cJSON_GetArraySize(cJSON_GetObjectItem(j, "estimators"));
        const cJSON *tiles = cJSON_GetObjectItem(j, "tiles");
        cr_assert(from == from_expected[lines] && tx == (w + 7) / 8 && ty == (h + 7) / 8 && cJSON_GetArraySize(tiles) == tx * ty,
                  "line %d: from_sample %ld, %dx%d tiles (%d listed)", lines + 1, from, tx, ty, cJSON_GetArraySize(tiles));
        long to = lines < 2 ? from_expected[lines + 1] : 20;
        cr_assert(tx * ty <= 12 && m == 3, "%dx%d tiles, %d estimators: hard-dense-block at 32x24 has 4x3 and 3", tx, ty, m);
        for (int k = 0; k < tx * ty; k++) {
            const cJSON *t = cJSON_GetArrayItem(tiles, k), *n = cJSON_GetObjectItem(t, "samples"), *c = cJSON_GetObjectItem(t, "cost");
            for (int e = 0; e < m; e++) {
                double got = cJSON_GetArrayItem(n, e)->valuedouble, cost = cJSON_GetArrayItem(c, e)->valuedouble;
                cr_assert(got == drawn[k][e], "line %d, tile %d, estimator %d: %g samples traced, %g drawn", lines + 1, k, e, got,
                          drawn[k][e]);
                cr_assert(cost > 0.0, "line %d, tile %d, estimator %d: cost %g a sample", lines + 1, k, e, cost);
            }
        }
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                const cJSON *t = cJSON_GetArrayItem(tiles, (y / 8) * tx + x / 8);
                int c = cJSON_GetObjectItem(t, "choice")->valueint, trial = cJSON_GetObjectItem(t, "trial")->valueint;
                cr_assert(c >= 0 && c < m && trial >= 0 && trial <= m, "a tile's choice %d, trial %d of %d estimators", c, trial, m);
                int hi = trial && trial - 1 > c ? trial - 1 : c, lo = trial && trial - 1 < c ? trial - 1 : c;
                int use = trial ? ((x + y) & 1 ? hi : lo) : c; /* rd_select_uses */
                delta_samples += use != RD_SEL_METHOD ? (uint64_t)(to - from) : 0;
                drawn[(y / 8) * tx + x / 8][use] += (double)(to - from);
                eq_samples += use == RD_SEL_DELTA_EQ ? (uint64_t)(to - from) : 0;
                moves += lines > 0 && use != last[y * w + x];
                last[y * w + x] = use;
            }
        cJSON_Delete(j);
        lines++;
    }
    fclose(f);
    cr_assert(lines == 3, "%d choices traced, not 3", lines);
    cr_assert(moves > 0, "no pixel changed estimator at the epochs: the check below could not see a stale trace");
    cr_assert(delta_samples == r[1].stats.delta_samples && eq_samples == r[1].stats.delta_eq_samples,
              "the trace gives delta's paths %llu samples (%llu with the strategy), the render %llu (%llu)",
              (unsigned long long)delta_samples, (unsigned long long)eq_samples, (unsigned long long)r[1].stats.delta_samples,
              (unsigned long long)r[1].stats.delta_eq_samples);
    for (int i = 0; i < 2; i++) rd_render_result_free(&r[i]);
    /* A render without a selection writes no trace (plain `delta`: its default "tiles" has one). */
    s->settings.equiangular = RD_EQ_OFF;
    const char *none = rt_tmp_path("no-trace.jsonl");
    rd_render_opts o = {.method = "delta", .spp = 2, .seed = 5, .threads = 1, .select_trace = none};
    cr_assert(rd_render(s, &o, &r[0], err, sizeof err) == RD_OK, "%s", err);
    cr_assert(access(none, F_OK) != 0 && r[0].stats.select_choices == 0, "delta without a selection: %d choices, or a trace",
              r[0].stats.select_choices);
    rd_render_result_free(&r[0]);
    /* A trace that cannot be written does not stop the render: the result says so. */
    o = (rd_render_opts){.method = "guided-unbiased", .spp = 5, .seed = 1, .threads = 1,
                         .select_trace = rt_tmp_path("no-such-dir/trace.jsonl")};
    cr_assert(rd_render(s, &o, &r[0], err, sizeof err) == RD_OK, "%s", err);
    cr_assert(r[0].stats.select_choices == 2 && r[0].stats.select_traced == 0 && strstr(r[0].select_trace_err, "no-such-dir"),
              "an unwritable trace: %d choices, %d traced, error \"%s\"", r[0].stats.select_choices, r[0].stats.select_traced,
              r[0].select_trace_err);
    rd_render_result_free(&r[0]);
    rd_scene_free(s);
}

/* select_scene (or, `wide`, the same 64 pixels wide: 8x3 tiles, the right two columns' 3x3
 * windows all fogless, so they go to delta whatever the rounding) with
 * "march":{"ls":"nee+beams","equiangular":false} and the given settings (a static buffer);
 * with `progressive`, photon passes of 4000 photons a sample. The marcher's equiangular sample
 * is off, as delta's is: two estimators (with it on, delta's path with equiangular sampling
 * took every lit tile from the beams with clang's rounding). */
static const char *beams_scene(const char *settings, int progressive, int wide)
{
    return rt_spot_fog_json_with(wide ? 64 : 32, 24, settings,
                                 progressive ? "\"photons\":{\"count\":40000,\"progressive\":true,\"pass_count\":4000,"
                                               "\"pass_spp\":1},\"march\":{\"ls\":\"nee+beams\",\"equiangular\":false}"
                                             : "\"photons\":{\"count\":40000},\"march\":{\"ls\":\"nee+beams\",\"equiangular\":false}");
}

Test(select, beams_mix_only_when_asked_and_the_choice_does_not_depend_on_the_threads, .timeout = 300)
{
    /* guided with march.ls nee+beams. By default ("auto") every pixel is marched, and the
     * photon passes are one per pass_spp samples of the image, as without a selection. With
     * "tiles" (and "pilot") some tiles go to delta's path, some to the beams (the 3x3 pooling
     * lets the lit tiles' figures reach into the fogless half, so which tiles is not fixed by
     * the fog's edge), the progressive photon passes follow the beams' samples, not the
     * image's (a pass per pass_spp x all pixels of them), and the image is the same on one
     * thread and two. */
    char path[256], err0[RD_ERRLEN];
    snprintf(path, sizeof path, "%s/selb0.json", rt_tmpdir());
    const char *j0 = beams_scene("{}", 0, 0);
    rt_write_file(path, j0, strlen(j0));
    rd_scene *s0 = NULL;
    cr_assert(rd_scene_load(&s0, path, NULL, 0, err0, sizeof err0) == RD_OK, "%s", err0);
    cr_assert(s0->settings.select == RD_SELECT_AUTO, "the default is auto (%d)", s0->settings.select);
    rd_scene_free(s0);
    rd_scene *sa = rt_scene("selba.json", beams_scene("{\"select\":\"auto\"}", 1, 0));
    rd_render_opts oa = {.method = "guided", .spp = 3, .seed = 5, .threads = 2};
    rd_render_result ra;
    char erra[RD_ERRLEN];
    cr_assert(rd_render(sa, &oa, &ra, erra, sizeof erra) == RD_OK, "%s", erra);
    cr_assert(ra.stats.delta_samples == 0 && ra.stats.beam_queries > 0, "auto mixed nee+beams with delta (%llu samples)",
              (unsigned long long)ra.stats.delta_samples);
    cr_assert(ra.stats.photon_passes == 3, "every pixel marched: a pass a sample, not %d passes", ra.stats.photon_passes);
    rd_render_result_free(&ra);
    rd_scene_free(sa);
    /* pilot, on the wide image: its fogless right columns go to delta (a tie), so mixing shows
     * as delta samples (which lit tiles the beams take depends on the compiler's rounding at
     * this size: with clang's, none at 32x24) */
    rd_scene *sp = rt_scene("selbp.json", beams_scene("{\"select\":\"pilot\"}", 0, 1));
    cr_assert(rd_render(sp, &oa, &ra, erra, sizeof erra) == RD_OK, "%s", erra);
    cr_assert(ra.stats.delta_samples > 0, "pilot: nee+beams not mixed with delta (%llu of %llu samples)",
              (unsigned long long)ra.stats.delta_samples, (unsigned long long)ra.stats.paths);
    rd_render_result_free(&ra);
    rd_scene_free(sp);
    rd_scene *s = rt_scene("selb.json", beams_scene("{\"select\":\"tiles\"}", 1, 0));
    rd_render_result r[2];
    render_on_1_and_2_threads(s, "guided", 20, 5, r);
    double share = (double)r[0].stats.delta_samples / (double)r[0].stats.paths;
    cr_log_info("nee+beams: delta renders %.0f%% of the samples", 100.0 * share);
    cr_assert(share > 0.0 && share < 1.0, "delta's share %g: one kind of tile only", share);
    cr_assert(r[0].stats.beam_queries > 0, "no beam estimate was made");
    /* M samples of the beams: passes p with (p - 1) per_pass < M <= p per_pass + a render
     * pass's overshoot (under one sample of every pixel); passes by the image's samples would
     * be 20. */
    double M = (double)(r[0].stats.paths - r[0].stats.delta_samples), per_pass = 32.0 * 24.0;
    int p = r[0].stats.photon_passes;
    cr_log_info("nee+beams: %d photon passes for %.0f beam samples (%.2f a pass of %.0f)", p, M, M / per_pass, per_pass);
    cr_assert((p - 1) * per_pass < M && M < p * per_pass + per_pass, "%d passes for %.0f samples of the beams", p, M);
    expect_one_and_two_threads_alike(r);
    rd_scene_free(s);
}

Test(select, pilot_keeps_the_pilot_s_choice_and_tiles_chooses_again, .timeout = 300)
{
    /* guided-unbiased, whose tiles change at the epochs on this scene with the gcc build (delta's
     * share 0.5 over samples 0-3, 0.75 over 0-19); the same pilot, so the same tiles for samples
     * 0-3 in both modes. "pilot" never changes them: its delta share over 20 samples is 5 times
     * its share over 4. That "tiles" does change them is logged, not asserted: which tiles a
     * pilot gives depends on the compiler's rounding (see above). */
    rd_scene *sp = rt_scene("selp.json", select_scene("{\"select\":\"pilot\"}"));
    rd_scene *st = rt_scene("selt2.json", select_scene("{\"select\":\"tiles\"}"));
    rd_render_result r[4];
    const rd_scene *sc[4] = {sp, sp, st, st};
    const int spp[4] = {4, 20, 4, 20};
    for (int i = 0; i < 4; i++) {
        rd_render_opts o = {.method = "guided-unbiased", .spp = spp[i], .seed = 5, .threads = 2};
        char err[RD_ERRLEN];
        cr_assert(rd_render(sc[i], &o, &r[i], err, sizeof err) == RD_OK, "%s", err);
    }
    cr_assert(r[0].stats.delta_samples * 5 == r[1].stats.delta_samples,
              "pilot: the tiles changed between samples 4 and 20 (%llu, %llu delta samples)",
              (unsigned long long)r[0].stats.delta_samples, (unsigned long long)r[1].stats.delta_samples);
    cr_assert(memcmp(r[0].image.rgb, r[2].image.rgb, sizeof(float) * 3 * r[0].image.w * r[0].image.h) == 0,
              "before the first epoch, pilot and tiles are the same render");
    cr_log_info("tiles: %llu delta samples over 4 spp, %llu over 20 (5x: the epochs changed nothing)",
                (unsigned long long)r[2].stats.delta_samples, (unsigned long long)r[3].stats.delta_samples);
    for (int i = 0; i < 4; i++) rd_render_result_free(&r[i]);
    rd_scene_free(sp);
    rd_scene_free(st);
}

/* ---- The beams estimator (march.beams) ---------------------------------------------------- */

/* A stand-in beams estimator (rd_select_more's `beams`): always 4, with 3 PDF segments a sample. */
static vec3 beams_stand_in(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    (void)ctx, (void)r, (void)smp;
    th->cells += 3;
    return v3(4, 4, 4);
}

/* With the beams, the bound's tile mean is the beams' mean (select_rule.c's head, "The bound's
 * tile mean with the beams"). A 5x5-tile selection of delta (cost 1) with a firefly in every
 * tile (mean 0.73, non-zero once in 128, variance 0.73^2 x 127), the method (cost 12: mean 0.12,
 * non-zero in a quarter of its samples, the rest its pixels that see no light, variance 0.02
 * about its pixels' means) and a third at 120 (mean 0.12, never zero, variance 0.023). With the
 * mean of the three means, 0.323, the method's bound is 0.323^2 x 3 = 0.31 a sample (V C 3.8)
 * against the third's 0.023 x 120 = 2.8: the third takes every tile, as estimator 2 of kind
 * RD_SEL_DELTA_EQ it still does. As the beams, whose mean 0.12 is the centre, the method's bound
 * is 0.043 (V C 0.52): the method takes every tile (the narrow spot's apex, docs/guided-marching.md
 * "The beams beside the marcher"). */
Test(select, with_the_beams_the_bound_s_tile_mean_is_the_beams_mean)
{
    for (int beams = 0; beams < 2; beams++) {
        rd_select sel;
        char err[RD_ERRLEN];
        cr_assert(rd_select_init(&sel, 40, 40, 1.0, 3, err, sizeof err) == RD_OK, "%s", err);
        if (beams) sel.kind[2] = RD_SEL_BEAMS, sel.paths &= ~(1u << 2); /* (as rd_select_prepare_more sets them) */
        for (int k = 0; k < 25; k++) {
            fake_pilot(&sel, 3 * k, 0.73, 0.73 * 0.73 * 127.0, 1.0 / 128.0, 1.0);
            fake_pilot(&sel, 3 * k + 1, 0.12, 0.02, 0.25, 12.0);
            fake_pilot(&sel, 3 * k + 2, 0.12, 0.023, 1.0, 120.0);
        }
        rd_select_epoch(&sel, NULL, NULL); /* no samples: the choice from these statistics */
        for (int k = 0; k < 25; k++)
            cr_expect(sel.choice[k] == (beams ? 1 : 2), "%s: tile %d took estimator %d", beams ? "beams" : "no beams", k,
                      sel.choice[k]);
        rd_select_free(&sel);
    }
}

/* A mean that lags the beams' (select_rule.c's head): a 5x5-tile selection of delta (cost 5:
 * mean 0.0031, non-zero in half its samples, variance 0.0018), the method (cost 14: never zero,
 * variance 0.00005, like the marcher at the dense block's dim edge) and a third (cost 285: mean
 * 0.008, variance 0.00005). The method's V C is 0.0007 against delta's 0.009 and the third's
 * 0.014: it takes every tile as long as nothing reads a lag. As the beams, the third's mean is
 * the centre, and the method's lag is 0.004 (half of theirs) less its mean, less three standard
 * errors of the two means over a tile's 3x3 in one half (64 samples a tile each: in a corner's 4
 * tiles 3 sqrt(4 x 1e-4 / 64) / 4 = 0.0019, an edge's 6 0.0015, the middle's 9 0.0013):
 * - mean 0.0001: a lag of 0.0039, so at least (0.0039 - 0.0019)^2 x 257 = 0.0010 a sample in a
 *   corner (V C 0.015, the middle's 0.057): delta takes every tile;
 * - mean 0.0019: a lag of 0.0021, just past three standard errors: at most (0.0021 - 0.0013)^2 x
 *   577 = 0.0004 (V C 0.0058): the method keeps every tile (a floor of d^2 (n + 1) from the gate on
 *   would give delta every tile);
 * - mean 0.0048, 0.6 of the beams': within the slack, the method keeps every tile (without the
 *   slack the middle's floor is 0.0022, V C 0.031: delta).
 * Without the beams (the third as DELTA_EQ) the method takes every tile in all three. Fails with
 * the bound removed, without the slack, or without the standard errors taken off the lag. */
Test(select, with_the_beams_a_mean_that_lags_theirs_reads_a_tail)
{
    const double mean[3] = {0.0001, 0.0019, 0.0048};
    for (int beams = 0; beams < 2; beams++)
        for (int i = 0; i < 3; i++) {
            rd_select sel;
            char err[RD_ERRLEN];
            cr_assert(rd_select_init(&sel, 40, 40, 1.0, 3, err, sizeof err) == RD_OK, "%s", err);
            if (beams) sel.kind[2] = RD_SEL_BEAMS, sel.paths &= ~(1u << 2);
            for (int k = 0; k < 25; k++) {
                fake_pilot(&sel, 3 * k, 0.0031, 0.0018, 0.5, 5.0);
                fake_pilot(&sel, 3 * k + 1, mean[i], 0.00005, 1.0, 14.0);
                fake_pilot(&sel, 3 * k + 2, 0.008, 0.00005, 1.0, 285.0);
            }
            rd_select_epoch(&sel, NULL, NULL);
            int want = beams && i == 0 ? RD_SEL_DELTA : RD_SEL_METHOD;
            for (int k = 0; k < 25; k++)
                cr_expect(sel.choice[k] == want && sel.trial[k] == 0,
                          "%s, the method's mean %g: tile %d took estimator %d (trial %d), not %d",
                          beams ? "beams" : "no beams", mean[i], k, sel.choice[k], sel.trial[k], want);
            rd_select_free(&sel);
        }
}

/* The beams' gaps of a 6x5-tile selection's pixels so far (sel->gaps, 48x40 pixels): the mean
 * gaps s g (1 + d_k), s g (1 + e_k), s g (1 - d_k) and s g (1 - e_k) on the passes of classes 0,
 * 1, 2 and 3 mod 4, with d_k = D x (1, -1, 0, 1, -1, 0.5) by the tile's column (the last column's
 * non-zero: a neighbour wrapped across the rows would count), e_k = d_k, or with `flip` -d_k in
 * the tiles of odd column + row (a checkerboard of tiles), and s = +-1 in a checkerboard of
 * pixels; even columns of pixels hold 2, 3, 1 and 2 samples of the classes, odd ones 1 of each.
 * A pixel's turned product is g^2 d_k e_k: with `flip` the tiles that share an edge have turned
 * products of opposite signs. Per tile k, what bias_fold should read: the weighted products in
 * S[k], the weights in Wk[k], the weighted turned products in Dk[k] (added to; NULL: not
 * wanted). */
static void beams_gaps(rd_select *sel, double g, double D, int flip, double *S, double *Wk, double *Dk)
{
    static const double col[6] = {1.0, -1.0, 0.0, 1.0, -1.0, 0.5};
    for (int y = 0; y < 40; y++)
        for (int x = 0; x < 48; x++) {
            int k = (y / 8) * 6 + x / 8;
            double d = D * col[x / 8], e = flip && (x / 8 + y / 8) & 1 ? -d : d, sg = (x + y) & 1 ? -g : g;
            const double c[4] = {x & 1 ? 1.0 : 2.0, x & 1 ? 1.0 : 3.0, 1.0, x & 1 ? 1.0 : 2.0};
            const double mean[4] = {sg * (1.0 + d), sg * (1.0 + e), sg * (1.0 - d), sg * (1.0 - e)};
            rd_select_gaps *gp = &sel->gaps[y * 48 + x];
            for (int j = 0; j < 4; j++) gp->gap[j] = c[j] * mean[j], gp->gap_n[j] = c[j];
            const double ne = c[0] + c[2], no = c[1] + c[3], w = ne * no / (ne + no);
            if (!S) continue;
            S[k] += w * (mean[0] + mean[2]) * (mean[1] + mean[3]) / 4.0;
            Wk[k] += w, Dk[k] += w * (mean[0] - mean[2]) * (mean[1] - mean[3]) / 4.0;
        }
}

/* The beams' bias at an epoch (select.c bias_fold, select_rule.c bias_ratio and "The beams'
 * bias"): a 6x5-tile selection (48x40 pixels) of delta and the method (variance 0.05 a sample)
 * and the beams (0.001), all at cost 1, the image's 16 samples a pixel so far the beams', as much
 * time left as taken. Every pixel's gaps so far (rd_select.gaps) are beams_gaps' (the signs in a
 * checkerboard: a blur's bias changes sign across an edge, so a tile's mean gaps are 0; even
 * columns weigh 3 x 5 / 8, odd ones 1). A pixel's product
 * (m0 + m2)(m1 + m3) / 4 is g^2 for every D, its turned product (m0 - m2)(m1 - m3) / 4 g^2 d_k e_k:
 * noise, which D sets. The ratio is 11.66 (RD_SELECT_BIAS_PER_GAP2, checked) x the weighted mean
 * product x the radius's square (radius_scale 0.8) over the beams' variance a sample, its
 * standard error sqrt(sum_k D_k^2 + the sum of D_k D_j over the ordered pairs of touching tiles,
 * that sum clamped at 0) over the weights' sum (D_k a tile's weighted turned products), both
 * checked against this test's own sums, and a second epoch with no new samples reads the same.
 * Then:
 * - no gap (g 0): the beams take every tile;
 * - g 0.046, D 0.3: a ratio of 15.8 +- 0.50, far beyond its standard errors; the beams' 50x lower
 *   variance does not pay for a squared bias weighed ~16 (1 + 2) times (the line is near a ratio
 *   of 1): delta keeps every tile;
 * - the same g, D 3: a ratio of 15.8 +- 50.0, so three standard errors take it all: the beams
 *   take every tile again;
 * - g 0.046, D 0.3 with `flip`: the touching tiles' covariances sum below 0 and count as 0, 15.8 +-
 *   0.21: delta keeps every tile.
 * Fails with the products taken from a tile's mean gaps instead of each pixel's, the factor or
 * the radius left out, the margin left out, the tiles' columns and rows swapped, the neighbours
 * wrapped across rows, or the clamp left out. */
Test(select, the_beams_bias_is_read_from_every_pixel_s_gaps_with_its_noise_from_disjoint_passes)
{
    cr_assert(fabs(RD_SELECT_BIAS_PER_GAP2 - pow(1.0 - sqrt(0.5), -2.0)) < 1e-12, "the factor %.15g", RD_SELECT_BIAS_PER_GAP2);
    const double g_of[4] = {0.0, 0.046, 0.046, 0.046}, D_of[4] = {0.0, 0.3, 3.0, 0.3};
    enum { W = 48, H = 40, T = 30 };
    for (int i = 0; i < 4; i++) {
        rd_select sel;
        char err[RD_ERRLEN];
        cr_assert(rd_select_init(&sel, W, H, 1.0, 3, err, sizeof err) == RD_OK, "%s", err);
        sel.kind[2] = RD_SEL_BEAMS, sel.paths &= ~(1u << 2);
        cr_assert((sel.gaps = calloc(W * H, sizeof *sel.gaps)) != NULL); /* (as rd_select_prepare_more with the beams) */
        for (int k = 0; k < T; k++) {
            fake_pilot(&sel, 3 * k, 0.5, 0.05, 1.0, 1.0);
            fake_pilot(&sel, 3 * k + 1, 0.5, 0.05, 1.0, 1.0);
            fake_pilot(&sel, 3 * k + 2, 0.5, 0.001, 1.0, 1.0);
            for (int h = 0; h < 2; h++) { /* the image's 16 samples a pixel, 32 pixels a half */
                rd_select_stats *st = &sel.stats[(size_t)h * 3 * T + 3 * k + 2];
                st->image_n = 32.0 * 16.0, st->image_cost = 32.0 * 16.0;
            }
        }
        const double g = g_of[i], r2 = 0.8 * 0.8;
        double S[T] = {0}, Wk[T] = {0}, Dk[T] = {0};
        beams_gaps(&sel, g, D_of[i], i == 3, S, Wk, Dk);
        double sum = 0.0, wsum = 0.0, d2 = 0.0, cross = 0.0;
        for (int k = 0; k < T; k++) sum += S[k], wsum += Wk[k], d2 += Dk[k] * Dk[k];
        for (int k = 0; k < T; k++) /* the touching tiles' covariances: every ordered pair */
            for (int j = 0; j < T; j++)
                if (j != k && abs(j % 6 - k % 6) <= 1 && abs(j / 6 - k / 6) <= 1) cross += Dk[k] * Dk[j];
        cr_assert(i != 3 || cross < 0.0, "flip: the covariances sum to %g, not below 0: the clamp is not tried", cross);
        d2 += fmax(0.0, cross);
        const double ratio = 11.656854249492380 * sum / wsum * r2 / 0.001;
        const double se = 11.656854249492380 * sqrt(d2) / wsum * r2 / 0.001;
        for (int epoch = 0; epoch < 2; epoch++) {
            rd_select_epoch(&sel, NULL, &(rd_select_end){1.0, 0.0, 0.8});
            if (g > 0.0)
                cr_assert(fabs(sel.bias_ratio / ratio - 1.0) < 1e-9 && fabs(sel.bias_se / se - 1.0) < 1e-9,
                          "g %g, D %g, epoch %d: the ratio read %g +- %g, want %g +- %g", g, D_of[i], epoch, sel.bias_ratio,
                          sel.bias_se, ratio, se);
            else cr_assert(sel.bias_ratio == 0.0 && sel.bias_se == 0.0, "no gap: the ratio read %g +- %g", sel.bias_ratio, sel.bias_se);
        }
        const int want = i == 1 || i == 3 ? RD_SEL_DELTA : 2;
        for (int k = 0; k < T; k++)
            cr_expect(sel.choice[k] == want && sel.trial[k] == 0, "g %g, D %g (ratio %g +- %g): tile %d took %d (trial %d), not %d",
                      g, D_of[i], sel.bias_ratio, sel.bias_se, k, sel.choice[k], sel.trial[k], want);
        rd_select_free(&sel);
    }
}

/* Off the biased beams at once (select_rule.c's head): the 6x5-tile selection of the test above
 * (delta at variance 0.05 a sample, cost 1), every tile held by one estimator, which has 1152 of
 * its samples against delta's 128 (the pilot's): evidence lopsided beyond RD_SELECT_TRIAL_RATIO.
 * - The beams hold the tiles and lose them on their variance, 0.5 a sample, with no gap read:
 *   the moves to delta's path go on trial.
 * - The beams hold them at a variance of 0.001 and the image reads their bias (the gaps above,
 *   g 0.046, D 0.3: 15.8 +- 0.50): every tile leaves them at once, none on trial.
 * - The method holds them at a variance of 0.5 (the beams' 0.001, the same bias read): the moves
 *   to delta's path go on trial (only a move off the beams skips it).
 * Fails with the move put on trial, or with a move off any estimator made at once. */
Test(select, a_tile_leaves_the_beams_at_once_where_the_image_reads_their_bias)
{
    enum { T = 30 };
    for (int c = 0; c < 3; c++) {
        rd_select sel;
        char err[RD_ERRLEN];
        cr_assert(rd_select_init(&sel, 48, 40, 1.0, 3, err, sizeof err) == RD_OK, "%s", err);
        sel.kind[2] = RD_SEL_BEAMS, sel.paths &= ~(1u << 2);
        cr_assert((sel.gaps = calloc(48 * 40, sizeof *sel.gaps)) != NULL);
        const int held = c == 2 ? RD_SEL_METHOD : 2;
        const double vb = c == 0 ? 0.5 : 0.001, vm = c == 2 ? 0.5 : 0.05;
        for (int k = 0; k < T; k++) {
            fake_pilot(&sel, 3 * k, 0.5, 0.05, 1.0, 1.0);
            fake_pilot(&sel, 3 * k + 1, 0.5, vm, 1.0, 1.0);
            fake_pilot(&sel, 3 * k + 2, 0.5, vb, 1.0, 1.0);
            for (int h = 0; h < 2; h++) { /* the image's 16 samples a pixel, 32 pixels a half: the holder's */
                add_half(&sel, h, 3 * k + held, 32.0, 16.0, 0.5, held == 2 ? vb : vm, 1.0, 1.0);
                rd_select_stats *st = &sel.stats[(size_t)h * 3 * T + 3 * k + held];
                st->image_n = 32.0 * 16.0, st->image_cost = 32.0 * 16.0;
            }
            sel.choice[k] = (uint8_t)held;
        }
        beams_gaps(&sel, c == 0 ? 0.0 : 0.046, 0.3, 0, NULL, NULL, NULL);
        rd_select_epoch(&sel, NULL, &(rd_select_end){1.0, 0.0, 0.8});
        cr_assert(c ? sel.bias_ratio > 3.0 * sel.bias_se + 1.0 : sel.bias_ratio == 0.0, "case %d: the ratio read %g +- %g", c,
                  sel.bias_ratio, sel.bias_se);
        for (int k = 0; k < T; k++)
            cr_expect(c == 1 ? sel.choice[k] == RD_SEL_DELTA && sel.trial[k] == 0
                             : sel.choice[k] == held && sel.trial[k] == 1 + RD_SEL_DELTA,
                      "case %d: tile %d took %d (trial %d)", c, k, sel.choice[k], sel.trial[k]);
        rd_select_free(&sel);
    }
}

/* settings.adaptive's shares (rd_select.share; select_share.c, "Samples where they pay"): a
 * tile's pixels draw sqrt(V / C) of their estimator's figures over the largest tile's. 6x5 tiles,
 * delta dominant in all (the choice), its variance a sample 4x as large in the left three
 * columns as in the right three at the same cost: the figures are pooled over 3x3 tiles, so the
 * edge columns 0 and 5 read their own side alone, and their shares are 1 and sqrt(1/4) = 1/2.
 * Before the first epoch's choice, and without the option, every pixel draws every sample. Fails with
 * the share taken as V / C (1/4), or read from the estimator the tile does not use. */
Test(select, a_tile_s_share_of_the_samples_is_the_root_of_its_variance_over_its_cost)
{
    enum { NX = 6, NY = 5, T = NX * NY };
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(&sel, 8 * NX, 8 * NY, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(rd_select_share(&sel, 3, 3, NULL) == 1.0, "without shares a pixel draws every sample");
    cr_assert((sel.share = malloc(2 * T * sizeof *sel.share)) != NULL);
    for (int i = 0; i < 2 * T; i++) sel.share[i] = 1.0f;
    cr_assert((sel.weight = calloc(2 * T, sizeof *sel.weight)) != NULL); /* (settings.adaptive true) */
    for (int k = 0; k < T; k++) {
        const double v = k % NX < 3 ? 0.04 : 0.01;
        fake_pilot(&sel, 2 * k, 0.5, v, 1.0, 1.0);       /* delta */
        fake_pilot(&sel, 2 * k + 1, 0.5, 9.0, 1.0, 2.0); /* the method: more variance and cost */
    }
    cr_assert(rd_select_share(&sel, 3, 3, NULL) == 1.0, "before the first choice a pixel draws every sample");
    rd_select_epoch(&sel, NULL, NULL); /* as the pilot's choice: it governs the samples all draw */
    cr_assert(rd_select_share(&sel, 3, 3, NULL) == 1.0, "under the pilot's choice a pixel draws every sample");
    rd_select_epoch(&sel, NULL, NULL); /* the first epoch's, with the same statistics */
    for (int k = 0; k < T; k++) cr_assert(sel.choice[k] == RD_SEL_DELTA && sel.trial[k] == 0, "tile %d: %d", k, sel.choice[k]);
    for (int ty = 0; ty < NY; ty++) {
        const double left = rd_select_share(&sel, 1, 8 * ty + 2, NULL), right = rd_select_share(&sel, 8 * 5 + 6, 8 * ty + 5, NULL);
        cr_assert(fabs(left - 1.0) < 1e-6, "row %d: the noisier side's share %g, not 1", ty, left);
        cr_assert(fabs(right - 0.5) < 1e-6, "row %d: the quieter side's share %g, not 1/2", ty, right);
    }
    rd_select_free(&sel);
}

/* A selection of nx x ny tiles and two estimators with shares (every share 1) in mode 0
 * ("pilot": no weights), 1 (true: weights) or 2 ("epochs": blocks). */
static void shares_select(rd_select *sel, int nx, int ny, int mode)
{
    char err[RD_ERRLEN];
    const int t = nx * ny;
    cr_assert(rd_select_init(sel, 8 * nx, 8 * ny, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    cr_assert((sel->share = malloc(2 * (size_t)t * sizeof *sel->share)) != NULL);
    for (int i = 0; i < 2 * t; i++) sel->share[i] = 1.0f;
    if (mode == 1) cr_assert((sel->weight = calloc(2 * (size_t)t, sizeof *sel->weight)) != NULL);
    sel->blocks = mode == 2;
}

/* settings.adaptive "pilot" (select_share.c, "Pilot shares"): with no weights the shares are set
 * at the pilot's choice alone and kept, one a tile whatever estimator it uses, so that no pixel's
 * count of samples depends on its image samples. 6x5 tiles as above; at the pilot the left three
 * columns are the noisier (shares 1 and 1/2), at the two epochs after it the right three. Without
 * weights the shares stay the pilot's; with weights (settings.adaptive true) the same figures
 * move them (1/2 and 1), which is what the check would see if "pilot" followed the epochs; and so
 * do "epochs"' (blocks, no weights: select_share.c "Epoch shares"), whose shares must follow. */
Test(select, pilot_shares_are_set_once_and_kept_whatever_the_epochs_read)
{
    enum { NX = 6, NY = 5, T = NX * NY };
    for (int mode = 0; mode < 3; mode++) { /* "pilot", true (weights), "epochs" (blocks) */
        const int follow = mode > 0;
        const char *name = mode == 0 ? "pilot" : mode == 1 ? "weights" : "blocks";
        rd_select sel;
        shares_select(&sel, NX, NY, mode);
        for (int round = 0; round < 3; round++) { /* the pilot's choice, then two epochs' */
            for (int k = 0; k < T; k++) {
                const double v = (round == 0) == (k % NX < 3) ? 0.04 : 0.01;
                fake_pilot(&sel, 2 * k, 0.5, v, 1.0, 1.0);       /* delta, the choice */
                fake_pilot(&sel, 2 * k + 1, 0.5, 9.0, 1.0, 2.0); /* the method: more variance and cost */
            }
            rd_select_epoch(&sel, NULL, NULL);
        }
        const double want_left = follow ? 0.5 : 1.0, want_right = follow ? 1.0 : 0.5;
        for (int ty = 0; ty < NY; ty++) {
            const double left = rd_select_share(&sel, 1, 8 * ty + 2, NULL), right = rd_select_share(&sel, 8 * 5 + 6, 8 * ty + 5, NULL);
            cr_assert(fabs(left - want_left) < 1e-6 && fabs(right - want_right) < 1e-6,
                      "%s, row %d: shares %g and %g, not %g and %g", name, ty, left, right, want_left, want_right);
        }
        if (!follow)
            for (int k = 0; k < T; k++)
                cr_assert(sel.share[2 * k] == sel.share[2 * k + 1], "tile %d: shares %g and %g by estimator", k,
                          sel.share[2 * k], sel.share[2 * k + 1]);
        rd_select_free(&sel);
    }
}

/* Past the pilot, "pilot"'s shares stay fixed, so the rule weighs each tile's figures in sample
 * indices, V / s and C s, and minimises their product over the image (select_rule.c's head,
 * "Fixed shares"); the adaptive rule's own sqrt(V C) a tile assumes the share follows the choice.
 * 6x5 tiles, two estimators (delta, cost 1; the method, cost 20 and 1/16 of delta's variance
 * on the right). The pilot reads delta's variance 1 on the left (share 1) and 1/256 on the
 * right (share sqrt(1/256) = 1/16); the epoch reads 1 everywhere. On the right the method's
 * sqrt(V C) is 1.12x delta's, so the shares that follow the choice keep delta there; at share
 * 1/16 all right tiles on delta make (15 + 15 x 16)(15 + 15 / 16) = 4064 against the method's
 * (15 + 15)(15 + 15 x 20 / 16) = 1013, so the fixed shares move them. Columns 4-5 (pooled over
 * right tiles only) are read; with shares that follow (true's, "epochs"') the adaptive rule keeps
 * delta. Fails with the adaptive rule under "pilot", or with V s and C / s. */
Test(select, fixed_shares_weigh_a_tile_s_figures_by_its_share)
{
    enum { NX = 6, NY = 5, T = NX * NY };
    for (int mode = 0; mode < 3; mode++) { /* "pilot", then shares that follow: true's, "epochs"' */
        const int weighted = mode > 0;
        rd_select sel;
        shares_select(&sel, NX, NY, mode);
        for (int round = 0; round < 2; round++) { /* the pilot's choice, then an epoch's */
            for (int k = 0; k < T; k++) {
                const int right = k % NX >= 3;
                fake_pilot(&sel, 2 * k, 0.5, round == 0 && right ? 1.0 / 256.0 : 1.0, 1.0, 1.0);
                fake_pilot(&sel, 2 * k + 1, 0.5, right ? (round == 0 ? 1.0 : 1.0 / 16.0) : 100.0, 1.0, 20.0);
            }
            rd_select_epoch(&sel, NULL, NULL);
            if (round == 0 && !weighted)
                for (int k = 0; k < T; k++) /* (columns 2 and 3 pool each other's) */
                    cr_assert(k % NX == 2 || k % NX == 3 || fabs(sel.share[2 * k] - (k % NX > 3 ? 1.0 / 16.0 : 1.0)) < 1e-6,
                              "pilot: tile %d share %g", k, sel.share[2 * k]);
        }
        for (int ty = 0; ty < NY; ty++)
            for (int tx = 0; tx < NX; tx++) {
                const int k = ty * NX + tx, want = tx >= 4 && !weighted ? 1 : 0;
                if (tx == 3) continue; /* (pooled with the left's column 2) */
                cr_assert(sel.choice[k] == want && sel.trial[k] == 0, "%s, tile (%d, %d): estimator %d (trial %d), not %d",
                          mode == 0 ? "pilot" : mode == 1 ? "weights" : "blocks", tx, ty, sel.choice[k], sel.trial[k], want);
            }
        rd_select_free(&sel);
    }
}

/* settings.adaptive "epochs" (select_share.c, "Epoch shares"): with each drawn sample weighing the
 * indices it stands for (rd_block_next, as render.c draws them), a pixel's mean stays unbiased
 * whatever its shares follow, its own past samples included; its plain mean does not. One pixel
 * of 256 samples X (1 with probability q = 1/4, else 0), epochs at 4, 16, 64 (x4, select.c's),
 * each epoch's share set by an adversary from the pixel's own mean so far: 1 where it is above q
 * (more samples to dilute a high start), 1/16 at or below (a low start kept). Over 2^18 pixels
 * (fixed seed) the weighted mean must lie within 5 standard errors of q and every pixel's
 * weights sum to 256; the plain mean of the same samples must lie beyond 5 (the test sees a
 * bias). Fails with every weight 1 (the plain mean), and by the weights' sum where blocks do not
 * begin at the epoch's first index or run past its end. */
Test(select, block_weights_keep_a_pixel_s_mean_unbiased_whatever_its_shares_follow)
{
    enum { N = 256, PIXELS = 1 << 18 };
    const double q = 0.25;
    pcg32 rng = pcg32_seed(2026, 12, 71);
    double s[2] = {0.0, 0.0}, s2[2] = {0.0, 0.0}; /* the weighted means', then the plain means' */
    for (int p = 0; p < PIXELS; p++) {
        double wx = 0.0, w = 0.0, x = 0.0, n = 0.0;
        for (int a = 0, b = RD_SHARE_FIRST; a < N; a = b, b = 4 * b < N ? 4 * b : N) {
            const double share = a < RD_SHARE_FIRST || x / n > q ? 1.0 : 1.0 / 16.0;
            for (int i = rd_block_next(a, a, b, share); i < b; i = rd_block_next(i + 1, a, b, share)) {
                const double X = pcg32_uniform(&rng) < q ? 1.0 : 0.0, wi = rd_block_next(i + 1, a, b, share) - i;
                wx += wi * X, w += wi, x += X, n += 1.0;
            }
        }
        if (w != N) cr_assert_fail("pixel %d: weights sum to %g, not %d", p, w, N);
        const double e[2] = {wx / w, x / n};
        for (int k = 0; k < 2; k++) s[k] += e[k], s2[k] += e[k] * e[k];
    }
    double z[2];
    for (int k = 0; k < 2; k++) {
        const double mean = s[k] / PIXELS, var = (s2[k] / PIXELS - mean * mean) * PIXELS / (PIXELS - 1.0);
        z[k] = (mean - q) / sqrt(var / PIXELS);
    }
    cr_log_info("epoch shares: z of the weighted mean %.2f, of the plain mean %.2f", z[0], z[1]);
    cr_assert(fabs(z[0]) < 5.0, "the weighted mean is %.2f standard errors off q", z[0]);
    cr_assert(fabs(z[1]) > 5.0, "the plain mean is only %.2f standard errors off q: the adversary shows no bias", z[1]);
}

/* The share of a dark tile (no sample of any estimator lit it or its 8 neighbours: its pooled
 * variance 0) by Laplace's rule of succession (select_share.c, "Dark tiles"): after N samples
 * over its 3x3 tiles, all 0, its variance a sample is M / (N + 2), M the
 * image's mean square of the estimator's lit samples, so its share shrinks as its samples prove
 * it dark and never reaches the floor at once. At share 1, session 67's rule, the cheap black
 * tiles of scenes/hard-dense-block.json drew 20000 samples a pixel where the lit ones drew 100.
 * 6x5 tiles: columns 0-2 lit (delta's variance 0.04 a sample, mean 0.5, every sample lit), 3-5
 * dark; tile (5, 4) has no samples (share 1: nothing read). Column 3 reads a pooled variance from
 * column 2; columns 4 and 5 are dark. Then the dark tiles draw as many samples again, and their
 * shares fall by sqrt((N + 2) / (2 N + 2)). Fails with share 1 or the floor (1/4096) for the
 * dark tiles, with N not counted over the 3x3 tiles, and with the floor given to the tile with
 * no samples. */
Test(select, a_dark_tile_s_share_follows_the_rule_of_succession_and_one_with_no_samples_draws_all)
{
    enum { NX = 6, NY = 5, T = NX * NY, SPP = 128 /* a fake pilot's samples a tile */ };
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(&sel, 8 * NX, 8 * NY, 1.0, 2, err, sizeof err) == RD_OK, "%s", err);
    cr_assert((sel.share = malloc(2 * T * sizeof *sel.share)) != NULL);
    for (int i = 0; i < 2 * T; i++) sel.share[i] = 1.0f;
    /* (settings.adaptive true: with weights; without, the pilot's shares are kept) */
    cr_assert((sel.weight = calloc(2 * T, sizeof *sel.weight)) != NULL);
    const double v = 0.04, mu = 0.5;
    for (int k = 0; k < T - 1; k++) {
        const int lit = k % NX < 3;
        fake_pilot(&sel, 2 * k, lit ? mu : 0.0, lit ? v : 0.0, lit ? 1.0 : 0.0, 1.0);     /* delta */
        fake_pilot(&sel, 2 * k + 1, lit ? mu : 0.0, lit ? 9.0 : 0.0, lit ? 1.0 : 0.0, 2.0); /* the method */
    }
    /* M: per lit tile, dev2 = v dof (dof = 112 of 128 samples) and n mu^2, over its 128 lit samples;
     * the largest sqrt(V / C) is a lit tile's, sqrt(v) (64 pixels' V and C alike) */
    const double M = (v * 112.0 + mu * mu * SPP) / SPP, top = sqrt(v);
    for (int round = 1; round <= 2; round++) {
        rd_select_epoch(&sel, NULL, NULL); /* (round 1: the pilot's choice, then the first epoch's) */
        if (round == 1) rd_select_epoch(&sel, NULL, NULL);
        for (int ty = 0; ty < NY; ty++)
            for (int tx = 0; tx < NX; tx++) {
                const double s = rd_select_share(&sel, 8 * tx + 3, 8 * ty + 4, NULL);
                if (tx == NX - 1 && ty == NY - 1) {
                    cr_assert(s == 1.0, "the tile with no samples: share %g, not 1", s);
                } else if (tx >= 4) {
                    /* delta's samples over the 3x3 tiles, and its cost a sample pooled over them
                     * (the tile with no samples counts 0: select_rule.c pool) */
                    double N = 0.0, tiles = 0.0, with = 0.0;
                    for (int y = ty - 1; y <= ty + 1; y++)
                        for (int x = tx - 1; x <= tx + 1; x++) {
                            if (x < 0 || y < 0 || x >= NX || y >= NY) continue;
                            tiles += 1.0;
                            if (x == NX - 1 && y == NY - 1) continue;
                            N += (x < 3 ? 1 : round) * SPP, with += 1.0;
                        }
                    const double want = sqrt(M / (N + 2.0) / (with / tiles)) / top;
                    cr_assert(fabs(s - want) <= 1e-5 * want, "round %d, dark tile (%d, %d): share %g, not %g", round, tx,
                              ty, s, want);
                } else {
                    cr_assert(s > 0.1 && s <= 1.0, "round %d, tile (%d, %d) reads a variance: share %g", round, tx, ty, s);
                }
            }
        for (int k = 0; k < T - 1; k++) /* the dark tiles draw as many samples again, all 0 */
            if (k % NX >= 3)
                for (int h = 0; h < 2; h++) add_half(&sel, h, 2 * k, 8, 8, 0.0, 0.0, 0.0, 1.0);
    }
    rd_select_free(&sel);
}

/* The weights of the samples (select_share.c, "Weights"), set by rd_select_set_shares from the
 * figures it is given: a tile's first estimator weighs 1; an estimator the tile takes later
 * weighs w_o V_o / V_e, o the tile's weighed estimator with the most image samples, V the figures
 * then; a weight once set stays, whatever the figures do after. 2x1 tiles, three estimators, every
 * sample lit (no floor reached). Fails with a weight set anew at every call (the third's, after
 * its variance doubles; a weight set once from w_o V_o / V_e with o = e is the same at once),
 * with o the first weighed estimator instead of the one of the most samples (the third move),
 * and with the trial's estimator left unweighed. */
Test(select, a_tile_s_weights_are_set_once_per_estimator_by_the_variances_at_the_move)
{
    enum { T = 2, M = 3 };
    rd_select sel;
    char err[RD_ERRLEN];
    cr_assert(rd_select_init(&sel, 8 * T, 8, 1.0, M, err, sizeof err) == RD_OK, "%s", err);
    cr_assert((sel.share = malloc(M * T * sizeof *sel.share)) != NULL);
    cr_assert((sel.weight = calloc(M * T, sizeof *sel.weight)) != NULL);
    rd_select_stats st[M * T];
    memset(st, 0, sizeof st);
    for (int i = 0; i < M * T; i++) st[i].n = st[i].nonzero = 128.0, st[i].sum[0] = st[i].sum[1] = st[i].sum[2] = 64.0;
    double var[M * T] = {0.08, 0.002, 0.01, 0.08, 0.002, 0.01}, cost[M * T] = {1, 30, 2, 1, 30, 2};
    double w;
    sel.choices = 1, sel.choice[0] = 0, sel.choice[1] = 1; /* the pilot's choice */
    rd_select_set_shares(&sel, st, var, cost);
    rd_select_share(&sel, 2, 2, &w);
    cr_assert(w == 1.0 && sel.weight[0] == 1.0 && sel.weight[4] == 1.0, "a tile's first estimator weighs %g, not 1", w);
    cr_assert(sel.weight[1] == 0.0 && sel.weight[2] == 0.0, "an estimator the tile does not use is weighed");
    /* an epoch: delta's variance doubles in tile 0, which keeps it: its weight stays 1 */
    sel.choices = 2, var[0] = 0.16, st[0].image_n = 4096.0;
    rd_select_set_shares(&sel, st, var, cost);
    cr_assert(sel.weight[0] == 1.0, "delta's weight moved with its figures: %g", sel.weight[0]);
    /* tile 0 moves to the method: its weight 1 x 0.16 / 0.002 = 80 */
    sel.choice[0] = 1;
    rd_select_set_shares(&sel, st, var, cost);
    rd_select_share(&sel, 2, 2, &w);
    cr_assert(fabs(w - 80.0) < 1e-4, "the method's weight after the move: %g, not 80", w);
    /* the method gathers more image samples than delta had; then the tile moves to the third, against
     * the method's figures: 80 x 0.004 / 0.01 = 32 (against delta's, 1 x 0.16 / 0.01 = 16) */
    st[1].image_n = 8192.0, var[1] = 0.004, sel.choice[0] = 2;
    rd_select_set_shares(&sel, st, var, cost);
    cr_assert(fabs(sel.weight[2] - 32.0) < 1e-4, "the third's weight: %g, not 32", sel.weight[2]);
    cr_assert(sel.weight[0] == 1.0 && fabs(sel.weight[1] - 80.0) < 1e-4, "the weights set before changed");
    /* the third's variance doubles while the tile keeps it: its weight stays 32 */
    var[2] = 0.02;
    rd_select_set_shares(&sel, st, var, cost);
    cr_assert(fabs(sel.weight[2] - 32.0) < 1e-4, "the third's weight moved with its figures: %g", sel.weight[2]);
    /* tile 1 puts the third on trial: half its pixels draw it, at 1 x 0.002 / 0.01 = 0.2 */
    sel.trial[1] = 1 + 2;
    rd_select_set_shares(&sel, st, var, cost);
    int seen[2] = {0, 0};
    for (int y = 0; y < 8; y++)
        for (int x = 8; x < 16; x++) {
            const int e = rd_select_uses(&sel, x, y);
            rd_select_share(&sel, x, y, &w);
            cr_assert(e == 1 || e == 2, "pixel (%d, %d) of the trial uses %d", x, y, e);
            const double want = e == 1 ? 1.0 : 0.2;
            cr_assert(fabs(w - want) < 1e-6, "pixel (%d, %d) with estimator %d weighs %g, not %g", x, y, e, w, want);
            seen[e - 1] = 1;
        }
    cr_assert(seen[0] && seen[1], "the trial's checkerboard did not hold both estimators");
    rd_select_free(&sel);
}

/* The beams estimator is the selection's last, after the third and the method's second (the
 * order of the kinds), not one of delta's paths; with RD_SELECT_PASSES its samples, not the
 * method's, carry the passes' share (a pass serves pass_spp x all pixels of them: render.c),
 * its PDF segments weigh the method's cell cost, and the pixels given to it are the ones that
 * pace the passes (rd_select_pass_pixels). Fails with the share left on the method, the
 * segments at the path's weight, or the pacing pixels counted from the method's tiles. */
Test(select, the_beams_estimator_is_the_last_and_carries_the_passes_share)
{
    rd_scene *s = rt_scene("selbeams.json", select_scene("{\"select\":\"tiles\"}"));
    rd_render_ctx ctx = {.scene = s, .method = rd_method_find("delta"), .threads = 1};
    ctx.pass_emitted = 1000, ctx.pass_collisions = 9000, ctx.pass_indexed = 4000;
    const double share = (RD_SELECT_COST_EMITTED * 1000 + RD_SELECT_COST_COLLISION * 9000 + RD_SELECT_COST_ORDERED * 4000) /
                         (32.0 * 24.0);
    char err[RD_ERRLEN];
    for (int third = 0; third < 2; third++)
        for (int path = 0; path < 2; path++) {
            rd_select sel;
            const rd_select_more more = {.path = path ? path_stand_in : NULL, .path_cell_cost = 0.5, .beams = beams_stand_in};
            int options = RD_SELECT_PASSES | RD_SELECT_PASSES_ORDERED | (third ? RD_SELECT_THIRD : 0);
            cr_assert(rd_select_prepare_more(&ctx, unit_method, NULL, 7.0, options, &more, &sel, err, sizeof err) == RD_OK,
                      "%s", err);
            int n = 3 + third + path, b = n - 1, tiles = sel.tiles_x * sel.tiles_y;
            cr_assert(sel.n == n && sel.kind[b] == RD_SEL_BEAMS && sel.pass_kind == RD_SEL_BEAMS,
                      "third %d, path %d: %d estimators, the last of kind %d", third, path, sel.n, sel.kind[b]);
            cr_expect(!path || sel.kind[b - 1] == RD_SEL_PATH, "the method's second estimator before the beams");
            cr_expect(sel.paths == (1u << RD_SEL_DELTA | (third ? 1u << RD_SEL_DELTA_EQ : 0u)), "delta's paths 0x%x", sel.paths);
            size_t mn = (size_t)sel.n * tiles;
            for (int k = 0; k < tiles; k++)
                for (int h = 0; h < 2; h++) {
                    const rd_select_stats *st = &sel.stats[h * mn + (size_t)sel.n * k];
                    double cb = st[b].cost / st[b].n, cm = st[RD_SEL_METHOD].cost / st[RD_SEL_METHOD].n;
                    /* (the beams' pilot: its first stage's 2 samples a pixel, or where they
                     * contend for the tile all 8, in both halves alike:
                     * the_beams_pilot_the_tiles_they_contend_for_in_full) */
                    const rd_select_stats *other = &sel.stats[(1 - h) * mn + (size_t)sel.n * k];
                    cr_expect((st[b].n == 16 || st[b].n == 64) && st[b].sum[0] == 4.0 * st[b].n && other[b].n == st[b].n,
                              "tile %d, half %d: %g beams samples (the other half %g), sum %g", k, h, st[b].n, other[b].n,
                              st[b].sum[0]);
                    cr_expect(fabs(cb - (RD_SELECT_COST_SAMPLE + 3 * 7.0 + share)) < 1e-4,
                              "tile %d, half %d: the beams' cost %g a sample, not %g", k, h, cb,
                              RD_SELECT_COST_SAMPLE + 3 * 7.0 + share);
                    cr_expect(fabs(cm - RD_SELECT_COST_SAMPLE) < 1e-4, "tile %d, half %d: the method's cost %g carries a share",
                              k, h, cm);
                }
            /* the left column of tiles to the beams (192 pixels), the rest to the method (576) */
            for (int k = 0; k < tiles; k++) sel.choice[k] = (uint8_t)(k % sel.tiles_x == 0 ? b : RD_SEL_METHOD), sel.trial[k] = 0;
            rd_thread th = {0};
            double Lx[32 * 24];
            sample_every_pixel(&ctx, &sel, &th, Lx);
            for (int i = 0; i < 32 * 24; i++)
                cr_expect(Lx[i] == (i % 32 < 8 ? 4.0 : 1.0), "pixel (%d, %d): %g", i % 32, i / 32, Lx[i]);
            cr_expect(th.beams_samples == 8 * 24 && th.path_samples == 0 && th.delta_samples == 0,
                      "%llu beams samples, %llu path, %llu delta", (unsigned long long)th.beams_samples,
                      (unsigned long long)th.path_samples, (unsigned long long)th.delta_samples);
            cr_expect(rd_select_pass_pixels(&sel, 32 * 24) == 8 * 24, "%llu pixels pace the passes, not the beams' 192",
                      (unsigned long long)rd_select_pass_pixels(&sel, 32 * 24));
            rd_select_free(&sel);
        }
    rd_scene_free(s);
}

/* The selection scene with guided's default source, settings.select `select` and march.beams
 * `beams` (absent: NULL; progressive passes of 4000 photons, 1 spp a pass; the marcher's
 * equiangular sample off, as delta's is). */
static const char *beams_estimator_scene(const char *select, const char *beams)
{
    static char extra[256], settings[64];
    snprintf(extra, sizeof extra,
             "\"photons\":{\"count\":40000,\"pass_count\":4000,\"pass_spp\":1},"
             "\"march\":{\"equiangular\":false%s%s}",
             beams ? ",\"beams\":" : "", beams ? beams : "");
    snprintf(settings, sizeof settings, "{\"select\":\"%s\"}", select);
    return rt_spot_fog_json_with(32, 24, settings, extra);
}

/* A guided render of scene `json` (6 spp) in which no sample is the beams' and no photon pass is
 * traced. */
static void expect_no_beams(const char *name, const char *json, const char *what)
{
    rd_scene *s = rt_scene(name, json);
    rd_render_opts o = {.method = "guided", .spp = 6, .seed = 5, .threads = 2};
    rd_render_result r;
    char err[RD_ERRLEN];
    cr_assert(rd_render(s, &o, &r, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(r.stats.beams_samples == 0 && r.stats.beam_queries == 0 && r.stats.photon_passes == 0,
              "%s: %llu beams samples, %d passes", what, (unsigned long long)r.stats.beams_samples, r.stats.photon_passes);
    rd_render_result_free(&r);
    rd_scene_free(s);
}

/* A dense, nearly white box under a point light (sigma_t 10, albedo 0.99), 32x24, with
 * march.beams and passes of 2000 photons, 4 spp each: where the beams take most tiles. */
static const char *dense_beams_scene(void)
{
    return "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[32,24]},"
           "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":{\"type\":\"constant\",\"value\":1},"
           "\"sigma_t\":10,\"albedo\":0.99,\"g\":0.3}],"
           "\"lights\":[{\"type\":\"point\",\"position\":[0,1.6,0.5],\"intensity\":4}],"
           "\"photons\":{\"count\":40000,\"pass_count\":2000,\"pass_spp\":4},"
           "\"march\":{\"equiangular\":false,\"beams\":true},\"settings\":{\"select\":\"tiles\"}}";
}

/* The photon passes of a render that gave M samples to the beams, a pass per per_pass of them:
 * pass 1 always, then one each time their count crosses a multiple of per_pass (a render pass
 * may overshoot by under one sample of every pixel, npix). */
static void expect_passes_paced_by(const rd_render_result *r, double per_pass, double npix, const char *what)
{
    double M = (double)r->stats.beams_samples;
    int p = r->stats.photon_passes;
    cr_log_info("%s: %d photon passes for %.0f beams samples of %llu (%.0f a pass)", what, p, M,
                (unsigned long long)r->stats.paths, per_pass);
    cr_expect(M > 0.0 ? (p - 1) * per_pass < M && M < p * per_pass + npix : p == 1,
              "%s: %d passes for %.0f samples of the beams", what, p, M);
}

/* guided with march.beams. Without the key (the default), or with settings.select off, no
 * sample is the beams' and no pass is traced. Where the beams pay (the dense box) the selection
 * gives them most samples and they gather balls. The photon passes follow the beams' samples
 * (a pass per pass_spp x all pixels of them), though photons.progressive is not set: on the
 * selection scene, where the beams take few samples or none (which, depends on the compiler's
 * rounding), passes by the image's samples would be 20. The image is the same on one thread
 * and two. */
Test(select, the_beams_estimator_takes_tiles_and_paces_its_own_passes, .timeout = 300)
{
    rd_scene *s0 = rt_scene("selbe0.json", beams_estimator_scene("tiles", NULL));
    cr_assert(s0->march.beams && !s0->photons.progressive, "march.beams is on by default (since session 61)");
    rd_scene_free(s0);
    expect_no_beams("selbe0.json", beams_estimator_scene("tiles", "false"), "without march.beams");
    /* with settings.select off there is no selection to hold the beams */
    expect_no_beams("selbeoff.json", beams_estimator_scene("off", "true"), "select off");
    rd_render_result r0;
    char err[RD_ERRLEN];
    /* the dense box: most samples on the beams */
    rd_scene *sd = rt_scene("selbed.json", dense_beams_scene());
    rd_render_opts od = {.method = "guided", .spp = 20, .seed = 5, .threads = 2};
    cr_assert(rd_render(sd, &od, &r0, err, sizeof err) == RD_OK, "%s", err);
    double share = (double)r0.stats.beams_samples / (double)r0.stats.paths;
    cr_assert(share > 0.5 && r0.stats.beam_queries > 0, "the dense box: the beams' share %g (%llu queries)", share,
              (unsigned long long)r0.stats.beam_queries);
    expect_passes_paced_by(&r0, 4.0 * 32 * 24, 32.0 * 24, "the dense box");
    rd_render_result_free(&r0);
    rd_scene_free(sd);
    /* the selection scene */
    rd_scene *s = rt_scene("selbe.json", beams_estimator_scene("tiles", "true"));
    rd_render_result r[2];
    render_on_1_and_2_threads(s, "guided", 20, 5, r);
    expect_passes_paced_by(&r[0], 32.0 * 24, 32.0 * 24, "the selection scene");
    expect_one_and_two_threads_alike(r);
    rd_scene_free(s);
}

/* render.c renders a pixel's samples in passes that end at the method's epochs and, where
 * photon passes run, at a photon pass's end; under settings.adaptive "epochs" a drawn index's
 * block runs to the next drawn index, or to its epoch's end or the render's last sample (lim,
 * rd_block_next), across render passes, so that the blocks tile every epoch. The index-by-index
 * test of rd_block_next (test_render.c) covers the rule; here the render: on the dense box the
 * beams' photon passes (4 spp a pass, paced by the beams' samples, which the shares thin) end
 * inside the epochs, and `guided` with "epochs" at 100 spp must pass render.c's check that every
 * pixel's weights sum to its samples (else RD_ERR_INTERNAL). Planted: a block cut at the render
 * pass's end (lim = s0 + done + n in render.c) fails it; in the other tests the render passes
 * end at the epochs' ends, where that mutation passes. */
Test(select, epoch_blocks_cut_by_photon_passes_still_tile_every_epoch, .timeout = 300)
{
    rd_scene *s = rt_scene("selbeep.json", dense_beams_scene());
    s->settings.adaptive = RD_ADAPTIVE_EPOCHS;
    rd_render_opts o = {.method = "guided", .spp = 100, .seed = 5, .threads = 2};
    rd_render_result r;
    char err[RD_ERRLEN];
    cr_assert(rd_render(s, &o, &r, err, sizeof err) == RD_OK, "%s", err);
    cr_log_info("guided with the epochs' shares and the beams: %d photon passes, %.1f samples a pixel of 100",
                r.stats.photon_passes, r.stats.spp_mean);
    cr_expect(r.stats.shares && r.stats.spp_mean < 100.0, "no shares (%.1f samples a pixel)", r.stats.spp_mean);
    cr_expect(r.stats.photon_passes > 3 && r.stats.beams_samples > 0, "%d photon passes, %llu beams samples: none to cut the epochs",
              r.stats.photon_passes, (unsigned long long)r.stats.beams_samples);
    for (size_t i = 0; i < (size_t)r.image.w * r.image.h * 3; i++) cr_assert(isfinite(r.image.rgb[i]));
    rd_render_result_free(&r);
    rd_scene_free(s);
}

/* ---- The beams' pilot in two stages (select.c's head) ---------------------------------------- */

/* Stand-ins on the 32x24 selection scene (4x3 tiles) whose variance a sample is 1/3 (2u, mean
 * 1) but in the left column of tiles (x < 8), where delta's path and the method are 10^4 times
 * that (200u: 3333) and the beams are still (1); the method costs 10 PDF segments a sample (72.18 at
 * the cell cost 7), the beams 3 (23.18 and the passes' share: none here). */
static vec3 two_stage_delta(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp, int equiangular)
{
    (void)ctx, (void)r, (void)equiangular;
    double v = (th->x < 8 ? 200.0 : 2.0) * rd_sampler_1d(smp);
    return v3(v, v, v);
}
static vec3 two_stage_method(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    th->cells += 10;
    return two_stage_delta(ctx, th, r, smp, 0);
}
static vec3 two_stage_beams(const rd_render_ctx *ctx, rd_thread *th, ray3 r, rd_sampler *smp)
{
    (void)ctx, (void)r;
    th->cells += 3;
    double v = th->x < 8 ? 1.0 : 2.0 * rd_sampler_1d(smp);
    return v3(v, v, v);
}

/* The beams' pilot in two stages: 2 samples of every pilot pixel (16 a half tile), then the
 * other 6 (64 a half tile, as every other estimator's) in the tiles the rule on the first stage
 * gives the beams or puts them on trial in, and their 3x3 neighbours. Above, pooled over 3x3
 * tiles, the beams take the two left columns (V C 0.17 x 23 and 0.22 x 23 against delta's 1667
 * x 2.18 and 1111 x 2.18; in the third column 0.33 x 23 against 0.33 x 2.18: delta), so the
 * three left columns have the beams' whole pilot and the right one its first stage; the tiles'
 * choices are the beams in the two left columns, delta's path elsewhere. Fails without the second
 * stage (16 everywhere), without the neighbours (the third column 16), or with the second stage
 * everywhere (the right column 64). */
Test(select, the_beams_pilot_the_tiles_they_contend_for_in_full)
{
    rd_scene *s = rt_scene("seltwo.json", select_scene("{\"select\":\"tiles\"}"));
    rd_render_ctx ctx = {.scene = s, .method = rd_method_find("delta"), .threads = 2};
    char err[RD_ERRLEN];
    rd_select sel;
    const rd_select_more more = {.beams = two_stage_beams};
    cr_assert(rd_select_prepare_more(&ctx, two_stage_method, two_stage_delta, 7.0, 0, &more, &sel, err, sizeof err) == RD_OK,
              "%s", err);
    cr_assert(sel.n == 3 && sel.kind[2] == RD_SEL_BEAMS, "%d estimators", sel.n);
    size_t mn = (size_t)sel.n * sel.tiles_x * sel.tiles_y;
    for (int k = 0; k < sel.tiles_x * sel.tiles_y; k++) {
        int col = k % sel.tiles_x;
        for (int h = 0; h < 2; h++) {
            const rd_select_stats *st = &sel.stats[h * mn + (size_t)sel.n * k];
            double want = col < 3 ? 64.0 : 16.0;
            cr_expect(st[2].n == want && st[0].n == 64.0 && st[1].n == 64.0,
                      "tile %d, half %d: %g beams samples (not %g), delta %g, the method %g", k, h, st[2].n, want, st[0].n, st[1].n);
            cr_expect(col > 0 || st[2].sum[0] == st[2].n, "tile %d, half %d: the beams' samples sum to %g, not %g", k, h,
                      st[2].sum[0], st[2].n);
        }
        int choice = col < 2 ? 2 : RD_SEL_DELTA;
        cr_expect(sel.choice[k] == choice && sel.trial[k] == 0, "tile %d: estimator %d (trial %d), not %d", k, sel.choice[k],
                  sel.trial[k], choice);
    }
    for (int p = 0; p < 32 * 24; p++) /* (the pilot's records are emptied for the image) */
        cr_expect(sel.pixels[p].n == 0.0 && sel.pixels[p].cost == 0.0, "pixel %d's record holds the pilot's samples", p);
    rd_select_free(&sel);
    rd_scene_free(s);
}
