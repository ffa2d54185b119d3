/* rd_vdb.h: OpenVDB reading and writing beyond rd_medium.h's rd_vdb_load / rd_vdb_save_dense,
 * for tests and tools.
 * Internal to renderer/ (not part of the public API); implemented in vdb_io.cpp, which catches
 * every exception. */
#ifndef RD_VDB_H
#define RD_VDB_H

#include "renderer.h"

#include <stddef.h>
#include <stdint.h>

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

/* Read the float grid `grid_name` with one storage forced: dense (every voxel of its active
 * bounding box into g->data) or sparse (the brick map), with the same transform, bounds and
 * checks as rd_vdb_load, which chooses (rd_medium.h). For the tests that compare the two. */
rd_status rd_vdb_load_dense(const char *path, const char *grid_name, rd_grid *g, vec3 *bmin,
                            vec3 *bmax, char *err, size_t errlen);
rd_status rd_vdb_load_sparse(const char *path, const char *grid_name, rd_grid *g, vec3 *bmin,
                             vec3 *bmax, char *err, size_t errlen);

/* Write a test grid: a float grid whose background is `background`, with voxel size 1 and the
 * identity placement, holding (1) the non-zero values of the dense block `data` (nx*ny*nz, x
 * fastest) at index (ox + i, oy + j, oz + k) and (2) the boxes `boxes[b]` = {x0, y0, z0, x1,
 * y1, z1} (inclusive) filled with `values[b]` by the tree's fill, which makes active tiles of
 * every whole aligned block. `type` "float" writes that grid; "double" or "vec3s" writes the
 * same shape in that value type (for the loader's type check). */
rd_status rd_vdb_save_test(const char *path, const char *grid_name, const char *type, float background,
                           const float *data, int nx, int ny, int nz, const int origin[3],
                           const int (*boxes)[6], const float *values, int n_boxes, char *err,
                           size_t errlen);

#ifdef __cplusplus
}
#endif
#endif /* RD_VDB_H */
