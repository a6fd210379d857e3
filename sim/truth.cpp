#include "sim/truth.hpp"

#include "base/check.hpp"
#include "base/fork_gate.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

namespace sim {

// Why it is built this way (docs/design/objects.md, "Ground truth"):
// - visible pixels, boxes and centroids come from the field's own warped ids: what the field
//   shows, exactly;
// - range, true_bbox and the unoccluded count come from the object's model placed exactly
//   (position, heading, scale; a moving one at its trajectory's position at the field's
//   instant) seen from the field's pose: the truth the field approximates;
// - the unoccluded count casts one ray per field pixel inside the projected box against that
//   one model: exact, and it costs only the pixels an object may cover.

namespace {

constexpr int kIds = 65536;
// Rays an object's unoccluded count casts before it samples its box instead of every pixel.
constexpr double kExactRays = 4096.0;
// How far (output pixels) a line's span of rays reaches beyond the box's projection: far more
// than the rounding of a projection (~1e-10 px), far less than a pixel.
constexpr double kSpanMarginPx = 1e-3;

// The convex hull of the eight projected corners of a box (Andrew's monotone chain): its
// vertices in order, `n` of them (a box wholly in front of the eye projects to this hull).
struct Hull {
    glm::dvec2 v[16];
    int n = 0;
};

Hull convexHull(const glm::dvec2 (&c)[8]) {
    glm::dvec2 s[8];
    std::copy(std::begin(c), std::end(c), s);
    std::sort(std::begin(s), std::end(s), [](const glm::dvec2& a, const glm::dvec2& b) {
        return a.x < b.x || (a.x == b.x && a.y < b.y);
    });
    const auto cross = [](const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
        return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    };
    Hull h;
    for (int i = 0; i < 8; ++i) {  // lower chain
        while (h.n >= 2 && cross(h.v[h.n - 2], h.v[h.n - 1], s[i]) <= 0.0)
            --h.n;
        h.v[h.n++] = s[i];
    }
    for (int i = 6, low = h.n + 1; i >= 0; --i) {  // upper chain
        while (h.n >= low && cross(h.v[h.n - 2], h.v[h.n - 1], s[i]) <= 0.0)
            --h.n;
        h.v[h.n++] = s[i];
    }
    --h.n;  // the first point closes the chain
    return h;
}

// Where the hull meets the band of lines within kSpanMarginPx of y: [s0, s1] widened to hold it
// (left empty, s0 > s1, when the band misses the hull). The band's extent is reached at a
// vertex inside it or where an edge crosses one of its two lines.
void hullSpan(const Hull& h, double y, double& s0, double& s1) {
    const double edges[2] = {y - kSpanMarginPx, y + kSpanMarginPx};
    for (int i = 0; i < h.n; ++i) {
        const glm::dvec2& a = h.v[i];
        const glm::dvec2& b = h.v[i + 1 < h.n ? i + 1 : 0];
        if (a.y >= edges[0] && a.y <= edges[1]) {
            s0 = std::min(s0, a.x);
            s1 = std::max(s1, a.x);
        }
        for (const double e : edges) {
            if ((a.y - e) * (b.y - e) > 0.0 || a.y == b.y) continue;
            const double x = a.x + (e - a.y) / (b.y - a.y) * (b.x - a.x);
            s0 = std::min(s0, x);
            s1 = std::max(s1, x);
        }
    }
}

double round2(double v) {
    return std::round(v * 100.0) / 100.0;
}

TruthObject filledBox(const ig::ObjectModel& model);

}  // namespace

TruthScene::TruthScene(const ig::Scene& scene, const SceneMotion& motion, const ig::Ground& ground)
    : scene_(&scene), motion_(&motion), ground_(&ground) {
    for (const auto& model : scene.models) {
        models_.push_back(filledBox(*model));
        const ig::VoxModel& g = model->grid;
        std::vector<std::uint8_t> solid(g.voxels.size(), 0);
        for (int k = 0; k < g.sizeZ; ++k) {
            for (int j = 0; j < g.sizeY; ++j) {
                for (int i = 0; i < g.sizeX; ++i) {
                    solid[g.index(i, j, k)] =
                        model->present(i, j, k) && model->color(i, j, k).a != 0;
                }
            }
        }
        solid_.push_back(std::move(solid));
        models_.back().solid = solid_.back().data();
    }
    for (const ig::PlacedObject& p : scene.staticLayer->objects()) {
        const int m = scene.modelIndex(p.model);
        CHECK_GE(m, 0) << "placed model " << p.model;
        static_.push_back(placed(*scene.models[static_cast<std::size_t>(m)], p.id, p.x, p.y, p.z,
                                 p.heading, p.scale, false));
    }
}

namespace {

// The model's filled voxels (non-zero opacity): their box, [lo, hi) per axis.
TruthObject filledBox(const ig::ObjectModel& model) {
    TruthObject o;
    o.model = &model;
    const ig::VoxModel& g = model.grid;
    int lo[3] = {g.sizeX, g.sizeY, g.sizeZ}, hi[3] = {0, 0, 0};
    for (int k = 0; k < g.sizeZ; ++k) {
        for (int j = 0; j < g.sizeY; ++j) {
            for (int i = 0; i < g.sizeX; ++i) {
                if (!model.present(i, j, k) || model.color(i, j, k).a == 0) continue;
                const int v[3] = {i, j, k};
                for (int a = 0; a < 3; ++a) {
                    lo[a] = std::min(lo[a], v[a]);
                    hi[a] = std::max(hi[a], v[a] + 1);
                }
            }
        }
    }
    for (int a = 0; a < 3; ++a) {
        o.lo[a] = std::min(lo[a], hi[a]);
        o.hi[a] = hi[a];
    }
    return o;
}

}  // namespace

TruthObject TruthScene::placed(const ig::ObjectModel& model, std::uint16_t id, double x, double y,
                               double z, double heading, double scale, bool moving) const {
    TruthObject o;
    for (std::size_t m = 0; m < scene_->models.size(); ++m) {
        if (scene_->models[m].get() == &model) o = models_[m];
    }
    CHECK(o.model == &model);
    o.id = id;
    o.x = x;
    o.y = y;
    o.z = z;
    o.heading = heading;
    o.scale = scale;
    o.moving = moving;
    return o;
}

void TruthScene::objectsAt(double t, std::vector<TruthObject>& out) const {
    std::vector<TruthObject> moving;
    movingAt(t, moving);
    out.assign(static_.begin(), static_.end());
    out.insert(out.end(), moving.begin(), moving.end());
}

TruthObject TruthScene::placedModel(int model, std::uint16_t id, double x, double y, double z,
                                    double heading, double scale) const {
    CHECK(model >= 0 && static_cast<std::size_t>(model) < scene_->models.size());
    return placed(*scene_->models[static_cast<std::size_t>(model)], id, x, y, z, heading, scale,
                  true);
}

TruthObject TruthScene::placedExtra(const ExtraObject& e) const {
    const ig::Placement& p = e.placement;
    double z = p.z;
    if (e.onGround && ground_->covers(p.x, p.y)) z = ground_->groundHeight(p.x, p.y);
    return placedModel(e.model, p.id, p.x, p.y, z, p.heading, p.scale);
}

void TruthScene::movingAt(double t, std::vector<TruthObject>& out) const {
    std::vector<ig::Placement> where;
    movingAt(t, out, where);
}

void TruthScene::movingAt(double t, std::vector<TruthObject>& out,
                          std::vector<ig::Placement>& where) const {
    out.clear();
    motion_->placementsAt(t, where);
    for (std::size_t i = 0; i < where.size(); ++i) {
        const ig::MovingObject& m = scene_->moving[i];
        const ig::Placement& p = where[i];
        // Off the map: not drawn (SceneMotion::stamp leaves it out), so not in the truth.
        if (!ground_->covers(p.x, p.y)) continue;
        const double z = m.z ? *m.z : ground_->groundHeight(p.x, p.y);
        out.push_back(placed(*scene_->models[static_cast<std::size_t>(m.model)], m.id, p.x, p.y, z,
                             p.heading, m.scale, true));
    }
}

namespace {

glm::dvec3 boxMiddle(const TruthObject& o) {
    glm::dvec3 middle{0.0};
    for (const glm::dvec3& q : objectCorners(o))
        middle += q * 0.125;
    return middle;
}

}  // namespace

std::span<const prp::ObjectMotion> ObjectMotionBetween::between(
    double frameTime, double fieldTime, std::span<const ExtraObject> extraAtFrame,
    std::span<const ExtraObject> extraAtField) {
    scene_->movingAt(frameTime, atFrame_, where_);
    scene_->movingAt(fieldTime, atField_, where_);
    motions_.clear();
    // Both lists are in the scene's order, less the objects off the map.
    std::size_t j = 0;
    for (const TruthObject& a : atFrame_) {
        std::size_t k = j;
        while (k < atField_.size() && atField_[k].id != a.id)
            ++k;
        if (k == atField_.size()) continue;  // off the map at the field's instant
        motions_.push_back({a.id, boxMiddle(a), boxMiddle(atField_[k])});
        j = k + 1;
    }
    // The others by id (a host's entities: a few, in the host's order of creation).
    for (const ExtraObject& a : extraAtFrame) {
        for (const ExtraObject& b : extraAtField) {
            if (b.placement.id != a.placement.id || b.model != a.model) continue;
            motions_.push_back({a.placement.id, boxMiddle(scene_->placedExtra(a)),
                                boxMiddle(scene_->placedExtra(b))});
            break;
        }
    }
    return motions_;
}

std::array<glm::dvec3, 8> objectCorners(const TruthObject& o) {
    // Model (mx, my) -> world: the inverse of ObjectLayer::place's rotation.
    const double s = std::sin(o.heading), c = std::cos(o.heading);
    const ig::VoxModel& g = o.model->grid;
    std::array<glm::dvec3, 8> out;
    for (int k = 0; k < 8; ++k) {
        const double u = ((k & 1) ? o.hi[0] : o.lo[0]) - 0.5 * g.sizeX;
        const double v = ((k & 2) ? o.hi[1] : o.lo[1]) - 0.5 * g.sizeY;
        const double h = (k & 4) ? o.hi[2] : o.lo[2];
        out[static_cast<std::size_t>(k)] = {o.x + o.scale * (u * c + v * s),
                                            o.y + o.scale * (-u * s + v * c), o.z + o.scale * h};
    }
    return out;
}

namespace {

// The world -> model voxel map of one placed object (ObjectLayer::place's, z from the base):
// worked out once per object and field, then applied to every ray.
struct ModelFrame {
    double s, c, inv, hx, hy;
    explicit ModelFrame(const TruthObject& o)
        : s(std::sin(o.heading)),
          c(std::cos(o.heading)),
          inv(1.0 / o.scale),
          hx(0.5 * o.model->grid.sizeX),
          hy(0.5 * o.model->grid.sizeY) {}
    void point(const TruthObject& o, const glm::dvec3& q, double p[3]) const {
        const double dx = q.x - o.x, dy = q.y - o.y;
        p[0] = (dx * c - dy * s) * inv + hx;
        p[1] = (dx * s + dy * c) * inv + hy;
        p[2] = (q.z - o.z) * inv;
    }
    void direction(const glm::dvec3& dir, double d[3]) const {
        d[0] = (dir.x * c - dir.y * s) * inv;
        d[1] = (dir.x * s + dir.y * c) * inv;
        d[2] = dir.z * inv;
    }
};

double firstSolidEntry(const TruthObject& o, const double p[3], const double d[3], double tMin,
                       ig::Rgba8* color);
bool rayMeetsModel(const TruthObject& o, const double p[3], const double d[3]) {
    return firstSolidEntry(o, p, d, -std::numeric_limits<double>::infinity(), nullptr) >= 0.0;
}
bool rayMeetsSolid(const TruthObject& o, const double p[3], const double d[3]);

}  // namespace

bool rayMeetsObject(const TruthObject& o, const glm::dvec3& origin, const glm::dvec3& dir) {
    const ModelFrame f(o);
    double p[3], d[3];
    f.point(o, origin, p);
    f.direction(dir, d);
    return rayMeetsModel(o, p, d);
}

double rayEntersObject(const TruthObject& o, const glm::dvec3& origin, const glm::dvec3& dir,
                       double tMin, ig::Rgba8* color, glm::dvec3* normal) {
    // The model's frame is the world's turned and scaled: a point t along the ray in the world
    // is the point t along the ray in the model's voxels.
    const ModelFrame f(o);
    double p[3], d[3];
    f.point(o, origin, p);
    f.direction(dir, d);
    const double t = firstSolidEntry(o, p, d, tMin, color);
    if (t >= 0.0 && normal) {
        // The face entered: the axis along which the entry point lies on a voxel boundary (of
        // those the ray moves along), facing back along the ray.
        int face = 2;
        double best = std::numeric_limits<double>::infinity();
        for (int a = 0; a < 3; ++a) {
            if (d[a] == 0.0) continue;
            const double q = p[a] + t * d[a];
            const double off = std::abs(q - std::round(q));
            if (off < best) {
                best = off;
                face = a;
            }
        }
        double n[3] = {0.0, 0.0, 0.0};
        n[face] = d[face] > 0.0 ? -1.0 : 1.0;
        // Model axes to world: the inverse of ModelFrame's turn.
        *normal = {f.c * n[0] + f.s * n[1], -f.s * n[0] + f.c * n[1], n[2]};
    }
    return t;
}

bool rayMeetsObjectFast(const TruthObject& o, const glm::dvec3& origin, const glm::dvec3& dir) {
    const ModelFrame f(o);
    double p[3], d[3];
    f.point(o, origin, p);
    f.direction(dir, d);
    return o.solid ? rayMeetsSolid(o, p, d) : rayMeetsModel(o, p, d);
}

namespace {

// The ray's entry into o's filled box and the walk's start (Amanatides-Woo): the voxel, the
// step per axis and the ray parameters of the next voxel face and between faces. False when
// the ray misses the box. Shared by both walks below, so they start alike.
struct Walk {
    double t0, t1;
    int v[3], step[3];
    double next[3], delta[3];
};

bool startWalk(const TruthObject& o, const double p[3], const double d[3], Walk& w) {
    // The filled box's slab interval.
    double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0) {
            if (p[a] < o.lo[a] || p[a] >= o.hi[a]) return false;
            continue;
        }
        double ta = (o.lo[a] - p[a]) / d[a], tb = (o.hi[a] - p[a]) / d[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    if (!(t0 < t1)) return false;
    // Amanatides-Woo through the voxels from the entry point.
    const double tm = t0 + 1e-9 * std::max(1.0, t0);
    w.t0 = t0;
    w.t1 = t1;
    int* v = w.v;
    int* step = w.step;
    double* next = w.next;
    double* delta = w.delta;
    for (int a = 0; a < 3; ++a) {
        const double q = p[a] + tm * d[a];
        v[a] = std::clamp(static_cast<int>(std::floor(q)), o.lo[a], o.hi[a] - 1);
        if (d[a] > 0.0) {
            step[a] = 1;
            next[a] = (v[a] + 1 - p[a]) / d[a];
            delta[a] = 1.0 / d[a];
        } else if (d[a] < 0.0) {
            step[a] = -1;
            next[a] = (v[a] - p[a]) / d[a];
            delta[a] = -1.0 / d[a];
        } else {
            step[a] = 0;
            next[a] = std::numeric_limits<double>::infinity();
            delta[a] = next[a];
        }
    }
    return true;
}

// The first voxel of o's model of non-zero opacity that the ray p + t d (t > 0, model voxels)
// enters at t >= tMin: where it enters it, or -1; the obvious walk, asking the model at every
// voxel (rayMeetsModel: whether there is one at all).
double firstSolidEntry(const TruthObject& o, const double p[3], const double d[3], double tMin,
                       ig::Rgba8* color) {
    Walk w;
    if (!startWalk(o, p, d, w)) return -1.0;
    int* v = w.v;
    const int* step = w.step;
    double* next = w.next;
    const double* delta = w.delta;
    const double t1 = w.t1;
    double enter = w.t0;
    for (;;) {
        if (enter >= tMin && o.model->present(v[0], v[1], v[2]) &&
            o.model->color(v[0], v[1], v[2]).a != 0) {
            if (color) *color = o.model->color(v[0], v[1], v[2]);
            return enter;
        }
        const int a = next[0] < next[1] ? (next[0] < next[2] ? 0 : 2) : (next[1] < next[2] ? 1 : 2);
        if (next[a] > t1) return -1.0;
        v[a] += step[a];
        if (v[a] < o.lo[a] || v[a] >= o.hi[a]) return -1.0;
        enter = next[a];
        next[a] += delta[a];
    }
}

// The same walk, step for step (the same voxels in the same order from the same arithmetic), made
// cheap: the scene's table of solid voxels (one byte each) at an index moved with the walk, the
// axis picked without branches, and the voxels left along each axis counted down instead of the
// box's bounds compared.
bool rayMeetsSolid(const TruthObject& o, const double p[3], const double d[3]) {
    Walk w;
    if (!startWalk(o, p, d, w)) return false;
    const ig::VoxModel& g = o.model->grid;
    const std::ptrdiff_t sx = g.sizeX, sxy = static_cast<std::ptrdiff_t>(g.sizeX) * g.sizeY;
    const std::uint8_t* __restrict__ solid = o.solid;
    std::ptrdiff_t at = w.v[2] * sxy + w.v[1] * sx + w.v[0];
    const std::ptrdiff_t stride[3] = {w.step[0], w.step[1] * sx, w.step[2] * sxy};
    int left[3];
    for (int a = 0; a < 3; ++a) {
        left[a] = w.step[a] > 0   ? o.hi[a] - 1 - w.v[a]
                  : w.step[a] < 0 ? w.v[a] - o.lo[a]
                                  : std::numeric_limits<int>::max();
    }
    double* next = w.next;
    const double t1 = w.t1;
    for (;;) {
        if (solid[at]) return true;
        // rayMeetsModel's choice: the least of next[], the earlier axis on a tie of the first
        // two, axis 2 unless strictly below it.
        const bool first = next[0] < next[1];
        const int i = first ? 0 : 1;
        const double ni = first ? next[0] : next[1];
        const int a = ni < next[2] ? i : 2;
        if (next[a] > t1) return false;
        if (--left[a] < 0) return false;
        at += stride[a];
        next[a] += w.delta[a];
    }
}

}  // namespace

TruthComputer::TruthComputer(int workers, bool reference)
    : acc_(kIds), objectOf_(kIds, -1), reference_(reference) {
    if (workers != 1) {
        arena_ = std::make_unique<tbb::task_arena>(workers > 1 ? workers
                                                               : int{tbb::task_arena::automatic});
    }
}

TruthComputer::~TruthComputer() = default;

void TruthComputer::compute(const TruthScene& scene, const TruthCamera& camera,
                            const std::uint16_t* ids, int width, int lines, int firstLine,
                            const ig::Pose& pose, double time, std::uint64_t index, FieldTruth& out,
                            bool late, std::span<const TruthObject> extra) {
    out.field = index;
    out.time = time;
    out.late = late;
    out.objects.clear();
    // What the field shows: its warped ids.
    seen_.clear();
    for (int line = 0; line < lines; ++line) {
        const int y = firstLine + 2 * line;
        const std::uint16_t* row = ids + static_cast<std::size_t>(line) * width;
        for (int x = 0; x < width; ++x) {
            const std::uint16_t id = row[x];
            if (id == 0) continue;
            Acc& a = acc_[id];
            if (a.n == 0) {
                seen_.push_back(id);
                a.x0 = a.x1 = x;
                a.y0 = a.y1 = y;
                a.sx = a.sy = 0.0;
            }
            ++a.n;
            a.x0 = std::min(a.x0, x);
            a.x1 = std::max(a.x1, x);
            a.y0 = std::min(a.y0, y);
            a.y1 = std::max(a.y1, y);
            a.sx += x + 0.5;
            a.sy += y + 0.5;
        }
    }

    // Where each object truly is at this instant, seen from this pose: the static ones where
    // the scene holds them, the moving ones placed at this instant (the reference copies all),
    // on a ground that keeps its data around this pose (a paged one).
    scene.ground().follow(pose.position.x, pose.position.y);
    std::span<const TruthObject> fixed;
    if (reference_) {
        scene.objectsAt(time, objects_);
    } else {
        fixed = scene.staticObjects();
        scene.movingAt(time, objects_);
    }
    objects_.insert(objects_.end(), extra.begin(), extra.end());
    const ig::Camera cam(pose, camera.window);
    const double kx = static_cast<double>(camera.outWidth) / camera.window.width;
    const double ky = static_cast<double>(camera.outHeight) / camera.window.height;
    // Each object's truth depends on that object alone (the warped ids' tallies are read only):
    // spread over the workers, each writing its own entry, merged in placement order below, so
    // the lines are the same whatever the worker count.
    // The field's frustum: a plane through the eye and each edge of the window, normal inward.
    constexpr double kNearM = 0.05;
    const double ww = camera.window.width, wh = camera.window.height;
    const glm::dvec3 edge[4] = {cam.rayDirection(0.0, 0.0), cam.rayDirection(ww, 0.0),
                                cam.rayDirection(ww, wh), cam.rayDirection(0.0, wh)};
    const glm::dvec3 inward = cam.rayDirection(0.5 * ww, 0.5 * wh);
    glm::dvec3 side[4];
    for (int k = 0; k < 4; ++k) {
        side[k] = glm::normalize(glm::cross(edge[k], edge[(k + 1) % 4]));
        if (glm::dot(side[k], inward) < 0.0) side[k] = -side[k];
    }
    // Whether an object that the field does not show lies wholly outside the frustum (or wholly
    // behind the clipping plane), tested on a sphere holding its box at any heading: then its
    // projected box misses the field and it is not listed, so its corners need not be worked out.
    // Conservative (a margin of a micrometre and a part in 1e9): the same lines as without it.
    const auto outside = [&](const TruthObject& o) {
        const ig::VoxModel& g = o.model->grid;
        const double u =
            std::max(std::abs(o.lo[0] - 0.5 * g.sizeX), std::abs(o.hi[0] - 0.5 * g.sizeX));
        const double v =
            std::max(std::abs(o.lo[1] - 0.5 * g.sizeY), std::abs(o.hi[1] - 0.5 * g.sizeY));
        const double h = 0.5 * (o.hi[2] - o.lo[2]);
        const double r = o.scale * std::sqrt(u * u + v * v + h * h) * (1.0 + 1e-9) + 1e-6;
        const glm::dvec3 q{o.x, o.y, o.z + o.scale * 0.5 * (o.lo[2] + o.hi[2])};
        if (cam.forwardDepth(q) + r < kNearM) return true;
        const glm::dvec3 d = q - pose.position;
        for (const glm::dvec3& n : side) {
            if (glm::dot(n, d) < -r) return true;
        }
        return false;
    };
    const auto one = [&](const TruthObject& o, ObjectTruth& t) -> bool {
        if (acc_[o.id].n == 0 && (late || (!reference_ && outside(o)))) return false;
        const std::array<glm::dvec3, 8> corners = objectCorners(o);
        t = ObjectTruth{};
        t.id = o.id;
        t.moving = o.moving;
        glm::dvec3 centre{0.0};
        for (const glm::dvec3& q : corners)
            centre += q * 0.125;
        t.rangeM = glm::length(centre - pose.position);
        // The box clipped to the space kNearM in front of the eye, projected: its corners there,
        // and where its edges cross that plane.
        double bx0 = std::numeric_limits<double>::infinity(), by0 = bx0, bx1 = -bx0, by1 = -bx0;
        bool behind = false, front = false;
        // The projected corners (output pixels), for the rows' spans below.
        glm::dvec2 projected[8];
        int nProjected = 0;
        const auto extend = [&](const glm::dvec3& q) {
            const std::optional<glm::dvec2> px = cam.project(q);
            if (!px) return;
            front = true;
            if (nProjected < 8) projected[nProjected++] = {px->x * kx, px->y * ky};
            bx0 = std::min(bx0, px->x * kx);
            bx1 = std::max(bx1, px->x * kx);
            by0 = std::min(by0, px->y * ky);
            by1 = std::max(by1, px->y * ky);
        };
        std::array<double, 8> depth;
        for (std::size_t k = 0; k < 8; ++k) {
            depth[k] = cam.forwardDepth(corners[k]);
            if (depth[k] >= kNearM) {
                extend(corners[k]);
            } else {
                behind = true;
            }
        }
        if (behind) {
            for (std::size_t k = 0; k < 8; ++k) {
                for (const std::size_t bit : {1u, 2u, 4u}) {
                    if ((k & bit) != 0) continue;
                    const std::size_t j = k | bit;
                    if ((depth[k] >= kNearM) == (depth[j] >= kNearM)) continue;
                    const double f = (kNearM - depth[k]) / (depth[j] - depth[k]);
                    extend(corners[k] + f * (corners[j] - corners[k]));
                }
            }
        }
        const bool shown = acc_[o.id].n > 0;
        if (!front && !shown) return false;
        if (!front) {
            // Shown although its box is behind the eye (a warp's shift): no pixel to trace.
            bx0 = by0 = 0.0;
            bx1 = by1 = -1.0;
        }
        if (!behind) {
            t.hasTrueBox = true;
            t.trueBox[0] = bx0;
            t.trueBox[1] = by0;
            t.trueBox[2] = bx1;
            t.trueBox[3] = by1;
        }
        const bool inFrustum =
            front && bx1 > 0.0 && by1 > 0.0 && bx0 < camera.outWidth && by0 < camera.outHeight;
        if (!inFrustum && !shown) return false;
        // Unoccluded: the field's pixels inside the box whose centre ray meets the model.
        if (inFrustum && !late) {
            const int x0 = std::max(0, static_cast<int>(std::floor(bx0)));
            const int x1 = std::min(camera.outWidth - 1, static_cast<int>(std::floor(bx1)));
            const int y0 = std::max(0, static_cast<int>(std::floor(by0)));
            const int y1 = std::min(camera.outHeight - 1, static_cast<int>(std::floor(by1)));
            // Every pixel while the box holds at most kExactRays of the field's pixels; beyond,
            // every step-th pixel of every step-th field line, each standing for step^2 pixels
            // (a near object's count is then an estimate, its error well under a percent).
            const int first = std::max(0, (y0 - firstLine + 1) / 2);
            const int last = std::min(lines - 1, (y1 - firstLine) / 2);
            const double area = static_cast<double>(std::max(0, x1 - x0 + 1)) *
                                static_cast<double>(std::max(0, last - first + 1));
            const int step =
                area > kExactRays ? static_cast<int>(std::ceil(std::sqrt(area / kExactRays))) : 1;
            // The model frame and the eye in it once per object (rayMeetsObject's arithmetic,
            // so the same answer ray for ray).
            const ModelFrame frame(o);
            double p[3], d[3];
            frame.point(o, pose.position, p);
            // Each line's rays only over the pixels whose centre lies in the box's projection
            // (all of the box in front of the eye: the convex hull of its projected corners),
            // widened by kSpanMarginPx: a ray outside it misses the box, so the count is the
            // same as over the whole rectangle (the reference casts that).
            const bool spans = !reference_ && !behind && nProjected == 8;
            const Hull hull = spans ? convexHull(projected) : Hull{};
            std::uint64_t met = 0;
            for (int line = first; line <= last; line += step) {
                const int y = firstLine + 2 * line;
                int xa = x0, xb = x1;
                if (spans) {
                    double s0 = std::numeric_limits<double>::infinity(), s1 = -s0;
                    hullSpan(hull, y + 0.5, s0, s1);
                    if (!(s0 <= s1)) continue;
                    s0 = std::clamp(s0 - kSpanMarginPx - 0.5, x0 - 1.0, x1 + 1.0);
                    s1 = std::clamp(s1 + kSpanMarginPx - 0.5, x0 - 1.0, x1 + 1.0);
                    const int a = static_cast<int>(std::ceil(s0));
                    if (a > x0) xa = x0 + (a - x0 + step - 1) / step * step;
                    xb = std::min(x1, static_cast<int>(std::floor(s1)));
                }
                for (int x = xa; x <= xb; x += step) {
                    const glm::dvec3 dir =
                        glm::normalize(cam.rayDirection((x + 0.5) / kx, (y + 0.5) / ky));
                    if (reference_) {
                        met += rayMeetsObject(o, pose.position, dir) ? 1 : 0;
                        continue;
                    }
                    frame.direction(dir, d);
                    met += (o.solid ? rayMeetsSolid(o, p, d) : rayMeetsModel(o, p, d)) ? 1 : 0;
                }
            }
            t.unoccludedPx =
                met * static_cast<std::uint64_t>(step) * static_cast<std::uint64_t>(step);
        }
        const Acc& a = acc_[o.id];
        t.visiblePx = a.n;
        if (a.n > 0) {
            t.bbox[0] = a.x0;
            t.bbox[1] = a.y0;
            t.bbox[2] = a.x1 + 1;
            t.bbox[3] = a.y1 + 1;
            t.centroid[0] = a.sx / static_cast<double>(a.n);
            t.centroid[1] = a.sy / static_cast<double>(a.n);
        }
        // Listed when the field shows it, or when its exact shape covers a pixel centre of the
        // field (it would show unless hidden); sub-pixel objects that show nothing are not.
        if (a.n == 0 && t.unoccludedPx == 0) return false;
        if (t.unoccludedPx > 0) {
            t.occluded = std::clamp(
                1.0 - static_cast<double>(t.visiblePx) / static_cast<double>(t.unoccludedPx), 0.0,
                1.0);
        }
        return true;
    };
    const std::size_t nFixed = fixed.size();
    const std::size_t n = nFixed + objects_.size();
    results_.resize(n);
    listed_.assign(n, 0);
    const auto range = [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const TruthObject& o = i < nFixed ? fixed[i] : objects_[i - nFixed];
            listed_[i] = one(o, results_[i]) ? 1 : 0;
        }
    };
    if (arena_) {
        arena_->execute(
            [&] { tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 64), range); });
    } else {
        range(tbb::blocked_range<std::size_t>(0, n));
    }
    for (std::size_t i = 0; i < n; ++i) {
        if (listed_[i]) out.objects.push_back(results_[i]);
    }
    for (const std::uint16_t id : seen_)
        acc_[id].n = 0;
    const auto byId = [](const ObjectTruth& a, const ObjectTruth& b) { return a.id < b.id; };
    if (!std::is_sorted(out.objects.begin(), out.objects.end(), byId)) {
        std::sort(out.objects.begin(), out.objects.end(), byId);
    }
}

