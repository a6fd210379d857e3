#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <vector>

#include "base/text.hpp"
#include "io/gpio_stick.hpp"
#include "io/stick.hpp"
#include "io/text_file.hpp"

namespace io {
namespace {

enum Axis { kPitch, kRoll, kYaw, kThrottle, kAxisCount };

struct AxisEvent {
    double time;
    double ramp;
    double from;  // the axis value when the event starts
    double to;
};

struct ButtonEvent {
    double time;
    bool down;
};

double axisValue(const std::vector<AxisEvent>& events, double t) {
    // Last event starting at or before t.
    auto it = std::upper_bound(events.begin(), events.end(), t,
                               [](double v, const AxisEvent& e) { return v < e.time; });
    if (it == events.begin()) return 0.0;
    const AxisEvent& e = *(it - 1);
    if (e.ramp <= 0.0 || t >= e.time + e.ramp) return e.to;
    return e.from + (e.to - e.from) * (t - e.time) / e.ramp;
}

class ScriptedStick final : public StickInput {
  public:
    std::array<std::vector<AxisEvent>, kAxisCount> axes;
    std::vector<ButtonEvent> trigger;

    StickState sample(double t) override {
        StickState s;
        s.pitch = axisValue(axes[kPitch], t);
        s.roll = axisValue(axes[kRoll], t);
        s.yaw = axisValue(axes[kYaw], t);
        s.throttle = axisValue(axes[kThrottle], t);
        auto it = std::upper_bound(trigger.begin(), trigger.end(), t,
                                   [](double v, const ButtonEvent& e) { return v < e.time; });
        s.trigger = it != trigger.begin() && (it - 1)->down;
        return s;
    }
};

bool parseNumber(std::string_view text, double* out) {
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), *out);
    return ec == std::errc() && end == text.data() + text.size() && std::isfinite(*out);
}

std::vector<std::string_view> words(std::string_view line) {
    std::vector<std::string_view> out;
    std::size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r'))
            ++i;
        const std::size_t start = i;
        while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r')
            ++i;
        if (i > start) out.push_back(line.substr(start, i - start));
    }
    return out;
}

}  // namespace

std::unique_ptr<StickInput> makeScriptedStick(std::string_view text, const std::string& name,
                                              std::string* error) {
    auto stick = std::make_unique<ScriptedStick>();
    double lastTime = 0.0;
    int lineNumber = 0;
    std::size_t pos = 0;
    auto fail = [&](const std::string& why) -> std::unique_ptr<StickInput> {
        if (error) *error = name + ":" + std::to_string(lineNumber) + ": " + why;
        return nullptr;
    };
    while (pos <= text.size()) {
        const std::size_t end = std::min(text.find('\n', pos), text.size());
        std::string_view line = text.substr(pos, end - pos);
        pos = end + 1;
        ++lineNumber;
        if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) {
            line = line.substr(0, hash);
        }
        const std::vector<std::string_view> w = words(line);
        if (w.empty()) continue;
        double time = 0.0;
        if (!parseNumber(w[0], &time) || time < 0.0) {
            return fail("time " + base::quoted(w[0]) + " is not a number of seconds >= 0");
        }
        if (time < lastTime) {
            return fail("time " + base::quoted(w[0]) + " is earlier than the event before it");
        }
        lastTime = time;
        if (w.size() < 2) return fail("missing event kind after the time (axis or button)");
        if (w[1] == "axis") {
            static constexpr std::array<std::string_view, kAxisCount> kNames = {"pitch", "roll",
                                                                                "yaw", "throttle"};
            if (w.size() < 4) return fail("expected 'TIME axis NAME VALUE [ramp SECONDS]'");
            const auto found = std::find(kNames.begin(), kNames.end(), w[2]);
            if (found == kNames.end()) {
                return fail("unknown axis " + base::quoted(w[2]) +
                            " (pitch, roll, yaw or throttle)");
            }
            double value = 0.0;
            if (!parseNumber(w[3], &value) || value < -1.0 || value > 1.0) {
                return fail("axis value " + base::quoted(w[3]) + " is not a number in [-1, 1]");
            }
            double ramp = 0.0;
            if (w.size() > 4) {
                if (w[4] != "ramp" || w.size() != 6) {
                    return fail("unexpected " + base::quoted(w[4]) +
                                " (only 'ramp SECONDS' may follow the value)");
                }
                if (!parseNumber(w[5], &ramp) || ramp < 0.0) {
                    return fail("ramp " + base::quoted(w[5]) + " is not a number of seconds >= 0");
                }
            }
            std::vector<AxisEvent>& events = stick->axes[found - kNames.begin()];
            const double from = axisValue(events, time);
            events.push_back({time, ramp, from, value});
        } else if (w[1] == "button") {
            if (w.size() != 4) return fail("expected 'TIME button trigger down|up'");
            if (w[2] != "trigger")
                return fail("unknown button " + base::quoted(w[2]) + " (trigger)");
            if (w[3] != "down" && w[3] != "up") {
                return fail("button state " + base::quoted(w[3]) + " is not down or up");
            }
            stick->trigger.push_back({time, w[3] == "down"});
        } else {
            return fail("unknown event kind " + base::quoted(w[1]) + " (axis or button)");
        }
    }
    return stick;
}

std::unique_ptr<StickInput> makeStick(const std::string& spec, std::string* error) {
    const std::size_t colon = spec.find(':');
    const std::string kind = spec.substr(0, colon);
    const std::string rest = colon == std::string::npos ? std::string() : spec.substr(colon + 1);
    if (kind == "script" && !rest.empty()) {
        std::string text, why;
        if (readTextFile(rest, text, &why) != 0) {
            if (error) *error = "stick script " + rest + ": " + why;
            return nullptr;
        }
        return makeScriptedStick(text, rest, error);
    }
    if (kind == "gpiod" && !rest.empty()) {
        std::optional<GpioStickConfig> config = parseGpioStickSpec(rest, error);
        if (!config) return nullptr;
        auto stick = std::make_unique<GpioStick>(*config, makeGpiodChipPort());
        if (stick->open(error) != 0) return nullptr;
        return stick;
    }
    if (error) {
        *error = "stick " + base::quoted(spec) +
                 ": expected script:FILE or gpiod:CHIP:OFFSETS[:active-low]";
    }
    return nullptr;
}

}  // namespace io
