/* images.c: EXR and PNG files in and out (renderer.h's rd_image_* calls). The pixels go through
 * OpenImageIO in a module of its own, loaded on the first call (image_plugin.h: why); here are
 * what is photonmarch's own: the temporary name and the rename (core/files.c), the PNG's
 * exposure and sRGB transfer, and the reader's RGB from any channel count. */
#define _GNU_SOURCE /* RTLD_NODELETE */
#include "core/image_plugin.h"
#include "core/rd_core.h"

#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

/* The module's entry points. The dynamic linker is the only keeper of state: RTLD_NODELETE keeps
 * the module loaded after the dlclose below, so every later call's dlopen finds it at once (a
 * reference count, no second load), from any thread. */
static const rd_image_plugin *plugin(const char *path, char *err, size_t errlen)
{
    /* (RTLD_LAZY: the libraries' functions bound on their first call, as for a program linked
     * against them) */
    void *h = dlopen(RD_IMAGE_PLUGIN_FILE, RTLD_LAZY | RTLD_LOCAL | RTLD_NODELETE);
    if (!h) {
        const char *why = dlerror();
        snprintf(err, errlen, "%s: cannot load the image module (the build folder's %s): %s", path,
                 RD_IMAGE_PLUGIN_FILE, why ? why : "not found");
        return NULL;
    }
    const rd_image_plugin *p = dlsym(h, RD_IMAGE_PLUGIN_SYMBOL);
    dlclose(h);
    if (!p) snprintf(err, errlen, "%s: %s has no %s (a module of another version?)", path, RD_IMAGE_PLUGIN_FILE,
                     RD_IMAGE_PLUGIN_SYMBOL);
    return p;
}

rd_status rd_image_io_ready(const char *path, char *err, size_t errlen)
{
    return plugin(path, err, errlen) ? RD_OK : RD_ERR_OUTPUT; /* (the outputs cannot be written) */
}

static rd_status write_pixels(const char *path, int w, int h, int u8, const void *pixels, char *err,
                              size_t errlen)
{
    char tmp[2200]; /* core/files.c's scheme, same extension: OpenImageIO picks the format by it */
    if (rd_temp_name(path, tmp, sizeof tmp) < 0) {
        snprintf(err, errlen, "%.200s...: path too long", path);
        return RD_ERR_IO;
    }
    const rd_image_plugin *p = plugin(path, err, errlen);
    if (!p) return RD_ERR_IO;
    rd_status st = p->write(path, tmp, w, h, u8, pixels, err, errlen);
    if (st != RD_OK) return st;
    return rd_commit_temp(tmp, path, err, errlen) == RD_OK ? RD_OK : RD_ERR_IO;
}

rd_status rd_image_write_exr(const char *path, const rd_image *img, char *err, size_t errlen)
{
    return write_pixels(path, img->w, img->h, 0, img->rgb, err, errlen);
}

/* Linear value -> 8-bit sRGB code (the sRGB transfer function, IEC 61966-2-1). */
static unsigned char to_srgb8(double v)
{
    if (!(v > 0.0)) return 0; /* also NaN */
    double s = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
    long q = lround(s * 255.0);
    return (unsigned char)(q < 0 ? 0 : (q > 255 ? 255 : q));
}

rd_status rd_image_write_png(const char *path, const rd_image *img, double exposure, char *err,
                             size_t errlen)
{
    double k = pow(2.0, exposure);
    size_t n = (size_t)img->w * img->h * 3;
    unsigned char *px = malloc(n ? n : 1);
    if (!px) {
        snprintf(err, errlen, "%s: out of memory", path);
        return RD_ERR_NOMEM;
    }
    for (size_t i = 0; i < n; i++) px[i] = to_srgb8(img->rgb[i] * k);
    rd_status st = write_pixels(path, img->w, img->h, 1, px, err, errlen);
    free(px);
    return st;
}

rd_status rd_image_read(const char *path, rd_image *out, char *err, size_t errlen)
{
    out->rgb = NULL;
    const rd_image_plugin *p = plugin(path, err, errlen);
    if (!p) return RD_ERR_IO;
    float *buf = NULL;
    int w = 0, h = 0, nc = 0;
    rd_status st = p->read(path, &buf, &w, &h, &nc, err, errlen);
    if (st != RD_OK) return st;
    float *rgb = malloc((size_t)w * h * 3 * sizeof(float));
    if (!rgb) {
        free(buf);
        snprintf(err, errlen, "%s: out of memory", path);
        return RD_ERR_NOMEM;
    }
    for (size_t q = 0; q < (size_t)w * h; q++)
        for (int c = 0; c < 3; c++) /* RGB(A): the first three; grey(+alpha): grey */
            rgb[3 * q + c] = buf[q * nc + (nc >= 3 ? c : 0)];
    free(buf);
    out->w = w;
    out->h = h;
    out->rgb = rgb;
    out->channels = nc;
    return RD_OK;
}

void rd_image_free_pixels(rd_image *img)
{
    if (!img) return;
    free(img->rgb);
    img->rgb = NULL;
}
