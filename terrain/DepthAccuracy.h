#pragma once
// Geometric accuracy of a terrain renderer against the full-resolution reference mesh (issue: "mean absolute depth
// difference converted to screen pixels"), plain C++ on two depth buffers of the same camera. Per pixel where both
// drew terrain: |Δz| / |∇z_ref|, the eye-depth difference divided by how much the reference's depth changes per
// pixel there, i.e. how many pixels the reference surface would have to slide on screen to explain the difference.
// Grazing surfaces (depth changing fast across pixels) forgive large depth errors; surfaces facing the viewer do not.
#include <cstdint>
#include <vector>

namespace seasonview {

struct DepthAccuracy {
    double meanErrorPx = 0;      // the figure the issue asks for
    double p95ErrorPx = 0;
    double meanAbsDepthM = 0;    // mean |Δz|, metres of eye depth
    std::int64_t pixels = 0;     // pixels where both drew terrain
    std::int64_t onlyOne = 0;    // pixels where exactly one of them drew terrain (silhouettes, edges)
};

/// `reference`, `test`: reversed-Z depth buffers (0 = nothing drawn, else near / eye depth), rows top first.
DepthAccuracy compareDepth(const std::vector<float>& reference, const std::vector<float>& test, int width, int height,
                           double near);

} // namespace seasonview
