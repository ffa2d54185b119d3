/* The command line on several MPI ranks (renderer/dist/, docs/cluster.md), through OpenMPI's
 * mpirun with two ranks on this machine:
 *  - render splits the image's tiles between the ranks and sums the films on rank 0: the image
 *    (and its standard error, and the report's counters) equals one process's bit for bit, for
 *    delta and for guided with the tile selection on (its epochs sum the ranks' samples first:
 *    without that sum the choice, and so the image, differs on this scene and seed);
 *  - a time-limited render on two ranks ends, and one set of outputs is written;
 *  - a rank that cannot read the scene, ranks with different scene files, an output rank 0
 *    cannot write, a command that is not shared: one line and a non-zero exit, no hang;
 *  - bake on two ranks (each traces a range of the photons, gathered on every rank) writes one
 *    process's .pmap byte for byte and its .guide but for the bake time; a render's bake through
 *    the cache is traced by the two ranks together and its image is one process's;
 *  - a rank killed mid-render (SIGKILL) ends the job with a non-zero status and the previous
 *    image stays as it was;
 *  - compare on two ranks (runs dealt round the ranks, the reference rendered by both) gives one
 *    process's numbers at equal spp, and its report records the ranks and the host.
 * Every run is waited for (rt_run); the timeouts only guard against a hang.
 * mpirun's options: as root (CI) it must be told so; --oversubscribe: two ranks on any number of
 * cores; --bind-to none: the ranks may use any core; the shared-memory transport's single copy
 * (CMA, process_vm_readv) is off because containers often forbid it, and these tests are about
 * the program, not the transport. */
#include "support/rd_test.h"

#include <cJSON.h>
#include <dirent.h>

#define MPIRUN "/usr/bin/mpirun"

/* The small scene of test_select.c (a spot beam through noise in the image's left half, the
 * tile selection on) at 48x24: 3x2 render tiles, so each rank's tiles (a checkerboard) hold
 * part of the medium, and 6x3 selection tiles. */
static const char *scene_file(const char *name)
{
    static char path[4][256];
    static int k = 0;
    k = (k + 1) % 4;
    snprintf(path[k], sizeof path[k], "%s/%s", rt_tmpdir(), name);
    /* guided's marcher against delta's path, no third estimator (march.equiangular false): with
     * the third, every tile here takes delta's path with the strategy since session 42 (the
     * pilot prefers it for the image, and the fog-less half is lit by no sample), and the
     * selection would mix nothing */
    const char *json = rt_spot_fog_json_with(48, 24, "{\"select\":\"tiles\"}",
                                             "\"photons\":{\"count\":40000},\"march\":{\"equiangular\":false}");
    rt_write_file(path[k], json, strlen(json));
    return path[k];
}

static const char *bin(void)
{
    const char *b = getenv("PHOTONMARCH_BIN");
    cr_assert(b != NULL, "PHOTONMARCH_BIN is not set (run through make test)");
    cr_assert(access(MPIRUN, X_OK) == 0, MPIRUN " not found: run scripts/install-deps.sh (openmpi-bin)");
    return b;
}

/* argv of `mpirun <options> -n 2 BIN <args...>` into a[] (NULL-terminated). */
#define MPI_ARGS MPIRUN, "--allow-run-as-root", "--oversubscribe", "--bind-to", "none", "--mca", \
                 "btl_vader_single_copy_mechanism", "none"

static void read_image(const char *path, rd_image *img)
{
    char err[RD_ERRLEN];
    cr_assert(rd_image_read(path, img, err, sizeof err) == RD_OK, "%s", err);
}

static void expect_same_pixels(const char *a, const char *b)
{
    rd_image x, y;
    read_image(a, &x);
    read_image(b, &y);
    cr_assert(x.w == y.w && x.h == y.h, "%s and %s: sizes differ", a, b);
    size_t n = (size_t)x.w * x.h * 3, diff = 0;
    for (size_t i = 0; i < n; i++) diff += memcmp(&x.rgb[i], &y.rgb[i], sizeof(float)) != 0;
    cr_assert(diff == 0, "%s and %s: %zu of %zu values differ", a, b, diff, n);
    rd_image_free_pixels(&x);
    rd_image_free_pixels(&y);
}

