// The texture-atlas tree build (thesis §4.5) and its file: structure invariants, atlas contents against the
// original textures, critical triangles, out-of-core texture reading, RGB/RGBA trees, bad files.
#include "AtlasCodec.h"
#include "AtlasPager.h"
#include "AtlasTraversal.h"
#include "Camera.h"
#include "AtlasTreeBuild.h"
#include "TestUtil.h"

#include <OpenImageIO/imageio.h>
#include <glm/common.hpp>
#include <glm/ext/vector_uint4_sized.hpp>
#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <thread>
#include <tuple>

using namespace seasonview;
using namespace seasonview::city;

namespace {

glm::u8vec4 colourOf(int i) {
    return {std::uint8_t(40 + (i * 67) % 200), std::uint8_t(40 + (i * 131) % 200), std::uint8_t(40 + (i * 29) % 200),
            std::uint8_t(i % 2 ? 255 : 128)};
}

/// A w×h 8-bit texture of `channels` interleaved channels, rows top down.
void writeTexture(const std::filesystem::path& p, int w, int h, int channels, const std::vector<std::uint8_t>& px) {
    auto out = OIIO::ImageOutput::create(p.string());
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open(p.string(), OIIO::ImageSpec(w, h, channels, OIIO::TypeDesc::UINT8)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data()));
    out->close();
}

/// A w×h texture of one colour (RGB or RGBA).
void writeSolid(const std::filesystem::path& p, int w, int h, glm::u8vec4 c, int channels) {
    std::vector<std::uint8_t> px(std::size_t(w * h * channels));
    for (std::size_t i = 0; i < px.size(); i += std::size_t(channels))
        for (int k = 0; k < channels; ++k) px[i + std::size_t(k)] = c[k];
    writeTexture(p, w, h, channels, px);
}

/// A row of `n` walls, 10 m wide and 8 m high, 15 m apart along x, each with its own solid texture (256×128,
/// `alphaEvery`-th RGBA), two triangles per wall, plus a flat roof per wall (a roof surface) and one untextured
/// triangle.
CityModel wallModel(const std::filesystem::path& dir, int n, int alphaEvery = 0) {
    CityModel m;
    m.source = (dir / "model").string();
    m.crs = Crs::utm(33, true);
    for (int i = 0; i < n; ++i) {
        const bool alpha = alphaEvery > 0 && i % alphaEvery == 0;
        const auto path = dir / ("t" + std::to_string(i) + ".png");
        writeSolid(path, 256, 128, colourOf(i), alpha ? 4 : 3);
        m.textures.push_back(CityTexture{path.string(), false, alpha ? 4 : 3, 256, 128});
        m.buildingIds.push_back("b" + std::to_string(i));
        const double x0 = 15.0 * i;
        TexturedTriangle a, b;
        a.v = {glm::dvec3(x0, 0, 0), glm::dvec3(x0 + 10, 0, 0), glm::dvec3(x0 + 10, 0, 8)};
        a.t = {glm::dvec2(0, 0), glm::dvec2(1, 0), glm::dvec2(1, 1)};
        b.v = {glm::dvec3(x0, 0, 0), glm::dvec3(x0 + 10, 0, 8), glm::dvec3(x0, 0, 8)};
        b.t = {glm::dvec2(0, 0), glm::dvec2(1, 1), glm::dvec2(0, 1)};
        a.texture = b.texture = i;
        for (const auto& t : {a, b}) {
            m.triangles.push_back(t);
            m.building.push_back(std::uint32_t(i));
            m.surface.push_back(Surface::Wall);
        }
        TexturedTriangle roof;
        roof.v = {glm::dvec3(x0, 0, 8), glm::dvec3(x0 + 10, 0, 8), glm::dvec3(x0 + 10, 5, 8)};
        roof.texture = i;
        roof.t = {glm::dvec2(0, 0), glm::dvec2(1, 0), glm::dvec2(1, 1)};
        m.triangles.push_back(roof);
        m.building.push_back(std::uint32_t(i));
        m.surface.push_back(Surface::Roof);
    }
    TexturedTriangle plain;
    plain.v = {glm::dvec3(0, -5, 0), glm::dvec3(5, -5, 0), glm::dvec3(0, -5, 5)};
    plain.texture = -1;
    m.triangles.push_back(plain);
    m.building.push_back(0);
    m.surface.push_back(Surface::Wall);
    return m;
}

/// A model of walls 10 m × 8 m, 12 m apart, each with its own noise texture of the given size, used over the given
/// texture rectangle (two triangles per wall).
CityModel noiseWalls(const std::filesystem::path& dir, const std::vector<glm::ivec2>& sizes,
                     const std::vector<std::pair<glm::dvec2, glm::dvec2>>& uvs) {
    CityModel m;
    m.source = (dir / "model").string();
    m.crs = Crs::utm(33, true);
    std::mt19937 rng(7);
    for (std::size_t i = 0; i < sizes.size(); ++i) {
        const auto path = dir / ("n" + std::to_string(i) + ".png");
        std::vector<std::uint8_t> px(std::size_t(sizes[i].x * sizes[i].y * 3));
        for (auto& v : px) v = std::uint8_t(rng() % 256);
        writeTexture(path, sizes[i].x, sizes[i].y, 3, px);
        m.textures.push_back(CityTexture{path.string(), false, 3, sizes[i].x, sizes[i].y});
        m.buildingIds.push_back("b" + std::to_string(i));
        const double x0 = 12.0 * double(i);
        const auto [lo, hi] = uvs[i];
        TexturedTriangle a, b;
        a.v = {glm::dvec3(x0, 0, 0), glm::dvec3(x0 + 10, 0, 0), glm::dvec3(x0 + 10, 0, 8)};
        a.t = {lo, glm::dvec2(hi.x, lo.y), hi};
        b.v = {glm::dvec3(x0, 0, 0), glm::dvec3(x0 + 10, 0, 8), glm::dvec3(x0, 0, 8)};
        b.t = {lo, hi, glm::dvec2(lo.x, hi.y)};
        a.texture = b.texture = int(i);
        for (const auto& t : {a, b}) {
            m.triangles.push_back(t);
            m.building.push_back(std::uint32_t(i));
            m.surface.push_back(Surface::Wall);
        }
    }
    return m;
}

/// A tree of `model` built with 128² lossless atlases at dmin 200 m (a wallModel wall: 64×54 atlas texels with its
/// border, four to a leaf) into `file`, and the file opened; nothing (and a test failure) if either fails.
struct BuiltTree {
    AtlasBuildReport report;
    AtlasTreeFile file;
};
std::optional<BuiltTree> buildSmall(const CityModel& model, const std::filesystem::path& file,
                                    AtlasPacker packer = AtlasPacker::MaxRects) {
    AtlasBuildSettings s;
    s.atlasSize = 128;
    s.dmin = 200.0;
    s.format = AtlasFormat::Deflate; // lossless, so colours compare exactly
    s.packer = packer;
    auto r = buildAtlasTree(model, s, file.string());
    if (!r) {
        ADD_FAILURE() << r.error().message;
        return std::nullopt;
    }
    auto f = AtlasTreeFile::open(file.string());
    if (!f) {
        ADD_FAILURE() << f.error().message;
        return std::nullopt;
    }
    return BuiltTree{*r, std::move(*f)};
}

/// Checks §4.3/§4.8.1 invariants of one tree; returns the number of leaves.
void checkStructure(const AtlasTreeData& t, const AtlasTreeInfo& info) {
    ASSERT_FALSE(t.nodes.empty());
    EXPECT_EQ(t.nodes[0].parent, -1);
    EXPECT_EQ(t.nodes[0].first, 0u);
    EXPECT_EQ(t.nodes[0].count, t.vertices.size() / 3);
    for (std::size_t i = 0; i < t.nodes.size(); ++i) {
        const AtlasNode& n = t.nodes[i];
        if (n.leaf()) {
            for (int c : n.children) EXPECT_EQ(c, -1);
            if (n.count > 0) {
                EXPECT_FLOAT_EQ(n.minDistance, float(info.dmin));
            }
            continue;
        }
        // Four children whose ranges tile the parent's, in order; minDistance doubles the largest child's.
        std::uint32_t next = n.first;
        float md = 0.0f;
        for (int c : n.children) {
            ASSERT_GE(c, 0);
            const AtlasNode& ch = t.nodes[std::size_t(c)];
            EXPECT_EQ(ch.parent, int(i));
            EXPECT_EQ(ch.level, n.level + 1);
            EXPECT_EQ(ch.first, next);
            next += ch.count;
            if (ch.count > 0) md = std::max(md, ch.minDistance);
            // The child's bounds lie inside the parent's.
            if (ch.count > 0)
                for (int k = 0; k < 3; ++k) {
                    EXPECT_GE(ch.boundsMin[k], n.boundsMin[k]);
                    EXPECT_LE(ch.boundsMax[k], n.boundsMax[k]);
                }
        }
        EXPECT_EQ(next, n.first + n.count);
        // At least the thesis's doubling; more above leaves whose originals capped the stored size.
        EXPECT_GE(n.minDistance, 2.0f * md * 0.99999f);
    }
}

/// Levels from `n` down to its deepest non-empty leaf.
int leafDepthBelow(const AtlasTreeData& t, const AtlasNode& n) {
    if (n.leaf()) return 0;
    int d = 0;
    for (int c : n.children)
        if (t.nodes[std::size_t(c)].count > 0) d = std::max(d, 1 + leafDepthBelow(t, t.nodes[std::size_t(c)]));
    return d;
}

std::vector<int> pathOf(const AtlasTreeData& t, int node) {
    std::vector<int> path;
    for (int n = node; t.nodes[std::size_t(n)].parent >= 0; n = t.nodes[std::size_t(n)].parent) {
        const auto& p = t.nodes[std::size_t(t.nodes[std::size_t(n)].parent)];
        path.insert(path.begin(), int(std::find(p.children.begin(), p.children.end(), n) - p.children.begin()));
    }
    return path;
}

glm::u8vec4 texel(const std::vector<std::uint8_t>& rgba, int size, glm::dvec2 uv) {
    const int x = std::clamp(int(uv.x * size), 0, size - 1), y = std::clamp(int(uv.y * size), 0, size - 1);
    const std::uint8_t* p = &rgba[(std::size_t(y) * std::size_t(size) + std::size_t(x)) * 4];
    return {p[0], p[1], p[2], p[3]};
}

} // namespace

