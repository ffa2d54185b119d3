/* sh_layout.c: a guide's cell layout, the first half of sh_guide_bake (THEORY.md §5; seed 001
 * §3.1, §3.4; docs/guide-grid.md). sh_guide_bake checks the parameters, fixes the box, lays out
 * the cells (uniform grid by the resolution rule, or the adaptive octree by the split rule) and
 * then hands the guide to sh_bake.c to fill the cells. The guide object itself (read access,
 * point location, evaluation, free) is sh_grid.c; its layout is in sh_internal.h. */
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "sh_internal.h"

/* ---- Bake parameters and the box ------------------------------------------------------------ */

void sh_bake_params_default(sh_bake_params *p)
{
    memset(p, 0, sizeof *p);
    p->kind = SH_GRID_UNIFORM;
    p->method = SH_BAKE_KNN;
    p->bands = 4;
    p->k = 50;
    p->lambda = 1.0;
    p->max_cells = (size_t)1 << 24;
    p->max_depth = 12;
    p->phase_b[0] = 1.0;
    p->sigma_t_samples = 2;
}

/* Validate params and fill the guide's box: params.lo/hi when given, else the bounds of the
 * photons (of the segment end points without photons) padded by 1e-4 of the largest extent. */
static sh_status check_params(const pm_map *map, const sh_bake_params *P, double lo[3],
                              double hi[3], char *err, size_t errlen)
{
    if (!map || !P) {
        shi_set_err(err, errlen, "sh_guide_bake: map and params must be non-NULL");
        return SH_ERR_ARG;
    }
    if (P->kind != SH_GRID_UNIFORM && P->kind != SH_GRID_ADAPTIVE) {
        shi_set_err(err, errlen, "sh_guide_bake: params.kind = %d: unknown grid kind",
                    (int)P->kind);
        return SH_ERR_ARG;
    }
    if (P->method != SH_BAKE_KNN && P->method != SH_BAKE_TRACK) {
        shi_set_err(err, errlen, "sh_guide_bake: params.method = %d: unknown bake method",
                    (int)P->method);
        return SH_ERR_ARG;
    }
    if (P->bands < 1 || P->bands > SH_MAX_BANDS) {
        shi_set_err(err, errlen, "sh_guide_bake: params.bands = %d: must be 1..%d", P->bands,
                    SH_MAX_BANDS);
        return SH_ERR_ARG;
    }
    if (P->k < 1) {
        shi_set_err(err, errlen, "sh_guide_bake: params.k = %d: must be >= 1", P->k);
        return SH_ERR_ARG;
    }
    if (!(P->lambda > 0.0) || !isfinite(P->lambda)) {
        shi_set_err(err, errlen, "sh_guide_bake: params.lambda = %g: must be finite and > 0",
                    P->lambda);
        return SH_ERR_ARG;
    }
    int nres = 0;
    for (int a = 0; a < 3; a++) {
        if (P->res[a] < 0 || P->res[a] > SH_MAX_RES) {
            shi_set_err(err, errlen, "sh_guide_bake: params.res[%d] = %d: must be 0..%d", a,
                        P->res[a], SH_MAX_RES);
            return SH_ERR_ARG;
        }
        nres += P->res[a] > 0;
    }
    if (nres != 0 && nres != 3) {
        shi_set_err(err, errlen, "sh_guide_bake: params.res: give all three or none");
        return SH_ERR_ARG;
    }
    if (P->max_cells < 1) {
        shi_set_err(err, errlen, "sh_guide_bake: params.max_cells = 0: must be >= 1");
        return SH_ERR_ARG;
    }
    if (P->max_depth < 0 || P->max_depth > SH_MAX_DEPTH) {
        shi_set_err(err, errlen, "sh_guide_bake: params.max_depth = %d: must be 0..%d",
                    P->max_depth, SH_MAX_DEPTH);
        return SH_ERR_ARG;
    }
    if (P->split_photons < 0) {
        shi_set_err(err, errlen, "sh_guide_bake: params.split_photons = %d: must be >= 0",
                    P->split_photons);
        return SH_ERR_ARG;
    }
    if (!(P->min_cell >= 0.0) || !isfinite(P->min_cell) || !(P->max_cell >= 0.0) ||
        !isfinite(P->max_cell)) {
        shi_set_err(err, errlen,
                    "sh_guide_bake: params.min_cell / max_cell must be finite and >= 0");
        return SH_ERR_ARG;
    }
    if (P->sigma_t_samples < 1 || P->sigma_t_samples > 8) {
        shi_set_err(err, errlen, "sh_guide_bake: params.sigma_t_samples = %d: must be 1..8",
                    P->sigma_t_samples);
        return SH_ERR_ARG;
    }
    for (int l = 0; l < P->bands; l++)
        if (!isfinite(P->phase_b[l])) {
            shi_set_err(err, errlen, "sh_guide_bake: params.phase_b[%d] is not finite", l);
            return SH_ERR_ARG;
        }
    int zero = 1;
    for (int a = 0; a < 3; a++) {
        if (!isfinite(P->lo[a]) || !isfinite(P->hi[a])) {
            shi_set_err(err, errlen, "sh_guide_bake: params.lo/hi[%d] is not finite", a);
            return SH_ERR_ARG;
        }
        zero &= P->lo[a] == 0.0 && P->hi[a] == 0.0;
    }
    if (!zero) {
        for (int a = 0; a < 3; a++) {
            if (!(P->lo[a] < P->hi[a])) {
                shi_set_err(err, errlen,
                            "sh_guide_bake: params.lo[%d] = %g >= params.hi[%d] = %g (leave "
                            "both all zero for the photon bounds)", a, P->lo[a], a, P->hi[a]);
                return SH_ERR_ARG;
            }
            lo[a] = P->lo[a], hi[a] = P->hi[a];
        }
        return SH_OK;
    }
    /* Default box: the photons' bounds (segment end points if there are no photons). */
    size_t np = pm_map_photon_count(map), ns = pm_map_segment_count(map);
    if (np > 0) {
        float flo[3], fhi[3];
        pm_map_bounds(map, flo, fhi);
        for (int a = 0; a < 3; a++)
            lo[a] = flo[a], hi[a] = fhi[a];
    } else if (ns > 0) {
        const pm_segment *s = pm_map_segments(map);
        double o[3];
        pm_map_origin(map, o); /* segment origins are stored relative to the map's origin */
        for (int a = 0; a < 3; a++)
            lo[a] = INFINITY, hi[a] = -INFINITY;
        for (size_t i = 0; i < ns; i++)
            for (int a = 0; a < 3; a++) {
                double so = o[a] + s[i].org[a], e = so + (double)s[i].length * s[i].dir[a];
                lo[a] = fmin(lo[a], fmin(so, e));
                hi[a] = fmax(hi[a], fmax(so, e));
            }
    } else {
        shi_set_err(err, errlen, "sh_guide_bake: no box given (params.lo/hi) and the photon map is "
                                 "empty");
        return SH_ERR_ARG;
    }
    double ext = 0.0;
    for (int a = 0; a < 3; a++)
        ext = fmax(ext, hi[a] - lo[a]);
    double pad = fmax(1e-4 * ext, 1e-6);
    for (int a = 0; a < 3; a++)
        lo[a] -= pad, hi[a] += pad;
    return SH_OK;
}

