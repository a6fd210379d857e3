#include <gtest/gtest.h>

#include <cerrno>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "io/field_clock.hpp"
#include "io/file_sinks.hpp"
#include "io/frame_sink.hpp"
#include "io_test_util.hpp"

namespace io {
namespace {

namespace fs = std::filesystem;
using test::lineCode;
using test::TestField;

// An independent YUV4MPEG2 reader: header tags, then FRAME records of planar data.
struct Y4mFile {
    std::map<char, std::string> tags;
    int width = 0, height = 0;
    std::vector<std::vector<std::uint8_t>> frames;  // planar: Y, then Cb, then Cr
    std::string error;
};

Y4mFile readY4m(const fs::path& path) {
    Y4mFile f;
    std::ifstream in(path, std::ios::binary);
    std::string header;
    if (!std::getline(in, header)) {
        f.error = "no header";
        return f;
    }
    std::istringstream words(header);
    std::string magic;
    words >> magic;
    if (magic != "YUV4MPEG2") {
        f.error = "bad magic";
        return f;
    }
    for (std::string w; words >> w;)
        f.tags[w[0]] = w.substr(1);
    f.width = std::stoi(f.tags['W']);
    f.height = std::stoi(f.tags['H']);
    const std::size_t luma = static_cast<std::size_t>(f.width) * f.height;
    const std::size_t frameBytes = f.tags['C'] == "mono" ? luma : 2 * luma;
    for (std::string line; std::getline(in, line);) {
        if (line != "FRAME") {
            f.error = "expected FRAME, got '" + line.substr(0, 16) + "'";
            return f;
        }
        std::vector<std::uint8_t> data(frameBytes);
        in.read(reinterpret_cast<char*>(data.data()), static_cast<std::streamsize>(frameBytes));
        if (static_cast<std::size_t>(in.gcount()) != frameBytes) {
            f.error = "short frame";
            return f;
        }
        f.frames.push_back(std::move(data));
    }
    return f;
}

int writeFields(FrameSink& sink, const VideoFormat& format, int count, std::uint64_t first = 0) {
    for (int i = 0; i < count; ++i) {
        TestField field(format, first + i, base::fieldTime(0.0, first + i));
        const int rc = sink.writeField(field.buffer);
        if (rc != 0) return rc;
    }
    return 0;
}

TEST(Y4mSink, HeaderDeclaresInterlacedNtsc422) {
    const fs::path dir = test::scratchDir();
    const VideoFormat format{720, 486, PixelFormat::Uyvy};
    Y4mSink sink((dir / "out.y4m").string());
    std::string error;
    ASSERT_EQ(sink.open(format, &error), 0) << error;
    ASSERT_EQ(writeFields(sink, format, 4), 0);
    ASSERT_EQ(sink.close(&error), 0) << error;
    const Y4mFile f = readY4m(dir / "out.y4m");
    ASSERT_TRUE(f.error.empty()) << f.error;
    EXPECT_EQ(f.width, 720);
    EXPECT_EQ(f.height, 486);
    EXPECT_EQ(f.tags.at('F'), "30000:1001");
    EXPECT_EQ(f.tags.at('I'), "b");
    EXPECT_EQ(f.tags.at('A'), "10:11");
    EXPECT_EQ(f.tags.at('C'), "422");
    EXPECT_EQ(f.frames.size(), 2u);
}

TEST(Y4mSink, MonoForGrey) {
    const fs::path dir = test::scratchDir();
    const VideoFormat format{64, 48, PixelFormat::Y8};
    Y4mSink sink((dir / "grey.y4m").string());
    std::string error;
    ASSERT_EQ(sink.open(format, &error), 0) << error;
    ASSERT_EQ(writeFields(sink, format, 6), 0);
    ASSERT_EQ(sink.close(&error), 0) << error;
    const Y4mFile f = readY4m(dir / "grey.y4m");
    ASSERT_TRUE(f.error.empty()) << f.error;
    EXPECT_EQ(f.tags.at('C'), "mono");
    EXPECT_EQ(f.frames.size(), 3u);
}

// Every frame line comes from the right field: odd lines from the bottom field (earlier in
// time), even lines from the top field after it; chroma travels with its line.
TEST(Y4mSink, WovenFrameOddLinesComeFromTheBottomField) {
    for (PixelFormat pf : {PixelFormat::Uyvy, PixelFormat::Y8, PixelFormat::Rgb8}) {
        for (int height : {486, 480, 37}) {
            const fs::path dir = test::scratchDir();
            const VideoFormat format{32, height, pf};
            Y4mSink sink((dir / "w.y4m").string());
            std::string error;
            ASSERT_EQ(sink.open(format, &error), 0) << error;
            ASSERT_EQ(writeFields(sink, format, 6), 0);
            ASSERT_EQ(sink.close(&error), 0) << error;
            const Y4mFile f = readY4m(dir / "w.y4m");
            ASSERT_TRUE(f.error.empty()) << f.error;
            ASSERT_EQ(f.frames.size(), 3u);
            const std::size_t luma = static_cast<std::size_t>(format.width) * height;
            for (std::size_t k = 0; k < f.frames.size(); ++k) {
                for (int y = 0; y < height; ++y) {
                    const bool bottom = y % 2 == 1;
                    const std::uint64_t field = 2 * k + (bottom ? 0 : 1);
                    const int fieldLine = y / 2;
                    // RGB grey goes through Y'CbCr: studio-range luma, allow rounding.
                    const int want = pf == PixelFormat::Rgb8
                                         ? 16 + (lineCode(field, fieldLine) * 219 + 127) / 255
                                         : lineCode(field, fieldLine);
                    for (int x = 0; x < format.width; x += 7) {
                        ASSERT_NEAR(f.frames[k][y * format.width + x], want,
                                    pf == PixelFormat::Rgb8 ? 1 : 0)
                            << pixelFormatName(pf) << " frame " << k << " line " << y;
                    }
                    if (pf == PixelFormat::Uyvy) {
                        const int half = format.width / 2;
                        ASSERT_EQ(f.frames[k][luma + y * half + 3],
                                  test::chromaCode(field, fieldLine, 6));
                    }
                }
            }
        }
    }
}

TEST(Y4mSink, FrameCountIsHalfTheFieldsRoundedUp) {
    const VideoFormat format{16, 12, PixelFormat::Y8};
    for (int fields : {0, 1, 2, 3, 7, 20}) {
        const fs::path dir = test::scratchDir();
        Y4mSink sink((dir / "n.y4m").string());
        std::string error;
        ASSERT_EQ(sink.open(format, &error), 0) << error;
        ASSERT_EQ(writeFields(sink, format, fields), 0);
        ASSERT_EQ(sink.close(&error), 0) << error;
        const Y4mFile f = readY4m(dir / "n.y4m");
        ASSERT_TRUE(f.error.empty()) << f.error;
        EXPECT_EQ(f.frames.size(), static_cast<std::size_t>((fields + 1) / 2))
            << fields << " fields";
        EXPECT_EQ(sink.framesWritten(), f.frames.size());
    }
}

TEST(Y4mSink, FileAppearsOnlyAtClose) {
    const fs::path dir = test::scratchDir();
    const fs::path path = dir / "late.y4m";
    const VideoFormat format{16, 12, PixelFormat::Uyvy};
    Y4mSink sink(path.string());
    std::string error;
    ASSERT_EQ(sink.open(format, &error), 0) << error;
    ASSERT_EQ(writeFields(sink, format, 4), 0);
    EXPECT_FALSE(fs::exists(path));
    EXPECT_TRUE(fs::exists(path.string() + ".part"));
    ASSERT_EQ(sink.close(&error), 0) << error;
    EXPECT_TRUE(fs::exists(path));
    EXPECT_FALSE(fs::exists(path.string() + ".part"));
}

TEST(Y4mSink, AbandonedSinkLeavesNoFile) {
    const fs::path dir = test::scratchDir();
    const VideoFormat format{16, 12, PixelFormat::Uyvy};
    {
        Y4mSink sink((dir / "gone.y4m").string());
        std::string error;
        ASSERT_EQ(sink.open(format, &error), 0) << error;
        ASSERT_EQ(writeFields(sink, format, 3), 0);
    }
    EXPECT_TRUE(fs::is_empty(dir));
}

TEST(Y4mSink, BadPathsFailAtOpenAndLeaveNothing) {
    const fs::path dir = test::scratchDir();
    const VideoFormat format{16, 12, PixelFormat::Uyvy};
    const std::vector<std::string> bad = {(dir / "missing" / "x.y4m").string(), dir.string(),
                                          "/proc/no-such-dir/x.y4m"};
    for (const std::string& path : bad) {
        Y4mSink sink(path);
        std::string error;
        EXPECT_LT(sink.open(format, &error), 0) << path;
        EXPECT_NE(error.find(path), std::string::npos) << error;
        EXPECT_NE(sink.writeField(TestField(format, 0).buffer), 0);
    }
    EXPECT_TRUE(fs::is_empty(dir));
}

TEST(Y4mSink, BadFormatOrFieldIsRefused) {
    const fs::path dir = test::scratchDir();
    Y4mSink odd((dir / "odd.y4m").string());
    std::string error;
    EXPECT_EQ(odd.open({15, 12, PixelFormat::Uyvy}, &error), -EINVAL);
    EXPECT_NE(error.find("even"), std::string::npos) << error;
    Y4mSink sink((dir / "ok.y4m").string());
    const VideoFormat format{16, 12, PixelFormat::Uyvy};
    ASSERT_EQ(sink.open(format, &error), 0) << error;
    TestField f(format, 0);
    FieldBuffer noData = f.buffer;
    noData.data = nullptr;
    EXPECT_EQ(sink.writeField(noData), -EINVAL);
    FieldBuffer shortStride = f.buffer;
    shortStride.stride = 8;
    EXPECT_EQ(sink.writeField(shortStride), -EINVAL);
    EXPECT_EQ(sink.close(&error), 0) << error;
}

}  // namespace
}  // namespace io
