// The BlockMap quadtree of a city (city/BlockMap.h: BlockMapFile, BlockMapQuadtree) and which maps a view draws
// (city/BlockMapTraversal.h; Cignoni et al. 2007 §4): the cut by projected error, what is left to the polygons, the
// coverage the atlas tree skips, the maps' paging requests, and what the atlas traversal then draws.
#include "AtlasTraversal.h"
#include "AtlasTreeBuild.h"
#include "BlockMap.h"
#include "BlockMapTraversal.h"
#include "Camera.h"
#include "PrismCity.h"
#include "Raster.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <set>

using namespace seasonview;
using namespace seasonview::city;

namespace {

// 16 × 16 prisms, 20 m wide, 10 to 40 m high, on a 64 m grid: a 1,024 m city.
std::vector<test::Prism> gridCity() {
    std::vector<test::Prism> p;
    for (int j = 0; j < 16; ++j)
        for (int i = 0; i < 16; ++i)
            p.push_back({i * 64.0 + 22.0, j * 64.0 + 22.0, i * 64.0 + 42.0, j * 64.0 + 42.0, 10.0 + double((i * 7 + j * 3) % 31)});
    return p;
}

// Its BlockMaps: 16² texels, 2 m leaf texels (32 m leaves, 5 levels below the root).
const std::filesystem::path& cityMaps() {
    static test::TempDir dir("blockmap-traversal");
    static const std::filesystem::path path = [] {
        CityBlockMapSettings s;
        s.map.size = 16;
        s.map.wallTexels = 4;
        s.leafTexel = 2.0;
        auto r = buildCityBlockMaps(test::prismModel(gridCity()), s, dir / "city.svbm");
        EXPECT_TRUE(r) << r.message();
        return dir / "city.svbm";
    }();
    return path;
}

AtlasView viewOf(const Camera& cam, int width = 640, int height = 360) {
    AtlasView v;
    v.eye = cam.position;
    const double aspect = double(width) / height;
    v.viewProj = cam.projectionMatrix(aspect, 0.1) * cam.viewMatrix();
    v.screenWidth = width;
    v.fovXDeg = 2.0 * std::atan(std::tan(cam.fovYDeg * M_PI / 360.0) * aspect) * 180.0 / M_PI;
    return v;
}

Camera street() {
    Camera c;
    c.position = {500.0, 4.0, 1.7};
    c.yawDeg = 0.0;
    c.pitchDeg = -2.0;
    return c;
}

Camera overview() {
    Camera c;
    c.position = {512.0, 512.0, 6000.0};
    c.pitchDeg = -90.0;
    return c;
}

struct Loaded {
    BlockMapFile file;
    BlockMapQuadtree tree;
};

Loaded load() {
    auto f = BlockMapFile::open(cityMaps());
    EXPECT_TRUE(f) << f.message();
    auto q = BlockMapQuadtree::of(*f);
    EXPECT_TRUE(q) << q.message();
    return {*f, *q};
}

} // namespace

TEST(BlockMapTraversalTest, TheFileIsTheCitysQuadtree) {
    const Loaded l = load();
    ASSERT_FALSE(l.tree.nodes.empty());
    EXPECT_EQ(l.tree.depth, 5);
    EXPECT_NEAR(l.tree.rootSide, 1024.0, 1e-6);
    const auto& recs = l.file.records();
    for (std::size_t k = 0; k < l.tree.nodes.size(); ++k) {
        const auto& n = l.tree.nodes[k];
        EXPECT_NEAR(recs[k].side(), l.tree.rootSide / std::ldexp(1.0, n.level), 1e-6) << k;
        if (k == 0) {
            EXPECT_EQ(n.parent, -1);
            continue;
        }
        ASSERT_GE(n.parent, 0) << k;
        const auto& p = l.tree.nodes[std::size_t(n.parent)];
        EXPECT_EQ(p.level + 1, n.level);
        EXPECT_EQ(p.children[std::size_t((n.cell.x & 1) + 2 * (n.cell.y & 1))], std::int32_t(k));
    }
    // Every leaf square with a prism's part has a map: 16 × 16 prisms, each in one 32 m leaf.
    std::size_t leaves = 0;
    for (const auto& n : l.tree.nodes) leaves += n.level == 5 ? 1 : 0;
    EXPECT_EQ(leaves, 256u);
    // A map read equals the one the whole-file reader gives.
    auto all = readBlockMaps(cityMaps());
    ASSERT_TRUE(all) << all.message();
    auto one = l.file.read(7);
    ASSERT_TRUE(one) << one.message();
    EXPECT_EQ(one->height, (*all)[7].height);
    EXPECT_EQ(one->wallRgba, (*all)[7].wallRgba);
    EXPECT_EQ(one->roofNormal, (*all)[7].roofNormal);
}

