// CIGI 3.3 codec: the packets a host and this image generator exchange, as plain structs, and
// the UDP datagrams that carry them (docs/design/cigi.md). Bytes only: no rendering, no session.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace io::cigi {

// Angles are degrees and distances metres, as on the wire; geodetic positions are degrees of
// latitude and longitude and metres above mean sea level. Frame numbers and timestamps (units of
// 10 microseconds) are carried as they come.

enum class ByteOrder : std::uint8_t { Big, Little };
// Written as a 16-bit value in the sender's byte order: 0x8000 read as 0x0080 means swapped.
inline constexpr std::uint16_t kByteSwapMagic = 0x8000;
inline constexpr std::uint8_t kMajorVersion = 3;
inline constexpr std::uint8_t kMinorVersion = 3;

// --- Host to image generator

enum class IgMode : std::uint8_t { Reset = 0, Operate = 1, Debug = 2, OfflineMaintenance = 3 };

struct IgControl {  // id 1, 24 bytes; the first packet of every host message
    static constexpr std::uint8_t kId = 1, kSize = 24;
    std::int8_t databaseNumber = 0;   // 0: keep the current database
    IgMode igMode = IgMode::Operate;  // Reset, Operate or Debug (OfflineMaintenance is the IG's)
    bool timestampValid = false;
    bool extrapolationEnable = false;
    std::uint32_t hostFrameNumber = 0;
    std::uint32_t timestamp = 0;
    std::uint32_t lastIgFrameNumber = 0;
    bool operator==(const IgControl&) const = default;
};

enum class EntityState : std::uint8_t { Inactive = 0, Active = 1, Destroyed = 2 };
enum class GroundClamp : std::uint8_t { None = 0, NonConformal = 1, Conformal = 2 };
enum class AnimationState : std::uint8_t { Stop = 0, Pause = 1, Play = 2, Continue = 3 };

struct EntityControl {  // id 2, 48 bytes
    static constexpr std::uint8_t kId = 2, kSize = 48;
    std::uint16_t entityId = 0;  // 0 is the ownship
    EntityState entityState = EntityState::Active;
    bool attached = false;  // to parentId: position and attitude are then relative offsets
    bool collisionDetection = false;
    bool inheritAlpha = false;
    GroundClamp groundClamp = GroundClamp::None;
    bool animationBackward = false;
    bool animationContinuous = false;  // loop, rather than play once
    AnimationState animationState = AnimationState::Stop;
    bool extrapolationEnable = false;
    std::uint8_t alpha = 255;
    std::uint16_t entityType = 0;
    std::uint16_t parentId = 0;
    float rollDeg = 0, pitchDeg = 0, yawDeg = 0;  // [-180, 180], [-90, 90], [0, 360]
    // Detached: latitude [-90, 90], longitude [-180, 180], altitude. Attached: x, y, z offsets.
    double latOrX = 0, lonOrY = 0, altOrZ = 0;
    bool operator==(const EntityControl&) const = default;
};

struct RateControl {  // id 8, 32 bytes
    static constexpr std::uint8_t kId = 8, kSize = 32;
    std::uint16_t entityId = 0;
    std::uint8_t partId = 0;
    bool applyToPart = false;
    bool localCoordinates = false;  // rates in the entity's own axes, rather than world/parent
    float xRate = 0, yRate = 0, zRate = 0;                    // metres per second
    float rollRateDeg = 0, pitchRateDeg = 0, yawRateDeg = 0;  // degrees per second
    bool operator==(const RateControl&) const = default;
};

struct ViewControl {  // id 16, 32 bytes
    static constexpr std::uint8_t kId = 16, kSize = 32;
    std::uint16_t viewId = 0;
    std::uint8_t groupId = 0;  // 0: the view alone
    bool xEnable = false, yEnable = false, zEnable = false;
    bool rollEnable = false, pitchEnable = false, yawEnable = false;
    std::uint16_t entityId = 0;
    float x = 0, y = 0, z = 0;                    // eyepoint offset in the entity's axes, metres
    float rollDeg = 0, pitchDeg = 0, yawDeg = 0;  // [-180, 180], [-90, 90], [0, 360]
    bool operator==(const ViewControl&) const = default;
};

