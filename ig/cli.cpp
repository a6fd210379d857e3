#include "ig/cli.hpp"

#include "base/text.hpp"
#include "ig/error.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_db.hpp"
#include "ig/terrain_db_build.hpp"
#include "ig/terrain_io.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <vector>

namespace ig {

void addTerrainOptions(CLI::App& app, TerrainOptions& o) {
    app.add_option("--height", o.height,
                   "Height map: 8/16-bit grey PNG or a GDAL raster such as GeoTIFF "
                   "(default: the shipped Puget Sound map)");
    app.add_option("--color", o.color, "Colour image over the same extent (PNG, JPEG, GeoTIFF)");
    app.add_option("--spacing", o.spacing,
                   "Metres between height samples (default: from the georeference, else 10)");
    app.add_option("--height-scale", o.heightScale, "Metres per height unit (default 1)");
    app.add_option("--height-offset", o.heightOffset, "Metres added to every height (default 0)");
    app.add_option("--void-height", o.voidHeight,
                   "Metres given to samples the height map has no data for (default: "
                   "interpolated from the samples around them)");
    app.add_option("--synthetic", o.synthetic,
                   "Synthetic terrain SIZE[:SEED] (power of two up to 16384) instead of files");
    app.add_option("--db", o.db,
                   "Terrain database (ig-build-db) instead of files, loaded whole when it fits "
                   "--cache-mb");
    app.add_option("--cache-mb", o.cacheMb,
                   "Memory for the terrain database, MB (default 4096): a larger map is paged by "
                   "the view (ig-render: one frame, caster fast|naive|reference; flythrough: a "
                   "--trajectory; refused elsewhere)");
}

namespace {
double parseNumber(const std::string& s, const std::string& what) {
    std::size_t used = 0;
    double v = 0.0;
    try {
        v = std::stod(s, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used == 0 || used != s.size() || !std::isfinite(v)) {
        throw InputError(what + ": " + base::quoted(s) + " is not a finite number");
    }
    return v;
}

std::vector<std::string> split(const std::string& s, char sep) {
    std::vector<std::string> parts;
    std::stringstream ss(s);
    std::string part;
    while (std::getline(ss, part, sep))
        parts.push_back(part);
    if (!s.empty() && s.back() == sep) parts.emplace_back();
    return parts;
}
}  // namespace

namespace {
// A terrain number against its range, before anything is loaded.
void checkRange(const std::optional<double>& v, const char* flag, double lo, double hi,
                const char* unit) {
    if (!v) return;
    if (!std::isfinite(*v) || *v < lo || *v > hi) {
        throw InputError(std::string(flag) + ": " + base::number(*v) + " is outside " +
                         base::number(lo) + " .. " + base::number(hi) + " " + unit);
    }
}
}  // namespace

std::optional<SyntheticSpec> parseSyntheticOption(const TerrainOptions& o, int maxSize) {
    checkRange(o.spacing, "--spacing", 0.001, 1e5, "metres");
    if (o.synthetic.empty()) return std::nullopt;
    if (!o.height.empty() || !o.color.empty()) {
        throw InputError("--synthetic: give either --synthetic or --height/--color, not both");
    }
    const auto parts = split(o.synthetic, ':');
    if (parts.empty() || parts.size() > 2) {
        throw InputError("--synthetic: expected SIZE[:SEED], got " + base::quoted(o.synthetic));
    }
    const double size = parseNumber(parts[0], "--synthetic size");
    const double seed = parts.size() == 2 ? parseNumber(parts[1], "--synthetic seed") : 1.0;
    if (size != std::floor(size) || seed != std::floor(seed) || seed < 0 || size < 2 ||
        size > maxSize || seed > 1e15) {
        throw InputError("--synthetic: SIZE must be a whole number 2.." + std::to_string(maxSize) +
                         " and SEED a whole number 0..1e15, got " + base::quoted(o.synthetic));
    }
    const double spacing = o.spacing.value_or(10.0);
    if (!(spacing > 0.0) || !std::isfinite(spacing)) {
        throw InputError("--spacing: must be a positive finite number of metres");
    }
    return SyntheticSpec{static_cast<int>(size), static_cast<std::uint64_t>(seed), spacing};
}

std::optional<TerrainSource> terrainSourceFromOptions(const TerrainOptions& o) {
    checkRange(o.spacing, "--spacing", 0.001, 1e5, "metres");
    checkRange(o.heightScale, "--height-scale", 1e-6, 1e4, "metres per height unit");
    checkRange(o.heightOffset, "--height-offset", -1e5, 1e5, "metres");
    checkRange(o.voidHeight, "--void-height", -1e5, 1e5, "metres");
    if (o.height.empty()) {
        if (!o.color.empty() || o.spacing || o.heightScale || o.heightOffset || o.voidHeight) {
            throw InputError("--height: terrain flags given without a height map");
        }
        return std::nullopt;
    }
    TerrainSource src;
    src.heightPath = o.height;
    src.colorPath = o.color;
    src.spacing = o.spacing;
    src.heightScale = o.heightScale;
    src.heightOffset = o.heightOffset;
    src.voidHeight = o.voidHeight;
    return src;
}

void addInsetOptions(CLI::App& app, InsetOptions& o) {
    app.add_option("--inset", o.specs,
                   "High-resolution inset (repeatable): synthetic:X,Y,CX,CY,FACTOR (with "
                   "--synthetic), HEIGHT[,COLOR]@X,Y,FACTOR (first sample on global sample X,Y, "
                   "FACTOR times finer), or HEIGHT[,COLOR] placed by its georeference");
    app.add_option("--inset-blend", o.blendCells,
                   "Fine cells over which an inset's rim blends into the global terrain")
        ->capture_default_str();
}

namespace {

// A whole number within [lo, hi] from `text`, or InputError naming `what`.
int parseWhole(const std::string& text, const std::string& what, int lo, int hi) {
    const double v = parseNumber(text, what);
    if (v != std::floor(v) || v < lo || v > hi) {
        throw InputError(what + ": " + base::quoted(text) + " must be a whole number " +
                         std::to_string(lo) + ".." + std::to_string(hi));
    }
    return static_cast<int>(v);
}

// A raster inset, loaded and placed.
InsetSource rasterInset(const std::string& spec, const GlobalGrid& global,
                        const Georeference& globalGeo, const TerrainOptions& terrain) {
    const std::string what = "--inset " + base::quoted(spec);
    const std::size_t at = spec.find('@');
    const std::vector<std::string> files = split(spec.substr(0, at), ',');
    if (files.empty() || files.size() > 2 || files[0].empty()) {
        throw InputError(what + ": expected HEIGHT[,COLOR][@X,Y,FACTOR]");
    }
    TerrainSource src;
    src.heightPath = files[0];
    if (files.size() == 2) src.colorPath = files[1];
    src.heightScale = terrain.heightScale;
    src.heightOffset = terrain.heightOffset;
    src.voidHeight = terrain.voidHeight;
    InsetSource in;
    in.name = "--inset " + files[0];
    if (at != std::string::npos) {
        const std::vector<std::string> p = split(spec.substr(at + 1), ',');
        if (p.size() != 3) throw InputError(what + ": expected @X,Y,FACTOR after the files");
        in.x0 = parseWhole(p[0], what + " X", 0, global.width - 2);
        in.y0 = parseWhole(p[1], what + " Y", 0, global.height - 2);
        in.factor = parseWhole(p[2], what + " FACTOR", 2, 256);
        src.spacing = global.spacingX / in.factor;
        if (std::abs(global.spacingX - global.spacingY) > 1e-9 * global.spacingX) {
            throw InputError(what +
                             ": the global map's cells are not square (give a "
                             "georeferenced inset)");
        }
    }
    TerrainMap fine = loadTerrain(src);
    if (at == std::string::npos) {
        const Georeference& g = globalGeo;
        const Georeference& f = fine.georeference();
        if (!g.present() || !f.present()) {
            throw InputError(what + ": " + (g.present() ? "the inset" : "the global map") +
                             " has no georeference; place it with @X,Y,FACTOR");
        }
        if (g.crs != f.crs) {
            throw InputError(what + ": its coordinate system is not the global map's");
        }
        const double ratio = global.spacingX / fine.spacingX();
        in.factor = static_cast<int>(std::lround(ratio));
        if (std::abs(ratio - in.factor) > 1e-6 * ratio ||
            std::abs(global.spacingY / fine.spacingY() - in.factor) > 1e-6 * ratio) {
            throw InputError(what + ": its spacing " + base::number(fine.spacingX()) +
                             " m is not the global " + base::number(global.spacingX) +
                             " m over a whole number");
        }
        const double gx = (f.originX - g.originX) / global.spacingX;
        const double gy = (f.originY - g.originY) / global.spacingY;
        in.x0 = static_cast<int>(std::lround(gx));
        in.y0 = static_cast<int>(std::lround(gy));
        if (std::abs(gx - in.x0) > 1e-6 || std::abs(gy - in.y0) > 1e-6) {
            throw InputError(what + ": its first sample lies between global samples (" +
                             base::number(gx) + ", " + base::number(gy) +
                             "); an inset's grid must continue the global one");
        }
    }
    // Whole global cells: samples past the last one are dropped.
    const int cx = (fine.width() - 1) / std::max(in.factor, 1);
    const int cy = (fine.height() - 1) / std::max(in.factor, 1);
    if (cx < 1 || cy < 1) {
        throw InputError(what + ": " + std::to_string(fine.width()) + " x " +
                         std::to_string(fine.height()) + " samples span no whole global cell");
    }
    const int w = cx * in.factor + 1, h = cy * in.factor + 1;
    if (w != fine.width() || h != fine.height()) {
        TerrainMap cut(w, h, fine.spacingX(), fine.spacingY(), fine.heightScale(),
                       fine.heightOffset());
        for (int v = 0; v < h; ++v) {
            for (int u = 0; u < w; ++u) {
                cut.setRaw(u, v, fine.raw(u, v));
                cut.setColor(u, v, fine.colorAt(u, v));
            }
        }
        cut.updateRange();
        fine = std::move(cut);
    }
    in.fine = std::move(fine);
    return in;
}

}  // namespace

std::vector<InsetSource> insetSources(const GlobalGrid& global, const Georeference& geo,
                                      const TerrainOptions& terrain, const InsetOptions& o,
                                      int syntheticLimit) {
    std::vector<InsetSource> sources;
    for (const std::string& spec : o.specs) {
        if (spec.rfind("synthetic:", 0) == 0) {
            const std::string what = "--inset " + base::quoted(spec);
            const auto syn = parseSyntheticOption(terrain, syntheticLimit);
            if (!syn) throw InputError(what + ": a synthetic inset needs --synthetic");
            const std::vector<std::string> p = split(spec.substr(10), ',');
            if (p.size() != 5) throw InputError(what + ": expected synthetic:X,Y,CX,CY,FACTOR");
            const int x = parseWhole(p[0], what + " X", 0, global.width - 2);
            const int y = parseWhole(p[1], what + " Y", 0, global.height - 2);
            const int cx = parseWhole(p[2], what + " CX", 1, global.width - 1);
            const int cy = parseWhole(p[3], what + " CY", 1, global.height - 1);
            const int f = parseWhole(p[4], what + " FACTOR", 2, 256);
            if ((f & (f - 1)) != 0) {
                throw InputError(what + ": FACTOR " + std::to_string(f) +
                                 " must be a power of two");
            }
            InsetSource src = syntheticInset(syn->seed, syn->spacing, x, y, cx, cy, f);
            src.name = "--inset " + spec;
            sources.push_back(std::move(src));
        } else {
            sources.push_back(rasterInset(spec, global, geo, terrain));
        }
    }
    return sources;
}

bool databaseHasInsets(const TerrainOptions& terrain) {
    return !terrain.db.empty() && !TerrainDb::open(terrain.db).insets().empty();
}

NestedTerrain loadNestedTerrain(TerrainMap global, const TerrainOptions& terrain,
                                const InsetOptions& o) {
    if (!terrain.db.empty()) {
        const TerrainDb db = TerrainDb::open(terrain.db);
        if (!db.insets().empty()) {
            if (o.any()) {
                throw InputError("--inset: " + terrain.db +
                                 " holds insets already; add more to it with ig-build-db --db " +
                                 terrain.db + " --inset ... --out DB");
            }
            return NestedTerrain::fromNested(std::move(global), readInsets(db));
        }
    }
    std::vector<InsetSource> sources =
        insetSources(GlobalGrid::of(global), global.georeference(), terrain, o, 16384);
    return NestedTerrain(std::move(global), std::move(sources), o.blendCells);
}

bool usesShippedMap(const TerrainOptions& o) {
    return o.height.empty() && o.synthetic.empty() && o.db.empty();
}

double databaseMemoryMb(const TerrainDb& db) {
    // Heights, colours and cell maxima, and the pyramid's third more.
    return 7.0 * 4.0 / 3.0 * db.info().width * db.info().height / (1 << 20);
}

bool databaseNeedsPaging(const TerrainOptions& o, const TerrainDb& db) {
    const std::size_t samples =
        static_cast<std::size_t>(db.info().width) * static_cast<std::size_t>(db.info().height);
    return databaseMemoryMb(db) > o.cacheMb || samples > kMaxImageSamples;
}

void checkDatabaseOptions(const TerrainOptions& o) {
    if (o.db.empty()) return;
    if (!o.height.empty() || !o.color.empty() || !o.synthetic.empty() || o.spacing ||
        o.heightScale || o.heightOffset || o.voidHeight) {
        throw InputError("--db: the database holds the map; give no other terrain flags");
    }
    if (!(o.cacheMb > 0) || !std::isfinite(o.cacheMb) || o.cacheMb > 1e8) {
        throw InputError("--cache-mb: must be a positive number of MB (at most 1e8)");
    }
}

TerrainMap loadTerrainFromOptions(const TerrainOptions& o) {
    if (!o.db.empty()) {
        checkDatabaseOptions(o);
        const TerrainDb db = TerrainDb::open(o.db);
        if (databaseNeedsPaging(o, db)) {
            throw InputError(
                o.db + ": the map (" + std::to_string(db.info().width) + " x " +
                std::to_string(db.info().height) + ") needs about " +
                std::to_string(static_cast<long long>(std::ceil(databaseMemoryMb(db)))) +
                " MB in memory, over --cache-mb " +
                std::to_string(static_cast<long long>(o.cacheMb)) +
                "; this program loads a database whole (ig-render pages one "
                "beyond the budget, and flythrough flies a --trajectory over one)");
        }
        return db.loadMap();
    }
    checkRange(o.heightScale, "--height-scale", 1e-6, 1e4, "metres per height unit");
    checkRange(o.heightOffset, "--height-offset", -1e5, 1e5, "metres");
    checkRange(o.voidHeight, "--void-height", -1e5, 1e5, "metres");
    if (const auto syn = parseSyntheticOption(o, 16384)) {
        return makeSyntheticTerrain(syn->size, syn->seed, syn->spacing);
    }
    if (const auto src = terrainSourceFromOptions(o)) return loadTerrain(*src);
    return loadPugetSound();
}

void addAppearanceOptions(CLI::App& app, AppearanceOptions& o) {
    app.add_option("--haze", o.haze,
                   "Distance haze: metres for a 63% blend to the horizon colour (0: off; auto: a "
                   "quarter of the map's larger extent)")
        ->capture_default_str();
    app.add_option("--haze-falloff", o.hazeFalloff,
                   "Haze height fall-off: scale height in metres (density exp(-z / H), --haze "
                   "holding at z = 0: denser haze in valleys); 0: off")
        ->capture_default_str();
    app.add_option("--supersample", o.supersample,
                   "Fast caster: vertical rays per pixel, N (1..8) or auto[:MAX] (per frame from "
                   "the pitch, at most MAX, default 4)")
        ->capture_default_str();
    app.add_option("--colors", o.colors,
                   "image (the colour image; without one, heights shaded at load) | ramp (the "
                   "elevation colour ramp, lit by --sun) | auto (a --color image, else the ramp)")
        ->capture_default_str();
    app.add_option("--sun", o.sun,
                   "Sun AZ,EL in degrees (azimuth clockwise from north): lights terrain without "
                   "a colour image; with one only under --shade")
        ->capture_default_str();
    app.add_option("--sun-time", o.sunTime,
                   "The sun at DATE,TIME (UTC, YYYY-MM-DD,HH:MM) from LAT,LON (degrees; the "
                   "shipped map's centre when omitted over it): DATE,TIME[,LAT,LON]");
    app.add_option("--sun-rate", o.sunRate,
                   "The sun moves with simulated time: degrees of azimuth per second (--sun), or "
                   "of the Earth's turn per second (--sun-time; default real time, 0.00417)");
    app.add_flag("--shade", o.shade,
                 "The sun shades the colour image too (flat ground keeps its colour)");
}

bool terrainHasImage(const TerrainOptions& terrain) {
    return !terrain.color.empty() || !terrain.db.empty() ||
           (terrain.height.empty() && terrain.synthetic.empty());
}

Appearance parseAppearance(const AppearanceOptions& o, const TerrainOptions& terrain,
                           const TerrainMap& map) {
    Appearance a;
    if (o.haze == "auto") {
        a.hazeDistance = 0.25 * std::max(map.extentX(), map.extentY());
    } else {
        a.hazeDistance = parseNumber(o.haze, "--haze");
        if (a.hazeDistance < 0.0 || a.hazeDistance > 1e7) {
            throw InputError("--haze: " + base::quoted(o.haze) +
                             " must be auto or 0..1e7 metres (0: off)");
        }
    }
    a.hazeFalloff = parseNumber(o.hazeFalloff, "--haze-falloff");
    if (!(a.hazeFalloff >= 0.0 && a.hazeFalloff <= 1e6)) {
        throw InputError("--haze-falloff: " + base::quoted(o.hazeFalloff) +
                         " must be 0..1e6 metres (0: off)");
    }
    if (a.hazeFalloff > 0.0 && !(a.hazeDistance > 0.0)) {
        throw InputError("--haze-falloff: shapes the haze of --haze; give a haze distance");
    }
    if (o.supersample.rfind("auto", 0) == 0) {
        a.supersample = kSupersampleAuto;
        if (o.supersample.size() > 4) {
            if (o.supersample[4] != ':') {
                throw InputError("--supersample: expected N or auto[:MAX], got " +
                                 base::quoted(o.supersample));
            }
            const double m = parseNumber(o.supersample.substr(5), "--supersample MAX");
            if (m != std::floor(m) || m < 1 || m > 8) {
                throw InputError("--supersample: MAX must be a whole number 1..8, got " +
                                 base::quoted(o.supersample));
            }
            a.supersampleMax = static_cast<int>(m);
        }
    } else {
        const double n = parseNumber(o.supersample, "--supersample");
        if (n != std::floor(n) || n < 1 || n > 8) {
            throw InputError("--supersample: must be 1..8 rays per pixel or auto[:MAX], got " +
                             base::quoted(o.supersample));
        }
        a.supersample = static_cast<int>(n);
    }
    if (o.colors != "image" && o.colors != "ramp" && o.colors != "auto") {
        throw InputError("--colors: expected image, ramp or auto, got " + base::quoted(o.colors));
    }
    if (!o.sun.empty() && !o.sunTime.empty()) {
        throw InputError("--sun-time: give either --sun or --sun-time, not both");
    }
    if (!o.sun.empty()) {
        const auto parts = split(o.sun, ',');
        if (parts.size() != 2) {
            throw InputError("--sun: expected AZ,EL in degrees, got " + base::quoted(o.sun));
        }
        Sun sun;
        const double az = parseNumber(parts[0], "--sun azimuth");
        const double el = parseNumber(parts[1], "--sun elevation");
        if (az < -360.0 || az > 720.0 || el < -90.0 || el > 90.0) {
            throw InputError("--sun: " + base::quoted(o.sun) +
                             ": azimuth must be -360..720 and elevation -90..90 degrees");
        }
        sun.azimuth = degToRad(az);
        sun.elevation = degToRad(el);
        a.sun = sun;
    } else if (!o.sunTime.empty()) {
        const auto parts = split(o.sunTime, ',');
        if (parts.size() != 2 && parts.size() != 4) {
            throw InputError("--sun-time: expected DATE,TIME[,LAT,LON], got " +
                             base::quoted(o.sunTime));
        }
        const double days = parseUtcDateTime(parts[0] + "," + parts[1], "--sun-time");
        double lat = kPugetSoundLatitude, lon = kPugetSoundLongitude;
        if (parts.size() == 4) {
            lat = parseNumber(parts[2], "--sun-time latitude");
            lon = parseNumber(parts[3], "--sun-time longitude");
            if (lat < -90.0 || lat > 90.0 || lon < -180.0 || lon > 180.0) {
                throw InputError(
                    "--sun-time: latitude must be -90..90 and longitude -180..180 "
                    "degrees, got " +
                    base::quoted(o.sunTime));
            }
        } else if (!usesShippedMap(terrain)) {
            const auto geo = geodeticOrigin(map.georeference());
            if (!geo) {
                throw InputError(
                    "--sun-time: this map's position is not known; give DATE,TIME,LAT,LON");
            }
            lat = (*geo)[0];
            lon = (*geo)[1];
        }
        a.sun = sunAt(lat, lon, days);
        a.sunClock.almanac = true;
        a.sunClock.latitudeDeg = lat;
        a.sunClock.longitudeDeg = lon;
        a.sunClock.days = days;
    }
    if (!o.sunRate.empty()) {
        const double rate = parseNumber(o.sunRate, "--sun-rate");
        if (o.sun.empty() && o.sunTime.empty()) {
            throw InputError("--sun-rate: moves the sun of --sun or --sun-time; give one");
        }
        if (std::abs(rate) > 360.0) {
            throw InputError("--sun-rate: " + base::quoted(o.sunRate) +
                             " must be -360..360 degrees per second");
        }
        if (a.sunClock.almanac) {
            a.sunClock.speed = rate / (360.0 / 86400.0);  // sun seconds per simulated second
        } else {
            a.sunClock.azimuthRate = degToRad(rate);
        }
    }
    a.shade = o.shade;
    // auto: a colour image the user names; the ramp over the shipped map (whose image is a
    // hypsometric tint, not a photograph) and over maps without one.
    const bool image = o.colors == "image"  ? terrainHasImage(terrain)
                       : o.colors == "auto" ? !terrain.color.empty()
                                            : false;
    if (a.shade && !(image && a.sun)) {
        throw InputError(
            "--shade: shades a colour image by the sun; give --sun or --sun-time and "
            "a map with a colour image (--colors image)");
    }
    a.ramp = o.colors == "ramp" || (o.colors == "auto" && !image) || (a.sun && !image);
    if (a.ramp && !a.sun) a.sun = Sun{degToRad(135.0), degToRad(30.0)};
    if (a.sun) a.sunClock.sun = *a.sun;
    return a;
}

namespace {
// The sky, supersampling and (ramp or --shade) the sun lighting of `a` over a map whose
// normals are `normalsOf`'s.
void applyLook(const Appearance& a, const TerrainMap& normalsOf, RenderOptions& render) {
    render.sky.hazeDistance = a.hazeDistance;
    render.sky.hazeFalloff = a.hazeFalloff;
    render.supersample = a.supersample;
    render.supersampleMax = a.supersampleMax;
    render.lighting = nullptr;
    if (!a.ramp && !a.shade) return;
    // The map keeps the albedo (the ramp, or the photo); each frame is lit as it is made.
    auto lighting = std::make_shared<SunLighting>();
    lighting->normals = std::make_shared<const TerrainNormals>(normalsOf);
    lighting->clock = a.sunClock;
    lighting->photo = !a.ramp;
    render.lighting = std::move(lighting);
}
}  // namespace

void applyAppearance(const Appearance& a, NestedTerrain& terrain, RenderOptions& render) {
    if (a.ramp) terrain.applyRamp();
    applyLook(a, terrain.global(), render);
}

void applyAppearance(const Appearance& a, TerrainMap& map, RenderOptions& render) {
    if (a.ramp) map.colors() = elevationRampAlbedo(map);
    applyLook(a, map, render);
}

Pose defaultViewPose(const TerrainMap& map) {
    Pose pose;
    const double x = 0.25 * map.extentX(), y = 0.25 * map.extentY();
    const double relief = std::max(map.maxHeight() - map.minHeight(), 1.0);
    // High enough to see over the relief ahead.
    pose.position = {
        x, y,
        std::max(map.surfaceHeight(x, y) + 0.15 * relief + 50.0, map.minHeight() + 0.6 * relief)};
    pose.yaw = std::atan2(map.extentX(), map.extentY());  // toward the far corner
    pose.pitch = degToRad(-8.0);
    return pose;
}

std::string describeTerrain(const TerrainMap& map) {
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "%d x %d samples, spacing %.3g x %.3g m, extent %.1f x %.1f km, heights "
                  "%.1f..%.1f m",
                  map.width(), map.height(), map.spacingX(), map.spacingY(), map.extentX() / 1000.0,
                  map.extentY() / 1000.0, map.minHeight(), map.maxHeight());
    std::string text = buf;
    if (map.filledSamples() > 0) {
        const double total = static_cast<double>(map.width()) * map.height();
        // Never "100 %" (or "1e+02 %") while some samples had data.
        const double pct = 100.0 * static_cast<double>(map.filledSamples()) / total;
        std::snprintf(
            buf, sizeof buf, ", %zu samples without data filled (%.4g %%)", map.filledSamples(),
            static_cast<double>(map.filledSamples()) < total ? std::min(pct, 99.99) : pct);
        text += buf;
    }
    return text;
}

std::pair<int, int> parseSize(const std::string& text, const std::string& what) {
    const auto parts = split(text, 'x');
    if (parts.size() != 2) throw InputError(what + ": expected WxH, got " + base::quoted(text));
    const double w = parseNumber(parts[0], what), h = parseNumber(parts[1], what);
    if (w != std::floor(w) || h != std::floor(h) || w < 1 || h < 1 || w > 16384 || h > 16384) {
        throw InputError(what + ": width and height must be whole numbers from 1 to 16384, got " +
                         base::quoted(text));
    }
    return {static_cast<int>(w), static_cast<int>(h)};
}

Pose parsePose(const std::string& text, const Ground& ground, const std::string& what) {
    const auto parts = split(text, ',');
    if (parts.size() != 6) {
        throw InputError(what + ": expected x,y,z,yaw,pitch,roll (6 numbers), got " +
                         base::quoted(text));
    }
    Pose p;
    p.position.x = parseNumber(parts[0], what + " x");
    p.position.y = parseNumber(parts[1], what + " y");
    if (!parts[2].empty() && parts[2][0] == '+') {
        p.position.z = ground.groundHeight(p.position.x, p.position.y) +
                       parseNumber(parts[2].substr(1), what + " z");
    } else {
        p.position.z = parseNumber(parts[2], what + " z");
    }
    p.yaw = degToRad(parseNumber(parts[3], what + " yaw"));
    p.pitch = degToRad(parseNumber(parts[4], what + " pitch"));
    p.roll = degToRad(parseNumber(parts[5], what + " roll"));
    return p;
}

int runProgram(const char* name, const std::function<int()>& body) {
    try {
        return body();
    } catch (const InputError& e) {
        std::fprintf(stderr, "%s: %s\n", name, e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "%s: error: %s\n", name, e.what());
        return 1;
    }
}

}  // namespace ig
