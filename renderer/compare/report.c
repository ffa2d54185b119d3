/* report.c: the report of a comparison (docs/compare.md), written from what runs.c keeps:
 * the report folder (every row's EXR and PNG, its false-colour error map and its crop of the
 * worst region; the reference's; the convergence plot drawn by gnuplot from curve-*.dat;
 * metrics.json; index.html, whose text report_page.c makes) and the metrics table on stdout.
 *
 * The error maps show the per-pixel relative error of luminance |L(x) - L(r)| / (L(r) + eps)
 * (THEORY.md §7) in viridis, on one scale for every map (the 99th percentile over all rows).
 * The worst region is the window with the largest squared error over every row, found with a
 * summed-area table. */
#include "compare/rd_compare.h"

#include <cJSON.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <sys/wait.h>
#include <unistd.h>
#include <stdlib.h>
#include <string.h>

/* ---- Images: error maps, crops ---------------------------------------------------------------- */

/* sRGB 8-bit colour -> the linear value rd_image_write_png (exposure 0) turns back into it. */
static float srgb_to_linear(double c)
{
    return (float)(c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
}

/* The viridis colour map (van der Walt & Smith, matplotlib), 9 stops, t in [0, 1]. */
static void viridis(double t, float rgb[3])
{
    static const unsigned char stop[9][3] = {{68, 1, 84},    {71, 44, 122},  {59, 81, 139},
                                             {44, 113, 142}, {33, 144, 141}, {39, 173, 129},
                                             {92, 200, 99},  {170, 220, 50}, {253, 231, 37}};
    t = fmin(fmax(t, 0.0), 1.0) * 8.0;
    int i = (int)fmin(t, 7.0);
    double f = t - i;
    for (int c = 0; c < 3; c++)
        rgb[c] = srgb_to_linear(((1 - f) * stop[i][c] + f * stop[i + 1][c]) / 255.0);
}

/* Per-pixel relative error of luminance, the quantity of the error maps and of homogeneity. */
static double pixel_rel_error(const rd_image *x, const rd_image *r, size_t p)
{
    double lr = luminance(r->rgb + 3 * p);
    return fabs(luminance(x->rgb + 3 * p) - lr) / (lr + RD_CMP_EPS);
}

/* The error maps' common scale: the 99th percentile of the relative error over every row, so
 * the maps can be compared with each other and a few fireflies do not set the scale. */
static double error_scale(const rd_comparison *c)
{
    size_t np = (size_t)c->w * c->h, n = np * (size_t)c->sum.n_rows;
    double *e = malloc((n + 1) * sizeof *e);
    if (!e || !n) { free(e); return 1.0; }
    for (int i = 0; i < c->sum.n_rows; i++)
        for (size_t p = 0; p < np; p++) e[i * np + p] = pixel_rel_error(c->row_img[i], &c->ref, p);
    qsort(e, n, sizeof *e, cmp_double);
    double s = e[(size_t)(0.99 * (n - 1))];
    free(e);
    return s > 0 ? s : 1.0;
}

/* The worst region: the square window (a quarter of the shorter side, at least 8 px) with the
 * largest squared error summed over every row, found with a summed-area table. */
static crop_box worst_region(const rd_comparison *c)
{
    int w = c->w, h = c->h, shorter = w < h ? w : h, s = shorter / 4;
    if (s < 8) s = shorter < 8 ? shorter : 8;
    crop_box best = {0, 0, s};
    double *sat = calloc((size_t)(w + 1) * (h + 1), sizeof *sat);
    if (!sat) return best;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double e = 0.0;
            size_t p = (size_t)y * w + x;
            for (int i = 0; i < c->sum.n_rows; i++)
                for (int ch = 0; ch < 3; ch++) {
                    double d = c->row_img[i]->rgb[3 * p + ch] - c->ref.rgb[3 * p + ch];
                    e += d * d;
                }
            sat[(size_t)(y + 1) * (w + 1) + x + 1] = e + sat[(size_t)y * (w + 1) + x + 1] +
                                                      sat[(size_t)(y + 1) * (w + 1) + x] - sat[(size_t)y * (w + 1) + x];
        }
    double top = -1.0;
    for (int y = 0; y + s <= h; y++)
        for (int x = 0; x + s <= w; x++) {
            double v = sat[(size_t)(y + s) * (w + 1) + x + s] - sat[(size_t)y * (w + 1) + x + s] -
                       sat[(size_t)(y + s) * (w + 1) + x] + sat[(size_t)y * (w + 1) + x];
            if (v > top) top = v, best.x = x, best.y = y;
        }
    free(sat);
    return best;
}

