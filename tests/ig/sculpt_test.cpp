#include "ig/sculpt.hpp"

#include "ig/error.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <string>

namespace {

using namespace ig;

// The shape, in model units (voxels): a box x 4..36, y 6..54, z 0..12 and a vertical cylinder
// of radius 9 about (20, 30) from z 12 to 27, in a 40 x 60 x 30 grid.
constexpr int kX = 40, kY = 60, kZ = 30;
bool inBox(double x, double y, double z) {
    return x >= 4 && x < 36 && y >= 6 && y < 54 && z >= 0 && z < 12;
}
bool inCylinder(double x, double y, double z) {
    return z >= 12 && z < 27 && std::hypot(x - 20, y - 30) < 9;
}
bool inShape(double x, double y, double z) {
    return inBox(x, y, z) || inCylinder(x, y, z);
}

constexpr Rgb8 kBackground{250, 250, 250};

// A view rendered from the analytic shape, 4 x 4 samples per pixel: each sample sees the part
// (box or cylinder) the orthographic ray meets, coloured per view and part; pixels blend their
// samples with the background (anti-aliased edges, as a photograph's).
SculptView renderView(int which) {
    const Rgb8 box[3] = {{90, 60, 40}, {60, 90, 40}, {120, 100, 70}};
    const Rgb8 cyl[3] = {{40, 70, 110}, {30, 60, 140}, {70, 110, 160}};
    SculptView v;
    v.width = which == 0 ? kY : kX;
    v.height = which == 2 ? kY : kZ;
    v.pixels.resize(static_cast<std::size_t>(v.width) * v.height);
    v.foreground.assign(v.pixels.size(), 0);
    for (int row = 0; row < v.height; ++row) {
        for (int col = 0; col < v.width; ++col) {
            float acc[3] = {0, 0, 0};
            for (int s = 0; s < 16; ++s) {
                const double u = col + (s % 4 + 0.5) / 4, w = row + (s / 4 + 0.5) / 4;
                bool hitBox = false, hitCyl = false;
                for (double d = 0.125; d < 60; d += 0.25) {  // along the view's axis
                    double x, y, z;
                    if (which == 0)
                        x = kX - d, y = u, z = kZ - w;
                    else if (which == 1)
                        x = kX - u, y = kY - d, z = kZ - w;
                    else
                        x = u, y = kY - w, z = kZ - d;
                    if (inCylinder(x, y, z)) {
                        hitCyl = true;
                        break;
                    }
                    if (inBox(x, y, z)) {
                        hitBox = true;
                        break;
                    }
                }
                const Rgb8 c = hitCyl ? cyl[which] : hitBox ? box[which] : kBackground;
                acc[0] += c.r, acc[1] += c.g, acc[2] += c.b;
            }
            v.pixels[static_cast<std::size_t>(row) * v.width + col] =
                Rgb8{static_cast<std::uint8_t>(acc[0] / 16 + 0.5f),
                     static_cast<std::uint8_t>(acc[1] / 16 + 0.5f),
                     static_cast<std::uint8_t>(acc[2] / 16 + 0.5f)};
        }
    }
    return v;
}

// The three views, rendered once per test program.
const SculptView& syntheticView(int which) {
    static const SculptView views[3] = {renderView(0), renderView(1), renderView(2)};
    return views[which];
}

// The background key of loadSculptView, applied in memory.
void key(SculptView& v, int tolerance) {
    for (std::size_t i = 0; i < v.pixels.size(); ++i) {
        const Rgb8 p = v.pixels[i];
        v.foreground[i] = std::max({std::abs(p.r - kBackground.r), std::abs(p.g - kBackground.g),
                                    std::abs(p.b - kBackground.b)}) > tolerance;
    }
}

TEST(Sculpt, CarvedVolumeMatchesTheVisualHull) {
    SculptViews views{syntheticView(0), syntheticView(1), syntheticView(2)};
    // A key half way between the parts' colours and the background: edge pixels count as the
    // object where it covers about half of them.
    key(views.side, 70), key(views.front, 70), key(views.top, 70);
    const ObjectModel m = sculptModel(views, "box+cylinder");
    ASSERT_EQ(m.grid.sizeX, kX);
    ASSERT_EQ(m.grid.sizeY, kY);
    ASSERT_EQ(m.grid.sizeZ, kZ);
    // The visual hull of the shape at voxel centres: inside all three silhouettes. (Not the
    // shape: the top view cannot see that the cylinder is round where it stands on the box, so
    // the hull keeps a square prism there.)
    auto silhouette = [](auto inside) {
        for (double d = 0.125; d < 60; d += 0.25)
            if (inside(d)) return true;
        return false;
    };
    auto inHull = [&](double x, double y, double z) {
        return silhouette([&](double d) { return inShape(d, y, z); }) &&
               silhouette([&](double d) { return inShape(x, d, z); }) &&
               silhouette([&](double d) { return inShape(x, y, d); });
    };
    std::size_t both = 0, either = 0, shapeBoth = 0, shapeEither = 0;
    for (int z = 0; z < kZ; ++z)
        for (int y = 0; y < kY; ++y)
            for (int x = 0; x < kX; ++x) {
                const bool hull = inHull(x + 0.5, y + 0.5, z + 0.5);
                const bool shape = inShape(x + 0.5, y + 0.5, z + 0.5);
                const bool carved = m.present(x, y, z);
                both += hull && carved;
                either += hull || carved;
                shapeBoth += shape && carved;
                shapeEither += shape || carved;
            }
    const double iou = static_cast<double>(both) / static_cast<double>(either);
    EXPECT_GE(iou, 0.95) << both << " / " << either;
    RecordProperty("iou", std::to_string(iou));
    // The shape itself is smaller than its hull, by the cylinder's corners.
    EXPECT_LT(static_cast<double>(shapeBoth) / static_cast<double>(shapeEither), iou);
    // Photomapping: each view rendered back from the model shows the view's colours.
    for (int which = 0; which < 3; ++which) {
        const SculptView& in = which == 0 ? views.side : which == 1 ? views.front : views.top;
        const SculptView back = renderSculptView(m, which);
        std::size_t seen = 0, exact = 0;
        double error = 0;
        for (std::size_t i = 0; i < in.pixels.size(); ++i) {
            if (!in.foreground[i] || !back.foreground[i]) continue;
            ++seen;
            const Rgb8 a = in.pixels[i], b = back.pixels[i];
            exact += a == b;
            error += std::abs(a.r - b.r) + std::abs(a.g - b.g) + std::abs(a.b - b.b);
        }
        ASSERT_GT(seen, 300u) << which;
        RecordProperty("exact_" + std::to_string(which),
                       std::to_string(static_cast<double>(exact) / seen));
        RecordProperty("mae_" + std::to_string(which),
                       std::to_string(error / (3.0 * 255.0 * seen)));
        EXPECT_GE(static_cast<double>(exact) / seen, 0.85) << "view " << which;
        EXPECT_LT(error / (3.0 * 255.0 * seen), 0.03) << "view " << which;
    }
}

TEST(Sculpt, ViewsThatDisagreeAreRefused) {
    SculptViews views{syntheticView(0), syntheticView(1), syntheticView(2)};
    key(views.side, 70), key(views.front, 70), key(views.top, 70);
    views.front.width -= 1;
    views.front.pixels.resize(views.front.pixels.size() - static_cast<std::size_t>(kZ));
    try {
        sculptModel(views, "tank");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("tank: the front view is 39 x 30 pixels, the other "
                                             "views make it 40 x 30"),
                  std::string::npos)
            << e.what();
    }
    SculptViews empty{syntheticView(0), syntheticView(1), syntheticView(2)};  // all background
    for (auto* v : {&empty.side, &empty.front, &empty.top})
        v->foreground.assign(v->foreground.size(), 0);
    EXPECT_THROW(sculptModel(empty, "nothing"), InputError);  // no foreground at all
    EXPECT_THROW(loadSculptView("/nonexistent.png", "", {}), InputError);
}

}  // namespace
