/* main.c: the photonmarch command line (docs/cli.md). A thin layer over renderer.h: it parses
 * options, reports errors as one line on stderr, and decides the exit code.
 *
 * Exit codes: 0 success; 1 usage error (unknown command or option, bad option value);
 * 2 invalid input (scene, volume or other input file); 3 output could not be written;
 * 4 internal error; 130 interrupted by Ctrl-C (what was rendered so far was written). */
#define _DEFAULT_SOURCE /* mkdir, isatty */
#include "renderer.h"
#include "rd_photons.h"
#include "sh.h"

#include <errno.h>
#include <math.h>
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
    "  voxelize SCENE sample a medium's density into an OpenVDB (.vdb) or raw (.raw) grid\n"
    "  bake SCENE     trace the volume photon map and bake its SH guide grid; save both and\n"
    "                 write pictures of where the light went and of guide slices\n"
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

static void progress(void *user, int done, int total, double seconds)
{
    const double *time_limit = user;
    double eta = done > 0 ? seconds * (total - done) / done : 0.0;
    if (*time_limit > 0 && *time_limit - seconds < eta) eta = fmax(0.0, *time_limit - seconds);
    if (total >= (1 << 24)) /* --time alone: no sample target */
        fprintf(stderr, "\r  %d spp  %.1f of %.0f s   ", done, seconds, *time_limit);
    else
        fprintf(stderr, "\r  %d/%d spp  %.1f s elapsed, about %.0f s left   ", done, total, seconds, eta);
    fflush(stderr);
}

/* OUT.exr -> OUT.png / OUT.json */
static void sibling(const char *exr, const char *ext, char *out, size_t n)
{
    size_t len = strlen(exr);
    snprintf(out, n, "%.*s%s", (int)(len - 4), exr, ext);
}

/* Write s as a JSON string body (quotes and backslashes escaped, control characters dropped). */
static void json_string(FILE *f, const char *s)
{
    for (; *s; s++) {
        if (*s == '"' || *s == '\\') fputc('\\', f);
        if ((unsigned char)*s >= 0x20) fputc(*s, f);
    }
}

