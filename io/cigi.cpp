// CIGI 3.3 codec. Layouts, sizes and sources: docs/design/cigi.md.
//
// Every packet is read and written through one view of its fixed-size span: offsets are
// the standard's byte offsets from the packet's first byte (its id), multi-byte fields in the
// datagram's byte order. Decoding checks the size byte before it reads, so a field read is
// always inside the datagram; values are checked after, by the same validate() that encoding
// CHECKs, so the codec never sends what it would refuse.
#include "io/cigi.hpp"

#include <bit>
#include <cmath>
#include <cstdio>
#include <type_traits>

#include "base/check.hpp"
#include "base/text.hpp"

namespace io::cigi {
namespace {

// --- Bytes in either order

// A packet's bytes in the datagram's byte order: Reader over const bytes, Writer over the
// output. Offsets count from the packet's first byte (its id).
template <typename Byte>
class PacketBytes {
  public:
    PacketBytes(Byte* p, ByteOrder order) : p_(p), little_(order == ByteOrder::Little) {}

    std::uint8_t u8(std::size_t at) const { return p_[at]; }
    std::uint16_t u16(std::size_t at) const { return static_cast<std::uint16_t>(get(at, 2)); }
    std::uint32_t u32(std::size_t at) const { return static_cast<std::uint32_t>(get(at, 4)); }
    float f32(std::size_t at) const { return std::bit_cast<float>(u32(at)); }
    double f64(std::size_t at) const { return std::bit_cast<double>(get(at, 8)); }

    void u8(std::size_t at, std::uint8_t v) { p_[at] = v; }
    void u16(std::size_t at, std::uint16_t v) { put(at, 2, v); }
    void u32(std::size_t at, std::uint32_t v) { put(at, 4, v); }
    void f32(std::size_t at, float v) { put(at, 4, std::bit_cast<std::uint32_t>(v)); }
    void f64(std::size_t at, double v) { put(at, 8, std::bit_cast<std::uint64_t>(v)); }

  private:
    int shift(int i, int n) const { return little_ ? 8 * i : 8 * (n - 1 - i); }
    std::uint64_t get(std::size_t at, int n) const {
        std::uint64_t v = 0;
        for (int i = 0; i < n; ++i)
            v |= static_cast<std::uint64_t>(p_[at + static_cast<std::size_t>(i)]) << shift(i, n);
        return v;
    }
    void put(std::size_t at, int n, std::uint64_t v) {
        for (int i = 0; i < n; ++i)
            p_[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> shift(i, n));
    }

