// Building a terrain database by streaming: the map's rows come strip by strip from a source
// (a map in memory, the synthetic generator, a GDAL raster) and leave as tiles of every level;
// memory stays a few tile rows per level whatever the map's size.
#pragma once

#include "ig/inset.hpp"
#include "ig/terrain_db.hpp"
#include "ig/terrain_io.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace ig {

// Rows of a map, south first, a strip at a time.
class TerrainRowSource {
  public:
    virtual ~TerrainRowSource() = default;
    // Size, spacing, height scale/offset and georeference (minRaw/maxRaw are the builder's).
    virtual TerrainDbInfo info() const = 0;
    // Fills rows [y0, y0 + rows) into `heights` and `colors`, width samples a row.
    virtual void readRows(int y0, int rows, std::uint16_t* heights, Rgb8* colors) = 0;
};

// A map already in memory (tests, and files the streaming reader does not take).
std::unique_ptr<TerrainRowSource> mapRowSource(const TerrainMap& map);
// Level 0 of a database, tile row by tile row (adding insets to it).
std::unique_ptr<TerrainRowSource> dbRowSource(const TerrainDb& db);
// Inset k of a database: its placement in world metres (its map empty).
Inset insetPlacement(const TerrainDb& db, std::size_t k);
// Its insets, their maps read back (each box's floor as stored).
std::vector<Inset> readInsets(const TerrainDb& db);
// The synthetic generator's map, any power-of-two size up to kMaxSyntheticStreamSize.
std::unique_ptr<TerrainRowSource> syntheticRowSource(int size, std::uint64_t seed,
                                                     double spacing = 10.0);
// A GDAL raster read window by window, when it can be: heights of an integer band of 16 bits
// or fewer that needs no scaling or void filling, a colour raster (if any) of the same size,
// north-up. Empty when the file needs the whole-map loader (float heights quantised over their
// range, voids, reprojection, colour resampling, a derived spacing); the reason in `why`.
// Throws InputError for a file that cannot be read at all.
std::unique_ptr<TerrainRowSource> gdalRowSource(const TerrainSource& source, std::string& why);

struct DbBuildOptions {
    int tileSize = 64;
    TileCodec codec = TileCodec::None;
    // Level-0 rows read from the source at a time (0: up to 512 rows and 64 MiB, at least a
    // tile row). The database does not depend on it.
    int stripRows = 0;
    // Called with the fraction done (0..1) now and then, from the building thread.
    std::function<void(double)> progress;
    // High-resolution insets (docs/design/insets.md): `insets` are nested as the map streams
    // by (the global samples over each lowered, each one's map made from a window of the
    // lowered map around it); `nestedInsets`, nested already (an existing database's,
    // readInsets), are kept. Each is embedded as a database of its own, its box reaching
    // down to the map's lowest sample. A new inset closer than the skirt to a kept one is
    // refused (nest them in one build).
    std::vector<InsetSource> insets;
    int insetBlend = 16;
    std::vector<Inset> nestedInsets;
};

struct DbBuildStats {
    double seconds = 0;
    double cpuSeconds = 0;        // user + system time of the whole process over the build
    std::uint64_t samples = 0;    // level-0 samples
    std::uint64_t fileBytes = 0;  // database size
    std::uint64_t tiles = 0;
    std::size_t peakRssBytes = 0;  // the process's high-water mark when the build finished
};

// Builds the database at `path` (written under a temporary name, renamed when complete).
DbBuildStats buildTerrainDb(TerrainRowSource& source, const std::string& path,
                            const DbBuildOptions& options);

// The process's peak resident set (VmHWM) and its resident set now (VmRSS), bytes; 0 where
// unknown.
std::size_t peakResidentBytes();
std::size_t residentBytes();

}  // namespace ig