namespace {

// JSON numbers written straight into the line (shortest round-trip form; a field lists thousands
// of objects, and a document tree per line cost more than the truth itself).
void put(std::string& out, double v) {
    if (!std::isfinite(v)) {
        out += "null";  // as JSON has no infinity
        return;
    }
    char buf[32];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    out.append(buf, r.ptr);
}
void put(std::string& out, std::uint64_t v) {
    char buf[24];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    out.append(buf, r.ptr);
}
void put(std::string& out, int v) {
    char buf[16];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    out.append(buf, r.ptr);
}
template <class T>
void putArray(std::string& out, const T* v, int n) {
    out += '[';
    for (int k = 0; k < n; ++k) {
        if (k) out += ',';
        put(out, v[k]);
    }
    out += ']';
}

}  // namespace

std::string truthLine(const FieldTruth& truth) {
    std::string out;
    out.reserve(64 + truth.objects.size() * 200);
    out += "{\"field\":";
    put(out, static_cast<std::uint64_t>(truth.field));
    out += ",\"time\":";
    put(out, std::round(truth.time * 1e6) / 1e6);
    if (truth.late) out += ",\"late\":true";
    out += ",\"objects\":[";
    bool firstObject = true;
    for (const ObjectTruth& o : truth.objects) {
        if (!firstObject) out += ',';
        firstObject = false;
        out += "{\"id\":";
        put(out, static_cast<int>(o.id));
        out += ",\"visible_px\":";
        put(out, static_cast<std::uint64_t>(o.visiblePx));
        if (o.visiblePx > 0) {
            out += ",\"bbox\":";
            putArray(out, o.bbox, 4);
            out += ",\"centroid\":";
            const double c[2] = {round2(o.centroid[0]), round2(o.centroid[1])};
            putArray(out, c, 2);
        } else {
            out += ",\"bbox\":null,\"centroid\":null";
        }
        out += ",\"range_m\":";
        put(out, round2(o.rangeM));
        out += ",\"occluded\":";
        if (truth.late) {
            out += "null";
        } else if (o.occluded >= 0.0) {
            put(out, round2(o.occluded));
        } else {
            out += "null";
        }
        out += ",\"true_bbox\":";
        if (o.hasTrueBox) {
            const double b[4] = {round2(o.trueBox[0]), round2(o.trueBox[1]), round2(o.trueBox[2]),
                                 round2(o.trueBox[3])};
            putArray(out, b, 4);
        } else {
            out += "null";
        }
        out += ",\"unoccluded_px\":";
        if (truth.late) {
            out += "null";
        } else {
            put(out, static_cast<std::uint64_t>(o.unoccludedPx));
        }
        out += ",\"moving\":";
        out += o.moving ? "true" : "false";
        out += '}';
    }
    out += "]}";
    return out;
}

