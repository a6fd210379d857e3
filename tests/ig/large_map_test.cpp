// Maps of more than 2^31 samples, as a paged 65536 x 65536 database presents to the casters:
// every caster and kernel reads them with 64-bit offsets (a 32-bit index wraps there, and a
// colour's byte offset, three times the sample's, wraps from 2^31 / 3 samples on).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "ig/caster.hpp"
#include "ig/pyramid.hpp"
#include "ig/slope_bound.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain.hpp"

namespace ig {
namespace {

// The large map: 65536 x 69632 samples (4.6e9). The small one: 1024 x 1024, whose first sample
// is the large one's (kAtX, kAtY) (multiples of 1024, so every pyramid level lines up).
constexpr int kBigX = 65536, kBigY = 68 * 1024;
constexpr int kSmall = 1024;
constexpr int kAtX = 62 * 1024, kAtY = 66 * 1024;

// The cell maxima of cells [x0, x0 + n] x [y0, y0 + n] of a w-sample-wide level, from its
// samples.
void fillCellMax(const std::uint16_t* heights, std::uint16_t* cellMax, int w, int x0, int y0,
                 int n) {
    for (int cy = y0; cy <= y0 + n; ++cy) {
        const std::uint16_t* a = heights + static_cast<std::size_t>(cy) * w;
        cellMaxRow(a + x0, a + w + x0, n + 1,
                   cellMax + static_cast<std::size_t>(cy) * (w - 1) + x0);
    }
}

// A synthetic 1024² map, and a sparse 65536² one holding the same samples (its pyramid, nodes
// and slope bounds likewise) at its far corner, from sample (kAtX, kAtY): raw index 4.4e9 there,
// colour byte offset 1.3e10. Elsewhere the large map reads raw 0: a plain at the height offset,
// whose cliff to the terrain every bound (cell maxima, slopes) covers; the nodes over the cliff
// stay unwritten (no bound).
struct LargeFixture {
    TerrainMap small;
    TerrainMap big;
    // The fast caster's pyramids over the large map: every level (levels auto), and the nodes
    // alone (levels 0).
    std::shared_ptr<TerrainPyramid> bigPyramid, bigNodes;
    float* slopeBounds = nullptr;
    std::size_t slopeBytes = 0;
    std::shared_ptr<const SlopeBlocks> bigSlopes;

    LargeFixture() : small(makeSyntheticTerrain(kSmall, 11, 8.0)) {
        const double sx = std::abs(small.heightScale()) / small.spacingX();
        const double sy = std::abs(small.heightScale()) / small.spacingY();
        std::uint16_t maxRaw = 0;
        for (const std::uint16_t h : small.rawHeights())
            maxRaw = std::max(maxRaw, h);
        const double cliff = SlopeBlocks::boundOf(maxRaw, maxRaw, sx, sy);
        big = TerrainMap::sparse(kBigX, kBigY, small.spacingX(), small.spacingY(),
                                 small.heightScale(), small.heightOffset(),
                                 std::min(small.minHeight(), small.heightOffset()),
                                 small.maxHeight(), std::max(small.maxSlope(), cliff));
        const int n = kSmall;
        for (int y = 0; y < n; ++y) {
            std::memcpy(&big.rawHeights()[big.index(kAtX, kAtY + y)],
                        &small.rawHeights()[small.index(0, y)], n * sizeof(std::uint16_t));
            std::memcpy(&big.colors()[big.index(kAtX, kAtY + y)],
                        &small.colors()[small.index(0, y)], n * sizeof(Rgb8));
        }
        fillCellMax(big.rawHeights().data(), big.cellMaxData(), kBigX, kAtX - 1, kAtY - 1, n);

        for (const int levels : {0, kLevelsAuto}) {
            const TerrainPyramid sp(small, levels);
            auto bp = std::make_shared<TerrainPyramid>(big, sp.levelCount() - 1,
                                                       TerrainPyramid::Sparse{});
            copyPyramid(sp, *bp);
            (levels == 0 ? bigNodes : bigPyramid) = std::move(bp);
        }
        const SlopeBlocks smallSlopes(small);
        const int bw = SlopeBlocks::blocksAlong(kBigX), bh = SlopeBlocks::blocksAlong(kBigY);
        slopeBytes = static_cast<std::size_t>(bw) * bh * sizeof(float);
        slopeBounds = static_cast<float*>(allocateSparse(slopeBytes));
        const int bx0 = kAtX / SlopeBlocks::kBlock, by0 = kAtY / SlopeBlocks::kBlock;
        const int blocks = smallSlopes.blocksX();
        // Blocks of the small map's cells only keep their bound; those holding a cell of the
        // cliff around it take the cliff's.
        auto within = [&](int b) { return b >= 0 && (b + 1) * SlopeBlocks::kBlock <= n - 1; };
        for (int j = -1; j <= blocks; ++j) {
            for (int i = -1; i <= blocks; ++i) {
                slopeBounds[static_cast<std::size_t>(by0 + j) * bw + bx0 + i] =
                    within(i) && within(j)
                        ? smallSlopes.data()[static_cast<std::size_t>(j) * blocks + i]
                        : static_cast<float>(cliff);
            }
        }
        bigSlopes = std::make_shared<const SlopeBlocks>(big, slopeBounds);
    }
    ~LargeFixture() {
        bigSlopes.reset();
        deallocateSparse(slopeBounds, slopeBytes);
    }
    LargeFixture(const LargeFixture&) = delete;
    LargeFixture& operator=(const LargeFixture&) = delete;

