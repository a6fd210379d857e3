#include "ig/terrain_io.hpp"

#include <gtest/gtest.h>
#include <jpeglib.h>
#include <png.h>

#if __has_include(<gdal.h>)
#include <gdal.h>
#include <ogr_srs_api.h>
#else
#include <gdal/gdal.h>
#include <gdal/ogr_srs_api.h>
#endif

#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "ig/error.hpp"

namespace {

using ig::fillVoids;
using ig::InputError;
using ig::loadTerrain;
using ig::Rgb8;
using ig::TerrainMap;
using ig::TerrainSource;

std::string tmpPath(const std::string& name) {
    const std::filesystem::path dir = std::filesystem::path(VIG_TEST_TMP) / "terrain_io";
    std::filesystem::create_directories(dir);
    return (dir / name).string();
}

// --- Fixture writers ---------------------------------------------------------------------------

[[noreturn]] void pngWriteError(png_structp png, png_const_charp) {
    png_longjmp(png, 1);
}

bool pngWriteRows(png_structp png, png_infop info, std::FILE* f, int w, int h, int colorType,
                  int bitDepth, const png_color* palette, int paletteSize, png_bytepp rows) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_init_io(png, f);
    png_set_IHDR(png, info, w, h, bitDepth, colorType, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    if (paletteSize > 0) png_set_PLTE(png, info, palette, paletteSize);
    png_write_info(png, info);
    png_write_image(png, rows);
    png_write_end(png, nullptr);
    return true;
}

// Writes a PNG of any type from packed rows (top first) exactly as the format stores them.
void writePng(const std::string& path, int w, int h, int colorType, int bitDepth,
              const std::vector<std::uint8_t>& bytes, const std::vector<png_color>& palette = {}) {
    const std::size_t rowBytes = bytes.size() / h;
    std::vector<png_bytep> rows(h);
    std::vector<std::uint8_t> copy = bytes;
    for (int y = 0; y < h; ++y)
        rows[y] = copy.data() + y * rowBytes;
    std::FILE* f = std::fopen(path.c_str(), "wb");
    ASSERT_NE(f, nullptr) << path;
    png_structp png =
        png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, pngWriteError, nullptr);
    png_infop info = png_create_info_struct(png);
    const bool ok = pngWriteRows(png, info, f, w, h, colorType, bitDepth, palette.data(),
                                 static_cast<int>(palette.size()), rows.data());
    png_destroy_write_struct(&png, &info);
    std::fclose(f);
    ASSERT_TRUE(ok) << path;
}

void writePng16Grey(const std::string& path, int w, int h, const std::vector<std::uint16_t>& v) {
    std::vector<std::uint8_t> bytes;
    for (std::uint16_t s : v) {
        bytes.push_back(static_cast<std::uint8_t>(s >> 8));
        bytes.push_back(static_cast<std::uint8_t>(s & 0xFF));
    }
    writePng(path, w, h, PNG_COLOR_TYPE_GRAY, 16, bytes);
}

void writePngRgb(const std::string& path, int w, int h, const std::vector<Rgb8>& px) {
    std::vector<std::uint8_t> bytes;
    for (Rgb8 c : px)
        bytes.insert(bytes.end(), {c.r, c.g, c.b});
    writePng(path, w, h, PNG_COLOR_TYPE_RGB, 8, bytes);
}

void writeJpegRgb(const std::string& path, int w, int h, const std::vector<Rgb8>& px,
                  int channels = 3) {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    ASSERT_NE(f, nullptr) << path;
    jpeg_compress_struct c{};
    jpeg_error_mgr err{};
    c.err = jpeg_std_error(&err);
    jpeg_create_compress(&c);
    jpeg_stdio_dest(&c, f);
    c.image_width = w;
    c.image_height = h;
    c.input_components = channels;
    c.in_color_space = channels == 3 ? JCS_RGB : JCS_GRAYSCALE;
    jpeg_set_defaults(&c);
    jpeg_set_quality(&c, 100, TRUE);
    for (int k = 0; k < c.num_components; ++k) {  // no chroma subsampling
        c.comp_info[k].h_samp_factor = 1;
        c.comp_info[k].v_samp_factor = 1;
    }
    jpeg_start_compress(&c, TRUE);
    std::vector<std::uint8_t> row(static_cast<std::size_t>(w) * channels);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const Rgb8 p = px[static_cast<std::size_t>(y) * w + x];
            if (channels == 3) {
                row[3 * x] = p.r;
                row[3 * x + 1] = p.g;
                row[3 * x + 2] = p.b;
            } else {
                row[x] = p.r;
            }
        }
        JSAMPROW r = row.data();
        jpeg_write_scanlines(&c, &r, 1);
    }
    jpeg_finish_compress(&c);
    jpeg_destroy_compress(&c);
    std::fclose(f);
}

// Writes a GeoTIFF, band-sequential data, optional geotransform (WGS84 when `geographic`).
void writeGeoTiff(const std::string& path, int w, int h, int bands, GDALDataType type,
                  const void* data, const double* gt, bool geographic = true,
                  const double* noData = nullptr) {
    GDALAllRegister();
    GDALDriverH drv = GDALGetDriverByName("GTiff");
    ASSERT_NE(drv, nullptr);
    char photometric[] = "PHOTOMETRIC=RGB";
    char* options[] = {bands == 3 ? photometric : nullptr, nullptr};
    GDALDatasetH ds = GDALCreate(drv, path.c_str(), w, h, bands, type, options);
    ASSERT_NE(ds, nullptr) << path;
    if (gt) {
        double copy[6];
        std::copy(gt, gt + 6, copy);
        GDALSetGeoTransform(ds, copy);
        if (geographic) {
            OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
            OSRSetWellKnownGeogCS(srs, "WGS84");
            GDALSetSpatialRef(ds, srs);
            OSRDestroySpatialReference(srs);
        }
    }
    if (noData) GDALSetRasterNoDataValue(GDALGetRasterBand(ds, 1), *noData);
    const CPLErr rc = GDALDatasetRasterIO(ds, GF_Write, 0, 0, w, h, const_cast<void*>(data), w, h,
                                          type, bands, nullptr, 0, 0, 0);
    GDALClose(ds);
    ASSERT_EQ(rc, CE_None) << path;
}

void writeText(const std::string& path, const std::string& text) {
    std::ofstream(path, std::ios::binary) << text;
}

// Reads an 8-bit RGB PNG with libpng's simplified API (rows top first).
std::vector<Rgb8> readPngRgb(const std::string& path, int& w, int& h) {
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    EXPECT_TRUE(png_image_begin_read_from_file(&image, path.c_str())) << path;
    image.format = PNG_FORMAT_RGB;
    w = static_cast<int>(image.width);
    h = static_cast<int>(image.height);
    std::vector<Rgb8> px(static_cast<std::size_t>(w) * h);
    EXPECT_TRUE(png_image_finish_read(&image, nullptr, px.data(), 0, nullptr)) << path;
    return px;
}

// Expects loadTerrain(src) to throw InputError whose message contains every `needles` entry.
void expectInputError(const TerrainSource& src, const std::vector<std::string>& needles) {
    try {
        loadTerrain(src);
        ADD_FAILURE() << "no error for " << src.heightPath << " / " << src.colorPath;
    } catch (const InputError& e) {
        const std::string msg = e.what();
        for (const std::string& n : needles) {
            EXPECT_NE(msg.find(n), std::string::npos) << "message: " << msg << "\nmissing: " << n;
        }
    }
}

// --- Grid convention ----------------------------------------------------------------------------

