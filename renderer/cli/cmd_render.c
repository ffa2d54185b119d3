/* cmd_render.c: photonmarch render, one method over a scene to OUT.exr, OUT-stderr.exr, OUT.png
 * and OUT.json (rd_render), with progress on stderr and Ctrl-C writing what it has. */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

/* render -o OUT.exr writes OUT.exr, OUT-stderr.exr, OUT.png and OUT.json: output i of the four
 * into path. */
static void render_output(const char *exr, int i, char *path, size_t n)
{
    static const char *const ext[] = {".exr", "-stderr.exr", ".png", ".json"};
    snprintf(path, n, "%.*s%s", (int)(strlen(exr) - 4), exr, ext[i]);
}

/* None of the four outputs may be the scene (`render scene.json -o scene.exr` would replace it
 * with the report). */
static int refuse_render_outputs(const char *exr, const char *scene)
{
    for (int i = 0; i < 4; i++) {
        char path[1100];
        render_output(exr, i, path, sizeof path);
        if (cli_refuse_input_as_output("render", path, scene)) return CLI_EXIT_USAGE;
    }
    return 0;
}

/* --select-trace FILE may be none of the render's inputs (the scene, --reference, --photons,
 * --guide) nor of its four outputs (the same string, or the same existing file): exit 1 after a
 * message. */
static int refuse_trace_path(const char *trace, const char *exr, const char *const in[4])
{
    static const char *const what[] = {"the scene", "--reference", "--photons", "--guide"};
    if (!trace) return 0;
    for (int i = 0; i < 4; i++)
        if (in[i] && (!strcmp(trace, in[i]) || cli_same_file(trace, in[i]))) {
            fprintf(stderr, "photonmarch render: --select-trace %s: is %s; choose another path\n", trace, what[i]);
            return CLI_EXIT_USAGE;
        }
    for (int i = 0; i < 4; i++) {
        char path[1100];
        render_output(exr, i, path, sizeof path);
        if (!strcmp(trace, path) || cli_same_file(trace, path)) {
            fprintf(stderr, "photonmarch render: --select-trace %s: is one of the render's outputs; choose another path\n", trace);
            return CLI_EXIT_USAGE;
        }
    }
    return 0;
}

static const char *const usage_render =
    "usage: photonmarch render SCENE [options]\n"
    "\n"
    "Renders SCENE (JSON, docs/scene-format.md). Writes OUT.exr (linear float RGB), OUT.png\n"
    "(sRGB preview, scaled by 2^camera.exposure) and OUT.json (method, samples, time, counters).\n"
    "Files are written under a temporary name and renamed, so a failed run never destroys a\n"
    "good image. Ctrl-C or SIGTERM (or the time limit) stops before the next pixel and writes\n"
    "what it has (exit 130 for Ctrl-C, 143 for SIGTERM); a second signal ends it at once; the\n"
    "per-pixel sample counts are in the report. A signal while the method's photon map and\n"
    "guide are baked stops the bake and writes nothing (exit 130 / 143).\n"
    "\n"
    "options:\n"
    "  --method M        rendering method (default: settings.method, else delta); the methods\n"
    "                    are listed below\n"
    "  --spp N           samples per pixel (default: settings.spp)\n"
    "  --time S          stop after S seconds, bake included (checked before every pixel,\n"
    "                    so the budget is kept to within a pixel's work); with --spp, the\n"
    "                    first limit reached stops the render\n"
    "  --seed N          random seed (default: settings.seed); same seed, same image on any\n"
    "                    number of threads (`guided`'s tile choices read how the render ends: with\n"
    "                    --spp N alone they depend on N, so a render of N samples is not the first N\n"
    "                    of a longer one; with --time they read the clock: docs/guided-marching.md\n"
    "                    \"The samples the image holds\")\n"
    "  --threads N       worker threads (default: all cores)\n"
    "  -o, --output OUT.exr   output path (default: out/<scene name>.exr); also writes\n"
    "                    OUT-stderr.exr, the per-pixel standard error of the mean\n"
    "  --photons FILE    a photon map saved by `bake` (methods that need one; otherwise they\n"
    "                    bake their own, cached in OUT's folder under .photonmarch-cache/,\n"
    "                    named by a hash of everything the bake depends on)\n"
    "  --guide FILE      a guide grid saved by `bake` (the guided method)\n"
    "  --no-cache        bake afresh and do not write the cache\n"
  "  --reference REF.exr    a converged image of the same size: the report records the RMSE\n"
    "                    against it after every pass (\"convergence\")\n"
    "  --set KEY=VALUE   override a scene field before validation, e.g. --set settings.spp=64,\n"
    "                    --set camera.resolution=[320,240], --set media[0].g=0.9 (repeatable)\n"
    "  --select-trace FILE  the tile selection's choices (guided, guided-unbiased, delta with\n"
    "                    settings.equiangular \"tiles\"): at its pilot and every epoch, one JSON\n"
    "                    line with each 8x8 tile's estimator and the samples, mean, variance\n"
    "                    and cost it was chosen from (docs/cli.md, \"The selection's trace\");\n"
    "                    a render without a selection writes none and says so\n"
    "  -q, --quiet       no progress and no summary\n"
    "  -h, --help        this text\n";

