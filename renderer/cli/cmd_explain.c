/* cmd_explain.c: photonmarch explain, camera rays laid open for the ray marchers: the integrand
 * along each and where each placement puts its samples (rd_explain). */
#include "cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const usage_explain =
    "usage: photonmarch explain SCENE --pixel X,Y [options]\n"
    "\n"
    "Lays open the camera ray through the centre of pixel (X, Y) (0,0 = top left) for the ray\n"
    "marchers (docs/guided-marching.md): the integrand f(t) = T(0,t) sigma_s L_s(t) along it,\n"
    "evaluated densely (T by quadrature, L_s from the scene's march.ls source averaged over 16\n"
    "draws), the PDF of each placement (guided, transmittance, uniform) against the ideal f/I,\n"
    "one draw of where each puts its samples, I_ray and N_ray of eq. 17, and the variance of\n"
    "each placement's estimate of the ray's integral (4000 simulated draws). Writes PREFIX.json,\n"
    "PREFIX.csv and PREFIX.gp, and PREFIX.png drawn by gnuplot. Bakes like render --method\n"
    "guided (cache beside PREFIX). In a scene with shapes: the ray's first straight segment,\n"
    "up to the first surface it meets. Ctrl-C or SIGTERM during the bake stops it and writes\n"
    "nothing (exit 130 / 143); later, the rays already written are kept and the rest skipped.\n"
    "\n"
    "options:\n"
    "  --pixel X,Y      the pixel (required; repeat it for several rays, which share one bake:\n"
    "                   each then writes PREFIX-X-Y.*)\n"
    "  -o PREFIX        output prefix (default out/SCENE-explain-X-Y)\n"
    "  --points N       dense points along the ray (default 2000, at least 16)\n"
    "  --seed N         seed of the draws (default: settings.seed)\n"
    "  --threads N      bake threads (default: all cores)\n"
    "  --no-cache       bake afresh, do not read or write the bake cache\n"
    "  --set KEY=VALUE  override a scene key (as in render)\n"
    "  -q, --quiet      print only the output file names\n";

/* The explain summary of one ray on stdout. */
static void print_explain(const rd_explain_result *e)
{
    printf("pixel (%d, %d): ray from (%.4g, %.4g, %.4g) along (%.4f, %.4f, %.4f)\n", e->px, e->py, e->origin[0],
           e->origin[1], e->origin[2], e->dir[0], e->dir[1], e->dir[2]);
    if (!e->hits_media) {
        printf("the ray misses the media: nothing to march\n");
        return;
    }
    printf("media from t = %.4g to %.4g; T(0, end) = %.4g; I = integral of f = %.6g\n", e->t0, e->t1, e->T_end, e->I);
    printf("guide: I_ray = %.6g, pilot mean I = %.6g -> N_ray = %d (eq. 17)\n", e->I_ray, e->mean_I,
           e->n_samples[RD_EXPLAIN_GUIDED]);
    printf("%-14s %8s %12s %12s %10s\n", "placement", "samples", "variance", "+- (se)", "rel. sd");
    for (int k = 0; k < RD_EXPLAIN_PLACEMENTS; k++)
        printf("%-14s %8d %12.4g %12.2g %9.3g%%\n", rd_explain_placement_name(k), e->n_samples[k], e->var[k],
               e->var_se[k], e->I > 0 ? 100.0 * sqrt(e->var[k]) / e->I : 0.0);
}

enum { MAX_PIXELS = 4096 }; /* --pixel options per run */

