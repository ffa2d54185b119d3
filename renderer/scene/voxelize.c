/* voxelize.c: a medium's density sampled at voxel centres, written as OpenVDB or raw float32
 * (docs/cli.md, voxelize; the format of raw grids in docs/scene-format.md). */
#include "core/rd_core.h"
#include "scene/rd_scene.h"

#include <stdlib.h>
#include <string.h>

rd_status rd_voxelize(const rd_scene *s, int medium, int res, const char *out_path, int dims[3],
                      char *err, size_t errlen)
{
    size_t olen = strlen(out_path);
    int vdb = olen > 4 && !strcmp(out_path + olen - 4, ".vdb");
    int raw = olen > 4 && !strcmp(out_path + olen - 4, ".raw");
    if (!vdb && !raw) {
        snprintf(err, errlen, "-o %s: expected a path ending in .vdb or .raw", out_path);
        return RD_ERR_ARG;
    }
    if (medium < 0 || medium >= s->n_media) {
        snprintf(err, errlen, "--medium %d: the scene has %d media", medium, s->n_media);
        return RD_ERR_ARG;
    }
    if (res < 1 || res > 1024) {
        snprintf(err, errlen, "--res %d: expected 1 to 1024", res);
        return RD_ERR_ARG;
    }
    const rd_medium *m = &s->media[medium];
    vec3 ext = v3_sub(m->bmax, m->bmin);
    double longest = fmax(ext.x, fmax(ext.y, ext.z)), vs = longest / res;
    for (int k = 0; k < 3; k++) dims[k] = (int)fmax(1.0, ceil(v3_get(ext, k) / vs - 1e-9));
    size_t n = (size_t)dims[0] * dims[1] * dims[2];
    float *data = malloc(n * sizeof *data);
    if (!data) {
        snprintf(err, errlen, "out of memory for %zu voxels", n);
        return RD_ERR_NOMEM;
    }
    /* Voxel centres: raw grids fill the bounds exactly (cell size ext/dims per axis), vdb
     * grids use cubic voxels of size vs starting at bmin. */
    double cell[3];
    for (int k = 0; k < 3; k++) cell[k] = raw ? v3_get(ext, k) / dims[k] : vs;
#pragma omp parallel for schedule(dynamic, 1)
    for (int z = 0; z < dims[2]; z++)
        for (int y = 0; y < dims[1]; y++)
            for (int x = 0; x < dims[0]; x++)
                data[((size_t)z * dims[1] + y) * dims[0] + x] = (float)rd_medium_density(
                    m, v3(m->bmin.x + (x + 0.5) * cell[0], m->bmin.y + (y + 0.5) * cell[1], m->bmin.z + (z + 0.5) * cell[2]));
    rd_status st = rd_make_parent_dirs(out_path, err, errlen);
    if (st == RD_OK && vdb) {
        double origin[3] = {m->bmin.x + 0.5 * vs, m->bmin.y + 0.5 * vs, m->bmin.z + 0.5 * vs};
        if (rd_vdb_save_dense(out_path, "density", data, dims[0], dims[1], dims[2], vs, origin, err, errlen))
            st = RD_ERR_OUTPUT;
    } else if (st == RD_OK) {
        st = rd_write_atomic(out_path, data, n * sizeof *data, err, errlen);
    }
    free(data);
    return st;
}
