// Fuzz target: trajectory CSV (sim::Trajectory::parseCsv), then the trajectory's use: poses
// interpolated over its time range and the fit onto a map.
#include <cstdint>
#include <string_view>

#include "fuzz_check.hpp"
#include "ig/error.hpp"
#include "ig/synthetic.hpp"
#include "sim/trajectory.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const ig::TerrainMap map = ig::makeSyntheticTerrain(32, 7, 30.0);
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    try {
        const sim::Trajectory tr = sim::Trajectory::parseCsv(text, "fuzz.csv");
        const double t0 = tr.startTime(), t1 = tr.endTime();
        for (int i = -1; i <= 9; ++i)
            (void)tr.poseAt(t0 + (t1 - t0) * i / 8.0);
        if (tr.samples().size() <= 4096) (void)sim::fitTrajectoryToMap(tr, map);
    } catch (const ig::InputError& e) {
        fuzz::checkMessage(e.what());
    }
    return 0;
}
