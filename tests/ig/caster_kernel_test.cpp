// The fast caster's kernels: chosen once when the caster is built, recorded in the frame's
// stats, refused where the processor lacks them, and each vector kernel's image against the
// scalar kernel's over pose sweeps on Puget Sound, Goleta and a synthetic map. A kernel the
// processor lacks is skipped, never compared with itself.
#include "base/cpu_features.hpp"
#include "ig/caster.hpp"
#include "ig/error.hpp"
#include "ig/fast_column.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_io.hpp"

#include <gtest/gtest.h>

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

TEST(CasterKernel, NamesParseAndPrint) {
    for (const CasterKernel k :
         {CasterKernel::Auto, CasterKernel::Scalar, CasterKernel::Avx2, CasterKernel::Avx512}) {
        EXPECT_EQ(ig::parseCasterKernel(ig::casterKernelName(k)), k);
    }
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
}