TEST(AtlasTreeTest, SplitTriangleKeepsTheTextureMapping) {
    TexturedTriangle t;
    t.v = {glm::dvec3(0, 0, 0), glm::dvec3(40, 0, 0), glm::dvec3(0, 0, 10)};
    t.t = {glm::dvec2(0, 0), glm::dvec2(4, 0), glm::dvec2(0, 1)};
    const auto halves = splitTriangle(t, 10.0);
    EXPECT_NEAR(triangleArea(halves[0]) + triangleArea(halves[1]), triangleArea(t), 1e-9);
    // 100 texels per repetition each way: the edges span 400, 412 and 100 texels, so the second (from (40, 0, 0)
    // to (0, 0, 10)) is split at (20, 0, 5).
    for (const auto& h : halves) {
        bool hasMid = false;
        for (int k = 0; k < 3; ++k) {
            const glm::dvec3 p = h.v[std::size_t(k)];
            // The same affine map: u = x / 10, v = z / 10.
            EXPECT_NEAR(h.t[std::size_t(k)].x, p.x / 10.0, 1e-12);
            EXPECT_NEAR(h.t[std::size_t(k)].y, p.z / 10.0, 1e-12);
            hasMid = hasMid || glm::length(p - glm::dvec3(20, 0, 5)) < 1e-12;
        }
        EXPECT_TRUE(hasMid);
    }
}

TEST(AtlasTreeTest, BuildsAValidTreeWhoseAtlasesHoldTheTextures) {
    test::TempDir dir("atlas_build");
    const CityModel model = wallModel(dir.path(), 40);
    AtlasBuildSettings s;
    s.atlasSize = 128; // small atlases force a deep tree
    s.dmin = 200.0; // a wall is 48×38 texels + border: four per 128² atlas
    s.format = AtlasFormat::Deflate; // lossless, so the colours can be compared exactly
    auto r = buildAtlasTree(model, s, (dir / "t.svat").string());
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->inputTreeTriangles, 80u);
    EXPECT_EQ(r->plainTriangles, 41u); // 40 roofs + the untextured triangle
    EXPECT_GT(r->depth, 1);
    EXPECT_GT(r->meanLeafFill, 0.0);
    EXPECT_LE(r->meanLeafFill, 1.0);
    auto f = AtlasTreeFile::open((dir / "t.svat").string());
    ASSERT_TRUE(f) << f.error().message;
    ASSERT_EQ(f->trees.size(), 1u);
    EXPECT_EQ(f->plain.surface.size(), 41u);
    EXPECT_EQ(f->info.atlasSize, 128);
    EXPECT_DOUBLE_EQ(f->info.dmin, 200.0);
    const AtlasTreeData& t = f->trees[0];
    checkStructure(t, f->info);
    EXPECT_EQ(t.vertices.size(), 240u);

    // Every leaf triangle's centroid, looked up through the root-atlas coordinates at the leaf's level, shows its
    // texture's colour in the leaf's atlas; at the parent's level (one halving), still inside its area.
    int checked = 0;
    for (std::size_t ni = 0; ni < t.nodes.size(); ++ni) {
        const AtlasNode& n = t.nodes[ni];
        if (!n.leaf() || n.count == 0) continue;
        auto leafAtlas = f->readAtlasRgba(0, int(ni));
        ASSERT_TRUE(leafAtlas);
        for (std::uint32_t tri = n.first; tri < n.first + n.count; ++tri) {
            glm::dvec2 root(0.0);
            for (int k = 0; k < 3; ++k) root += glm::dvec2(t.vertices[tri * 3 + std::size_t(k)].root) / 3.0;
            const glm::u8vec4 want = colourOf(int(t.triangleTexture[tri]));
            const glm::u8vec4 got = texel(*leafAtlas, 128, levelAtlasCoord(root, n.level));
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(int(got[c]), int(want[c]), 1) << "node " << ni << " tri " << tri;
            // The root coordinates reproduce the leaf coordinates through the path (§4.5.4).
            const auto path = pathOf(t, int(ni));
            EXPECT_EQ(int(path.size()), n.level);
            ++checked;
        }
        if (n.parent >= 0) {
            auto parentAtlas = f->readAtlasRgba(0, n.parent);
            ASSERT_TRUE(parentAtlas);
            const AtlasNode& p = t.nodes[std::size_t(n.parent)];
            for (std::uint32_t tri = n.first; tri < n.first + n.count; ++tri) {
                glm::dvec2 root(0.0);
                for (int k = 0; k < 3; ++k) root += glm::dvec2(t.vertices[tri * 3 + std::size_t(k)].root) / 3.0;
                const glm::u8vec4 want = colourOf(int(t.triangleTexture[tri]));
                const glm::u8vec4 got = texel(*parentAtlas, 128, levelAtlasCoord(root, p.level));
                for (int c = 0; c < 3; ++c) EXPECT_NEAR(int(got[c]), int(want[c]), 1);
            }
        }
    }
    EXPECT_EQ(checked, 80);
    // Splits keep a texture's triangles together (both halves of a wall in one leaf): no texture is copied twice.
    std::map<std::uint32_t, std::set<std::size_t>> leavesOf;
    for (std::size_t ni = 0; ni < t.nodes.size(); ++ni)
        if (t.nodes[ni].leaf())
            for (std::uint32_t tri = t.nodes[ni].first; tri < t.nodes[ni].first + t.nodes[ni].count; ++tri)
                leavesOf[t.triangleTexture[tri]].insert(ni);
    for (const auto& [tex, leaves] : leavesOf) EXPECT_EQ(leaves.size(), 1u) << "texture " << tex;
    // Each leaf lists the textures it uses and their decoded bytes (paging, §4.6).
    for (const auto& n : t.nodes)
        if (n.leaf() && n.count > 0) {
            EXPECT_FALSE(n.textures.empty());
            EXPECT_GT(n.textureBytes, 0u);
        }
}

TEST(AtlasTreeTest, MinDistancesDoubleUpTheTreeAndGrowWhereOriginalsCapped) {
    test::TempDir dir("atlas_mindist");
    const CityModel model = wallModel(dir.path(), 40);
    AtlasBuildSettings s;
    s.atlasSize = 128;
    s.dmin = 200.0; // walls want 48×38 texels of their 256×128 originals: nothing capped
    ASSERT_TRUE(buildAtlasTree(model, s, (dir / "a.svat").string()));
    auto a = AtlasTreeFile::open((dir / "a.svat").string());
    ASSERT_TRUE(a);
    const auto& root = a->trees[0].nodes[0];
    int leafLevel = 0;
    for (const auto& n : a->trees[0].nodes)
        if (n.leaf() && n.count > 0) leafLevel = std::max(leafLevel, n.level);
    EXPECT_FLOAT_EQ(root.minDistance, float(200.0 * std::ldexp(1.0, leafLevel)));

    // At dmin 10 m a wall wants 960×768 texels, its original has 256×128: capped by 6 (vertically). The leaf keeps
    // all of the original, so its parent's halved copy suffices only from 6 × 2 × dmin on.
    s.atlasSize = 512;
    s.dmin = 10.0;
    auto r = buildAtlasTree(model, s, (dir / "b.svat").string());
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_DOUBLE_EQ(r->dmin, 10.0);
    auto b = AtlasTreeFile::open((dir / "b.svat").string());
    ASSERT_TRUE(b);
    for (const auto& n : b->trees[0].nodes) {
        if (n.count == 0) continue;
        if (n.leaf()) {
            EXPECT_FLOAT_EQ(n.minDistance, 10.0f);
        } else {
            EXPECT_NEAR(n.minDistance, 10.0 * 6.0 * std::ldexp(1.0, 1) * std::ldexp(1.0, leafDepthBelow(b->trees[0], n) - 1), 1e-3);
        }
    }
}

TEST(AtlasTreeTest, BcAtlasesAreCloseToTheLosslessOnes) {
    test::TempDir dir("atlas_bc");
    const CityModel model = wallModel(dir.path(), 12);
    AtlasBuildSettings s;
    s.atlasSize = 128;
    s.dmin = 200.0; // a wall is 48×38 texels + border: four per 128² atlas
    s.format = AtlasFormat::Deflate;
    ASSERT_TRUE(buildAtlasTree(model, s, (dir / "d.svat").string()));
    s.format = AtlasFormat::Bc;
    ASSERT_TRUE(buildAtlasTree(model, s, (dir / "b.svat").string()));
    auto d = AtlasTreeFile::open((dir / "d.svat").string());
    auto b = AtlasTreeFile::open((dir / "b.svat").string());
    ASSERT_TRUE(d && b);
    ASSERT_EQ(d->trees[0].nodes.size(), b->trees[0].nodes.size());
    for (std::size_t n = 0; n < d->trees[0].nodes.size(); ++n) {
        auto x = d->readAtlasRgba(0, int(n)), y = b->readAtlasRgba(0, int(n));
        ASSERT_TRUE(x && y);
        const auto diff = test::compareRgb(test::rgbOf(*x), test::rgbOf(*y), 128, 128, 3);
        EXPECT_GT(diff.psnr, 35.0) << "node " << n; // solid colours: BC1's 5:6:5 endpoints are the only loss
        EXPECT_LT(b->trees[0].nodes[n].atlasBytes, 128u * 128u * 3u);
    }
}

TEST(AtlasTreeTest, RgbaTexturesGetTheirOwnTree) {
    test::TempDir dir("atlas_rgba");
    const CityModel model = wallModel(dir.path(), 9, 3);
    AtlasBuildSettings s;
    s.atlasSize = 256;
    s.dmin = 200.0; // a wall is 48×38 texels + border: four per 128² atlas
    auto r = buildAtlasTree(model, s, (dir / "t.svat").string());
    ASSERT_TRUE(r) << r.error().message;
    auto f = AtlasTreeFile::open((dir / "t.svat").string());
    ASSERT_TRUE(f);
    ASSERT_EQ(f->trees.size(), 2u);
    EXPECT_FALSE(f->trees[0].alpha);
    EXPECT_TRUE(f->trees[1].alpha);
    EXPECT_EQ(f->trees[0].vertices.size() / 3, 12u); // 6 RGB walls
    EXPECT_EQ(f->trees[1].vertices.size() / 3, 6u);  // 3 RGBA walls
    for (auto t : f->trees[1].triangleTexture) EXPECT_EQ(t % 3, 0u);
    // The RGBA atlas keeps alpha (BC3): the textures with alpha 128 show it.
    auto atlas = f->readAtlasRgba(1, 0);
    ASSERT_TRUE(atlas);
    const auto& v = f->trees[1].vertices;
    glm::dvec2 root = (glm::dvec2(v[0].root) + glm::dvec2(v[1].root) + glm::dvec2(v[2].root)) / 3.0;
    const int tex = int(f->trees[1].triangleTexture[0]);
    EXPECT_NEAR(int(texel(*atlas, 256, root)[3]), int(colourOf(tex)[3]), 4);
    checkStructure(f->trees[1], f->info);
}

