// Fuzz target: scene files (ig::parseScene) over a small synthetic map; the scene's paths
// resolve into the .vox corpus (VIG_FUZZ_SCENE_DIR), so mutated scenes place real models.
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_check.hpp"
#include "ig/error.hpp"
#include "ig/scene.hpp"
#include "ig/synthetic.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const ig::TerrainMap map = ig::makeSyntheticTerrain(32, 7, 30.0);
    static const std::string path = std::string(VIG_FUZZ_SCENE_DIR) + "/fuzz_scene.json";
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    try {
        const ig::Scene scene = ig::parseScene(text, path, map, true, 1 << 20);
        (void)scene.staticLayer->bytes();
    } catch (const ig::InputError& e) {
        fuzz::checkMessage(e.what());
    }
    return 0;
}
