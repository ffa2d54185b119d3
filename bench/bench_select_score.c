/* bench_select_score: how good a tile selection's choices were, with the images' noise taken
 * out (docs/benchmarks.md "Session 44").
 *
 *   bench_select_score --spp N --table NAME=V.exr [--table NAME=V.exr]... TRACE.jsonl...
 *
 * Each TRACE is the choices of one render, `render SCENE --spp N --select-trace TRACE.jsonl`
 * (docs/cli.md, "The selection's trace"), without shares (`--set settings.adaptive=false` for
 * `guided`, whose default takes them since session 70): the score reads every sample index of
 * every pixel as drawn. Each table is a long render of one of the selection's
 * estimators alone, NAME as the trace names it, rendered as the selection renders it, at the
 * traces' resolution. For `guided-unbiased`: `delta` is `render --method delta --set
 * settings.probes="auto"` (its delta tiles take guide.probes "auto"), `method` is `--method
 * guided-unbiased --set settings.select="off" --set guide.equiangular=false` (its own flights take
 * no equiangular strategy where the selection runs), `delta_equiangular` is `--method delta --set
 * settings.equiangular=true` (with the same probes); `settings.probes` as the scene's
 * guide.probes, and guide.equiangular false only where the scene leaves it unset. For `guided`,
 * whose delta tiles take no probes: `delta` is `--method delta --set settings.probes=1`, `method`
 * `--method guided --set settings.select="off"`, `delta_equiangular` `--method delta --set
 * settings.equiangular=true --set settings.probes=1`, and `guided_path` (march.guided_paths)
 * `--method guided-unbiased --set settings.select="off" --set guide.equiangular=false`; with march.beams, `beams` `--method
 * guided --set march.ls=nee+beams --set photons.progressive=true --set settings.select="off"`. For `delta` with settings.equiangular
 * "tiles": `delta` is `--set settings.equiangular=false --set settings.probes=1` and `method`
 * `--set settings.equiangular=true --set settings.probes=1`.
 * V-stderr.exr and V.json beside V.exr give each pixel's variance a sample, se^2 spp (mean over
 * RGB).
 *
 * A trace's score: each pixel's mean has variance sum_i n_i V_e(i)(pixel) / N^2, n_i the samples
 * the pixel drew under the trace's line i (from its from_sample to the next line's, or N) and
 * e(i) the estimator that line gave it (its tile's choice, or its square of a trial's
 * checkerboard); summed over the pixels, times the counted cost of all those samples (each
 * tile's cost a sample per estimator from the trace's last line; the pilot samples every
 * estimator in every tile, so each has one). Lower is better: its inverse is the efficiency at
 * equal time but for the selection's own overhead, which its choices do not move. The tables are
 * common to every trace scored, so two traces (two rules, or two seeds) differ only by their
 * choices. Printed: per trace the score, its two factors and the method's share of the samples;
 * then every tile on one estimator, one line per table, with the first trace's costs.
 * Then two figures that locate a rule's loss (docs/benchmarks.md "Session 52"): the best fixed
 * choice, the tiles chosen by the rule itself (rd_select_choose) on the tables' variances and the
 * first trace's costs and kept from the first sample to the last (the rule alone: none of the
 * selection's pooling, halves, trials or priors); and, per line of the first trace, each
 * estimator's variance in a tile as the trace gives it (the tile's own figure, which the
 * selection pools with its neighbours' before the rule reads it) over the table's mean over the
 * tile's pixels: the median over the tiles where both are known (the table's not 0, the trace's
 * not null) and the median of those tiles' samples. A heavy-tailed estimator's sample variance
 * reads low from a few hundred samples, and the rule then prefers it. (The pilot samples a
 * quarter of a tile's pixels, the table every pixel: where the variance sits in a few pixels,
 * part of a low reading at the pilot is that.)
 * Without a trace (as `make bench` runs every tool, with --json FILE and --quick, which it
 * ignores) it says so and exits 0. */
