#include "ClipmapSchedule.h"

#include <gtest/gtest.h>

using namespace seasonview;

namespace {
void storeAll(ClipmapSchedule& s) {
    for (const BlockKey& k : s.missingBlocks(1u << 30)) s.markStored(k);
}
} // namespace

TEST(ClipmapScheduleTest, LayoutSplitsToroidalAndResidentLevels) {
    const ClipmapLayout l = makeClipmapLayout(8192, 6000, 1024, 64);
    ASSERT_EQ(l.levelSizes.size(), 14u); // 8192 -> 1
    EXPECT_EQ(l.levelSizes[1], glm::ivec2(4096, 3000));
    EXPECT_EQ(l.levelSizes[3], glm::ivec2(1024, 750));
    EXPECT_EQ(l.clipLevels(), 3); // 8192, 4096, 2048 are toroidal; 1024 and smaller are resident
    EXPECT_EQ(makeClipmapLayout(65536, 65536, 1024, 64).clipLevels(), 6);
    EXPECT_EQ(makeClipmapLayout(900, 900, 1024, 64).clipLevels(), 0);
}

TEST(ClipmapScheduleTest, FinestLevelFirstNearestFirst) {
    ClipmapSchedule s(makeClipmapLayout(8192, 8192, 256, 64));
    s.setCenters({{4000, 4000}, {4000, 4000}, {4000, 4000}, {4000, 4000}, {4000, 4000}});
    const auto m = s.missingBlocks(1000);
    ASSERT_FALSE(m.empty());
    EXPECT_EQ(m.front().level, 0);
    for (size_t i = 1; i < m.size(); ++i) EXPECT_GE(m[i].level, m[i - 1].level);
    // The first block is one of the four around the centre (4000 / 64 = 62.5).
    EXPECT_GE(m.front().bx, 61);
    EXPECT_LE(m.front().bx, 62);
    EXPECT_EQ(s.missingBlocks(3).size(), 3u);
}

TEST(ClipmapScheduleTest, MovingOneBlockNeedsOneStrip) {
    ClipmapSchedule s(makeClipmapLayout(8192, 8192, 256, 64));
    const int levels = s.layout().clipLevels();
    std::vector<glm::dvec2> c(size_t(levels), glm::dvec2(4096, 4096));
    s.setCenters(c);
    storeAll(s);
    EXPECT_TRUE(s.missingBlocks(10).empty());
    for (auto& p : c) p.x += 64; // one block east at level 0, half a block at level 1 (window may not move)
    const long long exposed = s.setCenters(c);
    const auto m = s.missingBlocks(1000);
    long long texels = 0;
    for (const auto& k : m) texels += s.blockTexels(k).area();
    EXPECT_EQ(texels, exposed) << "uploads equal the geometric minimum";
    int level0 = 0;
    for (const auto& k : m) level0 += k.level == 0 ? 1 : 0;
    EXPECT_EQ(level0, 4); // a 256-texel window is 4 blocks tall
}

TEST(ClipmapScheduleTest, StaleSlotsAreMissesAfterWrapAround) {
    ClipmapSchedule s(makeClipmapLayout(4096, 4096, 256, 64));
    std::vector<glm::dvec2> c(size_t(s.layout().clipLevels()), glm::dvec2(1000, 1000));
    s.setCenters(c);
    storeAll(s);
    const BlockKey old{0, 15, 15};
    EXPECT_TRUE(s.holds(old));
    // Jump exactly one window (256 texels = 4 slots per side) east: every slot is reused for a new block.
    for (auto& p : c) p.x += 256;
    s.setCenters(c);
    const BlockKey now{0, 15 + 4, 15};
    EXPECT_FALSE(s.holds(now)) << "same slot, different tag";
    EXPECT_TRUE(s.holds(old)) << "until overwritten the slot still holds the old block";
    s.markStored(now);
    EXPECT_TRUE(s.holds(now));
    EXPECT_FALSE(s.holds(old));
}

TEST(ClipmapScheduleTest, BlocksOutsideTheImageAreNeverRequested) {
    ClipmapSchedule s(makeClipmapLayout(1000, 700, 256, 64));
    std::vector<glm::dvec2> c(size_t(s.layout().clipLevels()), glm::dvec2(0, 0)); // window hangs off the corner
    s.setCenters(c);
    for (const auto& k : s.missingBlocks(1000)) {
        const TexelRect t = s.blockTexels(k);
        EXPECT_FALSE(t.empty());
        EXPECT_GE(t.x0, 0);
        EXPECT_GE(t.y0, 0);
    }
    // The last block column of level 0 is partial: 1000 = 15 * 64 + 40.
    EXPECT_EQ(s.blockTexels({0, 15, 0}).width(), 40);
}

TEST(ClipmapScheduleTest, Tags) {
    EXPECT_EQ(ClipmapSchedule::tagOf(0, 0), 0);
    EXPECT_EQ(ClipmapSchedule::tagOf(3, 2), 3 | (2 << 16));
    EXPECT_NE(ClipmapSchedule::tagOf(32767, 32767), ClipmapSchedule::kEmptyTag);
}
