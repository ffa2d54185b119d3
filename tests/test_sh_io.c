/* test_sh_io.c: guide files (round trip, every kind of corruption rejected with a one-line
 * message naming the file) and slice images (docs/guide-grid.md). Fixed seeds. */
#include <criterion/criterion.h>
#include <dirent.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "photonmap.h"
#include "sh.h"

static pm_map *small_map(void)
{
    const size_t n = 3000;
    pm_photon *ph = malloc(n * sizeof *ph);
    uint64_t s = 12345;
    for (size_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            s = s * 6364136223846793005ull + 1442695040888963407ull;
            double u = (double)(s >> 11) * 0x1.0p-53;
            double x = i % 2 ? u : 0.3 + 0.1 * u; /* half of them in a small blob */
            ph[i].pos[a] = (float)x;
            ph[i].dir[a] = a == 0 ? 0.6f : a == 1 ? 0.8f : 0.0f;
            ph[i].power[a] = (float)(1.0 + a);
        }
    }
    pm_map *m = pm_map_new();
    cr_assert_eq(pm_map_add_photons(m, ph, n, NULL, 0), PM_OK);
    cr_assert_eq(pm_map_build(m, NULL, 0), PM_OK);
    free(ph);
    return m;
}

static double sig(const double x[3], void *u)
{
    (void)u;
    return 1.0 + x[1];
}

static sh_guide *bake(sh_grid_kind kind)
{
    pm_map *m = small_map();
    sh_bake_params P;
    sh_bake_params_default(&P);
    for (int a = 0; a < 3; a++)
        P.lo[a] = 0.0, P.hi[a] = 1.0;
    P.kind = kind;
    P.k = 10;
    P.bands = 3;
    P.sigma_t = sig;
    sh_phase_coeffs_hg(0.5, 3, P.phase_b);
    sh_guide *g = NULL;
    char err[256] = "";
    cr_assert_eq(sh_guide_bake(&g, m, &P, err, sizeof err), SH_OK, "%s", err);
    pm_map_free(m);
    return g;
}

static char dir_path[256];
static void make_dir(void)
{
    strcpy(dir_path, "/tmp/test_sh_io_XXXXXX");
    cr_assert_not_null(mkdtemp(dir_path));
}
static void remove_dir(void)
{
    DIR *d = opendir(dir_path);
    if (d) {
        struct dirent *e;
        char p[600];
        while ((e = readdir(d)))
            if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) {
                snprintf(p, sizeof p, "%s/%s", dir_path, e->d_name);
                remove(p);
            }
        closedir(d);
    }
    rmdir(dir_path);
}

static void same_guide(const sh_guide *a, const sh_guide *b)
{
    sh_guide_stats sa, sb;
    sh_guide_stats_get(a, &sa);
    sh_guide_stats_get(b, &sb);
    cr_assert_eq(sa.kind, sb.kind);
    cr_assert_eq(sa.method, sb.method);
    cr_assert_eq(sa.bands, sb.bands);
    cr_assert_eq(sa.cells, sb.cells);
    cr_assert_eq(sa.nodes, sb.nodes);
    cr_assert_eq(sa.depth_max, sb.depth_max);
    cr_assert_eq(sa.k, sb.k);
    cr_assert_eq(sa.bake_seconds, sb.bake_seconds);
    for (int i = 0; i < 3; i++)
        cr_assert_eq(sa.res[i], sb.res[i]);
    int nc = 3 * sa.bands * sa.bands;
    for (size_t c = 0; c < sa.cells; c++) {
        cr_assert(memcmp(sh_guide_cell_coeffs(a, c), sh_guide_cell_coeffs(b, c),
                         (size_t)nc * sizeof(float)) == 0);
        cr_assert_eq(sh_guide_cell_sigma_t(a, c), sh_guide_cell_sigma_t(b, c));
        double l1[3], h1[3], l2[3], h2[3];
        sh_guide_cell_bounds(a, c, l1, h1);
        sh_guide_cell_bounds(b, c, l2, h2);
        for (int i = 0; i < 3; i++)
            cr_assert(l1[i] == l2[i] && h1[i] == h2[i]);
        cr_assert_eq(sh_guide_cell_depth(a, c), sh_guide_cell_depth(b, c));
    }
    /* The same ray gives the same segments. */
    double o[3] = {-0.1, 0.31, 0.37}, d[3] = {1.0, 0.13, 0.07};
    sh_guide_ray ia, ib;
    sh_guide_seg s1, s2;
    sh_guide_ray_begin(a, o, d, 0.0, INFINITY, &ia);
    sh_guide_ray_begin(b, o, d, 0.0, INFINITY, &ib);
    int n = 0;
    while (sh_guide_ray_next(&ia, &s1)) {
        cr_assert(sh_guide_ray_next(&ib, &s2));
        cr_assert(s1.t0 == s2.t0 && s1.t1 == s2.t1 && s1.cell == s2.cell);
        n++;
    }
    cr_assert_not(sh_guide_ray_next(&ib, &s2));
    cr_assert_gt(n, 2);
}