TEST(BlockMapTraversalTest, MapsThatAreNotAQuadtreeAreRefusedWithOneLine) {
    test::TempDir dir("blockmap-notree");
    BlockMapOptions o;
    o.size = 8;
    const CityModel m = test::prismModel({{2, 2, 6, 6, 10}, {40, 40, 44, 44, 10}});
    auto colour = [](std::size_t, const glm::dvec3&) { return glm::dvec3(0.5); };
    auto root = buildBlockMap(m, {0, 0}, 64.0, o, colour);
    auto stray = buildBlockMap(m, {5, 3}, 32.0, o, colour); // not a quadrant of the root
    ASSERT_TRUE(root && stray);
    ASSERT_TRUE(writeBlockMaps(dir / "bad.svbm", {*root, *stray}));
    auto f = BlockMapFile::open(dir / "bad.svbm");
    ASSERT_TRUE(f) << f.message();
    auto q = BlockMapQuadtree::of(*f);
    ASSERT_FALSE(q);
    EXPECT_NE(q.message().find("bad.svbm"), std::string::npos) << q.message();
    EXPECT_EQ(q.message().find('\n'), std::string::npos);
    // A quadrant whose parent is missing.
    auto orphan = buildBlockMap(m, {32, 32}, 16.0, o, colour);
    ASSERT_TRUE(orphan);
    ASSERT_TRUE(writeBlockMaps(dir / "orphan.svbm", {*root, *orphan}));
    auto f2 = BlockMapFile::open(dir / "orphan.svbm");
    ASSERT_TRUE(f2);
    auto q2 = BlockMapQuadtree::of(*f2);
    ASSERT_FALSE(q2);
    EXPECT_NE(q2.message().find("no parent"), std::string::npos) << q2.message();
}

