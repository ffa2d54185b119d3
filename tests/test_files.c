/* core/files.c, the one implementation of "write under a hidden temporary name, then rename"
 * (docs/cli.md, "Signals"), and the bake's cancel flag: rd_write_file puts a complete file in
 * place or leaves the previous one, never leaves its temporary, honours the cancel flag before
 * the rename and clears the temporaries of dead processes; a cancelled bake (rd_bake,
 * rd_bake_cached) returns RD_ERR_CANCELLED and writes nothing. The command line's signals:
 * tests/test_cli.c. */
#include "support/rd_test.h"

#include <dirent.h>
#include <errno.h>

/* Entries of `dir` whose name contains `part`. */
static int entries_with(const char *dir, const char *part)
{
    DIR *d = opendir(dir);
    if (!d) return 0;
    int n = 0;
    for (struct dirent *e; (e = readdir(d)) != NULL;) n += strstr(e->d_name, part) != NULL;
    closedir(d);
    return n;
}

static char *slurp(const char *path)
{
    static char buf[4096];
    FILE *f = fopen(path, "rb");
    cr_assert(f != NULL, "%s: missing", path);
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    buf[n] = 0;
    fclose(f);
    return buf;
}

typedef struct { const char *text; int fail; volatile int *raise; } job;

/* Writes job.text; with fail, writes half of it and fails; with raise, raises the flag while
 * writing (a signal arriving mid-write). */
static rd_status write_job(FILE *f, void *user, char *err, size_t errlen)
{
    const job *j = user;
    size_t n = strlen(j->text);
    if (j->raise) *j->raise = 2;
    if (j->fail) {
        fwrite(j->text, 1, n / 2, f);
        snprintf(err, errlen, "planted failure");
        return RD_ERR_OUTPUT;
    }
    return fwrite(j->text, 1, n, f) == n ? RD_OK : RD_ERR_OUTPUT;
}

Test(files, write_file_replaces_or_keeps_the_previous_file_and_never_leaves_its_temporary)
{
    char dir[300], path[400], err[RD_ERRLEN];
    snprintf(dir, sizeof dir, "%s/wf", rt_tmpdir());
    cr_assert(mkdir(dir, 0777) == 0);
    snprintf(path, sizeof path, "%s/out.txt", dir);

    job good = {"first version", 0, NULL};
    cr_assert_eq(rd_write_file(path, write_job, &good, NULL, err, sizeof err), RD_OK, "%s", err);
    cr_expect_str_eq(slurp(path), "first version");

    /* A writer that fails: its status and message, the previous file as it was. */
    job bad = {"second version", 1, NULL};
    cr_expect_eq(rd_write_file(path, write_job, &bad, NULL, err, sizeof err), RD_ERR_OUTPUT);
    cr_expect(strstr(err, "planted failure") != NULL, "%s", err);
    cr_expect_str_eq(slurp(path), "first version");

    /* The cancel flag raised while the file is written: not put in place. */
    volatile int flag = 0;
    job cancelled = {"third version", 0, &flag};
    cr_expect_eq(rd_write_file(path, write_job, &cancelled, &flag, err, sizeof err), RD_ERR_CANCELLED);
    cr_expect(strstr(err, path) != NULL, "the message does not name the file: %s", err);
    cr_expect_str_eq(slurp(path), "first version");
    /* ... and a flag that is not raised changes nothing. */
    volatile int quiet = 0;
    job fourth = {"fourth version", 0, NULL};
    cr_expect_eq(rd_write_file(path, write_job, &fourth, &quiet, err, sizeof err), RD_OK, "%s", err);
    cr_expect_str_eq(slurp(path), "fourth version");

    /* A folder that does not exist: RD_ERR_OUTPUT naming the file. */
    char missing[400];
    snprintf(missing, sizeof missing, "%s/no/such/out.txt", dir);
    cr_expect_eq(rd_write_file(missing, write_job, &good, NULL, err, sizeof err), RD_ERR_OUTPUT);
    cr_expect(strstr(err, missing) != NULL, "%s", err);

    cr_expect_eq(entries_with(dir, ".tmp"), 0, "a temporary was left in %s", dir);
}

/* The pid of a process that has ended (forked, exited, reaped). */
static long dead_pid(void)
{
    pid_t pid = fork();
    cr_assert(pid >= 0);
    if (pid == 0) _exit(0);
    cr_assert(waitpid(pid, NULL, 0) == pid);
    return (long)pid;
}

