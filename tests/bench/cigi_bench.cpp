// CIGI: packets decoded a second (one host message of six packets), and datagrams a second a
// session takes from a loopback socket, decodes and applies (what bounds a flood).
#include "ig/synthetic.hpp"
#include "io/cigi.hpp"
#include "io/udp_socket.hpp"
#include "sim/cigi_session.hpp"

#include <benchmark/benchmark.h>

#include <cerrno>
#include <string>
#include <vector>

namespace {

namespace cigi = io::cigi;

// A host frame as a real host sends it: IG Control, the ownship, its rates, a view, a HAT/HOT
// request and a line-of-sight vector request.
std::vector<std::uint8_t> hostMessage() {
    cigi::IgControl ig;
    ig.hostFrameNumber = 1234;
    cigi::EntityControl e;
    e.latOrX = 47.1;
    e.lonOrY = -121.9;
    e.altOrZ = 2000.0;
    e.yawDeg = 40.0f;
    e.pitchDeg = -3.0f;
    cigi::RateControl r;
    r.xRate = 120.0f;
    r.yRate = 100.0f;
    cigi::ViewControl v;
    v.yawEnable = true;
    v.yawDeg = 30.0f;
    cigi::HatHotRequest h;
    h.latOrX = 47.1;
    h.lonOrY = -121.9;
    cigi::LosVectorRequest l;
    l.maxRangeM = 10000.0f;
    l.sourceLatOrX = 47.1;
    l.sourceLonOrY = -121.9;
    l.sourceAltOrZ = 2000.0;
    const std::vector<cigi::Packet> packets{ig, e, r, v, h, l};
    return cigi::encodeMessage(packets, cigi::ByteOrder::Big);
}

void BM_DecodeHostMessage(benchmark::State& state) {
    const std::vector<std::uint8_t> bytes = hostMessage();
    cigi::Message message;
    for (auto _ : state) {
        const bool ok = cigi::decodeMessage(bytes, cigi::Sender::Host, message, nullptr);
        benchmark::DoNotOptimize(ok);
        benchmark::DoNotOptimize(message.packets.data());
    }
    state.SetItemsProcessed(state.iterations() * 6);  // packets
    state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(bytes.size()));
}
BENCHMARK(BM_DecodeHostMessage);

// 256 host messages (IG Control, Entity Control, Rate Control) sent, then one poll takes them:
// receive, decode, apply, and its Start of Frame sent. Items: datagrams.
void BM_SessionPollFlood(benchmark::State& state) {
    const ig::TerrainMap map = ig::makeSyntheticTerrain(64, 3, 30.0);
    io::UdpSocket host;
    if (host.open({0x7f000001, 0}) != 0) {
        state.SkipWithError("cannot bind a loopback port");
        return;
    }
    sim::CigiOptions options;
    options.bind = {0x7f000001, 0};
    options.host = host.localEndpoint();
    options.origin = {47.0, -122.0, 0.0};
    sim::CigiSession session(map, options);
    std::string error;
    if (session.open(&error) != 0) {
        state.SkipWithError(error.c_str());
        return;
    }
    cigi::IgControl ig;
    cigi::EntityControl e;
    e.latOrX = 47.001;
    e.lonOrY = -121.999;
    e.altOrZ = 3000.0;
    cigi::RateControl r;
    r.xRate = 50.0f;
    const std::vector<cigi::Packet> packets{ig, e, r};
    const std::vector<std::uint8_t> bytes = cigi::encodeMessage(packets, cigi::ByteOrder::Big);
    std::vector<std::uint8_t> sink(65536);
    double t = 0.0;
    for (auto _ : state) {
        state.PauseTiming();
        for (int i = 0; i < 256; ++i)
            (void)host.sendTo(bytes, session.localEndpoint());
        state.ResumeTiming();
        session.poll(t);
        t += 1001.0 / 60000.0;
        state.PauseTiming();
        while (host.receive(sink) > 0) {
        }
        state.ResumeTiming();
    }
    state.SetItemsProcessed(state.iterations() * 256);
    state.counters["taken"] = static_cast<double>(session.stats().datagrams);
    state.counters["dropped"] = static_cast<double>(session.stats().droppedByKernel);
}
BENCHMARK(BM_SessionPollFlood)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
