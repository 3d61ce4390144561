#pragma once
// Crown centres and radii from a treetop mask: maxima of the mask's Euclidean distance transform (OpenCV), found
// band by band. The transform is clamped at a largest crown radius, which bounds the rows a band needs around it,
// so a band's crowns are exactly those of the same rows of the whole mask.
#include "Raster.h"

#include <cstdint>
#include <vector>

namespace seasonview {

/// A detected crown in image pixels: centre (col + 0.5, row + 0.5 of its pixel; (0,0) is the image's top-left
/// corner) and radius (distance from the centre to the mask's edge).
struct CrownDetection {
    double px = 0.0, py = 0.0, radiusPx = 0.0;
};

struct CrownParams {
    double minRadiusPx = 2.0;     // smaller maxima are not crowns (specks, thin strips)
    int maxRadiusPx = 40;         // the distance transform is clamped here (larger crowns report this radius)
    double separation = 0.75;     // a maximum must be the largest value within separation × its own distance
};

/// Parameters for imagery of `gsd` metres per pixel: crowns of 1 to 15 m radius.
CrownParams crownParamsForGsd(double gsd);

/// Mask rows each output row's crowns depend on, above and below.
int crownHalo(const CrownParams& params);

/// Crowns whose centre lies in image rows [outRow0, outRow0 + outRows), appended to `out` in raster order. `mask`
/// holds image rows [row0, row0 + rows) (width bytes each, non-zero = treetop) of a mask `imageHeight` rows high,
/// covering every row within crownHalo(params) of the output rows (outside the image counts as treetop, so crowns
/// cut by the image edge keep their centre inside the image).
void detectCrownRows(const std::uint8_t* mask, int width, int imageHeight, int row0, int rows, int outRow0,
                     int outRows, const CrownParams& params, std::vector<CrownDetection>& out);

/// All crowns of a whole mask (1 channel), in raster order.
std::vector<CrownDetection> detectCrowns(const Image<std::uint8_t>& mask, const CrownParams& params);

} // namespace seasonview
