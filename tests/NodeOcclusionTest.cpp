// NodeOcclusion (city/NodeOcclusion.h): the occlusion-culling policy without GL — what the traversal and the pager
// are told from the answers and for how long, when a node is tested, the bootstrap rounds, the query boxes.
#include "NodeOcclusion.h"

#include <gtest/gtest.h>

using namespace seasonview::city;

namespace {

// A root (0..100 m) and four children of 25 m.
AtlasTreeData fiveNodes() {
    AtlasTreeData t;
    AtlasNode root;
    root.boundsMin = {0, 0, 0};
    root.boundsMax = {100, 100, 20};
    t.nodes.push_back(root);
    for (int c = 0; c < 4; ++c) {
        AtlasNode n;
        n.boundsMin = {25.0f * float(c), 0, 0};
        n.boundsMax = {25.0f * float(c + 1), 100, 20};
        n.parent = 0;
        n.level = 1;
        t.nodes[0].children[std::size_t(c)] = int(t.nodes.size());
        t.nodes.push_back(n);
    }
    return t;
}

} // namespace

TEST(NodeOcclusionTest, BootstrapTestsEverythingNearestFirstInGrowingRounds) {
    const AtlasTreeData t = fiveNodes();
    NodeOcclusion o(t);
    o.beginFrame();
    EXPECT_TRUE(o.bootstrap());
    for (std::uint32_t n = 0; n < 5; ++n) EXPECT_EQ(o.forTraversal(n), NodeVisibility::Unknown) << n;
    EXPECT_EQ(o.roundSize(100, 0), NodeOcclusion::kBootstrapBatch);
    EXPECT_EQ(o.roundSize(100, 2), 4 * NodeOcclusion::kBootstrapBatch);
    EXPECT_EQ(o.roundSize(3, 0), 3u);
    // The root found visible in this frame's first round: the frame stays a bootstrap (its children are tested too).
    o.foundVisible(0);
    EXPECT_TRUE(o.bootstrap());
    EXPECT_EQ(o.forTraversal(1), NodeVisibility::Unknown);
    EXPECT_EQ(o.forTraversal(0), NodeVisibility::Visible);
    // The next frame knows the root: nodes without an answer are drawn at once, every deferred node in one round.
    o.beginFrame();
    EXPECT_FALSE(o.bootstrap());
    EXPECT_EQ(o.forTraversal(1), NodeVisibility::Visible);
    EXPECT_EQ(o.roundSize(100, 0), 100u);
    // reset(): nothing known again.
    o.reset();
    o.beginFrame();
    EXPECT_TRUE(o.bootstrap());
}

TEST(NodeOcclusionTest, AnswersHoldForAFewFramesAndVisibleOnesAreTestedAgainInTurn) {
    const AtlasTreeData t = fiveNodes();
    NodeOcclusion o(t);
    o.beginFrame(); // frame 1
    o.answered(0, true, 1);
    o.answered(1, false, 1);
    o.answered(2, true, 1);
    // Frame 2: the hidden child is deferred (and paged as Culled), the visible one trusted.
    EXPECT_EQ(o.forPaging(1), NodeVisibility::Hidden);
    o.beginFrame();
    EXPECT_EQ(o.forTraversal(1), NodeVisibility::Hidden);
    EXPECT_EQ(o.forTraversal(2), NodeVisibility::Visible);
    // A visible answer against a whole frame is trusted kPersistFrames frames before node 2 is tested again.
    for (std::uint64_t f = 2; f < 1 + NodeOcclusion::kPersistFrames; ++f) {
        EXPECT_EQ(o.frame(), f);
        EXPECT_FALSE(o.dueForTest(2)) << "frame " << f;
        o.beginFrame();
    }
    EXPECT_TRUE(o.dueForTest(2));
    // Node 3 drawn without an answer (new in view): tested at the end of this very frame.
    AtlasTraversalResult r;
    r.opened = {0};
    r.drawn = {2, 3};
    o.traversed(r);
    EXPECT_TRUE(o.dueForTest(3));
    EXPECT_EQ(o.forTraversal(3), NodeVisibility::Visible);
    // Found visible against the depth so far: tested again at the end of the frame.
    o.foundVisible(4);
    EXPECT_TRUE(o.dueForTest(4));
    // Any answer older than kAnswerFrames frames is unknown: node 1 was last answered in frame 1.
    EXPECT_EQ(o.visibility(1, 1 + NodeOcclusion::kAnswerFrames), NodeVisibility::Hidden);
    EXPECT_EQ(o.visibility(1, 2 + NodeOcclusion::kAnswerFrames), NodeVisibility::Unknown);
    // Traversed nodes stay known while traversed: the root is still Visible long after its answer.
    for (int i = 0; i < 20; ++i) {
        o.beginFrame();
        AtlasTraversalResult opened;
        opened.opened = {0};
        o.traversed(opened);
    }
    EXPECT_EQ(o.forTraversal(0), NodeVisibility::Visible);
    EXPECT_FALSE(o.bootstrap());
}

