#pragma once
// Building a texture-atlas tree file from a city model (Buchholz's thesis §4.5): texture size estimation at dmin,
// critical triangles (dmin enlarged until at most 10 % are critical, the rest split), recursive area-balanced
// splitting until each node's textures pack into one atlas, leaf atlases resampled from the original textures
// (read on demand through a capped cache), inner atlases by 2×2 downsampling of their children with minDistance
// doubling, root-atlas texture coordinates, depth-first triangle order (§4.8.1), separate RGB and RGBA trees.
#include "AtlasTree.h"
#include "CityModel.h"
#include "Result.h"

#include <cstdint>
#include <functional>
#include <string>

namespace seasonview::city {

struct AtlasBuildSettings {
    int atlasSize = 512;          // A (power of two)
    double dmin = 0.0;            // metres; <= 0: automatic, D / 72 with D the model's bounding-box diagonal (§4.7.1)
    double tpp = 1.0;             // texels sized for τ pixels per texel (minDistances scale by 1/τ)
    int screenWidth = 1920;       // the screen the minDistances are computed for (rescaled at runtime)
    double fovXDeg = 90.0;        // horizontal field of view likewise
    double maxCriticalFraction = 0.10;
    int border = 8;               // b
    AtlasPacker packer = AtlasPacker::MaxRects;
    AtlasFormat format = AtlasFormat::Bc;
    std::uint64_t cacheBytes = 512ull << 20; // original textures held while building
    bool roofsFromImagery = true; // roofs go to the plain triangles (drawn with the terrain imagery, §4.8.2)
    int threads = 0;              // 0: all cores (texture decoding, resampling, BC encoding; the file does not
                                  // depend on it)
    /// Called with the fraction done (0..1) and a stage name.
    std::function<void(double, const char*)> progress;
};

struct AtlasBuildReport {
    std::size_t treeTriangles = 0;     // after splitting critical triangles
    std::size_t inputTreeTriangles = 0;
    std::size_t plainTriangles = 0;
    std::size_t criticalAtDmin = 0;    // critical at the initial dmin
    std::size_t criticalSplit = 0;     // critical after enlarging dmin, split into smaller ones
    double dminInitial = 0.0, dmin = 0.0;
    std::size_t nodes = 0, leaves = 0, emptyLeaves = 0;
    int depth = 0;
    double meanLeafFill = 0.0;         // mean fraction of a leaf atlas covered by texture areas
    std::uint64_t atlasBytes = 0;      // compressed atlases in the file
    std::uint64_t fileBytes = 0;
    std::uint64_t textureReads = 0;    // original textures decoded (more than the textures when the cache evicts)
    std::uint64_t peakCacheBytes = 0;
    std::size_t textures = 0;
};

/// Builds the tree of `model` into `outPath` (written under a temporary name, renamed when complete). Errors name
/// the file (an unreadable texture, an unwritable output).
Result<AtlasBuildReport> buildAtlasTree(const CityModel& model, const AtlasBuildSettings& settings,
                                        const std::string& outPath);

/// Splits a triangle at the midpoint of its edge that spans the most atlas texels (positions and texture
/// coordinates interpolated) — the thesis's treatment of critical triangles. `maxTexels`: the original's size.
std::array<TexturedTriangle, 2> splitTriangle(const TexturedTriangle& tri, double fproj,
                                              glm::dvec2 maxTexels = glm::dvec2(INFINITY));

} // namespace seasonview::city
