/* cmd_bake.c: photonmarch bake, the volume photon map and its SH guide grid traced, baked and
 * saved, with pictures of the photons and guide slices (rd_bake, rd_baked_write). */
#include "cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* bake -o PREFIX writes PREFIX.pmap, .guide, -photons.exr/.png, -slice-A.exr/.png and
 * -cells-A.png (A = x, y, z): none may be the scene. */
static int refuse_bake_outputs(const char *prefix, const char *scene)
{
    static const char *const ext[] = {".pmap", ".guide", "-photons.exr", "-photons.png", "-slice-x.exr",
                                      "-slice-x.png", "-cells-x.png"};
    for (int i = 0; i < 7; i++) {
        for (char axis = 'x'; axis <= (i >= 4 ? 'z' : 'x'); axis++) {
            char path[1100];
            int n = snprintf(path, sizeof path, "%s%s", prefix, ext[i]);
            if (i >= 4) path[n - 5] = axis; /* "-slice-x.exr": the x */
            if (cli_refuse_input_as_output("bake", path, scene)) return CLI_EXIT_USAGE;
        }
    }
    return 0;
}

static const char *const usage_bake =
    "usage: photonmarch bake SCENE [options]\n"
    "\n"
    "Traces the scene's volume photon map (scene key \"photons\"), builds its FLANN kd-tree, bakes\n"
    "the spherical-harmonic guide grid (scene key \"guide\") and writes, for PREFIX (default\n"
    "out/<scene name>):\n"
    "  PREFIX.pmap                the photon map (docs/photonmap-format.md)\n"
    "  PREFIX.guide               the guide grid (docs/guide-grid.md)\n"
    "  PREFIX-photons.exr/.png    photon power projected through the scene camera\n"
    "  PREFIX-slice-A.exr/.png    a slice of the guide across axis A, evaluated toward --toward\n"
    "  PREFIX-cells-A.png         the same slice showing cell extinction (uniform) or depth (adaptive)\n"
    "Ctrl-C or SIGTERM while tracing or baking stops at once and writes nothing, leaving the\n"
    "previous files as they were (exit 130 / 143); once the files are being written, they are\n"
    "finished first.\n"
    "\n"
    "options:\n"
    "  -o, --output PREFIX    output prefix\n"
    "  --photons N            photons to emit (default: photons.count)\n"
    "  --seed N               photon seed (default: photons.seed)\n"
    "  --threads N            worker threads (default: all cores); results do not depend on it\n"
    "  --load-photons FILE    reuse a saved photon map instead of tracing\n"
    "  --no-guide             stop after the photon map\n"
    "  --slice A[=C]          slice axis x, y or z at coordinate C (default: the media centre);\n"
    "                         repeatable (default: z)\n"
    "  --toward X,Y,Z         direction the slice radiance leaves in (default: toward the camera)\n"
    "  --stats                print counts, memory, tracing rate, index and bake times\n"
    "  --set KEY=VALUE        override a scene field (repeatable)\n"
    "  -q, --quiet            print only errors\n"
    "\n"
    "bake writes the full bake, the one guided, uniform and transmittance use. A method that\n"
    "bakes something else for itself renders from its own cached bake unless given files:\n"
    "guided-unbiased traces guide.photon_share of the photons and leaves out the light a point,\n"
    "spot or directional light sends through glass (docs/guided-unbiased.md, \"The guide holds\n"
    "only light the paths can reach\"). Given bake's files with render --photons/--guide it uses\n"
    "them as they are: its guide only steers, so the image stays the same in expectation.\n";

static void print_bake_stats(const rd_bake_stats *b)
{
    printf("photons    emitted %zu, stored %zu, segments %zu%s\n", b->emitted, b->stored, b->segments,
           b->loaded ? " (loaded)" : "");
    printf("memory     %.2f MiB (%.1f bytes per photon, index included)\n", b->map_bytes / 1048576.0,
           b->stored ? (double)b->map_bytes / b->stored : 0.0);
    if (!b->loaded) {
        printf("tracing    %.3f s, %.0f photons/s emitted, %.2f tentative collisions per photon\n", b->trace_seconds,
               b->trace_seconds > 0 ? b->emitted / b->trace_seconds : 0.0, b->collisions_per_photon);
        if (b->ranks > 1)
            printf("gather     %d ranks traced a range each: %.3f s to gather, %.2f MiB received by each rank "
                   "(%.1f bytes per photon emitted)\n", b->ranks, b->gather_seconds, b->gather_bytes / 1048576.0,
                   b->emitted ? (double)b->gather_bytes / b->emitted : 0.0);
        if (b->power_absorbed_surfaces > 0.0)
            printf("power      emitted %.4g W = absorbed %.4g + by surfaces %.4g + escaped %.4g + cut at max depth %.4g (luminance)\n",
                   b->power_emitted, b->power_absorbed, b->power_absorbed_surfaces, b->power_escaped, b->power_cut);
        else
            printf("power      emitted %.4g W = absorbed %.4g + escaped %.4g + cut at max depth %.4g (luminance)\n",
                   b->power_emitted, b->power_absorbed, b->power_escaped, b->power_cut);
    }
    printf("index      FLANN kd-tree built in %.3f s\n", b->index_seconds);
}

