#include "prp/id_warp.hpp"

#include "ig/error.hpp"
#include "prp/processor.hpp"
#include "prp/synthetic_frame.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace prp {
namespace {

// 240 x 180 rendered (margins 16): every coordinate fits a colour channel.
const ig::Intrinsics kIn = ig::Intrinsics::fromFov(208, 148, 1.0, 16);

// A frame of the plane whose red is each pixel's column and green its row, and whose object id
// names the pixel (x + 256 y, never 0 inside: row 0's ids are x + 256 * 0, so id 0 is pixel
// (0, 0) only, which is fine for a position test).
ig::RenderedFrame coordinateFrame(const ig::Pose& pose) {
    ig::RenderedFrame f = test::renderPlane(pose, kIn);
    f.objectId.resize(f.color.size());
    for (int y = 0; y < kIn.height; ++y) {
        for (int x = 0; x < kIn.width; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * kIn.width + x;
            f.color[i] = {static_cast<std::uint8_t>(x), static_cast<std::uint8_t>(y), 9};
            f.objectId[i] = static_cast<std::uint16_t>(x + 256 * y);
        }
    }
    return f;
}

PrpOptions options(WarpModel m, bool depthReference = false) {
    PrpOptions o;
    o.outWidth = kIn.windowWidth();
    o.outHeight = kIn.windowHeight();
    o.format = PixelFormat::Rgb8;
    o.model = m;
    o.depthReference = depthReference;
    return o;
}

// Poses around the frame's: still, moved, rolled, far enough that samples leave the frame.
std::vector<ig::Pose> fieldPoses(const ig::Pose& pose) {
    std::vector<ig::Pose> out;
    for (int k = 0; k <= 12; k += 3) {
        ig::Pose at = pose;
        at.position += glm::dvec3{2.0, 5.0, -1.5} * static_cast<double>(k);
        at.yaw += 0.006 * k;
        at.pitch -= 0.003 * k;
        at.roll = 0.02 * k;
        out.push_back(at);
    }
    return out;
}

// For every model: the warped id of each output pixel is the rendered pixel the colour warp's
// sample there rounds to. The colour of a linear ramp sampled bilinearly with 8-bit weights
// rounds to the nearer tap (ties right and down), so red and green read back the colour
// sample's nearest pixel, which must be the id's pixel.
TEST(IdWarp, SamplesWhereTheColourWarpSamples) {
    const ig::Pose pose = test::lookingDown(-35.0, 300.0);
    const ig::RenderedFrame f = coordinateFrame(pose);
    struct Case {
        WarpModel model;
        bool reference;
    };
    for (const Case c : {Case{WarpModel::Poly, false}, Case{WarpModel::Affine, false},
                         Case{WarpModel::Homography, false}, Case{WarpModel::Depth, false},
                         Case{WarpModel::Depth, true}, Case{WarpModel::Auto, false},
                         Case{WarpModel::Hold, false}}) {
        PostRenderingProcessor prp(options(c.model, c.reference));
        std::uint64_t n = 0;
        for (const ig::Pose& at : fieldPoses(pose)) {
            for (int parity = 0; parity < 2; ++parity, ++n) {
                Field field;
                prp.process(f, at, 0.0, n, field);
                ASSERT_EQ(field.objectId.size(),
                          static_cast<std::size_t>(field.width) * field.lines);
                std::size_t mismatches = 0;
                for (int line = 0; line < field.lines; ++line) {
                    for (int x = 0; x < field.width; ++x) {
                        const std::uint8_t* rgb = field.line(line) + 3 * x;
                        const std::uint16_t id =
                            field.objectId[static_cast<std::size_t>(line) * field.width + x];
                        mismatches += id != rgb[0] + 256 * rgb[1];
                    }
                }
                // The double-precision reference rounds its own weights: ties may differ.
                const std::size_t allowed =
                    c.reference ? static_cast<std::size_t>(field.width) * field.lines / 200 : 0;
                EXPECT_LE(mismatches, allowed)
                    << warpModelName(c.model) << (c.reference ? " (reference)" : "") << " field "
                    << n;
            }
        }
    }
}

// The frame's own pose: every model maps each output pixel to its own rendered pixel, so the
// field's ids are the frame's window ids, line for line.
TEST(IdWarp, IdentityGivesTheFramesIds) {
    const ig::Pose pose = test::lookingDown(-35.0, 300.0);
    const ig::RenderedFrame f = coordinateFrame(pose);
    for (const WarpModel m : {WarpModel::Poly, WarpModel::Affine, WarpModel::Homography,
                              WarpModel::Depth, WarpModel::Auto, WarpModel::Hold}) {
        PostRenderingProcessor prp(options(m));
        for (std::uint64_t n = 0; n < 2; ++n) {
            Field field;
            prp.process(f, pose, 0.0, n, field);
            std::size_t wrong = 0;
            for (int line = 0; line < field.lines; ++line) {
                const int y = field.frameLine(line) + kIn.margin;
                for (int x = 0; x < field.width; ++x) {
                    wrong += field.objectId[static_cast<std::size_t>(line) * field.width + x] !=
                             f.objectId[static_cast<std::size_t>(y) * kIn.width + x + kIn.margin];
                }
            }
            EXPECT_EQ(wrong, 0u) << warpModelName(m) << " field " << n;
        }
    }
}

TEST(IdWarp, NearestIdClampsAsTheSamplerDoes) {
    const std::vector<std::uint16_t> ids = {1, 2, 3, 4, 5, 6};  // 3 x 2
    const IdSource s{ids.data(), 3, 2};
    constexpr std::int64_t one = std::int64_t{1} << 32;
    EXPECT_EQ(nearestId(s, -5 * one, -one), 1);
    EXPECT_EQ(nearestId(s, one / 2 - 1, 0), 1);  // just short of halfway: the left tap
    EXPECT_EQ(nearestId(s, one / 2, 0), 2);      // halfway: the right tap
    EXPECT_EQ(nearestId(s, 100 * one, 0), 3);    // past the right edge: the edge pixel
    EXPECT_EQ(nearestId(s, one, one / 2), 5);    // halfway down: the lower row
    EXPECT_EQ(nearestId(s, 100 * one, 9 * one), 6);
}

TEST(IdWarp, FramesWithoutIdsGiveFieldsWithoutIds) {
    const ig::Pose pose = test::lookingDown(-35.0, 300.0);
    ig::RenderedFrame f = coordinateFrame(pose);
    PostRenderingProcessor prp(options(WarpModel::Poly));
    Field field;
    prp.process(f, pose, 0.0, 0, field);
    EXPECT_FALSE(field.objectId.empty());
    f.objectId.clear();
    prp.process(f, pose, 0.0, 1, field);
    EXPECT_TRUE(field.objectId.empty());
    f.objectId.assign(10, 0);  // not the frame's size
    EXPECT_THROW(prp.process(f, pose, 0.0, 2, field), ig::InputError);
}

}  // namespace
}  // namespace prp
