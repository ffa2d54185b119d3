// vdb_io.cpp: OpenVDB behind a plain C API (rd_internal.h, rd_vdb.h). Reads one float grid by
// name into a dense array with its index-to-world transform; writes a dense array as a .vdb
// with a scale and translation or any affine index-to-world map (for tests and the
// scene-making scripts). Every exception is caught and turned into a one-line message.
#include "rd_internal.h"
#include "rd_vdb.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <sys/stat.h>
#include <unistd.h>

#define RD_VDB_MAX_VOXELS ((size_t)1 << 31) /* 8 GiB of floats: beyond that, refuse */

static void vdb_init()
{
    // openvdb::initialize() is idempotent and internally synchronised.
    openvdb::initialize();
}

extern "C" rd_status rd_vdb_load(const char *path, const char *grid_name, rd_grid *g, vec3 *bmin,
                                 vec3 *bmax, char *err, size_t errlen)
{
    g->data = nullptr;
    try {
        struct stat sb;
        if (stat(path, &sb) != 0) {
            std::snprintf(err, errlen, "%s: %s", path, std::strerror(errno));
            return RD_ERR_IO;
        }
        vdb_init();
        openvdb::io::File file(path);
        file.open(false); // no delayed loading: read everything now, errors surface here
        if (!file.hasGrid(grid_name)) {
            std::string names;
            for (auto it = file.beginName(); it != file.endName(); ++it) names += (names.empty() ? "" : ", ") + *it;
            file.close();
            if (names.empty())
                std::snprintf(err, errlen, "%s: holds no grids (empty or not a valid OpenVDB file)", path);
            else
                std::snprintf(err, errlen, "%s: no grid named \"%s\" (grids: %s)", path, grid_name, names.c_str());
            return RD_ERR_FORMAT;
        }
        openvdb::GridBase::Ptr base = file.readGrid(grid_name);
        file.close();
        openvdb::FloatGrid::Ptr grid = openvdb::gridPtrCast<openvdb::FloatGrid>(base);
        if (!grid) {
            std::snprintf(err, errlen, "%s: grid \"%s\" is of type %s, expected float", path, grid_name,
                          base->valueType().c_str());
            return RD_ERR_FORMAT;
        }
        openvdb::CoordBBox bb = grid->evalActiveVoxelBoundingBox();
        if (bb.empty()) {
            std::snprintf(err, errlen, "%s: grid \"%s\" has no active voxels", path, grid_name);
            return RD_ERR_FORMAT;
        }
        openvdb::Coord dim = bb.dim();
        size_t n = (size_t)dim.x() * dim.y() * dim.z();
        if (n > RD_VDB_MAX_VOXELS) {
            std::snprintf(err, errlen, "%s: grid \"%s\" is %dx%dx%d voxels, more than this renderer loads",
                          path, grid_name, dim.x(), dim.y(), dim.z());
            return RD_ERR_FORMAT;
        }
        float *data = (float *)std::malloc(n * sizeof(float));
        if (!data) {
            std::snprintf(err, errlen, "%s: out of memory for %zu voxels", path, n);
            return RD_ERR_NOMEM;
        }
        g->data = data; /* owned by g from here: the catch blocks below free it */
        auto acc = grid->getConstAccessor();
        double vmin = INFINITY, vmax = -INFINITY;
        size_t q = 0;
        for (int k = bb.min().z(); k <= bb.max().z(); k++)
            for (int j = bb.min().y(); j <= bb.max().y(); j++)
                for (int i = bb.min().x(); i <= bb.max().x(); i++, q++) {
                    float v = acc.getValue(openvdb::Coord(i, j, k));
                    if (!std::isfinite(v) || v < 0.0f) {
                        std::free(data);
                        g->data = nullptr;
                        std::snprintf(err, errlen, "%s: grid \"%s\" voxel (%d, %d, %d): %s density %g", path,
                                      grid_name, i, j, k, std::isfinite(v) ? "negative" : "non-finite", (double)v);
                        return RD_ERR_FORMAT;
                    }
                    data[q] = v;
                    vmin = std::fmin(vmin, v);
                    vmax = std::fmax(vmax, v);
                }
        // OpenVDB maps row vectors: world = [i j k 1] * M. We need index = world * M^-1, then
        // our grid coordinate u = index - bb.min + 0.5 (voxel centres at integer + 0.5).
        if (!grid->transform().isLinear()) {
            std::free(data);
            g->data = nullptr;
            std::snprintf(err, errlen, "%s: grid \"%s\" has a non-linear (frustum) transform; only affine transforms are supported",
                          path, grid_name);
            return RD_ERR_FORMAT;
        }
        openvdb::Mat4d M = grid->transform().baseMap()->getAffineMap()->getMat4();
        openvdb::Mat4d Minv = M.inverse();
        for (int a = 0; a < 3; a++) {
            for (int b = 0; b < 3; b++) g->w2g[a][b] = Minv(b, a);
            g->w2g[a][3] = Minv(3, a) - bb.min()[a] + 0.5;
        }
        // World bounds: the index box grown by one voxel (the trilinear support), transformed.
        openvdb::Vec3d lo(bb.min().x() - 1.0, bb.min().y() - 1.0, bb.min().z() - 1.0);
        openvdb::Vec3d hi(bb.max().x() + 1.0, bb.max().y() + 1.0, bb.max().z() + 1.0);
        openvdb::Vec3d wlo(INFINITY, INFINITY, INFINITY), whi(-INFINITY, -INFINITY, -INFINITY);
        for (int c = 0; c < 8; c++) {
            openvdb::Vec3d p((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
            openvdb::Vec3d w = grid->transform().indexToWorld(p);
            for (int a = 0; a < 3; a++) {
                wlo[a] = std::fmin(wlo[a], w[a]);
                whi[a] = std::fmax(whi[a], w[a]);
            }
        }
        *bmin = v3(wlo.x(), wlo.y(), wlo.z());
        *bmax = v3(whi.x(), whi.y(), whi.z());
        g->nx = dim.x();
        g->ny = dim.y();
        g->nz = dim.z();
        g->data = data;
        g->vmin = vmin;
        g->vmax = vmax;
        return RD_OK;
    } catch (const std::exception &e) {
        std::snprintf(err, errlen, "%s: not a readable OpenVDB file (%s)", path, e.what());
    } catch (...) {
        std::snprintf(err, errlen, "%s: not a readable OpenVDB file", path);
    }
    std::free(g->data);
    g->data = nullptr;
    return RD_ERR_FORMAT;
}

// Fill a float grid from a dense array (x fastest); zeros stay inactive (the background).
static void fill_dense(openvdb::FloatGrid &grid, const float *data, int nx, int ny, int nz)
{
    auto acc = grid.getAccessor();
    size_t q = 0;
    for (int k = 0; k < nz; k++)
        for (int j = 0; j < ny; j++)
            for (int i = 0; i < nx; i++, q++)
                if (data[q] != 0.0f) acc.setValue(openvdb::Coord(i, j, k), data[q]);
}

// Write one grid to a temporary name beside `path`, then rename it into place. Throws on an
// OpenVDB error (the callers catch); returns RD_ERR_IO with a message when the rename fails.
static rd_status write_grid(const char *path, openvdb::FloatGrid::Ptr grid, char *err, size_t errlen)
{
    std::string tmp = std::string(path) + ".tmp" + std::to_string((long)getpid());
    openvdb::GridPtrVec grids{grid};
    try {
        openvdb::io::File file(tmp);
        file.setCompression(openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
        file.write(grids);
        file.close();
    } catch (...) {
        std::remove(tmp.c_str()); /* never leave a half-written temporary behind */
        throw;
    }
    if (std::rename(tmp.c_str(), path) != 0) {
        std::snprintf(err, errlen, "%s: cannot rename into place: %s", path, std::strerror(errno));
        std::remove(tmp.c_str());
        return RD_ERR_IO;
    }
    return RD_OK;
}

static openvdb::FloatGrid::Ptr new_fog_grid(const char *grid_name)
{
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(0.0f);
    grid->setName(grid_name);
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    return grid;
}

extern "C" rd_status rd_vdb_save_dense(const char *path, const char *grid_name, const float *data,
                                       int nx, int ny, int nz, double voxel_size, const double origin[3],
                                       char *err, size_t errlen)
{
    try {
        vdb_init();
        openvdb::FloatGrid::Ptr grid = new_fog_grid(grid_name);
        openvdb::math::Transform::Ptr xf = openvdb::math::Transform::createLinearTransform(voxel_size);
        xf->postTranslate(openvdb::Vec3d(origin[0], origin[1], origin[2]));
        grid->setTransform(xf);
        fill_dense(*grid, data, nx, ny, nz);
        return write_grid(path, grid, err, errlen);
    } catch (const std::exception &e) {
        std::snprintf(err, errlen, "%s: %s", path, e.what());
    } catch (...) {
        std::snprintf(err, errlen, "%s: unknown error writing OpenVDB file", path);
    }
    return RD_ERR_IO;
}

extern "C" rd_status rd_vdb_save_dense_affine(const char *path, const char *grid_name, const float *data,
                                              int nx, int ny, int nz, const double index_to_world[4][4],
                                              char *err, size_t errlen)
{
    try {
        vdb_init();
        // OpenVDB maps row vectors (world = [i j k 1] * M): its matrix is the transpose of ours.
        openvdb::Mat4d M;
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++) M(c, r) = index_to_world[r][c];
        const double *last = index_to_world[3];
        if (last[0] != 0.0 || last[1] != 0.0 || last[2] != 0.0 || last[3] != 1.0) {
            std::snprintf(err, errlen, "%s: the index-to-world matrix is not affine (last row must be 0 0 0 1)", path);
            return RD_ERR_ARG;
        }
        if (!(std::fabs(M.getMat3().det()) > 1e-300)) {
            std::snprintf(err, errlen, "%s: the index-to-world matrix is singular", path);
            return RD_ERR_ARG;
        }
        openvdb::FloatGrid::Ptr grid = new_fog_grid(grid_name);
        grid->setTransform(openvdb::math::Transform::createLinearTransform(M));
        fill_dense(*grid, data, nx, ny, nz);
        return write_grid(path, grid, err, errlen);
    } catch (const std::exception &e) {
        std::snprintf(err, errlen, "%s: %s", path, e.what());
    } catch (...) {
        std::snprintf(err, errlen, "%s: unknown error writing OpenVDB file", path);
    }
    return RD_ERR_IO;
}
