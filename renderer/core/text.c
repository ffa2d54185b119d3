/* text.c: a growing text buffer for the files the renderer writes as text (the compare report,
 * explain's table and gnuplot script) and writes them. Contract in core/rd_core.h. */
#include "core/rd_core.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

void rd_text_printf(rd_text *b, const char *fmt, ...)
{
    if (b->oom) return;
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int n = vsnprintf(b->s ? b->s + b->n : NULL, b->s ? b->cap - b->n : 0, fmt, ap);
        va_end(ap);
        if (n < 0) { b->oom = 1; return; }
        if (b->s && b->n + (size_t)n < b->cap) { b->n += (size_t)n; return; }
        size_t cap = (b->cap + (size_t)n + 1) * 2;
        char *p = realloc(b->s, cap);
        if (!p) { b->oom = 1; return; }
        b->s = p, b->cap = cap;
    }
}

rd_status rd_text_write(rd_text *b, const char *path, char *err, size_t errlen)
{
    rd_status st;
    if (b->oom) {
        st = RD_ERR_NOMEM;
        if (err && errlen) snprintf(err, errlen, "%s: out of memory", path);
    } else {
        st = rd_write_atomic(path, b->s ? b->s : "", b->n, err, errlen);
    }
    free(b->s);
    *b = (rd_text){0};
    return st;
}
