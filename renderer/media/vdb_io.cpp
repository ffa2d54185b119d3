// vdb_io.cpp: OpenVDB behind a plain C API (rd_medium.h, rd_vdb.h). Reads one float grid by
// name, sparsely into a brick map (or, for comparison, into a dense array) with its
// index-to-world transform; writes a dense array as a .vdb
// with a scale and translation or any affine index-to-world map (for tests and the
// scene-making scripts). Every exception is caught and turned into a one-line message.
#include "media/rd_medium.h"
#include "media/rd_vdb.h"
#include "core/rd_core.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <sys/stat.h>
#include <unistd.h>

/* The largest active bounding box addressed: grid indices are int and the brick table must
 * stay small (2^36 voxels: a 4096^3 box, a 1 GiB table). */
#define RD_VDB_MAX_VOXELS ((size_t)1 << 36)

static void vdb_init()
{
    // openvdb::initialize() is idempotent and internally synchronised.
    openvdb::initialize();
}

// Open `path` and read the float grid `grid_name` into *out with its active bounding box. On
// failure returns RD_ERR_IO (no such file) or RD_ERR_FORMAT with a one-line message naming the
// file (and the grid).
static rd_status read_float_grid(const char *path, const char *grid_name, openvdb::FloatGrid::Ptr *out,
                                 openvdb::CoordBBox *bb, char *err, size_t errlen)
{
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
    if (!grid->transform().isLinear()) {
        std::snprintf(err, errlen, "%s: grid \"%s\" has a non-linear (frustum) transform; only affine transforms are supported",
                      path, grid_name);
        return RD_ERR_FORMAT;
    }
    *bb = grid->evalActiveVoxelBoundingBox();
    if (bb->empty()) {
        std::snprintf(err, errlen, "%s: grid \"%s\" has no active voxels", path, grid_name);
        return RD_ERR_FORMAT;
    }
    openvdb::Coord dim = bb->dim();
    if ((size_t)dim.x() * dim.y() * dim.z() > RD_VDB_MAX_VOXELS) {
        std::snprintf(err, errlen, "%s: grid \"%s\" spans %dx%dx%d voxels, more than this renderer addresses",
                      path, grid_name, dim.x(), dim.y(), dim.z());
        return RD_ERR_FORMAT;
    }
    *out = grid;
    return RD_OK;
}

// A voxel value must be a density: finite and >= 0. Writes the message and returns 0 if not.
static int check_density(float v, const char *path, const char *grid_name, openvdb::Coord c, char *err,
                         size_t errlen)
{
    if (std::isfinite(v) && v >= 0.0f) return 1;
    std::snprintf(err, errlen, "%s: grid \"%s\" voxel (%d, %d, %d): %s density %g", path, grid_name, c.x(), c.y(),
                  c.z(), std::isfinite(v) ? "negative" : "non-finite", (double)v);
    return 0;
}

