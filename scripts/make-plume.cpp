// make-plume.cpp: writes a sparse smoke plume as an OpenVDB float grid, for the scene library's
// out-of-core-sized volumes (scenes/plume-1024.json), built by scripts/make-volumes.sh.
//
//   make-plume OUT.vdb RES [SEED]
//
// The plume is a rising column in an RES^3 index box mapped to the world cube [-1, 1]^3: its
// radius grows linearly with height, its axis sways, and fractal value noise (a sum of octaves
// of smoothly interpolated lattice hashes, Perlin 1985 "An image synthesizer" §3 in its
// value-noise form) carves its edge and its inside. Only voxels of positive density are set,
// layer by layer, into the tree (OpenVDB allocates a leaf only where one is set), so the
// program's memory follows the active voxels, never RES^3. Prints the active voxel count.
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

// A lattice value in [-1, 1] from a 64-bit mix of the integer coordinates (SplitMix64 finaliser).
static double lattice(int64_t x, int64_t y, int64_t z, uint64_t seed)
{
    uint64_t h = seed ^ (uint64_t)x * 0x9E3779B97F4A7C15ull ^ (uint64_t)y * 0xC2B2AE3D27D4EB4Full ^
                 (uint64_t)z * 0x165667B19E3779F9ull;
    h = (h ^ (h >> 30)) * 0xBF58476D1CE4E5B9ull;
    h = (h ^ (h >> 27)) * 0x94D049BB133111EBull;
    h ^= h >> 31;
    return (double)(h >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

static double fade(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }

// Value noise: the lattice values interpolated with the quintic fade.
static double value_noise(double x, double y, double z, uint64_t seed)
{
    double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
    int64_t X = (int64_t)fx, Y = (int64_t)fy, Z = (int64_t)fz;
    double u = fade(x - fx), v = fade(y - fy), w = fade(z - fz), sum = 0.0;
    for (int c = 0; c < 8; c++) {
        int cx = c & 1, cy = (c >> 1) & 1, cz = (c >> 2) & 1;
        double wt = (cx ? u : 1 - u) * (cy ? v : 1 - v) * (cz ? w : 1 - w);
        sum += wt * lattice(X + cx, Y + cy, Z + cz, seed);
    }
    return sum;
}

// Fractal sum of 4 octaves (lacunarity 2, gain 0.5), in about [-1, 1].
static double fbm(double x, double y, double z, uint64_t seed)
{
    double s = 0.0, a = 0.5333, f = 1.0;
    for (int o = 0; o < 4; o++, a *= 0.5, f *= 2.0) s += a * value_noise(f * x, f * y, f * z, seed + o);
    return s;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        std::fprintf(stderr, "usage: make-plume OUT.vdb RES [SEED]\n");
        return 2;
    }
    const char *out = argv[1];
    int res = std::atoi(argv[2]);
    uint64_t seed = argc > 3 ? std::strtoull(argv[3], nullptr, 10) : 1;
    if (res < 16 || res > 4096) {
        std::fprintf(stderr, "make-plume: RES must be in [16, 4096]\n");
        return 2;
    }
    openvdb::initialize();
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(0.0f);
    grid->setName("density");
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    // Index (i, j, k) -> world: voxel centres spread over [-1, 1]^3.
    double h = 2.0 / res;
    openvdb::math::Transform::Ptr xf = openvdb::math::Transform::createLinearTransform(h);
    xf->postTranslate(openvdb::Vec3d(-1.0 + 0.5 * h, -1.0 + 0.5 * h, -1.0 + 0.5 * h));
    grid->setTransform(xf);
    auto acc = grid->getAccessor();
    size_t active = 0;
    for (int j = 0; j < res; j++) {
        double y = -1.0 + (j + 0.5) * h, t = (y + 1.0) / 2.0;   // height 0 (base) .. 1 (top)
        double r = 0.09 + 0.33 * t;                               // radius grows with height
        double cx = 0.18 * std::sin(5.0 * t + 0.3), cz = 0.12 * std::cos(4.0 * t);  // the sway
        if (t > 0.92) break;                                      // the top stays inside the box
        int i0 = std::max(0, (int)std::floor((cx - 1.3 * r + 1.0) / h)), i1 = std::min(res - 1, (int)std::ceil((cx + 1.3 * r + 1.0) / h));
        int k0 = std::max(0, (int)std::floor((cz - 1.3 * r + 1.0) / h)), k1 = std::min(res - 1, (int)std::ceil((cz + 1.3 * r + 1.0) / h));
        for (int k = k0; k <= k1; k++)
            for (int i = i0; i <= i1; i++) {
                double x = -1.0 + (i + 0.5) * h, z = -1.0 + (k + 0.5) * h;
                double d = std::hypot(x - cx, z - cz) / r;        // 1 at the nominal edge
                if (d > 1.3) continue;
                double n = fbm(6.0 * x, 6.0 * y - 3.0 * t, 6.0 * z, seed);
                double dens = (1.0 - t) * (1.0 - d + 0.5 * n) * 2.0; // thinner as it rises
                if (dens <= 0.0) continue;
                acc.setValue(openvdb::Coord(i, j, k), (float)std::min(dens, 2.0));
                active++;
            }
    }
    grid->pruneGrid(0.0f);
    openvdb::GridPtrVec grids{grid};
    try {
        openvdb::io::File file(out);
        file.setCompression(openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
        file.write(grids);
        file.close();
    } catch (const std::exception &e) {
        std::fprintf(stderr, "make-plume: %s: %s\n", out, e.what());
        return 1;
    }
    std::printf("%s: %d^3 box, %zu active voxels (%.2f%% of the box), %zu leaves\n", out, res, active,
                100.0 * active / ((double)res * res * res), (size_t)grid->tree().leafCount());
    return 0;
}
