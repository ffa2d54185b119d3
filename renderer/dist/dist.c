/* dist.c: MPI for the command line (rd_dist.h; docs/cluster.md). Everything this program does
 * with MPI is here: start and end, and the collectives behind the render's hooks (rd_comm).
 *
 * Large arrays (a film of 3 doubles per pixel) can exceed an int's count: every collective is
 * split into calls of at most CHUNK elements, the same split on every rank (counts and types
 * are the same everywhere by the hooks' contract), so the calls match one to one. */
#include "dist/rd_dist.h"

#include <limits.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CHUNK ((size_t)1 << 26) /* elements per MPI call: 512 MB of doubles, within an int */

struct rd_dist {
    int rank, size;
    rd_comm comm; /* the render's hooks, user = this */
};

static MPI_Datatype mpi_type(rd_comm_type t)
{
    switch (t) {
    case RD_COMM_DOUBLE: return MPI_DOUBLE;
    case RD_COMM_UINT32: return MPI_UINT32_T;
    case RD_COMM_UINT64: return MPI_UINT64_T;
    default: return MPI_INT;
    }
}

static size_t type_size(rd_comm_type t)
{
    switch (t) {
    case RD_COMM_DOUBLE: return sizeof(double);
    case RD_COMM_UINT32: return sizeof(uint32_t);
    case RD_COMM_UINT64: return sizeof(uint64_t);
    default: return sizeof(int);
    }
}

static MPI_Op mpi_op(rd_comm_op op)
{
    return op == RD_COMM_MIN ? MPI_MIN : op == RD_COMM_MAX ? MPI_MAX : MPI_SUM;
}

/* rd_comm.reduce: in place, chunk by chunk (MPI_IN_PLACE at the receiving ranks; a non-root
 * rank of a rooted reduce sends its buffer, which MPI leaves as it was). */
static void comm_reduce(void *user, void *buf, size_t count, rd_comm_type type, rd_comm_op op, int root)
{
    const rd_dist *d = user;
    MPI_Datatype dt = mpi_type(type);
    MPI_Op mop = mpi_op(op);
    size_t es = type_size(type);
    for (size_t i = 0; i < count; i += CHUNK) {
        int n = (int)(count - i < CHUNK ? count - i : CHUNK);
        char *p = (char *)buf + i * es;
        if (root < 0) MPI_Allreduce(MPI_IN_PLACE, p, n, dt, mop, MPI_COMM_WORLD);
        else if (d->rank == root) MPI_Reduce(MPI_IN_PLACE, p, n, dt, mop, root, MPI_COMM_WORLD);
        else MPI_Reduce(p, NULL, n, dt, mop, root, MPI_COMM_WORLD);
    }
}

/* rd_comm.allgatherv: counts[r] elements of elem_bytes from every rank r, in rank order, into
 * recv on every rank. MPI counts and displacements are ints: in units of one element (a
 * contiguous type of elem_bytes) they fit one MPI_Allgatherv up to INT_MAX elements in all (2e9
 * photons); beyond that each rank's part is broadcast from it in pieces of at most CHUNK
 * elements (the same calls on every rank). */
static void comm_allgatherv(void *user, const void *send, void *recv, const size_t *counts, size_t elem_bytes)
{
    const rd_dist *d = user;
    int K = d->size;
    size_t total = 0;
    for (int k = 0; k < K; k++) total += counts[k];
    if (total == 0) return;
    MPI_Datatype et;
    MPI_Type_contiguous((int)elem_bytes, MPI_BYTE, &et);
    MPI_Type_commit(&et);
    if (total <= (size_t)INT_MAX) {
        int *cn = malloc(2 * (size_t)K * sizeof *cn);
        if (!cn) MPI_Abort(MPI_COMM_WORLD, 4); /* (as a failed collective: the job ends) */
        int *displ = cn + K;
        size_t at = 0;
        for (int k = 0; k < K; k++) {
            cn[k] = (int)counts[k];
            displ[k] = (int)at;
            at += counts[k];
        }
        /* in place when send is this rank's own place in recv (MPI forbids aliased buffers) */
        const void *sb = send == (const char *)recv + (size_t)displ[d->rank] * elem_bytes ? MPI_IN_PLACE : send;
        MPI_Allgatherv(sb, cn[d->rank], et, recv, cn, displ, et, MPI_COMM_WORLD);
        free(cn);
    } else {
        char *at = recv;
        for (int k = 0; k < K; k++) {
            if (k == d->rank && counts[k] && at != send) memcpy(at, send, counts[k] * elem_bytes);
            for (size_t i = 0; i < counts[k]; i += CHUNK) {
                int n = (int)(counts[k] - i < CHUNK ? counts[k] - i : CHUNK);
                MPI_Bcast(at + i * elem_bytes, n, et, k, MPI_COMM_WORLD);
            }
            at += counts[k] * elem_bytes;
        }
    }
    MPI_Type_free(&et);
}

/* Launched by an MPI launcher? OpenMPI's mpirun sets OMPI_COMM_WORLD_SIZE in every rank; a PMIx
 * launcher (srun --mpi=pmix, prterun) sets PMIX_RANK. A plain run has neither. */
static int launched_by_mpi(void)
{
    return getenv("OMPI_COMM_WORLD_SIZE") != NULL || getenv("PMIX_RANK") != NULL;
}

rd_status rd_dist_start(int *argc, char ***argv, rd_dist **out, char *err, size_t errlen)
{
    *out = NULL;
    if (!launched_by_mpi()) return RD_OK;
    rd_dist *d = calloc(1, sizeof *d);
    if (!d) {
        snprintf(err, errlen, "out of memory starting MPI");
        return RD_ERR_NOMEM;
    }
    int provided = 0;
    if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) {
        free(d);
        snprintf(err, errlen, "MPI_Init_thread failed (launched by mpirun: OMPI_COMM_WORLD_SIZE is set)");
        return RD_ERR_INTERNAL;
    }
    MPI_Comm_rank(MPI_COMM_WORLD, &d->rank);
    MPI_Comm_size(MPI_COMM_WORLD, &d->size);
    d->comm = (rd_comm){.rank = d->rank, .size = d->size, .user = d, .reduce = comm_reduce,
                       .allgatherv = comm_allgatherv};
    *out = d;
    return RD_OK;
}

void rd_dist_finish(rd_dist *d)
{
    if (!d) return;
    MPI_Finalize();
    free(d);
}

int rd_dist_rank(const rd_dist *d) { return d ? d->rank : 0; }
int rd_dist_size(const rd_dist *d) { return d ? d->size : 1; }
const rd_comm *rd_dist_comm(const rd_dist *d) { return d && d->size > 1 ? &d->comm : NULL; }

void rd_dist_allreduce_int(const rd_dist *d, int *v, int n, rd_comm_op op)
{
    if (!d || d->size <= 1) return;
    MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_INT, mpi_op(op), MPI_COMM_WORLD);
}

int rd_dist_same(const rd_dist *d, uint64_t v)
{
    if (!d || d->size <= 1) return 1;
    uint64_t mm[2] = {v, ~v}; /* the largest v and the largest ~v, whose complement is the least v */
    MPI_Allreduce(MPI_IN_PLACE, mm, 2, MPI_UINT64_T, MPI_MAX, MPI_COMM_WORLD);
    return mm[0] == ~mm[1];
}