static void print_guide_line(const rd_bake_stats *b)
{
    printf("guide      %s grid, %s bake, %d bands, %zu cells", b->adaptive ? "adaptive" : "uniform",
           b->track ? "track-length" : "k-NN", b->bands, b->cells);
    if (!b->adaptive) printf(" (%dx%dx%d)", b->res[0], b->res[1], b->res[2]);
    else printf(" (depth %d, cell edge %.3g-%.3g m)", b->depth_max, b->cell_min, b->cell_max);
    printf(", %.2f MiB, baked in %.3f s\n", b->guide_bytes / 1048576.0, b->guide_seconds);
}

/* --toward X,Y,Z: three numbers, a non-zero finite direction, normalised. */
static int parse_toward(const char *v, double t[3])
{
    char *end = (char *)v;
    int n = 0;
    for (; n < 3; n++) {
        const char *start = n == 0 ? end : end + 1;
        if (n > 0 && *end != ',') break;
        t[n] = strtod(start, &end);
        if (end == start) break;
    }
    double len = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    if (n != 3 || *end || !(len > 0) || !isfinite(len)) {
        fprintf(stderr, "photonmarch bake: --toward %s: expected X,Y,Z, a non-zero direction\n", v);
        return 0;
    }
    for (int k = 0; k < 3; k++) t[k] /= len;
    return 1;
}

/* The command line of bake, parsed. */
typedef struct {
    cli_scene_args a;
    const char *prefix;
    int stats, quiet;
    rd_bake_opts bo;
    rd_bake_write_opts wo;
    char defprefix[1024];
} bake_args;

/* Parse argv into *r: -1 to go on, else the exit code (after a message, or --help). */
static int parse_bake(int argc, char **argv, bake_args *r)
{
    cli_scene_args *a = &r->a;
    rd_bake_opts *bo = &r->bo;
    rd_bake_write_opts *wo = &r->wo;
    const char *prefix = NULL;
    long photons = -1, seed = -1, threads = 0;
    for (int i = 0; i < argc; i++) {
        const char *o = argv[i];
        int t = cli_take_set(a, argc, argv, &i);
        if (t < 0) return CLI_EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        if (!strcmp(o, "-h") || !strcmp(o, "--help")) { fputs(usage_bake, stdout); return 0; }
        else if (!strcmp(o, "-q") || !strcmp(o, "--quiet")) r->quiet = 1;
        else if (!strcmp(o, "--stats")) r->stats = 1;
        else if (!strcmp(o, "--no-guide")) bo->no_guide = 1;
        else if ((!strcmp(o, "-o") || !strcmp(o, "--output")) && has_val) prefix = argv[++i];
        else if (!strcmp(o, "--load-photons") && has_val) bo->load_photons = argv[++i];
        else if (!strcmp(o, "--photons") && has_val) { if (!cli_parse_int(o, argv[++i], 1, 1000000000L, &photons)) return CLI_EXIT_USAGE; }
        else if (!strcmp(o, "--seed") && has_val) { if (!cli_parse_int(o, argv[++i], 0, 0x7fffffffL, &seed)) return CLI_EXIT_USAGE; }
        else if (!strcmp(o, "--threads") && has_val) { if (!cli_parse_int(o, argv[++i], 1, 1024, &threads)) return CLI_EXIT_USAGE; }
        else if (!strcmp(o, "--toward") && has_val) {
            if (!parse_toward(argv[++i], wo->toward)) return CLI_EXIT_USAGE;
            wo->has_toward = 1;
        } else if (!strcmp(o, "--slice") && has_val) {
            const char *v = argv[++i];
            int k = wo->nslices;
            if (k >= 8 || !v[0] || !strchr("xyz", v[0]) || (v[1] && v[1] != '=')) {
                fprintf(stderr, "photonmarch bake: --slice %s: expected x, y or z, optionally =COORD (at most 8)\n", v);
                return CLI_EXIT_USAGE;
            }
            wo->slice_axis[k] = v[0];
            wo->slice_has_at[k] = v[1] == '=';
            if (wo->slice_has_at[k] && !cli_parse_double("--slice", v + 2, -1e9, 1e9, &wo->slice_at[k])) return CLI_EXIT_USAGE;
            wo->nslices++;
        } else if (cli_take_positional(a, "bake", o)) return CLI_EXIT_USAGE;
    }
    if (cli_need_scene(a, "bake")) return CLI_EXIT_USAGE;
    if (!prefix) {
        cli_default_output(a->scene, "", r->defprefix, sizeof r->defprefix);
        prefix = r->defprefix;
    }
    if (strlen(prefix) > 1000) {
        fprintf(stderr, "photonmarch bake: -o: path too long\n");
        return CLI_EXIT_USAGE;
    }
    if (refuse_bake_outputs(prefix, a->scene)) return CLI_EXIT_USAGE;
    r->prefix = prefix;
    bo->photons = photons > 0 ? (size_t)photons : 0;
    bo->seed = seed;
    bo->threads = (int)threads;
    wo->write_map = !bo->load_photons;
    return -1;
}

