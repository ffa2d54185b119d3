/* test_photonmap.c: the photon map against brute force, the k-NN estimates against known
 * densities, batch and threading, and the file format against corrupt files.
 * Fixed seeds everywhere; statistical tolerances are derived from the standard error. */
#include <criterion/criterion.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "photonmap.h"

#define PI 3.14159265358979323846

/* ---------------------------------------------------------------------------------------- */
/* Test helpers                                                                               */

/* PCG32 (O'Neill 2014, pcg32_random_r), fixed seeds. */
typedef struct {
    uint64_t state, inc;
} pcg32;

static uint32_t pcg32_next(pcg32 *r)
{
    uint64_t old = r->state;
    r->state = old * 6364136223846793005ULL + r->inc;
    uint32_t xorshifted = (uint32_t)(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = (uint32_t)(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31));
}

static pcg32 pcg32_seed(uint64_t seed, uint64_t seq)
{
    pcg32 r = {0u, (seq << 1u) | 1u};
    pcg32_next(&r);
    r.state += seed;
    pcg32_next(&r);
    return r;
}

/* The queries take world points as double (photonmap.h). Most tests below build maps with the
 * default origin 0 and float positions, and compare against brute force in float; these
 * wrappers widen a float point to double (exact), so the query the map sees is the very float
 * point the brute force uses. A NULL point stays NULL (argument-error tests). */
static const double *widen(const float *q, double *buf)
{
    if (q == NULL)
        return NULL;
    for (int a = 0; a < 3; a++)
        buf[a] = q[a];
    return buf;
}

static int knn_f(const pm_map *m, const float q[3], int k, int *idx, float *d2)
{
    double b[3];
    return pm_map_knn(m, widen(q, b), k, idx, d2);
}

static int radius_f(const pm_map *m, const float q[3], float r, int max, int *idx, float *d2)
{
    double b[3];
    return pm_map_radius(m, widen(q, b), r, max, idx, d2);
}

static int density_f(const pm_map *m, const float q[3], int k, float out[3])
{
    double b[3];
    return pm_map_density(m, widen(q, b), k, out);
}

static int radiance_f(const pm_map *m, const float q[3], const float w[3], int k,
                      pm_phase_fn phase, void *user, float out[3])
{
    double b[3];
    return pm_map_radiance(m, widen(q, b), w, k, phase, user, out);
}

static pm_status knn_batch_f(const pm_map *m, const float *q, size_t nq, int k, int *idx,
                             float *d2, int threads, char *err, size_t errlen)
{
    double *qd = malloc((nq ? nq : 1) * 3 * sizeof *qd);
    cr_assert_not_null(qd);
    for (size_t i = 0; i < 3 * nq; i++)
        qd[i] = q[i];
    pm_status st = pm_map_knn_batch(m, qd, nq, k, idx, d2, threads, err, errlen);
    free(qd);
    return st;
}

static float uniform01(pcg32 *r) /* [0, 1) with 24 random bits */
{
    return (float)(pcg32_next(r) >> 8) * (1.0f / 16777216.0f);
}

static void random_unit(pcg32 *r, float d[3])
{
    float z = 2.0f * uniform01(r) - 1.0f, phi = 2.0f * (float)PI * uniform01(r);
    float s = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    d[0] = s * cosf(phi);
    d[1] = s * sinf(phi);
    d[2] = z;
}

/* n photons uniform in [0,1)^3 with random directions and powers. With `lattice`, coordinates
 * are multiples of 1/8, so many distances are exactly equal (ties without duplicates). With
 * `dups`, about a quarter of the photons copy the position of an earlier photon. */
static pm_photon *random_photons(pcg32 *r, size_t n, int lattice, int dups)
{
    pm_photon *ph = calloc(n ? n : 1, sizeof *ph);
    cr_assert_not_null(ph);
    for (size_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            float u = uniform01(r);
            ph[i].pos[a] = lattice ? floorf(u * 8.0f) / 8.0f : u;
            ph[i].power[a] = 0.5f + uniform01(r);
        }
        if (dups && i > 0 && pcg32_next(r) % 4 == 0)
            memcpy(ph[i].pos, ph[pcg32_next(r) % i].pos, sizeof ph[i].pos);
        random_unit(r, ph[i].dir);
    }
    return ph;
}

static pm_map *build_map(const pm_photon *ph, size_t n)
{
    char err[256] = "";
    pm_map *m = pm_map_new();
    cr_assert_not_null(m);
    cr_assert_eq(pm_map_add_photons(m, ph, n, err, sizeof err), PM_OK, "%s", err);
    cr_assert_eq(pm_map_build(m, err, sizeof err), PM_OK, "%s", err);
    return m;
}

/* Squared distance exactly as FLANN's L2<float> computes it: ((dx^2 + dy^2) + dz^2). */
static float dist2_flann(const float a[3], const float b[3])
{
    float s = 0.0f;
    for (int i = 0; i < 3; i++) {
        float d = a[i] - b[i];
        s += d * d;
    }
    return s;
}

typedef struct {
    float d2;
    int idx;
} hit;

static int hit_cmp(const void *a, const void *b)
{
    const hit *x = a, *y = b;
    if (x->d2 != y->d2)
        return x->d2 < y->d2 ? -1 : 1;
    return (x->idx > y->idx) - (x->idx < y->idx);
}

/* Brute force: every photon sorted by (dist2, idx). Caller frees. */
static hit *brute_sorted(const pm_photon *ph, size_t n, const float q[3])
{
    hit *h = malloc((n ? n : 1) * sizeof *h);
    cr_assert_not_null(h);
    for (size_t i = 0; i < n; i++) {
        h[i].d2 = dist2_flann(q, ph[i].pos);
        h[i].idx = (int)i;
    }
    qsort(h, n, sizeof *h, hit_cmp);
    return h;
}

/* Query points: random ones, and photon positions themselves (distance 0, duplicate ties). */
static void query_point(pcg32 *r, const pm_photon *ph, size_t n, int lattice, int j, float q[3])
{
    if (j % 3 == 0 && n > 0) {
        memcpy(q, ph[pcg32_next(r) % n].pos, 3 * sizeof(float));
        return;
    }
    for (int a = 0; a < 3; a++) {
        float u = 1.2f * uniform01(r) - 0.1f; /* some outside the cloud */
        q[a] = lattice ? floorf(u * 16.0f) / 16.0f : u;
    }
}

/* Henyey-Greenstein phase function, p(cos) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^(3/2)). */
static double p_hg(double cos_theta, void *user)
{
    double g = *(const double *)user;
    double denom = 1.0 + g * g - 2.0 * g * cos_theta;
    return (1.0 - g * g) / (4.0 * PI * denom * sqrt(denom));
}

static double p_iso(double cos_theta, void *user)
{
    (void)cos_theta;
    (void)user;
    return 1.0 / (4.0 * PI);
}

/* A fresh directory under /tmp for one test's files. */
static void make_tmpdir(char dir[64])
{
    strcpy(dir, "/tmp/pmtest.XXXXXX");
    cr_assert_not_null(mkdtemp(dir));
}

static void write_bytes(const char *path, const unsigned char *b, size_t n)
{
    FILE *f = fopen(path, "wb");
    cr_assert_not_null(f);
    cr_assert_eq(fwrite(b, 1, n, f), n);
    cr_assert_eq(fclose(f), 0);
}

