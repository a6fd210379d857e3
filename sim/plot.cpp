#include "sim/plot.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>

namespace sim {

namespace {

// 3x5 glyphs, rows top first, '#' set. Lower case prints as upper case.
struct Glyph {
    char c;
    const char* rows[5];
};
constexpr Glyph kGlyphs[] = {
    {'0', {"###", "#.#", "#.#", "#.#", "###"}}, {'1', {".#.", "##.", ".#.", ".#.", "###"}},
    {'2', {"###", "..#", "###", "#..", "###"}}, {'3', {"###", "..#", ".##", "..#", "###"}},
    {'4', {"#.#", "#.#", "###", "..#", "..#"}}, {'5', {"###", "#..", "###", "..#", "###"}},
    {'6', {"###", "#..", "###", "#.#", "###"}}, {'7', {"###", "..#", ".#.", ".#.", ".#."}},
    {'8', {"###", "#.#", "###", "#.#", "###"}}, {'9', {"###", "#.#", "###", "..#", "###"}},
    {'A', {".#.", "#.#", "###", "#.#", "#.#"}}, {'B', {"##.", "#.#", "##.", "#.#", "##."}},
    {'C', {".##", "#..", "#..", "#..", ".##"}}, {'D', {"##.", "#.#", "#.#", "#.#", "##."}},
    {'E', {"###", "#..", "##.", "#..", "###"}}, {'F', {"###", "#..", "##.", "#..", "#.."}},
    {'G', {".##", "#..", "#.#", "#.#", ".##"}}, {'H', {"#.#", "#.#", "###", "#.#", "#.#"}},
    {'I', {"###", ".#.", ".#.", ".#.", "###"}}, {'J', {"..#", "..#", "..#", "#.#", ".#."}},
    {'K', {"#.#", "#.#", "##.", "#.#", "#.#"}}, {'L', {"#..", "#..", "#..", "#..", "###"}},
    {'M', {"#.#", "###", "###", "#.#", "#.#"}}, {'N', {"##.", "#.#", "#.#", "#.#", "#.#"}},
    {'O', {".#.", "#.#", "#.#", "#.#", ".#."}}, {'P', {"##.", "#.#", "##.", "#..", "#.."}},
    {'Q', {".#.", "#.#", "#.#", "##.", ".##"}}, {'R', {"##.", "#.#", "##.", "#.#", "#.#"}},
    {'S', {".##", "#..", ".#.", "..#", "##."}}, {'T', {"###", ".#.", ".#.", ".#.", ".#."}},
    {'U', {"#.#", "#.#", "#.#", "#.#", "###"}}, {'V', {"#.#", "#.#", "#.#", "#.#", ".#."}},
    {'W', {"#.#", "#.#", "###", "###", "#.#"}}, {'X', {"#.#", "#.#", ".#.", "#.#", "#.#"}},
    {'Y', {"#.#", "#.#", ".#.", ".#.", ".#."}}, {'Z', {"###", "..#", ".#.", "#..", "###"}},
    {'.', {"...", "...", "...", "...", ".#."}}, {',', {"...", "...", "...", ".#.", "#.."}},
    {'-', {"...", "...", "###", "...", "..."}}, {'+', {"...", ".#.", "###", ".#.", "..."}},
    {':', {"...", ".#.", "...", ".#.", "..."}}, {'/', {"..#", "..#", ".#.", "#..", "#.."}},
    {'(', {".#.", "#..", "#..", "#..", ".#."}}, {')', {".#.", "..#", "..#", "..#", ".#."}},
    {'=', {"...", "###", "...", "###", "..."}}, {'%', {"#.#", "..#", ".#.", "#..", "#.#"}},
    {'_', {"...", "...", "...", "...", "###"}}, {'<', {"..#", ".#.", "#..", ".#.", "..#"}},
    {'>', {"#..", ".#.", "..#", ".#.", "#.."}},
};

constexpr int kScale = 2;             // font pixels per glyph dot
constexpr int kAdvance = 4 * kScale;  // glyph width + one column gap
constexpr int kTextHeight = 5 * kScale;

const std::array<std::array<std::uint8_t, 3>, 8> kColours{{{31, 119, 180},
                                                           {214, 39, 40},
                                                           {44, 160, 44},
                                                           {148, 103, 189},
                                                           {255, 127, 14},
                                                           {23, 190, 207},
                                                           {140, 86, 75},
                                                           {127, 127, 127}}};

class Canvas {
  public:
    Canvas(int w, int h) : w_(w), h_(h), px_(static_cast<std::size_t>(w) * h * 3, 255) {}