// The grid's transform and bounds: w2g maps world to our grid coordinate u = index - bb.min +
// 0.5 (voxel centres at integer + 0.5); the world bounds are the index box grown by one voxel
// (the trilinear support), transformed.
static void set_transform(const openvdb::FloatGrid &grid, const openvdb::CoordBBox &bb, rd_grid *g, vec3 *bmin,
                          vec3 *bmax)
{
    // OpenVDB maps row vectors: world = [i j k 1] * M; we need index = world * M^-1.
    openvdb::Mat4d M = grid.transform().baseMap()->getAffineMap()->getMat4();
    openvdb::Mat4d Minv = M.inverse();
    for (int a = 0; a < 3; a++) {
        for (int b = 0; b < 3; b++) g->w2g[a][b] = Minv(b, a);
        g->w2g[a][3] = Minv(3, a) - bb.min()[a] + 0.5;
    }
    openvdb::Vec3d lo(bb.min().x() - 1.0, bb.min().y() - 1.0, bb.min().z() - 1.0);
    openvdb::Vec3d hi(bb.max().x() + 1.0, bb.max().y() + 1.0, bb.max().z() + 1.0);
    openvdb::Vec3d wlo(INFINITY, INFINITY, INFINITY), whi(-INFINITY, -INFINITY, -INFINITY);
    for (int c = 0; c < 8; c++) {
        openvdb::Vec3d p((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
        openvdb::Vec3d w = grid.transform().indexToWorld(p);
        for (int a = 0; a < 3; a++) {
            wlo[a] = std::fmin(wlo[a], w[a]);
            whi[a] = std::fmax(whi[a], w[a]);
        }
    }
    *bmin = v3(wlo.x(), wlo.y(), wlo.z());
    *bmax = v3(whi.x(), whi.y(), whi.z());
    openvdb::Coord dim = bb.dim();
    g->nx = dim.x();
    g->ny = dim.y();
    g->nz = dim.z();
}

// The dense path: every voxel of the active bounding box read through an accessor.
static rd_status densify(const openvdb::FloatGrid &grid, const openvdb::CoordBBox &bb, const char *path,
                         const char *grid_name, rd_grid *g, char *err, size_t errlen)
{
    openvdb::Coord dim = bb.dim();
    size_t n = (size_t)dim.x() * dim.y() * dim.z();
    float *data = (float *)std::malloc(n * sizeof(float));
    if (!data) {
        std::snprintf(err, errlen, "%s: out of memory for %zu voxels", path, n);
        return RD_ERR_NOMEM;
    }
    g->data = data; /* owned by g from here: the callers free it on failure */
    auto acc = grid.getConstAccessor();
    double vmin = INFINITY, vmax = -INFINITY;
    size_t q = 0;
    for (int k = bb.min().z(); k <= bb.max().z(); k++)
        for (int j = bb.min().y(); j <= bb.max().y(); j++)
            for (int i = bb.min().x(); i <= bb.max().x(); i++, q++) {
                openvdb::Coord c(i, j, k);
                float v = acc.getValue(c);
                if (!check_density(v, path, grid_name, c, err, errlen)) return RD_ERR_FORMAT;
                data[q] = v;
                vmin = std::fmin(vmin, v);
                vmax = std::fmax(vmax, v);
            }
    g->vmin = vmin;
    g->vmax = vmax;
    return RD_OK;
}

// The sparse path (rd_medium.h rd_bricks): the brick table covers the active bounding box
// in 8^3 cells aligned with the tree's leaf nodes (OpenVDB leaves are 8^3 at multiples of 8).
// Every leaf inside the table becomes a brick; every other cell lies inside one tile or the
// background, so one accessor read gives its constant value. Memory: the table (a few bytes per
// 8^3 cell) plus 2 KiB per leaf, never the dense box.
static rd_status sparsify(const openvdb::FloatGrid &grid, const openvdb::CoordBBox &bb, const char *path,
                          const char *grid_name, rd_grid *g, char *err, size_t errlen)
{
    rd_bricks *b = (rd_bricks *)std::calloc(1, sizeof *b);
    if (!b) goto oom;
    g->bricks = b; /* owned by g from here: the callers free it on failure */
    {
        openvdb::Coord base; // index of table cell (0,0,0)'s first voxel
        for (int a = 0; a < 3; a++) {
            base[a] = bb.min()[a] & ~(RD_BRICK - 1); // floor to a multiple of 8 (also below 0)
            b->off[a] = bb.min()[a] - base[a];
            b->nb[a] = (bb.dim()[a] + b->off[a] + RD_BRICK - 1) / RD_BRICK;
        }
        size_t cells = (size_t)b->nb[0] * b->nb[1] * b->nb[2];
        b->brick = (int32_t *)std::malloc(cells * sizeof *b->brick);
        b->cmin = (float *)std::malloc(cells * sizeof *b->cmin);
        b->cmax = (float *)std::malloc(cells * sizeof *b->cmax);
        if (!b->brick || !b->cmin || !b->cmax) goto oom;
        for (size_t c = 0; c < cells; c++) b->brick[c] = -1;
        // The table cell of a leaf, or -1 when the leaf lies outside the table.
        auto cell_of = [&](const openvdb::Coord &o) -> long {
            long idx[3];
            for (int a = 0; a < 3; a++) {
                idx[a] = (o[a] - base[a]) / RD_BRICK;
                if (o[a] < base[a] || idx[a] >= b->nb[a]) return -1;
            }
            return (idx[2] * b->nb[1] + idx[1]) * b->nb[0] + idx[0];
        };
        for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf)
            if (cell_of(leaf->origin()) >= 0) b->n_bricks++;
        if (b->n_bricks > (size_t)INT32_MAX) goto oom;
        b->voxels = (float *)std::malloc(b->n_bricks * RD_BRICK * RD_BRICK * RD_BRICK * sizeof(float));
        if (b->n_bricks && !b->voxels) goto oom;
        // Bricks: copy the leaf's 512 values, x fastest (OpenVDB's leaf offset is z fastest:
        // (x << 6) | (y << 3) | z); min and max over the voxels inside the bounding box.
        int32_t next = 0;
        for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) {
            long cell = cell_of(leaf->origin());
            if (cell < 0) continue;
            b->brick[cell] = next;
            float *dst = b->voxels + (size_t)next * RD_BRICK * RD_BRICK * RD_BRICK;
            next++;
            float lo = INFINITY, hi = -INFINITY;
            for (int z = 0; z < RD_BRICK; z++)
                for (int y = 0; y < RD_BRICK; y++)
                    for (int x = 0; x < RD_BRICK; x++) {
                        openvdb::Coord c = leaf->origin() + openvdb::Coord(x, y, z);
                        float v = leaf->getValue((openvdb::Index)((x << 6) | (y << 3) | z));
                        int inside = bb.isInside(c);
                        *dst++ = inside ? v : 0.0f; /* outside the box the grid reads 0 anyway */
                        if (!inside) continue;
                        if (!check_density(v, path, grid_name, c, err, errlen)) return RD_ERR_FORMAT;
                        lo = std::fmin(lo, v);
                        hi = std::fmax(hi, v);
                    }
            b->cmin[cell] = lo;
            b->cmax[cell] = hi;
        }
        // Constant cells: a tile or the background; read at the cell's first voxel in the box.
        auto acc = grid.getConstAccessor();
        double vmin = INFINITY, vmax = -INFINITY;
        size_t cell = 0;
        for (int k = 0; k < b->nb[2]; k++)
            for (int j = 0; j < b->nb[1]; j++)
                for (int i = 0; i < b->nb[0]; i++, cell++) {
                    if (b->brick[cell] < 0) {
                        openvdb::Coord c(base.x() + RD_BRICK * i, base.y() + RD_BRICK * j, base.z() + RD_BRICK * k);
                        c.maxComponent(bb.min());
                        float v = acc.getValue(c);
                        if (!check_density(v, path, grid_name, c, err, errlen)) return RD_ERR_FORMAT;
                        b->cmin[cell] = b->cmax[cell] = v;
                    }
                    vmin = std::fmin(vmin, b->cmin[cell]);
                    vmax = std::fmax(vmax, b->cmax[cell]);
                }
        g->vmin = vmin;
        g->vmax = vmax;
        return RD_OK;
    }
oom:
    std::snprintf(err, errlen, "%s: out of memory for the bricks of grid \"%s\"", path, grid_name);
    return RD_ERR_NOMEM;
}

