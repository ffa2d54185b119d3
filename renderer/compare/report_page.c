/* report_page.c: the text of the comparison report's index.html (docs/compare.md), one
 * self-contained page (inline CSS and JS, images by relative path): the settings and the
 * reference, the metrics table (best RMSE and efficiency marked), the A/B/reference viewer,
 * the images side by side, the error maps, the worst-region crops and the convergence plot.
 * It only makes text; report.c writes it with the images it names. */
#include "compare/rd_compare.h"

#include <math.h>
#include <stddef.h>

static void sb_escape(rd_text *b, const char *s)
{
    for (; *s; s++) {
        switch (*s) {
        case '&': rd_text_printf(b, "&amp;"); break;
        case '<': rd_text_printf(b, "&lt;"); break;
        case '>': rd_text_printf(b, "&gt;"); break;
        case '"': rd_text_printf(b, "&quot;"); break;
        default: rd_text_printf(b, "%c", *s);
        }
    }
}

/* A table cell with a number in %.3g, or "n/a". */
static void sb_cell(rd_text *b, double v)
{
    if (isfinite(v)) rd_text_printf(b, "<td>%.3g</td>", v);
    else rd_text_printf(b, "<td class=na>n/a</td>");
}

static const char *page_css =
    "body{font:14px/1.4 system-ui,sans-serif;margin:1.5em auto;max-width:1200px;padding:0 1em;color:#222}\n"
    "h1{font-size:1.4em}h2{font-size:1.1em;margin-top:1.6em;border-bottom:1px solid #ddd}\n"
    ".warn{background:#fff3cd;border:1px solid #e0c060;padding:.5em .8em}\n"
    ".grid{display:flex;flex-wrap:wrap;gap:12px}.grid figure{margin:0}\n"
    ".grid img{display:block;max-width:360px;image-rendering:pixelated;min-width:192px}\n"
    "figcaption{font-size:12px;color:#444}\n"
    "#view{display:block;width:min(100%,720px);image-rendering:pixelated;cursor:pointer;border:1px solid #888}\n"
    "#viewer button{margin:0 .3em .5em 0;padding:.3em .7em}#viewer button.on{background:#333;color:#fff}\n"
    "table{border-collapse:collapse;font-variant-numeric:tabular-nums}\n"
    "td,th{border:1px solid #ccc;padding:.25em .5em;text-align:right}th{background:#f4f4f4}\n"
    "td:first-child{text-align:left}.na{color:#999}.best{font-weight:bold;background:#e8f5e9}\n"
    ".bar{display:flex;align-items:center;gap:.5em}.bar img{width:256px;height:16px}\n";

/* The page's script: the A/B/reference toggle (click or Space cycles, keys 1..N pick,
 * R the reference) and #selftest, which checks every image and the toggle and writes the
 * result into #selftest for headless Chromium (tests/compare_page.sh). */
static const char *page_js =
    "const views = JSON.parse(document.getElementById('views').textContent);\n"
    "const view = document.getElementById('view'), caption = document.getElementById('viewcap');\n"
    "const errors = [];\n"
    "window.addEventListener('error', e => errors.push(String(e.message)));\n"
    "let cur = 0;\n"
    "function show(i) {\n"
    "  cur = (i + views.length) % views.length;\n"
    "  view.src = views[cur].src;\n"
    "  caption.textContent = views[cur].label + ' (' + (cur + 1) + ' of ' + views.length + ')';\n"
    "  document.querySelectorAll('#viewer button').forEach((b, j) => b.classList.toggle('on', j === cur));\n"
    "}\n"
    "document.querySelectorAll('#viewer button').forEach((b, j) => b.addEventListener('click', () => show(j)));\n"
    "view.addEventListener('click', () => show(cur + 1));\n"
    "document.addEventListener('keydown', e => {\n"
    "  if (e.key === ' ') { e.preventDefault(); show(cur + 1); }\n"
    "  else if (e.key === 'r' || e.key === 'R') show(views.length - 1);\n"
    "  else if (e.key >= '1' && e.key <= '9' && +e.key <= views.length) show(+e.key - 1);\n"
    "});\n"
    "function selftest() {\n"
    "  const out = document.getElementById('selftest'), lines = [];\n"
    "  let ok = errors.length === 0;\n"
    "  errors.forEach(m => lines.push('script error: ' + m));\n"
    "  for (const img of document.images) {\n"
    "    const good = img.complete && img.naturalWidth > 0;\n"
    "    ok = ok && good;\n"
    "    lines.push((good ? 'loaded ' : 'NOT LOADED ') + img.getAttribute('src') + ' ' + img.naturalWidth + 'x' + img.naturalHeight);\n"
    "  }\n"
    "  const before = view.getAttribute('src');\n"
    "  view.addEventListener('load', () => {\n"
    "    const after = view.getAttribute('src');\n"
    "    const switched = after !== before && view.naturalWidth > 0;\n"
    "    ok = ok && switched;\n"
    "    lines.push('toggle ' + before + ' -> ' + after + (switched ? ' ok' : ' FAILED'));\n"
    "    out.textContent = (ok ? 'SELFTEST PASS' : 'SELFTEST FAIL') + '\\n' + lines.join('\\n');\n"
    "    out.hidden = false;\n"
    "  }, {once: true});\n"
    "  view.click();\n"
    "}\n"
    "show(0);\n"
    "window.addEventListener('load', () => { if (location.hash === '#selftest') selftest(); });\n";

