// The fast caster's kernels: chosen once when the caster is built, recorded in the frame's
// stats, refused where the processor lacks them, and each vector kernel's image against its
// scalar twin's (the scalar column kernel on the single level, the row batches' portable twins
// on the multiresolution caster) over pose sweeps on Puget Sound, Goleta and a synthetic map;
// the portable twins against the scalar column kernel and the reference. A kernel the
// processor lacks is skipped, never compared with itself.
#include "base/cpu_features.hpp"
#include "ig/caster.hpp"
#include "ig/error.hpp"
#include "ig/fast_column.hpp"
#include "ig/image_compare.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_io.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace {

using ig::CasterKernel;

const ig::TerrainMap& puget() {
    static const ig::TerrainMap map = ig::loadPugetSound();
    return map;
}
const ig::TerrainMap& goleta() {
    static const ig::TerrainMap map = ig::loadGoleta();
    return map;
}
const ig::TerrainMap& synthetic() {
    static const ig::TerrainMap map = ig::makeSyntheticTerrain(512, 3, 10.0);
    return map;
}

std::vector<CasterKernel> vectorKernelsPresent() {
    std::vector<CasterKernel> kernels;
    for (const CasterKernel k : {CasterKernel::Avx2, CasterKernel::Avx512}) {
        if (ig::casterKernelMissing(k).empty()) kernels.push_back(k);
    }
    return kernels;
}

struct Agreement {
    int frames = 0, framesEqual = 0;  // colour and depth equal to the bit
    int countsEqual = 0;              // steps and restarts equal too
    std::uint64_t pixels = 0, pixelsEqual = 0;
};

// `kernel` against the scalar kernel: six sweep poses on each map, a width that leaves a
// partial four-column group.
Agreement againstScalar(CasterKernel kernel, int levels, int supersample) {
    const ig::Intrinsics in = ig::Intrinsics::fromFov(61, 37, ig::degToRad(60), 3);
    Agreement a;
    for (const ig::TerrainMap* map : {&puget(), &goleta(), &synthetic()}) {
        ig::RenderOptions options;
        options.levels = levels;
        options.supersample = supersample;
        options.threads = 1;
        options.kernel = kernel;
        const auto vector = ig::makeCaster(ig::CasterKind::Fast, *map, options);
        options.kernel = CasterKernel::Scalar;
        const auto scalar = ig::makeCaster(ig::CasterKind::Fast, *map, options);
        for (const ig::Pose& pose : ig::sweepPoses(*map, 6)) {
            const ig::RenderedFrame v = ig::renderFrame(*vector, *map, pose, in);
            const ig::RenderedFrame s = ig::renderFrame(*scalar, *map, pose, in);
            EXPECT_NE(v.stats.kernel, "scalar");
            EXPECT_EQ(s.stats.kernel, "scalar");
            bool equal = true;
            for (std::size_t i = 0; i < v.color.size(); ++i) {
                const bool same = v.color[i] == s.color[i] &&
                                  std::memcmp(&v.depth[i], &s.depth[i], sizeof(float)) == 0;
                a.pixelsEqual += same;
                equal = equal && same;
            }
            a.pixels += v.color.size();
            a.framesEqual += equal;
            a.countsEqual +=
                equal && v.stats.steps == s.stats.steps && v.stats.restarts == s.stats.restarts;
            ++a.frames;
        }
    }
    return a;
}

// The maps and camera of caster-hashes (scripts/caster-hashes.sh), where the row batches and
// the scalar kernel's coherence proofs differ on a few poses of the synthetic map.
const ig::TerrainMap& hashesSynthetic() {
    static const ig::TerrainMap map = ig::makeSyntheticTerrain(512, 7, 10.0);
    return map;
}

struct TwinSweep {
    int frames = 0, framesEqual = 0;  // colour, depth, steps and restarts equal to the bit
    int framesLikeScalar = 0;         // the vector kernel's image the scalar kernel's too
};

