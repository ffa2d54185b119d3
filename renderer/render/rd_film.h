/* rd_film.h: the film (film.c): per pixel the sums of its samples, from which the image and its
 * standard error are resolved; a pixel's sums are carried in registers while its samples are
 * drawn (rd_film_pixel) and stored once after them (render.c). Internal to render/ (and tests). */
#ifndef RD_FILM_H
#define RD_FILM_H

#include "core/rd_math.h"
#include "renderer.h"

#include <stdint.h>

/* Per pixel and channel the sums of w L and w^2 L^2 over the pixel's samples L of weight w (1
 * unless the method weighs them: rd_method.sample_share), and per pixel their count; with
 * weights also per channel the sum of w^2 L and per pixel those of w and w^2 (else NULL). */
typedef struct {
    int w, h;
    double *sum, *sum2;
    uint32_t *n;
    double *wl, *wsum, *wsum2;
} rd_film;

/* A w x h film of zeros, with the weights' sums where `weighted`; 0 (and nothing held) out of
 * memory. rd_film_free frees it and leaves it empty (a second call is harmless). */
int rd_film_alloc(rd_film *f, int w, int h, int weighted);
void rd_film_free(rd_film *f);

/* One pixel's sums while its samples are drawn: load, add each sample, store. */
typedef struct {
    double sum[3], sum2[3], wl[3], w, w2;
    uint32_t n;
} rd_film_pixel;

static inline void rd_film_load(const rd_film *f, uint64_t pix, rd_film_pixel *a)
{
    for (int c = 0; c < 3; c++) {
        a->sum[c] = f->sum[3 * pix + c], a->sum2[c] = f->sum2[3 * pix + c];
        a->wl[c] = f->wl ? f->wl[3 * pix + c] : 0.0;
    }
    a->n = f->n[pix];
    a->w = f->wsum ? f->wsum[pix] : 0.0, a->w2 = f->wsum2 ? f->wsum2[pix] : 0.0;
}

/* Sample L of weight w (w = 1: the plain sums, exactly). */
static inline void rd_film_add(rd_film_pixel *a, vec3 L, double w)
{
    const double w2 = w * w;
    a->sum[0] += w * L.x, a->sum[1] += w * L.y, a->sum[2] += w * L.z;
    a->sum2[0] += w2 * L.x * L.x, a->sum2[1] += w2 * L.y * L.y, a->sum2[2] += w2 * L.z * L.z;
    a->wl[0] += w2 * L.x, a->wl[1] += w2 * L.y, a->wl[2] += w2 * L.z;
    a->w += w, a->w2 += w2, a->n++;
}

static inline void rd_film_store(rd_film *f, uint64_t pix, const rd_film_pixel *a)
{
    for (int c = 0; c < 3; c++) {
        f->sum[3 * pix + c] = a->sum[c], f->sum2[3 * pix + c] = a->sum2[c];
        if (f->wl) f->wl[3 * pix + c] = a->wl[c];
    }
    f->n[pix] = a->n;
    if (f->wsum) f->wsum[pix] = a->w, f->wsum2[pix] = a->w2;
}

/* The running mean's squared error against the reference ref over the pixels sampled so far:
 * acc[0] += the sum of squared errors, acc[1] += the channels counted (the RMSE is
 * sqrt(acc[0] / acc[1])); acc[2] += the samples in the film. */
void rd_film_sq_err(const rd_film *f, const rd_image *ref, double acc[3]);

/* Each pixel's mean and its standard error, 3 floats a pixel each (film.c has the formulas). */
void rd_film_resolve(const rd_film *f, float *mean, float *stderr_rgb);

#endif /* RD_FILM_H */