/* explain with room for MAX_PIXELS pixels in pxs. */
static int explain_run(int argc, char **argv, long (*pxs)[2])
{
    cli_scene_args a = {0};
    const char *prefix = NULL;
    long seed = -1, threads = 0, points = 2000;
    int npx = 0;
    int quiet = 0, no_cache = 0;
    for (int i = 0; i < argc; i++) {
        const char *o = argv[i];
        int t = cli_take_set(&a, argc, argv, &i);
        if (t < 0) return CLI_EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        if (!strcmp(o, "-h") || !strcmp(o, "--help")) { fputs(usage_explain, stdout); return 0; }
        else if (!strcmp(o, "-q") || !strcmp(o, "--quiet")) quiet = 1;
        else if (!strcmp(o, "--no-cache")) no_cache = 1;
        else if ((!strcmp(o, "-o") || !strcmp(o, "--output")) && has_val) prefix = argv[++i];
        else if (!strcmp(o, "--points") && has_val) { if (!cli_parse_int(o, argv[++i], 16, 1000000, &points)) return CLI_EXIT_USAGE; }
        else if (!strcmp(o, "--seed") && has_val) { if (!cli_parse_int(o, argv[++i], 0, 0x7fffffffL, &seed)) return CLI_EXIT_USAGE; }
        else if (!strcmp(o, "--threads") && has_val) { if (!cli_parse_int(o, argv[++i], 1, 1024, &threads)) return CLI_EXIT_USAGE; }
        else if (!strcmp(o, "--pixel") && has_val) {
            const char *v = argv[++i];
            char tail;
            long x, y;
            if (sscanf(v, "%ld,%ld%c", &x, &y, &tail) != 2 || x < 0 || y < 0) {
                fprintf(stderr, "photonmarch explain: --pixel %s: expected X,Y (two integers >= 0)\n", v);
                return CLI_EXIT_USAGE;
            }
            if (npx == MAX_PIXELS) {
                fprintf(stderr, "photonmarch explain: --pixel %s: at most %d pixels per run\n", v, MAX_PIXELS);
                return CLI_EXIT_USAGE;
            }
            pxs[npx][0] = x, pxs[npx][1] = y, npx++;
        } else if (cli_take_positional(&a, "explain", o)) return CLI_EXIT_USAGE;
    }
    if (cli_need_scene(&a, "explain")) return CLI_EXIT_USAGE;
    if (npx == 0) {
        fprintf(stderr, "photonmarch explain: missing --pixel X,Y (see photonmarch explain --help)\n");
        return CLI_EXIT_USAGE;
    }
    char defout[1024];
    if (!prefix) {
        char suffix[64];
        if (npx == 1) snprintf(suffix, sizeof suffix, "-explain-%ld-%ld", pxs[0][0], pxs[0][1]);
        else snprintf(suffix, sizeof suffix, "-explain");
        cli_default_output(a.scene, suffix, defout, sizeof defout);
        prefix = defout;
    }
    if (strlen(prefix) > 1000) {
        fprintf(stderr, "photonmarch explain: -o: path too long\n");
        return CLI_EXIT_USAGE;
    }
    /* PREFIX.json (and .csv, .gp, .png, per pixel with several) must not be the scene. */
    for (int q = 0; q < npx; q++) {
        static const char *const ext[] = {".json", ".csv", ".gp", ".png"};
        for (int k = 0; k < 4; k++) {
            char one[1100];
            if (npx == 1) snprintf(one, sizeof one, "%s%s", prefix, ext[k]);
            else snprintf(one, sizeof one, "%s-%ld-%ld%s", prefix, pxs[q][0], pxs[q][1], ext[k]);
            if (cli_refuse_input_as_output("explain", one, a.scene)) return CLI_EXIT_USAGE;
        }
    }
    char err[RD_ERRLEN];
    rd_scene *scene;
    rd_status st = rd_scene_load(&scene, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) return cli_report_error(st, err);
    int code = 0;
    rd_baked *baked = NULL;
    rd_explain_result e;
    memset(&e, 0, sizeof e);
    /* A pixel outside the image is a usage error, found before the bake (minutes on a big scene). */
    for (int q = 0; q < npx; q++)
        if (pxs[q][0] >= rd_scene_width(scene) || pxs[q][1] >= rd_scene_height(scene)) {
            fprintf(stderr, "photonmarch explain: --pixel %ld,%ld: outside the %dx%d image\n", pxs[q][0], pxs[q][1],
                    rd_scene_width(scene), rd_scene_height(scene));
            code = CLI_EXIT_USAGE;
            goto out;
        }
    if ((st = rd_make_parent_dirs(prefix, err, sizeof err)) != RD_OK) {
        code = cli_report_error(st, err);
        goto out;
    }
    rd_bake_opts bo = {0};
    bo.seed = -1;
    bo.threads = (int)threads;
    rd_bake_opts_for(&bo, rd_method_needs_for("guided", scene));
    cli_on_signal_cancel(); /* a signal stops the bake, which removes its cache temporaries */
    bo.cancel = cli_cancel_flag();
    if (!quiet)
        fprintf(stderr, "photonmarch explain: preparing the photon map and guide (Ctrl-C stops and writes nothing)\n");
    st = cli_bake_beside(scene, &bo, prefix, no_cache, quiet, &baked, err, sizeof err);
    if (st == RD_ERR_CANCELLED || (st == RD_OK && cli_interrupted())) {
        code = cli_report_cancelled("explain", "while baking");
        goto out;
    }
    if (st) {
        code = cli_report_error(st, err);
        goto out;
    }
    cli_on_signal_stop(); /* from here a signal lets the ray being written finish, then stops */
    for (int q = 0; q < npx && code == 0; q++) {
        if (cli_interrupted()) {
            fprintf(stderr, "photonmarch explain: interrupted after %d of %d rays; those are written\n", q, npx);
            code = cli_exit_interrupted(cli_interrupted());
            break;
        }
        long px = pxs[q][0], py = pxs[q][1];
        char one[1100];
        if (npx == 1) snprintf(one, sizeof one, "%s", prefix);
        else snprintf(one, sizeof one, "%s-%ld-%ld", prefix, px, py);
        rd_explain_opts eo = {.px = (int)px, .py = (int)py, .baked = baked, .n = (int)points,
                              .seed = seed >= 0 ? (uint64_t)seed : rd_scene_seed(scene), .threads = (int)threads};
        rd_explain_result_free(&e);
        if ((st = rd_explain(scene, &eo, &e, err, sizeof err)) != RD_OK ||
            (st = rd_explain_write(scene, &e, one, err, sizeof err)) != RD_OK) {
            code = cli_report_error(st, err);
            break;
        }
        if (!quiet) print_explain(&e);
        printf("report %s.json\n", one);
        if (e.hits_media) {
            printf("table  %s.csv\n", one);
            if (rd_explain_plot(one, err, sizeof err)) printf("plot   %s.png\n", one);
            else fprintf(stderr, "warning: %s (the table and %s.gp are written)\n", err, one);
        }
    }
out:
    rd_explain_result_free(&e);
    rd_baked_free(baked);
    rd_scene_free(scene);
    return code;
}

/* explain: camera rays laid open (rd_explain). */
int cli_cmd_explain(int argc, char **argv)
{
    long (*pxs)[2] = malloc(MAX_PIXELS * sizeof *pxs); /* 64 KB: on the heap, not the stack */
    if (!pxs) {
        fprintf(stderr, "photonmarch explain: out of memory\n");
        return CLI_EXIT_INTERNAL;
    }
    int code = explain_run(argc, argv, pxs);
    free(pxs);
    return code;
}
