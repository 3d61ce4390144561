#pragma once
// Which atlases and original textures a view needs, and what to draw with what is resident (thesis §4.4, Fig. 26,
// with the memory-management changes of §4.6, Fig. 30), plain C++ over an AtlasTreeData.
//
// Drawing: a node is drawn with its atlas when the camera is at least its (runtime-scaled) minDistance from its
// bounding box, or when refinement is impossible (children's atlases, or a leaf's original textures, not resident):
// so a coarser atlas stands in while finer data loads, never a missing texture (the root atlas is always resident).
// A node drawn with an atlas becomes a few contiguous triangle ranges (§4.8.1): its whole range when its box is
// inside the frustum, else its visible children's. Leaves closer than dmin are drawn with their original textures,
// one range per run of triangles sharing a texture.
//
// Paging (§4.6): every node's atlas and every original texture is a block with a category — Needed (used by the
// view with everything resident, and every ancestor of such a node), Culled (outside the frustum with a Needed
// sibling), ParentNeeded (the parent is Needed: the next refinement; a leaf's originals when its atlas is Needed),
// Unused — and a priority: category, then distance, then level.
//
// Occlusion (optional; beyond the paper, which names its absence as why street-level views drew the most nodes): the
// caller says which nodes it knows to be visible (hardware occlusion queries, Coherent Hierarchical Culling: Bittner
// et al. 2004, Wimmer & Bittner 2005, GPU Gems 2 ch. 6, cited by the thesis §3 for ground-level navigation). The
// traversal descends only into nodes known visible and lists the others in the frustum (`deferred`) for the caller to
// test against the depth of what it drew, then draw with drawsBelow() the ones that turn out visible. Paging treats
// nodes known hidden like nodes outside the frustum (Culled).
#include "AtlasTree.h"

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include <cstdint>
#include <functional>
#include <vector>

namespace seasonview::city {

/// Where a box lies against a view-projection's frustum (its side planes and the eye plane; the far plane is not used).
enum class FrustumSide : std::uint8_t { Outside, Intersects, Inside };
FrustumSide frustumSide(const glm::dmat4& viewProj, const glm::dvec3& lo, const glm::dvec3& hi);

/// How much of a box (local metres) is drawn by something else (BlockMaps far away, BlockMapTraversal::coverage):
/// 0 none, 1 part of it, 2 all of it.
using CoveredFn = std::function<std::uint8_t(const glm::dvec3& lo, const glm::dvec3& hi)>;

/// The view the traversal serves.
struct AtlasView {
    glm::dvec3 eye{0.0};       // metres, the tree's frame
    glm::dmat4 viewProj{1.0};  // frustum (reversed-Z infinite projections are fine: the far plane is not used)
    int screenWidth = 1920;    // pixels
    double fovXDeg = 90.0;     // horizontal field of view
    double tpp = 1.0;          // pixels per texel allowed at runtime (§4.5.2: minDistances divided by it)
};

/// What the caller knows of a node's visibility (CityRendererGL: the last occlusion query's answer, if recent). The
/// traversal may ask more than once per node, also of children it does not traverse (refinement checks): a pure
/// function of the node.
enum class NodeVisibility : std::uint8_t { Visible, Hidden, Unknown };
using VisibilityFn = std::function<NodeVisibility(std::uint32_t)>;

enum class BlockCategory : std::uint8_t { Needed = 0, Culled = 1, ParentNeeded = 2, Unused = 3 };
const char* blockCategoryName(BlockCategory c);

/// A block: a node's atlas (kind Atlas, index = node), an original texture (kind Texture, index = texture) or a
/// BlockMap (kind BlockMap, index = its node in the BlockMap quadtree, BlockMapTraversal.h); an
/// original texture over twice an atlas's bytes is paged as several blocks of rows (`part`, thesis §4.6; the
/// traversal asks for part 0, the pager for all of them).
struct BlockKey {
    enum class Kind : std::uint8_t { Atlas, Texture, BlockMap } kind = Kind::Atlas; // BlockMap: index = the map's node
    std::uint32_t index = 0;
    std::uint16_t part = 0;
    bool operator==(const BlockKey& o) const { return kind == o.kind && index == o.index && part == o.part; }
    bool operator<(const BlockKey& o) const {
        return kind != o.kind ? kind < o.kind : index != o.index ? index < o.index : part < o.part;
    }
};

struct BlockRequest {
    BlockKey key;
    BlockCategory category = BlockCategory::Unused;
    double distance = 0.0;
    int level = 0;
    /// Priority order: category, then distance, then level (the parent of a needed node first, §4.6).
    bool operator<(const BlockRequest& o) const;
};

/// One draw: a triangle range with a node's atlas (sampled at fract(root · 2^level)) or an original texture.
struct AtlasDraw {
    bool original = false;
    std::uint32_t node = 0;    // the atlas's node (original: the leaf)
    std::uint32_t texture = 0; // original only
    int level = 0;
    std::uint32_t first = 0, count = 0; // triangles
};

struct AtlasTraversalResult {
    std::vector<AtlasDraw> draws;
    std::size_t atlasNodes = 0;      // nodes drawn with an atlas (their own, or a resident ancestor's)
    std::size_t originalLeaves = 0;  // leaves drawn with their originals
    std::size_t coarserThanWanted = 0; // nodes drawn with an atlas because finer data was not resident
    std::vector<std::uint32_t> drawn;    // the nodes drawn (with an atlas or their originals), in traversal order
    std::vector<std::uint32_t> opened;   // inner nodes refined into their children
    std::vector<std::uint32_t> deferred; // with a VisibilityFn: nodes in the frustum not known visible, not drawn
};

class AtlasTraversal {
public:
    AtlasTraversal(const AtlasTreeData& tree, const AtlasTreeInfo& info);