// Bytes of the brick form of the active box: the table (brick index, min, max per 8^3 cell)
// and 2 KiB per leaf inside it. Counts leaves only; reads no voxel.
static size_t brick_form_bytes(const openvdb::FloatGrid &grid, const openvdb::CoordBBox &bb)
{
    openvdb::CoordBBox table; // the box rounded out to whole leaves
    for (int a = 0; a < 3; a++) {
        table.min()[a] = bb.min()[a] & ~(RD_BRICK - 1);
        table.max()[a] = bb.max()[a] | (RD_BRICK - 1);
    }
    size_t leaves = 0;
    for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) leaves += table.isInside(leaf->origin());
    openvdb::Coord d = table.dim();
    size_t cells = (size_t)(d.x() / RD_BRICK) * (d.y() / RD_BRICK) * (d.z() / RD_BRICK);
    return cells * (sizeof(int32_t) + 2 * sizeof(float)) + leaves * RD_BRICK * RD_BRICK * RD_BRICK * sizeof(float);
}

// Shared by the three loaders: read, convert, set the transform; every exception becomes a
// one-line message and the grid is left empty on any failure.
enum { RD_VDB_DENSE = 0, RD_VDB_SPARSE = 1, RD_VDB_AUTO = 2 };
static rd_status load(const char *path, const char *grid_name, int sparse, rd_grid *g, vec3 *bmin, vec3 *bmax,
                      char *err, size_t errlen)
{
    g->data = nullptr;
    g->bricks = nullptr;
    rd_status st = RD_ERR_FORMAT;
    try {
        openvdb::CoordBBox bb;
        openvdb::FloatGrid::Ptr grid;
        st = read_float_grid(path, grid_name, &grid, &bb, err, errlen);
        if (st != RD_OK) return st;
        // Storage: the brick map, unless the dense box costs at most twice as much (a grid that
        // is active almost everywhere: dense lookups are cheaper and nothing is wasted).
        size_t dense_bytes = (size_t)bb.dim().x() * bb.dim().y() * bb.dim().z() * sizeof(float);
        if (sparse == RD_VDB_AUTO) sparse = dense_bytes > 2 * brick_form_bytes(*grid, bb);
        st = sparse ? sparsify(*grid, bb, path, grid_name, g, err, errlen)
                    : densify(*grid, bb, path, grid_name, g, err, errlen);
        if (st == RD_OK) {
            set_transform(*grid, bb, g, bmin, bmax);
            return RD_OK;
        }
    } catch (const std::exception &e) {
        std::snprintf(err, errlen, "%s: not a readable OpenVDB file (%s)", path, e.what());
        st = RD_ERR_FORMAT;
    } catch (...) {
        std::snprintf(err, errlen, "%s: not a readable OpenVDB file", path);
        st = RD_ERR_FORMAT;
    }
    rd_grid_free(g);
    return st;
}