/* Light the method cannot render (rd_hidden_light, measured when the scene was loaded;
 * docs/compare.md, "Light only photons find"): `delta`, `guided-unbiased`, and the marchers
 * with an unbiased march.ls lack the light that leaves a point, spot or directional light by way
 * of glass first. A note on stderr after the render, only for a scene that has some. */
static void note_hidden_light(const rd_scene *scene, const char *method)
{
    int blind = !strcmp(method, "delta") || !strcmp(method, "guided-unbiased") || !rd_scene_march_uses_photons(scene);
    double share = rd_scene_hidden_light(scene); /* measured at load */
    if (blind && share > RD_HIDDEN_SHARE)
        fprintf(stderr, "note: %.3g%% of the light scattered in the media leaves a point, spot or directional light by "
                        "way of glass first; %s cannot render it (guided with its default march.ls here, nee+beams, can: "
                        "docs/compare.md, \"Light only photons find\")\n",
                100.0 * share, method);
}

/* render --help: the options, then the method table. */
static void print_render_help(void)
{
    fputs(usage_render, stdout);
    printf("\nmethods:\n");
    for (int i = 0; i < rd_method_count(); i++) {
        unsigned needs = rd_method_needs(i);
        printf("  %-16s %s%s\n", rd_method_name(i), rd_method_summary(i),
               needs ? " (bakes a photon map and guide first)" : "");
    }
}

/* Progress: on a terminal one line rewritten after every pass; elsewhere (logs, batch systems)
 * a line after the first pass and then at most every 10 s. */
static void progress(void *user, int done, int total, double seconds)
{
    cli_progress_state *ps = user;
    double eta = done > 0 ? seconds * (total - done) / done : 0.0;
    if (ps->time_limit > 0 && ps->time_limit - seconds < eta) eta = fmax(0.0, ps->time_limit - seconds);
    if (!ps->tty) {
        double now = cli_wall_seconds();
        if (ps->last_print > 0 && now - ps->last_print < 10.0) return;
        ps->last_print = now;
    }
    const char *lead = ps->tty ? "\r" : "", *tail = ps->tty ? "   " : "\n";
    if (total >= (1 << 24)) /* --time alone: no sample target */
        fprintf(stderr, "%s  %d spp  %.1f of %.0f s%s", lead, done, seconds, ps->time_limit, tail);
    else
        fprintf(stderr, "%s  %d/%d spp  %.1f s elapsed, about %.0f s left%s", lead, done, total, seconds, eta, tail);
    fflush(stderr);
}

/* The command line of render, parsed. */
typedef struct {
    cli_scene_args a;
    const char *method, *outpath, *refpath, *photons_path, *guide_path, *trace_path;
    long spp, seed, threads;
    double time_limit;
    int quiet, no_cache;
    char defout[1024];
} render_args;

