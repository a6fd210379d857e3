// Scene files: the voxel models of a world, their placements and scattered copies (JSON),
// resolved over a terrain map into an object layer. docs/formats.md describes the format.
#pragma once

#include "ig/sticks.hpp"
#include "ig/terrain.hpp"

#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace ig {

// An object that moves along a trajectory: kept apart from the static layer and stamped at each
// frame's instant. The trajectory file is named here, resolved by the caller (sim owns the
// trajectory format).
struct MovingObject {
    std::uint16_t id = 0;
    int model = 0;           // index into Scene::models
    std::string trajectory;  // path, resolved against the scene file's folder
    double scale = 1.0;
    std::optional<double> z;  // base height; unset: on the ground under it
    std::string entry;        // "objects[3]", for messages
};

class Scene {
  public:
    std::string path;
    // Stable addresses (the layers' column caches key on them).
    std::vector<std::unique_ptr<ObjectModel>> models;
    std::vector<std::string> modelNames;
    std::unique_ptr<ObjectLayer> staticLayer;
    std::vector<MovingObject> moving;
    double cellSize = 0.0;  // requested object cell size, metres

    int modelIndex(std::string_view name) const;  // -1 when none
    // A layer on the static layer's grid holding the moving objects at the given base positions
    // and headings (one per entry of `moving`, in order; CHECKed), each on the ground unless its
    // z is set: `ground`'s, or the static layer's map's (null).
    ObjectLayer stampMoving(std::span<const Placement> where, const Ground* ground = nullptr) const;
};

// Loads a scene over `map`. Every problem is an InputError naming the file and the entry
// (models.tank.sculpt.side, objects[2].scale, scatter[0].area): bad JSON, an unknown model or
// key, a NaN or negative scale, a placement off the map, an id reused or out of 1..65535, a
// model file that does not load.
// The object cells all placements together may sweep (their footprints' bounding boxes) before
// a scene is refused as too costly to resample: a 256-voxel model at 1000 m per voxel over
// 4 cm cells would otherwise run for hours.
inline constexpr double kMaxSceneCellVisits = 1 << 28;
// `shareSticks` false stores every cell's stick list anew (for measuring what sharing saves).
// `ground`, when given, is where placements stand and whose slopes a scatter rule reads (a map
// paged from a database: a ground that reads the tiles it is asked about); `map` gives the
// grid in any case.
Scene loadScene(const std::string& path, const TerrainMap& map, bool shareSticks = true,
                const Ground* ground = nullptr);
Scene parseScene(std::string_view text, const std::string& path, const TerrainMap& map,
                 bool shareSticks = true, double maxCellVisits = kMaxSceneCellVisits,
                 const Ground* ground = nullptr);

}  // namespace ig
