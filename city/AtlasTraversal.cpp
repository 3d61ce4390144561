#include "AtlasTraversal.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <map>

namespace seasonview::city {

const char* blockCategoryName(BlockCategory c) {
    switch (c) {
    case BlockCategory::Needed: return "needed";
    case BlockCategory::Culled: return "culled";
    case BlockCategory::ParentNeeded: return "parent needed";
    case BlockCategory::Unused: return "unused";
    }
    return "?";
}

bool BlockRequest::operator<(const BlockRequest& o) const {
    if (category != o.category) return category < o.category;
    if (distance != o.distance) return distance < o.distance;
    if (level != o.level) return level < o.level;
    return key < o.key;
}

namespace {

/// The side planes of the frustum (Gribb & Hartmann) and the eye plane, as (normal, offset) with inside >= 0.
std::array<glm::dvec4, 5> frustumPlanes(const glm::dmat4& m) {
    auto row = [&](int i) { return glm::dvec4(m[0][i], m[1][i], m[2][i], m[3][i]); };
    return {row(3) + row(0), row(3) - row(0), row(3) + row(1), row(3) - row(1), row(3)};
}

using Side = FrustumSide;

Side boxSide(const std::array<glm::dvec4, 5>& planes, glm::dvec3 lo, glm::dvec3 hi) {
    Side side = Side::Inside;
    for (const auto& p : planes) {
        const glm::dvec3 n(p);
        const glm::dvec3 pos(n.x >= 0 ? hi.x : lo.x, n.y >= 0 ? hi.y : lo.y, n.z >= 0 ? hi.z : lo.z);
        const glm::dvec3 neg(n.x >= 0 ? lo.x : hi.x, n.y >= 0 ? lo.y : hi.y, n.z >= 0 ? lo.z : hi.z);
        if (glm::dot(n, pos) + p.w < 0.0) return Side::Outside;
        if (glm::dot(n, neg) + p.w < 0.0) side = Side::Intersects;
    }
    return side;
}

} // namespace

FrustumSide frustumSide(const glm::dmat4& viewProj, const glm::dvec3& lo, const glm::dvec3& hi) {
    return boxSide(frustumPlanes(viewProj), lo, hi);
}

std::uint8_t AtlasTraversal::covered(std::uint32_t node) const {
    if (!m_covered) return 0;
    const AtlasNode& n = m_tree.nodes[node];
    return m_covered(glm::dvec3(n.boundsMin), glm::dvec3(n.boundsMax));
}

AtlasTraversal::AtlasTraversal(const AtlasTreeData& tree, const AtlasTreeInfo& info) : m_tree(tree), m_info(info) {}

double AtlasTraversal::minDistance(std::uint32_t node, const AtlasView& view) const {
    // minDistance ∝ f_proj ∝ w / tan(fov/2) (§4.5.2): the same texel covers more pixels on a wider screen.
    const double scale = (double(view.screenWidth) / double(m_info.screenWidth)) *
                         (std::tan(m_info.fovXDeg * M_PI / 360.0) / std::tan(view.fovXDeg * M_PI / 360.0));
    // A tree built for τ_b sized its texels to cover τ_b pixels at a node's minDistance: τ pixels per texel are
    // reached at minDistance · τ_b / τ.
    return double(m_tree.nodes[node].minDistance) * scale * std::max(m_info.tpp, 1e-6) / std::max(view.tpp, 1e-6);
}

double AtlasTraversal::distance(std::uint32_t node, const AtlasView& view) const {
    const AtlasNode& n = m_tree.nodes[node];
    const glm::dvec3 q = glm::clamp(view.eye, glm::dvec3(n.boundsMin), glm::dvec3(n.boundsMax));
    return glm::length(view.eye - q);
}

bool AtlasTraversal::visible(std::uint32_t node, const AtlasView& view) const {
    const AtlasNode& n = m_tree.nodes[node];
    return n.count > 0 && boxSide(frustumPlanes(view.viewProj), glm::dvec3(n.boundsMin), glm::dvec3(n.boundsMax)) != Side::Outside;
}

void AtlasTraversal::atlasRanges(std::uint32_t node, std::uint32_t atlasNode, const AtlasView& view,
                                 std::vector<AtlasDraw>& out, int level) const {
    const AtlasNode& n = m_tree.nodes[node];
    if (n.count == 0) return;
    const Side side = boxSide(frustumPlanes(view.viewProj), glm::dvec3(n.boundsMin), glm::dvec3(n.boundsMax));
    if (side == Side::Outside) return;
    const std::uint8_t cov = covered(node);
    if (cov == 2) return;
    if ((side == Side::Inside && cov == 0) || n.leaf()) {
        // Contiguous with the previous range (§4.8.1 order): one draw call for both.
        if (!out.empty() && !out.back().original && out.back().level == level &&
            out.back().first + out.back().count == n.first && out.back().node == atlasNode)
            out.back().count += n.count;
        else
            out.push_back(AtlasDraw{false, atlasNode, 0, level, n.first, n.count});
        return;
    }
    for (int c : n.children) atlasRanges(std::uint32_t(c), atlasNode, view, out, level);
}

void AtlasTraversal::originalRanges(std::uint32_t leaf, std::vector<AtlasDraw>& out) const {
    const AtlasNode& n = m_tree.nodes[leaf];
    for (std::uint32_t t = n.first; t < n.first + n.count;) {
        const std::uint32_t tex = m_tree.triangleTexture[t];
        std::uint32_t e = t + 1;
        while (e < n.first + n.count && m_tree.triangleTexture[e] == tex) ++e;
        out.push_back(AtlasDraw{true, leaf, tex, n.level, t, e - t});
        t = e;
    }
}

void AtlasTraversal::walk(std::uint32_t start, std::uint32_t fallback, const AtlasView& view,
                          const std::function<bool(std::uint32_t)>& atlasResident,
                          const std::function<bool(std::uint32_t)>& textureResident, const VisibilityFn& visibility,
                          bool startVisible, AtlasTraversalResult& r) const {
    auto known = [&](std::uint32_t n) { return !visibility || visibility(n) == NodeVisibility::Visible; };
    std::vector<std::pair<std::uint32_t, std::uint32_t>> stack{{start, fallback}}; // node, the atlas to fall back on
    while (!stack.empty()) {
        const auto [ni, fb] = stack.back();
        stack.pop_back();
        if (!visible(ni, view) || covered(ni) == 2) continue;
        if (!(startVisible && ni == start) && !known(ni)) {
            r.deferred.push_back(ni);
            continue;
        }
        const AtlasNode& n = m_tree.nodes[ni];
        const bool own = atlasResident(ni);
        const std::uint32_t atlas = own ? ni : fb;
        bool useAtlas = distance(ni, view) >= minDistance(ni, view);
        if (!useAtlas) {
            // §4.6, Fig. 30: refine only when the finer textures are all resident (of the children: those in view and
            // known visible; a deferred child found visible later falls back on this node's atlas).
            bool possible = true;
            if (n.leaf()) {
                for (auto t : n.textures) possible = possible && textureResident(t);
            } else {
                for (int c : n.children) {
                    const auto ci = std::uint32_t(c);
                    if (m_tree.nodes[ci].count > 0 && visible(ci, view) && known(ci) && covered(ci) != 2)
                        possible = possible && atlasResident(ci);
                }
            }
            if (!possible) {
                useAtlas = true;
                ++r.coarserThanWanted;
            }
        } else if (!own) {
            ++r.coarserThanWanted;
        }
        if (useAtlas) {
            atlasRanges(ni, atlas, view, r.draws, m_tree.nodes[atlas].level);
            ++r.atlasNodes;
            r.drawn.push_back(ni);
        } else if (n.leaf()) {
            originalRanges(ni, r.draws);
            ++r.originalLeaves;
            r.drawn.push_back(ni);
        } else {
            r.opened.push_back(ni);
            for (int q = 3; q >= 0; --q) stack.push_back({std::uint32_t(n.children[std::size_t(q)]), atlas});
        }
    }
}

AtlasTraversalResult AtlasTraversal::draws(const AtlasView& view, const std::function<bool(std::uint32_t)>& atlasResident,
                                           const std::function<bool(std::uint32_t)>& textureResident,
                                           const VisibilityFn& visibility) const {
    AtlasTraversalResult r;
    if (!m_tree.nodes.empty()) walk(0, 0, view, atlasResident, textureResident, visibility, false, r);
    return r;
}

AtlasTraversalResult AtlasTraversal::drawsBelow(std::uint32_t node, const AtlasView& view,
                                                const std::function<bool(std::uint32_t)>& atlasResident,
                                                const std::function<bool(std::uint32_t)>& textureResident,
                                                const VisibilityFn& visibility) const {
    assert(node < m_tree.nodes.size() && "AtlasTraversal::drawsBelow(): no such node");
    AtlasTraversalResult r;
    if (node >= m_tree.nodes.size()) return r;
    // The deepest resident ancestor (the root's atlas always is).
    std::uint32_t fallback = 0;
    for (std::int32_t a = m_tree.nodes[node].parent; a >= 0; a = m_tree.nodes[std::size_t(a)].parent)
        if (atlasResident(std::uint32_t(a))) {
            fallback = std::uint32_t(a);
            break;
        }
    walk(node, fallback, view, atlasResident, textureResident, visibility, true, r);
    return r;
}

std::vector<BlockRequest> AtlasTraversal::requests(const AtlasView& view, const VisibilityFn& visibility) const {
    auto hidden = [&](std::uint32_t n) { return visibility && visibility(n) == NodeVisibility::Hidden; };
    std::map<BlockKey, BlockRequest> blocks;
    auto mark = [&](BlockKey key, BlockCategory c, double d, int level) {
        auto [it, fresh] = blocks.try_emplace(key, BlockRequest{key, c, d, level});
        if (fresh) return;
        BlockRequest& b = it->second;
        if (c < b.category) b.category = c;
        b.distance = std::min(b.distance, d);
        b.level = std::min(b.level, level);
    };
    auto markAtlas = [&](std::uint32_t node, BlockCategory c) {
        const AtlasNode& n = m_tree.nodes[node];
        if (n.atlasBytes == 0) return; // empty: nothing to load
        mark({BlockKey::Kind::Atlas, node}, c, distance(node, view), n.level);
    };
    if (m_tree.nodes.empty()) return {};
    // The root is always needed (the fallback for everything).
    markAtlas(0, BlockCategory::Needed);
    std::vector<std::uint32_t> stack{0};
    while (!stack.empty()) {
        const std::uint32_t ni = stack.back();
        stack.pop_back();
        const AtlasNode& n = m_tree.nodes[ni];
        if (!visible(ni, view) || (ni == 0 && hidden(ni)) || covered(ni) == 2) continue;
        markAtlas(ni, BlockCategory::Needed); // used or refined: on the path to what is used
        const double d = distance(ni, view);
        const bool useAtlas = d >= minDistance(ni, view);
        if (n.leaf()) {
            const BlockCategory c = useAtlas ? BlockCategory::ParentNeeded : BlockCategory::Needed;
            for (auto t : n.textures) mark({BlockKey::Kind::Texture, t}, c, d, n.level + 1);
            continue;
        }
        for (int q = 0; q < 4; ++q) {
            const auto c = std::uint32_t(n.children[std::size_t(q)]);
            if (m_tree.nodes[c].count == 0 || covered(c) == 2) continue;
            if (useAtlas) markAtlas(c, BlockCategory::ParentNeeded); // the next refinement
            else if (!visible(c, view) || hidden(c)) markAtlas(c, BlockCategory::Culled); // a sibling is needed
            else stack.push_back(c);
        }
    }
    std::vector<BlockRequest> out;
    out.reserve(blocks.size());
    for (auto& [k, b] : blocks) out.push_back(b);
    std::sort(out.begin(), out.end());
    return out;
}

} // namespace seasonview::city
