// Sculpting a voxel model from three photographs (Cohen-Or et al. sec. 5): a solid box carved by
// the rays through the background pixels of a side, a front and a top view, then the remaining
// voxels photomapped from the views.
#pragma once

#include "ig/sticks.hpp"
#include "ig/terrain.hpp"

#include <optional>
#include <string>
#include <vector>

namespace ig {

// One orthographic view: its pixels (rows top first) and which of them show the object.
// The views and the model's axes (x right, y forward, z up), one pixel per voxel:
//   side:  seen from the right (+x) looking toward -x: column -> y (forward to the right),
//          row -> z (top row highest); size sizeY x sizeZ.
//   front: seen from the front (+y) looking toward -y: column -> x decreasing (the object's
//          right on the viewer's left), row -> z; size sizeX x sizeZ.
//   top:   seen from above looking down, forward at the top: column -> x, row -> y decreasing;
//          size sizeX x sizeY.
struct SculptView {
    int width = 0, height = 0;
    std::vector<Rgb8> pixels;
    std::vector<std::uint8_t> foreground;  // 1: the object, 0: background
};

struct SculptViews {
    SculptView side, front, top;
};

// How a photograph's background is told from the object.
struct BackgroundKey {
    std::optional<Rgb8> color;  // unset: the image's top-left pixel
    int tolerance = 24;         // a pixel within this of the colour on every channel is background
};

// A view from an RGB (or grey) PNG, background keyed by colour, or by a mask PNG when `maskPath`
// is given (grey, 0 background, anything else the object). InputError names the file.
SculptView loadSculptView(const std::string& imagePath, const std::string& maskPath,
                          const BackgroundKey& key);

// Carves and photomaps. The voxels that stay are those every view sees as foreground (the
// visual hull of the three silhouettes). Each remaining voxel takes the colour of the first view
// that sees it unobstructed, top, then side, then front; the palette holds the colours exactly
// when there are at most 255 of them, else a 6 x 7 x 6 colour cube. InputError (naming `name`)
// when the views' sizes disagree or exceed 256 voxels, or nothing is left.
ObjectModel sculptModel(const SculptViews& views, const std::string& name);

// The colour a view sees of a model along its axis, per pixel (the first voxel on the pixel's
// ray), and whether it sees one: the views rendered back from a model.
SculptView renderSculptView(const ObjectModel& model, int which /* 0 side, 1 front, 2 top */);

// Reads an 8-bit PNG as RGB (grey and palette expanded, alpha dropped); InputError names it.
std::vector<Rgb8> readRgbPng(const std::string& path, int& width, int& height);

}  // namespace ig
