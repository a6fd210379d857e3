// What paging a database did before each frame, kept where a renderer process writes it and
// the field process reads it.
#pragma once

#include "sim/frame_ring.hpp"

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace sim {

// Each frame's paging as the process that renders sees it (makePagedRenderer). The records
// live in a shared anonymous mapping made with the log, so a renderer process forked after it
// (and each one restarted) appends where the field process reads: a renderer process reports
// the same figures as a renderer thread. One writer at a time (the renderer); readers take a
// snapshot, normally once the run is over. A writer killed mid-record leaves it unpublished.
class PagingLog {
  public:
    struct Frame {
        double time = 0.0;               // the frame's simulation time
        std::uint64_t required = 0;      // display tiles its footprint needed
        std::uint64_t substituted = 0;   // of those, drawn from a coarser level
        std::uint64_t failed = 0;        // of those, unreadable
        std::uint64_t nodesMissing = 0;  // node tiles not resident (their nodes give no bound)
        double pageMs = 0.0;             // the placing, on the renderer's thread
        std::uint64_t tilesRead = 0;     // by the cache's loaders since the start (all levels)
        std::uint64_t bytesRead = 0;
        double detail = 1.0;  // the frame's Intrinsics::detail (PagedTerrain::chooseDetail)
        // The rendering process's peak resident set so far (bytes; 0 where unknown): a renderer
        // process's own, which the field process's does not include.
        std::uint64_t peakRssBytes = 0;
        // Its resident set after the frame, and of it at most: the tile cache's tiles, and the
        // pages the tiles placed in the map and pyramid hold (PagedTerrain::placedBytes), insets
        // included. The rest is the frames, the threads, the mapped slope bounds.
        std::uint64_t rssBytes = 0;
        std::uint64_t cacheBytes = 0;
        std::uint64_t mapBytes = 0;
        std::int32_t pid = 0;  // the process that rendered it
        // The renderer's longest silence in the frame, from taking the request to the image
        // cast (sim::takeRendererSilence): what the supervisor's silence rule sees of it.
        double silenceMs = 0.0;
        RenderStep silenceAfter = RenderStep::Request;
        RenderStep silenceUntil = RenderStep::Request;
    };
    // Frames kept (18 minutes at 60 frames a second); later ones are counted, not kept.
    static constexpr std::size_t kCapacity = std::size_t{1} << 16;
    // Unreadable tiles kept (each once), and the bytes of each message kept.
    static constexpr std::size_t kMaxFailures = 64;
    static constexpr std::size_t kFailureBytes = 256;

    // Throws std::runtime_error naming mmap when the system refuses the mapping.
    PagingLog();
    ~PagingLog();
    PagingLog(const PagingLog&) = delete;
    PagingLog& operator=(const PagingLog&) = delete;

    // Writer side.
    void add(const Frame& frame);
    void addFailure(std::string_view message);

    // Reader side: the frames kept so far, in order; the failures; the frames not kept.
    std::vector<Frame> frames() const;
    std::vector<std::string> failures() const;
    std::uint64_t dropped() const;

  private:
    struct Shared;
    Shared* shared_ = nullptr;
};

}  // namespace sim