TEST(AtlasTreeTest, CriticalTrianglesEnlargeDminThenSplit) {
    test::TempDir dir("atlas_critical");
    CityModel model = wallModel(dir.path(), 10);
    // At dmin 1 m a 10 m wall wants 9600 texels across, capped at its 256-texel original: with the border, more
    // than a 128² atlas holds, so all 20 wall triangles are critical (100 % > 10 %). dmin grows until only 10 %
    // are: one wall made 50 m long (its texture repeated 5 times, 2 triangles) needs 5 times the growth, stays
    // critical and is split.
    for (std::size_t i = 0; i < 2; ++i) {
        for (auto& v : model.triangles[i].v) v.x *= 5.0;
        for (auto& c : model.triangles[i].t) c.x *= 5.0;
    }
    AtlasBuildSettings s;
    s.atlasSize = 128;
    s.dmin = 1.0;
    auto r = buildAtlasTree(model, s, (dir / "t.svat").string());
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->criticalAtDmin, 20u);
    EXPECT_GT(r->dmin, 50.0);
    EXPECT_GT(r->criticalSplit, 0u);
    EXPECT_GT(r->treeTriangles, r->inputTreeTriangles);
    auto f = AtlasTreeFile::open((dir / "t.svat").string());
    ASSERT_TRUE(f);
    checkStructure(f->trees[0], f->info);
    // Whatever was split still covers the same area.
    double before = 0.0, after = 0.0;
    for (std::size_t i = 0; i < model.triangles.size(); ++i)
        if (model.surface[i] == Surface::Wall && model.triangles[i].texture >= 0) before += triangleArea(model.triangles[i]);
    const auto& v = f->trees[0].vertices;
    for (std::size_t i = 0; i < v.size(); i += 3)
        after += 0.5 * double(glm::length(glm::cross(v[i + 1].position - v[i].position, v[i + 2].position - v[i].position)));
    EXPECT_NEAR(after, before, 1e-3 * before);
}

TEST(AtlasTreeTest, BuildReadsTexturesOutOfCore) {
    test::TempDir dir("atlas_ooc");
    const CityModel model = wallModel(dir.path(), 30);
    AtlasBuildSettings s;
    s.atlasSize = 128;
    s.dmin = 200.0; // a wall is 48×38 texels + border: four per 128² atlas
    s.cacheBytes = 256 * 128 * 4 * 2; // about one texture with its mips
    auto r = buildAtlasTree(model, s, (dir / "t.svat").string());
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_GE(r->textureReads, 30u);
    // Never more than the capacity plus the texture being read.
    EXPECT_LE(r->peakCacheBytes, s.cacheBytes + 256u * 128u * 4u * 4u / 3u + 64u);
}

TEST(AtlasTreeTest, BadInputAndBadFiles) {
    test::TempDir dir("atlas_bad");
    CityModel model = wallModel(dir.path(), 4);
    std::filesystem::remove(dir / "t2.png"); // vanished after the model was read
    AtlasBuildSettings s;
    s.atlasSize = 128;
    s.dmin = 200.0; // a wall is 48×38 texels + border: four per 128² atlas
    auto r = buildAtlasTree(model, s, (dir / "t.svat").string());
    ASSERT_FALSE(r);
    EXPECT_NE(r.error().message.find("t2.png"), std::string::npos) << r.error().message;
    EXPECT_FALSE(std::filesystem::exists(dir / "t.svat"));
    for (const auto& e : std::filesystem::directory_iterator(dir.path()))
        EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << e.path();

    s.atlasSize = 100;
    EXPECT_FALSE(buildAtlasTree(model, s, (dir / "t.svat").string()));

    // A good file, then damaged copies.
    model = wallModel(dir.path(), 4);
    s.atlasSize = 128;
    ASSERT_TRUE(buildAtlasTree(model, s, (dir / "good.svat").string()));
    const std::string bytes = test::readBytes(dir / "good.svat");
    auto write = [&](const std::string& name, const std::string& b) {
        std::ofstream(dir / name, std::ios::binary) << b;
        return (dir / name).string();
    };
    auto cut = AtlasTreeFile::open(write("cut.svat", bytes.substr(0, bytes.size() - 10)));
    ASSERT_FALSE(cut);
    EXPECT_NE(cut.error().message.find("truncated"), std::string::npos) << cut.error().message;
    std::string foreign = bytes;
    foreign[0] = 'X';
    EXPECT_FALSE(AtlasTreeFile::open(write("foreign.svat", foreign)));
    std::string newer = bytes;
    newer[8] = char(99);
    auto nv = AtlasTreeFile::open(write("newer.svat", newer));
    ASSERT_FALSE(nv);
    EXPECT_NE(nv.error().message.find("version"), std::string::npos) << nv.error().message;
    EXPECT_FALSE(AtlasTreeFile::open((dir / "none.svat").string()));
    EXPECT_FALSE(AtlasTreeFile::open(write("empty.svat", "")));
}

TEST(AtlasTreeTest, CodecRoundTripsAndMipChain) {
    const int n = 64;
    std::vector<std::uint8_t> rgba(std::size_t(n * n * 4));
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            std::uint8_t* p = &rgba[std::size_t((y * n + x) * 4)];
            p[0] = std::uint8_t(x * 4);
            p[1] = std::uint8_t(y * 4);
            p[2] = std::uint8_t((x + y) * 2);
            p[3] = 255;
        }
    EXPECT_EQ(atlasLevels(64), 5); // 64, 32, 16, 8, 4
    const auto d = encodeAtlas(AtlasFormat::Deflate, false, rgba, n);
    EXPECT_EQ(decodeAtlasRgba(AtlasFormat::Deflate, false, d, n), rgba);
    const auto level1 = atlasLevelData(AtlasFormat::Deflate, false, d, n, 1);
    ASSERT_EQ(level1.size(), 32u * 32u * 3u);
    const auto half = halveRgba(rgba, n);
    EXPECT_EQ(level1[0], half[0]);
    EXPECT_EQ(level1[(5 * 32 + 7) * 3 + 1], half[(5 * 32 + 7) * 4 + 1]);
    const auto bc = encodeAtlas(AtlasFormat::Bc, false, rgba, n);
    std::uint64_t expect = 0;
    for (int l = 0; l < 5; ++l) expect += atlasLevelBytes(AtlasFormat::Bc, false, n, l);
    EXPECT_EQ(bc.size(), expect);
    const auto back = decodeAtlasRgba(AtlasFormat::Bc, false, bc, n);
    EXPECT_GT(test::compareRgb(test::rgbOf(back), test::rgbOf(rgba), n, n, 3).psnr, 35.0); // smooth gradients
    EXPECT_TRUE(decodeAtlasRgba(AtlasFormat::Deflate, false, std::vector<std::uint8_t>(10, 7), n).empty());
}

namespace {

/// A hand-made tree: the root (x 0..400) with four children along x; child 0 has four leaves (25 m each), the
/// others are leaves. Leaves' minDistance 10 m, child 0's 20 m, the root's 40 m; leaf i uses texture i.
AtlasTreeData handTree() {
    AtlasTreeData t;
    auto add = [&](float x0, float x1, float md, int level, int parent) {
        AtlasNode n;
        n.boundsMin = glm::vec3(x0, 0, 0);
        n.boundsMax = glm::vec3(x1, 100, 10);
        n.minDistance = md;
        n.level = level;
        n.parent = parent;
        n.atlasBytes = 1000;
        t.nodes.push_back(n);
        return int(t.nodes.size() - 1);
    };
    add(0, 400, 40, 0, -1);
    for (int c = 0; c < 4; ++c) t.nodes[0].children[std::size_t(c)] = add(100.0f * float(c), 100.0f * float(c + 1), c == 0 ? 20.0f : 10.0f, 1, 0);
    for (int c = 0; c < 4; ++c) t.nodes[1].children[std::size_t(c)] = add(25.0f * float(c), 25.0f * float(c + 1), 10.0f, 2, 1);
    // Ranges: depth-first, one triangle per leaf; textures: one per leaf.
    std::uint32_t next = 0, tex = 0;
    std::function<void(int)> fill = [&](int i) {
        AtlasNode& n = t.nodes[std::size_t(i)];
        n.first = next;
        if (n.leaf()) {
            n.count = 1;
            n.textures = {tex};
            t.triangleTexture.push_back(tex++);
            t.triangleBuilding.push_back(0);
            for (int k = 0; k < 3; ++k) t.vertices.push_back(TreeVertex{});
            ++next;
            return;
        }
        for (int c : n.children) fill(c);
        n.count = next - n.first;
    };
    fill(0);
    return t;
}

/// The tree of wallModel(dir, walls) with 128² atlases at dmin 200 m (four walls per atlas), built into dir/t.svat.
Result<AtlasTreeFile> wallTree(const std::filesystem::path& dir, int walls) {
    AtlasBuildSettings s;
    s.atlasSize = 128;
    s.dmin = 200.0;
    if (auto r = buildAtlasTree(wallModel(dir, walls), s, (dir / "t.svat").string()); !r) return r.error();
    return AtlasTreeFile::open((dir / "t.svat").string());
}

AtlasView viewOf(const Camera& cam, int width = 800, int height = 600) {
    AtlasView v;
    v.eye = cam.position;
    v.viewProj = cam.projectionMatrix(double(width) / height, 0.1) * cam.viewMatrix();
    v.screenWidth = 1920; // as the tree was built: minDistances unscaled
    v.fovXDeg = 90.0;
    return v;
}

/// The block requests of a view 4 m in front of wallTree's walls, looking along the row (their originals wanted).
std::vector<BlockRequest> wallRequests(const AtlasTreeFile& f) {
    Camera cam;
    cam.position = {150.0, -30.0, 4.0};
    cam.pitchDeg = 0.0;
    return AtlasTraversal(f.trees[0], f.info).requests(viewOf(cam));
}

std::map<std::pair<int, std::uint32_t>, BlockCategory> categories(const std::vector<BlockRequest>& r) {
    std::map<std::pair<int, std::uint32_t>, BlockCategory> m;
    for (const auto& b : r) m[{int(b.key.kind), b.key.index}] = b.category;
    return m;
}

} // namespace

