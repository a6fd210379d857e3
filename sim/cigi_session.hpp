// The image generator's side of a CIGI 3.3 session: a host drives the ownship and asks about the
// terrain over UDP; each field drains the socket without waiting, dead-reckons the ownship to
// the field's instant and answers with Start of Frame (docs/design/cigi_session.md).
#pragma once

#include "ig/camera.hpp"
#include "ig/object_trace.hpp"
#include "ig/terrain.hpp"
#include "io/cigi.hpp"
#include "io/udp_socket.hpp"
#include "sim/mailbox.hpp"
#include "sim/pose_source.hpp"
#include "sim/scene_motion.hpp"
#include "sim/terrain_queries.hpp"
#include "sim/truth.hpp"

#include <glm/vec3.hpp>
#include <nlohmann/json_fwd.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

namespace sim {

// --- Database origin: geodetic <-> world

// The geodetic position of the world's origin (x = y = z = 0: the map's south-west sample at
// height 0). World x east, y north, z up, metres.
struct GeoOrigin {
    double latDeg = 0.0, lonDeg = 0.0, altM = 0.0;
};

// "LAT,LON[,ALT]" in degrees and metres; latitude within +-85 degrees, longitude within +-180.
// Throws base::InputError naming `flag` and what is wrong.
GeoOrigin parseGeoOrigin(std::string_view text, std::string_view flag);

// A local tangent plane about the origin (equirectangular on the WGS 84 ellipsoid): one degree
// of latitude is the meridian's radius of curvature at the origin's latitude times pi/180 metres,
// one degree of longitude the prime vertical's times cos(latitude) times pi/180. Exact and
// invertible (linear), accurate to the curvature of the earth: the error grows as the square
// of the distance from the origin (about 0.1 % of the distance at 100 km).
class GeoFrame {
  public:
    explicit GeoFrame(const GeoOrigin& origin);
    glm::dvec3 worldFromGeodetic(double latDeg, double lonDeg, double altM) const;
    // Latitude, longitude (wrapped to [-180, 180]) and altitude of a world point.
    glm::dvec3 geodeticFromWorld(const glm::dvec3& world) const;
    double metresPerDegreeLat() const { return perLat_; }
    double metresPerDegreeLon() const { return perLon_; }
    const GeoOrigin& origin() const { return origin_; }

