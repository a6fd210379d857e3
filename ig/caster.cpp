#include "ig/caster.hpp"

#include "base/cpu_features.hpp"
#include "ig/caster_impl.hpp"
#include "ig/error.hpp"
#include "ig/near_clip.hpp"
#include "ig/surface_hit.hpp"

#include <glm/geometric.hpp>

#include <chrono>
#include <cmath>
#include <limits>
#include <string>

namespace ig {

std::string_view casterName(CasterKind kind) {
    switch (kind) {
        case CasterKind::Reference:
            return "reference";
        case CasterKind::Naive:
            return "naive";
        case CasterKind::Fast:
            return "fast";
        case CasterKind::Span:
            return "span";
    }
    return "?";
}

CasterKind parseCasterKind(std::string_view name) {
    if (name == "reference") return CasterKind::Reference;
    if (name == "naive") return CasterKind::Naive;
    if (name == "fast") return CasterKind::Fast;
    if (name == "span") return CasterKind::Span;
    throw InputError("caster '" + std::string(name) + "': expected fast, span, naive or reference");
}

std::string_view casterKernelName(CasterKernel kernel) {
    switch (kernel) {
        case CasterKernel::Auto:
            return "auto";
        case CasterKernel::Scalar:
            return "scalar";
        case CasterKernel::Avx2:
            return "avx2";
        case CasterKernel::Avx512:
            return "avx512";
        case CasterKernel::Rows4Portable:
            return "rows4-portable";
        case CasterKernel::Rows8Portable:
            return "rows8-portable";
    }
    return "?";
}

CasterKernel parseCasterKernel(std::string_view name) {
    for (const CasterKernel k :
         {CasterKernel::Auto, CasterKernel::Scalar, CasterKernel::Avx2, CasterKernel::Avx512,
          CasterKernel::Rows4Portable, CasterKernel::Rows8Portable}) {
        if (name == casterKernelName(k)) return k;
    }
    throw InputError("kernel '" + std::string(name) +
                     "': expected auto, scalar, avx2, avx512, rows4-portable or rows8-portable");
}

std::string casterKernelMissing(CasterKernel kernel) {
    const base::CpuFeatures& cpu = base::cpuFeatures();
    switch (kernel) {
        case CasterKernel::Auto:
        case CasterKernel::Scalar:
        case CasterKernel::Rows4Portable:
        case CasterKernel::Rows8Portable:
            return {};
        case CasterKernel::Avx2:
            return cpu.avx2 ? std::string() : std::string("AVX2");
        case CasterKernel::Avx512:
            return cpu.avx512 ? std::string() : std::string("AVX-512 F/DQ/VL/BW");
    }
    return {};
}

std::unique_ptr<Caster> makeCaster(CasterKind kind, const TerrainMap& map,
                                   const RenderOptions& options) {
    switch (kind) {
        case CasterKind::Reference:
            return makeReferenceCaster(map, options);
        case CasterKind::Naive:
            return makeNaiveCaster(map, options);
        case CasterKind::Fast:
            return options.supersample == kSupersampleAuto ? makeAutoSupersampleCaster(map, options)
                                                           : makeFastCaster(map, options);
        case CasterKind::Span:
            return makeSpanCaster(map, options);
    }
    return nullptr;
}

std::array<glm::dvec2, kControlPointCount> controlPointPixels(const Intrinsics& intrinsics) {
    std::array<glm::dvec2, kControlPointCount> px{};
    const double f[3] = {1.0 / 6.0, 0.5, 5.0 / 6.0};
    for (int j = 0; j < 3; ++j) {
        for (int i = 0; i < 3; ++i) {
            px[j * 3 + i] = glm::dvec2{f[i] * intrinsics.width, f[j] * intrinsics.height};
        }
    }
    return px;
}

void validateView(const TerrainMap& map, const Pose& pose, const Intrinsics& intrinsics) {
    if (!pose.isFinite()) throw InputError("pose: position and angles must be finite numbers");
    if (intrinsics.width <= 0 || intrinsics.height <= 0 || !(intrinsics.focal > 0.0)) {
        throw InputError("camera: image size and focal length must be positive");
    }
    const glm::dvec3& p = pose.position;
    if (p.x >= 0.0 && p.y >= 0.0 && p.x <= map.extentX() && p.y <= map.extentY() &&
        p.z <= map.surfaceHeight(p.x, p.y)) {
        throw InputError("pose: camera at z = " + std::to_string(p.z) +
                         " m is on or below the terrain surface (" +
                         std::to_string(map.surfaceHeight(p.x, p.y)) +
                         " m) at x = " + std::to_string(p.x) + ", y = " + std::to_string(p.y));
    }
}

RenderedFrame newFrame(const TerrainMap& map, const Pose& pose, const Intrinsics& intrinsics,
                       double time, std::uint64_t sequence) {
    validateView(map, pose, intrinsics);
    RenderedFrame frame;
    frame.sequence = sequence;
    frame.time = time;
    frame.pose = pose;
    frame.intrinsics = intrinsics;
    const std::size_t n = static_cast<std::size_t>(intrinsics.width) * intrinsics.height;
    frame.color.resize(n);
    frame.depth.resize(n);
    return frame;
}

void castControlPoints(const TerrainMap& map, const Camera& camera, RenderedFrame& frame) {
    const auto pixels = controlPointPixels(camera.intrinsics());
    for (int i = 0; i < kControlPointCount; ++i) {
        const glm::dvec3 dir = glm::normalize(camera.rayDirection(pixels[i].x, pixels[i].y));
        frame.controlPoints[i].pixel = pixels[i];
        if (frame.nearM > 0.0) {
            // What the pixel shows beyond the near plane.
            const TerrainRay ray(map, camera.pose().position, dir);
            const double t = entryBeyond(map, ray, nearPlaneRange(camera, ray.dir, frame.nearM),
                                         std::numeric_limits<double>::infinity());
            frame.controlPoints[i].world =
                t >= 0.0 ? glm::dvec4{ray.at(t), 1.0} : glm::dvec4{dir, 0.0};
            continue;
        }
        const RayHit hit = intersectTerrain(map, camera.pose().position, dir);
        frame.controlPoints[i].world = hit.hit ? glm::dvec4{hit.point, 1.0} : glm::dvec4{dir, 0.0};
    }
}

void checkNearPlane(double nearM) {
    if (!(nearM >= 0.0) || !std::isfinite(nearM)) {
        throw InputError("near plane " + std::to_string(nearM) +
                         " m: must be a finite distance of 0 (none) or more");
    }
}

void renderPixels(const Caster& caster, const Camera& camera, RenderedFrame& frame) {
    const auto start = std::chrono::steady_clock::now();
    caster.render(camera, frame);
    frame.stats.kernel = caster.kernelName();
    frame.stats.renderMs =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

RenderedFrame renderFrame(const Caster& caster, const TerrainMap& map, const Pose& pose,
                          const Intrinsics& intrinsics, double time, std::uint64_t sequence,
                          double nearM) {
    checkNearPlane(nearM);
    RenderedFrame frame = newFrame(map, pose, intrinsics, time, sequence);
    frame.nearM = nearM;
    const Camera camera(pose, intrinsics);
    renderPixels(caster, camera, frame);
    castControlPoints(map, camera, frame);
    return frame;
}

}  // namespace ig
