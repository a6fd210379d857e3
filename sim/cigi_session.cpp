#include "sim/cigi_session.hpp"

#include "base/check.hpp"
#include "base/error.hpp"
#include "base/text.hpp"
#include "ig/surface_hit.hpp"
#include "io/field_clock.hpp"

#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numbers>
#include <thread>
#include <type_traits>
#include <variant>

namespace sim {

namespace cigi = io::cigi;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
// The widest field of view a View Definition may ask for (as --fov): exclusive.
constexpr double kMaxFieldOfView = 179.0 * kDeg;
// Fields of view closer than this (radians) are the same one (a host's float degrees against
// the run's double).
constexpr double kSameFieldOfView = 1e-6;
// Levels of attached entities, the top one included (deeper chains are refused).
constexpr std::size_t kMaxChain = 64;
// WGS 84.
constexpr double kEarthA = 6378137.0;
constexpr double kEarthF = 1.0 / 298.257223563;
constexpr double kEarthE2 = kEarthF * (2.0 - kEarthF);

bool parseDouble(std::string_view text, double& value) {
    while (!text.empty() && text.front() == ' ')
        text.remove_prefix(1);
    while (!text.empty() && text.back() == ' ')
        text.remove_suffix(1);
    if (text.empty()) return false;
    if (text.front() == '+') text.remove_prefix(1);
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    return ec == std::errc() && end == text.data() + text.size() && std::isfinite(value);
}

double wrapLongitude(double lon) {
    if (lon >= -180.0 && lon <= 180.0) return lon;
    lon = std::fmod(lon + 180.0, 360.0);
    if (lon < 0.0) lon += 360.0;
    return lon - 180.0;
}

// Azimuth (clockwise from north) and elevation of the normal of a surface of gradient g,
// degrees.
void normalAngles(const glm::dvec2& g, float& azimuthDeg, float& elevationDeg) {
    const double slope = std::hypot(g.x, g.y);
    azimuthDeg = slope > 0.0 ? static_cast<float>(std::atan2(-g.x, -g.y) / kDeg) : 0.0f;
    elevationDeg = static_cast<float>(std::atan2(1.0, slope) / kDeg);
}

// A vector in an entity's axes (x forward, y right, z down) in world axes (x east, y north,
// z up), for the pose's yaw (clockwise from north), pitch (up) and roll (right wing down).
glm::dvec3 worldFromBody(const ig::Pose& pose, const glm::dvec3& v) {
    const double cy = std::cos(pose.yaw), sy = std::sin(pose.yaw);
    const double cp = std::cos(pose.pitch), sp = std::sin(pose.pitch);
    const double cr = std::cos(pose.roll), sr = std::sin(pose.roll);
    const glm::dvec3 forward{sy * cp, cy * cp, sp};
    const glm::dvec3 right0{cy, -sy, 0.0};
    const glm::dvec3 up0{-sy * sp, -cy * sp, cp};
    const glm::dvec3 right = right0 * cr - up0 * sr;
    const glm::dvec3 up = up0 * cr + right0 * sr;
    return forward * v.x + right * v.y - up * v.z;
}

}  // namespace

GeoOrigin parseGeoOrigin(std::string_view text, std::string_view flag) {
    const std::string what = std::string(flag) + " " + base::quoted(text);
    double v[3] = {0.0, 0.0, 0.0};
    int n = 0;
    std::string_view rest = text;
    while (true) {
        const std::size_t comma = rest.find(',');
        if (n == 3 || !parseDouble(rest.substr(0, comma), v[n])) {
            throw base::InputError(what + ": expected LAT,LON[,ALT] (degrees, degrees, metres)");
        }
        ++n;
        if (comma == std::string_view::npos) break;
        rest.remove_prefix(comma + 1);
    }
    if (n < 2) throw base::InputError(what + ": expected LAT,LON[,ALT] (degrees, degrees, metres)");
    if (!(std::abs(v[0]) <= 85.0)) {
        throw base::InputError(what + ": latitude " + base::number(v[0]) +
                               " is outside [-85, 85] degrees (a local tangent plane near a "
                               "pole is not supported)");
    }
    if (!(std::abs(v[1]) <= 180.0)) {
        throw base::InputError(what + ": longitude " + base::number(v[1]) +
                               " is outside [-180, 180] degrees");
    }
    if (!(std::abs(v[2]) <= 100000.0)) {
        throw base::InputError(what + ": altitude " + base::number(v[2]) +
                               " is outside [-100000, 100000] metres");
    }
    return {v[0], v[1], v[2]};
}

GeoFrame::GeoFrame(const GeoOrigin& origin) : origin_(origin) {
    const double s = std::sin(origin.latDeg * kDeg);
    const double w = std::sqrt(1.0 - kEarthE2 * s * s);
    const double meridian = kEarthA * (1.0 - kEarthE2) / (w * w * w);
    const double primeVertical = kEarthA / w;
    perLat_ = meridian * kDeg;
    perLon_ = primeVertical * std::cos(origin.latDeg * kDeg) * kDeg;
}

glm::dvec3 GeoFrame::worldFromGeodetic(double latDeg, double lonDeg, double altM) const {
    return {wrapLongitude(lonDeg - origin_.lonDeg) * perLon_, (latDeg - origin_.latDeg) * perLat_,
            altM - origin_.altM};
}

glm::dvec3 GeoFrame::geodeticFromWorld(const glm::dvec3& world) const {
    return {std::clamp(origin_.latDeg + world.y / perLat_, -90.0, 90.0),
            wrapLongitude(origin_.lonDeg + world.x / perLon_), world.z + origin_.altM};
}

namespace {

// The axes of a rotation by yaw (right), pitch (up), roll (right) from a frame of x forward, y
// right, z down, in that frame's coordinates.
void axesFromAngles(double yaw, double pitch, double roll, glm::dvec3& forward, glm::dvec3& right) {
    const double cy = std::cos(yaw), sy = std::sin(yaw);
    const double cp = std::cos(pitch), sp = std::sin(pitch);
    const double cr = std::cos(roll), sr = std::sin(roll);
    forward = {cp * cy, cp * sy, -sp};
    right = {sr * sp * cy - cr * sy, sr * sp * sy + cr * cy, sr * cp};
}

}  // namespace

ig::Pose eyePose(const ig::Pose& entity, const ViewOffset& view) {
    if (view.isIdentity()) return entity;
    glm::dvec3 f, r;
    axesFromAngles(view.yaw, view.pitch, view.roll, f, r);
    const glm::dvec3 forward = worldFromBody(entity, f), right = worldFromBody(entity, r);
    ig::Pose eye;
    eye.position = entity.position + worldFromBody(entity, view.offset);
    eye.pitch = std::asin(std::clamp(forward.z, -1.0, 1.0));
    // Straight up or down the heading is the entity's (any would do); roll then follows.
    eye.yaw =
        std::hypot(forward.x, forward.y) > 1e-12 ? std::atan2(forward.x, forward.y) : entity.yaw;
    const double cy = std::cos(eye.yaw), sy = std::sin(eye.yaw);
    const double sp = std::sin(eye.pitch), cp = std::cos(eye.pitch);
    const glm::dvec3 right0{cy, -sy, 0.0}, up0{-sy * sp, -cy * sp, cp};
    eye.roll = std::atan2(-glm::dot(right, up0), glm::dot(right, right0));
    return eye;
}

ig::Pose DeadReckoning::at(double t) const {
    const double dt = std::min(t, holdAfter) - time;
    ig::Pose p = pose;
    p.position += velocity * dt;
    p.yaw += yawRate * dt;
    p.pitch = std::clamp(p.pitch + pitchRate * dt, -0.5 * std::numbers::pi, 0.5 * std::numbers::pi);
    p.roll += rollRate * dt;
    return p;
}

