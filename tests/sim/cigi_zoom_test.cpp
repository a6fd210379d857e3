// A host's View Definition changing the field of view during the run (a sensor's zoom).
#include "sim/cigi_session.hpp"

#include "ig/synthetic.hpp"
#include "io/cigi.hpp"
#include "io/field_clock.hpp"
#include "io/file_sinks.hpp"
#include "sim/frame_ring.hpp"
#include "sim/pipeline.hpp"

#include "common/cigi_host.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

namespace {

namespace cigi = io::cigi;

constexpr int kWidth = 128, kHeight = 96;
constexpr double kDeg = 3.14159265358979323846 / 180.0;
constexpr std::uint64_t kChangeField = 30;  // the field the host's new field of view is sent for
constexpr std::uint64_t kFields = 90;
constexpr double kRenderHz = 6.0;  // a render takes ten fields (simulated)

// Before each field the host sends what the run's script says for it.
class Host final : public sim::PoseSource {
  public:
    Host(sim::CigiPoseSource& inner, vig_test::CigiHost& host, glm::dvec3 ownship, bool zoom)
        : inner_(inner), host_(host), ownship_(ownship), zoom_(zoom) {}
    ig::Pose advanceTo(double t) override {
        const std::uint64_t n = fields_++;
        if (n == 0) {
            // The ownship over the terrain, looking down a little.
            const glm::dvec3 g = inner_.session().geo().geodeticFromWorld(ownship_);
            cigi::EntityControl own;
            own.latOrX = g.x;
            own.lonOrY = g.y;
            own.altOrZ = g.z;
            own.yawDeg = 20.0f;
            own.pitchDeg = -15.0f;
            host_.send({own});
        }
        if (zoom_ && n == kChangeField) {
            cigi::ViewDefinition narrower;
            narrower.leftEnable = narrower.rightEnable = true;
            narrower.leftDeg = -20.0f;
            narrower.rightDeg = 20.0f;
            host_.send({narrower});
        }
        if (n == kChangeField + 10) {
            // Refused, changing nothing: wider than 179 degrees, and lopsided.
            cigi::ViewDefinition tooWide, lopsided;
            tooWide.leftEnable = tooWide.rightEnable = true;
            tooWide.leftDeg = -90.0f;
            tooWide.rightDeg = 90.0f;
            lopsided = tooWide;
            lopsided.leftDeg = -10.0f;
            lopsided.rightDeg = 30.0f;
            host_.send({tooWide, lopsided});
        }
        return inner_.advanceTo(t);
    }
    ig::Pose predict(double t) override { return inner_.predict(t); }
    double startTime() const override { return inner_.startTime(); }
    sim::RenderView view() const override { return inner_.view(); }

