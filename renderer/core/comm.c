/* comm.c: small collectives built on the rd_comm hooks (renderer.h; docs/cluster.md) that the
 * bake, the render and the comparison share: agreeing on an outcome, and a broadcast. */
#include "core/rd_core.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>

rd_status rd_comm_agree(const rd_comm *c, rd_status st, const char *what, char *err, size_t errlen)
{
    if (!c || c->size <= 1) return st;
    int v = (int)st;
    c->reduce(c->user, &v, 1, RD_COMM_INT, RD_COMM_MAX, -1);
    if (st == RD_OK && v != RD_OK)
        snprintf(err, errlen, "%s: %s " RD_ON_ANOTHER_RANK, what, v == RD_ERR_CANCELLED ? "interrupted" : "failed");
    return (rd_status)v;
}

/* A broadcast as an all-reduce sum to which every rank but the root adds zeros: exact (unsigned
 * integers), and in pieces of a buffer on the stack, so it allocates nothing (an allocation that
 * failed on one rank between collectives would leave the others waiting for it). */
void rd_comm_bcast(const rd_comm *c, void *buf, size_t bytes, int root)
{
    if (!c || c->size <= 1 || bytes == 0) return;
    uint32_t piece[4096];
    unsigned char *b = buf;
    for (size_t off = 0; off < bytes; off += sizeof piece) {
        size_t n = bytes - off < sizeof piece ? bytes - off : sizeof piece;
        size_t words = (n + sizeof *piece - 1) / sizeof *piece;
        memset(piece, 0, words * sizeof *piece);
        if (c->rank == root) memcpy(piece, b + off, n);
        c->reduce(c->user, piece, words, RD_COMM_UINT32, RD_COMM_SUM, -1);
        memcpy(b + off, piece, n);
    }
}
