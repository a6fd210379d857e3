// Questions a host asks of the terrain (the height under a point, the first hit along a line),
// answered exactly: at once over a map in memory (askTerrain), or, over a database paged beyond
// memory, on a thread of its own that first places the tiles each question reads
// (PagedTerrainQueries), so the field thread never waits for the disk and gets its answers a
// field or more later. docs/design/terrain_db.md, "A host's queries over a paged map".
#pragma once

#include "ig/inset.hpp"
#include "ig/paged_insets.hpp"
#include "ig/paged_terrain.hpp"
#include "ig/terrain.hpp"
#include "ig/terrain_db.hpp"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace sim {

struct TerrainQuestion {
    std::uint64_t ticket = 0;  // the asker's, given back with the answer
    bool line = false;         // false: the surface under `origin`; true: a line of sight
    glm::dvec3 origin{0.0};
    glm::dvec3 dir{0.0};                    // the line's direction (any length > 0)
    double minRange = 0.0, maxRange = 0.0;  // metres along the line
};

struct TerrainAnswer {
    std::uint64_t ticket = 0;
    // False: a tile the question reads could not be had (unreadable, or more tiles than the
    // cache may hold for one question); nothing else is set.
    bool known = true;
    double height = 0.0;         // the surface: its height under the point
    double range = -1.0;         // a line: its first hit in [minRange, maxRange]; -1: none
    glm::dvec2 slope{0.0};       // the surface's gradient (dz/dx, dz/dy) at the point or the hit
    float color[3] = {0, 0, 0};  // a line that hits: the surface's colour there
};

// Gradient of the bilinear surface at (x, y), as TerrainMap::surfaceHeight interpolates it.
glm::dvec2 surfaceGradient(const ig::TerrainMap& map, double x, double y);

// The answer from `map`, which holds every sample the question reads: the surface height and
// gradient (TerrainMap::surfaceHeight's bilinear surface); a line's first hit on that surface
// (ig::exactHitInRange), with the colour and gradient there.
TerrainAnswer askTerrain(const ig::TerrainMap& map, const TerrainQuestion& q);
// The same over a nested terrain (ig/inset.hpp), whose maps hold every sample the question
// reads: the nested surface's height, and its gradient from the map that gives it there (the
// inset's where one covers the point); a line's nearest hit over the global map and every
// inset, with the colour and gradient of the map it hit.
TerrainAnswer askTerrain(const ig::NestedMaps& maps, const TerrainQuestion& q);

class PagedTerrainQueries {
  public:
    struct Options {
        // The tile cache of the thread's own paged map (level 0 only).
        std::size_t budgetBytes = std::size_t{64} << 20;
        int loaderThreads = 1;
        // Questions asked and not yet collected; beyond, ask() refuses.
        std::size_t maxOutstanding = 1024;
    };
    struct Stats {
        std::uint64_t asked = 0, answered = 0;
        std::uint64_t unknown = 0;  // answered "not known" (a tile unreadable, or too many)
        std::uint64_t refused = 0;  // ask() with maxOutstanding outstanding
        std::uint64_t batches = 0;  // placements of tiles (several questions share one)
        std::uint64_t tilesRead = 0;
        double maxAnswerMs = 0.0;  // the longest from ask() to the answer ready
    };

    // `db` must outlive this. Starts the thread.
    PagedTerrainQueries(const ig::TerrainDb& db, const Options& options);
    ~PagedTerrainQueries();
    PagedTerrainQueries(const PagedTerrainQueries&) = delete;
    PagedTerrainQueries& operator=(const PagedTerrainQueries&) = delete;

    // The field thread's side: never waits for the disk, never allocates.
    // Hands a question over; false (counted) when maxOutstanding are outstanding.
    bool ask(const TerrainQuestion& q);
    // Appends the answers ready (at most `max`, and no more than `out`'s capacity leaves room
    // for), in the order asked.
    void collect(std::vector<TerrainAnswer>& out, std::size_t max);
    // Questions asked whose answers are not collected yet.
    std::size_t outstanding() const;
    // Waits until every question asked has its answer ready (tests, and tools without a field
    // clock).
    void waitIdle();

    Stats stats() const;
    // Test hook: tiles for which it returns true are never loaded (TileCache::setWithheld).
    void setWithheld(std::function<bool(const ig::TileKey&)> withheld);

  private:
    struct Asked {
        TerrainQuestion q;
        std::int64_t askedNs = 0;
    };
    void loop();
    void answerBatch(std::vector<Asked>& batch);

    Options options_;
    // The database's map and its insets (level 0 only).
    ig::PagedNestedTerrain paged_;
    std::vector<std::size_t> maxTilesPerBatch_;  // per map: the global one, then each inset
    mutable std::mutex mutex_;
    std::condition_variable wake_, idle_;
    std::vector<Asked> asked_;         // waiting for the thread
    std::vector<TerrainAnswer> done_;  // ready, not collected
    std::size_t outstanding_ = 0;      // asked, not collected
    std::size_t working_ = 0;          // taken by the thread, not done
    bool stop_ = false;
    Stats stats_;
    // The thread's own.
    std::vector<Asked> work_;
    std::vector<TerrainAnswer> answers_;
    std::thread thread_;
};

}  // namespace sim