CigiSession::CigiSession(const ig::TerrainMap& map, const CigiOptions& options)
    : map_(map),
      options_(options),
      geo_(options.origin),
      ground_(options.ground ? *options.ground : static_cast<const ig::Ground&>(map)) {
    in_.resize(65536);
    inFlight_.reserve(options_.maxPendingRequests + 256);
    ready_.reserve(options_.maxPendingRequests + 256);
    out_.reserve(65536);
    pending_.reserve(options_.maxPendingRequests);
    repeating_.reserve(kMaxRepeating);
    message_.packets.reserve(64);
    stats_.firstErrors.reserve(CigiStats::kReportedErrors);
    stats_.outages.reserve(CigiStats::kReportedOutages);
    ownship_.time = options_.startTime;
    ownship_.pose = options_.startPose;
    sensors_.reserve(256);
    sensorScratch_.reserve(options_.maxEntities);
}

int CigiSession::open(std::string* error) {
    const int rc = socket_.open(options_.bind, options_.receiveBufferBytes);
    stats_.receiveBufferBytes = socket_.receiveBufferBytes();
    if (rc != 0 && error) {
        *error = "cannot bind UDP " + io::toString(options_.bind) + ": " + std::strerror(-rc);
    }
    return rc;
}

void CigiSession::noteError(const std::string& message) {
    if (stats_.firstErrors.size() < CigiStats::kReportedErrors) {
        stats_.firstErrors.push_back(message);
    }
}

void CigiSession::heard(double t) {
    if (t > ownship_.holdAfter) {
        // Back after a hold: the ownship goes on from where it stopped, not from where its old
        // rates would have taken it (the host's next Entity Control puts it right).
        ownship_.pose = ownship_.at(t);
        ownship_.time = t;
    }
    ownship_.holdAfter = t + options_.extrapolateLimit;
    for (HostEntity& e : entities_) {
        if (t > e.motion.holdAfter) {
            e.motion.pose = e.motion.at(t);
            e.motion.time = t;
        }
        e.motion.holdAfter = ownship_.holdAfter;
    }
    lastHeard_ = t;
    if (silent_) {
        silent_ = false;
        if (!stats_.outages.empty() && stats_.outages.back().ongoing) {
            HostOutage& o = stats_.outages.back();
            o.length = t - o.lastMessage;
            o.ongoing = false;
        }
    }
}

void CigiSession::watch(double t) {
    if (!stats_.hostSeen) return;  // a host never heard has not vanished
    if (!silent_ && t - lastHeard_ > options_.hostTimeout) {
        silent_ = true;
        ++stats_.hostLosses;
        if (stats_.outages.size() < CigiStats::kReportedOutages) {
            stats_.outages.push_back({lastHeard_, t, t - lastHeard_, true, 0, 0});
        }
    }
    if (silent_ && stats_.hostLosses <= CigiStats::kReportedOutages && !stats_.outages.empty() &&
        stats_.outages.back().ongoing) {
        HostOutage& o = stats_.outages.back();
        o.length = t - o.lastMessage;
        if (t > ownship_.holdAfter) {
            ++o.fieldsHeld;
        } else {
            ++o.fieldsExtrapolated;
        }
    }
}

namespace {

// Re-based at t: the pose reached with the old rates, the new rates from here. World rates are
// CIGI's axes (x north, y east, z down) for a top-level entity; `inParentAxes` (an attached
// entity) takes them as they come, in the parent's axes like the offset they move.
void rebaseRates(DeadReckoning& dr, const cigi::RateControl& r, double t, bool inParentAxes) {
    dr.pose = dr.at(t);
    dr.time = t;
    const double x = r.xRate, y = r.yRate, z = r.zRate;
    const double rollRate = r.rollRateDeg * kDeg, pitchRate = r.pitchRateDeg * kDeg,
                 yawRate = r.yawRateDeg * kDeg;
    if (!r.localCoordinates) {
        dr.velocity = inParentAxes ? glm::dvec3{x, y, z} : glm::dvec3{y, x, -z};
        dr.rollRate = rollRate;
        dr.pitchRate = pitchRate;
        dr.yawRate = yawRate;
        return;
    }
    // Body rates: x forward, y right, z down, turned into world axes at the pose of time t (the
    // velocity is then held until the next update: linear dead reckoning).
    dr.velocity = worldFromBody(dr.pose, {x, y, z});
    const double cp = std::cos(dr.pose.pitch);
    const double cr = std::cos(dr.pose.roll), sr = std::sin(dr.pose.roll);
    // Body angular rates (p roll, q pitch, r yaw) to Euler angle rates.
    const double tp = std::tan(dr.pose.pitch);
    const double safeCp = std::max(std::abs(cp), 1e-6);
    dr.rollRate = rollRate + (pitchRate * sr + yawRate * cr) * tp;
    dr.pitchRate = pitchRate * cr - yawRate * sr;
    dr.yawRate = (pitchRate * sr + yawRate * cr) / safeCp;
}

}  // namespace

void CigiSession::setRates(double t) {
    rebaseRates(ownship_, rates_, t, false);
}

HostEntity* CigiSession::findEntity(std::uint16_t id) {
    for (HostEntity& e : entities_) {
        if (e.id == id) return &e;
    }
    return nullptr;
}

void CigiSession::applyEntity(const cigi::EntityControl& e, double t) {
    // Worded only for a refusal: a good Entity Control allocates nothing.
    const auto refuse = [&](const std::string& why) {
        ++stats_.entitiesRefused;
        noteError("Entity Control for entity " + std::to_string(e.entityId) + ": " + why);
    };
    HostEntity* entity = findEntity(e.entityId);
    if (e.entityState == cigi::EntityState::Destroyed) {
        if (!entity) {
            ++stats_.ignoredPackets;  // already gone (a host repeats its destroy messages)
            return;
        }
        ++stats_.entityControls;
        // Its children go with it, and theirs.
        std::vector<std::uint16_t> gone{e.entityId};
        for (std::size_t k = 0; k < gone.size(); ++k) {
            for (const HostEntity& c : entities_) {
                if (c.attached && c.parent == gone[k]) gone.push_back(c.id);
            }
        }
        std::erase_if(entities_, [&](const HostEntity& c) {
            return std::find(gone.begin(), gone.end(), c.id) != gone.end();
        });
        stats_.entitiesDestroyed += gone.size();
        return;
    }
    const auto type =
        std::find_if(options_.entityTypes.begin(), options_.entityTypes.end(),
                     [&](const EntityTypeModel& m) { return m.type == e.entityType; });
    if (type == options_.entityTypes.end()) {
        refuse("entity type " + std::to_string(e.entityType) +
               " maps to no model of the scene (--cigi-entity TYPE=MODEL)");
        return;
    }
    if (!entity && std::find(options_.reservedIds.begin(), options_.reservedIds.end(),
                             e.entityId) != options_.reservedIds.end()) {
        refuse("the id is taken by an object of the scene");
        return;
    }
    if (e.attached) {
        if (e.parentId == e.entityId) {
            refuse("attached to itself");
            return;
        }
        // Up the parent's chain: it must end at the ownship or a top-level entity, without
        // coming back to this one.
        std::uint16_t up = e.parentId;
        for (std::size_t steps = 0; up != 0; ++steps) {
            const HostEntity* p = findEntity(up);
            if (!p) {
                refuse("parent " + std::to_string(up) + " does not exist");
                return;
            }
            if (!p->attached) break;
            if (p->parent == e.entityId || steps > entities_.size()) {
                refuse("attaching it to " + std::to_string(e.parentId) +
                       " would make a loop of parents");
                return;
            }
            if (steps + 2 >= kMaxChain) {
                refuse("more than " + std::to_string(kMaxChain) + " levels of parents");
                return;
            }
            up = p->parent;
        }
    }
    if (!entity) {
        if (entities_.size() >= options_.maxEntities) {
            refuse("more than " + std::to_string(options_.maxEntities) + " entities");
            return;
        }
        entity = &entities_.emplace_back();
        entity->id = e.entityId;
        entity->motion.holdAfter = ownship_.holdAfter;
        ++stats_.entitiesCreated;
    }
    ++stats_.entityControls;
    const bool wasAttached = entity->attached;
    entity->type = e.entityType;
    entity->model = type->model;
    entity->scale = type->scale;
    entity->active = e.entityState == cigi::EntityState::Active;
    entity->attached = e.attached;
    entity->parent = e.attached ? e.parentId : 0;
    entity->onGround = e.groundClamp != cigi::GroundClamp::None;
    DeadReckoning& m = entity->motion;
    m.time = t;
    if (e.attached) {
        m.pose.position = {e.latOrX, e.lonOrY, e.altOrZ};
        const double yaw = e.yawDeg > 180.0f ? e.yawDeg - 360.0 : e.yawDeg;
        m.pose.yaw = yaw * kDeg;
    } else {
        m.pose.position = geo_.worldFromGeodetic(e.latOrX, e.lonOrY, e.altOrZ);
        m.pose.yaw = e.yawDeg * kDeg;
    }
    m.pose.pitch = e.pitchDeg * kDeg;
    m.pose.roll = e.rollDeg * kDeg;
    if (wasAttached != e.attached) {
        // Rates given in the old frame of reference mean nothing in the new one.
        m.velocity = glm::dvec3(0.0);
        m.yawRate = m.pitchRate = m.rollRate = 0.0;
        entity->rates = {};
    } else if (entity->rates.localCoordinates) {
        rebaseRates(m, entity->rates, t, false);
    }
}

