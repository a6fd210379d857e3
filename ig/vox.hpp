// MagicaVoxel .vox files: models (SIZE/XYZI pairs) and the RGBA palette, read and written.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace ig {

// A palette colour; alpha is the voxel's opacity (255 opaque, 0 fully transparent).
struct Rgba8 {
    std::uint8_t r = 0, g = 0, b = 0, a = 255;
    bool operator==(const Rgba8&) const = default;
};

// Largest model side the format can address (coordinates are bytes).
inline constexpr int kVoxMaxSide = 256;

// One model: a dense grid of palette indices (0 = empty), x fastest, then y, then z (up).
struct VoxModel {
    int sizeX = 0, sizeY = 0, sizeZ = 0;
    std::vector<std::uint8_t> voxels;  // sizeX * sizeY * sizeZ

    VoxModel() = default;
    VoxModel(int sx, int sy, int sz)
        : sizeX(sx),
          sizeY(sy),
          sizeZ(sz),
          voxels(static_cast<std::size_t>(sx) * static_cast<std::size_t>(sy) * sz, 0) {}
    std::size_t index(int x, int y, int z) const {
        return (static_cast<std::size_t>(z) * sizeY + y) * static_cast<std::size_t>(sizeX) + x;
    }
    std::uint8_t at(int x, int y, int z) const { return voxels[index(x, y, z)]; }
    void set(int x, int y, int z, std::uint8_t v) { voxels[index(x, y, z)] = v; }
    std::size_t filled() const;
};

// A file: its models and its palette, indexed by the voxels' colour index (entry 0 unused).
struct VoxFile {
    std::vector<VoxModel> models;
    std::array<Rgba8, 256> palette{};
    bool hasPalette = false;  // false: the file had no RGBA chunk (palette = the default one)
};

// The palette MagicaVoxel uses when a file has no RGBA chunk (the format description's list).
const std::array<Rgba8, 256>& defaultVoxPalette();

// Parses a .vox image; `name` names it in messages. Throws InputError naming the file, the chunk
// (and its byte offset) and what is wrong: a bad header, a chunk running past its parent or the
// end, a SIZE side of 0 or over 256, an XYZI without a SIZE or with a voxel outside the SIZE,
// colour index 0, models of more than 256^3 cells together, a PACK count that disagrees with the
// models, no model at all. Unknown chunks (nTRN, nGRP, nSHP, MATL, LAYR, rOBJ, ...) are skipped by
// their sizes.
VoxFile parseVox(std::span<const std::uint8_t> bytes, const std::string& name);
VoxFile readVox(const std::string& path);

// Encodes `file` as version 150: MAIN { [PACK when several models] SIZE XYZI ... RGBA }.
// Models must have sides 1..256 (CHECKed).
std::vector<std::uint8_t> encodeVox(const VoxFile& file);
// Writes the encoding to `path` (through a temporary file renamed into place); InputError on
// failure naming the path.
void writeVox(const std::string& path, const VoxFile& file);

}  // namespace ig
