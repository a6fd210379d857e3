#include "ig/paged_insets.hpp"

#include "ig/camera.hpp"
#include "ig/terrain_db_build.hpp"

#include <algorithm>

namespace ig {

namespace {

void addStats(PagedFrameStats& sum, const PagedFrameStats& s) {
    sum.required += s.required;
    sum.requiredCoarse += s.requiredCoarse;
    sum.copied += s.copied;
    sum.substituted += s.substituted;
    sum.failed += s.failed;
    sum.holes += s.holes;
    sum.released += s.released;
    sum.nodesRequired += s.nodesRequired;
    sum.nodesMissing += s.nodesMissing;
    sum.failures.insert(sum.failures.end(), s.failures.begin(), s.failures.end());
}

Camera shifted(const Camera& camera, const Inset& in) {
    Pose pose = camera.pose();
    pose.position -= glm::dvec3{in.origin, 0.0};
    return Camera(pose, camera.intrinsics());
}

}  // namespace

PagedNestedTerrain::PagedNestedTerrain(const TerrainDb& db, const PagedTerrain::Options& options) {
    const std::size_t n = db.insets().size();
    PagedTerrain::Options own = options;
    if (n > 0) {
        own.cache.budgetBytes = options.cache.budgetBytes / 2;
        own.mapBudgetBytes = options.mapBudgetBytes / 2;
    }
    global_ = std::make_unique<PagedTerrain>(db, own);
    PagedTerrain::Options share = options;
    if (n > 0) {
        share.cache.budgetBytes = options.cache.budgetBytes / 2 / n;
        share.mapBudgetBytes = options.mapBudgetBytes / 2 / n;
    }
    for (std::size_t k = 0; k < n; ++k) {
        insetDbs_.push_back(std::make_unique<TerrainDb>(db.openInset(k)));
        insets_.push_back(std::make_unique<PagedTerrain>(*insetDbs_.back(), share));
        placements_.push_back(insetPlacement(db, k));
    }
    maps_.global = &global_->map();
    std::vector<const TerrainMap*> maps;
    for (std::size_t k = 0; k < n; ++k) {
        maps_.insets.push_back({&placements_[k], &insets_[k]->map()});
        maps.push_back(&insets_[k]->map());
    }
    checkNestedInsets(GlobalGrid::of(global_->map()), placements_, maps);
}

PagedFrameStats PagedNestedTerrain::prepare(const Camera& camera, bool wait,
                                            const glm::dvec3& velocity, double yawRate,
                                            const Camera* otherEye) {
    PagedFrameStats sum = global_->prepare(camera, wait, velocity, yawRate, otherEye);
    for (std::size_t k = 0; k < insets_.size(); ++k) {
        const Camera local = shifted(camera, placements_[k]);
        if (otherEye) {
            const Camera other = shifted(*otherEye, placements_[k]);
            addStats(sum, insets_[k]->prepare(local, wait, velocity, yawRate, &other));
        } else {
            addStats(sum, insets_[k]->prepare(local, wait, velocity, yawRate));
        }
    }
    return sum;
}

void PagedNestedTerrain::placeAround(double x, double y) {
    global_->placeAround(x, y);
    for (std::size_t k = 0; k < insets_.size(); ++k) {
        const Inset& in = placements_[k];
        if (in.covers(x, y)) insets_[k]->placeAround(x - in.origin.x, y - in.origin.y);
    }
}

RenderOptions PagedNestedTerrain::globalOptions(const RenderOptions& options) const {
    RenderOptions g = options;
    g.pyramid = global_->pyramid();
    g.slopes = global_->slopes();
    return g;
}

std::vector<RenderOptions> PagedNestedTerrain::insetOptions(const RenderOptions& options) const {
    std::vector<RenderOptions> parts;
    for (const auto& p : insets_) {
        RenderOptions o = options;
        o.pyramid = p->pyramid();
        o.slopes = p->slopes();
        parts.push_back(std::move(o));
    }
    return parts;
}

std::unique_ptr<Caster> PagedNestedTerrain::makeCaster(CasterKind kind,
                                                       const RenderOptions& options) const {
    return makeNestedCaster(kind, maps_, globalOptions(options), insetOptions(options));
}

PagedNestedGround::PagedNestedGround(const PagedGround& global, const TerrainDb& db,
                                     const PagedGround::Options& options, double nearM)
    : global_(global), nearM_(nearM) {
    for (std::size_t k = 0; k < db.insets().size(); ++k) {
        dbs_.push_back(std::make_unique<TerrainDb>(db.openInset(k)));
        grounds_.push_back(std::make_unique<PagedGround>(*dbs_.back(), options));
        placements_.push_back(insetPlacement(db, k));
    }
}

double PagedNestedGround::groundHeight(double x, double y) const {
    for (std::size_t k = 0; k < placements_.size(); ++k) {
        const Inset& in = placements_[k];
        if (in.covers(x, y)) return grounds_[k]->groundHeight(x - in.origin.x, y - in.origin.y);
    }
    return global_.groundHeight(x, y);
}

void PagedNestedGround::follow(double x, double y) const {
    global_.follow(x, y);
    for (std::size_t k = 0; k < placements_.size(); ++k) {
        const Inset& in = placements_[k];
        const double dx = std::max({in.coverMin.x - x, 0.0, x - in.coverMax.x});
        const double dy = std::max({in.coverMin.y - y, 0.0, y - in.coverMax.y});
        if (dx * dx + dy * dy <= nearM_ * nearM_) {
            grounds_[k]->follow(x - in.origin.x, y - in.origin.y);
        }
    }
}

void PagedNestedGround::waitAround(double x, double y) {
    for (std::size_t k = 0; k < placements_.size(); ++k) {
        const Inset& in = placements_[k];
        if (in.covers(x, y)) grounds_[k]->waitAround(x - in.origin.x, y - in.origin.y);
    }
}

}  // namespace ig
