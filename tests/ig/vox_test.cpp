#include "ig/vox.hpp"

#include "ig/error.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace {

using ig::InputError;
using ig::VoxFile;
using ig::VoxModel;

void put32(std::vector<std::uint8_t>& v, std::uint32_t x) {
    for (int i = 0; i < 4; ++i)
        v.push_back(static_cast<std::uint8_t>(x >> (8 * i)));
}
void chunk(std::vector<std::uint8_t>& v, const char* id, const std::vector<std::uint8_t>& content,
           const std::vector<std::uint8_t>& children = {}) {
    v.insert(v.end(), id, id + 4);
    put32(v, static_cast<std::uint32_t>(content.size()));
    put32(v, static_cast<std::uint32_t>(children.size()));
    v.insert(v.end(), content.begin(), content.end());
    v.insert(v.end(), children.begin(), children.end());
}
std::vector<std::uint8_t> words(std::initializer_list<std::uint32_t> w) {
    std::vector<std::uint8_t> v;
    for (auto x : w)
        put32(v, x);
    return v;
}
std::vector<std::uint8_t> file(const std::vector<std::uint8_t>& children) {
    std::vector<std::uint8_t> v = {'V', 'O', 'X', ' '};
    put32(v, 150);
    chunk(v, "MAIN", {}, children);
    return v;
}
// SIZE 2x3x4 with two voxels.
std::vector<std::uint8_t> smallModel() {
    std::vector<std::uint8_t> c;
    chunk(c, "SIZE", words({2, 3, 4}));
    std::vector<std::uint8_t> xyzi = words({2});
    xyzi.insert(xyzi.end(), {0, 0, 0, 1, 1, 2, 3, 200});
    chunk(c, "XYZI", xyzi);
    return c;
}