/* The summary in words (summary.c): who won and by how much, and a sentence per row. */
static void page_summary(rd_text *b, const rd_comparison *c)
{
    const rd_cmp_summary *S = &c->sum;
    char line[1024];
    rd_cmp_verdict(S, line, sizeof line);
    rd_text_printf(b, "<section id=summary>\n");
    if (line[0]) {
        rd_text_printf(b, "<p><b>");
        sb_escape(b, line);
        rd_text_printf(b, "</b></p>\n");
    }
    rd_cmp_hidden_note(S, line, sizeof line);
    if (line[0]) {
        rd_text_printf(b, "<p id=hidden-light>");
        sb_escape(b, line);
        rd_text_printf(b, "</p>\n");
    }
    rd_text_printf(b, "<ul>\n");
    for (int i = 0; i < S->n_rows; i++) {
        rd_cmp_sentence(S, i, line, sizeof line);
        rd_text_printf(b, "<li>");
        sb_escape(b, line);
        rd_text_printf(b, "</li>\n");
    }
    rd_text_printf(b, "</ul>\n</section>\n");
}

static void page_head(rd_text *b, const rd_comparison *c, const rd_scene *s)
{
    const rd_cmp_opts *o = &c->opts;
    const rd_cmp_summary *S = &c->sum;
    rd_text_printf(b, "<!doctype html>\n<html lang=en><head><meta charset=utf-8><title>photonmarch compare: ");
    sb_escape(b, s->path);
    rd_text_printf(b, "</title>\n<style>\n%s</style></head><body>\n<h1>photonmarch compare: ", page_css);
    sb_escape(b, s->path);
    rd_text_printf(b, "</h1>\n");
    page_summary(b, c);
    rd_text_printf(b, "<p>%dx%d pixels; equal %s: %g %s per run; %d run%s per method (seeds %llu..%llu); "
                 "bake time charged to every run of a method that needs it.</p>\n",
              c->w, c->h, o->equal_spp ? "samples" : "time", o->budget, o->equal_spp ? "spp" : "s", o->runs,
              o->runs > 1 ? "s" : "", (unsigned long long)RUN_SEED(o->seed, 0), (unsigned long long)RUN_SEED(o->seed, o->runs - 1));
    if (c->sum.ranks > 1) {
        rd_text_printf(b, "<p>On %d ranks (", c->sum.ranks);
        sb_escape(b, c->sum.hosts);
        rd_text_printf(b, "): each run rendered whole by one rank, the reference by all together (docs/compare.md).</p>\n");
    }
    rd_text_printf(b, "<p>Reference: ");
    sb_escape(b, S->ref_source);
    if (S->ref_rendered) rd_text_printf(b, " (%s, %.6g spp, %.1f s%s%s)", S->ref_method, S->ref_spp, S->ref_seconds,
                                        S->ref_rendered == 2 ? ", from the cache" : "",
                                        S->ref_extended ? ", extended after the runs" : "");
    if (S->ref_auto)
        rd_text_printf(b, ", rendered until its variance is at most %.0f%% of the best method's MSE (at most %.0f s)",
                       100.0 * RD_CMP_REF_SHARE, S->ref_cap_seconds);
    if (isfinite(S->ref_var)) {
        rd_text_printf(b, "; its own variance (mean stderr&sup2;) %.3g", S->ref_var);
        if (isfinite(S->ref_share)) rd_text_printf(b, ", %.0f%% of the best MSE", 100.0 * S->ref_share);
        rd_text_printf(b, ".</p>\n");
    } else {
        rd_text_printf(b, "; its own standard error is unknown (no -stderr.exr beside it), so its noise is not accounted for.</p>\n");
    }
    if (S->ref_too_noisy)
        rd_text_printf(b, "<p class=warn><b>The reference is too noisy to rank the methods:</b> its variance (%.3g) is more than "
                     "%.0f%% of the best method's MSE: it makes up more than that share of the MSEs below and pulls their ratios toward 1. "
                     "Render it longer (--ref-time S) or pass a better one (--reference).</p>\n", S->ref_var,
                     100.0 * RD_CMP_REF_SHARE);
    if (S->cancelled) rd_text_printf(b, "<p class=warn>Interrupted: this report holds the runs that finished.</p>\n");
}

