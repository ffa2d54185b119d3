/* main.c: the photonmarch command line (docs/cli.md). A thin layer over renderer.h: it parses
 * options, reports errors as one line on stderr, and decides the exit code.
 *
 * Exit codes: 0 success; 1 usage error (unknown command or option, bad option value);
 * 2 invalid input (scene, volume or other input file); 3 output could not be written;
 * 4 internal error; 128 + N after signal N: 130 for SIGINT (Ctrl-C), 143 for SIGTERM (what was
 * rendered so far was written). */
#define _DEFAULT_SOURCE /* mkdir, isatty */
#include "renderer.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

enum { EXIT_USAGE = 1, EXIT_INPUT = 2, EXIT_OUTPUT = 3, EXIT_INTERNAL = 4 };

/* The one piece of mutable global state: the number of the first SIGINT or SIGTERM received
 * (0: none yet). Set by on_signal_stop, polled between pixels through rd_render_opts.cancel. */
static volatile sig_atomic_t interrupted = 0;

/* Both signals get one treatment (docs/cli.md, "Signals"). While a handler runs, the other
 * signal is blocked (sa_mask), so a SIGINT and a SIGTERM arriving together count as a first and a
 * second signal, not as two firsts. */
static void handle_stop_signals(void (*fn)(int))
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = fn;
    sigemptyset(&sa.sa_mask);
    sigaddset(&sa.sa_mask, SIGINT);
    sigaddset(&sa.sa_mask, SIGTERM);
    sa.sa_flags = SA_RESTART;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    /* A blocked mask is inherited through exec: unblock them, or they would never arrive. */
    sigset_t both;
    sigemptyset(&both);
    sigaddset(&both, SIGINT);
    sigaddset(&both, SIGTERM);
    sigprocmask(SIG_UNBLOCK, &both, NULL);
}

/* While there is something to write (a render's passes and the writing of any outputs): note
 * the signal, then let the next one end the process at once (default action). Only
 * async-signal-safe calls here (sigaction, write, raise; POSIX.1-2008 2.4.3). Every output goes
 * through a temporary name and a rename, so being killed mid-write keeps the previous files. */
static void on_signal_stop(int sig)
{
    static const char msg[] = "\nphotonmarch: stopping; writing what it has (a second Ctrl-C or SIGTERM ends at once)\n";
    static const struct sigaction dfl = {.sa_handler = SIG_DFL};
    /* Two threads can take a SIGINT and a SIGTERM at the same moment, each running this
     * handler: only the one that turns `interrupted` from 0 to its signal (atomically; a
     * lock-free compare-and-swap is async-signal-safe) is the first. The other is a second
     * signal: with its default action back, re-raised, it ends the process when this returns. */
    if (!__sync_bool_compare_and_swap(&interrupted, 0, sig)) {
        sigaction(sig, &dfl, NULL);
        raise(sig);
        return;
    }
    sigaction(SIGINT, &dfl, NULL);
    sigaction(SIGTERM, &dfl, NULL);
    ssize_t r = write(STDERR_FILENO, msg, sizeof msg - 1);
    (void)r;
}

/* Before there is anything to write (loading the scene, tracing and baking, which cannot stop
 * part-way): end at once with the documented status. */
static void on_signal_quit(int sig)
{
    static const char msg[] = "\nphotonmarch: interrupted before anything was rendered; nothing written\n";
    ssize_t r = write(STDERR_FILENO, msg, sizeof msg - 1);
    (void)r;
    _exit(128 + sig);
}

/* The exit status after signal `sig`: 128 + its number, the shell's convention (130 SIGINT,
 * 143 SIGTERM). */
static int exit_interrupted(int sig) { return 128 + sig; }

/* 1 when `out` names the same existing file as the input `in` (after symbolic links), so
 * writing it would replace the input. */
static int same_file(const char *out, const char *in)
{
    struct stat so, si;
    return stat(out, &so) == 0 && stat(in, &si) == 0 && so.st_dev == si.st_dev && so.st_ino == si.st_ino;
}

/* Refuse an output path that is the input scene (exit 1 after a message). */
static int refuse_input_as_output(const char *cmd, const char *out, const char *scene)
{
    if (!same_file(out, scene)) return 0;
    fprintf(stderr, "photonmarch %s: %s is the input scene %s; choose another output (-o)\n", cmd, out, scene);
    return EXIT_USAGE;
}

/* render -o OUT.exr writes OUT.exr, OUT-stderr.exr, OUT.png and OUT.json: none may be the scene
 * (`render scene.json -o scene.exr` would replace it with the report). */
static int refuse_render_outputs(const char *exr, const char *scene)
{
    static const char *const ext[] = {".exr", "-stderr.exr", ".png", ".json"};
    size_t stem = strlen(exr) - 4;
    for (int i = 0; i < 4; i++) {
        char path[1100];
        snprintf(path, sizeof path, "%.*s%s", (int)stem, exr, ext[i]);
        if (refuse_input_as_output("render", path, scene)) return EXIT_USAGE;
    }
    return 0;
}

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
            if (refuse_input_as_output("bake", path, scene)) return EXIT_USAGE;
        }
    }
    return 0;
}

