// BlockMaps (city/BlockMap.h; Cignoni et al. 2007 §3): construction from a model's triangles, the CPU ray traversal
// against the exact intersection with the prisms it was built from (a box, an L-shaped building, a courtyard,
// buildings of different heights in one block), the distance map's leaping against stepping every texel, the wall
// columns' colours and normals, and the file: round trip, truncated, damaged and foreign files refused with one line.
#include "BlockMap.h"
#include "PrismCity.h"
#include "Raster.h"
#include "TextureSource.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <fstream>
#include <random>

using namespace seasonview;
using namespace seasonview::city;

namespace {

using test::Prism;

// The side each triangle of the last model lies on (prismModel's faceOf), for the colour callback.
std::vector<int> g_faceOf;

CityModel modelOf(const std::vector<Prism>& prisms) { return test::prismModel(prisms, &g_faceOf); }

const glm::dvec3 kFaceColour[5] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}, {0.5, 0.5, 0.5}};

BlockMap build(const std::vector<Prism>& prisms, int size = 32, double side = 32.0) {
    const CityModel model = modelOf(prisms);
    BlockMapOptions o;
    o.size = size;
    o.wallTexels = 8;
    auto m = buildBlockMap(model, {0.0, 0.0}, side, o,
                           [](std::size_t tri, const glm::dvec3&) { return kFaceColour[g_faceOf[tri]]; });
    EXPECT_TRUE(m) << m.message();
    return m ? *m : BlockMap{};
}

struct Exact {
    BlockMapHit::Kind kind = BlockMapHit::Kind::None;
    double t = 0.0;
    glm::dvec3 normal{0.0};
};

// The nearest entry of the ray into any prism (t > 0); rays from above the ground only.
Exact exactHit(const std::vector<Prism>& prisms, glm::dvec3 o, glm::dvec3 d) {
    Exact best;
    best.t = 1e300;
    for (const Prism& p : prisms) {
        double t0 = 0.0, t1 = 1e300;
        int axis = -1;
        const double lo[3] = {p.x0, p.y0, p.base}, hi[3] = {p.x1, p.y1, p.top};
        bool miss = false;
        for (int a = 0; a < 3; ++a) {
            if (d[a] == 0.0) {
                if (o[a] < lo[a] || o[a] > hi[a]) miss = true;
                continue;
            }
            double ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
            if (ta > tb) std::swap(ta, tb);
            if (ta > t0) {
                t0 = ta;
                axis = a;
            }
            t1 = std::min(t1, tb);
        }
        if (miss || t0 > t1 || axis < 0 || t0 >= best.t) continue;
        best.t = t0;
        best.kind = axis == 2 ? BlockMapHit::Kind::Roof : BlockMapHit::Kind::Wall;
        best.normal = glm::dvec3(0.0);
        best.normal[axis] = d[axis] > 0.0 ? -1.0 : 1.0;
    }
    if (best.t == 1e300) best = Exact{};
    return best;
}

// Random rays from above and around the block, towards points in it.
void expectExact(const std::vector<Prism>& prisms, const char* what) {
    const BlockMap m = build(prisms);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    int hits = 0, walls = 0, roofs = 0;
    for (int i = 0; i < 4000; ++i) {
        const double azimuth = 6.283185307179586 * u(rng), elevation = 0.05 + 1.4 * u(rng), dist = 40.0 + 60.0 * u(rng);
        const glm::dvec3 target(32.0 * u(rng), 32.0 * u(rng), 12.0 * u(rng));
        const glm::dvec3 o = target + dist * glm::dvec3(std::cos(elevation) * std::cos(azimuth),
                                                        std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
        const glm::dvec3 d = glm::normalize(target - o);
        const Exact e = exactHit(prisms, o, d);
        for (bool leap : {true, false}) {
            const BlockMapHit h = traceBlockMap(m, o, d, leap);
            ASSERT_EQ(int(h.kind), int(e.kind)) << what << " ray " << i << (leap ? " leaping" : " stepping");
            if (e.kind == BlockMapHit::Kind::None) continue;
            EXPECT_NEAR(h.t, e.t, 1e-9 * dist) << what << " ray " << i;
            EXPECT_EQ(h.normal, e.normal) << what << " ray " << i;
            if (h.kind == BlockMapHit::Kind::Wall) {
                EXPECT_GE(h.column, 0) << what << " ray " << i; // a wall is always a boundary texel's
                EXPECT_GE(h.v, 0.0);
                EXPECT_LE(h.v, 1.0);
            }
        }
        hits += e.kind != BlockMapHit::Kind::None;
        walls += e.kind == BlockMapHit::Kind::Wall;
        roofs += e.kind == BlockMapHit::Kind::Roof;
    }
    // The rays exercise every case.
    EXPECT_GT(walls, 100) << what;
    EXPECT_GT(roofs, 100) << what;
    EXPECT_GT(4000 - hits, 100) << what;
}

// An untextured triangle of building 0 added to `model`.
void addTriangle(CityModel& model, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c, Surface surface) {
    TexturedTriangle t;
    t.v = {a, b, c};
    t.texture = -1;
    model.triangles.push_back(t);
    model.building.push_back(0);
    model.surface.push_back(surface);
}

} // namespace

// Heights on the grid of the block's range (25.5 m / 65535: 0.1 m is 257 steps), walls on texel edges (1 m): the BlockMap
// is then the prisms exactly, and every ray must meet what they meet.
TEST(BlockMapTest, BoxMatchesTheExactIntersection) { expectExact({{8, 10, 20, 18, 25.5}}, "box"); }

TEST(BlockMapTest, LShapedBuildingMatchesTheExactIntersection) {
    expectExact({{4, 4, 24, 12, 25.5}, {4, 12, 12, 28, 25.5}}, "L");
}

