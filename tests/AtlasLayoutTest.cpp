// The texture-atlas tree's geometry (city/AtlasLayout.h, Buchholz's thesis §4.5): texture sizes against hand-computed
// triangles (degenerate texture coordinates included), the required atlas area with repetitions and border, packing
// without overlaps, the area-balanced split, and root-atlas coordinates round-tripping through every level.
#include "AtlasLayout.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

using namespace seasonview;
using namespace seasonview::city;

namespace {
TexturedTriangle tri(glm::dvec3 a, glm::dvec3 b, glm::dvec3 c, glm::dvec2 ta, glm::dvec2 tb, glm::dvec2 tc, int tex = 0) {
    TexturedTriangle t;
    t.v = {a, b, c};
    t.t = {ta, tb, tc};
    t.texture = tex;
    return t;
}
} // namespace

TEST(AtlasLayoutTest, ProjectionFactorIsPixelsPerMetreAtDmin) {
    // 90 degrees across 1000 pixels at 10 m: the view is 20 m wide there, 50 px per metre.
    EXPECT_NEAR(projectionFactor(10.0, 90.0, 1000), 50.0, 1e-9);
    EXPECT_NEAR(projectionFactor(20.0, 90.0, 1000), 25.0, 1e-9) << "inversely proportional to the distance";
}

TEST(AtlasLayoutTest, TextureSizeOfHandComputedTriangles) {
    // A 4 m × 2 m facade triangle in the x-z plane mapped to the unit square: s_world 4 m, t_world 2 m.
    const TexturedTriangle facade = tri({0, 0, 0}, {4, 0, 0}, {4, 0, 2}, {0, 0}, {1, 0}, {1, 1});
    const WorldScale w = textureWorldScale(facade);
    EXPECT_NEAR(w.s, 4.0, 1e-12);
    EXPECT_NEAR(w.t, 2.0, 1e-12);
    EXPECT_EQ(requiredTextureSize(facade, 50.0), glm::ivec2(200, 100));
    // Repeated 3 × 2 times over the same wall: each repetition is a third as wide and half as high in the world.
    const TexturedTriangle tiled = tri({0, 0, 0}, {4, 0, 0}, {4, 0, 2}, {0, 0}, {3, 0}, {3, 2});
    EXPECT_NEAR(textureWorldScale(tiled).s, 4.0 / 3.0, 1e-12);
    EXPECT_NEAR(textureWorldScale(tiled).t, 1.0, 1e-12);
    // Sheared mapping: t = (x/4 + z/4, z/2) on the wall; (1,0) in texture space is 4 m along x, (0,1) is
    // 2 m up and -2 m along x: sqrt(8) m.
    const TexturedTriangle sheared = tri({0, 0, 0}, {4, 0, 0}, {0, 0, 2}, {0, 0}, {1, 0}, {0.5, 1});
    EXPECT_NEAR(textureWorldScale(sheared).s, 4.0, 1e-12);
    EXPECT_NEAR(textureWorldScale(sheared).t, std::sqrt(8.0), 1e-12);
    // Texture coordinates all equal: one colour, 1×1.
    const TexturedTriangle flat = tri({0, 0, 0}, {4, 0, 0}, {4, 0, 2}, {0.3, 0.3}, {0.3, 0.3}, {0.3, 0.3});
    EXPECT_TRUE(textureWorldScale(flat).singleColour);
    EXPECT_EQ(requiredTextureSize(flat, 50.0), glm::ivec2(1, 1));
    // Collinear texture coordinates: the stretch of the longest texture edge, (0,0)-(0.5,0) over 4 m: 8 m per unit.
    const TexturedTriangle line = tri({0, 0, 0}, {4, 0, 0}, {4, 0, 2}, {0, 0}, {0.5, 0}, {0.25, 0});
    EXPECT_NEAR(textureWorldScale(line).s, 8.0, 1e-12);
    EXPECT_NEAR(textureWorldScale(line).t, 8.0, 1e-12);
    // Degenerate positions: nothing to draw, the minimum size.
    const TexturedTriangle sliver = tri({0, 0, 0}, {4, 0, 0}, {8, 0, 0}, {0, 0}, {1, 0}, {1, 1});
    EXPECT_EQ(requiredTextureSize(sliver, 50.0), glm::ivec2(1, 1));
}

