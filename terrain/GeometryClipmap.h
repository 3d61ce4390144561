#pragma once
// Where the geometry-clipmap levels sit for a viewer (Asirvatham & Hoppe 2005, GPU Gems 2 ch. 2 §2.3-2.4), plain
// C++. Everything is in level-0 elevation sample coordinates (i east, j south; ElevationGrid): level l has cells of
// 2^l samples and n×n vertices. The coarsest level is snapped to its own double cells around the viewer; each finer
// level then takes one of the two positions inside the coarser level's hole that the L-shaped trim allows, the one
// nearer to centring it on the viewer. Finer levels whose extent is small against the viewer's height above the
// terrain are not drawn (§2.3: "when the viewer is high, the finest levels are disabled").
#include "GeometryClipmapLayout.h"

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <array>
#include <functional>
#include <vector>

namespace seasonview {

struct GeometryLevel {
    glm::ivec2 origin{0};            // sample coordinates of the level's vertex (0, 0); a multiple of 2^(l+1)
    TrimSide trimX = TrimSide::Low;  // where this level's interior trim lies (meaningless for the finest drawn)
    TrimSide trimY = TrimSide::Low;
    int cell = 1;                    // samples per cell, 2^l
};

struct GeometryPlacement {
    std::vector<GeometryLevel> levels; // all levels, finest first
    int finest = 0;                    // the finest level drawn: it is drawn whole (no hole)
};

/// Levels needed so the coarsest covers `extentSamples` (the grid's larger side) from any viewer inside it.
int geometryLevelCount(int n, int extentSamples);

/// The finest level worth drawing: the first whose cells, seen from `heightAboveTerrain` metres (the nearest any
/// terrain can be), span at least kMinCellPixels on screen. `pixelsPerRadian`: the viewport's height in pixels /
/// (2 tan(fovY / 2)). Finer levels would spend triangles below a pixel; the count of levels drawn then depends on
/// the view, not on the DEM's resolution (Asirvatham & Hoppe §2.3 disable them by viewer height alone).
inline constexpr double kMinCellPixels = 1.0;
int finestActiveLevel(int levels, double spacing, double heightAboveTerrain, double pixelsPerRadian);

/// Places all `levels` levels of n×n vertices around `viewer` (sample coordinates).
GeometryPlacement placeGeometryLevels(glm::dvec2 viewer, int n, int levels, int finest);

/// The pieces a level draws, in its own cells: ring blocks, fix-ups and the trim, or the whole grid for the finest
/// drawn level.
std::vector<GridRect> levelPieces(const RingLayout& ring, const GeometryPlacement& p, int level);

/// View-frustum culling: the four side planes of `viewProj` (an infinite reversed-Z projection has no useful
/// far plane). True when the box lies entirely outside one of them.
struct FrustumPlanes {
    std::array<glm::dvec4, 4> planes;
    static FrustumPlanes fromViewProj(const glm::dmat4& viewProj);
    bool outside(const glm::dvec3& lo, const glm::dvec3& hi) const;
};

/// Conservative height bounds over boxes of the elevation grid, for culling each piece against the frustum with its
/// own box (GPU Gems 2 ch. 2 §2.3.3 cull blocks by their bounding boxes) rather than the whole DEM's height range: a
/// lattice of tiles over the grid, each with the range of the heights inside it, and its max/min mip chain.
class HeightBounds {
public:
    /// `tileRange(lo, hi)`: the range of heights over the box [lo, hi] in level-0 sample coordinates (it may be
    /// wider, never narrower). Tiles of at least one sample, at most `tiles` per side.
    using TileRange = std::function<glm::vec2(glm::dvec2 lo, glm::dvec2 hi)>;
    static HeightBounds build(int width, int height, int tiles, const TileRange& tileRange);
    /// A flat grid: every box is [h, h].
    static HeightBounds flat(float h);
    /// Range over the box (sample coordinates; the part outside the grid takes its edge's heights, as the shader's
    /// clamped fetches do).
    glm::vec2 range(glm::dvec2 lo, glm::dvec2 hi) const;

private:
    struct Level {
        int w = 1, h = 1;
        std::vector<glm::vec2> r; // (min, max)
    };
    std::vector<Level> m_levels; // m_levels[0] = the tiles
    glm::dvec2 m_tileSize{1.0};  // samples per tile
    glm::dvec2 m_gridMax{0.0};   // last sample coordinate
};

} // namespace seasonview
