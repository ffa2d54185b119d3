/* sh_io.c: getting a guide out of memory: slice images for looking at it, and the guide file
 * (write to a caller's stream / load; format in docs/guide-grid.md "File format" and below). Loading validates
 * everything before the guide is handed out: sizes against the file length, the checksum,
 * the octree's shape, and finite values. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sh_internal.h"

/* ---- Slice images ---------------------------------------------------------------------------- *
 * One point lookup per pixel centre (docs/guide-grid.md "Slice images"); the SH basis is
 * evaluated once for the whole image since w is the same everywhere. */

sh_status sh_guide_slice(const sh_guide *g, int axis, double coord, const double w[3],
                         sh_slice_what what, int width, int height, float *out, char *err,
                         size_t errlen)
{
    if (!g || !out || axis < 0 || axis > 2 || width < 1 || height < 1 || !isfinite(coord) ||
        (unsigned)what > SH_SLICE_DEPTH) {
        shi_set_err(err, errlen, "sh_guide_slice: bad argument (axis %d, %dx%d, what %d)", axis,
                    width, height, (int)what);
        return SH_ERR_ARG;
    }
    static const int UV[3][2] = {{1, 2}, {0, 2}, {0, 1}};
    int u = UV[axis][0], v = UV[axis][1];
    float y[SH_MAX_COEFFS];
    double wd[3] = {0.0, 0.0, 1.0};
    if (w)
        wd[0] = w[0], wd[1] = w[1], wd[2] = w[2];
    sh_basis_evalf(&g->basis, wd, y);
#pragma omp parallel for schedule(static)
    for (int j = 0; j < height; j++) {
        for (int i = 0; i < width; i++) {
            double x[3];
            x[axis] = coord;
            x[u] = g->lo[u] + (i + 0.5) / width * (g->hi[u] - g->lo[u]);
            x[v] = g->hi[v] - (j + 0.5) / height * (g->hi[v] - g->lo[v]); /* row 0 at the top */
            float *px = out + 3 * ((size_t)j * (size_t)width + (size_t)i);
            px[0] = px[1] = px[2] = 0.0f;
            long c = sh_guide_locate(g, x);
            if (c < 0)
                continue;
            const float *cf = g->coeffs + (size_t)c * (size_t)g->ncoef;
            switch (what) {
            case SH_SLICE_RADIANCE:
                sh_eval_rgb_clamped(g->bands, cf, y, px);
                break;
            case SH_SLICE_GUIDE:
                px[0] = px[1] = px[2] = sh_eval_guide(g->bands, cf, y);
                break;
            case SH_SLICE_SIGMA_T:
                px[0] = px[1] = px[2] = g->sigma_t[c];
                break;
            case SH_SLICE_DEPTH:
                px[0] = px[1] = px[2] = (float)sh_guide_cell_depth(g, (size_t)c);
                break;
            }
        }
    }
    return SH_OK;
}

/* ---- Files -------------------------------------------------------------------------------------
 * Layout (little-endian; docs/guide-grid.md "file format"):
 *   0   char[8]  magic "SHGUIDE\0"
 *   8   u32      version (1)
 *   12  u32      kind (0 uniform, 1 adaptive)
 *   16  u32      method (0 k-NN, 1 track)
 *   20  u32      bands L (1..16)
 *   24  f64[3]   box lo;  48  f64[3] box hi
 *   72  i32[3]   res (uniform; 0 for adaptive)
 *   84  u32      k
 *   88  u64      cells
 *   96  u64      nodes (adaptive; 0 for uniform)
 *   104 f64      lambda
 *   112 f64      bake seconds
 *   120 u64      photons (or segments) used
 *   128 nodes x {i32 child, u32 mask}
 *       cells x 3 L^2 f32 coefficients (channel-major per cell)
 *       cells x f32 sigma_t
 *       u64      FNV-1a 64 of every byte above
 * Every number is written byte by byte through put_* / read through get_*, so the file is
 * little-endian on any host. */
#define SH_FILE_MAGIC "SHGUIDE"
#define SH_FILE_VERSION 1u
#define SH_HEADER_BYTES 128

/* An output file with the running checksum of every byte written; bad latches a write error
 * so that the caller checks once at the end. */
