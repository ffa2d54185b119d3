/* main.c: the photonmarch command line (docs/cli.md). A thin layer over renderer.h: it parses
 * options, reports errors as one line on stderr, and decides the exit code.
 *
 * Exit codes: 0 success; 1 usage error (unknown command or option, bad option value);
 * 2 invalid input (scene, volume or other input file); 3 output could not be written;
 * 4 internal error; 130 interrupted by Ctrl-C (what was rendered so far was written). */
#define _DEFAULT_SOURCE /* mkdir, isatty */
#include "renderer.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

enum { EXIT_USAGE = 1, EXIT_INPUT = 2, EXIT_OUTPUT = 3, EXIT_INTERNAL = 4, EXIT_INTERRUPTED = 130 };

/* The one piece of mutable global state: set by the SIGINT handler, read between passes.
 * A signal handler can reach nothing else. */
static volatile int interrupted = 0;

static void on_sigint(int sig)
{
    (void)sig;
    interrupted = 1;
    signal(SIGINT, SIG_DFL); /* a second Ctrl-C ends the process at once */
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
    "\n"
    "  photonmarch COMMAND --help   shows the options of a command\n"
    "  photonmarch --version        prints the version\n"
    "\n"
    "exit codes: 0 success, 1 usage error, 2 invalid input (scene or data file),\n"
    "            3 output not written, 4 internal error, 130 interrupted (partial image written)\n"
    "\n"
    "docs: docs/cli.md (this reference), docs/scene-format.md (the scene file)\n";

static const char *usage_render =
    "usage: photonmarch render SCENE [options]\n"
    "\n"
    "Renders SCENE (JSON, docs/scene-format.md). Writes OUT.exr (linear float RGB), OUT.png\n"
    "(sRGB preview, scaled by 2^camera.exposure) and OUT.json (method, samples, time, counters).\n"
    "Files are written under a temporary name and renamed, so a failed run never destroys a\n"
    "good image. Ctrl-C finishes the current pass and writes what it has (exit 130).\n"
    "\n"
    "options:\n"
    "  --method M        rendering method (default: settings.method, else delta). Available: delta\n"
    "  --spp N           samples per pixel (default: settings.spp)\n"
    "  --time S          stop after S seconds (the pass under way finishes); with --spp, the\n"
    "                    first limit reached stops the render\n"
    "  --seed N          random seed (default: settings.seed); same seed, same image on any\n"
    "                    number of threads\n"
    "  --threads N       worker threads (default: all cores)\n"
    "  -o, --output OUT.exr   output path (default: out/<scene name>.exr)\n"
    "  --set KEY=VALUE   override a scene field before validation, e.g. --set settings.spp=64,\n"
    "                    --set camera.resolution=[320,240], --set media[0].g=0.9 (repeatable)\n"
    "  -q, --quiet       no progress and no summary\n"
    "  -h, --help        this text\n";

static const char *usage_info =
    "usage: photonmarch info SCENE [--set KEY=VALUE ...]\n"
    "\n"
    "Loads and validates SCENE and describes it: camera, media (kind, bounds, density range,\n"
    "sigma_t scale, albedo, g, majorant), lights (kind, parameters, power), settings, memory.\n";

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

static void progress(void *user, int done, int total, double seconds)
{
    (void)user;
    fprintf(stderr, "\r  %d/%d spp  %.1f s", done, total, seconds);
    fflush(stderr);
}

/* OUT.exr -> OUT.png / OUT.json */
static void sibling(const char *exr, const char *ext, char *out, size_t n)
{
    size_t len = strlen(exr);
    snprintf(out, n, "%.*s%s", (int)(len - 4), exr, ext);
}

static int write_report(const char *path, const char *scene, const char *method, const rd_render_stats *st,
                        uint64_t seed, int threads, int w, int h)
{
    char tmp[2048];
    snprintf(tmp, sizeof tmp, "%s.tmp%ld", path, (long)getpid());
    FILE *f = fopen(tmp, "w");
    if (!f) return 0;
    double paths = st->paths > 0 ? (double)st->paths : 1.0;
    fprintf(f,
            "{\n  \"scene\": \"%s\",\n  \"method\": \"%s\",\n  \"width\": %d,\n  \"height\": %d,\n"
            "  \"spp\": %d,\n  \"seed\": %llu,\n  \"threads\": %d,\n  \"seconds\": %.6f,\n"
            "  \"interrupted\": %s,\n  \"paths\": %llu,\n  \"tentative_collisions\": %llu,\n"
            "  \"density_lookups\": %llu,\n  \"shadow_rays\": %llu,\n"
            "  \"collisions_per_path\": %.4f,\n  \"lookups_per_path\": %.4f,\n"
            "  \"paths_per_second\": %.1f,\n  \"invalid_samples\": %llu\n}\n",
            scene, method, w, h, st->spp, (unsigned long long)seed, threads, st->seconds,
            st->cancelled ? "true" : "false", (unsigned long long)st->paths,
            (unsigned long long)st->collisions, (unsigned long long)st->lookups,
            (unsigned long long)st->shadow_rays, st->collisions / paths, st->lookups / paths,
            st->seconds > 0 ? st->paths / st->seconds : 0.0, (unsigned long long)st->invalid);
    int ok = fclose(f) == 0;
    if (!ok || rename(tmp, path) != 0) {
        remove(tmp);
        return 0;
    }
    return 1;
}

/* mkdir -p for the folder of `path`. */
static int ensure_parent(const char *path)
{
    char dir[2048];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (!slash) return 1;
    *slash = 0;
    for (char *p = dir + 1; *p; p++) {
        if (*p != '/') continue;
        *p = 0;
        if (mkdir(dir, 0777) != 0 && errno != EEXIST) return 0;
        *p = '/';
    }
    return dir[0] == 0 || mkdir(dir, 0777) == 0 || errno == EEXIST;
}

static int cmd_render(int argc, char **argv)
{
    scene_args a = {0};
    const char *method = NULL, *outpath = NULL;
    long spp = -1, seed = -1, threads = 0;
    double time_limit = -1;
    int quiet = 0;
    for (int i = 0; i < argc; i++) {
        const char *o = argv[i];
        int t = take_set(&a, argc, argv, &i);
        if (t < 0) return EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        if (!strcmp(o, "-h") || !strcmp(o, "--help")) { fputs(usage_render, stdout); return 0; }
        else if (!strcmp(o, "-q") || !strcmp(o, "--quiet")) quiet = 1;
        else if (!strcmp(o, "--method") && has_val) method = argv[++i];
        else if (!strcmp(o, "--spp") && has_val) { if (!parse_int(o, argv[++i], 1, 1 << 24, &spp)) return EXIT_USAGE; }
        else if (!strcmp(o, "--time") && has_val) { if (!parse_double(o, argv[++i], 0.001, 1e7, &time_limit)) return EXIT_USAGE; }
        else if (!strcmp(o, "--seed") && has_val) { if (!parse_int(o, argv[++i], 0, 0x7fffffffL, &seed)) return EXIT_USAGE; }
        else if (!strcmp(o, "--threads") && has_val) { if (!parse_int(o, argv[++i], 1, 1024, &threads)) return EXIT_USAGE; }
        else if ((!strcmp(o, "-o") || !strcmp(o, "--output")) && has_val) outpath = argv[++i];
        else if (o[0] == '-') {
            fprintf(stderr, "photonmarch render: %s: unknown option or missing value (see photonmarch render --help)\n", o);
            return EXIT_USAGE;
        } else if (!a.scene) a.scene = o;
        else {
            fprintf(stderr, "photonmarch render: %s: only one scene per run\n", o);
            return EXIT_USAGE;
        }
    }
    if (!a.scene) {
        fprintf(stderr, "photonmarch render: missing SCENE (see photonmarch render --help)\n");
        return EXIT_USAGE;
    }
    char defout[1024];
    if (!outpath) {
        const char *base = strrchr(a.scene, '/');
        base = base ? base + 1 : a.scene;
        size_t n = strcspn(base, ".");
        snprintf(defout, sizeof defout, "out/%.*s.exr", (int)n, base);
        outpath = defout;
    }
    size_t olen = strlen(outpath);
    if (olen < 5 || strcmp(outpath + olen - 4, ".exr") != 0 || olen > 1000) {
        fprintf(stderr, "photonmarch render: -o %s: expected a path ending in .exr\n", outpath);
        return EXIT_USAGE;
    }

    char err[RD_ERRLEN];
    rd_scene *scene;
    rd_status st = rd_scene_load(&scene, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) {
        fprintf(stderr, "%s\n", err);
        return exit_for(st);
    }
    rd_render_opts ro = {0};
    ro.method = method ? method : rd_scene_method(scene);
    ro.spp = spp > 0 ? (int)spp : rd_scene_spp(scene);
    ro.time_limit = time_limit > 0 ? time_limit : rd_scene_time_limit(scene);
    if (time_limit > 0 && spp < 0) ro.spp = 1 << 24; /* --time alone: run until the time is up */
    ro.seed = seed >= 0 ? (uint64_t)seed : rd_scene_seed(scene);
    ro.threads = (int)threads;
    ro.cancel = &interrupted;
    if (!quiet && isatty(2)) ro.progress = progress;

    if (!ensure_parent(outpath)) {
        fprintf(stderr, "%s: cannot create its folder: %s\n", outpath, strerror(errno));
        rd_scene_free(scene);
        return EXIT_OUTPUT;
    }
    signal(SIGINT, on_sigint);
    rd_image img;
    rd_render_stats rs;
    st = rd_render(scene, &ro, &img, &rs, err, sizeof err);
    signal(SIGINT, SIG_DFL);
    if (ro.progress) fputc('\n', stderr);
    if (st) {
        fprintf(stderr, "%s\n", err);
        rd_scene_free(scene);
        return exit_for(st);
    }
    int code = 0;
    char png[1100], json[1100];
    sibling(outpath, ".png", png, sizeof png);
    sibling(outpath, ".json", json, sizeof json);
    if (rs.spp == 0) {
        fprintf(stderr, "photonmarch render: interrupted before the first pass finished; nothing written\n");
        code = EXIT_INTERRUPTED;
    } else {
        if ((st = rd_image_write_exr(outpath, &img, err, sizeof err)) ||
            (st = rd_image_write_png(png, &img, rd_scene_exposure(scene), err, sizeof err))) {
            fprintf(stderr, "%s\n", err);
            code = EXIT_OUTPUT;
        } else if (!write_report(json, a.scene, ro.method, &rs, ro.seed, ro.threads, img.w, img.h)) {
            fprintf(stderr, "%s: cannot write: %s\n", json, strerror(errno));
            code = EXIT_OUTPUT;
        }
        if (!code && !quiet) {
            double paths = rs.paths ? (double)rs.paths : 1.0;
            fprintf(stderr, "%s: %d spp in %.2f s (%.0f paths/s, %.2f collisions/path, %.2f lookups/path)%s\n",
                    ro.method, rs.spp, rs.seconds, rs.seconds > 0 ? rs.paths / rs.seconds : 0.0,
                    rs.collisions / paths, rs.lookups / paths, rs.cancelled ? " [interrupted]" : "");
            if (rs.invalid) fprintf(stderr, "warning: %llu non-finite samples were dropped\n", (unsigned long long)rs.invalid);
            printf("image  %s\npng    %s\nreport %s\n", outpath, png, json);
        }
        if (!code && rs.cancelled) code = EXIT_INTERRUPTED;
    }
    rd_image_free_pixels(&img);
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
        if (argv[i][0] == '-') {
            fprintf(stderr, "photonmarch info: %s: unknown option (see photonmarch info --help)\n", argv[i]);
            return EXIT_USAGE;
        }
        if (a.scene) {
            fprintf(stderr, "photonmarch info: %s: only one scene per run\n", argv[i]);
            return EXIT_USAGE;
        }
        a.scene = argv[i];
    }
    if (!a.scene) {
        fprintf(stderr, "photonmarch info: missing SCENE (see photonmarch info --help)\n");
        return EXIT_USAGE;
    }
    char err[RD_ERRLEN];
    rd_scene *scene;
    rd_status st = rd_scene_load(&scene, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) {
        fprintf(stderr, "%s\n", err);
        return exit_for(st);
    }
    rd_scene_info(scene, stdout);
    rd_scene_free(scene);
    return 0;
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
    fprintf(stderr, "photonmarch: %s: unknown command (see photonmarch --help)\n", argv[1]);
    return EXIT_USAGE;
}
