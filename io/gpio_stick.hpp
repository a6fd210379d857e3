// The libgpiod stick backend: digital lines with edge events, debounced, behind a chip seam.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "io/stick.hpp"

namespace io {

// One edge on a requested line: `active` is the logical level after it (active-low applied).
struct GpioEdge {
    unsigned offset = 0;
    bool active = false;
    std::int64_t timeNs = 0;  // event timestamp, the clock of nowNs()
};

// The seam: line requests and event waits on one chip. Calls return 0 or -errno.
class GpioChipPort {
  public:
    virtual ~GpioChipPort() = default;
    // Requests `offsets` as inputs with events on both edges.
    virtual int request(const std::string& chip, const std::vector<unsigned>& offsets,
                        bool activeLow, const std::string& consumer, std::string* error) = 0;
    // Logical levels of the requested lines, in request order.
    virtual int values(std::vector<int>* out) = 0;
    // Waits up to `timeoutNs` (0: just looks) and appends the pending edges, oldest first.
    virtual int readEdges(std::int64_t timeoutNs, std::vector<GpioEdge>* out) = 0;
    // Now, in the clock of the event timestamps (CLOCK_MONOTONIC for the kernel).
    virtual std::int64_t nowNs() = 0;
};

// libgpiod 1.6 (gpiodcxx) on a real /dev/gpiochipN.
std::unique_ptr<GpioChipPort> makeGpiodChipPort();

enum class StickLine { Up, Down, Left, Right, Trigger, ThrottleUp, ThrottleDown };
inline constexpr int kStickLineCount = 7;

struct GpioStickConfig {
    std::string chip;                            // "gpiochip0", "/dev/gpiochip0", "0" or a label
    std::array<int, kStickLineCount> offsets{};  // by StickLine; -1 = not wired
    bool activeLow = false;
    double debounceS = 0.010;       // a level must hold this long to count
    double throttleRatePerS = 0.5;  // throttle change per second while throttle+/- is held
};

// "CHIP:UP,DOWN,LEFT,RIGHT,TRIGGER,THROTTLE+,THROTTLE-[:active-low]", '-' for an unwired line.
std::optional<GpioStickConfig> parseGpioStickSpec(std::string_view spec, std::string* error);

// Up/down -> pitch +1/-1, right/left -> roll +1/-1, trigger, throttle+/- ramp the throttle in
// [-1, 1]. Debouncing: a line's level counts once it has held for debounceS without an edge,
// timed by the kernel's edge timestamps. sample() reads pending edges without blocking; its
// `t` is not used (the edge clock is the time base).
class GpioStick final : public StickInput {
  public:
    GpioStick(GpioStickConfig config, std::unique_ptr<GpioChipPort> port);
    int open(std::string* error);
    StickState sample(double t) override;
    // Debounced level of one line.
    bool pressed(StickLine line) const;
    std::uint64_t edgesSeen() const { return edgesSeen_; }

  private:
    struct Line {
        int offset = -1;
        bool raw = false, stable = false;
        std::int64_t rawSinceNs = 0;
    };
    void process(std::int64_t untilNs);
    void commitUpTo(std::int64_t timeNs);
    void advanceThrottle(std::int64_t toNs);

    GpioStickConfig config_;
    std::unique_ptr<GpioChipPort> port_;
    std::array<Line, kStickLineCount> lines_;
    std::vector<unsigned> requested_;
    std::vector<GpioEdge> edges_;
    std::int64_t debounceNs_;
    std::int64_t throttleTimeNs_ = 0;
    double throttle_ = 0.0;
    std::uint64_t edgesSeen_ = 0;
    bool open_ = false;
};

}  // namespace io
