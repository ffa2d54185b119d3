/* sh.h: real spherical harmonics, Legendre coefficients of phase functions, and the guide
 * grids of SH coefficients of in-scattered radiance baked from a photon map
 * (THEORY.md §4-5; seed 001 §3.1, §3.2, §3.4 and appendix A).
 *
 * This is the one public header of the sh/ module. sh/ depends on photonmap/ (its public API
 * only) and knows nothing of scenes: extinction, scattering coefficient and phase function
 * come in as parameters or callbacks.
 *
 * Conventions
 *   Bands      L = number of bands, l = 0..L-1, L^2 coefficients, index SH_INDEX(l, m) =
 *              l*l + l + m, m = -l..l. 1 <= L <= SH_MAX_BANDS.
 *   Basis      the standard orthonormal real basis, without the Condon-Shortley phase, i.e.
 *                Y_00 = 1/(2 sqrt(pi)),  (Y_1-1, Y_10, Y_11) = sqrt(3/(4 pi)) (y, z, x),
 *                Y_lm = sqrt(2) K_lm P_l^m(cos theta) cos(m phi)      m > 0
 *                Y_l0 = K_l0 P_l(cos theta)
 *                Y_lm = sqrt(2) K_l|m| P_l^|m|(cos theta) sin(|m| phi)  m < 0
 *              with K_lm = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!), theta measured from +z and phi
 *              from +x toward +y. Integral over the sphere of Y_i Y_j = delta_ij.
 *   Phase      p(mu) = sum_l (2l+1)/(4 pi) b_l P_l(mu), mu = w'.w (w' = direction light
 *              travels before scattering, w = after), b_l = 2 pi int_{-1}^{1} p P_l dmu; for
 *              Henyey-Greenstein b_l = g^l. Addition theorem (THEORY.md §4):
 *                p(w'.w) ~= p_L(w'.w) = sum_{l<L} b_l sum_m Y_lm(w') Y_lm(w).
 *   Coefficients of a cell (THEORY.md §4; seed 001 eq. of §3.2 and appendix A):
 *                c_lm = (1/|V|) sum_k dPhi_k b_l Y_lm(w'_k)       (k-NN bake)
 *              so that f(w) = sum_lm c_lm Y_lm(w) ~= sigma_s L_s(x, w) [W m^-3 sr^-1], the
 *              photon-map radiance estimate with the truncated phase p_L. Stored per RGB
 *              channel, channel-major: coeffs[c * L^2 + SH_INDEX(l, m)], c = 0 (R), 1, 2 (B),
 *              as float, 3 L^2 floats per cell. A camera ray with direction d evaluates
 *              toward w = -d (light travels toward the camera).
 *   Guide value the scalar a PDF uses: sh_eval_guide() = mean over R, G, B of max(0, f_c(w))
 *              (truncation rings make f negative for strongly peaked phase functions;
 *              clamping each channel at 0 keeps the value a valid, non-negative density).
 *
 * Errors: functions return sh_status; when `err` is non-NULL a one-line message (naming the
 * file or parameter) is written into it, at most errlen bytes, always NUL-terminated. Nothing
 * prints, nothing exits. Ownership: every _new/_bake/_load result has a _free; _free(NULL) is
 * safe. No mutable globals: precomputed tables live in sh_basis values or in the guide.
 * Threads: every const function is safe to call from many threads on the same guide.
 */
#ifndef SH_H
#define SH_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "photonmap.h"
#include "walk.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SH_MAX_BANDS 16
#define SH_MAX_COEFFS (SH_MAX_BANDS * SH_MAX_BANDS)
#define SH_INDEX(l, m) ((l) * (l) + (l) + (m))
#define SH_CHANNELS 3

typedef enum {
    SH_OK = 0,
    SH_ERR_ARG,      /* bad argument (NULL, bands out of range, NaN, inverted box, ...) */
    SH_ERR_NOMEM,    /* allocation failed (or the requested grid exceeds max_cells) */
    SH_ERR_IO,       /* open/read/write/rename failed */
    SH_ERR_FORMAT,   /* file is not a guide, wrong version, truncated, corrupt, bad checksum */
    SH_ERR_PHOTONMAP, /* a photon-map query failed (map not built, ...) */
    SH_ERR_CANCELLED  /* the caller's cancel flag stopped the work (sh_bake_params.cancel) */
} sh_status;

/* Short English name of a status ("ok", "bad argument", ...). Static storage. */
const char *sh_status_name(sh_status s);

/* ------------------------------------------------------------------------------------------
 * 1. Real spherical harmonics
 * ------------------------------------------------------------------------------------------ */