TEST(TerrainIo, GridConventionNorthRowLastInMemory) {
    const int w = 3, h = 2;
    std::vector<std::uint16_t> heights(w * h);
    std::vector<Rgb8> colors(w * h);
    for (int r = 0; r < h; ++r) {
        for (int c = 0; c < w; ++c) {
            heights[r * w + c] = static_cast<std::uint16_t>(1000 * r + 10 * c + 7);
            colors[r * w + c] = Rgb8{static_cast<std::uint8_t>(40 * c + 1),
                                     static_cast<std::uint8_t>(100 * r + 2), 200};
        }
    }
    TerrainSource src;
    src.heightPath = tmpPath("grid_h.png");
    src.colorPath = tmpPath("grid_c.png");
    writePng16Grey(src.heightPath, w, h, heights);
    writePngRgb(src.colorPath, w, h, colors);
    src.spacing = 5.0;
    src.heightScale = 0.5;
    src.heightOffset = -20.0;
    const TerrainMap map = loadTerrain(src);
    ASSERT_EQ(map.width(), w);
    ASSERT_EQ(map.height(), h);
    EXPECT_EQ(map.spacingX(), 5.0);
    EXPECT_EQ(map.spacingY(), 5.0);
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix) {
            const int fileRow = h - 1 - iy;  // file row 0 is the north edge, stored last
            EXPECT_EQ(map.raw(ix, iy), heights[fileRow * w + ix]) << ix << "," << iy;
            EXPECT_DOUBLE_EQ(map.heightAt(ix, iy), heights[fileRow * w + ix] * 0.5 - 20.0);
            EXPECT_EQ(map.colorAt(ix, iy), colors[fileRow * w + ix]) << ix << "," << iy;
        }
    }
    // Sample (ix, iy) sits at x = ix * spacing, y = iy * spacing.
    EXPECT_DOUBLE_EQ(map.surfaceHeight(2 * 5.0, 1 * 5.0), heights[0 * w + 2] * 0.5 - 20.0);
}

TEST(TerrainIo, EightBitPngHeightsDefaultScaleAndSpacing) {
    const int w = 5, h = 4;
    std::vector<std::uint8_t> bytes(w * h);
    for (int k = 0; k < w * h; ++k)
        bytes[k] = static_cast<std::uint8_t>(k * 13 % 256);
    TerrainSource src;
    src.heightPath = tmpPath("h8.png");
    writePng(src.heightPath, w, h, PNG_COLOR_TYPE_GRAY, 8, bytes);
    const TerrainMap map = loadTerrain(src);
    EXPECT_EQ(map.spacingX(), ig::kDefaultSpacing);
    EXPECT_EQ(map.spacingY(), ig::kDefaultSpacing);
    EXPECT_EQ(map.heightScale(), 1.0);
    EXPECT_EQ(map.heightOffset(), 0.0);
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix) {
            EXPECT_EQ(map.raw(ix, iy), bytes[(h - 1 - iy) * w + ix]);
        }
    }
    // No colour image: shaded from the heights, so not all black.
    bool anyLit = false;
    for (Rgb8 c : map.colors())
        anyLit |= c.r + c.g + c.b > 0;
    EXPECT_TRUE(anyLit);
}

TEST(TerrainIo, SixteenBitPngKeepsFullRange) {
    const int w = 4, h = 3;
    std::vector<std::uint16_t> v = {0,     1,     255,   256,   4095,  32767,
                                    32768, 40000, 65534, 65535, 12345, 54321};
    TerrainSource src;
    src.heightPath = tmpPath("h16.png");
    writePng16Grey(src.heightPath, w, h, v);
    const TerrainMap map = loadTerrain(src);
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix)
            EXPECT_EQ(map.raw(ix, iy), v[(h - 1 - iy) * w + ix]);
    }
    EXPECT_EQ(map.minHeight(), 0.0);
    EXPECT_EQ(map.maxHeight(), 65535.0);
}

TEST(TerrainIo, GreyAndPaletteColourImagesExpandToRgb) {
    const int w = 4, h = 2;
    TerrainSource src;
    src.heightPath = tmpPath("pal_h.png");
    writePng16Grey(src.heightPath, w, h, std::vector<std::uint16_t>(w * h, 5));
    // Grey colour image.
    std::vector<std::uint8_t> grey(w * h);
    for (int k = 0; k < w * h; ++k)
        grey[k] = static_cast<std::uint8_t>(30 * k);
    src.colorPath = tmpPath("grey_c.png");
    writePng(src.colorPath, w, h, PNG_COLOR_TYPE_GRAY, 8, grey);
    TerrainMap map = loadTerrain(src);
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix) {
            const std::uint8_t g = grey[(h - 1 - iy) * w + ix];
            EXPECT_EQ(map.colorAt(ix, iy), (Rgb8{g, g, g}));
        }
    }
    // Palette colour image.
    const std::vector<png_color> palette = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {9, 8, 7}};
    std::vector<std::uint8_t> idx(w * h);
    for (int k = 0; k < w * h; ++k)
        idx[k] = static_cast<std::uint8_t>(k % 4);
    src.colorPath = tmpPath("pal_c.png");
    writePng(src.colorPath, w, h, PNG_COLOR_TYPE_PALETTE, 8, idx, palette);
    map = loadTerrain(src);
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix) {
            const png_color p = palette[idx[(h - 1 - iy) * w + ix]];
            EXPECT_EQ(map.colorAt(ix, iy), (Rgb8{p.red, p.green, p.blue}));
        }
    }
}

TEST(TerrainIo, JpegColourAndGreyJpegHeights) {
    const int w = 16, h = 8;
    std::vector<Rgb8> px(w * h);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            px[y * w + x] = Rgb8{static_cast<std::uint8_t>(16 * x),
                                 static_cast<std::uint8_t>(30 * y), static_cast<std::uint8_t>(128)};
        }
    }
    TerrainSource src;
    src.heightPath = tmpPath("jpg_h.jpg");
    src.colorPath = tmpPath("jpg_c.jpg");
    writeJpegRgb(src.heightPath, w, h, px, 1);  // grey: the red ramp
    writeJpegRgb(src.colorPath, w, h, px, 3);
    const TerrainMap map = loadTerrain(src);
    ASSERT_EQ(map.width(), w);
    ASSERT_EQ(map.height(), h);
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix) {
            const Rgb8 want = px[(h - 1 - iy) * w + ix];
            const Rgb8 got = map.colorAt(ix, iy);
            // JPEG is lossy; at quality 100 without subsampling a ramp comes back close.
            EXPECT_NEAR(got.r, want.r, 6) << ix << "," << iy;
            EXPECT_NEAR(got.g, want.g, 6) << ix << "," << iy;
            EXPECT_NEAR(got.b, want.b, 6) << ix << "," << iy;
            EXPECT_NEAR(map.raw(ix, iy), want.r, 4) << ix << "," << iy;
        }
    }
}

// --- GeoTIFF ------------------------------------------------------------------------------------

TEST(TerrainIo, GeoTiffGeographicSpacingAndQuantisation) {
    const int w = 7, h = 5;
    const double gt[6] = {-119.9, 3.0e-5, 0, 34.5, 0, -2.5e-5};
    std::vector<float> z(w * h);
    for (int r = 0; r < h; ++r) {
        for (int c = 0; c < w; ++c)
            z[r * w + c] = 2.5f + 0.37f * c * c + 1.9f * r;
    }
    std::vector<std::uint8_t> rgb(3 * w * h);  // band-sequential
    for (int k = 0; k < w * h; ++k) {
        rgb[k] = static_cast<std::uint8_t>(k);
        rgb[w * h + k] = static_cast<std::uint8_t>(2 * k);
        rgb[2 * w * h + k] = static_cast<std::uint8_t>(255 - k);
    }
    TerrainSource src;
    src.heightPath = tmpPath("geo_h.tif");
    src.colorPath = tmpPath("geo_c.tif");
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float32, z.data(), gt);
    writeGeoTiff(src.colorPath, w, h, 3, GDT_Byte, rgb.data(), gt);
    const TerrainMap map = loadTerrain(src);
    ASSERT_EQ(map.width(), w);
    ASSERT_EQ(map.height(), h);

    const double lat = (gt[3] + gt[5] * h / 2) * std::numbers::pi / 180;
    const double mLat = 111132.954 - 559.822 * std::cos(2 * lat) + 1.175 * std::cos(4 * lat);
    const double mLon = 111412.84 * std::cos(lat) - 93.5 * std::cos(3 * lat);
    EXPECT_NEAR(map.spacingX(), gt[1] * mLon, 1e-9);
    EXPECT_NEAR(map.spacingY(), -gt[5] * mLat, 1e-9);
    EXPECT_GT(map.spacingY(), map.spacingX());  // a degree of longitude is shorter at 34 N

    const auto [lo, hi] = std::minmax_element(z.begin(), z.end());
    const double quantum = (*hi - *lo) / 65535.0;
    EXPECT_NEAR(map.heightScale(), quantum, 1e-12);
    EXPECT_NEAR(map.minHeight(), *lo, 1e-9);
    EXPECT_NEAR(map.maxHeight(), *hi, quantum);
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix) {
            const int k = (h - 1 - iy) * w + ix;
            EXPECT_NEAR(map.heightAt(ix, iy), z[k], quantum / 2 + 1e-9) << ix << "," << iy;
            // Same geotransform: one colour per sample, exactly.
            EXPECT_EQ(map.colorAt(ix, iy), (Rgb8{rgb[k], rgb[w * h + k], rgb[2 * w * h + k]}));
        }
    }
}

