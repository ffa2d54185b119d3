/* rd_core.h: what every part of the renderer may use to write files: growing text buffers and
 * atomic writes (a temporary name in the target's folder, then a rename). Internal to renderer/;
 * it uses nothing of the renderer but renderer.h's status codes. */
#ifndef RD_CORE_H
#define RD_CORE_H

#include "renderer.h"

#include <stddef.h>

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

/* Write n bytes to path through a temporary name in its folder and a rename (core/files.c), so a
 * failed write never leaves a partial file; RD_ERR_OUTPUT naming the path. */
rd_status rd_write_atomic(const char *path, const void *data, size_t n, char *err, size_t errlen);
/* Remove the hidden temporaries of `path` (".stem.tmp<pid>.ext", the scheme of rd_write_atomic
 * and image_io.cpp) left by processes that no longer run; best effort, reports nothing. */
void rd_remove_stale_temps(const char *path);

#ifdef __cplusplus
}
#endif
#endif /* RD_CORE_H */