static rd_status write_png_at(const char *dir, const char *name, const rd_image *im, double exposure,
                              char *err, size_t errlen)
{
    char path[1200];
    snprintf(path, sizeof path, "%.1000s/%s", dir, name);
    return rd_image_write_png(path, im, exposure, err, errlen);
}

static rd_status write_exr_at(const char *dir, const char *name, const rd_image *im, char *err,
                              size_t errlen)
{
    char path[1200];
    snprintf(path, sizeof path, "%.1000s/%s", dir, name);
    return rd_image_write_exr(path, im, err, errlen);
}

/* The false-colour error map of x: viridis(relative error / scale). */
static rd_status write_error_map(const rd_comparison *c, const rd_image *x, const char *dir,
                                 const char *name, double scale, char *err, size_t errlen)
{
    size_t np = (size_t)c->w * c->h;
    rd_image m = {c->w, c->h, malloc(np * 3 * sizeof(float)), 0};
    if (!m.rgb) return fail(err, errlen, RD_ERR_NOMEM, "%s: out of memory", name);
    for (size_t p = 0; p < np; p++) viridis(pixel_rel_error(x, &c->ref, p) / scale, m.rgb + 3 * p);
    rd_status st = write_png_at(dir, name, &m, 0.0, err, errlen);
    free(m.rgb);
    return st;
}

static rd_status write_colour_bar(const char *dir, char *err, size_t errlen)
{
    rd_image m = {256, 16, malloc(256 * 16 * 3 * sizeof(float)), 0};
    if (!m.rgb) return fail(err, errlen, RD_ERR_NOMEM, "%s: out of memory", "colorbar.png");
    for (int y = 0; y < 16; y++)
        for (int x = 0; x < 256; x++) viridis(x / 255.0, m.rgb + 3 * (y * 256 + x));
    rd_status st = write_png_at(dir, "colorbar.png", &m, 0.0, err, errlen);
    free(m.rgb);
    return st;
}

/* The crop box of x, enlarged by nearest neighbour to about 256 px. */
static rd_status write_crop(const rd_comparison *c, const rd_image *x, crop_box b, const char *dir,
                            const char *name, char *err, size_t errlen)
{
    int z = b.s >= 256 ? 1 : 256 / b.s, n = b.s * z;
    rd_image m = {n, n, malloc((size_t)n * n * 3 * sizeof(float)), 0};
    if (!m.rgb) return fail(err, errlen, RD_ERR_NOMEM, "%s: out of memory", name);
    for (int y = 0; y < n; y++)
        for (int xx = 0; xx < n; xx++) {
            size_t src = (size_t)(b.y + y / z) * c->w + b.x + xx / z;
            memcpy(m.rgb + 3 * ((size_t)y * n + xx), x->rgb + 3 * src, 3 * sizeof(float));
        }
    rd_status st = write_png_at(dir, name, &m, c->exposure, err, errlen);
    free(m.rgb);
    return st;
}

/* Every image of the report: per row LABEL.exr/.png, LABEL-error.png, LABEL-crop.png; the
 * reference's reference.exr/.png/-crop.png (and reference-stderr.exr), colorbar.png. */
static rd_status write_images(const rd_comparison *c, const char *dir, double scale, crop_box b,
                              char *err, size_t errlen)
{
    rd_status st;
    char name[128];
    if ((st = write_exr_at(dir, "reference.exr", &c->ref, err, errlen)) ||
        (st = write_png_at(dir, "reference.png", &c->ref, c->exposure, err, errlen)) ||
        (st = write_crop(c, &c->ref, b, dir, "reference-crop.png", err, errlen)) ||
        (st = write_colour_bar(dir, err, errlen)))
        return st;
    if (c->ref_se.rgb && (st = write_exr_at(dir, "reference-stderr.exr", &c->ref_se, err, errlen))) return st;
    for (int i = 0; i < c->sum.n_rows; i++) {
        const char *l = c->rows[i].label;
        const rd_image *x = c->row_img[i];
        snprintf(name, sizeof name, rd_cmp_row_file[ROW_EXR], l);
        if ((st = write_exr_at(dir, name, x, err, errlen))) return st;
        snprintf(name, sizeof name, rd_cmp_row_file[ROW_PNG], l);
        if ((st = write_png_at(dir, name, x, c->exposure, err, errlen))) return st;
        snprintf(name, sizeof name, rd_cmp_row_file[ROW_ERROR], l);
        if ((st = write_error_map(c, x, dir, name, scale, err, errlen))) return st;
        snprintf(name, sizeof name, rd_cmp_row_file[ROW_CROP], l);
        if ((st = write_crop(c, x, b, dir, name, err, errlen))) return st;
    }
    return RD_OK;
}

