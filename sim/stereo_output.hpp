// Stereo through the PRP: the pair's renderer, each eye's pose at a field, one output stream.
#pragma once

#include "ig/caster.hpp"
#include "ig/frame.hpp"
#include "ig/stereo.hpp"
#include "prp/field.hpp"
#include "prp/warp_fit.hpp"
#include "sim/render_process.hpp"

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

namespace sim {

struct RenderGeometry;

// How the two eyes share one output stream: side by side (left eye on the left, 2W x H),
// top-bottom (left eye on top, W x 2H), or a red-cyan anaglyph preview (W x H: red from the
// left eye, green and blue from the right).
enum class StereoLayout { SideBySide, TopBottom, Anaglyph };
std::optional<StereoLayout> parseStereoLayout(std::string_view name);  // "sbs" | "tb" | "anaglyph"
std::string_view stereoLayoutName(StereoLayout layout);

struct StereoOutput {
    double separation = 0.065;  // metres between the eyes, centred on the head
    StereoLayout layout = StereoLayout::SideBySide;
};

// The output frame a layout makes of eyes of eyeWidth x eyeHeight, and back.
void stereoOutputSize(StereoLayout layout, int eyeWidth, int eyeHeight, int& width, int& height);
void stereoEyeSize(StereoLayout layout, int width, int height, int& eyeWidth, int& eyeHeight);

// The eyes of a head pose: each `separation / 2` from the head along the head's right vector,
// roll included (a rolled head tilts the baseline: roll is about the head, not each eye), with
// the head's orientation.
struct EyePoses {
    ig::Pose left, right;
};
EyePoses eyePoses(const ig::Pose& head, double separation);

// Renders stereo pairs for the pipeline: the left eye (at the head pose with roll 0, moved half
// the separation to the left) by the caster, the right eye reprojected from it (Wan; gaps cast
// by the same caster), carried as the frame's `right`. The map must outlive the renderer.
FrameRenderer makeStereoRenderer(const ig::TerrainMap& map, const RenderGeometry& geometry,
                                 double separation, const ig::RenderOptions& options = {});
// The same over a terrain with insets (ig/inset.hpp): the left eye by the nested fast caster,
// the right eye's gaps cast on the nested surface. The terrain must outlive the renderer.
FrameRenderer makeStereoRenderer(const ig::NestedTerrain& terrain, const RenderGeometry& geometry,
                                 double separation, const ig::RenderOptions& options = {});

// Largest difference, in output rows, between where the two eyes' warps show the same world
// point: the pair's control points (terrain ones) and the left frame's check points. A
// quadratic warp shows a point moved by its fit residual at its true position (one Newton step
// through the warp's Jacobian); the depth warp where it truly is (its error is sampling, not
// geometry). True rows agree exactly (parallel eyes sharing the head's orientation), so this is
// what the two independent fits add. -1 when no point is usable.
double verticalDisparity(const ig::RenderedFrame& left, const ig::RenderedFrame& right,
                         const prp::WarpInfo& leftWarp, const prp::WarpInfo& rightWarp,
                         const EyePoses& eyes, const prp::OutputGeometry& geometry);
// Rows the two eyes may disagree by before a field's quadratic eyes are warped by the depth
// model instead (stereo only; see docs/design/stereo.md).
inline constexpr double kMaxVerticalDisparityRows = 0.25;

// Puts the two eyes' fields of one field index into the layout's field (`out`, whose pixels are
// reused). Side by side and top-bottom copy the eyes' lines (eye fields in the output format);
// the anaglyph takes eye fields in RGB8 and converts the combined rows to `format`.
class StereoComposer {
  public:
    StereoComposer(StereoLayout layout, prp::PixelFormat format)
        : layout_(layout), format_(format) {}
    // The pixel format the eyes' processors write.
    prp::PixelFormat eyeFormat() const;
    void compose(const prp::Field& left, const prp::Field& right, prp::Field& out);

  private:
    StereoLayout layout_;
    prp::PixelFormat format_;
    std::vector<std::uint8_t> row_;
};

}  // namespace sim