void CigiSession::applyEntityRates(const cigi::RateControl& r, double t) {
    HostEntity* entity = findEntity(r.entityId);
    if (!entity) {
        ++stats_.entitiesRefused;
        noteError("Rate Control for entity " + std::to_string(r.entityId) +
                  ": no such entity (an Entity Control creates it)");
        return;
    }
    if (entity->attached && r.localCoordinates) {
        ++stats_.entitiesRefused;
        noteError("Rate Control for entity " + std::to_string(r.entityId) +
                  ": rates in its own axes for an attached entity are not taken (give them in "
                  "its parent's)");
        return;
    }
    ++stats_.rateUpdates;
    entity->rates = r;
    rebaseRates(entity->motion, r, t, entity->attached);
}

SensorState* CigiSession::findSensor(std::uint8_t id) {
    for (SensorState& s : sensors_)
        if (s.id == id) return &s;
    return nullptr;
}

void CigiSession::applySensor(const cigi::SensorControl& c) {
    if (c.viewId != options_.viewId) {
        ++stats_.ignoredPackets;  // another image generator's view
        return;
    }
    ++stats_.sensorControls;
    SensorState* s = findSensor(c.sensorId);
    if (!s) {
        s = &sensors_.emplace_back();  // at most 256: ids are 8 bits (reserved)
        s->id = c.sensorId;
    }
    s->on = c.sensorOn;
    s->trackMode = c.trackMode;
    s->extended = c.extendedResponse;
    if (c.sensorOn && c.trackMode != cigi::SensorTrackMode::Off &&
        c.trackMode != cigi::SensorTrackMode::Target) {
        noteError("Sensor Control for view " + std::to_string(c.viewId) + ", sensor " +
                  std::to_string(c.sensorId) + ": track mode " +
                  std::to_string(static_cast<unsigned>(c.trackMode)) +
                  " is not taken (only 3, target, on an entity named by Component Control); "
                  "the sensor answers searching");
    }
}

void CigiSession::applyComponent(const cigi::ComponentControl& c) {
    if (c.componentClass != cigi::kComponentClassSensor || c.componentId != 0) {
        ++stats_.ignoredPackets;  // no other component is this image generator's
        return;
    }
    const auto refuse = [&](const std::string& why) {
        ++stats_.sensorTargetsRefused;
        noteError("Component Control for sensor " + std::to_string(c.instanceId) + ": " + why);
    };
    if (c.instanceId > 255) {
        refuse("sensor ids are 0..255");
        return;
    }
    const std::uint32_t target = c.data[0];
    if (target == 0 || target > 0xffff || !findEntity(static_cast<std::uint16_t>(target))) {
        refuse("entity " + std::to_string(target) + " is not an entity the host has placed");
        return;
    }
    ++stats_.sensorTargets;
    SensorState* s = findSensor(static_cast<std::uint8_t>(c.instanceId));
    if (!s) {
        s = &sensors_.emplace_back();
        s->id = static_cast<std::uint8_t>(c.instanceId);
    }
    s->hasTarget = true;
    s->target = static_cast<std::uint16_t>(target);
}

SensorSight sightInWindow(const ig::Pose& eye, const glm::dvec3& point, int width, int height,
                          double hfov) {
    SensorSight s;
    const ig::CameraBasis b = ig::CameraBasis::fromPose(eye);
    const glm::dvec3 d = point - eye.position;
    const double x = glm::dot(d, b.right), y = glm::dot(d, b.up), z = glm::dot(d, b.forward);
    s.rangeM = glm::length(d);
    s.gateXDeg = std::atan2(x, z) / kDeg;
    s.gateYDeg = std::atan2(y, std::hypot(x, z)) / kDeg;
    s.inFront = z > 0.0;
    if (s.inFront) {
        // The window's edges: half its width at the focal length that gives hfov.
        const double focal = 0.5 * width / std::tan(0.5 * hfov);
        s.inWindow =
            std::abs(x / z) * focal <= 0.5 * width && std::abs(y / z) * focal <= 0.5 * height;
    }
    return s;
}

SensorSight sightOf(const ig::TerrainMap& map, const ig::Pose& eye, const glm::dvec3& point,
                    int width, int height, double hfov) {
    SensorSight s = sightInWindow(eye, point, width, height, hfov);
    const glm::dvec3 d = point - eye.position;
    // The terrain between: the first hit of the exact surface along the segment, short of the
    // point by more than half a metre (a ground-clamped entity's base is on the surface).
    if (s.rangeM > 0.0 && std::isfinite(s.rangeM)) {
        const ig::TerrainRay ray(map, eye.position, d / s.rangeM);
        const double hit = ig::exactHitInRange(map, ray, 0.0, s.rangeM);
        s.unoccluded = !(hit >= 0.0 && hit < s.rangeM - 0.5);
    }
    return s;
}

SensorSight sightOf(const ig::NestedMaps& maps, const ig::Pose& eye, const glm::dvec3& point,
                    int width, int height, double hfov) {
    if (maps.insets.empty()) return sightOf(*maps.global, eye, point, width, height, hfov);
    SensorSight s = sightInWindow(eye, point, width, height, hfov);
    if (s.rangeM > 0.0 && std::isfinite(s.rangeM)) {
        TerrainQuestion q;
        q.line = true;
        q.origin = eye.position;
        q.dir = (point - eye.position) / s.rangeM;
        q.maxRange = s.rangeM;
        const double hit = askTerrain(maps, q).range;
        s.unoccluded = !(hit >= 0.0 && hit < s.rangeM - 0.5);
    }
    return s;
}

bool gateBox(const ig::Pose& eye, const std::array<glm::dvec3, 8>& corners, int width, int height,
             double hfov, double box[4]) {
    const ig::CameraBasis b = ig::CameraBasis::fromPose(eye);
    const double focal = 0.5 * width / std::tan(0.5 * hfov);
    box[0] = box[1] = std::numeric_limits<double>::infinity();
    box[2] = box[3] = -box[0];
    for (const glm::dvec3& q : corners) {
        const glm::dvec3 d = q - eye.position;
        const double z = glm::dot(d, b.forward);
        if (!(z > 0.0)) return false;
        const double px = 0.5 * width + focal * glm::dot(d, b.right) / z;
        const double py = 0.5 * height - focal * glm::dot(d, b.up) / z;
        box[0] = std::min(box[0], px);
        box[1] = std::min(box[1], py);
        box[2] = std::max(box[2], px);
        box[3] = std::max(box[3], py);
    }
    box[0] = std::clamp(box[0], 0.0, static_cast<double>(width));
    box[2] = std::clamp(box[2], 0.0, static_cast<double>(width));
    box[1] = std::clamp(box[1], 0.0, static_cast<double>(height));
    box[3] = std::clamp(box[3], 0.0, static_cast<double>(height));
    return true;
}