/* Recurrence constants for the normalised associated-Legendre recurrence, for up to `bands`
 * bands. Open value type (about 4 KiB); fill with sh_basis_init, then evaluate as often as
 * needed (e.g. once per camera ray). Read-only after init, shareable between threads. */
typedef struct {
    int bands;
    double a[SH_MAX_COEFFS]; /* a[SH_INDEX(l, m)] for m >= 0, l >= m + 2 (see sh_math.c) */
    double b[SH_MAX_COEFFS];
    double mm[SH_MAX_BANDS]; /* sqrt((2m+1)/(2m)) chain factors */
} sh_basis;

/* Fill `basis` for 1 <= bands <= SH_MAX_BANDS. Returns SH_ERR_ARG otherwise. */
sh_status sh_basis_init(sh_basis *basis, int bands);

/* All L^2 values Y_lm(w) of unit direction w into y[SH_INDEX(l, m)], by the associated-Legendre
 * recurrence in z = cos theta and the (x + i y)^m recurrence for cos/sin(m phi) sin^m theta:
 * no trigonometric calls at all. w need not be exactly unit; it is normalised (w = 0 gives
 * the values for +z). */
void sh_basis_eval(const sh_basis *basis, const double w[3], double *y);
void sh_basis_evalf(const sh_basis *basis, const double w[3], float *y);

/* Convenience without a table (computes the recurrence constants on the fly, slower). */
void sh_eval_basis(int bands, const double w[3], double *y);

/* ------------------------------------------------------------------------------------------
 * 2. Legendre polynomials, quadrature, phase-function coefficients
 * ------------------------------------------------------------------------------------------ */

/* P_l(x) by the three-term recurrence. */
double sh_legendre(int l, double x);
/* P_0(x)..P_{n-1}(x) into p[0..n-1]. */
void sh_legendre_all(int n, double x, double *p);

/* Gauss-Legendre rule of n points on [-1, 1] (Newton iteration on P_n; exact for polynomials of
 * degree <= 2n - 1). nodes ascending. 1 <= n <= 4096. */
sh_status sh_gauss_legendre(int n, double *nodes, double *weights);

/* Phase-function callback: p(mu) [1/sr], mu = w'.w in [-1, 1]. Same shape as pm_phase_fn. */
typedef double (*sh_phase_fn)(double mu, void *user);

/* Henyey-Greenstein value (THEORY.md §1) and its Legendre coefficients b_l = g^l, l < bands. */
double sh_phase_hg(double mu, double g);
sh_status sh_phase_coeffs_hg(double g, int bands, double *b);

/* b_l = 2 pi int_{-1}^{1} p(mu) P_l(mu) dmu for l < bands, of any phase function given as a
 * callback, by adaptive composite Gauss-Legendre quadrature (20-point panels, bisected until
 * every b_l agrees to 1e-12 between a panel and its halves), so a peaked phase function
 * (HG g = 0.99) is integrated as accurately as a smooth one. */
sh_status sh_phase_coeffs(sh_phase_fn phase, void *user, int bands, double *b, char *err,
                          size_t errlen);

/* The truncated phase p_L(mu) = sum_{l<bands} (2l+1)/(4 pi) b_l P_l(mu). */
double sh_phase_truncated(const double *b, int bands, double mu);

/* Hann window for a band-limited zonal kernel: w_l = (1 + cos(pi l / bands)) / 2, l < bands,
 * to multiply into b_l. Truncating HG at g = 0.85 to 4 bands rings to -0.064/sr at 90 degrees
 * (true value +0.0098) and to 20% of the peak below zero overall; with the window the kernel
 * gives +0.0077 at 90 degrees and dips at most 1.3% of its peak below zero, at the price of a
 * lower forward peak (Sloan 2008, "Stupid spherical harmonics tricks", windowing). w_0 = 1, so
 * the fluence (l = 0) is unchanged. Returns SH_ERR_ARG for bands outside 1..SH_MAX_BANDS. */
sh_status sh_window_hann(int bands, double *w);

/* ------------------------------------------------------------------------------------------
 * 3. Projection and evaluation of one cell's coefficients
 * ------------------------------------------------------------------------------------------ */

/* Add one photon to RGB coefficients (3 L^2, channel-major, doubles):
 *   c[ch][lm] += scale * power[ch] * b_l * Y_lm(w_prime)
 * (scale = 1/|V| for the k-NN estimate; THEORY.md §4). y = sh_basis_eval(w_prime). */
void sh_project_add(int bands, const double *b, const double *y, const double power[3],
                    double scale, double *coeffs);