    // The small map's pyramid `sp`, copied to the far corner of the large map's `bp`.
    static void copyPyramid(const TerrainPyramid& sp, TerrainPyramid& bp) {
        for (int k = 1; k < sp.levelCount(); ++k) {
            const PyramidLevel& s = sp.level(k);
            const PyramidLevel& b = bp.level(k);
            const int ax = kAtX >> k, ay = kAtY >> k;
            for (int y = 0; y < s.height; ++y) {
                std::memcpy(bp.levelHeights(k) + b.index(ax, ay + y), s.heights + s.index(0, y),
                            s.width * sizeof(std::uint16_t));
                std::memcpy(bp.levelColors(k) + b.index(ax, ay + y), s.colors + s.index(0, y),
                            s.width * sizeof(Rgb8));
            }
            fillCellMax(b.heights, bp.levelCellMax(k), b.width, ax - 1, ay - 1, s.width);
        }
        for (int j = 1; j < sp.nodeLevelCount(); ++j) {
            const int ax = kAtX >> j, ay = kAtY >> j;
            for (int ny = 0; ny < sp.nodesY(j); ++ny) {
                for (int nx = 0; nx < sp.nodesX(j); ++nx) {
                    bp.nodesComplement(
                        j)[static_cast<std::size_t>(ay + ny) * bp.nodesX(j) + ax + nx] =
                        static_cast<std::uint16_t>(~sp.nodeMaxRaw(j, nx, ny));
                }
            }
        }
    }