  private:
    sim::CigiPoseSource& inner_;
    vig_test::CigiHost& host_;
    glm::dvec3 ownship_;
    bool zoom_;
    std::uint64_t fields_ = 0;
};

struct ZoomRun {
    std::vector<std::vector<std::uint8_t>> fields;  // RGB lines of each field
    std::vector<std::uint64_t> frames;              // the frame each field was warped from
    sim::CigiStats stats;
};

// A simulated-clock run of kFields fields starting at `startDeg` degrees; with `zoom` the host
// narrows the field of view to 40 degrees at field kChangeField.
ZoomRun runZoom(sim::RendererMode mode, double startDeg, bool zoom) {
    const ig::TerrainMap map = ig::makeSyntheticTerrain(128, 11, 30.0);
    vig_test::CigiHost socket;
    sim::CigiOptions o;
    o.bind = {vig_test::kLoopback, 0};
    o.host = socket.socket.localEndpoint();
    o.origin = {47.0, -122.0, 10.0};
    const glm::dvec3 ownship{1900.0, 1200.0, map.maxHeight() + 250.0};
    o.startPose.position = ownship;
    o.windowWidth = kWidth;
    o.windowHeight = kHeight;
    sim::CigiPoseSource source(map, o);
    std::string error;
    EXPECT_EQ(source.open(&error), 0) << error;
    socket.ig = source.session().localEndpoint();
    Host host(source, socket, ownship, zoom);

    sim::RenderGeometry geometry;
    geometry.windowWidth = kWidth;
    geometry.windowHeight = kHeight;
    geometry.margin = 8;
    geometry.hfov = startDeg * kDeg;
    source.session().freezeFieldOfView(geometry.hfov);
    source.session().freezeFar(geometry.farM);

    sim::PipelineOptions po;
    po.clock = sim::ClockMode::Simulated;
    po.duration = static_cast<double>(kFields) * prp::kFieldPeriod;
    po.simulatedRenderHz = kRenderHz;
    po.rendererMode = mode;
    po.maxFramePixels = sim::maxFramePixels(geometry);
    ZoomRun run;
    po.onField = [&](const prp::Field& field, const io::FieldBuffer& buffer) {
        std::vector<std::uint8_t>& out = run.fields.emplace_back();
        for (int l = 0; l < buffer.lines; ++l) {
            const std::uint8_t* row = buffer.data + static_cast<std::size_t>(l) * buffer.stride;
            out.insert(out.end(), row, row + kWidth * 3);
        }
        run.frames.push_back(field.frameSequence);
    };
    io::NullSink sink;
    sink.open({kWidth, kHeight, io::PixelFormat::Rgb8}, &error);
    auto clock = io::makeSimulatedClock();
    sim::Pipeline pipeline(host, sim::makeCasterRenderer(map, geometry), sink, *clock, po);
    const sim::PipelineResult result = pipeline.run();
    EXPECT_TRUE(result.ok()) << result.error;
    run.stats = source.session().stats();
    return run;
}

double meanDifference(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
    EXPECT_EQ(a.size(), b.size());
    double sum = 0.0;
    for (std::size_t i = 0; i < a.size() && i < b.size(); ++i)
        sum += std::abs(static_cast<int>(a[i]) - static_cast<int>(b[i]));
    return sum / static_cast<double>(std::max<std::size_t>(a.size(), 1));
}

// The host narrows the view from 60 to 40 degrees at field 30. Against a run that starts at 40
// degrees: every field before 30 is far from it (the wider view); from field 30 on it is the
// same view: the fields warped from frames rendered at 60 degrees, scaled by the PRP, are
// within 2 levels on average of the fields of frames rendered at 40 (a frame of 128 pixels
// over 60 degrees resampled for 40: measured 1.3 levels at field 30), and once the first frame
// rendered after the change is shown the fields are the same bytes. The refused definitions change
// nothing and are reported.
TEST(CigiZoom, FieldOfViewChangesAtTheFieldTheHostSendsItFor) {
    const ZoomRun zoomed = runZoom(sim::RendererMode::Thread, 60.0, true);
    const ZoomRun narrow = runZoom(sim::RendererMode::Thread, 40.0, false);
    ASSERT_EQ(zoomed.fields.size(), kFields);
    ASSERT_EQ(narrow.fields.size(), kFields);
    EXPECT_EQ(zoomed.frames, narrow.frames);  // the same renders, at the same instants

    const double before =
        meanDifference(zoomed.fields[kChangeField - 1], narrow.fields[kChangeField - 1]);
    EXPECT_GT(before, 8.0);
    // The frame shown at the change and every later field of it: rendered before the change.
    std::uint64_t firstNew = kChangeField;
    while (firstNew < kFields && zoomed.frames[firstNew] == zoomed.frames[kChangeField])
        ++firstNew;
    // The frame after it was asked for before the change too (a render takes ten fields):
    // both are the old view, scaled.
    const std::uint64_t oldFrames = 2;
    std::uint64_t caughtUp = kChangeField;
    for (std::uint64_t k = 0; k < oldFrames && caughtUp < kFields; ++k) {
        const std::uint64_t shown = zoomed.frames[caughtUp];
        while (caughtUp < kFields && zoomed.frames[caughtUp] == shown)
            ++caughtUp;
    }
    ASSERT_LT(caughtUp + 10, kFields);
    for (std::uint64_t n = 0; n < kFields; ++n) {
        const double d = meanDifference(zoomed.fields[n], narrow.fields[n]);
        if (n < kChangeField) {
            EXPECT_GT(d, 8.0) << "field " << n;
        } else if (n < caughtUp) {
            EXPECT_LT(d, 2.0) << "field " << n;
            EXPECT_LT(d, 0.25 * before) << "field " << n;
        } else {
            EXPECT_TRUE(zoomed.fields[n] == narrow.fields[n]) << "field " << n << ": " << d;
        }
    }
    std::printf("before the change %.2f levels; scaled old frames %.3f (field %llu)\n", before,
                meanDifference(zoomed.fields[kChangeField], narrow.fields[kChangeField]),
                static_cast<unsigned long long>(kChangeField));

    EXPECT_EQ(zoomed.stats.fieldOfViewChanges, 1u);
    EXPECT_EQ(zoomed.stats.viewDefinitions, 1u);
    EXPECT_EQ(zoomed.stats.viewDefinitionsNotApplied, 2u);
    EXPECT_EQ(narrow.stats.fieldOfViewChanges, 0u);
    EXPECT_EQ(narrow.stats.viewDefinitionsNotApplied, 2u);
    int reported = 0;
    for (const std::string& e : zoomed.stats.firstErrors)
        reported += e.find("only a frustum symmetric") != std::string::npos;
    EXPECT_EQ(reported, 2);
}

// The renderer process takes the new field of view with its requests: the same fields, byte
// for byte, as the renderer thread.
TEST(CigiZoom, RendererProcessZoomsAsTheThread) {
    const ZoomRun thread = runZoom(sim::RendererMode::Thread, 60.0, true);
    const ZoomRun process = runZoom(sim::RendererMode::Process, 60.0, true);
    ASSERT_EQ(thread.fields.size(), kFields);
    ASSERT_EQ(process.fields.size(), kFields);
    EXPECT_EQ(thread.frames, process.frames);
    for (std::uint64_t n = 0; n < kFields; ++n)
        EXPECT_TRUE(thread.fields[n] == process.fields[n]) << "field " << n;
    EXPECT_EQ(process.stats.fieldOfViewChanges, 1u);
}

// A request carries its view to the renderer process.
TEST(CigiZoom, RequestCarriesItsView) {
    sim::FrameRing ring(64);
    sim::RenderView view;
    view.hfov = 0.4;
    view.farM = 250.0;
    ring.postRequest(ig::Pose{}, 1.5, 7, {}, view);
    const sim::RenderRequest r = ring.latestRequest();
    EXPECT_EQ(r.view.hfov, 0.4);
    EXPECT_EQ(r.view.farM, 250.0);
    ring.postRequest(ig::Pose{}, 1.6, 8);
    EXPECT_EQ(ring.latestRequest().view.hfov, 0.0);
}

}  // namespace
