#include "ig/pose_sweep.hpp"

#include <cctype>
#include <cmath>
#include <string>

#include "base/text.hpp"
#include "ig/cli.hpp"
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
        // The pose parser the flags use: numbers finite, "+H" above the ground, bad input
        // quoted briefly.
        const Pose p = parsePose(line, map, what);
        poses.push_back(p);
        if (lines) lines->push_back(lineNo);
    }
    if (poses.empty()) throw InputError(name + ": no poses in the file");
    return poses;
}

}  // namespace ig