TEST(BlockMapTest, CourtyardMatchesTheExactIntersection) {
    // A ring of four wings around an open court: rays into the court reach the ground (nothing) or the inner walls.
    expectExact({{4, 4, 28, 10, 25.5}, {4, 22, 28, 28, 25.5}, {4, 10, 10, 22, 25.5}, {22, 10, 28, 22, 25.5}}, "court");
}

TEST(BlockMapTest, BuildingsOfDifferentHeightsMatchTheExactIntersection) {
    // Touching buildings of different heights: the taller one's wall above the lower roof is hit, the shared wall
    // below it is not.
    expectExact({{2, 2, 14, 14, 25.5}, {14, 2, 26, 14, 12.3}, {2, 16, 9, 30, 7.0}, {20, 20, 30, 30, 18.8}}, "heights");
}

// Outlines between the texels' edges (on sixteenths of the 1 m texels): the texels' parts (BlockMap::rect) end the
// prisms where the buildings end, so every ray still meets what the polygons meet. Buildings that touch meet on a
// texel's edge; two buildings in one texel with a street between them are its two prisms (BlockMap::rect2, height2).
TEST(BlockMapTest, OutlinesOffTheGridMatchTheExactIntersection) {
    expectExact({{8.25, 10.5, 20.75, 18.125, 25.5}}, "box off the grid");
    expectExact({{4.375, 4.0625, 24.5, 12.0, 25.5}, {4.375, 12.0, 12.25, 28.6875, 25.5}}, "L off the grid");
    expectExact({{2.5, 2.25, 13.75, 13.5, 25.5}, {15.25, 2.5, 25.5, 13.75, 12.3}, {2.125, 16.5, 9.875, 29.5, 7.0},
                 {20.5, 20.25, 29.75, 30.5, 18.8, 2.5}},
                "heights off the grid");
    // Gaps of half a texel inside texels 12 (across x) and 20 (across y), the buildings either side of different
    // heights, and a lower one taller than its neighbour across the gap.
    expectExact({{4.25, 4, 12.25, 12, 25.5}, {12.75, 4, 20, 12, 12.3}, {4, 14.125, 12, 20.5, 7.0},
                 {4, 20.875, 12, 28, 18.8}, {20.5, 20.3125, 28, 28, 9.1}},
                "two buildings in a texel");
}

TEST(BlockMapTest, TexelsPartsFollowTheOutlines) {
    const BlockMap m = build({{8.5, 10.25, 20.0, 18.0, 25.5}, {23.98, 4.0, 28.0, 8.0, 12.3}});
    ASSERT_EQ(m.rect.size(), std::size_t(32 * 32));
    // From x = 8.5 the building stands on the right half of texel column 8, from y = 10.25 on three quarters of row 10.
    ASSERT_GT(m.heightAt(8, 12), 0);
    TexelPart p = texelPart(m.rectAt(8, 12));
    EXPECT_EQ(p.lo, glm::dvec2(0.5, 0.0));
    EXPECT_EQ(p.hi, glm::dvec2(1.0, 1.0));
    p = texelPart(m.rectAt(8, 10));
    EXPECT_EQ(p.lo, glm::dvec2(0.5, 0.25));
    EXPECT_EQ(p.hi, glm::dvec2(1.0, 1.0));
    EXPECT_EQ(m.rectAt(12, 12), BlockMap::kWholeTexel);
    EXPECT_EQ(m.rectAt(19, 17), BlockMap::kWholeTexel) << "an outline on the texels' edge";
    EXPECT_EQ(m.heightAt(7, 12), 0);
    // Walls stand where the outline is: the part's texels carry the columns, the whole ones inside them none.
    EXPECT_GT(m.column[std::size_t(12) * 32 + 8], 0u);
    EXPECT_EQ(m.column[std::size_t(12) * 32 + 9], 0u);
    EXPECT_EQ(m.distance[std::size_t(12) * 32 + 8], 0);
    EXPECT_EQ(m.distance[std::size_t(12) * 32 + 7], 1);
    // Under half a sixteenth of a texel (0.02 m of texel 23) is no building; texel 24, from 0.02 m, is whole.
    EXPECT_EQ(m.heightAt(23, 6), 0);
    EXPECT_EQ(m.rectAt(24, 6), BlockMap::kWholeTexel);
    // A level ray along row 12 meets the wall at x = 8.5, not at the texel's edge.
    const BlockMapHit h = traceBlockMap(m, {-5.0, 12.5, 10.0}, {1.0, 0.0, 0.0});
    ASSERT_EQ(int(h.kind), int(BlockMapHit::Kind::Wall));
    EXPECT_NEAR(h.point.x, 8.5, 1e-9);
    EXPECT_EQ(h.normal, glm::dvec3(-1.0, 0.0, 0.0));
    EXPECT_EQ(h.texel, glm::ivec2(8, 12));
    // A ray down past the wall's foot of the part, beside it: the ground, not the texel's empty half.
    const BlockMapHit g = traceBlockMap(m, {8.25, 12.5, 30.0}, {0.0, 0.0, -1.0});
    EXPECT_EQ(int(g.kind), int(BlockMapHit::Kind::None));
    EXPECT_EQ(m.height2At(8, 12), 0) << "one prism";
}