/* The text of a report field, "key": value, into out ("" when absent). */
static void report_field(const char *json_path, const char *key, char *out, size_t n)
{
    char buf[65536] = {0}, pat[128];
    FILE *f = fopen(json_path, "rb");
    cr_assert(f != NULL, "cannot read %s", json_path);
    size_t len = fread(buf, 1, sizeof buf - 1, f);
    buf[len] = 0;
    fclose(f);
    snprintf(pat, sizeof pat, "\"%s\":", key);
    const char *p = strstr(buf, pat);
    out[0] = 0;
    if (!p) return;
    p += strlen(pat);
    while (*p == ' ' || *p == '\t') p++;
    size_t k = 0;
    while (p[k] && p[k] != ',' && p[k] != '\n' && p[k] != '}' && k + 1 < n) k++;
    snprintf(out, n, "%.*s", (int)k, p);
}

/* Render on one process and on two ranks with the same options (and `--set set` unless NULL);
 * the images, standard errors and the report's counters must be equal. */
static void one_against_two(const char *method, const char *spp, const char *seed, const char *tag, const char *set)
{
    const char *b = bin(), *scene = scene_file("mpi.json");
    char one[256], two[256], out[8192], err[8192];
    snprintf(one, sizeof one, "%s/%s-one/img.exr", rt_tmpdir(), tag);
    snprintf(two, sizeof two, "%s/%s-two/img.exr", rt_tmpdir(), tag);
    char *a1[] = {(char *)b, "render", (char *)scene, "--method", (char *)method, "--spp", (char *)spp, "--seed",
                  (char *)seed, "--threads", "1", "--no-cache", "-q", "-o", one, set ? "--set" : NULL, (char *)set, NULL};
    int code = rt_run(a1, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "one process: exit %d: %s", code, err);
    char *a2[] = {MPI_ARGS, "-n", "2", (char *)b, "render", (char *)scene, "--method", (char *)method, "--spp",
                  (char *)spp, "--seed", (char *)seed, "--threads", "1", "--no-cache", "-q", "-o", two,
                  set ? "--set" : NULL, (char *)set, NULL};
    code = rt_run(a2, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "two ranks: exit %d: %s", code, err);
    expect_same_pixels(one, two);
    char s1[256], s2[256];
    snprintf(s1, sizeof s1, "%.*s-stderr.exr", (int)(strlen(one) - 4), one);
    snprintf(s2, sizeof s2, "%.*s-stderr.exr", (int)(strlen(two) - 4), two);
    expect_same_pixels(s1, s2);
    snprintf(s1, sizeof s1, "%.*s.json", (int)(strlen(one) - 4), one);
    snprintf(s2, sizeof s2, "%.*s.json", (int)(strlen(two) - 4), two);
    static const char *const keys[] = {"paths", "density_lookups", "tentative_collisions", "delta_share", "spp"};
    for (size_t k = 0; k < sizeof keys / sizeof keys[0]; k++) {
        char v1[64], v2[64];
        report_field(s1, keys[k], v1, sizeof v1);
        report_field(s2, keys[k], v2, sizeof v2);
        cr_assert(strcmp(v1, v2) == 0, "report %s: one process %s, two ranks %s", keys[k], v1, v2);
        cr_assert(v1[0] || !strcmp(keys[k], "delta_share"), "the report has no %s", keys[k]); /* delta: no share */
    }
}

/* `delta` at its default (since session 72 "tiles" with the epochs' shares, on this spot: the
 * selection's statistics summed over the ranks at every epoch) and plain `delta`. */
