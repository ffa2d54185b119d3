/* select_trace.c: the tile selection's trace (rd_render_opts.select_trace, `render
 * --select-trace`; docs/cli.md, "The selection's trace"): after the pilot and at every epoch
 * (select.c), one JSON line with every tile's choice and the figures it was made from, added to
 * the lines so far (a core rd_text) and the file written again whole (rd_write_atomic), so a
 * stopped render leaves the lines of the choices it made. bench/bench_select_score scores such
 * traces. */
#include "integrators/rd_select.h"
#include "core/rd_core.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rd_status rd_select_trace(rd_select *sel, long from, char *err, size_t errlen)
{
    if (!sel->trace_path) return RD_OK;
    static const char *const names[RD_SEL_MAX] = {"delta", "method", "delta_equiangular", "guided_path", "beams"};
    static const char *const keys[6] = {"samples", "mean", "variance", "cost", "gap", "bias2"};
    int nx = sel->tiles_x, ny = sel->tiles_y, n = nx * ny, m = sel->n;
    size_t mn = (size_t)m * n;
    rd_text *t = &sel->trace;
    rd_text_printf(t, "{\"from_sample\": %ld, \"tile\": %d, \"tiles_x\": %d, \"tiles_y\": %d, ", from, RD_SELECT_TILE, nx, ny);
    if (sel->kind[m - 1] == RD_SEL_BEAMS)
        rd_text_printf(t, "\"bias_ratio\": %.6g, \"bias_se\": %.6g, ", sel->bias_ratio, sel->bias_se);
    rd_text_printf(t, "\"estimators\": [");
    for (int e = 0; e < m; e++) rd_text_printf(t, "%s\"%s\"", e ? ", " : "", names[sel->kind[e]]);
    rd_text_printf(t, "], \"tiles\": [");
    for (int k = 0; k < n && !t->oom; k++) {
        double fig[6][RD_SEL_MAX]; /* samples, mean, variance, cost, the beams' gap and squared bias */
        for (int e = 0; e < m; e++) {
            const rd_select_stats *a = &sel->stats[(size_t)m * k + e], *b = &sel->stats[mn + (size_t)m * k + e];
            double N = a->n + b->n, dof = a->dof + b->dof, s = 0.0, d = 0.0;
            for (int ch = 0; ch < 3; ch++) s += a->sum[ch] + b->sum[ch], d += a->dev2[ch] + b->dev2[ch];
            fig[0][e] = N, fig[1][e] = N > 0.0 ? s / (3.0 * N) : 0.0, fig[2][e] = dof > 0.0 ? d / (3.0 * dof) : 0.0;
            fig[3][e] = N > 0.0 ? (a->cost + b->cost) / N : 0.0;
            fig[4][e] = N > 0.0 ? (a->gap + b->gap) / N : 0.0;
            double w = a->bias_n + b->bias_n; /* (the products' weights; they are at pass 1's radius) */
            fig[5][e] = w > 0.0 ? RD_SELECT_BIAS_PER_GAP2 * (a->bias2 + b->bias2) / w * sel->bias_r2 : 0.0;
        }
        rd_text_printf(t, "%s{\"choice\": %d, \"trial\": %d", k ? ", " : "", sel->choice[k], sel->trial[k]);
        for (int f = 0; f < 6; f++) {
            rd_text_printf(t, ", \"%s\": [", keys[f]);
            for (int e = 0; e < m; e++) { /* (float sums can overflow: JSON has no inf) */
                if (!isfinite(fig[f][e])) rd_text_printf(t, "%snull", e ? ", " : "");
                else rd_text_printf(t, f ? "%s%.6g" : "%s%.0f", e ? ", " : "", fig[f][e]);
            }
            rd_text_printf(t, "]");
        }
        rd_text_printf(t, "}");
    }
    rd_text_printf(t, "]}\n");
    if (t->oom) { /* (the caller stops tracing: the file keeps the lines written before) */
        snprintf(err, errlen, "%s: out of memory for the selection's trace", sel->trace_path);
        return RD_ERR_NOMEM;
    }
    return rd_write_atomic(sel->trace_path, t->s, t->n, err, errlen);
}
