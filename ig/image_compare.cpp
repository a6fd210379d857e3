#include "ig/image_compare.hpp"

#include "base/check.hpp"

#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>

namespace ig {
namespace {
void checkSizes(std::span<const Rgb8> a, std::span<const Rgb8> b) {
    CHECK(a.size() == b.size() && !a.empty())
        << "image comparison needs two non-empty images of one size (" << a.size() << ", "
        << b.size() << " pixels)";
}
}  // namespace

double meanAbsErrorPct(std::span<const Rgb8> a, std::span<const Rgb8> b) {
    checkSizes(a, b);
    std::uint64_t sum = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        sum += std::abs(a[i].r - b[i].r) + std::abs(a[i].g - b[i].g) + std::abs(a[i].b - b[i].b);
    }
    return 100.0 * static_cast<double>(sum) / (3.0 * 255.0 * static_cast<double>(a.size()));
}

double psnrDb(std::span<const Rgb8> a, std::span<const Rgb8> b) {
    checkSizes(a, b);
    double sum = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        const double dr = a[i].r - b[i].r, dg = a[i].g - b[i].g, db = a[i].b - b[i].b;
        sum += dr * dr + dg * dg + db * db;
    }
    const double mse = sum / (3.0 * static_cast<double>(a.size()));
    if (mse == 0.0) return std::numeric_limits<double>::infinity();
    return 10.0 * std::log10(255.0 * 255.0 / mse);
}

std::vector<Rgb8> boxDownsample(std::span<const Rgb8> src, int w, int h, int f) {
    CHECK(w > 0 && h > 0 && f > 0 && src.size() == static_cast<std::size_t>(w) * h * f * f)
        << "boxDownsample: the source must hold (w*f) x (h*f) pixels";
    std::vector<Rgb8> out(static_cast<std::size_t>(w) * h);
    const int n = f * f;
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            int s[3] = {0, 0, 0};
            for (int b = 0; b < f; ++b) {
                for (int a = 0; a < f; ++a) {
                    const Rgb8 c = src[static_cast<std::size_t>(y * f + b) * (w * f) + x * f + a];
                    s[0] += c.r;
                    s[1] += c.g;
                    s[2] += c.b;
                }
            }
            out[static_cast<std::size_t>(y) * w + x] =
                Rgb8{static_cast<std::uint8_t>((s[0] + n / 2) / n),
                     static_cast<std::uint8_t>((s[1] + n / 2) / n),
                     static_cast<std::uint8_t>((s[2] + n / 2) / n)};
        }
    }
    return out;
}

}  // namespace ig