Test(mpi, two_ranks_render_delta_as_one_process_bit_for_bit, .timeout = 300)
{
    one_against_two("delta", "20", "5", "delta", NULL);
    one_against_two("delta", "20", "5", "delta-plain", "settings.equiangular=false");
}

/* guided with the tile selection: 20 samples pass the epochs at 4 and 16. With seed 4 a build
 * whose epochs folded only each rank's own pixels (no sum over the ranks) chose other tiles
 * (delta's share 0.77 against 0.6) and gave another image (69 values differ): the test saw it
 * (on this scene with the third estimator, before session 42). */
Test(mpi, two_ranks_render_guided_with_selection_as_one_process_bit_for_bit, .timeout = 300)
{
    one_against_two("guided", "20", "4", "guided", NULL);
    char v[64];
    char path[256];
    snprintf(path, sizeof path, "%s/guided-one/img.json", rt_tmpdir());
    report_field(path, "delta_share", v, sizeof v);
    double share = atof(v);
    report_field(path, "delta_equiangular_share", v, sizeof v);
    double eq = atof(v);
    /* the marcher and delta's path, or delta's path in both equiangular modes (select.c) */
    cr_assert((share > 0.0 && share < 1.0) || (eq > 0.0 && eq < share),
              "delta's share %g (%g with equiangular sampling): the selection must mix estimators", share, eq);
}

/* The outputs in dir: exactly the four of one render, no temporary left behind. */
static void expect_one_output_set(const char *dir)
{
    DIR *d = opendir(dir);
    cr_assert(d != NULL, "%s: no output folder", dir);
    int files = 0;
    char names[1024] = "";
    for (struct dirent *e; (e = readdir(d)) != NULL;) {
        if (e->d_name[0] == '.' && (!e->d_name[1] || !strcmp(e->d_name, ".."))) continue;
        files++;
        strncat(names, e->d_name, sizeof names - strlen(names) - 2);
        strcat(names, " ");
    }
    closedir(d);
    cr_assert(files == 4, "%s holds %d files (%s), expected img.exr, img-stderr.exr, img.png, img.json", dir, files, names);
}

Test(mpi, time_limited_render_on_two_ranks_ends_and_writes_one_image, .timeout = 300)
{
    /* guided: a cut pass must be agreed, and the epochs' sums matched, or a rank would wait
     * for ever. */
    const char *b = bin(), *scene = scene_file("mpi-time.json");
    char dir[256], exr[300], js[300], out[8192], err[8192];
    snprintf(dir, sizeof dir, "%s/timed", rt_tmpdir());
    snprintf(exr, sizeof exr, "%s/img.exr", dir);
    snprintf(js, sizeof js, "%s/img.json", dir);
    /* The bake first, on one process: the time limit counts a bake made by the render, and on a
     * loaded machine that could take the whole budget (then nothing is rendered, by design). */
    char prefix[256], pmap[300], guide[300];
    snprintf(prefix, sizeof prefix, "%s/bk/sel", rt_tmpdir());
    snprintf(pmap, sizeof pmap, "%s.pmap", prefix);
    snprintf(guide, sizeof guide, "%s.guide", prefix);
    char *bake[] = {(char *)b, "bake", (char *)scene, "-q", "-o", prefix, NULL};
    int code = rt_run(bake, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "bake: exit %d: %s", code, err);
    char *a[] = {MPI_ARGS, "-n", "2", (char *)b, "render", (char *)scene, "--method", "guided", "--time", "3",
                 "--threads", "1", "--photons", pmap, "--guide", guide, "-o", exr, NULL};
    code = rt_run(a, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "exit %d: %s", code, err);
    expect_one_output_set(dir);
    const char *first = strstr(out, "image  "), *again = first ? strstr(first + 1, "image  ") : NULL;
    cr_assert(first && !again, "stdout names the image once (rank 0 alone writes): %s", out);
    char v[64];
    report_field(js, "timed_out", v, sizeof v);
    cr_assert(strcmp(v, "true") == 0 || strcmp(v, "1") == 0, "timed_out is %s", v);
    report_field(js, "spp_mean", v, sizeof v);
    cr_assert(atof(v) > 0.0, "spp_mean %s", v);
}