#include "renderer.h"
#include "integrators/rd_select.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { MAXE = 5, MAXLINES = 64 };
/* The estimators' names in a trace (select_trace.c; a trace lists those its selection has, in
 * its own order): the tables are named so. */
static const char *const names[MAXE] = {"delta", "method", "delta_equiangular", "guided_path", "beams"};

typedef struct {
    int w, h;
    double *v[MAXE]; /* per pixel, the estimator's variance a sample; NULL: no table */
} tables;

/* The whole text of a file (NUL-terminated, malloc'd), or NULL. */
static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    size_t cap = 1 << 16, n = 0;
    char *s = malloc(cap);
    for (size_t k; s && (k = fread(s + n, 1, cap - n - 1, f)) > 0;) {
        n += k;
        if (n + 1 == cap) {
            char *t = realloc(s, cap *= 2);
            if (!t) free(s);
            s = t;
        }
    }
    fclose(f);
    if (s) s[n] = '\0';
    return s;
}

/* Table NAME=V.exr into t; 0 after a message. */
static int load_table(const char *arg, tables *t)
{
    const char *eq = strchr(arg, '=');
    int e = -1;
    for (int i = 0; eq && i < MAXE; i++)
        if ((size_t)(eq - arg) == strlen(names[i]) && !strncmp(arg, names[i], (size_t)(eq - arg))) e = i;
    size_t len = eq ? strlen(eq + 1) : 0;
    if (e < 0 || len < 5 || strcmp(eq + 1 + len - 4, ".exr")) {
        fprintf(stderr, "bench_select_score: --table %s: must be delta=, method=, delta_equiangular=, guided_path= or beams= a .exr path\n", arg);
        return 0;
    }
    char se[4096], js[4096], err[RD_ERRLEN];
    snprintf(se, sizeof se, "%.*s-stderr.exr", (int)(len - 4), eq + 1);
    snprintf(js, sizeof js, "%.*s.json", (int)(len - 4), eq + 1);
    char *text = slurp(js);
    cJSON *j = text ? cJSON_Parse(text) : NULL;
    const cJSON *spp = j ? cJSON_GetObjectItem(j, "spp") : NULL;
    free(text);
    if (!cJSON_IsNumber(spp) || spp->valuedouble < 2) {
        fprintf(stderr, "bench_select_score: %s: no render report with spp >= 2\n", js);
        cJSON_Delete(j);
        return 0;
    }
    double n = spp->valuedouble;
    cJSON_Delete(j);
    rd_image img = {0};
    if (rd_image_read(se, &img, err, sizeof err) != RD_OK) {
        fprintf(stderr, "bench_select_score: %s\n", err);
        return 0;
    }
    if (t->w && (img.w != t->w || img.h != t->h)) {
        fprintf(stderr, "bench_select_score: %s: %dx%d, but the first table is %dx%d\n", se, img.w, img.h, t->w, t->h);
        rd_image_free_pixels(&img);
        return 0;
    }
    t->w = img.w, t->h = img.h;
    t->v[e] = malloc((size_t)img.w * img.h * sizeof *t->v[e]);
    for (size_t p = 0; t->v[e] && p < (size_t)img.w * img.h; p++) {
        const float *c = img.rgb + 3 * p;
        t->v[e][p] = ((double)c[0] * c[0] + (double)c[1] * c[1] + (double)c[2] * c[2]) / 3.0 * n;
    }
    rd_image_free_pixels(&img);
    return t->v[e] != NULL;
}

/* One trace's choices: per line, from_sample and each tile's choice and trial; the last line's
 * costs. */
typedef struct {
    int lines, tx, ty, m;
    int kind[MAXE]; /* estimator e's name: names[kind[e]] */
    long from[MAXLINES];
    int *choice[MAXLINES], *trial[MAXLINES];
    double *var[MAXLINES], *samples[MAXLINES]; /* [tile * MAXE + e]: the line's figures (var < 0: null) */
    double *cost; /* [tile * MAXE + e] */
} trace;