cigi::Packet CigiSession::sensorResponse(SensorState& sensor, double t) {
    cigi::SensorExtendedResponse r;
    r.viewId = static_cast<std::uint16_t>(options_.viewId);
    r.sensorId = sensor.id;
    r.frameCounter = igFrame_;
    r.status = cigi::SensorStatus::Searching;
    if (sensor.trackMode == cigi::SensorTrackMode::Target && sensor.hasTarget) {
        r.entityIdValid = true;
        r.entityId = sensor.target;
        r.status = cigi::SensorStatus::Breaklock;  // until it is seen
        entityPosesAt(entities_, ownship_, t, sensorScratch_);
        const auto it = std::find_if(sensorScratch_.begin(), sensorScratch_.end(),
                                     [&](const EntityPose& e) { return e.id == sensor.target; });
        if (it != sensorScratch_.end()) {
            const ig::Pose eye = eyePose(viewCarrier(t), view_);
            double hfov = fieldHfov_ > 0.0 ? fieldHfov_ : viewHfov_;
            if (!(hfov > 0.0)) hfov = 0.5 * std::numbers::pi;
            const int w = options_.windowWidth, h = options_.windowHeight;
            // Where the renderer stands it: a ground-clamped base on the terrain under it.
            glm::dvec3 base = it->pose.position;
            if (it->onGround && ground_.covers(base.x, base.y))
                base.z = ground_.groundHeight(base.x, base.y);
            // The track point: the middle of the model's box when its size is known (what a
            // tracker centres its gate on), else the base point.
            const HostEntity* entity = findEntity(sensor.target);
            const EntityTypeModel* type = nullptr;
            for (const EntityTypeModel& m : options_.entityTypes)
                if (entity && m.type == entity->type) type = &m;
            std::array<glm::dvec3, 8> corners{};
            const bool sized = type && type->sizeX > 0 && type->sizeY > 0 && type->sizeZ > 0;
            glm::dvec3 point = base;
            if (sized) {
                // Model (u across, v along the heading) -> world, as the renderer places it.
                const double sn = std::sin(it->pose.yaw), cs = std::cos(it->pose.yaw);
                const double k = it->scale;
                for (int c = 0; c < 8; ++c) {
                    const double u = ((c & 1) ? 0.5 : -0.5) * type->sizeX;
                    const double v = ((c & 2) ? 0.5 : -0.5) * type->sizeY;
                    const double z = (c & 4) ? type->sizeZ : 0.0;
                    corners[static_cast<std::size_t>(c)] =
                        base + k * glm::dvec3(u * cs + v * sn, -u * sn + v * cs, z);
                }
                point.z += 0.5 * k * type->sizeZ;
            }
            SensorSight s;
            if (!options_.terrainQueries) {
                s = options_.surface ? sightOf(*options_.surface, eye, point, w, h, hfov)
                                     : sightOf(map_, eye, point, w, h, hfov);
            } else {
                // Over a paged map the terrain's thread checks the line; the latest answer
                // stands until the next (none yet: not seen).
                s = sightInWindow(eye, point, w, h, hfov);
                s.unoccluded = sensor.clearKnown && sensor.clear;
                if (!sensor.clearAsked && s.rangeM > 0.5 && std::isfinite(s.rangeM)) {
                    Query q;
                    q.known = true;
                    q.sensor = sensor.id;
                    q.question.line = true;
                    q.question.origin = eye.position;
                    q.question.dir = (point - eye.position) / s.rangeM;
                    q.question.maxRange = s.rangeM - 0.5;
                    sensor.clearAsked = defer(std::move(q));
                } else if (!(s.rangeM > 0.5)) {
                    s.unoccluded = true;  // nothing between
                }
            }
            if (s.seen()) r.status = cigi::SensorStatus::Tracking;
            if (s.inFront) {
                r.gateXDeg = static_cast<float>(s.gateXDeg);
                r.gateYDeg = static_cast<float>(s.gateYDeg);
            }
            double box[4];
            if (sized && gateBox(eye, corners, w, h, hfov, box)) {
                r.gateXSize = static_cast<std::uint16_t>(std::lround(box[2] - box[0]));
                r.gateYSize = static_cast<std::uint16_t>(std::lround(box[3] - box[1]));
            }
            const glm::dvec3 g = geo_.geodeticFromWorld(point);
            r.latDeg = g.x;
            r.lonDeg = g.y;
            r.altM = g.z;
        }
    }
    if (sensor.extended) return r;
    cigi::SensorResponse b;
    b.viewId = r.viewId;
    b.sensorId = r.sensorId;
    b.status = r.status;
    b.gateXSize = r.gateXSize;
    b.gateYSize = r.gateYSize;
    b.gateXDeg = r.gateXDeg;
    b.gateYDeg = r.gateYDeg;
    b.frameCounter = r.frameCounter;
    return b;
}

