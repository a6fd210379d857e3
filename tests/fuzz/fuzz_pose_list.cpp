// Fuzz target: pose lists (ig::parsePoseList, stereo-eval --poses), over a small map for the
// heights above the terrain (z written +H).
#include <cstdint>
#include <string_view>

#include "fuzz_check.hpp"
#include "ig/error.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/synthetic.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const ig::TerrainMap map = ig::makeSyntheticTerrain(32, 3, 30.0);
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    try {
        (void)ig::parsePoseList(text, map, "fuzz.poses");
    } catch (const ig::InputError& e) {
        fuzz::checkMessage(e.what());
    }
    return 0;
}