/* ---- Convergence plot: gnuplot ------------------------------------------------------------ */

static rd_status write_text_at(const char *dir, const char *name, const char *text, char *err,
                               size_t errlen)
{
    char path[1200];
    snprintf(path, sizeof path, "%.1000s/%s", dir, name);
    return rd_write_atomic(path, text, strlen(text), err, errlen);
}

/* DIR/NAME from a text buffer (rd_text_write: atomic, frees the buffer). */
static rd_status write_buffer_at(const char *dir, const char *name, rd_text *b, char *err,
                                 size_t errlen)
{
    char path[1200];
    snprintf(path, sizeof path, "%.1000s/%s", dir, name);
    return rd_text_write(b, path, err, errlen);
}

/* curve-LABEL.dat: "seconds rmse" after every pass, one block per run (a blank line between
 * runs breaks the line in gnuplot); an added image with a time is one point. */
static rd_status write_curves(const rd_comparison *c, const char *dir, char *err, size_t errlen)
{
    for (int i = 0; i < c->sum.n_rows; i++) {
        const rd_cmp_row *r = &c->rows[i];
        rd_text b = {0};
        rd_text_printf(&b, "# seconds (bake included)  RMSE against the reference\n");
        if (r->is_extra) {
            if (r->seconds > 0) rd_text_printf(&b, "%.6g %.6g\n", r->seconds, r->err.rmse);
        } else {
            const cmp_method *m = NULL;
            for (int j = 0; j < c->n_methods; j++)
                if (!strcmp(c->m[j].name, r->label)) m = &c->m[j];
            for (int k = 0; m && k < m->done; k++) {
                for (int p = 0; p < m->n_curve[k]; p++)
                    if (m->curve[k][p].rmse > 0) rd_text_printf(&b, "%.6g %.6g\n", m->curve[k][p].seconds, m->curve[k][p].rmse);
                rd_text_printf(&b, "\n");
            }
        }
        char name[128];
        snprintf(name, sizeof name, rd_cmp_row_file[ROW_CURVE], r->label);
        rd_status st = write_buffer_at(dir, name, &b, err, errlen);
        if (st) return st;
    }
    return RD_OK;
}

/* Run gnuplot on convergence.gp in the report folder (no shell: fork, chdir, exec). */
static rd_status run_gnuplot(const char *dir, char *err, size_t errlen)
{
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) return fail(err, errlen, RD_ERR_OUTPUT, "%s/convergence.svg: cannot start gnuplot", dir);
    if (pid == 0) {
        int nul = open("/dev/null", O_WRONLY);
        if (nul >= 0) dup2(nul, 1);
        if (chdir(dir) == 0) execlp("gnuplot", "gnuplot", "convergence.gp", (char *)NULL);
        _exit(127);
    }
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {}
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
        return fail(err, errlen, RD_ERR_OUTPUT,
                    "%s/convergence.svg: gnuplot failed (exit 127: not installed; run scripts/install-deps.sh)", dir);
    return RD_OK;
}

static rd_status write_plot(const rd_comparison *c, const char *dir, char *err, size_t errlen)
{
    rd_status st = write_curves(c, dir, err, errlen);
    if (st) return st;
    rd_text b = {0};
    rd_text_printf(&b, "# RMSE against time, log-log (photonmarch compare; docs/compare.md)\n"
                  "set terminal svg size 720,440 dynamic font 'sans,12' background '#ffffff'\n"
                  "set output 'convergence.svg'\nset logscale xy\nset grid\nset key outside right\n"
                  "set xlabel 'time (s, bake included)'\nset ylabel 'RMSE'\n"
                  "set title 'RMSE against the reference after every pass (each run one line)'\nplot ");
    int plotted = 0;
    for (int i = 0; i < c->sum.n_rows; i++) {
        const rd_cmp_row *r = &c->rows[i];
        if (r->is_extra && !(r->seconds > 0)) continue;
        rd_text_printf(&b, "%s'curve-%s.dat' using 1:2 with %s lw 2 pt 7 title '%s'", plotted ? ", \\\n     " : "",
                  r->label, r->is_extra ? "points ps 1.5" : "linespoints", r->label);
        plotted++;
    }
    if (!plotted) rd_text_printf(&b, "NaN notitle");
    rd_text_printf(&b, "\n");
    st = write_buffer_at(dir, "convergence.gp", &b, err, errlen);
    return st ? st : run_gnuplot(dir, err, errlen);
}