TEST(TerrainIo, GeoTiffUserScaleAndSpacingOverride) {
    const int w = 4, h = 3;
    const double gt[6] = {500000, 30, 0, 4000000, 0, -30};  // no SRS: linear units
    std::vector<std::int16_t> z = {0, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 110};
    TerrainSource src;
    src.heightPath = tmpPath("geo_int.tif");
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Int16, z.data(), gt, false);
    TerrainMap map = loadTerrain(src);
    EXPECT_DOUBLE_EQ(map.spacingX(), 30.0);
    EXPECT_DOUBLE_EQ(map.spacingY(), 30.0);
    src.spacing = 12.5;
    src.heightScale = 0.3048;  // feet
    src.heightOffset = 100.0;
    map = loadTerrain(src);
    EXPECT_EQ(map.spacingX(), 12.5);
    EXPECT_EQ(map.spacingY(), 12.5);
    const double quantum = 110 * 0.3048 / 65535.0;
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix) {
            EXPECT_NEAR(map.heightAt(ix, iy), z[(h - 1 - iy) * w + ix] * 0.3048 + 100.0,
                        quantum / 2 + 1e-9);
        }
    }
}

TEST(TerrainIo, GeoTiffSouthUpRowsAreNotFlipped) {
    const int w = 3, h = 4;
    const double gt[6] = {0, 10, 0, 0, 0, 10};  // row 0 is the south edge
    std::vector<float> z(w * h);
    for (int k = 0; k < w * h; ++k)
        z[k] = static_cast<float>(k);
    TerrainSource src;
    src.heightPath = tmpPath("southup.tif");
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float32, z.data(), gt, false);
    const TerrainMap map = loadTerrain(src);
    const double quantum = 11.0 / 65535.0;
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix) {
            EXPECT_NEAR(map.heightAt(ix, iy), z[iy * w + ix], quantum);
        }
    }
}

TEST(TerrainIo, GeoTiffConstantHeights) {
    const int w = 3, h = 3;
    std::vector<double> z(w * h, 42.25);
    TerrainSource src;
    src.heightPath = tmpPath("flat.tif");
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float64, z.data(), nullptr);
    const TerrainMap map = loadTerrain(src);
    EXPECT_EQ(map.heightScale(), 1.0);
    EXPECT_EQ(map.heightOffset(), 42.25);
    for (std::uint16_t r : map.rawHeights())
        EXPECT_EQ(r, 0);
    EXPECT_EQ(map.spacingX(), ig::kDefaultSpacing);
}

TEST(TerrainIo, ColourResampledOntoLargerHeightGrid) {
    // 5 heights over the extent of 4 texels: sample i at i/4 of the extent, texel k at (k+0.5)/4.
    const int hw = 5, hh = 5, cw = 4, ch = 4;
    TerrainSource src;
    src.heightPath = tmpPath("rs_h.png");
    src.colorPath = tmpPath("rs_c.png");
    writePng16Grey(src.heightPath, hw, hh, std::vector<std::uint16_t>(hw * hh, 1));
    std::vector<Rgb8> tex(cw * ch);
    for (int y = 0; y < ch; ++y) {
        for (int x = 0; x < cw; ++x) {
            tex[y * cw + x] =
                Rgb8{static_cast<std::uint8_t>(60 * x), static_cast<std::uint8_t>(70 * y),
                     static_cast<std::uint8_t>(20 * x + 10 * y)};
        }
    }
    writePngRgb(src.colorPath, cw, ch, tex);
    const TerrainMap map = loadTerrain(src);
    for (int iy = 0; iy < hh; ++iy) {
        for (int ix = 0; ix < hw; ++ix) {
            const int row = hh - 1 - iy;
            // Texel coordinates (centres at integers), clamped at the edges.
            const double u = std::clamp(ix * double(cw) / (hw - 1) - 0.5, 0.0, cw - 1.0);
            const double v = std::clamp(row * double(ch) / (hh - 1) - 0.5, 0.0, ch - 1.0);
            // The texture is linear in x and y, so bilinear interpolation is exact.
            const Rgb8 got = map.colorAt(ix, iy);
            EXPECT_NEAR(got.r, 60 * u, 0.51) << ix << "," << iy;
            EXPECT_NEAR(got.g, 70 * v, 0.51) << ix << "," << iy;
            EXPECT_NEAR(got.b, 20 * u + 10 * v, 0.51) << ix << "," << iy;
        }
    }
}

// --- Shipped data -------------------------------------------------------------------------------

TEST(TerrainIo, PugetSoundShippedDefault) {
    const TerrainMap map = ig::loadPugetSound();
    ASSERT_EQ(map.width(), 1025);
    ASSERT_EQ(map.height(), 1025);
    EXPECT_EQ(map.spacingX(), 160.0);
    EXPECT_EQ(map.spacingY(), 160.0);
    EXPECT_EQ(map.heightScale(), 0.1);
    EXPECT_NEAR(map.minHeight(), 0.0, 1e-9);
    EXPECT_NEAR(map.maxHeight(), 4379.8, 1e-6);  // raw 43798: Mount Rainier
    int tw = 0, th = 0;
    const std::vector<Rgb8> tex =
        readPngRgb(VIG_DATA_DIR "/puget-sound-1k/ps_texture_1k.png", tw, th);
    ASSERT_EQ(tw, 1024);
    ASSERT_EQ(th, 1024);
    // Colour at sample (ix, iy) = bilinear sample of the texture at u = ix * 1024/1024 - 0.5.
    for (int ix : {0, 1, 17, 512, 777, 1023, 1024}) {
        for (int iy : {0, 3, 400, 1000, 1024}) {
            const int row = 1024 - iy;
            const double u = std::clamp(ix - 0.5, 0.0, 1023.0);
            const double v = std::clamp(row - 0.5, 0.0, 1023.0);
            const int u0 = std::min(static_cast<int>(u), 1022),
                      v0 = std::min(static_cast<int>(v), 1022);
            const double fu = u - u0, fv = v - v0;
            auto at = [&](int x, int y) { return tex[static_cast<std::size_t>(y) * 1024 + x]; };
            auto bil = [&](auto ch) {
                return (1 - fu) * (1 - fv) * ch(at(u0, v0)) + fu * (1 - fv) * ch(at(u0 + 1, v0)) +
                       (1 - fu) * fv * ch(at(u0, v0 + 1)) + fu * fv * ch(at(u0 + 1, v0 + 1));
            };
            const Rgb8 got = map.colorAt(ix, iy);
            EXPECT_NEAR(got.r, bil([](Rgb8 c) { return c.r; }), 0.51) << ix << "," << iy;
            EXPECT_NEAR(got.g, bil([](Rgb8 c) { return c.g; }), 0.51) << ix << "," << iy;
            EXPECT_NEAR(got.b, bil([](Rgb8 c) { return c.b; }), 0.51) << ix << "," << iy;
        }
    }
}