static void trace_free(trace *r)
{
    for (int i = 0; i < r->lines; i++) free(r->choice[i]), free(r->trial[i]), free(r->var[i]), free(r->samples[i]);
    free(r->cost);
}

/* Read TRACE into r; 0 after a message naming the file, the line and the field. */
static int load_trace(const char *path, trace *r)
{
    memset(r, 0, sizeof *r);
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "bench_select_score: %s: cannot open\n", path);
        return 0;
    }
    char *line = NULL;
    size_t cap = 0;
    int ok = 1;
    while (ok && getline(&line, &cap, f) > 0) {
        int i = r->lines;
        cJSON *j = cJSON_Parse(line);
        const cJSON *from = j ? cJSON_GetObjectItem(j, "from_sample") : NULL, *tiles = j ? cJSON_GetObjectItem(j, "tiles") : NULL;
        const cJSON *tx = j ? cJSON_GetObjectItem(j, "tiles_x") : NULL, *ty = j ? cJSON_GetObjectItem(j, "tiles_y") : NULL;
        const cJSON *est = j ? cJSON_GetObjectItem(j, "estimators") : NULL;
        if (i >= MAXLINES || !cJSON_IsNumber(from) || !cJSON_IsNumber(tx) || !cJSON_IsNumber(ty) || !cJSON_IsArray(est) ||
            cJSON_GetArraySize(est) > MAXE || !cJSON_IsArray(tiles) || cJSON_GetArraySize(tiles) != tx->valueint * ty->valueint) {
            fprintf(stderr, "bench_select_score: %s: line %d: not a trace line (from_sample, tiles_x, tiles_y, estimators, tiles)\n",
                    path, i + 1);
            ok = 0;
        } else if (i > 0 && (tx->valueint != r->tx || ty->valueint != r->ty || cJSON_GetArraySize(est) != r->m ||
                             (long)from->valuedouble <= r->from[i - 1])) {
            fprintf(stderr, "bench_select_score: %s: line %d: its tiles, estimators or from_sample do not follow line %d's\n", path,
                    i + 1, i);
            ok = 0;
        } else if (!cJSON_IsNumber(cJSON_GetObjectItem(j, "tile")) || cJSON_GetObjectItem(j, "tile")->valueint != 8) {
            fprintf(stderr, "bench_select_score: %s: line %d: tile: must be 8 (the selection's tiles)\n", path, i + 1);
            ok = 0;
        } else if (i == 0 && from->valuedouble != 0) {
            fprintf(stderr, "bench_select_score: %s: line 1: from_sample must be 0 (the pilot's choice)\n", path);
            ok = 0;
        } else {
            int n = tx->valueint * ty->valueint;
            r->tx = tx->valueint, r->ty = ty->valueint, r->m = cJSON_GetArraySize(est), r->from[i] = (long)from->valuedouble;
            for (int e = 0; e < r->m; e++) {
                const cJSON *name = cJSON_GetArrayItem(est, e);
                int kind = -1;
                for (int q = 0; cJSON_IsString(name) && q < MAXE; q++)
                    if (!strcmp(name->valuestring, names[q])) kind = q;
                if (kind < 0 || (i > 0 && kind != r->kind[e])) {
                    fprintf(stderr, "bench_select_score: %s: line %d: estimators[%d]: not one of delta, method, "
                                    "delta_equiangular, guided_path, beams, or not line 1's\n", path, i + 1, e);
                    ok = 0;
                } else {
                    r->kind[e] = kind;
                }
            }
            r->choice[i] = malloc((size_t)n * sizeof(int)), r->trial[i] = malloc((size_t)n * sizeof(int));
            r->var[i] = calloc((size_t)n * MAXE, sizeof(double)), r->samples[i] = calloc((size_t)n * MAXE, sizeof(double));
            free(r->cost);
            r->cost = calloc((size_t)n * MAXE, sizeof *r->cost);
            r->lines++;
            ok = ok && r->choice[i] && r->trial[i] && r->var[i] && r->samples[i] && r->cost;
            for (int k = 0; ok && k < n; k++) {
                const cJSON *t = cJSON_GetArrayItem(tiles, k), *c = cJSON_GetObjectItem(t, "cost");
                const cJSON *ch = cJSON_GetObjectItem(t, "choice"), *tr = cJSON_GetObjectItem(t, "trial");
                int costs = cJSON_IsArray(c) && cJSON_GetArraySize(c) == r->m;
                for (int e = 0; costs && e < r->m; e++) costs = cJSON_IsNumber(cJSON_GetArrayItem(c, e));
                if (!cJSON_IsNumber(ch) || !cJSON_IsNumber(tr) || !costs) {
                    fprintf(stderr, "bench_select_score: %s: line %d: tiles[%d]: needs choice, trial and a number of cost per estimator\n",
                            path, i + 1, k);
                    ok = 0;
                    break;
                }
                r->choice[i][k] = ch->valueint;
                r->trial[i][k] = tr->valueint;
                for (int e = 0; e < r->m && e < cJSON_GetArraySize(c); e++) r->cost[k * MAXE + e] = cJSON_GetArrayItem(c, e)->valuedouble;
                /* (the tile's own figures as traced: for the diagnostic only, so a missing one is null) */
                const cJSON *va = cJSON_GetObjectItem(t, "variance"), *sa = cJSON_GetObjectItem(t, "samples");
                for (int e = 0; e < r->m; e++) {
                    const cJSON *v = cJSON_IsArray(va) ? cJSON_GetArrayItem(va, e) : NULL;
                    const cJSON *q = cJSON_IsArray(sa) ? cJSON_GetArrayItem(sa, e) : NULL;
                    r->var[i][k * MAXE + e] = cJSON_IsNumber(v) ? v->valuedouble : -1.0;
                    r->samples[i][k * MAXE + e] = cJSON_IsNumber(q) ? q->valuedouble : 0.0;
                }
                if (r->choice[i][k] < 0 || r->choice[i][k] >= r->m || r->trial[i][k] < 0 || r->trial[i][k] > r->m) {
                    fprintf(stderr, "bench_select_score: %s: line %d: tiles[%d]: choice or trial out of range\n", path, i + 1, k);
                    ok = 0;
                }
            }
        }
        cJSON_Delete(j);
    }
    free(line);
    fclose(f);
    if (ok && !r->lines) fprintf(stderr, "bench_select_score: %s: no lines\n", path), ok = 0;
    if (!ok) trace_free(r);
    return ok;
}

