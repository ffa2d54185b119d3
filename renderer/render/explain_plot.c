/* explain_plot.c: the files of `photonmarch explain` (renderer.h rd_explain_write): the dense
 * table as CSV, the scalars and sample positions as JSON (cJSON), and a gnuplot script that
 * draws the picture; gnuplot itself is run by rd_explain_plot. */
#include "core/rd_core.h"
#include "scene/rd_scene.h"

#include <cJSON.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

static rd_status write_csv(const rd_explain_result *e, const char *path, char *err, size_t errlen)
{
    rd_text b = {0};
    /* p_ideal = f / I: the zero-variance placement, on the same axis as the pdfs. */
    rd_text_printf(&b, "t,T,f,p_ideal,p_guided,p_transmittance,p_uniform\n");
    for (int i = 0; i < e->n; i++)
        rd_text_printf(&b, "%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", e->t[i], e->T[i], e->f[i],
            e->I > 0.0 ? e->f[i] / e->I : 0.0, e->p[0][i], e->p[1][i], e->p[2][i]);
    return rd_text_write(&b, path, err, errlen);
}

static rd_status write_json(const rd_scene *s, const rd_explain_result *e, const char *path,
                            char *err, size_t errlen)
{
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "scene", s->path);
    cJSON *px = cJSON_AddArrayToObject(j, "pixel");
    cJSON_AddItemToArray(px, cJSON_CreateNumber(e->px));
    cJSON_AddItemToArray(px, cJSON_CreateNumber(e->py));
    cJSON_AddItemToObject(j, "origin", cJSON_CreateDoubleArray(e->origin, 3));
    cJSON_AddItemToObject(j, "direction", cJSON_CreateDoubleArray(e->dir, 3));
    cJSON_AddBoolToObject(j, "hits_media", e->hits_media);
    if (e->hits_media) {
        cJSON_AddNumberToObject(j, "t0", e->t0);
        cJSON_AddNumberToObject(j, "t1", e->t1);
        cJSON_AddNumberToObject(j, "dense_points", e->n);
        cJSON_AddNumberToObject(j, "I", e->I);
        cJSON_AddNumberToObject(j, "T_end", e->T_end);
        cJSON_AddNumberToObject(j, "I_ray_guide", e->I_ray);
        cJSON_AddNumberToObject(j, "mean_I_pilot", e->mean_I);
        cJSON *pl = cJSON_AddObjectToObject(j, "placements");
        for (int k = 0; k < RD_EXPLAIN_PLACEMENTS; k++) {
            cJSON *o = cJSON_AddObjectToObject(pl, rd_explain_placement_name(k));
            cJSON_AddNumberToObject(o, "samples", e->n_samples[k]);
            cJSON_AddNumberToObject(o, "variance", e->var[k]);
            cJSON_AddNumberToObject(o, "variance_se", e->var_se[k]);
            cJSON_AddNumberToObject(o, "relative_sd", e->I > 0.0 ? sqrt(e->var[k]) / e->I : 0.0);
            cJSON_AddItemToObject(o, "positions", cJSON_CreateDoubleArray(e->samples[k], e->n_samples[k]));
        }
    }
    char *text = cJSON_Print(j);
    cJSON_Delete(j);
    if (!text) {
        snprintf(err, errlen, "%s: out of memory", path);
        return RD_ERR_NOMEM;
    }
    rd_status st = rd_write_atomic(path, text, strlen(text), err, errlen);
    cJSON_free(text);
    return st;
}

/* The gnuplot script: top panel the pdfs against the ideal f/I, bottom panel one draw of each
 * placement's samples as ticks. Reads PREFIX.csv and a samples block written inline. */
