/* ranks.c: what the ranks of one MPI job agree on before they go on (cli.h, "several ranks";
 * docs/cluster.md). A step that fails on one rank must fail on all, or the others would wait in
 * the next collective call for ever: after each step that can fail (the options, the scene, the
 * bake, the writing of the outputs) the ranks exchange their outcome, and all go on or all stop
 * with a non-zero exit, the failure said once. */
#include "cli.h"

#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

int cli_ranks_agree(rd_dist *d, int code, const char *msg)
{
    int n = rd_dist_size(d), rank = rd_dist_rank(d);
    if (n <= 1) {
        if (code && msg) fprintf(stderr, "%s\n", msg);
        return code;
    }
    int v[2] = {code != 0, code}; /* ranks that failed, the largest code */
    rd_dist_allreduce_int(d, v, 1, RD_COMM_SUM);
    rd_dist_allreduce_int(d, v + 1, 1, RD_COMM_MAX);
    if (v[0] == 0) return 0;
    if (code && msg) {
        if (v[0] == n && rank == 0) fprintf(stderr, "%s\n", msg);
        else if (v[0] < n) fprintf(stderr, "photonmarch: rank %d of %d: %s\n", rank, n, msg);
    }
    return code ? code : v[1];
}

int cli_ranks_agree_shared(rd_dist *d, int code, const char *msg)
{
    size_t n = msg ? strlen(msg) : 0, k = strlen(RD_ON_ANOTHER_RANK);
    int own = code && msg && !(n >= k && !strcmp(msg + n - k, RD_ON_ANOTHER_RANK));
    int c = cli_ranks_agree(d, own ? code : 0, own ? msg : NULL);
    return code ? code : c;
}

int cli_ranks_mute(rd_dist *d)
{
    if (rd_dist_size(d) <= 1 || rd_dist_rank(d) == 0) return -1;
    fflush(stdout);
    fflush(stderr);
    int saved = dup(STDERR_FILENO), out = dup(STDOUT_FILENO), null = open("/dev/null", O_WRONLY);
    if (saved < 0 || out < 0 || null < 0) {
        if (saved >= 0) close(saved);
        if (out >= 0) close(out);
        if (null >= 0) close(null);
        return -1; /* then this rank speaks too */
    }
    dup2(null, STDERR_FILENO);
    dup2(null, STDOUT_FILENO);
    close(null);
    return saved * 65536 + out; /* both descriptors, small numbers */
}

int cli_ranks_unmute(rd_dist *d, int saved, int code)
{
    if (saved >= 0) {
        fflush(stdout);
        fflush(stderr);
        dup2(saved / 65536, STDERR_FILENO);
        dup2(saved % 65536, STDOUT_FILENO);
        close(saved / 65536);
        close(saved % 65536);
    }
    if (rd_dist_size(d) <= 1) return code;
    int v = rd_dist_rank(d) == 0 ? code : 0; /* rank 0's code, everywhere */
    rd_dist_allreduce_int(d, &v, 1, RD_COMM_SUM);
    if (v != code)
        fprintf(stderr, "photonmarch: rank %d of %d: its command line is not rank 0's (every rank runs the same "
                        "command)\n", rd_dist_rank(d), rd_dist_size(d));
    return v;
}

/* FNV-1a (64 bits) of n bytes, continuing from h. */
static uint64_t fnv1a(uint64_t h, const void *p, size_t n)
{
    for (size_t i = 0; i < n; i++) h = (h ^ ((const unsigned char *)p)[i]) * 1099511628211ULL;
    return h;
}

int cli_ranks_same_options(rd_dist *d, const char *text, const cli_scene_args *a)
{
    if (rd_dist_size(d) <= 1) return 0;
    uint64_t h = fnv1a(1469598103934665603ULL, text, strlen(text));
    for (int i = 0; a && i < a->nov; i++) { /* "|key=value" for every --set */
        h = fnv1a(h, "|", 1);
        h = fnv1a(h, a->ov[i].key, strlen(a->ov[i].key));
        h = fnv1a(h, "=", 1);
        h = fnv1a(h, a->ov[i].value, strlen(a->ov[i].value));
    }
    if (rd_dist_same(d, h)) return 0;
    if (rd_dist_rank(d) == 0)
        fprintf(stderr, "photonmarch: the ranks' options differ (method, samples, seed, time, --set, files): every "
                        "rank runs the same command\n");
    return CLI_EXIT_USAGE;
}

/* FNV-1a (64 bits) of the file's bytes; 0 when it cannot be read. */
static uint64_t file_hash(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    uint64_t h = 1469598103934665603ULL;
    unsigned char buf[65536];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, f)) > 0) h = fnv1a(h, buf, n);
    int bad = ferror(f);
    fclose(f);
    return bad ? 0 : h;
}

int cli_ranks_same_file(rd_dist *d, const char *path)
{
    if (rd_dist_size(d) <= 1) return 0;
    if (rd_dist_same(d, file_hash(path))) return 0;
    if (rd_dist_rank(d) == 0)
        fprintf(stderr, "%s: not the same file on every rank (the ranks must render one scene; copy it to every "
                        "node)\n", path);
    return CLI_EXIT_INPUT;
}

int cli_ranks_load_scene(rd_dist *d, const cli_scene_args *a, rd_scene **scene)
{
    char err[RD_ERRLEN];
    *scene = NULL;
    rd_status st = rd_scene_load(scene, a->scene, a->ov, a->nov, err, sizeof err);
    int code = cli_ranks_agree(d, cli_exit_for(st), err);
    return code ? code : cli_ranks_same_file(d, a->scene);
}