/* f_c(w) = sum_lm c[ch][lm] y[lm] for the three channels (no clamping), y = Y(w). */
void sh_eval_rgb(int bands, const float *coeffs, const float *y, float out[3]);
/* Same, each channel clamped at 0 (truncation rings). */
void sh_eval_rgb_clamped(int bands, const float *coeffs, const float *y, float out[3]);
/* The scalar a PDF uses: (1/3) sum_ch max(0, f_ch(w)). Never negative. */
float sh_eval_guide(int bands, const float *coeffs, const float *y);
/* The same scalar from the first `use` bands (1 <= use <= bands) of coefficients stored with
 * `bands` bands (channel stride bands^2): the band-limited guide sum_{l<use} c_lm Y_lm(w), y
 * needing only use^2 entries. A guide read for sampling decisions only, where any positive
 * function keeps the estimate unbiased, trades directional detail for cost this way. */
float sh_eval_guide_bands(int bands, int use, const float *coeffs, const float *y);

/* ------------------------------------------------------------------------------------------
 * 4. Guide grids
 * ------------------------------------------------------------------------------------------ */

typedef enum { SH_GRID_UNIFORM = 0, SH_GRID_ADAPTIVE = 1 } sh_grid_kind;
typedef enum {
    SH_BAKE_KNN = 0,  /* k nearest photons at the cell centre (seed 001 §3.1) */
    SH_BAKE_TRACK = 1 /* photon path segments, exact overlap lengths (THEORY.md §3) */
} sh_bake_method;

/* sigma_t(x) [1/m] at a point, for the cell-mean extinction. */
typedef double (*sh_scalar_field_fn)(const double x[3], void *user);
/* sigma_s(x) RGB [1/m] at a point, for the track-length bake. */
typedef void (*sh_rgb_field_fn)(const double x[3], void *user, double out[3]);
/* Phase Legendre coefficients b[0..bands-1] valid at x (media with position-dependent phase). */
typedef void (*sh_phase_at_fn)(const double x[3], void *user, double *b);

typedef struct {
    sh_grid_kind kind;     /* default SH_GRID_UNIFORM */
    sh_bake_method method; /* default SH_BAKE_KNN */
    int bands;             /* L, default 4 (16 coefficients, seed 001 §4) */
    /* Box [m], lo < hi on every axis. All six zero (the default) selects the bounds of the
     * photons (or, with no photons, of the segment end points), padded by 1e-4 of the
     * largest extent. */
    double lo[3], hi[3];
    int k;         /* photons per estimate n (k-NN), default 50 */
    double lambda; /* grid quality (seed 001 §3.1), default 1 */
    /* Uniform grid: explicit resolution; all zero (default) selects the rule (THEORY.md §5)
     *   n_a = max(1, round(l_a (lambda N / (n l_x l_y l_z))^(1/3))),
     * N = stored photons (segments if there are no photons), n = k. */
    int res[3];
    size_t max_cells; /* refuse (SH_ERR_NOMEM) grids with more cells; default 1 << 24 */
    /* Adaptive grid (docs/guide-grid.md, "split rule"): a node is split while it holds more
     * than split_photons photons and its longest edge is >= 2 min_cell, or while its longest
     * edge exceeds max_cell; never deeper than max_depth. Every axis whose edge exceeds half
     * the node's longest edge is halved, so cells stay within aspect ratio 2. */
    int split_photons; /* 0 (default) => ceil(k / lambda), the uniform rule's photons per cell */
    double min_cell;   /* [m]; 0 (default) => longest box edge / 2^max_depth */
    double max_cell;   /* [m]; 0 (default) => longest box edge / 4 */
    int max_depth;     /* default 12, at most 20 */
    /* Phase function: Legendre coefficients b_0..b_{bands-1}; default isotropic {1, 0, ...}.
     * Fill with sh_phase_coeffs_hg or sh_phase_coeffs. If phase_at is non-NULL it overrides
     * phase_b per cell, evaluated at the cell centre. */
    double phase_b[SH_MAX_BANDS];
    sh_phase_at_fn phase_at;
    void *phase_user;
    /* Cell-mean extinction: average of sigma_t at s^3 stratified, jittered points (fixed
     * hash of the cell index, so the bake is deterministic); s = sigma_t_samples, default 2.
     * NULL => sigma_t = 0 in every cell. */
    sh_scalar_field_fn sigma_t;
    void *sigma_t_user;
    int sigma_t_samples;
    /* Track-length bake: sigma_s evaluated at the midpoint of each segment-cell overlap.
     * NULL => 1 (the coefficients are then of the fluence-weighted phase, W m^-2 sr^-1). */
    sh_rgb_field_fn sigma_s;
    void *sigma_s_user;
    int threads; /* OpenMP threads, 0 (default) = all. The result does not depend on it. */
    /* Non-NULL: read between work units (16 cells, k-NN; one region, track); once it is
     * non-zero the bake stops within them and returns SH_ERR_CANCELLED, no guide. Default NULL. */
    const volatile int *cancel;
    /* The callbacks (sigma_t, sigma_s, phase_at) are called from several threads at once and
     * must be thread-safe (pure functions of x and a read-only user pointer). */
} sh_bake_params;

