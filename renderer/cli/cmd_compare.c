/* cmd_compare.c: photonmarch compare, several methods at equal time or samples, K runs each,
 * measured against a reference and written as a report folder (rd_compare_run). */
#include "cli.h"

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char *const usage_compare =
    "usage: photonmarch compare SCENE --methods A,B[,...] [options]\n"
    "\n"
    "Renders SCENE with every method K times (seeds seed+1..seed+K) at equal time or equal\n"
    "samples, measures each against a reference (docs/compare.md) and writes the report folder\n"
    "DIR: index.html (opens from disk: A/B/reference toggle, error maps, worst-region crops,\n"
    "metrics table, convergence plot), metrics.json, convergence.svg (gnuplot), and the EXR and\n"
    "PNG images. Prints progress on stderr, and on stdout the metrics table and the summary in\n"
    "words: the winner by efficiency 1/(MSE x time), and per method its efficiency relative to\n"
    "delta's (else the first method's) and the share of its error that is bias. Ctrl-C stops\n"
    "the run (or a method's bake) in progress and writes the report of the runs that finished\n"
    "(exit 130).\n"
    "\n"
    "options:\n"
    "  --methods A,B     methods to compare (listed below)\n"
    "  --equal time|spp  what every method gets the same of (default: time)\n"
    "  --budget X        per run: seconds with --equal time (default 10; a method's bake is\n"
    "                    done once and its time is charged to each of its runs), samples per\n"
    "                    pixel with --equal spp (default 64)\n"
    "  --runs K          independent runs per method, for bias^2 and variance (default 2)\n"
    "  --reference REF.exr   the converged image to measure against (REF-stderr.exr beside it,\n"
    "                    if present, gives its own noise); default: rendered with delta (its\n"
    "                    equiangular sample chosen per tile, settings.equiangular \"tiles\",\n"
    "                    where a point or spot light, or a directional beam that the beam\n"
    "                    connections do not serve, exists and the scene does not name the\n"
    "                    key) and cached, until its variance is at most a\n"
    "                    tenth of the best method's MSE (10x a run's budget before the runs,\n"
    "                    more after them if a method is better than delta; at most 50x the\n"
    "                    longest run), so the methods can be ranked; when part of the media's\n"
    "                    light leaves a point, spot or directional light by way of glass (which\n"
    "                    delta cannot render), one render of 10x a run's budget by guided with\n"
    "                    progressive photons\n"
    "  --ref-spp N       instead, a reference of N samples per pixel (with --ref-time: the\n"
    "                    first limit reached stops it)\n"
    "  --ref-time S      instead, a reference of S seconds (alone: time decides, no spp cap)\n"
    "  --cache DIR       where the rendered reference is cached (default: .photonmarch-cache\n"
    "                    beside the report folder), named by a hash of the scene's content and\n"
    "                    what decides the reference (the default one is extended in place)\n"
    "  --no-cache        render the reference afresh and do not cache it\n"
    "  --add LABEL=IMAGE.exr[@SECONDS]   an image from another renderer, with its render time\n"
    "                    (repeatable); measured like the methods (no runs: no bias/variance);\n"
    "                    LABEL may not be a method's name nor name one of the report's files\n"
    "                    (reference, colorbar, METHOD-error, ...)\n"
    "  --seed N          base seed (default: settings.seed)\n"
    "  --threads N       worker threads (default: all cores)\n"
    "  -o, --output DIR  report folder (default: out/compare-<scene name>)\n"
    "  --set KEY=VALUE   override a scene field before validation (repeatable)\n"
    "  -q, --quiet       no progress\n"
    "  -h, --help        this text\n";

static void print_compare_help(void)
{
    fputs(usage_compare, stdout);
    printf("\nmethods:\n");
    for (int i = 0; i < rd_method_count(); i++) printf("  %-16s %s\n", rd_method_name(i), rd_method_summary(i));
}

