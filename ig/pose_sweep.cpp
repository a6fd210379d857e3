#include "ig/pose_sweep.hpp"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <string>

#include "base/text.hpp"
#include "ig/error.hpp"

namespace ig {

std::vector<Pose> sweepPoses(const TerrainMap& map, int count) {
    std::vector<Pose> poses;
    poses.reserve(count);
    const double golden = 0.6180339887498949;
    for (int i = 0; i < count; ++i) {
        const double a = static_cast<double>(i) / (count - 1);  // 0..1 in order
        const double b = std::fmod(i * golden, 1.0);            // well spread, another order
        const double c = std::fmod(i * golden * golden + 0.3, 1.0);
        Pose p;
        p.position.x = map.extentX() * (0.2 + 0.6 * b);
        p.position.y = map.extentY() * (0.2 + 0.6 * c);
        const double agl = 5.0 * std::pow(4000.0, std::fmod(i * 0.37, 1.0));  // 5 m .. 20 km
        p.position.z = map.surfaceHeight(p.position.x, p.position.y) + agl;
        p.yaw = degToRad(360.0 * std::fmod(i * 7.0 / count + 0.5 * a, 1.0));
        p.pitch = degToRad(10.0 - 95.0 * c);
        p.roll = 0.0;
        poses.push_back(p);
    }
    return poses;
}

namespace {

// One number of a pose line, as strtod reads it (the whole field, finite).
double poseNumber(std::string_view field, const std::string& what) {
    const std::string text(field);
    char* end = nullptr;
    const double v = text.empty() ? 0.0 : std::strtod(text.c_str(), &end);
    if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v)) {
        throw InputError(what + ": " + base::quoted(field) + " is not a finite number");
    }
    return v;
}

}  // namespace

std::vector<Pose> parsePoseList(std::string_view text, const TerrainMap& map,
                                const std::string& name, std::vector<int>* lines) {
    std::vector<Pose> poses;
    if (lines) lines->clear();
    int lineNo = 0;
    while (!text.empty()) {
        const std::size_t eol = text.find('\n');
        std::string_view raw = text.substr(0, eol);
        text.remove_prefix(eol == std::string_view::npos ? text.size() : eol + 1);
        ++lineNo;
        raw = raw.substr(0, raw.find('#'));
        std::string line;
        for (const char c : raw) {
            if (!std::isspace(static_cast<unsigned char>(c))) line += c;
        }
        if (line.empty()) continue;
        const std::string what = name + " line " + std::to_string(lineNo);
        std::string_view fields[6];
        std::string_view rest = line;
        int count = 0;
        for (;;) {
            const std::size_t comma = rest.find(',');
            if (count < 6) fields[count] = rest.substr(0, comma);
            ++count;
            if (comma == std::string_view::npos) break;
            rest.remove_prefix(comma + 1);
        }
        if (count != 6) {
            throw InputError(what + ": expected x,y,z,yaw,pitch,roll (6 numbers), got " +
                             base::quoted(line));
        }
        Pose p;
        p.position.x = poseNumber(fields[0], what + " x");
        p.position.y = poseNumber(fields[1], what + " y");
        if (!fields[2].empty() && fields[2][0] == '+') {
            p.position.z = map.surfaceHeight(p.position.x, p.position.y) +
                           poseNumber(fields[2].substr(1), what + " z");
        } else {
            p.position.z = poseNumber(fields[2], what + " z");
        }
        p.yaw = degToRad(poseNumber(fields[3], what + " yaw"));
        p.pitch = degToRad(poseNumber(fields[4], what + " pitch"));
        p.roll = degToRad(poseNumber(fields[5], what + " roll"));
        if (!p.isFinite()) throw InputError(what + ": pose is not finite");
        poses.push_back(p);
        if (lines) lines->push_back(lineNo);
    }
    if (poses.empty()) throw InputError(name + ": no poses in the file");
    return poses;
}

}  // namespace ig