/* ---- metrics.json (schema: docs/compare.md) ----------------------------------------------- */

/* A number, or null when it is NaN or infinite (JSON has no NaN). */
static void json_num(cJSON *o, const char *key, double v)
{
    if (isfinite(v)) cJSON_AddNumberToObject(o, key, v);
    else cJSON_AddNullToObject(o, key);
}

static const cmp_method *method_of(const rd_comparison *c, const char *label)
{
    for (int j = 0; j < c->n_methods; j++)
        if (!strcmp(c->m[j].name, label)) return &c->m[j];
    return NULL;
}

static cJSON *json_row(const rd_comparison *c, const rd_cmp_row *r, int i)
{
    cJSON *o = cJSON_CreateObject();
    char name[128];
    cJSON_AddStringToObject(o, "label", r->label);
    cJSON_AddStringToObject(o, "kind", r->is_extra ? "added" : "method");
    cJSON_AddNumberToObject(o, "runs", r->runs);
    json_num(o, "seconds", r->seconds);
    json_num(o, "bake_seconds", r->bake_seconds);
    json_num(o, "spp", r->spp);
    json_num(o, "mse", r->err.mse);
    json_num(o, "rmse", r->err.rmse);
    json_num(o, "relmse", r->err.relmse);
    json_num(o, "mare", r->err.mare);
    json_num(o, "bias2", r->split.bias2);
    json_num(o, "bias2_se", r->split.bias2_se);
    json_num(o, "variance", r->split.variance);
    if (r->is_extra) cJSON_AddNullToObject(o, "variance_from");
    else cJSON_AddStringToObject(o, "variance_from", r->split_from_runs ? "runs" : "stderr image");
    json_num(o, "efficiency", r->efficiency);
    json_num(o, "ttuv", r->ttuv);
    cJSON *pp = cJSON_AddObjectToObject(o, "per_pixel");
    json_num(pp, "samples", r->spp);
    json_num(pp, "collisions", r->collisions_pp);
    json_num(pp, "lookups", r->lookups_pp);
    json_num(pp, "shadow_rays", r->shadow_rays_pp);
    json_num(o, "homogeneity", r->homogeneity);
    /* The summary's numbers (summary.c): efficiency over the baseline's, share of bias. */
    int b = rd_cmp_baseline(&c->sum);
    json_num(o, "efficiency_vs_baseline", b >= 0 ? r->efficiency / c->rows[b].efficiency : NAN);
    json_num(o, "bias_share", rd_cmp_bias_share(r));
    json_num(o, "seconds_per_sample", rd_cmp_time_per_sample(r));
    json_num(o, "variance_per_sample", rd_cmp_variance_per_sample(r));
    char line[512];
    rd_cmp_sentence(&c->sum, i, line, sizeof line);
    cJSON_AddStringToObject(o, "summary", line);
    cJSON *im = cJSON_AddObjectToObject(o, "images");
    static const char *const kinds[] = {"exr", "png", "error", "crop"}; /* ROW_EXR .. ROW_CROP */
    for (int k = 0; k < 4; k++) {
        snprintf(name, sizeof name, rd_cmp_row_file[k], r->label);
        cJSON_AddStringToObject(im, kinds[k], name);
    }
    cJSON *curve = cJSON_AddArrayToObject(o, "curve");
    const cmp_method *m = r->is_extra ? NULL : method_of(c, r->label);
    for (int k = 0; m && k < m->done; k++) {
        cJSON *run = cJSON_CreateArray();
        for (int p = 0; p < m->n_curve[k]; p++) {
            const double v[3] = {m->curve[k][p].seconds, m->curve[k][p].spp_mean, m->curve[k][p].rmse};
            cJSON_AddItemToArray(run, cJSON_CreateDoubleArray(v, 3));
        }
        cJSON_AddItemToArray(curve, run);
    }
    return o;
}