/* Save a map to path through pm_map_write (the renderer's temporary and rename are its own:
 * tests/test_cli.c). */
static pm_status save_map(const pm_map *m, const char *path, char *err, size_t errlen)
{
    FILE *f = fopen(path, "wb");
    cr_assert(f != NULL, "%s: cannot create", path);
    pm_status st = pm_map_write(m, f, path, err, errlen);
    cr_assert_eq(fclose(f), 0);
    return st;
}

static unsigned char *read_bytes(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    cr_assert_not_null(f);
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *b = malloc(len > 0 ? (size_t)len : 1);
    cr_assert_not_null(b);
    cr_assert_eq(fread(b, 1, (size_t)len, f), (size_t)len);
    fclose(f);
    *n = (size_t)len;
    return b;
}

/* FNV-1a 64, written again here so the test does not trust the library's copy. */
static uint64_t fnv1a64(const unsigned char *p, size_t n)
{
    uint64_t h = 0xcbf29ce484222325ULL;
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= 0x100000001b3ULL;
    }
    return h;
}

static void restamp_checksum(unsigned char *b, size_t n)
{
    uint64_t h = fnv1a64(b, n - 8);
    for (int i = 0; i < 8; i++)
        b[n - 8 + i] = (unsigned char)(h >> (8 * i));
}

/* Expect pm_map_load to fail with `code` and a message that names the file and contains
 * `needle` (when non-NULL). */
static void expect_load_fails(const char *path, pm_status code, const char *needle)
{
    char err[512] = "";
    pm_map *m = (pm_map *)&err; /* must be reset to NULL */
    pm_status s = pm_map_load(&m, path, err, sizeof err);
    cr_assert_eq(s, code, "%s: status %d, expected %d (%s)", path, s, code, err);
    cr_assert_null(m);
    cr_assert_not_null(strstr(err, path), "message does not name the file: %s", err);
    cr_assert_null(strchr(err, '\n'), "message is not one line: %s", err);
    if (needle)
        cr_assert_not_null(strstr(err, needle), "message lacks '%s': %s", needle, err);
}

/* File layout of version 2 (docs/photonmap-format.md): a 48-byte header (magic, version,
 * counts, origin as three float64), the records, an 8-byte checksum. */
#define HDR 48
/* The origin of the sample maps: far from 0 and not representable in float. */
static const double SAMPLE_ORIGIN[3] = {1.0e5 + 1.0 / 3.0, -2.5e4, 3.1};

/* A small map with photons and segments saved to dir/name; returns the path (static). */
static const char *save_sample(const char *dir, const char *name, size_t nph, size_t nseg,
                               char path[256])
{
    pcg32 r = pcg32_seed(77, 1);
    pm_photon *ph = random_photons(&r, nph, 0, 0);
    pm_segment *seg = calloc(nseg ? nseg : 1, sizeof *seg);
    for (size_t i = 0; i < nseg; i++) {
        for (int a = 0; a < 3; a++) {
            seg[i].org[a] = uniform01(&r);
            seg[i].power[a] = uniform01(&r);
        }
        random_unit(&r, seg[i].dir);
        seg[i].length = uniform01(&r);
    }
    char err[256] = "";
    pm_map *m = pm_map_new();
    cr_assert_eq(pm_map_set_origin(m, SAMPLE_ORIGIN, err, sizeof err), PM_OK, "%s", err);
    cr_assert_eq(pm_map_add_photons(m, ph, nph, err, sizeof err), PM_OK, "%s", err);
    cr_assert_eq(pm_map_add_segments(m, seg, nseg, err, sizeof err), PM_OK, "%s", err);
    snprintf(path, 256, "%s/%s", dir, name);
    cr_assert_eq(save_map(m, path, err, sizeof err), PM_OK, "%s", err);
    pm_map_free(m);
    free(ph);
    free(seg);
    return path;
}

/* ---------------------------------------------------------------------------------------- */
/* Queries against brute force                                                               */

Test(photonmap, knn_equals_brute_force)
{
    const size_t sizes[] = {1, 2, 7, 100, 1000, 5000};
    int cases = 0;
    for (int lattice = 0; lattice <= 1; lattice++) {
        for (int dups = 0; dups <= 1; dups++) {
            for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
                size_t n = sizes[s];
                pcg32 r = pcg32_seed(1000 + n, (uint64_t)(2 * lattice + dups));
                pm_photon *ph = random_photons(&r, n, lattice, dups);
                pm_map *m = build_map(ph, n);
                const int ks[] = {1, 3, 10, 64, (int)n, (int)n + 5};
                int idx[5100];
                float d2[5100];
                for (int j = 0; j < 30; j++) {
                    float q[3];
                    query_point(&r, ph, n, lattice, j, q);
                    hit *b = brute_sorted(ph, n, q);
                    for (size_t t = 0; t < sizeof ks / sizeof ks[0]; t++) {
                        int k = ks[t];
                        int want = k < (int)n ? k : (int)n;
                        int got = knn_f(m, q, k, idx, d2);
                        cr_assert_eq(got, want, "n=%zu k=%d: got %d", n, k, got);
                        for (int i = 0; i < got; i++) {
                            cr_assert_eq(idx[i], b[i].idx,
                                         "n=%zu lattice=%d dups=%d k=%d rank %d: idx %d != %d",
                                         n, lattice, dups, k, i, idx[i], b[i].idx);
                            cr_assert_eq(d2[i], b[i].d2, "n=%zu k=%d rank %d: d2 %.9g != %.9g",
                                         n, k, i, (double)d2[i], (double)b[i].d2);
                        }
                        cases++;
                    }
                    free(b);
                }
                pm_map_free(m);
                free(ph);
            }
        }
    }
    cr_assert_eq(cases, 4 * 6 * 30 * 6);
}

/* pm_map_spatial_order: NULL until built, then a permutation of the photons in which neighbours
 * lie near each other (what rd_beams_build lays its balls out by): consecutive photons in it
 * are on average far closer than in the order they were added (this seed's 5000 points over
 * the unit cube: 0.664 apart as added, 0.077 in the order, measured; the bound 0.25 of the first
 * fails an order that sorts along one axis alone, or none). */
Test(photonmap, spatial_order_is_a_permutation_that_keeps_neighbours_near)
{
    const size_t n = 5000;
    pcg32 r = pcg32_seed(77, 1);
    pm_photon *ph = random_photons(&r, n, 0, 0);
    pm_map *m = pm_map_new();
    char err[256];
    cr_assert(pm_map_add_photons(m, ph, n, err, sizeof err) == PM_OK, "%s", err);
    cr_expect(pm_map_spatial_order(m) == NULL, "an order before the build");
    cr_assert(pm_map_build(m, err, sizeof err) == PM_OK, "%s", err);
    const int *order = pm_map_spatial_order(m);
    cr_assert(order != NULL);
    char *seen = calloc(n, 1);
    cr_assert(seen != NULL);
    double d_order = 0.0, d_added = 0.0;
    for (size_t i = 0; i < n; i++) {
        cr_assert(order[i] >= 0 && (size_t)order[i] < n && !seen[order[i]], "entry %zu: %d", i, order[i]);
        seen[order[i]] = 1;
        if (i == 0) continue;
        const float *a = ph[order[i - 1]].pos, *b = ph[order[i]].pos, *c = ph[i - 1].pos, *e = ph[i].pos;
        d_order += sqrt(pow(a[0] - b[0], 2) + pow(a[1] - b[1], 2) + pow(a[2] - b[2], 2));
        d_added += sqrt(pow(c[0] - e[0], 2) + pow(c[1] - e[1], 2) + pow(c[2] - e[2], 2));
    }
    cr_expect(d_order < 0.25 * d_added, "mean step %.4f in the order, %.4f as added", d_order / (n - 1),
              d_added / (n - 1));
    cr_assert(pm_map_add_photons(m, ph, 1, err, sizeof err) == PM_OK, "%s", err);
    cr_expect(pm_map_spatial_order(m) == NULL, "an order after an add, before the next build");
    free(seen);
    pm_map_free(m);
    free(ph);
}