// Track modes 5-7 are the image generator's own; this one knows none of them.
enum class SensorTrackMode : std::uint8_t {
    Off = 0,
    ForceCorrelate = 1,
    Scene = 2,
    Target = 3,
    Ship = 4
};

struct SensorControl {  // id 17, 24 bytes
    static constexpr std::uint8_t kId = 17, kSize = 24;
    std::uint16_t viewId = 0;
    std::uint8_t sensorId = 0;
    bool sensorOn = false;
    bool blackHot = false;  // polarity: false white hot
    bool lineDropout = false;
    bool autoGain = false;
    bool trackBlack = false;  // track polarity: false tracks white
    SensorTrackMode trackMode = SensorTrackMode::Off;
    bool extendedResponse = false;  // answer with Sensor Extended Response (else Sensor Response)
    float gain = 0;                 // [0, 1]
    float level = 0, acCoupling = 0, noise = 0;
    bool operator==(const SensorControl&) const = default;
};

// Component classes 0-15 (6 bits on the wire, 16-63 reserved); 3 is a sensor, the instance
// its sensor id.
inline constexpr std::uint8_t kComponentClassSensor = 3;

struct ComponentControl {  // id 4, 32 bytes
    static constexpr std::uint8_t kId = 4, kSize = 32;
    std::uint16_t componentId = 0;  // which component of the instance (IG-defined)
    std::uint16_t instanceId = 0;   // the entity, view, sensor ... it belongs to
    std::uint8_t componentClass = 0;
    std::uint8_t componentState = 0;
    std::uint32_t data[6] = {0, 0, 0, 0, 0, 0};  // IG-defined words
    bool operator==(const ComponentControl&) const = default;
};

enum class MirrorMode : std::uint8_t { None = 0, Horizontal = 1, Vertical = 2, Both = 3 };

struct ViewDefinition {  // id 21, 32 bytes
    static constexpr std::uint8_t kId = 21, kSize = 32;
    std::uint16_t viewId = 0;
    std::uint8_t groupId = 0;
    bool nearEnable = false, farEnable = false, leftEnable = false;
    bool rightEnable = false, topEnable = false, bottomEnable = false;
    MirrorMode mirrorMode = MirrorMode::None;
    std::uint8_t pixelReplication = 0;  // 0 none, 1 1x2, 2 2x1, 3 2x2 (3 bits, 4-7 reserved)
    bool orthographic = false;
    bool reorder = false;
    std::uint8_t viewType = 0;  // 3 bits, IG-defined
    float nearM = 0, farM = 0;  // clipping planes, >= 0
    // Half angles of the frustum from the view axis, each in [-90, 90]: left and bottom are
    // usually negative, right and top positive.
    float leftDeg = 0, rightDeg = 0, topDeg = 0, bottomDeg = 0;
    bool operator==(const ViewDefinition&) const = default;
};

enum class HatHotType : std::uint8_t { Hat = 0, Hot = 1, Extended = 2 };

struct HatHotRequest {  // id 24, 32 bytes
    static constexpr std::uint8_t kId = 24, kSize = 32;
    std::uint16_t requestId = 0;
    HatHotType type = HatHotType::Hat;
    bool entityCoordinates = false;  // false: geodetic lat, lon, alt; true: offsets from entityId
    std::uint8_t updatePeriod = 0;   // 0: answer once; n: every n-th frame
    std::uint16_t entityId = 0;
    double latOrX = 0, lonOrY = 0, altOrZ = 0;
    bool operator==(const HatHotRequest&) const = default;
};

