// The small terrain database the paging tests share: a 257 x 257 synthetic map (10 m) and its
// database in tiles of 16, in a file of its own per process (ctest runs tests side by side).
#pragma once

#include "ig/synthetic.hpp"
#include "ig/terrain.hpp"
#include "ig/terrain_db_build.hpp"

#include <unistd.h>

#include <filesystem>
#include <string>

namespace vig_test {

// `name` in the test folder `folder` (made when missing).
inline std::string testTmpPath(const std::string& folder, const std::string& name) {
    const std::filesystem::path dir = std::filesystem::path(VIG_TEST_TMP) / folder;
    std::filesystem::create_directories(dir);
    return (dir / name).string();
}

struct SmallTerrainDb {
    ig::TerrainMap map;
    std::string path;
    explicit SmallTerrainDb(const std::string& folder)
        : map(ig::makeSyntheticTerrain(256, 6)),
          path(testTmpPath(folder, "map_" + std::to_string(::getpid()) + ".db")) {
        auto source = ig::mapRowSource(map);
        ig::DbBuildOptions o;
        o.tileSize = 16;
        ig::buildTerrainDb(*source, path, o);
    }
    ~SmallTerrainDb() { std::filesystem::remove(path); }
    SmallTerrainDb(const SmallTerrainDb&) = delete;
    SmallTerrainDb& operator=(const SmallTerrainDb&) = delete;
};

}  // namespace vig_test
