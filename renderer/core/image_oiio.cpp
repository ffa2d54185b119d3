// image_oiio.cpp: OpenImageIO behind the plain C contract of image_plugin.h. Built alone as a
// shared module that core/images.c loads on the first image read or write (image_plugin.h says
// why); it calls nothing of the renderer. Every entry point catches every exception.
#include "core/image_plugin.h"

#include <OpenImageIO/imageio.h>

#include <cstdio>
#include <cstdlib>
#include <memory>

using namespace OIIO;

namespace {

rd_status write_pixels(const char *path, const char *tmp, int w, int h, int u8, const void *pixels,
                       char *err, size_t errlen)
{
    try {
        TypeDesc type = u8 ? TypeDesc::UINT8 : TypeDesc::FLOAT;
        auto out = ImageOutput::create(path); // the format by path's extension (tmp keeps it)
        if (!out) {
            std::snprintf(err, errlen, "%s: cannot write this format (%s)", path, OIIO::geterror().c_str());
            return RD_ERR_ARG;
        }
        ImageSpec spec(w, h, 3, type);
        spec.attribute("Software", "photonmarch");
        if (!out->open(tmp, spec) || !out->write_image(type, pixels) || !out->close()) {
            std::snprintf(err, errlen, "%s: %s", path, out->geterror().c_str());
            std::remove(tmp);
            return RD_ERR_IO;
        }
        return RD_OK;
    } catch (const std::exception &e) {
        std::snprintf(err, errlen, "%s: %s", path, e.what());
    } catch (...) {
        std::snprintf(err, errlen, "%s: unknown error writing image", path);
    }
    std::remove(tmp);
    return RD_ERR_INTERNAL;
}

rd_status read_pixels(const char *path, float **pixels, int *w_out, int *h_out, int *nc_out,
                      char *err, size_t errlen)
{
    *pixels = nullptr;
    try {
        auto in = ImageInput::open(path);
        if (!in) {
            std::snprintf(err, errlen, "%s: %s", path, OIIO::geterror().c_str());
            return RD_ERR_IO;
        }
        const ImageSpec &spec = in->spec();
        int w = spec.width, h = spec.height, nc = spec.nchannels;
        if (w <= 0 || h <= 0 || nc <= 0 || (size_t)w * h > (size_t)1 << 28) {
            std::snprintf(err, errlen, "%s: unsupported image size %dx%dx%d", path, w, h, nc);
            return RD_ERR_FORMAT;
        }
        // Straight into the buffer the caller frees (one copy of the pixels, as OpenImageIO reads).
        std::unique_ptr<float, decltype(&std::free)> px((float *)std::malloc((size_t)w * h * nc * sizeof(float)), &std::free);
        if (!px) {
            std::snprintf(err, errlen, "%s: out of memory", path);
            return RD_ERR_NOMEM;
        }
        if (!in->read_image(0, 0, 0, nc, TypeDesc::FLOAT, px.get())) {
            std::snprintf(err, errlen, "%s: %s", path, in->geterror().c_str());
            return RD_ERR_FORMAT;
        }
        in->close();
        *pixels = px.release();
        *w_out = w;
        *h_out = h;
        *nc_out = nc;
        return RD_OK;
    } catch (const std::exception &e) {
        std::snprintf(err, errlen, "%s: %s", path, e.what());
    } catch (...) {
        std::snprintf(err, errlen, "%s: unknown error reading image", path);
    }
    return RD_ERR_INTERNAL;
}

} // namespace

extern "C" {
extern const rd_image_plugin rd_image_plugin_v1;
const rd_image_plugin rd_image_plugin_v1 = {write_pixels, read_pixels};
}