// `kernel` against `twin` over caster-hashes' sweeps (16 poses on Puget Sound, Goleta and the
// synthetic map, 64x48 with a margin of 4; levels 0, auto and 2; one and three rays per
// pixel; the single level with one): every frame equal to the bit, counts included. Also counts the
// frames where the kernel's image is the scalar column kernel's.
TwinSweep againstTwin(CasterKernel kernel, CasterKernel twin) {
    const ig::Intrinsics in = ig::Intrinsics::fromFov(64, 48, ig::degToRad(60), 4);
    TwinSweep r;
    for (const ig::TerrainMap* map : {&puget(), &goleta(), &hashesSynthetic()}) {
        const std::vector<ig::Pose> poses = ig::sweepPoses(*map, 16);
        for (const int levels : {0, ig::kLevelsAuto, 2}) {
            for (const int supersample : {1, 3}) {
                // (The single level's vector kernel casts one ray per pixel only.)
                if (levels == 0 && supersample > 1) continue;
                ig::RenderOptions options;
                options.levels = levels;
                options.supersample = supersample;
                options.threads = 1;
                options.kernel = kernel;
                const auto a = ig::makeCaster(ig::CasterKind::Fast, *map, options);
                options.kernel = twin;
                const auto b = ig::makeCaster(ig::CasterKind::Fast, *map, options);
                options.kernel = CasterKernel::Scalar;
                const auto s = ig::makeCaster(ig::CasterKind::Fast, *map, options);
                for (std::size_t k = 0; k < poses.size(); ++k) {
                    const ig::RenderedFrame fa = ig::renderFrame(*a, *map, poses[k], in);
                    const ig::RenderedFrame fb = ig::renderFrame(*b, *map, poses[k], in);
                    const ig::RenderedFrame fs = ig::renderFrame(*s, *map, poses[k], in);
                    const bool equal = fa.color == fb.color &&
                                       std::memcmp(fa.depth.data(), fb.depth.data(),
                                                   fa.depth.size() * sizeof(float)) == 0 &&
                                       fa.stats.steps == fb.stats.steps &&
                                       fa.stats.restarts == fb.stats.restarts;
                    EXPECT_TRUE(equal)
                        << ig::casterKernelName(kernel) << " against " << ig::casterKernelName(twin)
                        << ": pose " << k << " levels " << levels << " supersample " << supersample;
                    r.framesEqual += equal;
                    r.framesLikeScalar +=
                        fa.color == fs.color && std::memcmp(fa.depth.data(), fs.depth.data(),
                                                            fa.depth.size() * sizeof(float)) == 0;
                    ++r.frames;
                }
            }
        }
    }
    return r;
}

TEST(CasterKernel, NamesParseAndPrint) {
    for (const CasterKernel k :
         {CasterKernel::Auto, CasterKernel::Scalar, CasterKernel::Avx2, CasterKernel::Avx512,
          CasterKernel::Rows4Portable, CasterKernel::Rows8Portable}) {
        EXPECT_EQ(ig::parseCasterKernel(ig::casterKernelName(k)), k);
    }
    EXPECT_EQ(ig::casterKernelName(CasterKernel::Rows4Portable), "rows4-portable");
    EXPECT_EQ(ig::casterKernelName(CasterKernel::Rows8Portable), "rows8-portable");
    EXPECT_TRUE(ig::casterKernelMissing(CasterKernel::Rows4Portable).empty());
    EXPECT_TRUE(ig::casterKernelMissing(CasterKernel::Rows8Portable).empty());
    EXPECT_THROW(ig::parseCasterKernel("sse2"), ig::InputError);
    EXPECT_THROW(ig::parseCasterKernel(""), ig::InputError);
    EXPECT_TRUE(ig::casterKernelMissing(CasterKernel::Scalar).empty());
    EXPECT_TRUE(ig::casterKernelMissing(CasterKernel::Auto).empty());
}

TEST(CasterKernel, MissingFeaturesAreTheProcessors) {
    const base::CpuFeatures& cpu = base::cpuFeatures();
    EXPECT_EQ(ig::casterKernelMissing(CasterKernel::Avx2).empty(), cpu.avx2);
    EXPECT_EQ(ig::casterKernelMissing(CasterKernel::Avx512).empty(), cpu.avx512);
}

