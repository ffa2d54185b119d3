/* comm.c: small collectives built on the rd_comm hooks (renderer.h; docs/cluster.md) that the
 * bake, the render and the comparison share: agreeing on an outcome, and a broadcast. */
#include "core/rd_core.h"

#include <stdio.h>
#include <stdlib.h>

enum { RD_COMM_BCAST_MAX_RANKS_ON_STACK = 64 };

rd_status rd_comm_agree(const rd_comm *c, rd_status st, const char *what, char *err, size_t errlen)
{
    if (!c || c->size <= 1) return st;
    int v = (int)st;
    c->reduce(c->user, &v, 1, RD_COMM_INT, RD_COMM_MAX, -1);
    if (st == RD_OK && v != RD_OK)
        snprintf(err, errlen, "%s: %s " RD_ON_ANOTHER_RANK, what, v == RD_ERR_CANCELLED ? "interrupted" : "failed");
    return (rd_status)v;
}

void rd_comm_bcast(const rd_comm *c, void *buf, size_t bytes, int root)
{
    if (!c || c->size <= 1 || bytes == 0) return;
    size_t counts[RD_COMM_BCAST_MAX_RANKS_ON_STACK], *cn = counts;
    if (c->size > RD_COMM_BCAST_MAX_RANKS_ON_STACK) cn = NULL;
    /* (more ranks than the stack array: one count at a time would not match the hook's
     * contract, so the counts go on the heap; a failed allocation ends the job, as a failed
     * collective does) */
    if (!cn && !(cn = calloc((size_t)c->size, sizeof *cn))) abort();
    for (int k = 0; k < c->size; k++) cn[k] = k == root ? bytes : 0;
    /* the root's part is buf itself, in place; the others send nothing */
    c->allgatherv(c->user, buf, buf, cn, 1);
    if (cn != counts) free(cn);
}