/* Save a guide to path through sh_guide_write (the renderer's temporary and rename are its
 * own: tests/test_cli.c). */
static sh_status save_guide(const sh_guide *g, const char *path, char *err, size_t errlen)
{
    FILE *f = fopen(path, "wb");
    cr_assert(f != NULL, "%s: cannot create", path);
    sh_status st = sh_guide_write(g, f, path, err, errlen);
    cr_assert_eq(fclose(f), 0);
    return st;
}

Test(sh, save_load_round_trip, .init = make_dir, .fini = remove_dir)
{
    for (int kind = 0; kind < 2; kind++) {
        sh_guide *g = bake((sh_grid_kind)kind), *h = NULL;
        char path[400], err[512] = "";
        snprintf(path, sizeof path, "%s/guide%d.shg", dir_path, kind);
        cr_assert_eq(save_guide(g, path, err, sizeof err), SH_OK, "%s", err);
        cr_assert_eq(sh_guide_load(&h, path, err, sizeof err), SH_OK, "%s", err);
        same_guide(g, h);
        /* Saving over an existing file replaces it. */
        cr_assert_eq(save_guide(h, path, err, sizeof err), SH_OK, "%s", err);
        sh_guide_free(h);
        h = NULL;
        cr_assert_eq(sh_guide_load(&h, path, err, sizeof err), SH_OK, "%s", err);
        same_guide(g, h);
        sh_guide_free(h);
        sh_guide_free(g);
    }
}

Test(sh, write_to_a_full_disk_fails, .init = make_dir, .fini = remove_dir)
{
    sh_guide *g = bake(SH_GRID_UNIFORM);
    char err[512] = "";
    FILE *full = fopen("/dev/full", "wb"); /* every write fails with ENOSPC */
    cr_assert(full != NULL);
    cr_assert_eq(sh_guide_write(g, full, "g.shg", err, sizeof err), SH_ERR_IO);
    cr_assert(strstr(err, "g.shg: write failed") != NULL, "%s", err);
    fclose(full);
    cr_assert_eq(sh_guide_write(g, NULL, "g.shg", err, sizeof err), SH_ERR_ARG);
    sh_guide_free(g);
}

/* ---- corruption ------------------------------------------------------------------------------ */

static unsigned char *read_all(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    cr_assert_not_null(f);
    fseek(f, 0, SEEK_END);
    long sz = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *b = malloc((size_t)sz + 16);
    cr_assert_eq(fread(b, 1, (size_t)sz, f), (size_t)sz);
    fclose(f);
    *n = (size_t)sz;
    return b;
}
static void write_all(const char *path, const unsigned char *b, size_t n)
{
    FILE *f = fopen(path, "wb");
    cr_assert_not_null(f);
    cr_assert_eq(fwrite(b, 1, n, f), n);
    fclose(f);
}
/* Recompute the trailing FNV-1a 64 (the documented format), to reach the checks behind it. */
static void fix_checksum(unsigned char *b, size_t n)
{
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t i = 0; i < n - 8; i++) {
        h ^= b[i];
        h *= 0x100000001b3ull;
    }
    for (int i = 0; i < 8; i++)
        b[n - 8 + (size_t)i] = (unsigned char)(h >> (8 * i));
}

static void expect_reject(const char *path, const unsigned char *b, size_t n, sh_status want,
                          const char *what, const char *needle)
{
    write_all(path, b, n);
    sh_guide *g = (sh_guide *)0x1;
    char err[512] = "";
    sh_status st = sh_guide_load(&g, path, err, sizeof err);
    cr_assert_eq(st, want, "%s: status %d (%s)", what, (int)st, err);
    cr_assert_null(g, "%s", what);
    cr_assert(strstr(err, path) != NULL, "%s: message must name the file: %s", what, err);
    cr_assert(strchr(err, '\n') == NULL, "%s: one line", what);
    if (needle)
        cr_assert(strstr(err, needle) != NULL, "%s: '%s' not in: %s", what, needle, err);
}

