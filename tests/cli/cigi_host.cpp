// cigi-host: a scripted CIGI 3.3 host for tests and benchmarks. It binds a loopback port (written
// to --port-file), waits for Start of Frame from --igs image generators (each found by the
// address its Start of Frame came from), then for --seconds sends one message a host frame
// (--rate Hz) to each of them: IG Control, the ownship's Entity Control on a straight line,
// Rate Control, and with --views FOV one View Control and View Definition per image generator
// (view i yawed by (i - (N - 1) / 2) * FOV). Options:
//   --flood N          N more host messages a second on top (paced each millisecond)
//   --silent-from S --silent-for D   send nothing from S to S + D seconds
//   --steps N          every N-th host frame the ownship jumps 50 m east or back; the delay
//                      from sending it to the first Start of Frame naming that host frame (the
//                      field that applied it): to the kernel's arrival stamp of that Start of
//                      Frame (SO_TIMESTAMPNS, CLOCK_REALTIME, so the host's own wake-ups do not
//                      count), and to when this program read it (CLOCK_MONOTONIC)
//   --queries N        each host frame N HAT/HOT (extended) requests at geodetic points within
//                      2 km of the start and one extended line of sight from the ownship, 45
//                      degrees down ahead; the answers are counted, and their heights and how
//                      many host frames each took written to --json
//   --json FILE        what was sent and the measured delays
// Exit status 2 on bad arguments or when no image generator announces itself within 30 s.
#include "io/cigi.hpp"
#include "io/field_clock.hpp"
#include "io/udp_socket.hpp"
#include "sim/cigi_session.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace {

