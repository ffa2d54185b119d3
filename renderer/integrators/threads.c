/* threads.c: the worker threads' contexts and the per-pixel arrays they write, each on cache
 * lines of its own (rd_method.h: rd_threads_new, rd_alloc_lines). A leaf: render/render.c and
 * integrators/select.c allocate through it. */
#include "integrators/rd_method.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

void *rd_alloc_lines(size_t bytes)
{
    if (bytes > SIZE_MAX - RD_CACHE_LINE) return NULL; /* no wrap in the rounding below */
    size_t whole = (bytes + RD_CACHE_LINE - 1) / RD_CACHE_LINE * RD_CACHE_LINE; /* C11 asks a multiple */
    void *p = aligned_alloc(RD_CACHE_LINE, whole ? whole : RD_CACHE_LINE);
    if (p) memset(p, 0, whole);
    return p;
}

rd_thread *rd_threads_new(const rd_render_ctx *ctx, int n)
{
    size_t bytes = ctx->method->scratch_bytes ? ctx->method->scratch_bytes(ctx) : 0;
    rd_thread *th = rd_alloc_lines((size_t)n * sizeof *th);
    if (!th) return NULL;
    for (int i = 0; i < n; i++) {
        th[i].index = i;
        if (!bytes) continue;
        th[i].scratch_bytes = bytes;
        th[i].scratch = rd_alloc_lines(bytes);
        if (!th[i].scratch) {
            rd_threads_free(th, i);
            return NULL;
        }
    }
    return th;
}

void rd_threads_free(rd_thread *th, int n)
{
    for (int i = 0; th && i < n; i++) free(th[i].scratch);
    free(th);
}
