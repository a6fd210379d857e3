// A database's high-resolution insets paged with its global map (docs/design/insets.md,
// "Insets in a database"): each inset's map is a database of its own in the file, read
// through a tile cache of its own and drawn by the nested caster, as over the maps in memory.
#pragma once

#include "ig/caster.hpp"
#include "ig/inset.hpp"
#include "ig/paged_ground.hpp"
#include "ig/paged_terrain.hpp"
#include "ig/terrain_db.hpp"

#include <glm/vec3.hpp>

#include <memory>
#include <vector>

namespace ig {

class PagedNestedTerrain {
  public:
    // `db` must outlive this. With insets, the global map's cache takes half of
    // options.cache.budgetBytes and the insets share the other half equally (InputError when
    // a share cannot hold its map's resident coarse levels).
    PagedNestedTerrain(const TerrainDb& db, const PagedTerrain::Options& options);
    PagedNestedTerrain(const PagedNestedTerrain&) = delete;
    PagedNestedTerrain& operator=(const PagedNestedTerrain&) = delete;

    PagedTerrain& global() { return *global_; }
    const PagedTerrain& global() const { return *global_; }
    std::size_t insetCount() const { return insets_.size(); }
    PagedTerrain& inset(std::size_t k) { return *insets_[k]; }
    // Where inset k lies (its map is inset(k).map()).
    const Inset& placement(std::size_t k) const { return placements_[k]; }
    // The maps the casters read.
    const NestedMaps& maps() const { return maps_; }

    // As PagedTerrain::prepare, for the global map and every inset (each with the camera in
    // its own coordinates); the stats summed over all of them.
    PagedFrameStats prepare(const Camera& camera, bool wait, const glm::dvec3& velocity = {},
                            double yawRate = 0.0, const Camera* otherEye = nullptr);
    // As PagedTerrain::placeAround: the global tile under (x, y), and the inset's where one
    // covers it.
    void placeAround(double x, double y);
    // The nested caster over the paged maps (each with its own pyramid and slope bounds);
    // `options` as for the global map alone.
    std::unique_ptr<Caster> makeCaster(CasterKind kind, const RenderOptions& options) const;
    // The options it gives the global map's caster and each inset's: `options` with the map's
    // own pyramid and slope bounds.
    RenderOptions globalOptions(const RenderOptions& options) const;
    std::vector<RenderOptions> insetOptions(const RenderOptions& options) const;

  private:
    std::vector<std::unique_ptr<TerrainDb>> insetDbs_;
    std::unique_ptr<PagedTerrain> global_;
    std::vector<std::unique_ptr<PagedTerrain>> insets_;
    std::vector<Inset> placements_;
    NestedMaps maps_;
};

// PlacingGround over a paged database with insets: each height read first places, waiting,
// the tiles under its point (the global map's, and the inset's where one lies), so it is the
// nested surface there (a scene's placements, before a run). One thread at a time.
class PlacingNestedGround final : public Ground {
  public:
    explicit PlacingNestedGround(PagedNestedTerrain& paged) : paged_(paged) {}
    double groundHeight(double x, double y) const override {
        paged_.placeAround(x, y);
        return paged_.maps().surfaceHeight(x, y);
    }
    double extentX() const override { return paged_.global().map().extentX(); }
    double extentY() const override { return paged_.global().map().extentY(); }

  private:
    PagedNestedTerrain& paged_;
};

// A flight model's ground over a paged database with insets: `global` (the database's own
// PagedGround) outside them, a PagedGround of each inset's database over it (its surface, on
// which the nested caster draws). An inset's ground follows the points asked for within
// `nearM` of its square only. `global` and `db` must outlive this.
class PagedNestedGround final : public Ground {
  public:
    PagedNestedGround(const PagedGround& global, const TerrainDb& db,
                      const PagedGround::Options& options, double nearM = 1000.0);
    double groundHeight(double x, double y) const override;
    double extentX() const override { return global_.extentX(); }
    double extentY() const override { return global_.extentY(); }
    void follow(double x, double y) const override;
    // Loads, waiting, the tiles around (x, y): the global map's and, over an inset, its own.
    void waitAround(double x, double y);

  private:
    const PagedGround& global_;
    std::vector<std::unique_ptr<TerrainDb>> dbs_;
    std::vector<std::unique_ptr<PagedGround>> grounds_;
    std::vector<Inset> placements_;
    double nearM_;
};

}  // namespace ig
