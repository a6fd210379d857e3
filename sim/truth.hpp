// Exact per-field ground truth of a populated world: which objects each output field shows,
// where, how far, and how much of each is hidden (docs/design/objects.md, "Ground truth").
#pragma once

#include "ig/camera.hpp"
#include "ig/scene.hpp"
#include "prp/field.hpp"
#include "prp/object_restamp.hpp"
#include "sim/scene_motion.hpp"

#include <tbb/task_arena.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <vector>

namespace sim {

// One object as placed in the world: its model at its exact base centre, heading and scale
// (moving ones at their trajectory's position at the instant asked for).
struct TruthObject {
    std::uint16_t id = 0;
    const ig::ObjectModel* model = nullptr;
    double x = 0.0, y = 0.0, z = 0.0;  // base centre, metres
    double heading = 0.0, scale = 1.0;
    bool moving = false;
    // Voxels the model fills, [lo, hi) along its x, y, z (the box projected for true_bbox).
    int lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    // The model's voxels as one byte each, 1 where present with non-zero opacity (indexed as
    // VoxModel::index; owned by the TruthScene); null: ask the model (rayMeetsObject does).
    const std::uint8_t* solid = nullptr;
};

// The world's objects for the truth: the scene's static placements, and its moving objects
// placed at any instant, standing on `ground` (the scene, the motion and the ground must outlive
// this).
class TruthScene {
  public:
    TruthScene(const ig::Scene& scene, const SceneMotion& motion, const ig::Ground& ground);
    // Every object at time t (static first, in placement order), into `out` (reused).
    void objectsAt(double t, std::vector<TruthObject>& out) const;
    // The same in two parts: the static objects (never copied), and the moving ones at t.
    std::span<const TruthObject> staticObjects() const { return static_; }
    void movingAt(double t, std::vector<TruthObject>& out) const;
    // The same with the placements' scratch given: allocates only while `out` and `where` grow.
    void movingAt(double t, std::vector<TruthObject>& out, std::vector<ig::Placement>& where) const;
    // Model `model` of the scene placed as an object (a host's entity drawn as that model).
    TruthObject placedModel(int model, std::uint16_t id, double x, double y, double z,
                            double heading, double scale) const;
    // An object placed by a host as the renderer stands it (on the ground under its base when
    // it is ground-clamped and on the map).
    TruthObject placedExtra(const ExtraObject& e) const;
    const ig::Scene& scene() const { return *scene_; }
    const ig::Ground& ground() const { return *ground_; }

  private:
    TruthObject placed(const ig::ObjectModel& model, std::uint16_t id, double x, double y, double z,
                       double heading, double scale, bool moving) const;
    const ig::Scene* scene_;
    const SceneMotion* motion_;
    const ig::Ground* ground_;
    std::vector<TruthObject> static_;
    std::vector<TruthObject> models_;  // per model of the scene: its filled voxels' box
    std::vector<std::vector<std::uint8_t>> solid_;  // per model: TruthObject::solid
};

// The moving objects' own motion between a rendered frame's instant and a field's: the middle
// of each one's box at both (prp::ObjectMotion, for the processor's re-stamp). Objects on the
// map at only one of the two instants are left out. `extraAtFrame`, `extraAtField`: objects
// placed by someone else at the two instants (a host's entities), matched by id. Scratch
// reused: nothing allocated once it has grown.
class ObjectMotionBetween {
  public:
    explicit ObjectMotionBetween(const TruthScene& scene) : scene_(&scene) {}
    std::span<const prp::ObjectMotion> between(double frameTime, double fieldTime,
                                               std::span<const ExtraObject> extraAtFrame = {},
                                               std::span<const ExtraObject> extraAtField = {});

