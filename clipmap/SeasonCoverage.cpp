#include "SeasonCoverage.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace seasonview {

const char* SeasonCoverage::describe() const {
    return leafon && leafoff ? "both seasons" : leafon ? "leaf-on only" : leafoff ? "leaf-off only" : "no data";
}

Result<SeasonCoverageProbe> SeasonCoverageProbe::open(const std::vector<ImagePyramid>& pyramids) {
    assert(pyramids.size() == 2 && "SeasonCoverageProbe::open(): the leaf-on and leaf-off pyramids");
    SeasonCoverageProbe p;
    // Streamed seasons (ImagePyramid::streamedLevels): the first level both have on disk.
    for (const ImagePyramid& pyr : pyramids) p.m_level = std::max(p.m_level, pyr.streamedLevels);
    for (const ImagePyramid& pyr : pyramids) {
        const PyramidLevel& level = pyr.levels.at(size_t(p.m_level));
        auto probe = PixelProbe::open(level.file);
        if (!probe) return probe.error();
        if (probe->bands() != 4) return fileError(level.file.string(), "is not an RGBA pyramid level");
        p.m_levels.push_back(std::move(*probe));
    }
    return p;
}

std::optional<SeasonCoverage> SeasonCoverageProbe::at(glm::dvec2 pixel) const {
    pixel = std::ldexp(1.0, -m_level) * pixel;
    const int x = int(std::floor(pixel.x)), y = int(std::floor(pixel.y));
    auto on = m_levels[0].at(x, y), off = m_levels[1].at(x, y);
    if (!on || !off) return std::nullopt;
    return SeasonCoverage{(*on)[3] >= 128, (*off)[3] >= 128};
}

} // namespace seasonview
