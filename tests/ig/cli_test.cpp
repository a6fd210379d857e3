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

// A map nearly all void reads as such, never "1e+02 %" nor "100 %" while one sample had data.
TEST(DescribeTerrain, NearlyAllVoidReadsAsANumber) {
    TerrainMap map(100, 100, 1.0, 1.0, 1.0, 0.0);
    map.updateRange();
    map.setFilledSamples(9995);
    EXPECT_NE(ig::describeTerrain(map).find("(99.95 %)"), std::string::npos)
        << ig::describeTerrain(map);
    map.setFilledSamples(9999);
    EXPECT_NE(ig::describeTerrain(map).find("(99.99 %)"), std::string::npos)
        << ig::describeTerrain(map);
}

// Terrain numbers outside a physical range are refused before anything is loaded, readably.
TEST(LoadTerrainFromOptions, RefusesNumbersOutsideTheirRanges) {
    auto message = [](ig::TerrainOptions o) -> std::string {
        try {
            ig::loadTerrainFromOptions(o);
        } catch (const ig::InputError& e) {
            return e.what();
        }
        return "";
    };
    ig::TerrainOptions o;
    o.synthetic = "64:1";
    o.spacing = 1e300;
    EXPECT_EQ(message(o), "--spacing: 1e+300 is outside 0.001 .. 100000 metres");
    o.spacing = 0.0;
    EXPECT_NE(message(o).find("--spacing"), std::string::npos);
    o.spacing.reset();
    o.synthetic.clear();
    o.height = "unused.png";
    o.heightOffset = 1e300;
    EXPECT_EQ(message(o), "--height-offset: 1e+300 is outside -100000 .. 100000 metres");
    o.heightOffset.reset();
    o.heightScale = std::nan("");
    EXPECT_EQ(message(o), "--height-scale: nan is outside 1e-06 .. 10000 metres per height unit");
}

}  // namespace