  private:
    const TruthScene* scene_;
    std::vector<TruthObject> atFrame_, atField_;
    std::vector<ig::Placement> where_;
    std::vector<prp::ObjectMotion> motions_;
};

// The field's camera: the output window at the field's pose (roll included), `outWidth` x
// `outHeight` output pixels over the window's `window.width` x `window.height`.
struct TruthCamera {
    ig::Intrinsics window;
    int outWidth = 0, outHeight = 0;
};

// 3-D box corners of `o` (its filled voxels), world coordinates.
std::array<glm::dvec3, 8> objectCorners(const TruthObject& o);
// Whether the ray origin + t dir (t > 0) meets a voxel of `o`'s model of non-zero opacity.
bool rayMeetsObject(const TruthObject& o, const glm::dvec3& origin, const glm::dvec3& dir);
// Where the ray origin + t dir (dir of unit length) enters the first voxel of `o`'s model of
// non-zero opacity that it enters at t >= tMin (the same walk as rayMeetsObject), and that
// voxel's colour into `color` and the world normal of the face it enters by into `normal` when
// given; negative when there is none.
double rayEntersObject(const TruthObject& o, const glm::dvec3& origin, const glm::dvec3& dir,
                       double tMin, ig::Rgba8* color = nullptr, glm::dvec3* normal = nullptr);
// The same answer from the walk TruthComputer uses (o.solid's table; the model when null).
bool rayMeetsObjectFast(const TruthObject& o, const glm::dvec3& origin, const glm::dvec3& dir);

// One object's truth in one field. Pixel coordinates are output-frame pixels: x right, y the
// frame line (a field holds every other line); boxes are pixel edges [x0, y0, x1, y1].
struct ObjectTruth {
    std::uint16_t id = 0;
    bool moving = false;
    std::uint64_t visiblePx = 0;       // field pixels whose warped id is this object
    double bbox[4] = {0, 0, 0, 0};     // of those pixels (each pixel [x, x + 1] x [y, y + 1])
    double centroid[2] = {0, 0};       // mean of their centres
    double rangeM = 0.0;               // eye to the centre of the object's box, at the field's pose
    bool hasTrueBox = false;           // false when part of the box is behind the eye
    double trueBox[4] = {0, 0, 0, 0};  // the 3-D box projected, unclipped
    // Field pixels whose centre ray meets the object's model alone (no terrain, no other object).
    std::uint64_t unoccludedPx = 0;
    // 1 - visible / unoccluded, clamped to [0, 1]; negative: undefined (unoccluded 0).
    double occluded = -1.0;
};

struct FieldTruth {
    std::uint64_t field = 0;
    double time = 0.0;
    // Late: the writer was behind the field clock, so only what the field shows was worked out
    // (visible pixels, boxes, centroids, ranges, true boxes of the objects it shows): no exact
    // unoccluded count, and objects the field does not show are not listed.
    bool late = false;
    std::vector<ObjectTruth> objects;  // by increasing id
};

// Computes one field's truth from its warped ids and its pose (scratch reused: allocates only
// while its tables grow).
class TruthComputer {
  public:
    // `workers`: threads the per-object work is spread over (1: the calling thread alone; 0:
    // TBB's default). The result is the same whatever the count. `reference`: the slow, obvious
    // twin of the same lines, for tests (every object at its own copy, no frustum culling, a
    // ray per pixel of the projected box's rectangle, each through rayMeetsObject).
    explicit TruthComputer(int workers = 0, bool reference = false);
    ~TruthComputer();
    TruthComputer(const TruthComputer&) = delete;
    TruthComputer& operator=(const TruthComputer&) = delete;
    // `ids`: the field's lines (width * lines), line L being frame line firstLine + 2 L.
    // `late`: the shown objects only, without the unoccluded count (FieldTruth::late).
    // `extra`: objects placed at this instant besides the scene's (a host's entities).
    void compute(const TruthScene& scene, const TruthCamera& camera, const std::uint16_t* ids,
                 int width, int lines, int firstLine, const ig::Pose& pose, double time,
                 std::uint64_t index, FieldTruth& out, bool late = false,
                 std::span<const TruthObject> extra = {});