struct LosSegmentRequest {  // id 25, 64 bytes
    static constexpr std::uint8_t kId = 25, kSize = 64;
    std::uint16_t requestId = 0;
    bool extended = false;
    bool sourceEntityCoordinates = false;
    bool destinationEntityCoordinates = false;
    bool responseEntityCoordinates = false;
    bool destinationEntityIdValid = false;
    std::uint8_t alphaThreshold = 0;
    std::uint16_t entityId = 0;
    double sourceLatOrX = 0, sourceLonOrY = 0, sourceAltOrZ = 0;
    double destinationLatOrX = 0, destinationLonOrY = 0, destinationAltOrZ = 0;
    std::uint32_t materialMask = 0;
    std::uint8_t updatePeriod = 0;
    std::uint16_t destinationEntityId = 0;
    bool operator==(const LosSegmentRequest&) const = default;
};

struct LosVectorRequest {  // id 26, 56 bytes
    static constexpr std::uint8_t kId = 26, kSize = 56;
    std::uint16_t requestId = 0;
    bool extended = false;
    bool sourceEntityCoordinates = false;
    bool responseEntityCoordinates = false;
    std::uint8_t alphaThreshold = 0;
    std::uint16_t entityId = 0;
    float azimuthDeg = 0, elevationDeg = 0;  // [-180, 180], [-90, 90]
    float minRangeM = 0, maxRangeM = 0;      // 0 <= min <= max
    double sourceLatOrX = 0, sourceLonOrY = 0, sourceAltOrZ = 0;
    std::uint32_t materialMask = 0;
    std::uint8_t updatePeriod = 0;
    bool operator==(const LosVectorRequest&) const = default;
};

// --- Image generator to host

struct StartOfFrame {  // id 101, 24 bytes; the first packet of every image generator message
    static constexpr std::uint8_t kId = 101, kSize = 24;
    std::int8_t databaseNumber = 0;  // negative: loading; positive: loaded
    std::uint8_t igStatus = 0;       // 0: normal; otherwise an IG-defined error code
    IgMode igMode = IgMode::Operate;
    bool timestampValid = false;
    bool hostDefinedEarthModel = false;  // false: WGS 84
    std::uint32_t igFrameNumber = 0;
    std::uint32_t timestamp = 0;
    std::uint32_t lastHostFrameNumber = 0;
    bool operator==(const StartOfFrame&) const = default;
};

struct HatHotResponse {  // id 102, 16 bytes
    static constexpr std::uint8_t kId = 102, kSize = 16;
    std::uint16_t requestId = 0;
    bool valid = false;
    bool isHot = false;             // the height is a height of terrain, not a height above terrain
    std::uint8_t hostFrameLsn = 0;  // low 4 bits of the host frame the answer is for
    double heightM = 0;
    bool operator==(const HatHotResponse&) const = default;
};

struct HatHotExtendedResponse {  // id 103, 40 bytes
    static constexpr std::uint8_t kId = 103, kSize = 40;
    std::uint16_t requestId = 0;
    bool valid = false;
    std::uint8_t hostFrameLsn = 0;
    double hatM = 0, hotM = 0;
    std::uint32_t materialCode = 0;
    float normalAzimuthDeg = 0, normalElevationDeg = 0;  // [-180, 180], [-90, 90]
    bool operator==(const HatHotExtendedResponse&) const = default;
};

struct LosResponse {  // id 104, 16 bytes
    static constexpr std::uint8_t kId = 104, kSize = 16;
    std::uint16_t requestId = 0;
    bool valid = false;
    bool entityIdValid = false;
    bool visible = false;
    std::uint8_t hostFrameLsn = 0;
    std::uint8_t responseCount = 0;
    std::uint16_t entityId = 0;
    double rangeM = 0;  // >= 0
    bool operator==(const LosResponse&) const = default;
};