/* Parse argv into *r: -1 to go on, else the exit code (after a message, or --help). */
static int parse_render(int argc, char **argv, render_args *r)
{
    cli_scene_args *a = &r->a;
    const char *method = NULL, *outpath = NULL, *refpath = NULL, *photons_path = NULL, *guide_path = NULL, *trace_path = NULL;
    long spp = -1, seed = -1, threads = 0;
    double time_limit = -1;
    int quiet = 0, no_cache = 0;
    for (int i = 0; i < argc; i++) {
        const char *o = argv[i];
        int t = cli_take_set(a, argc, argv, &i);
        if (t < 0) return CLI_EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        if (!strcmp(o, "-h") || !strcmp(o, "--help")) { print_render_help(); return 0; }
        else if (!strcmp(o, "-q") || !strcmp(o, "--quiet")) quiet = 1;
        else if (!strcmp(o, "--method") && has_val) method = argv[++i];
        else if (!strcmp(o, "--reference") && has_val) refpath = argv[++i];
        else if (!strcmp(o, "--select-trace") && has_val) trace_path = argv[++i];
        else if (!strcmp(o, "--photons") && has_val) photons_path = argv[++i];
        else if (!strcmp(o, "--guide") && has_val) guide_path = argv[++i];
        else if (!strcmp(o, "--no-cache")) no_cache = 1;
        else if (!strcmp(o, "--spp") && has_val) { if (!cli_parse_int(o, argv[++i], 1, 1 << 24, &spp)) return CLI_EXIT_USAGE; }
        else if (!strcmp(o, "--time") && has_val) { if (!cli_parse_double(o, argv[++i], 0.001, 1e7, &time_limit)) return CLI_EXIT_USAGE; }
        else if (!strcmp(o, "--seed") && has_val) { if (!cli_parse_int(o, argv[++i], 0, 0x7fffffffL, &seed)) return CLI_EXIT_USAGE; }
        else if (!strcmp(o, "--threads") && has_val) { if (!cli_parse_int(o, argv[++i], 1, 1024, &threads)) return CLI_EXIT_USAGE; }
        else if ((!strcmp(o, "-o") || !strcmp(o, "--output")) && has_val) outpath = argv[++i];
        else if (cli_take_positional(a, "render", o)) return CLI_EXIT_USAGE;
    }
    if (cli_need_scene(a, "render")) return CLI_EXIT_USAGE;
    if (!outpath) {
        cli_default_output(a->scene, ".exr", r->defout, sizeof r->defout);
        outpath = r->defout;
    }
    size_t olen = strlen(outpath);
    if (olen < 5 || strcmp(outpath + olen - 4, ".exr") != 0 || olen > 1000) {
        fprintf(stderr, "photonmarch render: -o %s: expected a path ending in .exr\n", outpath);
        return CLI_EXIT_USAGE;
    }
    if (refuse_render_outputs(outpath, a->scene)) return CLI_EXIT_USAGE;
    const char *const inputs[4] = {a->scene, refpath, photons_path, guide_path};
    if (refuse_trace_path(trace_path, outpath, inputs)) return CLI_EXIT_USAGE;
    r->method = method, r->outpath = outpath, r->refpath = refpath;
    r->photons_path = photons_path, r->guide_path = guide_path, r->trace_path = trace_path;
    r->spp = spp, r->seed = seed, r->threads = threads, r->time_limit = time_limit;
    r->quiet = quiet, r->no_cache = no_cache;
    return -1;
}

int cli_cmd_render(int argc, char **argv) { return cli_cmd_render_on(argc, argv, NULL); }

/* The exit code of a bake's outcome, with its one line in err: a signal during the bake
 * (rd_bake_opts.cancel) ends the render with nothing written. */
static int bake_outcome(rd_status st, char *err, size_t errlen)
{
    if (st == RD_ERR_CANCELLED || (st == RD_OK && cli_interrupted())) {
        snprintf(err, errlen, "photonmarch render: interrupted while baking the photon map and guide; nothing "
                              "written, the previous files are as they were");
        return cli_exit_interrupted(cli_interrupted() ? cli_interrupted() : SIGINT);
    }
    return cli_exit_for(st);
}

/* Several ranks (d, docs/cluster.md): every rank parses, loads the scene and renders its share;
 * rank 0 alone prints progress and writes the outputs; after each step that can fail the ranks
 * agree (cli_ranks_agree), so a failure anywhere ends every rank with a non-zero exit. */