TEST(BlockMapTraversalTest, TheCutDrawsMapsWithinTheErrorAndLeavesTheNearFieldToPolygons) {
    const Loaded l = load();
    BlockMapTraversal t(l.tree, l.file.records());
    for (double maxError : {1.0, 2.0, 4.0}) {
        const AtlasView v = viewOf(street());
        const BlockMapCut c = t.cut(v, maxError);
        EXPECT_GT(c.drawn.size(), 0u) << maxError;
        EXPECT_GT(c.polygonNodes, 0u) << maxError;
        EXPECT_EQ(c.notResident, 0u);
        double last = 0.0;
        for (std::uint32_t k : c.drawn) {
            EXPECT_EQ(c.use[k], BlockMapUse::BlockMap);
            EXPECT_LE(t.errorPx(k, v), maxError) << k;
            EXPECT_GE(t.distance(k, v), last) << "nearest first";
            last = t.distance(k, v);
        }
        for (std::uint32_t k = 0; k < c.use.size(); ++k) {
            const auto& n = l.tree.nodes[k];
            if ((c.use[k] == BlockMapUse::BlockMap || c.use[k] == BlockMapUse::Refined ||
                 c.use[k] == BlockMapUse::Polygons) && n.parent >= 0) {
                EXPECT_EQ(c.use[std::size_t(n.parent)], BlockMapUse::Refined) << k;
            }
            if (c.use[k] == BlockMapUse::Refined) {
                EXPECT_GT(t.errorPx(k, v), maxError) << k;
            }
            if (c.use[k] == BlockMapUse::Polygons) {
                EXPECT_GT(t.errorPx(k, v), maxError) << k;
                EXPECT_EQ(n.level, l.tree.depth) << "only leaves are too coarse";
            }
        }
        // Around the eye the polygons draw; far ahead the maps cover everything.
        EXPECT_EQ(t.coverage(c, {490, 0, 0}, {530, 40, 30}), Coverage::None);
        EXPECT_EQ(t.coverage(c, {400, 700, 0}, {600, 1000, 30}), Coverage::Full);
        EXPECT_EQ(t.coverage(c, {480, 0, 0}, {540, 1000, 30}), Coverage::Partial);
        EXPECT_EQ(t.coverage(c, {-50, 700, 0}, {40, 800, 30}), Coverage::Partial) << "outside the root square";
    }
    // A finer error bound leaves more to the polygons.
    EXPECT_GT(t.cut(viewOf(street()), 1.0).polygonNodes, t.cut(viewOf(street()), 4.0).polygonNodes);
    // The overview: a few maps, no polygons, everything covered.
    const BlockMapCut o = t.cut(viewOf(overview()), 1.0);
    EXPECT_EQ(o.polygonNodes, 0u);
    EXPECT_GT(o.drawn.size(), 0u);
    EXPECT_LE(o.drawn.size(), 16u) << "16 m texels are 0.8 px from 6 km";
    EXPECT_EQ(t.coverage(o, {30, 30, 0}, {1000, 1000, 50}), Coverage::Full);
}

TEST(BlockMapTraversalTest, MapsNotResidentAreLeftToThePolygons) {
    const Loaded l = load();
    BlockMapTraversal t(l.tree, l.file.records());
    const AtlasView v = viewOf(street());
    const BlockMapCut all = t.cut(v, 1.0);
    // The even maps of the cut, with every map above and below them, not resident: nothing can stand in.
    std::set<std::uint32_t> loading;
    std::function<void(std::uint32_t)> below = [&](std::uint32_t k) {
        loading.insert(k);
        for (std::int32_t ch : l.tree.nodes[k].children)
            if (ch >= 0) below(std::uint32_t(ch));
    };
    std::size_t even = 0;
    for (std::uint32_t k : all.drawn)
        if (k % 2 == 0) {
            ++even;
            below(k);
            for (std::int32_t a = l.tree.nodes[k].parent; a >= 0; a = l.tree.nodes[std::size_t(a)].parent)
                loading.insert(std::uint32_t(a));
        }
    ASSERT_GT(even, 0u);
    const BlockMapCut odd = t.cut(v, 1.0, [&](std::uint32_t k) { return !loading.count(k); });
    EXPECT_EQ(odd.notResident, even);
    EXPECT_EQ(odd.standIns, 0u);
    EXPECT_EQ(odd.polygonNodes, all.polygonNodes + even);
    EXPECT_EQ(odd.drawn.size() + even, all.drawn.size());
    for (std::uint32_t k : all.drawn) {
        if (k % 2 != 0) continue;
        EXPECT_EQ(odd.use[k], BlockMapUse::Polygons);
        EXPECT_EQ(t.coverage(odd, t.boxMin(k), t.boxMax(k)), Coverage::None) << k;
        EXPECT_EQ(t.coverage(all, t.boxMin(k), t.boxMax(k)), Coverage::Full) << k;
    }
}