TEST(AtlasLayoutTest, RequiredAreaCoversRepetitionsAndBorder) {
    const TexturedTriangle a = tri({0, 0, 0}, {4, 0, 0}, {4, 0, 2}, {0, 0}, {1, 0}, {1, 1}, 7);
    const TexturedTriangle b = tri({0, 0, 0}, {4, 0, 2}, {0, 0, 2}, {0, 0}, {1, 1}, {0, 1}, 7);
    // Both halves of the wall at 50 px/m: 200 × 100 texels for the unit square (100 rounded up to 104, a multiple
    // of the border), plus an 8-texel border.
    const AtlasArea area = requiredAtlasArea({&a, &b}, 50.0, 8);
    EXPECT_EQ(area.texture, 7);
    EXPECT_EQ(area.size, glm::ivec2(216, 120));
    // The source rectangle grows about its centre by the border's share: 8 / 200 and 8 / 104 of a repetition.
    EXPECT_NEAR(area.srcMin.x, -0.04, 1e-12);
    EXPECT_NEAR(area.srcMax.x, 1.04, 1e-12);
    EXPECT_NEAR(area.srcMin.y, -8.0 / 104.0, 1e-12);
    EXPECT_NEAR(area.srcMax.y, 1.0 + 8.0 / 104.0, 1e-12);
    // Only part of the texture used: half the width in the atlas.
    const TexturedTriangle half = tri({0, 0, 0}, {2, 0, 0}, {2, 0, 2}, {0, 0}, {0.5, 0}, {0.5, 1}, 1);
    EXPECT_EQ(requiredAtlasArea({&half}, 50.0, 8).size, glm::ivec2(104 + 16, 104 + 16));
    // Repetitions: (0,0), (3,0), (3,2) over the same wall need 3 × 2 repetitions at 1/3, 1/2 of the size each: the
    // same texels as one repetition over the wall.
    const TexturedTriangle tiled = tri({0, 0, 0}, {4, 0, 0}, {4, 0, 2}, {0, 0}, {3, 0}, {3, 2}, 2);
    EXPECT_EQ(requiredAtlasArea({&tiled}, 50.0, 8).size, glm::ivec2(216, 120));
    // 1000 × 500 repetitions cost no more either (the thesis' remark).
    const TexturedTriangle many = tri({0, 0, 0}, {4, 0, 0}, {4, 0, 2}, {0, 0}, {1000, 0}, {1000, 500}, 3);
    EXPECT_EQ(requiredAtlasArea({&many}, 50.0, 8).size, glm::ivec2(216, 120));
    // Every size is a multiple of the border, so packed areas start on multiples of it.
    for (int border : {4, 8, 16})
        for (const TexturedTriangle* t : {&a, &half, &tiled, &many}) {
            const glm::ivec2 s = requiredAtlasArea({t}, 37.0, border).size;
            EXPECT_EQ(s.x % border, 0) << border;
            EXPECT_EQ(s.y % border, 0) << border;
        }
}

TEST(AtlasLayoutTest, CappedAreasSnapToTheOriginalsTexels) {
    // A 61×37 original used over u 0.13..0.91, v 0.07..0.83 on a 10 m × 8 m wall, wanted at 960 px/m: capped at the
    // original's size. The rectangle snaps outwards to the original's 8-texel grid (u texels 7.93..55.51 -> 0..56,
    // v texels 2.59..30.71 -> 0..32), then grows by the 8-texel border: atlas texel k is original texel k - 8 (+ the
    // snapped start), one to one.
    const TexturedTriangle w1 = tri({0, 0, 0}, {10, 0, 0}, {10, 0, 8}, {0.13, 0.07}, {0.91, 0.07}, {0.91, 0.83});
    const TexturedTriangle w2 = tri({0, 0, 0}, {10, 0, 8}, {0, 0, 8}, {0.13, 0.07}, {0.91, 0.83}, {0.13, 0.83});
    const glm::dvec2 orig(61, 37);
    const AtlasArea a = requiredAtlasArea({&w1, &w2}, 960.0, 8, orig);
    EXPECT_EQ(a.size, glm::ivec2(56 + 16, 32 + 16));
    EXPECT_NEAR(a.srcMin.x * orig.x, -8.0, 1e-9);
    EXPECT_NEAR(a.srcMax.x * orig.x, 64.0, 1e-9);
    EXPECT_NEAR(a.srcMin.y * orig.y, -8.0, 1e-9);
    EXPECT_NEAR(a.srcMax.y * orig.y, 40.0, 1e-9);
    EXPECT_GT(a.capFactor, 1.0);
    // Texture coordinates elsewhere in the repetition grid: the snap follows the grid (u texels 130.5..150.1 of a
    // 61-texel texture -> 128..152).
    const TexturedTriangle far = tri({0, 0, 0}, {10, 0, 0}, {10, 0, 8}, {130.5 / 61, 0.5}, {150.1 / 61, 0.5}, {150.1 / 61, 0.6});
    const AtlasArea b = requiredAtlasArea({&far}, 960.0, 8, orig);
    EXPECT_EQ(b.size.x, 24 + 16);
    EXPECT_NEAR(b.srcMin.x * orig.x, 120.0, 1e-9);
    // Not capped (wanted below the original's size): resampled, the size rounded up to a multiple of the border.
    const AtlasArea c = requiredAtlasArea({&w1, &w2}, 3.0, 8, orig);
    // 12.8 m per repetition × 3 px/m × 0.78 of it = 30 texels -> 32; 10.5 m × 3 × 0.76 = 24 texels.
    EXPECT_EQ(c.size, glm::ivec2(32 + 16, 24 + 16));
}

