// io-check: exercise the io layer alone: a test pattern to any output on the field clock (with
// timing figures), a live stick readout, and a list of the V4L2 and GPIO devices present.
#include <fcntl.h>
#include <linux/videodev2.h>
#include <pthread.h>
#include <sched.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "base/error.hpp"
#include "base/text.hpp"
#include "io/field_clock.hpp"
#include "io/frame_sink.hpp"
#include "io/output_file.hpp"
#include "io/stick.hpp"
#include "io/stop_signals.hpp"

namespace {

struct Percentiles {
    double p50 = 0, p99 = 0, p999 = 0, max = 0;
};

Percentiles percentiles(std::vector<double> v) {
    Percentiles p;
    if (v.empty()) return p;
    std::sort(v.begin(), v.end());
    auto at = [&](double q) {
        return v[std::min(v.size() - 1, static_cast<std::size_t>(std::ceil(q * v.size())) - 1)];
    };
    p.p50 = at(0.50);
    p.p99 = at(0.99);
    p.p999 = at(0.999);
    p.max = v.back();
    return p;
}

// One field of a moving test pattern: grey ramp background, a white bar whose position is a
// function of the field's time (so interlaced motion shows), a black bar for field parity.
void drawField(const io::VideoFormat& format, io::FieldParity parity, double time,
               std::vector<std::uint8_t>& row, std::vector<std::uint8_t>& pixels) {
    const int width = format.width;
    const int bpp = io::bytesPerPixel(format.format);
    const int lines = io::fieldLines(format.height, parity);
    const std::size_t stride = static_cast<std::size_t>(width) * bpp;
    pixels.resize(stride * lines);
    std::vector<std::uint8_t> rgb(static_cast<std::size_t>(width) * 3);
    const double speed = 240.0;  // pixels per second
    const int bar = static_cast<int>(std::fmod(time * speed, static_cast<double>(width)));
    for (int x = 0; x < width; ++x) {
        std::uint8_t v = static_cast<std::uint8_t>(40 + 160 * x / std::max(1, width - 1));
        if (x >= bar && x < bar + 8) v = 255;
        if (parity == io::FieldParity::Bottom && x < 16) v = 0;
        rgb[3 * x] = rgb[3 * x + 1] = rgb[3 * x + 2] = v;
    }
    row.resize(stride);
    switch (format.format) {
        case io::PixelFormat::Uyvy:
            io::rgbRowToUyvy(rgb.data(), width, row.data());
            break;
        case io::PixelFormat::Y8:
            for (int x = 0; x < width; ++x)
                row[x] = rgb[3 * x];
            break;
        case io::PixelFormat::Rgb8:
            row.assign(rgb.begin(), rgb.end());
            break;
    }
    for (int y = 0; y < lines; ++y)
        std::copy(row.begin(), row.end(), pixels.begin() + y * stride);
}

int runPattern(const std::string& outSpec, double duration, const std::string& sizeText,
               const std::string& formatText, const std::string& clockText,
               const std::string& jsonPath, bool overwrite, bool realtime) {
    int width = 0, height = 0;
    char x = 0;
    if (std::sscanf(sizeText.c_str(), "%d%c%d", &width, &x, &height) != 3 || x != 'x') {
        std::fprintf(stderr, "io-check: --size '%s': expected WIDTHxHEIGHT\n", sizeText.c_str());
        return 2;
    }
    const auto pf = io::parsePixelFormat(formatText);
    if (!pf) {
        std::fprintf(stderr, "io-check: --format '%s': expected uyvy, y8 or rgb8\n",
                     formatText.c_str());
        return 2;
    }
    if (clockText != "wall" && clockText != "simulated") {
        std::fprintf(stderr, "io-check: --clock '%s': expected wall or simulated\n",
                     clockText.c_str());
        return 2;
    }
    if (!(duration > 0 && duration <= 86400)) {
        std::fprintf(stderr, "io-check: --duration must be in (0, 86400] seconds\n");
        return 2;
    }
    std::string error;
    auto sink = io::makeSink(outSpec, &error, overwrite);
    if (!sink) {
        std::fprintf(stderr, "io-check: --out %s\n", error.c_str());
        return 2;
    }
    // Every path before the run: the JSON is written at the end.
    const std::vector<io::PathUse> paths = {
        {"--out", io::sinkPath(outSpec),
         io::sinkWritesFolder(outSpec) ? io::PathRole::OutputFolder : io::PathRole::Output},
        {"--json", jsonPath, io::PathRole::Output}};
    try {
        io::checkRunPaths(paths);
    } catch (const base::InputError& e) {
        std::fprintf(stderr, "io-check: %s\n", e.what());
        return 2;
    }
    // The report goes to standard output unless an output does.
    std::FILE* report = io::usesStdout(paths) ? stderr : stdout;
    io::installStopSignals();
    if (sink->open({width, height, *pf}, &error) != 0) {
        std::fprintf(stderr, "io-check: %s\n", error.c_str());
        return 1;
    }
    const io::VideoFormat format = sink->format();
    auto clock = clockText == "wall" ? io::makeWallClock() : io::makeSimulatedClock();
    const std::uint64_t fields =
        static_cast<std::uint64_t>(std::llround(duration / io::kFieldPeriod));
    // As the pipeline's field loop: real-time priority when the system grants it.
    bool granted = false;
    if (realtime) {
        sched_param param{};
        param.sched_priority = std::min(20, sched_get_priority_max(SCHED_FIFO));
        granted = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
    }
    const double t0 = clock->now() + 0.05;
    io::FieldPacer pacer(*clock, t0);
    std::vector<double> lateness, intervals, workMs;
    std::vector<std::uint8_t> row, pixels;
    std::uint64_t missed = 0, failed = 0, written = 0;
    int firstError = 0;
    double lastWake = 0;
    for (std::uint64_t n = 0; n < fields && !io::stopRequested(); ++n) {
        const io::FieldParity parity = io::fieldParity(n);
        const double fieldTime = pacer.deadline(n) - t0;
        drawField(format, parity, fieldTime, row, pixels);  // prepared before the deadline
        const io::FieldWake wake = pacer.wait(n);
        io::FieldBuffer field{
            n,
            parity,
            fieldTime,
            pixels.data(),
            static_cast<std::size_t>(format.width) * io::bytesPerPixel(format.format),
            io::fieldLines(format.height, parity)};
        if (const int rc = sink->writeField(field); rc != 0) {
            if (failed++ == 0) firstError = rc;
        } else {
            ++written;
        }
        const double done = clock->now();
        if (done > pacer.deadline(n + 1)) ++missed;
        lateness.push_back(wake.lateness * 1e3);
        workMs.push_back((done - wake.woke) * 1e3);
        if (n > 0) intervals.push_back((wake.woke - lastWake) * 1e3);
        lastWake = wake.woke;
    }
    const int closed = sink->close(&error);
    if (closed != 0) {
        std::fprintf(stderr, "io-check: %s\n", error.c_str());
        return 1;
    }
    const Percentiles late = percentiles(lateness), interval = percentiles(intervals),
                      work = percentiles(workMs);
    std::fprintf(report, "io-check pattern: %llu of %llu fields to %s (%dx%d %s, %s clock)%s\n",
                 static_cast<unsigned long long>(written), static_cast<unsigned long long>(fields),
                 outSpec.c_str(), format.width, format.height, io::pixelFormatName(format.format),
                 clockText.c_str(), io::stopRequested() ? ", stopped by a signal" : "");
    std::fprintf(report, "  missed deadlines %llu, sink errors %llu\n",
                 static_cast<unsigned long long>(missed), static_cast<unsigned long long>(failed));
    if (failed > 0) {
        std::fprintf(stderr, "io-check: --out %s: the first refused field: %s\n", outSpec.c_str(),
                     std::strerror(-firstError));
    }
    std::fprintf(report, "  wake lateness ms  p50 %.3f  p99 %.3f  p99.9 %.3f  max %.3f%s\n",
                 late.p50, late.p99, late.p999, late.max,
                 realtime ? (granted ? " (SCHED_FIFO)" : " (SCHED_FIFO refused)") : "");
    std::fprintf(report, "  field interval ms p50 %.3f  p99 %.3f  max %.3f\n", interval.p50,
                 interval.p99, interval.max);
    std::fprintf(report, "  sink write ms     p50 %.3f  p99 %.3f  max %.3f\n", work.p50, work.p99,
                 work.max);
    if (!jsonPath.empty()) {
        auto pj = [](const Percentiles& p) {
            return nlohmann::json{
                {"p50", p.p50}, {"p99", p.p99}, {"p99.9", p.p999}, {"max", p.max}};
        };
        const nlohmann::json j = {{"fields", written},
                                  {"fields_planned", fields},
                                  {"stopped_by_signal", io::stopSignalNumber()},
                                  {"missed_deadlines", missed},
                                  {"sink_errors", failed},
                                  {"wake_lateness_ms", pj(late)},
                                  {"field_interval_ms", pj(interval)},
                                  {"sink_write_ms", pj(work)},
                                  {"output", outSpec},
                                  {"realtime", granted},
                                  {"clock", clockText}};
        if (io::writeTextFile(jsonPath, j.dump(2) + "\n", &error) != 0) {
            std::fprintf(stderr, "io-check: --json %s\n", error.c_str());
            return 1;
        }
    }
    if (io::stopRequested()) return io::exitStatusForStop();
    return missed == 0 && failed == 0 ? 0 : 3;
}

int runStick(const std::string& spec, double duration, double rate) {
    std::string error;
    auto stick = io::makeStick(spec, &error);
    if (!stick) {
        std::fprintf(stderr, "io-check: %s\n", error.c_str());
        return 2;
    }
    io::installStopSignals();
    auto clock = io::makeWallClock();
    const double period = 1.0 / rate;
    const auto samples = static_cast<std::uint64_t>(std::floor(duration * rate + 1e-9)) + 1;
    for (std::uint64_t i = 0; i < samples && !io::stopRequested(); ++i) {
        const double t = static_cast<double>(i) * period;
        // Woken at least every 50 ms to see a stop.
        while (clock->now() < t - 0.05 && !io::stopRequested())
            clock->sleepUntil(std::min(t, clock->now() + 0.05));
        if (io::stopRequested()) break;
        clock->sleepUntil(t);
        const io::StickState s = stick->sample(t);
        std::printf("%8.3f  pitch %+5.2f  roll %+5.2f  yaw %+5.2f  throttle %+5.2f  trigger %d\n",
                    t, s.pitch, s.roll, s.yaw, s.throttle, s.trigger ? 1 : 0);
        std::fflush(stdout);
    }
    return io::exitStatusForStop();
}

int listDevices() {
    std::vector<std::filesystem::path> nodes;
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator("/dev", ec))
        nodes.push_back(e.path());
    std::sort(nodes.begin(), nodes.end());
    int count = 0;
    for (const auto& p : nodes) {
        const std::string name = p.filename().string();
        if (name.rfind("video", 0) == 0) {
            const int fd = ::open(p.c_str(), O_RDWR | O_NONBLOCK);
            v4l2_capability cap{};
            const bool ok = fd >= 0 && ::ioctl(fd, VIDIOC_QUERYCAP, &cap) == 0;
            if (fd >= 0) ::close(fd);
            const std::uint32_t caps =
                (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
            std::printf("%s: %s%s%s%s\n", p.c_str(),
                        ok ? reinterpret_cast<const char*>(cap.card) : "(cannot query)",
                        (caps & V4L2_CAP_VIDEO_OUTPUT) ? ", video output" : "",
                        (caps & V4L2_CAP_VIDEO_CAPTURE) ? ", video capture" : "",
                        (caps & V4L2_CAP_STREAMING) ? ", streaming" : "");
            ++count;
        } else if (name.rfind("gpiochip", 0) == 0) {
            std::printf("%s: GPIO chip\n", p.c_str());
            ++count;
        }
    }
    if (count == 0) std::printf("no /dev/video* or /dev/gpiochip* devices\n");
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"Checks the io layer alone: outputs, the field clock, sticks, devices"};
    app.require_subcommand(1);

