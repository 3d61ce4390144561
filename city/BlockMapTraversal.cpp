#include "BlockMapTraversal.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace seasonview::city {

BlockMapTraversal::BlockMapTraversal(const BlockMapQuadtree& tree, const std::vector<BlockMapRecord>& records)
    : m_tree(tree), m_records(records) {}

glm::dvec3 BlockMapTraversal::boxMin(std::uint32_t k) const {
    const BlockMapRecord& r = m_records[k];
    return {r.origin, r.zBase};
}

glm::dvec3 BlockMapTraversal::boxMax(std::uint32_t k) const {
    const BlockMapRecord& r = m_records[k];
    return {r.origin + r.side(), r.zTop};
}

double BlockMapTraversal::distance(std::uint32_t k, const AtlasView& view) const {
    const glm::dvec3 q = glm::clamp(view.eye, boxMin(k), boxMax(k));
    return glm::length(view.eye - q);
}

double BlockMapTraversal::errorPx(std::uint32_t k, const AtlasView& view) const {
    const double d = distance(k, view);
    if (!(d > 0.0)) return std::numeric_limits<double>::infinity();
    const double focalPx = double(view.screenWidth) / (2.0 * std::tan(view.fovXDeg * M_PI / 360.0));
    return m_records[k].texel * focalPx / d;
}

BlockMapCut BlockMapTraversal::cut(const AtlasView& view, double maxErrorPx,
                                   const std::function<bool(std::uint32_t)>& resident, const BlockMapCut* previous) const {
    BlockMapCut c;
    c.use.assign(m_tree.nodes.size(), BlockMapUse::Unvisited);
    if (m_tree.nodes.empty()) return c;
    const bool prev = previous && previous->use.size() == c.use.size();
    auto isResident = [&](std::uint32_t k) { return !resident || resident(k); };
    auto leafOf = [&](std::uint32_t k) {
        const auto& ch = m_tree.nodes[k].children;
        return std::none_of(ch.begin(), ch.end(), [](std::int32_t x) { return x >= 0; });
    };
    // Whether node k's square can be drawn with resident maps alone: its own, or its children's (recursively).
    std::function<bool(std::uint32_t)> mapsBelow = [&](std::uint32_t k) {
        if (isResident(k)) return true;
        if (leafOf(k)) return false;
        for (std::int32_t ch : m_tree.nodes[k].children)
            if (ch >= 0 && !mapsBelow(std::uint32_t(ch))) return false;
        return true;
    };
    std::vector<std::pair<double, std::uint32_t>> drawn;
    auto drawMap = [&](std::uint32_t k) {
        c.use[k] = BlockMapUse::BlockMap;
        drawn.emplace_back(distance(k, view), k);
    };
    auto toPolygons = [&](std::uint32_t k) {
        c.use[k] = BlockMapUse::Polygons;
        ++c.polygonNodes;
    };
    // `forced`: a parent's map is loading and its children's stand in for it, whatever their error.
    std::function<void(std::uint32_t, bool)> visit = [&](std::uint32_t k, bool forced) {
        if (frustumSide(view.viewProj, boxMin(k), boxMax(k)) == FrustumSide::Outside) {
            c.use[k] = BlockMapUse::Outside;
            return;
        }
        const BlockMapQuadtree::Node& n = m_tree.nodes[k];
        const bool leaf = leafOf(k);
        const double error = errorPx(k, view);
        bool useMap = forced || error <= maxErrorPx;
        // The previous cut's choice where it made one (a node refined there is refined here, and so on).
        const BlockMapUse before = prev ? previous->use[k] : BlockMapUse::Unvisited;
        if (!forced && before == BlockMapUse::BlockMap) useMap = true;
        else if (!forced && (before == BlockMapUse::Refined || (before == BlockMapUse::Polygons && leaf))) useMap = false;
        auto refine = [&](bool force) {
            c.use[k] = BlockMapUse::Refined;
            for (std::int32_t ch : n.children)
                if (ch >= 0) visit(std::uint32_t(ch), force);
        };
        if (useMap) {
            if (isResident(k)) {
                drawMap(k);
            } else if (!leaf && mapsBelow(k)) {
                ++c.standIns; // the eye moving away: the finer maps it had stand in
                refine(true);
            } else {
                toPolygons(k);
                ++c.notResident;
            }
            return;
        }
        if (leaf) {
            toPolygons(k);
            return;
        }
        // Too coarse: refined, unless a child that wants its map has none to draw while this one, one level coarser
        // than wanted, is resident (the eye coming nearer).
        if (resident && before == BlockMapUse::Unvisited && error <= 2.0 * maxErrorPx && isResident(k)) {
            bool missing = false;
            for (std::int32_t ch : n.children)
                if (ch >= 0 && errorPx(std::uint32_t(ch), view) <= maxErrorPx && !mapsBelow(std::uint32_t(ch)) &&
                    frustumSide(view.viewProj, boxMin(std::uint32_t(ch)), boxMax(std::uint32_t(ch))) != FrustumSide::Outside)
                    missing = true;
            if (missing) {
                ++c.standIns;
                drawMap(k);
                return;
            }
        }
        refine(false);
    };
    visit(0, false);
    std::sort(drawn.begin(), drawn.end());
    for (const auto& [d, k] : drawn) c.drawn.push_back(k);
    return c;
}

