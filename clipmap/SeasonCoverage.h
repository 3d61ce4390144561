#pragma once
// Which season has data at a pixel of the working grid, from the prepared pyramids' level 0 (alpha is coverage): the
// viewer's HUD line under the cursor.
#include "ImagePyramid.h"
#include "PixelProbe.h"
#include "Result.h"

#include <glm/vec2.hpp>

#include <optional>
#include <vector>

namespace seasonview {

struct SeasonCoverage {
    bool leafon = false, leafoff = false;
    /// "both seasons", "leaf-on only", "leaf-off only", "no data".
    const char* describe() const;
};

class SeasonCoverageProbe {
public:
    /// Opens level 0 of both pyramids (leaf-on, leaf-off, as preparePyramids returns them), or the first level both
    /// have on disk when a season is streamed. Errors name the file.
    static Result<SeasonCoverageProbe> open(const std::vector<ImagePyramid>& pyramids);
    /// Coverage at grid pixel coordinates (top-left origin, any fraction: the pixel containing them); nothing
    /// outside the grid.
    std::optional<SeasonCoverage> at(glm::dvec2 pixel) const;

private:
    std::vector<PixelProbe> m_levels;
    int m_level = 0; // the pyramid level probed
};

} // namespace seasonview
