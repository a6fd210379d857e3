// Fuzz target: height and colour images as ig::loadTerrain reads them (PNG by libpng, JPEG by
// libjpeg, everything else by GDAL, from memory): the header checks, the decode into the map's
// samples, the georeference and the colour's placement on the heights. Built once per format
// (VIG_FUZZ_NAME gives the file name, so the extension) with a corpus of that format.
//
// Input: one byte of options, then the file.
//   bit 0: the file is the colour image (over a 2 x 2 height map) rather than the heights
//   bit 1: the spacing is given (the georeference is then not used for it)
//   bit 2: samples without data get a fixed height rather than being filled
//   bit 3: the height scale is given (a band's vertical unit is then not used)
#include <cstdint>
#include <span>

#include "fuzz_check.hpp"
#include "ig/error.hpp"
#include "ig/terrain_io.hpp"

#ifndef VIG_FUZZ_NAME
#define VIG_FUZZ_NAME "fuzz.img"
#endif

namespace {

// A 2 x 2 8-bit greyscale PNG: the heights under a fuzzed colour image.
constexpr std::uint8_t kHeights2x2[] = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44,
    0x52, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x08, 0x00, 0x00, 0x00, 0x00, 0x57,
    0xdd, 0x52, 0xf8, 0x00, 0x00, 0x00, 0x0e, 0x49, 0x44, 0x41, 0x54, 0x78, 0xda, 0x63, 0x10,
    0x50, 0x60, 0x30, 0x70, 0x00, 0x00, 0x01, 0x76, 0x00, 0xa1, 0xf1, 0x58, 0xc4, 0x82, 0x00,
    0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 2) return 0;
    const std::uint8_t options = data[0];
    const std::span<const std::uint8_t> file(data + 1, size - 1);
    ig::TerrainSource src;
    // Far below the product's limit: a fuzzer's memory is bounded, and a claim the budget
    // refuses is as much a finding as one the file's length does.
    src.maxSamples = std::size_t{1} << 16;
    if (options & 1) {
        src.heightPath = "heights.png";
        src.heightBytes = kHeights2x2;
        src.colorPath = VIG_FUZZ_NAME;
        src.colorBytes = file;
    } else {
        src.heightPath = VIG_FUZZ_NAME;
        src.heightBytes = file;
    }
    if (options & 2) src.spacing = 10.0;
    if (options & 4) src.voidHeight = 0.0;
    if (options & 8) src.heightScale = 0.5;
    try {
        const ig::TerrainMap map = ig::loadTerrain(src);
        (void)map.surfaceHeight(0.5 * map.extentX(), 0.5 * map.extentY());
    } catch (const ig::InputError& e) {
        fuzz::checkMessage(e.what());
    }
    return 0;
}