int cli_cmd_bake(int argc, char **argv) { return cli_cmd_bake_on(argc, argv, NULL); }

/* Several ranks (d, docs/cluster.md): every rank parses and loads the scene, the ranks trace the
 * photons together (rd_bake_opts.comm: each a range of them, gathered on every rank) and each
 * builds the same index and guide; rank 0 alone prints and writes the files. After each step
 * that can fail the ranks agree, so a failure anywhere ends every rank with a non-zero exit. */
int cli_cmd_bake_on(int argc, char **argv, rd_dist *d)
{
    bake_args *r = calloc(1, sizeof *r);
    if (!r) {
        fprintf(stderr, "photonmarch bake: out of memory\n");
        return CLI_EXIT_INTERNAL;
    }
    int muted = cli_ranks_mute(d);
    int pc = cli_ranks_unmute(d, muted, parse_bake(argc, argv, r));
    if (pc >= 0) {
        free(r);
        return pc;
    }
    const int lead = rd_dist_rank(d) == 0;
    const char *prefix = r->prefix;
    int stats = r->stats, quiet = r->quiet || !lead;
    rd_bake_opts bo = r->bo;
    cli_on_signal_quit(); /* while the scene loads, a signal ends the process at once */

    char err[RD_ERRLEN];
    rd_scene *s = NULL;
    rd_status st;
    int code = cli_ranks_load_scene(d, &r->a, &s);
    if (!code && rd_dist_size(d) > 1) { /* the ranks must bake one map: the options that decide it agree */
        char opts[2048];
        snprintf(opts, sizeof opts, "%zu|%lld|%d|%s", bo.photons, bo.seed, bo.no_guide,
                 bo.load_photons ? bo.load_photons : "");
        code = cli_ranks_same_options(d, opts, &r->a);
    }
    rd_baked *b = NULL;
    if (code) goto done;
    cli_on_signal_cancel(); /* a signal stops the tracing and the guide bake: nothing written */
    bo.cancel = cli_cancel_flag();
    bo.comm = rd_dist_comm(d);
    if (!quiet) fprintf(stderr, "photonmarch bake: tracing and baking (Ctrl-C stops and writes nothing)\n");
    /* (the image module first: a bake writes its photons' picture, so a missing module fails it
     * before the bake, and before any folder is made) */
    st = lead ? rd_image_io_ready(prefix, err, sizeof err) : RD_OK;
    if (st == RD_OK && lead) st = rd_make_parent_dirs(prefix, err, sizeof err);
    if ((code = cli_ranks_agree(d, cli_exit_for(st), err)) != 0) goto done;
    st = rd_bake(s, &bo, &b, err, sizeof err); /* several ranks: the same status on every rank */
    if (st == RD_ERR_CANCELLED || (st == RD_OK && cli_interrupted())) {
        /* (after the bake's last check: still nothing written) */
        code = lead ? cli_report_cancelled("bake", "while baking")
                    : cli_exit_interrupted(cli_interrupted() ? cli_interrupted() : SIGINT);
        code = cli_ranks_agree(d, code, NULL);
        goto done;
    }
    if ((code = cli_ranks_agree_shared(d, cli_exit_for(st), err)) != 0) goto done;
    const rd_bake_stats *bs = rd_baked_stats(b);
    if (stats && lead) print_bake_stats(bs);
    if (bs->has_guide && (stats || !quiet) && lead) print_guide_line(bs);
    cli_on_signal_stop(); /* a signal now lets the files being written finish */
    st = lead ? rd_baked_write(b, s, prefix, &r->wo, err, sizeof err) : RD_OK;
    if (st != RD_OK) {
        code = st == RD_ERR_ARG ? CLI_EXIT_USAGE : cli_exit_for(st);
        if (rd_dist_size(d) <= 1) fprintf(stderr, "%s\n", err);
    }
    if (rd_dist_size(d) > 1) { /* rank 0's outcome to the others */
        int c = cli_ranks_agree(d, code, code ? err : NULL);
        if (!code) code = c;
    }
    if (code) goto done;
    if (!quiet) {
        if (r->wo.write_map) printf("photons    %s.pmap\n", prefix);
        printf("picture    %s-photons.png\n", prefix);
        if (bs->has_guide) printf("guide      %s.guide\nslices     %s-slice-*.png, %s-cells-*.png\n", prefix, prefix, prefix);
    }
    if (cli_interrupted()) code = cli_exit_interrupted(cli_interrupted());
done:
    rd_baked_free(b);
    rd_scene_free(s);
    free(r);
    return code;
}