// Auto takes the widest kernel the processor has, and the stats say which ran.
TEST(CasterKernel, AutoIsTheWidestAndRecorded) {
    const base::CpuFeatures& cpu = base::cpuFeatures();
    const ig::Intrinsics in = ig::Intrinsics::fromFov(32, 24, ig::degToRad(60));
    const ig::Pose pose = ig::sweepPoses(synthetic(), 2)[0];
    for (const int levels : {0, ig::kLevelsAuto}) {
        ig::RenderOptions options;
        options.levels = levels;
        const auto caster = ig::makeCaster(ig::CasterKind::Fast, synthetic(), options);
        const std::string widest = levels != 0 && cpu.avx512 ? "avx512"
                                   : cpu.avx2                ? "avx2"
                                                             : "scalar";
        EXPECT_EQ(caster->kernelName(), widest) << levels;
        EXPECT_EQ(ig::renderFrame(*caster, synthetic(), pose, in).stats.kernel, widest);
    }
    // The single level has no kernel wider than four columns, and none with supersampling.
    if (cpu.avx512) {
        ig::RenderOptions options;
        options.levels = 0;
        options.kernel = CasterKernel::Avx512;
        EXPECT_EQ(ig::makeCaster(ig::CasterKind::Fast, synthetic(), options)->kernelName(), "avx2");
        options.supersample = 2;
        EXPECT_EQ(ig::makeCaster(ig::CasterKind::Fast, synthetic(), options)->kernelName(),
                  "scalar");
    }
}

// A kernel the processor lacks is refused as bad input, naming the kernel and what is lacking.
TEST(CasterKernel, KernelTheProcessorLacksIsRefused) {
    int refused = 0;
    for (const CasterKernel k : {CasterKernel::Avx2, CasterKernel::Avx512}) {
        const std::string missing = ig::casterKernelMissing(k);
        if (missing.empty()) continue;
        ig::RenderOptions options;
        options.kernel = k;
        try {
            (void)ig::makeCaster(ig::CasterKind::Fast, synthetic(), options);
            ADD_FAILURE() << ig::casterKernelName(k) << " accepted";
        } catch (const ig::InputError& e) {
            EXPECT_NE(std::string(e.what()).find(std::string(ig::casterKernelName(k))),
                      std::string::npos);
            EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
        }
        ++refused;
    }
    if (refused == 0) GTEST_SKIP() << "the processor has every kernel";
}

// The single level (one ray per pixel: supersampling has the scalar kernel only): every
// vector kernel's image, depths, steps and restarts are the scalar kernel's to the bit.
TEST(CasterKernel, SingleLevelVectorKernelsGiveTheScalarImageToTheBit) {
    const std::vector<CasterKernel> kernels = vectorKernelsPresent();
    if (kernels.empty()) GTEST_SKIP() << "the processor has no vector kernel";
    for (const CasterKernel k : kernels) {
        const Agreement a = againstScalar(k, 0, 1);
        EXPECT_EQ(a.framesEqual, a.frames) << ig::casterKernelName(k);
        EXPECT_EQ(a.countsEqual, a.frames) << ig::casterKernelName(k);
        EXPECT_EQ(a.pixelsEqual, a.pixels) << ig::casterKernelName(k);
    }
}

// The multiresolution caster: a row batch proves each lane coherent against the ray below the
// batch, the scalar kernel each ray against the ray just below it, so where the two proofs
// differ a row is cast exactly by one and marched by the other (docs/design/multires.md), and
// the lanes of a batch step together (more steps). The images are otherwise the same to the
// bit: measured here over the sweeps (every frame equal), and by caster-hashes over 16 poses a
// map (a few frames of the synthetic map differ in a few pixels).
TEST(CasterKernel, MultiresVectorKernelsAgreeWithTheScalarKernel) {
    const std::vector<CasterKernel> kernels = vectorKernelsPresent();
    if (kernels.empty()) GTEST_SKIP() << "the processor has no vector kernel";
    for (const CasterKernel k : kernels) {
        for (const int levels : {ig::kLevelsAuto, 2}) {
            for (const int supersample : {1, 2}) {
                const Agreement a = againstScalar(k, levels, supersample);
                std::printf(
                    "%s levels %d supersample %d: %d of %d frames equal to the bit, "
                    "%.4f %% of pixels\n",
                    std::string(ig::casterKernelName(k)).c_str(), levels, supersample,
                    a.framesEqual, a.frames, 100.0 * a.pixelsEqual / a.pixels);
                EXPECT_EQ(a.framesEqual, a.frames) << ig::casterKernelName(k);
                EXPECT_EQ(a.pixelsEqual, a.pixels) << ig::casterKernelName(k);
            }
        }
    }
}

