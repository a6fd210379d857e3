// caster-hashes: a 64-bit hash of every image the casters make over pose sweeps on Puget Sound,
// Goleta and a synthetic map, for every caster, level setting, supersampling, kernel and node
// skipping, plus stereo pairs. One line per image; two runs print the same lines exactly when
// every image (colour, depth, control points) is the same to the bit. scripts/caster-hashes.sh
// runs it; docs/design/ray_casting.md reports the comparison.
#include "ig/caster.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/stereo.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_io.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

// FNV-1a, 64 bits.
struct Hash {
    std::uint64_t h = 1469598103934665603ull;
    void add(const void* data, std::size_t n) {
        const auto* p = static_cast<const unsigned char*>(data);
        for (std::size_t i = 0; i < n; ++i) {
            h ^= p[i];
            h *= 1099511628211ull;
        }
    }
};

std::uint64_t frameHash(const ig::RenderedFrame& f) {
    Hash h;
    h.add(f.color.data(), f.color.size() * sizeof(ig::Rgb8));
    h.add(f.depth.data(), f.depth.size() * sizeof(float));
    for (const ig::ControlPoint& cp : f.controlPoints) {
        h.add(&cp.pixel, sizeof(cp.pixel));
        h.add(&cp.world, sizeof(cp.world));
    }
    return h.h;
}

// The fast caster's kernels by name: the scalar column kernel, or the vector kernels up to an
// instruction set (avx2: four lanes; avx512: eight-lane row batches where they go).
const char* const kKernels[] = {"scalar", "avx2", "avx512"};

void setKernel(ig::RenderOptions& o, const std::string& kernel) {
    o.kernel = ig::parseCasterKernel(kernel);
}

}  // namespace