std::vector<BlockRequest> BlockMapTraversal::requests(const AtlasView& view, double maxErrorPx,
                                                     const BlockMapCut* ideal) const {
    const BlockMapCut own = ideal ? BlockMapCut{} : cut(view, maxErrorPx);
    const BlockMapCut& c = ideal ? *ideal : own;
    std::vector<BlockRequest> out;
    std::vector<std::int8_t> added(c.use.size(), -1); // the category a node was asked for (the first, the highest)
    auto add = [&](std::uint32_t k, BlockCategory cat) {
        if (added[k] >= 0 && added[k] <= std::int8_t(cat)) return;
        if (added[k] >= 0) // asked for in a lower category already: raise it
            for (BlockRequest& r : out)
                if (r.key.index == k) r.category = cat;
        if (added[k] < 0)
            out.push_back(BlockRequest{BlockKey{BlockKey::Kind::BlockMap, k, 0}, cat, distance(k, view), m_tree.nodes[k].level});
        added[k] = std::int8_t(cat);
    };
    for (std::uint32_t k = 0; k < c.use.size(); ++k) {
        const BlockMapQuadtree::Node& n = m_tree.nodes[k];
        switch (c.use[k]) {
        case BlockMapUse::BlockMap:
            add(k, BlockCategory::Needed);
            // The next refinement (the eye coming nearer), for a map within kPrefetchErrorRatio of refining.
            if (errorPx(k, view) > kPrefetchErrorRatio * maxErrorPx)
                for (std::int32_t ch : n.children)
                    if (ch >= 0) add(std::uint32_t(ch), BlockCategory::ParentNeeded);
            break;
        case BlockMapUse::Outside:
            // A sibling of something used: the eye may turn to it.
            if (n.parent >= 0 && c.use[std::size_t(n.parent)] == BlockMapUse::Refined) {
                bool used = false;
                for (std::int32_t s : m_tree.nodes[std::size_t(n.parent)].children)
                    used = used || (s >= 0 && (c.use[std::size_t(s)] == BlockMapUse::BlockMap ||
                                               c.use[std::size_t(s)] == BlockMapUse::Refined));
                if (used && errorPx(k, view) <= maxErrorPx) add(k, BlockCategory::Culled);
            }
            break;
        default: break;
        }
    }
    std::sort(out.begin(), out.end());
    return out;
}

Coverage BlockMapTraversal::coverage(const BlockMapCut& cut, const glm::dvec3& lo, const glm::dvec3& hi) const {
    if (m_tree.nodes.empty() || cut.use.size() != m_tree.nodes.size()) return Coverage::None;
    bool covered = false, uncovered = false;
    // Anything outside the root square is drawn by no BlockMap.
    const double eps = 1e-6 * std::max(1.0, m_tree.rootSide);
    const glm::dvec2 r0 = m_tree.origin, r1 = m_tree.origin + m_tree.rootSide;
    if (lo.x < r0.x - eps || lo.y < r0.y - eps || hi.x > r1.x + eps || hi.y > r1.y + eps) uncovered = true;
    std::vector<std::uint32_t> stack{0};
    while (!stack.empty() && !(covered && uncovered)) {
        const std::uint32_t k = stack.back();
        stack.pop_back();
        const BlockMapRecord& r = m_records[k];
        // Overlap with an area, not only a shared edge.
        if (!(lo.x < r.origin.x + r.side() - eps && hi.x > r.origin.x + eps && lo.y < r.origin.y + r.side() - eps &&
              hi.y > r.origin.y + eps))
            continue;
        switch (cut.use[k]) {
        case BlockMapUse::BlockMap: covered = true; break;
        case BlockMapUse::Polygons: uncovered = true; break;
        case BlockMapUse::Refined:
            for (std::int32_t ch : m_tree.nodes[k].children)
                if (ch >= 0) stack.push_back(std::uint32_t(ch));
            break;
        case BlockMapUse::Outside:
        case BlockMapUse::Unvisited: break;
        }
    }
    if (!uncovered) return Coverage::Full;
    return covered ? Coverage::Partial : Coverage::None;
}

