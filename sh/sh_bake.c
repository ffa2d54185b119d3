/* sh_bake.c: filling a guide's cells from a photon map (THEORY.md §3-5; seed 001 §3.1-3.2 and
 * appendix A; seed 004). sh_layout.c has already laid out the cells (sh_guide_bake); here every
 * cell gets its 3 L^2 coefficients and its mean extinction, by one of two estimators:
 *   k-NN   at each cell centre, the k nearest photons (shi_bake_knn);
 *   track  every photon path segment deposits into every cell it crosses, weighted by the
 *          exact overlap length (shi_bake_track).
 * Both are parallel with OpenMP and give bit-identical results for any thread count: every
 * cell is summed by exactly one thread, always in the same order. */
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "sh_internal.h"
#include "walk.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ---- Per-cell helpers shared by both bakes -------------------------------------------------- */

/* splitmix64: a fixed hash for the stratified sigma_t jitter (deterministic bake). */
static inline uint64_t mix64(uint64_t x)
{
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}
static inline double u01(uint64_t h) { return (double)(h >> 11) * 0x1.0p-53; }

/* Cell-mean extinction: mean of sigma_t at s^3 jittered strata of the cell (s = the
 * sigma_t_samples parameter). The jitter of stratum n is a fixed hash of (cell, n), so the
 * value does not depend on which thread computes it or when. */
static double cell_mean_sigma_t(const sh_bake_params *P, size_t cell, const double lo[3],
                                const double hi[3])
{
    if (!P->sigma_t)
        return 0.0;
    int s = P->sigma_t_samples;
    double sum = 0.0;
    int n = 0;
    for (int k = 0; k < s; k++)
        for (int j = 0; j < s; j++)
            for (int i = 0; i < s; i++, n++) {
                uint64_t h = mix64(((uint64_t)cell << 10) ^ (uint64_t)n);
                int ijk[3] = {i, j, k};
                double x[3];
                for (int a = 0; a < 3; a++) {
                    double u = (ijk[a] + u01(mix64(h + (uint64_t)a))) / s;
                    x[a] = lo[a] + u * (hi[a] - lo[a]);
                }
                sum += P->sigma_t(x, P->sigma_t_user);
            }
    return sum / n;
}

/* Phase Legendre coefficients b_0..b_{bands-1} for the cell centred at c: phase_at(c) when
 * the medium gives one, else the constant phase_b. */
static void cell_phase(const sh_bake_params *P, const double c[3], int bands, double *b)
{
    if (P->phase_at)
        P->phase_at(c, P->phase_user, b);
    else
        for (int l = 0; l < bands; l++)
            b[l] = P->phase_b[l];
}

/* The caller's cancel flag (params.cancel) has been raised: the loops skip their remaining work
 * units and the bake returns SH_ERR_CANCELLED. */
static int shi_cancelled(const sh_bake_params *P)
{
    return P->cancel && *P->cancel;
}

/* OpenMP threads for the bake: params.threads, or all (0). The result does not depend on it. */
static int nthreads(const sh_bake_params *P)
{
    return P->threads > 0 ? P->threads : omp_get_max_threads();
}

/* ---- k-NN bake (seed 001 §3.1-3.2, appendix A; THEORY.md §4-5) ----------------------------- *
 * One independent estimate per cell, at its centre: the k nearest photons, r = distance to the
 * farthest of them, c_lm = (1/|V|) sum_k dPhi_k b_l Y_lm(w'_k) with |V| = (4/3) pi r^3. Cells
 * are shared out dynamically; each thread has its own k-NN result buffers. */

