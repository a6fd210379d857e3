#include "io/image_file.hpp"

#include <png.h>

#include "io/output_file.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace io {
namespace {

int fail(std::string* error, const std::string& path, const std::string& what, int rc) {
    if (error) *error = path + ": " + what;
    return rc;
}

int writePngImpl(const std::string& path, int width, int height, int channels, int bitDepth,
                 const std::uint8_t* rows, std::size_t rowBytes, std::string* error) {
    if (width <= 0 || height <= 0) return fail(error, path, "image has no pixels", -EINVAL);
    OutputFile out;
    std::string why;
    if (const int rc = out.open(path, &why); rc != 0) {
        if (error) *error = why;
        return rc;
    }
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
    png_infop info = png ? png_create_info_struct(png) : nullptr;
    if (!png || !info) {
        png_destroy_write_struct(&png, &info);
        return fail(error, path, "out of memory", -ENOMEM);
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        const int err = errno ? errno : EIO;
        return fail(error, path, std::string("PNG encoding failed: ") + std::strerror(err), -err);
    }
    png_init_io(png, out.get());
    png_set_compression_level(png, 3);
    png_set_IHDR(png, info, width, height, bitDepth,
                 channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    if (bitDepth == 16) png_set_swap(png);  // our samples are host (little-endian) order
    for (int y = 0; y < height; ++y) {
        png_write_row(png, const_cast<png_bytep>(rows + static_cast<std::size_t>(y) * rowBytes));
    }
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
    const int rc = out.commit(&why);
    if (rc != 0 && error) *error = why;
    return rc;
}

}  // namespace

int writePng8(const std::string& path, int width, int height, int channels,
              std::span<const std::uint8_t> pixels, std::string* error) {
    if (channels != 1 && channels != 3)
        return fail(error, path, "channels must be 1 or 3", -EINVAL);
    if (pixels.size() < static_cast<std::size_t>(width) * height * channels) {
        return fail(error, path, "pixel buffer smaller than the image", -EINVAL);
    }
    return writePngImpl(path, width, height, channels, 8, pixels.data(),
                        static_cast<std::size_t>(width) * channels, error);
}

int writePng16(const std::string& path, int width, int height,
               std::span<const std::uint16_t> pixels, std::string* error) {
    if (pixels.size() < static_cast<std::size_t>(width) * height) {
        return fail(error, path, "pixel buffer smaller than the image", -EINVAL);
    }
    return writePngImpl(path, width, height, 1, 16,
                        reinterpret_cast<const std::uint8_t*>(pixels.data()),
                        static_cast<std::size_t>(width) * 2, error);
}

int writePfm(const std::string& path, int width, int height, std::span<const float> values,
             std::string* error) {
    if (width <= 0 || height <= 0) return fail(error, path, "image has no pixels", -EINVAL);
    if (values.size() < static_cast<std::size_t>(width) * height) {
        return fail(error, path, "value buffer smaller than the image", -EINVAL);
    }
    OutputFile out;
    std::string why;
    if (const int rc = out.open(path, &why); rc != 0) {
        if (error) *error = why;
        return rc;
    }
    std::fprintf(out.get(), "Pf\n%d %d\n-1.0\n", width, height);
    for (int y = height - 1; y >= 0; --y) {
        std::fwrite(values.data() + static_cast<std::size_t>(y) * width, sizeof(float), width,
                    out.get());
    }
    const int rc = out.commit(&why);
    if (rc != 0 && error) *error = why;
    return rc;
}

}  // namespace io