/* Progress of a comparison: which method, which run, the run's time and the time left. */
static void compare_progress(void *user, const rd_cmp_progress *p)
{
    cli_progress_state *ps = user;
    /* Not a terminal: a line when a run starts, then at most every 10 s. */
    if (!ps->tty) {
        double now = cli_wall_seconds();
        int started = p->spp_done == 0;
        if (!started && ps->last_print > 0 && now - ps->last_print < 10.0) return;
        ps->last_print = now;
    }
    const char *lead = ps->tty ? "\r" : "", *tail = ps->tty ? "      " : "\n";
    fprintf(stderr, "%s  %s run %d/%d: %d spp, %.1f s; about %.0f s left in all%s", lead, p->label, p->run, p->runs,
            p->spp_done, p->run_seconds, p->left_seconds, tail);
    fflush(stderr);
}

/* Split "a,b,c" (in buf, modified) into at most max names. */
static int split_methods(char *buf, const char **names, int max)
{
    int n = 0;
    for (char *t = strtok(buf, ","); t; t = strtok(NULL, ",")) {
        if (n == max) return -1;
        names[n++] = t;
    }
    return n;
}

typedef struct {
    cli_scene_args a;
    char methods_buf[512];
    const char *methods[9];
    rd_cmp_extra extras[9];
    char extra_buf[9][1100];
    const char *outdir, *cache;
    int no_cache, quiet, equal_set;
    long seed;
    rd_cmp_opts o;
} compare_args;

/* Parse the options into ca; 0 when fine, else the exit code (after a message). */
static int compare_parse(compare_args *ca, int argc, char **argv)
{
    rd_cmp_opts *o = &ca->o;
    double budget = -1;
    long v;
    for (int i = 0; i < argc; i++) {
        const char *opt = argv[i];
        int t = cli_take_set(&ca->a, argc, argv, &i);
        if (t < 0) return CLI_EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        char err[RD_ERRLEN];
        if (!strcmp(opt, "-h") || !strcmp(opt, "--help")) { print_compare_help(); return -1; }
        else if (!strcmp(opt, "-q") || !strcmp(opt, "--quiet")) ca->quiet = 1;
        else if (!strcmp(opt, "--no-cache")) ca->no_cache = 1;
        else if (!strcmp(opt, "--methods") && has_val) {
            snprintf(ca->methods_buf, sizeof ca->methods_buf, "%s", argv[++i]);
            o->n_methods = split_methods(ca->methods_buf, ca->methods, 8);
            if (o->n_methods <= 0) { fprintf(stderr, "photonmarch compare: --methods %s: expected 1 to 8 names separated by commas\n", argv[i]); return CLI_EXIT_USAGE; }
        } else if (!strcmp(opt, "--equal") && has_val) {
            const char *e = argv[++i];
            if (strcmp(e, "time") && strcmp(e, "spp")) { fprintf(stderr, "photonmarch compare: --equal %s: expected time or spp\n", e); return CLI_EXIT_USAGE; }
            o->equal_spp = !strcmp(e, "spp");
        } else if (!strcmp(opt, "--budget") && has_val) { if (!cli_parse_double(opt, argv[++i], 1e-3, 1e7, &budget)) return CLI_EXIT_USAGE; }
        else if (!strcmp(opt, "--runs") && has_val) { if (!cli_parse_int(opt, argv[++i], 1, 64, &v)) return CLI_EXIT_USAGE; o->runs = (int)v; }
        else if (!strcmp(opt, "--ref-spp") && has_val) { if (!cli_parse_int(opt, argv[++i], 1, 1 << 24, &v)) return CLI_EXIT_USAGE; o->ref_spp = (int)v; }
        else if (!strcmp(opt, "--ref-time") && has_val) { if (!cli_parse_double(opt, argv[++i], 1e-3, 1e7, &o->ref_time)) return CLI_EXIT_USAGE; }
        else if (!strcmp(opt, "--reference") && has_val) o->reference = argv[++i];
        else if (!strcmp(opt, "--cache") && has_val) ca->cache = argv[++i];
        else if (!strcmp(opt, "--seed") && has_val) { if (!cli_parse_int(opt, argv[++i], 0, 0x7fffffffL, &ca->seed)) return CLI_EXIT_USAGE; }
        else if (!strcmp(opt, "--threads") && has_val) { if (!cli_parse_int(opt, argv[++i], 1, 1024, &v)) return CLI_EXIT_USAGE; o->threads = (int)v; }
        else if ((!strcmp(opt, "-o") || !strcmp(opt, "--output")) && has_val) ca->outdir = argv[++i];
        else if (!strcmp(opt, "--add") && has_val) {
            if (o->n_extras >= 8) { fprintf(stderr, "photonmarch compare: --add: at most 8 images\n"); return CLI_EXIT_USAGE; }
            int k = o->n_extras;
            if (rd_cmp_extra_parse(argv[++i], ca->extra_buf[k], sizeof ca->extra_buf[k], &ca->extras[k], err, sizeof err)) {
                fprintf(stderr, "photonmarch compare: %s\n", err);
                return CLI_EXIT_USAGE;
            }
            o->n_extras++;
        } else if (cli_take_positional(&ca->a, "compare", opt)) return CLI_EXIT_USAGE;
    }
    if (cli_need_scene(&ca->a, "compare")) return CLI_EXIT_USAGE;
    if (o->n_methods == 0) { fprintf(stderr, "photonmarch compare: missing --methods (see photonmarch compare --help)\n"); return CLI_EXIT_USAGE; }
    if (o->equal_spp && budget > 0 && (budget != floor(budget) || budget > (1 << 24))) {
        fprintf(stderr, "photonmarch compare: --budget %g: with --equal spp, a whole number of samples\n", budget);
        return CLI_EXIT_USAGE;
    }
    o->budget = budget > 0 ? budget : o->equal_spp ? 64 : 10;
    o->methods = ca->methods;
    o->extras = ca->extras;
    return 0;
}