// Each vector kernel forced by name against its scalar twin over caster-hashes' sweeps: the
// row batches (levels auto and 2) against the same template on portable lanes, the single
// level's four-column packets against the scalar column kernel (which the portable kernels run
// there); every frame equal to the bit, step and restart counts included. A kernel the
// processor lacks is skipped.
TEST(CasterKernel, VectorKernelsEqualTheirPortableTwinsToTheBit) {
    int compared = 0;
    for (const auto& [kernel, twin] :
         {std::pair{CasterKernel::Avx2, CasterKernel::Rows4Portable},
          std::pair{CasterKernel::Avx512, CasterKernel::Rows8Portable}}) {
        if (!ig::casterKernelMissing(kernel).empty()) continue;
        const TwinSweep r = againstTwin(kernel, twin);
        std::printf("%s against %s: %d of %d frames equal to the bit (%d the scalar kernel's)\n",
                    std::string(ig::casterKernelName(kernel)).c_str(),
                    std::string(ig::casterKernelName(twin)).c_str(), r.framesEqual, r.frames,
                    r.framesLikeScalar);
        EXPECT_EQ(r.framesEqual, r.frames);
        ++compared;
    }
    if (compared == 0) GTEST_SKIP() << "the processor has no vector kernel";
}

// The portable twins run on any processor, are recorded by name, and are never chosen by auto.
TEST(CasterKernel, PortableTwinsRunAnywhereAndAreRecorded) {
    const ig::Intrinsics in = ig::Intrinsics::fromFov(32, 24, ig::degToRad(60));
    const ig::Pose pose = ig::sweepPoses(synthetic(), 2)[0];
    for (const CasterKernel k : {CasterKernel::Rows4Portable, CasterKernel::Rows8Portable}) {
        ig::RenderOptions options;
        options.levels = ig::kLevelsAuto;
        options.kernel = k;
        const auto caster = ig::makeCaster(ig::CasterKind::Fast, synthetic(), options);
        EXPECT_EQ(caster->kernelName(), ig::casterKernelName(k));
        EXPECT_EQ(ig::renderFrame(*caster, synthetic(), pose, in).stats.kernel,
                  ig::casterKernelName(k));
        // The single level has no row batches: the scalar column kernel runs.
        options.levels = 0;
        EXPECT_EQ(ig::makeCaster(ig::CasterKind::Fast, synthetic(), options)->kernelName(),
                  "scalar");
    }
    ig::RenderOptions options;
    options.levels = ig::kLevelsAuto;
    const std::string chosen(
        ig::makeCaster(ig::CasterKind::Fast, synthetic(), options)->kernelName());
    EXPECT_EQ(chosen.find("portable"), std::string::npos) << chosen;
}