static void page_viewer(rd_text *b, const rd_comparison *c)
{
    const rd_cmp_summary *S = &c->sum;
    rd_text_printf(b, "<h2>A / B / reference</h2>\n<section id=viewer>\n<div>");
    for (int i = 0; i < S->n_rows; i++) rd_text_printf(b, "<button>%d %s</button>", i + 1, c->rows[i].label);
    rd_text_printf(b, "<button>R reference</button></div>\n");
    rd_text_printf(b, "<img id=view src=\"%s.png\" alt=\"the image being compared\">\n", S->n_rows ? c->rows[0].label : "reference");
    rd_text_printf(b, "<p><b id=viewcap></b> &mdash; click the image or press Space to go to the next one at the same "
                 "place; keys 1&ndash;%d pick a method, R the reference.</p>\n</section>\n", S->n_rows > 9 ? 9 : S->n_rows);
    rd_text_printf(b, "<script type=\"application/json\" id=views>[");
    for (int i = 0; i < S->n_rows; i++) rd_text_printf(b, "{\"label\":\"%s\",\"src\":\"%s.png\"},", c->rows[i].label, c->rows[i].label);
    rd_text_printf(b, "{\"label\":\"reference\",\"src\":\"reference.png\"}]</script>\n");
}

static void page_images(rd_text *b, const rd_comparison *c, double scale, crop_box bx)
{
    const rd_cmp_summary *S = &c->sum;
    rd_text_printf(b, "<h2>Side by side</h2>\n<div class=grid>\n");
    for (int i = 0; i < S->n_rows; i++)
        rd_text_printf(b, "<figure><img src=\"%s.png\" alt=\"%s\"><figcaption>%s: RMSE %.3g</figcaption></figure>\n",
                  c->rows[i].label, c->rows[i].label, c->rows[i].label, c->rows[i].err.rmse);
    rd_text_printf(b, "<figure><img src=\"reference.png\" alt=reference><figcaption>reference</figcaption></figure>\n</div>\n");
    rd_text_printf(b, "<h2>Error maps</h2>\n<p>Per-pixel relative error of luminance |L(x) &minus; L(ref)| / (L(ref) + 0.01), "
                 "one colour scale for every map.</p>\n<div class=bar><span>0</span><img src=colorbar.png alt=\"colour bar\">"
                 "<span>&ge; %.3g</span></div>\n<div class=grid>\n", scale);
    for (int i = 0; i < S->n_rows; i++)
        rd_text_printf(b, "<figure><img src=\"%s-error.png\" alt=\"%s error\"><figcaption>%s</figcaption></figure>\n",
                  c->rows[i].label, c->rows[i].label, c->rows[i].label);
    rd_text_printf(b, "</div>\n<h2>Worst region</h2>\n<p>The %dx%d pixel window at (%d, %d) with the largest squared error "
                 "summed over the methods, enlarged.</p>\n<div class=grid>\n", bx.s, bx.s, bx.x, bx.y);
    for (int i = 0; i < S->n_rows; i++)
        rd_text_printf(b, "<figure><img src=\"%s-crop.png\" alt=\"%s crop\"><figcaption>%s</figcaption></figure>\n",
                  c->rows[i].label, c->rows[i].label, c->rows[i].label);
    rd_text_printf(b, "<figure><img src=\"reference-crop.png\" alt=\"reference crop\"><figcaption>reference</figcaption></figure>\n</div>\n");
}