  private:
    GeoOrigin origin_;
    double perLat_ = 0.0, perLon_ = 0.0;
};

// --- Ownship state

// The ownship as last told, and how it moves from there: pose(t) = pose + rates * (t - time),
// up to holdAfter (a silent host's ownship stops there and holds).
struct DeadReckoning {
    double time = 0.0;
    ig::Pose pose;
    glm::dvec3 velocity{0.0};                               // world, m/s
    double yawRate = 0.0, pitchRate = 0.0, rollRate = 0.0;  // rad/s of the pose's angles
    double holdAfter = std::numeric_limits<double>::infinity();
    ig::Pose at(double t) const;
};

// Where a view's eye is on its entity (View Control): an offset in the entity's axes (x
// forward, y right, z down, metres) and a rotation from them (yaw right, pitch up, roll right,
// radians, applied in that order).
struct ViewOffset {
    glm::dvec3 offset{0.0};
    double yaw = 0.0, pitch = 0.0, roll = 0.0;
    bool isIdentity() const {
        return offset == glm::dvec3(0.0) && yaw == 0.0 && pitch == 0.0 && roll == 0.0;
    }
};

// The eye of a view on an entity at `entity`: its position and yaw, pitch, roll in the product's
// convention (the entity's pose itself, untouched, when the offset is the identity).
ig::Pose eyePose(const ig::Pose& entity, const ViewOffset& view);

// The ownship and the view's eye on it (or on entity `entity`), as published to predict().
struct EyeState {
    DeadReckoning ownship;
    ViewOffset view;
    std::uint16_t entity = 0;  // the entity the view is on (View Control); 0: the ownship
};

// --- Entities other than the ownship

// How a CIGI entity type is drawn: a model of the scene file (its index in ig::Scene::models)
// at a scale (--cigi-entity TYPE=MODEL[:SCALE]).
struct EntityTypeModel {
    std::uint16_t type = 0;
    int model = 0;
    double scale = 1.0;
    // The model's grid in voxels (x across, y along its heading, z up; 0: unknown): a sensor's
    // gate is this box as the view sees it.
    int sizeX = 0, sizeY = 0, sizeZ = 0;
};

// "TYPE=MODEL[:SCALE]" against the scene's model names; throws base::InputError naming `flag`,
// the text and what is wrong (type out of 0..65535, unknown model, scale not positive).
EntityTypeModel parseEntityTypeModel(std::string_view text, std::string_view flag,
                                     const std::vector<std::string>& modelNames);

// One host-driven entity. Detached, `motion` is its world pose (x east, y north, z up) and how
// it moves; attached, `motion.pose` is its offset from the parent: position in the parent's
// axes (x forward, y right, z down), yaw right, pitch up, roll right from the parent's attitude,
// and `motion.velocity` the rates in those axes.
struct HostEntity {
    std::uint16_t id = 0, type = 0;
    int model = 0;
    double scale = 1.0;
    bool active = true;  // inactive entities keep their state but are not drawn
    bool attached = false;
    std::uint16_t parent = 0;  // when attached; 0 is the ownship
    bool onGround = false;     // ground clamp: the base sits on the terrain under it
    DeadReckoning motion;
    io::cigi::RateControl rates;  // the last Rate Control for it (persists)
};

// An entity's world pose at a frame's instant, as the renderer places it.
struct EntityPose {
    std::uint16_t id = 0;
    int model = 0;
    double scale = 1.0;
    bool onGround = false;
    ig::Pose pose;  // base point and attitude (the renderer draws upright models: heading only)
};

// World poses at t of the active entities, parents composed with children (an attached entity
// is its parent's pose followed by its offset, as eyePose composes a view on its entity).
// Inactive entities are left out, and so are the active children of inactive parents (they are
// still placed: only drawing is off). `out` is cleared first; it allocates only when it grows.
void entityPosesAt(const std::vector<HostEntity>& entities, const DeadReckoning& ownship, double t,
                   std::vector<EntityPose>& out);
// The world pose at t of entity `id` (its parents composed, active or not; a ground-clamped
// base on the ground under it, as the renderer stands it); false when there is no such
// entity or its chain is broken. `drawn`, when given: whether it and all its parents are active.
bool entityPoseAt(const std::vector<HostEntity>& entities, const DeadReckoning& ownship,
                  std::uint16_t id, double t, const ig::Ground& ground, ig::Pose& out,
                  bool* drawn = nullptr);

// --- Sensors

// A sensor of this view (Sensor Control) and the entity it tracks (Component Control, class
// Sensor, component 0: data word 1 is the entity id).
struct SensorState {
    std::uint8_t id = 0;
    bool on = false;
    io::cigi::SensorTrackMode trackMode = io::cigi::SensorTrackMode::Off;
    bool extended = false;
    bool hasTarget = false;
    std::uint16_t target = 0;
    // Over a paged map (CigiOptions::terrainQueries): whether the terrain was clear between the
    // eye and the target at the latest answer, whether there is one, and whether a question is
    // out.
    bool clear = false, clearKnown = false, clearAsked = false;
};

// Where an entity is in a view: the direction of its reference point from the view's axis
// (yaw right, pitch up, degrees) and whether the view sees it there (in front of the eye,
// inside the window, and no terrain between). The window is `width` x `height` pixels wide
// `hfov` radians.
struct SensorSight {
    bool inFront = false, inWindow = false, unoccluded = false;
    double gateXDeg = 0.0, gateYDeg = 0.0;
    double rangeM = 0.0;
    bool seen() const { return inFront && inWindow && unoccluded; }
};
// The window pixels [x0, x1] x [y0, y1] the box with these 8 corners covers (clipped to the
// window), or false when a corner is not in front of the eye.
bool gateBox(const ig::Pose& eye, const std::array<glm::dvec3, 8>& corners, int width, int height,
             double hfov, double box[4]);
SensorSight sightOf(const ig::TerrainMap& map, const ig::Pose& eye, const glm::dvec3& point,
                    int width, int height, double hfov);
// The same over a nested terrain's surface (ig/inset.hpp).
SensorSight sightOf(const ig::NestedMaps& maps, const ig::Pose& eye, const glm::dvec3& point,
                    int width, int height, double hfov);
// The same without the terrain (unoccluded left false).
SensorSight sightInWindow(const ig::Pose& eye, const glm::dvec3& point, int width, int height,
                          double hfov);

// --- Session

struct CigiOptions {
    io::UdpEndpoint bind;  // where host messages arrive
    io::UdpEndpoint host;  // where Start of Frame goes
    GeoOrigin origin;
    ig::Pose startPose;      // held until the first Entity Control for entity 0
    double startTime = 0.0;  // simulation time of the first field (Start of Frame timestamp 0)
    int viewId = 0;          // the view this image generator shows (View Control, Definition)
    // Each field drains the socket; this bounds one poll beyond what the kernel's receive
    // buffer can hold (about 2,000 small datagrams in 2 MiB), so it is never reached in
    // practice. Beyond it datagrams wait for the next field.
    int maxDatagramsPerField = 8192;
    // One-time HAT/HOT and LOS answers in one Start of Frame datagram (the rest wait); requests
    // with an update period (at most 64) are answered on top.
    int maxAnswersPerField = 64;
    std::size_t maxPendingRequests = 1024;  // beyond, requests are dropped and counted
    int receiveBufferBytes = 1 << 20;       // asked of the system (it may give less)
    // Watchdog (simulation seconds since the host's last good datagram): after hostTimeout the
    // host is reported lost; the ownship dead-reckons until extrapolateLimit, then holds.
    double hostTimeout = 0.5;
    double extrapolateLimit = 2.0;
    // Entities other than the ownship: their types' models (an Entity Control of another type
    // is refused and reported), at most maxEntities at a time, and ids they may not take (the
    // scene's own objects').
    std::vector<EntityTypeModel> entityTypes;
    std::size_t maxEntities = 256;
    std::vector<std::uint16_t> reservedIds;
    // The view's window in pixels (sensor gates are worked out in it).
    int windowWidth = 720, windowHeight = 486;
    // The scene's objects (not owned; null: none): a line of sight meets them, and the host's
    // entities drawn as its models, as well as the terrain.
    const TruthScene* objects = nullptr;
    // Over a database paged beyond memory (not owned; null: the map, whole): the ground the
    // ownship and the host's ground-clamped entities stand on, and the thread that answers
    // HAT/HOT requests, lines of sight and the sensors' terrain checks from the database's
    // own samples. With the thread, each answer goes out with the Start of Frame of the field
    // in which it is ready (a field or more after its request), in the order asked.
    const ig::Ground* ground = nullptr;
    PagedTerrainQueries* terrainQueries = nullptr;
    // Over insets held in memory (not owned; null: the map alone): the nested surface that
    // HAT/HOT requests, lines of sight and the sensors' terrain checks read (the ground, then,
    // a NestedGround over the same maps).
    const ig::NestedMaps* surface = nullptr;
};

// One silence of a host that had been heard: from its last good datagram to the next one (or
// to the end of the run). Simulation seconds.
struct HostOutage {
    double lastMessage = 0.0;  // the last good datagram before the silence
    double noticed = 0.0;      // when the watchdog declared the host lost
    double length = 0.0;       // last message to the next one (so far, while `ongoing`)
    bool ongoing = true;
    std::uint64_t fieldsExtrapolated = 0;  // fields of the silence dead-reckoned
    std::uint64_t fieldsHeld = 0;          // fields past the extrapolation limit
};

struct CigiStats {
    static constexpr std::size_t kReportedErrors = 4;
    static constexpr std::size_t kReportedOutages = 16;
    std::uint64_t datagrams = 0;         // received
    std::uint64_t droppedByKernel = 0;   // lost for want of receive-buffer room (flood)
    std::uint64_t cappedPolls = 0;       // fields that took maxDatagramsPerField (more waited)
    std::uint64_t maxPollDatagrams = 0;  // the most datagrams one field took
    double maxPollMs = 0.0;              // wall time of the longest poll
    int receiveBufferBytes = 0;          // granted by the system
    std::uint64_t badDatagrams = 0;      // refused by the codec, or cut (longer than 64 KiB)
    std::uint64_t skippedPackets = 0;    // of ids the codec does not know
    std::uint64_t ignoredPackets = 0;    // known but not acted on (other entities or views, Reset)
    std::uint64_t igControls = 0, entityUpdates = 0, rateUpdates = 0;
    std::uint64_t hatHotRequests = 0, losRequests = 0;
    // Over a paged map: answers sent that waited for the terrain's thread, the most fields one
    // waited, and those the thread could not answer (sent invalid).
    std::uint64_t deferredAnswers = 0, maxAnswerFields = 0, unknownTerrain = 0;
    std::uint64_t answers = 0, droppedRequests = 0;
    std::uint64_t framesSent = 0, sendErrors = 0, receiveErrors = 0;
    std::uint64_t clampedPoses = 0;  // fields whose pose was lifted above the terrain
    std::uint64_t resets = 0;
    std::uint64_t viewControls = 0, viewDefinitions = 0;  // for this view, applied
    std::uint64_t viewDefinitionsNotApplied = 0;          // asymmetric, out of range
    std::uint64_t fieldOfViewChanges = 0;  // View Definitions during the run that changed it
    std::uint64_t farPlaneChanges = 0;     // likewise the far plane
    std::uint64_t nearPlaneChanges = 0;    // likewise the near plane
    std::uint64_t entityControls = 0;      // for entities other than the ownship, applied
    std::uint64_t entitiesRefused = 0;     // unknown type or parent, a parent loop, a reserved id
    std::uint64_t entitiesCreated = 0, entitiesDestroyed = 0;
    std::uint64_t sensorControls = 0;        // for this view, applied
    std::uint64_t sensorTargets = 0;         // Component Controls naming a sensor's target
    std::uint64_t sensorTargetsRefused = 0;  // naming an unknown entity, or not a sensor's
    std::uint64_t sensorResponses = 0;       // sent
    bool hostSeen = false;
    std::uint32_t lastHostFrame = 0, lastHostTimestamp = 0;
    std::vector<std::string> firstErrors;  // the first kReportedErrors problems, as messages
    std::uint64_t hostLosses = 0;          // silences longer than hostTimeout
    std::vector<HostOutage> outages;       // the first kReportedOutages of them
};

// `{"datagrams": n, "bad_datagrams": n, ..., "host_outages": [...]}` for --json.
nlohmann::json toJson(const CigiStats& stats);

// One host, one ownship. Everything happens in poll(), on the field thread, without waiting.
class CigiSession {
  public:
    // The map must outlive the session. Nothing is opened before open().
    CigiSession(const ig::TerrainMap& map, const CigiOptions& options);
    // Binds the socket: 0, or -errno with `*error` saying what failed.
    int open(std::string* error);
    io::UdpEndpoint localEndpoint() const { return socket_.localEndpoint(); }