static int write_report(const char *path, const char *scene, const char *method, const rd_render_stats *st,
                        uint64_t seed, int threads, int w, int h)
{
    char tmp[2048];
    snprintf(tmp, sizeof tmp, "%s.tmp%ld", path, (long)getpid());
    FILE *f = fopen(tmp, "w");
    if (!f) return 0;
    double paths = st->paths > 0 ? (double)st->paths : 1.0;
    fputs("{\n  \"scene\": \"", f);
    json_string(f, scene);
    fprintf(f,
            "\",\n  \"method\": \"%s\",\n  \"width\": %d,\n  \"height\": %d,\n"
            "  \"spp\": %d,\n  \"seed\": %llu,\n  \"threads\": %d,\n  \"seconds\": %.6f,\n"
            "  \"interrupted\": %s,\n  \"paths\": %llu,\n  \"tentative_collisions\": %llu,\n"
            "  \"density_lookups\": %llu,\n  \"shadow_rays\": %llu,\n"
            "  \"collisions_per_path\": %.4f,\n  \"lookups_per_path\": %.4f,\n"
            "  \"paths_per_second\": %.1f,\n  \"invalid_samples\": %llu\n}\n",
            method, w, h, st->spp, (unsigned long long)seed, threads, st->seconds,
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
    /* A time limit without a sample count (--time, or settings.time with no settings.spp)
     * runs until the time is up. */
    if (ro.time_limit > 0 && spp < 0 && (time_limit > 0 || !scene->settings.spp_given)) ro.spp = 1 << 24;
    ro.seed = seed >= 0 ? (uint64_t)seed : rd_scene_seed(scene);
    ro.threads = (int)threads;
    ro.cancel = &interrupted;
    if (!quiet && isatty(2)) {
        ro.progress = progress;
        ro.progress_user = &ro.time_limit;
    }

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
        if (take_positional(&a, "info", argv[i])) return EXIT_USAGE;
    }
    if (need_scene(&a, "info")) return EXIT_USAGE;
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
    char err[RD_ERRLEN];
    rd_scene *s;
    rd_status st = rd_scene_load(&s, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) {
        fprintf(stderr, "%s\n", err);
        return exit_for(st);
    }
    if (medium >= s->n_media) {
        fprintf(stderr, "photonmarch voxelize: --medium %ld: the scene has %d media\n", medium, s->n_media);
        rd_scene_free(s);
        return EXIT_USAGE;
    }
    const rd_medium *m = &s->media[medium];
    vec3 ext = v3_sub(m->bmax, m->bmin);
    double longest = fmax(ext.x, fmax(ext.y, ext.z)), vs = longest / res;
    int dims[3];
    for (int k = 0; k < 3; k++) dims[k] = (int)fmax(1.0, ceil(v3_get(ext, k) / vs - 1e-9));
    size_t n = (size_t)dims[0] * dims[1] * dims[2];
    float *data = malloc(n * sizeof *data);
    if (!data) {
        fprintf(stderr, "photonmarch voxelize: out of memory for %zu voxels\n", n);
        rd_scene_free(s);
        return EXIT_INTERNAL;
    }
    /* Voxel centres: raw grids fill the bounds exactly (cell size ext/dims per axis), vdb
     * grids use cubic voxels of size vs starting at bmin. */
    double cell[3];
    for (int k = 0; k < 3; k++) cell[k] = raw ? v3_get(ext, k) / dims[k] : vs;
#pragma omp parallel for schedule(dynamic, 1)
    for (int z = 0; z < dims[2]; z++)
        for (int y = 0; y < dims[1]; y++)
            for (int x = 0; x < dims[0]; x++)
                data[((size_t)z * dims[1] + y) * dims[0] + x] = (float)rd_medium_density(
                    m, v3(m->bmin.x + (x + 0.5) * cell[0], m->bmin.y + (y + 0.5) * cell[1], m->bmin.z + (z + 0.5) * cell[2]));
    int code = 0;
    if (!ensure_parent(outpath)) {
        fprintf(stderr, "%s: cannot create its folder: %s\n", outpath, strerror(errno));
        code = EXIT_OUTPUT;
    } else if (vdb) {
        double origin[3] = {m->bmin.x + 0.5 * vs, m->bmin.y + 0.5 * vs, m->bmin.z + 0.5 * vs};
        if (rd_vdb_save_dense(outpath, "density", data, dims[0], dims[1], dims[2], vs, origin, err, sizeof err)) {
            fprintf(stderr, "%s\n", err);
            code = EXIT_OUTPUT;
        }
    } else {
        char tmp[1100];
        snprintf(tmp, sizeof tmp, "%s.tmp%ld", outpath, (long)getpid());
        FILE *f = fopen(tmp, "wb");
        int ok = f && fwrite(data, sizeof *data, n, f) == n;
        if (f && fclose(f) != 0) ok = 0;
        if (!ok || rename(tmp, outpath) != 0) {
            fprintf(stderr, "%s: cannot write: %s\n", outpath, strerror(errno));
            remove(tmp);
            code = EXIT_OUTPUT;
        }
    }
    if (!code)
        printf("%s: %dx%dx%d voxels of %s, medium \"%s\"%s\n", outpath, dims[0], dims[1], dims[2],
               raw ? "the bounds' size / dims" : "cubic size", m->name,
               raw ? " (use \"dims\" with these numbers and the same bounds)" : "");
    free(data);
    rd_scene_free(s);
    return code;
}

