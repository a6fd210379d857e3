#include "ig/terrain_db.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#if __has_include(<gdal.h>)
#include <gdal.h>
#include <ogr_srs_api.h>
#else
#include <gdal/gdal.h>
#include <gdal/ogr_srs_api.h>
#endif

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "ig/error.hpp"
#include "ig/paged_terrain.hpp"
#include "ig/pyramid.hpp"
#include "ig/slope_bound.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_db_build.hpp"
#include "ig/terrain_io.hpp"

namespace ig {
namespace {

std::string tmpPath(const std::string& name) {
    const std::filesystem::path dir =
        std::filesystem::path(VIG_TEST_TMP) / ("terrain_db-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    return (dir / name).string();
}

std::vector<char> readFile(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

void writeFile(const std::string& path, const std::vector<char>& bytes) {
    std::ofstream(path, std::ios::binary)
        .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// A map of random relief (heights spread over the whole 16-bit range, so every reduction and
// maximum is exercised) and random colours.
TerrainMap randomMap(int w, int h, unsigned seed) {
    TerrainMap map(w, h, 5.0, 7.0, 0.25, -30.0);
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> hd(0, 65535), cd(0, 255);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            map.setRaw(x, y, static_cast<std::uint16_t>(hd(rng)));
            map.setColor(
                x, y,
                Rgb8{static_cast<std::uint8_t>(cd(rng)), static_cast<std::uint8_t>(cd(rng)),
                     static_cast<std::uint8_t>(cd(rng))});
        }
    }
    map.updateRange();
    return map;
}

DbBuildStats build(const TerrainMap& map, const std::string& path, int tile, int strip = 0,
                   TileCodec codec = TileCodec::None) {
    auto source = mapRowSource(map);
    DbBuildOptions o;
    o.tileSize = tile;
    o.stripRows = strip;
    o.codec = codec;
    return buildTerrainDb(*source, path, o);
}

// Every tile of the database against the pyramid built in memory: the same samples, colours,
// cell maxima and node bounds, bit for bit.
void expectMatchesPyramid(const TerrainDb& db, const TerrainMap& map) {
    const TerrainPyramid pyr(map);
    const TerrainDbLayout& lay = db.layout();
    ASSERT_EQ(lay.displayLevels(), pyr.levelCount());
    ASSERT_EQ(lay.nodeLevels(), pyr.nodeLevelCount());
    int mismatches = 0;
    for (int k = 0; k < lay.displayLevels(); ++k) {
        const PyramidLevel& L = pyr.level(k);
        ASSERT_EQ(lay.levelWidth(k), L.width);
        ASSERT_EQ(lay.levelHeight(k), L.height);
        for (int ty = 0; ty < lay.tilesY(TileKind::Display, k); ++ty) {
            for (int tx = 0; tx < lay.tilesX(TileKind::Display, k); ++tx) {
                const TerrainTile t = db.readTile({TileKind::Display, k, tx, ty});
                for (int y = 0; y < t.height; ++y) {
                    for (int x = 0; x < t.width; ++x) {
                        const std::size_t i = static_cast<std::size_t>(y) * t.width + x;
                        mismatches += t.heights[i] != L.raw(t.x0 + x, t.y0 + y);
                        mismatches += !(t.colors[i] == L.colors[L.index(t.x0 + x, t.y0 + y)]);
                        if (x + 1 < t.width && y + 1 < t.height) {
                            mismatches +=
                                t.maxima[static_cast<std::size_t>(y) * (t.width - 1) + x] !=
                                L.cellMaxRaw(t.x0 + x, t.y0 + y);
                        }
                    }
                }
            }
        }
    }
    for (int j = 1; j < lay.nodeLevels(); ++j) {
        ASSERT_EQ(lay.nodesX(j), pyr.nodesX(j));
        ASSERT_EQ(lay.nodesY(j), pyr.nodesY(j));
        for (int ty = 0; ty < lay.tilesY(TileKind::Nodes, j); ++ty) {
            for (int tx = 0; tx < lay.tilesX(TileKind::Nodes, j); ++tx) {
                const TerrainTile t = db.readTile({TileKind::Nodes, j, tx, ty});
                for (int y = 0; y < t.height; ++y) {
                    for (int x = 0; x < t.width; ++x) {
                        mismatches += t.maxima[static_cast<std::size_t>(y) * t.width + x] !=
                                      pyr.nodeMaxRaw(j, t.x0 + x, t.y0 + y);
                    }
                }
            }
        }
    }
    EXPECT_EQ(mismatches, 0);
}

TEST(TerrainDb, StreamedLevelsEqualThePyramidBitForBit) {
    struct Case {
        int w, h, tile, strip;
    };
    // Odd and even sizes, one tile and many, thin maps whose node levels outlast the display
    // levels, strips shorter than a tile, and the smallest map.
    for (const Case c :
         {Case{300, 177, 16, 0}, Case{97, 513, 32, 7}, Case{2, 2, 16, 0}, Case{3, 40, 16, 1},
          Case{1025, 5, 16, 3}, Case{129, 129, 64, 0}, Case{257, 260, 16, 50}}) {
        SCOPED_TRACE(std::to_string(c.w) + "x" + std::to_string(c.h) + " tile " +
                     std::to_string(c.tile));
        const TerrainMap map = randomMap(c.w, c.h, static_cast<unsigned>(c.w * 31 + c.h));
        const std::string path = tmpPath("levels.db");
        build(map, path, c.tile, c.strip);
        const TerrainDb db = TerrainDb::open(path);
        EXPECT_EQ(db.info().width, c.w);
        EXPECT_EQ(db.info().spacingY, 7.0);
        EXPECT_EQ(db.info().heightOffset, -30.0);
        expectMatchesPyramid(db, map);
        // The slope section and the global bound: what the fast caster computes from the map.
        const ig::SlopeBlocks blocks(map);
        const std::size_t nb = static_cast<std::size_t>(blocks.blocksX()) * blocks.blocksY();
        EXPECT_EQ(std::memcmp(db.slopeBounds(), blocks.data(), nb * sizeof(float)), 0);
        EXPECT_EQ(db.info().maxSlope(), map.maxSlope());
    }
}

TEST(TerrainDb, SyntheticMapStreamedEqualsInMemory) {
    const TerrainMap map = makeSyntheticTerrain(512, 9, 20.0);
    const std::string a = tmpPath("syn_stream.db"), b = tmpPath("syn_map.db");
    auto source = syntheticRowSource(512, 9, 20.0);
    DbBuildOptions o;
    o.tileSize = 64;
    buildTerrainDb(*source, a, o);
    build(map, b, 64);
    // The synthetic source's rows are the generator's: the two files are the same bytes.
    EXPECT_TRUE(readFile(a) == readFile(b));
    const TerrainDb db = TerrainDb::open(a);
    expectMatchesPyramid(db, map);
    EXPECT_EQ(db.info().minRaw,
              *std::min_element(map.rawHeights().begin(), map.rawHeights().end()));
    EXPECT_EQ(db.info().maxRaw,
              *std::max_element(map.rawHeights().begin(), map.rawHeights().end()));
}

TEST(TerrainDb, SyntheticRowWindowsEqualTheWholeMap) {
    const int size = 256;
    const TerrainMap map = makeSyntheticTerrain(size, 4, 10.0);
    for (const auto& [j0, j1] : {std::pair{0, 1}, std::pair{37, 101}, std::pair{255, 256}}) {
        std::vector<std::uint16_t> h(static_cast<std::size_t>(j1 - j0) * size);
        std::vector<Rgb8> c(h.size());
        generateSyntheticRows(size, 4, 10.0, j0, j1, h.data(), c.data());
        EXPECT_TRUE(std::equal(h.begin(), h.end(), map.rawHeights().begin() + map.index(0, j0)));
        EXPECT_TRUE(std::equal(c.begin(), c.end(), map.colors().begin() + map.index(0, j0)));
    }
    EXPECT_THROW(generateSyntheticRows(3, 1, 10.0, 0, 0, nullptr, nullptr), InputError);
}

TEST(TerrainDb, SameInputSameBytesWhateverTheStrips) {
    const TerrainMap map = randomMap(200, 150, 5);
    const std::string a = tmpPath("det_a.db"), b = tmpPath("det_b.db");
    build(map, a, 32, 0);
    build(map, b, 32, 13);
    EXPECT_TRUE(readFile(a) == readFile(b));
}

TEST(TerrainDb, CodecsDecodeToTheSameTiles) {
    const TerrainMap map = makeSyntheticTerrain(256, 2);
    const std::string none = tmpPath("c_none.db");
    build(map, none, 32);
    const TerrainDb ref = TerrainDb::open(none);
    for (const TileCodec codec : {TileCodec::Lz4, TileCodec::Zstd}) {
        const std::string path = tmpPath(std::string("c_") + tileCodecName(codec) + ".db");
        build(map, path, 32, 0, codec);
        const TerrainDb db = TerrainDb::open(path);
        EXPECT_EQ(db.codec(), codec);
        EXPECT_LT(db.fileBytes(), ref.fileBytes());
        for (std::int64_t i = 0; i < db.layout().entryCount(); ++i) {
            const TileKey key = db.layout().keyAt(i);
            const TerrainTile a = ref.readTile(key), b = db.readTile(key);
            ASSERT_TRUE(a.heights == b.heights && a.colors == b.colors && a.maxima == b.maxima)
                << describeTile(key);
        }
    }
}

TEST(TerrainDb, LayoutIndexRoundTrips) {
    const TerrainDbLayout lay(1000, 333, 16);
    for (std::int64_t i = 0; i < lay.entryCount(); ++i)
        ASSERT_EQ(lay.entryIndex(lay.keyAt(i)), i);
    EXPECT_EQ(lay.entryIndex({TileKind::Display, 0, lay.tilesX(TileKind::Display, 0), 0}), -1);
    EXPECT_EQ(lay.entryIndex({TileKind::Nodes, 0, 0, 0}), -1);
}

TEST(TerrainDb, LoadMapGivesTheMapBack) {
    const TerrainMap map = randomMap(70, 90, 8);
    const std::string path = tmpPath("load.db");
    build(map, path, 16);
    const TerrainMap back = TerrainDb::open(path).loadMap();
    EXPECT_TRUE(back.rawHeights() == map.rawHeights());
    EXPECT_TRUE(back.colors() == map.colors());
    EXPECT_EQ(back.spacingX(), map.spacingX());
    EXPECT_EQ(back.heightScale(), map.heightScale());
    EXPECT_EQ(back.maxHeight(), map.maxHeight());
}

TEST(TerrainDb, UnfinishedWriteLeavesNoDatabase) {
    const std::string path = tmpPath("unfinished.db");
    std::filesystem::remove(path);
    {
        const TerrainDbLayout lay(40, 40, 16);
        TerrainDbWriter w(path, lay, TileCodec::None);
        EXPECT_TRUE(std::filesystem::exists(w.temporaryPath()));
    }
    EXPECT_FALSE(std::filesystem::exists(path));
    EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
}

// Expects opening (or reading every tile of) `path` to fail with a message holding `what`.
void expectError(const std::string& path, const std::string& what) {
    try {
        const TerrainDb db = TerrainDb::open(path);
        for (std::int64_t i = 0; i < db.layout().entryCount(); ++i)
            db.readTile(db.layout().keyAt(i));
        ADD_FAILURE() << "no error for " << path;
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
}

std::uint32_t crcOf(const char* p, std::size_t n) {
    return static_cast<std::uint32_t>(
        crc32(crc32(0L, Z_NULL, 0), reinterpret_cast<const Bytef*>(p), static_cast<uInt>(n)));
}

// Rewrites the index and header checksums after an edit of the index.
void resealIndex(std::vector<char>& f) {
    std::uint64_t indexOffset = 0, entries = 0;
    std::memcpy(&indexOffset, f.data() + 88, 8);
    std::memcpy(&entries, f.data() + 96, 8);
    const std::uint32_t ic = crcOf(f.data() + indexOffset, entries * 24);
    std::memcpy(f.data() + 104, &ic, 4);
    const std::uint32_t hc = crcOf(f.data(), 252);
    std::memcpy(f.data() + 252, &hc, 4);
}

TEST(TerrainDb, BadFilesAreClearErrorsNamingFileAndTile) {
    const TerrainMap map = randomMap(100, 100, 3);
    const std::string good = tmpPath("good.db");
    build(map, good, 32);
    const std::vector<char> bytes = readFile(good);
    const std::string bad = tmpPath("bad.db");

    writeFile(bad, std::vector<char>(bytes.begin(), bytes.begin() + 100));
    expectError(bad, "not a terrain database");

    std::vector<char> f = bytes;
    f[8] = 4;  // version
    writeFile(bad, f);
    expectError(bad, "format version 4");
    f[8] = 1;  // without the slope section
    writeFile(bad, f);
    expectError(bad, "format version 1");
    // Version 2 (without the insets table) is read, holding no insets.
    f[8] = 2;
    const std::uint32_t hc = crcOf(f.data(), 252);
    std::memcpy(f.data() + 252, &hc, 4);
    writeFile(bad, f);
    EXPECT_TRUE(TerrainDb::open(bad).insets().empty());

    // A flipped byte in the slope section (right after the header).
    f = bytes;
    f[256 + 5] ^= 0x10;
    writeFile(bad, f);
    expectError(bad, "slope section checksum mismatch");

    writeFile(bad, std::vector<char>(bytes.begin(), bytes.begin() + bytes.size() / 2));
    expectError(bad, "truncated");

    // A flipped byte inside display tile (0, 1, 2): its checksum fails, and the message says
    // which tile.
    const TerrainDb db = TerrainDb::open(good);
    const std::int64_t i = db.layout().entryIndex({TileKind::Display, 0, 1, 2});
    std::uint64_t off = 0;
    std::memcpy(
        &off,
        bytes.data() + 0 +
            [&] {
                std::uint64_t io = 0;
                std::memcpy(&io, bytes.data() + 88, 8);
                return io;
            }() +
            i * 24,
        8);
    f = bytes;
    f[off + 100] ^= 0x40;
    writeFile(bad, f);
    expectError(bad, "display tile (level 0, 1, 2): checksum mismatch");

    // Index entries of two tiles of the same size swapped (checksums resealed): the tile's own
    // header disagrees with the index.
    f = bytes;
    std::uint64_t io = 0;
    std::memcpy(&io, f.data() + 88, 8);
    const std::int64_t a = db.layout().entryIndex({TileKind::Display, 0, 0, 0});
    const std::int64_t b = db.layout().entryIndex({TileKind::Display, 0, 1, 0});
    std::swap_ranges(f.begin() + static_cast<std::ptrdiff_t>(io + a * 24),
                     f.begin() + static_cast<std::ptrdiff_t>(io + a * 24 + 24),
                     f.begin() + static_cast<std::ptrdiff_t>(io + b * 24));
    resealIndex(f);
    writeFile(bad, f);
    expectError(bad, "display tile (level 0, 0, 0): the index disagrees with the tile");

    // An index entry pointing past the tiles.
    f = bytes;
    const std::uint64_t far = bytes.size();
    std::memcpy(f.data() + io + a * 24, &far, 8);
    resealIndex(f);
    writeFile(bad, f);
    expectError(bad, "index entry of display tile (level 0, 0, 0) disagrees");

    // The index itself damaged without resealing.
    f = bytes;
    f[io + 5] ^= 1;
    writeFile(bad, f);
    expectError(bad, "index checksum mismatch");
}

void writeGeoTiff(const std::string& path, int w, int h, int bands, GDALDataType type,
                  const void* data, const double* gt) {
    GDALAllRegister();
    GDALDriverH drv = GDALGetDriverByName("GTiff");
    ASSERT_NE(drv, nullptr);
    char photometric[] = "PHOTOMETRIC=RGB";
    char* options[] = {bands == 3 ? photometric : nullptr, nullptr};
    GDALDatasetH ds = GDALCreate(drv, path.c_str(), w, h, bands, type, options);
    ASSERT_NE(ds, nullptr) << path;
    double copy[6];
    std::copy(gt, gt + 6, copy);
    GDALSetGeoTransform(ds, copy);
    OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
    OSRSetFromUserInput(srs, "EPSG:32610");
    GDALSetSpatialRef(ds, srs);
    OSRDestroySpatialReference(srs);
    const CPLErr rc = GDALDatasetRasterIO(ds, GF_Write, 0, 0, w, h, const_cast<void*>(data), w, h,
                                          type, bands, nullptr, 0, 0, 0);
    GDALClose(ds);
    ASSERT_EQ(rc, CE_None) << path;
}

TEST(TerrainDb, GdalStreamedEqualsTheWholeMapLoader) {
    const int w = 301, h = 203;
    std::vector<std::uint16_t> z(static_cast<std::size_t>(w) * h);
    std::vector<std::uint8_t> rgb(z.size() * 3);
    std::mt19937 rng(11);
    for (auto& v : z)
        v = static_cast<std::uint16_t>(rng() % 4000 + 100);
    for (auto& v : rgb)
        v = static_cast<std::uint8_t>(rng());
    const double gt[6] = {500000.0, 30.0, 0.0, 5200000.0, 0.0, -30.0};
    TerrainSource src;
    src.heightPath = tmpPath("g_h.tif");
    src.colorPath = tmpPath("g_c.tif");
    writeGeoTiff(src.heightPath, w, h, 1, GDT_UInt16, z.data(), gt);
    writeGeoTiff(src.colorPath, w, h, 3, GDT_Byte, rgb.data(), gt);

    std::string why;
    auto source = gdalRowSource(src, why);
    ASSERT_TRUE(source) << why;
    const TerrainDbInfo info = source->info();
    EXPECT_DOUBLE_EQ(info.spacingX, 30.0);
    EXPECT_DOUBLE_EQ(info.originX, 500015.0);
    EXPECT_DOUBLE_EQ(info.originY, 5200000.0 - 202.5 * 30.0);
    EXPECT_NE(info.crs.find("UTM"), std::string::npos);
    DbBuildOptions o;
    o.tileSize = 64;
    o.stripRows = 17;
    const std::string path = tmpPath("gdal.db");
    buildTerrainDb(*source, path, o);
    const TerrainMap map = loadTerrain(src);
    const TerrainDb db = TerrainDb::open(path);
    EXPECT_EQ(db.info().heightScale, map.heightScale());
    EXPECT_EQ(db.info().heightOffset, map.heightOffset());
    EXPECT_EQ(db.info().crs, info.crs);
    expectMatchesPyramid(db, map);

    // The georeference travels with the map: loaded from the files, from the database whole,
    // and paged; and gives the origin's latitude and longitude (UTM 10N, 15 m east of the
    // central meridian -123, northing 5193925 m: 46.899 N).
    for (const TerrainMap* m : {&map}) {
        EXPECT_TRUE(m->georeference().present());
        EXPECT_DOUBLE_EQ(m->georeference().originX, info.originX);
        EXPECT_DOUBLE_EQ(m->georeference().originY, info.originY);
        EXPECT_EQ(m->georeference().crs, info.crs);
    }
    const TerrainMap fromDb = db.loadMap();
    EXPECT_DOUBLE_EQ(fromDb.georeference().originX, info.originX);
    EXPECT_DOUBLE_EQ(fromDb.georeference().originY, info.originY);
    EXPECT_EQ(fromDb.georeference().crs, info.crs);
    PagedTerrain::Options po;
    po.cache.budgetBytes = std::size_t{1} << 20;
    const PagedTerrain paged(db, po);
    EXPECT_DOUBLE_EQ(paged.map().georeference().originY, info.originY);
    EXPECT_EQ(paged.map().georeference().crs, info.crs);
    const auto geo = geodeticOrigin(fromDb.georeference());
    ASSERT_TRUE(geo);
    EXPECT_NEAR((*geo)[0], 46.899, 0.01);
    EXPECT_NEAR((*geo)[1], -123.0 + 15.0 / (111320.0 * std::cos(46.899 * M_PI / 180.0)), 1e-4);
    EXPECT_FALSE(geodeticOrigin(makeSyntheticTerrain(16, 1).georeference()));

    // Without a colour image the heights are shaded over the whole map: not streamed, said why.
    src.colorPath.clear();
    EXPECT_FALSE(gdalRowSource(src, why));
    EXPECT_NE(why.find("colour"), std::string::npos);
    // A file that is no raster is an error naming it.
    src.heightPath = tmpPath("not_raster.tif");
    src.colorPath = tmpPath("g_c.tif");
    std::ofstream(src.heightPath) << "not a raster";
    try {
        gdalRowSource(src, why);
        ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("not_raster.tif"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace ig