TEST(TerrainIo, GoletaShippedGeoTiffs) {
    const TerrainMap map = ig::loadGoleta();
    ASSERT_EQ(map.width(), 512);
    ASSERT_EQ(map.height(), 512);
    EXPECT_NEAR(map.spacingX(), 2.8, 0.1);
    EXPECT_NEAR(map.spacingY(), 3.4, 0.1);
    // Geotransform (PROVENANCE.txt): top 34.4448 N, 512 rows of 3.02734375e-5 degrees.
    const double pixel = 3.02734375e-5;
    const double lat = (34.4448 - 256 * pixel) * std::numbers::pi / 180;
    EXPECT_NEAR(map.spacingX(), pixel * ig::metresPerDegreeLongitude(lat), 1e-9);
    EXPECT_NEAR(map.spacingY(), pixel * ig::metresPerDegreeLatitude(lat), 1e-9);
    const double quantum = map.heightScale();
    EXPECT_LT(quantum, 0.001);
    EXPECT_NEAR(map.minHeight(), 2.53, 0.005 + quantum);
    EXPECT_NEAR(map.maxHeight(), 20.73, 0.005 + quantum);
    // Identical geotransforms: each sample takes its own photo pixel.
    GDALAllRegister();
    GDALDatasetH photo =
        GDALOpen(VIG_DATA_DIR "/goleta-512/sba_rgb_wgs84_512x512.tif", GA_ReadOnly);
    ASSERT_NE(photo, nullptr);
    for (int c : {0, 5, 300, 511}) {
        for (int r : {0, 77, 256, 511}) {
            std::uint8_t px[3] = {};
            ASSERT_EQ(GDALDatasetRasterIO(photo, GF_Read, c, r, 1, 1, px, 1, 1, GDT_Byte, 3,
                                          nullptr, 0, 0, 0),
                      CE_None);
            EXPECT_EQ(map.colorAt(c, 511 - r), (Rgb8{px[0], px[1], px[2]})) << c << "," << r;
        }
    }
    GDALClose(photo);
    // A real photo: colours vary.
    std::size_t distinct = 0;
    for (int k = 1; k < 512; ++k)
        distinct += !(map.colorAt(k, 100) == map.colorAt(k - 1, 100));
    EXPECT_GT(distinct, 100u);
}

// --- Bad input ----------------------------------------------------------------------------------

TEST(TerrainIo, MissingAndNonImageFilesNameTheFile) {
    TerrainSource src;
    for (const char* name : {"missing.png", "missing.tif", "missing.dat"}) {
        src.heightPath = tmpPath(name);
        std::filesystem::remove(src.heightPath);
        expectInputError(src, {name});
    }
    for (const char* name : {"text.png", "text.jpg", "text.tif", "text.dat"}) {
        src.heightPath = tmpPath(name);
        writeText(src.heightPath, "this is not an image at all\n");
        expectInputError(src, {name});
    }
    src.heightPath = tmpPath("empty.png");
    writeText(src.heightPath, "");
    expectInputError(src, {"empty.png"});
    src.heightPath = tmpPath("");  // a directory
    expectInputError(src, {"terrain_io"});
    // A good height map with a missing colour image names the colour image.
    src.heightPath = tmpPath("ok_h.png");
    writePng16Grey(src.heightPath, 2, 2, {1, 2, 3, 4});
    src.colorPath = tmpPath("missing_colour.png");
    expectInputError(src, {"missing_colour.png"});
}

TEST(TerrainIo, RejectsColourAndOddDepthHeightPngs) {
    TerrainSource src;
    src.heightPath = tmpPath("rgb_h.png");
    writePngRgb(src.heightPath, 2, 2, std::vector<Rgb8>(4, Rgb8{1, 2, 3}));
    expectInputError(src, {"rgb_h.png", "RGB"});

    src.heightPath = tmpPath("palette_h.png");
    writePng(src.heightPath, 2, 2, PNG_COLOR_TYPE_PALETTE, 8, {0, 1, 1, 0},
             {{0, 0, 0}, {255, 255, 255}});
    expectInputError(src, {"palette_h.png", "palette"});

    src.heightPath = tmpPath("grey4_h.png");
    writePng(src.heightPath, 2, 2, PNG_COLOR_TYPE_GRAY, 4, {0x12, 0x34});
    expectInputError(src, {"grey4_h.png", "4-bit"});

    src.heightPath = tmpPath("ga_h.png");
    writePng(src.heightPath, 2, 2, PNG_COLOR_TYPE_GRAY_ALPHA, 8, {1, 255, 2, 255, 3, 255, 4, 255});
    expectInputError(src, {"ga_h.png", "alpha"});

    src.heightPath = tmpPath("rgb_h.jpg");
    writeJpegRgb(src.heightPath, 8, 8, std::vector<Rgb8>(64, Rgb8{200, 10, 10}));
    expectInputError(src, {"rgb_h.jpg", "colour"});

    src.heightPath = tmpPath("rgb_h.tif");
    std::vector<std::uint8_t> rgb(3 * 4, 9);
    writeGeoTiff(src.heightPath, 2, 2, 3, GDT_Byte, rgb.data(), nullptr);
    expectInputError(src, {"rgb_h.tif", "colour"});
}

TEST(TerrainIo, TruncatedFilesNameTheFile) {
    const int w = 64, h = 64;
    std::vector<std::uint16_t> v(w * h);
    for (int k = 0; k < w * h; ++k)
        v[k] = static_cast<std::uint16_t>(k * 2654435761u >> 16);
    TerrainSource src;
    src.heightPath = tmpPath("trunc.png");
    writePng16Grey(src.heightPath, w, h, v);
    const auto size = std::filesystem::file_size(src.heightPath);
    for (auto keep : {size / 2, std::uintmax_t{12}, std::uintmax_t{40}}) {
        std::filesystem::resize_file(src.heightPath, keep);
        expectInputError(src, {"trunc.png"});
        writePng16Grey(src.heightPath, w, h, v);
    }

    src.heightPath = tmpPath("ok_h2.png");
    writePng16Grey(src.heightPath, w, h, v);
    src.colorPath = tmpPath("trunc.jpg");
    std::vector<Rgb8> px(w * h);
    for (int k = 0; k < w * h; ++k)
        px[k] = Rgb8{static_cast<std::uint8_t>(k), 7, static_cast<std::uint8_t>(k / 64)};
    writeJpegRgb(src.colorPath, w, h, px);
    std::filesystem::resize_file(src.colorPath, std::filesystem::file_size(src.colorPath) / 2);
    expectInputError(src, {"trunc.jpg"});
}

TEST(TerrainIo, InfiniteHeightsNameTheSample) {
    const int w = 4, h = 3;
    std::vector<float> z(w * h, 1.0f);
    TerrainSource src;
    src.heightPath = tmpPath("inf.tif");
    z[1 * w + 2] = std::numeric_limits<float>::infinity();
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float32, z.data(), nullptr);
    expectInputError(src, {"inf.tif", "row 1", "column 2"});
    z[1 * w + 2] = -std::numeric_limits<float>::infinity();
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float32, z.data(), nullptr);
    expectInputError(src, {"inf.tif", "row 1", "column 2"});
}

// --- Samples without data ------------------------------------------------------------------------

TEST(FillVoids, HoleInAPlaneIsFilledCloseToThePlane) {
    const int w = 40, h = 30;
    auto plane = [](int x, int y) { return 100.0 + 2.0 * x - 1.5 * y; };
    std::vector<double> v(w * h);
    std::vector<std::uint8_t> ok(w * h, 1);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            v[y * w + x] = plane(x, y);
    const std::vector<double> original = v;
    // A 6 x 5 hole in the middle and a single sample at a corner.
    for (int y = 12; y < 17; ++y)
        for (int x = 17; x < 23; ++x) {
            ok[y * w + x] = 0;
            v[y * w + x] = -9999.0;
        }
    ok[0] = 0;
    v[0] = std::numeric_limits<double>::quiet_NaN();
    EXPECT_EQ(fillVoids(v, ok, w, h), 31u);
    double worst = 0.0;
    for (int k = 0; k < w * h; ++k) {
        ASSERT_TRUE(std::isfinite(v[k])) << k;
        if (ok[k]) {
            EXPECT_EQ(v[k], original[k]) << "a valid sample changed at " << k;
        } else {
            worst = std::max(worst, std::abs(v[k] - original[k]));
        }
    }
    // The plane rises 12 m across the hole; the fill stays within a sixth of that (1.13 m).
    EXPECT_LT(worst, 2.0);
}