sh_status shi_bake_knn(sh_guide *g, const pm_map *map, const sh_bake_params *P, char *err,
                       size_t errlen)
{
    const int L = g->bands, nc = L * L, k = P->k;
    const pm_photon *ph = pm_map_photons(map);
    int failed = 0, nomem = 0;
    long long ncell = (long long)g->ncells;
#pragma omp parallel num_threads(nthreads(P))
    {
        int *idx = malloc((size_t)k * sizeof *idx);
        float *d2 = malloc((size_t)k * sizeof *d2);
        if (!idx || !d2) {
#pragma omp atomic write
            nomem = 1;
        }
#pragma omp for schedule(dynamic, 16)
        for (long long ci = 0; ci < ncell; ci++) {
            if (!idx || !d2 || shi_cancelled(P))
                continue;
            size_t cell = (size_t)ci;
            double lo[3], hi[3], c[3];
            shi_cell_bounds(g, cell, lo, hi);
            for (int a = 0; a < 3; a++)
                c[a] = 0.5 * (lo[a] + hi[a]);
            g->sigma_t[cell] = (float)cell_mean_sigma_t(P, cell, lo, hi);
            float *out = g->coeffs + cell * (size_t)g->ncoef;
            int n = pm_map_knn(map, c, k, idx, d2); /* world coordinates, double */
            if (n < 0) {
#pragma omp atomic write
                failed = 1;
                continue;
            }
            double r2 = n > 0 ? (double)d2[n - 1] : 0.0;
            if (n == 0 || !(r2 > 0.0))
                continue; /* no photons (or all at the centre, r = 0): c = 0 */
            /* c_lm = (1/|V|) sum_k dPhi_k b_l Y_lm(w'_k), |V| = (4/3) pi r^3 (THEORY.md §4). */
            double acc[SH_CHANNELS * SH_MAX_COEFFS];
            memset(acc, 0, sizeof(double) * (size_t)(SH_CHANNELS * nc));
            double y[SH_MAX_COEFFS], b[SH_MAX_BANDS], one[SH_MAX_BANDS];
            for (int l = 0; l < L; l++)
                one[l] = 1.0; /* b_l is applied once per cell below */
            /* The k photons lie scattered over the photon array (the order they were stored
             * in): their loads issued together, not one a photon behind the SH evaluation of
             * the last (a profile of hard-dense-block's bake put 92% of this loop's own time on
             * the first use of a photon; the guide 0.44 -> 0.36 s, the same numbers). */
            for (int j = 0; j < n; j++)
                __builtin_prefetch(&ph[idx[j]]);
            for (int j = 0; j < n; j++) {
                const pm_photon *q = &ph[idx[j]];
                double w[3] = {q->dir[0], q->dir[1], q->dir[2]};
                double pw[3] = {q->power[0], q->power[1], q->power[2]};
                sh_basis_eval(&g->basis, w, y);
                sh_project_add(L, one, y, pw, 1.0, acc);
            }
            cell_phase(P, c, L, b);
            double invV = 1.0 / (4.0 / 3.0 * M_PI * r2 * sqrt(r2));
            for (int ch = 0; ch < SH_CHANNELS; ch++)
                for (int l = 0; l < L; l++)
                    for (int m = -l; m <= l; m++) {
                        int i = ch * nc + SH_INDEX(l, m);
                        out[i] = (float)(acc[i] * b[l] * invV);
                    }
        }
        free(idx);
        free(d2);
    }
    if (nomem) {
        shi_set_err(err, errlen, "sh_guide_bake: out of memory for k-NN buffers (k = %d)", k);
        return SH_ERR_NOMEM;
    }
    if (failed) {
        shi_set_err(err, errlen, "sh_guide_bake: pm_map_knn failed (is the photon map built?)");
        return SH_ERR_PHOTONMAP;
    }
    if (shi_cancelled(P)) {
        shi_set_err(err, errlen, "sh_guide_bake: cancelled");
        return SH_ERR_CANCELLED;
    }
    return SH_OK;
}

/* ---- Track-length bake (THEORY.md §3, seed 004 taken to volumes) ---------------------------- *
 * Every photon path segment deposits sigma_s(x_mid) dPhi l_cell b_l Y_lm(w') / |V_cell| into
 * every cell it crosses, l_cell being the exact overlap length found by the ray iterator
 * (sh_ray.c). To parallelise without atomics the cells are cut into a few fixed regions;
 * the segments are binned by region once, then each region is walked by one thread. */

/* A fixed spatial partition of the cells: the work unit of the parallel track bake. Every
 * region sums its own cells' deposits over all segments in segment order, so the result does
 * not depend on the thread count. */