/* Defaults as documented above. */
void sh_bake_params_default(sh_bake_params *p);

typedef struct sh_guide sh_guide; /* opaque */

/* Bake a guide from a built photon map (pm_map_build done; the track bake reads
 * pm_map_segments and needs no index). The map is only read and may be freed afterwards.
 *   k-NN   (seed 001 §3.1-3.2, THEORY.md §5): at each cell centre x the k nearest photons,
 *          r = distance to the k-th (the farthest found if fewer), |V| = (4/3) pi r^3,
 *          c_lm = (1/|V|) sum dPhi_k b_l Y_lm(w'_k).  No photon found => c = 0.
 *   track  (THEORY.md §3, seed 004): every segment deposits sigma_s(x_mid) dPhi l_cell b_l
 *          Y_lm(w') / |V_cell| into every cell it crosses (l_cell = exact overlap length).
 * Parallel over cells (k-NN) or over fixed spatial regions (track) with OpenMP; the result is
 * bit-identical for any thread count. */
sh_status sh_guide_bake(sh_guide **out, const pm_map *map, const sh_bake_params *params,
                        char *err, size_t errlen);
void sh_guide_free(sh_guide *g);
/* A copy of g that keeps only the first `bands` SH bands of every cell (1 <= bands <=
 * sh_guide_bands(g)): the same cells, extinctions and provenance, 3 bands^2 floats a cell.
 * Reading bands l < `bands` from it gives the same floats as reading them from g (the
 * coefficients are copied, not recomputed); a reader that uses only those bands touches
 * bands^2 / L^2 of the memory (guided-unbiased's flights and vertices read 2 of 8 bands: the
 * cell records were its cache misses). Free with sh_guide_free. */
sh_status sh_guide_truncate(const sh_guide *g, int bands, sh_guide **out, char *err, size_t errlen);

/* Read access. Cell ids are 0..cell_count-1: uniform cells x-fastest (i + nx (j + ny k)),
 * adaptive leaves in depth-first order. Coefficient pointers stay valid until _free. */
int sh_guide_bands(const sh_guide *g);
sh_grid_kind sh_guide_kind(const sh_guide *g);
size_t sh_guide_cell_count(const sh_guide *g);
void sh_guide_box(const sh_guide *g, double lo[3], double hi[3]);
const float *sh_guide_cell_coeffs(const sh_guide *g, size_t cell); /* 3 L^2 floats */
float sh_guide_cell_sigma_t(const sh_guide *g, size_t cell);
void sh_guide_cell_bounds(const sh_guide *g, size_t cell, double lo[3], double hi[3]);
int sh_guide_cell_depth(const sh_guide *g, size_t cell); /* octree depth; 0 for uniform */
/* Cell containing x (half-open cells [lo, hi), the box's upper faces included), -1 outside. */
long sh_guide_locate(const sh_guide *g, const double x[3]);
/* The guide's SH table (bands = sh_guide_bands): evaluate Y(-d) once per ray with it. */
const sh_basis *sh_guide_basis(const sh_guide *g);
/* f(w) at point x, RGB, unclamped (0 outside the box): a piecewise-constant lookup. */
void sh_guide_eval(const sh_guide *g, const double x[3], const double w[3], float out[3]);

typedef struct {
    sh_grid_kind kind;
    sh_bake_method method;
    int bands;
    int res[3];          /* uniform: cells per axis; adaptive: the finest level's equivalent */
    int depth_max;       /* adaptive: deepest leaf; uniform 0 */
    size_t cells;        /* cells (uniform) or leaves (adaptive) */
    size_t nodes;        /* adaptive: octree nodes including leaves; uniform 0 */
    size_t memory_bytes; /* guide object total */
    double bake_seconds; /* wall time of the bake (0 for a loaded guide unless stored) */
    size_t photons;      /* photons (k-NN) or segments (track) the bake used */
    int k;
    double lambda;
    double cell_min, cell_max; /* smallest / largest longest-edge of a cell [m] */
} sh_guide_stats;
void sh_guide_stats_get(const sh_guide *g, sh_guide_stats *st);