TEST(FillVoids, StaysWithinTheValidRange) {
    // Noisy valid samples around a large hole: no overshoot beyond what surrounds it.
    const int w = 64, h = 48;
    std::vector<double> v(w * h);
    std::vector<std::uint8_t> ok(w * h, 1);
    std::uint32_t state = 12345;
    double lo = 1e300, hi = -1e300;
    for (int k = 0; k < w * h; ++k) {
        state = state * 1664525u + 1013904223u;
        v[k] = (state >> 8) % 1000;
        const int x = k % w, y = k / w;
        if (x > 10 && x < 50 && y > 5 && y < 40) {
            ok[k] = 0;
        } else {
            lo = std::min(lo, v[k]);
            hi = std::max(hi, v[k]);
        }
    }
    fillVoids(v, ok, w, h);
    for (int k = 0; k < w * h; ++k) {
        EXPECT_GE(v[k], lo) << k;
        EXPECT_LE(v[k], hi) << k;
    }
}

TEST(FillVoids, OneValidSampleFillsEverything) {
    for (auto [w, h] : {std::pair{1, 7}, std::pair{9, 1}, std::pair{5, 6}}) {
        std::vector<double> v(w * h, 0.0);
        std::vector<std::uint8_t> ok(w * h, 0);
        ok[w * h / 2] = 1;
        v[w * h / 2] = 42.5;
        EXPECT_EQ(fillVoids(v, ok, w, h), static_cast<std::size_t>(w * h - 1));
        for (double x : v)
            EXPECT_EQ(x, 42.5);
    }
}

TEST(FillVoids, RejectsNoValidSampleAndMismatchedSizes) {
    std::vector<double> v(6, 1.0);
    std::vector<std::uint8_t> none(6, 0), all(6, 1);
    EXPECT_DEATH(fillVoids(v, none, 3, 2), "no valid sample");
    EXPECT_DEATH(fillVoids(v, all, 2, 2), "grid sizes disagree");
    EXPECT_EQ(fillVoids(v, all, 3, 2), 0u);
    EXPECT_EQ(v, std::vector<double>(6, 1.0));
}

TEST(TerrainIo, NoDataAndNanSamplesAreFilledAndCounted) {
    const int w = 24, h = 20;
    std::vector<float> z(w * h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            z[y * w + x] = 50.0f + 3.0f * x + 2.0f * y;
    const std::vector<float> clean = z;
    for (int y = 8; y < 11; ++y)
        for (int x = 10; x < 14; ++x)
            z[y * w + x] = -9999.0f;
    z[2 * w + 3] = std::numeric_limits<float>::quiet_NaN();
    TerrainSource src;
    src.heightPath = tmpPath("voids.tif");
    const double noData = -9999.0;
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float32, z.data(), nullptr, false, &noData);
    const TerrainMap map = loadTerrain(src);
    EXPECT_EQ(map.filledSamples(), 13u);
    // No -9999 leaks into the map's range; filled samples sit near the plane they interrupt.
    EXPECT_GE(map.minHeight(), 50.0 - 0.01);
    for (int fileRow = 0; fileRow < h; ++fileRow) {
        for (int x = 0; x < w; ++x) {
            const double got = map.heightAt(x, h - 1 - fileRow);
            const double want = clean[fileRow * w + x];
            const bool hole = std::isnan(z[fileRow * w + x]) || z[fileRow * w + x] == -9999.0f;
            EXPECT_NEAR(got, want, hole ? 3.0 : 0.01) << "row " << fileRow << " column " << x;
        }
    }

    // A given height instead.
    src.voidHeight = -5.0;
    const TerrainMap sea = loadTerrain(src);
    EXPECT_EQ(sea.filledSamples(), 13u);
    EXPECT_NEAR(sea.heightAt(10, h - 1 - 8), -5.0, 0.01);
    EXPECT_NEAR(sea.heightAt(3, h - 1 - 2), -5.0, 0.01);
    EXPECT_NEAR(sea.heightAt(0, 0), clean[(h - 1) * w], 0.01);
    src.voidHeight = std::numeric_limits<double>::quiet_NaN();
    expectInputError(src, {"voids.tif", "void height"});
}

TEST(TerrainIo, IntegerNoDataIsFilled) {
    const int w = 8, h = 6;
    std::vector<std::int16_t> z(w * h, 700);
    z[3 * w + 4] = -32768;
    TerrainSource src;
    src.heightPath = tmpPath("int_voids.tif");
    const double noData = -32768.0;
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Int16, z.data(), nullptr, false, &noData);
    const TerrainMap map = loadTerrain(src);
    EXPECT_EQ(map.filledSamples(), 1u);
    EXPECT_NEAR(map.heightAt(4, h - 1 - 3), 700.0, 0.01);
    EXPECT_NEAR(map.minHeight(), 700.0, 0.01);
}

TEST(TerrainIo, AllNoDataIsAnError) {
    const int w = 4, h = 3;
    std::vector<float> z(w * h, -9999.0f);
    TerrainSource src;
    src.heightPath = tmpPath("all_void.tif");
    const double noData = -9999.0;
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float32, z.data(), nullptr, false, &noData);
    expectInputError(src, {"all_void.tif", "no data"});
    std::fill(z.begin(), z.end(), std::numeric_limits<float>::quiet_NaN());
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float32, z.data(), nullptr);
    expectInputError(src, {"all_void.tif", "no data"});
}

TEST(TerrainIo, RejectsBadSpacingAndScale) {
    TerrainSource src;
    src.heightPath = tmpPath("good_h.png");
    writePng16Grey(src.heightPath, 2, 2, {1, 2, 3, 4});
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    for (double bad : {0.0, -1.0, -0.0, nan, inf, -inf}) {
        TerrainSource s = src;
        s.spacing = bad;
        expectInputError(s, {"good_h.png", "spacing"});
        s = src;
        s.heightScale = bad;
        expectInputError(s, {"good_h.png", "scale"});
    }
    for (double bad : {nan, inf}) {
        TerrainSource s = src;
        s.heightOffset = bad;
        expectInputError(s, {"good_h.png", "offset"});
    }
    TerrainSource s = src;
    s.spacing = 0.25;
    s.heightScale = 1e-3;
    s.heightOffset = -5;
    EXPECT_NO_THROW(loadTerrain(s));
}

TEST(TerrainIo, RejectsMismatchedExtentsAndAspect) {
    const int w = 6, h = 6;
    const double gtH[6] = {-119.9, 3.0e-5, 0, 34.5, 0, -3.0e-5};
    std::vector<float> z(w * h, 3.0f);
    std::vector<std::uint8_t> rgb(3 * w * h, 100);
    TerrainSource src;
    src.heightPath = tmpPath("ext_h.tif");
    src.colorPath = tmpPath("ext_c.tif");
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float32, z.data(), gtH);
    // Shifted by two pixels east: more than one pixel off.
    double gtC[6] = {gtH[0] + 2 * gtH[1], gtH[1], 0, gtH[3], 0, gtH[5]};
    writeGeoTiff(src.colorPath, w, h, 3, GDT_Byte, rgb.data(), gtC);
    expectInputError(src, {"ext_h.tif", "ext_c.tif", "does not cover"});
    // Half a pixel off is tolerated.
    gtC[0] = gtH[0] + 0.5 * gtH[1];
    writeGeoTiff(src.colorPath, w, h, 3, GDT_Byte, rgb.data(), gtC);
    EXPECT_NO_THROW(loadTerrain(src));

    // Without georeference, a different aspect ratio is an error.
    src.heightPath = tmpPath("asp_h.png");
    src.colorPath = tmpPath("asp_c.png");
    writePng16Grey(src.heightPath, 11, 11, std::vector<std::uint16_t>(121, 0));
    writePngRgb(src.colorPath, 10, 8, std::vector<Rgb8>(80, Rgb8{1, 1, 1}));
    expectInputError(src, {"asp_h.png", "asp_c.png", "aspect"});
    writePngRgb(src.colorPath, 20, 20, std::vector<Rgb8>(400, Rgb8{1, 1, 1}));
    EXPECT_NO_THROW(loadTerrain(src));
}

