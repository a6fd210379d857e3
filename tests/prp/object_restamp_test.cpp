// Moving objects re-stamped at the field's instant (prp/object_restamp.hpp), against frames
// rendered with the object where it truly is at the field's instant.
#include "prp/object_restamp.hpp"

#include "prp/processor.hpp"
#include "prp/synthetic_frame.hpp"

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

namespace prp {
namespace {

const ig::Intrinsics kIn = ig::Intrinsics::fromFov(320, 240, 0.6, 16);
constexpr std::uint16_t kTank = 5;
constexpr std::uint16_t kWall = 7;
constexpr ig::Rgb8 kTankColor{200, 40, 40};
constexpr ig::Rgb8 kWallColor{30, 30, 200};

struct Box {
    glm::dvec3 lo, hi;
    glm::dvec3 middle() const { return 0.5 * (lo + hi); }
    Box moved(const glm::dvec3& by) const { return {lo + by, hi + by}; }
};

// Distance along the unit ray to the box (slabs), +inf when missed.
double boxDistance(const glm::dvec3& o, const glm::dvec3& d, const Box& b) {
    double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        if (std::abs(d[a]) < 1e-12) {
            if (o[a] < b.lo[a] || o[a] > b.hi[a]) return std::numeric_limits<double>::infinity();
            continue;
        }
        double ta = (b.lo[a] - o[a]) / d[a], tb = (b.hi[a] - o[a]) / d[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t0 <= t1 ? t0 : std::numeric_limits<double>::infinity();
}

// The plane of synthetic_frame.hpp with solid boxes on it: colour, depth and ids.
struct Solid {
    Box box;
    std::uint16_t id;
    ig::Rgb8 color;
};
ig::RenderedFrame renderWith(const ig::Pose& pose, const std::vector<Solid>& solids,
                             double time = 0.0) {
    ig::RenderedFrame f = test::renderPlane(pose, kIn, time);
    f.objectId.assign(f.color.size(), 0);
    const ig::Camera cam(pose, kIn);
    for (int y = 0; y < kIn.height; ++y) {
        for (int x = 0; x < kIn.width; ++x) {
            const glm::dvec3 dir = glm::normalize(cam.rayDirection(x + 0.5, y + 0.5));
            const std::size_t i = static_cast<std::size_t>(y) * kIn.width + x;
            for (const Solid& s : solids) {
                const double t = boxDistance(pose.position, dir, s.box);
                if (t < static_cast<double>(f.depth[i])) {
                    f.depth[i] = static_cast<float>(t);
                    f.color[i] = s.color;
                    f.objectId[i] = s.id;
                }
            }
        }
    }
    return f;
}

ig::Pose camera() {
    return test::lookingDown(-35.0, 120.0);
}

// The ground point at the middle of the view.
glm::dvec3 viewMiddle(const ig::Pose& pose) {
    const ig::Camera cam(pose, kIn);
    glm::dvec3 dir;
    const double t = test::groundDistance(cam, 0.5 * kIn.width, 0.5 * kIn.height, dir);
    return pose.position + t * dir;
}

PrpOptions options(WarpModel m, PixelFormat f = PixelFormat::Rgb8) {
    PrpOptions o;
    o.outWidth = kIn.windowWidth();
    o.outHeight = kIn.windowHeight();
    o.format = f;
    o.model = m;
    return o;
}

// The field's lines of a frame rendered at the output's own window (margins dropped).
std::vector<std::uint16_t> trueIds(const ig::RenderedFrame& frame, const Field& field) {
    std::vector<std::uint16_t> ids(static_cast<std::size_t>(field.width) * field.lines);
    for (int line = 0; line < field.lines; ++line) {
        for (int x = 0; x < field.width; ++x) {
            ids[static_cast<std::size_t>(line) * field.width + x] =
                frame.objectId[static_cast<std::size_t>(field.frameLine(line) + kIn.margin) *
                                   kIn.width +
                               x + kIn.margin];
        }
    }
    return ids;
}

struct Count {
    std::uint64_t n = 0;
    double x = 0.0, y = 0.0;
};
Count countOf(const std::vector<std::uint16_t>& ids, const Field& field, std::uint16_t id) {
    Count c;
    for (int line = 0; line < field.lines; ++line) {
        for (int x = 0; x < field.width; ++x) {
            if (ids[static_cast<std::size_t>(line) * field.width + x] != id) continue;
            ++c.n;
            c.x += x + 0.5;
            c.y += field.frameLine(line) + 0.5;
        }
    }
    if (c.n > 0) {
        c.x /= static_cast<double>(c.n);
        c.y /= static_cast<double>(c.n);
    }
    return c;
}

// Pixels that are `id` in `shown` with no pixel of `id` in `real` within a column and a line:
// an object drawn where it is not (not merely its outline a pixel off).
std::uint64_t ghosts(const std::vector<std::uint16_t>& shown,
                     const std::vector<std::uint16_t>& real, const Field& field, std::uint16_t id) {
    std::uint64_t n = 0;
    for (int line = 0; line < field.lines; ++line) {
        for (int x = 0; x < field.width; ++x) {
            if (shown[static_cast<std::size_t>(line) * field.width + x] != id) continue;
            bool near = false;
            for (int l = std::max(0, line - 1); l <= std::min(field.lines - 1, line + 1); ++l) {
                for (int c = std::max(0, x - 1); c <= std::min(field.width - 1, x + 1); ++c)
                    near = near || real[static_cast<std::size_t>(l) * field.width + c] == id;
            }
            n += near ? 0 : 1;
        }
    }
    return n;
}

std::uint64_t differing(const std::vector<std::uint16_t>& a, const std::vector<std::uint16_t>& b) {
    std::uint64_t n = 0;
    for (std::size_t i = 0; i < a.size(); ++i)
        n += a[i] != b[i] ? 1 : 0;
    return n;
}

struct Scene {
    ig::Pose framePose, fieldPose;
    Box tankAtFrame, tankAtField;
    double frameTime = 0.0, fieldTime = 4 * kFieldPeriod;
};

Scene tankDriving(const glm::dvec3& by = {3.0, 2.0, 0.0}) {
    Scene s;
    s.framePose = camera();
    s.fieldPose = s.framePose;
    s.fieldPose.position += glm::dvec3{1.5, 2.0, -0.5};  // the camera moves too
    s.fieldPose.yaw += 0.01;
    s.fieldPose.roll = 0.03;
    const glm::dvec3 g = viewMiddle(s.framePose);
    s.tankAtFrame = {g + glm::dvec3{-6.0, -4.0, 0.0}, g + glm::dvec3{6.0, 4.0, 5.0}};
    s.tankAtField = s.tankAtFrame.moved(by);
    return s;
}

// A tank driving 3.6 m over four fields, seen from a moving, rolling camera: re-stamped, its
// pixels are where a frame rendered at the field's instant shows them, to its outline; warped
// alone, they lag by its whole motion.
TEST(ObjectRestamp, MovedObjectMatchesTheFieldInstant) {
    const Scene s = tankDriving();
    const ig::RenderedFrame frame =
        renderWith(s.framePose, {{s.tankAtFrame, kTank, kTankColor}}, s.frameTime);
    // The truth: the field's pose and the tank where it is then, rendered at the window (the
    // camera's motion warped exactly: no margin needed when nothing moves after rendering).
    const ig::RenderedFrame truth =
        renderWith(s.fieldPose, {{s.tankAtField, kTank, kTankColor}}, s.fieldTime);
    const ObjectMotion motion{kTank, s.tankAtFrame.middle(), s.tankAtField.middle()};
    for (const WarpModel model : {WarpModel::Poly, WarpModel::Depth}) {
        SCOPED_TRACE(warpModelName(model));
        Field plain, moved;
        PostRenderingProcessor(options(model)).process(frame, s.fieldPose, s.fieldTime, 1, plain);
        PostRenderingProcessor(options(model))
            .process(frame, s.fieldPose, s.fieldTime, 1, moved, std::nullopt, 0.0, {&motion, 1});
        const std::vector<std::uint16_t> real = trueIds(truth, moved);
        const Count t = countOf(real, moved, kTank);
        const Count p = countOf(plain.objectId, plain, kTank);
        const Count m = countOf(moved.objectId, moved, kTank);
        ASSERT_GT(t.n, 200u);
        const double lag = std::hypot(p.x - t.x, p.y - t.y);
        const double error = std::hypot(m.x - t.x, m.y - t.y);
        EXPECT_GT(lag, 5.0);  // the motion is worth re-stamping
        EXPECT_LT(error, 0.5) << "lag " << lag;
        EXPECT_EQ(moved.restampedObjects, 1);
        EXPECT_GT(moved.restampedPixels, t.n / 2);
        // Pixel for pixel: only the outline differs (perspective over the tank's own depth,
        // half-pixel rounding of the shift), against the whole motion without.
        const std::uint64_t after = differing(moved.objectId, real);
        const std::uint64_t before = differing(plain.objectId, real);
        EXPECT_LT(after, t.n / 5) << "before " << before;
        EXPECT_LT(5 * after, before);
        // Nothing of the tank is left where it was: it is drawn only where it is now.
        EXPECT_EQ(ghosts(moved.objectId, real, moved, kTank), 0u);
        EXPECT_GT(ghosts(plain.objectId, real, plain, kTank), t.n / 8);  // the check can fail
    }
}

// The colour goes with the ids: the tank's own colour where it is now, ground where it was.
TEST(ObjectRestamp, ColourFollowsTheObject) {
    const Scene s = tankDriving();
    const ig::RenderedFrame frame =
        renderWith(s.framePose, {{s.tankAtFrame, kTank, kTankColor}}, s.frameTime);
    const ObjectMotion motion{kTank, s.tankAtFrame.middle(), s.tankAtField.middle()};
    Field moved;
    PostRenderingProcessor(options(WarpModel::Poly))
        .process(frame, s.fieldPose, s.fieldTime, 1, moved, std::nullopt, 0.0, {&motion, 1});
    std::uint64_t tank = 0, red = 0, ground = 0, notRed = 0;
    for (int line = 0; line < moved.lines; ++line) {
        for (int x = 0; x < moved.width; ++x) {
            const std::uint8_t* p = moved.line(line) + 3 * x;
            const bool isRed = p[0] == kTankColor.r && p[1] == kTankColor.g && p[2] == kTankColor.b;
            // Inner pixels only (two pixels from any other id): the outline mixes tank and
            // ground in the bilinear sample.
            const auto idAt = [&](int l, int c) {
                l = std::clamp(l, 0, moved.lines - 1);
                c = std::clamp(c, 0, moved.width - 1);
                return moved.objectId[static_cast<std::size_t>(l) * moved.width + c];
            };
            const std::uint16_t id = idAt(line, x);
            bool inner = true;
            for (int l = line - 2; l <= line + 2; ++l) {
                for (int c = x - 2; c <= x + 2; ++c)
                    inner = inner && idAt(l, c) == id;
            }
            if (!inner) continue;
            if (id == kTank) {
                ++tank;
                red += isRed;
            } else {
                ++ground;
                notRed += !isRed;
            }
        }
    }
    ASSERT_GT(tank, 100u);
    EXPECT_EQ(red, tank);
    EXPECT_EQ(notRed, ground);
}

// Without motions, or with objects that do not move, the field is the warp's alone, to the byte.
TEST(ObjectRestamp, StillObjectsLeaveTheFieldAsWarped) {
    const Scene s = tankDriving({0.0, 0.0, 0.0});
    const ig::RenderedFrame frame =
        renderWith(s.framePose, {{s.tankAtFrame, kTank, kTankColor}}, s.frameTime);
    const ObjectMotion still{kTank, s.tankAtFrame.middle(), s.tankAtFrame.middle()};
    const ObjectMotion absent{99, s.tankAtFrame.middle(), s.tankAtFrame.middle() + 3.0};
    for (const PixelFormat f : {PixelFormat::Rgb8, PixelFormat::Uyvy, PixelFormat::Y8}) {
        Field plain, a, b;
        PostRenderingProcessor(options(WarpModel::Poly, f))
            .process(frame, s.fieldPose, s.fieldTime, 1, plain);
        PostRenderingProcessor(options(WarpModel::Poly, f))
            .process(frame, s.fieldPose, s.fieldTime, 1, a, std::nullopt, 0.0, {&still, 1});
        PostRenderingProcessor(options(WarpModel::Poly, f))
            .process(frame, s.fieldPose, s.fieldTime, 1, b, std::nullopt, 0.0, {&absent, 1});
        EXPECT_EQ(a.pixels, plain.pixels);
        EXPECT_EQ(a.objectId, plain.objectId);
        EXPECT_EQ(a.restampedObjects, 0);
        // An object the field does not show is not drawn.
        EXPECT_EQ(b.pixels, plain.pixels);
        EXPECT_EQ(b.objectId, plain.objectId);
    }
}

// A nearer object in the way hides the moved one: its pixels are never overwritten.
TEST(ObjectRestamp, NearerObjectsHideTheMovedOne) {
    const Scene s = tankDriving({6.0, 0.0, 0.0});
    // A wall between the camera and where the tank drives to, standing in the way of part of it.
    const glm::dvec3 toEye = glm::normalize(s.framePose.position - s.tankAtField.middle());
    const glm::dvec3 wallMiddle = s.tankAtField.middle() + 30.0 * toEye;
    const Box wall{wallMiddle + glm::dvec3{-1.0, -1.0, -4.0},
                   wallMiddle + glm::dvec3{1.0, 1.0, 4.0}};
    const ig::RenderedFrame frame = renderWith(
        s.framePose, {{s.tankAtFrame, kTank, kTankColor}, {wall, kWall, kWallColor}}, s.frameTime);
    const ig::RenderedFrame truth = renderWith(
        s.fieldPose, {{s.tankAtField, kTank, kTankColor}, {wall, kWall, kWallColor}}, s.fieldTime);
    const ObjectMotion motion{kTank, s.tankAtFrame.middle(), s.tankAtField.middle()};
    Field plain, moved;
    PostRenderingProcessor(options(WarpModel::Poly))
        .process(frame, s.fieldPose, s.fieldTime, 1, plain);
    PostRenderingProcessor(options(WarpModel::Poly))
        .process(frame, s.fieldPose, s.fieldTime, 1, moved, std::nullopt, 0.0, {&motion, 1});
    const std::vector<std::uint16_t> real = trueIds(truth, moved);
    std::uint64_t wallPixels = 0, kept = 0;
    for (std::size_t i = 0; i < plain.objectId.size(); ++i) {
        if (plain.objectId[i] != kWall) continue;
        ++wallPixels;
        kept += moved.objectId[i] == kWall;
    }
    ASSERT_GT(wallPixels, 50u);
    EXPECT_EQ(kept, wallPixels);
    // The tank is drawn only where the truth shows it (the part the wall hid in the frame stays
    // missing: the frame has nothing of it), and the wall does not spread into what it left.
    EXPECT_EQ(ghosts(moved.objectId, real, moved, kTank), 0u);
    EXPECT_GT(ghosts(plain.objectId, real, plain, kTank), 50u);
    EXPECT_EQ(ghosts(moved.objectId, real, moved, kWall), 0u);
}

// Every pixel format rewrites the same pixels: ids equal across formats, and UYVY pairs only
// where the moved object is (or was).
TEST(ObjectRestamp, SameIdsInEveryFormatAndNothingElseRewritten) {
    const Scene s = tankDriving();
    const ig::RenderedFrame frame =
        renderWith(s.framePose, {{s.tankAtFrame, kTank, kTankColor}}, s.frameTime);
    const ObjectMotion motion{kTank, s.tankAtFrame.middle(), s.tankAtField.middle()};
    Field rgb;
    PostRenderingProcessor(options(WarpModel::Poly))
        .process(frame, s.fieldPose, s.fieldTime, 1, rgb, std::nullopt, 0.0, {&motion, 1});
    for (const PixelFormat f : {PixelFormat::Uyvy, PixelFormat::Y8}) {
        Field plain, moved;
        PostRenderingProcessor(options(WarpModel::Poly, f))
            .process(frame, s.fieldPose, s.fieldTime, 1, plain);
        PostRenderingProcessor(options(WarpModel::Poly, f))
            .process(frame, s.fieldPose, s.fieldTime, 1, moved, std::nullopt, 0.0, {&motion, 1});
        EXPECT_EQ(moved.objectId, rgb.objectId);
        const std::size_t bpp = bytesPerPixel(f);
        std::uint64_t changedElsewhere = 0;
        for (int line = 0; line < moved.lines; ++line) {
            for (int x = 0; x < moved.width; ++x) {
                const std::size_t i = static_cast<std::size_t>(line) * moved.width + x;
                // A pixel is the tank's in either field, or the other of a pair with one.
                const std::size_t pair = f == PixelFormat::Uyvy ? (i ^ 1) : i;
                const bool tank = plain.objectId[i] == kTank || moved.objectId[i] == kTank ||
                                  plain.objectId[pair] == kTank || moved.objectId[pair] == kTank;
                if (tank) continue;
                changedElsewhere +=
                    std::memcmp(plain.line(line) + bpp * x, moved.line(line) + bpp * x, bpp) != 0;
            }
        }
        EXPECT_EQ(changedElsewhere, 0u) << pixelFormatName(f);
    }
}

// A field that holds the frame (the renderer has stopped) leaves the objects as rendered.
TEST(ObjectRestamp, NotOnAHeldField) {
    const Scene s = tankDriving();
    const ig::RenderedFrame frame =
        renderWith(s.framePose, {{s.tankAtFrame, kTank, kTankColor}}, s.frameTime);
    const ObjectMotion motion{kTank, s.tankAtFrame.middle(), s.tankAtField.middle()};
    PrpOptions o = options(WarpModel::Poly);
    o.holdAfter = 0.01;
    Field plain, moved;
    PostRenderingProcessor(o).process(frame, s.fieldPose, s.fieldTime, 1, plain);
    PostRenderingProcessor(o).process(frame, s.fieldPose, s.fieldTime, 1, moved, std::nullopt, 0.0,
                                      {&motion, 1});
    EXPECT_EQ(moved.warp.model, WarpModel::Hold);
    EXPECT_EQ(moved.restampedObjects, 0);
    EXPECT_EQ(moved.pixels, plain.pixels);
    EXPECT_EQ(moved.objectId, plain.objectId);
}

// A motion past kMaxRestampShiftPx (a jump), behind the eye or not finite is left alone.
TEST(ObjectRestamp, JumpsAndBadPointsAreLeftAlone) {
    const Scene s = tankDriving();
    const ig::RenderedFrame frame =
        renderWith(s.framePose, {{s.tankAtFrame, kTank, kTankColor}}, s.frameTime);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const glm::dvec3 m = s.tankAtFrame.middle();
    const ObjectMotion bad[] = {
        {kTank, m, m + glm::dvec3{400.0, 0.0, 0.0}},  // far off: a jump
        {kTank, m, s.framePose.position - 50.0 * glm::normalize(m - s.framePose.position)},
        {kTank, m, glm::dvec3{nan, 0.0, 0.0}},
    };
    Field plain;
    PostRenderingProcessor(options(WarpModel::Poly))
        .process(frame, s.fieldPose, s.fieldTime, 1, plain);
    for (const ObjectMotion& b : bad) {
        Field moved;
        PostRenderingProcessor(options(WarpModel::Poly))
            .process(frame, s.fieldPose, s.fieldTime, 1, moved, std::nullopt, 0.0, {&b, 1});
        EXPECT_EQ(moved.restampedObjects, 0);
        EXPECT_EQ(moved.pixels, plain.pixels);
        EXPECT_EQ(moved.objectId, plain.objectId);
    }
}

}  // namespace
}  // namespace prp