typedef struct {
    FILE *f;
    uint64_t h;
    int bad;
} wstream;

static inline uint64_t fnv1a(uint64_t h, const unsigned char *p, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= 0x100000001b3ull;
    }
    return h;
}
#define FNV_OFFSET 0xcbf29ce484222325ull

static void w_bytes(wstream *w, const void *p, size_t n)
{
    w->h = fnv1a(w->h, p, n);
    if (!w->bad && fwrite(p, 1, n, w->f) != n)
        w->bad = 1;
}
static void put_u32(unsigned char *b, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        b[i] = (unsigned char)(v >> (8 * i));
}
static void put_u64(unsigned char *b, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        b[i] = (unsigned char)(v >> (8 * i));
}
static void put_f64(unsigned char *b, double v)
{
    uint64_t u;
    memcpy(&u, &v, 8);
    put_u64(b, u);
}
static uint32_t get_u32(const unsigned char *b)
{
    uint32_t v = 0;
    for (int i = 0; i < 4; i++)
        v |= (uint32_t)b[i] << (8 * i);
    return v;
}
static uint64_t get_u64(const unsigned char *b)
{
    uint64_t v = 0;
    for (int i = 0; i < 8; i++)
        v |= (uint64_t)b[i] << (8 * i);
    return v;
}
static double get_f64(const unsigned char *b)
{
    uint64_t u = get_u64(b);
    double v;
    memcpy(&v, &u, 8);
    return v;
}

/* Write n floats little-endian through a chunk buffer. */
static void w_floats(wstream *w, const float *x, size_t n)
{
    unsigned char buf[4096];
    while (n) {
        size_t m = n < sizeof buf / 4 ? n : sizeof buf / 4;
        for (size_t i = 0; i < m; i++) {
            uint32_t u;
            memcpy(&u, &x[i], 4);
            put_u32(buf + 4 * i, u);
        }
        w_bytes(w, buf, 4 * m);
        x += m, n -= m;
    }
}

sh_status sh_guide_write(const sh_guide *g, FILE *f, const char *name, char *err, size_t errlen)
{
    if (!g || !f || !name) {
        shi_set_err(err, errlen, "sh_guide_write: guide, stream and name must be non-NULL");
        return SH_ERR_ARG;
    }
    wstream w = {f, FNV_OFFSET, 0};
    unsigned char hd[SH_HEADER_BYTES];
    memset(hd, 0, sizeof hd);
    memcpy(hd, SH_FILE_MAGIC, 8);
    put_u32(hd + 8, SH_FILE_VERSION);
    put_u32(hd + 12, (uint32_t)g->kind);
    put_u32(hd + 16, (uint32_t)g->method);
    put_u32(hd + 20, (uint32_t)g->bands);
    for (int a = 0; a < 3; a++) {
        put_f64(hd + 24 + 8 * a, g->lo[a]);
        put_f64(hd + 48 + 8 * a, g->hi[a]);
        put_u32(hd + 72 + 4 * a, (uint32_t)(g->kind == SH_GRID_UNIFORM ? g->res[a] : 0));
    }
    put_u32(hd + 84, (uint32_t)g->k);
    put_u64(hd + 88, g->ncells);
    put_u64(hd + 96, g->kind == SH_GRID_ADAPTIVE ? g->nnodes : 0);
    put_f64(hd + 104, g->lambda);
    put_f64(hd + 112, g->bake_seconds);
    put_u64(hd + 120, g->photons);
    w_bytes(&w, hd, sizeof hd);
    if (g->kind == SH_GRID_ADAPTIVE) {
        unsigned char nb[8];
        for (size_t i = 0; i < g->nnodes; i++) {
            put_u32(nb, (uint32_t)g->nodes[i].child);
            put_u32(nb + 4, g->nodes[i].mask);
            w_bytes(&w, nb, 8);
        }
    }
    w_floats(&w, g->coeffs, g->ncells * (size_t)g->ncoef);
    w_floats(&w, g->sigma_t, g->ncells);
    unsigned char cs[8];
    put_u64(cs, w.h);
    if (!w.bad && fwrite(cs, 1, 8, w.f) != 8)
        w.bad = 1;
    if (fflush(w.f) != 0 || ferror(w.f))
        w.bad = 1;
    if (w.bad) {
        shi_set_err(err, errlen, "%s: write failed", name);
        return SH_ERR_IO;
    }
    return SH_OK;
}

