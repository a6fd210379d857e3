// A tiny line plot rendered to an RGB image with a built-in 3x5 bitmap font (for tool output).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace sim {

struct PlotSeries {
    std::string label;
    std::vector<double> x, y;  // non-finite points are skipped
};

struct PlotOptions {
    int width = 800, height = 500;
    std::string title, xLabel, yLabel;
};

// Renders the series (lines with point marks, distinct colours, a legend) into interleaved
// RGB8 pixels, rows top first: width * height * 3 bytes.
std::vector<std::uint8_t> renderPlot(const std::vector<PlotSeries>& series,
                                     const PlotOptions& options);

}  // namespace sim