/* The lines photonmarch printed (those starting with "photonmarch" or naming `needle`), not
 * mpirun's own notice. */
static int count_lines_with(const char *text, const char *needle)
{
    int n = 0;
    for (const char *p = text; p && *p;) {
        const char *e = strchr(p, '\n');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        char line[1024];
        snprintf(line, sizeof line, "%.*s", (int)(len < sizeof line ? len : sizeof line - 1), p);
        n += strstr(line, needle) != NULL;
        p = e ? e + 1 : NULL;
    }
    return n;
}

Test(mpi, a_rank_that_cannot_read_the_scene_ends_every_rank, .timeout = 120)
{
    /* mpirun's MPMD form: rank 0 gets a scene, rank 1 a path that is not there. */
    const char *b = bin(), *scene = scene_file("mpi-ok.json");
    char missing[256], exr[256], out[8192], err[8192];
    snprintf(missing, sizeof missing, "%s/not-there.json", rt_tmpdir());
    snprintf(exr, sizeof exr, "%s/miss/img.exr", rt_tmpdir());
    char *a[] = {MPI_ARGS, "-n", "1", (char *)b, "render", (char *)scene, "-q", "-o", exr, ":",
                 "-n", "1", (char *)b, "render", missing, "-q", "-o", exr, NULL};
    int code = rt_run(a, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 2, "exit %d (expected 2, invalid input): %s", code, err);
    cr_assert(count_lines_with(err, "photonmarch") == 1 && count_lines_with(err, "not-there.json") == 1,
              "one line naming the file: %s", err);
    cr_assert(access(exr, F_OK) != 0, "nothing is written");
}

Test(mpi, ranks_with_different_scene_files_refuse, .timeout = 120)
{
    const char *b = bin(), *s1 = scene_file("mpi-a.json");
    char s2[256], exr[256], out[8192], err[8192];
    snprintf(s2, sizeof s2, "%s/mpi-b.json", rt_tmpdir());
    /* the same scene with another seed of its noise: a valid scene, another file */
    FILE *f = fopen(s1, "rb");
    cr_assert(f != NULL);
    char buf[4096];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    char *seed = strstr(buf, "\"seed\":5");
    cr_assert(seed != NULL);
    seed[7] = '6';
    rt_write_file(s2, buf, n);
    snprintf(exr, sizeof exr, "%s/diff/img.exr", rt_tmpdir());
    char *a[] = {MPI_ARGS, "-n", "1", (char *)b, "render", (char *)s1, "-q", "-o", exr, ":",
                 "-n", "1", (char *)b, "render", s2, "-q", "-o", exr, NULL};
    int code = rt_run(a, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 2, "exit %d (expected 2): %s", code, err);
    cr_assert(count_lines_with(err, "not the same file on every rank") == 1, "one line: %s", err);
    cr_assert(access(exr, F_OK) != 0, "nothing is written");
}

Test(mpi, an_output_rank_0_cannot_write_ends_every_rank, .timeout = 120)
{
    const char *b = bin(), *scene = scene_file("mpi-out.json");
    char file[256], exr[300], out[8192], err[8192];
    snprintf(file, sizeof file, "%s/a-file", rt_tmpdir());
    rt_write_file(file, "x", 1);
    snprintf(exr, sizeof exr, "%s/img.exr", file); /* a folder that is a file */
    char *a[] = {MPI_ARGS, "-n", "2", (char *)b, "render", (char *)scene, "--spp", "2", "-q", "-o", exr, NULL};
    int code = rt_run(a, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 3, "exit %d (expected 3, output not written): %s", code, err);
    cr_assert(count_lines_with(err, "a-file") == 1, "one line naming the output: %s", err);
}