    // The field at simulation time t: takes the datagrams waiting (at most
    // maxDatagramsPerField), applies them in order at t, answers pending requests and sends
    // Start of Frame. Never throws for what the network sends; never blocks.
    void poll(double t);

    const DeadReckoning& ownship() const { return ownship_; }
    const ViewOffset& view() const { return view_; }
    // The entity this view is on (View Control's entity; 0: the ownship).
    std::uint16_t viewEntity() const { return viewEntity_; }
    // That entity's pose at t, dead-reckoned (the ownship's when the view's entity is gone).
    ig::Pose viewCarrier(double t) const;
    // The host's entities other than the ownship, in order of creation.
    const std::vector<HostEntity>& entities() const { return entities_; }
    // The horizontal field of view (radians) of this view's last View Definition that gave
    // both left and right, or 0 when none did.
    double viewHfov() const { return viewHfov_; }
    // The run starts with field of view `hfov`: from now on a View Definition with another
    // changes the field of view from the field it is received for (fieldHfov()).
    void freezeFieldOfView(double hfov) { fieldHfov_ = hfov; }
    // The field of view of the field polled last: the run's start's, changed by each View
    // Definition during the run; 0 before freezeFieldOfView().
    double fieldHfov() const { return fieldHfov_; }
    // This view's far plane (metres) from its last View Definition that enabled one, or
    // +infinity when none did: the renderer's draw distance.
    double viewFar() const { return viewFar_; }
    // The run starts with draw distance `farM` (infinite: none): from now on a View
    // Definition with another far plane changes it for the renders asked from then on.
    void freezeFar(double farM) {
        fieldFar_ = farM;
        farFrozen_ = true;
    }
    // The draw distance of the field polled last (0 before freezeFar()).
    double fieldFar() const { return farFrozen_ ? fieldFar_ : 0.0; }
    // This view's near plane (metres ahead along the view axis) from its last View Definition
    // that enabled one, or 0 (none) when none did.
    double viewNear() const { return viewNear_; }
    // The run starts with near plane `nearM` (0: none): from now on a View Definition with
    // another changes it for the renders asked from then on.
    void freezeNear(double nearM) {
        fieldNear_ = nearM;
        nearFrozen_ = true;
    }
    // The near plane of the field polled last (negative before freezeNear(): the renderer's
    // own, sim::RenderView).
    double fieldNear() const { return nearFrozen_ ? fieldNear_ : -1.0; }
    // The host's active entities at t as objects of the scene (each entity's model at its base
    // point and heading, its entity id as the object id), from the session's own state: the
    // field thread's (CigiPoseSource::objectsAt is the renderer's). `out` is cleared first.
    void objectsAt(double t, std::vector<ExtraObject>& out) const;
    // This view's sensors, as the host last set them.
    const std::vector<SensorState>& sensors() const { return sensors_; }
    // The response of one sensor at time t (the field's instant): the tracked entity's
    // direction from the view's eye; Breaklock when the view does not see it (behind the eye,
    // outside the window, hidden by the terrain, inactive or destroyed), Searching when no
    // target is named. Public for tests.
    io::cigi::Packet sensorResponse(SensorState& sensor, double t);
    io::cigi::IgMode igMode() const { return igMode_; }
    std::uint32_t igFrame() const { return igFrame_; }
    const CigiStats& stats() const { return stats_; }
    CigiStats& stats() { return stats_; }
    const GeoFrame& geo() const { return geo_; }
    // What the ownship and the ground-clamped entities stand on (CigiOptions::ground, else the
    // map).
    const ig::Ground& ground() const { return ground_; }