    /// minDistance of a node for this view: the build's value scaled to the view's screen width and field of view
    /// and divided by its τ (§4.5.2).
    double minDistance(std::uint32_t node, const AtlasView& view) const;
    /// Distance from the eye to the node's box (0 inside) and whether the box is in the frustum.
    double distance(std::uint32_t node, const AtlasView& view) const;
    bool visible(std::uint32_t node, const AtlasView& view) const;

    /// What to draw given what is resident (`atlasResident(node)`, `textureResident(texture)`); the root's atlas
    /// must be resident. With `visibility`, only nodes it calls Visible are drawn or refined (the rest: deferred);
    /// a node's refinement then waits only for its visible children's atlases.
    AtlasTraversalResult draws(const AtlasView& view, const std::function<bool(std::uint32_t)>& atlasResident,
                               const std::function<bool(std::uint32_t)>& textureResident,
                               const VisibilityFn& visibility = {}) const;
    /// The same for the subtree of `node` alone (a deferred node found visible: `node` itself is taken as visible). A node whose atlas is not resident
    /// is drawn with its deepest resident ancestor's (any ancestor's atlas holds its triangles at a coarser
    /// level, §4.5.4), counted as coarser than wanted: never a missing texture.
    AtlasTraversalResult drawsBelow(std::uint32_t node, const AtlasView& view,
                                    const std::function<bool(std::uint32_t)>& atlasResident,
                                    const std::function<bool(std::uint32_t)>& textureResident,
                                    const VisibilityFn& visibility = {}) const;

    /// Every block's category and priority for the view (the traversal as if everything were resident), in
    /// priority order, Unused blocks left out. Nodes `visibility` calls Hidden are Culled and not descended into
    /// (Unknown ones are treated as visible; a hidden root leaves only the root's atlas Needed).
    std::vector<BlockRequest> requests(const AtlasView& view, const VisibilityFn& visibility = {}) const;

    const AtlasTreeData& tree() const { return m_tree; }

    /// What else draws (BlockMaps): draws() and drawsBelow() skip nodes it covers entirely and draw a node whole only
    /// where it covers none of it (else its children's ranges); requests() does not ask for the atlases of nodes it
    /// covers entirely (the root's always). Empty: nothing else draws.
    void setCovered(CoveredFn covered) { m_covered = std::move(covered); }

private:
    std::uint8_t covered(std::uint32_t node) const;
    /// The visible triangle ranges of `node`'s subtree, drawn with `atlasNode`'s atlas.
    void atlasRanges(std::uint32_t node, std::uint32_t atlasNode, const AtlasView& view, std::vector<AtlasDraw>& out,
                     int level) const;
    void originalRanges(std::uint32_t leaf, std::vector<AtlasDraw>& out) const;
    /// The traversal from `start`, drawing with `fallback`'s atlas (a resident ancestor) where a node's own is not
    /// resident; `startVisible`: `start` is drawn or opened whatever `visibility` says (drawsBelow).
    void walk(std::uint32_t start, std::uint32_t fallback, const AtlasView& view,
              const std::function<bool(std::uint32_t)>& atlasResident,
              const std::function<bool(std::uint32_t)>& textureResident, const VisibilityFn& visibility,
              bool startVisible, AtlasTraversalResult& r) const;

    const AtlasTreeData& m_tree;
    AtlasTreeInfo m_info;
    CoveredFn m_covered;
};

} // namespace seasonview::city