Test(mpi, commands_not_shared_between_ranks_refuse, .timeout = 120)
{
    const char *b = bin(), *scene = scene_file("mpi-info.json");
    char out[8192], err[8192];
    char *a[] = {MPI_ARGS, "-n", "2", (char *)b, "info", (char *)scene, NULL};
    int code = rt_run(a, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 1, "exit %d (expected 1): %s", code, err);
    cr_assert(count_lines_with(err, "photonmarch info") == 1, "one line: %s", err);
    /* One rank runs any command as a plain process does. */
    char *a1[] = {MPI_ARGS, "-n", "1", (char *)b, "info", (char *)scene, NULL};
    code = rt_run(a1, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "one rank: exit %d: %s", code, err);
}

Test(mpi, ranks_with_different_options_refuse, .timeout = 120)
{
    /* Both command lines parse, but the ranks would render different images (and call their
     * collectives a different number of times): they must stop before the passes. */
    const char *b = bin(), *scene = scene_file("mpi-opt.json");
    char exr[256], out[8192], err[8192];
    snprintf(exr, sizeof exr, "%s/opt/img.exr", rt_tmpdir());
    char *a[] = {MPI_ARGS, "-n", "1", (char *)b, "render", (char *)scene, "--spp", "2", "-q", "-o", exr, ":",
                 "-n", "1", (char *)b, "render", (char *)scene, "--spp", "3", "-q", "-o", exr, NULL};
    int code = rt_run(a, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 1, "exit %d (expected 1): %s", code, err);
    cr_assert(count_lines_with(err, "options differ") == 1, "one line: %s", err);
    cr_assert(access(exr, F_OK) != 0, "nothing is written");
}

/* The bytes of a file (a caller-freed buffer, its size in *n). */
static char *file_bytes(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    cr_assert(f != NULL, "cannot read %s", path);
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    rewind(f);
    char *buf = malloc((size_t)len + 1);
    cr_assert(buf != NULL && fread(buf, 1, (size_t)len, f) == (size_t)len);
    fclose(f);
    *n = (size_t)len;
    return buf;
}

Test(mpi, two_ranks_bake_the_files_of_one_process, .timeout = 300)
{
    /* 40000 photons: 10 blocks of 4096, 5 traced by each rank and gathered in block order */
    const char *b = bin(), *scene = scene_file("mpi-bake.json");
    char one[256], two[256], out[8192], err[8192];
    snprintf(one, sizeof one, "%s/bake-one/b", rt_tmpdir());
    snprintf(two, sizeof two, "%s/bake-two/b", rt_tmpdir());
    char *a1[] = {(char *)b, "bake", (char *)scene, "--seed", "7", "--threads", "1", "-o", one, NULL};
    int code = rt_run(a1, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "one process: exit %d: %s", code, err);
    char *a2[] = {MPI_ARGS, "-n", "2", (char *)b, "bake", (char *)scene, "--seed", "7", "--threads", "1", "--stats",
                  "-o", two, NULL};
    code = rt_run(a2, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "two ranks: exit %d: %s", code, err);
    const char *first = strstr(out, "photons    emitted"), *again = first ? strstr(first + 1, "photons    emitted") : NULL;
    cr_assert(first && !again, "rank 0 alone prints: %s", out);
    cr_assert(strstr(out, "gather") != NULL, "--stats on two ranks says the gather: %s", out);
    char p1[300], p2[300];
    size_t n1, n2;
    snprintf(p1, sizeof p1, "%s.pmap", one);
    snprintf(p2, sizeof p2, "%s.pmap", two);
    char *x = file_bytes(p1, &n1), *y = file_bytes(p2, &n2);
    cr_assert(n1 == n2 && memcmp(x, y, n1) == 0, "%s and %s differ (%zu and %zu bytes)", p1, p2, n1, n2);
    free(x), free(y);
    snprintf(p1, sizeof p1, "%s.guide", one);
    snprintf(p2, sizeof p2, "%s.guide", two);
    x = file_bytes(p1, &n1), y = file_bytes(p2, &n2);
    cr_assert(rt_same_guide_bytes(x, n1, y, n2), "%s and %s differ (but for the bake time)", p1, p2);
    free(x), free(y);
    snprintf(p1, sizeof p1, "%s-photons.exr", one);
    snprintf(p2, sizeof p2, "%s-photons.exr", two);
    expect_same_pixels(p1, p2);
}