// A map loading while its children's are resident (the eye moving away) is drawn with theirs; a map loading whose
// parent's is resident and at most twice too coarse (the eye coming nearer) is drawn with its parent's.
TEST(BlockMapTraversalTest, ResidentChildrenOrParentStandInForAMapLoading) {
    const Loaded l = load();
    BlockMapTraversal t(l.tree, l.file.records());
    const AtlasView o = viewOf(overview());
    std::optional<std::uint32_t> inner, nearParent;
    for (std::uint32_t k : t.cut(o, 1.0).drawn) {
        const auto& n = l.tree.nodes[k];
        if (!inner && std::any_of(n.children.begin(), n.children.end(), [](std::int32_t c) { return c >= 0; })) inner = k;
        if (!nearParent && n.parent >= 0 && t.errorPx(std::uint32_t(n.parent), o) <= 2.0) nearParent = k;
    }
    ASSERT_TRUE(inner && nearParent);
    // Children stand in.
    const BlockMapCut away = t.cut(o, 1.0, [&](std::uint32_t k) { return k != *inner; });
    EXPECT_EQ(away.use[*inner], BlockMapUse::Refined);
    EXPECT_EQ(away.notResident, 0u);
    EXPECT_GE(away.standIns, 1u);
    EXPECT_EQ(t.coverage(away, t.boxMin(*inner), t.boxMax(*inner)), Coverage::Full);
    // The parent stands in: the map and everything under it loading.
    std::set<std::uint32_t> loading;
    std::function<void(std::uint32_t)> below = [&](std::uint32_t k) {
        loading.insert(k);
        for (std::int32_t ch : l.tree.nodes[k].children)
            if (ch >= 0) below(std::uint32_t(ch));
    };
    below(*nearParent);
    const BlockMapCut nearer = t.cut(o, 1.0, [&](std::uint32_t k) { return !loading.count(k); });
    const auto parent = std::uint32_t(l.tree.nodes[*nearParent].parent);
    EXPECT_EQ(nearer.use[parent], BlockMapUse::BlockMap);
    EXPECT_GE(nearer.standIns, 1u);
    EXPECT_EQ(t.coverage(nearer, t.boxMin(*nearParent), t.boxMax(*nearParent)), Coverage::Full);
}

TEST(BlockMapTraversalTest, RequestsAreTheCutNeededAndItsNextRefinement) {
    const Loaded l = load();
    BlockMapTraversal t(l.tree, l.file.records());
    int prefetching = 0, notPrefetching = 0;
    Camera higher = overview(); // the root's map alone, well under the bound
    higher.position.z *= 3.0;
    for (const Camera& cam : {street(), overview(), higher}) {
        const AtlasView v = viewOf(cam);
        const BlockMapCut c = t.cut(v, 1.0);
        const auto req = t.requests(v, 1.0);
        std::set<std::uint32_t> needed, parentNeeded;
        for (std::size_t i = 0; i < req.size(); ++i) {
            EXPECT_EQ(req[i].key.kind, BlockKey::Kind::BlockMap);
            if (i > 0) {
                EXPECT_FALSE(req[i] < req[i - 1]) << "priority order";
            }
            if (req[i].category == BlockCategory::Needed) needed.insert(req[i].key.index);
            if (req[i].category == BlockCategory::ParentNeeded) parentNeeded.insert(req[i].key.index);
        }
        EXPECT_EQ(needed, std::set<std::uint32_t>(c.drawn.begin(), c.drawn.end()));
        // The children of the maps near refinement come next; those of maps well under the bound are not asked for.
        for (std::uint32_t k : c.drawn) {
            const bool near = t.errorPx(k, v) > kPrefetchErrorRatio * 1.0;
            bool anyChild = false;
            for (std::int32_t ch : l.tree.nodes[k].children) {
                if (ch < 0) continue;
                anyChild = true;
                EXPECT_EQ(parentNeeded.count(std::uint32_t(ch)), near ? 1u : 0u) << "map " << k << ", child " << ch;
            }
            if (anyChild) ++(near ? prefetching : notPrefetching);
        }
    }
    EXPECT_GT(prefetching, 0);
    EXPECT_GT(notPrefetching, 0);
}

