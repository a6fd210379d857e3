// The deferred sun lighting pass (docs/design/appearance.md, "Sun lighting"). The casters write
// albedo hazed toward the horizon colour; the light is one factor per pixel, so a new sun is a
// new Sun value and nothing is rebuilt. The haze is undone and redone exactly: the caster's
// colour is c = a (1 - f) + h f with f known from the depth, so the lit colour
// a L (1 - f) + h f equals h f + L (c - h f).
#include "ig/lighting_pass.hpp"

#include "base/check.hpp"
#include "ig/caster_impl.hpp"
#include "ig/shading.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

namespace ig {

namespace {

inline int ceilHalf(int n) {
    return (n + 1) / 2;
}

// Bilinear normal of one level at its grid coordinates (clamped), unnormalised.
inline void levelNormal(const float* samples, int width, int height, double gx, double gy,
                        float n[3]) {
    gx = std::clamp(gx, 0.0, width - 1.0);
    gy = std::clamp(gy, 0.0, height - 1.0);
    const int ix = std::min(static_cast<int>(gx), std::max(width - 2, 0));
    const int iy = std::min(static_cast<int>(gy), std::max(height - 2, 0));
    const int ix1 = std::min(ix + 1, width - 1), iy1 = std::min(iy + 1, height - 1);
    const float fx = static_cast<float>(gx - ix), fy = static_cast<float>(gy - iy);
    const float* a = samples + 3 * (static_cast<std::size_t>(iy) * width + ix);
    const float* b = samples + 3 * (static_cast<std::size_t>(iy) * width + ix1);
    const float* c = samples + 3 * (static_cast<std::size_t>(iy1) * width + ix);
    const float* d = samples + 3 * (static_cast<std::size_t>(iy1) * width + ix1);
    const float w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy, w11 = fx * fy;
    for (int i = 0; i < 3; ++i)
        n[i] = w00 * a[i] + w10 * b[i] + w01 * c[i] + w11 * d[i];
}

// The level the caster drew at horizontal distance `horizontal` and the weight of the next.
inline void bandAt(const LevelBands& bands, int levels, double horizontal, int& k, double& w) {
    const int top = std::min(bands.topLevel, levels - 1);
    k = 0;
    w = 0.0;
    if (!(bands.d0 < std::numeric_limits<double>::infinity()) || top <= 0) return;
    double dk = bands.d0;
    while (k < top && horizontal >= 2.0 * dk) {
        ++k;
        dk *= 2.0;
    }
    if (k < top) w = std::clamp(horizontal / dk - 1.0, 0.0, 1.0);
}

// 2^-k, k = 0..31, so a level's grid coordinates are a multiplication away.
constexpr std::array<double, 32> kInvPow2 = [] {
    std::array<double, 32> t{};
    double v = 1.0;
    for (double& x : t) {
        x = v;
        v *= 0.5;
    }
    return t;
}();

// The mean normal the caster's level (blend) shows at level-0 grid coordinates (gx, gy) (world
// x / spacing, y / spacing).
inline void bandNormal(const SunLighting& lighting, const LevelBands& bands, double gx0, double gy0,
                       double horizontal, float n[3]) {
    const TerrainNormals& normals = *lighting.normals;
    int k = 0;
    double w = 0.0;
    if (!lighting.levelZeroNormals) bandAt(bands, normals.levelCount(), horizontal, k, w);
    const double gx = gx0 * kInvPow2[k], gy = gy0 * kInvPow2[k];
    levelNormal(normals.samples(k), normals.width(k), normals.height(k), gx, gy, n);
    if (w > 0.0) {
        float m[3];
        levelNormal(normals.samples(k + 1), normals.width(k + 1), normals.height(k + 1), 0.5 * gx,
                    0.5 * gy, m);
        const float wf = static_cast<float>(w);
        for (int i = 0; i < 3; ++i)
            n[i] += (m[i] - n[i]) * wf;
    }
}

// Light factor from a normal: ambient + diffuse * max(0, n . s), times `scale`.
struct LightModel {
    float sx, sy, sz, ambient, diffuse, scale;

