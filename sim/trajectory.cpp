#include "sim/trajectory.hpp"

#include "base/text.hpp"
#include "ig/error.hpp"
#include "io/text_file.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

namespace sim {

namespace {

constexpr std::string_view kHeader = "t,x,y,z,yaw_deg,pitch_deg,roll_deg";

std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) {
        s.remove_prefix(1);
    }
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) {
        s.remove_suffix(1);
    }
    return s;
}

std::string stripSpaces(std::string_view s) {
    std::string r;
    for (const char c : s) {
        if (c != ' ' && c != '\t' && c != '\r') r += c;
    }
    return r;
}

// Nearest equivalent of `angle` to `reference` (shortest arc).
double unwrapNear(double angle, double reference) {
    constexpr double kTwoPi = 2.0 * std::numbers::pi;
    return angle - kTwoPi * std::round((angle - reference) / kTwoPi);
}

// Cubic Hermite on [t0, t1] with tangents m0, m1 (per second).
double hermite(double p0, double p1, double m0, double m1, double t0, double t1, double t) {
    const double h = t1 - t0;
    const double s = (t - t0) / h;
    const double s2 = s * s, s3 = s2 * s;
    return (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * h * m0 + (-2 * s3 + 3 * s2) * p1 +
           (s3 - s2) * h * m1;
}

}  // namespace

Trajectory Trajectory::loadCsv(const std::string& path) {
    std::string text, why;
    if (io::readTextFile(path, text, &why) != 0)
        throw ig::InputError("trajectory " + path + ": " + why);
    return parseCsv(text, path);
}

Trajectory Trajectory::parseCsv(std::string_view text, const std::string& name) {
    // The header names the columns: the seven of kHeader in any order; others are ignored.
    constexpr std::string_view kNames[7] = {"t", "x", "y", "z", "yaw_deg", "pitch_deg", "roll_deg"};
    auto splitFields = [](std::string_view line) {
        std::vector<std::string_view> fields;
        while (true) {
            const std::size_t comma = line.find(',');
            fields.push_back(trim(line.substr(0, comma)));
            if (comma == std::string_view::npos) break;
            line.remove_prefix(comma + 1);
        }
        return fields;
    };
    std::vector<TrajectorySample> samples;
    bool header = false;
    std::size_t columns = 0;
    std::size_t at[7] = {};  // the column of each of kNames
    int lineNo = 0;
    while (!text.empty()) {
        const std::size_t eol = text.find('\n');
        std::string_view line = trim(text.substr(0, eol));
        text.remove_prefix(eol == std::string_view::npos ? text.size() : eol + 1);
        ++lineNo;
        const std::string where = name + ":" + std::to_string(lineNo) + ": ";
        if (line.empty() || line.front() == '#') continue;
        const std::vector<std::string_view> fields = splitFields(line);
        if (!header) {
            const std::string expected = "expected a header naming the columns " +
                                         std::string(kHeader) +
                                         " (any order, other columns ignored)";
            bool seen[7] = {};
            for (std::size_t c = 0; c < fields.size(); ++c) {
                std::string lower = stripSpaces(fields[c]);
                std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char ch) {
                    return static_cast<char>(std::tolower(ch));
                });
                for (int k = 0; k < 7; ++k) {
                    if (lower != kNames[k]) continue;
                    if (seen[k]) {
                        throw ig::InputError(where + "column '" + std::string(kNames[k]) +
                                             "' appears twice in the header");
                    }
                    seen[k] = true;
                    at[k] = c;
                }
            }
            for (int k = 0; k < 7; ++k) {
                if (!seen[k]) {
                    throw ig::InputError(where + "no column '" + std::string(kNames[k]) + "'; " +
                                         expected + ", found " + base::quoted(line));
                }
            }
            columns = fields.size();
            header = true;
            continue;
        }
        if (fields.size() != columns) {
            throw ig::InputError(where + "expected " + std::to_string(columns) +
                                 " columns as in the header, found " +
                                 std::to_string(fields.size()));
        }
        double v[7];
        for (int k = 0; k < 7; ++k) {
            const std::string_view field = fields[at[k]];
            const std::string column =
                "column " + std::to_string(at[k] + 1) + " (" + std::string(kNames[k]) + ")";
            const char* end = field.data() + field.size();
            const auto [ptr, ec] = std::from_chars(field.data(), end, v[k]);
            if (field.empty() || ec != std::errc() || ptr != end) {
                throw ig::InputError(where + column + " " + base::quoted(field) +
                                     " is not a number");
            }
            if (!std::isfinite(v[k])) throw ig::InputError(where + column + " is not finite");
        }
        if (!(std::abs(v[0]) <= kMaxTrajectoryTime)) {
            throw ig::InputError(where + "time " + base::number(v[0], 10) +
                                 " s is out of range: trajectory times lie within +-" +
                                 base::number(kMaxTrajectoryTime) +
                                 " s (beyond that a double cannot resolve a field period)");
        }
        if (!samples.empty() && !(v[0] > samples.back().t)) {
            throw ig::InputError(where + "time " + base::number(v[0], 10) +
                                 " does not increase (previous " +
                                 base::number(samples.back().t, 10) + ")");
        }
        TrajectorySample s;
        s.t = v[0];
        s.pose.position = {v[1], v[2], v[3]};
        s.pose.yaw = ig::degToRad(v[4]);
        s.pose.pitch = ig::degToRad(v[5]);
        s.pose.roll = ig::degToRad(v[6]);
        samples.push_back(s);
    }
    if (!header) throw ig::InputError(name + ": no header line '" + std::string(kHeader) + "'");
    if (samples.empty()) throw ig::InputError(name + ": no trajectory rows after the header");
    return fromSamples(std::move(samples), name);
}

