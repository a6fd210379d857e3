#include "ig/appearance.hpp"

#include "base/check.hpp"
#include "base/text.hpp"
#include "ig/error.hpp"

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>

namespace ig {

namespace {
constexpr double kDeg = std::numbers::pi / 180.0;
}

glm::dvec3 sunDirection(const Sun& sun) {
    const double c = std::cos(sun.elevation);
    return {std::sin(sun.azimuth) * c, std::cos(sun.azimuth) * c, std::sin(sun.elevation)};
}

Sun sunAt(double latitudeDeg, double longitudeDeg, double n) {
    // Astronomical Almanac low-precision formulae (as NOAA's calculator uses), degrees.
    const double meanLongitude = 280.460 + 0.9856474 * n;
    const double g = (357.528 + 0.9856003 * n) * kDeg;
    const double lambda = (meanLongitude + 1.915 * std::sin(g) + 0.020 * std::sin(2 * g)) * kDeg;
    const double epsilon = (23.439 - 0.0000004 * n) * kDeg;
    const double ra = std::atan2(std::cos(epsilon) * std::sin(lambda), std::cos(lambda));
    const double dec = std::asin(std::sin(epsilon) * std::sin(lambda));
    const double gmstDeg = 15.0 * (18.697374558 + 24.06570982441908 * n);
    const double hourAngle = std::remainder(gmstDeg + longitudeDeg, 360.0) * kDeg - ra;
    const double lat = latitudeDeg * kDeg;
    Sun sun;
    sun.elevation = std::asin(std::clamp(
        std::sin(lat) * std::sin(dec) + std::cos(lat) * std::cos(dec) * std::cos(hourAngle), -1.0,
        1.0));
    sun.azimuth = std::atan2(-std::sin(hourAngle),
                             std::tan(dec) * std::cos(lat) - std::sin(lat) * std::cos(hourAngle));
    if (sun.azimuth < 0.0) sun.azimuth += 2 * std::numbers::pi;
    return sun;
}

namespace {
// Days from 1970-01-01 to a civil date (proleptic Gregorian).
long daysFromCivil(long y, unsigned m, unsigned d) {
    y -= m <= 2;
    const long era = (y >= 0 ? y : y - 399) / 400;
    const unsigned yoe = static_cast<unsigned>(y - era * 400);
    const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
    const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    return era * 146097 + static_cast<long>(doe) - 719468;
}
}  // namespace

double parseUtcDateTime(const std::string& text, const std::string& what) {
    int y = 0, mo = 0, d = 0, h = 0, mi = 0, used = 0;
    double s = 0.0;
    const bool withSeconds =
        std::sscanf(text.c_str(), "%d-%d-%d,%d:%d:%lf%n", &y, &mo, &d, &h, &mi, &s, &used) == 6 &&
        used == static_cast<int>(text.size());
    if (!withSeconds) {
        s = 0.0;
        used = 0;
        if (!(std::sscanf(text.c_str(), "%d-%d-%d,%d:%d%n", &y, &mo, &d, &h, &mi, &used) == 5 &&
              used == static_cast<int>(text.size()))) {
            throw InputError(what + ": expected YYYY-MM-DD,HH:MM[:SS] (UTC), got " +
                             base::quoted(text));
        }
    }
    static constexpr std::array<int, 12> kDays = {31, 29, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
    const bool leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    if (y < 1900 || y > 2100 || mo < 1 || mo > 12 || d < 1 || d > kDays[mo - 1] ||
        (mo == 2 && d == 29 && !leap) || h < 0 || h > 23 || mi < 0 || mi > 59 || !(s >= 0.0) ||
        !(s < 60.0)) {
        throw InputError(what + ": " + base::quoted(text) +
                         " is not a date and time of 1900..2100 (UTC)");
    }
    const long days = daysFromCivil(y, static_cast<unsigned>(mo), static_cast<unsigned>(d));
    return static_cast<double>(days - 10957) + (h * 3600.0 + mi * 60.0 + s) / 86400.0 - 0.5;
}

LargeVector<Rgb8> elevationRampAlbedo(const TerrainMap& map) {
    return elevationRampAlbedo(map, map);
}

LargeVector<Rgb8> elevationRampAlbedo(const TerrainMap& map, const TerrainMap& rangeOf) {
    struct Stop {
        double metres;
        double r, g, b;
    };
    // Lowland fields, forest, high conifers, rock, grey rock, snow.
    static constexpr std::array<Stop, 7> kRamp = {{{0.0, 170, 172, 118},
                                                   {150.0, 118, 145, 82},
                                                   {500.0, 72, 108, 60},
                                                   {1300.0, 78, 96, 62},
                                                   {1800.0, 140, 128, 110},
                                                   {2400.0, 178, 172, 166},
                                                   {2900.0, 246, 248, 252}}};
    const Rgb8 water{45, 85, 130};
    const double relief = rangeOf.maxHeight() - rangeOf.minHeight();
    // Little relief: the map's own range over lowland to rock.
    const bool spread = relief < 300.0;
    const std::uint16_t lowest = [&] {
        std::uint16_t lo = std::numeric_limits<std::uint16_t>::max();
        for (const std::uint16_t v : rangeOf.rawHeights())
            lo = std::min(lo, v);
        return lo;
    }();
    // Water: a sample at rangeOf's lowest raw height (in map's quantisation) with its four
    // neighbours there too.
    const double lowestMetres = lowest * rangeOf.heightScale() + rangeOf.heightOffset();
    LargeVector<Rgb8> albedo(map.rawHeights().size());
    const int w = map.width(), h = map.height();
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix) {
            auto low = [&](int x, int y) {
                return map.heightAt(std::clamp(x, 0, w - 1), std::clamp(y, 0, h - 1)) ==
                       lowestMetres;
            };
            if (!spread && low(ix, iy) && low(ix - 1, iy) && low(ix + 1, iy) && low(ix, iy - 1) &&
                low(ix, iy + 1)) {
                albedo[map.index(ix, iy)] = water;
                continue;
            }
            const double z = spread ? (map.heightAt(ix, iy) - rangeOf.minHeight()) /
                                          std::max(relief, 1e-9) * 2000.0
                                    : map.heightAt(ix, iy);
            std::size_t k = 1;
            while (k + 1 < kRamp.size() && z > kRamp[k].metres)
                ++k;
            const Stop& a = kRamp[k - 1];
            const Stop& b = kRamp[k];
            const double t = std::clamp((z - a.metres) / (b.metres - a.metres), 0.0, 1.0);
            auto q = [](double v) {
                return static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0) + 0.5);
            };
            albedo[map.index(ix, iy)] =
                Rgb8{q(a.r + (b.r - a.r) * t), q(a.g + (b.g - a.g) * t), q(a.b + (b.b - a.b) * t)};
        }
    }
    return albedo;
}