/* The score of choices r (or, with r->lines 0, every tile on r's estimator fixed) against t, N
 * samples a pixel; *var, *cost: its two factors, *own: the method's share of the samples. 0
 * after a message when a choice has no table. */
static int score(const trace *r, int fixed, const tables *t, long N, double *var, double *cost, double *own)
{
    *var = *cost = *own = 0.0;
    int lines = r->lines ? r->lines : 1;
    for (int y = 0; y < t->h; y++)
        for (int x = 0; x < t->w; x++) {
            int k = (y / 8) * r->tx + x / 8;
            double v = 0.0;
            for (int i = 0; i < lines; i++) {
                long a = r->lines ? r->from[i] : 0, b = r->lines && i + 1 < r->lines ? r->from[i + 1] : N;
                if (b > N) b = N;
                if (b <= a) continue;
                int use = fixed;
                if (r->lines) {
                    int c = r->choice[i][k], tr = r->trial[i][k] - 1;
                    use = tr < 0 ? c : (x + y) & 1 ? (c > tr ? c : tr) : (c < tr ? c : tr); /* rd_select_uses */
                }
                const double *tab = t->v[r->kind[use]];
                if (!tab) {
                    fprintf(stderr, "bench_select_score: the choices use %s, which has no --table\n", names[r->kind[use]]);
                    return 0;
                }
                v += (double)(b - a) * tab[(size_t)y * t->w + x];
                *cost += (double)(b - a) * r->cost[k * MAXE + use];
                *own += use == 1 ? (double)(b - a) : 0.0;
            }
            *var += v / ((double)N * N);
        }
    *own /= (double)N * t->w * t->h;
    return 1;
}

