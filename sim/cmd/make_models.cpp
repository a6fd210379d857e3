// make-models: writes the shipped voxel models (data/models/): two kinds of tree, a house and a
// radio mast built procedurally, and a tank sculpted from three views rendered of simple shapes.
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/sculpt.hpp"
#include "ig/vox.hpp"
#include "io/image_file.hpp"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

namespace {

using ig::Rgba8;
using ig::VoxFile;
using ig::VoxModel;

// A one-model file whose palette gets colours as they are first used.
struct Builder {
    VoxFile file;
    int next = 1;
    explicit Builder(int sx, int sy, int sz) {
        file.models.emplace_back(sx, sy, sz);
        file.palette = ig::defaultVoxPalette();
        file.hasPalette = true;
    }
    std::uint8_t color(Rgba8 c) {
        for (int i = 1; i < next; ++i)
            if (file.palette[static_cast<std::size_t>(i)] == c) return static_cast<std::uint8_t>(i);
        if (next > 255) throw ig::InputError("make-models: more than 255 colours");
        file.palette[static_cast<std::size_t>(next)] = c;
        return static_cast<std::uint8_t>(next++);
    }
    VoxModel& m() { return file.models[0]; }
    void set(int x, int y, int z, Rgba8 c) {
        if (x < 0 || y < 0 || z < 0 || x >= m().sizeX || y >= m().sizeY || z >= m().sizeZ) return;
        m().set(x, y, z, color(c));
    }
};

// A small deterministic hash for colour variation.
unsigned hash3(int x, int y, int z) {
    unsigned h = static_cast<unsigned>(x) * 73856093u ^ static_cast<unsigned>(y) * 19349663u ^
                 static_cast<unsigned>(z) * 83492791u;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    return h ^ (h >> 15);
}

Rgba8 vary(Rgba8 c, int x, int y, int z, int amount) {
    const int d = static_cast<int>(hash3(x, y, z) % static_cast<unsigned>(2 * amount + 1)) - amount;
    auto ch = [d](int v) { return static_cast<std::uint8_t>(std::clamp(v + d, 0, 255)); };
    return Rgba8{ch(c.r), ch(c.g), ch(c.b), c.a};
}

// Conifer: 12 x 12 x 32, a trunk and a stack of shrinking discs (uniform trunk, textured crown).
VoxFile conifer() {
    Builder b(12, 12, 32);
    for (int z = 0; z < 6; ++z)
        for (int y = 5; y < 7; ++y)
            for (int x = 5; x < 7; ++x)
                b.set(x, y, z, Rgba8{92, 64, 40, 255});
    for (int z = 4; z < 32; ++z) {
        const double r = 5.8 * (1.0 - (z - 4) / 28.0) * (0.8 + 0.2 * ((z % 4) / 3.0));
        for (int y = 0; y < 12; ++y)
            for (int x = 0; x < 12; ++x)
                if (std::hypot(x - 5.5, y - 5.5) <= r + 0.3)
                    b.set(x, y, z, vary(Rgba8{34, 84, 44, 255}, x, y, z / 2, 6));
    }
    return b.file;
}

// Broadleaf: 16 x 16 x 20, a trunk and a round crown whose outer leaves are half transparent
// (complex sticks).
VoxFile broadleaf() {
    Builder b(16, 16, 20);
    for (int z = 0; z < 9; ++z)
        for (int y = 7; y < 9; ++y)
            for (int x = 7; x < 9; ++x)
                b.set(x, y, z, Rgba8{101, 74, 50, 255});
    for (int z = 6; z < 20; ++z)
        for (int y = 0; y < 16; ++y)
            for (int x = 0; x < 16; ++x) {
                const double d = std::sqrt((x - 7.5) * (x - 7.5) + (y - 7.5) * (y - 7.5) +
                                           1.6 * (z - 13.0) * (z - 13.0));
                if (d > 7.6) continue;
                const bool outer = d > 6.4;
                b.set(x, y, z,
                      outer ? Rgba8{96, 150, 60, 150} : vary(Rgba8{70, 122, 48, 255}, x, y, z, 8));
            }
    return b.file;
}

// House: 16 x 20 x 16, walls with glass windows (semi-transparent), an open doorway (cavity
// through the wall: a fully transparent colour), a pitched roof.
VoxFile house() {
    Builder b(16, 20, 16);
    const Rgba8 wall{222, 214, 196, 255}, glass{120, 170, 200, 110}, door{0, 0, 0, 0},
        roof{150, 52, 40, 255}, floor{120, 110, 100, 255};
    for (int z = 0; z < 9; ++z)
        for (int y = 0; y < 20; ++y)
            for (int x = 0; x < 16; ++x) {
                const bool edge = x == 0 || x == 15 || y == 0 || y == 19;
                if (z == 0) b.set(x, y, z, floor);
                if (!edge || z == 0) continue;
                const bool window = z >= 3 && z <= 6 &&
                                    ((y % 6 >= 2 && y % 6 <= 3 && (x == 0 || x == 15)) ||
                                     (x % 5 >= 2 && x % 5 <= 3 && y == 19));
                const bool doorway = y == 0 && x >= 6 && x <= 9 && z <= 6;
                b.set(x, y, z, doorway ? door : window ? glass : wall);
            }
    for (int z = 9; z < 16; ++z) {
        const int inset = z - 9;
        for (int y = 0; y < 20; ++y)
            for (int x = inset; x < 16 - inset; ++x) {
                const bool gable = y == 0 || y == 19;
                if (x == inset || x == 15 - inset || x == inset + 1 || x == 14 - inset)
                    b.set(x, y, z, roof);
                else if (gable)
                    b.set(x, y, z, wall);
            }
    }
    return b.file;
}

// Radio mast: 6 x 6 x 120, four corner posts with bracing, red and white bands, empty inside
// (sticks with many runs: the bracing floats above the ground).
VoxFile mast() {
    Builder b(6, 6, 120);
    for (int z = 0; z < 120; ++z) {
        const Rgba8 c = (z / 12) % 2 ? Rgba8{200, 40, 30, 255} : Rgba8{235, 235, 235, 255};
        for (const int x : {0, 5})
            for (const int y : {0, 5})
                b.set(x, y, z, c);
        if (z % 6 == 0)
            for (int i = 1; i < 5; ++i) {
                b.set(i, 0, z, c), b.set(i, 5, z, c), b.set(0, i, z, c), b.set(5, i, z, c);
            }
    }
    return b.file;
}

// Three views of a tank made of simple shapes (hull box, turret cylinder, barrel), one pixel per
// voxel of a 24 x 48 x 14 grid, on a white background; each view shaded differently.
struct TankShape {
    static bool hull(double x, double y, double z) {
        return x >= 1 && x < 23 && y >= 2 && y < 46 && z >= 1 && z < 7;
    }
    static bool tracks(double x, double y, double z) {
        return (x < 5 || x >= 19) && y >= 0 && y < 48 && z >= 0 && z < 4;
    }
    static bool turret(double x, double y, double z) {
        return z >= 7 && z < 11 && std::hypot(x - 12, y - 22) < 7;
    }
    static bool barrel(double x, double y, double z) {
        return y >= 28 && y < 48 && std::hypot(x - 12, z - 9) < 1.2;
    }
};

void writeTankViews(const std::string& dir) {
    const int sx = 24, sy = 48, sz = 14;
    const ig::Rgb8 bg{255, 255, 255};
    for (int which = 0; which < 3; ++which) {
        const int w = which == 0 ? sy : sx, h = which == 2 ? sy : sz;
        std::vector<std::uint8_t> rgb(static_cast<std::size_t>(w) * h * 3);
        for (int row = 0; row < h; ++row)
            for (int col = 0; col < w; ++col) {
                ig::Rgb8 c = bg;
                for (double d = 0.25; d < 48; d += 0.5) {
                    double x, y, z;
                    const double u = col + 0.5, v = row + 0.5;
                    if (which == 0)
                        x = sx - d, y = u, z = sz - v;
                    else if (which == 1)
                        x = sx - u, y = sy - d, z = sz - v;
                    else
                        x = u, y = sy - v, z = sz - d;
                    const double shade = which == 2 ? 1.0 : which == 0 ? 0.8 : 0.9;
                    auto s = [shade](int a) { return static_cast<std::uint8_t>(a * shade); };
                    if (TankShape::barrel(x, y, z))
                        c = {s(60), s(66), s(52)};
                    else if (TankShape::turret(x, y, z))
                        c = {s(104), s(112), s(78)};
                    else if (TankShape::tracks(x, y, z))
                        c = {s(54), s(50), s(46)};
                    else if (TankShape::hull(x, y, z))
                        c = {s(94), s(104), s(70)};
                    else
                        continue;
                    break;
                }
                std::uint8_t* p = &rgb[(static_cast<std::size_t>(row) * w + col) * 3];
                p[0] = c.r, p[1] = c.g, p[2] = c.b;
            }
        const char* names[3] = {"side.png", "front.png", "top.png"};
        std::string error;
        if (io::writePng8(dir + "/" + names[which], w, h, 3, rgb, &error) != 0) {
            throw ig::InputError(error);
        }
    }
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"Write the shipped voxel models (MagicaVoxel .vox) and the tank's three views."};
    std::string outDir = std::string(VIG_DATA_DIR) + "/models";
    app.add_option("--out-dir", outDir, "Folder to write into")->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    return ig::runProgram("make-models", [&]() -> int {
        std::filesystem::create_directories(outDir + "/tank");
        ig::writeVox(outDir + "/conifer.vox", conifer());
        ig::writeVox(outDir + "/broadleaf.vox", broadleaf());
        ig::writeVox(outDir + "/house.vox", house());
        ig::writeVox(outDir + "/mast.vox", mast());
        writeTankViews(outDir + "/tank");
        ig::SculptViews views{ig::loadSculptView(outDir + "/tank/side.png", "", {}),
                              ig::loadSculptView(outDir + "/tank/front.png", "", {}),
                              ig::loadSculptView(outDir + "/tank/top.png", "", {})};
        const ig::ObjectModel tank = ig::sculptModel(views, "tank");
        VoxFile f;
        f.models.push_back(tank.grid);
        f.palette = tank.palette;
        f.hasPalette = true;
        ig::writeVox(outDir + "/tank.vox", f);
        for (const char* name : {"conifer", "broadleaf", "house", "mast", "tank"}) {
            const VoxFile g = ig::readVox(outDir + "/" + name + ".vox");
            std::fprintf(stderr, "%s/%s.vox: %d x %d x %d, %zu voxels\n", outDir.c_str(), name,
                         g.models[0].sizeX, g.models[0].sizeY, g.models[0].sizeZ,
                         g.models[0].filled());
        }
        return 0;
    });
}