TEST(TerrainIo, ColourImageWiderThanTheHeightsIsCropped) {
    // Heights 6 x 5; an orthophoto of 12 x 10 pixels of the same size reaching 2 pixels beyond
    // the heights on the west and north and further on the east and south.
    const int w = 6, h = 5, cw = 12, ch = 10;
    const double gtH[6] = {500000.0, 30.0, 0, 5200000.0, 0, -30.0};
    const double gtC[6] = {gtH[0] - 60.0, 30.0, 0, gtH[3] + 60.0, 0, -30.0};
    std::vector<float> z(w * h, 10.0f);
    std::vector<std::uint8_t> rgb(3 * cw * ch);  // band-sequential: r = column, g = row
    for (int y = 0; y < ch; ++y) {
        for (int x = 0; x < cw; ++x) {
            rgb[y * cw + x] = static_cast<std::uint8_t>(10 * x);
            rgb[cw * ch + y * cw + x] = static_cast<std::uint8_t>(10 * y);
            rgb[2 * cw * ch + y * cw + x] = 77;
        }
    }
    TerrainSource src;
    src.heightPath = tmpPath("crop_h.tif");
    src.colorPath = tmpPath("crop_c.tif");
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float32, z.data(), gtH, false);
    writeGeoTiff(src.colorPath, cw, ch, 3, GDT_Byte, rgb.data(), gtC, false);
    const TerrainMap map = loadTerrain(src);
    for (int fileRow = 0; fileRow < h; ++fileRow) {
        for (int x = 0; x < w; ++x) {
            const Rgb8 c = map.colorAt(x, h - 1 - fileRow);
            EXPECT_EQ(c, (Rgb8{static_cast<std::uint8_t>(10 * (x + 2)),
                               static_cast<std::uint8_t>(10 * (fileRow + 2)), 77}))
                << "row " << fileRow << " column " << x;
        }
    }
    // Reaching beyond the heights on one side but short of them on another: an error.
    const double gtShort[6] = {gtH[0] + 60.0, 30.0, 0, gtH[3] + 60.0, 0, -30.0};
    writeGeoTiff(src.colorPath, cw, ch, 3, GDT_Byte, rgb.data(), gtShort, false);
    expectInputError(src, {"crop_h.tif", "crop_c.tif", "does not cover"});
}

// Gives a GeoTIFF the coordinate reference system of an EPSG code.
void setEpsg(const std::string& path, int epsg) {
    GDALDatasetH ds = GDALOpen(path.c_str(), GA_Update);
    ASSERT_NE(ds, nullptr) << path;
    OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
    ASSERT_EQ(OSRImportFromEPSG(srs, epsg), OGRERR_NONE);
    GDALSetSpatialRef(ds, srs);
    OSRDestroySpatialReference(srs);
    GDALClose(ds);
}

TEST(TerrainIo, ColourInAnotherCoordinateSystemIsReprojected) {
    // Heights in UTM zone 10N, colours in WGS84 degrees whose red counts columns and green rows:
    // each sample's colour tells where in the colour image it was taken.
    const int w = 40, h = 30, cw = 200, ch = 150;
    const double gtH[6] = {500000.0, 30.0, 0, 5200000.0, 0, -30.0};
    OGRSpatialReferenceH utm = OSRNewSpatialReference(nullptr),
                         wgs = OSRNewSpatialReference(nullptr);
    ASSERT_EQ(OSRImportFromEPSG(utm, 32610), OGRERR_NONE);
    ASSERT_EQ(OSRImportFromEPSG(wgs, 4326), OGRERR_NONE);
    OSRSetAxisMappingStrategy(utm, OAMS_TRADITIONAL_GIS_ORDER);
    OSRSetAxisMappingStrategy(wgs, OAMS_TRADITIONAL_GIS_ORDER);
    OGRCoordinateTransformationH ct = OCTNewCoordinateTransformation(utm, wgs);
    ASSERT_NE(ct, nullptr);
    auto toLonLat = [&](double x, double y) {
        double px = x, py = y, pz = 0.0;
        EXPECT_TRUE(OCTTransform(ct, 1, &px, &py, &pz));
        return std::pair{px, py};
    };
    double lon0 = 1e9, lon1 = -1e9, lat0 = 1e9, lat1 = -1e9;
    for (double x : {gtH[0], gtH[0] + w * gtH[1]}) {
        for (double y : {gtH[3], gtH[3] + h * gtH[5]}) {
            const auto [lon, lat] = toLonLat(x, y);
            lon0 = std::min(lon0, lon);
            lon1 = std::max(lon1, lon);
            lat0 = std::min(lat0, lat);
            lat1 = std::max(lat1, lat);
        }
    }
    const double margin = 0.002;
    const double gtC[6] = {lon0 - margin,
                           (lon1 - lon0 + 2 * margin) / cw,
                           0,
                           lat1 + margin,
                           0,
                           -(lat1 - lat0 + 2 * margin) / ch};
    std::vector<float> z(w * h, 10.0f);
    std::vector<std::uint8_t> rgb(3 * cw * ch);
    for (int y = 0; y < ch; ++y) {
        for (int x = 0; x < cw; ++x) {
            rgb[y * cw + x] = static_cast<std::uint8_t>(x);
            rgb[cw * ch + y * cw + x] = static_cast<std::uint8_t>(y);
            rgb[2 * cw * ch + y * cw + x] = 5;
        }
    }
    TerrainSource src;
    src.heightPath = tmpPath("utm_h.tif");
    src.colorPath = tmpPath("wgs_c.tif");
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float32, z.data(), gtH, false);
    setEpsg(src.heightPath, 32610);
    writeGeoTiff(src.colorPath, cw, ch, 3, GDT_Byte, rgb.data(), gtC, true);
    const TerrainMap map = loadTerrain(src);
    EXPECT_NEAR(map.spacingX(), 30.0, 1e-9);
    double worst = 0.0;
    for (int fileRow = 0; fileRow < h; ++fileRow) {
        for (int x = 0; x < w; ++x) {
            const auto [lon, lat] =
                toLonLat(gtH[0] + (x + 0.5) * gtH[1], gtH[3] + (fileRow + 0.5) * gtH[5]);
            const double u = (lon - gtC[0]) / gtC[1] - 0.5, v = (lat - gtC[3]) / gtC[5] - 0.5;
            const Rgb8 c = map.colorAt(x, h - 1 - fileRow);
            worst = std::max({worst, std::abs(c.r - u), std::abs(c.g - v)});
            EXPECT_EQ(c.b, 5);
        }
    }
    EXPECT_LE(worst, 0.51);  // only the rounding to 8 bits
    OCTDestroyCoordinateTransformation(ct);
    OSRDestroySpatialReference(utm);
    OSRDestroySpatialReference(wgs);

    // A colour image that misses part of the heights.
    const double gtSmall[6] = {gtC[0] + 0.3 * (lon1 - lon0), gtC[1], 0, gtC[3], 0, gtC[5]};
    writeGeoTiff(src.colorPath, cw, ch, 3, GDT_Byte, rgb.data(), gtSmall, true);
    expectInputError(src, {"utm_h.tif", "wgs_c.tif", "does not cover"});
}

