// ig-build-db: builds a tiled terrain database (docs/formats.md) from terrain files or the
// synthetic generator, streaming strip by strip; prints what it built and its peak memory.
#include "base/text.hpp"
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_db_build.hpp"
#include "ig/terrain_io.hpp"

#include <unistd.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <optional>
#include <string>

namespace {

// The temporary file of the build in progress, removed when the build is interrupted.
char gPartial[4096];

extern "C" void onStopSignal(int sig) {
    if (gPartial[0] != '\0') ::unlink(gPartial);
    std::signal(sig, SIG_DFL);
    std::raise(sig);
}

}  // namespace

int main(int argc, char** argv) {
    return ig::runProgram("ig-build-db", [&]() -> int {
        CLI::App app{
            "Builds a tiled terrain database: heights, colours, the display pyramid and the "
            "max-height nodes cut into square tiles per level (docs/formats.md). Reads the map "
            "strip by strip, so maps larger than memory build in a few hundred MB."};
        ig::TerrainOptions terrain;
        ig::addTerrainOptions(app, terrain);
        ig::InsetOptions insets;
        ig::addInsetOptions(app, insets);
        std::string out, json, codec;
        int tile = 0;
        bool quiet = false;
        app.add_option("--out", out,
                       "Database file to write (replaced only when complete; may be --db's)")
            ->required();
        app.add_option("--tile", tile,
                       "Tile size in cells, a power of two 16..4096 (default 64, or --db's)");
        app.add_option("--codec", codec,
                       "Tile compression: none, lz4 or zstd (default none, or --db's)");
        app.add_option("--json", json, "Write build statistics as JSON to this file");
        app.add_flag("--quiet", quiet, "No progress bar");
        try {
            app.parse(argc, argv);
        } catch (const CLI::ParseError& e) {
            return app.exit(e) == 0 ? 0 : 2;
        }
        // An existing database: its level 0 streamed again, its insets kept, new ones added.
        std::optional<ig::TerrainDb> db;
        if (!terrain.db.empty()) {
            if (!terrain.height.empty() || !terrain.color.empty() ||
                (terrain.spacing && terrain.synthetic.empty()) || terrain.heightScale ||
                terrain.heightOffset || terrain.voidHeight) {
                throw ig::InputError(
                    "--db: the database holds the map; give no other terrain flags (only "
                    "--synthetic and --spacing, the generator it was built from, for synthetic "
                    "insets)");
            }
            db.emplace(ig::TerrainDb::open(terrain.db));
            if (tile == 0) tile = db->layout().tileSize();
            if (codec.empty()) codec = ig::tileCodecName(db->codec());
        }
        if (tile == 0) tile = 64;
        if (codec.empty()) codec = "none";
        if (tile < ig::kMinDbTileSize || tile > ig::kMaxDbTileSize || (tile & (tile - 1)) != 0) {
            throw ig::InputError(
                "--tile: " + std::to_string(tile) + " is not a power of two from " +
                std::to_string(ig::kMinDbTileSize) + " to " + std::to_string(ig::kMaxDbTileSize));
        }
        ig::DbBuildOptions options;
        options.tileSize = tile;
        options.codec = ig::parseTileCodec(codec);

        std::unique_ptr<ig::TerrainRowSource> source;
        ig::TerrainMap whole;  // a map the streaming reader does not take, loaded whole
        std::string how;
        if (db) {
            if (const auto syn = ig::parseSyntheticOption(terrain, ig::kMaxSyntheticStreamSize)) {
                if (syn->size != db->info().width || syn->size != db->info().height ||
                    syn->spacing != db->info().spacingX) {
                    throw ig::InputError("--synthetic: " + std::to_string(syn->size) +
                                         " samples at " + base::number(syn->spacing) +
                                         " m is not " + terrain.db + "'s map (" +
                                         std::to_string(db->info().width) + " x " +
                                         std::to_string(db->info().height) + " at " +
                                         base::number(db->info().spacingX) + " m)");
                }
            }
            source = ig::dbRowSource(*db);
            options.nestedInsets = ig::readInsets(*db);
            how = "level 0 of " + terrain.db + ", " + std::to_string(db->insets().size()) +
                  " inset(s) kept";
        } else if (const auto syn =
                       ig::parseSyntheticOption(terrain, ig::kMaxSyntheticStreamSize)) {
            source = ig::syntheticRowSource(syn->size, syn->seed, syn->spacing);
            how = "synthetic, streamed";
        } else if (const auto src = ig::terrainSourceFromOptions(terrain)) {
            std::string why;
            source = ig::gdalRowSource(*src, why);
            how = "streamed window by window";
            if (!source) {
                whole = ig::loadTerrain(*src);
                source = ig::mapRowSource(whole);
                how = "read whole: " + why;
            }
        } else {
            whole = ig::loadPugetSound();
            source = ig::mapRowSource(whole);
            how = "the shipped Puget Sound map";
        }
        const ig::TerrainDbInfo info = source->info();
        if (insets.any()) {
            const ig::GlobalGrid grid{info.width,    info.height,      info.spacingX,
                                      info.spacingY, info.heightScale, info.heightOffset};
            ig::Georeference geo;
            geo.originX = info.originX;
            geo.originY = info.originY;
            geo.crs = info.crs;
            options.insets =
                ig::insetSources(grid, geo, terrain, insets, ig::kMaxSyntheticStreamSize);
            options.insetBlend = insets.blendCells;
        }
        if (!quiet) {
            std::fprintf(stderr, "ig-build-db: %d x %d samples (%s) -> %s, tiles %d, %s\n",
                         info.width, info.height, how.c_str(), out.c_str(), tile, codec.c_str());
        }
        const std::string partial = out + ".partial";
        if (partial.size() < sizeof gPartial) {
            std::memcpy(gPartial, partial.c_str(), partial.size() + 1);
            std::signal(SIGINT, onStopSignal);
            std::signal(SIGTERM, onStopSignal);
            std::signal(SIGHUP, onStopSignal);
        }
        const bool bar = !quiet && isatty(STDERR_FILENO) != 0;
        int shown = -1;
        if (bar) {
            options.progress = [&](double f) {
                const int pct = static_cast<int>(f * 100.0);
                if (pct == shown) return;
                shown = pct;
                const int filled = pct / 4;
                std::fprintf(stderr, "\r[%.*s%*s] %3d%%", filled, "#########################",
                             25 - filled, "", pct);
                if (pct >= 100) std::fputc('\n', stderr);
                std::fflush(stderr);
            };
        }
        const ig::DbBuildStats stats = ig::buildTerrainDb(*source, out, options);
        gPartial[0] = '\0';
        const double rate = stats.samples / std::max(stats.seconds, 1e-9);
        std::printf(
            "%s: %llu tiles, %.1f MB, %.2f s (%.2f s of CPU), %.3g samples/s, peak RSS %.1f MB\n",
            out.c_str(), static_cast<unsigned long long>(stats.tiles), stats.fileBytes / 1e6,
            stats.seconds, stats.cpuSeconds, rate, stats.peakRssBytes / 1e6);
        const std::size_t insetCount = options.nestedInsets.size() + options.insets.size();
        if (insetCount > 0) {
            std::printf("%s: %zu inset(s) embedded, each a database of its own\n", out.c_str(),
                        insetCount);
        }
        if (!json.empty()) {
            nlohmann::json j = {{"width", info.width},
                                {"height", info.height},
                                {"tile", tile},
                                {"codec", codec},
                                {"tiles", stats.tiles},
                                {"file_bytes", stats.fileBytes},
                                {"seconds", stats.seconds},
                                {"cpu_seconds", stats.cpuSeconds},
                                {"samples_per_second", rate},
                                {"peak_rss_bytes", stats.peakRssBytes},
                                {"source", how},
                                {"insets", insetCount}};
            std::ofstream f(json);
            f << j.dump(2) << "\n";
            if (!f) throw ig::InputError(json + ": cannot write");
        }
        return 0;
    });
}
