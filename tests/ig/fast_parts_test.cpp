// Parts of the fast caster on their own: the coherence proof and the level-0 march, against
// the arithmetic they state and against the naive caster's grid march.
#include "ig/coherence.hpp"
#include "ig/grid_march.hpp"
#include "ig/level0_march.hpp"
#include "ig/surface_hit.hpp"
#include "ig/synthetic.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>

namespace {

TEST(Coherence, ClearExactlyWhenTheClimbOutrunsTheTerrainAcrossTheGap) {
    // Terrain rising at most 1 per metre, cells of 10 m: a gap of 0.04 cells lets it rise 0.4.
    EXPECT_TRUE(ig::climbsClearOf(0.5, 1.0, 10.0, 0.04));
    EXPECT_TRUE(ig::climbsClearOf(0.4, 1.0, 10.0, 0.04));
    EXPECT_FALSE(ig::climbsClearOf(0.39, 1.0, 10.0, 0.04));
    EXPECT_FALSE(ig::climbsClearOf(-0.1, 0.0, 10.0, 0.0));  // a ray lower than the one below
    EXPECT_TRUE(ig::climbsClearOf(0.0, 0.0, 10.0, 0.0));    // flat terrain, the same track
}

TEST(Coherence, LanesGiveTheOneRayAnswer) {
    using V4 = double __attribute__((vector_size(32)));
    using M4 = decltype(V4{} < V4{});
    const V4 climb = {0.5, 0.4, 0.39, -0.1}, gap = {0.04, 0.04, 0.04, 0.0};
    M4 clear;
    ig::testClimb(climb, 1.0, 10.0, gap, clear);
    for (int l = 0; l < 4; ++l)
        EXPECT_EQ(clear[l] != 0, ig::climbsClearOf(climb[l], 1.0, 10.0, gap[l])) << l;
}

// From the eye (inside the map), the coherent level-0 march finds the grid march's hit: the
// same step, solved in the major-axis parameter instead of t.
TEST(Level0March, FindsTheGridMarchHit) {
    const ig::TerrainMap map = ig::makeSyntheticTerrain(128, 5, 10.0);
    const double scale = map.heightScale(), offset = map.heightOffset();
    const ig::fast::MapView mv{map.rawHeights().data(),
                               map.cellMaxData(),
                               map.colors().data(),
                               map.width(),
                               map.height(),
                               scale,
                               offset,
                               1.0 / scale,
                               (map.maxHeight() - offset) / scale};
    const glm::dvec3 eye{640.0, 610.0, map.surfaceHeight(640.0, 610.0) + 150.0};
    const double invSx = 1.0 / map.spacingX(), invSy = 1.0 / map.spacingY();
    const ig::fast::EyeGrid eg{eye.x * invSx, eye.y * invSy, eye.z, true, (eye.z - offset) / scale};
    int hits = 0, rays = 0;
    for (int k = 0; k < 36; ++k) {
        for (const double pitchDeg : {-3.0, -8.0, -20.0, -45.0}) {
            const double yaw = (10.0 * k + 3.0) * M_PI / 180.0, pitch = pitchDeg * M_PI / 180.0;
            const glm::dvec3 d{std::cos(pitch) * std::sin(yaw), std::cos(pitch) * std::cos(yaw),
                               std::sin(pitch)};
            // The ray in major-axis form, as the caster's kernels set it up.
            const double gx = d.x * invSx, gy = d.y * invSy;
            const bool majorX = std::abs(gx) >= std::abs(gy);
            const double gm = majorX ? gx : gy, gn = majorX ? gy : gx;
            const double inv = 1.0 / std::abs(gm);
            const int sgn = gm > 0 ? 1 : -1;
            const double len = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
            std::uint64_t steps = 0;
            const double inf = std::numeric_limits<double>::infinity();
            const ig::fast::ColumnMarch r =
                majorX ? ig::fast::marchCoherent<true>(mv, eg, sgn, gn * inv, d.z * inv, 0.0, inf,
                                                       steps)
                       : ig::fast::marchCoherent<false>(mv, eg, sgn, gn * inv, d.z * inv, 0.0, inf,
                                                        steps);
            const ig::TerrainRay ray(map, eye, d);
            double t0 = 0.0, t1 = 0.0, t = -1.0;
            std::uint64_t gridSteps = 0;
            if (ig::clipToMapBox(map, ray, t0, t1)) t = ig::marchRay(map, ray, t0, t1, gridSteps);
            ++rays;
            if (r.kind == ig::fast::ColumnMarch::kHit) {
                ++hits;
                ASSERT_GE(t, 0.0) << "ray " << k << " pitch " << pitchDeg;
                EXPECT_NEAR(r.u * len * inv, t, 1e-9 * t) << "ray " << k << " pitch " << pitchDeg;
            } else {
                EXPECT_LT(t, 0.0) << "ray " << k << " pitch " << pitchDeg;
            }
        }
    }
    EXPECT_GE(hits, rays / 2);  // measured: 72 of 144 (the shallow ones leave the map)
}

}  // namespace