/* Write img as PREFIX<suffix>.exr and, normalised, .png. */
static int write_pair(const char *prefix, const char *suffix, rd_image *img, int png_only, char *err, size_t errlen)
{
    char path[1200];
    if (!png_only) {
        snprintf(path, sizeof path, "%s%s.exr", prefix, suffix);
        if (rd_image_write_exr(path, img, err, errlen)) return 0;
    }
    rd_image_normalise(img);
    snprintf(path, sizeof path, "%s%s.png", prefix, suffix);
    return rd_image_write_png(path, img, 0.0, err, errlen) == RD_OK;
}

static int cmd_bake(int argc, char **argv)
{
    scene_args a = {0};
    const char *prefix = NULL, *load = NULL;
    long photons = -1, seed = -1, threads = 0;
    int stats = 0, quiet = 0, no_guide = 0, nslices = 0;
    char slice_axis[8];
    double slice_at[8];
    int slice_has[8];
    double toward[3] = {0, 0, 0};
    int has_toward = 0;
    for (int i = 0; i < argc; i++) {
        const char *o = argv[i];
        int t = take_set(&a, argc, argv, &i);
        if (t < 0) return EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        if (!strcmp(o, "-h") || !strcmp(o, "--help")) { fputs(usage_bake, stdout); return 0; }
        else if (!strcmp(o, "-q") || !strcmp(o, "--quiet")) quiet = 1;
        else if (!strcmp(o, "--stats")) stats = 1;
        else if (!strcmp(o, "--no-guide")) no_guide = 1;
        else if ((!strcmp(o, "-o") || !strcmp(o, "--output")) && has_val) prefix = argv[++i];
        else if (!strcmp(o, "--load-photons") && has_val) load = argv[++i];
        else if (!strcmp(o, "--photons") && has_val) { if (!parse_int(o, argv[++i], 1, 1000000000L, &photons)) return EXIT_USAGE; }
        else if (!strcmp(o, "--seed") && has_val) { if (!parse_int(o, argv[++i], 0, 0x7fffffffL, &seed)) return EXIT_USAGE; }
        else if (!strcmp(o, "--threads") && has_val) { if (!parse_int(o, argv[++i], 1, 1024, &threads)) return EXIT_USAGE; }
        else if (!strcmp(o, "--toward") && has_val) {
            const char *v = argv[++i];
            char *end;
            int ncomp = 0;
            end = (char *)v;
            for (; ncomp < 3; ncomp++) {
                const char *start = ncomp == 0 ? end : end + 1;
                if (ncomp > 0 && *end != ',') break;
                toward[ncomp] = strtod(start, &end);
                if (end == start) break;
            }
            double len = sqrt(toward[0] * toward[0] + toward[1] * toward[1] + toward[2] * toward[2]);
            if (ncomp != 3 || *end || !(len > 0) || !isfinite(len)) {
                fprintf(stderr, "photonmarch bake: --toward %s: expected X,Y,Z, a non-zero direction\n", v);
                return EXIT_USAGE;
            }
            for (int k = 0; k < 3; k++) toward[k] /= len;
            has_toward = 1;
        } else if (!strcmp(o, "--slice") && has_val) {
            const char *v = argv[++i];
            if (nslices >= 8 || !strchr("xyz", v[0]) || !v[0] || (v[1] && v[1] != '=')) {
                fprintf(stderr, "photonmarch bake: --slice %s: expected x, y or z, optionally =COORD (at most 8)\n", v);
                return EXIT_USAGE;
            }
            slice_axis[nslices] = v[0];
            slice_has[nslices] = v[1] == '=';
            if (slice_has[nslices] && !parse_double("--slice", v + 2, -1e9, 1e9, &slice_at[nslices])) return EXIT_USAGE;
            nslices++;
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
    if (nslices == 0) { slice_axis[0] = 'z'; slice_has[0] = 0; nslices = 1; }

    char err[RD_ERRLEN];
    rd_scene *scene;
    rd_status st = rd_scene_load(&scene, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) {
        fprintf(stderr, "%s\n", err);
        return exit_for(st);
    }
    rd_scene *s = scene;
    int code = 0;
    pm_map *map = NULL;
    sh_guide *guide = NULL;
    rd_image img = {0, 0, NULL};
    char path[1200], pmerr[RD_ERRLEN];
    if (!ensure_parent(prefix)) {
        fprintf(stderr, "%s: cannot create its folder: %s\n", prefix, strerror(errno));
        code = EXIT_OUTPUT;
        goto done;
    }
    rd_photon_stats ps;
    memset(&ps, 0, sizeof ps);
    if (load) {
        if (pm_map_load(&map, load, pmerr, sizeof pmerr) != PM_OK) {
            fprintf(stderr, "%s\n", pmerr);
            code = EXIT_INPUT;
            goto done;
        }
    } else {
        rd_photon_opts po = {.count = photons > 0 ? (size_t)photons : s->photons.count,
                             .store_direct = s->photons.store_direct, .segments = s->photons.segments,
                             .max_depth = s->photons.max_depth,
                             .seed = seed >= 0 ? (uint64_t)seed : s->photons.seed, .threads = (int)threads};
        map = pm_map_new();
        if (!map || (st = rd_trace_photons(s, &po, map, &ps, err, sizeof err)) != RD_OK) {
            fprintf(stderr, "%s\n", map ? err : "out of memory");
            code = exit_for(map ? st : RD_ERR_NOMEM);
            goto done;
        }
    }
    if (pm_map_build(map, pmerr, sizeof pmerr) != PM_OK) {
        fprintf(stderr, "photon map: %s\n", pmerr);
        code = EXIT_INTERNAL;
        goto done;
    }
    if (!load) {
        snprintf(path, sizeof path, "%s.pmap", prefix);
        if (pm_map_save(map, path, pmerr, sizeof pmerr) != PM_OK) {
            fprintf(stderr, "%s\n", pmerr);
            code = EXIT_OUTPUT;
            goto done;
        }
    }
    if (rd_photon_image(s, map, &img, err, sizeof err) || !write_pair(prefix, "-photons", &img, 0, err, sizeof err)) {
        fprintf(stderr, "%s\n", err);
        code = EXIT_OUTPUT;
        goto done;
    }
    rd_image_free_pixels(&img);
    if (stats) {
        size_t np = pm_map_photon_count(map), mem = pm_map_memory_bytes(map);
        printf("photons    emitted %zu, stored %zu, segments %zu%s\n", ps.emitted, np, pm_map_segment_count(map),
               load ? " (loaded)" : "");
        printf("memory     %.2f MiB (%.1f bytes per photon, index included)\n", mem / 1048576.0, np ? (double)mem / np : 0.0);
        if (!load) {
            printf("tracing    %.3f s, %.0f photons/s emitted, %.2f tentative collisions per photon\n", ps.seconds,
                   ps.seconds > 0 ? ps.emitted / ps.seconds : 0.0, ps.emitted ? (double)ps.collisions / ps.emitted : 0.0);
            printf("power      emitted %.4g W = absorbed %.4g + escaped %.4g + cut at max depth %.4g (luminance)\n",
                   0.2126 * ps.power_emitted[0] + 0.7152 * ps.power_emitted[1] + 0.0722 * ps.power_emitted[2],
                   0.2126 * ps.power_absorbed[0] + 0.7152 * ps.power_absorbed[1] + 0.0722 * ps.power_absorbed[2],
                   0.2126 * ps.power_escaped[0] + 0.7152 * ps.power_escaped[1] + 0.0722 * ps.power_escaped[2],
                   0.2126 * ps.power_carried[0] + 0.7152 * ps.power_carried[1] + 0.0722 * ps.power_carried[2]);
        }
        printf("index      FLANN kd-tree built in %.3f s\n", pm_map_build_seconds(map));
    }
    if (!no_guide) {
        if ((st = rd_guide_bake(s, map, (int)threads, &guide, err, sizeof err)) != RD_OK) {
            fprintf(stderr, "%s\n", err);
            code = exit_for(st);
            goto done;
        }
        snprintf(path, sizeof path, "%s.guide", prefix);
        if (sh_guide_save(guide, path, pmerr, sizeof pmerr) != SH_OK) {
            fprintf(stderr, "%s\n", pmerr);
            code = EXIT_OUTPUT;
            goto done;
        }
        sh_guide_stats gst;
        sh_guide_stats_get(guide, &gst);
        if (stats || !quiet) {
            printf("guide      %s grid, %s bake, %d bands, %zu cells", gst.kind == SH_GRID_UNIFORM ? "uniform" : "adaptive",
                   gst.method == SH_BAKE_KNN ? "k-NN" : "track-length", gst.bands, gst.cells);
            if (gst.kind == SH_GRID_UNIFORM) printf(" (%dx%dx%d)", gst.res[0], gst.res[1], gst.res[2]);
            else printf(" (depth %d, cell edge %.3g-%.3g m)", gst.depth_max, gst.cell_min, gst.cell_max);
            printf(", %.2f MiB, baked in %.3f s\n", gst.memory_bytes / 1048576.0, gst.bake_seconds);
        }
        /* Slices toward the camera unless told otherwise. */
        double w[3] = {-s->camera.forward.x, -s->camera.forward.y, -s->camera.forward.z};
        if (has_toward) memcpy(w, toward, sizeof w);
        double lo[3], hi[3];
        sh_guide_box(guide, lo, hi);
        for (int k = 0; k < nslices; k++) {
            int axis = slice_axis[k] - 'x';
            double c = slice_has[k] ? slice_at[k] : 0.5 * (lo[axis] + hi[axis]);
            int u = axis == 0 ? 1 : 0, v = axis == 2 ? 1 : 2;
            double ext_u = hi[u] - lo[u], ext_v = hi[v] - lo[v];
            int W = 512, H = (int)fmax(1.0, fmin(2048.0, round(512.0 * ext_v / ext_u)));
            img.w = W;
            img.h = H;
            img.rgb = malloc((size_t)W * H * 3 * sizeof(float));
            if (!img.rgb) { code = EXIT_INTERNAL; goto done; }
            char suffix[32];
            sh_slice_what what[2] = {SH_SLICE_RADIANCE, gst.kind == SH_GRID_UNIFORM ? SH_SLICE_SIGMA_T : SH_SLICE_DEPTH};
            for (int q = 0; q < 2; q++) {
                if (sh_guide_slice(guide, axis, c, w, what[q], W, H, img.rgb, pmerr, sizeof pmerr) != SH_OK) {
                    fprintf(stderr, "--slice %c: %s\n", slice_axis[k], pmerr);
                    code = EXIT_USAGE;
                    goto done;
                }
                snprintf(suffix, sizeof suffix, q == 0 ? "-slice-%c" : "-cells-%c", slice_axis[k]);
                if (!write_pair(prefix, suffix, &img, q == 1, err, sizeof err)) {
                    fprintf(stderr, "%s\n", err);
                    code = EXIT_OUTPUT;
                    goto done;
                }
            }
            rd_image_free_pixels(&img);
        }
    }
    if (!quiet) {
        if (!load) printf("photons    %s.pmap\n", prefix);
        printf("picture    %s-photons.png\n", prefix);
        if (!no_guide) printf("guide      %s.guide\nslices     %s-slice-*.png, %s-cells-*.png\n", prefix, prefix, prefix);
    }
done:
    rd_image_free_pixels(&img);
    sh_guide_free(guide);
    pm_map_free(map);
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
    fprintf(stderr, "photonmarch: %s: unknown command (see photonmarch --help)\n", argv[1]);
    return EXIT_USAGE;
}