    // The answer to one request at simulation time t, as sent (public for tests and tools).
    // Entity coordinates are offsets from the ownship (entity 0) in its own axes: x forward,
    // y right, z down; or from another of the host's entities, active at t, in its axes (an
    // unknown or inactive one answers invalid).
    io::cigi::Packet answer(const io::cigi::Packet& request, std::uint8_t hostFrameLsn,
                            double t) const;

  private:
    // One request worked out at its time on the field thread (its points, the objects on a
    // line), and the question it asks of the terrain; compose() makes the answer of the two.
    struct Query {
        io::cigi::Packet request;
        std::uint8_t lsn = 0;
        bool known = false;  // its points could be worked out (entities active, on the map)
        TerrainQuestion question;
        glm::dvec3 point{0.0};  // HAT/HOT
        // A line of sight: the object met first within its range, if any.
        std::uint16_t requestId = 0;
        bool extended = false, segment = false;
        double objectRange = 0.0;
        std::uint16_t objectId = 0;
        ig::Rgba8 objectColor{};
        glm::dvec3 objectNormal{0.0, 0.0, 1.0};
        // Waiting for the terrain's thread: the field asked in; a sensor's check: its id.
        std::uint32_t askedFrame = 0;
        int sensor = -1;
    };
    Query resolve(const io::cigi::Packet& request, std::uint8_t lsn, double t) const;
    io::cigi::Packet compose(const Query& q, const TerrainAnswer& a) const;
    // Over a paged map: hands a query to the terrain's thread (false when it takes no more).
    bool defer(Query&& q);
    // Sends the answers the terrain's thread has ready.
    void sendReady();