    static LightModel of(const SunLighting& lighting, const Sun& sun) {
        const glm::dvec3 s = sunDirection(sun);
        const double a = lighting.ambient;
        const double flat = a + (1.0 - a) * std::max(0.0, s.z);
        LightModel m;
        m.sx = static_cast<float>(s.x);
        m.sy = static_cast<float>(s.y);
        m.sz = static_cast<float>(s.z);
        m.ambient = static_cast<float>(a);
        m.diffuse = static_cast<float>(1.0 - a);
        m.scale = static_cast<float>(lighting.photo ? 1.0 / std::max(flat, 1e-6) : 1.0);
        return m;
    }
    float operator()(const float n[3]) const {
        const float lambert = std::max(0.0f, n[0] * sx + n[1] * sy + n[2] * sz);
        return (ambient + diffuse * lambert) * scale;
    }
};

inline std::uint8_t toByte(float v) {
    return static_cast<std::uint8_t>(std::clamp(v + 0.5f, 0.0f, 255.0f));
}

// Recomposes one pixel: h f + L (c - h f).
inline void relightPixel(Rgb8& c, const SkyModel& sky, float haze, float light) {
    const float hr = sky.horizon.r * haze, hg = sky.horizon.g * haze, hb = sky.horizon.b * haze;
    c = Rgb8{toByte(hr + light * (c.r - hr)), toByte(hg + light * (c.g - hg)),
             toByte(hb + light * (c.b - hb))};
}

inline bool litPixel(const RenderedFrame& frame, std::size_t i) {
    const float d = frame.depth[i];
    if (!(d >= 0.0f && d < kSkyDepth)) return false;  // sky, NaN, negative
    return frame.objectId.empty() || frame.objectId[i] == 0;
}

void checkFrame(const SunLighting& lighting, const Camera& camera, const RenderedFrame& frame) {
    CHECK(lighting.normals != nullptr) << "sun lighting without normals";
    const std::size_t n =
        static_cast<std::size_t>(camera.intrinsics().width) * camera.intrinsics().height;
    CHECK(frame.color.size() == n && frame.depth.size() == n)
        << "lighting a frame whose buffers do not match the camera";
    CHECK(frame.objectId.empty() || frame.objectId.size() == n);
}

}  // namespace

TerrainNormals::TerrainNormals(const TerrainMap& map)
    : spacingX_(map.spacingX()), spacingY_(map.spacingY()) {
    Level base;
    base.width = map.width();
    base.height = map.height();
    base.normals.resize(3 * static_cast<std::size_t>(base.width) * base.height);
    const int w = base.width, h = base.height;
    tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
        for (int iy = rows.begin(); iy < rows.end(); ++iy) {
            for (int ix = 0; ix < w; ++ix) {
                const int x0 = std::max(ix - 1, 0), x1 = std::min(ix + 1, w - 1);
                const int y0 = std::max(iy - 1, 0), y1 = std::min(iy + 1, h - 1);
                const double dzdx = (map.heightAt(x1, iy) - map.heightAt(x0, iy)) /
                                    std::max((x1 - x0) * map.spacingX(), 1e-12);
                const double dzdy = (map.heightAt(ix, y1) - map.heightAt(ix, y0)) /
                                    std::max((y1 - y0) * map.spacingY(), 1e-12);
                const double inv = 1.0 / std::sqrt(dzdx * dzdx + dzdy * dzdy + 1.0);
                float* n = &base.normals[3 * map.index(ix, iy)];
                n[0] = static_cast<float>(-dzdx * inv);
                n[1] = static_cast<float>(-dzdy * inv);
                n[2] = static_cast<float>(inv);
            }
        }
    });
    levels_.push_back(std::move(base));
    if (w < 2 || h < 2) return;
    // The display pyramid's levels (ig/pyramid.cpp): same sizes, same filter.
    for (;;) {
        const Level& fine = levels_.back();
        const int cw = ceilHalf(fine.width - 1), ch = ceilHalf(fine.height - 1);
        if (cw < 2 || ch < 2) break;
        Level coarse;
        coarse.width = cw + 1;
        coarse.height = ch + 1;
        coarse.normals.resize(3 * static_cast<std::size_t>(coarse.width) * coarse.height);
        tbb::parallel_for(
            tbb::blocked_range<int>(0, coarse.height), [&](const tbb::blocked_range<int>& rows) {
                for (int j = rows.begin(); j < rows.end(); ++j) {
                    for (int i = 0; i < coarse.width; ++i) {
                        double acc[3] = {0.0, 0.0, 0.0};
                        for (int b = 0; b < 3; ++b) {
                            const int y = std::clamp(2 * j + b - 1, 0, fine.height - 1);
                            for (int a = 0; a < 3; ++a) {
                                const int x = std::clamp(2 * i + a - 1, 0, fine.width - 1);
                                const double wgt = (b == 1 ? 2.0 : 1.0) * (a == 1 ? 2.0 : 1.0);
                                const float* n =
                                    &fine.normals[3 *
                                                  (static_cast<std::size_t>(y) * fine.width + x)];
                                for (int c = 0; c < 3; ++c)
                                    acc[c] += wgt * n[c];
                            }
                        }
                        float* out =
                            &coarse.normals[3 * (static_cast<std::size_t>(j) * coarse.width + i)];
                        for (int c = 0; c < 3; ++c)
                            out[c] = static_cast<float>(acc[c] / 16.0);
                    }
                }
            });
        levels_.push_back(std::move(coarse));
    }
}

void TerrainNormals::normalAt(int k, double x, double y, float n[3]) const {
    CHECK(k >= 0 && k < levelCount());
    const double inv = 1.0 / (1 << k);
    levelNormal(samples(k), width(k), height(k), x / spacingX_ * inv, y / spacingY_ * inv, n);
}