int cli_cmd_render_on(int argc, char **argv, rd_dist *d)
{
    render_args *r = calloc(1, sizeof *r);
    if (!r) {
        fprintf(stderr, "photonmarch render: out of memory\n");
        return CLI_EXIT_INTERNAL;
    }
    int muted = cli_ranks_mute(d);
    int pc = cli_ranks_unmute(d, muted, parse_render(argc, argv, r));
    if (pc >= 0) {
        free(r);
        return pc;
    }
    const int lead = rd_dist_rank(d) == 0, ranks = rd_dist_size(d);
    cli_scene_args *a = &r->a;
    const char *method = r->method, *outpath = r->outpath, *refpath = r->refpath;
    const char *photons_path = r->photons_path, *guide_path = r->guide_path, *trace_path = r->trace_path;
    long spp = r->spp, seed = r->seed, threads = r->threads;
    double time_limit = r->time_limit;
    int quiet = r->quiet || !lead, no_cache = r->no_cache;
    cli_on_signal_quit(); /* nothing to save until the passes begin */

    char err[RD_ERRLEN];
    rd_scene *scene = NULL;
    rd_status st;
    int code = cli_ranks_load_scene(d, a, &scene);
    rd_image ref = {0, 0, NULL, 0};
    if (!code && refpath) {
        st = rd_image_read(refpath, &ref, err, sizeof err);
        code = cli_ranks_agree(d, cli_exit_for(st), err);
    }
    if (code) {
        rd_scene_free(scene);
        rd_image_free_pixels(&ref);
        free(r);
        return code;
    }
    rd_render_opts ro = {0};
    ro.method = method ? method : rd_scene_method(scene);
    ro.spp = spp > 0 ? (int)spp : rd_scene_spp(scene);
    ro.time_limit = time_limit > 0 ? time_limit : rd_scene_time_limit(scene);
    /* A time limit without a sample count (--time, or settings.time with no settings.spp)
     * runs until the time is up. */
    if (ro.time_limit > 0 && spp < 0 && (time_limit > 0 || !rd_scene_spp_given(scene))) ro.spp = 1 << 24;
    ro.seed = seed >= 0 ? (uint64_t)seed : rd_scene_seed(scene);
    ro.threads = (int)threads;
    ro.cancel = cli_cancel_flag();
    ro.reference = refpath ? &ref : NULL;
    ro.comm = rd_dist_comm(d);
    ro.select_trace = trace_path;
    cli_progress_state ps = {ro.time_limit, isatty(2), 0.0};
    if (!quiet) {
        ro.progress = progress;
        ro.progress_user = &ps;
    }
    rd_baked *baked = NULL; /* before the first goto out, which frees it */
    if (ranks > 1) { /* the ranks must render one image: the options that decide it agree */
        char opts[8192];
        snprintf(opts, sizeof opts, "%s|%d|%llu|%a|%d|%s|%s|%s", ro.method, ro.spp, (unsigned long long)ro.seed,
                 ro.time_limit, no_cache, photons_path ? photons_path : "", guide_path ? guide_path : "",
                 refpath ? refpath : "");
        if ((code = cli_ranks_same_options(d, opts, a)) != 0) goto out;
    }
    /* Only rank 0 writes. */
    st = lead ? rd_image_io_ready(outpath, err, sizeof err) : RD_OK; /* (before any folder is made) */
    if (st == RD_OK && lead) st = rd_make_parent_dirs(outpath, err, sizeof err);
    if ((code = cli_ranks_agree(d, cli_exit_for(st), err)) != 0) goto out;
    /* What the method needs baked: from --photons/--guide, the cache, or a fresh bake. */
    unsigned needs = rd_method_needs_for(ro.method, scene);
    if (needs) {
        rd_bake_opts bo = {0};
        bo.seed = -1;
        bo.threads = (int)threads;
        rd_bake_opts_for(&bo, needs);
        bo.load_photons = photons_path;
        bo.load_guide = guide_path;
        double t0 = cli_wall_seconds();
        int fresh = photons_path || guide_path || no_cache;
        cli_on_signal_cancel(); /* a signal stops the bake, which removes its cache temporaries */
        bo.cancel = cli_cancel_flag();
        /* Several ranks trace the photons together (each a range, gathered on every rank); they
         * use the cache when every rank can read it, and rank 0 alone saves it. */
        bo.comm = rd_dist_comm(d);
        if (!quiet && lead)
            fprintf(stderr, "photonmarch render: preparing the photon map and guide (Ctrl-C stops and writes nothing)\n");
        st = cli_bake_beside(scene, &bo, outpath, fresh, quiet, &baked, err, sizeof err);
        if ((code = cli_ranks_agree_shared(d, bake_outcome(st, err, sizeof err), err)) != 0) goto out;
        ro.baked = baked;
        ro.baked_seconds = cli_wall_seconds() - t0;
    }
    cli_on_signal_stop(); /* from here on, a signal stops and writes what it has */
    rd_render_result res;
    st = rd_render(scene, &ro, &res, err, sizeof err);
    if (ro.progress && ps.tty) fputc('\n', stderr);
    if (refpath && st == RD_ERR_ARG) { /* the only argument rd_render checks against a file */
        char msg[RD_ERRLEN + 1100];
        snprintf(msg, sizeof msg, "%s: %s", refpath, err);
        code = cli_ranks_agree(d, CLI_EXIT_INPUT, msg);
        goto out;
    }
    /* (a cancel while tracing the first progressive photon pass: nothing rendered) */
    code = st == RD_ERR_CANCELLED ? bake_outcome(st, err, sizeof err) : cli_exit_for(st);
    if ((code = cli_ranks_agree_shared(d, code, err)) != 0) goto out;
    if (!lead) { /* rank 0 writes; the others end with its status */
        code = cli_ranks_agree(d, 0, NULL);
        if (!code && cli_interrupted()) code = cli_exit_interrupted(cli_interrupted());
        rd_render_result_free(&res);
        goto out;
    }
    if (res.stats.spp_mean <= 0.0 && !res.stats.cancelled) {
        fprintf(stderr, "photonmarch render: --time %g: the time ran out before any pixel was sampled (the bake took "
                        "%.1f s); nothing written\n", ro.time_limit, res.stats.bake_seconds);
        code = CLI_EXIT_USAGE;
    } else if (res.stats.spp_mean <= 0.0) {
        fprintf(stderr, "photonmarch render: interrupted before any pixel was sampled; nothing written\n");
        code = cli_exit_interrupted(cli_interrupted());
    } else if ((st = rd_render_write(scene, &ro, &res, outpath, err, sizeof err)) != RD_OK) {
        code = cli_exit_for(st);
        if (ranks <= 1) fprintf(stderr, "%s\n", err);
    } else {
        if (!quiet) {
            const rd_render_stats *rs = &res.stats;
            double paths = rs->paths ? (double)rs->paths : 1.0;
            fprintf(stderr, "%s: %.4g spp in %.2f s (%.0f paths/s, %.2f collisions/path, %.2f lookups/path)%s%s\n",
                    ro.method, rs->spp_mean, rs->seconds, rs->seconds > 0 ? rs->paths / rs->seconds : 0.0,
                    rs->collisions / paths, rs->lookups / paths, rs->cancelled ? " [interrupted]" : "",
                    rs->timed_out ? " [time limit]" : "");
            if (rs->invalid) fprintf(stderr, "warning: %llu non-finite samples were dropped\n", (unsigned long long)rs->invalid);
            note_hidden_light(scene, ro.method);
            char base[1100];
            snprintf(base, sizeof base, "%.*s", (int)(strlen(outpath) - 4), outpath);
            printf("image  %s\nstderr %s-stderr.exr\npng    %s.png\nreport %s.json\n", outpath, base, base, base);
        }
        if (trace_path && lead) { /* (rank 0 writes the trace) */
            const rd_render_stats *rs = &res.stats;
            if (!rs->select_choices) {
                fprintf(stderr, "note: --select-trace %s: this render made no tile selection (method %s; settings.select, "
                                "or delta's settings.equiangular \"tiles\"), so nothing was written there\n", trace_path, ro.method);
            } else if (rs->select_traced < rs->select_choices) {
                fprintf(stderr, "photonmarch render: --select-trace %s: %s (%d of the %d choices written)\n", trace_path,
                        res.select_trace_err, rs->select_traced, rs->select_choices);
                code = cli_exit_for(RD_ERR_OUTPUT);
            } else if (!quiet) {
                printf("trace  %s\n", trace_path);
            }
        }
        /* A signal that came after the last pixel still says so in the status. */
        if (cli_interrupted()) code = cli_exit_interrupted(cli_interrupted());
    }
    if (ranks > 1) { /* rank 0's outcome to the others (its message printed above or here) */
        int failed = code && code != cli_exit_interrupted(cli_interrupted());
        int c = cli_ranks_agree(d, failed ? code : 0, failed && st ? err : NULL);
        if (!code) code = c;
    }
    rd_render_result_free(&res);
out:
    rd_baked_free(baked);
    rd_image_free_pixels(&ref);
    rd_scene_free(scene);
    free(r);
    return code;
}
