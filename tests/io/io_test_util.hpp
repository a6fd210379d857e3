// Helpers shared by the io tests: synthetic fields with recognisable lines, scratch folders.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "io/video_format.hpp"

namespace io::test {

// The luma (or grey) value line `line` of field `index` carries: distinct for nearby fields and
// lines, inside the studio range.
inline std::uint8_t lineCode(std::uint64_t index, int line) {
    return static_cast<std::uint8_t>(16 +
                                     (index * 37 + static_cast<std::uint64_t>(line) * 5) % 219);
}
inline std::uint8_t chromaCode(std::uint64_t index, int line, int x) {
    return static_cast<std::uint8_t>(16 +
                                     (index * 11 + static_cast<std::uint64_t>(line) * 3 + x) % 224);
}

// A field of `format` whose every pixel on line `l` has luma lineCode(index, l).
struct TestField {
    std::vector<std::uint8_t> pixels;
    FieldBuffer buffer;

    TestField(const VideoFormat& format, std::uint64_t index, double time = 0.0) {
        const FieldParity parity = fieldParity(index);
        const int lines = fieldLines(format.height, parity);
        const std::size_t stride =
            static_cast<std::size_t>(format.width) * bytesPerPixel(format.format);
        pixels.resize(stride * lines);
        for (int l = 0; l < lines; ++l) {
            std::uint8_t* row = pixels.data() + l * stride;
            for (int x = 0; x < format.width; ++x) {
                switch (format.format) {
                    case PixelFormat::Uyvy:
                        row[2 * x] = chromaCode(index, l, x);
                        row[2 * x + 1] = lineCode(index, l);
                        break;
                    case PixelFormat::Y8:
                        row[x] = lineCode(index, l);
                        break;
                    case PixelFormat::Rgb8:
                        row[3 * x] = row[3 * x + 1] = row[3 * x + 2] = lineCode(index, l);
                        break;
                }
            }
        }
        buffer = {index, parity, time, pixels.data(), stride, lines};
    }
};

// A fresh, empty scratch folder for the running test.
inline std::filesystem::path scratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::filesystem::path dir = std::filesystem::path(VIG_TEST_TMP) / "io" /
                                (std::string(info->test_suite_name()) + "." + info->name());
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

}  // namespace io::test