/* Uniform resolution rule (THEORY.md §5; seed 001 §3.1, reconstructed):
 *   n_a = max(1, round(l_a (lambda N / (n l_x l_y l_z))^(1/3))). */
static void uniform_rule(const double lo[3], const double hi[3], double lambda, size_t N, int n,
                         int res[3])
{
    double l[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
    double s = cbrt(lambda * (double)N / ((double)n * l[0] * l[1] * l[2]));
    for (int a = 0; a < 3; a++) {
        double r = round(l[a] * s);
        res[a] = r < 1.0 ? 1 : r > SH_MAX_RES ? SH_MAX_RES : (int)r;
    }
}

/* ---- Adaptive octree build (seed 001 §3.4; docs/guide-grid.md "split rule") ----------------- *
 * Recursive subdivision of the box driven by a point set (photon positions, or segment
 * midpoints without photons). Nodes live in one growing array g->nodes; a split appends its
 * children as one contiguous block. Leaves are appended to the leaf arrays in the order the
 * recursion reaches them, which is the depth-first numbering of the cells. */

/* The split rule's axis choice: halve every axis whose edge exceeds half the longest edge, so
 * cells stay within aspect ratio 2 (docs/guide-grid.md, "split rule"). */
static uint32_t split_mask(const double lo[3], const double hi[3])
{
    double e[3], emax = 0.0;
    for (int a = 0; a < 3; a++) {
        e[a] = hi[a] - lo[a];
        emax = fmax(emax, e[a]);
    }
    uint32_t m = 0;
    for (int a = 0; a < 3; a++)
        if (e[a] > 0.5 * emax)
            m |= 1u << a;
    return m;
}

/* State of one build: the guide being built, the points, and the split rule's limits. */
typedef struct {
    sh_guide *g;
    const double *pts; /* 3 per point, world coordinates */
    uint32_t *idx, *tmp; /* point ids; scatter buffer */
    uint8_t *off;         /* child offset of each point during a split */
    int split_count, max_depth;
    double min_cell, max_cell;
    size_t max_cells;
    size_t cap_nodes, cap_leaves;
    int failed; /* 1 nomem, 2 too many cells */
} build_ctx;

/* Make room for `need` nodes in g->nodes (capacity doubles). 0 when out of memory. */
static int grow_nodes(build_ctx *B, size_t need)
{
    sh_guide *g = B->g;
    if (need <= B->cap_nodes)
        return 1;
    size_t cap = B->cap_nodes ? B->cap_nodes : 64;
    while (cap < need)
        cap *= 2;
    sh_node *n = realloc(g->nodes, cap * sizeof *n);
    if (!n)
        return 0;
    g->nodes = n;
    B->cap_nodes = cap;
    return 1;
}

/* Turn node `node` into a leaf: append the next cell id with its box and depth. 0 (and
 * B->failed set) when out of memory or past max_cells. */
static int add_leaf(build_ctx *B, size_t node, const double lo[3], const double hi[3], int depth)
{
    sh_guide *g = B->g;
    if (g->ncells >= B->max_cells) {
        B->failed = 2;
        return 0;
    }
    if (g->ncells == B->cap_leaves) {
        size_t cap = B->cap_leaves ? 2 * B->cap_leaves : 64;
        double *l = realloc(g->leaf_lo, 3 * cap * sizeof *l);
        if (l)
            g->leaf_lo = l;
        double *h = realloc(g->leaf_hi, 3 * cap * sizeof *h);
        if (h)
            g->leaf_hi = h;
        uint8_t *d = realloc(g->leaf_depth, cap);
        if (d)
            g->leaf_depth = d;
        if (!l || !h || !d) {
            B->failed = 1;
            return 0;
        }
        B->cap_leaves = cap;
    }
    size_t c = g->ncells++;
    for (int a = 0; a < 3; a++) {
        g->leaf_lo[3 * c + a] = lo[a];
        g->leaf_hi[3 * c + a] = hi[a];
    }
    g->leaf_depth[c] = (uint8_t)depth;
    g->nodes[node].child = -(int32_t)c - 1;
    g->nodes[node].mask = 0;
    if (depth > g->depth_max)
        g->depth_max = depth;
    return 1;
}

/* Split while count > split_count and the longest edge >= 2 min_cell, or while the longest
 * edge > max_cell; never deeper than max_depth. Points [a, b) of B->idx lie in this node.
 * Children are allocated as one contiguous block and visited in order, so leaves are numbered
 * depth-first. */
static void build_node(build_ctx *B, size_t node, const double lo[3], const double hi[3],
                       int depth, size_t a, size_t b)
{
    if (B->failed)
        return;
    double emax = 0.0;
    for (int ax = 0; ax < 3; ax++)
        emax = fmax(emax, hi[ax] - lo[ax]);
    size_t count = b - a;
    int split = depth < B->max_depth &&
                ((count > (size_t)B->split_count && emax >= 2.0 * B->min_cell) ||
                 emax > B->max_cell);
    if (!split) {
        add_leaf(B, node, lo, hi, depth);
        return;
    }
    uint32_t mask = split_mask(lo, hi);
    int nch = 1 << shi_popcount3(mask);
    size_t first = B->g->nnodes;
    if (first + (size_t)nch > (size_t)INT32_MAX || !grow_nodes(B, first + (size_t)nch)) {
        B->failed = 1;
        return;
    }
    B->g->nnodes += (size_t)nch;
    B->g->nodes[node].child = (int32_t)first;
    B->g->nodes[node].mask = mask;
    /* Counting sort of the node's points into the children (same tie rule as locate): after
     * it, child c's points are idx[a + start[c] .. a + start[c + 1]). */
    size_t cnt[9] = {0};
    const double zero[3] = {0, 0, 0};
    for (size_t i = a; i < b; i++) {
        const double *q = B->pts + 3 * (size_t)B->idx[i];
        double p[3] = {q[0], q[1], q[2]}, cl[3] = {lo[0], lo[1], lo[2]},
               ch[3] = {hi[0], hi[1], hi[2]};
        int o = shi_child_of(mask, p, zero, cl, ch);
        B->off[i] = (uint8_t)o;
        cnt[o + 1]++;
    }
    for (int c = 0; c < nch; c++)
        cnt[c + 1] += cnt[c];
    size_t start[9];
    memcpy(start, cnt, sizeof start);
    for (size_t i = a; i < b; i++)
        B->tmp[a + cnt[B->off[i]]++] = B->idx[i];
    memcpy(B->idx + a, B->tmp + a, count * sizeof *B->idx);
    for (int c = 0; c < nch; c++) {
        double cl[3], chh[3];
        shi_child_box(mask, c, lo, hi, cl, chh);
        build_node(B, first + (size_t)c, cl, chh, depth + 1, a + start[c], a + start[c + 1]);
        if (B->failed)
            return;
    }
}

static sh_status build_octree(sh_guide *g, const pm_map *map, const sh_bake_params *P,
                              char *err, size_t errlen)
{
    /* Points that drive the split: photon positions, or segment midpoints without photons. */
    size_t np = pm_map_photon_count(map), ns = pm_map_segment_count(map);
    size_t n = np > 0 ? np : ns;
    double *pts = malloc((n ? n : 1) * 3 * sizeof *pts);
    uint32_t *idx = malloc((n ? n : 1) * sizeof *idx);
    uint32_t *tmp = malloc((n ? n : 1) * sizeof *tmp);
    uint8_t *off = malloc(n ? n : 1);
    if (!pts || !idx || !tmp || !off || n > UINT32_MAX) {
        free(pts), free(idx), free(tmp), free(off);
        shi_set_err(err, errlen,
                    "sh_guide_bake: out of memory for the octree build (%zu points)", n);
        return SH_ERR_NOMEM;
    }
    size_t m = 0;
    double o[3];
    pm_map_origin(map, o); /* stored positions are relative to the map's origin */
    if (np > 0) {
        const pm_photon *ph = pm_map_photons(map);
        for (size_t i = 0; i < np; i++)
            for (int a = 0; a < 3; a++)
                pts[3 * i + a] = o[a] + (double)ph[i].pos[a];
    } else {
        const pm_segment *s = pm_map_segments(map);
        for (size_t i = 0; i < ns; i++)
            for (int a = 0; a < 3; a++)
                pts[3 * i + a] = o[a] + (double)s[i].org[a] + 0.5 * s[i].length * s[i].dir[a];
    }
    for (size_t i = 0; i < n; i++) {
        const double *q = pts + 3 * i;
        int in = 1;
        for (int a = 0; a < 3; a++)
            in &= q[a] >= g->lo[a] && q[a] <= g->hi[a];
        if (in)
            idx[m++] = (uint32_t)i;
    }
    double emax = 0.0;
    for (int a = 0; a < 3; a++)
        emax = fmax(emax, g->hi[a] - g->lo[a]);
    build_ctx B;
    memset(&B, 0, sizeof B);
    B.g = g;
    B.pts = pts;
    B.idx = idx;
    B.tmp = tmp;
    B.off = off;
    B.max_depth = P->max_depth;
    B.split_count = P->split_photons > 0 ? P->split_photons : (int)ceil(P->k / P->lambda);
    B.min_cell = P->min_cell > 0.0 ? P->min_cell : emax / ldexp(1.0, P->max_depth);
    B.max_cell = P->max_cell > 0.0 ? P->max_cell : emax / 4.0;
    B.max_cells = P->max_cells;
    g->ncells = 0;
    g->nnodes = 0;
    g->depth_max = 0;
    if (!grow_nodes(&B, 1)) {
        B.failed = 1;
    } else {
        g->nnodes = 1;
        build_node(&B, 0, g->lo, g->hi, 0, 0, m);
    }
    free(pts), free(idx), free(tmp), free(off);
    if (B.failed == 2) {
        shi_set_err(err, errlen, "sh_guide_bake: adaptive grid exceeds params.max_cells = %zu "
                                 "(raise split_photons, min_cell or max_cells)",
                    P->max_cells);
        return SH_ERR_NOMEM;
    }
    if (B.failed) {
        shi_set_err(err, errlen, "sh_guide_bake: out of memory building the octree");
        return SH_ERR_NOMEM;
    }
    return SH_OK;
}

/* ---- The entry point ------------------------------------------------------------------------- *
 * Check the parameters and fix the box; lay out the cells (uniform: explicit res or the rule;
 * adaptive: the octree); allocate the cell arrays; fill them with the chosen bake (sh_bake.c). */

sh_status sh_guide_bake(sh_guide **out, const pm_map *map, const sh_bake_params *P, char *err,
                        size_t errlen)
{
    if (!out) {
        shi_set_err(err, errlen, "sh_guide_bake: out must be non-NULL");
        return SH_ERR_ARG;
    }
    *out = NULL;
    double lo[3], hi[3];
    sh_status st = check_params(map, P, lo, hi, err, errlen);
    if (st != SH_OK)
        return st;
    double t_start = omp_get_wtime();
    sh_guide *g = calloc(1, sizeof *g);
    if (!g) {
        shi_set_err(err, errlen, "sh_guide_bake: out of memory");
        return SH_ERR_NOMEM;
    }
    g->kind = P->kind;
    g->method = P->method;
    g->bands = P->bands;
    g->ncoef = SH_CHANNELS * P->bands * P->bands;
    g->k = P->k;
    g->lambda = P->lambda;
    sh_basis_init(&g->basis, g->bands);
    for (int a = 0; a < 3; a++)
        g->lo[a] = lo[a], g->hi[a] = hi[a];
    size_t np = pm_map_photon_count(map), ns = pm_map_segment_count(map);
    g->photons = P->method == SH_BAKE_KNN ? np : ns;

    if (P->kind == SH_GRID_UNIFORM) {
        if (P->res[0] > 0) {
            for (int a = 0; a < 3; a++)
                g->res[a] = P->res[a];
        } else {
            uniform_rule(lo, hi, P->lambda, np > 0 ? np : ns, P->k, g->res);
        }
        double cells = (double)g->res[0] * g->res[1] * g->res[2];
        if (cells > (double)P->max_cells) {
            shi_set_err(err, errlen,
                        "sh_guide_bake: uniform grid %dx%dx%d exceeds params.max_cells = %zu",
                        g->res[0], g->res[1], g->res[2], P->max_cells);
            sh_guide_free(g);
            return SH_ERR_NOMEM;
        }
        g->ncells = (size_t)cells;
        for (int a = 0; a < 3; a++)
            g->h[a] = (hi[a] - lo[a]) / g->res[a];
    } else {
        st = build_octree(g, map, P, err, errlen);
        if (st != SH_OK) {
            sh_guide_free(g);
            return st;
        }
    }
    g->coeffs = calloc(g->ncells * (size_t)g->ncoef, sizeof *g->coeffs);
    g->sigma_t = calloc(g->ncells, sizeof *g->sigma_t);
    if (!g->coeffs || !g->sigma_t) {
        shi_set_err(err, errlen, "sh_guide_bake: out of memory for %zu cells x %d coefficients",
                    g->ncells, g->ncoef);
        sh_guide_free(g);
        return SH_ERR_NOMEM;
    }
    st = P->method == SH_BAKE_KNN ? shi_bake_knn(g, map, P, err, errlen)
                                  : shi_bake_track(g, map, P, err, errlen);
    if (st != SH_OK) {
        sh_guide_free(g);
        return st;
    }
    g->bake_seconds = omp_get_wtime() - t_start;
    *out = g;
    return SH_OK;
}