void CigiSession::apply(const cigi::Packet& packet, double t, std::uint8_t& lsn) {
    const bool operating = igMode_ != cigi::IgMode::Reset;
    if (const auto* ig = std::get_if<cigi::IgControl>(&packet)) {
        ++stats_.igControls;
        stats_.hostSeen = true;
        stats_.lastHostFrame = ig->hostFrameNumber;
        stats_.lastHostTimestamp = ig->timestamp;
        lsn = static_cast<std::uint8_t>(ig->hostFrameNumber & 15u);
        if (ig->igMode == cigi::IgMode::Reset) {
            if (igMode_ != cigi::IgMode::Reset) ++stats_.resets;
            // Reset: the ownship goes back to its start pose, still; requests are forgotten.
            ownship_ = DeadReckoning{};
            ownship_.time = t;
            ownship_.pose = options_.startPose;
            ownship_.holdAfter = t + options_.extrapolateLimit;
            view_ = {};
            viewControl_ = {};
            viewEntity_ = 0;
            rates_ = {};
            pending_.clear();
            repeating_.clear();
            inFlight_.clear();  // their answers, when they come, are dropped
            stats_.entitiesDestroyed += entities_.size();
            entities_.clear();
            sensors_.clear();
        }
        igMode_ = ig->igMode;
    } else if (const auto* e = std::get_if<cigi::EntityControl>(&packet)) {
        if (operating && e->entityId != 0) {
            applyEntity(*e, t);
            return;
        }
        if (!operating || e->attached) {
            ++stats_.ignoredPackets;
            return;
        }
        ++stats_.entityUpdates;
        ownship_.time = t;
        ownship_.pose.position = geo_.worldFromGeodetic(e->latOrX, e->lonOrY, e->altOrZ);
        ownship_.pose.yaw = e->yawDeg * kDeg;
        ownship_.pose.pitch = e->pitchDeg * kDeg;
        ownship_.pose.roll = e->rollDeg * kDeg;
        // Rates given in the entity's own axes turn with it.
        if (rates_.localCoordinates) setRates(t);
    } else if (const auto* r = std::get_if<cigi::RateControl>(&packet)) {
        if (operating && r->entityId != 0 && !r->applyToPart) {
            applyEntityRates(*r, t);
            return;
        }
        if (!operating || r->entityId != 0 || r->applyToPart) {
            ++stats_.ignoredPackets;
            return;
        }
        ++stats_.rateUpdates;
        rates_ = *r;
        setRates(t);
    } else if (std::holds_alternative<cigi::HatHotRequest>(packet) ||
               std::holds_alternative<cigi::LosSegmentRequest>(packet) ||
               std::holds_alternative<cigi::LosVectorRequest>(packet)) {
        if (std::holds_alternative<cigi::HatHotRequest>(packet)) {
            ++stats_.hatHotRequests;
        } else {
            ++stats_.losRequests;
        }
        if (!operating) {
            ++stats_.ignoredPackets;
            return;
        }
        // A request with an update period is answered every that many fields until a request
        // of the same kind and id replaces it (period 0: once, and the repeating one ends).
        const auto [id, period] = std::visit(
            [](const auto& q) -> std::pair<std::uint16_t, std::uint8_t> {
                if constexpr (requires { q.updatePeriod; }) {
                    return {q.requestId, q.updatePeriod};
                } else {
                    return {0, 0};
                }
            },
            packet);
        std::erase_if(repeating_, [&, id = id](const Repeating& old) {
            return old.request.index() == packet.index() && old.requestId == id;
        });
        if (period > 0) {
            if (repeating_.size() >= kMaxRepeating) {
                ++stats_.droppedRequests;
            } else {
                repeating_.push_back({packet, id, period, igFrame_});
            }
        } else if (pending_.size() >= options_.maxPendingRequests) {
            ++stats_.droppedRequests;
        } else {
            pending_.push_back({packet, lsn});
        }
    } else if (const auto* vc = std::get_if<cigi::ViewControl>(&packet)) {
        if (!operating || vc->viewId != options_.viewId) {
            ++stats_.ignoredPackets;  // another image generator's view
            return;
        }
        if (vc->entityId != 0 && findEntity(vc->entityId) == nullptr) {
            // An entity the host has not created: the view stays where it was.
            ++stats_.ignoredPackets;
            noteError("View Control for view " + std::to_string(vc->viewId) + " names entity " +
                      std::to_string(vc->entityId) + ", which the host has not created");
            return;
        }
        ++stats_.viewControls;
        viewEntity_ = vc->entityId;
        // Only the enabled fields change; the others keep their last value.
        cigi::ViewControl& v = viewControl_;
        if (vc->xEnable) v.x = vc->x;
        if (vc->yEnable) v.y = vc->y;
        if (vc->zEnable) v.z = vc->z;
        if (vc->yawEnable) v.yawDeg = vc->yawDeg;
        if (vc->pitchEnable) v.pitchDeg = vc->pitchDeg;
        if (vc->rollEnable) v.rollDeg = vc->rollDeg;
        view_.offset = {v.x, v.y, v.z};
        // Yaw travels in [0, 360]: turned to (-180, 180] so a small left turn stays small.
        const double yaw = v.yawDeg > 180.0f ? v.yawDeg - 360.0 : v.yawDeg;
        view_.yaw = yaw * kDeg;
        view_.pitch = v.pitchDeg * kDeg;
        view_.roll = v.rollDeg * kDeg;
    } else if (const auto* sc = std::get_if<cigi::SensorControl>(&packet)) {
        if (!operating) {
            ++stats_.ignoredPackets;
            return;
        }
        applySensor(*sc);
    } else if (const auto* cc = std::get_if<cigi::ComponentControl>(&packet)) {
        if (!operating) {
            ++stats_.ignoredPackets;
            return;
        }
        applyComponent(*cc);
    } else if (const auto* vd = std::get_if<cigi::ViewDefinition>(&packet)) {
        if (vd->viewId != options_.viewId) {
            ++stats_.ignoredPackets;
            return;
        }
        const auto refuse = [&](const std::string& why) {
            ++stats_.viewDefinitionsNotApplied;
            noteError("View Definition for view " + std::to_string(vd->viewId) + ": " + why);
        };
        // Both parts are checked before either is taken: a refused definition changes nothing.
        const bool symmetric = vd->leftEnable && vd->rightEnable;
        const double hfov = symmetric ? (vd->rightDeg - vd->leftDeg) * kDeg : 0.0;
        if (vd->farEnable) {
            // The far plane is the draw distance (what lies beyond is sky).
            if (!(vd->farM > 0.0f) || !std::isfinite(vd->farM) ||
                (vd->nearEnable && !(vd->farM > vd->nearM))) {
                refuse("far plane " + base::number(vd->farM) +
                       " m: must be positive and beyond the near plane");
                return;
            }
        }
        if (vd->nearEnable) {
            // The near plane: nothing nearer is drawn (0: none). It must stay short of the
            // far plane this definition leaves in force.
            const double far = vd->farEnable ? static_cast<double>(vd->farM) : viewFar_;
            if (!(vd->nearM >= 0.0f) || !std::isfinite(vd->nearM) || !(vd->nearM < far)) {
                refuse("near plane " + base::number(vd->nearM) +
                       " m: must be 0 or more and short of the far plane (" + base::number(far) +
                       " m)");
                return;
            }
        }
        if (symmetric && (std::abs(vd->rightDeg + vd->leftDeg) > 0.01f || !(hfov > 0.0) ||
                          !(hfov < kMaxFieldOfView))) {
            refuse("left " + base::number(vd->leftDeg) + ", right " + base::number(vd->rightDeg) +
                   " degrees: only a frustum symmetric about the view axis, narrower than " +
                   base::number(kMaxFieldOfView / kDeg) + " degrees, is rendered");
            return;
        }
        bool taken = false;
        if (vd->farEnable) {
            viewFar_ = vd->farM;
            // During the run: the renders asked from this field on draw to the new distance.
            if (farFrozen_ && viewFar_ != fieldFar_) {
                fieldFar_ = viewFar_;
                ++stats_.farPlaneChanges;
            }
            taken = true;
        }
        if (vd->nearEnable) {
            viewNear_ = vd->nearM;
            // During the run: the renders asked from this field on clip at the new plane.
            if (nearFrozen_ && viewNear_ != fieldNear_) {
                fieldNear_ = viewNear_;
                ++stats_.nearPlaneChanges;
            }
            taken = true;
        }
        if (symmetric) {
            viewHfov_ = hfov;
            // During the run: this field and every later one at the new field of view (the PRP
            // scales the frames rendered at the old one until the renderer's catch up).
            if (fieldHfov_ > 0.0 && std::abs(hfov - fieldHfov_) > kSameFieldOfView) {
                fieldHfov_ = hfov;
                ++stats_.fieldOfViewChanges;
            }
            taken = true;
        }
        if (taken) {
            ++stats_.viewDefinitions;
        } else {
            ++stats_.ignoredPackets;  // nothing this image generator takes
        }
    } else {
        ++stats_.ignoredPackets;
    }
}

CigiSession::Query CigiSession::resolve(const cigi::Packet& request, std::uint8_t lsn,
                                        double t) const {
    Query q;
    q.request = request;
    q.lsn = lsn;
    // A point of a request: geodetic, or an offset from an entity (the ownship or one of the
    // host's active entities, at t) in its own axes.
    const ig::Pose ownship = ownship_.at(t);
    const auto point = [&](bool entity, std::uint16_t entityId, double a, double b, double c,
                           bool& ok) {
        if (!entity) return geo_.worldFromGeodetic(a, b, c);
        ig::Pose from = ownship;
        bool drawn = true;
        if (entityId != 0 &&
            (!entityPoseAt(entities_, ownship_, entityId, t, ground_, from, &drawn) || !drawn)) {
            ok = false;  // no such entity, or not active
            return glm::dvec3{0.0};
        }
        return from.position + worldFromBody(from, {a, b, c});
    };
    if (const auto* h = std::get_if<cigi::HatHotRequest>(&request)) {
        bool known = true;
        q.point = point(h->entityCoordinates, h->entityId, h->latOrX, h->lonOrY, h->altOrZ, known);
        q.known = known && ground_.covers(q.point.x, q.point.y);
        q.question.origin = q.point;
        return q;
    }
    // Line of sight: a ray from the source, its first hit within the range on the bilinear
    // surface (the reference model of ig::intersectTerrain) or on an object (objectOnLine).
    std::uint16_t fromEntity = 0;  // a line from a host entity does not meet that entity
    glm::dvec3 source{0.0}, dir{0.0};
    double minRange = 0.0, maxRange = 0.0;
    if (const auto* s = std::get_if<cigi::LosSegmentRequest>(&request)) {
        q.requestId = s->requestId;
        q.extended = s->extended;
        q.segment = true;
        bool known = true;
        if (s->sourceEntityCoordinates) fromEntity = s->entityId;
        source = point(s->sourceEntityCoordinates, s->entityId, s->sourceLatOrX, s->sourceLonOrY,
                       s->sourceAltOrZ, known);
        // The destination's entity is the request's unless it names one of its own.
        dir = point(s->destinationEntityCoordinates,
                    s->destinationEntityIdValid ? s->destinationEntityId : s->entityId,
                    s->destinationLatOrX, s->destinationLonOrY, s->destinationAltOrZ, known) -
              source;
        maxRange = std::sqrt(dir.x * dir.x + dir.y * dir.y + dir.z * dir.z);
        q.known = known && maxRange > 0.0 && std::isfinite(maxRange);
    } else if (const auto* v = std::get_if<cigi::LosVectorRequest>(&request)) {
        q.requestId = v->requestId;
        q.extended = v->extended;
        bool known = true;
        if (v->sourceEntityCoordinates) fromEntity = v->entityId;
        source = point(v->sourceEntityCoordinates, v->entityId, v->sourceLatOrX, v->sourceLonOrY,
                       v->sourceAltOrZ, known);
        const double az = v->azimuthDeg * kDeg, el = v->elevationDeg * kDeg;
        dir = {std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el)};
        minRange = v->minRangeM;
        maxRange = v->maxRangeM;
        q.known = known && maxRange > 0.0 && std::isfinite(maxRange);
    } else {
        CHECK(false) << "not a request: " << cigi::packetName(request);
    }
    q.question.line = true;
    q.question.origin = source;
    q.question.dir = dir;
    q.question.minRange = minRange;
    q.question.maxRange = maxRange;
    if (q.known) {
        // The nearest object within the whole range: compose() keeps it if the terrain's hit
        // is not nearer (the same as looking for one short of the terrain's hit).
        const ig::TerrainRay ray(map_, source, dir);
        double nearest = maxRange;
        if (objectOnLine(ray.origin, ray.dir, minRange, t, fromEntity, nearest, q.objectId,
                         q.objectColor, q.objectNormal)) {
            q.objectRange = nearest;
        }
    }
    return q;
}

