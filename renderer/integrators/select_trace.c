/* select_trace.c: the tile selection's trace (rd_render_opts.select_trace, `render
 * --select-trace`; docs/cli.md, "The selection's trace"): after the pilot and at every epoch
 * (select.c), one JSON line with every tile's choice and the figures it was made from, appended
 * to the lines so far and the file written again whole (rd_write_atomic), so a stopped render
 * leaves the lines of the choices it made. bench/bench_select_score scores such traces. */
#include "integrators/rd_select.h"
#include "core/rd_core.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Append printf-style text to the trace (sel->trace); 0 when out of memory. */
static int trace_add(rd_select *sel, const char *fmt, ...)
{
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        size_t room = sel->trace_cap - sel->trace_len;
        int k = vsnprintf(sel->trace ? sel->trace + sel->trace_len : NULL, sel->trace ? room : 0, fmt, ap);
        va_end(ap);
        if (k < 0) return 0;
        if (sel->trace && (size_t)k < room) {
            sel->trace_len += (size_t)k;
            return 1;
        }
        size_t cap = sel->trace_cap ? 2 * sel->trace_cap : 65536;
        while (cap - sel->trace_len <= (size_t)k) cap *= 2;
        char *t = realloc(sel->trace, cap);
        if (!t) return 0;
        sel->trace = t, sel->trace_cap = cap;
    }
}

rd_status rd_select_trace(rd_select *sel, long from, char *err, size_t errlen)
{
    if (!sel->trace_path) return RD_OK;
    static const char *const names[RD_SEL_MAX] = {"delta", "method", "delta_equiangular"};
    int nx = sel->tiles_x, ny = sel->tiles_y, n = nx * ny, m = sel->n;
    size_t mn = (size_t)m * n, start = sel->trace_len; /* (a line cut short is taken back) */
    int ok = trace_add(sel, "{\"from_sample\": %ld, \"tile\": %d, \"tiles_x\": %d, \"tiles_y\": %d, \"estimators\": [", from,
                       RD_SELECT_TILE, nx, ny);
    for (int e = 0; e < m; e++) ok = ok && trace_add(sel, "%s\"%s\"", e ? ", " : "", names[e]);
    ok = ok && trace_add(sel, "], \"tiles\": [");
    for (int k = 0; ok && k < n; k++) {
        double fig[4][RD_SEL_MAX]; /* samples, mean, variance, cost */
        for (int e = 0; e < m; e++) {
            const rd_select_stats *a = &sel->stats[(size_t)m * k + e], *b = &sel->stats[mn + (size_t)m * k + e];
            double N = a->n + b->n, dof = a->dof + b->dof, s = 0.0, d = 0.0;
            for (int ch = 0; ch < 3; ch++) s += a->sum[ch] + b->sum[ch], d += a->dev2[ch] + b->dev2[ch];
            fig[0][e] = N, fig[1][e] = N > 0.0 ? s / (3.0 * N) : 0.0, fig[2][e] = dof > 0.0 ? d / (3.0 * dof) : 0.0;
            fig[3][e] = N > 0.0 ? (a->cost + b->cost) / N : 0.0;
        }
        static const char *const keys[4] = {"samples", "mean", "variance", "cost"};
        ok = trace_add(sel, "%s{\"choice\": %d, \"trial\": %d", k ? ", " : "", sel->choice[k], sel->trial[k]);
        for (int f = 0; ok && f < 4; f++) {
            ok = trace_add(sel, ", \"%s\": [", keys[f]);
            for (int e = 0; ok && e < m; e++) /* (float sums can overflow: JSON has no inf) */
                ok = isfinite(fig[f][e]) ? trace_add(sel, f ? "%s%.6g" : "%s%.0f", e ? ", " : "", fig[f][e])
                                         : trace_add(sel, "%snull", e ? ", " : "");
            ok = ok && trace_add(sel, "]");
        }
        ok = ok && trace_add(sel, "}");
    }
    ok = ok && trace_add(sel, "]}\n");
    if (!ok) {
        sel->trace_len = start;
        snprintf(err, errlen, "%s: out of memory for the selection's trace", sel->trace_path);
        return RD_ERR_NOMEM;
    }
    return rd_write_atomic(sel->trace_path, sel->trace, sel->trace_len, err, errlen);
}