  private:
    struct Acc {
        std::uint64_t n = 0;
        int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
        double sx = 0.0, sy = 0.0;
    };
    std::vector<Acc> acc_;                // by id
    std::vector<std::int32_t> objectOf_;  // id -> index into objects_, -1
    std::vector<std::uint16_t> seen_;
    std::vector<TruthObject> objects_;  // reference: every object; else the moving ones
    bool reference_ = false;
    std::vector<ObjectTruth> results_;        // per object of objects_
    std::vector<std::uint8_t> listed_;        // per object: its results_ entry is listed
    std::unique_ptr<tbb::task_arena> arena_;  // null: one worker
};

// One JSON line (no newline): {"field", "time", "objects": [{"id", "visible_px", "bbox",
// "centroid", "range_m", "occluded", "true_bbox", "unoccluded_px", "moving"}]}; a late field
// adds "late": true (its objects' "occluded" and "unoccluded_px" null).
std::string truthLine(const FieldTruth& truth);
// The line of a field whose ids could not be queued: {"field", "time", "lost": true,
// "objects": null}.
std::string lostTruthLine(std::uint64_t field, double time);

// Writes exactly one truth line per field, in field order, from a thread of its own. record()
// copies the field's ids and pose into a slot allocated up front (the field thread never
// allocates or writes a file). On the wall clock (`waitWhenFull` false) the writer keeps up by
// the rule of docs/design/objects.md ("When the truth falls behind"): a field it reaches with
// more than `lateAfter` fields queued behind it is written late (FieldTruth::late); a field
// that finds every slot taken is written as lost (lostTruthLine). Both are counted (late(),
// lost()), and neither is an error. The simulated clock (`waitWhenFull`) waits for a slot and
// never writes late: its stream is deterministic.
class TruthWriter {
  public:
    TruthWriter(const TruthScene& scene, const TruthCamera& camera, std::FILE* out, int width,
                int maxLines, bool waitWhenFull, int slots = 32, int lateAfter = 4);
    ~TruthWriter();
    TruthWriter(const TruthWriter&) = delete;
    TruthWriter& operator=(const TruthWriter&) = delete;

    // `focal`: the field's own focal length in window pixels (a host's field of view during
    // the run, sim::fieldFocal); 0: the camera's. `extra`: objects at the field's instant besides
    // the scene's (a host's entities; the first kMaxExtraObjects, the rest counted).
    void record(const prp::Field& field, const ig::Pose& pose, double focal = 0.0,
                std::span<const ExtraObject> extra = {});
    static constexpr std::size_t kMaxExtraObjects = 256;
    // Extra objects left out of a field's truth (beyond kMaxExtraObjects).
    std::uint64_t extraCut() const { return extraCut_.load(std::memory_order_acquire); }
    // Writes what was recorded and stops the thread; empty, or what went wrong (a write error,
    // a field without object ids, more lost fields queued at once than the writer holds).
    std::string finish();
    // Lines written (every kind), fields written late, fields written as lost.
    std::uint64_t written() const { return written_.load(std::memory_order_acquire); }
    std::uint64_t late() const { return late_.load(std::memory_order_acquire); }
    std::uint64_t lost() const { return lost_.load(std::memory_order_acquire); }

  private:
    struct Slot {
        std::vector<std::uint16_t> ids;
        int width = 0, lines = 0, firstLine = 0;
        bool hasIds = false;
        ig::Pose pose;
        double focal = 0.0;
        double time = 0.0;
        std::uint64_t index = 0;
        std::vector<ExtraObject> extra;  // capacity kMaxExtraObjects, reserved up front
    };
    // A field whose ids found no slot: written as lost, in its place among the others.
    struct Lost {
        std::uint64_t index = 0;
        double time = 0.0;
    };
    void loop();
    bool writeLine(const std::string& line);

    const TruthScene& scene_;
    TruthCamera camera_;
    std::FILE* out_;
    bool waitWhenFull_;
    std::uint64_t lateAfter_;
    std::vector<Slot> slots_;
    std::vector<Lost> lostQueue_;  // allocated up front, a ring like slots_
    std::atomic<std::uint64_t> head_{0}, tail_{0}, lostHead_{0}, lostTail_{0};
    std::atomic<bool> stop_{false};
    std::atomic<std::uint64_t> written_{0}, late_{0}, lost_{0}, dropped_{0}, missingIds_{0};
    std::atomic<std::uint64_t> extraCut_{0};
    std::string error_;  // writer thread, read after join
    std::thread thread_;
};

}  // namespace sim
