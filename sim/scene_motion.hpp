// The moving objects of a scene: their trajectories loaded, and the objects stamped at any
// instant into a layer apart from the static world.
#pragma once

#include "ig/scene.hpp"
#include "sim/trajectory.hpp"

#include <span>
#include <vector>

namespace sim {

// An object placed by someone other than the scene's trajectories (a CIGI host): a model of the
// scene at a placement whose id, scale and base height are its own (or on the ground under it).
struct ExtraObject {
    int model = 0;  // index into ig::Scene::models
    ig::Placement placement;
    bool onGround = false;
};

class SceneMotion {
  public:
    // Loads the trajectory of each moving object of `scene` (which must outlive this); throws
    // ig::InputError naming the scene file, the entry and the trajectory's own problem.
    explicit SceneMotion(const ig::Scene& scene);

    bool empty() const { return trajectories_.empty(); }
    // Earliest start of the trajectories (0 when there are none).
    double startTime() const;
    // Base centre and heading of every moving object at time t (each clamped to its
    // trajectory's range), in the scene's order.
    std::vector<ig::Placement> placementsAt(double t) const;
    // The same into `out` (cleared first; it allocates only when it grows).
    void placementsAt(double t, std::vector<ig::Placement>& out) const;
    // The moving objects at time t, on the static layer's object grid, standing on `ground`
    // (null: the static layer's map); an object whose trajectory takes it off the map is left
    // out.
    ig::ObjectLayer stamp(double t, const ig::Ground* ground = nullptr) const;
    // The same with `extra` objects beside them; one whose base is off the map is left out.
    ig::ObjectLayer stamp(double t, std::span<const ExtraObject> extra,
                          const ig::Ground* ground = nullptr) const;

  private:
    const ig::Scene* scene_;
    std::vector<Trajectory> trajectories_;
};

}  // namespace sim