namespace {

/// Every area inside the atlas, no two overlapping (as placed: turned areas by their transposed size).
void expectDisjointInside(const std::vector<AtlasArea>& areas, int atlasSize) {
    for (size_t i = 0; i < areas.size(); ++i) {
        const AtlasArea& a = areas[i];
        const glm::ivec2 fa = a.footprint();
        EXPECT_GE(a.position.x, 0);
        EXPECT_GE(a.position.y, 0);
        EXPECT_LE(a.position.x + fa.x, atlasSize);
        EXPECT_LE(a.position.y + fa.y, atlasSize);
        for (size_t j = i + 1; j < areas.size(); ++j) {
            const AtlasArea& b = areas[j];
            const glm::ivec2 fb = b.footprint();
            const bool apart = a.position.x + fa.x <= b.position.x || b.position.x + fb.x <= a.position.x ||
                               a.position.y + fa.y <= b.position.y || b.position.y + fb.y <= a.position.y;
            ASSERT_TRUE(apart) << i << " and " << j << " overlap";
        }
    }
}

} // namespace

TEST(AtlasLayoutTest, PackingNeverOverlapsAndKeepsEachAreaInside) {
    for (const AtlasPacker packer : {AtlasPacker::MaxRects, AtlasPacker::Skyline}) {
        SCOPED_TRACE(atlasPackerName(packer));
        std::mt19937 rng(5);
        std::uniform_int_distribution<int> side(20, 140);
        for (int trial = 0; trial < 20; ++trial) {
            std::vector<AtlasArea> areas(60);
            for (size_t i = 0; i < areas.size(); ++i) {
                areas[i].texture = int(i);
                areas[i].size = {side(rng), side(rng)};
            }
            double fill = 0.0;
            auto again = areas;
            ASSERT_TRUE(packAtlas(areas, 1024, &fill, packer));
            ASSERT_TRUE(packAtlas(again, 1024, nullptr, packer));
            for (size_t i = 0; i < areas.size(); ++i) { // deterministic: the same input, the same places
                EXPECT_EQ(areas[i].position, again[i].position);
                EXPECT_EQ(areas[i].rotated, again[i].rotated);
            }
            EXPECT_GT(fill, 0.3);
            EXPECT_LT(fill, 1.0);
            expectDisjointInside(areas, 1024);
            if (packer == AtlasPacker::Skyline) {
                for (const auto& a : areas) EXPECT_FALSE(a.rotated);
            }
        }
        // The borders are inside each area's size, so areas that do not overlap never share a border texel either.
        // Too much for the atlas: it says so.
        std::vector<AtlasArea> big(5);
        for (auto& a : big) a.size = {600, 600};
        EXPECT_FALSE(packAtlas(big, 1024, nullptr, packer));
        std::vector<AtlasArea> tooLong(1);
        tooLong[0].size = {1025, 10};
        EXPECT_FALSE(packAtlas(tooLong, 1024, nullptr, packer));
    }
}

TEST(AtlasLayoutTest, MaxRectsTurnsAreasToFitWhatTheSkylineCannot) {
    // Three 48×80 areas in a 128² atlas: side by side they need 144 texels, stacked 160; two upright leave a
    // 128×48 strip below them that holds the third turned (Jylänki's MAXRECTS with rotation). Facades taller than
    // half an atlas are this case: two to a leaf without turns, three or four with them.
    std::vector<AtlasArea> three(3);
    for (auto& a : three) a.size = {48, 80};
    auto skyline = three;
    EXPECT_FALSE(packAtlas(skyline, 128, nullptr, AtlasPacker::Skyline));
    double fill = 0.0;
    ASSERT_TRUE(packAtlas(three, 128, &fill, AtlasPacker::MaxRects));
    EXPECT_NEAR(fill, 3.0 * 48 * 80 / (128.0 * 128.0), 1e-12);
    expectDisjointInside(three, 128);
    EXPECT_EQ(std::count_if(three.begin(), three.end(), [](const AtlasArea& a) { return a.rotated; }), 1);
    // A turned area's texels are transposed: local (x, y) lands at position + (y, x).
    for (const auto& a : three)
        if (a.rotated) {
            EXPECT_EQ(a.footprint(), glm::ivec2(80, 48));
            EXPECT_EQ(a.atlasTexel({5.0, 70.0}), glm::dvec2(a.position) + glm::dvec2(70.0, 5.0));
        } else {
            EXPECT_EQ(a.atlasTexel({5.0, 70.0}), glm::dvec2(a.position) + glm::dvec2(5.0, 70.0));
        }
    // Exactly full: four 64² areas in 128², and a fifth never fits.
    std::vector<AtlasArea> four(4);
    for (auto& a : four) a.size = {64, 64};
    ASSERT_TRUE(packAtlas(four, 128, &fill));
    EXPECT_DOUBLE_EQ(fill, 1.0);
    expectDisjointInside(four, 128);
    four.push_back(four.back());
    EXPECT_FALSE(packAtlas(four, 128));
}

