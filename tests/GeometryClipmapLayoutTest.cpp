#include "GeometryClipmapLayout.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <map>
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

// The stitch to the coarser level, as the vertex shader draws it: with every odd outer-edge vertex moved onto its
// even neighbour, a ring level's triangles still tile its annulus exactly once (positive areas that add up to it, no
// fold-over), outerDegenerateTriangles() of them collapse, and the outer boundary is made only of segments between
// consecutive even vertices: the coarser level's own inner-edge segments, so no T-junction is left for a crack.
TEST(GeometryClipmapLayoutTest, StitchedOuterEdgeIsTheCoarserLevelsEdge) {
    for (int n : {7, 15, 31, 63, 255}) {
        const RingLayout L = RingLayout::make(n);
        for (TrimSide tx : {TrimSide::Low, TrimSide::High})
            for (TrimSide ty : {TrimSide::Low, TrimSide::High}) {
                std::vector<GridRect> pieces = L.ringBlocks();
                for (const auto& f : L.fixups()) pieces.push_back(f);
                for (const auto& t : L.trim(tx, ty)) pieces.push_back(t);
                long long area2 = 0; // twice the area
                int degenerate = 0;
                std::map<std::pair<std::pair<int, int>, std::pair<int, int>>, int> edges; // directed edge -> uses
                for (const GridRect& r : pieces) {
                    const auto idx = pieceTriangles(r.cellsX(), r.cellsY());
                    ASSERT_EQ(idx.size(), size_t(r.cellsX()) * size_t(r.cellsY()) * 6u);
                    auto at = [&](std::uint32_t i) {
                        const int w = r.cellsX() + 1;
                        return L.stitchedVertex(r.x0 + int(i) % w, r.y0 + int(i) / w);
                    };
                    for (size_t k = 0; k < idx.size(); k += 3) {
                        const auto a = at(idx[k]), b = at(idx[k + 1]), c = at(idx[k + 2]);
                        const long long cross = (long long)(b.first - a.first) * (c.second - a.second) -
                                                (long long)(b.second - a.second) * (c.first - a.first);
                        ASSERT_GE(cross, 0) << "n " << n << ": a triangle folded over";
                        if (cross == 0) {
                            ++degenerate;
                            continue;
                        }
                        area2 += cross;
                        for (auto [p, q] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) ++edges[{p, q}];
                    }
                }
                const long long cells = (long long)(n - 1) * (n - 1) - (long long)((n - 1) / 2) * ((n - 1) / 2);
                EXPECT_EQ(area2, 2 * cells) << "n " << n;
                EXPECT_EQ(degenerate, L.outerDegenerateTriangles()) << "n " << n;
                // Boundary edges: used once and not in the opposite direction. Those on the outer border must
                // join consecutive even vertices.
                int outer = 0;
                for (const auto& [e, uses] : edges) {
                    EXPECT_EQ(uses, 1) << "n " << n << ": an edge used twice in one direction (overlap)";
                    if (edges.count({e.second, e.first})) continue;
                    const auto [p, q] = e;
                    const bool onOuter = (p.first == q.first && (p.first == 0 || p.first == n - 1)) ||
                                         (p.second == q.second && (p.second == 0 || p.second == n - 1));
                    if (!onOuter) continue;
                    ++outer;
                    EXPECT_EQ(p.first % 2 + p.second % 2 + q.first % 2 + q.second % 2, 0)
                        << "n " << n << ": outer edge ends on an odd vertex";
                    EXPECT_EQ(std::abs(p.first - q.first) + std::abs(p.second - q.second), 2)
                        << "n " << n << ": outer edge is not one coarser cell";
                }
                EXPECT_EQ(outer, 4 * ((n - 1) / 2)) << "n " << n;
            }
    }
}
