// Shared program helpers: the default view of any map, the terrain line, output checks.
#include "ig/cli.hpp"
#include "ig/caster.hpp"
#include "ig/error.hpp"
#include "ig/synthetic.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

namespace {

using ig::TerrainMap;

// Share of a frame's pixels that show terrain.
double terrainShare(const TerrainMap& map, const ig::Pose& pose) {
    const ig::Intrinsics in = ig::Intrinsics::fromFov(64, 48, ig::degToRad(60), 0);
    const auto caster = ig::makeCaster(ig::CasterKind::Fast, map);
    const ig::RenderedFrame frame = ig::renderFrame(*caster, map, pose, in);
    int terrain = 0;
    for (float d : frame.depth)
        terrain += std::isfinite(d);
    return static_cast<double>(terrain) / frame.depth.size();
}

TEST(DefaultViewPose, LooksAtTheTerrainOfAnyMap) {
    // A rough square map, a flat one, and a long narrow one with unequal spacing.
    TerrainMap flat(50, 40, 30.0, 30.0, 1.0, -120.0);
    flat.updateRange();
    TerrainMap narrow(400, 60, 5.0, 40.0, 0.5, 2000.0);
    for (int iy = 0; iy < 60; ++iy)
        for (int ix = 0; ix < 400; ++ix)
            narrow.setRaw(ix, iy, static_cast<std::uint16_t>(200 + 150 * std::sin(ix * 0.05)));
    narrow.updateRange();
    const TerrainMap maps[] = {ig::makeSyntheticTerrain(256, 3, 10.0), std::move(flat),
                               std::move(narrow)};
    for (const TerrainMap& map : maps) {
        const ig::Pose pose = ig::defaultViewPose(map);
        SCOPED_TRACE(ig::describeTerrain(map));
        EXPECT_GT(pose.position.x, 0.0);
        EXPECT_LT(pose.position.x, map.extentX());
        EXPECT_GT(pose.position.y, 0.0);
        EXPECT_LT(pose.position.y, map.extentY());
        EXPECT_GE(pose.position.z - map.surfaceHeight(pose.position.x, pose.position.y), 50.0);
        EXPECT_LT(pose.pitch, 0.0);
        EXPECT_EQ(pose.roll, 0.0);
        EXPECT_GT(terrainShare(map, pose), 0.3);
    }
}

TEST(DescribeTerrain, CountsFilledSamples) {
    TerrainMap map(10, 10, 1.0, 1.0, 1.0, 0.0);
    map.updateRange();
    EXPECT_EQ(ig::describeTerrain(map).find("without data"), std::string::npos);
    map.setFilledSamples(25);
    EXPECT_NE(ig::describeTerrain(map).find("25 samples without data filled (25 %)"),
              std::string::npos)
        << ig::describeTerrain(map);
}

}  // namespace