TEST(NodeOcclusionTest, QueryBoxesAreGrownAndTheEyeNextToOneNeedsNoTest) {
    const AtlasTreeData t = fiveNodes();
    const NodeOcclusion o(t);
    const auto [lo, hi] = o.queryBox(0);
    const float grow = NodeOcclusion::kGrowFraction * 100.0f + NodeOcclusion::kGrowMetres; // 1.05 m in x and y
    EXPECT_FLOAT_EQ(lo.x, -grow);
    EXPECT_FLOAT_EQ(hi.y, 100.0f + grow);
    EXPECT_FLOAT_EQ(hi.z, 20.0f + NodeOcclusion::kGrowFraction * 20.0f + NodeOcclusion::kGrowMetres);
    // Measured to the grown box: 1.5 m outside the bounds is 0.45 m from it.
    EXPECT_TRUE(o.eyeNear(0, {-1.5, 50.0, 2.0}));
    EXPECT_FALSE(o.eyeNear(0, {-2.5, 50.0, 2.0}));
    EXPECT_TRUE(o.eyeNear(0, {50.0, 50.0, 2.0})); // inside
}

TEST(NodeOcclusionTest, BootstrapRoundsGoFrontToBack) {
    // While nothing is known a round takes only nodes within 2 d0 + 16 m · 2^(rounds that drew), so far coarse
    // nodes wait until the near ones are drawn (and can hide them).
    const AtlasTreeData t = fiveNodes();
    NodeOcclusion o(t);
    o.beginFrame();
    std::vector<double> metres = {10.0, 30.0, 100.0, 240.0, 300.0};
    const auto distance = [&](std::uint32_t n) { return metres[n]; };
    const glm::dvec3 eye(-500.0, -500.0, 2.0); // next to no box: every node is tested
    std::vector<std::uint32_t> pending = {4, 3, 2, 1, 0};
    NodeOcclusion::Round r = o.nextRound(pending, distance, eye, 0); // reach 2 · 10 + 16 m (d0 + 16 would miss 30)
    EXPECT_EQ(r.test, (std::vector<std::uint32_t>{0, 1}));
    EXPECT_EQ(pending, (std::vector<std::uint32_t>{2, 3, 4}));
    r = o.nextRound(pending, distance, eye, 2); // reach 2 · 100 + 64 m (2 · 100 + 16 or 100 + 64 would miss 240)
    EXPECT_EQ(r.test, (std::vector<std::uint32_t>{2, 3}));
    EXPECT_EQ(pending, (std::vector<std::uint32_t>{4}));
    r = o.nextRound(pending, distance, eye, 0); // always at least the nearest
    EXPECT_EQ(r.test, (std::vector<std::uint32_t>{4}));
    EXPECT_TRUE(pending.empty());
    // Once anything is known, distance does not limit a round.
    o.answered(0, true, o.frame());
    o.beginFrame();
    pending = {4, 3, 2, 1, 0};
    EXPECT_EQ(o.nextRound(pending, distance, eye, 0).test.size(), 5u);
}

TEST(NodeOcclusionTest, RoundsTakeTheNearestAndTheEyeNextToABoxNeedsNoQuery) {
    const AtlasTreeData t = fiveNodes();
    NodeOcclusion o(t);
    o.beginFrame(); // nothing known: rounds of kBootstrapBatch << rounds that drew
    std::vector<std::uint32_t> pending;
    std::vector<double> metres(5, 0.0);
    for (std::uint32_t i = 0; i < 20; ++i) pending.push_back(1 + i % 4); // repeats: only order and count matter
    for (std::uint32_t n = 1; n < 5; ++n) metres[n] = 10.0 * n;
    const auto distance = [&](std::uint32_t n) { return metres[n]; };
    const glm::dvec3 eye(12.0, 50.0, 2.0); // inside child 1's box (x 0..25)
    const NodeOcclusion::Round r = o.nextRound(pending, distance, eye, 0);
    EXPECT_EQ(r.visible.size() + r.test.size(), NodeOcclusion::kBootstrapBatch);
    EXPECT_EQ(pending.size(), 20u - NodeOcclusion::kBootstrapBatch);
    for (std::uint32_t n : r.visible) EXPECT_EQ(n, 1u) << "only the box the eye is in";
    for (std::uint32_t n : r.test) EXPECT_LE(metres[n], 20.0) << "the nearest first";
    for (std::uint32_t n : pending) EXPECT_GE(metres[n], 20.0);
    // Once something is known, one round takes every pending node.
    o.answered(0, true, o.frame());
    o.beginFrame();
    std::vector<std::uint32_t> all = {4, 3, 2};
    EXPECT_EQ(o.nextRound(all, distance, eye, 0).test.size(), 3u);
    EXPECT_TRUE(all.empty());

    // The end of the frame: the node the eye is in is answered visible at once, the due ones queried.
    AtlasTraversalResult drawn;
    drawn.drawn = {1, 2, 3};
    o.traversed(drawn); // drawn untested: all due
    const auto tests = o.endOfFrameTests({1, 2, 3}, eye);
    EXPECT_EQ(tests, (std::vector<std::uint32_t>{2, 3}));
    EXPECT_FALSE(o.dueForTest(1));
}