// The atlas tree of the same city skips what the maps cover: at the overview it draws nothing, at street level only
// the near field, and its requests leave the covered nodes' atlases out.
TEST(BlockMapTraversalTest, TheAtlasTreeDrawsOnlyWhatTheMapsDoNotCover) {
    const Loaded l = load();
    BlockMapTraversal t(l.tree, l.file.records());
    test::TempDir dir("blockmap-atlas");
    AtlasBuildSettings bs;
    bs.atlasSize = 64;
    // The walls textured with one 128² image (an atlas tree is built from textured triangles; 64² atlases make it
    // a tree of several levels).
    CityModel model = test::prismModel(gridCity());
    std::vector<std::uint8_t> px(128 * 128 * 3);
    for (std::size_t i = 0; i < px.size(); ++i) px[i] = std::uint8_t((i * 37) % 251);
    ASSERT_TRUE(writeImageAtomic(dir / "wall.png", px.data(), 128, 128, 3));
    model.textures.push_back(CityTexture{(dir / "wall.png").string(), true, 3, 128, 128});
    for (std::size_t i = 0; i < model.triangles.size(); ++i)
        if (model.surface[i] == Surface::Wall) {
            model.triangles[i].texture = 0;
            model.triangles[i].t = {glm::dvec2(0, 0), glm::dvec2(4, 0), glm::dvec2(4, 4)};
        }
    auto built = buildAtlasTree(model, bs, (dir / "t.svat").string());
    ASSERT_TRUE(built) << built.message();
    auto file = AtlasTreeFile::open((dir / "t.svat").string());
    ASSERT_TRUE(file) << file.message();
    AtlasTraversal at(file->trees[0], file->info);
    auto all = [](std::uint32_t) { return true; };
    auto triangles = [](const AtlasTraversalResult& r) {
        std::uint64_t n = 0;
        for (const AtlasDraw& d : r.draws) n += d.count;
        return n;
    };
    for (const Camera& cam : {street(), overview()}) {
        const AtlasView v = viewOf(cam);
        const std::uint64_t alone = triangles(at.draws(v, all, all));
        const std::size_t requestsAlone = at.requests(v).size();
        const BlockMapCut c = t.cut(v, 1.0);
        at.setCovered([&](const glm::dvec3& lo, const glm::dvec3& hi) { return std::uint8_t(t.coverage(c, lo, hi)); });
        const AtlasTraversalResult r = at.draws(v, all, all);
        const std::uint64_t with = triangles(r);
        std::printf("atlas nodes %zu, leaves drawn %zu, maps drawn %zu, polygon nodes %zu: %llu of %llu triangles\n",
                    file->trees[0].nodes.size(), r.drawn.size(), c.drawn.size(), c.polygonNodes,
                    (unsigned long long)with, (unsigned long long)alone);
        EXPECT_GT(alone, 0u);
        if (c.polygonNodes == 0) {
            EXPECT_EQ(with, 0u);
        } else {
            EXPECT_GT(with, 0u);
            EXPECT_LT(with, alone);
        }
        EXPECT_LE(at.requests(v).size(), requestsAlone);
        at.setCovered({});
        EXPECT_EQ(triangles(at.draws(v, all, all)), alone);
    }
}

