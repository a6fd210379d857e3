// Scene file loading: models (.vox or sculpted from three views), placed objects, scatter.
#include "ig/scene.hpp"

#include "base/check.hpp"
#include "base/text.hpp"
#include "ig/error.hpp"
#include "ig/sculpt.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <set>
#include <sstream>

namespace ig {
namespace {

using Json = nlohmann::json;

struct Ctx {
    const std::string& file;
    [[noreturn]] void fail(const std::string& entry, const std::string& what) const {
        throw InputError(file + ": " + entry + ": " + what);
    }
};

void checkKeys(const Ctx& ctx, const Json& j, const std::string& entry,
               std::initializer_list<const char*> allowed) {
    if (!j.is_object()) ctx.fail(entry, "expected an object");
    for (const auto& [key, value] : j.items()) {
        bool ok = false;
        for (const char* a : allowed)
            ok = ok || key == a;
        if (!ok) ctx.fail(entry, "unknown key " + base::quoted(key));
    }
}

double number(const Ctx& ctx, const Json& j, const std::string& entry, const char* key,
              std::optional<double> fallback = std::nullopt) {
    if (!j.contains(key)) {
        if (fallback) return *fallback;
        ctx.fail(entry, std::string("missing \"") + key + "\"");
    }
    const Json& v = j.at(key);
    if (!v.is_number()) ctx.fail(entry + "." + key, "expected a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) ctx.fail(entry + "." + key, "not a finite number");
    return d;
}

std::string text(const Ctx& ctx, const Json& j, const std::string& entry, const char* key) {
    if (!j.contains(key)) ctx.fail(entry, std::string("missing \"") + key + "\"");
    if (!j.at(key).is_string()) ctx.fail(entry + "." + key, "expected a string");
    std::string v = j.at(key).get<std::string>();
    if (v.size() > 512) {
        ctx.fail(entry + "." + key, base::quoted(v, 60) + ": longer than 512 bytes");
    }
    return v;
}

double positiveScale(const Ctx& ctx, const Json& j, const std::string& entry) {
    const double s = number(ctx, j, entry, "scale", 1.0);
    if (!(s >= 0.001) || s > 1000.0) {
        ctx.fail(entry + ".scale", base::number(s) + ": metres per voxel must be in [0.001, 1000]");
    }
    return s;
}

// A base height, metres: within 100 km of sea level, as the terrain's heights are.
double height(const Ctx& ctx, const Json& j, const std::string& entry) {
    const double z = number(ctx, j, entry, "z");
    if (std::abs(z) > 1e5) ctx.fail(entry + ".z", base::number(z) + ": must be within +-100 km");
    return z;
}

std::string resolve(const std::string& scenePath, const std::string& p) {
    const std::filesystem::path path(p);
    if (path.is_absolute()) return p;
    return (std::filesystem::path(scenePath).parent_path() / path).lexically_normal().string();
}

void checkOnMap(const Ctx& ctx, const TerrainMap& map, const std::string& entry, double x,
                double y) {
    if (!(x >= 0.0 && y >= 0.0 && x <= map.extentX() && y <= map.extentY())) {
        ctx.fail(entry, "(" + base::number(x) + ", " + base::number(y) + ") is off the map (x 0.." +
                            base::number(map.extentX()) + ", y 0.." + base::number(map.extentY()) +
                            " m)");
    }
}

std::uint16_t objectId(const Ctx& ctx, double v, const std::string& entry, std::set<int>& used) {
    if (!(v >= 1.0 && v <= 65535.0 && v == std::floor(v))) {
        ctx.fail(entry, base::number(v) + ": ids are whole numbers 1..65535");
    }
    const int id = static_cast<int>(v);
    if (!used.insert(id).second) ctx.fail(entry, "id " + std::to_string(id) + " is used twice");
    return static_cast<std::uint16_t>(id);
}

// Gradient magnitude of the bilinear surface at (x, y), metres per metre.
double slopeAt(const TerrainMap& map, const Ground& ground, double x, double y) {
    const double hx = 0.5 * map.spacingX(), hy = 0.5 * map.spacingY();
    const double gx = (ground.groundHeight(x + hx, y) - ground.groundHeight(x - hx, y)) / (2 * hx);
    const double gy = (ground.groundHeight(x, y + hy) - ground.groundHeight(x, y - hy)) / (2 * hy);
    return std::hypot(gx, gy);
}

ObjectModel loadModel(const Ctx& ctx, const std::string& name, const Json& m) {
    if (name.empty() || name.size() > 64) {
        ctx.fail("models", "model name " + base::quoted(name, 60) + ": 1..64 bytes expected");
    }
    const std::string entry = "models." + name;
    checkKeys(ctx, m, entry, {"vox", "model", "sculpt"});
    if (m.contains("vox") == m.contains("sculpt"))
        ctx.fail(entry, "give one of \"vox\" or \"sculpt\"");
    try {
        if (m.contains("vox")) {
            const std::string path = resolve(ctx.file, text(ctx, m, entry, "vox"));
            const double index = number(ctx, m, entry, "model", 0.0);
            if (index < 0 || index != std::floor(index) || index > 65535) {
                ctx.fail(entry + ".model", "expected a model index >= 0");
            }
            ObjectModel model = objectModelFromVox(readVox(path), static_cast<int>(index), path);
            model.name = name;
            return model;
        }
        const Json& s = m.at("sculpt");
        const std::string se = entry + ".sculpt";
        checkKeys(ctx, s, se,
                  {"side", "front", "top", "side_mask", "front_mask", "top_mask", "background",
                   "tolerance"});
        BackgroundKey key;
        if (s.contains("background")) {
            const Json& b = s.at("background");
            if (!b.is_array() || b.size() != 3) ctx.fail(se + ".background", "expected [r, g, b]");
            std::uint8_t c[3];
            for (int i = 0; i < 3; ++i) {
                if (!b[static_cast<std::size_t>(i)].is_number_integer() ||
                    b[static_cast<std::size_t>(i)].get<int>() < 0 ||
                    b[static_cast<std::size_t>(i)].get<int>() > 255) {
                    ctx.fail(se + ".background", "components are 0..255");
                }
                c[i] = static_cast<std::uint8_t>(b[static_cast<std::size_t>(i)].get<int>());
            }
            key.color = Rgb8{c[0], c[1], c[2]};
        }
        const double tol = number(ctx, s, se, "tolerance", 24.0);
        if (!(tol >= 0.0 && tol <= 255.0)) ctx.fail(se + ".tolerance", "must be 0..255");
        key.tolerance = static_cast<int>(tol);
        auto view = [&](const char* which) {
            const std::string mask = std::string(which) + "_mask";
            return loadSculptView(resolve(ctx.file, text(ctx, s, se, which)),
                                  s.contains(mask)
                                      ? resolve(ctx.file, text(ctx, s, se, mask.c_str()))
                                      : std::string(),
                                  key);
        };
        SculptViews views{view("side"), view("front"), view("top")};
        return sculptModel(views, ctx.file + ": " + se);
    } catch (const InputError& e) {
        const std::string what = e.what();
        if (what.rfind(ctx.file + ": ", 0) == 0) throw;
        ctx.fail(entry, what);
    }
}

}  // namespace

int Scene::modelIndex(std::string_view name) const {
    for (std::size_t i = 0; i < modelNames.size(); ++i)
        if (modelNames[i] == name) return static_cast<int>(i);
    return -1;
}

ObjectLayer Scene::stampMoving(std::span<const Placement> where, const Ground* ground) const {
    CHECK_EQ(where.size(), moving.size());
    const TerrainMap& map = staticLayer->map();
    const Ground& under = ground ? *ground : map;
    ObjectLayer layer(map, cellSize);
    for (std::size_t i = 0; i < moving.size(); ++i) {
        Placement p = where[i];
        if (!(p.x >= 0.0 && p.y >= 0.0 && p.x <= map.extentX() && p.y <= map.extentY())) continue;
        p.id = moving[i].id;
        p.scale = moving[i].scale;
        p.z = moving[i].z ? *moving[i].z : under.groundHeight(p.x, p.y);
        layer.place(*models[static_cast<std::size_t>(moving[i].model)], p);
    }
    layer.finish();
    return layer;
}

Scene parseScene(std::string_view content, const std::string& path, const TerrainMap& map,
                 bool shareSticks, double maxCellVisits, const Ground* ground) {
    const Ctx ctx{path};
    const Ground& under = ground ? *ground : map;
    Json j;
    try {
        j = Json::parse(content);
    } catch (const Json::parse_error& e) {
        // The parser's message without its echo of the input ("; last read: ...").
        std::string what = e.what();
        what = what.substr(0, std::min<std::size_t>(what.find("; last read"), 300));
        throw InputError(path + ": not valid JSON (" + what + ")");
    }
    checkKeys(ctx, j, "scene", {"cell_m", "models", "objects", "scatter"});
    Scene scene;
    scene.path = path;
    scene.cellSize = number(ctx, j, "scene", "cell_m", map.spacingX());
    if (!(scene.cellSize > 0.0) || scene.cellSize > map.spacingX() ||
        map.spacingX() / scene.cellSize > 4096) {
        ctx.fail("cell_m", base::number(scene.cellSize) +
                               ": the object cell must be at most the "
                               "terrain spacing (" +
                               base::number(map.spacingX()) + " m) and at least 1/4096 of it");
    }
    scene.staticLayer = std::make_unique<ObjectLayer>(map, scene.cellSize, shareSticks);
    if (!j.contains("models") || !j.at("models").is_object()) {
        ctx.fail("models", "expected an object of named models");
    }
    for (const auto& [name, m] : j.at("models").items()) {
        scene.models.push_back(std::make_unique<ObjectModel>(loadModel(ctx, name, m)));
        scene.modelNames.push_back(name);
    }
    // The object cells a placement's footprint box sweeps, counted against the budget.
    double visits = 0.0;
    auto charge = [&](int model, double scale, const std::string& entry) {
        const VoxModel& g = scene.models[static_cast<std::size_t>(model)]->grid;
        const double r = scale * std::hypot(0.5 * g.sizeX, 0.5 * g.sizeY);
        const double nx = std::min(2.0 * r / scene.staticLayer->cellSizeX() + 3.0,
                                   static_cast<double>(scene.staticLayer->cellsX()));
        const double ny = std::min(2.0 * r / scene.staticLayer->cellSizeY() + 3.0,
                                   static_cast<double>(scene.staticLayer->cellsY()));
        visits += nx * ny;
        if (visits > maxCellVisits) {
            ctx.fail(entry, "the placements so far sweep " + base::number(visits) +
                                " object cells (at most " + base::number(maxCellVisits) +
                                "): use a larger cell_m, a smaller scale or fewer copies");
        }
    };
    auto modelOf = [&](const Json& o, const std::string& entry) {
        const std::string name = text(ctx, o, entry, "model");
        const int k = scene.modelIndex(name);
        if (k < 0) ctx.fail(entry + ".model", "unknown model " + base::quoted(name));
        return k;
    };
    std::set<int> used;
    int highest = 0;
    if (j.contains("objects")) {
        if (!j.at("objects").is_array()) ctx.fail("objects", "expected an array");
        std::size_t i = 0;
        for (const Json& o : j.at("objects")) {
            const std::string entry = "objects[" + std::to_string(i++) + "]";
            checkKeys(ctx, o, entry,
                      {"id", "model", "x", "y", "z", "heading", "scale", "trajectory"});
            const std::uint16_t id =
                objectId(ctx, number(ctx, o, entry, "id"), entry + ".id", used);
            highest = std::max<int>(highest, id);
            const int model = modelOf(o, entry);
            const double scale = positiveScale(ctx, o, entry);
            if (o.contains("trajectory")) {
                if (o.contains("x") || o.contains("y") || o.contains("heading")) {
                    ctx.fail(entry,
                             "a moving object takes its position and heading from its "
                             "trajectory; drop x, y and heading");
                }
                charge(model, scale, entry);
                MovingObject mo{
                    id,    model,        resolve(path, text(ctx, o, entry, "trajectory")),
                    scale, std::nullopt, entry};
                if (o.contains("z")) mo.z = height(ctx, o, entry);
                scene.moving.push_back(std::move(mo));
                continue;
            }
            Placement p;
            p.id = id;
            p.x = number(ctx, o, entry, "x");
            p.y = number(ctx, o, entry, "y");
            checkOnMap(ctx, map, entry, p.x, p.y);
            p.z = o.contains("z") ? height(ctx, o, entry) : under.groundHeight(p.x, p.y);
            p.heading = number(ctx, o, entry, "heading", 0.0) * std::numbers::pi / 180.0;
            p.scale = scale;
            charge(model, scale, entry);
            scene.staticLayer->place(*scene.models[static_cast<std::size_t>(model)], p);
        }
    }
    if (j.contains("scatter")) {
        if (!j.at("scatter").is_array()) ctx.fail("scatter", "expected an array");
        std::size_t i = 0;
        int nextId = highest + 1;
        for (const Json& s : j.at("scatter")) {
            const std::string entry = "scatter[" + std::to_string(i++) + "]";
            checkKeys(ctx, s, entry,
                      {"model", "count", "area", "seed", "max_slope_deg", "min_ground_m", "scale",
                       "first_id"});
            const int model = modelOf(s, entry);
            const double count = number(ctx, s, entry, "count");
            if (!(count >= 0 && count <= 65535 && count == std::floor(count))) {
                ctx.fail(entry + ".count", "expected a whole number 0..65535");
            }
            if (!s.contains("area") || !s.at("area").is_array() || s.at("area").size() != 4) {
                ctx.fail(entry + ".area", "expected [x0, y0, x1, y1] in metres");
            }
            double a[4];
            for (int k = 0; k < 4; ++k) {
                const Json& v = s.at("area")[static_cast<std::size_t>(k)];
                if (!v.is_number() || !std::isfinite(v.get<double>())) {
                    ctx.fail(entry + ".area", "expected four finite numbers");
                }
                a[k] = v.get<double>();
            }
            if (!(a[0] < a[2] && a[1] < a[3]))
                ctx.fail(entry + ".area", "expected x0 < x1 and y0 < y1");
            checkOnMap(ctx, map, entry + ".area", a[0], a[1]);
            checkOnMap(ctx, map, entry + ".area", a[2], a[3]);
            const double seed = number(ctx, s, entry, "seed", 1.0);
            if (!(seed >= 0.0 && seed <= 9007199254740992.0 && seed == std::floor(seed))) {
                ctx.fail(entry + ".seed", "expected a whole number 0..2^53");
            }
            const double maxSlope = number(ctx, s, entry, "max_slope_deg", 90.0);
            if (!(maxSlope > 0.0 && maxSlope <= 90.0)) {
                ctx.fail(entry + ".max_slope_deg", "must be in (0, 90]");
            }
            const double minGround = number(ctx, s, entry, "min_ground_m", -HUGE_VAL);
            const double scale = positiveScale(ctx, s, entry);
            if (s.contains("first_id")) {
                const double f = number(ctx, s, entry, "first_id");
                if (!(f >= 1 && f <= 65535 && f == std::floor(f))) {
                    ctx.fail(entry + ".first_id", "expected a whole number 1..65535");
                }
                nextId = static_cast<int>(f);
            }
            std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
            std::uniform_real_distribution<double> ux(a[0], a[2]), uy(a[1], a[3]),
                uh(0.0, 2 * std::numbers::pi);
            const double tanMax =
                maxSlope >= 90.0 ? HUGE_VAL : std::tan(maxSlope * std::numbers::pi / 180.0);
            int placed = 0;
            const auto wanted = static_cast<int>(count);
            for (long tries = 0; placed < wanted; ++tries) {
                if (tries > 100L * wanted) {
                    ctx.fail(entry, "placed " + std::to_string(placed) + " of " +
                                        std::to_string(wanted) + " copies in " +
                                        std::to_string(tries) +
                                        " tries: too little ground within max_slope_deg (and above "
                                        "min_ground_m) in "
                                        "the area");
                }
                Placement p;
                p.x = ux(rng);
                p.y = uy(rng);
                p.heading = uh(rng);
                if (slopeAt(map, under, p.x, p.y) > tanMax) continue;
                if (under.groundHeight(p.x, p.y) < minGround) continue;
                if (nextId > 65535) ctx.fail(entry, "ids run past 65535");
                p.id = objectId(ctx, nextId++, entry + " (scattered id)", used);
                p.z = under.groundHeight(p.x, p.y);
                p.scale = scale;
                charge(model, scale, entry);
                scene.staticLayer->place(*scene.models[static_cast<std::size_t>(model)], p);
                ++placed;
            }
        }
    }
    scene.staticLayer->finish();
    return scene;
}

Scene loadScene(const std::string& path, const TerrainMap& map, bool shareSticks,
                const Ground* ground) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path + ": cannot open the scene file");
    std::ostringstream ss;
    ss << in.rdbuf();
    const std::string content = ss.str();
    if (content.size() > (std::size_t{64} << 20)) throw InputError(path + ": larger than 64 MiB");
    return parseScene(content, path, map, shareSticks, kMaxSceneCellVisits, ground);
}

}  // namespace ig