cigi::Packet CigiSession::compose(const Query& q, const TerrainAnswer& terrain) const {
    if (const auto* h = std::get_if<cigi::HatHotRequest>(&q.request)) {
        const glm::dvec3& p = q.point;
        const bool valid = q.known && terrain.known;
        const double hot = valid ? terrain.height + options_.origin.altM : 0.0;
        const double hat = valid ? (p.z + options_.origin.altM) - hot : 0.0;
        if (h->type == cigi::HatHotType::Extended) {
            cigi::HatHotExtendedResponse a;
            a.requestId = h->requestId;
            a.valid = valid;
            a.hostFrameLsn = q.lsn;
            if (valid) {
                a.hatM = hat;
                a.hotM = hot;
                normalAngles(terrain.slope, a.normalAzimuthDeg, a.normalElevationDeg);
            }
            return a;
        }
        cigi::HatHotResponse a;
        a.requestId = h->requestId;
        a.valid = valid;
        a.isHot = h->type == cigi::HatHotType::Hot;
        a.hostFrameLsn = q.lsn;
        a.heightM = a.isHot ? hot : hat;
        return a;
    }
    // Line of sight: the terrain's hit, or the object's where that is nearer.
    bool valid = q.known && terrain.known;
    double range = -1.0;
    std::uint16_t objectId = 0;  // the object met first; 0: the terrain
    if (valid) {
        range = terrain.range;
        if (q.objectId != 0 && (range < 0.0 || q.objectRange < range)) {
            range = q.objectRange;
            objectId = q.objectId;
        }
        valid = range >= 0.0 && std::isfinite(range);
    }
    if (!q.extended) {
        cigi::LosResponse a;
        a.requestId = q.requestId;
        a.valid = valid;
        // The destination is seen when nothing is in the way (and the terrain is known).
        a.visible = q.segment && !valid && terrain.known;
        a.hostFrameLsn = q.lsn;
        a.responseCount = 1;
        a.rangeM = valid ? range : 0.0;
        a.entityIdValid = objectId != 0;
        a.entityId = objectId;
        return a;
    }
    cigi::LosExtendedResponse a;
    a.requestId = q.requestId;
    a.valid = valid;
    a.rangeValid = valid;
    a.visible = q.segment && !valid && terrain.known;
    a.hostFrameLsn = q.lsn;
    a.responseCount = 1;
    a.entityIdValid = objectId != 0;
    a.entityId = objectId;
    if (valid) {
        const ig::TerrainRay ray(map_, q.question.origin, q.question.dir);
        const glm::dvec3 hit = ray.at(range);
        const glm::dvec3 geo = geo_.geodeticFromWorld(hit);
        a.rangeM = range;
        a.latOrX = geo.x;
        a.lonOrY = geo.y;
        a.altOrZ = geo.z;
        if (objectId != 0) {
            // The voxel's own colour and opacity, and its face's normal.
            a.red = q.objectColor.r;
            a.green = q.objectColor.g;
            a.blue = q.objectColor.b;
            a.alpha = q.objectColor.a;
            const glm::dvec3& n = q.objectNormal;
            a.normalAzimuthDeg =
                static_cast<float>(std::fmod(std::atan2(n.x, n.y) / kDeg + 360.0, 360.0));
            a.normalElevationDeg = static_cast<float>(std::asin(std::clamp(n.z, -1.0, 1.0)) / kDeg);
        } else {
            const float* rgb = terrain.color;
            a.red = static_cast<std::uint8_t>(std::lround(std::clamp(rgb[0], 0.0f, 255.0f)));
            a.green = static_cast<std::uint8_t>(std::lround(std::clamp(rgb[1], 0.0f, 255.0f)));
            a.blue = static_cast<std::uint8_t>(std::lround(std::clamp(rgb[2], 0.0f, 255.0f)));
            a.alpha = 255;
            normalAngles(terrain.slope, a.normalAzimuthDeg, a.normalElevationDeg);
        }
    }
    return a;
}

cigi::Packet CigiSession::answer(const cigi::Packet& request, std::uint8_t lsn, double t) const {
    const Query q = resolve(request, lsn, t);
    if (!q.known) return compose(q, TerrainAnswer{});
    return compose(q, options_.surface ? askTerrain(*options_.surface, q.question)
                                       : askTerrain(map_, q.question));
}

bool CigiSession::defer(Query&& q) {
    if (inFlight_.size() >= inFlight_.capacity()) return false;
    q.question.ticket = nextTicket_;
    q.askedFrame = igFrame_;
    if (!options_.terrainQueries->ask(q.question)) return false;
    ++nextTicket_;
    inFlight_.push_back(std::move(q));
    return true;
}

void CigiSession::sendReady() {
    ready_.clear();
    options_.terrainQueries->collect(
        ready_, static_cast<std::size_t>(std::max(options_.maxAnswersPerField, 1)));
    std::size_t next = 0;  // in inFlight_, in the order asked (answers come in that order)
    for (const TerrainAnswer& a : ready_) {
        while (next < inFlight_.size() && inFlight_[next].question.ticket < a.ticket)
            ++next;  // dropped meanwhile (a reset cleared it): never here
        if (next == inFlight_.size() || inFlight_[next].question.ticket != a.ticket) continue;
        Query& q = inFlight_[next++];
        stats_.maxAnswerFields =
            std::max<std::uint64_t>(stats_.maxAnswerFields, igFrame_ - q.askedFrame);
        if (!a.known) ++stats_.unknownTerrain;
        if (q.sensor >= 0) {
            // A sensor's check: clear when nothing is hit short of the target.
            if (SensorState* sensor = findSensor(static_cast<std::uint8_t>(q.sensor))) {
                sensor->clearAsked = false;
                sensor->clearKnown = a.known;
                sensor->clear = a.known && a.range < 0.0;
            }
            q.question.ticket = 0;
            continue;
        }
        cigi::encodePacket(compose(q, a), cigi::ByteOrder::Big, out_);
        ++stats_.answers;
        ++stats_.deferredAnswers;
        q.question.ticket = 0;  // done
    }
    std::erase_if(inFlight_, [](const Query& q) { return q.question.ticket == 0; });
}

bool CigiSession::objectOnLine(const glm::dvec3& origin, const glm::dvec3& dir, double tMin,
                               double t, std::uint16_t skip, double& range, std::uint16_t& id,
                               ig::Rgba8& color, glm::dvec3& normal) const {
    if (!options_.objects) return false;
    const TruthScene& scene = *options_.objects;
    bool met = false;
    // Each object by its exact model (voxels as boxes, as the truth and the reference caster
    // see them).
    const auto meet = [&](const TruthObject& o) {
        ig::Rgba8 c{};
        glm::dvec3 n{0.0};
        const double e = rayEntersObject(o, origin, dir, tMin, &c, &n);
        if (e >= 0.0 && e < range) {
            range = e;
            id = o.id;
            color = c;
            normal = n;
            met = true;
        }
    };
    // The static world through its object grid (tens of thousands of objects): the first one
    // drawn along the line, then its exact model (a line that grazes a resampled edge may meet
    // the grid and miss the model: then nothing).
    if (const ig::ObjectLayer* layer = scene.scene().staticLayer.get()) {
        const ig::ObjectLayer* const layers[] = {layer};
        ig::ObjectShading shading;
        ig::traceObjects(layers, origin, dir, range, ig::SkyModel{}, losTrace_, shading, tMin);
        if (shading.id != 0) {
            for (const TruthObject& o : scene.staticObjects()) {
                if (o.id == shading.id) meet(o);
            }
        }
    }
    // The scene's moving objects at t, and the host's entities drawn as its models.
    scene.movingAt(t, losObjects_, losWhere_);
    for (const TruthObject& o : losObjects_)
        meet(o);
    objectsAt(t, losEntities_);
    for (const ExtraObject& e : losEntities_)
        if (e.placement.id != skip || skip == 0) meet(scene.placedExtra(e));
    return met;
}