TEST(BlockMapTest, TwoBuildingsInATexelAreTwoPrisms) {
    // Texel column 12 holds the taller building's last quarter and the lower one's first, a half-metre street between.
    const BlockMap m = build({{4.25, 4, 12.25, 12, 25.5}, {12.75, 4, 20, 12, 12.3}});
    EXPECT_NEAR(m.topAt(12, 8), 25.5, 1e-9) << "the taller is the first";
    TexelPart p = texelPart(m.rectAt(12, 8));
    EXPECT_EQ(p.lo, glm::dvec2(0.0, 0.0));
    EXPECT_EQ(p.hi, glm::dvec2(0.25, 1.0));
    ASSERT_EQ(m.height2At(12, 8), 123 * 257); // 12.3 m of 25.5
    p = texelPart(m.rect2At(12, 8));
    EXPECT_EQ(p.lo, glm::dvec2(0.75, 0.0));
    EXPECT_EQ(p.hi, glm::dvec2(1.0, 1.0));
    EXPECT_GT(m.column[std::size_t(8) * 32 + 12], 0u) << "the street's walls have a column";
    // Down into the street: the ground; onto either roof: that roof, at its height.
    EXPECT_EQ(int(traceBlockMap(m, {12.5, 8.5, 30.0}, {0.0, 0.0, -1.0}).kind), int(BlockMapHit::Kind::None));
    const BlockMapHit low = traceBlockMap(m, {12.875, 8.5, 30.0}, {0.0, 0.0, -1.0});
    ASSERT_EQ(int(low.kind), int(BlockMapHit::Kind::Roof));
    EXPECT_NEAR(low.point.z, 12.3, 1e-9);
    // Level from +x at 10 m: the lower building's wall at x = 20; at 20 m, over it, the taller one's across the
    // street at x = 12.25, in the texel's column at its height.
    const BlockMapHit low10 = traceBlockMap(m, {30.0, 8.5, 10.0}, {-1.0, 0.0, 0.0});
    ASSERT_EQ(int(low10.kind), int(BlockMapHit::Kind::Wall));
    EXPECT_NEAR(low10.point.x, 20.0, 1e-9);
    const BlockMapHit above = traceBlockMap(m, {30.0, 8.5, 20.0}, {-1.0, 0.0, 0.0});
    ASSERT_EQ(int(above.kind), int(BlockMapHit::Kind::Wall));
    EXPECT_NEAR(above.point.x, 12.25, 1e-9);
    EXPECT_EQ(above.texel, glm::ivec2(12, 8));
    EXPECT_NEAR(above.v, 20.0 / 25.5, 1e-9);
    EXPECT_EQ(above.normal, glm::dvec3(1.0, 0.0, 0.0));
    // Level from the street's middle towards +x at 5 m: the lower building's wall across the street.
    const BlockMapHit inStreet = traceBlockMap(m, {12.5, 8.5, 5.0}, {1.0, 0.0, 0.0});
    ASSERT_EQ(int(inStreet.kind), int(BlockMapHit::Kind::Wall));
    EXPECT_NEAR(inStreet.point.x, 12.75, 1e-9);
    EXPECT_NEAR(inStreet.v, 5.0 / 12.3, 1e-6) << "the lower prism's height in the column";
}

// A shed roof (one plane, rising 4 m over 8 m) on a building off the grid: each texel's top is the roof's plane
// (BlockMap::roofNormal through its height at the texel's centre), so rays meet the roof where the polygons are, to
// the normal's 8 bits (steps of texels would be up to 0.25 m off), and the walls up to the slope.
TEST(BlockMapTest, SlopedRoofsAreTheirPlanes) {
    const double x0 = 8.25, x1 = 20.5, y0 = 10.5, y1 = 18.5, low = 10.0, high = 14.0;
    CityModel model;
    test::addSlopedBuilding(model, x0, y0, x1, y1, low, high, false);
    BlockMapOptions o;
    o.size = 32;
    o.wallTexels = 8;
    auto built =
        buildBlockMap(model, {0.0, 0.0}, 32.0, o, [](std::size_t, const glm::dvec3&) { return glm::dvec3(0.5); });
    ASSERT_TRUE(built) << built.message();
    const BlockMap& m = *built;
    const double slope = (high - low) / (y1 - y0);
    EXPECT_NEAR(m.roofSlopeAt(14, 14).y, slope, 0.01);
    EXPECT_NEAR(m.roofSlopeAt(14, 14).x, 0.0, 1e-12);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    int roofs = 0, walls = 0, mismatched = 0;
    double worstRoof = 0.0, worstWall = 0.0;
    for (int i = 0; i < 4000; ++i) {
        const double azimuth = 6.283185307179586 * u(rng), elevation = 0.2 + 1.3 * u(rng), dist = 40.0 + 60.0 * u(rng);
        const glm::dvec3 target(x0 - 1.0 + (x1 - x0 + 2.0) * u(rng), y0 - 1.0 + (y1 - y0 + 2.0) * u(rng),
                                16.0 * u(rng));
        const glm::dvec3 orig =
            target + dist * glm::dvec3(std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
                                       std::sin(elevation));
        const glm::dvec3 d = glm::normalize(target - orig);
        // The exact entry into the building: its box from the ground up, under the roof's plane.
        double t0 = 0.0, t1 = 1e300;
        int axis = -1;
        const double lo[3] = {x0, y0, 0.0}, hi[3] = {x1, y1, 1e9};
        for (int a = 0; a < 3; ++a) {
            double ta = (lo[a] - orig[a]) / d[a], tb = (hi[a] - orig[a]) / d[a];
            if (ta > tb) std::swap(ta, tb);
            if (ta > t0) {
                t0 = ta;
                axis = a;
            }
            t1 = std::min(t1, tb);
        }
        const double num = low + slope * (orig.y - y0) - orig.z, den = d.z - slope * d.y; // z <= low + slope (y - y0)
        if (den < 0.0 && num / den > t0) {
            t0 = num / den;
            axis = 3;
        } else if (den > 0.0) {
            t1 = std::min(t1, num / den);
        }
        const BlockMapHit::Kind kind = !(t0 <= t1 && axis >= 0) ? BlockMapHit::Kind::None
                                       : axis == 3                 ? BlockMapHit::Kind::Roof
                                                                   : BlockMapHit::Kind::Wall;
        const BlockMapHit h = traceBlockMap(m, orig, d);
        if (h.kind != kind) {
            ++mismatched;
            continue;
        }
        if (kind == BlockMapHit::Kind::None) continue;
        roofs += kind == BlockMapHit::Kind::Roof;
        walls += kind == BlockMapHit::Kind::Wall;
        // A roof hit's height against the roof's there (heights are steps of 14 m / 65535, the normal's 8 bits
        // tilt the plane a little); a wall's place along the ray.
        if (kind == BlockMapHit::Kind::Roof)
            worstRoof = std::max(worstRoof, std::abs(h.point.z - (low + slope * (h.point.y - y0))));
        else worstWall = std::max(worstWall, std::abs(h.t - t0));
    }
    // A ray grazing an edge may meet the roof or the wall it tops.
    EXPECT_LT(mismatched, 40) << mismatched << " of 4000";
    EXPECT_LT(worstRoof, 0.04) << "metres";
    EXPECT_LT(worstWall, 0.05) << "metres along the ray";
    EXPECT_GT(roofs, 500);
    EXPECT_GT(walls, 500);
}