/* pm_map_order: the built map's order without its kd-tree (what nee+beams' passes after the
 * first take: rd_method.pass_maps, RD_PASS_NO_INDEX). The same permutation as pm_map_build's, no
 * query answered (k-NN and radius say not built), an add drops it, a build after it serves
 * queries; an empty map orders to NULL. */
Test(photonmap, order_alone_is_the_build_s_order_and_answers_no_query)
{
    const size_t n = 3000;
    pcg32 r = pcg32_seed(78, 1);
    pm_photon *ph = random_photons(&r, n, 0, 0);
    pm_map *a = pm_map_new(), *b = pm_map_new();
    char err[256];
    cr_assert(pm_map_add_photons(a, ph, n, err, sizeof err) == PM_OK, "%s", err);
    cr_assert(pm_map_add_photons(b, ph, n, err, sizeof err) == PM_OK, "%s", err);
    cr_assert(pm_map_build(a, err, sizeof err) == PM_OK, "%s", err);
    cr_assert(pm_map_order(b, err, sizeof err) == PM_OK, "%s", err);
    const int *oa = pm_map_spatial_order(a), *ob = pm_map_spatial_order(b);
    cr_assert(oa != NULL && ob != NULL);
    cr_expect(memcmp(oa, ob, n * sizeof *oa) == 0, "the order alone differs from the build's");
    const double x[3] = {0.5, 0.5, 0.5};
    int idx[8];
    float d2[8];
    cr_expect(pm_map_knn(b, x, 8, idx, d2) == -1, "an ordered map answered a k-NN query");
    cr_expect(pm_map_knn(a, x, 8, idx, d2) == 8);
    cr_assert(pm_map_add_photons(b, ph, 1, err, sizeof err) == PM_OK, "%s", err);
    cr_expect(pm_map_spatial_order(b) == NULL, "an order after an add");
    cr_assert(pm_map_build(b, err, sizeof err) == PM_OK, "%s", err);
    cr_expect(pm_map_knn(b, x, 8, idx, d2) == 8, "a build after the order answers");
    pm_map *e = pm_map_new();
    cr_expect(pm_map_order(e, err, sizeof err) == PM_OK && pm_map_spatial_order(e) == NULL, "an empty map's order");
    cr_expect(pm_map_order(NULL, err, sizeof err) == PM_ERR_ARG);
    pm_map_free(e);
    pm_map_free(a);
    pm_map_free(b);
    free(ph);
}

Test(photonmap, radius_equals_brute_force)
{
    const size_t sizes[] = {1, 7, 100, 2000};
    const float radii[] = {0.0f, 0.05f, 0.125f, 0.25f, 0.5f, 3.0f};
    /* 300 and 100000 lie above the query's first try of 257 (pm_query.c PM_STACK_K): a gather
     * that fills it is asked again with the whole cap */
    const int maxes[] = {1, 4, 50, 300, 100000};
    static int idx[100000];
    static float d2[100000];
    int nonempty = 0;
    for (int lattice = 0; lattice <= 1; lattice++) {
        for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
            size_t n = sizes[s];
            pcg32 r = pcg32_seed(2000 + n, (uint64_t)lattice);
            pm_photon *ph = random_photons(&r, n, lattice, 1);
            pm_map *m = build_map(ph, n);
            for (int j = 0; j < 20; j++) {
                float q[3];
                query_point(&r, ph, n, lattice, j, q);
                hit *b = brute_sorted(ph, n, q);
                for (size_t ri = 0; ri < sizeof radii / sizeof radii[0]; ri++) {
                    /* inclusive: every photon with dist2 <= r*r (lattice radii hit it exactly) */
                    float rr = radii[ri], r2 = rr * rr;
                    int inside = 0;
                    while (inside < (int)n && b[inside].d2 <= r2)
                        inside++;
                    for (size_t mi = 0; mi < sizeof maxes / sizeof maxes[0]; mi++) {
                        int want = inside < maxes[mi] ? inside : maxes[mi];
                        int got = radius_f(m, q, rr, maxes[mi], idx, d2);
                        cr_assert_eq(got, want, "n=%zu r=%g max=%d: got %d, want %d", n,
                                     (double)rr, maxes[mi], got, want);
                        for (int i = 0; i < got; i++) {
                            cr_assert_eq(idx[i], b[i].idx, "n=%zu r=%g rank %d", n, (double)rr,
                                         i);
                            cr_assert_eq(d2[i], b[i].d2);
                        }
                        nonempty += got > 0;
                    }
                }
                free(b);
            }
            pm_map_free(m);
            free(ph);
        }
    }
    cr_assert_gt(nonempty, 100); /* the comparison really compared something */
}

/* The radius boundary: dist2 == r^2 counts as inside, and photons just outside r (closer
 * than FLANN's rounding slack) never leak in even when more than `max` lie near r. */
Test(photonmap, radius_boundary_inclusive_and_exact)
{
    pm_photon ph[8];
    const float xs[8] = {0.5f, 0.6f, 1.000004f, 1.000005f, 5.0f, 6.0f, 1.0f, 7.0f};
    for (int i = 0; i < 8; i++)
        ph[i] = (pm_photon){{xs[i], 0, 0}, {0, 0, 1}, {1, 1, 1}};
    pm_map *m = build_map(ph, 6); /* without the photon at exactly 1 */
    float q[3] = {0, 0, 0}, d2[8];
    int idx[8];
    /* 2 inside r = 1, 2 in the thin shell just outside: max = 3 must still give 2 */
    cr_assert_eq(radius_f(m, q, 1.0f, 3, idx, d2), 2);
    cr_assert(idx[0] == 0 && idx[1] == 1);
    cr_assert_eq(radius_f(m, q, 1.0f, 1, idx, d2), 1);
    cr_assert_eq(radius_f(m, q, 1.0f, 8, idx, d2), 2);
    pm_map_free(m);
    m = build_map(ph, 8); /* now photon 6 sits exactly at distance 1 */
    cr_assert_eq(radius_f(m, q, 1.0f, 3, idx, d2), 3);
    cr_assert(idx[2] == 6 && d2[2] == 1.0f);
    cr_assert_eq(radius_f(m, q, 1.0f, 2, idx, d2), 2);
    cr_assert_eq(radius_f(m, q, 0.99999f, 8, idx, d2), 2);
    pm_map_free(m);
}

