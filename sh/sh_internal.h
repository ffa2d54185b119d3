/* sh_internal.h: private to the sh/ module. The layout of the guide object (opaque in sh.h) and
 * the few helpers that more than one source file of the module needs. Only the .c files in sh/
 * include it; nothing outside sh/ may (sh.h stays the module's one public header).
 *
 * Where things live (THEORY.md §4-5; seed 001 §3.1, §3.2, §3.4; docs/guide-grid.md):
 *   sh_math.c   SH basis, Legendre polynomials, quadrature, phase coefficients, and the
 *               projection / evaluation of one cell's coefficients.
 *   sh_grid.c   the guide object: cell boxes, read access, point location and evaluation,
 *               statistics, free, truncated copies.
 *   sh_layout.c sh_guide_bake: parameter checks, the box, the cell layout by the uniform
 *               resolution rule or the adaptive octree build; then sh_bake.c fills the cells.
 *   sh_bake.c   filling the cells once the layout exists: the k-NN bake, the track-length
 *               bake, and the cell-mean extinction.
 *   sh_ray.c    the ray iterator over both grid kinds (the walks themselves are walk/'s).
 *   sh_io.c     slice images and the guide file (save / load).
 * No cycle among the files: in the order sh_layout.c, sh_bake.c, sh_io.c, sh_ray.c, sh_grid.c,
 * sh_math.c each file calls only files after it.
 *
 * Names: functions shared between these files start with shi_ (sh internal); everything else
 * in a .c file is static. The helpers below are static inline because the ray iterator and
 * the point lookup call them in their innermost loops. */
#ifndef SH_INTERNAL_H
#define SH_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "sh.h"
#include "walk.h"

#define SH_MAX_DEPTH 20        /* deepest octree level a bake or a file may have */
#define SH_MAX_RES (1 << 20)   /* most uniform cells per axis */

/* ---- The guide object ----------------------------------------------------------------------- */

/* Octree node, 8 bytes (also the on-disk record). child >= 0: the node is split and its
 * 2^popcount(mask) children are the contiguous nodes child, child + 1, ...; child < 0: the node
 * is a leaf with cell id -(child + 1). mask bit a set = axis a is halved at the node's midpoint.
 * Children are ordered by the bits of the split axes in axis order (lowest split axis = bit 0
 * of the child offset); shi_child_box below turns an offset into the child's box. */
typedef struct {
    int32_t child;
    uint32_t mask;
} sh_node;

/* A guide grid: a box [lo, hi] cut into cells, each with 3 L^2 SH coefficients (channel-major,
 * see sh.h) and a mean extinction. Two kinds share everything but the cell layout:
 *   uniform   res[0] x res[1] x res[2] equal cells of edge h; cell id i + nx (j + ny k).
 *   adaptive  an octree over the box; the leaves are the cells, numbered depth-first. The
 *             leaf boxes and depths are derivable from the nodes, but are stored once
 *             (by the build, or by the loader's validation) so that lookups by id are cheap. */
struct sh_guide {
    sh_grid_kind kind;
    sh_bake_method method;
    int bands, ncoef; /* L, and ncoef = 3 L^2 floats per cell */
    double lo[3], hi[3];
    /* uniform */
    int res[3];
    double h[3];      /* cell edge (hi - lo) / res per axis */
    /* adaptive */
    sh_node *nodes;   /* nnodes, root at 0 */
    size_t nnodes;
    double *leaf_lo, *leaf_hi; /* 3 per leaf */
    uint8_t *leaf_depth;
    int depth_max;
    /* cells */
    size_t ncells;
    float *coeffs;  /* ncells * ncoef */
    float *sigma_t; /* ncells */
    /* provenance */
    double bake_seconds;
    size_t photons;  /* photons (k-NN) or segments (track) the bake used */
    int k;
    double lambda;
    sh_basis basis;  /* SH table for bands (built by the bake and by the loader) */
};

/* ---- Shared functions (defined in the file named) ------------------------------------------- */