static void put32(unsigned char *b, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        b[i] = (unsigned char)(v >> (8 * i));
}

Test(sh, corrupt_files_are_rejected, .init = make_dir, .fini = remove_dir)
{
    for (int kind = 0; kind < 2; kind++) {
        sh_guide *g = bake((sh_grid_kind)kind);
        char good[400], bad[400];
        snprintf(good, sizeof good, "%s/good.shg", dir_path);
        snprintf(bad, sizeof bad, "%s/bad.shg", dir_path);
        cr_assert_eq(save_guide(g, good, NULL, 0), SH_OK);
        size_t n;
        unsigned char *b = read_all(good, &n), *c = malloc(n + 16);
        cr_assert_gt(n, 200);

        memcpy(c, b, n);
        c[0] = 'X';
        expect_reject(bad, c, n, SH_ERR_FORMAT, "magic", "magic");

        memcpy(c, b, n);
        put32(c + 8, 2);
        expect_reject(bad, c, n, SH_ERR_FORMAT, "version", "version");

        const size_t cuts[] = {0, 7, 100, 127, 136, n / 2, n - 9, n - 1};
        for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++)
            expect_reject(bad, b, cuts[i], SH_ERR_FORMAT, "truncated", NULL);

        memcpy(c, b, n);
        c[n] = 0;
        expect_reject(bad, c, n + 1, SH_ERR_FORMAT, "trailing byte", "trailing");

        memcpy(c, b, n);
        c[n - 20] ^= 0x10; /* a coefficient / sigma_t bit */
        expect_reject(bad, c, n, SH_ERR_FORMAT, "flipped bit", "checksum");

        memcpy(c, b, n);
        c[n - 3] ^= 0x01; /* the checksum itself */
        expect_reject(bad, c, n, SH_ERR_FORMAT, "checksum byte", "checksum");

        memcpy(c, b, n);
        put32(c + 20, 17); /* bands out of range, checksum fixed */
        fix_checksum(c, n);
        expect_reject(bad, c, n, SH_ERR_FORMAT, "bands", "bands");

        memcpy(c, b, n);
        uint64_t huge = (uint64_t)1 << 40; /* absurd cell count */
        for (int i = 0; i < 8; i++)
            c[88 + i] = (unsigned char)(huge >> (8 * i));
        fix_checksum(c, n);
        expect_reject(bad, c, n, SH_ERR_FORMAT, "cell count", "size mismatch");

        memcpy(c, b, n);
        float nanf_ = NAN; /* a NaN coefficient behind a valid checksum: the first cell's c_00 */
        size_t nodes = 0;
        for (int i = 0; i < 8; i++)
            nodes |= (size_t)c[96 + i] << (8 * i);
        memcpy(c + 128 + 8 * nodes, &nanf_, 4);
        fix_checksum(c, n);
        expect_reject(bad, c, n, SH_ERR_FORMAT, "NaN coefficient", "not finite");

        if (kind == SH_GRID_ADAPTIVE) {
            cr_assert_gt(nodes, 8);
            memcpy(c, b, n);
            put32(c + 128, 0); /* root's children start at the root itself: a cycle */
            fix_checksum(c, n);
            expect_reject(bad, c, n, SH_ERR_FORMAT, "octree cycle", "octree");
            memcpy(c, b, n);
            /* node 1 becomes a leaf reusing leaf id 0: a duplicated leaf / unreachable nodes */
            put32(c + 128 + 8, (uint32_t)-1);
            put32(c + 128 + 12, 0);
            fix_checksum(c, n);
            expect_reject(bad, c, n, SH_ERR_FORMAT, "octree leaf", "octree");
            memcpy(c, b, n);
            put32(c + 128 + 4, 9); /* root mask beyond 3 axes */
            fix_checksum(c, n);
            expect_reject(bad, c, n, SH_ERR_FORMAT, "octree mask", "octree");
        } else {
            memcpy(c, b, n);
            put32(c + 72, 3); /* res no longer matches the cell count */
            fix_checksum(c, n);
            expect_reject(bad, c, n, SH_ERR_FORMAT, "res", "res");
        }
        /* Sanity: the untouched bytes, rewritten, still load (the fixes above are real). */
        memcpy(c, b, n);
        fix_checksum(c, n);
        write_all(bad, c, n);
        sh_guide *h = NULL;
        cr_assert_eq(sh_guide_load(&h, bad, NULL, 0), SH_OK);
        sh_guide_free(h);
        free(b);
        free(c);
        sh_guide_free(g);
    }
    char missing[400], err[512] = "";
    snprintf(missing, sizeof missing, "%s/missing.shg", dir_path);
    sh_guide *g = NULL;
    cr_assert_eq(sh_guide_load(&g, missing, err, sizeof err), SH_ERR_IO);
    cr_assert(strstr(err, missing) != NULL, "%s", err);
}