TEST(TerrainIo, SixteenBitAndFloatColoursAreStretchedToEightBits) {
    // 16-bit imagery: red counts columns, green rows, blue equals red.
    const int w = 64, h = 32;
    std::vector<std::uint16_t> rgb(3 * w * h);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            rgb[y * w + x] = static_cast<std::uint16_t>(100 * x);
            rgb[w * h + y * w + x] = static_cast<std::uint16_t>(200 * y);
            rgb[2 * w * h + y * w + x] = static_cast<std::uint16_t>(100 * x);
        }
    }
    std::vector<float> z(w * h, 1.0f);
    TerrainSource src;
    src.heightPath = tmpPath("wide_h.tif");
    src.colorPath = tmpPath("wide_c.tif");
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Float32, z.data(), nullptr);
    writeGeoTiff(src.colorPath, w, h, 3, GDT_UInt16, rgb.data(), nullptr);
    const TerrainMap map = loadTerrain(src);
    int lowest = 255, highest = 0;
    for (int iy = 0; iy < h; ++iy) {
        for (int x = 0; x < w; ++x) {
            const Rgb8 c = map.colorAt(x, iy);
            EXPECT_EQ(c.b, c.r) << "one stretch for every band";
            if (x > 0) {
                EXPECT_GE(c.r, map.colorAt(x - 1, iy).r);
            }
            if (iy > 0) {
                EXPECT_LE(c.g, map.colorAt(x, iy - 1).g);  // file rows run north first
            }
            lowest = std::min(lowest, int{c.r});
            highest = std::max(highest, int{c.r});
        }
    }
    EXPECT_EQ(lowest, 0);  // clipped below the 2nd percentile
    EXPECT_EQ(highest, 255);
    // 3200 sits near the middle of the pooled values 0..6300.
    EXPECT_NEAR(map.colorAt(32, 0).r, 128, 20);

    // Float samples with NaN: the NaN pixels are black, the rest stretched.
    std::vector<float> grey(w * h);
    for (int k = 0; k < w * h; ++k)
        grey[k] = static_cast<float>(k % w) * 0.01f;
    grey[5] = std::numeric_limits<float>::quiet_NaN();
    writeGeoTiff(src.colorPath, w, h, 1, GDT_Float32, grey.data(), nullptr);
    const TerrainMap greyMap = loadTerrain(src);
    EXPECT_EQ(greyMap.colorAt(5, h - 1), (Rgb8{0, 0, 0}));
    EXPECT_EQ(greyMap.colorAt(w - 1, 0), (Rgb8{255, 255, 255}));
    EXPECT_EQ(greyMap.colorAt(0, 0), (Rgb8{0, 0, 0}));
}

// Sets band 1's vertical unit, scale and offset (GDAL's metadata) of a GeoTIFF.
void setBandUnits(const std::string& path, const char* unit, double scale, double offset) {
    GDALDatasetH ds = GDALOpen(path.c_str(), GA_Update);
    ASSERT_NE(ds, nullptr) << path;
    GDALRasterBandH band = GDALGetRasterBand(ds, 1);
    GDALSetRasterUnitType(band, unit);
    GDALSetRasterScale(band, scale);
    GDALSetRasterOffset(band, offset);
    GDALClose(ds);
}

TEST(TerrainIo, BandScaleOffsetAndVerticalUnitsGiveMetres) {
    const int w = 3, h = 2;
    const std::vector<std::int16_t> z = {0, 100, 200, 300, 400, 500};
    TerrainSource src;
    src.heightPath = tmpPath("units.tif");
    auto heightAt = [&](const TerrainMap& map, int k) {
        return map.heightAt(k % w, h - 1 - k / w);
    };
    // Feet: metres = raw * 0.3048.
    writeGeoTiff(src.heightPath, w, h, 1, GDT_Int16, z.data(), nullptr, false);
    setBandUnits(src.heightPath, "ft", 1.0, 0.0);
    TerrainMap map = loadTerrain(src);
    for (int k = 0; k < w * h; ++k)
        EXPECT_NEAR(heightAt(map, k), z[k] * 0.3048, 0.01) << k;
    // US survey feet, with a band scale and offset: (raw * 0.1 + 20) US feet.
    setBandUnits(src.heightPath, "US survey foot", 0.1, 20.0);
    map = loadTerrain(src);
    for (int k = 0; k < w * h; ++k)
        EXPECT_NEAR(heightAt(map, k), (z[k] * 0.1 + 20.0) * 1200.0 / 3937.0, 0.001) << k;
    // The user's scale says what a unit is (it replaces the unit, not the band's scale), and
    // the user's offset comes last.
    src.heightScale = 2.0;
    src.heightOffset = -1.0;
    map = loadTerrain(src);
    for (int k = 0; k < w * h; ++k)
        EXPECT_NEAR(heightAt(map, k), (z[k] * 0.1 + 20.0) * 2.0 - 1.0, 0.001) << k;
    // An unknown unit without a user scale is an error naming it.
    src.heightScale.reset();
    src.heightOffset.reset();
    setBandUnits(src.heightPath, "furlong", 1.0, 0.0);
    expectInputError(src, {"units.tif", "furlong", "--height-scale"});
}

TEST(TerrainIo, PngWithWorldFilesIsGeoreferenced) {
    // 16-bit PNG heights, 6 x 5 samples of 25 m, and a PNG photo of 12 x 10 pixels of 25 m
    // reaching two pixels beyond the heights on the west and north: each with a world file
    // (pixel size x, rotation, rotation, pixel size y, then the upper-left pixel's centre).
    const int w = 6, h = 5, cw = 12, ch = 10;
    TerrainSource src;
    src.heightPath = tmpPath("world_h.png");
    src.colorPath = tmpPath("world_c.png");
    std::vector<std::uint16_t> z(w * h);
    for (int k = 0; k < w * h; ++k)
        z[k] = static_cast<std::uint16_t>(100 + k);
    writePng16Grey(src.heightPath, w, h, z);
    std::vector<Rgb8> px(cw * ch);
    for (int y = 0; y < ch; ++y)
        for (int x = 0; x < cw; ++x)
            px[y * cw + x] =
                Rgb8{static_cast<std::uint8_t>(10 * x), static_cast<std::uint8_t>(10 * y), 9};
    writePngRgb(src.colorPath, cw, ch, px);
    writeText(tmpPath("world_h.pgw"), "25\n0\n0\n-25\n500012.5\n5199987.5\n");
    writeText(tmpPath("world_c.pgw"), "25\n0\n0\n-25\n499962.5\n5200037.5\n");
    const TerrainMap map = loadTerrain(src);
    EXPECT_DOUBLE_EQ(map.spacingX(), 25.0);
    EXPECT_DOUBLE_EQ(map.spacingY(), 25.0);
    for (int fileRow = 0; fileRow < h; ++fileRow) {
        for (int x = 0; x < w; ++x) {
            EXPECT_NEAR(map.heightAt(x, h - 1 - fileRow), 100 + fileRow * w + x, 0.01);
            EXPECT_EQ(map.colorAt(x, h - 1 - fileRow),
                      (Rgb8{static_cast<std::uint8_t>(10 * (x + 2)),
                            static_cast<std::uint8_t>(10 * (fileRow + 2)), 9}))
                << "row " << fileRow << " column " << x;
        }
    }
    std::filesystem::remove(tmpPath("world_h.pgw"));
    std::filesystem::remove(tmpPath("world_c.pgw"));
}

TEST(TerrainIo, RejectsTooSmallHeightMap) {
    TerrainSource src;
    src.heightPath = tmpPath("one_row.png");
    writePng16Grey(src.heightPath, 5, 1, {1, 2, 3, 4, 5});
    expectInputError(src, {"one_row.png", "2 x 2"});
}

// --- Sizes the header claims, in-memory and streamed input ---------------------------------------

// 74 bytes: a PNG header claiming 30000 x 30000 16-bit samples (1.8 GB), a few bytes of IDAT.
const std::vector<std::uint8_t> kHugePng = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44,
    0x52, 0x00, 0x00, 0x75, 0x30, 0x00, 0x00, 0x75, 0x30, 0x10, 0x00, 0x00, 0x00, 0x00, 0x13,
    0xdc, 0x7b, 0x25, 0x00, 0x00, 0x00, 0x11, 0x49, 0x44, 0x41, 0x54, 0x78, 0xda, 0x63, 0x60,
    0x80, 0x00, 0x00, 0x00, 0x08, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xf1, 0x5c,
    0xec, 0x8a, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

std::vector<std::uint8_t> readBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void writeBytes(const std::string& path, const std::vector<std::uint8_t>& bytes) {
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()),
               static_cast<std::streamsize>(bytes.size()));
}

// Refused from the header, before any decoding or allocation for the pixels: well under a
// second (reading it used to allocate 1.8 GB and take seconds).
TEST(TerrainIo, PngClaimingMoreThanItsLengthCanHoldIsRefusedAtOnce) {
    ASSERT_EQ(kHugePng.size(), 74u);
    TerrainSource src;
    src.heightPath = tmpPath("huge_claim.png");
    writeBytes(src.heightPath, kHugePng);
    const auto start = std::chrono::steady_clock::now();
    expectInputError(src, {"huge_claim.png", "30000 x 30000", "74 bytes", "1032", "corrupt"});
    src.heightPath = "in_memory.png";
    src.heightBytes = kHugePng;
    expectInputError(src, {"in_memory.png", "30000 x 30000", "74 bytes"});
    // As a colour image too.
    src.heightPath = tmpPath("ok_for_huge.png");
    src.heightBytes = {};
    writePng16Grey(src.heightPath, 2, 2, {1, 2, 3, 4});
    src.colorPath = tmpPath("huge_claim.png");
    expectInputError(src, {"huge_claim.png", "30000 x 30000"});
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 0.5);
}

