/* image_plugin.h: the contract between core/images.c and the OpenImageIO module it loads on the
 * first image read or write (image_oiio.cpp, built alone as RD_IMAGE_PLUGIN_FILE in the build
 * folder, beside build/photonmarch).
 *
 * Why a module of its own: Debian's OpenImageIO pulls in about 260 shared objects (OpenCV,
 * FFmpeg, GDAL, GStreamer, ...), and linking it into a program makes every start of that
 * program pay their loading and symbol binding: 0.26-0.34 s before `main` in the release build,
 * 0.53-0.59 s under the sanitizers, measured with an empty program linked against -lOpenImageIO
 * alone (docs/benchmarks.md "Session 63"). Every command that only reads a scene (`info`,
 * `explain`, a refused scene) and every test process paid it; now only the processes that read
 * or write an image do, once. */
#ifndef RD_IMAGE_PLUGIN_H
#define RD_IMAGE_PLUGIN_H

#include "renderer.h"

#include <stddef.h>

/* The file the loader asks the dynamic linker for: found through the program's run path, which
 * the Makefile sets to the build folder ($ORIGIN or $ORIGIN/..). */
#define RD_IMAGE_PLUGIN_FILE "libphotonmarch-images.so"
/* The one symbol the module exports, an rd_image_plugin; the version is in the name, so a module
 * of another version is not found rather than misread. */
#define RD_IMAGE_PLUGIN_SYMBOL "rd_image_plugin_v1"

#ifdef __cplusplus
extern "C" {
#endif
typedef struct {
    /* Write w x h RGB pixels (float, or unsigned char when u8) to `tmp` in the format of `path`'s
     * extension (the caller renames tmp to path). No partial file is left at tmp on failure. */
    rd_status (*write)(const char *path, const char *tmp, int w, int h, int u8, const void *pixels,
                       char *err, size_t errlen);
    /* Read the image at `path`: *pixels (malloc'd, the caller frees) holds w x h x nc floats. */
    rd_status (*read)(const char *path, float **pixels, int *w, int *h, int *nc, char *err,
                      size_t errlen);
} rd_image_plugin;
#ifdef __cplusplus
}
#endif

#endif