    struct Pending {
        io::cigi::Packet request;
        std::uint8_t hostFrameLsn = 0;
    };
    struct Repeating {
        io::cigi::Packet request;
        std::uint16_t requestId = 0;
        std::uint8_t period = 1;
        std::uint32_t firstFrame = 0;
    };
    // Requests with an update period answered at once, each field (beyond, dropped).
    static constexpr std::size_t kMaxRepeating = 64;

    void apply(const io::cigi::Packet& packet, double t, std::uint8_t& lsn);
    void heard(double t);
    void watch(double t);
    void setRates(double t);
    void applyEntity(const io::cigi::EntityControl& e, double t);
    void applyEntityRates(const io::cigi::RateControl& r, double t);
    void applySensor(const io::cigi::SensorControl& c);
    void applyComponent(const io::cigi::ComponentControl& c);
    SensorState* findSensor(std::uint8_t id);
    HostEntity* findEntity(std::uint16_t id);
    void noteError(const std::string& message);

    const ig::TerrainMap& map_;
    CigiOptions options_;
    GeoFrame geo_;
    io::UdpSocket socket_;
    io::cigi::Message message_;
    std::vector<std::uint8_t> in_, out_;
    std::vector<Pending> pending_;
    std::vector<Repeating> repeating_;
    const ig::Ground& ground_;          // options_.ground, else the map
    std::vector<Query> inFlight_;       // with the terrain's thread, in the order asked
    std::vector<TerrainAnswer> ready_;  // collected from it (scratch)
    std::uint64_t nextTicket_ = 1;
    std::vector<HostEntity> entities_;
    std::vector<SensorState> sensors_;       // at most 256 (ids are 8 bits), reserved
    std::vector<EntityPose> sensorScratch_;  // entity poses for the sensors
    // The first object on a line of sight within [tMin, range) (range: the terrain's hit or the
    // line's end), if any, host entity `skip` (the line's source; 0: none) left out: range, its id
    // and the colour and world normal of the voxel face it meets. Scratch reused (answer() is const
    // to its callers).
    bool objectOnLine(const glm::dvec3& origin, const glm::dvec3& dir, double tMin, double t,
                      std::uint16_t skip, double& range, std::uint16_t& id, ig::Rgba8& color,
                      glm::dvec3& normal) const;
    mutable std::vector<EntityPose> entityScratch_;  // objectsAt()'s
    mutable std::vector<ExtraObject> losEntities_;
    mutable std::vector<TruthObject> losObjects_;
    mutable std::vector<ig::Placement> losWhere_;
    mutable ig::ObjectTraceScratch losTrace_;
    DeadReckoning ownship_;
    io::cigi::RateControl rates_;  // the last Rate Control for entity 0 (persists)
    io::cigi::IgMode igMode_ = io::cigi::IgMode::Reset;
    std::uint32_t igFrame_ = 0;
    ViewOffset view_;
    std::uint16_t viewEntity_ = 0;
    io::cigi::ViewControl viewControl_;  // enabled fields as last set
    double viewHfov_ = 0.0, fieldHfov_ = 0.0;
    double viewFar_ = std::numeric_limits<double>::infinity(), fieldFar_ = 0.0;
    bool farFrozen_ = false;
    double viewNear_ = 0.0, fieldNear_ = 0.0;
    bool nearFrozen_ = false;
    double lastHeard_ = 0.0;  // simulation time of the last good datagram
    bool silent_ = false;     // an outage is open
    CigiStats stats_;
};

// The session as the pipeline's pose source: advanceTo(t) polls the session (field thread) and
// returns the view's eye on the ownship dead-reckoned to t; predict(t) extrapolates the latest
// state (any one other thread). A pose on or under the terrain is lifted to `clearance` above it.
class CigiPoseSource final : public PoseSource {
  public:
    CigiPoseSource(const ig::TerrainMap& map, const CigiOptions& options, double clearance = 1.0);
    int open(std::string* error) { return session_.open(error); }

