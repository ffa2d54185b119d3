/* rd_vdb.h: OpenVDB writing beyond rd_internal.h's rd_vdb_save_dense, for tests and tools.
 * Internal to renderer/ (not part of the public API); implemented in vdb_io.cpp, which catches
 * every exception. */
#ifndef RD_VDB_H
#define RD_VDB_H

#include "renderer.h"

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Write a dense float grid (nx*ny*nz values, x fastest) as a .vdb whose index-to-world
 * transform is the affine map `index_to_world`, column-vector convention:
 *   world = M [i j k 1]^T,  M = index_to_world[row][col], last row (0 0 0 1).
 * The 3x3 part may hold any rotation, scale and shear (non-singular); voxel (i,j,k) is
 * centred at M (i,j,k,1). Zero voxels are left inactive (the background). Written to a
 * temporary name and renamed. Returns RD_ERR_ARG for a singular or non-affine matrix,
 * RD_ERR_IO when the file cannot be written; `err` names the file. */
rd_status rd_vdb_save_dense_affine(const char *path, const char *grid_name, const float *data,
                                   int nx, int ny, int nz, const double index_to_world[4][4],
                                   char *err, size_t errlen);

#ifdef __cplusplus
}
#endif
#endif /* RD_VDB_H */
