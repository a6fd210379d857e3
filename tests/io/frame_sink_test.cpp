#include <gtest/gtest.h>
#include <png.h>

#include <cerrno>
#include <cstdio>
#include <filesystem>

#include "io/contact_sheet.hpp"
#include "io/field_weaver.hpp"
#include "io/file_sinks.hpp"
#include "io/frame_sink.hpp"
#include "io/v4l2_sink.hpp"
#include "io_test_util.hpp"

namespace io {
namespace {

namespace fs = std::filesystem;
using test::lineCode;
using test::TestField;

struct PngInfo {
    int width = 0, height = 0, channels = 0;
    std::vector<std::uint8_t> pixels;
};

PngInfo readPng(const fs::path& path) {
    PngInfo info;
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&image, path.c_str())) return info;
    image.format = PNG_FORMAT_RGB;
    info.pixels.resize(PNG_IMAGE_SIZE(image));
    if (!png_image_finish_read(&image, nullptr, info.pixels.data(), 0, nullptr)) return info;
    info.width = static_cast<int>(image.width);
    info.height = static_cast<int>(image.height);
    info.channels = 3;
    return info;
}

TEST(MakeSink, ParsesSpecs) {
    std::string error;
    EXPECT_NE(dynamic_cast<NullSink*>(makeSink("null", &error).get()), nullptr);
    EXPECT_NE(dynamic_cast<Y4mSink*>(makeSink("y4m:out.y4m", &error).get()), nullptr);
    EXPECT_NE(dynamic_cast<V4l2Sink*>(makeSink("v4l2:/dev/video7", &error).get()), nullptr);
    EXPECT_NE(dynamic_cast<PngSink*>(makeSink("png:shots", &error).get()), nullptr);
    EXPECT_NE(dynamic_cast<PngSink*>(makeSink("png:shots:10", &error).get()), nullptr);
    for (const char* bad : {"", "y4m", "y4m:", "v4l2:", "png:", "png:dir:0", "png:dir:x", "png::5",
                            "null:x", "mp4:out.mp4", "file.y4m"}) {
        error.clear();
        EXPECT_EQ(makeSink(bad, &error), nullptr) << bad;
        EXPECT_NE(error.find(std::string("'") + bad + "'"), std::string::npos) << error;
    }
}

TEST(MakeSink, ConstructionTouchesNothing) {
    const fs::path dir = test::scratchDir();
    std::string error;
    auto y4m = makeSink("y4m:" + (dir / "a.y4m").string(), &error);
    auto png = makeSink("png:" + (dir / "shots").string(), &error);
    auto v4l2 = makeSink("v4l2:/dev/no-such-video", &error);
    ASSERT_TRUE(y4m && png && v4l2);
    EXPECT_TRUE(fs::is_empty(dir));
    EXPECT_LT(v4l2->open({}, &error), 0);
    EXPECT_NE(error.find("/dev/no-such-video"), std::string::npos) << error;
}

TEST(NullSink, CountsFields) {
    NullSink sink;
    std::string error;
    const VideoFormat format{16, 8, PixelFormat::Uyvy};
    EXPECT_EQ(sink.writeField(TestField(format, 0).buffer), -EBADF);
    ASSERT_EQ(sink.open(format, &error), 0);
    for (int i = 0; i < 5; ++i)
        EXPECT_EQ(sink.writeField(TestField(format, i).buffer), 0);
    EXPECT_EQ(sink.fieldsWritten(), 5u);
    EXPECT_EQ(sink.close(&error), 0);
}

TEST(PngSink, WritesEveryNthWovenFrame) {
    const fs::path dir = test::scratchDir() / "shots";
    const VideoFormat format{24, 10, PixelFormat::Y8};
    PngSink sink(dir.string(), 3);
    std::string error;
    ASSERT_EQ(sink.open(format, &error), 0) << error;
    EXPECT_TRUE(fs::is_directory(dir));
    for (int i = 0; i < 14; ++i)
        ASSERT_EQ(sink.writeField(TestField(format, i).buffer), 0);
    ASSERT_EQ(sink.close(&error), 0) << error;
    // 7 woven frames: 0, 3 and 6 written.
    EXPECT_EQ(sink.filesWritten(), 3u);
    for (int k : {0, 3, 6}) {
        char name[32];
        std::snprintf(name, sizeof name, "frame_%06d.png", k);
        const PngInfo png = readPng(dir / name);
        ASSERT_EQ(png.width, 24) << name;
        ASSERT_EQ(png.height, 10);
        for (int y = 0; y < 10; ++y) {
            // Odd lines from the bottom field 2k, even lines from the top field 2k+1.
            const int want = lineCode(y % 2 == 1 ? 2 * k : 2 * k + 1, y / 2);
            EXPECT_EQ(png.pixels[(y * 24 + 5) * 3], want) << name << " line " << y;
        }
    }
    EXPECT_FALSE(fs::exists(dir / "frame_000001.png"));
}