Test(mpi, two_ranks_bake_through_the_cache_together_and_render_one_process_s_image, .timeout = 300)
{
    /* A render's own bake through the cache on two ranks: no cache yet, so the ranks trace
     * together and rank 0 saves the cache; the second render finds it on every rank. Both
     * images are one process's (which baked with --no-cache). */
    const char *b = bin(), *scene = scene_file("mpi-cache.json");
    char one[256], two[300], dir[256], out[8192], err[8192];
    snprintf(one, sizeof one, "%s/cache-one/img.exr", rt_tmpdir());
    snprintf(dir, sizeof dir, "%s/cache-two", rt_tmpdir());
    snprintf(two, sizeof two, "%s/img.exr", dir);
    char *a1[] = {(char *)b, "render", (char *)scene, "--method", "guided", "--spp", "6", "--seed", "2", "--threads",
                  "1", "--no-cache", "-q", "-o", one, NULL};
    int code = rt_run(a1, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "one process: exit %d: %s", code, err);
    for (int run = 0; run < 2; run++) {
        char *a2[] = {MPI_ARGS, "-n", "2", (char *)b, "render", (char *)scene, "--method", "guided", "--spp", "6",
                      "--seed", "2", "--threads", "1", "-o", two, NULL};
        code = rt_run(a2, out, sizeof out, err, sizeof err, NULL);
        cr_assert(code == 0, "two ranks, run %d: exit %d: %s", run, code, err);
        const char *said = run == 0 ? "baked the photon map" : "reused the cached photon map";
        cr_assert(count_lines_with(err, said) == 1, "run %d: rank 0 says \"%s\" once: %s", run, said, err);
        expect_same_pixels(one, two);
    }
    char cache[300];
    snprintf(cache, sizeof cache, "%s/.photonmarch-cache", dir);
    DIR *dd = opendir(cache);
    cr_assert(dd != NULL, "no cache folder %s", cache);
    int pmaps = 0, others = 0;
    for (struct dirent *e; (e = readdir(dd)) != NULL;) {
        if (e->d_name[0] == '.') continue;
        size_t len = strlen(e->d_name);
        if (len > 5 && !strcmp(e->d_name + len - 5, ".pmap")) pmaps++;
        else if (len <= 6 || strcmp(e->d_name + len - 6, ".guide")) others++;
    }
    closedir(dd);
    cr_assert(pmaps >= 1 && others == 0, "the cache holds %d maps and %d other files (temporaries?)", pmaps, others);
}

/* The pid of the process whose parent is `parent` and whose environment says
 * OMPI_COMM_WORLD_RANK=rank (0: none found). */
static pid_t rank_pid(pid_t parent, int rank)
{
    DIR *proc = opendir("/proc");
    cr_assert(proc != NULL);
    pid_t found = 0;
    char want[64];
    int wlen = snprintf(want, sizeof want, "OMPI_COMM_WORLD_RANK=%d", rank);
    for (struct dirent *e; !found && (e = readdir(proc)) != NULL;) {
        pid_t pid = (pid_t)atoi(e->d_name);
        if (pid <= 0) continue;
        char path[64], buf[4096];
        snprintf(path, sizeof path, "/proc/%d/stat", (int)pid);
        FILE *f = fopen(path, "r");
        if (!f) continue;
        size_t n = fread(buf, 1, sizeof buf - 1, f);
        fclose(f);
        buf[n] = 0;
        const char *rp = strrchr(buf, ')'); /* "pid (comm) state ppid ..." */
        int ppid = 0;
        char state;
        if (!rp || sscanf(rp + 1, " %c %d", &state, &ppid) != 2 || ppid != parent) continue;
        snprintf(path, sizeof path, "/proc/%d/environ", (int)pid);
        if (!(f = fopen(path, "r"))) continue;
        static char env[1 << 16];
        n = fread(env, 1, sizeof env - 1, f);
        fclose(f);
        for (size_t i = 0; i < n; i += strlen(env + i) + 1)
            if (!strncmp(env + i, want, (size_t)wlen) && env[i + wlen] == 0) found = pid;
    }
    closedir(proc);
    return found;
}