static rd_status write_gnuplot(const rd_explain_result *e, const char *prefix, char *err,
                               size_t errlen)
{
    char csv[1100], png[1100], gp[1100];
    snprintf(csv, sizeof csv, "%s.csv", prefix);
    snprintf(png, sizeof png, "%s.png", prefix);
    snprintf(gp, sizeof gp, "%s.gp", prefix);
    const char *base = strrchr(csv, '/');
    base = base ? base + 1 : csv;
    const char *pbase = strrchr(png, '/');
    pbase = pbase ? pbase + 1 : png;
    rd_text b = {0};
    rd_text_printf(&b, "# gnuplot script written by photonmarch explain; run it in this folder: gnuplot %s\n",
        strrchr(gp, '/') ? strrchr(gp, '/') + 1 : gp);
    rd_text_printf(&b, "set terminal pngcairo size 1000,640 font ',10' noenhanced\nset output '%s'\n", pbase);
    rd_text_printf(&b, "set datafile separator ','\nset multiplot layout 2,1 title 'pixel (%d, %d): "
            "I = %.4g, guide I_ray = %.4g (pilot mean %.4g)'\n", e->px, e->py, e->I, e->I_ray, e->mean_I);
    rd_text_printf(&b, "set lmargin 10\nset xrange [%.9g:%.9g]\nset ylabel 'pdf [1/m]'\nset key top right\n",
        e->t0, e->t1);
    rd_text_printf(&b, "set size 1,0.64\nset origin 0,0.3\n");
    rd_text_printf(&b, "plot '%s' using 1:4 skip 1 with filledcurves y1=0 fs transparent solid 0.25 lc rgb '#888888' "
            "title 'ideal f/I (zero variance)', \\\n", base);
    rd_text_printf(&b, "  '' using 1:5 skip 1 with lines lw 2 lc rgb '#d62728' title 'guided (sd %.3g%%)', \\\n",
        e->I > 0 ? 100.0 * sqrt(e->var[0]) / e->I : 0.0);
    rd_text_printf(&b, "  '' using 1:6 skip 1 with lines lw 2 lc rgb '#1f77b4' title 'transmittance (sd %.3g%%)', \\\n",
        e->I > 0 ? 100.0 * sqrt(e->var[1]) / e->I : 0.0);
    rd_text_printf(&b, "  '' using 1:7 skip 1 with lines lw 2 lc rgb '#2ca02c' title 'uniform (sd %.3g%%)'\n",
        e->I > 0 ? 100.0 * sqrt(e->var[2]) / e->I : 0.0);
    rd_text_printf(&b, "set size 1,0.3\nset origin 0,0\nset xlabel 't along the camera ray'\nset ylabel ''\n"
            "set yrange [0.5:3.5]\nset ytics ('uniform' 1, 'transmittance' 2, 'guided' 3)\nunset key\n");
    rd_text_printf(&b, "set datafile separator whitespace\n");
    rd_text_printf(&b, "plot '-' using 1:2 with points pt 2 ps 1.5 lc rgb '#2ca02c', "
            "'-' using 1:2 with points pt 2 ps 1.5 lc rgb '#1f77b4', "
            "'-' using 1:2 with points pt 2 ps 1.5 lc rgb '#d62728'\n");
    const int order[3] = {RD_EXPLAIN_UNIFORM, RD_EXPLAIN_TRANSMITTANCE, RD_EXPLAIN_GUIDED};
    for (int q = 0; q < 3; q++) {
        int k = order[q];
        for (int i = 0; i < e->n_samples[k]; i++) rd_text_printf(&b, "%.9g %d\n", e->samples[k][i], q + 1);
        rd_text_printf(&b, "e\n");
    }
    rd_text_printf(&b, "unset multiplot\n");
    return rd_text_write(&b, gp, err, errlen);
}

rd_status rd_explain_write(const rd_scene *s, const rd_explain_result *e, const char *prefix,
                           char *err, size_t errlen)
{
    char path[1100];
    rd_status st;
    snprintf(path, sizeof path, "%s.json", prefix);
    if ((st = write_json(s, e, path, err, errlen)) != RD_OK) return st;
    if (!e->hits_media) return RD_OK;
    snprintf(path, sizeof path, "%s.csv", prefix);
    if ((st = write_csv(e, path, err, errlen)) != RD_OK) return st;
    return write_gnuplot(e, prefix, err, errlen);
}

int rd_explain_plot(const char *prefix, char *err, size_t errlen)
{
    /* gnuplot runs in the prefix's folder so the script's relative names resolve. */
    char dir[1100], cmd[2400];
    const char *slash = strrchr(prefix, '/');
    snprintf(dir, sizeof dir, "%.*s", slash ? (int)(slash - prefix) : 1, slash ? prefix : ".");
    const char *base = slash ? slash + 1 : prefix;
    if (strchr(prefix, '\'')) {
        snprintf(err, errlen, "%s: a quote in the output name; run gnuplot %s.gp yourself", prefix, prefix);
        return 0;
    }
    snprintf(cmd, sizeof cmd, "cd '%s' && gnuplot '%s.gp' 2>&1", dir, base);
    FILE *p = popen(cmd, "r");
    if (!p) {
        snprintf(err, errlen, "could not run gnuplot for %s.png", prefix);
        return 0;
    }
    char line[512] = "", first[512] = "";
    while (fgets(line, sizeof line, p))
        if (!first[0]) snprintf(first, sizeof first, "%s", line);
    int rc = pclose(p);
    if (rc != 0) {
        first[strcspn(first, "\n")] = 0;
        snprintf(err, errlen, "gnuplot failed on %s.gp (is gnuplot installed? scripts/install-deps.sh installs it)%s%s",
                 prefix, first[0] ? ": " : "", first);
        return 0;
    }
    return 1;
}
