// Sculpting from three views: carving (the visual hull) and photomapping.
#include "ig/sculpt.hpp"

#include "base/check.hpp"
#include "ig/error.hpp"

#include <png.h>

#include <algorithm>
#include <cstdlib>
#include <map>

namespace ig {
namespace {

// Pixel (u, v) of each view for voxel (x, y, z) of a sx x sy x sz model.
struct ViewMap {
    int sx, sy, sz;
    std::size_t side(int y, int z) const {  // column y, row sz-1-z; width sy
        return static_cast<std::size_t>(sz - 1 - z) * sy + y;
    }
    std::size_t front(int x, int z) const {  // column sx-1-x, row sz-1-z; width sx
        return static_cast<std::size_t>(sz - 1 - z) * sx + (sx - 1 - x);
    }
    std::size_t top(int x, int y) const {  // column x, row sy-1-y; width sx
        return static_cast<std::size_t>(sy - 1 - y) * sx + x;
    }
};

void checkView(const SculptView& v, const char* what, int w, int h, const std::string& name) {
    if (v.width != w || v.height != h) {
        throw InputError(name + ": the " + what + " view is " + std::to_string(v.width) + " x " +
                         std::to_string(v.height) + " pixels, the other views make it " +
                         std::to_string(w) + " x " + std::to_string(h));
    }
}

}  // namespace

std::vector<Rgb8> readRgbPng(const std::string& path, int& width, int& height) {
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&image, path.c_str())) {
        throw InputError(path + ": cannot read as PNG (" + image.message + ")");
    }
    if (image.width == 0 || image.height == 0 || image.width > 4096 || image.height > 4096) {
        png_image_free(&image);
        throw InputError(path + ": " + std::to_string(image.width) + " x " +
                         std::to_string(image.height) + " pixels (1..4096 on a side expected)");
    }
    image.format = PNG_FORMAT_RGB;
    std::vector<Rgb8> pixels(static_cast<std::size_t>(image.width) * image.height);
    if (!png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr)) {
        const std::string message = image.message;
        png_image_free(&image);
        throw InputError(path + ": cannot decode PNG (" + message + ")");
    }
    width = static_cast<int>(image.width);
    height = static_cast<int>(image.height);
    return pixels;
}

SculptView loadSculptView(const std::string& imagePath, const std::string& maskPath,
                          const BackgroundKey& key) {
    SculptView v;
    v.pixels = readRgbPng(imagePath, v.width, v.height);
    v.foreground.resize(v.pixels.size());
    if (!maskPath.empty()) {
        int mw = 0, mh = 0;
        const std::vector<Rgb8> mask = readRgbPng(maskPath, mw, mh);
        if (mw != v.width || mh != v.height) {
            throw InputError(maskPath + ": mask of " + std::to_string(mw) + " x " +
                             std::to_string(mh) + " pixels for an image of " +
                             std::to_string(v.width) + " x " + std::to_string(v.height));
        }
        for (std::size_t i = 0; i < mask.size(); ++i)
            v.foreground[i] = (mask[i].r | mask[i].g | mask[i].b) != 0;
        return v;
    }
    const Rgb8 bg = key.color.value_or(v.pixels[0]);
    for (std::size_t i = 0; i < v.pixels.size(); ++i) {
        const Rgb8 p = v.pixels[i];
        const int d = std::max({std::abs(p.r - bg.r), std::abs(p.g - bg.g), std::abs(p.b - bg.b)});
        v.foreground[i] = d > key.tolerance;
    }
    return v;
}

