#pragma once
// A small line-chart rasteriser for benchmark reports (paper Fig. 8 style): stacked panels sharing the x axis,
// one coloured polyline per series, axis labels drawn with stb_easy_font. Plain C++, writes PNG via core.
#include "Result.h"

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace seasonview::app {

struct PlotSeries {
    std::string label;
    std::vector<double> y; // one value per x sample (NaN: not measured there; the measured ones are joined and dotted)
};

struct PlotPanel {
    std::string title;             // e.g. "frame time (ms)"
    std::vector<PlotSeries> series;
    double yMin = 0.0, yMax = -1.0; // yMax < yMin: automatic (0 .. max)
};

/// Renders the panels stacked vertically (x = sample index, labelled `xLabel`) into a width×height PNG.
Status writeLinePlot(const std::filesystem::path& out, const std::vector<PlotPanel>& panels, const std::string& xLabel,
                     int width = 1200, int height = 700);

} // namespace seasonview::app
