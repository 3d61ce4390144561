#include "ToroidalWindow.h"

#include <gtest/gtest.h>

#include <set>

using namespace seasonview;

TEST(ToroidalWindowTest, WrapIsPositiveModulo) {
    EXPECT_EQ(wrapTexel(0, 256), 0);
    EXPECT_EQ(wrapTexel(255, 256), 255);
    EXPECT_EQ(wrapTexel(256, 256), 0);
    EXPECT_EQ(wrapTexel(-1, 256), 255);
    EXPECT_EQ(wrapTexel(-256, 256), 0);
    EXPECT_EQ(wrapTexel(-257, 256), 255);
}

TEST(ToroidalWindowTest, WindowAroundIsEvenAndCentred) {
    const TexelRect w = windowAround({1000.4, 2000.9}, 256);
    EXPECT_EQ(w.width(), 256);
    EXPECT_EQ(w.x0 % 2, 0);
    EXPECT_EQ(w.y0 % 2, 0);
    EXPECT_LE(std::abs((w.x0 + w.x1) / 2.0 - 1000.4), 1.0);
    EXPECT_LE(std::abs((w.y0 + w.y1) / 2.0 - 2000.9), 1.0);
    const TexelRect n = windowAround({-3.0, -700.2}, 64);
    EXPECT_EQ(n.x0 % 2, 0);
    EXPECT_LE(std::abs((n.x0 + n.x1) / 2.0 + 3.0), 1.0);
    const TexelRect b = windowAround({1000.4, -2000.9}, 1024, 64);
    EXPECT_EQ(b.x0 % 64, 0);
    EXPECT_EQ(b.y0 % 64, 0);
    EXPECT_LE(std::abs((b.x0 + b.x1) / 2.0 - 1000.4), 32.0);
    EXPECT_LE(std::abs((b.y0 + b.y1) / 2.0 + 2000.9), 32.0);
}

TEST(ToroidalWindowTest, ExposedStripsAreExactlyTheNewTexels) {
    const TexelRect a{0, 0, 64, 64};
    for (int dx : {-70, -64, -13, -1, 0, 1, 5, 63, 64, 100})
        for (int dy : {-64, -7, 0, 2, 64}) {
            const TexelRect b{a.x0 + dx, a.y0 + dy, a.x1 + dx, a.y1 + dy};
            const auto strips = exposedRects(a, b);
            EXPECT_LE(strips.size(), 2u);
            long long area = 0;
            std::set<std::pair<int, int>> seen;
            for (const auto& s : strips) {
                area += s.area();
                for (int y = s.y0; y < s.y1; ++y)
                    for (int x = s.x0; x < s.x1; ++x) {
                        EXPECT_TRUE(b.contains(x, y));
                        EXPECT_FALSE(a.contains(x, y));
                        EXPECT_TRUE(seen.insert({x, y}).second) << "strips overlap";
                    }
            }
            EXPECT_EQ(area, b.area() - intersect(a, b).area()) << dx << "," << dy;
        }
    EXPECT_TRUE(exposedRects(a, a).empty());
}

TEST(ToroidalWindowTest, PiecesAcrossTheWrapSeam) {
    const int n = 64;
    // A window straddling the seam in both axes: four pieces, each landing where texel mod n says.
    const TexelRect r{60, -3, 60 + n, -3 + n};
    const auto pieces = toroidalPieces(r, n);
    ASSERT_EQ(pieces.size(), 4u);
    std::set<std::pair<int, int>> dest;
    long long area = 0;
    for (const auto& p : pieces) {
        area += p.source.area();
        EXPECT_LE(p.destX + p.source.width(), n);
        EXPECT_LE(p.destY + p.source.height(), n);
        for (int y = p.source.y0; y < p.source.y1; ++y)
            for (int x = p.source.x0; x < p.source.x1; ++x) {
                const int tx = p.destX + (x - p.source.x0), ty = p.destY + (y - p.source.y0);
                EXPECT_EQ(tx, wrapTexel(x, n));
                EXPECT_EQ(ty, wrapTexel(y, n));
                EXPECT_TRUE(dest.insert({tx, ty}).second);
            }
    }
    EXPECT_EQ(area, (long long)n * n);
    EXPECT_EQ(dest.size(), size_t(n) * n) << "every texture texel written exactly once";
    // Aligned with the texture: one piece.
    EXPECT_EQ(toroidalPieces({128, 64, 192, 128}, n).size(), 1u);
    // A strip one texel wide at the seam.
    const auto strip = toroidalPieces({63, 10, 65, 11}, n);
    ASSERT_EQ(strip.size(), 2u);
    EXPECT_EQ(strip[0].destX, 63);
    EXPECT_EQ(strip[1].destX, 0);
}