/* An input file with the running checksum of every byte read. */
typedef struct {
    FILE *f;
    uint64_t h;
} rstream;

static int r_bytes(rstream *r, void *p, size_t n)
{
    if (fread(p, 1, n, r->f) != n)
        return 0;
    r->h = fnv1a(r->h, p, n);
    return 1;
}

static int r_floats(rstream *r, float *x, size_t n)
{
    unsigned char buf[4096];
    while (n) {
        size_t m = n < sizeof buf / 4 ? n : sizeof buf / 4;
        if (!r_bytes(r, buf, 4 * m))
            return 0;
        for (size_t i = 0; i < m; i++) {
            uint32_t u = get_u32(buf + 4 * i);
            memcpy(&x[i], &u, 4);
        }
        x += m, n -= m;
    }
    return 1;
}

/* Walk the octree from the root: every node reached exactly once, children after their
 * parent, every leaf id used exactly once; fills the leaf bounds and depths (which the file
 * does not store). Depth-first with an explicit stack, sized for 7 pending siblings on each
 * level down to SH_MAX_DEPTH (deeper nodes are rejected) plus the 8 children last pushed. */
static int validate_octree(sh_guide *g, char *why, size_t whylen)
{
    uint8_t *seen = calloc(g->nnodes, 1);
    uint8_t *leaf_seen = calloc(g->ncells ? g->ncells : 1, 1);
    g->leaf_lo = malloc(3 * (g->ncells ? g->ncells : 1) * sizeof(double));
    g->leaf_hi = malloc(3 * (g->ncells ? g->ncells : 1) * sizeof(double));
    g->leaf_depth = malloc(g->ncells ? g->ncells : 1);
    typedef struct {
        size_t node;
        int depth;
        double lo[3], hi[3];
    } item;
    item *stack = malloc((size_t)(7 * (SH_MAX_DEPTH + 1) + 8) * sizeof *stack);
    int ok = seen && leaf_seen && g->leaf_lo && g->leaf_hi && g->leaf_depth && stack;
    if (!ok)
        snprintf(why, whylen, "out of memory");
    size_t sp = 0, visited = 0, leaves = 0;
    if (ok) {
        stack[sp].node = 0;
        stack[sp].depth = 0;
        for (int a = 0; a < 3; a++)
            stack[sp].lo[a] = g->lo[a], stack[sp].hi[a] = g->hi[a];
        sp++;
    }
    g->depth_max = 0;
    while (ok && sp) {
        item it = stack[--sp];
        if (seen[it.node]) {
            snprintf(why, whylen, "octree node %zu reached twice", it.node);
            ok = 0;
            break;
        }
        seen[it.node] = 1;
        visited++;
        const sh_node *n = &g->nodes[it.node];
        if (n->child < 0) {
            size_t c = (size_t)(-(int64_t)n->child - 1);
            if (c >= g->ncells || leaf_seen[c] || n->mask != 0) {
                snprintf(why, whylen, "octree node %zu: bad leaf id %zu", it.node, c);
                ok = 0;
                break;
            }
            leaf_seen[c] = 1;
            leaves++;
            for (int a = 0; a < 3; a++)
                g->leaf_lo[3 * c + a] = it.lo[a], g->leaf_hi[3 * c + a] = it.hi[a];
            g->leaf_depth[c] = (uint8_t)it.depth;
            if (it.depth > g->depth_max)
                g->depth_max = it.depth;
            continue;
        }
        int nch = 1 << shi_popcount3(n->mask);
        if (n->mask == 0 || n->mask > 7 || it.depth >= SH_MAX_DEPTH ||
            (size_t)n->child <= it.node || (size_t)n->child + (size_t)nch > g->nnodes) {
            snprintf(why, whylen, "octree node %zu: bad children (first %d, mask %u, depth %d)",
                     it.node, (int)n->child, (unsigned)n->mask, it.depth);
            ok = 0;
            break;
        }
        /* push in reverse so that children are popped in order (depth-first ids) */
        for (int c = nch - 1; c >= 0; c--) {
            item ch;
            ch.node = (size_t)n->child + (size_t)c;
            ch.depth = it.depth + 1;
            shi_child_box(n->mask, c, it.lo, it.hi, ch.lo, ch.hi);
            stack[sp++] = ch;
        }
    }
    if (ok && (visited != g->nnodes || leaves != g->ncells)) {
        snprintf(why, whylen, "octree has %zu unreachable nodes / %zu unused leaves",
                 g->nnodes - visited, g->ncells - leaves);
        ok = 0;
    }
    free(seen);
    free(leaf_seen);
    free(stack);
    return ok;
}