    Byte* p_;
    bool little_;
};
using Reader = PacketBytes<const std::uint8_t>;
using Writer = PacketBytes<std::uint8_t>;

constexpr bool bit(std::uint8_t byte, int n) {
    return (byte >> n) & 1u;
}
constexpr std::uint8_t flag(bool b, int n) {
    return static_cast<std::uint8_t>((b ? 1u : 0u) << n);
}
constexpr std::uint8_t field(unsigned value, int shift) {
    return static_cast<std::uint8_t>(value << shift);
}
template <typename E>
constexpr unsigned raw(E e) {
    return static_cast<unsigned>(e);
}

// --- Field layouts
// encode(p, b) writes everything after the id and size bytes (the buffer is zeroed, so reserved
// bytes stay 0); decode(b, p) reads the same bytes.

void encode(const IgControl& p, Writer& b) {
    b.u8(2, kMajorVersion);
    b.u8(3, static_cast<std::uint8_t>(p.databaseNumber));
    b.u8(4, static_cast<std::uint8_t>(field(raw(p.igMode), 0) | flag(p.timestampValid, 2) |
                                      flag(p.extrapolationEnable, 3) | field(kMinorVersion, 4)));
    b.u16(6, kByteSwapMagic);
    b.u32(8, p.hostFrameNumber);
    b.u32(12, p.timestamp);
    b.u32(16, p.lastIgFrameNumber);
}
void decode(const Reader& b, IgControl& p) {
    p.databaseNumber = static_cast<std::int8_t>(b.u8(3));
    const std::uint8_t f = b.u8(4);
    p.igMode = static_cast<IgMode>(f & 0x03);
    p.timestampValid = bit(f, 2);
    p.extrapolationEnable = bit(f, 3);
    p.hostFrameNumber = b.u32(8);
    p.timestamp = b.u32(12);
    p.lastIgFrameNumber = b.u32(16);
}

void encode(const EntityControl& p, Writer& b) {
    b.u16(2, p.entityId);
    b.u8(4, static_cast<std::uint8_t>(field(raw(p.entityState), 0) | flag(p.attached, 2) |
                                      flag(p.collisionDetection, 3) | flag(p.inheritAlpha, 4) |
                                      field(raw(p.groundClamp), 5)));
    b.u8(5, static_cast<std::uint8_t>(
                flag(p.animationBackward, 0) | flag(p.animationContinuous, 1) |
                field(raw(p.animationState), 2) | flag(p.extrapolationEnable, 4)));
    b.u8(6, p.alpha);
    b.u16(8, p.entityType);
    b.u16(10, p.parentId);
    b.f32(12, p.rollDeg);
    b.f32(16, p.pitchDeg);
    b.f32(20, p.yawDeg);
    b.f64(24, p.latOrX);
    b.f64(32, p.lonOrY);
    b.f64(40, p.altOrZ);
}
void decode(const Reader& b, EntityControl& p) {
    p.entityId = b.u16(2);
    const std::uint8_t f = b.u8(4);
    p.entityState = static_cast<EntityState>(f & 0x03);
    p.attached = bit(f, 2);
    p.collisionDetection = bit(f, 3);
    p.inheritAlpha = bit(f, 4);
    p.groundClamp = static_cast<GroundClamp>((f >> 5) & 0x03);
    const std::uint8_t g = b.u8(5);
    p.animationBackward = bit(g, 0);
    p.animationContinuous = bit(g, 1);
    p.animationState = static_cast<AnimationState>((g >> 2) & 0x03);
    p.extrapolationEnable = bit(g, 4);
    p.alpha = b.u8(6);
    p.entityType = b.u16(8);
    p.parentId = b.u16(10);
    p.rollDeg = b.f32(12);
    p.pitchDeg = b.f32(16);
    p.yawDeg = b.f32(20);
    p.latOrX = b.f64(24);
    p.lonOrY = b.f64(32);
    p.altOrZ = b.f64(40);
}

void encode(const RateControl& p, Writer& b) {
    b.u16(2, p.entityId);
    b.u8(4, p.partId);
    b.u8(5, static_cast<std::uint8_t>(flag(p.applyToPart, 0) | flag(p.localCoordinates, 1)));
    b.f32(8, p.xRate);
    b.f32(12, p.yRate);
    b.f32(16, p.zRate);
    b.f32(20, p.rollRateDeg);
    b.f32(24, p.pitchRateDeg);
    b.f32(28, p.yawRateDeg);
}
void decode(const Reader& b, RateControl& p) {
    p.entityId = b.u16(2);
    p.partId = b.u8(4);
    p.applyToPart = bit(b.u8(5), 0);
    p.localCoordinates = bit(b.u8(5), 1);
    p.xRate = b.f32(8);
    p.yRate = b.f32(12);
    p.zRate = b.f32(16);
    p.rollRateDeg = b.f32(20);
    p.pitchRateDeg = b.f32(24);
    p.yawRateDeg = b.f32(28);
}

void encode(const ViewControl& p, Writer& b) {
    b.u16(2, p.viewId);
    b.u8(4, p.groupId);
    b.u8(5, static_cast<std::uint8_t>(flag(p.xEnable, 0) | flag(p.yEnable, 1) | flag(p.zEnable, 2) |
                                      flag(p.rollEnable, 3) | flag(p.pitchEnable, 4) |
                                      flag(p.yawEnable, 5)));
    b.u16(6, p.entityId);
    b.f32(8, p.x);
    b.f32(12, p.y);
    b.f32(16, p.z);
    b.f32(20, p.rollDeg);
    b.f32(24, p.pitchDeg);
    b.f32(28, p.yawDeg);
}
void decode(const Reader& b, ViewControl& p) {
    p.viewId = b.u16(2);
    p.groupId = b.u8(4);
    const std::uint8_t f = b.u8(5);
    p.xEnable = bit(f, 0);
    p.yEnable = bit(f, 1);
    p.zEnable = bit(f, 2);
    p.rollEnable = bit(f, 3);
    p.pitchEnable = bit(f, 4);
    p.yawEnable = bit(f, 5);
    p.entityId = b.u16(6);
    p.x = b.f32(8);
    p.y = b.f32(12);
    p.z = b.f32(16);
    p.rollDeg = b.f32(20);
    p.pitchDeg = b.f32(24);
    p.yawDeg = b.f32(28);
}

void encode(const ViewDefinition& p, Writer& b) {
    b.u16(2, p.viewId);
    b.u8(4, p.groupId);
    b.u8(5, static_cast<std::uint8_t>(flag(p.nearEnable, 0) | flag(p.farEnable, 1) |
                                      flag(p.leftEnable, 2) | flag(p.rightEnable, 3) |
                                      flag(p.topEnable, 4) | flag(p.bottomEnable, 5) |
                                      field(raw(p.mirrorMode), 6)));
    b.u8(6, static_cast<std::uint8_t>(field(p.pixelReplication, 0) | flag(p.orthographic, 3) |
                                      flag(p.reorder, 4) | field(p.viewType, 5)));
    b.f32(8, p.nearM);
    b.f32(12, p.farM);
    b.f32(16, p.leftDeg);
    b.f32(20, p.rightDeg);
    b.f32(24, p.topDeg);
    b.f32(28, p.bottomDeg);
}
void decode(const Reader& b, ViewDefinition& p) {
    p.viewId = b.u16(2);
    p.groupId = b.u8(4);
    const std::uint8_t f = b.u8(5);
    p.nearEnable = bit(f, 0);
    p.farEnable = bit(f, 1);
    p.leftEnable = bit(f, 2);
    p.rightEnable = bit(f, 3);
    p.topEnable = bit(f, 4);
    p.bottomEnable = bit(f, 5);
    p.mirrorMode = static_cast<MirrorMode>((f >> 6) & 0x03);
    const std::uint8_t g = b.u8(6);
    p.pixelReplication = g & 0x07;
    p.orthographic = bit(g, 3);
    p.reorder = bit(g, 4);
    p.viewType = (g >> 5) & 0x07;
    p.nearM = b.f32(8);
    p.farM = b.f32(12);
    p.leftDeg = b.f32(16);
    p.rightDeg = b.f32(20);
    p.topDeg = b.f32(24);
    p.bottomDeg = b.f32(28);
}

void encode(const HatHotRequest& p, Writer& b) {
    b.u16(2, p.requestId);
    b.u8(4, static_cast<std::uint8_t>(field(raw(p.type), 0) | flag(p.entityCoordinates, 2)));
    b.u8(5, p.updatePeriod);
    b.u16(6, p.entityId);
    b.f64(8, p.latOrX);
    b.f64(16, p.lonOrY);
    b.f64(24, p.altOrZ);
}
void decode(const Reader& b, HatHotRequest& p) {
    p.requestId = b.u16(2);
    p.type = static_cast<HatHotType>(b.u8(4) & 0x03);
    p.entityCoordinates = bit(b.u8(4), 2);
    p.updatePeriod = b.u8(5);
    p.entityId = b.u16(6);
    p.latOrX = b.f64(8);
    p.lonOrY = b.f64(16);
    p.altOrZ = b.f64(24);
}

void encode(const LosSegmentRequest& p, Writer& b) {
    b.u16(2, p.requestId);
    b.u8(4, static_cast<std::uint8_t>(flag(p.extended, 0) | flag(p.sourceEntityCoordinates, 1) |
                                      flag(p.destinationEntityCoordinates, 2) |
                                      flag(p.responseEntityCoordinates, 3) |
                                      flag(p.destinationEntityIdValid, 4)));
    b.u8(5, p.alphaThreshold);
    b.u16(6, p.entityId);
    b.f64(8, p.sourceLatOrX);
    b.f64(16, p.sourceLonOrY);
    b.f64(24, p.sourceAltOrZ);
    b.f64(32, p.destinationLatOrX);
    b.f64(40, p.destinationLonOrY);
    b.f64(48, p.destinationAltOrZ);
    b.u32(56, p.materialMask);
    b.u8(60, p.updatePeriod);
    b.u16(62, p.destinationEntityId);
}
void decode(const Reader& b, LosSegmentRequest& p) {
    p.requestId = b.u16(2);
    const std::uint8_t f = b.u8(4);
    p.extended = bit(f, 0);
    p.sourceEntityCoordinates = bit(f, 1);
    p.destinationEntityCoordinates = bit(f, 2);
    p.responseEntityCoordinates = bit(f, 3);
    p.destinationEntityIdValid = bit(f, 4);
    p.alphaThreshold = b.u8(5);
    p.entityId = b.u16(6);
    p.sourceLatOrX = b.f64(8);
    p.sourceLonOrY = b.f64(16);
    p.sourceAltOrZ = b.f64(24);
    p.destinationLatOrX = b.f64(32);
    p.destinationLonOrY = b.f64(40);
    p.destinationAltOrZ = b.f64(48);
    p.materialMask = b.u32(56);
    p.updatePeriod = b.u8(60);
    p.destinationEntityId = b.u16(62);
}

void encode(const LosVectorRequest& p, Writer& b) {
    b.u16(2, p.requestId);
    b.u8(4, static_cast<std::uint8_t>(flag(p.extended, 0) | flag(p.sourceEntityCoordinates, 1) |
                                      flag(p.responseEntityCoordinates, 2)));
    b.u8(5, p.alphaThreshold);
    b.u16(6, p.entityId);
    b.f32(8, p.azimuthDeg);
    b.f32(12, p.elevationDeg);
    b.f32(16, p.minRangeM);
    b.f32(20, p.maxRangeM);
    b.f64(24, p.sourceLatOrX);
    b.f64(32, p.sourceLonOrY);
    b.f64(40, p.sourceAltOrZ);
    b.u32(48, p.materialMask);
    b.u8(52, p.updatePeriod);
}
void decode(const Reader& b, LosVectorRequest& p) {
    p.requestId = b.u16(2);
    const std::uint8_t f = b.u8(4);
    p.extended = bit(f, 0);
    p.sourceEntityCoordinates = bit(f, 1);
    p.responseEntityCoordinates = bit(f, 2);
    p.alphaThreshold = b.u8(5);
    p.entityId = b.u16(6);
    p.azimuthDeg = b.f32(8);
    p.elevationDeg = b.f32(12);
    p.minRangeM = b.f32(16);
    p.maxRangeM = b.f32(20);
    p.sourceLatOrX = b.f64(24);
    p.sourceLonOrY = b.f64(32);
    p.sourceAltOrZ = b.f64(40);
    p.materialMask = b.u32(48);
    p.updatePeriod = b.u8(52);
}

void encode(const StartOfFrame& p, Writer& b) {
    b.u8(2, kMajorVersion);
    b.u8(3, static_cast<std::uint8_t>(p.databaseNumber));
    b.u8(4, p.igStatus);
    b.u8(5, static_cast<std::uint8_t>(field(raw(p.igMode), 0) | flag(p.timestampValid, 2) |
                                      flag(p.hostDefinedEarthModel, 3) | field(kMinorVersion, 4)));
    b.u16(6, kByteSwapMagic);
    b.u32(8, p.igFrameNumber);
    b.u32(12, p.timestamp);
    b.u32(16, p.lastHostFrameNumber);
}
void decode(const Reader& b, StartOfFrame& p) {
    p.databaseNumber = static_cast<std::int8_t>(b.u8(3));
    p.igStatus = b.u8(4);
    const std::uint8_t f = b.u8(5);
    p.igMode = static_cast<IgMode>(f & 0x03);
    p.timestampValid = bit(f, 2);
    p.hostDefinedEarthModel = bit(f, 3);
    p.igFrameNumber = b.u32(8);
    p.timestamp = b.u32(12);
    p.lastHostFrameNumber = b.u32(16);
}

void encode(const HatHotResponse& p, Writer& b) {
    b.u16(2, p.requestId);
    b.u8(4,
         static_cast<std::uint8_t>(flag(p.valid, 0) | flag(p.isHot, 1) | field(p.hostFrameLsn, 4)));
    b.f64(8, p.heightM);
}
void decode(const Reader& b, HatHotResponse& p) {
    p.requestId = b.u16(2);
    const std::uint8_t f = b.u8(4);
    p.valid = bit(f, 0);
    p.isHot = bit(f, 1);
    p.hostFrameLsn = f >> 4;
    p.heightM = b.f64(8);
}

void encode(const HatHotExtendedResponse& p, Writer& b) {
    b.u16(2, p.requestId);
    b.u8(4, static_cast<std::uint8_t>(flag(p.valid, 0) | field(p.hostFrameLsn, 4)));
    b.f64(8, p.hatM);
    b.f64(16, p.hotM);
    b.u32(24, p.materialCode);
    b.f32(28, p.normalAzimuthDeg);
    b.f32(32, p.normalElevationDeg);
}
void decode(const Reader& b, HatHotExtendedResponse& p) {
    p.requestId = b.u16(2);
    p.valid = bit(b.u8(4), 0);
    p.hostFrameLsn = b.u8(4) >> 4;
    p.hatM = b.f64(8);
    p.hotM = b.f64(16);
    p.materialCode = b.u32(24);
    p.normalAzimuthDeg = b.f32(28);
    p.normalElevationDeg = b.f32(32);
}

void encode(const LosResponse& p, Writer& b) {
    b.u16(2, p.requestId);
    b.u8(4, static_cast<std::uint8_t>(flag(p.valid, 0) | flag(p.entityIdValid, 1) |
                                      flag(p.visible, 2) | field(p.hostFrameLsn, 4)));
    b.u8(5, p.responseCount);
    b.u16(6, p.entityId);
    b.f64(8, p.rangeM);
}
void decode(const Reader& b, LosResponse& p) {
    p.requestId = b.u16(2);
    const std::uint8_t f = b.u8(4);
    p.valid = bit(f, 0);
    p.entityIdValid = bit(f, 1);
    p.visible = bit(f, 2);
    p.hostFrameLsn = f >> 4;
    p.responseCount = b.u8(5);
    p.entityId = b.u16(6);
    p.rangeM = b.f64(8);
}

void encode(const LosExtendedResponse& p, Writer& b) {
    b.u16(2, p.requestId);
    b.u8(4, static_cast<std::uint8_t>(flag(p.valid, 0) | flag(p.entityIdValid, 1) |
                                      flag(p.rangeValid, 2) | flag(p.visible, 3) |
                                      field(p.hostFrameLsn, 4)));
    b.u8(5, p.responseCount);
    b.u16(6, p.entityId);
    b.f64(8, p.rangeM);
    b.f64(16, p.latOrX);
    b.f64(24, p.lonOrY);
    b.f64(32, p.altOrZ);
    b.u8(40, p.red);
    b.u8(41, p.green);
    b.u8(42, p.blue);
    b.u8(43, p.alpha);
    b.u32(44, p.materialCode);
    b.f32(48, p.normalAzimuthDeg);
    b.f32(52, p.normalElevationDeg);
}
void decode(const Reader& b, LosExtendedResponse& p) {
    p.requestId = b.u16(2);
    const std::uint8_t f = b.u8(4);
    p.valid = bit(f, 0);
    p.entityIdValid = bit(f, 1);
    p.rangeValid = bit(f, 2);
    p.visible = bit(f, 3);
    p.hostFrameLsn = f >> 4;
    p.responseCount = b.u8(5);
    p.entityId = b.u16(6);
    p.rangeM = b.f64(8);
    p.latOrX = b.f64(16);
    p.lonOrY = b.f64(24);
    p.altOrZ = b.f64(32);
    p.red = b.u8(40);
    p.green = b.u8(41);
    p.blue = b.u8(42);
    p.alpha = b.u8(43);
    p.materialCode = b.u32(44);
    p.normalAzimuthDeg = b.f32(48);
    p.normalElevationDeg = b.f32(52);
}

void encode(const SensorControl& p, Writer& b) {
    b.u16(2, p.viewId);
    b.u8(4, p.sensorId);
    b.u8(5, static_cast<std::uint8_t>(flag(p.sensorOn, 0) | flag(p.blackHot, 1) |
                                      flag(p.lineDropout, 2) | flag(p.autoGain, 3) |
                                      flag(p.trackBlack, 4) | field(raw(p.trackMode), 5)));
    b.u8(6, flag(p.extendedResponse, 0));
    b.f32(8, p.gain);
    b.f32(12, p.level);
    b.f32(16, p.acCoupling);
    b.f32(20, p.noise);
}
void decode(const Reader& b, SensorControl& p) {
    p.viewId = b.u16(2);
    p.sensorId = b.u8(4);
    const std::uint8_t f = b.u8(5);
    p.sensorOn = bit(f, 0);
    p.blackHot = bit(f, 1);
    p.lineDropout = bit(f, 2);
    p.autoGain = bit(f, 3);
    p.trackBlack = bit(f, 4);
    p.trackMode = static_cast<SensorTrackMode>(f >> 5);
    p.extendedResponse = bit(b.u8(6), 0);
    p.gain = b.f32(8);
    p.level = b.f32(12);
    p.acCoupling = b.f32(16);
    p.noise = b.f32(20);
}

void encode(const ComponentControl& p, Writer& b) {
    b.u16(2, p.componentId);
    b.u16(4, p.instanceId);
    b.u8(6, p.componentClass);
    b.u8(7, p.componentState);
    for (std::size_t i = 0; i < 6; ++i)
        b.u32(8 + 4 * i, p.data[i]);
}
void decode(const Reader& b, ComponentControl& p) {
    p.componentId = b.u16(2);
    p.instanceId = b.u16(4);
    p.componentClass = b.u8(6) & 0x3f;
    p.componentState = b.u8(7);
    for (std::size_t i = 0; i < 6; ++i)
        p.data[i] = b.u32(8 + 4 * i);
}

void encode(const SensorResponse& p, Writer& b) {
    b.u16(2, p.viewId);
    b.u8(4, p.sensorId);
    b.u8(5, field(raw(p.status), 0));
    b.u16(8, p.gateXSize);
    b.u16(10, p.gateYSize);
    b.f32(12, p.gateXDeg);
    b.f32(16, p.gateYDeg);
    b.u32(20, p.frameCounter);
}
void decode(const Reader& b, SensorResponse& p) {
    p.viewId = b.u16(2);
    p.sensorId = b.u8(4);
    p.status = static_cast<SensorStatus>(b.u8(5) & 0x03);
    p.gateXSize = b.u16(8);
    p.gateYSize = b.u16(10);
    p.gateXDeg = b.f32(12);
    p.gateYDeg = b.f32(16);
    p.frameCounter = b.u32(20);
}

void encode(const SensorExtendedResponse& p, Writer& b) {
    b.u16(2, p.viewId);
    b.u8(4, p.sensorId);
    b.u8(5, static_cast<std::uint8_t>(field(raw(p.status), 0) | flag(p.entityIdValid, 2)));
    b.u16(6, p.entityId);
    b.u16(8, p.gateXSize);
    b.u16(10, p.gateYSize);
    b.f32(12, p.gateXDeg);
    b.f32(16, p.gateYDeg);
    b.u32(20, p.frameCounter);
    b.f64(24, p.latDeg);
    b.f64(32, p.lonDeg);
    b.f64(40, p.altM);
}
void decode(const Reader& b, SensorExtendedResponse& p) {
    p.viewId = b.u16(2);
    p.sensorId = b.u8(4);
    p.status = static_cast<SensorStatus>(b.u8(5) & 0x03);
    p.entityIdValid = bit(b.u8(5), 2);
    p.entityId = b.u16(6);
    p.gateXSize = b.u16(8);
    p.gateYSize = b.u16(10);
    p.gateXDeg = b.f32(12);
    p.gateYDeg = b.f32(16);
    p.frameCounter = b.u32(20);
    p.latDeg = b.f64(24);
    p.lonDeg = b.f64(32);
    p.altM = b.f64(40);
}

// --- Field checks

// Collects the first problem; later checks do nothing once one is found. Builds no string
// unless there is a problem, so checking a good packet allocates nothing.
class Checker {
  public:
    // A value in [lo, hi] (NaN and infinities are never in range).
    void range(std::string_view name, double v, double lo, double hi, const char* unit,
               std::string_view prefix = {}) {
        if (!problem.empty() || (v >= lo && v <= hi)) return;
        report(prefix, name,
               base::number(v) + " is outside [" + base::number(lo) + ", " + base::number(hi) +
                   "] " + unit);
    }
    void finite(std::string_view name, double v, std::string_view prefix = {}) {
        if (!problem.empty() || std::isfinite(v)) return;
        report(prefix, name, "is " + base::number(v) + ", not a finite number");
    }
    void atLeast(std::string_view name, double v, double lo, const char* unit) {
        finite(name, v);
        if (!problem.empty() || v >= lo) return;
        report({}, name, base::number(v) + " is below " + base::number(lo) + " " + unit);
    }
    // An enumerated value: one of 0 .. count-1, named in `names` ("0 (reset), 1 (operate)").
    void oneOf(std::string_view name, unsigned v, unsigned count, const char* names) {
        if (!problem.empty() || v < count) return;
        report({}, name, std::to_string(v) + " is not one of " + names);
    }
    void bits(std::string_view name, unsigned v, int width) {
        if (!problem.empty() || v < (1u << width)) return;
        report({}, name,
               std::to_string(v) + " does not fit in its " + std::to_string(width) + " bits");
    }
    // Latitude, longitude and altitude when geodetic, three finite offsets otherwise.
    void position(bool geodetic, std::string_view prefix, double latOrX, double lonOrY,
                  double altOrZ) {
        if (geodetic) {
            range("latitude", latOrX, -90, 90, "degrees", prefix);
            range("longitude", lonOrY, -180, 180, "degrees", prefix);
            finite("altitude", altOrZ, prefix);
        } else {
            finite("x offset", latOrX, prefix);
            finite("y offset", lonOrY, prefix);
            finite("z offset", altOrZ, prefix);
        }
    }
    void attitude(double roll, double pitch, double yaw) {
        range("roll", roll, -180, 180, "degrees");
        range("pitch", pitch, -90, 90, "degrees");
        range("yaw", yaw, 0, 360, "degrees");
    }

