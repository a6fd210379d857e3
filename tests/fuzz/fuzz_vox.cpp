// Fuzz target: MagicaVoxel .vox (ig::parseVox), then the model's encoding parsed again.
#include <cstdint>

#include "fuzz_check.hpp"
#include "ig/error.hpp"
#include "ig/vox.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    try {
        const ig::VoxFile f = ig::parseVox({data, size}, "fuzz.vox");
        const ig::VoxFile g = ig::parseVox(ig::encodeVox(f), "again.vox");
        if (g.models.size() != f.models.size()) __builtin_trap();
        for (std::size_t i = 0; i < f.models.size(); ++i) {
            if (g.models[i].voxels != f.models[i].voxels) __builtin_trap();
        }
    } catch (const ig::InputError& e) {
        fuzz::checkMessage(e.what());
    }
    return 0;
}
