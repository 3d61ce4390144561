#pragma once
// What occlusion queries said of one atlas tree's nodes, and the policy of Coherent Hierarchical Culling over it
// (Bittner et al. 2004; Wimmer & Bittner 2005, GPU Gems 2 ch. 6; the visibility persistence of CHC++, Mattausch et al.
// 2008), plain C++: CityRendererGL issues the queries and draws, this decides which nodes the traversal trusts, which
// to test and when, and how long an answer holds. Frames are counted by beginFrame() (one per draw of the tree).
//
// Per frame: the traversal trusts nodes known visible and defers the ones known hidden (tested before they are drawn,
// nearest first, in rounds); once anything is known, a node without a recent answer (new in view, newly refined) is
// drawn at once and tested at the end of the frame; while nothing is known (the first frame, after reset()) every
// node is tested before it is drawn, in rounds of the kBootstrapBatch, 2·kBootstrapBatch, ... nearest that reach
// further each round (nextRound), so that near buildings are drawn first and hide far ones. A visible answer measured against a whole frame's depth is trusted for kPersistFrames
// frames; any answer is a hint for kAnswerFrames frames (a hidden node is still tested before it is skipped).
#include "AtlasTraversal.h"
#include "AtlasTree.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

namespace seasonview::city {

class NodeOcclusion {
public:
    static constexpr std::uint64_t kPersistFrames = 4; // a visible answer trusted this many frames
    static constexpr std::uint64_t kAnswerFrames = 8;  // any answer older than this: unknown
    static constexpr std::size_t kBootstrapBatch = 8;  // the first round's nodes while nothing is known
    static constexpr double kBootstrapReachMetres = 16.0; // ... and how far beyond twice the nearest one they reach
    static constexpr float kGrowFraction = 0.01f;      // query boxes grown by this fraction of their size ...
    static constexpr float kGrowMetres = 0.05f;        // ... plus this, to enclose their triangles once rasterised
    static constexpr double kNearMetres = 1.0;         // the eye this near a query box: visible without a test

    explicit NodeOcclusion(const AtlasTreeData& tree);

    /// A new frame of this tree.
    void beginFrame();
    std::uint64_t frame() const { return m_frame; }
    /// Forgets every answer (a still from a new camera).
    void reset();

    /// Whether nothing was known when this frame began (the root had no recent answer): every node is tested before
    /// it is drawn, all frame long.
    bool bootstrap() const { return m_bootstrap; }
    /// What the traversal of this frame is told: recent answers; a node without one is Visible (drawn, tested at the
    /// end of the frame) unless nothing is known.
    NodeVisibility forTraversal(std::uint32_t node) const;
    /// What the pager is told before the frame to come (the last frame's answers: hidden nodes are paged as Culled).
    NodeVisibility forPaging(std::uint32_t node) const { return visibility(node, m_frame + 1); }
    /// The recent answer for `node` as seen in frame `atFrame`.
    NodeVisibility visibility(std::uint32_t node, std::uint64_t atFrame) const;

    /// After a traversal of this frame: the nodes it opened or drew are visible now; those drawn without an answer
    /// are due for a test at the end of the frame.
    void traversed(const AtlasTraversalResult& r);
    /// A query's answer for `node`, measured against the depth of frame `measured` (this one or the last).
    void answered(std::uint32_t node, bool visible, std::uint64_t measured);
    /// A deferred node found visible against the depth drawn so far: drawn now, tested again at the end of the frame.
    void foundVisible(std::uint32_t node);
    /// How many of `pending` deferred nodes (nearest first) the next round tests: all once anything is known, else
    /// kBootstrapBatch << `roundsThatDrew` (rounds that only opened inner nodes keep the batch small).
    std::size_t roundSize(std::size_t pending, int roundsThatDrew) const;
    /// A round of deferred nodes: those the eye is next to (visible without a test) and those whose boxes to query.
    struct Round {
        std::vector<std::uint32_t> visible, test;
    };
    /// The next round: the roundSize() nearest of `pending` (metres from the eye by `distance`); `pending` keeps the
    /// rest. While nothing is known, also only those within 2 d0 + kBootstrapReachMetres · 2^roundsThatDrew (d0 the
    /// nearest's distance, at least one node): the traversal reaches the leaves next to the eye only after a round per
    /// level, and coarse far nodes tested before the near buildings are drawn would all be found visible.
    Round nextRound(std::vector<std::uint32_t>& pending, const std::function<double(std::uint32_t)>& distance,
                    const glm::dvec3& eye, int roundsThatDrew) const;
    /// Of the nodes drawn this frame, those whose boxes to query at its end (dueForTest()); the ones the eye is next
    /// to are answered visible at once.
    std::vector<std::uint32_t> endOfFrameTests(const std::vector<std::uint32_t>& drawn, const glm::dvec3& eye);
    /// Whether a node drawn this frame has its box queried at the end of it: never answered, drawn untested, or its
    /// visible answer older than kPersistFrames.
    bool dueForTest(std::uint32_t node) const;

    /// The box a node's query draws: its bounds grown by kGrowFraction of their size plus kGrowMetres.
    std::pair<glm::vec3, glm::vec3> queryBox(std::uint32_t node) const;
    /// Whether the eye is within kNearMetres of the query box: the near plane could cut the box's front faces away
    /// and leave only far faces that nearer geometry hides, so such a node counts as visible without a test.
    bool eyeNear(std::uint32_t node, const glm::dvec3& eye) const;

private:
    struct State {
        std::uint64_t frame = 0;  // when `visible` was last known (answered, or traversed as visible)
        std::uint64_t tested = 0; // when a query last answered against a whole frame (0: due)
        bool visible = false;
    };
    const AtlasTreeData& m_tree;
    std::vector<State> m_states;
    std::uint64_t m_frame = 0;
    bool m_bootstrap = true;
};

} // namespace seasonview::city