// A texel across a gable's ridge: its roof is the plane that fits both slopes over it best (least squares), level at
// their mean there, not one slope continued past the ridge (on the far side as high as the ridge, where the block's
// top stops it).
TEST(BlockMapTest, ARidgesTexelIsThePlaneThatFitsItsRoofs) {
    const double x0 = 4.0, x1 = 28.0, y0 = 4.0, y1 = 16.0, low = 10.0, high = 14.0; // the ridge at y = 10
    CityModel model;
    test::addSlopedBuilding(model, x0, y0, x1, y1, low, high, true);
    BlockMapOptions o;
    o.size = 8; // 4 m texels: the row y = 8..12 has the ridge along its middle
    o.wallTexels = 8;
    auto built =
        buildBlockMap(model, {0.0, 0.0}, 32.0, o, [](std::size_t, const glm::dvec3&) { return glm::dvec3(0.5); });
    ASSERT_TRUE(built) << built.message();
    const BlockMap& m = *built;
    const double slope = (high - low) / (0.5 * (y1 - y0));
    for (int x = 2; x <= 5; ++x) {
        SCOPED_TRACE(x);
        EXPECT_NEAR(m.roofSlopeAt(x, 2).y, 0.0, 0.02) << "level across the ridge";
        // The mean over 4 × 4 points of the texel: 14 − slope · mean |y − 10| = 14 − slope · 1.
        EXPECT_NEAR(m.topAt(x, 2), high - slope * 1.0, 0.06);
        EXPECT_NEAR(m.roofSlopeAt(x, 1).y, slope, 0.02) << "one slope: its plane";
    }
    // Down onto the ridge's texels: the maps' roof as much above the slopes as below them (one slope continued, under
    // the block's top: a third of a metre above on average).
    double err = 0.0;
    int n = 0;
    for (double x = 8.25; x < 24.0; x += 0.5)
        for (double y = 8.125; y < 12.0; y += 0.25) {
            const BlockMapHit h = traceBlockMap(m, {x, y, 100.0}, {0.0, 0.0, -1.0});
            ASSERT_EQ(h.kind, BlockMapHit::Kind::Roof) << x << ", " << y;
            err += h.point.z - (high - slope * std::abs(y - 10.0));
            ++n;
        }
    EXPECT_NEAR(err / n, 0.0, 0.1) << "metres";
}

TEST(BlockMapTest, RaisedBuildingsEndAtTheirFeet) {
    // Buildings standing higher than the block's floor (on a slope): their walls end at their feet, and a ray below
    // a foot passes under the building (in the ground there) to what is behind, as under the polygons. Two texels
    // of street around the raised ones, so no lower neighbour's walls lower their feet.
    const std::vector<Prism> prisms = {{2, 2, 12, 12, 20.0}, {16, 4, 28, 12, 22.4, 6.0}, {4, 17, 11, 29, 17.1, 9.3},
                                       {16, 17, 30, 30, 25.5, 2.5}};
    const BlockMap m = build(prisms);
    EXPECT_DOUBLE_EQ(m.footAt(20, 8), 6.0) << "an inner texel's foot is its building's";
    EXPECT_DOUBLE_EQ(m.footAt(16, 8), 6.0);
    EXPECT_DOUBLE_EQ(m.footAt(5, 5), 0.0);
    expectExact(prisms, "raised");
    // Level rays under the raised building: below the foot of the one behind it too, nothing; above that, its wall.
    const BlockMapHit h = traceBlockMap(m, {22.0, -10.0, 2.0}, {0.0, 1.0, 0.0});
    EXPECT_EQ(int(h.kind), int(BlockMapHit::Kind::None));
    const BlockMapHit g = traceBlockMap(m, {20.0, -10.0, 4.0}, {0.0, 1.0, 0.0});
    ASSERT_EQ(int(g.kind), int(BlockMapHit::Kind::Wall));
    EXPECT_NEAR(g.point.y, 17.0, 1e-9) << "under the raised building to the wall of the one behind";
    // A ray rising from under the raised building into it (from under the ground) meets nothing, not the inside of
    // its prisms (whose texels have no wall column).
    const BlockMapHit r = traceBlockMap(m, {22.0, -10.0, 1.0}, glm::normalize(glm::dvec3(0.0, 1.0, 0.3)));
    EXPECT_EQ(int(r.kind), int(BlockMapHit::Kind::None));
}