    // `p` (over the small map) over the large one.
    Pose moved(Pose p) const {
        p.position.x += kAtX * small.spacingX();
        p.position.y += kAtY * small.spacingY();
        return p;
    }
};

const LargeFixture& fixture() {
    static const LargeFixture f;
    return f;
}

// Views over the middle of the small map, looking down steeply enough that every ray ends on its
// terrain, along both axes and both ways of each.
std::vector<Pose> views(const TerrainMap& small) {
    std::vector<Pose> poses;
    const double yaws[] = {0.0, 100.0, 190.0, 290.0};
    for (int i = 0; i < 4; ++i) {
        Pose p;
        p.position.x = small.extentX() * (0.45 + 0.03 * i);
        p.position.y = small.extentY() * (0.5 - 0.02 * i);
        p.position.z = small.maxHeight() + 150.0 + 60.0 * i;
        p.yaw = yaws[i] * M_PI / 180.0;
        p.pitch = -(50.0 + 6.0 * i) * M_PI / 180.0;
        poses.push_back(p);
    }
    return poses;
}

const Intrinsics kView = Intrinsics::fromFov(160, 96, 50.0 * M_PI / 180.0);

struct Difference {
    std::size_t colour = 0, depth = 0, sky = 0;
    double worstDepth = 0.0;  // relative
};

Difference compare(const RenderedFrame& a, const RenderedFrame& b) {
    Difference d;
    for (std::size_t i = 0; i < a.color.size(); ++i) {
        d.colour += !(a.color[i] == b.color[i]);
        d.depth += !(std::abs(a.depth[i] - b.depth[i]) <= 1e-6 * a.depth[i]);
        d.worstDepth =
            std::max<double>(d.worstDepth, std::abs(a.depth[i] - b.depth[i]) / a.depth[i]);
        d.sky += !std::isfinite(a.depth[i]);
    }
    return d;
}

// The same terrain drawn from the same place relative to it: on the small map, and at the large
// map's far corner, past 2^32 samples. The positions differ by a whole number of cells and are
// exact in binary, so the casters make the same steps and the same solves over level 0: the
// images agree to the pixel (depths to a millionth; the eye's coordinates round differently).
// With coarser levels, where a march starts also depends on the map's box and its empty-space
// descent (the larger map's), and the level blend is taken where the ray enters a cell or
// starts in it, so a few depths differ past the millionth; the colours still agree.
TEST(LargeMaps, EveryCasterReadsPast2To32SamplesAsOnASmallMap) {
    const LargeFixture& f = fixture();
    ASSERT_GT(f.big.index(kAtX, kAtY), std::size_t{1} << 32);
    struct Case {
        CasterKind kind;
        int levels;
        CasterKernel kernel;
    };
    std::vector<Case> cases = {{CasterKind::Reference, 0, CasterKernel::Auto},
                               {CasterKind::Naive, 0, CasterKernel::Auto}};
    for (const CasterKernel k : {CasterKernel::Scalar, CasterKernel::Avx2, CasterKernel::Avx512,
                                 CasterKernel::Rows4Portable, CasterKernel::Rows8Portable}) {
        if (!casterKernelMissing(k).empty()) continue;
        cases.push_back({CasterKind::Fast, 0, k});
        cases.push_back({CasterKind::Fast, kLevelsAuto, k});
    }
    for (const Case& c : cases) {
        const std::string what = std::string(casterName(c.kind)) + " levels " +
                                 std::to_string(c.levels) + " kernel " +
                                 std::string(casterKernelName(c.kernel));
        SCOPED_TRACE(what);
        RenderOptions o;
        o.levels = c.levels;
        o.kernel = c.kernel;
        o.threads = 1;
        const auto onSmall = makeCaster(c.kind, f.small, o);
        if (c.kind == CasterKind::Fast) {
            o.pyramid = c.levels == 0 ? f.bigNodes : f.bigPyramid;
            o.slopes = f.bigSlopes;
        }
        const auto onBig = makeCaster(c.kind, f.big, o);
        int view = 0;
        for (const Pose& p : views(f.small)) {
            const RenderedFrame a = renderFrame(*onSmall, f.small, p, kView);
            const RenderedFrame b = renderFrame(*onBig, f.big, f.moved(p), kView);
            const Difference d = compare(a, b);
            ASSERT_EQ(d.sky, 0u) << "view " << view << ": every ray must end on the small map";
            EXPECT_EQ(d.colour, 0u) << "view " << view << ": pixels of another colour";
            if (c.levels == 0) {
                EXPECT_EQ(d.depth, 0u)
                    << "view " << view << ": pixels at another depth, worst " << d.worstDepth;
            } else {
                EXPECT_LE(d.depth, a.depth.size() / 200) << "view " << view;
                EXPECT_LT(d.worstDepth, 1e-3) << "view " << view;
            }
            ++view;
        }
    }
}

}  // namespace
}  // namespace ig
