#include "GeometryClipmap.h"

#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include <random>

using namespace seasonview;

TEST(GeometryClipmapTest, LevelCountCoversTheGridFromAnywhereInIt) {
    EXPECT_EQ(geometryLevelCount(255, 100), 1);
    EXPECT_EQ(geometryLevelCount(255, 1201), 5);  // 254 * 16 = 4064 >= 2402
    EXPECT_EQ(geometryLevelCount(255, 16384), 9); // 254 * 256 = 65024 >= 32768
    for (int extent : {1201, 5000, 16384})
        EXPECT_GE(254.0 * std::ldexp(1.0, geometryLevelCount(255, extent) - 1), 2.0 * extent);
}

TEST(GeometryClipmapTest, FinestLevelFollowsPixelsNotTheDem) {
    const double ppr = 1080.0 / (2.0 * std::tan(M_PI / 6.0)); // 1080 rows, 60 deg
    EXPECT_EQ(finestActiveLevel(8, 1.0, 10.0, ppr), 0);     // low: every level
    const int high = finestActiveLevel(8, 1.0, 4000.0, ppr);
    EXPECT_GT(high, 0);
    EXPECT_LT(std::ldexp(1.0, high - 1) * ppr / 4000.0, kMinCellPixels);
    EXPECT_GE(std::ldexp(1.0, high) * ppr / 4000.0, kMinCellPixels);
    // A DEM 8x finer (spacing / 8) with 3 more levels: the same number of levels drawn.
    EXPECT_EQ(finestActiveLevel(11, 0.125, 4000.0, ppr), high + 3);
    EXPECT_EQ(finestActiveLevel(3, 1.0, 1e6, ppr), 2); // never past the coarsest
}

// GPU Gems 2 ch. 2 §2.3: every level sits in its coarser level's hole at one of the two trim positions, on the
// coarser grid, and stays centred on the viewer within a couple of cells.
TEST(GeometryClipmapTest, LevelsNestInsideTheCoarserHoleAroundTheViewer) {
    const int n = 255, levels = 7;
    const RingLayout ring = RingLayout::make(n);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> pos(-3000.0, 9000.0);
    for (int trial = 0; trial < 200; ++trial) {
        const glm::dvec2 viewer(pos(rng), pos(rng));
        const GeometryPlacement p = placeGeometryLevels(viewer, n, levels, 0);
        ASSERT_EQ(int(p.levels.size()), levels);
        for (int l = 0; l < levels; ++l) {
            const GeometryLevel& g = p.levels[size_t(l)];
            EXPECT_EQ(g.cell, 1 << l);
            EXPECT_EQ(g.origin.x % (2 * g.cell), 0);
            EXPECT_EQ(g.origin.y % (2 * g.cell), 0);
            const glm::dvec2 centre = glm::dvec2(g.origin) + double(n - 1) / 2.0 * g.cell;
            EXPECT_LE(std::abs(centre.x - viewer.x), 2.0 * g.cell) << l;
            EXPECT_LE(std::abs(centre.y - viewer.y), 2.0 * g.cell) << l;
            if (l + 1 == levels) continue;
            const GeometryLevel& c = p.levels[size_t(l + 1)];
            const GridRect finer = ring.finerLevel(c.trimX, c.trimY);
            EXPECT_EQ(g.origin.x, c.origin.x + finer.x0 * c.cell);
            EXPECT_EQ(g.origin.y, c.origin.y + finer.y0 * c.cell);
        }
    }
}

// The pieces of every drawn level plus the finer level's square tile the level's square exactly once.
TEST(GeometryClipmapTest, PiecesTileEachLevelExactlyOnce) {
    const int n = 63;
    const RingLayout ring = RingLayout::make(n);
    for (auto viewer : {glm::dvec2(0.3, 0.2), glm::dvec2(77.7, -41.2), glm::dvec2(1000.5, 3.9)}) {
        const GeometryPlacement p = placeGeometryLevels(viewer, n, 4, 1);
        for (int l = p.finest; l < 4; ++l) {
            std::vector<int> count(size_t(n - 1) * size_t(n - 1), 0);
            for (const GridRect& r : levelPieces(ring, p, l))
                for (int y = r.y0; y < r.y1; ++y)
                    for (int x = r.x0; x < r.x1; ++x) ++count[size_t(y) * size_t(n - 1) + size_t(x)];
            if (l > p.finest) {
                const GridRect f = ring.finerLevel(p.levels[size_t(l)].trimX, p.levels[size_t(l)].trimY);
                for (int y = f.y0; y < f.y1; ++y)
                    for (int x = f.x0; x < f.x1; ++x) ++count[size_t(y) * size_t(n - 1) + size_t(x)];
            }
            for (int c : count) ASSERT_EQ(c, 1) << "level " << l;
        }
    }
}