    ig::Pose advanceTo(double t) override;
    ig::Pose predict(double t) override;
    double startTime() const override { return startTime_; }
    // The session's field of view and draw distance (fieldHfov(), fieldFar()).
    RenderView view() const override;
    // Polls at t0 (advanceTo): the host's messages that arrived while the run started (the
    // first frame rendered, the renderer started) are applied before the first field, which
    // then drains only what arrives in its own period.
    void settle(double t0) override { advanceTo(t0); }
    // The renderer's side (one thread, the one calling predict): the host's active entities at
    // t, from the latest state advanceTo() published.
    void entitiesAt(double t, std::vector<EntityPose>& out);
    // The same as objects for the scene's renderer: each entity's model at its base point and
    // heading, its entity id as the object id.
    void objectsAt(double t, std::vector<ExtraObject>& out);

    // Before a run (never during one): polls at the start time once a field period of wall
    // time, each poll sending Start of Frame (a synchronous host answers those), until the
    // host's first Entity Control arrives or `seconds` pass. Whether it arrived.
    bool waitForHost(double seconds);

    CigiSession& session() { return session_; }
    const CigiSession& session() const { return session_; }

  private:
    ig::Pose clamped(ig::Pose pose, bool count);

    const ig::TerrainMap& map_;
    CigiSession session_;
    double startTime_, clearance_;
    Mailbox<EyeState> latest_;  // field loop -> predict()
    struct EntitySnapshot {
        DeadReckoning ownship;
        std::vector<HostEntity> entities;
    };
    Mailbox<EntitySnapshot> entities_;  // field loop -> entitiesAt()
    std::vector<EntityPose> poses_;     // objectsAt()'s scratch
};

}  // namespace sim
