// Insets read from georeferenced rasters through the command-line loader (ig/cli.hpp):
// placed by their georeference on the global grid, or refused with a reason when they do not
// continue it (between samples, another coordinate system, a spacing that is not the global
// one over a whole number).
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/inset.hpp"

#include <gtest/gtest.h>

#if __has_include(<gdal.h>)
#include <gdal.h>
#include <ogr_srs_api.h>
#else
#include <gdal/gdal.h>
#include <gdal/ogr_srs_api.h>
#endif

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

namespace ig {
namespace {

// A file of this process alone (the tests of this file run in parallel, each in a process).
std::string tmpPath(const std::string& name) {
    std::filesystem::create_directories(VIG_TEST_TMP);
    return std::string(VIG_TEST_TMP) + "/inset_raster_" + std::to_string(::getpid()) + "_" + name;
}

// Heights in metres at UTM (x, y): broad hills, and detail only the finer raster resolves.
double broad(double x, double y) {
    return 300.0 + 80.0 * std::sin(x / 700.0) * std::cos(y / 900.0);
}
double detail(double x, double y) {
    return 6.0 * std::sin(x / 13.0) * std::sin(y / 17.0);
}

// A w x h float GeoTIFF of `z(x, y)` at the pixel centres, north up, its top-left corner at
// (left, top), `cell` metres a pixel, in EPSG `epsg`.
template <typename Z>
void writeDem(const std::string& path, int w, int h, double left, double top, double cell, int epsg,
              Z z) {
    GDALAllRegister();
    GDALDriverH drv = GDALGetDriverByName("GTiff");
    ASSERT_NE(drv, nullptr);
    GDALDatasetH ds = GDALCreate(drv, path.c_str(), w, h, 1, GDT_Float32, nullptr);
    ASSERT_NE(ds, nullptr);
    double gt[6] = {left, cell, 0.0, top, 0.0, -cell};
    GDALSetGeoTransform(ds, gt);
    OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
    ASSERT_EQ(OSRImportFromEPSG(srs, epsg), OGRERR_NONE);
    GDALSetSpatialRef(ds, srs);
    OSRDestroySpatialReference(srs);
    std::vector<float> v(static_cast<std::size_t>(w) * h);
    for (int r = 0; r < h; ++r) {
        for (int c = 0; c < w; ++c) {
            v[static_cast<std::size_t>(r) * w + c] =
                static_cast<float>(z(left + (c + 0.5) * cell, top - (r + 0.5) * cell));
        }
    }
    const CPLErr rc = GDALDatasetRasterIO(ds, GF_Write, 0, 0, w, h, v.data(), w, h, GDT_Float32, 1,
                                          nullptr, 0, 0, 0);
    GDALClose(ds);
    ASSERT_EQ(rc, CE_None);
}

constexpr double kLeft = 500000.0, kTop = 4200000.0, kCell = 40.0;
constexpr int kSize = 65;

struct Files {
    std::string global = tmpPath("global.tif");
    Files() { writeDem(global, kSize, kSize, kLeft, kTop, kCell, 32610, broad); }
    ~Files() { std::filesystem::remove(global); }
};

// An inset `factor` times finer whose south-west sample lies at global sample (i + di, j + dj)
// (fractions allowed), `cells` global cells a side (plus `extra` samples), in EPSG `epsg`.
std::string writeInset(const std::string& name, double i, double j, int cells, int factor,
                       int epsg = 32610, int extra = 0) {
    const double fine = kCell / factor;
    const int n = cells * factor + 1 + extra;
    // The global sample (0, 0) is the south-west pixel's centre.
    const double x0 = kLeft + 0.5 * kCell + i * kCell,
                 y0 = kTop - (kSize - 0.5) * kCell + j * kCell;
    const std::string path = tmpPath(name);
    writeDem(path, n, n, x0 - 0.5 * fine, y0 + (n - 0.5) * fine, fine, epsg,
             [](double x, double y) { return broad(x, y) + detail(x, y); });
    return path;
}

TEST(InsetRasters, PlacedByTheirGeoreference) {
    const Files files;
    TerrainOptions terrain;
    terrain.height = files.global;
    InsetOptions insets;
    const std::string path = writeInset("fine.tif", 16, 20, 12, 4, 32610, 3);
    insets.specs = {path};
    const NestedTerrain t = loadNestedTerrain(loadTerrainFromOptions(terrain), terrain, insets);
    ASSERT_EQ(t.insets().size(), 1u);
    const Inset& in = t.insets()[0];
    EXPECT_EQ(in.x0, 16);
    EXPECT_EQ(in.y0, 20);
    EXPECT_EQ(in.factor, 4);
    // Cut to whole global cells: the three extra samples dropped.
    EXPECT_EQ(in.x1, 28);
    EXPECT_EQ(in.y1, 32);
    EXPECT_NEAR(in.map.spacingX(), 10.0, 1e-9);
    // Inside, past the blend (16 cells of 10 m), the nested surface is the fine raster's (to its
    // quantisation). World (0, 0) is the global south-west sample: UTM (ox, oy).
    const double ox = kLeft + 0.5 * kCell, oy = kTop - (kSize - 0.5) * kCell;
    double worst = 0.0;
    for (double x = in.coverMin.x + 165.0; x < in.coverMax.x - 165.0; x += 3.7) {
        for (double y = in.coverMin.y + 165.0; y < in.coverMax.y - 165.0; y += 4.1) {
            // The fine raster's bilinear surface at the nearest of its samples.
            const double fx = std::round((x - in.coverMin.x) / 10.0) * 10.0 + in.coverMin.x;
            const double fy = std::round((y - in.coverMin.y) / 10.0) * 10.0 + in.coverMin.y;
            const double utmX = fx + ox, utmY = fy + oy;
            worst = std::max(worst, std::abs(t.surfaceHeight(fx, fy) -
                                             (broad(utmX, utmY) + detail(utmX, utmY))));
        }
    }
    EXPECT_LE(worst, 0.01);
    std::filesystem::remove(path);
}

TEST(InsetRasters, ThatDoNotContinueTheGlobalGridAreRefused) {
    const Files files;
    TerrainOptions terrain;
    terrain.height = files.global;
    auto refused = [&](const std::string& path, const std::string& words) {
        InsetOptions insets;
        insets.specs = {path};
        try {
            (void)loadNestedTerrain(loadTerrainFromOptions(terrain), terrain, insets);
            ADD_FAILURE() << path << ": accepted";
        } catch (const InputError& e) {
            const std::string m = e.what();
            EXPECT_NE(m.find(path), std::string::npos) << m;
            EXPECT_NE(m.find(words), std::string::npos) << m;
        }
        std::filesystem::remove(path);
    };
    refused(writeInset("half.tif", 16.5, 20, 8, 4), "between global samples");
    refused(writeInset("wgs.tif", 16, 20, 8, 4, 32611), "coordinate system");
    refused(writeInset("third.tif", 16, 20, 8, 3), "power of two");
    refused(writeInset("off.tif", 60, 60, 8, 4), "outside");
}

}  // namespace
}  // namespace ig