/* Per tile k and estimator e, the sum over the tile's pixels of e's table (tv[k MAXE + e]) and the
 * tile's pixels (px[k]). */
static void tile_sums(const trace *r, const tables *t, double *tv, double *px)
{
    for (int k = 0; k < r->tx * r->ty; k++) {
        px[k] = 0.0;
        for (int e = 0; e < MAXE; e++) tv[k * MAXE + e] = 0.0;
    }
    for (int y = 0; y < t->h; y++)
        for (int x = 0; x < t->w; x++) {
            int k = (y / 8) * r->tx + x / 8;
            px[k] += 1.0;
            for (int e = 0; e < r->m; e++)
                if (t->v[r->kind[e]]) tv[k * MAXE + e] += t->v[r->kind[e]][(size_t)y * t->w + x];
        }
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The median of a[0 .. c-1] (c > 0), which it sorts. */
static double median(double *a, int c)
{
    qsort(a, (size_t)c, sizeof *a, cmp_double);
    return c % 2 ? a[c / 2] : 0.5 * (a[c / 2 - 1] + a[c / 2]);
}

/* The best fixed choice for trace r's costs (see the head), scored as a trace of one line. An
 * estimator without a table: says there is none and returns 1; 0 when out of memory. */
static int best_fixed(const trace *r, const tables *t, long N)
{
    int n = r->tx * r->ty, m = r->m;
    for (int e = 0; e < m; e++)
        if (!t->v[r->kind[e]]) {
            printf("best fixed choice: none (%s has no --table)\n", names[r->kind[e]]);
            return 1;
        }
    double *tv = malloc((size_t)n * MAXE * sizeof *tv), *px = malloc((size_t)n * sizeof *px);
    double *var = malloc((size_t)n * m * sizeof *var), *cost = malloc((size_t)n * m * sizeof *cost);
    uint8_t *ch = malloc((size_t)n);
    trace b = *r;
    b.lines = 1, b.from[0] = 0;
    b.choice[0] = malloc((size_t)n * sizeof(int)), b.trial[0] = calloc((size_t)n, sizeof(int));
    int ok = tv && px && var && cost && ch && b.choice[0] && b.trial[0];
    if (ok) {
        tile_sums(r, t, tv, px);
        for (int k = 0; k < n; k++)
            for (int e = 0; e < m; e++) var[m * k + e] = tv[k * MAXE + e], cost[m * k + e] = px[k] * r->cost[k * MAXE + e];
        rd_select_choose(var, cost, NULL, n, m, NULL, ch);
        int count[MAXE] = {0};
        for (int k = 0; k < n; k++) b.choice[0][k] = ch[k], count[ch[k]]++;
        double v, c, own;
        ok = score(&b, 0, t, N, &v, &c, &own);
        if (ok) {
            printf("best fixed choice: score %.4g (variance %.4g x cost %.4g), the method's share %.3f; tiles:", v * c, v, c, own);
            for (int e = 0; e < m; e++) printf(" %s %d", names[r->kind[e]], count[e]);
            printf("\n");
        }
    } else {
        fprintf(stderr, "bench_select_score: out of memory\n");
    }
    free(tv), free(px), free(var), free(cost), free(ch), free(b.choice[0]), free(b.trial[0]);
    return ok;
}

/* Per line of trace r, each estimator's variance as the line gives it over its table's (see the
 * head). */
static void read_over_table(const trace *r, const tables *t)
{
    int n = r->tx * r->ty;
    double *tv = malloc((size_t)n * MAXE * sizeof *tv), *px = malloc((size_t)n * sizeof *px);
    double *q = malloc((size_t)n * sizeof *q), *ns = malloc((size_t)n * sizeof *ns);
    if (!tv || !px || !q || !ns) {
        fprintf(stderr, "bench_select_score: out of memory (the variances read over the tables' left out)\n");
        free(tv), free(px), free(q), free(ns);
        return;
    }
    tile_sums(r, t, tv, px);
    printf("the first trace's variances over the tables' (median over the tiles; the median of their samples):\n");
    for (int i = 0; i < r->lines; i++) {
        printf("  from sample %ld:", r->from[i]);
        for (int e = 0; e < r->m; e++) {
            int c = 0;
            for (int k = 0; k < n; k++) {
                double tab = px[k] > 0.0 ? tv[k * MAXE + e] / px[k] : 0.0, v = r->var[i][k * MAXE + e];
                if (t->v[r->kind[e]] && tab > 0.0 && v >= 0.0 && r->samples[i][k * MAXE + e] > 1.0)
                    ns[c] = r->samples[i][k * MAXE + e], q[c++] = v / tab;
            }
            if (c)
                printf("  %s %.3f (%.0f)", names[r->kind[e]], median(q, c), median(ns, c));
            else
                printf("  %s -", names[r->kind[e]]);
        }
        printf("\n");
    }
    free(tv), free(px), free(q), free(ns);
}

int main(int argc, char **argv)
{
    int traces = 0;
    for (int i = 1; i < argc; i++) {
        if ((!strcmp(argv[i], "--spp") || !strcmp(argv[i], "--table") || !strcmp(argv[i], "--json")) && i + 1 < argc) i++;
        else traces += argv[i][0] != '-';
    }
    if (!traces) {
        printf("bench_select_score: scores tile-selection traces against variance tables (usage in its head, "
               "bench/bench_select_score.c); no trace given, nothing to do\n");
        return 0;
    }
    tables t = {0};
    long N = 0;
    int first = 0, status = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc) i++; /* (make bench's; nothing to write) */
        else if (!strcmp(argv[i], "--quick")) continue;
        else if (!strcmp(argv[i], "--spp") && i + 1 < argc) N = strtol(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--table") && i + 1 < argc) { if (!load_table(argv[++i], &t)) return 1; }
        else if (argv[i][0] == '-') { fprintf(stderr, "bench_select_score: %s: unknown option\n", argv[i]); return 1; }
        else if (!first) first = i;
    }
    if (N < 1 || !first || !t.w) {
        fprintf(stderr, "bench_select_score: needs --spp N (the traces' samples a pixel), a --table and a trace\n");
        return 1;
    }
    trace first_trace = {0};
    for (int i = first; i < argc; i++) {
        if (!strcmp(argv[i], "--spp") || !strcmp(argv[i], "--table") || !strcmp(argv[i], "--json")) { i++; continue; }
        if (!strcmp(argv[i], "--quick")) continue;
        trace r;
        if (!load_trace(argv[i], &r)) return 1;
        if (r.tx != (t.w + 7) / 8 || r.ty != (t.h + 7) / 8) {
            fprintf(stderr, "bench_select_score: %s: %dx%d tiles, but the tables are %dx%d pixels\n", argv[i], r.tx, r.ty, t.w, t.h);
            return 1;
        }
        double v, c, own;
        if (!score(&r, 0, &t, N, &v, &c, &own)) return 1;
        printf("%s: score %.4g (variance %.4g x cost %.4g), the method's share %.3f\n", argv[i], v * c, v, c, own);
        if (!first_trace.lines) first_trace = r;
        else trace_free(&r);
    }
    for (int e = 0; e < first_trace.m; e++) {
        if (!t.v[first_trace.kind[e]]) continue;
        trace fixed = first_trace;
        fixed.lines = 0;
        double v, c, own;
        if (!score(&fixed, e, &t, N, &v, &c, &own)) status = 1;
        else printf("every tile on %s: score %.4g (variance %.4g x cost %.4g)\n", names[first_trace.kind[e]], v * c, v, c);
    }
    if (!best_fixed(&first_trace, &t, N)) status = 1;
    read_over_table(&first_trace, &t);
    trace_free(&first_trace);
    for (int e = 0; e < MAXE; e++) free(t.v[e]);
    return status;
}