std::string lostTruthLine(std::uint64_t field, double time) {
    std::string out = "{\"field\":";
    put(out, field);
    out += ",\"time\":";
    put(out, std::round(time * 1e6) / 1e6);
    out += ",\"lost\":true,\"objects\":null}";
    return out;
}

TruthWriter::TruthWriter(const TruthScene& scene, const TruthCamera& camera, std::FILE* out,
                         int width, int maxLines, bool waitWhenFull, int slots, int lateAfter)
    : scene_(scene),
      camera_(camera),
      out_(out),
      waitWhenFull_(waitWhenFull),
      lateAfter_(static_cast<std::uint64_t>(std::max(0, lateAfter))) {
    CHECK_GT(slots, 0);
    slots_.resize(static_cast<std::size_t>(slots));
    for (Slot& s : slots_) {
        s.ids.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(maxLines));
        s.extra.reserve(kMaxExtraObjects);
    }
    // About a minute of fields at 59.94 Hz: lost fields are a few words each.
    lostQueue_.resize(4096);
    thread_ = base::ForkGate::startThread([this] { loop(); });
}

TruthWriter::~TruthWriter() {
    stop_.store(true, std::memory_order_release);
    if (thread_.joinable()) thread_.join();
}

void TruthWriter::record(const prp::Field& field, const ig::Pose& pose, double focal,
                         std::span<const ExtraObject> extra) {
    const std::uint64_t head = head_.load(std::memory_order_relaxed);
    while (head - tail_.load(std::memory_order_acquire) >= slots_.size()) {
        if (!waitWhenFull_) {
            // No slot: the field is written as lost, in its place (its index and instant
            // only). When even that queue is full the stream has a gap: finish() reports it.
            const std::uint64_t lh = lostHead_.load(std::memory_order_relaxed);
            if (lh - lostTail_.load(std::memory_order_acquire) >= lostQueue_.size()) {
                dropped_.fetch_add(1, std::memory_order_relaxed);
                return;
            }
            lostQueue_[lh % lostQueue_.size()] = Lost{field.index, field.time};
            lostHead_.store(lh + 1, std::memory_order_release);
            return;
        }
        std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    Slot& s = slots_[head % slots_.size()];
    const std::size_t n = static_cast<std::size_t>(field.width) * field.lines;
    s.hasIds = field.objectId.size() == n && n <= s.ids.size();
    if (s.hasIds) std::copy(field.objectId.begin(), field.objectId.end(), s.ids.begin());
    s.width = field.width;
    s.lines = field.lines;
    s.firstLine = prp::fieldFirstLine(field.parity);
    s.pose = pose;
    s.focal = focal;
    const std::size_t kept = std::min(extra.size(), kMaxExtraObjects);
    s.extra.assign(extra.begin(), extra.begin() + static_cast<std::ptrdiff_t>(kept));
    if (kept < extra.size()) extraCut_.fetch_add(extra.size() - kept, std::memory_order_relaxed);
    s.time = field.time;
    s.index = field.index;
    head_.store(head + 1, std::memory_order_release);
}

bool TruthWriter::writeLine(const std::string& line) {
    if (std::fwrite(line.data(), 1, line.size(), out_) != line.size() ||
        std::fputc('\n', out_) == EOF) {
        error_ = "a write failed after " + std::to_string(written()) + " fields";
        return false;
    }
    written_.fetch_add(1, std::memory_order_release);
    return true;
}

void TruthWriter::loop() {
    // The computer's tables are made, and freed at the end, as pieces of work for a fork to wait
    // on (base/fork_gate.hpp); `setUp` outlives them.
    std::optional<base::ForkGate::Working> setUp(std::in_place);
    TruthComputer computer;
    FieldTruth truth;
    std::vector<TruthObject> extra;
    setUp.reset();
    for (;;) {
        // The lost queue is read before the slots: a field published to it comes after every
        // slot published before it, so the merge below keeps the field order.
        const std::uint64_t lostTail = lostTail_.load(std::memory_order_relaxed);
        const std::uint64_t lostHead = lostHead_.load(std::memory_order_acquire);
        const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
        const std::uint64_t head = head_.load(std::memory_order_acquire);
        if (tail == head && lostTail == lostHead) {
            if (stop_.load(std::memory_order_acquire) &&
                tail == head_.load(std::memory_order_acquire) &&
                lostTail == lostHead_.load(std::memory_order_acquire)) {
                setUp.emplace();
                return;
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
            continue;
        }
        // One field's truth is one piece of work for a fork to wait on (base/fork_gate.hpp).
        const base::ForkGate::Working working;
        const Slot& s = slots_[tail % slots_.size()];
        if (lostTail != lostHead &&
            (tail == head || lostQueue_[lostTail % lostQueue_.size()].index < s.index)) {
            const Lost& l = lostQueue_[lostTail % lostQueue_.size()];
            if (error_.empty() && writeLine(lostTruthLine(l.index, l.time))) {
                lost_.fetch_add(1, std::memory_order_release);
            }
            lostTail_.store(lostTail + 1, std::memory_order_release);
            continue;
        }
        if (!s.hasIds) {
            missingIds_.fetch_add(1, std::memory_order_relaxed);
        } else if (error_.empty()) {
            // Late when more than lateAfter fields wait behind this one (wall clock only).
            const bool late = !waitWhenFull_ && head - tail - 1 > lateAfter_;
            // The field's own camera: the window at the field's focal length.
            TruthCamera camera = camera_;
            if (s.focal > 0.0) camera.window.focal = s.focal;
            extra.clear();
            for (const ExtraObject& e : s.extra)
                extra.push_back(scene_.placedExtra(e));
            computer.compute(scene_, camera, s.ids.data(), s.width, s.lines, s.firstLine, s.pose,
                             s.time, s.index, truth, late, extra);
            if (writeLine(truthLine(truth)) && late) late_.fetch_add(1, std::memory_order_release);
        }
        tail_.store(tail + 1, std::memory_order_release);
    }
}

std::string TruthWriter::finish() {
    stop_.store(true, std::memory_order_release);
    if (thread_.joinable()) thread_.join();
    if (!error_.empty()) return error_;
    if (const std::uint64_t dropped = dropped_.load(); dropped > 0) {
        return std::to_string(dropped) + " fields' truth dropped (more than " +
               std::to_string(lostQueue_.size()) + " fields lost at once)";
    }
    if (const std::uint64_t missing = missingIds_.load(); missing > 0) {
        return std::to_string(missing) +
               " fields carried no object ids (the renderer drew no objects)";
    }
    return {};
}

}  // namespace sim
