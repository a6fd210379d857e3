#include "sim/frame_ring.hpp"

#include "base/check.hpp"

#include <linux/futex.h>
#include <sys/mman.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <type_traits>

namespace sim {

static_assert(std::is_trivially_copyable_v<ig::Pose>);
static_assert(std::is_trivially_copyable_v<ig::Intrinsics>);
static_assert(std::is_trivially_copyable_v<ig::ControlPoint>);
static_assert(std::is_trivially_copyable_v<ig::RenderStats>);
static_assert(std::atomic<std::uint64_t>::is_always_lock_free);
static_assert(std::atomic<std::uint32_t>::is_always_lock_free);
static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t));

namespace {

constexpr std::uint32_t kFresh = 4;
constexpr std::uint32_t kIndexMask = 3;
constexpr std::size_t kAlign = 64;
constexpr std::size_t kErrorBytes = 256;
constexpr int kRequestWords = 11;
constexpr int kObjectWords = 6;  // model | id << 32 | on ground << 48, x, y, z, heading, scale

std::size_t roundUp(std::size_t n) {
    return (n + kAlign - 1) / kAlign * kAlign;
}

std::uint64_t bits(double v) {
    return std::bit_cast<std::uint64_t>(v);
}
double real(std::uint64_t v) {
    return std::bit_cast<double>(v);
}

bool finite(const glm::dvec2& v) {
    return std::isfinite(v.x) && std::isfinite(v.y);
}
bool finite(const glm::dvec4& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z) && std::isfinite(v.w);
}

}  // namespace

// Lives at the start of the mapping; both processes see the same bytes. Every field two
// processes touch at once is atomic.
struct FrameRing::Header {
    alignas(kAlign) std::atomic<std::uint32_t> middle;
    alignas(kAlign) std::atomic<std::uint32_t> back;  // the writer's slot
    std::atomic<std::uint64_t> published;
    std::atomic<std::uint32_t> publishWord;  // low bits of `published`, for futex waits
    std::atomic<std::int64_t> lastPublishNs;
    std::atomic<std::int64_t> lastAliveNs;     // the renderer's last sign of life between frames
    std::atomic<std::uint32_t> lastAliveStep;  // its RenderStep
    alignas(kAlign) std::atomic<std::uint64_t> requestLock;  // odd while a post is written
    std::atomic<std::uint64_t> request[kRequestWords];
    std::atomic<std::uint64_t> requestObjectCount;
    std::atomic<std::uint64_t> requestObjects[kMaxRequestObjects * kObjectWords];
    alignas(kAlign) std::atomic<std::uint32_t> stop;
    std::atomic<std::uint32_t> faultClaimed;
    std::atomic<std::uint32_t> errorLength;
    char errorText[kErrorBytes];
};

struct FrameRing::SlotMeta {
    std::uint64_t sequence;
    double time;
    ig::Pose pose;
    ig::Intrinsics intrinsics;
    ig::ControlPoint controlPoints[ig::kControlPointCount];
    ig::RenderStats stats;
    std::uint64_t pixels;
    std::uint64_t idPixels;  // 0 (no object ids) or `pixels`
    std::int64_t publishNs;
};

void FrameRing::wake(Header& h) {
    h.publishWord.fetch_add(1, std::memory_order_release);
    syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&h.publishWord), FUTEX_WAKE, 1, nullptr,
            nullptr, 0);
}

void FrameRing::waitForPublish(std::uint64_t seen, double seconds) const {
    Header& h = header();
    const std::uint32_t word = h.publishWord.load(std::memory_order_acquire);
    if (h.published.load(std::memory_order_acquire) != seen || !(seconds > 0.0)) return;
    timespec timeout{};
    timeout.tv_sec = static_cast<time_t>(seconds);
    timeout.tv_nsec = static_cast<long>((seconds - static_cast<double>(timeout.tv_sec)) * 1e9);
    // Returns at once if a publish moved the word since it was read (no lost wake-up).
    syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&h.publishWord), FUTEX_WAIT, word, &timeout,
            nullptr, 0);
}

