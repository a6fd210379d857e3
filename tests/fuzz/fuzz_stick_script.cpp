// Fuzz target: stick scripts (io::makeScriptedStick), then the stick sampled over the script.
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "fuzz_check.hpp"
#include "io/stick.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    std::string error;
    const std::unique_ptr<io::StickInput> stick = io::makeScriptedStick(text, "fuzz.stick", &error);
    if (!stick) {
        fuzz::checkMessage(error);
        return 0;
    }
    for (const double t : {-1.0, 0.0, 0.05, 0.5, 1.0, 2.5, 10.0, 100.0, 1e6, 1e300})
        (void)stick->sample(t);
    return 0;
}
