// Stereo pairs: the right eye reprojected from the left eye's colour and depth (Wan et al.,
// Adelson-Hodges), the gaps ray cast in a second pass, and the pair's composite images.
#pragma once

#include "ig/caster.hpp"
#include "ig/frame.hpp"
#include "ig/inset.hpp"
#include "ig/terrain.hpp"

#include <cstdint>
#include <string_view>
#include <vector>

namespace ig {

// How the right eye is made: reprojected from the left, or fully ray cast (the reference).
enum class RightEyeMethod { Reproject, Raycast };
// Visibility rule of the reprojection: Wan's right-to-left pass keeping the left-most
// reprojection, or Adelson-Hodges' left-to-right overwrite with gap clearing.
enum class ReprojectVariant { Wan, AdelsonHodges };

std::string_view rightEyeMethodName(RightEyeMethod method);
// Parses "reproject" | "raycast"; throws InputError otherwise.
RightEyeMethod parseRightEyeMethod(std::string_view name);

struct StereoOptions {
    double eyeSeparation = 0.065;  // metres; the right eye is this far along the camera's right
    RightEyeMethod method = RightEyeMethod::Reproject;
    ReprojectVariant variant = ReprojectVariant::Wan;
    bool abuffer = true;        // 1x8 sub-pixel coverage; false: integer placement
    double gapThreshold = 2.0;  // pixels; wider gaps between reprojections are ray cast (Wan only)
    // Rows by the first implementation: Wan's by one sweep over each row's regions with a
    // running pixel instead of four pixels at a time, Adelson-Hodges' through per-pixel sums
    // instead of straight to the row. The same image to the bit, slower; the twin the tests
    // compare against.
    bool referenceSweep = false;
    // The near clipping plane of both eyes, metres ahead along the view axis (0: none): the left
    // eye is rendered with it (renderFrame's nearM) and the right takes it from the left
    // (reprojectRightEye). renderStereo only.
    double nearM = 0.0;
};

// Throws InputError for a negative or non-finite separation or gap threshold.
void validateStereoOptions(const StereoOptions& options);

// Where a right-eye pixel's colour came from.
enum class RightPixelSource : std::uint8_t {
    Reprojected,   // a reprojected left pixel's footprint covers part of it
    Interpolated,  // only slots interpolated between reprojections up to the threshold apart
    RayCast,       // cast in the second pass (sky found without casting included)
};

struct StereoStats {
    double leftMs = 0.0;       // left eye by the fast caster
    double reprojectMs = 0.0;  // reprojection pass
    double castMs = 0.0;       // second pass over the marked pixels
    double objectsMs = 0.0;    // voxel objects' footprint pass over the right eye
    double rightMs = 0.0;      // reprojectMs + castMs + objectsMs, or the full cast
    // CPU time of the calling thread over the reprojection and second pass: all of the work
    // when RenderOptions::threads == 1, immune to other processes' load.
    double rightCpuMs = 0.0;
    std::uint64_t reprojected = 0, interpolated = 0, rayCast = 0;
    std::uint64_t skyWithoutCast = 0;  // marked pixels above a column's last hit, not cast
    std::uint64_t steps = 0;           // grid steps of the second pass
    std::uint64_t restarts = 0;        // second-pass rays marched from the map entry
    std::uint64_t wholeColumns = 0;    // columns cast whole by the caster in the second pass
};

struct StereoFrame {
    RenderedFrame left;
    RenderedFrame right;
    std::vector<RightPixelSource> source;  // per right pixel (empty for a fully cast right eye)
    StereoStats stats;
};

// The right eye's pose: `left` moved `eyeSeparation` metres along its camera right vector, same
// orientation (parallel, coplanar image planes).
Pose rightEyePose(const Pose& left, double eyeSeparation);

// CPU time consumed by the calling thread so far, milliseconds.
double threadCpuMs();

// Horizontal disparity of a left pixel (x, y) (integer indices) seen at Euclidean distance
// `depth`: the right image shows it at x + 0.5 - disparity on the same row. 0 for sky (+inf).
double stereoDisparity(const Intrinsics& intrinsics, int x, int y, double depth,
                       double eyeSeparation);

// Renders a stereo pair: the left eye by the fast caster (roll must be 0), the right eye as
// `options` say (reprojected, or fully cast by the fast caster). With renderOptions.objects,
// the reprojection takes the left eye's terrain alone and the objects' footprint pass draws
// the objects over each eye afterwards, as over a mono frame: both eyes carry object ids. Throws
// InputError for bad options, a rolled pose, or either eye on or below the terrain.
// `time`: the frames' simulation time (the sun's).
StereoFrame renderStereo(const TerrainMap& map, const Pose& pose, const Intrinsics& intrinsics,
                         const StereoOptions& options, const RenderOptions& renderOptions = {},
                         double time = 0.0);

// The same over a nested terrain (docs/design/insets.md): both eyes on the nested surface, the
// left by the nested fast caster.
StereoFrame renderStereo(const NestedTerrain& terrain, const Pose& pose,
                         const Intrinsics& intrinsics, const StereoOptions& options,
                         const RenderOptions& renderOptions = {}, double time = 0.0);
// The same over maps held elsewhere (a paged database's), as makeNestedCaster's overload:
// `renderOptions` the global map's, `insetOptions` one per inset.
StereoFrame renderStereo(const NestedMaps& maps, const std::vector<RenderOptions>& insetOptions,
                         const Pose& pose, const Intrinsics& intrinsics,
                         const StereoOptions& options, const RenderOptions& renderOptions,
                         double time = 0.0);

// The right eye reprojected from a rendered left frame (pose.roll == 0), gaps cast over `map`.
// Fills `source` (per right pixel) and the right-eye fields of `stats`. With `caster` (over
// `map`; the fast caster's units are columns), groups of columns at least a quarter to be cast
// (the strip at the right edge that only the right eye sees) are cast whole by it, and their
// marked pixels taken from that; the other marked pixels are cast one by one. The right eye
// takes the left's near plane (left.nearM, the same plane: the eyes are apart across the view
// axis): a pixel whose surface lies nearer is redrawn from beyond it, as the casters do.
RenderedFrame reprojectRightEye(const TerrainMap& map, const RenderedFrame& left,
                                const StereoOptions& options, const RenderOptions& renderOptions,
                                std::vector<RightPixelSource>& source, StereoStats& stats,
                                const Caster* caster = nullptr);

// The same over a nested terrain's maps: the left frame drawn on the nested surface, the marked
// pixels cast on it (each ray's nearest hit over the global map and every inset), each lit and
// hazed by its own map's passes: the global map's by `renderOptions`, inset k's by
// insetOptions[k] (insetPassOptions', made once). With `globalCaster` (the nested caster's
// global pass, nestedGlobalCaster()), groups of columns mostly marked are cast whole by it over
// the global map (its levels far away, as the left eye's), and their marked pixels' rays then
// over the insets.
RenderedFrame reprojectRightEye(const NestedMaps& maps,
                                const std::vector<RenderOptions>& insetOptions,
                                const RenderedFrame& left, const StereoOptions& options,
                                const RenderOptions& renderOptions,
                                std::vector<RightPixelSource>& source, StereoStats& stats,
                                const Caster* globalCaster = nullptr);

// Draws options.objects over both eyes of a pair that holds terrain alone (the right eye
// reprojected from the left's terrain) by the objects' footprint pass, as over a mono frame
// (ig/object_pass.hpp): each eye gets its object ids. With a near plane (frame.nearM), nothing
// of an object nearer than it is drawn: an object pixel nearer shows the voxels its ray enters
// beyond the plane over the eye's terrain, as the casters' near pass. Adds each eye's pass time to
// its stats.renderMs and returns the right eye's, milliseconds.
double drawStereoObjects(const RenderOptions& options, RenderedFrame& left, RenderedFrame& right);

// Composite images, RGB8 rows top first.
// Left and right side by side (2W x H).
std::vector<Rgb8> sideBySide(const RenderedFrame& left, const RenderedFrame& right);
// Red-cyan anaglyph: red from the left eye, green and blue from the right.
std::vector<Rgb8> anaglyph(const RenderedFrame& left, const RenderedFrame& right);
// The right eye dimmed to grey with its ray-cast pixels in pure red (Wan fig. 8c).
std::vector<Rgb8> rayCastMask(const RenderedFrame& right,
                              const std::vector<RightPixelSource>& source);

}  // namespace ig