TEST(AtlasLayoutTest, PackerNamesRoundTrip) {
    for (const AtlasPacker p : {AtlasPacker::MaxRects, AtlasPacker::Skyline})
        EXPECT_EQ(parseAtlasPacker(atlasPackerName(p)), p);
    EXPECT_FALSE(parseAtlasPacker("guillotine"));
}

TEST(AtlasLayoutTest, SplitBalancesAreaAlongTheTwoLongestAxes) {
    // A street of 40 × 10 wall quads along x (each 2 triangles), walls 1..3 m wide at random, 5 m high.
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> width(1.0, 3.0);
    std::vector<TexturedTriangle> tris;
    double x = 0.0;
    for (int i = 0; i < 400; ++i) {
        const double w = width(rng), y = double(i % 10) * 8.0;
        tris.push_back(tri({x, y, 0}, {x + w, y, 0}, {x + w, y, 5}, {0, 0}, {1, 0}, {1, 1}));
        tris.push_back(tri({x, y, 0}, {x + w, y, 5}, {x, y, 5}, {0, 0}, {1, 1}, {0, 1}));
        if (i % 10 == 9) x += 4.0;
    }
    std::vector<std::uint32_t> all(tris.size());
    for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
    const auto groups = splitByArea(tris, all);
    double total = 0.0;
    for (const auto& t : tris) total += triangleArea(t);
    size_t count = 0;
    for (const auto& g : groups) {
        ASSERT_FALSE(g.empty());
        count += g.size();
        double area = 0.0;
        double lo = 1e9, hi = -1e9, ylo = 1e9, yhi = -1e9;
        for (std::uint32_t i : g) {
            area += triangleArea(tris[i]);
            for (const auto& v : tris[i].v) {
                lo = std::min(lo, v.x);
                hi = std::max(hi, v.x);
                ylo = std::min(ylo, v.y);
                yhi = std::max(yhi, v.y);
            }
        }
        EXPECT_NEAR(area / total, 0.25, 0.02) << "equal summed areas";
        // Cut along x (the longest) and then along y (the second): each group spans about half of each.
        EXPECT_LT(hi - lo, 0.6 * 160.0);
        EXPECT_LT(yhi - ylo, 0.6 * 72.0);
    }
    EXPECT_EQ(count, tris.size()) << "every triangle in exactly one group";
    // Two triangles: each cut still leaves both sides non-empty, so splitting always makes progress.
    const auto two = splitByArea(tris, {0, 1});
    EXPECT_EQ(two[0].size() + two[1].size() + two[2].size() + two[3].size(), 2u);
    EXPECT_LE(std::max({two[0].size(), two[1].size(), two[2].size(), two[3].size()}), 1u);
}

TEST(AtlasLayoutTest, RootAtlasCoordinatesRoundTripThroughLevels) {
    // The thesis' example: path (3, 0) is the bottom-left quadrant of the top-right quadrant.
    const glm::dvec2 r = rootAtlasCoord({0.5, 0.5}, {3, 0});
    EXPECT_NEAR(r.x, 0.625, 1e-15);
    EXPECT_NEAR(r.y, 0.625, 1e-15);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0.001, 0.999);
    std::uniform_int_distribution<int> child(0, 3);
    for (int trial = 0; trial < 200; ++trial) {
        std::vector<int> path(size_t(1 + trial % 9));
        for (int& c : path) c = child(rng);
        const glm::dvec2 t(u(rng), u(rng));
        const glm::dvec2 root = rootAtlasCoord(t, path);
        ASSERT_GE(root.x, 0.0);
        ASSERT_LT(root.x, 1.0);
        const glm::dvec2 back = levelAtlasCoord(root, int(path.size()));
        EXPECT_NEAR(back.x, t.x, 1e-9);
        EXPECT_NEAR(back.y, t.y, 1e-9);
        // At every ancestor's level the coordinate lies in the quadrant the path takes next.
        for (size_t k = 0; k < path.size(); ++k) {
            const glm::dvec2 at = levelAtlasCoord(root, int(k));
            EXPECT_EQ(int(at.x >= 0.5) + 2 * int(at.y >= 0.5), path[k]) << "level " << k;
        }
    }
}