namespace {

ExtraObject entityObject(const EntityPose& e) {
    ExtraObject o;
    o.model = e.model;
    o.placement.id = e.id;
    o.placement.x = e.pose.position.x;
    o.placement.y = e.pose.position.y;
    o.placement.z = e.pose.position.z;
    o.placement.heading = e.pose.yaw;
    o.placement.scale = e.scale;
    o.onGround = e.onGround;
    return o;
}

}  // namespace

void CigiSession::objectsAt(double t, std::vector<ExtraObject>& out) const {
    entityPosesAt(entities_, ownship_, t, entityScratch_);
    out.clear();
    for (const EntityPose& e : entityScratch_)
        out.push_back(entityObject(e));
}

void CigiSession::poll(double t) {
    const std::int64_t pollStart = io::monotonicNs();
    std::uint8_t lsn = static_cast<std::uint8_t>(stats_.lastHostFrame & 15u);
    int taken = 0;
    for (; taken < options_.maxDatagramsPerField && socket_.isOpen(); ++taken) {
        const long n = socket_.receive(in_);
        if (n == -EAGAIN) break;
        if (n < 0) {
            ++stats_.receiveErrors;
            noteError(std::string("receiving: ") + std::strerror(static_cast<int>(-n)));
            break;
        }
        ++stats_.datagrams;
        if (static_cast<std::size_t>(n) > in_.size()) {
            ++stats_.badDatagrams;
            noteError("a datagram of " + std::to_string(n) +
                      " bytes is longer than any CIGI "
                      "message this image generator takes");
            continue;
        }
        // The codec words its refusal only while there is room to report it.
        std::string error;
        const bool report = stats_.firstErrors.size() < CigiStats::kReportedErrors;
        const bool ok = cigi::decodeMessage(
            std::span<const std::uint8_t>(in_.data(), static_cast<std::size_t>(n)),
            cigi::Sender::Host, message_, report ? &error : nullptr);
        stats_.skippedPackets += message_.skippedPackets;
        if (!ok) {
            // The whole datagram is refused: a host message is applied entirely or not at all.
            ++stats_.badDatagrams;
            if (report) noteError(error);
            continue;
        }
        heard(t);
        for (const cigi::Packet& packet : message_.packets)
            apply(packet, t, lsn);
    }
    if (taken == options_.maxDatagramsPerField) ++stats_.cappedPolls;
    stats_.maxPollDatagrams = std::max(stats_.maxPollDatagrams, static_cast<std::uint64_t>(taken));
    stats_.droppedByKernel = socket_.droppedByKernel();
    watch(t);

    // Start of Frame, then the answers of up to maxAnswersPerField requests.
    out_.clear();
    cigi::StartOfFrame sof;
    sof.igMode = igMode_;
    sof.igFrameNumber = igFrame_;
    sof.timestampValid = true;
    const double ticks = std::max(0.0, (t - options_.startTime) * 1e5);
    sof.timestamp = static_cast<std::uint32_t>(
        static_cast<std::uint64_t>(std::llround(std::min(ticks, 1e18))) & 0xffffffffu);
    sof.lastHostFrameNumber = stats_.lastHostFrame;
    cigi::encodePacket(sof, cigi::ByteOrder::Big, out_);
    const std::size_t perField = static_cast<std::size_t>(std::max(options_.maxAnswersPerField, 0));
    const std::uint8_t lastLsn = static_cast<std::uint8_t>(stats_.lastHostFrame & 15u);
    if (!options_.terrainQueries) {
        const std::size_t answered = std::min(pending_.size(), perField);
        for (std::size_t i = 0; i < answered; ++i) {
            cigi::encodePacket(answer(pending_[i].request, pending_[i].hostFrameLsn, t),
                               cigi::ByteOrder::Big, out_);
        }
        pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(answered));
        stats_.answers += answered;
        for (const Repeating& r : repeating_) {
            if ((igFrame_ - r.firstFrame) % r.period != 0) continue;
            cigi::encodePacket(answer(r.request, lastLsn, t), cigi::ByteOrder::Big, out_);
            ++stats_.answers;
        }
    } else {
        // Over a paged map: the answers the terrain's thread has ready go out now; the new
        // requests are worked out at this field's time and handed to it (those that need no
        // terrain, being invalid, are answered at once).
        sendReady();
        const auto hand = [&](const cigi::Packet& request, std::uint8_t requestLsn) {
            Query q = resolve(request, requestLsn, t);
            if (!q.known) {
                cigi::encodePacket(compose(q, TerrainAnswer{}), cigi::ByteOrder::Big, out_);
                ++stats_.answers;
                return true;
            }
            return defer(std::move(q));
        };
        std::size_t handed = 0;
        while (handed < std::min(pending_.size(), perField) &&
               hand(pending_[handed].request, pending_[handed].hostFrameLsn)) {
            ++handed;
        }
        pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(handed));
        for (const Repeating& r : repeating_) {
            if ((igFrame_ - r.firstFrame) % r.period != 0) continue;
            if (!hand(r.request, lastLsn)) ++stats_.droppedRequests;
        }
    }
    // Each sensor that is on answers every field.
    for (SensorState& sensor : sensors_) {
        if (!sensor.on || igMode_ == cigi::IgMode::Reset) continue;
        cigi::encodePacket(sensorResponse(sensor, t), cigi::ByteOrder::Big, out_);
        ++stats_.sensorResponses;
    }
    ++igFrame_;
    stats_.maxPollMs = std::max(stats_.maxPollMs, (io::monotonicNs() - pollStart) * 1e-6);
    if (socket_.isOpen()) {
        const int rc = socket_.sendTo(out_, options_.host);
        if (rc == 0) {
            ++stats_.framesSent;
        } else {
            ++stats_.sendErrors;
            if (stats_.sendErrors == 1) {
                noteError("sending Start of Frame to " + io::toString(options_.host) + ": " +
                          std::strerror(-rc));
            }
        }
    }
}

EntityTypeModel parseEntityTypeModel(std::string_view text, std::string_view flag,
                                     const std::vector<std::string>& modelNames) {
    const auto bad = [&](const std::string& why) {
        throw base::InputError(std::string(flag) + " " + base::quoted(text) + ": " + why);
    };
    const std::size_t eq = text.find('=');
    if (eq == std::string_view::npos) bad("expected TYPE=MODEL[:SCALE]");
    EntityTypeModel m;
    double type = 0.0;
    if (!parseDouble(text.substr(0, eq), type) || type != std::floor(type) || type < 0.0 ||
        type > 65535.0) {
        bad("the entity type must be an integer 0..65535");
    }
    m.type = static_cast<std::uint16_t>(type);
    std::string_view model = text.substr(eq + 1);
    const std::size_t colon = model.find(':');
    if (colon != std::string_view::npos) {
        if (!parseDouble(model.substr(colon + 1), m.scale) || !(m.scale > 0.0) || m.scale > 1e4) {
            bad("the scale must be a number in (0, 10000]");
        }
        model = model.substr(0, colon);
    }
    const auto it = std::find(modelNames.begin(), modelNames.end(), model);
    if (it == modelNames.end()) {
        std::string known;
        for (const std::string& n : modelNames)
            known += (known.empty() ? "" : ", ") + n;
        bad("the scene has no model " + base::quoted(model) +
            " (it has: " + (known.empty() ? "none" : known) + ")");
    }
    m.model = static_cast<int>(it - modelNames.begin());
    return m;
}