/* ---- slices ------------------------------------------------------------------------------------ */

Test(sh, slice_images)
{
    for (int kind = 0; kind < 2; kind++) {
        sh_guide *g = bake((sh_grid_kind)kind);
        const int W = 40, H = 30;
        float *img = malloc((size_t)W * H * 3 * sizeof *img);
        double w[3] = {0.0, 0.6, -0.8};
        char err[256] = "";
        for (int axis = 0; axis < 3; axis++) {
            static const int UV[3][2] = {{1, 2}, {0, 2}, {0, 1}};
            int u = UV[axis][0], v = UV[axis][1];
            double coord = 0.33;
            cr_assert_eq(sh_guide_slice(g, axis, coord, w, SH_SLICE_RADIANCE, W, H, img, err,
                                        sizeof err),
                         SH_OK, "%s", err);
            for (int j = 0; j < H; j += 7)
                for (int i = 0; i < W; i += 5) {
                    double x[3];
                    x[axis] = coord;
                    x[u] = (i + 0.5) / W;       /* box [0,1]^3; column i from the left */
                    x[v] = 1.0 - (j + 0.5) / H; /* row 0 at the top */
                    float ref[3];
                    sh_guide_eval(g, x, w, ref);
                    for (int ch = 0; ch < 3; ch++)
                        cr_assert_eq(img[3 * (j * W + i) + ch], ref[ch] > 0 ? ref[ch] : 0.0f);
                }
            cr_assert_eq(sh_guide_slice(g, axis, coord, w, SH_SLICE_SIGMA_T, W, H, img, err,
                                        sizeof err),
                         SH_OK);
            /* sigma_t = 1 + y: a cell mean lies in [1, 2] */
            for (int p = 0; p < W * H; p++)
                cr_assert(img[3 * p] >= 1.0f && img[3 * p] <= 2.0f);
        }
        cr_assert_eq(sh_guide_slice(g, 2, 0.35, w, SH_SLICE_DEPTH, W, H, img, err, sizeof err),
                     SH_OK);
        float dmin = 1e9f, dmax = 0.0f;
        for (int p = 0; p < W * H; p++)
            dmin = fminf(dmin, img[3 * p]), dmax = fmaxf(dmax, img[3 * p]);
        if (kind == SH_GRID_ADAPTIVE)
            cr_assert_gt(dmax, dmin, "the blob's leaves are deeper");
        else
            cr_assert_eq(dmax, 0.0f);
        cr_assert_eq(sh_guide_slice(g, 2, 0.35, w, SH_SLICE_GUIDE, W, H, img, err, sizeof err),
                     SH_OK);
        for (int p = 0; p < W * H; p++)
            cr_assert(img[3 * p] >= 0.0f && img[3 * p] == img[3 * p + 2]);
        /* Outside the box: zeros. Bad arguments: SH_ERR_ARG. */
        cr_assert_eq(sh_guide_slice(g, 2, 5.0, w, SH_SLICE_RADIANCE, W, H, img, err, sizeof err),
                     SH_OK);
        for (int p = 0; p < 3 * W * H; p++)
            cr_assert_eq(img[p], 0.0f);
        cr_assert_eq(sh_guide_slice(g, 3, 0.5, w, SH_SLICE_RADIANCE, W, H, img, err, sizeof err),
                     SH_ERR_ARG);
        cr_assert_eq(sh_guide_slice(g, 0, 0.5, w, SH_SLICE_RADIANCE, 0, H, img, err, sizeof err),
                     SH_ERR_ARG);
        free(img);
        sh_guide_free(g);
    }
}