TEST(AtlasPagingTest, CategoriesOnAHandMadeTree) {
    const AtlasTreeData t = handTree();
    AtlasTreeInfo info;
    info.dmin = 10.0;
    const AtlasTraversal trav(t, info);
    const int atlas = int(BlockKey::Kind::Atlas), texture = int(BlockKey::Kind::Texture);

    // Straight down inside the first leaf (x 0..25), 5 m up: only it is visible and nearer than every minDistance.
    Camera close;
    close.position = {12.0, 50.0, 5.0};
    close.pitchDeg = -90.0;
    close.fovYDeg = 30.0;
    auto c = categories(trav.requests(viewOf(close)));
    EXPECT_EQ(c.at({atlas, 0}), BlockCategory::Needed);
    EXPECT_EQ(c.at({atlas, 1}), BlockCategory::Needed);   // child 0, refined
    EXPECT_EQ(c.at({atlas, 5}), BlockCategory::Needed);   // its first leaf
    EXPECT_EQ(c.at({texture, 0}), BlockCategory::Needed); // the leaf's original texture
    for (std::uint32_t n : {6u, 7u, 8u, 2u, 3u, 4u}) EXPECT_EQ(c.at({atlas, n}), BlockCategory::Culled) << n;
    EXPECT_EQ(c.count({texture, 1}), 0u);
    // In priority order: the needed ones first.
    const auto req = trav.requests(viewOf(close));
    for (std::size_t i = 1; i < req.size(); ++i) EXPECT_FALSE(req[i] < req[i - 1]);
    // With only the root resident, everything is drawn with the root's atlas, counted as coarser than wanted.
    auto onlyRoot = trav.draws(viewOf(close), [](std::uint32_t n) { return n == 0; }, [](std::uint32_t) { return false; });
    ASSERT_EQ(onlyRoot.draws.size(), 1u);
    EXPECT_EQ(onlyRoot.draws[0].node, 0u);
    EXPECT_FALSE(onlyRoot.draws[0].original);
    EXPECT_EQ(onlyRoot.coarserThanWanted, 1u);
    // Everything resident: the leaf's original texture.
    auto all = trav.draws(viewOf(close), [](std::uint32_t) { return true; }, [](std::uint32_t) { return true; });
    ASSERT_EQ(all.draws.size(), 1u);
    EXPECT_TRUE(all.draws[0].original);
    EXPECT_EQ(all.draws[0].texture, 0u);
    EXPECT_EQ(all.coarserThanWanted, 0u);

    // Far away, everything in view: the root's atlas is enough; its children are the next refinement.
    Camera far;
    far.position = {200.0, -2000.0, 300.0};
    far.yawDeg = 0.0;
    far.pitchDeg = -8.0;
    c = categories(trav.requests(viewOf(far)));
    EXPECT_EQ(c.at({atlas, 0}), BlockCategory::Needed);
    for (std::uint32_t n : {1u, 2u, 3u, 4u}) EXPECT_EQ(c.at({atlas, n}), BlockCategory::ParentNeeded) << n;
    EXPECT_EQ(c.count({atlas, 5}), 0u);
    auto farDraws = trav.draws(viewOf(far), [](std::uint32_t) { return true; }, [](std::uint32_t) { return true; });
    ASSERT_EQ(farDraws.draws.size(), 1u); // the whole tree in one call (§4.8.1)
    EXPECT_EQ(farDraws.draws[0].count, 7u);

    // A wider screen needs finer atlases from further away (minDistance scales with the width, §4.5.2).
    AtlasView wide = viewOf(far);
    wide.screenWidth = 1920 * 100;
    c = categories(trav.requests(wide));
    EXPECT_EQ(c.at({atlas, 1}), BlockCategory::Needed);
}

// Pixels per texel (§4.5.2): a node's atlas serves from its minDistance · τ_build / τ on, τ_build the tree's
// (`atlas build --tpp`, its texels sized to cover τ_build pixels at minDistance) and τ the view's (`--city-tpp`).
TEST(AtlasPagingTest, PixelsPerTexelOfTheBuildAndOfTheView) {
    const AtlasTreeData t = handTree();
    Camera far;
    far.position = {200.0, -2000.0, 300.0};
    far.pitchDeg = -8.0;
    for (const double built : {1.0, 2.0, 0.5}) {
        AtlasTreeInfo info;
        info.dmin = 10.0;
        info.tpp = built;
        const AtlasTraversal trav(t, info);
        for (const double tpp : {1.0, 2.0, 0.25}) {
            AtlasView v = viewOf(far);
            v.tpp = tpp;
            for (std::uint32_t n = 0; n < t.nodes.size(); ++n)
                EXPECT_NEAR(trav.minDistance(n, v), double(t.nodes[n].minDistance) * built / tpp, 1e-9)
                    << "node " << n << " built for " << built << " viewed at " << tpp;
        }
    }
    // The same view asks for finer atlases when fewer pixels per texel are allowed, or when the tree's texels were
    // sized coarser.
    AtlasTreeInfo info;
    info.dmin = 10.0;
    const AtlasTraversal plain(t, info);
    info.tpp = 1000.0;
    const AtlasTraversal coarse(t, info);
    AtlasView v = viewOf(far);
    EXPECT_EQ(categories(plain.requests(v)).at({int(BlockKey::Kind::Atlas), 1}), BlockCategory::ParentNeeded);
    EXPECT_EQ(categories(coarse.requests(v)).at({int(BlockKey::Kind::Atlas), 1}), BlockCategory::Needed);
    v.tpp = 0.001;
    EXPECT_EQ(categories(plain.requests(v)).at({int(BlockKey::Kind::Atlas), 1}), BlockCategory::Needed);
}

// Occlusion (CityRendererGL's queries, here a hand-made answer): the traversal descends only into nodes known
// visible, lists the rest of what is in view as deferred, draws a deferred node's subtree on demand with the nearest
// resident atlas, and pages hidden nodes as Culled.
TEST(AtlasPagingTest, VisibilityDefersHiddenAndUnknownNodes) {
    const AtlasTreeData t = handTree();
    AtlasTreeInfo info;
    info.dmin = 10.0;
    const AtlasTraversal trav(t, info);
    const auto all = [](std::uint32_t) { return true; };
    auto has = [](const std::vector<std::uint32_t>& v, std::uint32_t n) { return std::find(v.begin(), v.end(), n) != v.end(); };

    // 15 m in front of the root's middle, looking along it with a wide view: the root refines into its four children,
    // each drawn with its atlas.
    Camera cam;
    cam.position = {200.0, -15.0, 5.0};
    cam.pitchDeg = 0.0;
    cam.fovYDeg = 90.0;
    const AtlasView v = viewOf(cam);
    const auto plain = trav.draws(v, all, all);
    ASSERT_EQ(plain.drawn.size(), 4u);
    EXPECT_TRUE(plain.deferred.empty());

    // Node 2 hidden, node 3 not known: neither drawn, both deferred; the others as before.
    const VisibilityFn vis = [](std::uint32_t n) {
        return n == 2 ? NodeVisibility::Hidden : n == 3 ? NodeVisibility::Unknown : NodeVisibility::Visible;
    };
    const auto occl = trav.draws(v, all, all, vis);
    EXPECT_EQ(occl.drawn.size(), 2u);
    EXPECT_TRUE(has(occl.drawn, 1) && has(occl.drawn, 4));
    EXPECT_EQ(occl.deferred.size(), 2u);
    EXPECT_TRUE(has(occl.deferred, 2) && has(occl.deferred, 3));
    for (const AtlasDraw& d : occl.draws) {
        // Leaves 2 and 3 are triangles 4 and 5 (depth-first order).
        EXPECT_FALSE(d.first <= 4 && 4 < d.first + d.count) << "node 2's triangle drawn";
        EXPECT_FALSE(d.first <= 5 && 5 < d.first + d.count) << "node 3's triangle drawn";
    }

    // Paging: the hidden node is Culled (and its originals not asked for), the unknown one treated as visible.
    const auto c = categories(trav.requests(v, vis));
    const int atlas = int(BlockKey::Kind::Atlas);
    EXPECT_EQ(c.at({atlas, 2}), BlockCategory::Culled);
    EXPECT_EQ(c.at({atlas, 3}), BlockCategory::Needed);
    EXPECT_EQ(c.at({atlas, 1}), BlockCategory::Needed);
    EXPECT_EQ(categories(trav.requests(v)).at({atlas, 2}), BlockCategory::Needed);

    // Node 3 found visible: drawn alone, with its own atlas, or the root's while its own is not resident.
    const auto below = trav.drawsBelow(3, v, all, all, vis);
    ASSERT_EQ(below.drawn.size(), 1u);
    EXPECT_EQ(below.drawn[0], 3u);
    ASSERT_EQ(below.draws.size(), 1u);
    EXPECT_EQ(below.draws[0].first, 5u);
    EXPECT_EQ(below.draws[0].node, 3u);
    EXPECT_EQ(below.coarserThanWanted, 0u);
    const auto standIn = trav.drawsBelow(3, v, [](std::uint32_t n) { return n == 0; }, all, vis);
    ASSERT_EQ(standIn.draws.size(), 1u);
    EXPECT_EQ(standIn.draws[0].node, 0u) << "the root's atlas stands in";
    EXPECT_EQ(standIn.draws[0].level, 0);
    EXPECT_EQ(standIn.draws[0].first, 5u);
    EXPECT_EQ(standIn.coarserThanWanted, 1u);

    // Refinement waits only for the children known visible: node 1 refines although hidden node 6's atlas is not
    // resident (without the answer it would be drawn coarse, waiting for it).
    Camera near;
    near.position = {50.0, -10.0, 5.0};
    near.pitchDeg = 0.0;
    near.fovYDeg = 90.0;
    const AtlasView nv = viewOf(near);
    const auto not6 = [](std::uint32_t n) { return n != 6; };
    const VisibilityFn hide6 = [](std::uint32_t n) { return n == 6 ? NodeVisibility::Hidden : NodeVisibility::Visible; };
    const auto waits = trav.draws(nv, not6, all);
    EXPECT_TRUE(has(waits.drawn, 1)) << "drawn with its own atlas while a child loads";
    EXPECT_GE(waits.coarserThanWanted, 1u);
    const auto refined = trav.draws(nv, not6, all, hide6);
    EXPECT_FALSE(has(refined.drawn, 1));
    EXPECT_TRUE(has(refined.drawn, 5) && has(refined.drawn, 7));
    EXPECT_TRUE(has(refined.deferred, 6));
    EXPECT_EQ(refined.coarserThanWanted, 0u);
    EXPECT_TRUE(has(refined.opened, 0) && has(refined.opened, 1));

    // An inner node found visible whose own atlas is not resident: its children, refined into, fall back on the
    // root's atlas too (at the root's level).
    const auto rootOnly = [](std::uint32_t n) { return n == 0; };
    const auto fallback = trav.drawsBelow(1, nv, rootOnly, all, hide6);
    EXPECT_TRUE(has(fallback.drawn, 1)) << "node 1 cannot refine: its visible children's atlases are missing";
    for (const AtlasDraw& d : fallback.draws) {
        EXPECT_EQ(d.node, 0u);
        EXPECT_EQ(d.level, 0);
    }
    const auto childrenResident = [](std::uint32_t n) { return n != 1; };
    const auto through = trav.drawsBelow(1, nv, childrenResident, all, hide6);
    EXPECT_TRUE(has(through.opened, 1) && has(through.drawn, 5) && has(through.drawn, 7));
    EXPECT_EQ(through.coarserThanWanted, 0u);

    // A hidden root: nothing below it is asked for, only the root's own atlas (the fallback for everything).
    const VisibilityFn hideAll = [](std::uint32_t) { return NodeVisibility::Hidden; };
    const auto onlyRootAsked = trav.requests(v, hideAll);
    ASSERT_EQ(onlyRootAsked.size(), 1u);
    EXPECT_EQ(onlyRootAsked[0].key.index, 0u);
    EXPECT_EQ(onlyRootAsked[0].category, BlockCategory::Needed);
    const auto nothing = trav.draws(v, all, all, hideAll);
    EXPECT_TRUE(nothing.draws.empty());
    ASSERT_EQ(nothing.deferred.size(), 1u);
    EXPECT_EQ(nothing.deferred[0], 0u);
}