// The plain triangles in the maps' quadtree order: a permutation in which every node's triangles are one range, and
// the ranges the polygons draw for a cut hold every triangle the maps do not cover entirely (and, at the overview,
// none).
TEST(BlockMapTraversalTest, PlainTrianglesInQuadtreeOrderDrawWhatTheMapsDoNotCover) {
    const Loaded l = load();
    BlockMapTraversal t(l.tree, l.file.records());
    const CityModel model = test::prismModel(gridCity());
    std::vector<std::pair<glm::dvec2, glm::dvec2>> boxes;
    for (const auto& tri : model.triangles) {
        const glm::dvec3 lo = glm::min(tri.v[0], glm::min(tri.v[1], tri.v[2]));
        const glm::dvec3 hi = glm::max(tri.v[0], glm::max(tri.v[1], tri.v[2]));
        boxes.emplace_back(glm::dvec2(lo), glm::dvec2(hi));
    }
    const glm::dvec2 centre = 0.5 * (glm::dvec2(t.boxMin(0)) + glm::dvec2(t.boxMax(0)));
    boxes.push_back({centre - 1.0, centre + 1.0});        // across the root's children: the root's own
    boxes.push_back({{-40.0, -40.0}, {-30.0, -30.0}}); // outside the root square
    const BlockMapTriangleOrder order = BlockMapTriangleOrder::of(l.tree, boxes);
    ASSERT_EQ(order.order.size(), boxes.size());
    EXPECT_EQ(std::set<std::uint32_t>(order.order.begin(), order.order.end()).size(), boxes.size());
    EXPECT_EQ(order.order.back(), std::uint32_t(boxes.size() - 1));
    EXPECT_EQ(order.outsideFirst, std::uint32_t(boxes.size() - 1));
    for (std::size_t k = 0; k < l.tree.nodes.size(); ++k) {
        // A node's own triangles lie in its square; its subtree holds its children's.
        const glm::dvec3 lo = t.boxMin(std::uint32_t(k)), hi = t.boxMax(std::uint32_t(k));
        for (std::uint32_t p = order.first[k]; p < order.end[k]; ++p) {
            const auto& b = boxes[order.order[p]];
            EXPECT_TRUE(b.first.x >= lo.x - 1e-9 && b.first.y >= lo.y - 1e-9 && b.second.x <= hi.x + 1e-9 &&
                        b.second.y <= hi.y + 1e-9)
                << k;
        }
        for (std::int32_t ch : l.tree.nodes[k].children)
            if (ch >= 0) {
                EXPECT_GE(order.first[std::size_t(ch)], order.ownEnd[k]);
                EXPECT_LE(order.end[std::size_t(ch)], order.end[k]);
            }
    }
    auto drawnSet = [&](const BlockMapCut& c) {
        std::vector<bool> drawn(boxes.size(), false);
        std::uint32_t last = 0;
        for (const auto& [first, n] : order.ranges(c)) {
            EXPECT_GE(first, last) << "ranges in order, apart";
            last = first + n;
            for (std::uint32_t p = first; p < first + n; ++p) drawn[order.order[p]] = true;
        }
        return drawn;
    };
    const BlockMapCut s = t.cut(viewOf(street()), 1.0);
    const auto drawn = drawnSet(s);
    std::size_t count = 0;
    for (std::size_t i = 0; i + 1 < boxes.size(); ++i) {
        count += drawn[i] ? 1 : 0;
        if (t.coverage(s, glm::dvec3(boxes[i].first, 0.0), glm::dvec3(boxes[i].second, 0.0)) != Coverage::Full) {
            EXPECT_TRUE(drawn[i]) << i;
        }
    }
    EXPECT_GT(count, 0u);
    EXPECT_LT(count, boxes.size() - 1);
    EXPECT_TRUE(drawn.back()) << "outside the root square: always";
    const auto none = drawnSet(t.cut(viewOf(overview()), 1.0));
    EXPECT_EQ(std::count(none.begin(), none.end(), true), 1) << "only the one outside";
    // The root refined into its children's maps: its own triangles (across the children's squares) are in those
    // maps, not drawn again; with one child left to the polygons they are.
    const auto& rootChildren = l.tree.nodes[0].children;
    ASSERT_GT(order.ownEnd[0], order.first[0]) << "the root holds triangles across its children";
    BlockMapCut refined;
    refined.use.assign(l.tree.nodes.size(), BlockMapUse::Unvisited);
    refined.use[0] = BlockMapUse::Refined;
    for (std::int32_t c : rootChildren)
        if (c >= 0) refined.use[std::size_t(c)] = BlockMapUse::BlockMap;
    EXPECT_EQ(order.ranges(refined).size(), 1u) << "the one outside only";
    for (std::int32_t c : rootChildren)
        if (c >= 0) {
            refined.use[std::size_t(c)] = BlockMapUse::Polygons;
            break;
        }
    const auto some = drawnSet(refined);
    for (std::uint32_t p = order.first[0]; p < order.ownEnd[0]; ++p) EXPECT_TRUE(some[order.order[p]]) << p;
}
