// Tiled terrain database on disk: the height map, colours and both pyramids (display levels with
// their cell maxima, max-height nodes) cut into square tiles per level, one file with a header
// and an index (docs/formats.md, docs/design/terrain_db.md).
#pragma once

#include "ig/terrain.hpp"

#include <compare>
#include <cstdint>
#include <string>
#include <vector>

namespace ig {

// Version 3 adds the insets table (version 2 files, without it, are read as holding none).
inline constexpr std::uint32_t kTerrainDbVersion = 3;
inline constexpr int kMinDbTileSize = 16, kMaxDbTileSize = 4096;

enum class TileCodec : std::uint8_t { None = 0, Lz4 = 1, Zstd = 2 };
const char* tileCodecName(TileCodec codec);
// "none" | "lz4" | "zstd"; throws InputError otherwise.
TileCodec parseTileCodec(const std::string& name);

// Display tiles hold samples, their colours and cell maxima; node tiles the max-height nodes.
enum class TileKind : std::uint8_t { Display = 0, Nodes = 1 };

struct TileKey {
    TileKind kind = TileKind::Display;
    int level = 0, tx = 0, ty = 0;
    auto operator<=>(const TileKey&) const = default;
};
std::string describeTile(const TileKey& key);  // "display tile (level 2, 3, 4)"

// Where the tiles lie. Display level k (the pyramid's, TerrainPyramid rules) has W_k x H_k
// samples and W_k - 1 x H_k - 1 cells; its tile (tx, ty) holds the T x T cells from cell
// (tx * T, ty * T) (fewer at the far edges) and the T + 1 x T + 1 samples around them (tiles
// share their edge samples). Node level j >= 1 has N_j nodes per axis; its tile (tx, ty) holds
// nodes [tx * T, tx * T + T) x [ty * T, ty * T + T), the same region of the map as display tile
// (j, tx, ty).
class TerrainDbLayout {
  public:
    TerrainDbLayout() = default;
    TerrainDbLayout(int width, int height, int tileSize);

    int tileSize() const { return tileSize_; }
    int displayLevels() const { return static_cast<int>(levelW_.size()); }
    int nodeLevels() const { return static_cast<int>(nodeW_.size()); }  // level 0 unused
    int levelWidth(int k) const { return levelW_[k]; }
    int levelHeight(int k) const { return levelH_[k]; }
    int nodesX(int j) const { return nodeW_[j]; }
    int nodesY(int j) const { return nodeH_[j]; }
    int tilesX(TileKind kind, int level) const;
    int tilesY(TileKind kind, int level) const;
    // Position of a tile in the index; -1 when the key names no tile.
    std::int64_t entryIndex(const TileKey& key) const;
    std::int64_t entryCount() const { return entryCount_; }
    // The key at an index position (the inverse of entryIndex).
    TileKey keyAt(std::int64_t index) const;
    // A tile's first sample (display) or node, and its extent in samples or nodes.
    void tileExtent(const TileKey& key, int& x0, int& y0, int& width, int& height) const;

  private:
    int tileSize_ = 0;
    std::vector<int> levelW_, levelH_, nodeW_, nodeH_;
    std::vector<std::int64_t> displayBase_, nodeBase_;
    std::int64_t entryCount_ = 0;
};

// One tile, decoded. Display: heights and colours width x height (rows south first), maxima
// the (width - 1) x (height - 1) cell maxima. Nodes: maxima width x height node bounds.
struct TerrainTile {
    TileKey key;
    int x0 = 0, y0 = 0, width = 0, height = 0;
    std::vector<std::uint16_t> heights;
    std::vector<Rgb8> colors;
    std::vector<std::uint16_t> maxima;
    std::size_t bytes() const {
        return heights.size() * 2 + colors.size() * sizeof(Rgb8) + maxima.size() * 2;
    }
};

// What the header says about the map.
struct TerrainDbInfo {
    int width = 0, height = 0;  // level-0 samples
    double spacingX = 1.0, spacingY = 1.0, heightScale = 1.0, heightOffset = 0.0;
    // Georeference: the CRS coordinates of sample (0, 0) (the south-west one) and the CRS as
    // WKT; NaN and empty when the source had none.
    double originX = 0.0, originY = 0.0;
    std::string crs;
    std::uint16_t minRaw = 0, maxRaw = 0;  // raw height range of level 0
    // The largest raw difference between neighbouring level-0 samples along x and along y
    // (what TerrainMap's global slope bound is made of).
    std::uint16_t maxDx = 0, maxDy = 0;
    // The global slope bound, m/m: TerrainMap::maxSlope() of the whole map, to the bit.
    double maxSlope() const;
};

// A high-resolution inset held in a database (docs/design/insets.md): its nested map (the
// fine samples blended into the global surface, inside a skirt) is a whole database of its own
// embedded in the file, so it is paged like the global map; where it lies is ig::Inset's
// placement, in global samples.
struct DbInset {
    std::string name;
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;   // global samples of its corners
    int factor = 2;                       // global spacing / its spacing
    int mapX0 = 0, mapY0 = 0;             // the global sample at its map's sample (0, 0)
    std::uint64_t offset = 0, bytes = 0;  // the embedded database's place in the file
};

// Encodes a tile as stored (tile header + payload, compressed by `codec`); thread-safe.
std::vector<std::uint8_t> encodeTile(const TerrainTile& tile, TileCodec codec,
                                     std::uint32_t& rawPayloadBytes);

// Writes a database to `path` through a temporary file beside it, renamed over `path` only by
// finish() (after fsync): an interrupted write leaves no file at `path`. Tiles may come in any
// order; every tile of the layout must be written once.
class TerrainDbWriter {
  public:
    TerrainDbWriter(const std::string& path, const TerrainDbLayout& layout, TileCodec codec);
    ~TerrainDbWriter();  // removes the temporary file unless finished
    TerrainDbWriter(const TerrainDbWriter&) = delete;
    TerrainDbWriter& operator=(const TerrainDbWriter&) = delete;