static rd_status write_json(const rd_comparison *c, const rd_scene *s, const char *dir, double scale,
                            crop_box b, char *err, size_t errlen)
{
    const rd_cmp_opts *o = &c->opts;
    const rd_cmp_summary *S = &c->sum;
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "schema", "photonmarch-compare/1");
    cJSON_AddStringToObject(j, "scene", s->path);
    cJSON_AddNumberToObject(j, "width", c->w);
    cJSON_AddNumberToObject(j, "height", c->h);
    cJSON_AddStringToObject(j, "equal", o->equal_spp ? "spp" : "time");
    cJSON_AddNumberToObject(j, "budget", o->budget);
    cJSON_AddNumberToObject(j, "runs", o->runs);
    cJSON_AddNumberToObject(j, "seed", (double)o->seed);
    cJSON_AddBoolToObject(j, "cancelled", S->cancelled);
    cJSON_AddNumberToObject(j, "ranks", S->ranks); /* several ranks: docs/compare.md */
    cJSON_AddStringToObject(j, "hosts", S->hosts);
    cJSON *ref = cJSON_AddObjectToObject(j, "reference");
    cJSON_AddStringToObject(ref, "source", S->ref_source);
    cJSON_AddStringToObject(ref, "origin", S->ref_rendered == 1 ? "rendered" : S->ref_rendered == 2 ? "cache" : "given");
    cJSON_AddStringToObject(ref, "method", S->ref_method);
    /* the share of the media's light on L S+ paths (docs/compare.md, "Light only photons find") */
    cJSON_AddNumberToObject(ref, "hidden_light_share", S->hidden_share);
    json_num(ref, "spp", S->ref_rendered ? S->ref_spp : NAN);
    json_num(ref, "seconds", S->ref_rendered ? S->ref_seconds : NAN);
    json_num(ref, "variance", S->ref_var);
    cJSON_AddBoolToObject(ref, "too_noisy", S->ref_too_noisy);
    /* How the reference was decided (docs/compare.md): "rule" (the default: until its variance
     * is at most variance_limit of the best MSE, within cap_seconds), "budget" (the photon
     * reference: 10x a run's budget), "spp", "time", "spp+time" (--ref-spp / --ref-time) or
     * "given". */
    cJSON_AddStringToObject(ref, "decided_by", !S->ref_rendered ? "given" : S->ref_auto ? "rule"
                                               : o->ref_spp <= 0 && o->ref_time <= 0 ? "budget"
                                               : o->ref_spp > 0 && o->ref_time > 0 ? "spp+time"
                                               : o->ref_spp > 0 ? "spp" : "time");
    json_num(ref, "variance_share", S->ref_share);
    cJSON_AddNumberToObject(ref, "variance_limit", RD_CMP_REF_SHARE);
    cJSON_AddNumberToObject(ref, "extended", S->ref_extended);
    json_num(ref, "cap_seconds", S->ref_auto ? S->ref_cap_seconds : NAN);
    cJSON_AddBoolToObject(ref, "capped", S->ref_capped);
    cJSON *em = cJSON_AddObjectToObject(j, "error_map");
    cJSON_AddStringToObject(em, "quantity", "|L(x) - L(r)| / (L(r) + 0.01), L = luminance");
    cJSON_AddNumberToObject(em, "scale_max", scale);
    cJSON *cr = cJSON_AddObjectToObject(j, "crop");
    cJSON_AddNumberToObject(cr, "x", b.x);
    cJSON_AddNumberToObject(cr, "y", b.y);
    cJSON_AddNumberToObject(cr, "size", b.s);
    cJSON *rows = cJSON_AddArrayToObject(j, "methods");
    for (int i = 0; i < S->n_rows; i++) cJSON_AddItemToArray(rows, json_row(c, &c->rows[i], i));
    cJSON *sm = cJSON_AddObjectToObject(j, "summary");
    int base = rd_cmp_baseline(S), w = rd_cmp_winner(S);
    if (base >= 0) cJSON_AddStringToObject(sm, "baseline", c->rows[base].label);
    else cJSON_AddNullToObject(sm, "baseline");
    if (w >= 0) cJSON_AddStringToObject(sm, "winner", c->rows[w].label);
    else cJSON_AddNullToObject(sm, "winner");
    char line[1024];
    rd_cmp_verdict(S, line, sizeof line);
    cJSON_AddStringToObject(sm, "verdict", line);
    rd_cmp_hidden_note(S, line, sizeof line); /* "" unless light only photons find */
    cJSON_AddStringToObject(sm, "note", line);
    cJSON *lines = cJSON_AddArrayToObject(sm, "lines");
    for (int i = 0; i < S->n_rows; i++) {
        rd_cmp_sentence(S, i, line, sizeof line);
        cJSON_AddItemToArray(lines, cJSON_CreateString(line));
    }
    char *text = cJSON_Print(j);
    cJSON_Delete(j);
    if (!text) return fail(err, errlen, RD_ERR_NOMEM, "%s: out of memory", "metrics.json");
    rd_status st = write_text_at(dir, "metrics.json", text, err, errlen);
    cJSON_free(text);
    return st;
}

