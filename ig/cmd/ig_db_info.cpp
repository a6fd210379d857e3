// ig-db-info: prints a terrain database's header and, with --verify, reads every tile (checksums,
// index against tiles); exit status 2 names the first problem.
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/terrain_db.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

int main(int argc, char** argv) {
    return ig::runProgram("ig-db-info", [&]() -> int {
        CLI::App app{
            "Prints a terrain database's header (docs/formats.md) as JSON; --verify "
            "reads and checks every tile."};
        std::string path;
        bool verify = false;
        app.add_option("db", path, "Database file")->required();
        app.add_flag("--verify", verify, "Read every tile and check its checksum and header");
        try {
            app.parse(argc, argv);
        } catch (const CLI::ParseError& e) {
            return app.exit(e) == 0 ? 0 : 2;
        }
        const ig::TerrainDb db = ig::TerrainDb::open(path);
        const ig::TerrainDbInfo& info = db.info();
        const ig::TerrainDbLayout& lay = db.layout();
        nlohmann::json j = {{"width", info.width},
                            {"height", info.height},
                            {"tile", lay.tileSize()},
                            {"codec", ig::tileCodecName(db.codec())},
                            {"display_levels", lay.displayLevels()},
                            {"node_levels", lay.nodeLevels() - 1},
                            {"tiles", lay.entryCount()},
                            {"spacing", {info.spacingX, info.spacingY}},
                            {"height_scale", info.heightScale},
                            {"height_offset", info.heightOffset},
                            {"raw_range", {info.minRaw, info.maxRaw}},
                            {"file_bytes", db.fileBytes()}};
        if (std::isfinite(info.originX)) j["origin"] = {info.originX, info.originY};
        if (!info.crs.empty()) j["crs"] = info.crs;
        // The insets' own databases, each opened (and verified) as the map's.
        std::int64_t insetTiles = 0;
        for (std::size_t k = 0; k < db.insets().size(); ++k) {
            const ig::DbInset& in = db.insets()[k];
            const ig::TerrainDb own = db.openInset(k);
            j["insets"].push_back({{"name", in.name},
                                   {"cells", {in.x0, in.y0, in.x1, in.y1}},
                                   {"factor", in.factor},
                                   {"samples", {own.info().width, own.info().height}},
                                   {"tiles", own.layout().entryCount()},
                                   {"bytes", in.bytes}});
            if (verify) {
                for (std::int64_t i = 0; i < own.layout().entryCount(); ++i)
                    own.readTile(own.layout().keyAt(i));
                insetTiles += own.layout().entryCount();
            }
        }
        if (verify) {
            const auto start = std::chrono::steady_clock::now();
            for (std::int64_t i = 0; i < lay.entryCount(); ++i)
                db.readTile(lay.keyAt(i));
            const double s =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            j["verified_tiles"] = lay.entryCount() + insetTiles;
            j["verify_seconds"] = s;
        }
        std::printf("%s\n", j.dump(2).c_str());
        return 0;
    });
}