int cli_cmd_compare(int argc, char **argv) { return cli_cmd_compare_on(argc, argv, NULL); }

/* Several ranks (d, docs/compare.md "On several ranks"): every rank parses and loads the scene;
 * the runs are dealt round the ranks, the reference is rendered by all together
 * (rd_cmp_opts.comm); rank 0 alone prints and writes the report. After each step that can fail
 * the ranks agree, so a failure anywhere ends every rank with a non-zero exit. */
int cli_cmd_compare_on(int argc, char **argv, rd_dist *d)
{
    compare_args *ca = calloc(1, sizeof *ca); /* 44 KB, most of it the --set and --add buffers */
    if (!ca) {
        fprintf(stderr, "photonmarch compare: out of memory\n");
        return CLI_EXIT_INTERNAL;
    }
    ca->seed = -1;
    ca->o.runs = 2;
    int muted = cli_ranks_mute(d);
    int pc = compare_parse(ca, argc, argv);
    pc = cli_ranks_unmute(d, muted, pc == 0 ? -1 : pc < 0 ? 0 : pc);
    if (pc >= 0) {
        free(ca);
        return pc;
    }
    const int lead = rd_dist_rank(d) == 0;
    char defout[1024], cache[1100];
    if (!ca->outdir) {
        char name[1024];
        cli_default_output(ca->a.scene, "", name, sizeof name); /* out/<scene name> */
        snprintf(defout, sizeof defout, "out/compare-%.900s", name + 4);
        ca->outdir = defout;
    }
    /* The reference cache: beside the report folder unless --cache says otherwise. */
    if (!ca->cache) {
        const char *slash = strrchr(ca->outdir, '/');
        snprintf(cache, sizeof cache, "%.*s.photonmarch-cache", slash ? (int)(slash - ca->outdir + 1) : 0, ca->outdir);
        ca->cache = cache;
    }
    ca->o.cache_dir = ca->no_cache ? NULL : ca->cache;

    char err[RD_ERRLEN];
    rd_scene *scene = NULL;
    rd_comparison *cmp = NULL;
    rd_status st;
    int code = cli_ranks_load_scene(d, &ca->a, &scene);
    if (!code && rd_dist_size(d) > 1) { /* the ranks must run one comparison: its options agree */
        char opts[8192];
        const rd_cmp_opts *o = &ca->o;
        int len = snprintf(opts, sizeof opts, "%d|%a|%d|%ld|%s|%d|%a|%s|%d", o->equal_spp, o->budget, o->runs,
                           ca->seed, o->reference ? o->reference : "", o->ref_spp, o->ref_time,
                           o->cache_dir ? o->cache_dir : "", o->n_methods);
        for (int i = 0; i < o->n_methods && len >= 0 && (size_t)len < sizeof opts; i++)
            len += snprintf(opts + len, sizeof opts - (size_t)len, "|%s", o->methods[i]);
        for (int i = 0; i < o->n_extras && len >= 0 && (size_t)len < sizeof opts; i++)
            len += snprintf(opts + len, sizeof opts - (size_t)len, "|%s=%s", o->extras[i].label, o->extras[i].path);
        code = cli_ranks_same_options(d, opts, &ca->a);
    }
    if (!code) { /* only rank 0 writes: a missing image module fails the command now, not at the end */
        st = lead ? rd_image_io_ready(ca->outdir, err, sizeof err) : RD_OK;
        code = cli_ranks_agree(d, cli_exit_for(st), err);
    }
    if (code) goto out;
    ca->o.seed = ca->seed >= 0 ? (uint64_t)ca->seed : rd_scene_seed(scene);
    ca->o.cancel = cli_cancel_flag();
    ca->o.comm = rd_dist_comm(d);
    cli_progress_state ps = {0.0, isatty(2), 0.0};
    if (!ca->quiet && lead) {
        ca->o.progress = compare_progress;
        ca->o.progress_user = &ps;
    }
    cli_on_signal_stop(); /* a signal ends the run in progress; the report is written */
    st = rd_compare_run(scene, &ca->o, &cmp, err, sizeof err); /* several ranks: the same status everywhere */
    if (ca->o.progress && ps.tty) fputc('\n', stderr);
    if ((code = cli_ranks_agree_shared(d, cli_exit_for(st), err)) != 0) goto out;
    const rd_cmp_summary *sum = rd_comparison_summary(cmp);
    if (sum->cancelled && sum->n_rows == 0) { /* (the same on every rank) */
        if (lead) fprintf(stderr, "photonmarch compare: interrupted before any run finished; nothing written\n");
        code = cli_exit_interrupted(cli_interrupted() ? cli_interrupted() : SIGINT);
        goto out;
    }
    st = lead ? rd_compare_write_report(cmp, scene, ca->outdir, err, sizeof err) : RD_OK;
    code = cli_exit_for(st);
    if (code && rd_dist_size(d) <= 1) fprintf(stderr, "%s\n", err);
    if (rd_dist_size(d) > 1) { /* rank 0's outcome to the others */
        int c = cli_ranks_agree(d, code, code ? err : NULL);
        if (!code) code = c;
    }
    if (code) goto out;
    if (lead) {
        rd_compare_print_table(cmp, stdout);
        printf("report %s/index.html\n", ca->outdir);
    }
    if (sum->cancelled) {
        if (lead) fprintf(stderr, "photonmarch compare: interrupted; the report holds the runs that finished\n");
        code = cli_exit_interrupted(cli_interrupted() ? cli_interrupted() : SIGINT);
    }
out:
    rd_comparison_free(cmp);
    rd_scene_free(scene);
    free(ca);
    return code;
}