/* Putting a file in place clears the temporaries of that path left by dead processes, and only
 * those: not a running process's, not another output's. rd_temp_name is the scheme the C++ shims
 * write to. */
Test(files, temporaries_of_dead_processes_are_cleared_by_the_next_write)
{
    char dir[300], path[400], p[500], err[RD_ERRLEN];
    snprintf(dir, sizeof dir, "%s/stale", rt_tmpdir());
    cr_assert(mkdir(dir, 0777) == 0);
    snprintf(path, sizeof path, "%s/b.pmap", dir);
    char mine[500];
    cr_assert_eq(rd_temp_name(path, mine, sizeof mine), 0);
    snprintf(p, sizeof p, "%s/.b.tmp%ld.pmap", dir, (long)getpid());
    cr_expect_str_eq(mine, p, "the temporary name scheme changed: %s", mine);

    long dead = dead_pid(), live = (long)getppid();
    char gone[500], kept_live[500], kept_other[500];
    snprintf(gone, sizeof gone, "%s/.b.tmp%ld.pmap", dir, dead);
    snprintf(kept_live, sizeof kept_live, "%s/.b.tmp%ld.pmap", dir, live);
    snprintf(kept_other, sizeof kept_other, "%s/.b.tmp%ld.guide", dir, dead);
    rt_write_file(gone, "x", 1);
    rt_write_file(kept_live, "x", 1);
    rt_write_file(kept_other, "x", 1);
    job good = {"map", 0, NULL};
    cr_assert_eq(rd_write_file(path, write_job, &good, NULL, err, sizeof err), RD_OK, "%s", err);
    cr_expect(access(gone, F_OK) != 0, "%s: the temporary of a dead process was not removed", gone);
    cr_expect(access(kept_live, F_OK) == 0, "%s: the temporary of a running process was removed", kept_live);
    cr_expect(access(kept_other, F_OK) == 0, "%s: another output's temporary was removed", kept_other);

    /* rd_commit_temp (the shims' rename) clears them too. */
    rt_write_file(gone, "x", 1);
    rt_write_file(mine, "shim", 4);
    cr_assert_eq(rd_commit_temp(mine, path, err, sizeof err), RD_OK, "%s", err);
    cr_expect_str_eq(slurp(path), "shim");
    cr_expect(access(gone, F_OK) != 0, "rd_commit_temp left a dead process's temporary");
}

static const char *bake_scene_json =
    "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"resolution\":[16,12]},"
    "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":2,\"albedo\":0.9,\"g\":0.4}],"
    "\"lights\":[{\"type\":\"point\",\"position\":[1,2,1],\"intensity\":5}],"
    "\"photons\":{\"count\":20000}}";

/* A raised cancel flag stops rd_bake (tracing skips every block) and rd_bake_cached, which then
 * saves nothing: no cache file and no temporary. The same bake without the flag succeeds, so
 * the status is the flag's doing. */
Test(files, a_cancelled_bake_returns_cancelled_and_writes_nothing)
{
    rd_scene *s = rt_scene("bake.json", bake_scene_json);
    char err[RD_ERRLEN], dir[300];
    snprintf(dir, sizeof dir, "%s/cache", rt_tmpdir());
    volatile int flag = SIGTERM;
    rd_bake_opts bo = {.seed = -1, .threads = 2, .cancel = &flag};
    rd_baked *b = NULL;
    cr_expect_eq(rd_bake(s, &bo, &b, err, sizeof err), RD_ERR_CANCELLED, "%s", err);
    cr_expect_null(b);
    cr_expect(strstr(err, "interrupted") != NULL, "%s", err);
    int hit = 0;
    cr_expect_eq(rd_bake_cached(s, &bo, dir, &b, &hit, err, sizeof err), RD_ERR_CANCELLED, "%s", err);
    cr_expect_null(b);
    cr_expect(access(dir, F_OK) != 0 || (entries_with(dir, ".pmap") == 0 && entries_with(dir, ".guide") == 0),
              "a cancelled bake wrote into the cache %s", dir);

    flag = 0;
    cr_assert_eq(rd_bake_cached(s, &bo, dir, &b, &hit, err, sizeof err), RD_OK, "%s", err);
    cr_expect_eq(hit, 0);
    cr_expect_eq(entries_with(dir, ".pmap"), 1);
    cr_expect_eq(entries_with(dir, ".guide"), 1);
    cr_expect_eq(entries_with(dir, ".tmp"), 0);
    rd_baked_free(b);
    rd_scene_free(s);
}