// Two buildings with a street of 0.6 m between them, narrower than half a 2 m texel, the one on the right standing
// lower (on a slope): the left one's walls facing the street are its own colour, not the back of its neighbour's
// wall that the column's rays, starting from the next texel's middle, meet first, and its feet stay its own, not its
// neighbour's lower ones (which would hang its walls below it where no terrain hides them).
TEST(BlockMapTest, NeighboursAcrossANarrowStreetKeepTheirOwnWallsAndFeet) {
    const std::vector<Prism> prisms = {{2, 4, 10, 28, 20.0, 6.0}, {10.6, 4, 20, 28, 18.0, 0.0}};
    CityModel model = modelOf(prisms);
    ASSERT_EQ(model.triangles.size(), std::size_t(20));
    for (std::size_t i = 10; i < 20; ++i) model.building[i] = 1;
    model.buildingIds = {"left", "right"};
    BlockMapOptions o;
    o.size = 16;
    o.wallTexels = 8;
    const auto colour = [](std::size_t tri, const glm::dvec3&) { return kFaceColour[g_faceOf[tri]]; };
    auto m = buildBlockMap(model, {0.0, 0.0}, 32.0, o, colour);
    ASSERT_TRUE(m) << m.message();
    const double step = (m->zTop - m->zBase) / BlockMap::kHeightSteps;
    const std::uint32_t c = m->column[std::size_t(8) * 16 + 4]; // the left building's texel on the street
    ASSERT_GT(c, 0u);
    for (int j : {3, 5, 7}) {
        const std::size_t at = (std::size_t(c - 1) * 8 + std::size_t(j)) * 4;
        EXPECT_EQ(glm::ivec3(m->wallRgba[at], m->wallRgba[at + 1], m->wallRgba[at + 2]), glm::ivec3(0, 255, 0))
            << "its own +x wall (green), not the neighbour's -x one (red), at " << j;
    }
    for (int y : {2, 8, 13}) {
        EXPECT_NEAR(m->footAt(4, y), 6.0, 0.5 * step + 1e-9) << "the left building's foot on the street, row " << y;
        EXPECT_NEAR(m->footAt(2, y), 6.0, 0.5 * step + 1e-9) << "and inside it, row " << y;
    }
    EXPECT_NEAR(m->footAt(7, 8), 0.0, 1e-9) << "the right one's foot";
    // With no buildings told apart (one building), the column sees the neighbour's wall first: the test can fail.
    std::fill(model.building.begin(), model.building.end(), 0u);
    auto merged = buildBlockMap(model, {0.0, 0.0}, 32.0, o, colour);
    ASSERT_TRUE(merged);
    const std::size_t at = (std::size_t(merged->column[std::size_t(8) * 16 + 4] - 1) * 8 + 5) * 4;
    EXPECT_NE(glm::ivec3(merged->wallRgba[at], merged->wallRgba[at + 1], merged->wallRgba[at + 2]), glm::ivec3(0, 255, 0));
    EXPECT_NEAR(merged->footAt(4, 8), 0.0, 1e-9);
}

// A model that keeps no buildings (an atlas tree's) gets one per set of triangles joined by shared corners.
TEST(BlockMapTest, ConnectedTrianglesAreOneBuilding) {
    CityModel model = modelOf({{0, 0, 4, 4, 10.0}, {4, 0, 8, 4, 12.0}, {10, 0, 14, 4, 10.0}});
    labelConnectedBuildings(model);
    ASSERT_EQ(model.building.size(), std::size_t(30));
    EXPECT_EQ(model.buildingIds.size(), std::size_t(2)) << "the two touching prisms are one";
    for (std::size_t i = 0; i < 20; ++i) EXPECT_EQ(model.building[i], model.building[0]) << i;
    for (std::size_t i = 20; i < 30; ++i) EXPECT_EQ(model.building[i], model.building[20]) << i;
    EXPECT_NE(model.building[0], model.building[20]);
}

TEST(BlockMapTest, LeapingVisitsFewerTexels) {
    const std::vector<Prism> prisms = {{28, 28, 31, 31, 25.5}};
    const BlockMap m = build(prisms);
    // A grazing ray across the empty block to the one building in its corner.
    const glm::dvec3 o(-5.0, -4.0, 20.0), d = glm::normalize(glm::dvec3(29.5, 29.5, 10.0) - o);
    const BlockMapHit leap = traceBlockMap(m, o, d, true), step = traceBlockMap(m, o, d, false);
    ASSERT_EQ(int(step.kind), int(BlockMapHit::Kind::Wall));
    EXPECT_EQ(int(leap.kind), int(step.kind));
    EXPECT_DOUBLE_EQ(leap.t, step.t);
    EXPECT_LT(leap.texelsVisited * 3, step.texelsVisited) << leap.texelsVisited << " vs " << step.texelsVisited;
}

TEST(BlockMapTest, HeightsDistancesAndColumns) {
    const BlockMap m = build({{8, 10, 20, 18, 25.5}, {20, 10, 24, 14, 12.3}});
    ASSERT_EQ(m.size, 32);
    EXPECT_DOUBLE_EQ(m.zBase, 0.0);
    EXPECT_DOUBLE_EQ(m.zTop, 25.5);
    EXPECT_EQ(m.heightAt(8, 10), BlockMap::kHeightSteps);
    EXPECT_EQ(m.heightAt(19, 17), BlockMap::kHeightSteps);
    EXPECT_EQ(m.heightAt(21, 11), 123 * 257); // 12.3 m of 25.5
    EXPECT_NEAR(m.topAt(21, 11), 12.3, 1e-9);
    EXPECT_EQ(m.heightAt(7, 10), 0);
    EXPECT_EQ(m.heightAt(20, 14), 0);
    // Chebyshev distance to the nearest building texel.
    EXPECT_EQ(m.distance[std::size_t(12) * 32 + 10], 0);
    EXPECT_EQ(m.distance[std::size_t(12) * 32 + 7], 1);
    EXPECT_EQ(m.distance[std::size_t(2) * 32 + 2], 8); // (2, 2) to (8, 10): max(6, 8)
    // Boundary texels have columns, inner ones none; the lower building's texels next to the taller one are boundary
    // texels all the same (their other sides), the taller one's texels against it are boundary texels (its wall
    // shows above the lower roof).
    EXPECT_EQ(m.column[std::size_t(12) * 32 + 12], 0u);
    EXPECT_GT(m.column[std::size_t(12) * 32 + 8], 0u);
    EXPECT_GT(m.column[std::size_t(11) * 32 + 19], 0u);
    std::size_t boundary = 0;
    for (std::uint32_t c : m.column) boundary += c > 0;
    EXPECT_EQ(boundary, std::size_t(m.columns()));
}

