#include "GeometryClipmapLayout.h"

#include <gtest/gtest.h>

#include <vector>

using namespace seasonview;

namespace {
// Counts how often each cell of the level is covered.
std::vector<int> cover(const RingLayout& L, const std::vector<GridRect>& rects) {
    const int c = L.n - 1;
    std::vector<int> hits(size_t(c) * size_t(c), 0);
    for (const GridRect& r : rects) {
        EXPECT_GE(r.x0, 0);
        EXPECT_GE(r.y0, 0);
        EXPECT_LE(r.x1, c);
        EXPECT_LE(r.y1, c);
        for (int y = r.y0; y < r.y1; ++y)
            for (int x = r.x0; x < r.x1; ++x) ++hits[size_t(y) * size_t(c) + size_t(x)];
    }
    return hits;
}
} // namespace

TEST(GeometryClipmapLayoutTest, SizesAsDesigned) {
    const RingLayout L = RingLayout::make(255);
    EXPECT_EQ(L.m, 64);
    EXPECT_EQ(L.blockOffset(3) + L.m - 1, L.n - 1) << "4 blocks + a 2-cell gap span the level";
    const auto blocks = L.ringBlocks();
    ASSERT_EQ(blocks.size(), 12u);
    for (const auto& b : blocks) EXPECT_EQ(b.vertices(), 64 * 64);
    const auto fix = L.fixups();
    ASSERT_EQ(fix.size(), 4u);
    for (const auto& f : fix) EXPECT_EQ(f.vertices(), 64 * 3);
    const auto trim = L.trim(TrimSide::Low, TrimSide::High);
    EXPECT_EQ(trim[0].vertices() + trim[1].vertices(), 2 * (2 * 64 + 1) + 2 * (2 * 64)) << "L-shape of (2m+1)x2";
    EXPECT_EQ(L.outerDegenerateTriangles(), 4 * 127);
    EXPECT_EQ(L.finerLevel(TrimSide::Low, TrimSide::Low).cellsX(), 127);
}

TEST(GeometryClipmapLayoutTest, EveryAnnulusCellCoveredExactlyOnce) {
    for (int n : {7, 15, 31, 63, 255}) {
        const RingLayout L = RingLayout::make(n);
        for (TrimSide x : {TrimSide::Low, TrimSide::High})
            for (TrimSide y : {TrimSide::Low, TrimSide::High}) {
                std::vector<GridRect> pieces = L.ringBlocks();
                for (const auto& f : L.fixups()) pieces.push_back(f);
                for (const auto& t : L.trim(x, y)) pieces.push_back(t);
                pieces.push_back(L.finerLevel(x, y)); // the hole the finer level fills
                const auto hits = cover(L, pieces);
                for (size_t i = 0; i < hits.size(); ++i)
                    ASSERT_EQ(hits[i], 1) << "n " << n << " cell " << i % size_t(n - 1) << "," << i / size_t(n - 1);
            }
    }
}

TEST(GeometryClipmapLayoutTest, FinestLevelIsTheFullGrid) {
    for (int n : {15, 255}) {
        const RingLayout L = RingLayout::make(n);
        const auto hits = cover(L, L.finestPieces());
        for (int h : hits) ASSERT_EQ(h, 1) << "n " << n;
    }
}

TEST(GeometryClipmapLayoutTest, FinerLevelIsAlignedToEvenFinerCells) {
    // The finer level's vertices must land on this level's vertices every other fine vertex: its origin in fine
    // cells is twice its origin in coarse cells, so any integer coarse origin works; check it stays in the hole.
    const RingLayout L = RingLayout::make(31);
    for (TrimSide x : {TrimSide::Low, TrimSide::High}) {
        const GridRect f = L.finerLevel(x, TrimSide::Low);
        EXPECT_GE(f.x0, L.m - 1);
        EXPECT_LE(f.x1, 3 * L.m - 1);
        EXPECT_EQ(2 * f.cellsX(), L.n - 1);
    }
}