static const char *usage_main =
    "photonmarch: a renderer for participating media (volume photon map guided ray marching\n"
    "and unbiased delta tracking).\n"
    "\n"
    "usage: photonmarch COMMAND [options]\n"
    "\n"
    "commands:\n"
    "  render SCENE   render a scene to a linear EXR, an sRGB PNG preview and a JSON report\n"
    "  info SCENE     describe media, bounds, density range, lights, majorants and memory\n"
    "  voxelize SCENE sample a medium's density into an OpenVDB (.vdb) or raw (.raw) grid\n"
    "  bake SCENE     trace the volume photon map and bake its SH guide grid; save both and\n"
    "                 write pictures of where the light went and of guide slices\n"
    "  compare SCENE  render with several methods at equal time or samples, K runs each, and\n"
    "                 write a report (HTML page, metrics.json, error maps, convergence plot)\n"
    "  explain SCENE --pixel X,Y\n"
    "                 lay one camera ray open: the integrand along it, where guided,\n"
    "                 transmittance and uniform marching put their samples, their variances\n"
    "\n"
    "  photonmarch COMMAND --help   shows the options of a command\n"
    "  photonmarch --version        prints the version\n"
    "\n"
    "exit codes: 0 success, 1 usage error, 2 invalid input (scene or data file),\n"
    "            3 output not written, 4 internal error, 130 / 143 interrupted by SIGINT (Ctrl-C)\n"
    "            / SIGTERM (the image so far written)\n"
    "\n"
    "docs: docs/cli.md (this reference), docs/scene-format.md (the scene file)\n";

static const char *usage_explain =
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
    "up to the first surface it meets.\n"
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

static const char *usage_compare =
    "usage: photonmarch compare SCENE --methods A,B[,...] [options]\n"
    "\n"
    "Renders SCENE with every method K times (seeds seed+1..seed+K) at equal time or equal\n"
    "samples, measures each against a reference (docs/compare.md) and writes the report folder\n"
    "DIR: index.html (opens from disk: A/B/reference toggle, error maps, worst-region crops,\n"
    "metrics table, convergence plot), metrics.json, convergence.svg (gnuplot), and the EXR and\n"
    "PNG images. Prints progress on stderr and the metrics table on stdout. Ctrl-C stops the\n"
    "run in progress and writes the report of the runs that finished (exit 130).\n"
    "\n"
    "options:\n"
    "  --methods A,B     methods to compare (listed below)\n"
    "  --equal time|spp  what every method gets the same of (default: time)\n"
    "  --budget X        per run: seconds with --equal time (default 10; a method's bake is\n"
    "                    done once and its time is charged to each of its runs), samples per\n"
    "                    pixel with --equal spp (default 64)\n"
    "  --runs K          independent runs per method, for bias^2 and variance (default 2)\n"
    "  --reference REF.exr   the converged image to measure against (REF-stderr.exr beside it,\n"
    "                    if present, gives its own noise); default: rendered with delta and\n"
    "                    cached (see --ref-spp, --cache)\n"
    "  --ref-spp N       samples per pixel of the rendered reference (default 1024)\n"
    "  --ref-time S      time cap of the rendered reference in seconds (default: none)\n"
    "  --cache DIR       where the rendered reference is cached (default: .photonmarch-cache\n"
    "                    beside the report folder), named by a hash of the scene's content and\n"
    "                    the reference settings\n"
    "  --no-cache        render the reference afresh and do not cache it\n"
    "  --add LABEL=IMAGE.exr[@SECONDS]   an image from another renderer, with its render time\n"
    "                    (repeatable); measured like the methods (no runs: no bias/variance)\n"
    "  --seed N          base seed (default: settings.seed)\n"
    "  --threads N       worker threads (default: all cores)\n"
    "  -o, --output DIR  report folder (default: out/compare-<scene name>)\n"
    "  --set KEY=VALUE   override a scene field before validation (repeatable)\n"
    "  -q, --quiet       no progress\n"
    "  -h, --help        this text\n";

static const char *usage_render =
    "usage: photonmarch render SCENE [options]\n"
    "\n"
    "Renders SCENE (JSON, docs/scene-format.md). Writes OUT.exr (linear float RGB), OUT.png\n"
    "(sRGB preview, scaled by 2^camera.exposure) and OUT.json (method, samples, time, counters).\n"
    "Files are written under a temporary name and renamed, so a failed run never destroys a\n"
    "good image. Ctrl-C or SIGTERM (or the time limit) stops before the next pixel and writes\n"
    "what it has (exit 130 for Ctrl-C, 143 for SIGTERM); a second signal ends it at once; the\n"
    "per-pixel sample counts are in the report.\n"
    "\n"
    "options:\n"
    "  --method M        rendering method (default: settings.method, else delta); the methods\n"
    "                    are listed below\n"
    "  --spp N           samples per pixel (default: settings.spp)\n"
    "  --time S          stop after S seconds, bake included (checked before every pixel,\n"
    "                    so the budget is kept to within a pixel's work); with --spp, the\n"
    "                    first limit reached stops the render\n"
    "  --seed N          random seed (default: settings.seed); same seed, same image on any\n"
    "                    number of threads\n"
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
    "  -q, --quiet       no progress and no summary\n"
    "  -h, --help        this text\n";

static const char *usage_info =
    "usage: photonmarch info SCENE [--set KEY=VALUE ...]\n"
    "\n"
    "Loads and validates SCENE and describes it: camera, media (kind, bounds, density range,\n"
    "sigma_t scale, albedo, g, majorant), lights (kind, parameters, power), settings, memory.\n";

static const char *usage_bake =
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
    "  -q, --quiet            print only errors\n";

static const char *usage_voxelize =
    "usage: photonmarch voxelize SCENE -o OUT.vdb|OUT.raw [options]\n"
    "\n"
    "Samples the density of one medium at voxel centres over its bounds and writes it as an\n"
    "OpenVDB float grid named \"density\" (cubic voxels, the transform places it where the medium\n"
    "is) or as a raw float32 grid (docs/scene-format.md; the dims to use are printed).\n"
    "\n"
    "options:\n"
    "  -o, --output OUT   .vdb or .raw (required)\n"
    "  --medium I         which medium (default 0)\n"
    "  --res N            voxels along the longest axis (default 64, at most 1024)\n"
    "  --set KEY=VALUE    override a scene field (repeatable)\n";