/* ---- The report folder --------------------------------------------------------------------- */

rd_status rd_compare_write_report(const rd_comparison *c, const rd_scene *scene, const char *dir,
                                  char *err, size_t errlen)
{
    char dummy[8], probe[1200];
    if (!err) { err = dummy; errlen = sizeof dummy; }
    if (!c->ref.rgb) return fail(err, errlen, RD_ERR_ARG, "%s: no reference, nothing to report", dir);
    snprintf(probe, sizeof probe, "%.1000s/index.html", dir);
    rd_status st = rd_make_parent_dirs(probe, err, errlen);
    if (st) return st;
    double scale = error_scale(c);
    crop_box bx = worst_region(c);
    if ((st = write_images(c, dir, scale, bx, err, errlen)) || (st = write_plot(c, dir, err, errlen)) ||
        (st = write_json(c, scene, dir, scale, bx, err, errlen)))
        return st;
    rd_text page = {0};
    rd_cmp_page_text(&page, c, scene, scale, bx);
    return write_buffer_at(dir, "index.html", &page, err, errlen);
}

/* ---- The summary table on stdout ----------------------------------------------------------- */

static void put_num(FILE *out, double v)
{
    if (isfinite(v)) fprintf(out, " %10.4g", v);
    else fprintf(out, " %10s", "n/a");
}

void rd_compare_print_table(const rd_comparison *c, FILE *out)
{
    fprintf(out, "%-16s %4s %10s %10s %10s %10s %10s %10s %10s %10s %10s\n", "method", "runs", "time_s", "spp", "RMSE",
            "relMSE", "MARE", "bias^2", "variance", "efficiency", "TTUV");
    for (int i = 0; i < c->sum.n_rows; i++) {
        const rd_cmp_row *r = &c->rows[i];
        fprintf(out, "%-16.16s %4d", r->label, r->runs);
        const double v[9] = {r->seconds, r->spp, r->err.rmse, r->err.relmse, r->err.mare, r->split.bias2,
                             r->split.variance, r->efficiency, r->ttuv};
        for (int k = 0; k < 9; k++) put_num(out, v[k]);
        fputc('\n', out);
    }
    const rd_cmp_summary *S = &c->sum;
    fprintf(out, "reference: %s", S->ref_source);
    if (S->ref_rendered) fprintf(out, " (%s, %.6g spp, %.1f s%s)", S->ref_method, S->ref_spp, S->ref_seconds,
                                 S->ref_extended ? ", extended after the runs" : "");
    if (isfinite(S->ref_var)) fprintf(out, "; variance %.3g", S->ref_var);
    if (isfinite(S->ref_share)) fprintf(out, " = %.0f%% of the best MSE", 100.0 * S->ref_share);
    fprintf(out, "%s\n", S->ref_too_noisy ? "; TOO NOISY to rank the methods (see the report)" : "");
    if (S->ranks > 1) fprintf(out, "ranks: %d (%s): each run on one, the reference on all\n", S->ranks, S->hosts);
    /* The summary in words (summary.c). */
    char line[1024];
    rd_cmp_verdict(S, line, sizeof line);
    if (line[0]) fprintf(out, "%s\n", line);
    rd_cmp_hidden_note(S, line, sizeof line);
    if (line[0]) fprintf(out, "%s\n", line);
    for (int i = 0; i < S->n_rows; i++) {
        rd_cmp_sentence(S, i, line, sizeof line);
        fprintf(out, "  %s\n", line);
    }
}