BlockMapTriangleOrder BlockMapTriangleOrder::of(const BlockMapQuadtree& tree,
                                                const std::vector<std::pair<glm::dvec2, glm::dvec2>>& boxes) {
    BlockMapTriangleOrder o;
    const std::size_t nodes = tree.nodes.size();
    std::vector<std::vector<std::uint32_t>> at(nodes);
    std::vector<std::uint32_t> outside;
    for (std::size_t i = 0; i < boxes.size(); ++i) {
        const glm::dvec2 lo = (boxes[i].first - tree.origin) / std::max(tree.rootSide, 1e-12);
        const glm::dvec2 hi = (boxes[i].second - tree.origin) / std::max(tree.rootSide, 1e-12);
        if (nodes == 0 || lo.x < 0.0 || lo.y < 0.0 || hi.x > 1.0 || hi.y > 1.0) {
            outside.push_back(std::uint32_t(i));
            continue;
        }
        // Down while both corners fall in the same quadrant and it has a map (a quadrant without one holds no
        // triangle's box: the maps were built from the same boxes).
        std::int32_t k = 0;
        for (int level = 1; level <= tree.depth; ++level) {
            const double cells = std::ldexp(1.0, level);
            const glm::ivec2 a(int(std::floor(lo.x * cells)), int(std::floor(lo.y * cells)));
            const glm::ivec2 b(int(std::floor(hi.x * cells)), int(std::floor(hi.y * cells)));
            if (a != b) break;
            const std::int32_t child = tree.nodes[std::size_t(k)].children[std::size_t((a.x & 1) + 2 * (a.y & 1))];
            if (child < 0) break;
            k = child;
        }
        at[std::size_t(k)].push_back(std::uint32_t(i));
    }
    o.first.assign(nodes, 0);
    o.ownEnd.assign(nodes, 0);
    o.end.assign(nodes, 0);
    for (const auto& n : tree.nodes) o.children.push_back(n.children);
    o.order.reserve(boxes.size());
    // Pre-order: a node's own, then its children's subtrees.
    std::vector<std::pair<std::uint32_t, bool>> stack;
    if (nodes > 0) stack.push_back({0, false});
    while (!stack.empty()) {
        const auto [k, closing] = stack.back();
        stack.pop_back();
        if (closing) {
            o.end[k] = std::uint32_t(o.order.size());
            continue;
        }
        o.first[k] = std::uint32_t(o.order.size());
        o.order.insert(o.order.end(), at[k].begin(), at[k].end());
        o.ownEnd[k] = std::uint32_t(o.order.size());
        stack.push_back({k, true});
        const auto& ch = tree.nodes[k].children;
        for (int q = 3; q >= 0; --q)
            if (ch[std::size_t(q)] >= 0) stack.push_back({std::uint32_t(ch[std::size_t(q)]), false});
    }
    o.outsideFirst = std::uint32_t(o.order.size());
    o.order.insert(o.order.end(), outside.begin(), outside.end());
    return o;
}

std::vector<std::pair<std::uint32_t, std::uint32_t>> BlockMapTriangleOrder::ranges(const BlockMapCut& cut) const {
    std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
    auto add = [&](std::uint32_t a, std::uint32_t b) {
        if (b <= a) return;
        if (!out.empty() && out.back().first + out.back().second == a) out.back().second += b - a;
        else out.emplace_back(a, b - a);
    };
    const std::size_t nodes = first.size();
    if (nodes > 0 && cut.use.size() == nodes) {
        // Whether the maps drawn cover all of a node's square that is seen: drawn with its map, or refined into
        // children all covered (children come after their parent). A refined node's own triangles (across its
        // children's squares) are in its children's maps, which are built from every triangle over their square:
        // where the children all show maps, those triangles are drawn already.
        std::vector<char> covered(nodes, 0);
        for (std::size_t k = nodes; k-- > 0;) {
            switch (cut.use[k]) {
            case BlockMapUse::BlockMap:
            case BlockMapUse::Outside: covered[k] = 1; break;
            case BlockMapUse::Refined: {
                bool all = true;
                for (std::int32_t c : children[k])
                    if (c >= 0 && !covered[std::size_t(c)]) all = false;
                covered[k] = all;
                break;
            }
            default: break;
            }
        }
        // Pre-order again, so the ranges come in order and merge.
        std::vector<std::uint32_t> stack{0};
        while (!stack.empty()) {
            const std::uint32_t k = stack.back();
            stack.pop_back();
            switch (cut.use[k]) {
            case BlockMapUse::Polygons: add(first[k], end[k]); break;
            case BlockMapUse::Refined:
                if (!covered[k]) add(first[k], ownEnd[k]);
                for (int q = 3; q >= 0; --q) // the first quadrant pops first, as of() laid them out
                    if (children[k][std::size_t(q)] >= 0) stack.push_back(std::uint32_t(children[k][std::size_t(q)]));
                break;
            default: break;
            }
        }
    }
    add(outsideFirst, std::uint32_t(order.size()));
    return out;
}

} // namespace seasonview::city
