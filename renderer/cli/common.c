/* common.c: what the subcommands share (declared in cli.h): the --set, positional SCENE and
 * number options, exit codes from rd_status, refusing an output that is the input scene, default
 * output names, the wall clock for progress, and the bake through the cache beside an output. */
#include "cli.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

/* 1 when `out` names the same existing file as the input `in` (after symbolic links), so
 * writing it would replace the input. */
int cli_same_file(const char *out, const char *in)
{
    struct stat so, si;
    return stat(out, &so) == 0 && stat(in, &si) == 0 && so.st_dev == si.st_dev && so.st_ino == si.st_ino;
}

/* Refuse an output path that is the input scene (exit 1 after a message). */
int cli_refuse_input_as_output(const char *cmd, const char *out, const char *scene)
{
    if (!cli_same_file(out, scene)) return 0;
    fprintf(stderr, "photonmarch %s: %s is the input scene %s; choose another output (-o)\n", cmd, out, scene);
    return CLI_EXIT_USAGE;
}

int cli_parse_int(const char *opt, const char *s, long lo, long hi, long *out)
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

int cli_parse_double(const char *opt, const char *s, double lo, double hi, double *out)
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

int cli_exit_for(rd_status st)
{
    switch (st) {
    case RD_OK: return 0;
    case RD_ERR_ARG: return CLI_EXIT_USAGE;
    case RD_ERR_IO:
    case RD_ERR_PARSE:
    case RD_ERR_SCENE:
    case RD_ERR_FORMAT: return CLI_EXIT_INPUT;
    case RD_ERR_OUTPUT: return CLI_EXIT_OUTPUT;
    default: return CLI_EXIT_INTERNAL;
    }
}

/* Consume --set at argv[*i]; returns 1 if handled, 0 if not --set, -1 on error. */
int cli_take_set(cli_scene_args *a, int argc, char **argv, int *i)
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

/* The positional SCENE, or an unknown option: returns 0 when taken, CLI_EXIT_USAGE after a message. */
int cli_take_positional(cli_scene_args *a, const char *cmd, const char *o)
{
    if (o[0] == '-') {
        fprintf(stderr, "photonmarch %s: %s: unknown option or missing value (see photonmarch %s --help)\n", cmd, o, cmd);
        return CLI_EXIT_USAGE;
    }
    if (a->scene) {
        fprintf(stderr, "photonmarch %s: %s: only one scene per run\n", cmd, o);
        return CLI_EXIT_USAGE;
    }
    a->scene = o;
    return 0;
}

int cli_need_scene(const cli_scene_args *a, const char *cmd)
{
    if (a->scene) return 0;
    fprintf(stderr, "photonmarch %s: missing SCENE (see photonmarch %s --help)\n", cmd, cmd);
    return CLI_EXIT_USAGE;
}

/* out/<scene file name without extension><suffix> */
void cli_default_output(const char *scene, const char *suffix, char *out, size_t n)
{
    const char *base = strrchr(scene, '/');
    base = base ? base + 1 : scene;
    const char *dot = strrchr(base, '.');
    snprintf(out, n, "out/%.*s%s", dot && dot != base ? (int)(dot - base) : (int)strlen(base), base, suffix);
}

double cli_wall_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int cli_report_error(rd_status st, const char *err)
{
    fprintf(stderr, "%s\n", err);
    return cli_exit_for(st);
}

/* Bake what `bo` asks for through the cache folder beside `out` (OUT's folder, then
 * .photonmarch-cache), or afresh with `fresh`; a cache that cannot be saved is a warning. */
rd_status cli_bake_beside(const rd_scene *scene, const rd_bake_opts *bo, const char *out, int fresh,
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