static int parse_int(const char *opt, const char *s, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi) {
        fprintf(stderr, "photonmarch: %s: expected an integer in [%ld, %ld], got \"%s\"\n", opt, lo, hi, s);
        return 0;
    }
    *out = v;
    return 1;
}

static int parse_double(const char *opt, const char *s, double lo, double hi, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || end == s || *end || !(v >= lo && v <= hi)) {
        fprintf(stderr, "photonmarch: %s: expected a number in [%g, %g], got \"%s\"\n", opt, lo, hi, s);
        return 0;
    }
    *out = v;
    return 1;
}

static int exit_for(rd_status st)
{
    switch (st) {
    case RD_OK: return 0;
    case RD_ERR_ARG: return EXIT_USAGE;
    case RD_ERR_IO:
    case RD_ERR_PARSE:
    case RD_ERR_SCENE:
    case RD_ERR_FORMAT: return EXIT_INPUT;
    case RD_ERR_OUTPUT: return EXIT_OUTPUT;
    default: return EXIT_INTERNAL;
    }
}

/* Options shared by the commands that load a scene. */
typedef struct {
    const char *scene;
    rd_override ov[64];
    int nov;
    char ovbuf[64][512];
} scene_args;

/* Consume --set at argv[*i]; returns 1 if handled, 0 if not --set, -1 on error. */
static int take_set(scene_args *a, int argc, char **argv, int *i)
{
    if (strcmp(argv[*i], "--set") != 0) return 0;
    if (*i + 1 >= argc) {
        fprintf(stderr, "photonmarch: --set: expected KEY=VALUE\n");
        return -1;
    }
    const char *kv = argv[++*i];
    const char *eq = strchr(kv, '=');
    if (!eq || eq == kv || a->nov >= 64 || strlen(kv) >= sizeof a->ovbuf[0]) {
        fprintf(stderr, "photonmarch: --set %s: expected KEY=VALUE (at most 64 of them)\n", kv);
        return -1;
    }
    char *buf = a->ovbuf[a->nov];
    snprintf(buf, sizeof a->ovbuf[0], "%s", kv);
    buf[eq - kv] = 0;
    a->ov[a->nov].key = buf;
    a->ov[a->nov].value = buf + (eq - kv) + 1;
    a->nov++;
    return 1;
}

/* The positional SCENE, or an unknown option: returns 0 when taken, EXIT_USAGE after a message. */
static int take_positional(scene_args *a, const char *cmd, const char *o)
{
    if (o[0] == '-') {
        fprintf(stderr, "photonmarch %s: %s: unknown option or missing value (see photonmarch %s --help)\n", cmd, o, cmd);
        return EXIT_USAGE;
    }
    if (a->scene) {
        fprintf(stderr, "photonmarch %s: %s: only one scene per run\n", cmd, o);
        return EXIT_USAGE;
    }
    a->scene = o;
    return 0;
}

static int need_scene(const scene_args *a, const char *cmd)
{
    if (a->scene) return 0;
    fprintf(stderr, "photonmarch %s: missing SCENE (see photonmarch %s --help)\n", cmd, cmd);
    return EXIT_USAGE;
}