ObjectModel sculptModel(const SculptViews& views, const std::string& name) {
    const int sx = views.top.width, sy = views.top.height, sz = views.side.height;
    if (sx < 1 || sy < 1 || sz < 1 || sx > kVoxMaxSide || sy > kVoxMaxSide || sz > kVoxMaxSide) {
        throw InputError(name + ": the views make a model of " + std::to_string(sx) + " x " +
                         std::to_string(sy) + " x " + std::to_string(sz) +
                         " voxels (1..256 on a side; one pixel is one voxel)");
    }
    checkView(views.side, "side", sy, sz, name);
    checkView(views.front, "front", sx, sz, name);
    const ViewMap vm{sx, sy, sz};
    // Carving: a voxel goes when any view's ray through it starts at a background pixel.
    std::vector<std::uint8_t> solid(static_cast<std::size_t>(sx) * sy * sz, 0);
    VoxModel grid(sx, sy, sz);
    for (int z = 0; z < sz; ++z)
        for (int y = 0; y < sy; ++y)
            for (int x = 0; x < sx; ++x)
                solid[grid.index(x, y, z)] = views.side.foreground[vm.side(y, z)] &&
                                             views.front.foreground[vm.front(x, z)] &&
                                             views.top.foreground[vm.top(x, y)];
    // Photomapping: each view's pixel colours the first solid voxel along its ray, unless an
    // earlier view already did.
    std::vector<Rgb8> color(solid.size());
    std::vector<std::uint8_t> colored(solid.size(), 0);
    auto paint = [&](std::size_t voxel, Rgb8 c) {
        if (!colored[voxel]) {
            color[voxel] = c;
            colored[voxel] = 1;
        }
    };
    for (int y = 0; y < sy; ++y)  // top: down from the highest z
        for (int x = 0; x < sx; ++x)
            for (int z = sz - 1; z >= 0; --z)
                if (solid[grid.index(x, y, z)]) {
                    paint(grid.index(x, y, z), views.top.pixels[vm.top(x, y)]);
                    break;
                }
    for (int z = 0; z < sz; ++z)  // side: in from +x
        for (int y = 0; y < sy; ++y)
            for (int x = sx - 1; x >= 0; --x)
                if (solid[grid.index(x, y, z)]) {
                    paint(grid.index(x, y, z), views.side.pixels[vm.side(y, z)]);
                    break;
                }
    for (int z = 0; z < sz; ++z)  // front: in from +y
        for (int x = 0; x < sx; ++x)
            for (int y = sy - 1; y >= 0; --y)
                if (solid[grid.index(x, y, z)]) {
                    paint(grid.index(x, y, z), views.front.pixels[vm.front(x, z)]);
                    break;
                }
    // Voxels no view sees directly (the inside, and hollows no axis reaches) take the colour of
    // the nearest painted voxel below or above them in their column, else grey.
    for (int y = 0; y < sy; ++y)
        for (int x = 0; x < sx; ++x) {
            Rgb8 last{128, 128, 128};
            for (int z = sz - 1; z >= 0; --z) {
                const std::size_t i = grid.index(x, y, z);
                if (!solid[i]) continue;
                if (colored[i])
                    last = color[i];
                else
                    color[i] = last;
            }
        }
    // Palette.
    std::map<std::uint32_t, int> distinct;
    for (std::size_t i = 0; i < solid.size(); ++i) {
        if (solid[i]) distinct.emplace(packRgba(Rgba8{color[i].r, color[i].g, color[i].b, 255}), 0);
    }
    if (distinct.empty())
        throw InputError(
            name + ": nothing is left after carving (no pixel is foreground in all three views)");
    ObjectModel m;
    m.name = name;
    m.palette[0] = Rgba8{0, 0, 0, 0};
    const bool exact = distinct.size() <= 255;
    if (exact) {
        int k = 1;
        for (auto& [packed, index] : distinct) {
            index = k;
            m.palette[static_cast<std::size_t>(k++)] = unpackRgba(packed);
        }
    } else {
        for (int r = 0; r < 6; ++r)
            for (int g = 0; g < 7; ++g)
                for (int b = 0; b < 6; ++b)
                    m.palette[static_cast<std::size_t>(1 + (r * 7 + g) * 6 + b)] = Rgba8{
                        static_cast<std::uint8_t>(r * 51), static_cast<std::uint8_t>(g * 255 / 6),
                        static_cast<std::uint8_t>(b * 51), 255};
    }
    for (std::size_t i = 0; i < solid.size(); ++i) {
        if (!solid[i]) continue;
        const Rgb8 c = color[i];
        if (exact) {
            grid.voxels[i] =
                static_cast<std::uint8_t>(distinct.at(packRgba(Rgba8{c.r, c.g, c.b, 255})));
        } else {
            const int r = (c.r * 5 + 127) / 255, g = (c.g * 6 + 127) / 255,
                      b = (c.b * 5 + 127) / 255;
            grid.voxels[i] = static_cast<std::uint8_t>(1 + (r * 7 + g) * 6 + b);
        }
    }
    m.grid = std::move(grid);
    return m;
}

SculptView renderSculptView(const ObjectModel& model, int which) {
    const VoxModel& g = model.grid;
    const int sx = g.sizeX, sy = g.sizeY, sz = g.sizeZ;
    const ViewMap vm{sx, sy, sz};
    SculptView v;
    v.width = which == 0 ? sy : sx;
    v.height = which == 2 ? sy : sz;
    v.pixels.assign(static_cast<std::size_t>(v.width) * v.height, Rgb8{});
    v.foreground.assign(v.pixels.size(), 0);
    auto see = [&](std::size_t pixel, int x, int y, int z) {
        if (v.foreground[pixel] || !model.present(x, y, z)) return;
        const Rgba8 c = model.color(x, y, z);
        v.pixels[pixel] = Rgb8{c.r, c.g, c.b};
        v.foreground[pixel] = 1;
    };
    for (int a = 0; a < (which == 0 ? sx : which == 1 ? sy : sz); ++a) {
        for (int p = 0; p < (which == 2 ? sy : sz); ++p) {
            for (int q = 0; q < (which == 0 ? sy : sx); ++q) {
                if (which == 0) see(vm.side(q, p), sx - 1 - a, q, p);
                if (which == 1) see(vm.front(q, p), q, sy - 1 - a, p);
                if (which == 2) see(vm.top(q, p), q, p, sz - 1 - a);
            }
        }
    }
    return v;
}

}  // namespace ig