TEST(PngSink, BadDirectoriesFailAtOpen) {
    const fs::path dir = test::scratchDir();
    std::FILE* f = std::fopen((dir / "file").c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fclose(f);
    for (const fs::path& bad : {dir / "a" / "b", dir / "file"}) {
        PngSink sink(bad.string(), 1);
        std::string error;
        EXPECT_LT(sink.open({16, 8, PixelFormat::Y8}, &error), 0) << bad;
        EXPECT_NE(error.find(bad.string()), std::string::npos) << error;
    }
    EXPECT_FALSE(fs::exists(dir / "a"));
}

TEST(FieldWeaver, EveryFieldLandsInExactlyOneFrame) {
    const VideoFormat format{8, 7, PixelFormat::Y8};
    // Sequences of parities, including repeats and a leading Top.
    const std::vector<std::vector<FieldParity>> sequences = {
        {FieldParity::Bottom, FieldParity::Top, FieldParity::Bottom, FieldParity::Top},
        {FieldParity::Top, FieldParity::Bottom, FieldParity::Top},
        {FieldParity::Bottom, FieldParity::Bottom, FieldParity::Top, FieldParity::Bottom},
    };
    for (const auto& seq : sequences) {
        FieldWeaver weaver(format);
        int frames = 0;
        for (std::size_t i = 0; i < seq.size(); ++i) {
            TestField f(format, seq[i] == FieldParity::Bottom ? 0 : 1);
            f.buffer.index = i;
            weaver.add(f.buffer, [&](const std::uint8_t*, std::size_t) { ++frames; });
        }
        weaver.flush([&](const std::uint8_t*, std::size_t) { ++frames; });
        int expected = 0;
        bool waiting = false;
        for (FieldParity p : seq) {
            if (p == FieldParity::Bottom) {
                expected += waiting ? 1 : 0;
                waiting = true;
            } else {
                ++expected;
                waiting = false;
            }
        }
        expected += waiting ? 1 : 0;
        EXPECT_EQ(frames, expected);
    }
}

TEST(ContactSheet, KeepsEvenlySpacedFramesIncludingTheFirst) {
    const std::string path = (test::scratchDir() / "sheet.png").string();
    for (int cells : {1, 4, 6, 12}) {
        for (int offered : {1, 5, 12, 13, 50, 301}) {
            ContactSheet sheet(cells, 1, 8);
            const VideoFormat format{16, 12, PixelFormat::Y8};
            std::vector<std::uint8_t> frame(16 * 12);
            for (int i = 0; i < offered; ++i)
                sheet.offer(format, frame.data(), 16);
            const auto numbers = sheet.frameNumbers();
            ASSERT_FALSE(numbers.empty());
            EXPECT_LE(numbers.size(), static_cast<std::size_t>(cells));
            EXPECT_EQ(numbers.front(), 0u);
            if (offered >= cells) {
                EXPECT_GE(2 * numbers.size(), static_cast<std::size_t>(cells));
            }
            for (std::size_t i = 1; i < numbers.size(); ++i) {
                EXPECT_EQ(numbers[i] - numbers[i - 1], numbers[1] - numbers[0])
                    << cells << "/" << offered;
            }
            EXPECT_LT(numbers.back(), static_cast<std::uint64_t>(offered));
            // Every kept thumbnail still holds its pixels after the thinning, and the grid writes.
            for (int i = 0; i < sheet.count(); ++i) {
                ASSERT_EQ(sheet.thumbnail(i).size(), static_cast<std::size_t>(8 * 6 * 3)) << i;
            }
            std::string error;
            EXPECT_EQ(sheet.write(path, &error), 0) << error;
        }
    }
}

TEST(ContactSheet, ThumbnailsAverageTheFrameAndWriteAGrid) {
    const fs::path dir = test::scratchDir();
    const VideoFormat format{40, 30, PixelFormat::Uyvy};
    ContactSheet sheet(3, 2, 10);
    for (int i = 0; i < 12; ++i)
        sheet.offerField(format, TestField(format, i).buffer);
    ASSERT_EQ(sheet.offered(), 6u);
    ASSERT_EQ(sheet.count(), 6);
    EXPECT_EQ(sheet.thumbHeight(), 7);
    // A flat grey frame gives a flat thumbnail of the same grey.
    ContactSheet flat(1, 1, 5);
    std::vector<std::uint8_t> grey(40 * 30 * 3, 77);
    flat.offer({40, 30, PixelFormat::Rgb8}, grey.data(), 40 * 3);
    for (std::uint8_t v : flat.thumbnail(0))
        EXPECT_EQ(v, 77);
    const fs::path path = dir / "sheet.png";
    std::string error;
    ASSERT_EQ(sheet.write(path.string(), &error), 0) << error;
    const PngInfo png = readPng(path);
    EXPECT_EQ(png.width, 4 + 3 * (10 + 4));
    EXPECT_EQ(png.height, 4 + 2 * (7 + 4));
    ContactSheet empty(2, 2, 10);
    EXPECT_LT(empty.write((dir / "empty.png").string(), &error), 0);
    EXPECT_FALSE(fs::exists(dir / "empty.png"));
    EXPECT_LT(sheet.write((dir / "no" / "sheet.png").string(), &error), 0);
    EXPECT_NE(error.find("sheet.png"), std::string::npos) << error;
}

TEST(PixelConversion, RgbThroughUyvyRoundTrips) {
    std::vector<std::uint8_t> rgb;
    for (int r = 0; r < 256; r += 51) {
        for (int g = 0; g < 256; g += 51) {
            for (int b = 0; b < 256; b += 51) {
                for (int twice = 0; twice < 2; ++twice) {  // pairs share chroma
                    rgb.push_back(static_cast<std::uint8_t>(r));
                    rgb.push_back(static_cast<std::uint8_t>(g));
                    rgb.push_back(static_cast<std::uint8_t>(b));
                }
            }
        }
    }
    const int width = static_cast<int>(rgb.size() / 3);
    std::vector<std::uint8_t> uyvy(width * 2), back(width * 3);
    rgbRowToUyvy(rgb.data(), width, uyvy.data());
    uyvyRowToRgb(uyvy.data(), width, back.data());
    for (std::size_t i = 0; i < rgb.size(); ++i)
        EXPECT_NEAR(back[i], rgb[i], 3) << i;
    // Black and white land on the studio-range limits.
    const std::uint8_t bw[6] = {0, 0, 0, 255, 255, 255};
    std::uint8_t out[4];
    rgbRowToUyvy(bw, 2, out);
    EXPECT_EQ(out[1], 16);
    EXPECT_EQ(out[3], 235);
    EXPECT_EQ(out[0], 128);
    EXPECT_EQ(out[2], 128);
}

TEST(VideoFormat, FieldGeometry) {
    for (int h : {2, 3, 486, 480, 487}) {
        EXPECT_EQ(fieldLines(h, FieldParity::Top) + fieldLines(h, FieldParity::Bottom), h);
    }
    EXPECT_EQ(fieldLines(486, FieldParity::Bottom), 243);
    EXPECT_EQ(fieldParity(0), FieldParity::Bottom);
    EXPECT_EQ(fieldParity(1), FieldParity::Top);
    EXPECT_TRUE(checkVideoFormat({720, 486, PixelFormat::Uyvy}).empty());
    EXPECT_FALSE(checkVideoFormat({0, 486, PixelFormat::Uyvy}).empty());
    EXPECT_FALSE(checkVideoFormat({721, 486, PixelFormat::Uyvy}).empty());
    EXPECT_TRUE(checkVideoFormat({721, 486, PixelFormat::Y8}).empty());
    for (PixelFormat f : {PixelFormat::Uyvy, PixelFormat::Y8, PixelFormat::Rgb8}) {
        EXPECT_EQ(parsePixelFormat(pixelFormatName(f)), f);
    }
    EXPECT_FALSE(parsePixelFormat("yuv420"));
}

}  // namespace
}  // namespace io