/* sh_grid.c: printf into err (at most errlen bytes, NUL-terminated); no-op for err = NULL. */
void shi_set_err(char *err, size_t errlen, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* sh_grid.c: the box of cell `cell` (< g->ncells) of either grid kind. */
void shi_cell_bounds(const sh_guide *g, size_t cell, double lo[3], double hi[3]);

/* sh_bake.c, called by sh_layout.c: fill g->coeffs and g->sigma_t of a guide whose cells are laid out (box, kind,
 * bands, basis and cells set; coeffs and sigma_t allocated and zeroed). params are checked. */
sh_status shi_bake_knn(sh_guide *g, const pm_map *map, const sh_bake_params *P, char *err,
                       size_t errlen);
sh_status shi_bake_track(sh_guide *g, const pm_map *map, const sh_bake_params *P, char *err,
                         size_t errlen);

/* ---- Uniform-grid geometry ------------------------------------------------------------------ */

/* Plane i of axis a of the uniform grid; planes 0 and n are the box faces exactly, so the DDA
 * and the box clip agree to the bit (walk/walk.h wk_plane: the one definition). */
static inline double shi_uplane(const sh_guide *g, int a, int i)
{
    return wk_plane(g->lo[a], g->hi[a], g->h[a], g->res[a], i);
}

/* Index of the uniform cell holding coordinate p on axis a: half-open [plane_i, plane_i+1),
 * clamped to the grid, decided by the planes themselves so that lookups and the DDA agree
 * (walk/walk.h wk_cell_of). */
static inline int shi_ucell(const sh_guide *g, int a, double p)
{
    return wk_cell_of(g->lo[a], g->hi[a], g->h[a], g->res[a], p);
}

/* ---- Octree geometry ------------------------------------------------------------------------ */

/* Number of axes a node splits (bits set in a 3-bit mask): it has 1 << shi_popcount3 children. */
static inline int shi_popcount3(uint32_t m)
{
    return (int)((m & 1u) + ((m >> 1) & 1u) + ((m >> 2) & 1u));
}

/* The box [clo, chi] of child c (offset 0 .. 2^popcount(mask) - 1) of the node [lo, hi], by the
 * child order of sh_node: bit b of c picks the lower (0) or upper (1) half of the b-th split
 * axis. The midpoint is 0.5 (lo + hi) everywhere, so build, walk and load agree to the bit. */
static inline void shi_child_box(uint32_t mask, int c, const double lo[3], const double hi[3],
                                 double clo[3], double chi[3])
{
    for (int ax = 0; ax < 3; ax++)
        clo[ax] = lo[ax], chi[ax] = hi[ax];
    int bit = 0;
    for (int ax = 0; ax < 3; ax++) {
        if (!(mask & (1u << ax)))
            continue;
        double mid = 0.5 * (lo[ax] + hi[ax]);
        if (c & (1 << bit))
            clo[ax] = mid;
        else
            chi[ax] = mid;
        bit++;
    }
}

/* The inverse of shi_child_box for a point: child offset for point p moving along d. The upper
 * half if p > mid, or p == mid and d >= 0 (so a point on a plane belongs to the cell the ray is
 * about to enter; d = 0 gives half-open cells [lo, hi)). Updates blo/bhi to the child's box. */
static inline int shi_child_of(uint32_t mask, const double p[3], const double d[3],
                               double blo[3], double bhi[3])
{
    int off = 0, bit = 0;
    for (int a = 0; a < 3; a++) {
        if (!(mask & (1u << a)))
            continue;
        double mid = 0.5 * (blo[a] + bhi[a]);
        int up = p[a] > mid || (p[a] == mid && d[a] >= 0.0);
        if (up) {
            off |= 1 << bit;
            blo[a] = mid;
        } else {
            bhi[a] = mid;
        }
        bit++;
    }
    return off;
}

/* Descend from the root to the leaf holding p (direction-aware ties as in shi_child_of; pass
 * d = 0 for a plain point lookup). Returns the leaf's cell id; blo/bhi receive its box. */
static inline long shi_descend(const sh_guide *g, const double p[3], const double d[3],
                               double blo[3], double bhi[3])
{
    for (int a = 0; a < 3; a++)
        blo[a] = g->lo[a], bhi[a] = g->hi[a];
    size_t n = 0;
    while (g->nodes[n].child >= 0) {
        int off = shi_child_of(g->nodes[n].mask, p, d, blo, bhi);
        n = (size_t)g->nodes[n].child + (size_t)off;
    }
    return -(long)g->nodes[n].child - 1;
}

#endif /* SH_INTERNAL_H */
