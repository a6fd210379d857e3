// One CIGI 3.3 packet of each kind, with every flag and field set to something recognisable;
// shared by the codec tests, the Wireshark cross-check and the fuzz corpus writer.
#pragma once

#include <vector>

#include "io/cigi.hpp"

namespace io::cigi::test {

inline IgControl sampleIgControl() {
    IgControl p;
    p.databaseNumber = -5;
    p.igMode = IgMode::Operate;
    p.timestampValid = true;
    p.extrapolationEnable = true;
    p.hostFrameNumber = 123456;
    p.timestamp = 987654;
    p.lastIgFrameNumber = 123455;
    return p;
}

inline StartOfFrame sampleStartOfFrame() {
    StartOfFrame p;
    p.databaseNumber = 7;
    p.igStatus = 3;
    p.igMode = IgMode::Debug;
    p.timestampValid = true;
    p.hostDefinedEarthModel = true;
    p.igFrameNumber = 4000000000u;
    p.timestamp = 1234567;
    p.lastHostFrameNumber = 77;
    return p;
}

// Host to image generator, IG Control first.
inline std::vector<Packet> sampleHostPackets() {
    std::vector<Packet> v;
    v.emplace_back(sampleIgControl());

    EntityControl e;
    e.entityId = 4660;
    e.entityState = EntityState::Active;
    e.collisionDetection = true;
    e.inheritAlpha = true;
    e.groundClamp = GroundClamp::Conformal;
    e.animationBackward = true;
    e.animationContinuous = true;
    e.animationState = AnimationState::Continue;
    e.extrapolationEnable = true;
    e.alpha = 200;
    e.entityType = 1001;
    e.parentId = 3;
    e.rollDeg = -12.5f;
    e.pitchDeg = 3.25f;
    e.yawDeg = 271.5f;
    e.latOrX = 47.6062;
    e.lonOrY = -122.3321;
    e.altOrZ = 1520.75;
    v.emplace_back(e);

    EntityControl child = e;
    child.entityId = 4661;
    child.attached = true;
    child.parentId = 4660;
    child.groundClamp = GroundClamp::None;
    child.latOrX = 250.5;  // offsets, not degrees
    child.lonOrY = -1000.25;
    child.altOrZ = -3.5;
    v.emplace_back(child);

    RateControl r;
    r.entityId = 4660;
    r.partId = 9;
    r.applyToPart = true;
    r.localCoordinates = true;
    r.xRate = 100.5f;
    r.yRate = -2.25f;
    r.zRate = 0.125f;
    r.rollRateDeg = 15.0f;
    r.pitchRateDeg = -3.5f;
    r.yawRateDeg = 1.75f;
    v.emplace_back(r);

    ViewControl vc;
    vc.viewId = 2;
    vc.groupId = 1;
    vc.xEnable = vc.zEnable = vc.pitchEnable = vc.yawEnable = true;
    vc.entityId = 4660;
    vc.x = 1.5f;
    vc.y = -0.25f;
    vc.z = 2.0f;
    vc.rollDeg = -170.0f;
    vc.pitchDeg = -45.0f;
    vc.yawDeg = 359.5f;
    v.emplace_back(vc);

    ViewDefinition vd;
    vd.viewId = 2;
    vd.groupId = 1;
    vd.nearEnable = vd.farEnable = vd.leftEnable = vd.rightEnable = true;
    vd.topEnable = vd.bottomEnable = true;
    vd.mirrorMode = MirrorMode::Vertical;
    vd.pixelReplication = 3;
    vd.orthographic = true;
    vd.reorder = true;
    vd.viewType = 5;
    vd.nearM = 0.5f;
    vd.farM = 50000.0f;
    vd.leftDeg = -30.0f;
    vd.rightDeg = 30.0f;
    vd.topDeg = 22.5f;
    vd.bottomDeg = -22.5f;
    v.emplace_back(vd);

    HatHotRequest h;
    h.requestId = 31;
    h.type = HatHotType::Extended;
    h.updatePeriod = 4;
    h.entityId = 0;
    h.latOrX = -33.9;
    h.lonOrY = 151.2;
    h.altOrZ = 3000.0;
    v.emplace_back(h);

    LosSegmentRequest s;
    s.requestId = 32;
    s.extended = true;
    s.destinationEntityCoordinates = true;
    s.responseEntityCoordinates = true;
    s.destinationEntityIdValid = true;
    s.alphaThreshold = 128;
    s.entityId = 4660;
    s.sourceLatOrX = 10.5;
    s.sourceLonOrY = 20.25;
    s.sourceAltOrZ = 500.0;
    s.destinationLatOrX = 100.0;
    s.destinationLonOrY = -50.0;
    s.destinationAltOrZ = -10.0;
    s.materialMask = 0xdeadbeef;
    s.updatePeriod = 2;
    s.destinationEntityId = 4661;
    v.emplace_back(s);

    LosVectorRequest lv;
    lv.requestId = 33;
    lv.extended = true;
    lv.sourceEntityCoordinates = true;
    lv.alphaThreshold = 64;
    lv.entityId = 4660;
    lv.azimuthDeg = -90.0f;
    lv.elevationDeg = -10.0f;
    lv.minRangeM = 5.0f;
    lv.maxRangeM = 20000.0f;
    lv.sourceLatOrX = 1.0;
    lv.sourceLonOrY = 2.0;
    lv.sourceAltOrZ = -3.0;
    lv.materialMask = 0x0000ffff;
    lv.updatePeriod = 1;
    v.emplace_back(lv);

    SensorControl sc;
    sc.viewId = 2;
    sc.sensorId = 7;
    sc.sensorOn = true;
    sc.blackHot = true;
    sc.autoGain = true;
    sc.trackBlack = true;
    sc.trackMode = SensorTrackMode::Target;
    sc.extendedResponse = true;
    sc.gain = 0.75f;
    sc.level = -0.5f;
    sc.acCoupling = 2.5f;
    sc.noise = 0.125f;
    v.emplace_back(sc);

    ComponentControl cc;
    cc.componentId = 1;
    cc.instanceId = 7;
    cc.componentClass = kComponentClassSensor;
    cc.componentState = 2;
    cc.data[0] = 4661;
    cc.data[5] = 0xcafef00d;
    v.emplace_back(cc);
    return v;
}

// Image generator to host, Start of Frame first.
inline std::vector<Packet> sampleIgPackets() {
    std::vector<Packet> v;
    v.emplace_back(sampleStartOfFrame());

    HatHotResponse h;
    h.requestId = 31;
    h.valid = true;
    h.isHot = true;
    h.hostFrameLsn = 9;
    h.heightM = 123.375;
    v.emplace_back(h);

    HatHotExtendedResponse x;
    x.requestId = 31;
    x.valid = true;
    x.hostFrameLsn = 15;
    x.hatM = 2876.625;
    x.hotM = 123.375;
    x.materialCode = 42;
    x.normalAzimuthDeg = -135.0f;
    x.normalElevationDeg = 80.5f;
    v.emplace_back(x);

    LosResponse l;
    l.requestId = 33;
    l.valid = true;
    l.entityIdValid = true;
    l.visible = true;
    l.hostFrameLsn = 6;
    l.responseCount = 2;
    l.entityId = 4661;
    l.rangeM = 15000.5;
    v.emplace_back(l);

    LosExtendedResponse le;
    le.requestId = 32;
    le.valid = true;
    le.rangeValid = true;
    le.hostFrameLsn = 12;
    le.responseCount = 1;
    le.entityId = 0;
    le.rangeM = 812.25;
    le.latOrX = 47.5;
    le.lonOrY = -122.25;
    le.altOrZ = 61.0;
    le.red = 10;
    le.green = 20;
    le.blue = 30;
    le.alpha = 255;
    le.materialCode = 7;
    le.normalAzimuthDeg = 45.0f;
    le.normalElevationDeg = 60.0f;
    v.emplace_back(le);

    SensorResponse sr;
    sr.viewId = 2;
    sr.sensorId = 7;
    sr.status = SensorStatus::Tracking;
    sr.gateXSize = 24;
    sr.gateYSize = 18;
    sr.gateXDeg = -3.25f;
    sr.gateYDeg = 1.5f;
    sr.frameCounter = 3000000000u;
    v.emplace_back(sr);

    SensorExtendedResponse sx;
    sx.viewId = 2;
    sx.sensorId = 7;
    sx.status = SensorStatus::Breaklock;
    sx.entityIdValid = true;
    sx.entityId = 4661;
    sx.gateXSize = 40;
    sx.gateYSize = 30;
    sx.gateXDeg = 12.75f;
    sx.gateYDeg = -6.5f;
    sx.frameCounter = 99;
    sx.latDeg = 47.625;
    sx.lonDeg = -122.375;
    sx.altM = 450.5;
    v.emplace_back(sx);
    return v;
}

}  // namespace io::cigi::test