    void set(int x, int y, const std::array<std::uint8_t, 3>& c) {
        if (x < 0 || y < 0 || x >= w_ || y >= h_) return;
        std::uint8_t* p = &px_[(static_cast<std::size_t>(y) * w_ + x) * 3];
        p[0] = c[0];
        p[1] = c[1];
        p[2] = c[2];
    }
    void rect(int x0, int y0, int x1, int y1, const std::array<std::uint8_t, 3>& c) {
        for (int y = y0; y <= y1; ++y) {
            for (int x = x0; x <= x1; ++x)
                set(x, y, c);
        }
    }
    void line(double x0, double y0, double x1, double y1, const std::array<std::uint8_t, 3>& c,
              int thick) {
        const int steps = static_cast<int>(std::max(std::abs(x1 - x0), std::abs(y1 - y0))) + 1;
        for (int i = 0; i <= steps; ++i) {
            const double t = static_cast<double>(i) / steps;
            const int x = static_cast<int>(std::lround(x0 + t * (x1 - x0)));
            const int y = static_cast<int>(std::lround(y0 + t * (y1 - y0)));
            rect(x - thick / 2, y - thick / 2, x + (thick - 1) / 2, y + (thick - 1) / 2, c);
        }
    }
    void text(int x, int y, const std::string& s, const std::array<std::uint8_t, 3>& c) {
        for (const char ch : s) {
            const char u = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
            for (const Glyph& g : kGlyphs) {
                if (g.c != u) continue;
                for (int r = 0; r < 5; ++r) {
                    for (int k = 0; k < 3; ++k) {
                        if (g.rows[r][k] == '#') {
                            rect(x + k * kScale, y + r * kScale, x + (k + 1) * kScale - 1,
                                 y + (r + 1) * kScale - 1, c);
                        }
                    }
                }
            }
            x += kAdvance;
        }
    }
    std::vector<std::uint8_t> take() { return std::move(px_); }

  private:
    int w_, h_;
    std::vector<std::uint8_t> px_;
};

std::string format(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

// A "nice" tick step for a range.
double niceStep(double range, int ticks) {
    const double raw = range / ticks;
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    for (const double m : {1.0, 2.0, 5.0, 10.0}) {
        if (m * mag >= raw) return m * mag;
    }
    return 10.0 * mag;
}

}  // namespace

std::vector<std::uint8_t> renderPlot(const std::vector<PlotSeries>& series, const PlotOptions& o) {
    const int w = std::max(o.width, 200), h = std::max(o.height, 150);
    Canvas cv(w, h);
    const std::array<std::uint8_t, 3> black{0, 0, 0}, grey{220, 220, 220};
    double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin, ymin = xmin, ymax = -xmin;
    for (const PlotSeries& s : series) {
        for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
            if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
            xmin = std::min(xmin, s.x[i]);
            xmax = std::max(xmax, s.x[i]);
            ymin = std::min(ymin, s.y[i]);
            ymax = std::max(ymax, s.y[i]);
        }
    }
    if (!(xmin <= xmax)) xmin = 0, xmax = 1, ymin = 0, ymax = 1;
    if (xmax - xmin < 1e-12) xmax = xmin + 1;
    if (ymax - ymin < 1e-12) ymax = ymin + 1;
    const double ystep = niceStep(ymax - ymin, 6);
    ymin = std::floor(ymin / ystep) * ystep;
    ymax = std::ceil(ymax / ystep) * ystep;
    const double xstep = niceStep(xmax - xmin, 8);

    const int left = 70, right = w - 20, top = 40, bottom = h - 50;
    auto sx = [&](double x) { return left + (x - xmin) / (xmax - xmin) * (right - left); };
    auto sy = [&](double y) { return bottom - (y - ymin) / (ymax - ymin) * (bottom - top); };

    for (double y = ymin; y <= ymax + 1e-9 * ystep; y += ystep) {
        cv.line(left, sy(y), right, sy(y), grey, 1);
        const std::string t = format(std::abs(y) < 1e-12 * ystep ? 0.0 : y);
        cv.text(left - 8 - kAdvance * static_cast<int>(t.size()),
                static_cast<int>(sy(y)) - kTextHeight / 2, t, black);
    }
    for (double x = std::ceil(xmin / xstep) * xstep; x <= xmax + 1e-9 * xstep; x += xstep) {
        cv.line(sx(x), top, sx(x), bottom, grey, 1);
        const std::string t = format(x);
        cv.text(static_cast<int>(sx(x)) - kAdvance * static_cast<int>(t.size()) / 2, bottom + 8, t,
                black);
    }
    cv.line(left, bottom, right, bottom, black, 1);
    cv.line(left, top, left, bottom, black, 1);
    cv.text(left, 12, o.title, black);
    cv.text((left + right) / 2 - kAdvance * static_cast<int>(o.xLabel.size()) / 2, h - 22, o.xLabel,
            black);
    cv.text(6, top - 16, o.yLabel, black);

    for (std::size_t k = 0; k < series.size(); ++k) {
        const PlotSeries& s = series[k];
        const auto& c = kColours[k % kColours.size()];
        bool have = false;
        double px = 0, py = 0;
        for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
            if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) {
                have = false;
                continue;
            }
            const double x = sx(s.x[i]), y = sy(s.y[i]);
            if (have) cv.line(px, py, x, y, c, 2);
            cv.rect(static_cast<int>(x) - 2, static_cast<int>(y) - 2, static_cast<int>(x) + 2,
                    static_cast<int>(y) + 2, c);
            have = true;
            px = x;
            py = y;
        }
        // Legend, top right.
        const int ly = top + 6 + static_cast<int>(k) * (kTextHeight + 6);
        const int lx = right - 10 - kAdvance * 34;
        cv.rect(lx, ly + 2, lx + 14, ly + kTextHeight - 3, c);
        cv.text(lx + 20, ly, s.label, black);
    }
    return cv.take();
}

}  // namespace sim