Test(photonmap, query_argument_errors)
{
    pcg32 r = pcg32_seed(5, 5);
    pm_photon *ph = random_photons(&r, 10, 0, 0);
    pm_map *m = pm_map_new();
    char err[256];
    cr_assert_eq(pm_map_add_photons(m, ph, 10, err, sizeof err), PM_OK);
    int idx[20];
    float d2[20], q[3] = {0.5f, 0.5f, 0.5f}, out[3];
    cr_assert_eq(knn_f(m, q, 3, idx, d2), -1, "not built must fail");
    cr_assert_eq(radius_f(m, q, 0.5f, 3, idx, d2), -1);
    cr_assert_eq(knn_batch_f(m, q, 1, 3, idx, d2, 1, err, sizeof err), PM_ERR_ARG);
    cr_assert_eq(pm_map_build(m, err, sizeof err), PM_OK);
    cr_assert_eq(knn_f(m, q, 0, idx, d2), -1);
    cr_assert_eq(knn_f(m, q, -2, idx, d2), -1);
    cr_assert_eq(knn_f(NULL, q, 3, idx, d2), -1);
    cr_assert_eq(radius_f(m, q, -1.0f, 3, idx, d2), -1);
    cr_assert_eq(radius_f(m, q, NAN, 3, idx, d2), -1);
    cr_assert_eq(radius_f(m, q, 1.0f, 0, idx, d2), -1);
    cr_assert_eq(density_f(m, q, 0, out), -1);
    cr_assert_eq(radiance_f(m, q, q, 3, NULL, NULL, out), -1);
    float qn[3] = {NAN, 0.0f, 0.0f};
    cr_assert_eq(knn_f(m, qn, 3, idx, d2), -1);
    cr_assert_eq(knn_batch_f(m, qn, 1, 3, idx, d2, 1, err, sizeof err), PM_ERR_ARG);
    cr_assert_not_null(strstr(err, "query 0"), "%s", err);
    cr_assert_eq(knn_f(m, q, 20, idx, d2), 10, "k > count returns count");
    /* adding photons invalidates the tree until the next build */
    cr_assert_eq(pm_map_add_photons(m, ph, 1, err, sizeof err), PM_OK);
    cr_assert_eq(knn_f(m, q, 3, idx, d2), -1);
    cr_assert_eq(pm_map_build(m, err, sizeof err), PM_OK);
    cr_assert_eq(knn_f(m, q, 20, idx, d2), 11);
    pm_map_free(m);
    free(ph);
}

Test(photonmap, add_rejects_non_finite_and_keeps_map)
{
    pcg32 r = pcg32_seed(6, 6);
    pm_photon *ph = random_photons(&r, 5, 0, 0);
    pm_map *m = pm_map_new();
    char err[256] = "";
    cr_assert_eq(pm_map_add_photons(m, ph, 2, err, sizeof err), PM_OK);
    ph[3].pos[1] = NAN;
    cr_assert_eq(pm_map_add_photons(m, ph, 5, err, sizeof err), PM_ERR_ARG);
    cr_assert_not_null(strstr(err, "photon 3"), "%s", err);
    cr_assert_not_null(strstr(err, "position"), "%s", err);
    cr_assert_eq(pm_map_photon_count(m), 2, "a rejected add must add nothing");
    ph[3].pos[1] = 0.5f;
    ph[4].power[2] = INFINITY;
    cr_assert_eq(pm_map_add_photons(m, ph, 5, err, sizeof err), PM_ERR_ARG);
    cr_assert_eq(pm_map_add_photons(NULL, ph, 5, err, sizeof err), PM_ERR_ARG);

    pm_segment sg = {{0, 0, 0}, {0, 0, 1}, 1.0f, {1, 1, 1}};
    cr_assert_eq(pm_map_add_segments(m, &sg, 1, err, sizeof err), PM_OK);
    sg.length = -1.0f;
    cr_assert_eq(pm_map_add_segments(m, &sg, 1, err, sizeof err), PM_ERR_ARG);
    cr_assert_not_null(strstr(err, "segment 0"), "%s", err);
    sg.length = 1.0f;
    sg.org[0] = NAN;
    cr_assert_eq(pm_map_add_segments(m, &sg, 1, err, sizeof err), PM_ERR_ARG);
    cr_assert_eq(pm_map_segment_count(m), 1);
    pm_map_free(m);
    free(ph);
}

Test(photonmap, bounds_and_memory)
{
    pcg32 r = pcg32_seed(7, 7);
    size_t n = 3000;
    pm_photon *ph = random_photons(&r, n, 0, 0);
    pm_map *m = build_map(ph, n);
    float lo[3], hi[3], elo[3], ehi[3];
    for (int a = 0; a < 3; a++) {
        elo[a] = ehi[a] = ph[0].pos[a];
        for (size_t i = 1; i < n; i++) {
            elo[a] = fminf(elo[a], ph[i].pos[a]);
            ehi[a] = fmaxf(ehi[a], ph[i].pos[a]);
        }
    }
    pm_map_bounds(m, lo, hi);
    for (int a = 0; a < 3; a++) {
        cr_assert_eq(lo[a], elo[a]);
        cr_assert_eq(hi[a], ehi[a]);
    }
    size_t mem = pm_map_memory_bytes(m);
    /* photons (36 B) + at least FLANN's reordered copy and our position array (24 B) */
    cr_assert_geq(mem, n * (36 + 24), "memory %zu", mem);
    cr_assert_lt(mem, n * 400, "memory %zu is implausibly large", mem);
    cr_assert_geq(pm_map_build_seconds(m), 0.0);
    cr_assert_eq(memcmp(pm_map_photons(m), ph, n * sizeof *ph), 0, "photons are copied as is");
    pm_map_free(m);
    free(ph);
}

/* ---------------------------------------------------------------------------------------- */
/* Estimates                                                                                  */

/* N photons uniform in the unit box, each of power P*(1, 2, 0.5): the photon density is
 * rho = N per m^3. The k-NN estimate k P / V_k (V_k = volume of the ball through the k-th
 * neighbour) has, for a binomial cloud and a ball inside the box, V_k ~ Beta(k, N-k+1), so
 *   E[k P / V_k]  = rho P k / (k - 1)
 *   std / mean    = 1 / sqrt(k - 2).
 * Query points on a 5^3 grid 0.15 apart in [0.2, 0.8]^3; their balls (r ~ 0.07 for k = 256)
 * do not overlap, so the estimates are (nearly) independent. We test each point at 4.5 sigma
 * and the mean over the 125 points at 4.5 sigma of the mean, 4.5/sqrt(125 (k-2)) = 2.5%. */
Test(photonmap, density_of_uniform_cloud)
{
    const size_t n = 200000;
    const int k = 256;
    const float P = 1e-3f, rgb[3] = {1.0f, 2.0f, 0.5f};
    pcg32 r = pcg32_seed(42, 3);
    pm_photon *ph = random_photons(&r, n, 0, 0);
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++)
            ph[i].power[a] = P * rgb[a];
    pm_map *m = build_map(ph, n);
    const double expect = (double)n * P * k / (k - 1.0); /* red channel, W m^-3 */
    const double rel_sd = 1.0 / sqrt(k - 2.0);
    double sum = 0.0;
    int count = 0;
    for (int i = 0; i < 5; i++)
        for (int j = 0; j < 5; j++)
            for (int l = 0; l < 5; l++) {
                float x[3] = {0.2f + 0.15f * i, 0.2f + 0.15f * j, 0.2f + 0.15f * l}, out[3];
                cr_assert_eq(density_f(m, x, k, out), k);
                cr_assert_lt(fabs(out[0] / expect - 1.0), 4.5 * rel_sd, "point (%d,%d,%d): %g vs %g",
                             i, j, l, (double)out[0], expect);
                /* channels scale with the photon power exactly (up to float rounding) */
                cr_assert_float_eq(out[1], 2.0f * out[0], 1e-5f * out[1]);
                cr_assert_float_eq(out[2], 0.5f * out[0], 1e-5f * out[1]);
                sum += out[0];
                count++;
            }
    double mean = sum / count;
    cr_assert_lt(fabs(mean / expect - 1.0), 4.5 * rel_sd / sqrt(count), "mean %g vs %g", mean,
                 expect);
    pm_map_free(m);
    free(ph);
}