TEST(TerrainIo, JpegClaimingMoreThanItsLengthCanHoldIsRefusedAtOnce) {
    const std::string path = tmpPath("huge_claim.jpg");
    writeJpegRgb(path, 8, 8, std::vector<Rgb8>(64, Rgb8{90, 90, 90}), 1);
    std::vector<std::uint8_t> bytes = readBytes(path);
    // The frame header (SOF0): FF C0, length, precision, then height and width, big-endian.
    bool patched = false;
    for (std::size_t k = 0; k + 9 < bytes.size() && !patched; ++k) {
        if (bytes[k] == 0xFF && bytes[k + 1] == 0xC0) {
            for (std::size_t at : {k + 5, k + 7}) {
                bytes[at] = 30000 >> 8;
                bytes[at + 1] = 30000 & 0xFF;
            }
            patched = true;
        }
    }
    ASSERT_TRUE(patched);
    writeBytes(path, bytes);
    TerrainSource src;
    src.heightPath = path;
    const auto start = std::chrono::steady_clock::now();
    expectInputError(src, {"huge_claim.jpg", "30000 x 30000", "corrupt"});
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 0.5);
}

TEST(TerrainIo, SampleBudgetRefusesLargerImages) {
    TerrainSource src;
    src.heightPath = tmpPath("budget.png");
    writePng16Grey(src.heightPath, 4, 4, std::vector<std::uint16_t>(16, 7));
    src.maxSamples = 15;
    expectInputError(src, {"budget.png", "4 x 4", "too large"});
    src.maxSamples = 16;
    EXPECT_EQ(loadTerrain(src).width(), 4);

    // GDAL reads whole blocks of every interleaved band: four bands of the largest image at most.
    const std::vector<std::uint8_t> bands(2 * 2 * 5, 9);
    src.heightPath = tmpPath("five_bands.tif");
    writeGeoTiff(src.heightPath, 2, 2, 5, GDT_Byte, bands.data(), nullptr);
    src.maxSamples = 4;
    expectInputError(src, {"five_bands.tif", "5 bands", "more samples"});
    src.heightPath = tmpPath("two_bands.tif");
    writeGeoTiff(src.heightPath, 2, 2, 2, GDT_Byte, bands.data(), nullptr);
    EXPECT_EQ(loadTerrain(src).width(), 2);
}

TEST(TerrainIo, BytesInMemoryLoadAsTheFileDoes) {
    const int w = 5, h = 4;
    std::vector<std::uint16_t> v(w * h);
    for (int k = 0; k < w * h; ++k)
        v[k] = static_cast<std::uint16_t>(100 * k);
    const std::vector<float> z(w * h, 12.5f);
    const double gt[6] = {-120.0, 0.001, 0.0, 35.0, 0.0, -0.001};
    writePng16Grey(tmpPath("mem.png"), w, h, v);
    writeGeoTiff(tmpPath("mem.tif"), w, h, 1, GDT_Float32, z.data(), gt);
    for (const char* name : {"mem.png", "mem.tif"}) {
        TerrainSource fromFile;
        fromFile.heightPath = tmpPath(name);
        const std::vector<std::uint8_t> bytes = readBytes(fromFile.heightPath);
        TerrainSource fromMemory;
        fromMemory.heightPath = name;
        fromMemory.heightBytes = bytes;
        const TerrainMap a = loadTerrain(fromFile), b = loadTerrain(fromMemory);
        ASSERT_EQ(a.width(), b.width()) << name;
        ASSERT_EQ(a.height(), b.height()) << name;
        EXPECT_EQ(a.spacingX(), b.spacingX()) << name;
        EXPECT_TRUE(
            std::equal(a.rawHeights().begin(), a.rawHeights().end(), b.rawHeights().begin()))
            << name;
    }
}

// A height map (and a colour image) read from a pipe, as from /dev/stdin: held in memory.
TEST(TerrainIo, HeightMapAndColourFromPipes) {
    const int w = 6, h = 5;
    std::vector<std::uint16_t> v(w * h);
    for (int k = 0; k < w * h; ++k)
        v[k] = static_cast<std::uint16_t>(1000 + 37 * k);
    const std::string pngPath = tmpPath("pipe_source.png");
    writePng16Grey(pngPath, w, h, v);
    const std::string jpgPath = tmpPath("pipe_source.jpg");
    writeJpegRgb(jpgPath, w, h, std::vector<Rgb8>(w * h, Rgb8{200, 100, 50}));
    const std::string tifPath = tmpPath("pipe_source.tif");
    const std::vector<float> z(w * h, 3.0f);
    writeGeoTiff(tifPath, w, h, 1, GDT_Float32, z.data(), nullptr);

    // Writes `source` into the FIFO at `fifo` from a thread (a FIFO opens when both ends do).
    auto feed = [](const std::string& fifo, const std::string& source) {
        return std::thread([fifo, bytes = readBytes(source)] {
            std::FILE* f = std::fopen(fifo.c_str(), "wb");
            if (!f) return;
            std::fwrite(bytes.data(), 1, bytes.size(), f);
            std::fclose(f);
        });
    };
    auto makeFifo = [](const std::string& name) {
        const std::string path = tmpPath(name);
        std::filesystem::remove(path);
        EXPECT_EQ(::mkfifo(path.c_str(), 0600), 0) << path;
        return path;
    };
    const std::string heightFifo = makeFifo("heights.fifo"), colorFifo = makeFifo("colour.fifo");
    TerrainSource src;
    src.heightPath = heightFifo;
    src.colorPath = colorFifo;
    // loadTerrain opens the heights first, then the colours.
    std::thread a = feed(heightFifo, pngPath), b = feed(colorFifo, jpgPath);
    TerrainMap map;
    EXPECT_NO_THROW(map = loadTerrain(src));
    a.join();
    b.join();
    ASSERT_EQ(map.width(), w);
    ASSERT_EQ(map.height(), h);
    EXPECT_EQ(map.raw(0, h - 1), v[0]);  // file row 0 is the north edge
    EXPECT_EQ(map.raw(w - 1, 0), v[w * h - 1]);
    EXPECT_NEAR(map.colorAt(2, 2).r, 200, 3);

    src.colorPath.clear();
    std::thread c = feed(heightFifo, tifPath);
    EXPECT_NO_THROW(map = loadTerrain(src));
    c.join();
    EXPECT_EQ(map.width(), w);
    EXPECT_DOUBLE_EQ(map.heightAt(1, 1), 3.0);

    // A corrupt stream names the FIFO.
    const std::string junk = tmpPath("junk.bin");
    writeText(junk, "not an image, through a pipe\n");
    std::thread d = feed(heightFifo, junk);
    expectInputError(src, {"heights.fifo"});
    d.join();
}

TEST(TerrainIo, WgsDegreeLengths) {
    // Known values of the series: equator and 45 degrees.
    EXPECT_NEAR(ig::metresPerDegreeLatitude(0), 110574.3, 0.1);
    EXPECT_NEAR(ig::metresPerDegreeLongitude(0), 111319.3, 0.1);
    EXPECT_NEAR(ig::metresPerDegreeLatitude(std::numbers::pi / 4), 111132.0, 1.0);
    EXPECT_NEAR(ig::metresPerDegreeLongitude(std::numbers::pi / 4), 78846.8, 1.0);
    // Longitude degrees shrink toward the pole.
    for (int d = 0; d < 89; ++d) {
        const double a = d * std::numbers::pi / 180, b = (d + 1) * std::numbers::pi / 180;
        EXPECT_GT(ig::metresPerDegreeLongitude(a), ig::metresPerDegreeLongitude(b));
        EXPECT_LT(ig::metresPerDegreeLatitude(a), ig::metresPerDegreeLatitude(b));
    }
}

}  // namespace
