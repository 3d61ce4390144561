#include "NodeOcclusion.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cassert>
#include <cmath>

namespace seasonview::city {

NodeOcclusion::NodeOcclusion(const AtlasTreeData& tree) : m_tree(tree), m_states(tree.nodes.size()) {}

void NodeOcclusion::beginFrame() {
    ++m_frame;
    m_bootstrap = m_states.empty() || visibility(0, m_frame) == NodeVisibility::Unknown;
}

void NodeOcclusion::reset() { std::fill(m_states.begin(), m_states.end(), State{}); }

NodeVisibility NodeOcclusion::visibility(std::uint32_t node, std::uint64_t atFrame) const {
    assert(node < m_states.size() && "NodeOcclusion: no such node");
    const State& s = m_states[node];
    if (s.frame == 0 || s.frame + kAnswerFrames < atFrame) return NodeVisibility::Unknown;
    return s.visible ? NodeVisibility::Visible : NodeVisibility::Hidden;
}

NodeVisibility NodeOcclusion::forTraversal(std::uint32_t node) const {
    const NodeVisibility v = visibility(node, m_frame);
    return v == NodeVisibility::Unknown && !bootstrap() ? NodeVisibility::Visible : v;
}

void NodeOcclusion::traversed(const AtlasTraversalResult& r) {
    for (const auto* list : {&r.opened, &r.drawn})
        for (std::uint32_t n : *list) {
            State& s = m_states[n];
            if (visibility(n, m_frame) == NodeVisibility::Unknown) s.tested = 0; // drawn untested
            s.frame = m_frame;
            s.visible = true;
        }
}

void NodeOcclusion::answered(std::uint32_t node, bool visible, std::uint64_t measured) {
    m_states[node] = {measured, measured, visible};
}

void NodeOcclusion::foundVisible(std::uint32_t node) { m_states[node] = {m_frame, 0, true}; }

std::size_t NodeOcclusion::roundSize(std::size_t pending, int roundsThatDrew) const {
    if (!bootstrap()) return pending;
    return std::min(pending, kBootstrapBatch << std::clamp(roundsThatDrew, 0, 20));
}

NodeOcclusion::Round NodeOcclusion::nextRound(std::vector<std::uint32_t>& pending,
                                             const std::function<double(std::uint32_t)>& distance,
                                             const glm::dvec3& eye, int roundsThatDrew) const {
    std::vector<std::pair<double, std::uint32_t>> byDistance;
    byDistance.reserve(pending.size());
    for (std::uint32_t n : pending) byDistance.emplace_back(distance(n), n);
    std::sort(byDistance.begin(), byDistance.end());
    std::size_t take = roundSize(byDistance.size(), roundsThatDrew);
    if (bootstrap() && take > 1) {
        const double reach = 2.0 * byDistance.front().first +
                             kBootstrapReachMetres * std::ldexp(1.0, std::clamp(roundsThatDrew, 0, 40));
        std::size_t within = 1;
        while (within < take && byDistance[within].first <= reach) ++within;
        take = within;
    }
    Round round;
    for (std::size_t i = 0; i < take; ++i)
        (eyeNear(byDistance[i].second, eye) ? round.visible : round.test).push_back(byDistance[i].second);
    pending.clear();
    for (std::size_t i = take; i < byDistance.size(); ++i) pending.push_back(byDistance[i].second);
    return round;
}

std::vector<std::uint32_t> NodeOcclusion::endOfFrameTests(const std::vector<std::uint32_t>& drawn,
                                                           const glm::dvec3& eye) {
    std::vector<std::uint32_t> test;
    for (std::uint32_t n : drawn) {
        if (eyeNear(n, eye)) answered(n, true, m_frame);
        else if (dueForTest(n)) test.push_back(n);
    }
    return test;
}

bool NodeOcclusion::dueForTest(std::uint32_t node) const {
    const State& s = m_states[node];
    return s.tested == 0 || s.tested + kPersistFrames <= m_frame;
}

std::pair<glm::vec3, glm::vec3> NodeOcclusion::queryBox(std::uint32_t node) const {
    const AtlasNode& n = m_tree.nodes[node];
    const glm::vec3 grow = kGrowFraction * (n.boundsMax - n.boundsMin) + glm::vec3(kGrowMetres);
    return {n.boundsMin - grow, n.boundsMax + grow};
}

bool NodeOcclusion::eyeNear(std::uint32_t node, const glm::dvec3& eye) const {
    const auto [lo, hi] = queryBox(node);
    return glm::length(eye - glm::clamp(eye, glm::dvec3(lo), glm::dvec3(hi))) < kNearMetres;
}

} // namespace seasonview::city
