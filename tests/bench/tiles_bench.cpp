// bench-tiles: the terrain database's tile size and codec by measurement. For each tile
// size and codec it builds the synthetic map's database, then reads every level-0 tile with
// `--threads` readers (pread + decode, as the tile cache's loaders do), cold (the file dropped
// from the page cache with posix_fadvise) and warm, `--runs` times; and it sums the decoded
// bytes of the frame footprints over a pose sweep (what a frame needs resident at that tile
// size). Writes JSON (--json) for scripts/results.py.
#include "ig/camera.hpp"
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_db_build.hpp"
#include "ig/tile_footprint.hpp"

#include <fcntl.h>
#include <unistd.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

namespace {

void dropFromPageCache(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return;
    ::fdatasync(fd);
    ::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
    ::close(fd);
}

// Reads every level-0 display tile with `threads` readers; returns seconds, adds decoded bytes.
double readLevel0(const ig::TerrainDb& db, int threads, std::uint64_t& bytes) {
    const ig::TerrainDbLayout& lay = db.layout();
    const int nx = lay.tilesX(ig::TileKind::Display, 0), ny = lay.tilesY(ig::TileKind::Display, 0);
    std::atomic<int> next{0};
    std::atomic<std::uint64_t> total{0};
    const auto start = std::chrono::steady_clock::now();
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) {
        pool.emplace_back([&] {
            for (int i = next++; i < nx * ny; i = next++) {
                const ig::TerrainTile tile =
                    db.readTile({ig::TileKind::Display, 0, i % nx, i / nx});
                total += tile.bytes();
            }
        });
    }
    for (std::thread& t : pool)
        t.join();
    bytes = total;
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

nlohmann::json summary(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return {{"median", v[v.size() / 2]}, {"min", v.front()}, {"max", v.back()}, {"runs", v}};
}

}  // namespace

int main(int argc, char** argv) {
    return ig::runProgram("bench-tiles", [&]() -> int {
        CLI::App app{"Terrain database tile size and codec, measured"};
        int size = 2048, runs = 3, threads = 2, poses = 16;
        std::string dir = "/tmp/bench-tiles", json;
        std::vector<int> tiles = {64, 128, 256, 512};
        std::vector<std::string> codecs = {"none", "lz4", "zstd"};
        app.add_option("--size", size, "Synthetic map size (power of two)");
        app.add_option("--runs", runs, "Read passes per configuration");
        app.add_option("--threads", threads, "Reader threads");
        app.add_option("--tiles", tiles, "Tile sizes");
        app.add_option("--codecs", codecs, "Codecs");
        app.add_option("--poses", poses, "Poses of the footprint sweep");
        app.add_option("--dir", dir, "Scratch folder for the databases");
        app.add_option("--json", json, "Write the results here");
        try {
            app.parse(argc, argv);
        } catch (const CLI::ParseError& e) {
            return app.exit(e) == 0 ? 0 : 2;
        }
        std::filesystem::create_directories(dir);
        nlohmann::json out = {
            {"size", size}, {"threads", threads}, {"configs", nlohmann::json::array()}};
        // Poses over the map (the sweep needs a map: the 1024 corner is the same terrain).
        const ig::TerrainMap corner = ig::makeSyntheticTerrain(std::min(size, 4096), 1);
        std::vector<ig::Pose> sweep = ig::sweepPoses(corner, poses);
        const ig::Intrinsics intr = ig::Intrinsics::fromFov(720, 486, 50.0 * M_PI / 180.0, 32);
        for (const int tile : tiles) {
            for (const std::string& codec : codecs) {
                const std::string path = dir + "/s" + std::to_string(size) + "_t" +
                                         std::to_string(tile) + "_" + codec + ".db";
                auto source = ig::syntheticRowSource(size, 1);
                ig::DbBuildOptions o;
                o.tileSize = tile;
                o.codec = ig::parseTileCodec(codec);
                const ig::DbBuildStats b = ig::buildTerrainDb(*source, path, o);
                const ig::TerrainDb db = ig::TerrainDb::open(path);
                std::vector<double> coldTiles, warmTiles, coldMB, warmMB;
                const int n = db.layout().tilesX(ig::TileKind::Display, 0) *
                              db.layout().tilesY(ig::TileKind::Display, 0);
                for (int r = 0; r < runs; ++r) {
                    std::uint64_t bytes = 0;
                    dropFromPageCache(path);
                    double s = readLevel0(db, threads, bytes);
                    coldTiles.push_back(n / s);
                    coldMB.push_back(bytes / s / 1e6);
                    s = readLevel0(db, threads, bytes);
                    warmTiles.push_back(n / s);
                    warmMB.push_back(bytes / s / 1e6);
                }
                // Decoded bytes a frame needs at this tile size (mean over the sweep).
                double footprintBytes = 0, footprintTiles = 0;
                for (const ig::Pose& pose : sweep) {
                    const ig::Camera cam(pose, intr);
                    const auto sel = ig::LevelSelection::forCamera(intr, db.info(), -1);
                    const ig::Footprint fp = ig::frameFootprint(cam, db.layout(), db.info(), sel);
                    for (const ig::TileKey& k : fp.tiles) {
                        int x0, y0, w, h;
                        db.layout().tileExtent(k, x0, y0, w, h);
                        const double cells = static_cast<double>(w) * h;
                        footprintBytes += k.kind == ig::TileKind::Display
                                              ? cells * 5 + (w - 1.0) * (h - 1.0) * 2
                                              : cells * 2;
                        footprintTiles += 1;
                    }
                }
                footprintBytes /= static_cast<double>(sweep.size());
                footprintTiles /= static_cast<double>(sweep.size());
                nlohmann::json c = {{"tile", tile},
                                    {"codec", codec},
                                    {"file_bytes", b.fileBytes},
                                    {"build_seconds", b.seconds},
                                    {"build_cpu_seconds", b.cpuSeconds},
                                    {"level0_tiles", n},
                                    {"cold_tiles_per_s", summary(coldTiles)},
                                    {"warm_tiles_per_s", summary(warmTiles)},
                                    {"cold_mb_per_s", summary(coldMB)},
                                    {"warm_mb_per_s", summary(warmMB)},
                                    {"footprint_mb", footprintBytes / 1e6},
                                    {"footprint_tiles", footprintTiles}};
                std::printf(
                    "tile %4d %-4s: %7.1f MB, build %.1f s (%.1f CPU s), cold %8.0f tiles/s "
                    "%7.0f MB/s, warm %8.0f tiles/s %7.0f MB/s, footprint %.1f MB in %.0f tiles\n",
                    tile, codec.c_str(), b.fileBytes / 1e6, b.seconds, b.cpuSeconds,
                    c["cold_tiles_per_s"]["median"].get<double>(),
                    c["cold_mb_per_s"]["median"].get<double>(),
                    c["warm_tiles_per_s"]["median"].get<double>(),
                    c["warm_mb_per_s"]["median"].get<double>(), footprintBytes / 1e6,
                    footprintTiles);
                std::fflush(stdout);
                out["configs"].push_back(c);
                std::filesystem::remove(path);
            }
        }
        if (!json.empty()) std::ofstream(json) << out.dump(2) << "\n";
        return 0;
    });
}