/* out/<scene file name without extension><suffix> */
static void default_output(const char *scene, const char *suffix, char *out, size_t n)
{
    const char *base = strrchr(scene, '/');
    base = base ? base + 1 : scene;
    const char *dot = strrchr(base, '.');
    snprintf(out, n, "out/%.*s%s", dot && dot != base ? (int)(dot - base) : (int)strlen(base), base, suffix);
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

static double wall_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* Progress: on a terminal one line rewritten after every pass; elsewhere (logs, batch systems)
 * a line after the first pass and then at most every 10 s. */
typedef struct {
    double time_limit;
    int tty;
    double last_print;
} progress_state;

static void progress(void *user, int done, int total, double seconds)
{
    progress_state *ps = user;
    double eta = done > 0 ? seconds * (total - done) / done : 0.0;
    if (ps->time_limit > 0 && ps->time_limit - seconds < eta) eta = fmax(0.0, ps->time_limit - seconds);
    if (!ps->tty) {
        double now = wall_seconds();
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

static int report_error(rd_status st, const char *err)
{
    fprintf(stderr, "%s\n", err);
    return exit_for(st);
}

/* Bake what `bo` asks for through the cache folder beside `out` (OUT's folder, then
 * .photonmarch-cache), or afresh with `fresh`; a cache that cannot be saved is a warning. */
static rd_status bake_beside(const rd_scene *scene, const rd_bake_opts *bo, const char *out, int fresh,
                             int quiet, rd_baked **baked, char *err, size_t errlen)
{
    if (fresh) return rd_bake(scene, bo, baked, err, errlen);
    char dir[1100];
    const char *slash = strrchr(out, '/');
    snprintf(dir, sizeof dir, "%.*s.photonmarch-cache", slash ? (int)(slash - out + 1) : 0, out);
    int hit = 0;
    rd_status st = rd_bake_cached(scene, bo, dir, baked, &hit, err, errlen);
    if (st == RD_OK && hit < 0 && !quiet) fprintf(stderr, "warning: %s\n", err);
    if (st == RD_OK && !quiet)
        fprintf(stderr, "%s photon map and guide (%s)\n", hit > 0 ? "reused the cached" : "baked the", dir);
    return st;
}

static int cmd_render(int argc, char **argv)
{
    scene_args a = {0};
    const char *method = NULL, *outpath = NULL, *refpath = NULL, *photons_path = NULL, *guide_path = NULL;
    long spp = -1, seed = -1, threads = 0;
    double time_limit = -1;
    int quiet = 0, no_cache = 0;
    for (int i = 0; i < argc; i++) {
        const char *o = argv[i];
        int t = take_set(&a, argc, argv, &i);
        if (t < 0) return EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        if (!strcmp(o, "-h") || !strcmp(o, "--help")) { print_render_help(); return 0; }
        else if (!strcmp(o, "-q") || !strcmp(o, "--quiet")) quiet = 1;
        else if (!strcmp(o, "--method") && has_val) method = argv[++i];
        else if (!strcmp(o, "--reference") && has_val) refpath = argv[++i];
        else if (!strcmp(o, "--photons") && has_val) photons_path = argv[++i];
        else if (!strcmp(o, "--guide") && has_val) guide_path = argv[++i];
        else if (!strcmp(o, "--no-cache")) no_cache = 1;
        else if (!strcmp(o, "--spp") && has_val) { if (!parse_int(o, argv[++i], 1, 1 << 24, &spp)) return EXIT_USAGE; }
        else if (!strcmp(o, "--time") && has_val) { if (!parse_double(o, argv[++i], 0.001, 1e7, &time_limit)) return EXIT_USAGE; }
        else if (!strcmp(o, "--seed") && has_val) { if (!parse_int(o, argv[++i], 0, 0x7fffffffL, &seed)) return EXIT_USAGE; }
        else if (!strcmp(o, "--threads") && has_val) { if (!parse_int(o, argv[++i], 1, 1024, &threads)) return EXIT_USAGE; }
        else if ((!strcmp(o, "-o") || !strcmp(o, "--output")) && has_val) outpath = argv[++i];
        else if (take_positional(&a, "render", o)) return EXIT_USAGE;
    }
    if (need_scene(&a, "render")) return EXIT_USAGE;
    char defout[1024];
    if (!outpath) {
        default_output(a.scene, ".exr", defout, sizeof defout);
        outpath = defout;
    }
    size_t olen = strlen(outpath);
    if (olen < 5 || strcmp(outpath + olen - 4, ".exr") != 0 || olen > 1000) {
        fprintf(stderr, "photonmarch render: -o %s: expected a path ending in .exr\n", outpath);
        return EXIT_USAGE;
    }
    if (refuse_render_outputs(outpath, a.scene)) return EXIT_USAGE;
    handle_stop_signals(on_signal_quit); /* nothing to save until the passes begin */

    char err[RD_ERRLEN];
    rd_scene *scene;
    rd_status st = rd_scene_load(&scene, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) return report_error(st, err);
    rd_image ref = {0, 0, NULL, 0};
    if (refpath && (st = rd_image_read(refpath, &ref, err, sizeof err)) != RD_OK) {
        rd_scene_free(scene);
        return report_error(st, err);
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
    ro.cancel = &interrupted;
    ro.reference = refpath ? &ref : NULL;
    progress_state ps = {ro.time_limit, isatty(2), 0.0};
    if (!quiet) {
        ro.progress = progress;
        ro.progress_user = &ps;
    }
    int code = 0;
    rd_baked *baked = NULL; /* before the first goto out, which frees it */
    if ((st = rd_make_parent_dirs(outpath, err, sizeof err)) != RD_OK) {
        code = report_error(st, err);
        goto out;
    }
    /* What the method needs baked: from --photons/--guide, the cache, or a fresh bake. */
    unsigned needs = rd_method_needs_for(ro.method, scene);
    if (needs) {
        rd_bake_opts bo = {0};
        bo.seed = -1;
        bo.threads = (int)threads;
        rd_bake_opts_for(&bo, needs);
        bo.load_photons = photons_path;
        bo.load_guide = guide_path;
        double t0 = wall_seconds();
        st = bake_beside(scene, &bo, outpath, photons_path || guide_path || no_cache, quiet, &baked, err, sizeof err);
        if (st) {
            code = report_error(st, err);
            goto out;
        }
        ro.baked = baked;
        ro.baked_seconds = wall_seconds() - t0;
    }
    handle_stop_signals(on_signal_stop); /* from here on, a signal stops and writes what it has */
    rd_render_result res;
    st = rd_render(scene, &ro, &res, err, sizeof err);
    if (ro.progress && ps.tty) fputc('\n', stderr);
    if (refpath && st == RD_ERR_ARG) { /* the only argument rd_render checks against a file */
        fprintf(stderr, "%s: %s\n", refpath, err);
        code = EXIT_INPUT;
        goto out;
    }
    if (st) {
        code = report_error(st, err);
        goto out;
    }
    if (res.stats.spp_mean <= 0.0 && !res.stats.cancelled) {
        fprintf(stderr, "photonmarch render: --time %g: the time ran out before any pixel was sampled (the bake took "
                        "%.1f s); nothing written\n", ro.time_limit, res.stats.bake_seconds);
        code = EXIT_USAGE;
    } else if (res.stats.spp_mean <= 0.0) {
        fprintf(stderr, "photonmarch render: interrupted before any pixel was sampled; nothing written\n");
        code = exit_interrupted(interrupted);
    } else if ((st = rd_render_write(scene, &ro, &res, outpath, err, sizeof err)) != RD_OK) {
        code = report_error(st, err);
    } else {
        if (!quiet) {
            const rd_render_stats *rs = &res.stats;
            double paths = rs->paths ? (double)rs->paths : 1.0;
            fprintf(stderr, "%s: %.4g spp in %.2f s (%.0f paths/s, %.2f collisions/path, %.2f lookups/path)%s%s\n",
                    ro.method, rs->spp_mean, rs->seconds, rs->seconds > 0 ? rs->paths / rs->seconds : 0.0,
                    rs->collisions / paths, rs->lookups / paths, rs->cancelled ? " [interrupted]" : "",
                    rs->timed_out ? " [time limit]" : "");
            if (rs->invalid) fprintf(stderr, "warning: %llu non-finite samples were dropped\n", (unsigned long long)rs->invalid);
            char base[1100];
            snprintf(base, sizeof base, "%.*s", (int)(strlen(outpath) - 4), outpath);
            printf("image  %s\nstderr %s-stderr.exr\npng    %s.png\nreport %s.json\n", outpath, base, base, base);
        }
        /* A signal that came after the last pixel still says so in the status. */
        if (interrupted) code = exit_interrupted(interrupted);
    }
    rd_render_result_free(&res);
out:
    rd_baked_free(baked);
    rd_image_free_pixels(&ref);
    rd_scene_free(scene);
    return code;
}

static int cmd_info(int argc, char **argv)
{
    scene_args a = {0};
    for (int i = 0; i < argc; i++) {
        int t = take_set(&a, argc, argv, &i);
        if (t < 0) return EXIT_USAGE;
        if (t) continue;
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) { fputs(usage_info, stdout); return 0; }
        if (take_positional(&a, "info", argv[i])) return EXIT_USAGE;
    }
    if (need_scene(&a, "info")) return EXIT_USAGE;
    char err[RD_ERRLEN];
    rd_scene *scene;
    rd_status st = rd_scene_load(&scene, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) return report_error(st, err);
    rd_scene_info(scene, stdout);
    rd_scene_free(scene);
    return 0;
}

static int cmd_voxelize(int argc, char **argv)
{
    scene_args a = {0};
    const char *outpath = NULL;
    long medium = 0, res = 64;
    for (int i = 0; i < argc; i++) {
        const char *o = argv[i];
        int t = take_set(&a, argc, argv, &i);
        if (t < 0) return EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        if (!strcmp(o, "-h") || !strcmp(o, "--help")) { fputs(usage_voxelize, stdout); return 0; }
        else if ((!strcmp(o, "-o") || !strcmp(o, "--output")) && has_val) outpath = argv[++i];
        else if (!strcmp(o, "--medium") && has_val) { if (!parse_int(o, argv[++i], 0, 63, &medium)) return EXIT_USAGE; }
        else if (!strcmp(o, "--res") && has_val) { if (!parse_int(o, argv[++i], 1, 1024, &res)) return EXIT_USAGE; }
        else if (take_positional(&a, "voxelize", o)) return EXIT_USAGE;
    }
    size_t olen = outpath ? strlen(outpath) : 0;
    int vdb = olen > 4 && !strcmp(outpath + olen - 4, ".vdb"), raw = olen > 4 && !strcmp(outpath + olen - 4, ".raw");
    if (!a.scene || !(vdb || raw)) {
        fprintf(stderr, "photonmarch voxelize: need SCENE and -o OUT.vdb or OUT.raw (see photonmarch voxelize --help)\n");
        return EXIT_USAGE;
    }
    if (refuse_input_as_output("voxelize", outpath, a.scene)) return EXIT_USAGE;
    char err[RD_ERRLEN];
    rd_scene *s;
    rd_status st = rd_scene_load(&s, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) return report_error(st, err);
    int dims[3];
    st = rd_voxelize(s, (int)medium, (int)res, outpath, dims, err, sizeof err);
    if (st == RD_ERR_ARG) fprintf(stderr, "photonmarch voxelize: %s\n", err);
    else if (st) fprintf(stderr, "%s\n", err);
    else
        printf("%s: %dx%dx%d voxels of %s%s\n", outpath, dims[0], dims[1], dims[2],
               raw ? "the bounds' size / dims" : "cubic size",
               raw ? " (use \"dims\" with these numbers and the same bounds)" : "");
    rd_scene_free(s);
    return exit_for(st);
}

static void print_bake_stats(const rd_bake_stats *b)
{
    printf("photons    emitted %zu, stored %zu, segments %zu%s\n", b->emitted, b->stored, b->segments,
           b->loaded ? " (loaded)" : "");
    printf("memory     %.2f MiB (%.1f bytes per photon, index included)\n", b->map_bytes / 1048576.0,
           b->stored ? (double)b->map_bytes / b->stored : 0.0);
    if (!b->loaded) {
        printf("tracing    %.3f s, %.0f photons/s emitted, %.2f tentative collisions per photon\n", b->trace_seconds,
               b->trace_seconds > 0 ? b->emitted / b->trace_seconds : 0.0, b->collisions_per_photon);
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

static int cmd_bake(int argc, char **argv)
{
    scene_args a = {0};
    const char *prefix = NULL;
    long photons = -1, seed = -1, threads = 0;
    int stats = 0, quiet = 0;
    rd_bake_opts bo = {0};
    rd_bake_write_opts wo = {0};
    for (int i = 0; i < argc; i++) {
        const char *o = argv[i];
        int t = take_set(&a, argc, argv, &i);
        if (t < 0) return EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        if (!strcmp(o, "-h") || !strcmp(o, "--help")) { fputs(usage_bake, stdout); return 0; }
        else if (!strcmp(o, "-q") || !strcmp(o, "--quiet")) quiet = 1;
        else if (!strcmp(o, "--stats")) stats = 1;
        else if (!strcmp(o, "--no-guide")) bo.no_guide = 1;
        else if ((!strcmp(o, "-o") || !strcmp(o, "--output")) && has_val) prefix = argv[++i];
        else if (!strcmp(o, "--load-photons") && has_val) bo.load_photons = argv[++i];
        else if (!strcmp(o, "--photons") && has_val) { if (!parse_int(o, argv[++i], 1, 1000000000L, &photons)) return EXIT_USAGE; }
        else if (!strcmp(o, "--seed") && has_val) { if (!parse_int(o, argv[++i], 0, 0x7fffffffL, &seed)) return EXIT_USAGE; }
        else if (!strcmp(o, "--threads") && has_val) { if (!parse_int(o, argv[++i], 1, 1024, &threads)) return EXIT_USAGE; }
        else if (!strcmp(o, "--toward") && has_val) {
            if (!parse_toward(argv[++i], wo.toward)) return EXIT_USAGE;
            wo.has_toward = 1;
        } else if (!strcmp(o, "--slice") && has_val) {
            const char *v = argv[++i];
            int k = wo.nslices;
            if (k >= 8 || !v[0] || !strchr("xyz", v[0]) || (v[1] && v[1] != '=')) {
                fprintf(stderr, "photonmarch bake: --slice %s: expected x, y or z, optionally =COORD (at most 8)\n", v);
                return EXIT_USAGE;
            }
            wo.slice_axis[k] = v[0];
            wo.slice_has_at[k] = v[1] == '=';
            if (wo.slice_has_at[k] && !parse_double("--slice", v + 2, -1e9, 1e9, &wo.slice_at[k])) return EXIT_USAGE;
            wo.nslices++;
        } else if (take_positional(&a, "bake", o)) return EXIT_USAGE;
    }
    if (need_scene(&a, "bake")) return EXIT_USAGE;
    char defprefix[1024];
    if (!prefix) {
        default_output(a.scene, "", defprefix, sizeof defprefix);
        prefix = defprefix;
    }
    if (strlen(prefix) > 1000) {
        fprintf(stderr, "photonmarch bake: -o: path too long\n");
        return EXIT_USAGE;
    }
    if (refuse_bake_outputs(prefix, a.scene)) return EXIT_USAGE;
    handle_stop_signals(on_signal_quit); /* tracing and baking cannot stop part-way */
    bo.photons = photons > 0 ? (size_t)photons : 0;
    bo.seed = seed;
    bo.threads = (int)threads;
    wo.write_map = !bo.load_photons;

    char err[RD_ERRLEN];
    rd_scene *s;
    rd_status st = rd_scene_load(&s, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) return report_error(st, err);
    rd_baked *b = NULL;
    int code = 0;
    if ((st = rd_make_parent_dirs(prefix, err, sizeof err)) != RD_OK ||
        (st = rd_bake(s, &bo, &b, err, sizeof err)) != RD_OK) {
        code = report_error(st, err);
        goto done;
    }
    const rd_bake_stats *bs = rd_baked_stats(b);
    if (stats) print_bake_stats(bs);
    if (bs->has_guide && (stats || !quiet)) print_guide_line(bs);
    handle_stop_signals(on_signal_stop); /* a signal now lets the files being written finish */
    if ((st = rd_baked_write(b, s, prefix, &wo, err, sizeof err)) != RD_OK) {
        code = st == RD_ERR_ARG ? (fprintf(stderr, "%s\n", err), EXIT_USAGE) : report_error(st, err);
        goto done;
    }
    if (!quiet) {
        if (wo.write_map) printf("photons    %s.pmap\n", prefix);
        printf("picture    %s-photons.png\n", prefix);
        if (bs->has_guide) printf("guide      %s.guide\nslices     %s-slice-*.png, %s-cells-*.png\n", prefix, prefix, prefix);
    }
    if (interrupted) code = exit_interrupted(interrupted);
done:
    rd_baked_free(b);
    rd_scene_free(s);
    return code;
}

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

/* explain: camera rays laid open (rd_explain). */
static int cmd_explain(int argc, char **argv)
{
    scene_args a = {0};
    const char *prefix = NULL;
    long seed = -1, threads = 0, points = 2000;
    enum { MAX_PIXELS = 4096 };
    static long pxs[MAX_PIXELS][2];
    int npx = 0;
    int quiet = 0, no_cache = 0;
    for (int i = 0; i < argc; i++) {
        const char *o = argv[i];
        int t = take_set(&a, argc, argv, &i);
        if (t < 0) return EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        if (!strcmp(o, "-h") || !strcmp(o, "--help")) { fputs(usage_explain, stdout); return 0; }
        else if (!strcmp(o, "-q") || !strcmp(o, "--quiet")) quiet = 1;
        else if (!strcmp(o, "--no-cache")) no_cache = 1;
        else if ((!strcmp(o, "-o") || !strcmp(o, "--output")) && has_val) prefix = argv[++i];
        else if (!strcmp(o, "--points") && has_val) { if (!parse_int(o, argv[++i], 16, 1000000, &points)) return EXIT_USAGE; }
        else if (!strcmp(o, "--seed") && has_val) { if (!parse_int(o, argv[++i], 0, 0x7fffffffL, &seed)) return EXIT_USAGE; }
        else if (!strcmp(o, "--threads") && has_val) { if (!parse_int(o, argv[++i], 1, 1024, &threads)) return EXIT_USAGE; }
        else if (!strcmp(o, "--pixel") && has_val) {
            const char *v = argv[++i];
            char tail;
            long x, y;
            if (sscanf(v, "%ld,%ld%c", &x, &y, &tail) != 2 || x < 0 || y < 0) {
                fprintf(stderr, "photonmarch explain: --pixel %s: expected X,Y (two integers >= 0)\n", v);
                return EXIT_USAGE;
            }
            if (npx == MAX_PIXELS) {
                fprintf(stderr, "photonmarch explain: --pixel %s: at most %d pixels per run\n", v, MAX_PIXELS);
                return EXIT_USAGE;
            }
            pxs[npx][0] = x, pxs[npx][1] = y, npx++;
        } else if (take_positional(&a, "explain", o)) return EXIT_USAGE;
    }
    if (need_scene(&a, "explain")) return EXIT_USAGE;
    if (npx == 0) {
        fprintf(stderr, "photonmarch explain: missing --pixel X,Y (see photonmarch explain --help)\n");
        return EXIT_USAGE;
    }
    char defout[1024];
    if (!prefix) {
        char suffix[64];
        if (npx == 1) snprintf(suffix, sizeof suffix, "-explain-%ld-%ld", pxs[0][0], pxs[0][1]);
        else snprintf(suffix, sizeof suffix, "-explain");
        default_output(a.scene, suffix, defout, sizeof defout);
        prefix = defout;
    }
    if (strlen(prefix) > 1000) {
        fprintf(stderr, "photonmarch explain: -o: path too long\n");
        return EXIT_USAGE;
    }
    /* PREFIX.json (and .csv, .gp, .png, per pixel with several) must not be the scene. */
    for (int q = 0; q < npx; q++) {
        static const char *const ext[] = {".json", ".csv", ".gp", ".png"};
        for (int k = 0; k < 4; k++) {
            char one[1100];
            if (npx == 1) snprintf(one, sizeof one, "%s%s", prefix, ext[k]);
            else snprintf(one, sizeof one, "%s-%ld-%ld%s", prefix, pxs[q][0], pxs[q][1], ext[k]);
            if (refuse_input_as_output("explain", one, a.scene)) return EXIT_USAGE;
        }
    }
    char err[RD_ERRLEN];
    rd_scene *scene;
    rd_status st = rd_scene_load(&scene, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) return report_error(st, err);
    int code = 0;
    rd_baked *baked = NULL;
    rd_explain_result e;
    memset(&e, 0, sizeof e);
    /* A pixel outside the image is a usage error, found before the bake (minutes on a big scene). */
    for (int q = 0; q < npx; q++)
        if (pxs[q][0] >= rd_scene_width(scene) || pxs[q][1] >= rd_scene_height(scene)) {
            fprintf(stderr, "photonmarch explain: --pixel %ld,%ld: outside the %dx%d image\n", pxs[q][0], pxs[q][1],
                    rd_scene_width(scene), rd_scene_height(scene));
            code = EXIT_USAGE;
            goto out;
        }
    if ((st = rd_make_parent_dirs(prefix, err, sizeof err)) != RD_OK) {
        code = report_error(st, err);
        goto out;
    }
    rd_bake_opts bo = {0};
    bo.seed = -1;
    bo.threads = (int)threads;
    rd_bake_opts_for(&bo, rd_method_needs_for("guided", scene));
    st = bake_beside(scene, &bo, prefix, no_cache, quiet, &baked, err, sizeof err);
    if (st) {
        code = report_error(st, err);
        goto out;
    }
    for (int q = 0; q < npx && code == 0; q++) {
        long px = pxs[q][0], py = pxs[q][1];
        char one[1100];
        if (npx == 1) snprintf(one, sizeof one, "%s", prefix);
        else snprintf(one, sizeof one, "%s-%ld-%ld", prefix, px, py);
        rd_explain_opts eo = {.px = (int)px, .py = (int)py, .baked = baked, .n = (int)points,
                              .seed = seed >= 0 ? (uint64_t)seed : rd_scene_seed(scene), .threads = (int)threads};
        rd_explain_result_free(&e);
        if ((st = rd_explain(scene, &eo, &e, err, sizeof err)) != RD_OK ||
            (st = rd_explain_write(scene, &e, one, err, sizeof err)) != RD_OK) {
            code = report_error(st, err);
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

/* ---- compare ------------------------------------------------------------------------------ */

static void print_compare_help(void)
{
    fputs(usage_compare, stdout);
    printf("\nmethods:\n");
    for (int i = 0; i < rd_method_count(); i++) printf("  %-16s %s\n", rd_method_name(i), rd_method_summary(i));
}

/* Progress of a comparison: which method, which run, the run's time and the time left. */
static void compare_progress(void *user, const rd_cmp_progress *p)
{
    progress_state *ps = user;
    /* Not a terminal: a line when a run starts, then at most every 10 s. */
    if (!ps->tty) {
        double now = wall_seconds();
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
    scene_args a;
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
        int t = take_set(&ca->a, argc, argv, &i);
        if (t < 0) return EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        char err[RD_ERRLEN];
        if (!strcmp(opt, "-h") || !strcmp(opt, "--help")) { print_compare_help(); return -1; }
        else if (!strcmp(opt, "-q") || !strcmp(opt, "--quiet")) ca->quiet = 1;
        else if (!strcmp(opt, "--no-cache")) ca->no_cache = 1;
        else if (!strcmp(opt, "--methods") && has_val) {
            snprintf(ca->methods_buf, sizeof ca->methods_buf, "%s", argv[++i]);
            o->n_methods = split_methods(ca->methods_buf, ca->methods, 8);
            if (o->n_methods <= 0) { fprintf(stderr, "photonmarch compare: --methods %s: expected 1 to 8 names separated by commas\n", argv[i]); return EXIT_USAGE; }
        } else if (!strcmp(opt, "--equal") && has_val) {
            const char *e = argv[++i];
            if (strcmp(e, "time") && strcmp(e, "spp")) { fprintf(stderr, "photonmarch compare: --equal %s: expected time or spp\n", e); return EXIT_USAGE; }
            o->equal_spp = !strcmp(e, "spp");
        } else if (!strcmp(opt, "--budget") && has_val) { if (!parse_double(opt, argv[++i], 1e-3, 1e7, &budget)) return EXIT_USAGE; }
        else if (!strcmp(opt, "--runs") && has_val) { if (!parse_int(opt, argv[++i], 1, 64, &v)) return EXIT_USAGE; o->runs = (int)v; }
        else if (!strcmp(opt, "--ref-spp") && has_val) { if (!parse_int(opt, argv[++i], 1, 1 << 24, &v)) return EXIT_USAGE; o->ref_spp = (int)v; }
        else if (!strcmp(opt, "--ref-time") && has_val) { if (!parse_double(opt, argv[++i], 1e-3, 1e7, &o->ref_time)) return EXIT_USAGE; }
        else if (!strcmp(opt, "--reference") && has_val) o->reference = argv[++i];
        else if (!strcmp(opt, "--cache") && has_val) ca->cache = argv[++i];
        else if (!strcmp(opt, "--seed") && has_val) { if (!parse_int(opt, argv[++i], 0, 0x7fffffffL, &ca->seed)) return EXIT_USAGE; }
        else if (!strcmp(opt, "--threads") && has_val) { if (!parse_int(opt, argv[++i], 1, 1024, &v)) return EXIT_USAGE; o->threads = (int)v; }
        else if ((!strcmp(opt, "-o") || !strcmp(opt, "--output")) && has_val) ca->outdir = argv[++i];
        else if (!strcmp(opt, "--add") && has_val) {
            if (o->n_extras >= 8) { fprintf(stderr, "photonmarch compare: --add: at most 8 images\n"); return EXIT_USAGE; }
            int k = o->n_extras;
            if (rd_cmp_extra_parse(argv[++i], ca->extra_buf[k], sizeof ca->extra_buf[k], &ca->extras[k], err, sizeof err)) {
                fprintf(stderr, "photonmarch compare: %s\n", err);
                return EXIT_USAGE;
            }
            o->n_extras++;
        } else if (take_positional(&ca->a, "compare", opt)) return EXIT_USAGE;
    }
    if (need_scene(&ca->a, "compare")) return EXIT_USAGE;
    if (o->n_methods == 0) { fprintf(stderr, "photonmarch compare: missing --methods (see photonmarch compare --help)\n"); return EXIT_USAGE; }
    if (o->equal_spp && budget > 0 && (budget != floor(budget) || budget > (1 << 24))) {
        fprintf(stderr, "photonmarch compare: --budget %g: with --equal spp, a whole number of samples\n", budget);
        return EXIT_USAGE;
    }
    o->budget = budget > 0 ? budget : o->equal_spp ? 64 : 10;
    o->methods = ca->methods;
    o->extras = ca->extras;
    return 0;
}

static int cmd_compare(int argc, char **argv)
{
    static compare_args ca; /* large buffers; one comparison per process */
    memset(&ca, 0, sizeof ca);
    ca.seed = -1;
    ca.o.runs = 2;
    ca.o.ref_spp = 1024;
    int code = compare_parse(&ca, argc, argv);
    if (code) return code < 0 ? 0 : code;
    char defout[1024], cache[1100];
    if (!ca.outdir) {
        char name[1024];
        default_output(ca.a.scene, "", name, sizeof name); /* out/<scene name> */
        snprintf(defout, sizeof defout, "out/compare-%.900s", name + 4);
        ca.outdir = defout;
    }
    /* The reference cache: beside the report folder unless --cache says otherwise. */
    if (!ca.cache) {
        const char *slash = strrchr(ca.outdir, '/');
        snprintf(cache, sizeof cache, "%.*s.photonmarch-cache", slash ? (int)(slash - ca.outdir + 1) : 0, ca.outdir);
        ca.cache = cache;
    }
    ca.o.cache_dir = ca.no_cache ? NULL : ca.cache;

    char err[RD_ERRLEN];
    rd_scene *scene;
    rd_status st = rd_scene_load(&scene, ca.a.scene, ca.a.ov, ca.a.nov, err, sizeof err);
    if (st) return report_error(st, err);
    ca.o.seed = ca.seed >= 0 ? (uint64_t)ca.seed : rd_scene_seed(scene);
    ca.o.cancel = &interrupted;
    progress_state ps = {0.0, isatty(2), 0.0};
    if (!ca.quiet) {
        ca.o.progress = compare_progress;
        ca.o.progress_user = &ps;
    }
    rd_comparison *cmp = NULL;
    handle_stop_signals(on_signal_stop); /* a signal ends the run in progress; the report is written */
    st = rd_compare_run(scene, &ca.o, &cmp, err, sizeof err);
    if (!ca.quiet && ps.tty) fputc('\n', stderr);
    if (st) {
        code = report_error(st, err);
        goto out;
    }
    const rd_cmp_summary *sum = rd_comparison_summary(cmp);
    if (sum->cancelled && sum->n_rows == 0) {
        fprintf(stderr, "photonmarch compare: interrupted before any run finished; nothing written\n");
        code = exit_interrupted(interrupted ? interrupted : SIGINT);
        goto out;
    }
    if ((st = rd_compare_write_report(cmp, scene, ca.outdir, err, sizeof err)) != RD_OK) {
        code = report_error(st, err);
        goto out;
    }
    rd_compare_print_table(cmp, stdout);
    printf("report %s/index.html\n", ca.outdir);
    if (sum->cancelled) {
        fprintf(stderr, "photonmarch compare: interrupted; the report holds the runs that finished\n");
        code = exit_interrupted(interrupted ? interrupted : SIGINT);
    }
out:
    rd_comparison_free(cmp);
    rd_scene_free(scene);
    return code;
}

int main(int argc, char **argv)
{
    if (argc < 2 || !strcmp(argv[1], "-h") || !strcmp(argv[1], "--help") || !strcmp(argv[1], "help")) {
        fputs(usage_main, argc < 2 ? stderr : stdout);
        return argc < 2 ? EXIT_USAGE : 0;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("photonmarch 0.1.0\n");
        return 0;
    }
    if (!strcmp(argv[1], "render")) return cmd_render(argc - 2, argv + 2);
    if (!strcmp(argv[1], "info")) return cmd_info(argc - 2, argv + 2);
    if (!strcmp(argv[1], "bake")) return cmd_bake(argc - 2, argv + 2);
    if (!strcmp(argv[1], "voxelize")) return cmd_voxelize(argc - 2, argv + 2);
    if (!strcmp(argv[1], "explain")) return cmd_explain(argc - 2, argv + 2);
    if (!strcmp(argv[1], "compare")) return cmd_compare(argc - 2, argv + 2);
    fprintf(stderr, "photonmarch: %s: unknown command (see photonmarch --help)\n", argv[1]);
    return EXIT_USAGE;
}