std::int64_t realtimeNs() {
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

namespace cigi = io::cigi;

[[noreturn]] void usage(const std::string& what) {
    std::fprintf(stderr, "cigi-host: %s\n", what.c_str());
    std::exit(2);
}

double number(const char* flag, const char* text) {
    char* end = nullptr;
    const double v = std::strtod(text, &end);
    if (!end || *end != '\0' || !std::isfinite(v)) usage(std::string(flag) + ": not a number");
    return v;
}

void sleepUntilNs(std::int64_t ns) {
    timespec ts{static_cast<time_t>(ns / 1000000000), static_cast<long>(ns % 1000000000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
}

double percentile(std::vector<double> v, double q) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const std::size_t i = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
    return v[std::min(v.size() - 1, i == 0 ? 0 : i - 1)];
}

}  // namespace

int main(int argc, char** argv) {
    std::string portFile, jsonPath;
    int igs = 1;
    double seconds = 3.0, rate = 60.0, flood = 0.0, viewsFov = 0.0;
    double silentFrom = -1.0, silentFor = 0.0;
    int steps = 0, queries = 0;
    sim::GeoOrigin origin{47.0, -122.0, 0.0};
    double x0 = 500.0, y0 = 500.0, z0 = 1500.0, heading = 45.0, pitch = -10.0, speed = 60.0;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const auto value = [&]() -> const char* {
            if (i + 1 >= argc) usage(a + ": needs a value");
            return argv[++i];
        };
        if (a == "--port-file") {
            portFile = value();
        } else if (a == "--json") {
            jsonPath = value();
        } else if (a == "--igs") {
            igs = static_cast<int>(number("--igs", value()));
        } else if (a == "--seconds") {
            seconds = number("--seconds", value());
        } else if (a == "--rate") {
            rate = number("--rate", value());
        } else if (a == "--flood") {
            flood = number("--flood", value());
        } else if (a == "--views") {
            viewsFov = number("--views", value());
        } else if (a == "--silent-from") {
            silentFrom = number("--silent-from", value());
        } else if (a == "--silent-for") {
            silentFor = number("--silent-for", value());
        } else if (a == "--steps") {
            steps = static_cast<int>(number("--steps", value()));
        } else if (a == "--queries") {
            queries = static_cast<int>(number("--queries", value()));
        } else if (a == "--origin") {
            origin = sim::parseGeoOrigin(value(), "--origin");
        } else if (a == "--start") {
            if (std::sscanf(value(), "%lf,%lf,%lf", &x0, &y0, &z0) != 3) usage("--start X,Y,Z");
        } else if (a == "--heading") {
            heading = number("--heading", value());
        } else if (a == "--pitch") {
            pitch = number("--pitch", value());
        } else if (a == "--speed") {
            speed = number("--speed", value());
        } else {
            usage("unknown argument " + a);
        }
    }
    if (portFile.empty()) usage("--port-file FILE is needed");
    if (igs < 1 || igs > 16) usage("--igs: 1..16");
    if (!(rate > 0.0 && rate <= 1000.0)) usage("--rate: 0 < HZ <= 1000");
    if (!(flood >= 0.0 && flood <= 1e6)) usage("--flood: 0 .. 1e6 a second");
    if (!(heading >= 0.0 && heading < 360.0)) usage("--heading: 0 <= DEG < 360");
    if (steps < 0 || steps > 1000000) usage("--steps: a count of host frames");
    if (queries < 0 || queries > 32) usage("--queries: 0..32 a host frame");

    io::UdpSocket socket;
    if (socket.open({0x7f000001, 0}, 1 << 20) != 0) usage("cannot bind a loopback UDP port");
    const bool stamped = socket.stampArrivals() == 0;
    {
        const std::string tmp = portFile + ".tmp";
        std::ofstream(tmp) << socket.localEndpoint().port << "\n";
        if (std::rename(tmp.c_str(), portFile.c_str()) != 0) usage("cannot write " + portFile);
    }

    // The image generators announce themselves with their Start of Frame.
    std::vector<io::UdpEndpoint> targets;
    std::vector<std::uint8_t> buffer(65536);
    cigi::Message message;
    const std::int64_t giveUp = io::monotonicNs() + 30'000'000'000LL;
    while (static_cast<int>(targets.size()) < igs) {
        io::UdpEndpoint from;
        const long n = socket.receive(buffer, &from);
        if (n > 0) {
            if (std::find(targets.begin(), targets.end(), from) == targets.end())
                targets.push_back(from);
            continue;
        }
        if (io::monotonicNs() > giveUp)
            usage("no Start of Frame from the image generators in 30 s");
        sleepUntilNs(io::monotonicNs() + 200'000);
    }

    const sim::GeoFrame geo(origin);
    const double kDeg = 3.14159265358979323846 / 180.0;
    const double vx = speed * std::sin(heading * kDeg) * std::cos(pitch * kDeg);
    const double vy = speed * std::cos(heading * kDeg) * std::cos(pitch * kDeg);
    const double vz = speed * std::sin(pitch * kDeg);
    std::uint32_t hostFrame = 0;
    std::uint64_t sent = 0, floodSent = 0, sendErrors = 0, sofs = 0;
    std::vector<std::uint8_t> out;
    // Queries: request id -> (host frame sent, world point of a HAT/HOT; NaN for a line).
    struct Asked {
        std::uint32_t frame;
        double x, y;
    };
    std::map<std::uint16_t, Asked> asked;
    std::uint16_t nextId = 0;
    std::uint64_t queriesSent = 0, hatAnswers = 0, losAnswers = 0, validAnswers = 0;
    std::uint32_t maxQueryFrames = 0;
    std::vector<std::array<double, 3>> hotSamples;  // x, y, HOT (metres above the origin)
    const auto addQueries = [&](std::vector<cigi::Packet>& packets, std::uint32_t frame) {
        for (int q = 0; q < queries; ++q) {
            // A fixed walk over the square within 2 km of the start.
            const double u = std::fmod(0.6180339887 * (queriesSent + 1), 1.0);
            const double v = std::fmod(0.7548776662 * (queriesSent + 1), 1.0);
            const double x = x0 - 2000.0 + 4000.0 * u, y = y0 - 2000.0 + 4000.0 * v;
            const glm::dvec3 g = geo.geodeticFromWorld({x, y, z0});
            cigi::HatHotRequest r;
            r.requestId = nextId++;
            r.type = cigi::HatHotType::Extended;
            r.latOrX = g.x;
            r.lonOrY = g.y;
            r.altOrZ = g.z;
            packets.push_back(r);
            asked[r.requestId] = {frame, x, y};
            ++queriesSent;
        }
        if (queries > 0) {
            cigi::LosVectorRequest l;
            l.requestId = nextId++;
            l.extended = true;
            l.sourceEntityCoordinates = true;
            l.entityId = 0;
            l.azimuthDeg = static_cast<float>(heading);
            l.elevationDeg = -45.0f;
            l.maxRangeM = 20000.0f;
            packets.push_back(l);
            asked[l.requestId] = {frame, std::nan(""), std::nan("")};
            ++queriesSent;
        }
    };
    const auto encode = [&](double t, std::uint32_t frame, bool stepped) {
        cigi::IgControl ig;
        ig.hostFrameNumber = frame;
        ig.timestampValid = true;
        ig.timestamp = static_cast<std::uint32_t>(std::llround(t * 1e5));
        cigi::EntityControl e;
        const glm::dvec3 g =
            geo.geodeticFromWorld({x0 + vx * t + (stepped ? 50.0 : 0.0), y0 + vy * t, z0 + vz * t});
        e.latOrX = g.x;
        e.lonOrY = g.y;
        e.altOrZ = g.z;
        e.yawDeg = static_cast<float>(heading);
        e.pitchDeg = static_cast<float>(pitch);
        cigi::RateControl r;
        r.xRate = static_cast<float>(vy);
        r.yRate = static_cast<float>(vx);
        r.zRate = static_cast<float>(-vz);
        std::vector<cigi::Packet> packets{ig, e, r};
        addQueries(packets, frame);
        if (viewsFov > 0.0) {
            for (int v = 0; v < static_cast<int>(targets.size()); ++v) {
                cigi::ViewControl vc;
                vc.viewId = static_cast<std::uint16_t>(v);
                vc.yawEnable = true;
                const double yaw = (v - 0.5 * (static_cast<double>(targets.size()) - 1)) * viewsFov;
                vc.yawDeg = static_cast<float>(yaw < 0.0 ? yaw + 360.0 : yaw);
                cigi::ViewDefinition vd;
                vd.viewId = vc.viewId;
                vd.leftEnable = vd.rightEnable = true;
                vd.leftDeg = static_cast<float>(-0.5 * viewsFov);
                vd.rightDeg = static_cast<float>(0.5 * viewsFov);
                packets.push_back(vc);
                packets.push_back(vd);
            }
        }
        out = cigi::encodeMessage(packets, cigi::ByteOrder::Big);
    };
    const auto sendAll = [&](bool isFlood) {
        for (const io::UdpEndpoint& to : targets) {
            if (socket.sendTo(out, to) == 0) {
                ++(isFlood ? floodSent : sent);
            } else {
                ++sendErrors;
            }
        }
    };

    struct Step {
        std::uint32_t frame;
        std::int64_t sentNs;
        std::int64_t sentRealNs;
        double latencyMs = -1.0;  // to the kernel's arrival stamp of the Start of Frame
        double readMs = -1.0;     // to this program reading it
    };
    std::vector<Step> stepsSent;
    const double periodNs = 1e9 / rate;
    const std::int64_t start = io::monotonicNs();
    const std::int64_t end = start + static_cast<std::int64_t>(seconds * 1e9);
    std::int64_t nextFrame = start, nextFlood = start;
    bool stepped = false;
    double floodOwed = 0.0;
    while (true) {
        const std::int64_t now = io::monotonicNs();
        if (now >= end) break;
        const double t = (now - start) * 1e-9;
        const bool silent = silentFrom >= 0.0 && t >= silentFrom && t < silentFrom + silentFor;
        if (now >= nextFrame) {
            ++hostFrame;
            if (steps > 0 && hostFrame % steps == 0) stepped = !stepped;
            if (!silent) {
                encode(t, hostFrame, stepped);
                const std::int64_t sentNs = io::monotonicNs();
                const std::int64_t sentRealNs = realtimeNs();
                sendAll(false);
                if (steps > 0 && hostFrame % steps == 0)
                    stepsSent.push_back({hostFrame, sentNs, sentRealNs});
            }
            nextFrame = start + static_cast<std::int64_t>(hostFrame * periodNs);
        }
        if (flood > 0.0 && now >= nextFlood) {
            // The same host frame again (the ownship where it is): real work for the decoder.
            floodOwed += flood * 1e-3;
            if (!silent) {
                encode(t, hostFrame, stepped);
                for (; floodOwed >= 1.0; floodOwed -= 1.0)
                    sendAll(true);
            }
            nextFlood += 1'000'000;
        }
        // Start of Frame: the first naming a step's host frame ends that step's delay.
        while (true) {
            io::UdpEndpoint from;
            const long n = socket.receive(buffer, &from);
            if (n <= 0) break;
            const std::int64_t got = io::monotonicNs();
            if (!cigi::decodeMessage(
                    std::span<const std::uint8_t>(buffer.data(), static_cast<std::size_t>(n)),
                    cigi::Sender::ImageGenerator, message, nullptr) ||
                message.packets.empty() || !(from == targets[0])) {
                continue;
            }
            ++sofs;
            for (const cigi::Packet& p : message.packets) {
                std::uint16_t id = 0;
                bool valid = false, answer = false;
                double hot = std::nan("");
                if (const auto* h = std::get_if<cigi::HatHotExtendedResponse>(&p)) {
                    id = h->requestId;
                    valid = h->valid;
                    hot = h->hotM;
                    answer = true;
                    ++hatAnswers;
                } else if (const auto* l = std::get_if<cigi::LosExtendedResponse>(&p)) {
                    id = l->requestId;
                    valid = l->valid;
                    answer = true;
                    ++losAnswers;
                }
                if (!answer) continue;
                validAnswers += valid;
                const auto it = asked.find(id);
                if (it == asked.end()) continue;
                maxQueryFrames = std::max(maxQueryFrames, hostFrame - it->second.frame);
                if (valid && !std::isnan(it->second.x) && hotSamples.size() < 400)
                    hotSamples.push_back({it->second.x, it->second.y, hot});
                asked.erase(it);
            }
            const auto& sof = std::get<cigi::StartOfFrame>(message.packets[0]);
            for (Step& s : stepsSent) {
                if (s.readMs < 0.0 && sof.lastHostFrameNumber >= s.frame) {
                    s.readMs = (got - s.sentNs) * 1e-6;
                    s.latencyMs =
                        stamped ? (socket.arrivalRealtimeNs() - s.sentRealNs) * 1e-6 : s.readMs;
                }
            }
        }
        std::int64_t wake = std::min(nextFrame, end);
        if (flood > 0.0) wake = std::min(wake, nextFlood);
        // Wake at least every 0.2 ms to take Start of Frame as it comes.
        sleepUntilNs(std::min(wake, io::monotonicNs() + 200'000));
    }

    std::vector<double> delays, reads;
    for (const Step& s : stepsSent) {
        if (s.latencyMs >= 0.0) delays.push_back(s.latencyMs);
        if (s.readMs >= 0.0) reads.push_back(s.readMs);
    }
    double mean = 0.0;
    for (double d : delays)
        mean += d / static_cast<double>(delays.size());
    std::fprintf(stderr,
                 "cigi-host: %d image generator(s), %u host frames, %llu messages, %llu flood, "
                 "%llu send errors, %llu Start of Frame",
                 igs, hostFrame, static_cast<unsigned long long>(sent),
                 static_cast<unsigned long long>(floodSent),
                 static_cast<unsigned long long>(sendErrors),
                 static_cast<unsigned long long>(sofs));
    if (steps > 0) {
        std::fprintf(stderr,
                     "; step to field: %zu of %zu seen, p50 %.2f p99 %.2f max %.2f ms (read "
                     "p50 %.2f p99 %.2f ms)",
                     delays.size(), stepsSent.size(), percentile(delays, 0.5),
                     percentile(delays, 0.99), percentile(delays, 1.0), percentile(reads, 0.5),
                     percentile(reads, 0.99));
    }
    std::fprintf(stderr, "\n");
    if (!jsonPath.empty()) {
        std::ofstream j(jsonPath);
        j.precision(12);
        j << "{\"image_generators\": " << igs << ", \"host_frames\": " << hostFrame
          << ", \"rate_hz\": " << rate << ", \"messages\": " << sent
          << ", \"flood_messages\": " << floodSent << ", \"flood_per_second\": " << flood
          << ", \"send_errors\": " << sendErrors << ", \"start_of_frame\": " << sofs
          << ", \"steps\": " << stepsSent.size() << ", \"steps_seen\": " << delays.size()
          << ", \"step_to_field_ms\": {\"mean\": " << mean
          << ", \"p50\": " << percentile(delays, 0.5) << ", \"p90\": " << percentile(delays, 0.9)
          << ", \"p99\": " << percentile(delays, 0.99) << ", \"max\": " << percentile(delays, 1.0)
          << "}, \"kernel_arrival_stamps\": " << (stamped ? "true" : "false")
          << ", \"step_to_field_read_ms\": {\"p50\": " << percentile(reads, 0.5)
          << ", \"p90\": " << percentile(reads, 0.9) << ", \"p99\": " << percentile(reads, 0.99)
          << ", \"max\": " << percentile(reads, 1.0) << "}, \"samples_ms\": [";
        for (std::size_t i = 0; i < delays.size(); ++i)
            j << (i ? ", " : "") << delays[i];
        j << "], \"queries\": {\"sent\": " << queriesSent << ", \"hat_hot_answers\": " << hatAnswers
          << ", \"los_answers\": " << losAnswers << ", \"valid\": " << validAnswers
          << ", \"unanswered\": " << asked.size() << ", \"max_host_frames\": " << maxQueryFrames
          << ", \"hot_samples\": [";
        for (std::size_t i = 0; i < hotSamples.size(); ++i) {
            j << (i ? ", " : "") << "[" << hotSamples[i][0] << ", " << hotSamples[i][1] << ", "
              << hotSamples[i][2] << "]";
        }
        j << "]}}\n";
        if (!j) usage("cannot write " + jsonPath);
    }
    return 0;
}