    std::string outSpec = "null", sizeText = "720x486", formatText = "uyvy", clockText = "wall",
                jsonPath;
    double duration = 5.0;
    bool overwrite = false, realtime = false;
    auto* pattern =
        app.add_subcommand("pattern", "A moving test pattern to an output, on the field clock");
    pattern->add_option("--out", outSpec, "y4m:PATH | v4l2:/dev/videoN | png:DIR[:EVERY_N] | null")
        ->capture_default_str();
    pattern->add_option("--duration", duration, "Seconds")->capture_default_str();
    pattern->add_option("--size", sizeText, "WIDTHxHEIGHT (frame)")->capture_default_str();
    pattern->add_option("--format", formatText, "uyvy | y8 | rgb8")->capture_default_str();
    pattern->add_option("--clock", clockText, "wall | simulated")->capture_default_str();
    pattern->add_option("--json", jsonPath, "Write timing figures as JSON");
    pattern->add_flag("--realtime", realtime,
                      "Run the field loop at SCHED_FIFO, as flythrough does, where the system "
                      "allows it (the field clock's own lateness, with no renderer)");

    std::string stickSpec;
    double stickDuration = 10.0, rate = 10.0;
    auto* stick = app.add_subcommand("stick", "Print a stick's state");
    stick->add_option("spec", stickSpec, "script:FILE | gpiod:CHIP:OFFSETS[:active-low]")
        ->required();
    stick->add_option("--duration", stickDuration, "Seconds")->capture_default_str();
    stick->add_option("--rate", rate, "Samples per second")->capture_default_str();

    auto* devices = app.add_subcommand("devices", "List V4L2 and GPIO devices");

    pattern->add_flag("--overwrite", overwrite,
                      "png:DIR may be a folder that is not empty (its frames are replaced)");
    CLI11_PARSE(app, argc, argv);
    if (*pattern) {
        return runPattern(outSpec, duration, sizeText, formatText, clockText, jsonPath, overwrite,
                          realtime);
    }
    if (*stick) {
        if (!(rate >= 0.1 && rate <= 1000.0)) {
            std::fprintf(stderr,
                         "io-check stick: --rate %s: must be 0.1 .. 1000 samples a second\n",
                         base::number(rate).c_str());
            return 2;
        }
        if (!(stickDuration >= 0.0 && stickDuration <= 86400.0)) {
            std::fprintf(stderr, "io-check stick: --duration %s: must be 0 .. 86400 seconds\n",
                         base::number(stickDuration).c_str());
            return 2;
        }
        return runStick(stickSpec, stickDuration, rate);
    }
    if (*devices) return listDevices();
    return 0;
}