TEST(BlockMapTest, WallColumnsShowTheirSidesColours) {
    const BlockMap m = build({{8, 10, 20, 18, 25.5}});
    auto rgbOf = [&](int x, int y, int j) {
        const std::uint32_t c = m.column[std::size_t(y) * 32 + std::size_t(x)];
        EXPECT_GT(c, 0u) << x << "," << y;
        const std::size_t at = (std::size_t(c - 1) * std::size_t(m.wallTexels) + std::size_t(j)) * 4;
        EXPECT_EQ(m.wallRgba[at + 3], 255) << "all wall";
        return glm::ivec3(m.wallRgba[at], m.wallRgba[at + 1], m.wallRgba[at + 2]);
    };
    auto normalOf = [&](int x, int y) { return m.wallNormal[m.column[std::size_t(y) * 32 + std::size_t(x)] - 1]; };
    // The middle of each side: that side's colour all the way up, its normal outwards.
    for (int j : {0, 3, 7}) {
        EXPECT_EQ(rgbOf(8, 14, j), glm::ivec3(255, 0, 0)) << j;   // -x: red
        EXPECT_EQ(rgbOf(19, 14, j), glm::ivec3(0, 255, 0)) << j;  // +x: green
        EXPECT_EQ(rgbOf(14, 10, j), glm::ivec3(0, 0, 255)) << j;  // -y: blue
        EXPECT_EQ(rgbOf(14, 17, j), glm::ivec3(255, 255, 0)) << j; // +y: yellow
    }
    EXPECT_EQ(normalOf(8, 14), glm::vec3(-1, 0, 0));
    EXPECT_EQ(normalOf(14, 17), glm::vec3(0, 1, 0));
    // A corner texel averages its two sides (red and blue), its normal between them.
    EXPECT_EQ(rgbOf(8, 10, 4), glm::ivec3(128, 0, 128));
    EXPECT_NEAR(normalOf(8, 10).x, -0.70710678f, 1e-6f);
    EXPECT_NEAR(normalOf(8, 10).y, -0.70710678f, 1e-6f);
    // Every wall runs along the grid: each column is shaded by the side a ray enters by.
    for (std::uint8_t g : m.wallOnGrid) EXPECT_EQ(g, 1);
}

// A building turned 30° from the grid: its walls cross the texels' sides at an angle, so its columns are shaded by
// their normals (a face-by-face shading would stripe its stepped outline), which follow its walls.
TEST(BlockMapTest, WallsAtAnAngleAreOffTheGrid) {
    CityModel model;
    model.buildingIds = {"b"};
    const double a = 30.0 * 3.141592653589793 / 180.0, half = 6.0, top = 10.0;
    std::array<glm::dvec3, 4> c;
    for (int k = 0; k < 4; ++k) {
        const double u = (k == 1 || k == 2) ? half : -half, v = k >= 2 ? half : -half;
        c[std::size_t(k)] = glm::dvec3(16.0 + u * std::cos(a) - v * std::sin(a), 16.0 + u * std::sin(a) + v * std::cos(a), 0.0);
    }
    auto tri = [&](glm::dvec3 p, glm::dvec3 q, glm::dvec3 r) {
        addTriangle(model, p, q, r, p.z == q.z && q.z == r.z ? Surface::Roof : Surface::Wall);
    };
    const glm::dvec3 up(0.0, 0.0, top);
    for (int k = 0; k < 4; ++k) {
        const glm::dvec3 p = c[std::size_t(k)], q = c[std::size_t((k + 1) % 4)];
        tri(p, q, q + up);
        tri(p, q + up, p + up);
    }
    tri(c[0] + up, c[1] + up, c[2] + up);
    tri(c[0] + up, c[2] + up, c[3] + up);
    BlockMapOptions o;
    o.size = 32;
    o.wallTexels = 8;
    auto m = buildBlockMap(model, {0.0, 0.0}, 32.0, o, [](std::size_t, const glm::dvec3&) { return glm::dvec3(0.5); });
    ASSERT_TRUE(m) << m.message();
    ASSERT_GT(m->columns(), 20);
    int off = 0;
    for (std::uint8_t g : m->wallOnGrid) off += g == 0;
    EXPECT_EQ(off, m->columns());
    // Each column is shaded by the walls it shows, not by its texel's exposed sides (the steps: ±x, ±y or between,
    // 15-45° off the walls here): away from the corners, within a degree of the nearest wall's normal.
    int along = 0;
    for (const glm::vec3& nrm : m->wallNormal) {
        double best = -1.0;
        for (int k = 0; k < 4; ++k) {
            const double w = a + double(k) * 3.141592653589793 / 2.0;
            best = std::max(best, double(nrm.x) * std::cos(w - 3.141592653589793 / 2.0) +
                                      double(nrm.y) * std::sin(w - 3.141592653589793 / 2.0));
        }
        along += best > std::cos(1.0 * 3.141592653589793 / 180.0);
    }
    std::printf("%d of %d columns along their walls\n", along, m->columns());
    EXPECT_GE(along * 10, m->columns() * 8);
    // The texels' parts cover what the roof covers (12 × 12 m) within 2 %: their boxes' sides inside the texels stand
    // halfway along the edge across them, not at its outermost point (153 m²: the building grown all round). What is
    // left over: texels whose corner the outline cuts off, whose part touches all four sides and stays whole.
    double covered = 0.0;
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 32; ++x)
            if (m->heightAt(x, y) > 0) {
                const TexelPart p = texelPart(m->rectAt(x, y));
                covered += (p.hi.x - p.lo.x) * (p.hi.y - p.lo.y);
            }
    std::printf("parts cover %.2f m2 of 144\n", covered);
    EXPECT_NEAR(covered, 144.0, 3.0);
}