Test(mpi, a_rank_killed_mid_render_ends_the_job_and_leaves_the_old_image, .timeout = 300)
{
    const char *b = bin(), *scene = scene_file("mpi-kill.json");
    char exr[256], out[8192], err[8192];
    snprintf(exr, sizeof exr, "%s/kill/img.exr", rt_tmpdir());
    /* a good image there first */
    char *a1[] = {(char *)b, "render", (char *)scene, "--method", "delta", "--spp", "2", "--threads", "1", "-q", "-o",
                  exr, NULL};
    int code = rt_run(a1, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "the first render: exit %d: %s", code, err);
    size_t n0, nj0;
    char js[300];
    snprintf(js, sizeof js, "%s/kill/img.json", rt_tmpdir());
    char *before = file_bytes(exr, &n0), *before_js = file_bytes(js, &nj0);
    /* A long render on two ranks; rank 0's first progress line says the passes have begun. */
    char *a2[] = {MPI_ARGS, "-n", "2", (char *)b, "render", (char *)scene, "--method", "delta", "--time", "60",
                  "--threads", "1", "-o", exr, NULL};
    child c = spawn_until(a2, " spp ", err, sizeof err);
    pid_t victim = rank_pid(c.pid, 1);
    cr_assert(victim > 0, "rank 1's process (a child of mpirun %d) not found", (int)c.pid);
    cr_assert(kill(victim, SIGKILL) == 0);
    /* mpirun must end the job: poll for its end, well within the 60 s the render asked for */
    struct timespec t0, now, nap = {0, 20 * 1000 * 1000};
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int status = 0, ended = 0;
    for (;;) {
        pid_t w = waitpid(c.pid, &status, WNOHANG);
        cr_assert(w >= 0);
        if (w == c.pid) { ended = 1; break; }
        clock_gettime(CLOCK_MONOTONIC, &now);
        if (now.tv_sec - t0.tv_sec > 30) break;
        nanosleep(&nap, NULL);
    }
    if (!ended) { /* fail, but leave nothing running */
        kill(c.pid, SIGKILL);
        waitpid(c.pid, &status, 0);
    }
    child_stderr(&c, err, sizeof err);
    close(c.efd), close(c.ofd);
    unlink(c.path), unlink(c.opath);
    cr_assert(ended, "mpirun still ran 30 s after rank 1 was killed: %s", err);
    cr_assert(!(WIFEXITED(status) && WEXITSTATUS(status) == 0), "the job ended with status 0: %s", err);
    size_t n1, nj1;
    char *after = file_bytes(exr, &n1), *after_js = file_bytes(js, &nj1);
    cr_assert(n0 == n1 && memcmp(before, after, n0) == 0, "%s changed", exr);
    cr_assert(nj0 == nj1 && memcmp(before_js, after_js, nj0) == 0, "%s changed", js);
    free(before), free(after), free(before_js), free(after_js);
}

/* metrics.json of a compare report, parsed (the caller frees it with cJSON_Delete). */
static cJSON *read_metrics(const char *dir)
{
    char path[300];
    size_t n;
    snprintf(path, sizeof path, "%s/metrics.json", dir);
    char *text = file_bytes(path, &n);
    cJSON *j = cJSON_Parse(text);
    free(text);
    cr_assert(j != NULL, "%s: not JSON", path);
    return j;
}

