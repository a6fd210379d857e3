// Control-stick input: one interface, a scripted backend and a libgpiod backend.
#pragma once

#include <memory>
#include <string>
#include <string_view>

namespace io {

// Axes in [-1, 1]: pitch +1 = pull back (nose up), roll +1 = right wing down, yaw +1 = nose
// right, throttle -1 slowest .. 0 cruise .. +1 fastest (the flight model gives them meaning).
struct StickState {
    double pitch = 0, roll = 0, yaw = 0;
    double throttle = 0;
    bool trigger = false;
};

class StickInput {
  public:
    virtual ~StickInput() = default;
    // The stick at `t` seconds since the start of the run.
    virtual StickState sample(double t) = 0;
};

// spec: "script:FILE" | "gpiod:CHIP:OFFSETS[:active-low]" (OFFSETS = up,down,left,right,trigger,
// throttle+,throttle-, each a line offset or '-' for none). nullptr and `error` when the spec,
// the file or the chip is bad.
std::unique_ptr<StickInput> makeStick(const std::string& spec, std::string* error);

// A script of timed stick events, one per line ('#' starts a comment, blank lines are skipped):
//   TIME axis pitch|roll|yaw|throttle VALUE [ramp SECONDS]
//   TIME button trigger down|up
// TIME in seconds (non-decreasing down the file), VALUE in [-1, 1]. An axis holds its value until
// the next event for it; with `ramp` it moves linearly from where it is to VALUE over SECONDS.
// Errors name `name` and the line: "NAME:LINE: ...".
std::unique_ptr<StickInput> makeScriptedStick(std::string_view scriptText, const std::string& name,
                                              std::string* error);

}  // namespace io