TEST(GeometryClipmapTest, FrustumCullsBoxesOutsideTheSidePlanes) {
    const glm::dmat4 proj = glm::perspective(glm::radians(60.0), 1.5, 0.1, 1000.0);
    const glm::dmat4 view = glm::lookAt(glm::dvec3(0, 0, 10), glm::dvec3(0, 100, 10), glm::dvec3(0, 0, 1));
    const FrustumPlanes f = FrustumPlanes::fromViewProj(proj * view);
    EXPECT_FALSE(f.outside({-5, 50, 0}, {5, 60, 20}));     // ahead
    EXPECT_TRUE(f.outside({-5, -60, 0}, {5, -50, 20}));    // behind
    EXPECT_TRUE(f.outside({500, 10, 0}, {600, 20, 20}));   // far right of a narrow wedge
    EXPECT_TRUE(f.outside({-5, 50, 200}, {5, 60, 300}));   // above
    EXPECT_FALSE(f.outside({-1000, -1000, -5}, {1000, 1000, 5})); // around the viewer
}

// Per-piece culling boxes: the range over any box contains every height a point inside it can take (the grid
// samples around it), and small boxes get ranges far tighter than the whole grid's.
TEST(GeometryClipmapTest, HeightBoundsAreConservativeAndTight) {
    const int w = 300, h = 200;
    std::mt19937 rng(3);
    std::vector<float> z(size_t(w) * h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            z[size_t(y) * w + size_t(x)] = float(100.0 * std::sin(x * 0.05) * std::cos(y * 0.07)) +
                                           float(rng() % 100) * 0.01f;
    auto brute = [&](glm::dvec2 lo, glm::dvec2 hi) {
        glm::vec2 r(1e30f, -1e30f);
        const int x0 = std::clamp(int(std::floor(lo.x)), 0, w - 1), x1 = std::clamp(int(std::ceil(hi.x)), 0, w - 1);
        const int y0 = std::clamp(int(std::floor(lo.y)), 0, h - 1), y1 = std::clamp(int(std::ceil(hi.y)), 0, h - 1);
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
                const float v = z[size_t(y) * w + size_t(x)];
                r = glm::vec2(std::min(r.x, v), std::max(r.y, v));
            }
        return r;
    };
    const HeightBounds b = HeightBounds::build(w, h, 32, brute);
    const glm::vec2 all = brute({0.0, 0.0}, {w - 1.0, h - 1.0});
    std::uniform_real_distribution<double> px(-50.0, w + 50.0), py(-50.0, h + 50.0), size(0.0, 40.0);
    int tight = 0;
    for (int trial = 0; trial < 2000; ++trial) {
        const glm::dvec2 lo(px(rng), py(rng)), hi = lo + glm::dvec2(size(rng), size(rng));
        const glm::vec2 want = brute(glm::clamp(lo, glm::dvec2(0.0), glm::dvec2(w - 1, h - 1)),
                                     glm::clamp(hi, glm::dvec2(0.0), glm::dvec2(w - 1, h - 1)));
        const glm::vec2 got = b.range(lo, hi);
        ASSERT_LE(got.x, want.x) << trial;
        ASSERT_GE(got.y, want.y) << trial;
        tight += (got.y - got.x) < 0.5f * (all.y - all.x) ? 1 : 0;
    }
    EXPECT_GT(tight, 1000);
    EXPECT_EQ(HeightBounds::flat(7.0f).range({-1e6, -1e6}, {1e6, 1e6}), glm::vec2(7.0f, 7.0f));
}