TerrainLighting::TerrainLighting(const TerrainMap& map, Albedo albedo, double ambient)
    : width_(map.width()), height_(map.height()), kind_(albedo), ambient_(ambient) {
    CHECK(ambient >= 0.0 && ambient <= 1.0);
    albedo_ = albedo == Albedo::Ramp ? elevationRampAlbedo(map) : map.colors();
    normals_.resize(3 * albedo_.size());
    for (int iy = 0; iy < height_; ++iy) {
        for (int ix = 0; ix < width_; ++ix) {
            const int x0 = std::max(ix - 1, 0), x1 = std::min(ix + 1, width_ - 1);
            const int y0 = std::max(iy - 1, 0), y1 = std::min(iy + 1, height_ - 1);
            const double dzdx = (map.heightAt(x1, iy) - map.heightAt(x0, iy)) /
                                std::max((x1 - x0) * map.spacingX(), 1e-12);
            const double dzdy = (map.heightAt(ix, y1) - map.heightAt(ix, y0)) /
                                std::max((y1 - y0) * map.spacingY(), 1e-12);
            const double inv = 1.0 / std::sqrt(dzdx * dzdx + dzdy * dzdy + 1.0);
            float* n = &normals_[3 * map.index(ix, iy)];
            n[0] = static_cast<float>(-dzdx * inv);
            n[1] = static_cast<float>(-dzdy * inv);
            n[2] = static_cast<float>(inv);
        }
    }
}

double TerrainLighting::light(int ix, int iy, const Sun& sun) const {
    const glm::dvec3 s = sunDirection(sun);
    const float* n = &normals_[3 * (static_cast<std::size_t>(iy) * width_ + ix)];
    const double lambert = std::max(0.0, n[0] * s.x + n[1] * s.y + n[2] * s.z);
    return ambient_ + (1.0 - ambient_) * lambert;
}

void TerrainLighting::relight(TerrainMap& map, const Sun& sun) const {
    CHECK(map.width() == width_ && map.height() == height_);
    const glm::dvec3 s = sunDirection(sun);
    const double flat = ambient_ + (1.0 - ambient_) * std::max(0.0, s.z);
    const double norm = kind_ == Albedo::Photo ? 1.0 / std::max(flat, 1e-6) : 1.0;
    const float sx = static_cast<float>(s.x), sy = static_cast<float>(s.y),
                sz = static_cast<float>(s.z);
    const float a = static_cast<float>(ambient_), diffuse = static_cast<float>(1.0 - ambient_);
    const float scale = static_cast<float>(norm);
    Rgb8* out = map.colors().data();
    const std::size_t count = albedo_.size();
    for (std::size_t i = 0; i < count; ++i) {
        const float* n = &normals_[3 * i];
        const float lambert = std::max(0.0f, n[0] * sx + n[1] * sy + n[2] * sz);
        const float f = (a + diffuse * lambert) * scale;
        auto q = [f](std::uint8_t v) {
            return static_cast<std::uint8_t>(std::min(v * f + 0.5f, 255.0f));
        };
        out[i] = Rgb8{q(albedo_[i].r), q(albedo_[i].g), q(albedo_[i].b)};
    }
}

double footprintStretch(const Pose& pose, const Intrinsics& intrinsics) {
    const Camera camera(pose, intrinsics);
    const double cx = intrinsics.cx();
    auto depression = [&](double y) {
        const glm::dvec3 d = glm::normalize(camera.rayDirection(cx, y));
        return -std::asin(std::clamp(d.z, -1.0, 1.0));
    };
    const double top = depression(0.0), bottom = depression(intrinsics.height);
    const double lo = std::max(0.0, std::min(top, bottom)), hi = std::max(top, bottom);
    if (!(hi > 0.0)) return std::numeric_limits<double>::infinity();
    return 1.0 / std::sin(0.5 * (lo + hi));
}

int autoSupersample(const Pose& pose, const Intrinsics& intrinsics, int maxRays) {
    const double stretch = footprintStretch(pose, intrinsics);
    if (!std::isfinite(stretch)) return 1;
    const int most = std::max(maxRays, 1);
    const double rays = std::ceil(stretch / 2.0 - 1e-9);
    return rays >= most ? most : std::max(static_cast<int>(rays), 1);
}

}  // namespace ig