/* Radiance with the isotropic phase 1/(4 pi) is the density over 4 pi: same k photons, same
 * volume, so they agree to float rounding (relative 1e-6). With HG (g = 0.7, strongly
 * forward) the estimate must equal the sum over the same k neighbours computed here. */
Test(photonmap, radiance_isotropic_and_hg)
{
    const size_t n = 20000;
    const int k = 50;
    pcg32 r = pcg32_seed(43, 4);
    pm_photon *ph = random_photons(&r, n, 0, 0);
    pm_map *m = build_map(ph, n);
    int idx[50];
    float d2[50];
    double g = 0.7;
    for (int j = 0; j < 40; j++) {
        float x[3], w[3], dens[3], iso[3], hg[3];
        for (int a = 0; a < 3; a++)
            x[a] = 0.1f + 0.8f * uniform01(&r);
        random_unit(&r, w);
        cr_assert_eq(density_f(m, x, k, dens), k);
        cr_assert_eq(radiance_f(m, x, w, k, p_iso, NULL, iso), k);
        for (int a = 0; a < 3; a++)
            cr_assert_float_eq(iso[a], dens[a] / (4.0 * PI), 1e-6 * dens[a]);

        cr_assert_eq(radiance_f(m, x, w, k, p_hg, &g, hg), k);
        cr_assert_eq(knn_f(m, x, k, idx, d2), k);
        double sum[3] = {0, 0, 0};
        for (int i = 0; i < k; i++) {
            const pm_photon *p = &ph[idx[i]];
            double c = (double)p->dir[0] * w[0] + (double)p->dir[1] * w[1] +
                       (double)p->dir[2] * w[2];
            for (int a = 0; a < 3; a++)
                sum[a] += p_hg(c, &g) * p->power[a];
        }
        double rk = sqrt((double)d2[k - 1]);
        double vol = 4.0 / 3.0 * PI * rk * rk * rk;
        for (int a = 0; a < 3; a++)
            cr_assert_float_eq(hg[a], sum[a] / vol, 1e-5 * sum[a] / vol, "query %d ch %d", j, a);
    }
    /* and HG really weighs directions: forward and backward differ for a beam of photons */
    pm_photon beam[64];
    for (int i = 0; i < 64; i++) {
        beam[i] = (pm_photon){{uniform01(&r), uniform01(&r), uniform01(&r)}, {0, 0, 1}, {1, 1, 1}};
    }
    pm_map *mb = build_map(beam, 64);
    float x[3] = {0.5f, 0.5f, 0.5f}, fwd[3] = {0, 0, 1}, back[3] = {0, 0, -1}, lf[3], lb[3];
    cr_assert_eq(radiance_f(mb, x, fwd, 64, p_hg, &g, lf), 64);
    cr_assert_eq(radiance_f(mb, x, back, 64, p_hg, &g, lb), 64);
    /* ratio p(1)/p(-1) = ((1+g)/(1-g))^3 for HG */
    cr_assert_float_eq(lf[0] / lb[0], pow((1 + g) / (1 - g), 3), 1e-4 * pow((1 + g) / (1 - g), 3));
    pm_map_free(mb);
    pm_map_free(m);
    free(ph);
}

/* ---------------------------------------------------------------------------------------- */
/* Batch and threads                                                                          */

Test(photonmap, batch_equals_single_and_thread_count)
{
    const size_t n = 20000, nq = 3000;
    pcg32 r = pcg32_seed(44, 5);
    pm_photon *ph = random_photons(&r, n, 0, 1);
    pm_map *m = build_map(ph, n);
    float *q = malloc(nq * 3 * sizeof(float));
    for (size_t j = 0; j < nq; j++)
        query_point(&r, ph, n, 0, (int)j, q + 3 * j);
    const int ks[] = {1, 16, 100};
    for (size_t t = 0; t < sizeof ks / sizeof ks[0]; t++) {
        int k = ks[t];
        int *i1 = malloc(nq * k * sizeof(int)), *i2 = malloc(nq * k * sizeof(int));
        float *d1 = malloc(nq * k * sizeof(float)), *d2 = malloc(nq * k * sizeof(float));
        char err[256] = "";
        cr_assert_eq(knn_batch_f(m, q, nq, k, i1, d1, 1, err, sizeof err), PM_OK, "%s", err);
        cr_assert_eq(knn_batch_f(m, q, nq, k, i2, d2, 2, err, sizeof err), PM_OK, "%s", err);
        cr_assert_eq(memcmp(i1, i2, nq * k * sizeof(int)), 0, "k=%d: 1 vs 2 threads differ", k);
        cr_assert_eq(memcmp(d1, d2, nq * k * sizeof(float)), 0);
        int si[100];
        float sd[100];
        for (size_t j = 0; j < nq; j++) {
            cr_assert_eq(knn_f(m, q + 3 * j, k, si, sd), k);
            cr_assert_eq(memcmp(si, i1 + j * k, k * sizeof(int)), 0, "k=%d query %zu", k, j);
            cr_assert_eq(memcmp(sd, d1 + j * k, k * sizeof(float)), 0);
        }
        free(i1);
        free(i2);
        free(d1);
        free(d2);
    }
    /* rows with fewer than k photons are padded with -1 / INFINITY */
    pm_map *small = build_map(ph, 5);
    int pi[3 * 8];
    float pd[3 * 8];
    char err[256];
    cr_assert_eq(knn_batch_f(small, q, 3, 8, pi, pd, 0, err, sizeof err), PM_OK);
    for (int j = 0; j < 3; j++)
        for (int c = 0; c < 8; c++) {
            if (c < 5) {
                cr_assert_geq(pi[j * 8 + c], 0);
            } else {
                cr_assert_eq(pi[j * 8 + c], -1);
                cr_assert(isinf(pd[j * 8 + c]));
            }
        }
    pm_map_free(small);
    pm_map_free(m);
    free(q);
    free(ph);
}

/* Single queries from several threads at once on one map give the serial answers (FLANN's
 * search is read-only; see the notes in photonmap.c). */