TEST(AtlasPagingTest, CapacityIsNeverExceededUnderARandomCamera) {
    test::TempDir dir("atlas_paging");
    auto f = wallTree(dir.path(), 40);
    ASSERT_TRUE(f) << f.error().message;
    const AtlasTraversal trav(f->trees[0], f->info);
    PagerSettings ps;
    ps.threaded = false;
    ps.queueLength = 3;
    AtlasPager probe(*f, 0, ps);
    const std::uint64_t atlasBytes = probe.blockBytes({BlockKey::Kind::Atlas, 0});
    ps.capacityBytes = 4 * atlasBytes + 256u * 128u * 4u * 4u / 3u; // four atlases and one original texture
    AtlasPager pager(*f, 0, ps);
    // The 256×128 wall photos (RGBA8 with mips: 2.7 atlases of 128² RGB8) are paged as three bands of rows of about
    // an atlas each (§4.6: blocks of about equal size), together the whole texture.
    ASSERT_EQ(pager.textureParts(0), 3);
    std::uint64_t partBytes = 0;
    int rows = 0;
    for (int p = 0; p < 3; ++p) {
        const auto [r0, r1] = pager.partRows(0, p);
        EXPECT_EQ(r0, rows);
        rows = r1;
        const std::uint64_t b = pager.blockBytes({BlockKey::Kind::Texture, 0, std::uint16_t(p)});
        EXPECT_LE(b, 65536u + 65536u / 4u) << p;
        partBytes += b;
    }
    EXPECT_EQ(rows, 128);
    EXPECT_NEAR(double(partBytes), 256.0 * 128.0 * 4.0 * 4.0 / 3.0, 3.0);
    std::uint64_t seed = 7;
    auto rnd = [&] {
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        return double(seed >> 11) / 9007199254740992.0;
    };
    std::size_t uploads = 0, evictions = 0, textureParts = 0;
    std::set<std::tuple<int, std::uint32_t, int>> gpu; // what the GL side would hold
    for (int frame = 0; frame < 300; ++frame) {
        Camera cam;
        cam.position = {rnd() * 700.0 - 50.0, -5.0 - rnd() * 300.0, 1.0 + rnd() * 100.0};
        cam.yawDeg = rnd() * 90.0 - 45.0;
        cam.pitchDeg = -rnd() * 40.0;
        const AtlasView v = viewOf(cam);
        auto out = pager.update(trav.requests(v));
        for (const auto& k : out.evict) EXPECT_EQ(gpu.erase({int(k.kind), k.index, k.part}), 1u);
        for (const auto& k : out.evict) // a split texture leaves whole: no band of it stays behind
            if (k.kind == BlockKey::Kind::Texture) {
                for (int p = 0; p < 3; ++p) EXPECT_EQ(gpu.count({int(k.kind), k.index, p}), 0u) << k.index << " part " << p;
            }
        for (const auto& b : out.upload) {
            EXPECT_TRUE(gpu.insert({int(b.key.kind), b.key.index, b.key.part}).second);
            if (b.key.kind == BlockKey::Kind::Texture) {
                ++textureParts;
                EXPECT_EQ(b.parts, 3);
                EXPECT_EQ(b.firstRow, pager.partRows(b.key.index, b.key.part).first);
                EXPECT_EQ(b.data.size(), std::size_t(b.size.x) * std::size_t(b.rows) * 4u);
            }
        }
        uploads += out.upload.size();
        evictions += out.evict.size();
        const auto& st = pager.stats();
        EXPECT_LE(st.residentBytes + st.reservedBytes, ps.capacityBytes) << "frame " << frame;
        // The GL side allocates a split texture whole with its first band and frees it with its last.
        std::uint64_t held = 0;
        std::set<std::uint32_t> textures;
        for (const auto& [kind, index, part] : gpu)
            if (BlockKey::Kind(kind) == BlockKey::Kind::Atlas) held += pager.blockBytes({BlockKey::Kind::Atlas, index});
            else if (textures.insert(index).second) held += pager.textureBytes(index);
        EXPECT_EQ(held, st.residentBytes);
        EXPECT_LE(held, ps.capacityBytes) << "frame " << frame;
        // The root is always there after the first frame, and every draw uses a resident texture.
        EXPECT_TRUE(pager.resident({BlockKey::Kind::Atlas, 0}));
        auto d = trav.draws(v, [&](std::uint32_t n) { return pager.resident({BlockKey::Kind::Atlas, n}); },
                            [&](std::uint32_t t) { return pager.textureResident(t); });
        for (const auto& dr : d.draws) {
            if (!dr.original) {
                EXPECT_TRUE(pager.resident({BlockKey::Kind::Atlas, dr.node}));
                continue;
            }
            for (int p = 0; p < 3; ++p) // an original is drawn only with all its rows on the GPU
                EXPECT_TRUE(gpu.count({int(BlockKey::Kind::Texture), dr.texture, p})) << dr.texture << " part " << p;
        }
    }
    EXPECT_GT(uploads, 10u);
    EXPECT_GT(evictions, 0u); // the capacity forced paging
    EXPECT_GT(textureParts, 0u); // originals were paged (in parts)
    EXPECT_TRUE(pager.error().empty());
}

// The bands of a split original tile its rows exactly, none empty, whatever its size against the atlases' (a
// 4096² texture beside 512² atlases: 65 bands of 64 rows would leave the last one empty).
TEST(AtlasPagingTest, TextureBandsAreNeverEmpty) {
    for (const int atlasSize : {64, 128, 512})
    for (const bool alpha : {false, true}) {
        AtlasTreeFile f;
        f.info.atlasSize = atlasSize;
        f.trees.resize(1);
        f.trees[0].alpha = alpha;
        for (const int w : {64, 256, 300, 1024, 4096})
            for (const int h : {1, 7, 128, 256, 1000, 4096}) f.textureSizes.push_back({w, h});
        f.textures.resize(f.textureSizes.size());
        PagerSettings ps;
        ps.threaded = false;
        const AtlasPager pager(f, 0, ps);
        for (std::uint32_t t = 0; t < f.textureSizes.size(); ++t) {
            const int parts = pager.textureParts(t), h = f.textureSizes[t].y;
            ASSERT_GE(parts, 1);
            int next = 0;
            std::uint64_t bytes = 0;
            for (int p = 0; p < parts; ++p) {
                const auto [r0, r1] = pager.partRows(t, p);
                EXPECT_EQ(r0, next) << atlasSize << " " << f.textureSizes[t].x << "x" << h << " part " << p;
                EXPECT_GT(r1, r0) << atlasSize << " " << f.textureSizes[t].x << "x" << h << " part " << p << " of " << parts;
                next = r1;
                bytes += pager.blockBytes({BlockKey::Kind::Texture, t, std::uint16_t(p)});
            }
            EXPECT_EQ(next, h);
            // Each band's share of every mip level's rows: together they are all of them, once.
            for (int l = 1; (std::max(f.textureSizes[t].x, h) >> l) > 0; ++l) {
                int at = 0;
                for (int p = 0; p < parts; ++p) {
                    const auto [r0, r1] = pager.partRows(t, p);
                    const auto [m0, m1] = bandMipRows(r0, r1, h, l);
                    EXPECT_EQ(m0, at) << h << " rows, level " << l << ", part " << p;
                    EXPECT_GE(m1, m0);
                    at = m1;
                }
                EXPECT_EQ(at, std::max(h >> l, 1)) << h << " rows, level " << l;
            }
            const double whole = double(f.textureSizes[t].x) * h * 4.0 * 4.0 / 3.0;
            EXPECT_NEAR(double(bytes), whole, double(parts) + 1.0);
        }
    }
}

