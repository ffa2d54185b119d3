// image_io.cpp: OpenImageIO behind the plain C API of renderer.h. Every entry point catches
// every exception; files are written to a temporary name in the same folder and renamed
// (rd_temp_name, rd_commit_temp: core/files.c).
#include "core/rd_core.h"

#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>
#include <unistd.h>

using namespace OIIO;

namespace {

rd_status write_pixels(const char *path, int w, int h, TypeDesc type, const void *pixels,
                       char *err, size_t errlen)
{
    char tmp[2200]; // core/files.c's scheme, same extension: OpenImageIO picks the format by it
    if (rd_temp_name(path, tmp, sizeof tmp) < 0) {
        std::snprintf(err, errlen, "%.200s...: path too long", path);
        return RD_ERR_IO;
    }
    auto out = ImageOutput::create(path);
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
    return rd_commit_temp(tmp, path, err, errlen) == RD_OK ? RD_OK : RD_ERR_IO;
}

unsigned char to_srgb8(double v)
{
    if (!(v > 0.0)) return 0; // also NaN
    double s = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
    long q = std::lround(s * 255.0);
    return (unsigned char)(q < 0 ? 0 : (q > 255 ? 255 : q));
}

} // namespace

extern "C" rd_status rd_image_write_exr(const char *path, const rd_image *img, char *err, size_t errlen)
{
    try {
        return write_pixels(path, img->w, img->h, TypeDesc::FLOAT, img->rgb, err, errlen);
    } catch (const std::exception &e) {
        std::snprintf(err, errlen, "%s: %s", path, e.what());
    } catch (...) {
        std::snprintf(err, errlen, "%s: unknown error writing image", path);
    }
    return RD_ERR_INTERNAL;
}

extern "C" rd_status rd_image_write_png(const char *path, const rd_image *img, double exposure,
                                        char *err, size_t errlen)
{
    try {
        double k = std::pow(2.0, exposure);
        std::vector<unsigned char> px((size_t)img->w * img->h * 3);
        for (size_t i = 0; i < px.size(); i++) px[i] = to_srgb8(img->rgb[i] * k);
        return write_pixels(path, img->w, img->h, TypeDesc::UINT8, px.data(), err, errlen);
    } catch (const std::exception &e) {
        std::snprintf(err, errlen, "%s: %s", path, e.what());
    } catch (...) {
        std::snprintf(err, errlen, "%s: unknown error writing image", path);
    }
    return RD_ERR_INTERNAL;
}

extern "C" rd_status rd_image_read(const char *path, rd_image *out, char *err, size_t errlen)
{
    out->rgb = nullptr;
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
        std::vector<float> buf((size_t)w * h * nc);
        if (!in->read_image(0, 0, 0, nc, TypeDesc::FLOAT, buf.data())) {
            std::snprintf(err, errlen, "%s: %s", path, in->geterror().c_str());
            return RD_ERR_FORMAT;
        }
        in->close();
        float *rgb = (float *)std::malloc((size_t)w * h * 3 * sizeof(float));
        if (!rgb) {
            std::snprintf(err, errlen, "%s: out of memory", path);
            return RD_ERR_NOMEM;
        }
        for (size_t p = 0; p < (size_t)w * h; p++)
            for (int c = 0; c < 3; c++) /* RGB(A): the first three; grey(+alpha): grey */
                rgb[3 * p + c] = buf[p * nc + (nc >= 3 ? c : 0)];
        out->w = w;
        out->h = h;
        out->rgb = rgb;
        out->channels = nc;
        return RD_OK;
    } catch (const std::exception &e) {
        std::snprintf(err, errlen, "%s: %s", path, e.what());
    } catch (...) {
        std::snprintf(err, errlen, "%s: unknown error reading image", path);
    }
    return RD_ERR_INTERNAL;
}

extern "C" void rd_image_free_pixels(rd_image *img)
{
    if (!img) return;
    std::free(img->rgb);
    img->rgb = nullptr;
}