Test(photonmap, concurrent_single_queries)
{
    const size_t n = 20000;
    const int nq = 2000, k = 32;
    pcg32 r = pcg32_seed(45, 6);
    pm_photon *ph = random_photons(&r, n, 0, 1);
    pm_map *m = build_map(ph, n);
    float *q = malloc(nq * 3 * sizeof(float));
    for (int j = 0; j < nq; j++)
        query_point(&r, ph, n, 0, j, q + 3 * j);
    int *ser_i = malloc(nq * k * sizeof(int)), *par_i = malloc(nq * k * sizeof(int));
    float *ser_d = malloc(nq * 3 * sizeof(float)), *par_d = malloc(nq * 3 * sizeof(float));
    int *ser_n = malloc(nq * sizeof(int)), *par_n = malloc(nq * sizeof(int));
    float dd[32];
    for (int j = 0; j < nq; j++) {
        ser_n[j] = radius_f(m, q + 3 * j, 0.03f, k, ser_i + j * k, dd) +
                   1000 * density_f(m, q + 3 * j, k, ser_d + 3 * j);
    }
#pragma omp parallel for num_threads(2) schedule(dynamic, 7)
    for (int j = 0; j < nq; j++) {
        float d[32];
        par_n[j] = radius_f(m, q + 3 * j, 0.03f, k, par_i + j * k, d) +
                   1000 * density_f(m, q + 3 * j, k, par_d + 3 * j);
    }
    int nonempty = 0;
    for (int j = 0; j < nq; j++) {
        cr_assert_eq(par_n[j], ser_n[j], "query %d", j);
        int nr = ser_n[j] % 1000;
        cr_assert_eq(memcmp(par_i + j * k, ser_i + j * k, nr * sizeof(int)), 0, "query %d", j);
        cr_assert_eq(memcmp(par_d + 3 * j, ser_d + 3 * j, 3 * sizeof(float)), 0, "query %d", j);
        nonempty += nr > 0;
    }
    cr_assert_gt(nonempty, nq / 2);
    free(ser_i);
    free(par_i);
    free(ser_d);
    free(par_d);
    free(ser_n);
    free(par_n);
    free(q);
    pm_map_free(m);
    free(ph);
}

/* ---------------------------------------------------------------------------------------- */
/* Empty maps and NULL                                                                        */

Test(photonmap, free_null_and_empty_map)
{
    pm_map_free(NULL);
    pm_map *m = pm_map_new();
    char err[256] = "";
    cr_assert_eq(pm_map_build(m, err, sizeof err), PM_OK, "%s", err);
    float x[3] = {0, 0, 0}, w[3] = {0, 0, 1}, out[3] = {1, 1, 1}, d2[4];
    int idx[4];
    cr_assert_eq(pm_map_photon_count(m), 0);
    cr_assert_eq(knn_f(m, x, 4, idx, d2), 0);
    cr_assert_eq(radius_f(m, x, 1.0f, 4, idx, d2), 0);
    cr_assert_eq(density_f(m, x, 4, out), 0);
    cr_assert(out[0] == 0.0f && out[1] == 0.0f && out[2] == 0.0f);
    out[0] = 1;
    cr_assert_eq(radiance_f(m, x, w, 4, p_iso, NULL, out), 0);
    cr_assert_eq(out[0], 0.0f);
    cr_assert_eq(knn_batch_f(m, x, 1, 4, idx, d2, 2, err, sizeof err), PM_OK);
    cr_assert(idx[0] == -1 && idx[3] == -1 && isinf(d2[0]));
    float lo[3], hi[3];
    pm_map_bounds(m, lo, hi);
    cr_assert(lo[0] == 0.0f && hi[2] == 0.0f);
    pm_map_free(m);

    /* all photons at the query point: no volume, so no estimate (0 used) rather than inf */
    pm_photon same[3] = {{{1, 1, 1}, {0, 0, 1}, {1, 1, 1}}, {{1, 1, 1}, {0, 0, 1}, {1, 1, 1}},
                         {{1, 1, 1}, {0, 0, 1}, {1, 1, 1}}};
    pm_map *s = build_map(same, 3);
    float at[3] = {1, 1, 1};
    cr_assert_eq(density_f(s, at, 3, out), 0);
    cr_assert_eq(out[0], 0.0f);
    cr_assert_eq(knn_f(s, at, 2, idx, d2), 2);
    cr_assert(idx[0] == 0 && idx[1] == 1, "ties go to the lower index");
    pm_map_free(s);
}

/* ---------------------------------------------------------------------------------------- */
/* File format                                                                                */

Test(photonmap, save_load_round_trip_bit_exact)
{
    char dir[64], path[256], path0[256], err[256] = "";
    make_tmpdir(dir);
    const size_t nph = 1234, nseg = 321;
    save_sample(dir, "a.pmap", nph, nseg, path);
    size_t len;
    unsigned char *bytes = read_bytes(path, &len);
    cr_assert_eq(len, HDR + 8 + 36 * nph + 40 * nseg, "file size %zu", len);
    cr_assert_eq(memcmp(bytes, "PMAP", 4), 0);
    cr_assert_eq(bytes[4], 2, "format version 2");

    pm_map *m = NULL;
    cr_assert_eq(pm_map_load(&m, path, err, sizeof err), PM_OK, "%s", err);
    cr_assert_eq(pm_map_photon_count(m), nph);
    cr_assert_eq(pm_map_segment_count(m), nseg);
    /* the origin comes back bit for bit */
    double o[3];
    pm_map_origin(m, o);
    cr_assert_eq(memcmp(o, SAMPLE_ORIGIN, sizeof o), 0, "origin (%.17g, %.17g, %.17g)", o[0],
                 o[1], o[2]);
    /* the records are the little-endian floats, so on this host the file bytes equal memory */
    cr_assert_eq(memcmp(pm_map_photons(m), bytes + HDR, 36 * nph), 0);
    cr_assert_eq(memcmp(pm_map_segments(m), bytes + HDR + 36 * nph, 40 * nseg), 0);
    /* the loaded map is not built; after building it answers like the original, in world
     * coordinates: the nearest photon to origin + p_0 is photon 0 at distance 0 */
    const pm_photon *p0 = pm_map_photons(m);
    double x[3];
    for (int a = 0; a < 3; a++)
        x[a] = SAMPLE_ORIGIN[a] + (double)p0->pos[a];
    float d2[8];
    int idx[8];
    cr_assert_eq(pm_map_knn(m, x, 8, idx, d2), -1);
    cr_assert_eq(pm_map_build(m, err, sizeof err), PM_OK);
    cr_assert_eq(pm_map_knn(m, x, 8, idx, d2), 8);
    cr_assert(idx[0] == 0 && d2[0] == 0.0f, "nearest %d at %g", idx[0], d2[0]);
    /* saving again gives the same bytes */
    snprintf(path0, sizeof path0, "%s/b.pmap", dir);
    cr_assert_eq(save_map(m, path0, err, sizeof err), PM_OK, "%s", err);
    size_t len2;
    unsigned char *bytes2 = read_bytes(path0, &len2);
    cr_assert_eq(len2, len);
    cr_assert_eq(memcmp(bytes, bytes2, len), 0);
    pm_map_free(m);
    free(bytes2);
    unlink(path0);

    /* an empty map round-trips too */
    pm_map *e = pm_map_new();
    snprintf(path0, sizeof path0, "%s/empty.pmap", dir);
    cr_assert_eq(save_map(e, path0, err, sizeof err), PM_OK);
    pm_map_free(e);
    e = NULL;
    cr_assert_eq(pm_map_load(&e, path0, err, sizeof err), PM_OK, "%s", err);
    cr_assert_eq(pm_map_photon_count(e), 0);
    pm_map_free(e);

    /* a stream that cannot be written (a full disk: /dev/full) is an I/O error naming the file */
    pm_map *tiny = pm_map_new();
    FILE *full = fopen("/dev/full", "wb");
    cr_assert(full != NULL);
    cr_assert_eq(pm_map_write(tiny, full, "x.pmap", err, sizeof err), PM_ERR_IO);
    cr_assert_not_null(strstr(err, "x.pmap: write failed"), "%s", err);
    fclose(full);
    cr_assert_eq(pm_map_write(tiny, NULL, "x.pmap", err, sizeof err), PM_ERR_ARG);
    pm_map_free(tiny);

    unlink(path0);
    unlink(path);
    free(bytes);
    cr_assert_eq(rmdir(dir), 0, "temporary files left behind in %s", dir);
}