struct LosExtendedResponse {  // id 105, 56 bytes
    static constexpr std::uint8_t kId = 105, kSize = 56;
    std::uint16_t requestId = 0;
    bool valid = false;
    bool entityIdValid = false;
    bool rangeValid = false;
    bool visible = false;
    std::uint8_t hostFrameLsn = 0;
    std::uint8_t responseCount = 0;
    std::uint16_t entityId = 0;
    double rangeM = 0;                          // >= 0
    double latOrX = 0, lonOrY = 0, altOrZ = 0;  // in the request's response coordinates
    std::uint8_t red = 0, green = 0, blue = 0, alpha = 0;
    std::uint32_t materialCode = 0;
    float normalAzimuthDeg = 0, normalElevationDeg = 0;
    bool operator==(const LosExtendedResponse&) const = default;
};

enum class SensorStatus : std::uint8_t {
    Searching = 0,
    Tracking = 1,
    ImpendingBreaklock = 2,
    Breaklock = 3  // the target is lost
};

// The gate: its size in pixels (raster lines vertically) and its centre's direction from the
// view's axis, yaw right and pitch up in degrees.
struct SensorResponse {  // id 106, 24 bytes
    static constexpr std::uint8_t kId = 106, kSize = 24;
    std::uint16_t viewId = 0;
    std::uint8_t sensorId = 0;
    SensorStatus status = SensorStatus::Searching;
    std::uint16_t gateXSize = 0, gateYSize = 0;
    float gateXDeg = 0, gateYDeg = 0;  // [-180, 180], [-90, 90]
    std::uint32_t frameCounter = 0;    // the IG frame the gate was worked out for
    bool operator==(const SensorResponse&) const = default;
};

struct SensorExtendedResponse {  // id 107, 48 bytes
    static constexpr std::uint8_t kId = 107, kSize = 48;
    std::uint16_t viewId = 0;
    std::uint8_t sensorId = 0;
    SensorStatus status = SensorStatus::Searching;
    bool entityIdValid = false;  // the target is an entity (entityId)
    std::uint16_t entityId = 0;
    std::uint16_t gateXSize = 0, gateYSize = 0;
    float gateXDeg = 0, gateYDeg = 0;
    std::uint32_t frameCounter = 0;
    double latDeg = 0, lonDeg = 0, altM = 0;  // the track point, geodetic
    bool operator==(const SensorExtendedResponse&) const = default;
};

using Packet =
    std::variant<IgControl, EntityControl, RateControl, ViewControl, ViewDefinition, HatHotRequest,
                 LosSegmentRequest, LosVectorRequest, StartOfFrame, HatHotResponse,
                 HatHotExtendedResponse, LosResponse, LosExtendedResponse, SensorControl,
                 ComponentControl, SensorResponse, SensorExtendedResponse>;

// "Entity Control (id 2)".
std::string_view packetName(const Packet& packet);

// --- Messages

enum class Sender : std::uint8_t { Host, ImageGenerator };

struct Message {
    ByteOrder byteOrder = ByteOrder::Big;
    std::vector<Packet> packets;     // in datagram order; the first is IgControl or StartOfFrame
    std::size_t skippedPackets = 0;  // packets of ids this codec does not know, skipped by size
};

// Decodes one datagram sent by `from` into `message` (its vector is reused: a caller that keeps
// one Message allocates nothing once it has grown). The first packet must be IG Control (host)
// or Start of Frame (image generator), version 3.3; its byte-swap magic gives the byte order
// of the whole datagram. Every size and field is checked; on a problem returns false and sets
// `*error` to a message naming the packet, its offset and what is wrong (message.packets then
// holds the packets before it).
bool decodeMessage(std::span<const std::uint8_t> datagram, Sender from, Message& message,
                   std::string* error);

// The problem with a packet's fields ("roll 200 is outside [-180, 180] degrees"), or empty when
// it may be sent as it is.
std::string validate(const Packet& packet);

// Appends one packet's bytes. The packet must be valid (CHECKed).
void encodePacket(const Packet& packet, ByteOrder order, std::vector<std::uint8_t>& out);
// A whole datagram: the packets in order, the first IgControl or StartOfFrame (CHECKed).
std::vector<std::uint8_t> encodeMessage(std::span<const Packet> packets, ByteOrder order);

}  // namespace io::cigi
