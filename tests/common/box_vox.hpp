// A solid box model written as a MagicaVoxel file: the objects tests' simplest shape.
#pragma once

#include "ig/vox.hpp"

#include <string>

namespace vig_test {

// Writes `path`: one model of sx x sy x sz voxels, every one palette entry 7 of the default
// palette.
inline void writeBoxVox(const std::string& path, int sx, int sy, int sz) {
    ig::VoxFile vox;
    vox.palette = ig::defaultVoxPalette();
    vox.models.push_back(ig::VoxModel(sx, sy, sz));
    for (auto& v : vox.models[0].voxels)
        v = 7;
    ig::writeVox(path, vox);
}

}  // namespace vig_test