// The portable twins against the scalar column kernel (multiresolution, caster-hashes' sweeps):
// they differ only where the two coherence proofs differ (a batch proves each lane against the
// ray below the batch, the scalar kernel against the ray just below), in few pixels: at most
// 0.5 % of a frame's pixels, and over all frames at most 0.05 % of the pixels, with colour within
// kTwinColour of 255 and depth within 0.1 % where they differ (measured: 3 and 5 of 387 072
// pixels, worst frame 0.12 %, colour equal, depth within 2.4e-5).
// And against the reference: on the single level the same image (the scalar kernel's: 0.0000 %
// colour error); on the multiresolution caster the scalar kernel's mean colour error against the
// reference within 0.01 percentage points.
TEST(CasterKernel, PortableTwinsAgreeWithTheScalarKernelAndTheReference) {
    constexpr int kTwinColour = 8;
    const ig::Intrinsics in = ig::Intrinsics::fromFov(64, 48, ig::degToRad(60), 4);
    for (const CasterKernel twin : {CasterKernel::Rows4Portable, CasterKernel::Rows8Portable}) {
        std::uint64_t pixels = 0, differ = 0;
        int worstColour = 0;
        double worstDepth = 0.0, worstFrame = 0.0, worstMaeGap = 0.0;
        for (const ig::TerrainMap* map : {&puget(), &goleta(), &hashesSynthetic()}) {
            const auto reference = ig::makeCaster(ig::CasterKind::Reference, *map);
            for (const int levels : {0, ig::kLevelsAuto}) {
                ig::RenderOptions options;
                options.levels = levels;
                options.threads = 1;
                options.kernel = twin;
                const auto t = ig::makeCaster(ig::CasterKind::Fast, *map, options);
                options.kernel = CasterKernel::Scalar;
                const auto s = ig::makeCaster(ig::CasterKind::Fast, *map, options);
                for (const ig::Pose& pose : ig::sweepPoses(*map, 16)) {
                    const ig::RenderedFrame ft = ig::renderFrame(*t, *map, pose, in);
                    const ig::RenderedFrame fs = ig::renderFrame(*s, *map, pose, in);
                    const ig::RenderedFrame fr = ig::renderFrame(*reference, *map, pose, in);
                    std::uint64_t frameDiffer = 0;
                    for (std::size_t i = 0; i < ft.color.size(); ++i) {
                        const bool same =
                            ft.color[i] == fs.color[i] &&
                            std::memcmp(&ft.depth[i], &fs.depth[i], sizeof(float)) == 0;
                        if (same) continue;
                        ++frameDiffer;
                        worstColour =
                            std::max({worstColour, std::abs(ft.color[i].r - fs.color[i].r),
                                      std::abs(ft.color[i].g - fs.color[i].g),
                                      std::abs(ft.color[i].b - fs.color[i].b)});
                        const double rel =
                            std::isfinite(fs.depth[i]) || std::isfinite(ft.depth[i])
                                ? std::abs(static_cast<double>(ft.depth[i]) - fs.depth[i]) /
                                      fs.depth[i]
                                : 0.0;
                        worstDepth = std::max(worstDepth, std::isfinite(rel) ? rel : 1.0);
                    }
                    pixels += ft.color.size();
                    differ += frameDiffer;
                    worstFrame = std::max(worstFrame, static_cast<double>(frameDiffer) /
                                                          static_cast<double>(ft.color.size()));
                    const double maeGap = std::abs(ig::meanAbsErrorPct(ft.color, fr.color) -
                                                   ig::meanAbsErrorPct(fs.color, fr.color));
                    worstMaeGap = std::max(worstMaeGap, maeGap);
                    if (levels == 0) {
                        EXPECT_EQ(ig::meanAbsErrorPct(ft.color, fr.color), 0.0);
                        EXPECT_EQ(frameDiffer, 0u);
                    }
                }
            }
        }
        std::printf(
            "%s against scalar: %llu of %llu pixels differ (worst frame %.3f %%), colour by at "
            "most %d, depth by at most %.2e relative; mean colour error against the reference "
            "within %.4f points of the scalar kernel's\n",
            std::string(ig::casterKernelName(twin)).c_str(),
            static_cast<unsigned long long>(differ), static_cast<unsigned long long>(pixels),
            100.0 * worstFrame, worstColour, worstDepth, worstMaeGap);
        EXPECT_LE(worstFrame, 0.005);
        EXPECT_LE(static_cast<double>(differ), 0.0005 * static_cast<double>(pixels));
        EXPECT_LE(worstColour, kTwinColour);
        EXPECT_LE(worstDepth, 1e-3);
        EXPECT_LE(worstMaeGap, 0.01);
    }
}

}  // namespace

// The row batches' objects, one per instruction set, each give their kernel (of their width,
// both entries set) in an x86-64 build, and an empty one elsewhere; asking for a kernel runs
// none of its code, so this holds on any processor.
TEST(CasterKernel, EachInstructionSetObjectGivesItsRowKernel) {
    const ig::fast::RowKernel narrow = ig::rows_avx2::kernel();
    const ig::fast::RowKernel wide = ig::rows_avx512::kernel();
#if VIG_CASTER_PACKETS
    EXPECT_EQ(narrow.lanes, 4);
    EXPECT_EQ(wide.lanes, 8);
#else
    EXPECT_EQ(narrow.lanes, 0);
    EXPECT_EQ(wide.lanes, 0);
#endif
    for (const ig::fast::RowKernel& k : {narrow, wide}) {
        EXPECT_EQ(k.run != nullptr, k.lanes > 0);
        EXPECT_EQ(k.cast != nullptr, k.lanes > 0);
    }
    if (narrow.lanes > 0 && wide.lanes > 0) {
        EXPECT_NE(reinterpret_cast<void*>(narrow.run), reinterpret_cast<void*>(wide.run));
    }
    // The portable twins: wherever the compiler has vector types.
    const ig::fast::RowKernel p4 = ig::rows_portable::kernel4();
    const ig::fast::RowKernel p8 = ig::rows_portable::kernel8();
    EXPECT_EQ(p4.lanes, VIG_CASTER_ROWS ? 4 : 0);
    EXPECT_EQ(p8.lanes, VIG_CASTER_ROWS ? 8 : 0);
    for (const ig::fast::RowKernel& k : {p4, p8}) {
        EXPECT_EQ(k.run != nullptr, k.lanes > 0);
        EXPECT_EQ(k.cast != nullptr, k.lanes > 0);
    }
}
