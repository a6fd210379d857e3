// Frames between processes: the latest-frame mailbox of the pipeline, in shared memory.
//
// One anonymous shared-memory file (memfd) holds a header and three frame slots. The renderer
// process writes its back slot and publishes it with one atomic exchange of the "middle" word
// (slot index + fresh bit); the field process exchanges its front slot for the middle one when
// the fresh bit is set. Neither side waits and the field process never sees a slot being
// written. Every slot is checked on the way in (sizes, finite pose and control points): a
// renderer that writes garbage is caught there, not in the warp.
//
// A stereo ring's slots hold the two eyes of a pair, each eye a block of its own (description,
// colour, depth): the right eye travels as the left one does, published and fetched with it.
//
// Render requests go the other way through a sequence lock: the field process posts the pose it
// wants rendered, the time it is for and the view (field of view, draw distance) to render it
// with; the renderer reads the newest one.
#pragma once

#include "ig/frame.hpp"
#include "sim/render_view.hpp"
#include "sim/scene_motion.hpp"

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace sim {

// What the field process asks the renderer for. `generation` counts posts (0: none yet).
struct RenderRequest {
    double time = 0.0;  // simulation time of the pose
    ig::Pose pose;      // the full predicted pose, roll included
    std::uint64_t sequence = 0;
    std::uint64_t generation = 0;
    RenderView view;
};

// Objects a request carries at most (a CIGI host's entities placed at the request's instant).
inline constexpr std::size_t kMaxRequestObjects = 1024;

// Where a renderer is in its frame when it gives a sign of life (sim::noteRendererAlive): the
// step just done. The placing's steps are ig::PlacingStep's, in its order.
enum class RenderStep : std::uint8_t {
    Request,    // a request taken; the frame begins
    Detail,     // its detail chosen (PagedTerrain::chooseDetail)
    WarmUp,     // the first frame's view all round requested
    Footprint,  // the placing's steps (ig::PlacingStep)
    Requested,
    Decided,
    Released,
    Backed,
    Written,
    StandIns,
    Placed,   // every map's tiles placed (insets too)
    Objects,  // the moving objects stamped
    Cast,     // the image cast; published next
};
const char* renderStepName(RenderStep step);

class FrameRing {
  public:
    // A new shared mapping with three slots of up to `maxPixels` pixels per eye, `eyes` (1, or
    // 2 for stereo pairs) eyes per slot; with `objectIds`, each eye also holds an object-id
    // plane. Throws std::runtime_error naming the system call when the system refuses.
    explicit FrameRing(std::size_t maxPixels, int eyes = 1, bool objectIds = false);
    ~FrameRing();
    FrameRing(const FrameRing&) = delete;
    FrameRing& operator=(const FrameRing&) = delete;

    std::size_t maxPixels() const { return maxPixels_; }
    int eyes() const { return eyes_; }
    bool objectIds() const { return objectIds_; }

    // Renderer side: copies `frame` (and, in a stereo ring, its right eye) into the back slot
    // and publishes it. False (nothing published) when an eye holds more pixels than a slot,
    // its colour and depth sizes disagree, a stereo ring's frame has no right eye, or an eye has
    // object ids of another size, or object ids the ring has no plane for.
    bool publish(const ig::RenderedFrame& frame, std::int64_t clockNs);
    // Renderer side, for fault injection and tests: publishes the back slot with `meta` as
    // it is (sizes and values unchecked) and no pixels copied.
    void publishRaw(const ig::RenderedFrame& meta, std::uint64_t claimedPixels);

    enum class Fetch { None, New, Bad };
    // Field side: when a frame newer than the last fetched was published, copies it into
    // `into` (reusing its buffers: no allocation once they have grown to the slot size; a
    // stereo ring's right eye into `into.right`, reused when nothing else holds it) and
    // returns New (`into.objectId` empty when the frame has none); Bad (and `why`) when the slot
    // does not hold a usable frame; None otherwise (also for a frame whose sequence is not above
    // the last one fetched).
    Fetch fetch(ig::RenderedFrame& into, std::string* why);

    // Field side: the next writer (a restarted renderer) writes the slot that is neither the
    // field side's nor the published one, whatever the last writer was doing when it died.
    void resetWriter();

    // Requests (field side posts, renderer side reads; any number of posts, one reader).
    // `objects`: placed at `time` (a host's entities), carried with the request; false when
    // there are more than kMaxRequestObjects (the first ones are carried). `view`: the field of
    // view and draw distance to render with.
    bool postRequest(const ig::Pose& pose, double time, std::uint64_t sequence,
                     std::span<const ExtraObject> objects = {}, const RenderView& view = {});
    // The newest request; with `objects`, the objects posted with it (the same post).
    RenderRequest latestRequest(std::vector<ExtraObject>* objects = nullptr) const;

    // Published frames so far; clock (ns, CLOCK_MONOTONIC) of the last publish, 0 before any.
    std::uint64_t published() const;
    // Sleeps until a frame is published after `published()` returned `seen`, or `seconds`
    // pass (a futex on the shared word: the publishing process wakes the waiter).
    void waitForPublish(std::uint64_t seen, double seconds) const;
    std::int64_t lastPublishNs() const;
    // Renderer side: a sign of life while a frame takes long (its tiles being placed), clock
    // in ns (CLOCK_MONOTONIC), and the step just done; field side: the last one's clock (0
    // before any) and step.
    void noteAlive(std::int64_t clockNs, RenderStep step);
    std::int64_t lastAliveNs() const;
    RenderStep lastAliveStep() const;

    // Flags shared by both sides.
    void requestStop();
    bool stopRequested() const;
    // A fault to inject fires once per run, whichever renderer process reaches it.
    bool claimFault();
    // The renderer's last words before it exits on an error (at most 255 bytes kept).
    void setError(const std::string& text);
    std::string error() const;
    void clearError();

  private:
    struct Header;
    struct SlotMeta;
    Header& header() const;
    static void wake(Header& h);
    // Writes `frame`'s description (and, when `copyPixels`, its pixels) into the back slot and
    // publishes it.
    void publishBack(const ig::RenderedFrame& frame, std::uint64_t pixels, std::int64_t clockNs,
                     bool copyPixels);
    // Eye `eye` of slot `slot`: its description, colour, depth and object ids.
    unsigned char* eyeBlock(std::uint32_t slot, int eye) const;
    SlotMeta& meta(std::uint32_t slot, int eye = 0) const;
    ig::Rgb8* color(std::uint32_t slot, int eye = 0) const;
    float* depth(std::uint32_t slot, int eye = 0) const;
    std::uint16_t* ids(std::uint32_t slot, int eye = 0) const;
    // Eye `eye` of the front slot: usable (else false and why), and copied into a frame.
    bool checkEye(int eye, std::string* why) const;
    void copyEye(int eye, ig::RenderedFrame& into) const;

    std::size_t maxPixels_ = 0;
    int eyes_ = 1;
    bool objectIds_ = false;
    std::size_t eyeBytes_ = 0;
    std::size_t slotBytes_ = 0;
    std::size_t mapBytes_ = 0;
    unsigned char* base_ = nullptr;
    std::uint32_t front_ = 2;  // field side's slot (process-local: only the field side reads it)
    std::uint64_t lastSequence_ = 0;
    bool fetchedAny_ = false;
};

}  // namespace sim
