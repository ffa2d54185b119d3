/* rd_guide_pdf.h: the per-ray histogram PDF that guided ray marching samples distances from
 * (THEORY.md §6; seed 001 §3.3 eq. 16-17). Internal to renderer/ (tests include it too).
 *
 * For one camera ray x(t) = o + t d, t in the medium interval [tmin, tmax], the guide grid gives
 * segments [t_j, t_{j+1}) with a non-negative guide value f_j (sh_eval_guide toward -d) and a
 * cell-mean extinction sigma_j. Seed 001 eq. 16 (THEORY.md §6):
 *
 *   h(t)     = T~(0,t) f_j                         t in [t_j, t_{j+1})
 *   T~(0,t)  = exp(-tau_j - sigma_j (t - t_j)),    tau_j = sum_{k<j} sigma_k (t_{k+1} - t_k)
 *   H_j      = integral of h over [t_0, t_j)       (prefix sums; per segment in closed form
 *              f_j T~(0,t_j) (1 - exp(-sigma_j dt_j)) / sigma_j, -> f_j T~ dt_j as sigma -> 0)
 *   I_ray    = integral of h over [tmin, tmax]
 *
 * and the sampled density is the defensive mixture
 *
 *   p(t) = (1 - alpha) h(t) / I_ray + alpha / (tmax - tmin)     (p = uniform if I_ray == 0),
 *
 * with cumulative P(t); samples are t = P^-1(u), inverted on the mixture CDF itself so that a
 * stratified set u_n = (n + u) / N goes through one monotone map.
 *
 * Storage: the caller provides the segment array (rd_guide_pdf_init); nothing here allocates.
 * Segments tile [tmin, tmax] exactly: the guide's own segments with their exact bounds (merged
 * with nothing), plus at most one leading and one trailing filler segment (f = 0, sigma = 0,
 * cell = -1) where the medium interval sticks out of the guide box. A ray therefore needs at
 * most (guide cells crossed) + 2 entries; a uniform nx x ny x nz grid is crossed in at most
 * nx + ny + nz - 2 cells. Value type: copy it freely while the storage lives. Read-only after a
 * build, so threads may sample one pdf concurrently. No globals. */
#ifndef RD_GUIDE_PDF_H
#define RD_GUIDE_PDF_H

#include "renderer.h"
#include "sh.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double t0, t1; /* [t0, t1), t0 < t1 (scene units along d) */
    double f;      /* guide value f_j >= 0 [W m^-3 sr^-1 for a baked guide; any unit] */
    double sigma;  /* extinction estimate sigma_j >= 0 [1/m] */
    double tau0;   /* optical depth of T~ at t0: sum of sigma_k dt_k over earlier segments */
    double H0;     /* integral of h over [tmin, t0) (prefix sum) */
    double C0;     /* mixture CDF P(t0) */
    long cell;     /* guide cell id, -1 for a filler segment or a plain-array build */
} rd_gpdf_seg;

typedef struct {
    rd_gpdf_seg *seg; /* caller-owned storage of cap entries */
    int cap;
    int n;            /* segments in use; 0 = empty pdf (tmax <= tmin) */
    int needed;       /* after a build that ran out of room: the entries it would have needed */
    int last;         /* last segment with positive probability (sampling never goes beyond) */
    double tmin, tmax;
    double alpha;     /* defensive weight actually used: the requested one, or 1 if I == 0 */
    double I;         /* I_ray = integral of h over [tmin, tmax] */
} rd_guide_pdf;

/* Attach caller storage (cap >= 1 entries); the pdf is empty until built. */
void rd_guide_pdf_init(rd_guide_pdf *pdf, rd_gpdf_seg *storage, int cap);

/* Build from a guide grid and a ray: o, d (d unit: t in metres), medium interval [tmin, tmax],
 * defensive weight alpha in [0, 1]. Walks sh_guide_ray over [tmin, tmax]; f_j =
 * sh_eval_guide(L, coeffs, Y(-d)), sigma_j = seg.sigma_t. tmax <= tmin gives an empty pdf.
 * Errors (pdf left empty, message in err when err != NULL): RD_ERR_ARG for NULL, non-finite or
 * alpha out of range; RD_ERR_NOMEM when the storage is too small (pdf->needed then says how many
 * entries this ray needs). */
