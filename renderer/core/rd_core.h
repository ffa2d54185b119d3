/* rd_core.h: what every part of the renderer may use to write files: growing text buffers and
 * atomic writes (a temporary name in the target's folder, then a rename). Internal to renderer/;
 * it uses nothing of the renderer but renderer.h's status codes. */
#ifndef RD_CORE_H
#define RD_CORE_H

#include "renderer.h"

#include <stddef.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/* A growing text buffer (core/text.c): rd_text_printf appends; on a failed allocation it sets oom
 * and ignores later calls, so a writer checks oom once at the end. Start with {0}; free(s). */
typedef struct { char *s; size_t n, cap; int oom; } rd_text;
void rd_text_printf(rd_text *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Write the buffer to path atomically (rd_write_atomic) and free it; a buffer that ran out of
 * memory writes nothing and fails with RD_ERR_NOMEM, "PATH: out of memory". */
rd_status rd_text_write(rd_text *b, const char *path, char *err, size_t errlen);

/* ---- Atomic writes (core/files.c), the one implementation of the policy of docs/cli.md,
 * "Signals": a file is written under a hidden temporary name in its folder,
 * ".stem.tmp<pid>.ext", and renamed into place, so an output is always the previous file or the
 * complete new one; putting a file in place removes the temporaries of that path left by
 * processes that no longer run. */

/* Writes one file's bytes to f (opened "wb"; not to be closed); on failure a message naming the
 * file in err and a status other than RD_OK. */
typedef rd_status (*rd_file_writer)(FILE *f, void *user, char *err, size_t errlen);
/* Write path through its temporary: write(f, user, ...), flush, fsync, close, then, unless
 * *cancel (when cancel is not NULL) has become non-zero meanwhile, rename into place. On any
 * failure, or when cancelled (RD_ERR_CANCELLED), the temporary is removed and path is left as it
 * was. Errors: the writer's status, or RD_ERR_OUTPUT naming the path. */
rd_status rd_write_file(const char *path, rd_file_writer write, void *user, const volatile int *cancel,
                        char *err, size_t errlen);
/* Write n bytes to path (rd_write_file); RD_ERR_OUTPUT naming the path. */
rd_status rd_write_atomic(const char *path, const void *data, size_t n, char *err, size_t errlen);

/* ---- Collectives on the rd_comm hooks (core/comm.c; renderer.h, docs/cluster.md). Each is
 * collective when c has several ranks (every rank calls it, in the same order) and does the
 * one-process thing when c is NULL or has one rank. */

/* The worst outcome over the ranks (the largest rd_status), the same on every rank. A rank whose
 * own st was RD_OK and that gets a failure writes "WHAT: failed " RD_ON_ANOTHER_RANK (or
 * "interrupted ...") into err. */
rd_status rd_comm_agree(const rd_comm *c, rd_status st, const char *what, char *err, size_t errlen);
/* Rank root's `bytes` bytes at buf into every rank's buf (bytes the same on every rank). */
void rd_comm_bcast(const rd_comm *c, void *buf, size_t bytes, int root);
/* For writers that need a file name (OpenImageIO, OpenVDB): the temporary name of path for this
 * process into out (n bytes); -1 when it does not fit. Write it, then rd_commit_temp (or
 * remove it on failure). */
int rd_temp_name(const char *path, char *out, size_t n);
/* Rename tmp onto path and remove path's stale temporaries; on failure remove tmp and return
 * RD_ERR_OUTPUT naming both. */
rd_status rd_commit_temp(const char *tmp, const char *path, char *err, size_t errlen);
/* Remove the hidden temporaries of `path` left by processes that no longer run (kill(pid, 0)
 * fails with ESRCH); those of running processes stay. Best effort, reports nothing. */
void rd_remove_stale_temps(const char *path);

#ifdef __cplusplus
}
#endif
#endif /* RD_CORE_H */
