/* files.c: the renderer's files on disk: making an output's folder, and writing a file through
 * a temporary name in its folder and a rename, so a failed or interrupted run never leaves a
 * partial file where a good one was. A run killed mid-write leaves at most a hidden temporary
 * (".OUT.tmp<pid>.ext"), which the next run writing the same output removes. This is the one
 * implementation of that policy: the leaf libraries write to a stream (pm_map_write,
 * sh_guide_write, through rd_write_file); images.c (for the OpenImageIO module) and vdb_io.cpp
 * have their files written at rd_temp_name's name and call rd_commit_temp. */
#define _DEFAULT_SOURCE /* mkdir, kill */
#include "core/rd_core.h"

#include <dirent.h>
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

rd_status rd_make_parent_dirs(const char *path, char *err, size_t errlen)
{
    char dir[2048];
    if (snprintf(dir, sizeof dir, "%s", path) >= (int)sizeof dir) {
        snprintf(err, errlen, "%.200s...: path too long", path);
        return RD_ERR_OUTPUT;
    }
    char *slash = strrchr(dir, '/');
    if (!slash) return RD_OK;
    *slash = 0;
    for (char *p = dir + 1; *p; p++) {
        if (*p != '/') continue;
        *p = 0;
        if (mkdir(dir, 0777) != 0 && errno != EEXIST) goto fail;
        *p = '/';
    }
    if (dir[0] == 0 || mkdir(dir, 0777) == 0 || errno == EEXIST) return RD_OK;
fail:
    snprintf(err, errlen, "%s: cannot create its folder: %s", path, strerror(errno));
    return RD_ERR_OUTPUT;
}

/* The temporary name of `path` for process `pid`: "dir/stem.ext" -> "dir/.stem.tmp<pid>.ext":
 * in the same folder (so the rename is atomic), hidden (a leading dot), keeping the extension
 * (OpenImageIO picks the format by it). Returns the length of "dir/.stem.tmp" (the part before
 * the pid), or -1 if the name does not fit. */
static int temp_name(const char *path, long pid, char *out, size_t n)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    if (!dot || dot == base) dot = base + strlen(base);
    int dirlen = (int)(base - path), stemlen = (int)(dot - base);
    int len = snprintf(out, n, "%.*s.%.*s.tmp%ld%s", dirlen, path, stemlen, base, pid, dot);
    return len < 0 || (size_t)len >= n ? -1 : dirlen + 1 + stemlen + 4;
}

int rd_temp_name(const char *path, char *out, size_t n)
{
    return temp_name(path, (long)getpid(), out, n) < 0 ? -1 : 0;
}

/* A process killed mid-write (SIGKILL, a second Ctrl-C, a power cut) leaves its hidden
 * temporary file; remove those of `path` whose process no longer runs (kill(pid, 0) fails with
 * ESRCH). A temporary of a running process (a concurrent run writing the same output) is left
 * alone. Best effort: nothing is reported. */
void rd_remove_stale_temps(const char *path)
{
    char pattern[2200], dir[2200], victim[2600];
    int pre = temp_name(path, 0, pattern, sizeof pattern);
    if (pre < 0) return;
    const char *slash = strrchr(path, '/');
    snprintf(dir, sizeof dir, "%.*s", slash ? (int)(slash - path + 1) : 2, slash ? path : "./");
    const char *want = pattern + (slash ? slash - path + 1 : 0); /* ".stem.tmp0.ext" */
    size_t wlen = (size_t)(pre - (want - pattern));                 /* ".stem.tmp" */
    const char *ext = pattern + pre + 1;                            /* after the "0" */
    DIR *d = opendir(dir);
    if (!d) return;
    for (struct dirent *e; (e = readdir(d)) != NULL;) {
        const char *name = e->d_name;
        if (strncmp(name, want, wlen) != 0) continue;
        char *end;
        errno = 0;
        long pid = strtol(name + wlen, &end, 10);
        if (errno || end == name + wlen || pid <= 0 || strcmp(end, ext) != 0 || pid == (long)getpid()) continue;
        if (kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue;
        snprintf(victim, sizeof victim, "%s%s", dir, name);
        unlink(victim);
    }
    closedir(d);
}

rd_status rd_commit_temp(const char *tmp, const char *path, char *err, size_t errlen)
{
    if (rename(tmp, path) != 0) {
        snprintf(err, errlen, "%s: cannot rename %s into place: %s", path, tmp, strerror(errno));
        remove(tmp);
        return RD_ERR_OUTPUT;
    }
    rd_remove_stale_temps(path);
    return RD_OK;
}

rd_status rd_write_file(const char *path, rd_file_writer write, void *user, const volatile int *cancel,
                        char *err, size_t errlen)
{
    char tmp[2200];
    if (rd_temp_name(path, tmp, sizeof tmp) < 0) {
        snprintf(err, errlen, "%.200s...: path too long", path);
        return RD_ERR_OUTPUT;
    }
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        snprintf(err, errlen, "%s: cannot write: %s", path, strerror(errno));
        return RD_ERR_OUTPUT;
    }
    /* The writer's own message names the file; a failure of the flush, fsync (so that after a
     * power cut the renamed file has its bytes) or close is ours. */
    rd_status st = write(f, user, err, errlen);
    if (st == RD_OK && (fflush(f) != 0 || fsync(fileno(f)) != 0)) {
        snprintf(err, errlen, "%s: cannot write: %s", path, strerror(errno));
        st = RD_ERR_OUTPUT;
    }
    if (fclose(f) != 0 && st == RD_OK) {
        snprintf(err, errlen, "%s: cannot write: %s", path, strerror(errno));
        st = RD_ERR_OUTPUT;
    }
    if (st == RD_OK && cancel && *cancel) {
        snprintf(err, errlen, "%s: not written (interrupted)", path);
        st = RD_ERR_CANCELLED;
    }
    if (st != RD_OK) {
        remove(tmp);
        return st;
    }
    return rd_commit_temp(tmp, path, err, errlen);
}

typedef struct { const void *data; size_t n; const char *path; } bytes_job;

static rd_status write_bytes(FILE *f, void *user, char *err, size_t errlen)
{
    const bytes_job *j = user;
    if (fwrite(j->data, 1, j->n, f) == j->n) return RD_OK;
    snprintf(err, errlen, "%s: cannot write: %s", j->path, strerror(errno));
    return RD_ERR_OUTPUT;
}

rd_status rd_write_atomic(const char *path, const void *data, size_t n, char *err, size_t errlen)
{
    bytes_job j = {data, n, path};
    return rd_write_file(path, write_bytes, &j, NULL, err, errlen);
}