// A split original enters the ideal set with all its bands or none (§4.6: a partial texture cannot be drawn), so
// under any capacity the view's completed set holds every texture whole or not at all, and the bytes counted are the
// whole textures' (the GL side allocates a texture whole with its first band).
TEST(AtlasPagingTest, SplitTexturesAreHeldWholeOrNotAtAll) {
    test::TempDir dir("atlas_paging_whole");
    auto f = wallTree(dir.path(), 20);
    ASSERT_TRUE(f) << f.error().message;
    const auto req = wallRequests(*f);
    PagerSettings ps;
    ps.threaded = false;
    const AtlasPager probe(*f, 0, ps);
    ASSERT_EQ(probe.textureParts(0), 3);
    const std::uint64_t root = probe.blockBytes({BlockKey::Kind::Atlas, 0}),
                        band = probe.blockBytes({BlockKey::Kind::Texture, 0, 1}), whole = probe.textureBytes(0);
    // What the requests would take whole (each split texture once, whole), whatever the capacity.
    std::uint64_t requested = 0;
    for (const auto& r : req)
        requested += r.key.kind == BlockKey::Kind::Texture && probe.textureParts(r.key.index) > 1 ? probe.textureBytes(r.key.index)
                                                                                                  : probe.blockBytes(r.key);
    std::size_t wholeSeen = 0, capacities = 0;
    for (std::uint64_t capacity = root + band / 2; capacity < root + 12 * whole; capacity += band / 2, ++capacities) {
        ps.capacityBytes = capacity;
        AtlasPager pager(*f, 0, ps);
        pager.complete(req);
        EXPECT_EQ(pager.stats().idealMissing, 0u) << "capacity " << capacity << ": the ideal set is what fits";
        EXPECT_EQ(pager.stats().requestedBytes, requested) << "capacity " << capacity;
        EXPECT_LE(pager.stats().idealBytes, capacity);
        if (capacity < requested) {
            EXPECT_LT(pager.stats().idealBytes, requested) << "capacity " << capacity << ": the view wants more than fits";
        } else {
            EXPECT_EQ(pager.stats().idealBytes, requested) << "capacity " << capacity << ": everything fits";
        }
        std::map<std::uint32_t, int> parts; // texture -> resident parts
        for (const auto& r : req)
            if (r.key.kind == BlockKey::Kind::Texture)
                for (int p = 0; p < 3; ++p) parts[r.key.index] += pager.resident({BlockKey::Kind::Texture, r.key.index, std::uint16_t(p)});
        std::uint64_t expected = 0;
        for (const auto& r : req)
            if (r.key.kind == BlockKey::Kind::Atlas && pager.resident(r.key)) expected += pager.blockBytes(r.key);
        for (const auto& [t, n] : parts) {
            EXPECT_TRUE(n == 0 || n == 3) << "capacity " << capacity << ": texture " << t << " has " << n << " of 3 bands";
            wholeSeen += n == 3;
            if (n > 0) expected += whole;
        }
        EXPECT_EQ(pager.stats().residentBytes, expected) << "capacity " << capacity;
        EXPECT_LE(pager.stats().residentBytes, capacity);
    }
    EXPECT_GT(capacities, 30u);
    EXPECT_GT(wholeSeen, 20u) << "textures were paged in under the larger capacities";
    ps.capacityBytes = requested; // everything fits: the ideal set is every request
    AtlasPager all(*f, 0, ps);
    all.complete(req);
    EXPECT_EQ(all.stats().requestedBytes, requested);
    EXPECT_EQ(all.stats().idealBytes, requested);
}

// Original textures arrive with their box mips (the atlases' filter), made on the loader thread: a whole texture
// with all its levels, a split one with each band's share of every level's rows; put together they are the
// original's mips exactly.
TEST(AtlasPagingTest, OriginalsArriveWithTheirBoxMips) {
    test::TempDir dir("atlas_paging_mips");
    const CityModel m = noiseWalls(dir.path(), {{300, 200}, {21, 13}}, {{{0, 0}, {1, 1}}, {{0, 0}, {1, 1}}});
    AtlasBuildSettings s;
    s.atlasSize = 64;
    s.dmin = 200.0;
    ASSERT_TRUE(buildAtlasTree(m, s, (dir / "t.svat").string()));
    auto f = AtlasTreeFile::open((dir / "t.svat").string());
    ASSERT_TRUE(f) << f.error().message;
    Camera cam;
    cam.position = {11.0, -12.0, 4.0};
    cam.pitchDeg = 0.0;
    PagerSettings ps;
    ps.threaded = false;
    AtlasPager pager(*f, 0, ps);
    ASSERT_GT(pager.textureParts(0), 2);
    ASSERT_EQ(pager.textureParts(1), 1);
    const auto frame = pager.complete(AtlasTraversal(f->trees[0], f->info).requests(viewOf(cam)));
    for (std::uint32_t tex = 0; tex < 2; ++tex) {
        auto st = readSourceTexture(m.textures[tex]);
        ASSERT_TRUE(st);
        std::vector<std::vector<std::uint8_t>> got(st->mips.size());
        std::vector<std::vector<int>> filled(st->mips.size());
        for (std::size_t l = 0; l < st->mips.size(); ++l) {
            got[l].assign(st->mips[l].size(), 0);
            filled[l].assign(std::size_t(st->sizes[l].y), 0);
        }
        int blocks = 0;
        for (const LoadedBlock& b : frame.upload) {
            if (b.key.kind != BlockKey::Kind::Texture || b.key.index != tex) continue;
            ++blocks;
            ASSERT_EQ(b.mips.size(), st->mips.size() - 1);
            ASSERT_EQ(b.mipFirstRows.size(), b.mips.size());
            auto put = [&](std::size_t l, int first, const std::vector<std::uint8_t>& rows) {
                const std::size_t row = std::size_t(st->sizes[l].x) * 4;
                ASSERT_EQ(rows.size() % row, 0u);
                const int n = int(rows.size() / row);
                ASSERT_LE(first + n, st->sizes[l].y);
                std::copy(rows.begin(), rows.end(), got[l].begin() + std::ptrdiff_t(row * std::size_t(first)));
                for (int y = first; y < first + n; ++y) ++filled[l][std::size_t(y)];
            };
            put(0, b.firstRow, b.data);
            for (std::size_t l = 1; l < st->mips.size(); ++l) put(l, b.mipFirstRows[l - 1], b.mips[l - 1]);
        }
        EXPECT_EQ(blocks, pager.textureParts(tex)) << "texture " << tex << " paged in whole";
        for (std::size_t l = 0; l < st->mips.size(); ++l) {
            for (int y = 0; y < st->sizes[l].y; ++y)
                EXPECT_EQ(filled[l][std::size_t(y)], 1) << "texture " << tex << " level " << l << " row " << y;
            EXPECT_TRUE(got[l] == st->mips[l]) << "texture " << tex << " level " << l;
        }
    }
}