rd_status rd_guide_pdf_build_guide(rd_guide_pdf *pdf, const sh_guide *g, const double o[3],
                                   const double d[3], double tmin, double tmax, double alpha,
                                   char *err, size_t errlen);
/* The same with the guide read through its first basis->bands bands only (basis->bands <=
 * the guide's; sh_eval_guide_bands): f_j = the band-limited guide toward -d. NULL basis: all
 * of them, as rd_guide_pdf_build_guide. */
rd_status rd_guide_pdf_build_guide_bands(rd_guide_pdf *pdf, const sh_guide *g,
                                         const sh_basis *basis, const double o[3],
                                         const double d[3], double tmin, double tmax,
                                         double alpha, char *err, size_t errlen);

/* Build from plain arrays: n >= 0 segments with bounds t[0..n] (strictly increasing,
 * tmin <= t[0], t[n] <= tmax), heights f[0..n-1] >= 0 and extinctions sigma[0..n-1] >= 0, all
 * finite. For tests and for guides other than sh_guide. Errors as above. */
rd_status rd_guide_pdf_build(rd_guide_pdf *pdf, int n, const double *t, const double *f,
                             const double *sigma, double tmin, double tmax, double alpha,
                             char *err, size_t errlen);

/* h(t) = T~(0,t) f_j (unnormalised, eq. 16); 0 outside [tmin, tmax]. */
double rd_guide_pdf_h(const rd_guide_pdf *pdf, double t);
/* p(t) of the mixture [1/m]; 0 outside [tmin, tmax] and for an empty pdf. */
double rd_guide_pdf_eval(const rd_guide_pdf *pdf, double t);
/* P(t) = integral of p over [tmin, t], clamped to [0, 1]. */
double rd_guide_pdf_cdf(const rd_guide_pdf *pdf, double t);

/* t = P^-1(u), u in [0, 1) (clamped; u >= 1 acts as the largest double below 1, so a sample
 * never sits where T~ has underflowed), and *p = p(t) if p != NULL (the density of the
 * segment sampled, at the unrounded offset inside it). Binary search of the segment
 * by its CDF at t_j, then inside the segment the exponential is inverted in closed form (alpha
 * = 0), the uniform linearly (alpha = 1 or f_j = 0), and their sum by bracketed Newton to
 * ~1e-15 relative. Empty pdf: returns tmin, *p = 0. */
double rd_guide_pdf_sample(const rd_guide_pdf *pdf, double u, double *p);

/* Optical depth of the guide's cheap extinction over the whole interval: T~(tmin, tmax) =
 * exp(-rd_guide_pdf_tau(pdf)) (THEORY.md §6). 0 for an empty pdf. */
double rd_guide_pdf_tau(const rd_guide_pdf *pdf);

/* Stratified samples (THEORY.md §6 estimator): t[n] = P^-1((n + u) / N), n = 0..N-1, u in
 * [0, 1), increasing in n, and p[n] = p(t[n]) (p may be NULL). One forward sweep over the
 * segments, O(N + segments). */
void rd_guide_pdf_sample_stratified(const rd_guide_pdf *pdf, int N, double u, double *t,
                                    double *p);

/* Samples per ray (seed 001 eq. 17, reconstructed; THEORY.md §6):
 *   N_ray = clamp(round(N_mean I_ray / mean_I), N_min, N_max),
 * mean_I from a pilot pass. mean_I <= 0 or non-finite (no pilot information) gives
 * clamp(round(N_mean), N_min, N_max). Never less than 1: N_min < 1 acts as 1 (a ray with no
 * sample drops its integral), and N_max < N_min acts as N_min. */
int rd_guide_samples_per_ray(double I_ray, double mean_I, double N_mean, int N_min, int N_max);

/* The settings an unbiased guided estimate needs (call it wherever one is promised): the
 * defensive weight alpha in (0, 1] so p > 0 wherever the integrand can be non-zero, and
 * 1 <= N_min <= N_max. RD_ERR_ARG with the reason otherwise. */
rd_status rd_guide_sampler_check(double alpha, int N_min, int N_max, char *err, size_t errlen);

#ifdef __cplusplus
}
#endif
#endif /* RD_GUIDE_PDF_H */