std::string errorOf(const std::vector<std::uint8_t>& bytes) {
    try {
        ig::parseVox(bytes, "m.vox");
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

TEST(Vox, DefaultPaletteMatchesTheFormatDescription) {
    const auto& p = ig::defaultVoxPalette();
    // Entries quoted in the format's list (0xAABBGGRR): 1 = ffffffff, 2 = ffccffff,
    // 7 = ffffccff, 37 = ffffffcc, 215 = ff330000 (r = 00, g = 00, b = 33), 216 = ff0000ee,
    // 255 = ff111111.
    EXPECT_EQ(p[1], (ig::Rgba8{255, 255, 255, 255}));
    EXPECT_EQ(p[2], (ig::Rgba8{255, 255, 0xcc, 255}));
    EXPECT_EQ(p[7], (ig::Rgba8{255, 0xcc, 255, 255}));
    EXPECT_EQ(p[37], (ig::Rgba8{0xcc, 255, 255, 255}));
    EXPECT_EQ(p[215], (ig::Rgba8{0, 0, 0x33, 255}));
    EXPECT_EQ(p[216], (ig::Rgba8{0xee, 0, 0, 255}));
    EXPECT_EQ(p[226], (ig::Rgba8{0, 0xee, 0, 255}));
    EXPECT_EQ(p[236], (ig::Rgba8{0, 0, 0xee, 255}));
    EXPECT_EQ(p[255], (ig::Rgba8{0x11, 0x11, 0x11, 255}));
}

TEST(Vox, KnownBytesWithoutPaletteUseTheDefault) {
    const VoxFile f = ig::parseVox(file(smallModel()), "m.vox");
    ASSERT_EQ(f.models.size(), 1u);
    const VoxModel& m = f.models[0];
    EXPECT_EQ(m.sizeX, 2);
    EXPECT_EQ(m.sizeY, 3);
    EXPECT_EQ(m.sizeZ, 4);
    EXPECT_EQ(m.filled(), 2u);
    EXPECT_EQ(m.at(0, 0, 0), 1);
    EXPECT_EQ(m.at(1, 2, 3), 200);
    EXPECT_FALSE(f.hasPalette);
    EXPECT_EQ(f.palette, ig::defaultVoxPalette());
}

TEST(Vox, PaletteEntryIMapsToIndexIPlusOne) {
    std::vector<std::uint8_t> c = smallModel();
    std::vector<std::uint8_t> rgba(1024, 0);
    rgba[0] = 10, rgba[1] = 20, rgba[2] = 30, rgba[3] = 128;  // chunk colour 0 -> index 1
    chunk(c, "RGBA", rgba);
    const VoxFile f = ig::parseVox(file(c), "m.vox");
    EXPECT_TRUE(f.hasPalette);
    EXPECT_EQ(f.palette[1], (ig::Rgba8{10, 20, 30, 128}));
}

TEST(Vox, UnknownChunksAreSkippedBySize) {
    std::vector<std::uint8_t> c;
    chunk(c, "nTRN", std::vector<std::uint8_t>(37, 0xab));
    chunk(c, "MATL", std::vector<std::uint8_t>(5, 1), std::vector<std::uint8_t>(12, 0));
    const auto m = smallModel();
    c.insert(c.end(), m.begin(), m.end());
    chunk(c, "LAYR", std::vector<std::uint8_t>(3, 0));
    chunk(c, "rOBJ", {});
    const VoxFile f = ig::parseVox(file(c), "m.vox");
    EXPECT_EQ(f.models.size(), 1u);
    EXPECT_EQ(f.models[0].filled(), 2u);
}

TEST(Vox, RoundTripThroughTheWriter) {
    VoxFile f;
    f.palette = ig::defaultVoxPalette();
    f.palette[5] = ig::Rgba8{1, 2, 3, 100};
    f.hasPalette = true;
    for (int k = 0; k < 3; ++k) {
        VoxModel m(1 + 7 * k, 5, 256 - k);
        for (int z = 0; z < m.sizeZ; z += 3)
            for (int y = 0; y < m.sizeY; ++y)
                for (int x = 0; x < m.sizeX; x += 2)
                    m.set(x, y, z, static_cast<std::uint8_t>(1 + (x + y * 7 + z * 13 + k) % 255));
        f.models.push_back(m);
    }
    const std::filesystem::path dir = VIG_TEST_TMP;
    std::filesystem::create_directories(dir);
    const std::string path = (dir / "round_trip.vox").string();
    ig::writeVox(path, f);
    const VoxFile g = ig::readVox(path);
    ASSERT_EQ(g.models.size(), 3u);
    for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(g.models[k].sizeX, f.models[k].sizeX);
        EXPECT_EQ(g.models[k].sizeZ, f.models[k].sizeZ);
        EXPECT_EQ(g.models[k].voxels, f.models[k].voxels);
    }
    for (int i = 1; i < 256; ++i)
        EXPECT_EQ(g.palette[i], f.palette[i]) << i;
    // A second encoding is the same bytes.
    EXPECT_EQ(ig::encodeVox(g), ig::encodeVox(f));
}

TEST(Vox, EachMalformedInputIsNamed) {
    EXPECT_NE(errorOf({}).find("m.vox: empty file"), std::string::npos);
    EXPECT_NE(errorOf({'R', 'I', 'F', 'F', 0, 0, 0, 0}).find("does not start with 'VOX '"),
              std::string::npos);
    {
        auto v = file(smallModel());
        v[4] = 7;  // version 7
        EXPECT_NE(errorOf(v).find("version 7"), std::string::npos);
    }
    {
        auto v = file(smallModel());
        v.resize(v.size() - 3);  // truncated
        EXPECT_NE(errorOf(v).find("MAIN chunk at byte 8: its sizes"), std::string::npos)
            << errorOf(v);
    }
    {
        // A child chunk whose length runs past MAIN's end.
        std::vector<std::uint8_t> c = smallModel();
        std::vector<std::uint8_t> bad = {'n', 'G', 'R', 'P'};
        put32(bad, 1000);
        put32(bad, 0);
        c.insert(c.end(), bad.begin(), bad.end());
        const std::string e = errorOf(file(c));
        EXPECT_NE(e.find("'nGRP' chunk at byte"), std::string::npos) << e;
        EXPECT_NE(e.find("run past the end of its parent"), std::string::npos) << e;
    }
    {
        std::vector<std::uint8_t> c;
        chunk(c, "SIZE", words({257, 1, 1}));
        chunk(c, "XYZI", words({0}));
        EXPECT_NE(errorOf(file(c)).find("'SIZE' chunk at byte 20: side x = 257 (expected 1..256)"),
                  std::string::npos)
            << errorOf(file(c));
    }
    {
        std::vector<std::uint8_t> c;
        chunk(c, "SIZE", words({4, 4, 0}));
        EXPECT_NE(errorOf(file(c)).find("side z = 0"), std::string::npos);
    }
    {
        std::vector<std::uint8_t> c;
        chunk(c, "SIZE", words({2, 2, 2}));
        auto xyzi = words({1});
        xyzi.insert(xyzi.end(), {0, 2, 0, 1});  // y = 2 outside
        chunk(c, "XYZI", xyzi);
        const std::string e = errorOf(file(c));
        EXPECT_NE(e.find("'XYZI' chunk"), std::string::npos) << e;
        EXPECT_NE(e.find("voxel 0 at (0, 2, 0) lies outside the model's SIZE 2 x 2 x 2"),
                  std::string::npos)
            << e;
    }
    {
        std::vector<std::uint8_t> c;
        chunk(c, "SIZE", words({2, 2, 2}));
        chunk(c, "XYZI", words({1000}));  // count beyond the chunk
        EXPECT_NE(errorOf(file(c)).find("1000 voxels need 4004 bytes"), std::string::npos);
    }
    {
        std::vector<std::uint8_t> c;
        chunk(c, "XYZI", words({0}));
        EXPECT_NE(errorOf(file(c)).find("no SIZE chunk before it"), std::string::npos);
    }
    {
        std::vector<std::uint8_t> c;
        chunk(c, "SIZE", words({2, 2}));  // short content
        EXPECT_NE(errorOf(file(c)).find("content of 8 bytes, expected 12"), std::string::npos);
    }
    {
        std::vector<std::uint8_t> c;
        chunk(c, "RGBA", std::vector<std::uint8_t>(1024, 0));
        EXPECT_NE(errorOf(file(c)).find("no model"), std::string::npos);
    }
    {
        std::vector<std::uint8_t> c;
        chunk(c, "PACK", words({2}));
        const auto m = smallModel();
        c.insert(c.end(), m.begin(), m.end());
        EXPECT_NE(errorOf(file(c)).find("says 2 models, the file has 1"), std::string::npos);
    }
    {
        std::vector<std::uint8_t> c;
        chunk(c, "SIZE", words({2, 2, 2}));
        auto xyzi = words({1});
        xyzi.insert(xyzi.end(), {0, 0, 0, 0});
        chunk(c, "XYZI", xyzi);
        EXPECT_NE(errorOf(file(c)).find("colour index 0"), std::string::npos);
    }
    EXPECT_THROW(ig::readVox("/nonexistent/x.vox"), InputError);
}

}  // namespace
