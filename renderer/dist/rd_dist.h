/* rd_dist.h: photonmarch on several processes, one job under mpirun or srun (MPI ranks;
 * docs/cluster.md). The one module that calls MPI (OpenMPI): it starts and ends MPI and gives
 * the render library its hooks (rd_comm, renderer.h), whose collectives it implements with MPI.
 * The library itself knows no MPI; the command line (renderer/cli/) is this module's only user.
 *
 * A process not launched by an MPI launcher never touches MPI: rd_dist_start gives NULL, and
 * every function here takes NULL for "this process alone".
 * Errors: MPI's default handler (MPI_ERRORS_ARE_FATAL) ends the whole job on a failed call, so
 * the collectives below return nothing; rd_dist_start reports a failed start as a status. */
#ifndef RD_DIST_H
#define RD_DIST_H

#include "renderer.h"

#include <stddef.h>
#include <stdint.h>

typedef struct rd_dist rd_dist; /* opaque */

/* Start MPI (MPI_Init_thread, funneled: only the calling thread talks to MPI) when the
 * environment says an MPI launcher started this process (OMPI_COMM_WORLD_SIZE from OpenMPI's
 * mpirun, PMIX_RANK from a PMIx launcher such as srun --mpi=pmix); else *out = NULL and MPI is
 * not touched. *out is the caller's (rd_dist_finish). */
rd_status rd_dist_start(int *argc, char ***argv, rd_dist **out, char *err, size_t errlen);
/* End MPI (MPI_Finalize; every rank calls it) and free d. NULL is safe. */
void rd_dist_finish(rd_dist *d);
/* This process's rank (0 alone) and the number of ranks (1 alone). */
int rd_dist_rank(const rd_dist *d);
int rd_dist_size(const rd_dist *d);
/* The render's hooks (rd_render_opts.comm): NULL alone or on one rank. Lives as long as d. */
const rd_comm *rd_dist_comm(const rd_dist *d);
/* Element-wise allreduce of n ints with op, in place (alone: nothing to do). Collective. */
void rd_dist_allreduce_int(const rd_dist *d, int *v, int n, rd_comm_op op);
/* 1 when every rank passed the same value v (e.g. a hash of its scene file), else 0.
 * Collective. */
int rd_dist_same(const rd_dist *d, uint64_t v);
#endif /* RD_DIST_H */