Sun SunClock::at(double t) const {
    if (almanac) return sunAt(latitudeDeg, longitudeDeg, days + t * speed / 86400.0);
    Sun s = sun;
    s.azimuth = std::remainder(sun.azimuth + azimuthRate * t, 2.0 * std::numbers::pi);
    if (s.azimuth < 0.0) s.azimuth += 2.0 * std::numbers::pi;
    return s;
}

double lightFactor(const SunLighting& lighting, const LevelBands& bands, const Sun& sun, double x,
                   double y, double horizontal) {
    float n[3];
    const TerrainNormals& normals = *lighting.normals;
    bandNormal(lighting, bands, x / normals.spacingX(), y / normals.spacingY(), horizontal, n);
    return LightModel::of(lighting, sun)(n);
}

void lightFrame(const SunLighting& lighting, const SkyModel& sky, const LevelBands& bands,
                const Camera& camera, RenderedFrame& frame, int threads) {
    checkFrame(lighting, camera, frame);
    const LightModel model = LightModel::of(lighting, lighting.clock.at(frame.time));
    const Intrinsics& in = camera.intrinsics();
    const CameraBasis& basis = camera.basis();
    const glm::dvec3 eye = camera.pose().position;
    // With a height fall-off the caster drew no haze (hazeFrame adds it after the light).
    const double invHaze = hazeInKernel(sky) ? 1.0 / sky.hazeDistance : 0.0;
    // Level 0 at every distance: no horizontal distance needed.
    const bool banded = !lighting.levelZeroNormals && bands.topLevel > 0 &&
                        bands.d0 < std::numeric_limits<double>::infinity();
    const double invSx = 1.0 / lighting.normals->spacingX();
    const double invSy = 1.0 / lighting.normals->spacingY();
    const int w = in.width;
    auto rows = [&](const tbb::blocked_range<int>& range) {
        for (int y = range.begin(); y < range.end(); ++y) {
            // Pixel (x, y)'s ray: first + x * right (x + 0.5, y + 0.5 its centre).
            const glm::dvec3 first = in.focal * basis.forward + (0.5 - in.cx()) * basis.right -
                                     (y + 0.5 - in.cy()) * basis.up;
            const double fx = first.x, fy = first.y, fz = first.z;
            const double rx = basis.right.x, ry = basis.right.y, rz = basis.right.z;
            const std::size_t row = static_cast<std::size_t>(y) * w;
            Rgb8* __restrict color = frame.color.data() + row;
            for (int x = 0; x < w; ++x) {
                if (!litPixel(frame, row + x)) continue;
                const double depth = frame.depth[row + x];
                const double dx = fx + x * rx, dy = fy + x * ry, dz = fz + x * rz;
                const double scale = depth / std::sqrt(dx * dx + dy * dy + dz * dz);
                const double horizontal = banded ? scale * std::sqrt(dx * dx + dy * dy) : 0.0;
                float n[3];
                bandNormal(lighting, bands, (eye.x + dx * scale) * invSx,
                           (eye.y + dy * scale) * invSy, horizontal, n);
                const float haze =
                    invHaze > 0.0 ? 1.0f - std::exp(static_cast<float>(-depth * invHaze)) : 0.0f;
                relightPixel(color[x], sky, haze, model(n));
            }
        }
    };
    runWithThreads(threads,
                   [&] { tbb::parallel_for(tbb::blocked_range<int>(0, in.height, 8), rows); });
}

void lightFrameReference(const SunLighting& lighting, const SkyModel& sky, const LevelBands& bands,
                         const Camera& camera, RenderedFrame& frame) {
    checkFrame(lighting, camera, frame);
    const Sun sun = lighting.clock.at(frame.time);
    const Intrinsics& in = camera.intrinsics();
    for (int y = 0; y < in.height; ++y) {
        for (int x = 0; x < in.width; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * in.width + x;
            if (!litPixel(frame, i)) continue;
            const double depth = frame.depth[i];
            const glm::dvec3 dir = glm::normalize(camera.rayDirection(x + 0.5, y + 0.5));
            const glm::dvec3 hit = camera.pose().position + depth * dir;
            const double horizontal = depth * std::hypot(dir.x, dir.y);
            const double light = lightFactor(lighting, bands, sun, hit.x, hit.y, horizontal);
            const double f = hazeInKernel(sky) ? 1.0 - std::exp(-depth / sky.hazeDistance) : 0.0;
            Rgb8& c = frame.color[i];
            auto mix = [&](std::uint8_t v, std::uint8_t h) {
                const double hf = h * f;
                return static_cast<std::uint8_t>(
                    std::clamp(std::floor(hf + light * (v - hf) + 0.5), 0.0, 255.0));
            };
            c = Rgb8{mix(c.r, sky.horizon.r), mix(c.g, sky.horizon.g), mix(c.b, sky.horizon.b)};
        }
    }
}

}  // namespace ig