    std::string problem;

  private:
    void report(std::string_view prefix, std::string_view name, const std::string& what) {
        problem.append(prefix).append(name).append(" ").append(what);
    }
};

void check(const IgControl& p, Checker& c) {
    c.oneOf("IG mode", raw(p.igMode), 3, "0 (reset/standby), 1 (operate), 2 (debug)");
}
void check(const EntityControl& p, Checker& c) {
    c.oneOf("entity state", raw(p.entityState), 3, "0 (inactive), 1 (active), 2 (destroyed)");
    c.oneOf("ground/ocean clamp", raw(p.groundClamp), 3,
            "0 (none), 1 (non-conformal), 2 (conformal)");
    c.oneOf("animation state", raw(p.animationState), 4,
            "0 (stop), 1 (pause), 2 (play), 3 (continue)");
    c.attitude(p.rollDeg, p.pitchDeg, p.yawDeg);
    c.position(!p.attached, "", p.latOrX, p.lonOrY, p.altOrZ);
}
void check(const RateControl& p, Checker& c) {
    c.finite("x rate", p.xRate);
    c.finite("y rate", p.yRate);
    c.finite("z rate", p.zRate);
    c.finite("roll rate", p.rollRateDeg);
    c.finite("pitch rate", p.pitchRateDeg);
    c.finite("yaw rate", p.yawRateDeg);
}
void check(const ViewControl& p, Checker& c) {
    c.finite("x offset", p.x);
    c.finite("y offset", p.y);
    c.finite("z offset", p.z);
    c.attitude(p.rollDeg, p.pitchDeg, p.yawDeg);
}
void check(const ViewDefinition& p, Checker& c) {
    c.bits("pixel replication", p.pixelReplication, 3);
    c.bits("view type", p.viewType, 3);
    c.oneOf("mirror mode", raw(p.mirrorMode), 4,
            "0 (none), 1 (horizontal), 2 (vertical), 3 (both)");
    c.atLeast("near clipping plane", p.nearM, 0, "metres");
    c.atLeast("far clipping plane", p.farM, 0, "metres");
    c.range("left half angle", p.leftDeg, -90, 90, "degrees");
    c.range("right half angle", p.rightDeg, -90, 90, "degrees");
    c.range("top half angle", p.topDeg, -90, 90, "degrees");
    c.range("bottom half angle", p.bottomDeg, -90, 90, "degrees");
}
void check(const HatHotRequest& p, Checker& c) {
    c.oneOf("request type", raw(p.type), 3, "0 (HAT), 1 (HOT), 2 (extended)");
    c.position(!p.entityCoordinates, "", p.latOrX, p.lonOrY, p.altOrZ);
}
void check(const LosSegmentRequest& p, Checker& c) {
    c.position(!p.sourceEntityCoordinates, "source ", p.sourceLatOrX, p.sourceLonOrY,
               p.sourceAltOrZ);
    c.position(!p.destinationEntityCoordinates, "destination ", p.destinationLatOrX,
               p.destinationLonOrY, p.destinationAltOrZ);
}
void check(const LosVectorRequest& p, Checker& c) {
    c.range("azimuth", p.azimuthDeg, -180, 180, "degrees");
    c.range("elevation", p.elevationDeg, -90, 90, "degrees");
    c.atLeast("minimum range", p.minRangeM, 0, "metres");
    c.atLeast("maximum range", p.maxRangeM, p.minRangeM, "metres (the minimum range)");
    c.position(!p.sourceEntityCoordinates, "source ", p.sourceLatOrX, p.sourceLonOrY,
               p.sourceAltOrZ);
}
void check(const StartOfFrame& p, Checker& c) {
    c.oneOf("IG mode", raw(p.igMode), 4,
            "0 (reset/standby), 1 (operate), 2 (debug), 3 (offline maintenance)");
}
void check(const HatHotResponse& p, Checker& c) {
    c.bits("host frame number LSN", p.hostFrameLsn, 4);
    c.finite("height", p.heightM);
}
void check(const HatHotExtendedResponse& p, Checker& c) {
    c.bits("host frame number LSN", p.hostFrameLsn, 4);
    c.finite("height above terrain", p.hatM);
    c.finite("height of terrain", p.hotM);
    c.range("normal azimuth", p.normalAzimuthDeg, -180, 180, "degrees");
    c.range("normal elevation", p.normalElevationDeg, -90, 90, "degrees");
}
void check(const LosResponse& p, Checker& c) {
    c.bits("host frame number LSN", p.hostFrameLsn, 4);
    c.atLeast("range", p.rangeM, 0, "metres");
}
void check(const LosExtendedResponse& p, Checker& c) {
    c.bits("host frame number LSN", p.hostFrameLsn, 4);
    c.atLeast("range", p.rangeM, 0, "metres");
    c.position(false, "intersection ", p.latOrX, p.lonOrY, p.altOrZ);
    c.range("normal azimuth", p.normalAzimuthDeg, -180, 180, "degrees");
    c.range("normal elevation", p.normalElevationDeg, -90, 90, "degrees");
}

void check(const SensorControl& p, Checker& c) {
    c.range("gain", p.gain, 0, 1, "(a fraction of full gain)");
    c.finite("level", p.level);
    c.finite("AC coupling", p.acCoupling);
    c.finite("noise", p.noise);
}
void check(const ComponentControl& p, Checker& c) {
    c.bits("component class", p.componentClass, 6);
    c.oneOf("component class", p.componentClass, 16,
            "0-15 (entity, view, view group, sensor, ... symbol); 16-63 are reserved");
}
void gate(float x, float y, Checker& c) {
    c.range("gate x position", x, -180, 180, "degrees");
    c.range("gate y position", y, -90, 90, "degrees");
}
void check(const SensorResponse& p, Checker& c) {
    gate(p.gateXDeg, p.gateYDeg, c);
}
void check(const SensorExtendedResponse& p, Checker& c) {
    gate(p.gateXDeg, p.gateYDeg, c);
    c.position(true, "track point ", p.latDeg, p.lonDeg, p.altM);
}

template <typename T>
constexpr bool kFromHost = T::kId < 100;

template <typename T>
constexpr std::string_view kName = "";
template <>
constexpr std::string_view kName<IgControl> = "IG Control (id 1)";
template <>
constexpr std::string_view kName<EntityControl> = "Entity Control (id 2)";
template <>
constexpr std::string_view kName<RateControl> = "Rate Control (id 8)";
template <>
constexpr std::string_view kName<ViewControl> = "View Control (id 16)";
template <>
constexpr std::string_view kName<ViewDefinition> = "View Definition (id 21)";
template <>
constexpr std::string_view kName<HatHotRequest> = "HAT/HOT Request (id 24)";
template <>
constexpr std::string_view kName<LosSegmentRequest> = "Line of Sight Segment Request (id 25)";
template <>
constexpr std::string_view kName<LosVectorRequest> = "Line of Sight Vector Request (id 26)";
template <>
constexpr std::string_view kName<SensorControl> = "Sensor Control (id 17)";
template <>
constexpr std::string_view kName<ComponentControl> = "Component Control (id 4)";
template <>
constexpr std::string_view kName<SensorResponse> = "Sensor Response (id 106)";
template <>
constexpr std::string_view kName<SensorExtendedResponse> = "Sensor Extended Response (id 107)";
template <>
constexpr std::string_view kName<StartOfFrame> = "Start of Frame (id 101)";
template <>
constexpr std::string_view kName<HatHotResponse> = "HAT/HOT Response (id 102)";
template <>
constexpr std::string_view kName<HatHotExtendedResponse> = "HAT/HOT Extended Response (id 103)";
template <>
constexpr std::string_view kName<LosResponse> = "Line of Sight Response (id 104)";
template <>
constexpr std::string_view kName<LosExtendedResponse> = "Line of Sight Extended Response (id 105)";

// --- Decoding a datagram

class Decoder {
  public:
    Decoder(std::span<const std::uint8_t> d, Sender from, Message& m, std::string* error)
        : d_(d), from_(from), m_(m), error_(error) {}