    const std::string& temporaryPath() const { return tmpPath_; }
    TileCodec codec() const { return codec_; }
    // Appends an encoded tile (encodeTile's output).
    void append(const TileKey& key, const std::vector<std::uint8_t>& stored,
                std::uint32_t rawPayloadBytes);
    void write(const TerrainTile& tile);
    // Writes row `by` of the slope section: SlopeBlocks::blocksAlong(width) bounds, as
    // SlopeBlocks computes them over the map. Every row must be written once.
    void writeSlopeRow(int by, const float* bounds);
    // An inset's database to embed at finish(): `file`, a finished database written with
    // keepTemporary(), is copied in and removed.
    struct Embedded {
        DbInset inset;
        std::string file;
    };
    // finish() leaves the complete file at temporaryPath() (for the caller to embed) instead
    // of renaming it.
    void keepTemporary() { keepTemporary_ = true; }
    // Writes index, header and the embedded insets, syncs and renames; returns the file's size.
    std::uint64_t finish(const TerrainDbInfo& info, const std::vector<Embedded>& insets = {});

  private:
    struct Entry;
    std::string path_, tmpPath_;
    TerrainDbLayout layout_;
    TileCodec codec_;
    int fd_ = -1;
    std::uint64_t end_ = 0;
    std::vector<std::uint8_t> index_;  // entryCount * entry bytes
    std::vector<std::uint8_t> written_;
    int slopeRowsWritten_ = 0;
    bool finished_ = false;
    bool keepTemporary_ = false;
};

// A database opened for reading. Reads are pread()s: readTile may be called from any thread.
// Every problem (not a database, another version, a truncated or corrupt file, an index that
// disagrees with a tile) is an InputError naming the file and, for a tile, the tile.
class TerrainDb {
  public:
    static TerrainDb open(const std::string& path);
    TerrainDb(TerrainDb&&) noexcept;
    TerrainDb& operator=(TerrainDb&&) noexcept;
    ~TerrainDb();

    const std::string& path() const { return path_; }
    const TerrainDbInfo& info() const { return info_; }
    const TerrainDbLayout& layout() const { return layout_; }
    TileCodec codec() const { return codec_; }
    std::uint64_t fileBytes() const { return fileBytes_; }
    // Stored bytes of a tile (header, payload, as on disk).
    std::uint32_t storedBytes(const TileKey& key) const;
    TerrainTile readTile(const TileKey& key) const;
    // InputError when the map has more samples than a map loaded whole holds
    // (kMaxImageSamples, 2^30).
    void checkLoadable() const;
    // InputError when the map has more samples than a paged map's sparse arrays address
    // (kMaxPagedSamples, 2^36: about 640 GB of address space reserved, pages taken only where
    // tiles are placed; the casters index with 64-bit offsets).
    void checkPageable() const;
    // Level 0 assembled into a map (heights, colours; ranges recomputed).
    TerrainMap loadMap() const;
    // The insets the database holds (none in a version 2 file).
    const std::vector<DbInset>& insets() const { return insets_; }
    // Inset k's own database (its map nested already), read from this file; checked as open().
    TerrainDb openInset(std::size_t k) const;
    // The slope section: SlopeBlocks::blocksAlong(width) x blocksAlong(height) per-block slope
    // bounds, rows south first, equal to SlopeBlocks(map) of the whole map (checked against
    // its CRC-32 at open; mapped from the file, so only the pages read take memory).
    const float* slopeBounds() const { return slopes_; }

  private:
    TerrainDb() = default;
    // The database in bytes [base, base + bytes) of `file` (bytes 0: to its end), named `name`
    // in messages.
    static TerrainDb openAt(const std::string& file, const std::string& name, std::uint64_t base,
                            std::uint64_t bytes);
    std::string path_, file_;
    std::uint64_t base_ = 0;
    std::vector<DbInset> insets_;
    int fd_ = -1;
    TerrainDbInfo info_;
    TerrainDbLayout layout_;
    TileCodec codec_ = TileCodec::None;
    std::uint64_t fileBytes_ = 0, indexOffset_ = 0;
    std::vector<std::uint8_t> index_;
    void* mapped_ = nullptr;  // header and slope section, read-only
    std::size_t mappedBytes_ = 0;
    const float* slopes_ = nullptr;
};

}  // namespace ig