int main(int argc, char** argv) {
    int poses = 6;
    int w = 64, h = 48;
    // --kernel-diffs: instead of hashes, the pixels where each vector kernel's image differs
    // from the scalar kernel's, for every fast-caster configuration where any does.
    bool kernelDiffs = false;
    // --march-diffs: per map, how far the two level-0 marches' images are apart: the naive
    // caster (grid_march.hpp: the ray parameter t, heights in metres) against the fast caster's
    // single level, scalar kernel (level0_march.hpp: major grid units, raw heights), 320x240.
    bool marchDiffs = false;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--poses") && i + 1 < argc) poses = std::atoi(argv[++i]);
        if (!std::strcmp(argv[i], "--kernel-diffs")) kernelDiffs = true;
        if (!std::strcmp(argv[i], "--march-diffs")) marchDiffs = true;
    }
    struct Named {
        const char* name;
        ig::TerrainMap map;
    };
    std::vector<Named> maps;
    maps.push_back({"puget", ig::loadPugetSound()});
    maps.push_back({"goleta", ig::loadGoleta()});
    maps.push_back({"synthetic", ig::makeSyntheticTerrain(512, 7, 10.0)});
    const ig::Intrinsics in = ig::Intrinsics::fromFov(w, h, ig::degToRad(60.0), 4);
    if (marchDiffs) {
        const ig::Intrinsics big = ig::Intrinsics::fromFov(320, 240, ig::degToRad(60.0), 4);
        for (const Named& m : maps) {
            ig::RenderOptions o;
            o.levels = 0;
            o.threads = 1;
            o.kernel = ig::CasterKernel::Scalar;
            const auto naive = ig::makeCaster(ig::CasterKind::Naive, m.map);
            const auto fast = ig::makeCaster(ig::CasterKind::Fast, m.map, o);
            long pixels = 0, colour = 0, hitOnlyOne = 0, bothHit = 0, depthBits = 0;
            int maxChannel = 0;
            double maxRel = 0.0;
            for (const ig::Pose& pose : ig::sweepPoses(m.map, poses)) {
                const auto a = ig::renderFrame(*naive, m.map, pose, big);
                const auto b = ig::renderFrame(*fast, m.map, pose, big);
                for (std::size_t i = 0; i < a.color.size(); ++i) {
                    ++pixels;
                    const int d = std::max({std::abs(a.color[i].r - b.color[i].r),
                                            std::abs(a.color[i].g - b.color[i].g),
                                            std::abs(a.color[i].b - b.color[i].b)});
                    colour += d > 0;
                    maxChannel = std::max(maxChannel, d);
                    const bool ha = std::isfinite(a.depth[i]), hb = std::isfinite(b.depth[i]);
                    if (ha != hb) ++hitOnlyOne;
                    if (!ha || !hb) continue;
                    ++bothHit;
                    depthBits += std::memcmp(&a.depth[i], &b.depth[i], sizeof(float)) != 0;
                    maxRel =
                        std::max(maxRel, std::abs(static_cast<double>(a.depth[i]) - b.depth[i]) /
                                             a.depth[i]);
                }
            }
            std::printf(
                "%s: %ld pixels over %d poses; colour differs in %ld (at most %d of 255); hit by "
                "one caster only: %ld; of %ld hit by both, depth differs in %ld, by at most "
                "%.2e relative\n",
                m.name, pixels, poses, colour, maxChannel, hitOnlyOne, bothHit, depthBits, maxRel);
        }
        return 0;
    }
    int images = 0;
    for (const Named& m : maps) {
        const std::vector<ig::Pose> sweep = ig::sweepPoses(m.map, poses);
        for (std::size_t k = 0; k < sweep.size(); ++k) {
            const ig::Pose& pose = sweep[k];
            auto line = [&](const std::string& what, std::uint64_t hash) {
                std::printf("%s pose %zu %s %016llx\n", m.name, k, what.c_str(),
                            static_cast<unsigned long long>(hash));
                ++images;
            };
            if (kernelDiffs) {
                for (const int levels : {0, ig::kLevelsAuto, 2}) {
                    for (const int ss : {1, 3}) {
                        std::vector<ig::RenderedFrame> f;
                        for (const char* kernel : kKernels) {
                            ig::RenderOptions o;
                            o.levels = levels;
                            o.supersample = ss;
                            o.threads = 1;
                            setKernel(o, kernel);
                            const auto caster = ig::makeCaster(ig::CasterKind::Fast, m.map, o);
                            f.push_back(ig::renderFrame(*caster, m.map, pose, in));
                        }
                        for (std::size_t v = 1; v < f.size(); ++v) {
                            int differ = 0;
                            for (std::size_t i = 0; i < f[0].color.size(); ++i) {
                                differ +=
                                    !(f[v].color[i] == f[0].color[i]) ||
                                    std::memcmp(&f[v].depth[i], &f[0].depth[i], sizeof(float)) != 0;
                            }
                            if (differ > 0) {
                                std::printf(
                                    "%s pose %zu levels %d ss %d %s: %d of %zu pixels "
                                    "differ from scalar\n",
                                    m.name, k, levels, ss, kKernels[v], differ, f[0].color.size());
                            }
                        }
                    }
                }
                continue;
            }
            for (const ig::CasterKind kind : {ig::CasterKind::Reference, ig::CasterKind::Naive}) {
                const auto caster = ig::makeCaster(kind, m.map);
                line(std::string(ig::casterName(kind)),
                     frameHash(ig::renderFrame(*caster, m.map, pose, in)));
            }
            for (const int levels : {0, ig::kLevelsAuto, 2}) {
                for (const int ss : {1, 3}) {
                    for (const bool skip : {true, false}) {
                        if (levels == 0 && !skip) continue;  // no nodes to skip on one level
                        for (const char* kernel : kKernels) {
                            ig::RenderOptions o;
                            o.levels = levels;
                            o.supersample = ss;
                            o.skipNodes = skip;
                            o.threads = 1;
                            setKernel(o, kernel);
                            const auto caster = ig::makeCaster(ig::CasterKind::Fast, m.map, o);
                            const std::string what = "fast levels " + std::to_string(levels) +
                                                     " ss " + std::to_string(ss) + " skip " +
                                                     std::to_string(skip) + " " + kernel;
                            line(what, frameHash(ig::renderFrame(*caster, m.map, pose, in)));
                        }
                    }
                }
            }
            // Haze on the fast caster (its own shading path).
            for (const int levels : {0, ig::kLevelsAuto}) {
                ig::RenderOptions o;
                o.levels = levels;
                o.sky.hazeDistance = 15000.0;
                const auto caster = ig::makeCaster(ig::CasterKind::Fast, m.map, o);
                line("fast haze levels " + std::to_string(levels),
                     frameHash(ig::renderFrame(*caster, m.map, pose, in)));
            }
            // Stereo pairs: reprojected (both variants, the reference sweep) and ray cast.
            for (int variant = 0; variant < 4; ++variant) {
                ig::StereoOptions so;
                so.eyeSeparation = 2.0 + 0.01 * pose.position.z;
                if (variant == 1) so.variant = ig::ReprojectVariant::AdelsonHodges;
                if (variant == 2) so.referenceSweep = true;
                if (variant == 3) so.method = ig::RightEyeMethod::Raycast;
                for (const int levels : {0, ig::kLevelsAuto}) {
                    ig::RenderOptions o;
                    o.levels = levels;
                    o.threads = 1;
                    const ig::StereoFrame f = ig::renderStereo(m.map, pose, in, so, o);
                    Hash hs;
                    hs.add(f.source.data(), f.source.size());
                    const std::string what =
                        "stereo " + std::to_string(variant) + " levels " + std::to_string(levels);
                    line(what + " left", frameHash(f.left));
                    line(what + " right", frameHash(f.right) ^ hs.h);
                }
            }
        }
    }
    std::fprintf(stderr, "%d images\n", images);
    return 0;
}
