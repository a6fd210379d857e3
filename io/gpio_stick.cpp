#include "io/gpio_stick.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>

namespace io {
namespace {

constexpr const char* kConsumer = "vig-stick";
constexpr std::array<const char*, kStickLineCount> kLineNames = {
    "up", "down", "left", "right", "trigger", "throttle+", "throttle-"};

}  // namespace

std::optional<GpioStickConfig> parseGpioStickSpec(std::string_view spec, std::string* error) {
    auto bad = [&](const std::string& why) -> std::optional<GpioStickConfig> {
        if (error) {
            *error = "gpiod stick '" + std::string(spec) + "': " + why +
                     " (expected CHIP:UP,DOWN,LEFT,RIGHT,TRIGGER,THROTTLE+,THROTTLE-[:active-low])";
        }
        return std::nullopt;
    };
    GpioStickConfig config;
    const std::size_t colon = spec.find(':');
    if (colon == std::string_view::npos || colon == 0) return bad("missing chip or offsets");
    config.chip = std::string(spec.substr(0, colon));
    std::string_view rest = spec.substr(colon + 1);
    if (const std::size_t opt = rest.find(':'); opt != std::string_view::npos) {
        if (rest.substr(opt + 1) != "active-low") {
            return bad("unknown option '" + std::string(rest.substr(opt + 1)) + "'");
        }
        config.activeLow = true;
        rest = rest.substr(0, opt);
    }
    int count = 0, wired = 0;
    std::size_t pos = 0;
    while (pos <= rest.size()) {
        const std::size_t comma = std::min(rest.find(',', pos), rest.size());
        const std::string_view item = rest.substr(pos, comma - pos);
        pos = comma + 1;
        if (count == kStickLineCount) return bad("more than 7 offsets");
        int offset = -1;
        if (item != "-") {
            const auto [end, ec] = std::from_chars(item.data(), item.data() + item.size(), offset);
            if (ec != std::errc() || end != item.data() + item.size() || offset < 0) {
                return bad(std::string("offset for ") + kLineNames[count] + " '" +
                           std::string(item) + "' is not a line number or '-'");
            }
            for (int i = 0; i < count; ++i) {
                if (config.offsets[i] == offset) {
                    return bad("line " + std::to_string(offset) + " is given for both " +
                               kLineNames[i] + " and " + kLineNames[count]);
                }
            }
            ++wired;
        }
        config.offsets[count++] = offset;
    }
    if (count != kStickLineCount) return bad("needs 7 offsets, got " + std::to_string(count));
    if (wired == 0) return bad("no line is wired");
    return config;
}

GpioStick::GpioStick(GpioStickConfig config, std::unique_ptr<GpioChipPort> port)
    : config_(std::move(config)),
      port_(std::move(port)),
      debounceNs_(std::llround(std::max(0.0, config_.debounceS) * 1e9)) {
    for (int i = 0; i < kStickLineCount; ++i)
        lines_[i].offset = config_.offsets[i];
}

int GpioStick::open(std::string* error) {
    requested_.clear();
    for (const Line& l : lines_) {
        if (l.offset >= 0) requested_.push_back(static_cast<unsigned>(l.offset));
    }
    if (requested_.empty()) {
        if (error) *error = "gpiod:" + config_.chip + ": no line is wired";
        return -EINVAL;
    }
    int rc = port_->request(config_.chip, requested_, config_.activeLow, kConsumer, error);
    if (rc != 0) return rc;
    std::vector<int> levels;
    rc = port_->values(&levels);
    if (rc != 0 || levels.size() != requested_.size()) {
        if (error) *error = "gpiod:" + config_.chip + ": cannot read the line levels";
        return rc != 0 ? rc : -EIO;
    }
    const std::int64_t now = port_->nowNs();
    for (Line& l : lines_) {
        if (l.offset < 0) continue;
        const auto at =
            std::find(requested_.begin(), requested_.end(), static_cast<unsigned>(l.offset));
        l.raw = l.stable = levels[at - requested_.begin()] != 0;
        l.rawSinceNs = now;
    }
    throttleTimeNs_ = now;
    throttle_ = 0.0;
    open_ = true;
    return 0;
}

void GpioStick::advanceThrottle(std::int64_t toNs) {
    if (toNs <= throttleTimeNs_) return;
    const int direction = (lines_[static_cast<int>(StickLine::ThrottleUp)].stable ? 1 : 0) -
                          (lines_[static_cast<int>(StickLine::ThrottleDown)].stable ? 1 : 0);
    throttle_ = std::clamp(throttle_ + direction * config_.throttleRatePerS *
                                           static_cast<double>(toNs - throttleTimeNs_) * 1e-9,
                           -1.0, 1.0);
    throttleTimeNs_ = toNs;
}

void GpioStick::commitUpTo(std::int64_t timeNs) {
    // Commit settled levels in time order, so the throttle integrates each interval exactly.
    for (;;) {
        Line* next = nullptr;
        for (Line& l : lines_) {
            if (l.offset < 0 || l.raw == l.stable || l.rawSinceNs + debounceNs_ > timeNs) continue;
            if (!next || l.rawSinceNs < next->rawSinceNs) next = &l;
        }
        if (!next) return;
        advanceThrottle(next->rawSinceNs + debounceNs_);
        next->stable = next->raw;
    }
}

void GpioStick::process(std::int64_t untilNs) {
    edges_.clear();
    port_->readEdges(0, &edges_);
    std::stable_sort(edges_.begin(), edges_.end(),
                     [](const GpioEdge& a, const GpioEdge& b) { return a.timeNs < b.timeNs; });
    for (const GpioEdge& e : edges_) {
        commitUpTo(e.timeNs);
        for (Line& l : lines_) {
            if (l.offset != static_cast<int>(e.offset)) continue;
            if (e.active != l.raw) {
                l.raw = e.active;
                l.rawSinceNs = e.timeNs;
            }
            ++edgesSeen_;
        }
    }
    commitUpTo(untilNs);
    advanceThrottle(untilNs);
}

bool GpioStick::pressed(StickLine line) const {
    return lines_[static_cast<int>(line)].stable;
}

StickState GpioStick::sample(double) {
    StickState s;
    if (!open_) return s;
    process(port_->nowNs());
    auto held = [this](StickLine l) { return pressed(l) ? 1.0 : 0.0; };
    s.pitch = held(StickLine::Up) - held(StickLine::Down);
    s.roll = held(StickLine::Right) - held(StickLine::Left);
    s.trigger = pressed(StickLine::Trigger);
    s.throttle = throttle_;
    return s;
}

}  // namespace io