// A gabled roof (45° slopes, the ridge along x): each texel's roof normal is its slope's, and the steps the slope
// makes between texels are roof in the wall columns (their walls' share 0), while the walls under the eaves are wall.
TEST(BlockMapTest, SlopedRoofsAreShadedAsRoofsAndTheirStepsAreRoof) {
    CityModel model;
    model.buildingIds = {"b"};
    auto tri = [&](glm::dvec3 a, glm::dvec3 b, glm::dvec3 c) { addTriangle(model, a, b, c, Surface::Wall); };
    auto quad = [&](glm::dvec3 a, glm::dvec3 b, glm::dvec3 c, glm::dvec3 d) {
        tri(a, b, c);
        tri(a, c, d);
    };
    const double x0 = 10, x1 = 20, y0 = 10, y1 = 18, eaves = 10, ridge = 14; // the ridge at y = 14
    quad({x0, y0, 0}, {x1, y0, 0}, {x1, y0, eaves}, {x0, y0, eaves});                 // south wall
    quad({x0, y1, 0}, {x1, y1, 0}, {x1, y1, eaves}, {x0, y1, eaves});                 // north wall
    quad({x0, y0, 0}, {x0, y1, 0}, {x0, y1, eaves}, {x0, y0, eaves});                 // west wall
    quad({x1, y0, 0}, {x1, y1, 0}, {x1, y1, eaves}, {x1, y0, eaves});                 // east wall
    tri({x0, y0, eaves}, {x0, y1, eaves}, {x0, 14, ridge});                            // west gable
    tri({x1, y0, eaves}, {x1, y1, eaves}, {x1, 14, ridge});                            // east gable
    quad({x0, y0, eaves}, {x1, y0, eaves}, {x1, 14, ridge}, {x0, 14, ridge});         // south slope
    quad({x0, 14, ridge}, {x1, 14, ridge}, {x1, y1, eaves}, {x0, y1, eaves});         // north slope
    BlockMapOptions o;
    o.size = 32;
    o.wallTexels = 8;
    auto built = buildBlockMap(model, {0.0, 0.0}, 32.0, o, [](std::size_t, const glm::dvec3&) { return glm::dvec3(0.5); });
    ASSERT_TRUE(built) << built.message();
    const BlockMap& m = *built;
    auto normalAt = [&](int x, int y) {
        const std::size_t i = (std::size_t(y) * 32 + std::size_t(x)) * 2;
        return glm::dvec2(m.roofNormal[i], m.roofNormal[i + 1]) / 255.0 * 2.0 - 1.0;
    };
    EXPECT_NEAR(normalAt(15, 11).x, 0.0, 0.01);
    EXPECT_NEAR(normalAt(15, 11).y, -0.7071, 0.01) << "the south slope faces south";
    EXPECT_NEAR(normalAt(15, 16).y, 0.7071, 0.01) << "the north slope faces north";
    auto share = [&](int x, int y, int j) {
        const std::uint32_t c = m.column[std::size_t(y) * 32 + std::size_t(x)];
        EXPECT_GT(c, 0u) << x << "," << y;
        return c > 0 ? int(m.wallRgba[((std::size_t(c) - 1) * std::size_t(m.wallTexels) + std::size_t(j)) * 4 + 3]) : -1;
    };
    // Texel (15, 12) rises 1 m above (15, 11): its column's top texel is the slope between them.
    EXPECT_EQ(share(15, 12, 7), 0);
    // The south wall's column (15, 10): wall below the eaves.
    EXPECT_EQ(share(15, 10, 2), 255);
}

TEST(BlockMapTest, AnEmptyBlockHasNoBuildingsAndEveryRayMisses) {
    const BlockMap m = build({{100, 100, 110, 110, 10}});
    EXPECT_EQ(m.columns(), 0);
    for (std::uint16_t h : m.height) EXPECT_EQ(h, 0);
    EXPECT_EQ(m.distance[0], 255);
    const BlockMapHit h = traceBlockMap(m, {-10, -10, 50}, glm::normalize(glm::dvec3(1, 1, -1)));
    EXPECT_EQ(int(h.kind), int(BlockMapHit::Kind::None));
}

TEST(BlockMapTest, BadOptionsAreRefused) {
    const CityModel model = modelOf({{8, 10, 20, 18, 25.5}});
    auto colour = [](std::size_t, const glm::dvec3&) { return glm::dvec3(0.5); };
    BlockMapOptions o;
    o.size = 1;
    EXPECT_FALSE(buildBlockMap(model, {0, 0}, 32.0, o, colour));
    o.size = 32;
    o.wallTexels = 0;
    EXPECT_FALSE(buildBlockMap(model, {0, 0}, 32.0, o, colour));
    o.wallTexels = 8;
    EXPECT_FALSE(buildBlockMap(model, {0, 0}, 0.0, o, colour));
    EXPECT_TRUE(buildBlockMap(model, {0, 0}, 32.0, o, colour));
}