namespace {

const HostEntity* entityById(const std::vector<HostEntity>& entities, std::uint16_t id) {
    for (const HostEntity& e : entities) {
        if (e.id == id) return &e;
    }
    return nullptr;
}

// World pose of `e` at t by walking up its chain of parents (the session refuses loops; the walk
// is bounded all the same); whether it and all its parents are active (false as well when the
// chain is broken: `pose` is then not set).
bool worldPose(const std::vector<HostEntity>& entities, const DeadReckoning& ownship,
               const HostEntity& e, double t, ig::Pose& pose, bool& drawn) {
    // The chain, child to top (at most the entity count: the session refuses loops).
    const HostEntity* chain[kMaxChain];
    std::size_t n = 0;
    const HostEntity* at = &e;
    drawn = true;
    while (true) {
        if (n == kMaxChain) return false;
        chain[n++] = at;
        drawn = drawn && at->active;
        if (!at->attached || at->parent == 0) break;
        at = entityById(entities, at->parent);
        if (!at) return false;
    }
    const HostEntity& top = *chain[n - 1];
    pose = top.attached ? ownship.at(t) : top.motion.at(t);
    for (std::size_t k = n; k-- > 0;) {
        if (!chain[k]->attached) continue;
        const ig::Pose o = chain[k]->motion.at(t);
        pose = eyePose(pose, ViewOffset{o.position, o.yaw, o.pitch, o.roll});
    }
    return true;
}

}  // namespace

ig::Pose CigiSession::viewCarrier(double t) const {
    ig::Pose pose;
    if (viewEntity_ != 0 && entityPoseAt(entities_, ownship_, viewEntity_, t, ground_, pose))
        return pose;
    return ownship_.at(t);
}

bool entityPoseAt(const std::vector<HostEntity>& entities, const DeadReckoning& ownship,
                  std::uint16_t id, double t, const ig::Ground& ground, ig::Pose& out,
                  bool* drawn) {
    const HostEntity* e = entityById(entities, id);
    bool active = false;
    if (!e || !worldPose(entities, ownship, *e, t, out, active)) return false;
    if (drawn) *drawn = active;
    if (e->onGround && ground.covers(out.position.x, out.position.y))
        out.position.z = ground.groundHeight(out.position.x, out.position.y);
    return true;
}

void entityPosesAt(const std::vector<HostEntity>& entities, const DeadReckoning& ownship, double t,
                   std::vector<EntityPose>& out) {
    out.clear();
    const auto world = [&](const HostEntity& e, ig::Pose& pose) {
        bool drawn = false;
        return worldPose(entities, ownship, e, t, pose, drawn) && drawn;
    };
    for (const HostEntity& e : entities) {
        ig::Pose pose;
        if (!e.active || !world(e, pose)) continue;
        out.push_back({e.id, e.model, e.scale, e.onGround, pose});
    }
}

nlohmann::json toJson(const CigiStats& c) {
    nlohmann::json outages = nlohmann::json::array();
    for (const HostOutage& o : c.outages) {
        outages.push_back({{"last_message_s", o.lastMessage},
                           {"noticed_s", o.noticed},
                           {"length_s", o.length},
                           {"ongoing", o.ongoing},
                           {"fields_extrapolated", o.fieldsExtrapolated},
                           {"fields_held", o.fieldsHeld}});
    }
    return {{"datagrams", c.datagrams},
            {"bad_datagrams", c.badDatagrams},
            {"dropped_by_kernel", c.droppedByKernel},
            {"sensor_controls", c.sensorControls},
            {"sensor_targets", c.sensorTargets},
            {"sensor_targets_refused", c.sensorTargetsRefused},
            {"sensor_responses", c.sensorResponses},
            {"capped_polls", c.cappedPolls},
            {"max_poll_datagrams", c.maxPollDatagrams},
            {"max_poll_ms", c.maxPollMs},
            {"receive_buffer_bytes", c.receiveBufferBytes},
            {"skipped_packets", c.skippedPackets},
            {"ignored_packets", c.ignoredPackets},
            {"entity_updates", c.entityUpdates},
            {"entity_controls", c.entityControls},
            {"entities_refused", c.entitiesRefused},
            {"entities_created", c.entitiesCreated},
            {"entities_destroyed", c.entitiesDestroyed},
            {"rate_updates", c.rateUpdates},
            {"answers", c.answers},
            {"deferred_answers", c.deferredAnswers},
            {"max_answer_fields", c.maxAnswerFields},
            {"unknown_terrain_answers", c.unknownTerrain},
            {"dropped_requests", c.droppedRequests},
            {"start_of_frame_sent", c.framesSent},
            {"send_errors", c.sendErrors},
            {"last_host_frame", c.lastHostFrame},
            {"clamped_poses", c.clampedPoses},
            {"view_definitions", c.viewDefinitions},
            {"view_definitions_not_applied", c.viewDefinitionsNotApplied},
            {"field_of_view_changes", c.fieldOfViewChanges},
            {"far_plane_changes", c.farPlaneChanges},
            {"near_plane_changes", c.nearPlaneChanges},
            {"host_losses", c.hostLosses},
            {"host_outages", outages},
            {"first_errors", c.firstErrors}};
}

CigiPoseSource::CigiPoseSource(const ig::TerrainMap& map, const CigiOptions& options,
                               double clearance)
    : map_(map), session_(map, options), startTime_(options.startTime), clearance_(clearance) {
    latest_.back() = {session_.ownship(), session_.view()};
    latest_.publish();
    entities_.back() = {session_.ownship(), session_.entities()};
    entities_.publish();
}

ig::Pose CigiPoseSource::clamped(ig::Pose pose, bool count) {
    // The renderer refuses a camera on or under the surface; a host that flies into the ground
    // (or sends a position off the database) gets the ownship held just above it.
    const double floor =
        session_.ground().groundHeight(pose.position.x, pose.position.y) + clearance_;
    if (!(pose.position.z >= floor)) {
        pose.position.z = floor;
        if (count) ++session_.stats().clampedPoses;
    }
    return pose;
}

ig::Pose CigiPoseSource::advanceTo(double t) {
    session_.poll(t);
    latest_.back() = {session_.ownship(), session_.view(), session_.viewEntity()};
    latest_.publish();
    EntitySnapshot& snapshot = entities_.back();
    snapshot.ownship = session_.ownship();
    snapshot.entities = session_.entities();  // allocates only when the host adds entities
    entities_.publish();
    const ig::Pose eye = clamped(eyePose(session_.viewCarrier(t), session_.view()), true);
    session_.ground().follow(eye.position.x, eye.position.y);
    return eye;
}

bool CigiPoseSource::waitForHost(double seconds) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (true) {
        advanceTo(startTime_);
        if (session_.stats().entityUpdates > 0) return true;
        if (std::chrono::steady_clock::now() >= until) return false;
        std::this_thread::sleep_for(std::chrono::microseconds(16683));
    }
}

RenderView CigiPoseSource::view() const {
    return {session_.fieldHfov(), session_.fieldFar(), session_.fieldNear()};
}

ig::Pose CigiPoseSource::predict(double t) {
    latest_.fetch();
    const EyeState& s = latest_.front();
    ig::Pose carrier = s.ownship.at(t);
    if (s.entity != 0) {
        // A view on another entity: that entity from the latest state the field loop published
        // (the same mailbox entitiesAt() reads, on this same thread).
        entities_.fetch();
        const EntitySnapshot& e = entities_.front();
        ig::Pose pose;
        if (entityPoseAt(e.entities, e.ownship, s.entity, t, session_.ground(), pose))
            carrier = pose;
    }
    return clamped(eyePose(carrier, s.view), false);
}

void CigiPoseSource::entitiesAt(double t, std::vector<EntityPose>& out) {
    entities_.fetch();
    const EntitySnapshot& s = entities_.front();
    entityPosesAt(s.entities, s.ownship, t, out);
}

void CigiPoseSource::objectsAt(double t, std::vector<ExtraObject>& out) {
    entitiesAt(t, poses_);
    out.clear();
    for (const EntityPose& e : poses_)
        out.push_back(entityObject(e));
}

}  // namespace sim