    bool run();

  private:
    // Always false, so callers can `return fail(...)`.
    bool fail(const std::string& what) {
        if (error_) {
            *error_ = std::string("CIGI message from the ") +
                      (from_ == Sender::Host ? "host" : "image generator") + " (" +
                      std::to_string(d_.size()) + " bytes): " + what;
        }
        return false;
    }
    static std::string at(std::string_view name, std::size_t offset) {
        return std::string(name) + " at offset " + std::to_string(offset);
    }

    template <typename T>
    bool packet(std::size_t offset, std::size_t size);
    bool header();

    std::span<const std::uint8_t> d_;
    Sender from_;
    Message& m_;
    std::string* error_;
};

bool Decoder::header() {
    if (d_.size() < 2) return fail("too short for a packet header");
    const bool host = from_ == Sender::Host;
    const std::uint8_t firstId = host ? IgControl::kId : StartOfFrame::kId;
    const std::string_view firstName = host ? kName<IgControl> : kName<StartOfFrame>;
    if (d_[0] != firstId) {
        return fail("the first packet is id " + std::to_string(d_[0]) + ", not " +
                    std::string(firstName));
    }
    if (d_[1] != 24) {
        return fail(at(firstName, 0) + ": size " + std::to_string(d_[1]) + ", expected 24");
    }
    if (d_.size() < 24) {
        return fail(at(firstName, 0) + ": truncated, " + std::to_string(d_.size()) +
                    " of its 24 bytes");
    }
    if (d_[2] != kMajorVersion) {
        return fail(at(firstName, 0) + ": CIGI major version " + std::to_string(d_[2]) +
                    ", this image generator speaks 3.3");
    }
    const unsigned minor = (host ? d_[4] : d_[5]) >> 4;
    if (minor != kMinorVersion) {
        return fail(at(firstName, 0) + ": CIGI version 3." + std::to_string(minor) +
                    ", this image generator speaks 3.3");
    }
    if (d_[6] == 0x80 && d_[7] == 0x00) {
        m_.byteOrder = ByteOrder::Big;
    } else if (d_[6] == 0x00 && d_[7] == 0x80) {
        m_.byteOrder = ByteOrder::Little;
    } else {
        char magic[16];
        std::snprintf(magic, sizeof magic, "0x%02x%02x", d_[6], d_[7]);
        return fail(at(firstName, 0) + ": byte-swap magic " + magic +
                    " is neither 0x8000 (big-endian) nor 0x0080 (little-endian)");
    }
    return true;
}

template <typename T>
bool Decoder::packet(std::size_t offset, std::size_t size) {
    if (size != T::kSize) {
        return fail(at(kName<T>, offset) + ": size " + std::to_string(size) + ", expected " +
                    std::to_string(T::kSize));
    }
    if (kFromHost<T> != (from_ == Sender::Host)) {
        return fail(at(kName<T>, offset) + ": sent by the " +
                    (kFromHost<T> ? "host" : "image generator") + ", not the " +
                    (from_ == Sender::Host ? "host" : "image generator"));
    }
    if constexpr (std::is_same_v<T, IgControl> || std::is_same_v<T, StartOfFrame>) {
        if (offset != 0) return fail(at(kName<T>, offset) + ": only one per message, first");
    }
    T& p = std::get<T>(m_.packets.emplace_back(std::in_place_type<T>));
    const Reader b(d_.data() + offset, m_.byteOrder);
    decode(b, p);
    Checker c;
    check(p, c);
    if (!c.problem.empty()) {
        m_.packets.pop_back();
        return fail(at(kName<T>, offset) + ": " + c.problem);
    }
    return true;
}

bool Decoder::run() {
    m_.packets.clear();
    m_.skippedPackets = 0;
    if (!header()) return false;
    std::size_t offset = 0;
    while (offset < d_.size()) {
        const std::size_t left = d_.size() - offset;
        if (left < 2) {
            return fail("offset " + std::to_string(offset) +
                        ": 1 byte left, too short for a packet header");
        }
        const std::uint8_t id = d_[offset];
        const std::size_t size = d_[offset + 1];
        const std::string name = "packet id " + std::to_string(id);
        if (size < 2) {
            // A size of 0 would never advance: refused rather than looped on.
            return fail(at(name, offset) + ": size " + std::to_string(size) +
                        ", less than its own 2-byte header");
        }
        if (size > left) {
            return fail(at(name, offset) + ": size " + std::to_string(size) + " but only " +
                        std::to_string(left) + " bytes left in the datagram");
        }
        bool ok = true;
        switch (id) {
            case IgControl::kId:
                ok = packet<IgControl>(offset, size);
                break;
            case EntityControl::kId:
                ok = packet<EntityControl>(offset, size);
                break;
            case RateControl::kId:
                ok = packet<RateControl>(offset, size);
                break;
            case ViewControl::kId:
                ok = packet<ViewControl>(offset, size);
                break;
            case ViewDefinition::kId:
                ok = packet<ViewDefinition>(offset, size);
                break;
            case HatHotRequest::kId:
                ok = packet<HatHotRequest>(offset, size);
                break;
            case LosSegmentRequest::kId:
                ok = packet<LosSegmentRequest>(offset, size);
                break;
            case LosVectorRequest::kId:
                ok = packet<LosVectorRequest>(offset, size);
                break;
            case StartOfFrame::kId:
                ok = packet<StartOfFrame>(offset, size);
                break;
            case HatHotResponse::kId:
                ok = packet<HatHotResponse>(offset, size);
                break;
            case HatHotExtendedResponse::kId:
                ok = packet<HatHotExtendedResponse>(offset, size);
                break;
            case LosResponse::kId:
                ok = packet<LosResponse>(offset, size);
                break;
            case LosExtendedResponse::kId:
                ok = packet<LosExtendedResponse>(offset, size);
                break;
            case SensorControl::kId:
                ok = packet<SensorControl>(offset, size);
                break;
            case ComponentControl::kId:
                ok = packet<ComponentControl>(offset, size);
                break;
            case SensorResponse::kId:
                ok = packet<SensorResponse>(offset, size);
                break;
            case SensorExtendedResponse::kId:
                ok = packet<SensorExtendedResponse>(offset, size);
                break;
            default:
                ++m_.skippedPackets;
                break;
        }
        if (!ok) return false;
        offset += size;
    }
    return true;
}

}  // namespace

std::string_view packetName(const Packet& packet) {
    return std::visit([](const auto& p) { return kName<std::decay_t<decltype(p)>>; }, packet);
}

std::string validate(const Packet& packet) {
    Checker c;
    std::visit([&](const auto& p) { check(p, c); }, packet);
    return c.problem;
}

bool decodeMessage(std::span<const std::uint8_t> datagram, Sender from, Message& message,
                   std::string* error) {
    return Decoder(datagram, from, message, error).run();
}

void encodePacket(const Packet& packet, ByteOrder order, std::vector<std::uint8_t>& out) {
    const std::string problem = validate(packet);
    CHECK(problem.empty()) << packetName(packet) << ": " << problem;
    std::visit(
        [&](const auto& p) {
            using T = std::decay_t<decltype(p)>;
            const std::size_t at = out.size();
            out.resize(at + T::kSize, 0);
            Writer b(out.data() + at, order);
            b.u8(0, T::kId);
            b.u8(1, T::kSize);
            encode(p, b);
        },
        packet);
}

std::vector<std::uint8_t> encodeMessage(std::span<const Packet> packets, ByteOrder order) {
    CHECK(!packets.empty() && (std::holds_alternative<IgControl>(packets.front()) ||
                               std::holds_alternative<StartOfFrame>(packets.front())))
        << "a CIGI message starts with IG Control or Start of Frame";
    std::vector<std::uint8_t> out;
    for (const Packet& p : packets)
        encodePacket(p, order, out);
    return out;
}

}  // namespace io::cigi