FrameRing::FrameRing(std::size_t maxPixels, int eyes, bool objectIds)
    : maxPixels_(maxPixels), eyes_(eyes), objectIds_(objectIds) {
    CHECK_GT(maxPixels, 0u);
    CHECK(eyes == 1 || eyes == 2) << "eyes " << eyes;
    eyeBytes_ = roundUp(sizeof(SlotMeta)) + roundUp(maxPixels * sizeof(ig::Rgb8)) +
                roundUp(maxPixels * sizeof(float)) +
                (objectIds ? roundUp(maxPixels * sizeof(std::uint16_t)) : 0);
    slotBytes_ = static_cast<std::size_t>(eyes_) * eyeBytes_;
    mapBytes_ = roundUp(sizeof(Header)) + 3 * slotBytes_;
    const int fd = memfd_create("vig-frames", MFD_CLOEXEC);
    if (fd < 0) throw std::runtime_error(std::string("memfd_create: ") + std::strerror(errno));
    if (ftruncate(fd, static_cast<off_t>(mapBytes_)) != 0) {
        const int e = errno;
        close(fd);
        throw std::runtime_error("ftruncate of the frame ring (" + std::to_string(mapBytes_) +
                                 " bytes): " + std::strerror(e));
    }
    void* p = mmap(nullptr, mapBytes_, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    const int e = errno;
    close(fd);
    if (p == MAP_FAILED) throw std::runtime_error(std::string("mmap: ") + std::strerror(e));
    base_ = static_cast<unsigned char*>(p);
    Header* h = new (base_) Header{};
    h->middle.store(1);
    h->back.store(0);
    for (std::uint32_t s = 0; s < 3; ++s)
        for (int eye = 0; eye < eyes_; ++eye)
            new (eyeBlock(s, eye)) SlotMeta{};
}

FrameRing::~FrameRing() {
    if (base_) munmap(base_, mapBytes_);
}

FrameRing::Header& FrameRing::header() const {
    return *std::launder(reinterpret_cast<Header*>(base_));
}

unsigned char* FrameRing::eyeBlock(std::uint32_t slot, int eye) const {
    DCHECK_LT(slot, 3u);
    DCHECK_LT(eye, eyes_);
    return base_ + roundUp(sizeof(Header)) + slot * slotBytes_ +
           static_cast<std::size_t>(eye) * eyeBytes_;
}

FrameRing::SlotMeta& FrameRing::meta(std::uint32_t slot, int eye) const {
    return *std::launder(reinterpret_cast<SlotMeta*>(eyeBlock(slot, eye)));
}

ig::Rgb8* FrameRing::color(std::uint32_t slot, int eye) const {
    return reinterpret_cast<ig::Rgb8*>(eyeBlock(slot, eye) + roundUp(sizeof(SlotMeta)));
}

float* FrameRing::depth(std::uint32_t slot, int eye) const {
    return reinterpret_cast<float*>(eyeBlock(slot, eye) + roundUp(sizeof(SlotMeta)) +
                                    roundUp(maxPixels_ * sizeof(ig::Rgb8)));
}

std::uint16_t* FrameRing::ids(std::uint32_t slot, int eye) const {
    DCHECK(objectIds_);
    return reinterpret_cast<std::uint16_t*>(eyeBlock(slot, eye) + roundUp(sizeof(SlotMeta)) +
                                            roundUp(maxPixels_ * sizeof(ig::Rgb8)) +
                                            roundUp(maxPixels_ * sizeof(float)));
}

void FrameRing::publishBack(const ig::RenderedFrame& frame, std::uint64_t pixels,
                            std::int64_t clockNs, bool copyPixels) {
    Header& h = header();
    const std::uint32_t back = h.back.load(std::memory_order_relaxed);
    for (int e = 0; e < eyes_; ++e) {
        // The right eye of a raw publish without one is described as the left.
        const ig::RenderedFrame& eye = e == 1 && frame.right ? *frame.right : frame;
        SlotMeta& m = meta(back, e);
        m.sequence = eye.sequence;
        m.time = eye.time;
        m.pose = eye.pose;
        m.intrinsics = eye.intrinsics;
        std::copy(eye.controlPoints.begin(), eye.controlPoints.end(), m.controlPoints);
        m.stats = eye.stats;
        m.pixels = e == 0 || !copyPixels ? pixels : eye.color.size();
        m.idPixels = eye.objectId.empty() ? 0 : eye.objectId.size();
        m.publishNs = clockNs;
        if (copyPixels) {
            std::memcpy(color(back, e), eye.color.data(), m.pixels * sizeof(ig::Rgb8));
            std::memcpy(depth(back, e), eye.depth.data(), m.pixels * sizeof(float));
            if (m.idPixels != 0) {
                std::memcpy(ids(back, e), eye.objectId.data(), m.pixels * sizeof(std::uint16_t));
            }
        }
    }
    const std::uint32_t old = h.middle.exchange(back | kFresh, std::memory_order_acq_rel);
    h.back.store(old & kIndexMask, std::memory_order_relaxed);
    if (clockNs != 0) h.lastPublishNs.store(clockNs, std::memory_order_relaxed);
    h.published.fetch_add(1, std::memory_order_release);
    wake(h);
}

bool FrameRing::publish(const ig::RenderedFrame& frame, std::int64_t clockNs) {
    const std::size_t n = frame.color.size();
    if (n > maxPixels_ || frame.depth.size() != n) return false;
    if (!frame.objectId.empty() && (!objectIds_ || frame.objectId.size() != n)) return false;
    if (eyes_ == 2) {
        if (!frame.right) return false;
        const std::size_t r = frame.right->color.size();
        if (r > maxPixels_ || frame.right->depth.size() != r) return false;
        if (!frame.right->objectId.empty() && (!objectIds_ || frame.right->objectId.size() != r)) {
            return false;
        }
    }
    publishBack(frame, n, clockNs, true);
    return true;
}

void FrameRing::publishRaw(const ig::RenderedFrame& frame, std::uint64_t claimedPixels) {
    publishBack(frame, claimedPixels, 0, false);
}

bool FrameRing::checkEye(int eye, std::string* why) const {
    const SlotMeta& m = meta(front_, eye);
    const ig::Intrinsics& in = m.intrinsics;
    const auto bad = [&](const std::string& what) {
        if (why) {
            *why = "frame " + std::to_string(meta(front_, 0).sequence) +
                   (eye == 1 ? ", right eye: " : ": ") + what;
        }
        return false;
    };
    if (in.width < 2 || in.height < 2 || in.margin < 0 || in.windowWidth() < 1 ||
        in.windowHeight() < 1 || !(in.focal > 0.0) || !std::isfinite(in.focal)) {
        return bad("unusable size " + std::to_string(in.width) + "x" + std::to_string(in.height) +
                   " margin " + std::to_string(in.margin));
    }
    const std::uint64_t n = static_cast<std::uint64_t>(in.width) * in.height;
    if (n > maxPixels_ || m.pixels != n) {
        return bad(std::to_string(m.pixels) + " pixels for " + std::to_string(in.width) + "x" +
                   std::to_string(in.height) + " (a slot holds " + std::to_string(maxPixels_) +
                   ")");
    }
    if (m.idPixels != 0 && (m.idPixels != n || !objectIds_)) {
        return bad(std::to_string(m.idPixels) + " object ids for " + std::to_string(n) + " pixels" +
                   (objectIds_ ? "" : " (the ring carries no object ids)"));
    }
    if (!m.pose.isFinite() || !std::isfinite(m.time)) return bad("pose or time not finite");
    for (const ig::ControlPoint& c : m.controlPoints) {
        if (!finite(c.pixel) || !finite(c.world)) return bad("a control point is not finite");
    }
    return true;
}

void FrameRing::copyEye(int eye, ig::RenderedFrame& into) const {
    const SlotMeta& m = meta(front_, eye);
    const std::size_t n = static_cast<std::size_t>(m.pixels);
    into.sequence = m.sequence;
    into.time = m.time;
    into.pose = m.pose;
    into.intrinsics = m.intrinsics;
    std::copy(std::begin(m.controlPoints), std::end(m.controlPoints), into.controlPoints.begin());
    into.stats = m.stats;
    into.color.resize(n);
    into.depth.resize(n);
    std::memcpy(into.color.data(), color(front_, eye), n * sizeof(ig::Rgb8));
    std::memcpy(into.depth.data(), depth(front_, eye), n * sizeof(float));
    if (m.idPixels != 0) {
        into.objectId.resize(n);
        std::memcpy(into.objectId.data(), ids(front_, eye), n * sizeof(std::uint16_t));
    } else {
        into.objectId.clear();
    }
}

FrameRing::Fetch FrameRing::fetch(ig::RenderedFrame& into, std::string* why) {
    Header& h = header();
    if ((h.middle.load(std::memory_order_acquire) & kFresh) == 0) return Fetch::None;
    front_ = h.middle.exchange(front_, std::memory_order_acq_rel) & kIndexMask;
    // Every eye is checked before `into` is touched.
    for (int e = 0; e < eyes_; ++e) {
        if (!checkEye(e, why)) return Fetch::Bad;
    }
    // A frame no newer than the one shown (a restarted renderer answering a request the
    // last one already had) is not shown.
    const std::uint64_t sequence = meta(front_, 0).sequence;
    if (fetchedAny_ && sequence <= lastSequence_) return Fetch::None;
    fetchedAny_ = true;
    lastSequence_ = sequence;
    copyEye(0, into);
    if (eyes_ == 2) {
        // The right eye's frame is written in place only while `into` alone holds it (made
        // here, so not const); one still shown elsewhere is left as it is.
        if (!into.right || into.right.use_count() != 1) {
            into.right = std::make_shared<ig::RenderedFrame>();
        }
        copyEye(1, const_cast<ig::RenderedFrame&>(*into.right));
    } else {
        into.right.reset();
    }
    return Fetch::New;
}

void FrameRing::resetWriter() {
    Header& h = header();
    const std::uint32_t middle = h.middle.load(std::memory_order_acquire) & kIndexMask;
    h.back.store(3 - front_ - middle, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
}

bool FrameRing::postRequest(const ig::Pose& pose, double time, std::uint64_t sequence,
                            std::span<const ExtraObject> objects, const RenderView& view) {
    Header& h = header();
    const std::size_t count = std::min(objects.size(), kMaxRequestObjects);
    const std::uint64_t lock = h.requestLock.load(std::memory_order_relaxed);
    h.requestLock.store(lock + 1, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
    const std::uint64_t words[kRequestWords] = {
        bits(time),      bits(pose.position.x), bits(pose.position.y), bits(pose.position.z),
        bits(pose.yaw),  bits(pose.pitch),      bits(pose.roll),       sequence,
        bits(view.hfov), bits(view.farM),       bits(view.nearM)};
    for (int k = 0; k < kRequestWords; ++k)
        h.request[k].store(words[k], std::memory_order_relaxed);
    h.requestObjectCount.store(count, std::memory_order_relaxed);
    for (std::size_t i = 0; i < count; ++i) {
        const ExtraObject& o = objects[i];
        const std::uint64_t w[kObjectWords] = {static_cast<std::uint32_t>(o.model) |
                                                   (std::uint64_t{o.placement.id} << 32) |
                                                   (std::uint64_t{o.onGround} << 48),
                                               bits(o.placement.x),
                                               bits(o.placement.y),
                                               bits(o.placement.z),
                                               bits(o.placement.heading),
                                               bits(o.placement.scale)};
        for (int k = 0; k < kObjectWords; ++k)
            h.requestObjects[i * kObjectWords + k].store(w[k], std::memory_order_relaxed);
    }
    h.requestLock.store(lock + 2, std::memory_order_release);
    return count == objects.size();
}

RenderRequest FrameRing::latestRequest(std::vector<ExtraObject>* objects) const {
    const Header& h = header();
    for (;;) {
        const std::uint64_t before = h.requestLock.load(std::memory_order_acquire);
        if (before % 2 != 0) continue;  // a post is being written (a few stores long)
        std::uint64_t w[kRequestWords];
        for (int k = 0; k < kRequestWords; ++k)
            w[k] = h.request[k].load(std::memory_order_relaxed);
        if (objects) {
            // Read as words, checked below: a post that overlapped is read again.
            const std::size_t count = std::min<std::uint64_t>(
                h.requestObjectCount.load(std::memory_order_relaxed), kMaxRequestObjects);
            objects->resize(count);
            for (std::size_t i = 0; i < count; ++i) {
                std::uint64_t o[kObjectWords];
                for (int k = 0; k < kObjectWords; ++k)
                    o[k] = h.requestObjects[i * kObjectWords + k].load(std::memory_order_relaxed);
                ExtraObject& e = (*objects)[i];
                e.model = static_cast<int>(static_cast<std::int32_t>(o[0] & 0xffffffffu));
                e.placement.id = static_cast<std::uint16_t>(o[0] >> 32);
                e.onGround = ((o[0] >> 48) & 1u) != 0;
                e.placement.x = real(o[1]);
                e.placement.y = real(o[2]);
                e.placement.z = real(o[3]);
                e.placement.heading = real(o[4]);
                e.placement.scale = real(o[5]);
            }
        }
        std::atomic_thread_fence(std::memory_order_acquire);
        if (h.requestLock.load(std::memory_order_relaxed) != before) continue;
        RenderRequest r;
        r.time = real(w[0]);
        r.pose.position = {real(w[1]), real(w[2]), real(w[3])};
        r.pose.yaw = real(w[4]);
        r.pose.pitch = real(w[5]);
        r.pose.roll = real(w[6]);
        r.sequence = w[7];
        r.view.hfov = real(w[8]);
        r.view.farM = real(w[9]);
        r.view.nearM = real(w[10]);
        r.generation = before / 2;
        return r;
    }
}

std::uint64_t FrameRing::published() const {
    return header().published.load(std::memory_order_acquire);
}

std::int64_t FrameRing::lastPublishNs() const {
    return header().lastPublishNs.load(std::memory_order_relaxed);
}

void FrameRing::noteAlive(std::int64_t clockNs, RenderStep step) {
    header().lastAliveStep.store(static_cast<std::uint32_t>(step), std::memory_order_relaxed);
    header().lastAliveNs.store(clockNs, std::memory_order_relaxed);
}

RenderStep FrameRing::lastAliveStep() const {
    const std::uint32_t step = header().lastAliveStep.load(std::memory_order_relaxed);
    return step <= static_cast<std::uint32_t>(RenderStep::Cast) ? static_cast<RenderStep>(step)
                                                                : RenderStep::Request;
}

const char* renderStepName(RenderStep step) {
    switch (step) {
        case RenderStep::Request:
            return "request taken";
        case RenderStep::Detail:
            return "detail chosen";
        case RenderStep::WarmUp:
            return "warm-up requested";
        case RenderStep::Footprint:
            return "footprint";
        case RenderStep::Requested:
            return "tiles requested";
        case RenderStep::Released:
            return "pages given back";
        case RenderStep::Decided:
            return "writes decided";
        case RenderStep::Backed:
            return "pages backed";
        case RenderStep::Written:
            return "tiles written";
        case RenderStep::StandIns:
            return "stand-ins' bounds";
        case RenderStep::Placed:
            return "tiles placed";
        case RenderStep::Objects:
            return "objects stamped";
        case RenderStep::Cast:
            return "image cast";
    }
    return "?";
}

std::int64_t FrameRing::lastAliveNs() const {
    return header().lastAliveNs.load(std::memory_order_relaxed);
}

void FrameRing::requestStop() {
    header().stop.store(1, std::memory_order_release);
}

bool FrameRing::stopRequested() const {
    return header().stop.load(std::memory_order_acquire) != 0;
}

bool FrameRing::claimFault() {
    return header().faultClaimed.exchange(1, std::memory_order_acq_rel) == 0;
}

void FrameRing::setError(const std::string& text) {
    Header& h = header();
    const std::size_t n = std::min(text.size(), kErrorBytes - 1);
    std::memcpy(h.errorText, text.data(), n);
    h.errorLength.store(static_cast<std::uint32_t>(n), std::memory_order_release);
}

std::string FrameRing::error() const {
    const Header& h = header();
    const std::uint32_t n = h.errorLength.load(std::memory_order_acquire);
    return std::string(h.errorText, std::min<std::size_t>(n, kErrorBytes - 1));
}

void FrameRing::clearError() {
    header().errorLength.store(0, std::memory_order_release);
}

}  // namespace sim