/* --- Ray iterator over either grid kind (DESIGN.md convention 7) -------------------------
 *
 *     const int L = sh_guide_bands(g);
 *     const double w[3] = {-d[0], -d[1], -d[2]};     light travels toward the camera
 *     float y[SH_MAX_COEFFS];
 *     sh_basis_evalf(sh_guide_basis(g), w, y);       once per ray
 *     sh_guide_ray it;  sh_guide_seg seg;
 *     sh_guide_ray_begin(g, o, d, tmin, tmax, &it);
 *     while (sh_guide_ray_next(&it, &seg)) {
 *         float f = sh_eval_guide(L, seg.coeffs, y);  histogram height on [seg.t0, seg.t1)
 *         ... seg.sigma_t for the transmittance estimate T~ (THEORY.md §6) ...
 *     }
 *
 * Ray x(t) = o + t d (d need not be unit; t is in units of |d|). The segments returned tile
 * [max(tmin, t_enter), min(tmax, t_exit)] of the box exactly, in increasing t, t0 of one
 * segment equal to t1 of the previous, each t1 > t0 (zero-length crossings at corners are
 * skipped). A ray missing the box returns no segment. Uniform grids: 3D-DDA (Amanatides-Woo)
 * with boundary parameters recomputed from the plane position of the axis crossed (no drift);
 * adaptive: neighbour stepping, descending from the root at each step with the crossed
 * plane snapped exactly, so rounding can never send the walk back. Value type, no
 * allocation; the fields are private. The guide must outlive the iterator. */
typedef struct {
    double t0, t1;        /* segment along the ray, t0 < t1 */
    const float *coeffs;  /* the cell's 3 L^2 coefficients (channel-major) */
    float sigma_t;        /* cell-mean extinction [1/m] */
    long cell;            /* cell id */
} sh_guide_seg;

typedef struct {
    /* private: the walk itself (walk/walk.h), stepped in place */
    const sh_guide *g;
    int done;
    union {
        wk_dda grid;       /* uniform */
        wk_tree_walk tree; /* adaptive */
    } w;
} sh_guide_ray;

void sh_guide_ray_begin(const sh_guide *g, const double o[3], const double d[3], double tmin,
                        double tmax, sh_guide_ray *it);
int sh_guide_ray_next(sh_guide_ray *it, sh_guide_seg *seg);

/* --- Slice images --------------------------------------------------------------------------
 * Sample the plane x[axis] = coord of the box on a width x height pixel raster (pixel centres
 * spanning the box) into out (width*height*3 floats, row-major, row 0 at the top). In-plane
 * axes (u right, v up): axis 0 (x): (y, z); axis 1 (y): (x, z); axis 2 (z): (x, y).
 * what = SH_SLICE_RADIANCE: f(w) RGB clamped at 0 [W m^-3 sr^-1] toward w (THEORY.md §4);
 *        SH_SLICE_GUIDE: sh_eval_guide in all three channels; SH_SLICE_SIGMA_T: cell-mean
 *        extinction; SH_SLICE_DEPTH: octree depth of the cell (uniform: 0), for seeing the
 *        adaptive refinement. */
typedef enum {
    SH_SLICE_RADIANCE = 0,
    SH_SLICE_GUIDE = 1,
    SH_SLICE_SIGMA_T = 2,
    SH_SLICE_DEPTH = 3
} sh_slice_what;
sh_status sh_guide_slice(const sh_guide *g, int axis, double coord, const double w[3],
                         sh_slice_what what, int width, int height, float *out, char *err,
                         size_t errlen);

/* --- Files (format in docs/guide-grid.md) --------------------------------------------------
 * Magic "SHGUIDE\0", version, kind, method, bands, box, resolution / octree nodes, cell
 * coefficients and extinctions, FNV-1a 64 checksum; little-endian. sh_guide_write writes the
 * file to the stream f (opened for binary writing by the caller, who closes it; the renderer
 * writes through a temporary name and a rename) and flushes it; a failed write is SH_ERR_IO
 * naming `name` (the file's name for messages). Load rejects a wrong magic or version, truncation, trailing bytes,
 * absurd sizes, a malformed octree, non-finite values and checksum mismatches with
 * SH_ERR_FORMAT and a one-line message naming the file. */
sh_status sh_guide_write(const sh_guide *g, FILE *f, const char *name, char *err, size_t errlen);
sh_status sh_guide_load(sh_guide **out, const char *path, char *err, size_t errlen);

#ifdef __cplusplus
}
#endif
#endif /* SH_H */