typedef struct {
    double lo[3], hi[3];
    int i0[3], i1[3];     /* uniform: cell index ranges [i0, i1) */
    size_t c0, c1;        /* adaptive: leaf range [c0, c1) (a depth-first subtree) */
} region;

/* The regions of an octree: the subtrees rooted at depth 2 (and leaves shallower than that),
 * in depth-first order, so that each region's leaves are the contiguous ids [c0, c1). Called
 * twice: with r = NULL it only counts (returns the number of regions), then it fills r. */
static size_t collect_regions(const sh_guide *g, size_t node, const double lo[3],
                              const double hi[3], int depth, size_t *leaf_next, region *r,
                              size_t nr)
{
    /* Subtrees at depth 2 (or shallower leaves) are regions; count their leaves. */
    if (g->nodes[node].child < 0 || depth == 2) {
        size_t first = *leaf_next;
        /* count leaves of this subtree: walk it (depth-first; the stack holds at most 8
         * entries per level, well within its size) */
        size_t stack[64 * SH_MAX_DEPTH + 8], sp = 0, nleaves = 0;
        stack[sp++] = node;
        while (sp) {
            size_t n = stack[--sp];
            if (g->nodes[n].child < 0) {
                nleaves++;
                continue;
            }
            int nch = 1 << shi_popcount3(g->nodes[n].mask);
            for (int c = 0; c < nch; c++)
                stack[sp++] = (size_t)g->nodes[n].child + (size_t)c;
        }
        if (r) {
            for (int a = 0; a < 3; a++)
                r[nr].lo[a] = lo[a], r[nr].hi[a] = hi[a];
            r[nr].c0 = first;
            r[nr].c1 = first + nleaves;
        }
        *leaf_next += nleaves;
        return nr + 1;
    }
    uint32_t mask = g->nodes[node].mask;
    int nch = 1 << shi_popcount3(mask);
    for (int c = 0; c < nch; c++) {
        double cl[3], chh[3];
        shi_child_box(mask, c, lo, hi, cl, chh);
        nr = collect_regions(g, (size_t)g->nodes[node].child + (size_t)c, cl, chh, depth + 1,
                             leaf_next, r, nr);
    }
    return nr;
}

/* Conservative bounding box of a segment in world coordinates (the map origin plus the
 * stored float offsets), padded against rounding: the end point is org + length dir for a unit
 * dir, else it lies within the cube org +- length. */
static void segment_bbox(const pm_segment *S, const double origin[3], double lo[3], double hi[3])
{
    float dd = S->dir[0] * S->dir[0] + S->dir[1] * S->dir[1] + S->dir[2] * S->dir[2];
    int unit = fabsf(dd - 1.0f) < 1e-3f;
    for (int a = 0; a < 3; a++) {
        float e = S->org[a] + S->length * S->dir[a];
        float l = unit ? fminf(S->org[a], e) : S->org[a] - S->length;
        float h = unit ? fmaxf(S->org[a], e) : S->org[a] + S->length;
        double pad = 1e-3 * S->length + 1e-6 * (fabs(S->org[a]) + 1.0);
        lo[a] = origin[a] + (l - pad), hi[a] = origin[a] + (h + pad);
    }
}

/* Lists of the segments whose bounding box meets each region, in compressed-row form: region
 * r's segment ids are ids[off[r] .. off[r + 1]), ascending. Two passes: count, then fill.
 * When the regions form a regular block grid (always for uniform grids, and for octrees split
 * at least to depth 2) the blocks a box meets are found per axis; otherwise every region is
 * tested. Returns 0, or -1 when out of memory. */