/* The index of the row with the smallest (dir = 1) or largest (dir = -1) value, or -1. */
static int best_row(const rd_comparison *c, size_t off, int dir)
{
    int best = -1;
    for (int i = 0; i < c->sum.n_rows; i++) {
        double v = *(const double *)((const char *)&c->rows[i] + off);
        if (!isfinite(v)) continue;
        double bv = best < 0 ? 0 : *(const double *)((const char *)&c->rows[best] + off);
        if (best < 0 || dir * v < dir * bv) best = i;
    }
    return c->sum.n_rows > 1 ? best : -1;
}

static void page_table(rd_text *b, const rd_comparison *c)
{
    int be = best_row(c, offsetof(rd_cmp_row, efficiency), -1), br = best_row(c, offsetof(rd_cmp_row, err.rmse), 1);
    rd_text_printf(b, "<h2>Metrics</h2>\n<table><tr><th>method</th><th>runs</th><th>time s</th><th>bake s</th><th>spp</th>"
                 "<th>RMSE</th><th>relMSE</th><th>MARE</th><th>bias&sup2;</th><th>variance</th><th>efficiency<br>1/(MSE&middot;t)</th>"
                 "<th>TTUV<br>t&middot;RMSE</th><th>collisions /px</th><th>lookups /px</th><th>shadow rays /px</th><th>homogeneity</th></tr>\n");
    for (int i = 0; i < c->sum.n_rows; i++) {
        const rd_cmp_row *r = &c->rows[i];
        rd_text_printf(b, "<tr><td>%s%s</td><td>%d</td>", r->label, r->is_extra ? " (added)" : "", r->runs);
        sb_cell(b, r->seconds), sb_cell(b, r->bake_seconds), sb_cell(b, r->spp);
        rd_text_printf(b, i == br ? "<td class=best>%.3g</td>" : "<td>%.3g</td>", r->err.rmse);
        sb_cell(b, r->err.relmse), sb_cell(b, r->err.mare), sb_cell(b, r->split.bias2), sb_cell(b, r->split.variance);
        if (i == be) rd_text_printf(b, "<td class=best>%.3g</td>", r->efficiency);
        else sb_cell(b, r->efficiency);
        sb_cell(b, r->ttuv), sb_cell(b, r->collisions_pp), sb_cell(b, r->lookups_pp), sb_cell(b, r->shadow_rays_pp);
        sb_cell(b, r->homogeneity);
        rd_text_printf(b, "</tr>\n");
    }
    rd_text_printf(b, "</table>\n<p>Errors against the reference over every pixel and channel, the mean over the runs. "
                 "bias&sup2; and variance (of one run) from the %d runs%s. Efficiency: higher is better; TTUV (seed 002): lower "
                 "is better. Homogeneity: 90th / 50th percentile of the per-pixel relative error over lit pixels (1 = even). "
                 "Definitions: docs/compare.md; numbers: <a href=metrics.json>metrics.json</a>.</p>\n",
              c->opts.runs, c->opts.runs < 2 ? " (one run: variance from its standard-error image)" : "");
}

void rd_cmp_page_text(rd_text *b, const rd_comparison *c, const rd_scene *s, double scale,
                      crop_box bx)
{
    page_head(b, c, s);
    page_table(b, c);
    page_viewer(b, c);
    page_images(b, c, scale, bx);
    rd_text_printf(b, "<h2>Convergence</h2>\n<p>RMSE against time during each run (log-log; drawn by gnuplot from "
                  "curve-*.dat).</p>\n<img src=convergence.svg alt=\"RMSE against time\" style=\"max-width:100%%\">\n");
    rd_text_printf(b, "<pre id=selftest hidden></pre>\n<script>\n%s</script>\n</body></html>\n", page_js);
}
