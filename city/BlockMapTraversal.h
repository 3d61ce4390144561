#pragma once
// Which of a city's BlockMaps a view draws, and where the polygons (the atlas tree) are drawn instead (Cignoni et al.
// 2007 §4: "a quadtree hierarchy of finer and finer BlockMap representations", the near field drawn with polygons),
// plain C++ over a BlockMapQuadtree.
//
// The cut: from the root, a node in the frustum whose texels project to at most `maxErrorPx` pixels (its texel's
// side over its distance from the eye, times the focal length in pixels) is drawn with its BlockMap; a coarser one
// is refined into its children (a square without a map has no triangles: nothing to draw there); a leaf still too
// coarse is left to the polygons. A node the cut wants whose map is not resident is left to the polygons too (never a
// missing block: the atlas tree's root atlas is always resident), unless maps stand in for it: its children's (the
// eye moving away: they were drawn before) or, for a node that wants its children's, its own one level coarser (the
// eye coming nearer), as the atlas traversal draws a coarser atlas while finer ones load. The atlas tree then draws
// only what no BlockMap covers (coverage()).
//
// Paging, with the atlas tree's categories (Buchholz's thesis §4.6): the cut's maps are Needed, the children of those
// near refinement (the next refinement as the eye comes nearer, kPrefetchErrorRatio) ParentNeeded, a refined node's
// children outside the frustum Culled.
#include "AtlasTraversal.h"
#include "BlockMap.h"

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

namespace seasonview::city {

enum class BlockMapUse : std::uint8_t {
    Unvisited, // below a node drawn, or outside the frustum above it
    Outside,   // outside the frustum: nothing of it is seen
    BlockMap,  // drawn with its BlockMap
    Polygons,  // left to the polygons: too near for its finest map, or its map not resident
    Refined,   // its children decide
};

struct BlockMapCut {
    std::vector<BlockMapUse> use;    // per node
    std::vector<std::uint32_t> drawn; // the nodes drawn with their BlockMaps, nearest first
    std::size_t polygonNodes = 0;     // nodes left to the polygons
    std::size_t notResident = 0;      // of those, because the map was not resident
    std::size_t standIns = 0;         // maps loading whose children's maps, or parent's (one level coarser), stand in
};

/// How much of a box the BlockMaps drawn cover (the atlas tree skips what they cover entirely).
enum class Coverage : std::uint8_t { None, Partial, Full };

/// Triangles outside the atlas tree (the plain roofs and walls, drawn in ranges) in an order where each BlockMap
/// node's are one range: each triangle belongs to the smallest node whose square holds its footprint box (a triangle
/// across two squares to their common ancestor), the nodes in pre-order, so a node's subtree is contiguous. Triangles
/// outside the root square come last, drawn always.
struct BlockMapTriangleOrder {
    std::vector<std::uint32_t> order;       // position -> the triangle's index
    std::vector<std::uint32_t> first;       // per node: its own triangles [first, ownEnd), its subtree's [first, end)
    std::vector<std::uint32_t> ownEnd, end;
    std::vector<std::array<std::int32_t, 4>> children; // the quadtree's
    std::uint32_t outsideFirst = 0;         // [outsideFirst, order.size()): outside the root square

    /// `boxes[i]`: triangle i's footprint (x, y of its lowest and highest corner).
    static BlockMapTriangleOrder of(const BlockMapQuadtree& tree, const std::vector<std::pair<glm::dvec2, glm::dvec2>>& boxes);
    /// The ranges (first, count) of what the polygons draw for `cut`: the subtrees of nodes left to the polygons, the
    /// own triangles of refined nodes with some square under them not covered by maps, the triangles outside;
    /// contiguous ones merged.
    std::vector<std::pair<std::uint32_t, std::uint32_t>> ranges(const BlockMapCut& cut) const;
};

/// A drawn map's children are asked for ahead (ParentNeeded) only while its error is above this fraction of the
/// bound: within a factor 1.25 of the distance at which it is refined. Every drawn map's four children would be four
/// times the cut's maps (each 0.25–0.5 MB on the GPU), filling the capacity with blocks evicted again as the view
/// moves on before most are drawn; a refinement whose children are not in yet draws the map itself (cut()).
constexpr double kPrefetchErrorRatio = 0.8;

class BlockMapTraversal {
public:
    /// Both kept by reference.
    BlockMapTraversal(const BlockMapQuadtree& tree, const std::vector<BlockMapRecord>& records);

    /// Pixels one of node `k`'s texels covers at its box's nearest point (infinite with the eye in the box).
    double errorPx(std::uint32_t k, const AtlasView& view) const;
    double distance(std::uint32_t k, const AtlasView& view) const;
    /// The cut for the view; `resident(k)`: whether node k's map can be drawn (empty: all of them). With `previous`,
    /// every node in the frustum that `previous` drew with its map, refined or left to the polygons keeps that choice
    /// (the others are decided by their error): the picture the last frame's switches give at this camera, which,
    /// against this frame's, is what the viewer sees pop.
    BlockMapCut cut(const AtlasView& view, double maxErrorPx, const std::function<bool(std::uint32_t)>& resident = {},
                    const BlockMapCut* previous = nullptr) const;
    /// The maps' requests for the view (the cut with every map resident: `ideal` when the caller has it), in priority
    /// order.
    std::vector<BlockRequest> requests(const AtlasView& view, double maxErrorPx, const BlockMapCut* ideal = nullptr) const;
    /// How much of the box [lo, hi] (local metres; x and y count) the cut's BlockMaps cover. Squares outside the
    /// frustum or without a map count for neither (nothing is drawn there); anything outside the root square is
    /// uncovered.
    Coverage coverage(const BlockMapCut& cut, const glm::dvec3& lo, const glm::dvec3& hi) const;

    glm::dvec3 boxMin(std::uint32_t k) const;
    glm::dvec3 boxMax(std::uint32_t k) const;
    const BlockMapQuadtree& tree() const { return m_tree; }

private:
    const BlockMapQuadtree& m_tree;
    const std::vector<BlockMapRecord>& m_records;
};

} // namespace seasonview::city