static int bin_segments(const region *R, size_t nr, const pm_segment *seg, size_t ns,
                        const double origin[3], uint32_t **ids_out, size_t **off_out)
{
    /* Block boundaries per axis: the distinct region lo values, plus the largest hi. */
    double bnd[3][65];
    int nb[3] = {0, 0, 0}, regular = nr <= 64;
    for (int a = 0; a < 3 && regular; a++) {
        for (size_t r = 0; r < nr && regular; r++) {
            int found = 0;
            for (int j = 0; j < nb[a]; j++)
                found |= bnd[a][j] == R[r].lo[a];
            if (!found) {
                if (nb[a] >= 64)
                    regular = 0;
                else
                    bnd[a][nb[a]++] = R[r].lo[a];
            }
        }
        /* sort (tiny) */
        for (int i = 1; i < nb[a]; i++)
            for (int j = i; j > 0 && bnd[a][j - 1] > bnd[a][j]; j--) {
                double t = bnd[a][j];
                bnd[a][j] = bnd[a][j - 1], bnd[a][j - 1] = t;
            }
        double top = -INFINITY;
        for (size_t r = 0; r < nr; r++)
            top = fmax(top, R[r].hi[a]);
        bnd[a][nb[a]] = top;
    }
    int map[64];
    if (regular && (size_t)nb[0] * nb[1] * nb[2] == nr) {
        for (int i = 0; i < 64; i++)
            map[i] = -1;
        for (size_t r = 0; r < nr && regular; r++) {
            int jj[3];
            for (int a = 0; a < 3; a++) {
                jj[a] = -1;
                for (int j = 0; j < nb[a]; j++)
                    if (bnd[a][j] == R[r].lo[a] && bnd[a][j + 1] == R[r].hi[a])
                        jj[a] = j;
                if (jj[a] < 0)
                    regular = 0;
            }
            if (regular) {
                int q = jj[0] + nb[0] * (jj[1] + nb[1] * jj[2]);
                if (map[q] >= 0)
                    regular = 0;
                map[q] = (int)r;
            }
        }
    } else {
        regular = 0;
    }
    size_t *off = calloc(nr + 1, sizeof *off);
    if (!off)
        return -1;
    uint32_t *ids = NULL;
    for (int pass = 0; pass < 2; pass++) {
        size_t *fill = NULL;
        if (pass == 1) {
            for (size_t r = 0; r < nr; r++)
                off[r + 1] += off[r];
            ids = malloc((off[nr] ? off[nr] : 1) * sizeof *ids);
            fill = malloc((nr ? nr : 1) * sizeof *fill);
            if (!ids || !fill) {
                free(ids), free(fill), free(off);
                return -1;
            }
            memcpy(fill, off, nr * sizeof *fill);
        }
        for (size_t s = 0; s < ns; s++) {
            double lo[3], hi[3];
            segment_bbox(&seg[s], origin, lo, hi);
            if (regular) {
                int j0[3], j1[3], empty = 0;
                for (int a = 0; a < 3; a++) {
                    j0[a] = nb[a], j1[a] = -1;
                    for (int j = 0; j < nb[a]; j++)
                        if (hi[a] >= bnd[a][j] && lo[a] <= bnd[a][j + 1]) {
                            if (j < j0[a])
                                j0[a] = j;
                            j1[a] = j;
                        }
                    empty |= j1[a] < 0;
                }
                if (empty)
                    continue;
                for (int z = j0[2]; z <= j1[2]; z++)
                    for (int y = j0[1]; y <= j1[1]; y++)
                        for (int x = j0[0]; x <= j1[0]; x++) {
                            int r = map[x + nb[0] * (y + nb[1] * z)];
                            if (pass == 0)
                                off[r + 1]++;
                            else
                                ids[fill[r]++] = (uint32_t)s;
                        }
            } else {
                for (size_t r = 0; r < nr; r++) {
                    int meet = 1;
                    for (int a = 0; a < 3; a++)
                        meet &= hi[a] >= R[r].lo[a] && lo[a] <= R[r].hi[a];
                    if (!meet)
                        continue;
                    if (pass == 0)
                        off[r + 1]++;
                    else
                        ids[fill[r]++] = (uint32_t)s;
                }
            }
        }
        free(fill);
    }
    *ids_out = ids;
    *off_out = off;
    return 0;
}