extern "C" rd_status rd_vdb_load(const char *path, const char *grid_name, rd_grid *g, vec3 *bmin,
                                 vec3 *bmax, char *err, size_t errlen)
{
    return load(path, grid_name, RD_VDB_AUTO, g, bmin, bmax, err, errlen);
}

extern "C" rd_status rd_vdb_load_dense(const char *path, const char *grid_name, rd_grid *g, vec3 *bmin,
                                       vec3 *bmax, char *err, size_t errlen)
{
    return load(path, grid_name, RD_VDB_DENSE, g, bmin, bmax, err, errlen);
}

extern "C" rd_status rd_vdb_load_sparse(const char *path, const char *grid_name, rd_grid *g, vec3 *bmin,
                                        vec3 *bmax, char *err, size_t errlen)
{
    return load(path, grid_name, RD_VDB_SPARSE, g, bmin, bmax, err, errlen);
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
    char tmp[2200]; // core/files.c's scheme
    if (rd_temp_name(path, tmp, sizeof tmp) < 0) {
        std::snprintf(err, errlen, "%.200s...: path too long", path);
        return RD_ERR_IO;
    }
    openvdb::GridPtrVec grids{grid};
    try {
        openvdb::io::File file(tmp);
        file.setCompression(openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
        file.write(grids);
        file.close();
    } catch (...) {
        std::remove(tmp); /* never leave a half-written temporary behind */
        throw;
    }
    return rd_commit_temp(tmp, path, err, errlen) == RD_OK ? RD_OK : RD_ERR_IO;
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

// A copy of `src` (a float grid) in another value type, for the type-check tests.
template <typename GridT>
static openvdb::GridBase::Ptr retyped(const openvdb::FloatGrid &src)
{
    using V = typename GridT::ValueType;
    typename GridT::Ptr out = GridT::create(V(src.background()));
    auto acc = out->getAccessor();
    for (auto it = src.cbeginValueOn(); it; ++it) acc.setValue(it.getCoord(), V(*it));
    out->setName(src.getName());
    return out;
}

extern "C" rd_status rd_vdb_save_test(const char *path, const char *grid_name, const char *type, float background,
                                      const float *data, int nx, int ny, int nz, const int origin[3],
                                      const int (*boxes)[6], const float *values, int n_boxes, char *err,
                                      size_t errlen)
{
    try {
        vdb_init();
        openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(background);
        grid->setName(grid_name);
        auto acc = grid->getAccessor();
        size_t q = 0;
        for (int k = 0; k < nz; k++)
            for (int j = 0; j < ny; j++)
                for (int i = 0; i < nx; i++, q++)
                    if (data[q] != 0.0f) acc.setValue(openvdb::Coord(origin[0] + i, origin[1] + j, origin[2] + k), data[q]);
        for (int b = 0; b < n_boxes; b++) {
            const int *x = boxes[b];
            grid->tree().fill(openvdb::CoordBBox(x[0], x[1], x[2], x[3], x[4], x[5]), values[b], true);
        }
        openvdb::GridPtrVec grids;
        if (std::strcmp(type, "double") == 0) grids.push_back(retyped<openvdb::DoubleGrid>(*grid));
        else if (std::strcmp(type, "vec3s") == 0) grids.push_back(retyped<openvdb::Vec3SGrid>(*grid));
        else grids.push_back(grid);
        openvdb::io::File file(path);
        file.write(grids);
        file.close();
        return RD_OK;
    } catch (const std::exception &e) {
        std::snprintf(err, errlen, "%s: %s", path, e.what());
    } catch (...) {
        std::snprintf(err, errlen, "%s: unknown error writing OpenVDB file", path);
    }
    return RD_ERR_IO;
}