Trajectory Trajectory::fromSamples(std::vector<TrajectorySample> samples, const std::string& name) {
    if (samples.empty()) throw ig::InputError(name + ": empty trajectory");
    for (std::size_t i = 0; i < samples.size(); ++i) {
        if (!samples[i].pose.isFinite() || !std::isfinite(samples[i].t)) {
            throw ig::InputError(name + ": sample " + std::to_string(i) + " is not finite");
        }
        if (!(std::abs(samples[i].t) <= kMaxTrajectoryTime)) {
            throw ig::InputError(name + ": sample " + std::to_string(i) + ": time " +
                                 base::number(samples[i].t, 10) + " s is out of range (+-" +
                                 base::number(kMaxTrajectoryTime) + " s)");
        }
        if (i > 0) {
            if (!(samples[i].t > samples[i - 1].t)) {
                throw ig::InputError(name + ": sample " + std::to_string(i) +
                                     ": time does not increase");
            }
            ig::Pose& p = samples[i].pose;
            const ig::Pose& q = samples[i - 1].pose;
            p.yaw = unwrapNear(p.yaw, q.yaw);
            p.pitch = unwrapNear(p.pitch, q.pitch);
            p.roll = unwrapNear(p.roll, q.roll);
        }
    }
    Trajectory tr;
    tr.samples_ = std::move(samples);
    return tr;
}

ig::Pose Trajectory::poseAt(double t) const {
    const auto& s = samples_;
    if (s.size() == 1 || !(t > s.front().t)) return s.front().pose;
    if (t >= s.back().t) return s.back().pose;
    const std::size_t i1 = static_cast<std::size_t>(
        std::upper_bound(s.begin(), s.end(), t,
                         [](double v, const TrajectorySample& a) { return v < a.t; }) -
        s.begin());
    const std::size_t i0 = i1 - 1;
    // Tangent at sample i: central difference over its neighbours (one-sided at the ends).
    auto tangent = [&](std::size_t i, auto get) {
        const std::size_t a = i == 0 ? 0 : i - 1;
        const std::size_t b = i + 1 < s.size() ? i + 1 : i;
        return (get(s[b].pose) - get(s[a].pose)) / (s[b].t - s[a].t);
    };
    auto interp = [&](auto get) {
        return hermite(get(s[i0].pose), get(s[i1].pose), tangent(i0, get), tangent(i1, get),
                       s[i0].t, s[i1].t, t);
    };
    ig::Pose p;
    p.position.x = interp([](const ig::Pose& q) { return q.position.x; });
    p.position.y = interp([](const ig::Pose& q) { return q.position.y; });
    p.position.z = interp([](const ig::Pose& q) { return q.position.z; });
    p.yaw = interp([](const ig::Pose& q) { return q.yaw; });
    p.pitch = interp([](const ig::Pose& q) { return q.pitch; });
    p.roll = interp([](const ig::Pose& q) { return q.roll; });
    return p;
}

FittedTrajectory fitTrajectoryToMap(const Trajectory& trajectory, const ig::TerrainMap& map) {
    const std::vector<TrajectorySample>& in = trajectory.samples();
    double x0 = in.front().pose.position.x, x1 = x0;
    double y0 = in.front().pose.position.y, y1 = y0;
    double zLow = 0.0;
    for (const TrajectorySample& s : in) {
        x0 = std::min(x0, s.pose.position.x);
        x1 = std::max(x1, s.pose.position.x);
        y0 = std::min(y0, s.pose.position.y);
        y1 = std::max(y1, s.pose.position.y);
        zLow = std::min(zLow, s.pose.position.z);
    }
    FittedTrajectory out;
    const double span = std::max(x1 - x0, y1 - y0);
    const double room = 0.6 * std::min(map.extentX(), map.extentY());
    out.scale = span > room ? room / span : 1.0;
    const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
    const double mx = 0.5 * map.extentX(), my = 0.5 * map.extentY();
    std::vector<TrajectorySample> samples = in;
    for (TrajectorySample& s : samples) {
        s.pose.position.x = mx + out.scale * (s.pose.position.x - cx);
        s.pose.position.y = my + out.scale * (s.pose.position.y - cy);
        s.pose.position.z = out.scale * (s.pose.position.z - zLow);
    }
    // The highest ground under the curve between the samples and two cells to each side.
    const Trajectory flat = Trajectory::fromSamples(samples, "fitted trajectory");
    const double reach = 2.0 * std::max(map.spacingX(), map.spacingY());
    const double t0 = flat.startTime(), t1 = flat.endTime();
    constexpr int kProbes = 400;
    out.ground = -std::numeric_limits<double>::infinity();
    for (int i = 0; i <= kProbes; ++i) {
        const glm::dvec3 p = flat.poseAt(t0 + (t1 - t0) * i / kProbes).position;
        for (const auto& [dx, dy] :
             {std::pair{0.0, 0.0}, std::pair{reach, 0.0}, std::pair{-reach, 0.0},
              std::pair{0.0, reach}, std::pair{0.0, -reach}}) {
            const double x = std::clamp(p.x + dx, 0.0, map.extentX());
            const double y = std::clamp(p.y + dy, 0.0, map.extentY());
            out.ground = std::max(out.ground, map.surfaceHeight(x, y));
        }
    }
    for (TrajectorySample& s : samples)
        s.pose.position.z += out.ground;
    out.trajectory = Trajectory::fromSamples(std::move(samples), "fitted trajectory");
    return out;
}

}  // namespace sim