sh_status shi_bake_track(sh_guide *g, const pm_map *map, const sh_bake_params *P, char *err,
                         size_t errlen)
{
    const int L = g->bands, nc = L * L;
    const size_t ns = pm_map_segment_count(map);
    const pm_segment *seg = pm_map_segments(map);
    double origin[3]; /* segment origins are stored relative to it */
    pm_map_origin(map, origin);
    /* Regions: up to 4 blocks per axis (uniform) or the depth-2 subtrees (adaptive). */
    region *R = NULL;
    size_t nr = 0;
    if (g->kind == SH_GRID_UNIFORM) {
        int nb[3];
        for (int a = 0; a < 3; a++)
            nb[a] = g->res[a] < 4 ? g->res[a] : 4;
        nr = (size_t)nb[0] * nb[1] * nb[2];
        R = calloc(nr, sizeof *R);
        if (!R)
            goto nomem;
        size_t q = 0;
        for (int bz = 0; bz < nb[2]; bz++)
            for (int by = 0; by < nb[1]; by++)
                for (int bx = 0; bx < nb[0]; bx++, q++) {
                    int bb[3] = {bx, by, bz};
                    for (int a = 0; a < 3; a++) {
                        R[q].i0[a] = (int)((long)g->res[a] * bb[a] / nb[a]);
                        R[q].i1[a] = (int)((long)g->res[a] * (bb[a] + 1) / nb[a]);
                        R[q].lo[a] = shi_uplane(g, a, R[q].i0[a]);
                        R[q].hi[a] = shi_uplane(g, a, R[q].i1[a]);
                    }
                }
    } else {
        size_t leaf = 0;
        nr = collect_regions(g, 0, g->lo, g->hi, 0, &leaf, NULL, 0);
        R = calloc(nr, sizeof *R);
        if (!R)
            goto nomem;
        leaf = 0;
        collect_regions(g, 0, g->lo, g->hi, 0, &leaf, R, 0);
    }

    /* Bin the segments by region (ascending segment order within each region, so the sums
     * below run in a fixed order). */
    uint32_t *bin_seg = NULL;
    size_t *bin_off = NULL;
    if (ns > UINT32_MAX || bin_segments(R, nr, seg, ns, origin, &bin_seg, &bin_off) != 0) {
        free(R);
        R = NULL; /* nomem: frees R too */
        goto nomem;
    }
    int nomem_flag = 0;
    long long nreg = (long long)nr;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads(P))
    for (long long ri = 0; ri < nreg; ri++) {
        if (shi_cancelled(P))
            continue;
        const region *r = &R[ri];
        size_t rc; /* cells in the region */
        int ni[3] = {0, 0, 0};
        if (g->kind == SH_GRID_UNIFORM) {
            for (int a = 0; a < 3; a++)
                ni[a] = r->i1[a] - r->i0[a];
            rc = (size_t)ni[0] * ni[1] * ni[2];
        } else {
            rc = r->c1 - r->c0;
        }
        double *acc = calloc(rc * (size_t)(SH_CHANNELS * nc) + 1, sizeof *acc);
        if (!acc) {
#pragma omp atomic write
            nomem_flag = 1;
            continue;
        }
        double y[SH_MAX_COEFFS];
        for (size_t q = bin_off[ri]; q < bin_off[ri + 1]; q++) {
            const pm_segment *S = &seg[bin_seg[q]];
            /* world start point: the map origin plus the stored offset, in double */
            double o[3] = {origin[0] + S->org[0], origin[1] + S->org[1], origin[2] + S->org[2]};
            double d[3] = {S->dir[0], S->dir[1], S->dir[2]};
            double dn = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            double len = S->length;
            if (!(dn > 0.0) || !(len > 0.0) || !isfinite(len) || !isfinite(dn))
                continue;
            for (int a = 0; a < 3; a++)
                d[a] /= dn;
            /* Clip [0, len] to the region's box (walk/'s slab clip). */
            double t0, t1;
            if (!wk_box_clip(r->lo, r->hi, o, d, 0.0, len, &t0, &t1, NULL))
                continue;
            int have_y = 0;
            sh_guide_ray it;
            sh_guide_seg gs;
            sh_guide_ray_begin(g, o, d, t0, t1, &it);
            while (sh_guide_ray_next(&it, &gs)) {
                size_t local;
                size_t cell = (size_t)gs.cell;
                if (g->kind == SH_GRID_UNIFORM) {
                    size_t nx = (size_t)g->res[0], ny = (size_t)g->res[1];
                    int ijk[3] = {(int)(cell % nx), (int)((cell / nx) % ny),
                                  (int)(cell / (nx * ny))};
                    int in = 1;
                    for (int a = 0; a < 3; a++)
                        in &= ijk[a] >= r->i0[a] && ijk[a] < r->i1[a];
                    if (!in)
                        continue; /* a rounding sliver of a neighbouring region */
                    local = (size_t)(ijk[0] - r->i0[0]) +
                            (size_t)ni[0] * ((size_t)(ijk[1] - r->i0[1]) +
                                             (size_t)ni[1] * (size_t)(ijk[2] - r->i0[2]));
                } else {
                    if (cell < r->c0 || cell >= r->c1)
                        continue;
                    local = cell - r->c0;
                }
                if (!have_y) {
                    sh_basis_eval(&g->basis, d, y);
                    have_y = 1;
                }
                /* deposit sigma_s(x_mid) dPhi l Y_lm(w') (b_l / |V_cell| applied below) */
                double l = gs.t1 - gs.t0;
                double ss[3] = {1.0, 1.0, 1.0};
                if (P->sigma_s) {
                    double tm = 0.5 * (gs.t0 + gs.t1);
                    double xm[3] = {o[0] + tm * d[0], o[1] + tm * d[1], o[2] + tm * d[2]};
                    P->sigma_s(xm, P->sigma_s_user, ss);
                }
                double pw[3] = {S->power[0] * ss[0], S->power[1] * ss[1], S->power[2] * ss[2]};
                double *A = acc + local * (size_t)(SH_CHANNELS * nc);
                for (int ch = 0; ch < SH_CHANNELS; ch++) {
                    double v = pw[ch] * l;
                    for (int i = 0; i < nc; i++)
                        A[ch * nc + i] += v * y[i];
                }
            }
        }
        /* c_lm = b_l acc / |V_cell| */
        for (size_t local = 0; local < rc; local++) {
            size_t cell;
            if (g->kind == SH_GRID_UNIFORM) {
                size_t li = local % (size_t)ni[0], lj = (local / (size_t)ni[0]) % (size_t)ni[1],
                       lk = local / ((size_t)ni[0] * (size_t)ni[1]);
                cell = (size_t)(r->i0[0] + (int)li) +
                       (size_t)g->res[0] * ((size_t)(r->i0[1] + (int)lj) +
                                            (size_t)g->res[1] * (size_t)(r->i0[2] + (int)lk));
            } else {
                cell = r->c0 + local;
            }
            double lo[3], hi[3], c[3], b[SH_MAX_BANDS];
            shi_cell_bounds(g, cell, lo, hi);
            double V = 1.0;
            for (int a = 0; a < 3; a++) {
                V *= hi[a] - lo[a];
                c[a] = 0.5 * (lo[a] + hi[a]);
            }
            cell_phase(P, c, L, b);
            g->sigma_t[cell] = (float)cell_mean_sigma_t(P, cell, lo, hi);
            const double *A = acc + local * (size_t)(SH_CHANNELS * nc);
            float *out = g->coeffs + cell * (size_t)g->ncoef;
            for (int ch = 0; ch < SH_CHANNELS; ch++)
                for (int l = 0; l < L; l++)
                    for (int m = -l; m <= l; m++) {
                        int i = ch * nc + SH_INDEX(l, m);
                        out[i] = (float)(A[i] * b[l] / V);
                    }
        }
        free(acc);
    }
    free(R);
    R = NULL;
    free(bin_seg);
    free(bin_off);
    if (nomem_flag)
        goto nomem;
    if (shi_cancelled(P)) {
        shi_set_err(err, errlen, "sh_guide_bake: cancelled");
        return SH_ERR_CANCELLED;
    }
    return SH_OK;
nomem:
    free(R);
    shi_set_err(err, errlen, "sh_guide_bake: out of memory for the track-length accumulators");
    return SH_ERR_NOMEM;
}