// The loader gets at most queueLength blocks at a time, and loaded blocks are handed out for upload within the
// per-frame byte budget (at least one block a frame), so the ideal set arrives over several frames.
TEST(AtlasPagingTest, LoaderQueueAndUploadBudget) {
    test::TempDir dir("atlas_paging_budget");
    auto f = wallTree(dir.path(), 20);
    ASSERT_TRUE(f) << f.error().message;
    const auto req = wallRequests(*f);

    // Loads inside update(): no more than queueLength a frame; uploads within the budget.
    PagerSettings ps;
    ps.threaded = false;
    ps.queueLength = 2;
    ps.capacityBytes = 64ull << 20;
    int calls = 0;
    AtlasPager probe(*f, 0, ps);
    ps.uploadBytesPerFrame = 2 * probe.blockBytes({BlockKey::Kind::Texture, 0, 1}) + 10;
    AtlasPager pager(*f, 0, ps, [&](const BlockKey& k) -> Result<LoadedBlock> {
        ++calls;
        LoadedBlock b;
        b.key = k;
        b.bytes = probe.blockBytes(k);
        return b;
    });
    int frames = 0, loadsBefore = 0;
    std::uint64_t total = 0;
    std::size_t maxBlocksAFrame = 0;
    for (; frames < 1000; ++frames) {
        const auto out = pager.update(req);
        EXPECT_LE(calls - loadsBefore, ps.queueLength) << "frame " << frames;
        loadsBefore = calls;
        std::uint64_t bytes = 0;
        for (const auto& b : out.upload) bytes += b.bytes;
        if (out.upload.size() > 1) {
            EXPECT_LE(bytes, ps.uploadBytesPerFrame) << "frame " << frames;
        }
        maxBlocksAFrame = std::max(maxBlocksAFrame, out.upload.size());
        total += bytes;
        if (pager.stats().idealMissing == 0 && pager.stats().queued == 0) break;
    }
    EXPECT_EQ(pager.stats().idealMissing, 0u);
    EXPECT_NEAR(double(total), double(pager.stats().residentBytes), 100.0); // bands' bytes vs whole textures'
    EXPECT_GE(std::uint64_t(frames + 1) * ps.uploadBytesPerFrame, total) << "the budget spread the uploads";
    EXPECT_GT(total, 4 * ps.uploadBytesPerFrame);
    EXPECT_GE(maxBlocksAFrame, 2u);

    // A background loader that is slow: what waits for it (queued, loading, loaded) never exceeds queueLength.
    std::mutex gate;
    std::unique_lock<std::mutex> closed(gate);
    int threadedCalls = 0;
    std::mutex callsMutex;
    ps.threaded = true;
    ps.queueLength = 3;
    {
        AtlasPager slow(*f, 0, ps, [&](const BlockKey& k) -> Result<LoadedBlock> {
            {
                std::lock_guard lock(callsMutex);
                ++threadedCalls;
            }
            std::lock_guard wait(gate); // held closed by the test until it opens it
            LoadedBlock b;
            b.key = k;
            b.bytes = probe.blockBytes(k);
            return b;
        });
        for (int i = 0; i < 20; ++i) {
            const auto out = slow.update(req);
            EXPECT_TRUE(out.upload.empty());
            EXPECT_LE(slow.stats().queued, std::size_t(ps.queueLength)) << "update " << i;
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
        EXPECT_EQ(slow.stats().queued, std::size_t(ps.queueLength));
        EXPECT_GT(slow.stats().idealMissing, std::size_t(ps.queueLength)) << "more is missing than may wait";
        closed.unlock();
        slow.complete(req);
        EXPECT_EQ(slow.stats().idealMissing, 0u);
        EXPECT_EQ(slow.stats().queued, 0u);
    }
    std::lock_guard lock(callsMutex);
    EXPECT_GT(threadedCalls, ps.queueLength);
}

// The view changes while the loader is busy (the eye comes down after an overview): the blocks that come first now
// (coarser, then higher priority) wait before those queued earlier, and take the place of the last of them when the
// queue is full.
TEST(AtlasPagingTest, QueuedBlocksWaitInTheLatestFramesOrder) {
    test::TempDir dir("atlas_paging_priority");
    auto f = wallTree(dir.path(), 40);
    ASSERT_TRUE(f) << f.error().message;
    std::vector<std::uint32_t> nodes; // atlases other than the root's
    for (std::uint32_t n = 1; n < f->trees[0].nodes.size() && nodes.size() < 6; ++n)
        if (f->trees[0].nodes[n].atlasBytes > 0) nodes.push_back(n);
    ASSERT_EQ(nodes.size(), 6u);
    auto ask = [](std::uint32_t node, double distance, int level = 2) {
        return BlockRequest{{BlockKey::Kind::Atlas, node}, BlockCategory::Needed, distance, node == 0 ? 0 : level};
    };
    std::mutex gate, orderMutex;
    std::unique_lock<std::mutex> closed(gate);
    std::vector<std::uint32_t> order; // atlases in the order the loader began them
    PagerSettings ps;
    ps.threaded = true;
    ps.queueLength = 3;
    AtlasPager probe(*f, 0, PagerSettings{});
    AtlasPager pager(*f, 0, ps, [&](const BlockKey& k) -> Result<LoadedBlock> {
        {
            std::lock_guard lock(orderMutex);
            order.push_back(k.index);
        }
        std::lock_guard wait(gate); // held closed by the test until it opens it
        LoadedBlock b;
        b.key = k;
        b.bytes = probe.blockBytes(k);
        return b;
    });
    auto begun = [&] {
        std::lock_guard lock(orderMutex);
        return order.size();
    };
    // Far blocks: the root goes to the loader (which waits at the gate), nodes[0] and nodes[1] wait in the queue.
    const std::vector<BlockRequest> far{ask(0, 0.0), ask(nodes[0], 100.0), ask(nodes[1], 110.0), ask(nodes[2], 120.0)};
    pager.update(far);
    for (int i = 0; i < 5000 && begun() == 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    ASSERT_EQ(begun(), 1u);
    EXPECT_EQ(pager.stats().queued, 3u);
    // Nearer now: nodes[5] first (coarser, though farther), then nodes[3] and nodes[4], then nodes[1] (nearer than
    // nodes[0] now); nodes[0] last.
    const std::vector<BlockRequest> near{ask(0, 0.0),          ask(nodes[3], 5.0),   ask(nodes[4], 6.0),
                                         ask(nodes[1], 50.0),  ask(nodes[0], 200.0), ask(nodes[5], 300.0, 1)};
    pager.update(near);
    EXPECT_LE(pager.stats().queued, 3u);
    closed.unlock();
    pager.complete(near);
    EXPECT_EQ(pager.stats().idealMissing, 0u);
    std::lock_guard lock(orderMutex);
    const std::vector<std::uint32_t> expected{0, nodes[5], nodes[3], nodes[4], nodes[1], nodes[0]};
    EXPECT_EQ(order, expected);
}

TEST(AtlasPagingTest, ThreadedLoaderCompletesTheIdealSet) {
    test::TempDir dir("atlas_paging_thread");
    auto f = wallTree(dir.path(), 20);
    ASSERT_TRUE(f) << f.error().message;
    const AtlasTraversal trav(f->trees[0], f->info);
    PagerSettings ps;
    ps.capacityBytes = 64ull << 20;
    AtlasPager pager(*f, 0, ps);
    Camera cam;
    cam.position = {150.0, -30.0, 4.0};
    cam.pitchDeg = 0.0;
    const auto req = trav.requests(viewOf(cam));
    auto done = pager.complete(req);
    EXPECT_FALSE(done.upload.empty());
    for (const auto& r : req)
        EXPECT_TRUE(r.key.kind == BlockKey::Kind::Texture ? pager.textureResident(r.key.index) : pager.resident(r.key));
    // Nothing coarser than wanted once the ideal set is resident.
    auto d = trav.draws(viewOf(cam), [&](std::uint32_t n) { return pager.resident({BlockKey::Kind::Atlas, n}); },
                        [&](std::uint32_t t) { return pager.textureResident(t); });
    EXPECT_EQ(d.coarserThanWanted, 0u);
    EXPECT_GT(d.draws.size(), 0u);
    // 4 m from the walls their originals are drawn: every part of each was loaded.
    std::size_t originals = 0;
    for (const auto& dr : d.draws)
        if (dr.original) {
            ++originals;
            for (int p = 0; p < pager.textureParts(dr.texture); ++p)
                EXPECT_TRUE(pager.resident({BlockKey::Kind::Texture, dr.texture, std::uint16_t(p)}));
        }
    EXPECT_GT(originals, 0u);
    EXPECT_EQ(pager.textureParts(0), 3);
}

TEST(AtlasTreeTest, SplitFillsLeavesInsteadOfQuartering) {
    // 40 walls of 64×54 atlas texels (border included) at dmin 200 m; a 128² atlas holds four. Quartering the
    // texture groups area-evenly leaves 2–3 walls per leaf (16 leaves); the build packs Hilbert-ordered runs of
    // walls as long as they still pack instead, so the leaves are as few as the atlas allows and each still
    // holds whole texture groups.
    test::TempDir dir("atlas_fill");
    auto built = buildSmall(wallModel(dir.path(), 40), dir / "t.svat");
    ASSERT_TRUE(built);
    const AtlasTreeData& t = built->file.trees[0];
    checkStructure(t, built->file.info);
    int full = 0;
    for (const auto& n : t.nodes)
        if (n.leaf() && n.count > 0) {
            ++full;
            EXPECT_LE(n.count, 4u * 2u) << "at most four walls fit a leaf";
        }
    EXPECT_EQ(full, 10) << "40 walls, four per leaf";
    EXPECT_GE(built->report.meanLeafFill, 0.8);
}

TEST(AtlasTreeTest, InnerNodesHoldAsManyLeavesAsTheirMinDistanceAllows) {
    // 68 walls, four per leaf: 17 leaves. A node whose minDistance is dmin · 2^k shows its subtree at 1/2^k of the
    // leaves' resolution, so it should hold 4^k leaves: then the fewest nodes cover a view at every distance. The
    // runs are dealt full shares first (16 + 1 here): only the root holds fewer (17 of 64), the 17th leaf hangs
    // under it. Near-equal shares (5 + 4 + 4 + 4, then 2 + 1 + 1 + 1) leave the first child with 5 of 16 and a
    // grandchild with 2 of 4.
    test::TempDir dir("atlas_full");
    auto built = buildSmall(wallModel(dir.path(), 68), dir / "t.svat");
    ASSERT_TRUE(built);
    const AtlasTreeData& t = built->file.trees[0];
    checkStructure(t, built->file.info);
    std::function<int(std::size_t)> leavesBelow = [&](std::size_t i) {
        const AtlasNode& n = t.nodes[i];
        if (n.leaf()) return n.count > 0 ? 1 : 0;
        int sum = 0;
        for (int c : n.children) sum += leavesBelow(std::size_t(c));
        return sum;
    };
    EXPECT_EQ(leavesBelow(0), 17);
    int shortNodes = 0, inner = 0;
    for (std::size_t i = 0; i < t.nodes.size(); ++i) {
        const AtlasNode& n = t.nodes[i];
        if (n.leaf() || n.count == 0) continue;
        ++inner;
        const int k = int(std::lround(std::log2(double(n.minDistance) / built->file.info.dmin)));
        ASSERT_GE(k, 1);
        const int want = 1 << (2 * k);
        if (leavesBelow(i) < want) {
            ++shortNodes;
            EXPECT_EQ(i, 0u) << "node " << i << " at level " << n.level << ": " << leavesBelow(i) << " of " << want;
        }
        EXPECT_LE(leavesBelow(i), want) << "node " << i;
    }
    EXPECT_EQ(shortNodes, 1);
    EXPECT_EQ(inner, 6) << "the root, the parent of the first 16 leaves and its four children of four leaves each";

    // 72 walls, 18 leaves: the tail of two runs becomes two leaves under the root's second child, not a chain of
    // single-child copies of that node down to the leaves' level.
    test::TempDir dir2("atlas_full18");
    auto built2 = buildSmall(wallModel(dir2.path(), 72), dir2 / "t.svat");
    ASSERT_TRUE(built2);
    const AtlasTreeData& t2 = built2->file.trees[0];
    checkStructure(t2, built2->file.info);
    int leaves2 = 0;
    for (std::size_t i = 0; i < t2.nodes.size(); ++i) {
        const AtlasNode& n = t2.nodes[i];
        if (n.leaf()) {
            leaves2 += n.count > 0 ? 1 : 0;
            continue;
        }
        int nonEmpty = 0;
        for (int c : n.children) nonEmpty += t2.nodes[std::size_t(c)].count > 0 ? 1 : 0;
        EXPECT_GE(nonEmpty, 2) << "node " << i << " at level " << n.level << " has one non-empty child";
    }
    EXPECT_EQ(leaves2, 18);
    EXPECT_EQ(t2.nodes.size(), 1u + 4u + 8u + 16u)
        << "the root; its four children (16 runs, 2 runs, two empty); their 4 + 4 children; 16 leaves below the first";
}

TEST(AtlasTreeTest, TurnedAreasKeepTheTextureOrientation) {
    // Three walls 6.6 m × 13.3 m with 64² gradient textures (red = u, green = v) at dmin 200 m (4.8 px/m): 48×80
    // atlas texels each with the border, so a 128² atlas holds them only with one turned (MAXRECTS); the skyline
    // packer needs two leaves. Every triangle, sampled through its atlas coordinates, shows the original's texel
    // at its texture coordinates: a turned area is transposed consistently in texels and coordinates.
    test::TempDir dir("atlas_turn");
    CityModel m;
    m.source = (dir / "model").string();
    m.crs = Crs::utm(33, true);
    for (int i = 0; i < 3; ++i) {
        const auto path = dir / ("g" + std::to_string(i) + ".png");
        std::vector<std::uint8_t> px(64 * 64 * 3);
        for (int y = 0; y < 64; ++y)
            for (int x = 0; x < 64; ++x) {
                px[std::size_t(y * 64 + x) * 3 + 0] = std::uint8_t(x * 4 + 2);
                px[std::size_t(y * 64 + x) * 3 + 1] = std::uint8_t(y * 4 + 2);
                px[std::size_t(y * 64 + x) * 3 + 2] = std::uint8_t(60 * i);
            }
        writeTexture(path, 64, 64, 3, px);
        m.textures.push_back(CityTexture{path.string(), false, 3, 64, 64});
        m.buildingIds.push_back("b" + std::to_string(i));
        const double x0 = 20.0 * i, w = 6.6, h = 13.3;
        TexturedTriangle a, b;
        a.v = {glm::dvec3(x0, 0, 0), glm::dvec3(x0 + w, 0, 0), glm::dvec3(x0 + w, 0, h)};
        a.t = {glm::dvec2(0, 0), glm::dvec2(1, 0), glm::dvec2(1, 1)};
        b.v = {glm::dvec3(x0, 0, 0), glm::dvec3(x0 + w, 0, h), glm::dvec3(x0, 0, h)};
        b.t = {glm::dvec2(0, 0), glm::dvec2(1, 1), glm::dvec2(0, 1)};
        a.texture = b.texture = i;
        for (const auto& t : {a, b}) {
            m.triangles.push_back(t);
            m.building.push_back(std::uint32_t(i));
            m.surface.push_back(Surface::Wall);
        }
    }
    auto sky = buildSmall(m, dir / "s.svat", AtlasPacker::Skyline);
    ASSERT_TRUE(sky);
    EXPECT_EQ(sky->report.leaves - sky->report.emptyLeaves, 2u);
    auto built = buildSmall(m, dir / "t.svat");
    ASSERT_TRUE(built);
    EXPECT_EQ(built->report.nodes, 1u) << "all three walls in the root's atlas";
    EXPECT_NEAR(built->report.meanLeafFill, 3.0 * 48 * 80 / (128.0 * 128.0), 1e-9);
    const AtlasTreeData& t = built->file.trees[0];
    auto atlas = built->file.readAtlasRgba(0, 0);
    ASSERT_TRUE(atlas);
    int checked = 0, worst = 0;
    for (std::uint32_t tri = 0; tri < t.nodes[0].count; ++tri)
        for (const glm::dvec3 bary : {glm::dvec3(0.6, 0.2, 0.2), glm::dvec3(0.2, 0.6, 0.2), glm::dvec3(0.2, 0.2, 0.6),
                                      glm::dvec3(0.45, 0.45, 0.1), glm::dvec3(0.1, 0.3, 0.6)}) {
            glm::dvec2 uv(0.0), root(0.0);
            for (int k = 0; k < 3; ++k) {
                uv += bary[k] * glm::dvec2(t.vertices[tri * 3 + std::size_t(k)].uv);
                root += bary[k] * glm::dvec2(t.vertices[tri * 3 + std::size_t(k)].root);
            }
            const glm::u8vec4 got = texel(*atlas, 128, levelAtlasCoord(root, 0));
            // The atlas holds the 64² texture at 32×64 texels: red steps by 8 per atlas texel, green by 4. Image
            // rows run down, v up (OpenGL's convention): green = (1 - v) · 256.
            const double red = uv.x * 256.0, green = (1.0 - uv.y) * 256.0;
            EXPECT_NEAR(int(got.r), red, 10.0) << "triangle " << tri << " uv " << uv.x << "," << uv.y;
            EXPECT_NEAR(int(got.g), green, 6.0) << "triangle " << tri << " uv " << uv.x << "," << uv.y;
            EXPECT_EQ(int(got.b), 60 * int(t.triangleTexture[tri]));
            worst = std::max({worst, int(std::abs(got.r - red)), int(std::abs(got.g - green))});
            ++checked;
        }
    EXPECT_EQ(checked, 30);
    RecordProperty("worst_channel_error", worst);
}

// Where the original caps a texture's size (a view at dmin would want more texels than it has), its leaf area is
// the original's texels one to one (snapped to its 8-texel grid, placed on multiples of 8), so the atlas's mips 0–3
// are the original's box mips texel for texel: no half-texel resampling blur, no other blocks averaged.
TEST(AtlasTreeTest, CappedOriginalsAreCopiedTexelForTexelAndMipForMip) {
    test::TempDir dir("atlas_copy");
    const CityModel m = noiseWalls(dir.path(), {{61, 37}, {45, 29}, {23, 50}, {70, 19}},
                                   {{{0.13, 0.07}, {0.91, 0.83}}, {{0.0, 0.0}, {1.0, 1.0}}, {{0.31, 0.2}, {0.77, 0.95}},
                                    {{0.05, 0.11}, {0.66, 0.9}}});
    AtlasBuildSettings s;
    s.atlasSize = 128;
    s.dmin = 1.0; // 960 px/m: every wall is capped at its original's size
    s.format = AtlasFormat::Deflate;
    auto r = buildAtlasTree(m, s, (dir / "t.svat").string());
    ASSERT_TRUE(r) << r.error().message;
    auto f = AtlasTreeFile::open((dir / "t.svat").string());
    ASSERT_TRUE(f) << f.error().message;
    const AtlasTreeData& t = f->trees[0];
    std::vector<SourceTexture> src;
    for (const auto& ct : m.textures) {
        auto st = readSourceTexture(ct);
        ASSERT_TRUE(st) << st.error().message;
        src.push_back(std::move(*st));
    }
    const int A = 128;
    std::size_t checked = 0, turned = 0;
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (std::size_t ni = 0; ni < t.nodes.size(); ++ni) {
        const AtlasNode& n = t.nodes[ni];
        if (!n.leaf() || n.count == 0) continue;
        auto blob = f->readAtlasBlob(0, int(ni));
        ASSERT_TRUE(blob);
        std::vector<std::vector<std::uint8_t>> levels; // RGB8, bottom-up
        for (int l = 0; l <= 3; ++l) levels.push_back(atlasLevelData(AtlasFormat::Deflate, false, *blob, A, l));
        for (std::uint32_t tri = n.first; tri < n.first + n.count; ++tri) {
            const SourceTexture& st = src[t.triangleTexture[tri]];
            const glm::ivec2 W = st.sizes[0];
            for (int k = 0; k < 40; ++k) {
                double b0 = unit(rng), b1 = unit(rng);
                if (b0 + b1 > 1.0) b0 = 1.0 - b0, b1 = 1.0 - b1;
                const glm::dvec3 bary(b0, b1, 1.0 - b0 - b1);
                glm::dvec2 uv(0.0), root(0.0);
                for (int v = 0; v < 3; ++v) {
                    uv += bary[v] * glm::dvec2(t.vertices[tri * 3 + std::size_t(v)].uv);
                    root += bary[v] * glm::dvec2(t.vertices[tri * 3 + std::size_t(v)].root);
                }
                const glm::dvec2 p = levelAtlasCoord(root, n.level) * double(A); // atlas texels
                glm::dvec2 q = uv * glm::dvec2(W);                                 // original texels
                auto integral = [](glm::dvec2 d) {
                    return std::abs(d.x - std::round(d.x)) < 1e-3 && std::abs(d.y - std::round(d.y)) < 1e-3;
                };
                const bool straight = integral(p - q), turn = integral(p - glm::dvec2(q.y, q.x));
                ASSERT_TRUE(straight || turn) << "triangle " << tri << ": atlas texel " << p.x << "," << p.y
                                              << " is not on the original's texel grid at " << q.x << "," << q.y;
                // Texel centres away from the grid lines only (where floor() is unambiguous).
                const glm::dvec2 fq = q - glm::floor(q);
                if (fq.x < 0.01 || fq.x > 0.99 || fq.y < 0.01 || fq.y > 0.99) continue;
                glm::dvec2 qa = straight ? q : glm::dvec2(q.y, q.x); // q along the atlas's axes
                const glm::dvec2 off = glm::round(p - qa);
                EXPECT_EQ(std::fmod(std::abs(off.x), 8.0), 0.0) << "triangle " << tri;
                EXPECT_EQ(std::fmod(std::abs(off.y), 8.0), 0.0) << "triangle " << tri;
                turned += !straight;
                for (int l = 0; l <= 3; ++l) {
                    const glm::ivec2 sl = st.sizes[std::size_t(l)];
                    const glm::ivec2 ql(int(q.x) >> l, int(q.y) >> l);
                    if (ql.x >= sl.x - 1 || ql.y >= sl.y - 1) continue; // a folded last row or column
                    const glm::ivec2 pl(int(p.x) >> l, int(p.y) >> l);
                    const int al = A >> l;
                    const std::uint8_t* a = &levels[std::size_t(l)][(std::size_t(pl.y) * std::size_t(al) + std::size_t(pl.x)) * 3];
                    const std::uint8_t* o = &st.mips[std::size_t(l)][(std::size_t(ql.y) * std::size_t(sl.x) + std::size_t(ql.x)) * 4];
                    for (int c = 0; c < 3; ++c)
                        EXPECT_EQ(int(a[c]), int(o[c])) << "triangle " << tri << " level " << l << " texel " << ql.x << "," << ql.y;
                    ++checked;
                }
            }
        }
    }
    EXPECT_GT(checked, 500u);
    RecordProperty("turned_samples", int(turned));
}

TEST(AtlasTreeTest, EmptyAtlasSpaceContinuesTheNearestArea) {
    // Three covered texels of distinct colours in a 16² image; every other texel takes the colour of a covered
    // texel at the least 4-neighbour distance; covered texels keep theirs; nothing covered: unchanged.
    const int n = 16;
    std::vector<std::uint8_t> img(std::size_t(n * n * 4), 0), covered(std::size_t(n * n), 0);
    const std::vector<std::pair<glm::ivec2, glm::u8vec4>> seeds = {
        {glm::ivec2(2, 3), glm::u8vec4(200, 10, 10, 255)},
        {glm::ivec2(12, 4), glm::u8vec4(10, 200, 10, 255)},
        {glm::ivec2(7, 13), glm::u8vec4(10, 10, 200, 255)}};
    for (const auto& [p, c] : seeds) {
        covered[std::size_t(p.y * n + p.x)] = 1;
        for (int k = 0; k < 4; ++k) img[std::size_t(p.y * n + p.x) * 4 + std::size_t(k)] = c[k];
    }
    auto untouched = img;
    std::vector<std::uint8_t> none(covered.size(), 0);
    dilateRgba(untouched, n, none);
    EXPECT_EQ(untouched, img);
    dilateRgba(img, n, covered);
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            int best = 1 << 30;
            for (const auto& [p, c] : seeds) best = std::min(best, std::abs(p.x - x) + std::abs(p.y - y));
            bool ok = false;
            for (const auto& [p, c] : seeds)
                if (std::abs(p.x - x) + std::abs(p.y - y) == best)
                    ok = ok || (img[std::size_t(y * n + x) * 4] == c[0] && img[std::size_t(y * n + x) * 4 + 1] == c[1] &&
                                img[std::size_t(y * n + x) * 4 + 2] == c[2]);
            EXPECT_TRUE(ok) << x << "," << y;
        }
}
