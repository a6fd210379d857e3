// Which database tiles a frame can touch (Cohen-Or sec. 3.2: square tiles paged by the frame's
// footprint, a wider footprint prefetched): the cells of the view frustum between the terrain's
// lowest and highest heights, at the levels the multiresolution caster uses at each distance.
#pragma once

#include "ig/camera.hpp"
#include "ig/terrain_db.hpp"

#include <set>
#include <vector>

namespace ig {

// How the caster picks a level by distance (docs/design/multires.md): level 0 out to the
// horizontal distance d0 = focal * spacing (and level 0 is still blended in up to 2 d0); band k
// covers [d0 2^k, d0 2^(k+1)) and blends level k toward k + 1; the coarsest level in use runs
// to infinity. `coarseLevels` 0: level 0 everywhere (the single-level caster); -1: every level.
struct LevelSelection {
    int coarseLevels = -1;
    double d0 = 0;  // metres
    // Level 0 is read out to level0Reach * d0 (2: the first band blends level 0).
    double level0Reach = 2.0;
    static LevelSelection forCamera(const Intrinsics& intrinsics, const TerrainDbInfo& info,
                                    int coarseLevels);
    // [near, far) horizontal distances over which display level k is read, given the levels
    // the database has.
    void band(int level, int displayLevels, double& near, double& far) const;
};

// The tiles a frame needs: display tiles per level, and the node tiles above them.
struct Footprint {
    std::set<TileKey> tiles;
    std::size_t count(TileKind kind, int level) const;
};

// The footprint of one camera. `margin` metres widens the region (prefetch).
Footprint frameFootprint(const Camera& camera, const TerrainDbLayout& layout,
                         const TerrainDbInfo& info, const LevelSelection& selection,
                         double margin = 0.0);

// What to prefetch: the union of the footprints along the motion over `lookahead` seconds
// (position by `velocity` m/s, heading by `yawRate` rad/s, sampled every `step` s), widened by
// `margin` metres. Holds the frame's own footprint.
Footprint extendedFootprint(const Camera& camera, const TerrainDbLayout& layout,
                            const TerrainDbInfo& info, const LevelSelection& selection,
                            const glm::dvec3& velocity, double yawRate, double lookahead,
                            double step, double margin);

}  // namespace ig