static double json_number(const cJSON *o, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    cr_assert(v != NULL && cJSON_IsNumber(v), "no number \"%s\"", key);
    return v->valuedouble;
}

Test(mpi, compare_on_two_ranks_gives_one_process_s_numbers, .timeout = 600)
{
    /* equal spp, a fixed reference: every number but the times is decided by the images, which
     * must be one process's (each run whole on one rank, the reference by both together) */
    const char *b = bin(), *scene = scene_file("mpi-cmp.json");
    char one[256], two[256], out[16384], err[8192];
    snprintf(one, sizeof one, "%s/cmp-one", rt_tmpdir());
    snprintf(two, sizeof two, "%s/cmp-two", rt_tmpdir());
#define CMP_ARGS "compare", (char *)scene, "--methods", "delta,guided", "--equal", "spp", "--budget", "4", "--runs", \
                 "3", "--ref-spp", "16", "--seed", "3", "--threads", "1", "--no-cache", "-q"
    char *a1[] = {(char *)b, CMP_ARGS, "-o", one, NULL};
    int code = rt_run(a1, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "one process: exit %d: %s", code, err);
    char *a2[] = {MPI_ARGS, "-n", "2", (char *)b, CMP_ARGS, "-o", two, NULL};
#undef CMP_ARGS
    code = rt_run(a2, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "two ranks: exit %d: %s", code, err);
    const char *first = strstr(out, "report "), *again = first ? strstr(first + 1, "report ") : NULL;
    cr_assert(first && !again, "rank 0 alone prints: %s", out);
    cJSON *x = read_metrics(one), *y = read_metrics(two);
    cr_assert(json_number(x, "ranks") == 1 && json_number(y, "ranks") == 2, "the report records the ranks");
    const cJSON *hosts = cJSON_GetObjectItemCaseSensitive(y, "hosts");
    cr_assert(cJSON_IsString(hosts) && strstr(hosts->valuestring, " x2"), "hosts: one host, two ranks");
    const cJSON *rx = cJSON_GetObjectItemCaseSensitive(x, "reference"), *ry = cJSON_GetObjectItemCaseSensitive(y, "reference");
    cr_assert(json_number(rx, "spp") == json_number(ry, "spp") && json_number(rx, "variance") == json_number(ry, "variance"),
              "the reference differs");
    const cJSON *mx = cJSON_GetObjectItemCaseSensitive(x, "methods"), *my = cJSON_GetObjectItemCaseSensitive(y, "methods");
    cr_assert(cJSON_GetArraySize(mx) == 2 && cJSON_GetArraySize(my) == 2);
    static const char *const keys[] = {"runs", "spp", "mse", "rmse", "relmse", "mare", "bias2", "bias2_se", "variance",
                                       "homogeneity"};
    for (int i = 0; i < 2; i++) {
        const cJSON *p = cJSON_GetArrayItem(mx, i), *q = cJSON_GetArrayItem(my, i);
        for (size_t k = 0; k < sizeof keys / sizeof keys[0]; k++) {
            double u = json_number(p, keys[k]), v = json_number(q, keys[k]);
            cr_assert(u == v, "%s %s: one process %.17g, two ranks %.17g", cJSON_GetObjectItem(p, "label")->valuestring,
                      keys[k], u, v);
        }
        const cJSON *pp = cJSON_GetObjectItemCaseSensitive(p, "per_pixel"), *qp = cJSON_GetObjectItemCaseSensitive(q, "per_pixel");
        cr_assert(json_number(pp, "collisions") == json_number(qp, "collisions") &&
                      json_number(pp, "lookups") == json_number(qp, "lookups"),
                  "the counters per pixel differ");
    }
    cJSON_Delete(x);
    cJSON_Delete(y);
}