TEST(BlockMapTest, FilesRoundTripAndDamagedOnesAreRefusedWithOneLine) {
    test::TempDir dir("blockmap-file");
    const std::vector<BlockMap> maps = {build({{8, 10, 20, 18, 25.5}}),
                                        build({{2.25, 2, 14, 14.5, 25.5}, {14, 2, 26.125, 14, 12.3, 1.5}})};
    const auto path = dir / "city.svbm";
    ASSERT_TRUE(writeBlockMaps(path, maps));
    auto back = readBlockMaps(path);
    ASSERT_TRUE(back) << back.message();
    ASSERT_EQ(back->size(), 2u);
    for (std::size_t k = 0; k < 2; ++k) {
        const BlockMap &a = maps[k], &b = (*back)[k];
        EXPECT_EQ(a.size, b.size);
        EXPECT_EQ(a.origin, b.origin);
        EXPECT_EQ(a.zTop, b.zTop);
        EXPECT_EQ(a.height, b.height);
        EXPECT_EQ(a.distance, b.distance);
        EXPECT_EQ(a.column, b.column);
        EXPECT_EQ(a.wallRgba, b.wallRgba);
        EXPECT_EQ(a.roofNormal, b.roofNormal);
        EXPECT_EQ(a.wallNormal, b.wallNormal);
        EXPECT_EQ(a.foot, b.foot);
        EXPECT_EQ(a.wallOnGrid, b.wallOnGrid);
        EXPECT_EQ(a.rect, b.rect);
    }
    EXPECT_NE(maps[1].rect[std::size_t(5) * 32 + 2], BlockMap::kWholeTexel) << "the file holds parts";
    std::ifstream in(path, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    auto refused = [&](const std::string& content, const char* problem) {
        const auto bad = dir / "bad.svbm";
        std::ofstream(bad, std::ios::binary | std::ios::trunc) << content;
        auto r = readBlockMaps(bad);
        ASSERT_FALSE(r) << problem;
        EXPECT_NE(r.message().find(bad.string()), std::string::npos) << r.message();
        EXPECT_NE(r.message().find(problem), std::string::npos) << r.message();
        EXPECT_EQ(r.message().find('\n'), std::string::npos) << r.message();
    };
    for (std::size_t cut : {std::size_t(10), std::size_t(40), bytes.size() / 2, bytes.size() - 1})
        refused(bytes.substr(0, cut), cut < 16 ? "not a BlockMap file" : "truncated");
    std::string flipped = bytes;
    flipped[bytes.size() / 3] = char(flipped[bytes.size() / 3] ^ 0x10);
    refused(flipped, "damaged");
    refused(bytes + "x", "damaged");
    refused("SVATLAS\0 an atlas tree, not BlockMaps", "not a BlockMap file");
    std::string version = bytes;
    version[8] = 9;
    refused(version, "version 9");
    EXPECT_FALSE(readBlockMaps(dir / "missing.svbm"));
}

// Every truncation and every single damaged byte of a file is refused (CRC-32 per map, sizes checked before they are
// allocated), never read as something else or crashed on.
TEST(BlockMapTest, EveryTruncationAndDamagedByteIsRefused) {
    test::TempDir dir("blockmap-damage");
    const auto path = dir / "city.svbm";
    ASSERT_TRUE(writeBlockMaps(path, {build({{8, 10, 20, 18, 25.5}}, 8, 32.0), build({{2, 2, 14, 14, 25.5}}, 8, 32.0)}));
    std::ifstream in(path, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto bad = dir / "bad.svbm";
    auto read = [&](const std::string& content) {
        std::ofstream(bad, std::ios::binary | std::ios::trunc) << content;
        return readBlockMaps(bad);
    };
    for (std::size_t cut = 0; cut < bytes.size(); ++cut) EXPECT_FALSE(read(bytes.substr(0, cut))) << cut;
    for (std::size_t i = 0; i < bytes.size(); ++i) {
        std::string damaged = bytes;
        damaged[i] = char(damaged[i] ^ 0x5a);
        EXPECT_FALSE(read(damaged)) << i;
    }
}

// Written map by map: a writer given up before finish() leaves neither the file nor its temporary.
TEST(BlockMapTest, AnUnfinishedWriterLeavesNothing) {
    test::TempDir dir("blockmap-writer");
    const auto path = dir / "city.svbm";
    {
        auto w = BlockMapWriter::open(path);
        ASSERT_TRUE(w) << w.message();
        ASSERT_TRUE(w->add(build({{8, 10, 20, 18, 25.5}}, 8, 32.0)));
    }
    EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
    auto w = BlockMapWriter::open(path);
    ASSERT_TRUE(w);
    ASSERT_TRUE(w->add(build({{8, 10, 20, 18, 25.5}}, 8, 32.0)));
    ASSERT_TRUE(w->finish());
    auto back = readBlockMaps(path);
    ASSERT_TRUE(back) << back.message();
    EXPECT_EQ(back->size(), 1u);
}

// The texture cache keeps only the mips a BlockMap build can read (setFinestLevels): fewer bytes, the same samples at
// every footprint it is asked for, and the finest kept level for anything finer.
TEST(BlockMapTest, TextureCacheKeepsOnlyTheMipsReadAndSamplesTheSame) {
    test::TempDir dir("blockmap-texcache");
    std::vector<std::uint8_t> px(256 * 256 * 3);
    for (std::size_t i = 0; i < px.size(); ++i) px[i] = std::uint8_t((i * 37) ^ (i >> 7));
    const auto path = dir / "facade.png";
    ASSERT_TRUE(writeImageAtomic(path, px.data(), 256, 256, 3));
    const std::vector<CityTexture> textures = {CityTexture{path.string(), true, 3, 256, 256}};
    TextureCache full(textures, 64 << 20), reduced(textures, 64 << 20);
    reduced.setFinestLevels({3});
    auto a = full.get(0), b = reduced.get(0);
    ASSERT_TRUE(a) << a.message();
    ASSERT_TRUE(b) << b.message();
    EXPECT_EQ((*b)->firstLevel, 3);
    EXPECT_LT(reduced.bytes() * 40, full.bytes()); // 32² and coarser of 256²: about 1/64
    for (double tps : {8.0, 11.0, 16.0, 40.0, 300.0})
        for (glm::dvec2 uv : {glm::dvec2(0.1, 0.2), glm::dvec2(0.77, 0.5), glm::dvec2(1.3, -0.4)})
            EXPECT_EQ((*a)->sample(uv, tps), (*b)->sample(uv, tps)) << tps;
    EXPECT_EQ((*b)->sample({0.3, 0.3}, 1.0), (*a)->sample({0.3, 0.3}, 8.0)); // finer than kept: the finest kept
}
