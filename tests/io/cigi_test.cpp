#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "cigi_samples.hpp"
#include "io/cigi.hpp"

namespace io::cigi {
namespace {

using Bytes = std::vector<std::uint8_t>;
constexpr ByteOrder kOrders[] = {ByteOrder::Big, ByteOrder::Little};

const char* orderName(ByteOrder o) {
    return o == ByteOrder::Big ? "big-endian" : "little-endian";
}

// Decodes and expects success.
Message decodeOk(const Bytes& d, Sender from) {
    Message m;
    std::string error;
    EXPECT_TRUE(decodeMessage(d, from, m, &error)) << error;
    return m;
}

// Decodes and expects a refusal; returns the message.
std::string decodeError(const Bytes& d, Sender from) {
    Message m;
    std::string error;
    EXPECT_FALSE(decodeMessage(d, from, m, &error)) << "accepted " << d.size() << " bytes";
    EXPECT_FALSE(error.empty());
    return error;
}

Bytes hostMessage(const Packet& p, ByteOrder order = ByteOrder::Big) {
    const std::vector<Packet> v{test::sampleIgControl(), p};
    return encodeMessage(v, order);
}

// --- Round trips

TEST(CigiCodec, EveryPacketRoundTripsInBothByteOrders) {
    for (const ByteOrder order : kOrders) {
        for (const auto& [packets, from] :
             {std::pair{test::sampleHostPackets(), Sender::Host},
              std::pair{test::sampleIgPackets(), Sender::ImageGenerator}}) {
            for (std::size_t i = 1; i < packets.size(); ++i) {
                const std::vector<Packet> two{packets[0], packets[i]};
                const Bytes d = encodeMessage(two, order);
                const Message m = decodeOk(d, from);
                EXPECT_EQ(m.byteOrder, order);
                ASSERT_EQ(m.packets.size(), 2u) << packetName(packets[i]);
                EXPECT_TRUE(m.packets[0] == packets[0]) << orderName(order);
                EXPECT_TRUE(m.packets[1] == packets[i])
                    << packetName(packets[i]) << " " << orderName(order);
            }
            // All of them in one datagram, sizes adding up.
            const Bytes d = encodeMessage(packets, order);
            const Message m = decodeOk(d, from);
            EXPECT_TRUE(m.packets == packets) << orderName(order);
            EXPECT_EQ(m.skippedPackets, 0u);
        }
    }
}

TEST(CigiCodec, PacketSizesAreTheStandards) {
    const std::pair<Packet, std::size_t> sizes[] = {
        {IgControl{}, 24},           {EntityControl{}, 48},          {RateControl{}, 32},
        {ViewControl{}, 32},         {ViewDefinition{}, 32},         {HatHotRequest{}, 32},
        {LosSegmentRequest{}, 64},   {LosVectorRequest{}, 56},       {StartOfFrame{}, 24},
        {HatHotResponse{}, 16},      {HatHotExtendedResponse{}, 40}, {LosResponse{}, 16},
        {LosExtendedResponse{}, 56}, {SensorControl{}, 24},          {ComponentControl{}, 32},
        {SensorResponse{}, 24},      {SensorExtendedResponse{}, 48}};
    for (const auto& [p, size] : sizes) {
        Bytes out;
        encodePacket(p, ByteOrder::Big, out);
        EXPECT_EQ(out.size(), size) << packetName(p);
        EXPECT_EQ(out[1], size) << packetName(p);
        EXPECT_EQ(out.size() % 8, 0u) << packetName(p);
    }
}

TEST(CigiCodec, ByteOrdersMirrorEachField) {
    const Packet e = test::sampleHostPackets()[1];
    Bytes big, little;
    encodePacket(e, ByteOrder::Big, big);
    encodePacket(e, ByteOrder::Little, little);
    ASSERT_EQ(big.size(), little.size());
    // Entity id 4660 = 0x1234 at bytes 2-3; latitude (8 bytes) at 24-31.
    EXPECT_EQ(big[2], 0x12);
    EXPECT_EQ(big[3], 0x34);
    EXPECT_EQ(little[2], 0x34);
    EXPECT_EQ(little[3], 0x12);
    for (int i = 0; i < 8; ++i)
        EXPECT_EQ(big[24 + i], little[31 - i]) << i;
    // One-byte fields are the same in both.
    EXPECT_EQ(big[4], little[4]);
    EXPECT_EQ(big[5], little[5]);
    // The magic number tells the orders apart.
    const Bytes bigMessage = encodeMessage(std::vector<Packet>{IgControl{}}, ByteOrder::Big);
    const Bytes littleMessage = encodeMessage(std::vector<Packet>{IgControl{}}, ByteOrder::Little);
    EXPECT_EQ(bigMessage[6], 0x80);
    EXPECT_EQ(bigMessage[7], 0x00);
    EXPECT_EQ(littleMessage[6], 0x00);
    EXPECT_EQ(littleMessage[7], 0x80);
}

// --- Byte images written by hand from the standard's layouts

const Bytes kIgControlBig = {
    0x01, 0x18, 0x03, 0x05,  // id 1, 24 bytes, major version 3, database 5
    0x35, 0x00, 0x80, 0x00,  // minor 3 << 4 | timestamp valid (bit 2) | operate (1); magic
    0x00, 0x00, 0x00, 0x2a,  // host frame 42
    0x00, 0x01, 0x86, 0xa0,  // timestamp 100000
    0x00, 0x00, 0x00, 0x29,  // last IG frame 41
    0x00, 0x00, 0x00, 0x00};
const Bytes kIgControlLittle = {0x01, 0x18, 0x03, 0x05, 0x35, 0x00, 0x00, 0x80,
                                0x2a, 0x00, 0x00, 0x00, 0xa0, 0x86, 0x01, 0x00,
                                0x29, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00};

TEST(CigiCodec, HandWrittenIgControlInBothOrders) {
    for (const Bytes* d : {&kIgControlBig, &kIgControlLittle}) {
        const Message m = decodeOk(*d, Sender::Host);
        EXPECT_EQ(m.byteOrder, d == &kIgControlBig ? ByteOrder::Big : ByteOrder::Little);
        ASSERT_EQ(m.packets.size(), 1u);
        const auto& p = std::get<IgControl>(m.packets[0]);
        EXPECT_EQ(p.databaseNumber, 5);
        EXPECT_EQ(p.igMode, IgMode::Operate);
        EXPECT_TRUE(p.timestampValid);
        EXPECT_FALSE(p.extrapolationEnable);
        EXPECT_EQ(p.hostFrameNumber, 42u);
        EXPECT_EQ(p.timestamp, 100000u);
        EXPECT_EQ(p.lastIgFrameNumber, 41u);
        // And our encoder writes the same bytes.
        const std::vector<Packet> v{p};
        EXPECT_EQ(encodeMessage(v, m.byteOrder), *d);
    }
}

TEST(CigiCodec, HandWrittenEntityControl) {
    Bytes d = kIgControlBig;
    const Bytes entity = {
        0x02, 0x30, 0x00, 0x07,  // id 2, 48 bytes, entity 7
        0x41, 0x0a, 0xff, 0x00,  // active (1) | conformal clamp (2 << 5); play (2 << 2) | loop
        0x00, 0x0b, 0x00, 0x00,  // type 11, parent 0
        0x42, 0x34, 0x00, 0x00,  // roll 45
        0xc2, 0x34, 0x00, 0x00,  // pitch -45
        0x42, 0xb4, 0x00, 0x00,  // yaw 90
        0x40, 0x47, 0xc0, 0x00, 0x00, 0x00, 0x00, 0x00,   // latitude 47.5
        0xc0, 0x5e, 0x90, 0x00, 0x00, 0x00, 0x00, 0x00,   // longitude -122.25
        0x40, 0x59, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00};  // altitude 100
    d.insert(d.end(), entity.begin(), entity.end());
    const Message m = decodeOk(d, Sender::Host);
    ASSERT_EQ(m.packets.size(), 2u);
    const auto& e = std::get<EntityControl>(m.packets[1]);
    EXPECT_EQ(e.entityId, 7);
    EXPECT_EQ(e.entityState, EntityState::Active);
    EXPECT_FALSE(e.attached);
    EXPECT_FALSE(e.collisionDetection);
    EXPECT_EQ(e.groundClamp, GroundClamp::Conformal);
    EXPECT_EQ(e.animationState, AnimationState::Play);
    EXPECT_TRUE(e.animationContinuous);
    EXPECT_FALSE(e.animationBackward);
    EXPECT_FALSE(e.extrapolationEnable);
    EXPECT_EQ(e.alpha, 255);
    EXPECT_EQ(e.entityType, 11);
    EXPECT_EQ(e.rollDeg, 45.0f);
    EXPECT_EQ(e.pitchDeg, -45.0f);
    EXPECT_EQ(e.yawDeg, 90.0f);
    EXPECT_EQ(e.latOrX, 47.5);
    EXPECT_EQ(e.lonOrY, -122.25);
    EXPECT_EQ(e.altOrZ, 100.0);
}

TEST(CigiCodec, HandWrittenLosVectorRequest) {
    Bytes d = kIgControlBig;
    const Bytes los = {
        0x1a, 0x38, 0x00, 0x09,  // id 26, 56 bytes, request 9
        0x03, 0x80, 0x00, 0x00,  // extended | source in entity coordinates; alpha 128; entity 0
        0x42, 0x34, 0x00, 0x00,  // azimuth 45
        0xc2, 0x34, 0x00, 0x00,  // elevation -45
        0x3f, 0xc0, 0x00, 0x00,  // minimum range 1.5
        0x44, 0x7a, 0x00, 0x00,  // maximum range 1000
        0x3f, 0xf0, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // x 1
        0xc0, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // y -2
        0x3f, 0xe0, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // z 0.5
        0x00, 0x00, 0x00, 0xff,                          // material mask
        0x03, 0x00, 0x00, 0x00};                         // update period 3
    d.insert(d.end(), los.begin(), los.end());
    const Message m = decodeOk(d, Sender::Host);
    ASSERT_EQ(m.packets.size(), 2u);
    const auto& p = std::get<LosVectorRequest>(m.packets[1]);
    EXPECT_EQ(p.requestId, 9);
    EXPECT_TRUE(p.extended);
    EXPECT_TRUE(p.sourceEntityCoordinates);
    EXPECT_FALSE(p.responseEntityCoordinates);
    EXPECT_EQ(p.alphaThreshold, 128);
    EXPECT_EQ(p.azimuthDeg, 45.0f);
    EXPECT_EQ(p.elevationDeg, -45.0f);
    EXPECT_EQ(p.minRangeM, 1.5f);
    EXPECT_EQ(p.maxRangeM, 1000.0f);
    EXPECT_EQ(p.sourceLatOrX, 1.0);
    EXPECT_EQ(p.sourceLonOrY, -2.0);
    EXPECT_EQ(p.sourceAltOrZ, 0.5);
    EXPECT_EQ(p.materialMask, 0xffu);
    EXPECT_EQ(p.updatePeriod, 3);
}

TEST(CigiCodec, HandWrittenStartOfFrameAndHatHotResponseLittleEndian) {
    const Bytes d = {
        0x65, 0x18, 0x03, 0x02,  // id 101, 24 bytes, version 3, database 2
        0x00, 0x31, 0x00, 0x80,  // status 0; minor 3 << 4 | operate; magic (little-endian)
        0xe8, 0x03, 0x00, 0x00,  // IG frame 1000
        0x00, 0x00, 0x00, 0x00,  // timestamp 0
        0xe7, 0x03, 0x00, 0x00,  // last host frame 999
        0x00, 0x00, 0x00, 0x00, 0x66, 0x10, 0x05, 0x00,  // id 102, 16 bytes, request 5
        0xa3, 0x00, 0x00, 0x00,  // valid | HOT (bit 1) | host frame LSN 10 << 4
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x59, 0x40};  // height 100
    const Message m = decodeOk(d, Sender::ImageGenerator);
    EXPECT_EQ(m.byteOrder, ByteOrder::Little);
    ASSERT_EQ(m.packets.size(), 2u);
    const auto& s = std::get<StartOfFrame>(m.packets[0]);
    EXPECT_EQ(s.databaseNumber, 2);
    EXPECT_EQ(s.igStatus, 0);
    EXPECT_EQ(s.igMode, IgMode::Operate);
    EXPECT_FALSE(s.timestampValid);
    EXPECT_EQ(s.igFrameNumber, 1000u);
    EXPECT_EQ(s.lastHostFrameNumber, 999u);
    const auto& h = std::get<HatHotResponse>(m.packets[1]);
    EXPECT_EQ(h.requestId, 5);
    EXPECT_TRUE(h.valid);
    EXPECT_TRUE(h.isHot);
    EXPECT_EQ(h.hostFrameLsn, 10);
    EXPECT_EQ(h.heightM, 100.0);
}

TEST(CigiCodec, HandWrittenSensorControlAndComponentControl) {
    Bytes d = kIgControlBig;
    const Bytes sensor = {0x11, 0x18, 0x00, 0x02,   // id 17, 24 bytes, view 2
                          0x07, 0x7b, 0x01, 0x00,   // sensor 7; on | black hot | auto gain | track
                                                    // black | target (3 << 5); extended response
                          0x3f, 0x40, 0x00, 0x00,   // gain 0.75
                          0xbf, 0x00, 0x00, 0x00,   // level -0.5
                          0x40, 0x20, 0x00, 0x00,   // AC coupling 2.5
                          0x3e, 0x00, 0x00, 0x00};  // noise 0.125
    const Bytes component = {0x04, 0x20, 0x00, 0x01,   // id 4, 32 bytes, component 1
                             0x00, 0x07, 0x03, 0x02,   // instance 7, class 3 (sensor), state 2
                             0x00, 0x00, 0x12, 0x35,   // data word 1: 4661
                             0x00, 0x00, 0x00, 0x00,   // data word 2
                             0x00, 0x00, 0x00, 0x00,   // data word 3
                             0x00, 0x00, 0x00, 0x00,   // data word 4
                             0x00, 0x00, 0x00, 0x00,   // data word 5
                             0xca, 0xfe, 0xf0, 0x0d};  // data word 6
    d.insert(d.end(), sensor.begin(), sensor.end());
    d.insert(d.end(), component.begin(), component.end());
    const Message m = decodeOk(d, Sender::Host);
    ASSERT_EQ(m.packets.size(), 3u);
    const auto samples = test::sampleHostPackets();
    const auto& s = std::get<SensorControl>(m.packets[1]);
    EXPECT_TRUE(m.packets[1] == samples[samples.size() - 2]);
    EXPECT_EQ(s.trackMode, SensorTrackMode::Target);
    EXPECT_FALSE(s.lineDropout);
    EXPECT_TRUE(m.packets[2] == samples.back());
    EXPECT_EQ(encodeMessage(m.packets, ByteOrder::Big), d);
}

TEST(CigiCodec, HandWrittenSensorResponsesLittleEndian) {
    Bytes d = encodeMessage(std::vector<Packet>{test::sampleStartOfFrame()}, ByteOrder::Little);
    const Bytes response = {0x6a, 0x18, 0x02, 0x00,   // id 106, 24 bytes, view 2
                            0x07, 0x01, 0x00, 0x00,   // sensor 7, tracking
                            0x18, 0x00, 0x12, 0x00,   // gate 24 x 18
                            0x00, 0x00, 0x50, 0xc0,   // gate x -3.25
                            0x00, 0x00, 0xc0, 0x3f,   // gate y 1.5
                            0x00, 0x5e, 0xd0, 0xb2};  // frame 3000000000
    const Bytes extended = {
        0x6b, 0x30, 0x02, 0x00,  // id 107, 48 bytes, view 2
        0x07, 0x07, 0x35, 0x12,  // sensor 7, breaklock (3) | entity id valid; entity 4661
        0x28, 0x00, 0x1e, 0x00,  // gate 40 x 30
        0x00, 0x00, 0x4c, 0x41,  // gate x 12.75
        0x00, 0x00, 0xd0, 0xc0,  // gate y -6.5
        0x63, 0x00, 0x00, 0x00,  // frame 99
        0x00, 0x00, 0x00, 0x00, 0x00, 0xd0, 0x47, 0x40,   // latitude 47.625
        0x00, 0x00, 0x00, 0x00, 0x00, 0x98, 0x5e, 0xc0,   // longitude -122.375
        0x00, 0x00, 0x00, 0x00, 0x00, 0x28, 0x7c, 0x40};  // altitude 450.5
    d.insert(d.end(), response.begin(), response.end());
    d.insert(d.end(), extended.begin(), extended.end());
    const Message m = decodeOk(d, Sender::ImageGenerator);
    ASSERT_EQ(m.packets.size(), 3u);
    const auto samples = test::sampleIgPackets();
    EXPECT_TRUE(m.packets[1] == samples[samples.size() - 2]);
    EXPECT_TRUE(m.packets[2] == samples.back());
    const auto& x = std::get<SensorExtendedResponse>(m.packets[2]);
    EXPECT_EQ(x.status, SensorStatus::Breaklock);
    EXPECT_EQ(x.altM, 450.5);
    EXPECT_EQ(encodeMessage(m.packets, ByteOrder::Little), d);
}

// --- Refusals

TEST(CigiCodec, EmptyAndTinyDatagramsAreRefused) {
    EXPECT_NE(decodeError({}, Sender::Host).find("too short"), std::string::npos);
    EXPECT_NE(decodeError({0x01}, Sender::Host).find("too short"), std::string::npos);
    Bytes d = kIgControlBig;
    d.resize(10);
    EXPECT_NE(decodeError(d, Sender::Host).find("truncated, 10 of its 24 bytes"),
              std::string::npos);
}

TEST(CigiCodec, HostMessageMustStartWithIgControl) {
    Bytes entity;
    encodePacket(test::sampleHostPackets()[1], ByteOrder::Big, entity);
    const std::string e = decodeError(entity, Sender::Host);
    EXPECT_NE(e.find("from the host"), std::string::npos) << e;
    EXPECT_NE(e.find("first packet is id 2, not IG Control (id 1)"), std::string::npos) << e;
    // And an image generator's message with Start of Frame.
    const std::string f = decodeError(kIgControlBig, Sender::ImageGenerator);
    EXPECT_NE(f.find("not Start of Frame (id 101)"), std::string::npos) << f;
}

TEST(CigiCodec, PacketsOfTheOtherDirectionAndSecondIgControlAreRefused) {
    Bytes d = kIgControlBig;
    encodePacket(test::sampleIgPackets()[1], ByteOrder::Big, d);
    std::string e = decodeError(d, Sender::Host);
    EXPECT_NE(e.find("HAT/HOT Response (id 102) at offset 24: sent by the image generator"),
              std::string::npos)
        << e;
    d = kIgControlBig;
    d.insert(d.end(), kIgControlBig.begin(), kIgControlBig.end());
    e = decodeError(d, Sender::Host);
    EXPECT_NE(e.find("IG Control (id 1) at offset 24: only one per message"), std::string::npos)
        << e;
}

TEST(CigiCodec, VersionAndMagicAreChecked) {
    Bytes d = kIgControlBig;
    d[2] = 2;
    EXPECT_NE(decodeError(d, Sender::Host).find("major version 2"), std::string::npos);
    d = kIgControlBig;
    d[4] = 0x25;  // minor version 2
    EXPECT_NE(decodeError(d, Sender::Host).find("version 3.2"), std::string::npos);
    d = kIgControlBig;
    d[6] = 0x12;
    d[7] = 0x34;
    EXPECT_NE(decodeError(d, Sender::Host).find("magic 0x1234"), std::string::npos);
}

TEST(CigiCodec, TruncatedDatagramsAreRefusedWhereverTheyAreCut) {
    for (const ByteOrder order : kOrders) {
        const std::vector<Packet> packets = test::sampleHostPackets();
        const Bytes full = encodeMessage(packets, order);
        std::vector<std::size_t> boundaries{0};
        for (const Packet& p : packets) {
            Bytes one;
            encodePacket(p, order, one);
            boundaries.push_back(boundaries.back() + one.size());
        }
        for (std::size_t n = 0; n < full.size(); ++n) {
            const Bytes cut(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(n));
            Message m;
            std::string error;
            const bool ok = decodeMessage(cut, Sender::Host, m, &error);
            const bool onBoundary =
                n >= 24 && std::find(boundaries.begin(), boundaries.end(), n) != boundaries.end();
            EXPECT_EQ(ok, onBoundary) << n << " bytes: " << error;
        }
    }
}

TEST(CigiCodec, WrongSizeIsRefusedNamingPacketAndOffset) {
    Bytes d = hostMessage(test::sampleHostPackets()[1]);
    d[24 + 1] = 40;  // Entity Control claims 40 bytes, the datagram still holds 48
    const std::string e = decodeError(d, Sender::Host);
    EXPECT_NE(e.find("Entity Control (id 2) at offset 24: size 40, expected 48"), std::string::npos)
        << e;
    d[24 + 1] = 56;  // more than is left
    EXPECT_NE(decodeError(d, Sender::Host).find("size 56 but only 48 bytes left"),
              std::string::npos);
}

TEST(CigiCodec, SizeZeroOrOneIsRefusedNotLoopedOn) {
    for (const std::uint8_t id : {std::uint8_t{2}, std::uint8_t{200}}) {
        for (const std::uint8_t size : {std::uint8_t{0}, std::uint8_t{1}}) {
            Bytes d = kIgControlBig;
            d.insert(d.end(), {id, size, 0, 0, 0, 0, 0, 0});
            const std::string e = decodeError(d, Sender::Host);
            EXPECT_NE(e.find("at offset 24: size " + std::to_string(size) +
                             ", less than its own 2-byte header"),
                      std::string::npos)
                << e;
        }
    }
    Bytes d = kIgControlBig;
    d.push_back(2);  // one stray byte
    EXPECT_NE(decodeError(d, Sender::Host).find("offset 24: 1 byte left"), std::string::npos);
}

TEST(CigiCodec, UnknownPacketsAreSkippedBySize) {
    Bytes d = kIgControlBig;
    // Articulated Part Control (id 6, 32 bytes) and a user-defined packet (id 201, 12 bytes).
    Bytes unknown(32, 0x5a);
    unknown[0] = 6;
    unknown[1] = 32;
    d.insert(d.end(), unknown.begin(), unknown.end());
    d.insert(d.end(), {201, 12, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10});
    encodePacket(test::sampleHostPackets()[1], ByteOrder::Big, d);
    const Message m = decodeOk(d, Sender::Host);
    EXPECT_EQ(m.skippedPackets, 2u);
    ASSERT_EQ(m.packets.size(), 2u);
    EXPECT_TRUE(m.packets[1] == test::sampleHostPackets()[1]);
}

TEST(CigiCodec, OutOfRangeEnumsAreRefused) {
    Bytes d = kIgControlBig;
    d[4] = 0x33;  // IG mode 3 from a host
    std::string e = decodeError(d, Sender::Host);
    EXPECT_NE(e.find("IG Control (id 1) at offset 0: IG mode 3 is not one of"), std::string::npos)
        << e;

    const Bytes entity = hostMessage(test::sampleHostPackets()[1]);
    d = entity;
    d[24 + 4] = static_cast<std::uint8_t>((d[24 + 4] & ~0x03) | 0x03);  // entity state 3
    e = decodeError(d, Sender::Host);
    EXPECT_NE(e.find("Entity Control (id 2) at offset 24: entity state 3"), std::string::npos) << e;
    d = entity;
    d[24 + 4] = static_cast<std::uint8_t>(d[24 + 4] | 0x60);  // clamp 3
    EXPECT_NE(decodeError(d, Sender::Host).find("ground/ocean clamp 3"), std::string::npos);

    d = hostMessage(test::sampleHostPackets()[6]);  // HAT/HOT request
    d[24 + 4] = static_cast<std::uint8_t>(d[24 + 4] | 0x03);
    EXPECT_NE(decodeError(d, Sender::Host)
                  .find("HAT/HOT Request (id 24) at offset 24: request "
                        "type 3"),
              std::string::npos);
}

TEST(CigiCodec, NonFiniteAndOutOfRangeNumbersAreRefused) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    for (const ByteOrder order : kOrders) {
        auto entity = std::get<EntityControl>(test::sampleHostPackets()[1]);
        // Encoding refuses invalid packets (a CHECK), so the bad value is written into the bytes.
        const Bytes good = hostMessage(entity, order);
        auto withDouble = [&](std::size_t at, double v) {
            Bytes d = good;
            std::uint64_t bits;
            std::memcpy(&bits, &v, 8);
            for (int i = 0; i < 8; ++i) {
                const int shift = order == ByteOrder::Big ? 8 * (7 - i) : 8 * i;
                d[24 + at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(bits >> shift);
            }
            return d;
        };
        std::string e = decodeError(withDouble(24, nan), Sender::Host);
        EXPECT_NE(e.find("Entity Control (id 2) at offset 24: latitude nan is outside [-90, 90]"),
                  std::string::npos)
            << e;
        EXPECT_NE(decodeError(withDouble(24, 91.0), Sender::Host).find("latitude 91"),
                  std::string::npos);
        EXPECT_NE(decodeError(withDouble(32, -180.5), Sender::Host).find("longitude -180.5"),
                  std::string::npos);
        e = decodeError(withDouble(40, inf), Sender::Host);
        EXPECT_NE(e.find("altitude is inf, not a finite number"), std::string::npos) << e;
    }
    // Through validate(), for every kind that holds numbers.
    auto problem = [](Packet p) { return validate(p); };
    EntityControl e;
    e.attached = true;
    e.latOrX = 1e6;  // an offset, not a latitude
    EXPECT_EQ(problem(e), "");
    e.yawDeg = 360.5f;
    EXPECT_EQ(problem(e), "yaw 360.5 is outside [0, 360] degrees");
    ViewControl v;
    v.pitchDeg = std::numeric_limits<float>::quiet_NaN();
    EXPECT_EQ(problem(v), "pitch nan is outside [-90, 90] degrees");
    ViewDefinition vd;
    vd.nearM = -1;
    EXPECT_EQ(problem(vd), "near clipping plane -1 is below 0 metres");
    vd = {};
    vd.topDeg = 91;
    EXPECT_EQ(problem(vd), "top half angle 91 is outside [-90, 90] degrees");
    vd = {};
    vd.viewType = 8;
    EXPECT_EQ(problem(vd), "view type 8 does not fit in its 3 bits");
    RateControl r;
    r.yawRateDeg = std::numeric_limits<float>::infinity();
    EXPECT_EQ(problem(r), "yaw rate is inf, not a finite number");
    LosVectorRequest lv;
    lv.minRangeM = 10;
    lv.maxRangeM = 5;
    EXPECT_EQ(problem(lv), "maximum range 5 is below 10 metres (the minimum range)");
    LosSegmentRequest ls;
    ls.destinationLonOrY = 200;
    EXPECT_EQ(problem(ls), "destination longitude 200 is outside [-180, 180] degrees");
    HatHotRequest h;
    h.altOrZ = nan;
    EXPECT_EQ(problem(h), "altitude is nan, not a finite number");
    HatHotResponse hr;
    hr.hostFrameLsn = 16;
    EXPECT_EQ(problem(hr), "host frame number LSN 16 does not fit in its 4 bits");
    HatHotExtendedResponse hx;
    hx.normalElevationDeg = -91;
    EXPECT_EQ(problem(hx), "normal elevation -91 is outside [-90, 90] degrees");
    LosResponse lr;
    lr.rangeM = -1;
    EXPECT_EQ(problem(lr), "range -1 is below 0 metres");
    LosExtendedResponse lx;
    lx.altOrZ = inf;
    EXPECT_EQ(problem(lx), "intersection z offset is inf, not a finite number");
    EntityControl animated;
    animated.animationState = static_cast<AnimationState>(4);  // does not fit its 2 bits
    EXPECT_EQ(problem(animated),
              "animation state 4 is not one of 0 (stop), 1 (pause), 2 (play), "
              "3 (continue)");
    SensorControl sc;
    sc.gain = 1.5f;
    EXPECT_EQ(problem(sc), "gain 1.5 is outside [0, 1] (a fraction of full gain)");
    sc = {};
    sc.noise = std::numeric_limits<float>::quiet_NaN();
    EXPECT_EQ(problem(sc), "noise is nan, not a finite number");
    ComponentControl cc;
    cc.componentClass = 16;
    EXPECT_EQ(problem(cc),
              "component class 16 is not one of 0-15 (entity, view, view group, sensor, ... "
              "symbol); 16-63 are reserved");
    SensorResponse sr;
    sr.gateXDeg = 181;
    EXPECT_EQ(problem(sr), "gate x position 181 is outside [-180, 180] degrees");
    SensorExtendedResponse sx;
    sx.latDeg = -90.5;
    EXPECT_EQ(problem(sx), "track point latitude -90.5 is outside [-90, 90] degrees");
    StartOfFrame s;
    s.igMode = static_cast<IgMode>(4);
    EXPECT_EQ(problem(s),
              "IG mode 4 is not one of 0 (reset/standby), 1 (operate), 2 (debug), "
              "3 (offline maintenance)");
}

TEST(CigiCodec, AFailedDecodeKeepsThePacketsBeforeTheProblem) {
    Message m;
    std::string error;
    Bytes d = encodeMessage(test::sampleHostPackets(), ByteOrder::Little);
    d.push_back(0);
    EXPECT_FALSE(decodeMessage(d, Sender::Host, m, &error));
    EXPECT_EQ(m.packets.size(), test::sampleHostPackets().size());
    // The same Message decodes the next datagram from scratch.
    EXPECT_TRUE(decodeMessage(kIgControlBig, Sender::Host, m, &error)) << error;
    EXPECT_EQ(m.packets.size(), 1u);
    EXPECT_EQ(m.byteOrder, ByteOrder::Big);
    // A null error pointer is allowed.
    EXPECT_FALSE(decodeMessage(Bytes{}, Sender::Host, m, nullptr));
}

TEST(CigiCodec, EveryByteChangeDecodesOrIsRefusedCleanly) {
    for (const auto& [packets, from] :
         {std::pair{test::sampleHostPackets(), Sender::Host},
          std::pair{test::sampleIgPackets(), Sender::ImageGenerator}}) {
        const Bytes good = encodeMessage(packets, ByteOrder::Big);
        Message m;
        std::string error;
        for (std::size_t i = 0; i < good.size(); ++i) {
            for (const std::uint8_t v : {0x00, 0x01, 0x7f, 0x80, 0xff}) {
                Bytes d = good;
                d[i] = v;
                error.clear();
                if (decodeMessage(d, from, m, &error)) {
                    // Accepted: it re-encodes to the bytes it came from, reserved bytes aside.
                    const Bytes again = encodeMessage(m.packets, m.byteOrder);
                    Message m2;
                    ASSERT_TRUE(decodeMessage(again, from, m2, &error)) << error;
                    EXPECT_TRUE(m2.packets == m.packets) << "byte " << i;
                } else {
                    EXPECT_LT(error.size(), 300u) << error;
                }
            }
        }
    }
}

TEST(CigiCodecDeathTest, EncodingAnInvalidPacketIsABug) {
    EntityControl e;
    e.pitchDeg = 95;
    Bytes out;
    EXPECT_DEATH(encodePacket(e, ByteOrder::Big, out), "pitch 95 is outside");
    EXPECT_DEATH((void)encodeMessage(std::vector<Packet>{e}, ByteOrder::Big),
                 "starts with IG Control");
}

}  // namespace
}  // namespace io::cigi