sh_status sh_guide_load(sh_guide **out, const char *path, char *err, size_t errlen)
{
    if (!out || !path) {
        shi_set_err(err, errlen, "sh_guide_load: out and path must be non-NULL");
        return SH_ERR_ARG;
    }
    *out = NULL;
    rstream r = {fopen(path, "rb"), FNV_OFFSET};
    if (!r.f) {
        shi_set_err(err, errlen, "%s: cannot open", path);
        return SH_ERR_IO;
    }
    sh_status st = SH_ERR_FORMAT;
    sh_guide *g = NULL;
    char why[160] = "";
    /* File size, to reject truncation and trailing bytes before allocating anything. */
    long fsize = -1;
    if (fseek(r.f, 0, SEEK_END) == 0)
        fsize = ftell(r.f);
    if (fsize < 0 || fseek(r.f, 0, SEEK_SET) != 0) {
        shi_set_err(err, errlen, "%s: cannot determine the file size", path);
        fclose(r.f);
        return SH_ERR_IO;
    }
    unsigned char hd[SH_HEADER_BYTES];
    if ((size_t)fsize < SH_HEADER_BYTES + 8 || !r_bytes(&r, hd, sizeof hd)) {
        snprintf(why, sizeof why, "truncated header (%ld bytes)", fsize);
        goto fail;
    }
    if (memcmp(hd, SH_FILE_MAGIC, 8) != 0) {
        snprintf(why, sizeof why, "not a guide file (bad magic)");
        goto fail;
    }
    uint32_t version = get_u32(hd + 8);
    if (version != SH_FILE_VERSION) {
        snprintf(why, sizeof why, "unsupported version %u (expected %u)", version,
                 SH_FILE_VERSION);
        goto fail;
    }
    g = calloc(1, sizeof *g);
    if (!g) {
        st = SH_ERR_NOMEM;
        snprintf(why, sizeof why, "out of memory");
        goto fail;
    }
    uint32_t kind = get_u32(hd + 12), method = get_u32(hd + 16), bands = get_u32(hd + 20);
    if (kind > 1 || method > 1) {
        snprintf(why, sizeof why, "bad kind %u or method %u", kind, method);
        goto fail;
    }
    if (bands < 1 || bands > SH_MAX_BANDS) {
        snprintf(why, sizeof why, "bands %u out of range 1..%d", bands, SH_MAX_BANDS);
        goto fail;
    }
    g->kind = (sh_grid_kind)kind;
    g->method = (sh_bake_method)method;
    g->bands = (int)bands;
    g->ncoef = SH_CHANNELS * g->bands * g->bands;
    for (int a = 0; a < 3; a++) {
        g->lo[a] = get_f64(hd + 24 + 8 * a);
        g->hi[a] = get_f64(hd + 48 + 8 * a);
        if (!isfinite(g->lo[a]) || !isfinite(g->hi[a]) || !(g->lo[a] < g->hi[a])) {
            snprintf(why, sizeof why, "box axis %d is empty or not finite", a);
            goto fail;
        }
        g->res[a] = (int)get_u32(hd + 72 + 4 * a);
    }
    g->k = (int)get_u32(hd + 84);
    uint64_t ncells = get_u64(hd + 88), nnodes = get_u64(hd + 96);
    g->lambda = get_f64(hd + 104);
    g->bake_seconds = get_f64(hd + 112);
    g->photons = (size_t)get_u64(hd + 120);
    /* Sizes: every count must be consistent with the file length (no absurd allocations). */
    uint64_t per_cell = (uint64_t)g->ncoef * 4 + 4;
    uint64_t avail = (uint64_t)fsize - SH_HEADER_BYTES - 8;
    if (ncells == 0 || ncells > avail / per_cell || nnodes > avail / 8 ||
        nnodes * 8 + ncells * per_cell != avail) {
        snprintf(why, sizeof why,
                 "size mismatch: %llu cells, %llu nodes do not fill %ld bytes (truncated or "
                 "trailing data)", (unsigned long long)ncells, (unsigned long long)nnodes,
                 fsize);
        goto fail;
    }
    g->ncells = (size_t)ncells;
    if (g->kind == SH_GRID_UNIFORM) {
        uint64_t prod = 1;
        for (int a = 0; a < 3; a++) {
            if (g->res[a] < 1 || g->res[a] > SH_MAX_RES) {
                snprintf(why, sizeof why, "res[%d] = %d out of range", a, g->res[a]);
                goto fail;
            }
            prod *= (uint64_t)g->res[a];
            g->h[a] = (g->hi[a] - g->lo[a]) / g->res[a];
        }
        if (prod != ncells || nnodes != 0) {
            snprintf(why, sizeof why, "res %dx%dx%d does not match %llu cells", g->res[0],
                     g->res[1], g->res[2], (unsigned long long)ncells);
            goto fail;
        }
    } else {
        if (nnodes < 1 || nnodes > (uint64_t)INT32_MAX || ncells > nnodes) {
            snprintf(why, sizeof why, "bad octree size (%llu nodes, %llu leaves)",
                     (unsigned long long)nnodes, (unsigned long long)ncells);
            goto fail;
        }
        g->nnodes = (size_t)nnodes;
        g->nodes = malloc(g->nnodes * sizeof *g->nodes);
        if (!g->nodes) {
            st = SH_ERR_NOMEM;
            snprintf(why, sizeof why, "out of memory for %zu nodes", g->nnodes);
            goto fail;
        }
        for (size_t i = 0; i < g->nnodes; i++) {
            unsigned char nb[8];
            if (!r_bytes(&r, nb, 8)) {
                snprintf(why, sizeof why, "truncated in the octree nodes");
                goto fail;
            }
            g->nodes[i].child = (int32_t)get_u32(nb);
            g->nodes[i].mask = get_u32(nb + 4);
        }
    }
    g->coeffs = malloc(g->ncells * (size_t)g->ncoef * sizeof(float));
    g->sigma_t = malloc(g->ncells * sizeof(float));
    if (!g->coeffs || !g->sigma_t) {
        st = SH_ERR_NOMEM;
        snprintf(why, sizeof why, "out of memory for %zu cells", g->ncells);
        goto fail;
    }
    if (!r_floats(&r, g->coeffs, g->ncells * (size_t)g->ncoef) ||
        !r_floats(&r, g->sigma_t, g->ncells)) {
        snprintf(why, sizeof why, "truncated in the cell data");
        goto fail;
    }
    uint64_t h = r.h;
    unsigned char cs[8];
    if (fread(cs, 1, 8, r.f) != 8) {
        snprintf(why, sizeof why, "truncated before the checksum");
        goto fail;
    }
    if (get_u64(cs) != h) {
        snprintf(why, sizeof why, "checksum mismatch (file corrupt)");
        goto fail;
    }
    if (g->kind == SH_GRID_ADAPTIVE && !validate_octree(g, why, sizeof why))
        goto fail;
    for (size_t i = 0; i < g->ncells * (size_t)g->ncoef; i++)
        if (!isfinite(g->coeffs[i])) {
            snprintf(why, sizeof why, "coefficient %zu of cell %zu is not finite",
                     i % (size_t)g->ncoef, i / (size_t)g->ncoef);
            goto fail;
        }
    for (size_t c = 0; c < g->ncells; c++)
        if (!isfinite(g->sigma_t[c]) || g->sigma_t[c] < 0.0f) {
            snprintf(why, sizeof why, "sigma_t of cell %zu is negative or not finite", c);
            goto fail;
        }
    if (!(g->lambda > 0.0) || !isfinite(g->lambda) || !isfinite(g->bake_seconds)) {
        snprintf(why, sizeof why, "bad lambda or bake time");
        goto fail;
    }
    sh_basis_init(&g->basis, g->bands);
    fclose(r.f);
    *out = g;
    return SH_OK;
fail:
    fclose(r.f);
    sh_guide_free(g);
    shi_set_err(err, errlen, "%s: %s", path, why);
    return st;
}