Test(photonmap, load_rejects_corrupt_files)
{
    char dir[64], path[256], bad[300];
    make_tmpdir(dir);
    const size_t nph = 50, nseg = 7;
    save_sample(dir, "good.pmap", nph, nseg, path);
    size_t len;
    unsigned char *good = read_bytes(path, &len);
    unsigned char *b = malloc(len + 16);
    snprintf(bad, sizeof bad, "%s/bad.pmap", dir);

    /* one flipped bit anywhere in the records or the checksum: checksum mismatch */
    /* ... or in the origin (bytes 24..47) */
    const size_t flips[] = {24, 31, 47, HDR, HDR + 1, HDR + 36 * 20 + 7, HDR + 36 * nph + 3,
                            len - 9, len - 8, len - 1};
    for (size_t i = 0; i < sizeof flips / sizeof flips[0]; i++) {
        memcpy(b, good, len);
        b[flips[i]] ^= 0x10;
        write_bytes(bad, b, len);
        expect_load_fails(bad, PM_ERR_FORMAT, "checksum");
    }
    /* a flipped bit in a count: the size no longer matches */
    memcpy(b, good, len);
    b[8] ^= 0x01;
    write_bytes(bad, b, len);
    expect_load_fails(bad, PM_ERR_FORMAT, "expected");

    /* truncated at several lengths */
    const size_t cuts[] = {1,  3,  4,   7,       8,       16,      23,     24,
                           31, 47, HDR, HDR + 7, HDR + 8, 100, len / 2, len - 8, len - 1};
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
        write_bytes(bad, good, cuts[i]);
        expect_load_fails(bad, PM_ERR_FORMAT, "truncated");
    }
    /* trailing garbage */
    memcpy(b, good, len);
    memset(b + len, 0xAB, 16);
    write_bytes(bad, b, len + 16);
    expect_load_fails(bad, PM_ERR_FORMAT, "trailing");

    /* wrong magic, wrong version */
    memcpy(b, good, len);
    memcpy(b, "PMAQ", 4);
    write_bytes(bad, b, len);
    expect_load_fails(bad, PM_ERR_FORMAT, "magic");
    memcpy(b, good, len);
    b[4] = 3;
    restamp_checksum(b, len);
    write_bytes(bad, b, len);
    expect_load_fails(bad, PM_ERR_FORMAT, "version 3");
    memcpy(b, good, len);
    b[4] = 0;
    restamp_checksum(b, len);
    write_bytes(bad, b, len);
    expect_load_fails(bad, PM_ERR_FORMAT, "version 0");

    /* huge counts in a tiny file: rejected before any allocation (ASan would catch a huge
     * malloc attempt as an allocation-size error) */
    memcpy(b, good, HDR + 8);
    memset(b + 8, 0xFF, 8); /* 2^64 - 1 photons */
    write_bytes(bad, b, HDR + 8);
    expect_load_fails(bad, PM_ERR_FORMAT, "photons");
    memcpy(b, good, HDR + 8);
    memset(b + 8, 0, 8);
    b[8 + 5] = 0x10; /* 2^44 photons (and 7 segments): 56 + 36 2^44 + 280 = 633 TB expected */
    write_bytes(bad, b, HDR + 8);
    expect_load_fails(bad, PM_ERR_FORMAT, "truncated: expected 633318697599312 bytes, found 56");

    /* a NaN with a valid checksum is still rejected */
    memcpy(b, good, len);
    const uint32_t qnan = 0x7FC00000u;
    memcpy(b + HDR + 36 * 3 + 4, &qnan, 4); /* photon 3, pos.y (little-endian host) */
    restamp_checksum(b, len);
    write_bytes(bad, b, len);
    expect_load_fails(bad, PM_ERR_FORMAT, "photon 3");
    memcpy(b, good, len);
    const uint32_t inf = 0x7F800000u;
    memcpy(b + HDR + 36 * nph + 40 * 2 + 24, &inf, 4); /* segment 2, length */
    restamp_checksum(b, len);
    write_bytes(bad, b, len);
    expect_load_fails(bad, PM_ERR_FORMAT, "segment 2");
    /* a NaN or infinite origin with a valid checksum */
    const uint64_t dnan = 0x7FF8000000000000ull, dinf = 0x7FF0000000000000ull;
    memcpy(b, good, len);
    memcpy(b + 24 + 8, &dnan, 8); /* origin y */
    restamp_checksum(b, len);
    write_bytes(bad, b, len);
    expect_load_fails(bad, PM_ERR_FORMAT, "origin");
    memcpy(b, good, len);
    memcpy(b + 24 + 16, &dinf, 8); /* origin z */
    restamp_checksum(b, len);
    write_bytes(bad, b, len);
    expect_load_fails(bad, PM_ERR_FORMAT, "origin");

    /* empty file, a directory, and a missing file */
    write_bytes(bad, b, 0);
    expect_load_fails(bad, PM_ERR_FORMAT, "empty");
    expect_load_fails(dir, PM_ERR_IO, "regular");
    char missing[300];
    snprintf(missing, sizeof missing, "%s/missing.pmap", dir);
    expect_load_fails(missing, PM_ERR_IO, "cannot open");

    /* the good file still loads (the test files above differ from it only as stated) */
    char err[256] = "";
    pm_map *m = NULL;
    cr_assert_eq(pm_map_load(&m, path, err, sizeof err), PM_OK, "%s", err);
    pm_map_free(m);

    unlink(bad);
    unlink(path);
    free(b);
    free(good);
    cr_assert_eq(rmdir(dir), 0, "temporary files left behind in %s", dir);
}

/* ---------------------------------------------------------------------------------------- */
/* The map origin: a scene far from the world origin                                          */

static double hg_phase(double c, void *user)
{
    double g = *(const double *)user, d = 1.0 + g * g - 2.0 * g * c;
    return (1.0 - g * g) / (4.0 * PI * d * sqrt(d));
}

Test(photonmap, radiance_far_from_origin_equals_near)
{
    /* The same photon set in a 1 m cube, once around the world origin and once around
     * C = (1e5 + 1/3, -1e5, 2e5) (the positions built in double as C + r, then stored relative
     * to the map origin C), queried at the same points (q and C + q). Float positions at 1e5 m
     * are 0.0078 m apart, a tenth of the k = 64 radius here, so storing world floats moved the
     * estimate by tens of percent; relative storage must agree to float precision relative to
     * the scene size.
     * Tolerance: (C + r) - C differs from r by at most ulp_double(2e5) = 3e-11 m, which can
     * move a float coordinate in [-0.5, 0.5] by one ulp (6e-8 m), so a photon or query point
     * moves by eps <= sqrt(3) 6e-8 = 1.04e-7 m and the k-th distance r_k by at most 2 eps;
     * V ~ r_k^3 then changes by 6 eps / r_k relative. Plus float rounding of the output (1e-7).
     * (A change of which photons are the k nearest would need a photon within 2 eps of the
     * k-th distance: with fixed seeds it does not happen here, and would fail the test.) */
    const size_t n = 20000;
    const double C[3] = {1.0e5 + 1.0 / 3.0, -1.0e5, 2.0e5};
    pcg32 r = pcg32_seed(91, 2);
    pm_photon *near = malloc(n * sizeof *near), *far = malloc(n * sizeof *far);
    cr_assert(near && far);
    for (size_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            double x = (double)uniform01(&r) - 0.5;
            near[i].pos[a] = (float)x;
            far[i].pos[a] = (float)((C[a] + x) - C[a]); /* world position, made relative */
            near[i].power[a] = far[i].power[a] = 0.5f + uniform01(&r);
        }
        random_unit(&r, near[i].dir);
        memcpy(far[i].dir, near[i].dir, sizeof near[i].dir);
    }
    char err[256] = "";
    pm_map *a = build_map(near, n);
    pm_map *b = pm_map_new();
    cr_assert_eq(pm_map_set_origin(b, C, err, sizeof err), PM_OK, "%s", err);
    cr_assert_eq(pm_map_add_photons(b, far, n, err, sizeof err), PM_OK, "%s", err);
    cr_assert_eq(pm_map_build(b, err, sizeof err), PM_OK, "%s", err);
    const int k = 64;
    double g = 0.5, worst = 0.0;
    for (int j = 0; j < 200; j++) {
        double q[3], qc[3];
        float w[3], la[3], lb[3], da[3], db[3], d2[64];
        int idx[64];
        for (int t = 0; t < 3; t++) {
            q[t] = 0.8 * ((double)uniform01(&r) - 0.5);
            qc[t] = C[t] + q[t];
        }
        random_unit(&r, w);
        cr_assert_eq(pm_map_radiance(a, q, w, k, hg_phase, &g, la), k);
        cr_assert_eq(pm_map_radiance(b, qc, w, k, hg_phase, &g, lb), k);
        cr_assert_eq(pm_map_density(a, q, k, da), k);
        cr_assert_eq(pm_map_density(b, qc, k, db), k);
        cr_assert_eq(pm_map_knn(b, qc, k, idx, d2), k);
        double rk = sqrt((double)d2[k - 1]);
        double tol = 6.0 * 1.04e-7 / rk + 1e-7;
        for (int c = 0; c < 3; c++) {
            double e1 = fabs(lb[c] - la[c]) / la[c], e2 = fabs(db[c] - da[c]) / da[c];
            cr_assert(e1 <= tol && e2 <= tol,
                      "query %d channel %d: radiance %.9g vs %.9g, density %.9g vs %.9g "
                      "(relative %.3g, %.3g > %.3g)", j, c, lb[c], la[c], db[c], da[c], e1, e2, tol);
            worst = fmax(worst, fmax(e1, e2));
        }
    }
    cr_log_info("far vs near: worst relative difference %.3g", worst);
    /* bounds come back in world coordinates, rounded outward to float */
    float lo[3], hi[3];
    pm_map_bounds(b, lo, hi);
    for (int t = 0; t < 3; t++)
        cr_assert(lo[t] <= C[t] - 0.49 && hi[t] >= C[t] + 0.49 && hi[t] - lo[t] < 1.05,
                  "axis %d: [%.9g, %.9g]", t, lo[t], hi[t]);
    pm_map_free(a);
    pm_map_free(b);
    free(near);
    free(far);
}

Test(photonmap, origin_is_set_before_records_and_finite)
{
    char err[256] = "";
    pm_map *m = pm_map_new();
    double o[3] = {7, 7, 7};
    pm_map_origin(m, o);
    cr_assert(o[0] == 0.0 && o[1] == 0.0 && o[2] == 0.0, "default origin is 0");
    const double bad[3] = {1.0, NAN, 0.0}, good[3] = {1.0, 2.0, 3.0};
    cr_assert_eq(pm_map_set_origin(m, bad, err, sizeof err), PM_ERR_ARG);
    cr_assert_not_null(strstr(err, "not finite"), "%s", err);
    cr_assert_eq(pm_map_set_origin(m, good, err, sizeof err), PM_OK, "%s", err);
    pm_photon p = {{0, 0, 0}, {0, 0, 1}, {1, 1, 1}};
    cr_assert_eq(pm_map_add_photons(m, &p, 1, err, sizeof err), PM_OK, "%s", err);
    cr_assert_eq(pm_map_set_origin(m, good, err, sizeof err), PM_ERR_ARG,
                 "moving the origin under stored photons must be refused");
    cr_assert_not_null(strstr(err, "before adding"), "%s", err);
    pm_map_origin(m, o);
    cr_assert(o[0] == 1.0 && o[1] == 2.0 && o[2] == 3.0);
    pm_map *s = pm_map_new();
    pm_segment sg = {{0, 0, 0}, {1, 0, 0}, 1.0f, {1, 1, 1}};
    cr_assert_eq(pm_map_add_segments(s, &sg, 1, err, sizeof err), PM_OK, "%s", err);
    cr_assert_eq(pm_map_set_origin(s, good, err, sizeof err), PM_ERR_ARG, "segments too");
    cr_assert_eq(pm_map_set_origin(NULL, good, err, sizeof err), PM_ERR_ARG);
    pm_map_free(m);
    pm_map_free(s);
}

Test(photonmap, version_1_file_loads_with_origin_zero)
{
    /* A version 1 file (docs/photonmap-format.md: 24-byte header, no origin) is the version 2
     * file without bytes 24..47, with version 1 and its own checksum. It loads with origin 0
     * and the same records; a truncated or corrupted version 1 file is still rejected. */
    char dir[64], path[256], v1[300], err[256] = "";
    make_tmpdir(dir);
    const size_t nph = 40, nseg = 5;
    save_sample(dir, "v2.pmap", nph, nseg, path);
    size_t len;
    unsigned char *good = read_bytes(path, &len);
    size_t len1 = len - 24;
    unsigned char *b = malloc(len1);
    memcpy(b, good, 24);
    memcpy(b + 24, good + HDR, len - HDR);
    b[4] = 1;
    restamp_checksum(b, len1);
    snprintf(v1, sizeof v1, "%s/v1.pmap", dir);
    write_bytes(v1, b, len1);
    pm_map *m = NULL;
    cr_assert_eq(pm_map_load(&m, v1, err, sizeof err), PM_OK, "%s", err);
    double o[3] = {1, 1, 1};
    pm_map_origin(m, o);
    cr_assert(o[0] == 0.0 && o[1] == 0.0 && o[2] == 0.0, "version 1: origin 0");
    cr_assert_eq(pm_map_photon_count(m), nph);
    cr_assert_eq(memcmp(pm_map_photons(m), good + HDR, 36 * nph), 0);
    cr_assert_eq(memcmp(pm_map_segments(m), good + HDR + 36 * nph, 40 * nseg), 0);
    pm_map_free(m);
    write_bytes(v1, b, len1 - 1);
    expect_load_fails(v1, PM_ERR_FORMAT, "truncated");
    write_bytes(v1, b, 30);
    expect_load_fails(v1, PM_ERR_FORMAT, "truncated");
    b[30] ^= 0x04;
    write_bytes(v1, b, len1);
    expect_load_fails(v1, PM_ERR_FORMAT, "checksum");
    unlink(v1);
    unlink(path);
    free(b);
    free(good);
    cr_assert_eq(rmdir(dir), 0, "temporary files left behind in %s", dir);
}
